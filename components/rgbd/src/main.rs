//! The `rgbd` component binary: see [`rgbd::component`].

use clap::Parser;
use interfaces::node::{self, NodeArgs};
use rgbd::component::{self, Config, Source};
use std::process::ExitCode;

/// The head RGB-D camera: publishes `vision/rgbd` from the `sim` or `playback` driver.
#[derive(Debug, Parser)]
#[command(name = "rgbd")]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    #[command(flatten)]
    config: Config,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let interface = component::interface(&args.config);
    if args.node.describe {
        return node::run(args.node, interface, |_, _| async { Ok(()) });
    }
    // Open the driver before joining the bus: a bad recording is reported at once.
    node::init_logging();
    let source = match Source::open(&args.config) {
        Ok(s) => s,
        Err(e) => {
            tracing::error!("{e:#}");
            return ExitCode::FAILURE;
        }
    };
    let config = args.config;
    node::run(args.node, interface, move |bus, shutdown| {
        component::run(bus, config, source, shutdown)
    })
}
