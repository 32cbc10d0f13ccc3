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
pub mod launch;
pub mod record;
pub mod replay;
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
