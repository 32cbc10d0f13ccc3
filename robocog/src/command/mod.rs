//! One file per verb of the `robocog` command line.

/// Print a line; when stdout is gone (`| head`), stop quietly with success, as Unix tools do.
macro_rules! out {
    ($($arg:tt)*) => {
        if writeln!(std::io::stdout().lock(), $($arg)*).is_err() {
            return Ok(0);
        }
    };
}

pub mod agent;
pub mod certs;
pub mod check;
pub mod component;
pub mod interface;
pub mod launch;
pub mod record;
pub mod replay;
pub mod router;
pub mod service;
pub mod topic;
pub mod view;

/// The bus of a command-line tool: joins the graph without announcing itself as a component.
pub(crate) async fn cli_bus(args: &interfaces::ConnectArgs) -> anyhow::Result<interfaces::Bus> {
    let options = interfaces::bus::BusOptions {
        announce: false,
        ..Default::default()
    };
    Ok(interfaces::Bus::open_with(args, "robocog-cli", options).await?)
}

/// Load a manifest for a verb, its problems printed (then `None`: the verb exits 2).
pub(crate) fn load_manifest(
    path: &std::path::Path,
    overrides: &crate::manifest::Overrides,
) -> Option<crate::manifest::Manifest> {
    match crate::manifest::Manifest::load(path, overrides) {
        Ok(m) => Some(m),
        Err(problems) => {
            eprintln!("{problems}");
            None
        }
    }
}

/// A manifest of a graph over several machines for a verb that needs one (`agent`, `certs`),
/// or `None` (said why: the verb exits 2).
pub(crate) fn load_machines_manifest(
    path: &std::path::Path,
    overrides: &crate::manifest::Overrides,
    why: &str,
) -> Option<crate::manifest::Manifest> {
    let manifest = load_manifest(path, overrides)?;
    if manifest.machines.is_empty() {
        eprintln!("error: {} declares no [machines]: {why}", path.display());
        return None;
    }
    Some(manifest)
}

/// The namespace a verb runs in: its flag, else the manifest's, else the default; checked.
pub(crate) fn namespace_of(
    flag: Option<String>,
    manifest: &crate::manifest::Manifest,
) -> anyhow::Result<String> {
    let namespace = flag
        .or_else(|| manifest.namespace.clone())
        .unwrap_or_else(|| interfaces::args::DEFAULT_NAMESPACE.to_string());
    if !interfaces::topic::is_valid_segment(&namespace) {
        anyhow::bail!("invalid namespace {namespace:?}: use letters, digits, '_', '-'");
    }
    Ok(namespace)
}
