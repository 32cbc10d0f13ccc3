//! `deep_representation`: the world model component (see `deep_representation::service`).
//!
//! `deep_representation --scene touch --state-dir /var/lib/robocog/dr` serves the scene graph on
//! the bus; with a state folder, a restart recovers every change.

use clap::Parser;
use deep_representation::service::{self, Scene, ServiceConfig, find_model};
use interfaces::node::{self, NodeArgs};
use std::path::PathBuf;
use std::process::ExitCode;
use world_model::persist::StoreOptions;

/// The deep representation: robocog's world model, served on the bus.
#[derive(Debug, Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    /// Keep the state here (snapshot + change log) and recover it on start. Without it the state
    /// lives in memory only.
    #[arg(long, env = "ROBOCOG_DR_STATE_DIR")]
    state_dir: Option<PathBuf>,
    /// Start scene when there is no saved state.
    #[arg(long, value_enum, default_value_t = Scene::Touch)]
    scene: Scene,
    /// The robot's URDF (default: models/loki.urdf found above the binary or the working folder).
    #[arg(long, env = "ROBOCOG_URDF")]
    urdf: Option<PathBuf>,
    /// The SPL field model (default: models/spl_field.toml, found like the URDF).
    #[arg(long, env = "ROBOCOG_FIELD")]
    field: Option<PathBuf>,
    /// Write a fresh snapshot every this many changes.
    #[arg(long, default_value_t = 1000)]
    compact_every: usize,
    /// fdatasync the change log after every change (survives a power loss, costs a disk flush).
    #[arg(long)]
    fsync: bool,
    /// Follow the measured joints: subscribe body/joint_states (from joint_motor) and apply them
    /// to the robot's joints, so transforms of the hands and the head camera follow the body.
    #[arg(long)]
    follow_joint_states: bool,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let config = ServiceConfig {
        state_dir: args.state_dir,
        scene: args.scene,
        urdf: find_model(args.urdf.as_deref(), "loki.urdf"),
        field: find_model(args.field.as_deref(), "spl_field.toml"),
        store: StoreOptions {
            compact_every: args.compact_every.max(1),
            fsync: args.fsync,
        },
        follow_joint_states: args.follow_joint_states,
        ..ServiceConfig::new(args.scene)
    };
    let interface = service::interface_with(config.follow_joint_states);
    node::run(args.node, interface, move |bus, shutdown| {
        service::run(bus, config, shutdown)
    })
}
