//! `robocog launch <manifest>`: run a graph.

use crate::manifest::{Manifest, Overrides};
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
}

pub async fn execute(args: Args) -> anyhow::Result<i32> {
    let manifest = match Manifest::load(&args.manifest, &args.overrides) {
        Ok(m) => m,
        Err(problems) => {
            eprintln!("{problems}");
            return Ok(2);
        }
    };
    match crate::check::check(&manifest) {
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
    let namespace = args
        .namespace
        .or_else(|| manifest.namespace.clone())
        .unwrap_or_else(|| interfaces::args::DEFAULT_NAMESPACE.to_string());
    if !interfaces::topic::is_valid_segment(&namespace) {
        anyhow::bail!("invalid namespace {namespace:?}: use letters, digits, '_', '-'");
    }
    let router = args
        .router
        .or_else(|| manifest.router.clone())
        .unwrap_or_else(|| interfaces::args::DEFAULT_ROUTER.to_string());
    let color = match args.color.as_str() {
        "always" => true,
        "never" => false,
        _ => std::io::stdout().is_terminal(),
    };
    launch(
        manifest,
        LaunchOptions {
            namespace,
            router,
            color,
        },
    )
    .await
}
