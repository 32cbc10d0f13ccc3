//! `robocog view`: watch a running graph in the rerun viewer.
//!
//! The work is done by the `viewer` component (its own binary, installed beside `robocog`), so the
//! launcher stays free of the rerun SDK: this verb replaces itself with `viewer`, handing over
//! every flag unchanged (`robocog view --help` is the viewer's own help).

use std::os::unix::process::CommandExt;
use std::path::PathBuf;

/// Everything after `view`, for the `viewer` binary.
#[derive(Debug, clap::Args)]
#[command(disable_help_flag = true)]
pub struct Args {
    /// The viewer's flags (see `robocog view --help`).
    #[arg(
        trailing_var_arg = true,
        allow_hyphen_values = true,
        value_name = "FLAGS"
    )]
    pub args: Vec<String>,
}

/// The `viewer` binary beside this executable.
fn viewer_binary() -> anyhow::Result<PathBuf> {
    let me = std::env::current_exe()
        .map_err(|e| anyhow::anyhow!("cannot locate the robocog executable: {e}"))?;
    let dir = me
        .parent()
        .ok_or_else(|| anyhow::anyhow!("{} has no parent folder", me.display()))?;
    let viewer = dir.join("viewer");
    if viewer.is_file() {
        Ok(viewer)
    } else {
        anyhow::bail!(
            "no `viewer` binary beside {} (build it with `cargo build --release -p viewer`)",
            me.display()
        )
    }
}

/// Replace this process with `viewer <flags>`; returns only if that fails.
pub async fn execute(args: Args) -> anyhow::Result<i32> {
    let viewer = viewer_binary()?;
    let err = std::process::Command::new(&viewer).args(&args.args).exec();
    anyhow::bail!("cannot run {}: {err}", viewer.display())
}
