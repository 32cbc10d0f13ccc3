//! The `joint_motor` component binary: see [`joint_motor::component`].

use clap::Parser;
use interfaces::node::{self, NodeArgs};
use joint_motor::component::{self, Config};
use std::process::ExitCode;

/// Loki's joints on the bus: publishes body/joint_states at --rate-hz (every joint's position,
/// velocity and owner) and serves body/joint_goal (position or velocity goals, refused with the
/// joint, the limit and the owner when they break a limit or another client owns the joint).
/// Drivers: `sim` (no hardware) or `dynamixel` (Protocol 2.0 servos on a serial port).
#[derive(Debug, Parser)]
#[command(name = "joint_motor", version)]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    #[command(flatten)]
    config: Config,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let config = args.config;
    node::run(args.node, component::interface(), move |bus, shutdown| {
        component::run(bus, config, shutdown)
    })
}
