//! The `body_inverse_kinematics` component binary: see [`body_inverse_kinematics::component`].

use body_inverse_kinematics::component::{self, Config};
use clap::Parser;
use interfaces::node::{self, NodeArgs};
use std::process::ExitCode;

/// Reach and gaze for Loki's body parts: takes goals on body/reach (a DR frame and a point in it,
/// for a named chain such as left_arm_7 or neck), solves them with Levenberg-Marquardt IK from the
/// measured joints (body/joint_states), drives joint_motor along a smooth trajectory
/// (body/joint_goal) and reports Moving, Reached, Unreachable, Cancelled or Failed on
/// body/reach_status. `follow` goals track a moving DR frame (the ball).
#[derive(Debug, Parser)]
#[command(name = "body_inverse_kinematics", version)]
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
