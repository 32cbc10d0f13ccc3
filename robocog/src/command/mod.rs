//! One file per verb of the `robocog` command line.

pub mod check;
pub mod component;
pub mod launch;
pub mod topic;

/// The bus of a command-line tool: joins the graph without announcing itself as a component.
pub(crate) async fn cli_bus(args: &interfaces::ConnectArgs) -> anyhow::Result<interfaces::Bus> {
    let options = interfaces::bus::BusOptions {
        announce: false,
        ..Default::default()
    };
    Ok(interfaces::Bus::open_with(args, "robocog-cli", options).await?)
}
