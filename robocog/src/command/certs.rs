//! `robocog certs <manifest>`: the certificates of a graph over several machines.
//!
//! One CA for the graph (`ca.pem`, and its key `ca.key`, which stays with whoever makes the
//! certificates: the machines need only `ca.pem`), and per machine a certificate whose common
//! name is the machine's name (what the routers' access control checks) and whose subject
//! names hold the host of its router endpoint (what a router dialling it checks). Existing
//! files are kept (a machine added later gets its certificate from the same CA) unless
//! `--renew`. Keys are written readable by their owner only.
//!
//! The same with openssl, for one machine `robot` at 10.0.0.2:
//!
//! ```text
//! openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -days 825 \
//!     -subj /CN=robocog-ca -keyout ca.key -out ca.pem
//! openssl req -newkey ec -pkeyopt ec_paramgen_curve:P-256 -nodes -subj /CN=robot \
//!     -keyout robot.key -out robot.csr
//! openssl x509 -req -in robot.csr -CA ca.pem -CAkey ca.key -days 825 \
//!     -extfile <(printf "subjectAltName=IP:10.0.0.2") -out robot.pem
//! ```

use crate::manifest::Overrides;
use anyhow::Context;
use rcgen::{
    BasicConstraints, CertificateParams, DnType, ExtendedKeyUsagePurpose, IsCa, Issuer, KeyPair,
    KeyUsagePurpose,
};
use std::io::Write;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The graph's launch manifest; its [machines] say which certificates to make, and for
    /// which hosts.
    pub manifest: PathBuf,
    /// Where to write them (default: the manifest's [graph] certs folder).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// How long the certificates are valid (days).
    #[arg(long, default_value_t = 825)]
    pub days: u32,
    /// Make new certificates for every machine even where some exist (the CA is kept).
    #[arg(long)]
    pub renew: bool,
    #[command(flatten)]
    pub overrides: Overrides,
}

/// The host part of an endpoint (`tls/10.0.0.2:7447` -> `10.0.0.2`).
fn host_of(endpoint: &str) -> Option<String> {
    let addr = endpoint.split_once('/')?.1;
    let addr = addr.split('#').next()?;
    let (host, _port) = addr.rsplit_once(':')?;
    Some(
        host.trim_start_matches('[')
            .trim_end_matches(']')
            .to_string(),
    )
}

fn write_file(path: &Path, text: &str, private: bool) -> anyhow::Result<()> {
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .create(true)
        .truncate(true)
        .mode(if private { 0o600 } else { 0o644 })
        .open(path)
        .with_context(|| format!("cannot write {}", path.display()))?;
    f.write_all(text.as_bytes())
        .with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

fn validity(params: &mut CertificateParams, days: u32) {
    let now = time::OffsetDateTime::now_utc();
    params.not_before = now - time::Duration::hours(1);
    params.not_after = now + time::Duration::days(i64::from(days));
}

pub fn execute(args: Args) -> anyhow::Result<i32> {
    let Some(manifest) = super::load_machines_manifest(
        &args.manifest,
        &args.overrides,
        "a graph of one machine has no links to secure",
    ) else {
        return Ok(2);
    };
    let Some(out) = args.out.clone().or_else(|| manifest.certs.clone()) else {
        eprintln!(
            "error: say where the certificates go: --out, or certs in the manifest's [graph]"
        );
        return Ok(2);
    };
    if args.days == 0 {
        anyhow::bail!("--days must be at least 1");
    }
    std::fs::create_dir_all(&out).with_context(|| format!("cannot create {}", out.display()))?;

    // The graph's CA: kept when it exists.
    let (ca_pem, ca_key) = (out.join("ca.pem"), out.join("ca.key"));
    let issuer = if ca_pem.is_file() && ca_key.is_file() {
        let key = KeyPair::from_pem(&std::fs::read_to_string(&ca_key)?)
            .with_context(|| format!("cannot read the CA key {}", ca_key.display()))?;
        let issuer = Issuer::from_ca_cert_pem(&std::fs::read_to_string(&ca_pem)?, key)
            .with_context(|| format!("cannot read the CA {}", ca_pem.display()))?;
        eprintln!("keeping the graph's CA {}", ca_pem.display());
        issuer
    } else {
        let mut params = CertificateParams::new(Vec::<String>::new())?;
        params
            .distinguished_name
            .push(DnType::CommonName, format!("robocog {} CA", manifest.name));
        params.is_ca = IsCa::Ca(BasicConstraints::Constrained(0));
        params.key_usages = vec![KeyUsagePurpose::KeyCertSign, KeyUsagePurpose::CrlSign];
        validity(&mut params, args.days);
        let key = KeyPair::generate()?;
        let cert = params.self_signed(&key)?;
        write_file(&ca_key, &key.serialize_pem(), true)?;
        write_file(&ca_pem, &cert.pem(), false)?;
        eprintln!(
            "made the graph's CA {} (keep ca.key off the robots)",
            ca_pem.display()
        );
        Issuer::new(params, key)
    };

    for m in &manifest.machines {
        let files = interfaces::router::TlsFiles::in_folder(&out, &m.name);
        let (cert_path, key_path) = (files.cert, files.key);
        if cert_path.is_file() && key_path.is_file() && !args.renew {
            eprintln!("machine {}: keeping {}", m.name, cert_path.display());
            continue;
        }
        let host = host_of(&m.router)
            .with_context(|| format!("machine {}: no host in {:?}", m.name, m.router))?;
        let mut params = CertificateParams::new(vec![host.clone()]).with_context(|| {
            format!("machine {}: {host:?} is no IP address or DNS name", m.name)
        })?;
        params
            .distinguished_name
            .push(DnType::CommonName, m.name.clone());
        params.key_usages = vec![KeyUsagePurpose::DigitalSignature];
        params.extended_key_usages = vec![
            ExtendedKeyUsagePurpose::ServerAuth,
            ExtendedKeyUsagePurpose::ClientAuth,
        ];
        validity(&mut params, args.days);
        let key = KeyPair::generate()?;
        let cert = params.signed_by(&key, &issuer)?;
        write_file(&key_path, &key.serialize_pem(), true)?;
        write_file(&cert_path, &cert.pem(), false)?;
        eprintln!(
            "machine {}: made {} for {host} ({} days)",
            m.name,
            cert_path.display(),
            args.days
        );
    }
    println!(
        "certificates in {}: copy ca.pem, <machine>.pem and <machine>.key to each machine's certs folder",
        out.display()
    );
    Ok(0)
}

#[cfg(test)]
mod tests {
    use super::host_of;

    #[test]
    fn the_host_of_an_endpoint() {
        assert_eq!(host_of("tls/10.0.0.2:7447").as_deref(), Some("10.0.0.2"));
        assert_eq!(host_of("tls/[fd00::2]:7447").as_deref(), Some("fd00::2"));
        assert_eq!(
            host_of("tls/robot.local:7447").as_deref(),
            Some("robot.local")
        );
        assert_eq!(host_of("robot"), None);
    }
}
