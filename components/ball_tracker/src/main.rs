//! The `ball_tracker` component binary: see [`ball_tracker::component`].

use ball_tracker::component::{self, Config};
use clap::Parser;
use interfaces::node::{self, NodeArgs};
use std::process::ExitCode;

/// Tracks a coloured ball in `vision/rgbd`; publishes `vision/ball` and `vision/ball_events`.
#[derive(Debug, Parser)]
#[command(name = "ball_tracker")]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    #[command(flatten)]
    config: Config,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let config = args.config;
    node::run(
        args.node,
        component::interface(&config),
        move |bus, shutdown| component::run(bus, config, shutdown),
    )
}
