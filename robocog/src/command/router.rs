//! `robocog router --config <file>`: one machine's zenoh router as a process of its own. The
//! launcher and the agent start it (and start it again when it dies) with the configuration they
//! wrote; it prints `listening on <endpoint>` once its clients can join, and runs until SIGTERM or
//! Ctrl-C.

use std::io::Write;
use std::path::PathBuf;

#[derive(Debug, clap::Args)]
pub struct Args {
    /// The router's zenoh configuration (JSON5), as the launcher or the agent wrote it.
    #[arg(long)]
    pub config: PathBuf,
}

pub async fn execute(args: Args) -> anyhow::Result<i32> {
    let config = zenoh::Config::from_file(&args.config).map_err(|e| {
        anyhow::anyhow!(
            "cannot read the router's configuration {}: {e}",
            args.config.display()
        )
    })?;
    let listen = config
        .get_json("listen/endpoints")
        .unwrap_or_else(|_| "[]".into());
    let (session, endpoint) = interfaces::router::open_configured(config, &listen).await?;
    {
        let mut out = std::io::stdout().lock();
        writeln!(out, "{} {endpoint}", crate::router_process::LISTENING)?;
        out.flush()?;
    }
    use tokio::signal::unix::{SignalKind, signal};
    let mut term = signal(SignalKind::terminate())?;
    let mut int = signal(SignalKind::interrupt())?;
    tokio::select! {
        _ = term.recv() => {}
        _ = int.recv() => {}
    }
    if let Err(e) = session.close().await {
        eprintln!("closing the router: {e}");
    }
    Ok(0)
}
