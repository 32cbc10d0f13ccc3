//! The routers of a graph over several machines.
//!
//! Every machine of a graph hosts one router (the launcher's machine in `robocog launch`, every
//! other one in `robocog agent`). It listens twice:
//!
//! - on loopback (`tcp/127.0.0.1:<port>`), plain: the machine's own components join there, as
//!   they do on a graph of one machine;
//! - on the machine's `router` endpoint of the manifest (`tls/10.0.0.2:7447`), where the other
//!   machines' routers join it. Each router also dials every other machine's endpoint (zenoh
//!   keeps one link per pair and redials a lost one), so any machine can come first, and a
//!   machine that comes back rejoins by itself. No multicast, no gossip: explicit endpoints.
//!
//! With TLS (`tls/` endpoints and the graph's `certs` folder) the links between machines are
//! mutual TLS: both sides show a certificate signed by the graph's CA (`ca.pem`), each machine
//! its own (`<machine>.pem`, `<machine>.key`, common name = the machine's name), and the name of
//! the endpoint dialled must be in the certificate. On top, zenoh's access control lets through
//! only what comes from loopback or from a link whose certificate names one of the graph's
//! machines, and only on the graph's keys (`robocog/<namespace>/**`): a host with no
//! certificate cannot open a link, and one with a certificate of this CA but not of this graph
//! can neither publish nor subscribe.
//!
//! A lost machine is noticed in 3 s (the links' lease), not zenoh's default 10 s: its tokens go,
//! and the launcher and the games hear of it.

use crate::manifest::{Machine, Manifest};
use anyhow::{Context, bail};
use interfaces::router::{MachineRouter, TlsFiles, machine_router_config};
use std::path::Path;

/// Machine `machine`'s certificate files in `folder`, or an error naming the missing ones and
/// how to make them.
pub fn machine_certs(folder: &Path, machine: &str) -> anyhow::Result<TlsFiles> {
    let files = TlsFiles::in_folder(folder, machine);
    let missing: Vec<String> = files
        .missing()
        .iter()
        .map(|p| p.display().to_string())
        .collect();
    if !missing.is_empty() {
        bail!(
            "machine {machine:?} has no certificate: missing {} (robocog certs <manifest> makes the graph's CA and one certificate per machine)",
            missing.join(", ")
        );
    }
    Ok(files)
}

/// The machine `name` of `manifest`, or an error listing those there are.
pub fn machine<'m>(manifest: &'m Manifest, name: &str) -> anyhow::Result<&'m Machine> {
    manifest
        .machines
        .iter()
        .find(|m| m.name == name)
        .with_context(|| {
            let known: Vec<&str> = manifest.machines.iter().map(|m| m.name.as_str()).collect();
            format!(
                "the graph {:?} has no machine {name:?} (machines: {})",
                manifest.name,
                known.join(", ")
            )
        })
}

/// The zenoh configuration of machine `me`'s router ([`interfaces::router::machine_router_config`]):
/// loopback at `local_listen`, the machine's endpoint for the others, a dial to every other
/// machine, TLS and access control when its endpoint is `tls/`.
pub fn router_config(
    manifest: &Manifest,
    me: &Machine,
    local_listen: &str,
    namespace: &str,
) -> anyhow::Result<zenoh::Config> {
    let tls = if me.is_tls() {
        let folder = manifest
            .certs
            .as_deref()
            .context("TLS between machines needs [graph] certs")?;
        Some(machine_certs(folder, &me.name)?)
    } else {
        None
    };
    let router = MachineRouter {
        local_listen: local_listen.to_string(),
        endpoint: me.router.clone(),
        peers: manifest
            .machines
            .iter()
            .filter(|m| m.name != me.name)
            .map(|m| m.router.clone())
            .collect(),
        tls,
        machines: manifest.machines.iter().map(|m| m.name.clone()).collect(),
        namespace: namespace.to_string(),
        ros2_domain: ros2_domain(manifest)?,
    };
    Ok(machine_router_config(&router)?)
}

/// The ROS 2 domain whose keys the routers let through: the manifest's `ros2_domain` when its
/// `ros2` variable turns the rmw_zenoh-compatible mode on (every machine's agent needs the same
/// `--set ros2=true`), else none.
fn ros2_domain(manifest: &Manifest) -> anyhow::Result<Option<u32>> {
    if manifest.vars.get("ros2").map(String::as_str) != Some("true") {
        return Ok(None);
    }
    let text = manifest.vars.get("ros2_domain").map_or("0", String::as_str);
    let domain = text.parse::<u32>().map_err(|_| {
        anyhow::anyhow!("ros2_domain = {text:?} is not a ROS 2 domain id (0 to 232)")
    })?;
    Ok(Some(domain))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::manifest::Overrides;

    fn manifest(dir: &Path, text: &str) -> Manifest {
        let p = dir.join("g.toml");
        std::fs::write(&p, text).unwrap();
        Manifest::load(&p, &Overrides::default()).unwrap()
    }

    #[test]
    fn a_tls_router_listens_on_loopback_and_its_endpoint_and_dials_the_others() {
        let dir = std::env::temp_dir().join(format!("robocog-machines-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let m = manifest(
            &dir,
            r#"
[graph]
certs = "certs"
[machines.robot]
router = "tls/10.1.0.1:7447"
[machines.speech]
router = "tls/10.1.0.2:7447"
[[component]]
name = "a"
binary = "true"
machine = "speech"
"#,
        );
        let me = machine(&m, "robot").unwrap();
        // No certificates yet: the error says what is missing and how to make it.
        let e = router_config(&m, me, "tcp/127.0.0.1:0", "ns")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("robot.pem") && e.contains("robocog certs"),
            "{e}"
        );
        let certs = dir.join("certs");
        std::fs::create_dir_all(&certs).unwrap();
        for f in ["ca.pem", "robot.pem", "robot.key"] {
            std::fs::write(certs.join(f), "x").unwrap();
        }
        let c = router_config(&m, me, "tcp/127.0.0.1:0", "ns").unwrap();
        let get = |k: &str| c.get_json(k).unwrap();
        assert_eq!(
            get("listen/endpoints"),
            r#"["tcp/127.0.0.1:0","tls/10.1.0.1:7447"]"#
        );
        assert_eq!(get("connect/endpoints"), r#"["tls/10.1.0.2:7447"]"#);
        assert_eq!(get("transport/link/tls/enable_mtls"), "true");
        assert!(get("access_control").contains("robocog/ns/**"));
        assert!(get("access_control").contains("speech"));
        assert!(!get("access_control").contains("@ros2_lv"));
        // With the rmw_zenoh-compatible mode on, the ROS 2 domain's keys get through too.
        let mut ros = m.clone();
        ros.vars.insert("ros2".into(), "true".into());
        ros.vars.insert("ros2_domain".into(), "7".into());
        let c = router_config(&ros, me, "tcp/127.0.0.1:0", "ns").unwrap();
        let acl = c.get_json("access_control").unwrap();
        assert!(
            acl.contains("@ros2_lv/7/**") && acl.contains("\"7/**\""),
            "{acl}"
        );
        ros.vars.insert("ros2_domain".into(), "seven".into());
        let e = router_config(&ros, me, "tcp/127.0.0.1:0", "ns")
            .unwrap_err()
            .to_string();
        assert!(e.contains("\"seven\" is not a ROS 2 domain id"), "{e}");
        let e = machine(&m, "field").unwrap_err().to_string();
        assert!(e.contains("robot, speech"), "{e}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
