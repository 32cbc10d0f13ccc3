use clap::Parser;
use interfaces::node::{self, Interface, NodeArgs};
use interfaces::topics;
use nao_bridge::component::{Config, ProposeVia, run};
use std::net::IpAddr;
use std::process::ExitCode;

/// The operator-side end of the Nao coach link: commands out on UDP, the robots' world models
/// and the GameController's state in, all on the bus.
#[derive(Debug, Parser)]
#[command(version)]
struct Args {
    #[command(flatten)]
    node: NodeArgs,
    /// Address of the controlled robot (player 2), which receives the commands.
    #[arg(long, default_value = "127.0.0.2")]
    robot: IpAddr,
    /// Address of the autonomous teammate (player 1), whose debug packets are also accepted.
    #[arg(long)]
    teammate: Option<IpAddr>,
    /// The robot's command port.
    #[arg(long, default_value_t = spl::COMMAND_PORT)]
    command_port: u16,
    /// Address to listen on for debug and GameController packets (UDP).
    #[arg(long, default_value = "127.0.0.1")]
    udp_listen: IpAddr,
    /// Port of the robots' debug packets.
    #[arg(long, default_value_t = spl::DEBUG_PORT)]
    debug_port: u16,
    /// Port of the GameController's packets.
    #[arg(long, default_value_t = spl::GAMECONTROLLER_PORT)]
    gamecontroller_port: u16,
    /// Our team number (finds our block in the GameController packet).
    #[arg(long, default_value_t = 19)]
    team_number: u8,
    /// No packet from a robot for this long: "robot not responding" (s).
    #[arg(long, default_value_t = 1.0)]
    link_timeout_s: f64,
    /// Mirror the team model (our robots, the ball, the obstacles) and the game state into the
    /// deep representation's coach scene with `dr/update` (needs `deep_representation --scene
    /// coach`). Obstacles come and go, so their nodes are added and removed by structural
    /// proposals (see --dr-propose-via).
    #[arg(long)]
    dr_updates: bool,
    /// Where the obstacle nodes' structural proposals go with --dr-updates: `executive` (checked
    /// against the game by the Executive first, as every structural change should be) or `dr`
    /// (straight to the DR, for graphs without an Executive).
    #[arg(long, value_enum, default_value_t = ProposeVia::Executive)]
    dr_propose_via: ProposeVia,
}

fn main() -> ExitCode {
    let args = Args::parse();
    let mut base = Interface::new("nao_bridge")
        .subscribes(&topics::NAO_COMMAND)
        .publishes(&topics::NAO_LOCAL_MODEL)
        .publishes(&topics::NAO_WORLD_MODEL)
        .publishes(&topics::NAO_GAME_STATE)
        .publishes(&topics::NAO_LINK);
    if args.dr_updates {
        base = base
            .calls(&topics::DR_UPDATE)
            .calls(args.dr_propose_via.service());
    }
    let interface = Interface {
        hardware: vec![
            format!("udp:{}", args.debug_port),
            format!("udp:{}", args.gamecontroller_port),
        ],
        ..base
    };
    let config = Config {
        controlled: args.robot,
        teammate: args.teammate,
        command_port: args.command_port,
        listen: args.udp_listen,
        debug_port: args.debug_port,
        gamecontroller_port: args.gamecontroller_port,
        team_number: args.team_number,
        link_timeout_s: args.link_timeout_s,
        dr_updates: args.dr_updates,
        propose_via: args.dr_propose_via,
    };
    node::run(args.node, interface, |bus, shutdown| {
        run(bus, config, shutdown)
    })
}
