//! `robocog agent --machine <name> <manifest>`: run one machine's share of a graph.

use crate::agent::{AgentOptions, run};
use crate::manifest::Overrides;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The graph's launch manifest (the same file as the launcher's): its [machines] say where
    /// this machine's router listens and which routers to join, its certs folder holds this
    /// machine's certificate.
    pub manifest: PathBuf,
    /// This machine's name in the manifest's [machines].
    #[arg(long, env = "ROBOCOG_MACHINE")]
    pub machine: String,
    /// Namespace of the deployment (default: the manifest's, else "default").
    #[arg(long, env = "ROBOCOG_NAMESPACE")]
    pub namespace: Option<String>,
    /// The loopback endpoint this machine's components join; port 0 picks a free port.
    #[arg(long, default_value = interfaces::args::DEFAULT_ROUTER)]
    pub router: String,
    #[command(flatten)]
    pub overrides: Overrides,
    /// Where components keep their state (`<root>/<graph>/<namespace>/<component>`)
    /// (default: $XDG_STATE_HOME/robocog, else ~/.local/state/robocog).
    #[arg(long, env = "ROBOCOG_STATE_ROOT")]
    pub state_root: Option<PathBuf>,
    /// Stop the components a launch started here once its launcher has been out of reach this
    /// long (seconds): a machine that drops off for a moment keeps its components, one whose
    /// launcher is gone for good does not leave them running.
    #[arg(long, default_value_t = 60.0)]
    pub orphan_after_s: f64,
}

pub async fn execute(args: Args) -> anyhow::Result<i32> {
    let Some(manifest) = super::load_machines_manifest(
        &args.manifest,
        &args.overrides,
        "a graph of one machine needs no agent (robocog launch runs it)",
    ) else {
        return Ok(2);
    };
    let namespace = super::namespace_of(args.namespace, &manifest)?;
    if !(args.orphan_after_s.is_finite() && args.orphan_after_s > 0.0) {
        anyhow::bail!("--orphan-after-s must be a positive number of seconds");
    }
    run(
        manifest,
        AgentOptions {
            machine: args.machine,
            namespace,
            local_router: args.router,
            state_root: args
                .state_root
                .unwrap_or_else(super::launch::default_state_root),
            orphan_after: Duration::from_secs_f64(args.orphan_after_s),
        },
    )
    .await
}
