use clap::Parser;
use interfaces::node::{self, Interface, NodeArgs};
use interfaces::topics;
use spl_field::process::{NetConfig, run};
use spl_field::types::{RobotId, SimConfig};
use std::net::IpAddr;
use std::process::ExitCode;

/// A simulated RoboCup SPL field for the coach game: two robots of ours (one controlled, one
/// autonomous), two opponents, a ball and a GameController, speaking the real UDP protocols.
#[derive(Debug, Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    /// The operator PC (where the bridge listens).
    #[arg(long, default_value = "127.0.0.1")]
    operator: IpAddr,
    /// The bridge's debug port.
    #[arg(long, default_value_t = 65305)]
    debug_port: u16,
    /// The bridge's GameController port.
    #[arg(long, default_value_t = 3838)]
    gamecontroller_port: u16,
    /// Address of the simulated controlled robot (player 2).
    #[arg(long, default_value = "127.0.0.2")]
    controlled: IpAddr,
    /// Address of the simulated autonomous teammate (player 1).
    #[arg(long, default_value = "127.0.0.3")]
    teammate: IpAddr,
    /// The controlled robot's command port.
    #[arg(long, default_value_t = 65306)]
    command_port: u16,
    /// Random seed (falls, perception noise).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Simulated seconds per real second.
    #[arg(long, default_value_t = 1.0)]
    time_scale: f64,
    /// Seconds in INITIAL, READY and SET before the 90 s attack starts.
    #[arg(long)]
    pre_game_s: Option<f64>,
    /// Falls per minute per robot (0: never).
    #[arg(long)]
    falls_per_min: Option<f64>,
    /// Whether the two opponents stand still in PLAYING (obstacles only; scripted scenarios).
    #[arg(long, default_value_t = false, action = clap::ArgAction::Set)]
    passive_opponents: bool,
    /// Penalise the controlled robot this many simulated seconds into PLAYING (scripted
    /// scenarios): the GameController reports it, the robot stands out of play.
    #[arg(long)]
    penalty_at_s: Option<f64>,
    /// Length of that penalty (simulated s).
    #[arg(long, default_value_t = 45.0)]
    penalty_s: f64,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let interface = Interface {
        hardware: vec![format!("udp:{}:{}", args.controlled, args.command_port)],
        ..Interface::new("spl_field").publishes(&topics::SIM_FIELD_TRUTH)
    };
    let mut sim = SimConfig {
        seed: args.seed,
        ..SimConfig::default()
    };
    if let Some(p) = args.pre_game_s {
        let p = p.max(0.0) / 3.0;
        (sim.initial_s, sim.ready_s, sim.set_s) = (p, p, p);
    }
    if let Some(f) = args.falls_per_min {
        sim.falls_per_min = f.max(0.0);
    }
    sim.penalty_at_s = args.penalty_at_s.filter(|s| s.is_finite() && *s >= 0.0);
    sim.penalty_s = args.penalty_s.max(0.0);
    if args.passive_opponents {
        sim.passive_robots = vec![RobotId::KEEPER, RobotId::DEFENDER];
    }
    let net = NetConfig {
        operator: args.operator,
        debug_port: args.debug_port,
        gamecontroller_port: args.gamecontroller_port,
        controlled: args.controlled,
        teammate: args.teammate,
        command_port: args.command_port,
        time_scale: args.time_scale.max(0.01),
    };
    node::run(args.node, interface, |bus, shutdown| {
        run(bus, net, sim, shutdown)
    })
}
