//! `robocog launch <manifest>`: run a graph.

use crate::manifest::Overrides;
use crate::supervisor::{LaunchOptions, launch};
use std::io::IsTerminal;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The launch manifest (TOML).
    pub manifest: PathBuf,
    /// Namespace of this deployment (default: the manifest's, else "default").
    #[arg(long, env = "ROBOCOG_NAMESPACE")]
    pub namespace: Option<String>,
    /// Endpoint of the launcher's router; port 0 picks a free port
    /// (default: the manifest's, else tcp/127.0.0.1:7447).
    #[arg(long)]
    pub router: Option<String>,
    #[command(flatten)]
    pub overrides: Overrides,
    /// Colour the component prefixes: auto, always, never.
    #[arg(long, default_value = "auto")]
    pub color: String,
    /// Where components keep their state (each in `<root>/<graph>/<namespace>/<component>`,
    /// given to it as ROBOCOG_STATE_DIR), so that a restarted component takes up where it was
    /// (default: $XDG_STATE_HOME/robocog, else ~/.local/state/robocog).
    #[arg(long, env = "ROBOCOG_STATE_ROOT")]
    pub state_root: Option<PathBuf>,
    /// Take up the state an earlier launch of this graph and namespace left (one that did not
    /// end cleanly: the launcher or the machine died). Without it the graph starts afresh and
    /// what an earlier launch left is moved aside to `<namespace>.previous`.
    #[arg(long)]
    pub resume: bool,
    /// For a graph over several machines ([machines] in the manifest): which one this is. The
    /// components placed on the others are started there by their agents (`robocog agent`).
    #[arg(long, env = "ROBOCOG_MACHINE")]
    pub machine: Option<String>,
    /// How long to wait for the other machines' agents (seconds).
    #[arg(long, default_value_t = 30.0)]
    pub machine_timeout_s: f64,
}

/// A graph's name as one folder name.
fn path_segment(name: &str) -> String {
    let s: String = name
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '_' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect();
    if s.is_empty() { "graph".into() } else { s }
}

/// The default root of the components' state folders.
pub(crate) fn default_state_root() -> PathBuf {
    std::env::var_os("XDG_STATE_HOME")
        .filter(|v| !v.is_empty())
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".local/state")))
        .unwrap_or_else(std::env::temp_dir)
        .join("robocog")
}

pub async fn execute(args: Args) -> anyhow::Result<i32> {
    let Some(manifest) = super::load_manifest(&args.manifest, &args.overrides) else {
        return Ok(2);
    };
    // The graph's structure only: a component whose files or devices are missing says so
    // itself at start (exit 78), and the launcher stops at once with its message.
    match crate::check::check(&manifest, false, args.machine.as_deref()) {
        Ok(report) => {
            for w in &report.warnings {
                eprintln!("warning: {w}");
            }
        }
        Err(problems) => {
            eprintln!("{problems}");
            return Ok(2);
        }
    }
    let namespace = super::namespace_of(args.namespace, &manifest)?;
    let router = args
        .router
        .or_else(|| manifest.router.clone())
        .unwrap_or_else(|| interfaces::args::DEFAULT_ROUTER.to_string());
    let color = match args.color.as_str() {
        "always" => true,
        "never" => false,
        _ => std::io::stdout().is_terminal(),
    };
    let state_dir = args
        .state_root
        .unwrap_or_else(default_state_root)
        .join(path_segment(&manifest.name))
        .join(&namespace);
    launch(
        manifest,
        LaunchOptions {
            namespace,
            router,
            color,
            state_dir,
            resume: args.resume,
            machine: args.machine,
            machine_timeout: std::time::Duration::from_secs_f64(
                args.machine_timeout_s.clamp(1.0, 3600.0),
            ),
        },
    )
    .await
}
