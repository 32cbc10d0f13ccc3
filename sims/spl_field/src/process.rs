//! The simulated field as a process: it plays the robots and the GameController on UDP exactly
//! where real ones would be, so the bridge cannot tell it from a real field.
//!
//! - The controlled robot (player 2) listens for command packets on `controlled:command_port`
//!   and sends its debug packets from that address; the teammate (player 1) sends from its own
//!   address (robots are told apart by address, as on a real network: on one host, use two
//!   loopback addresses such as 127.0.0.2 and 127.0.0.3).
//! - Debug packets go every 100 ms per robot to `operator:debug_port`, GameController packets
//!   at 2 Hz to `operator:gamecontroller_port`.
//! - Ground truth is published on `sim/field_truth` at 10 Hz, for tests and viewers only.
//! - Scripted falls, for tests and demos: `SIGUSR1` knocks the controlled robot over, `SIGUSR2`
//!   the autonomous teammate (each gets up after the configured get-up time). A scripted
//!   penalty of the controlled robot comes from the configuration (`penalty_at_s`).
//! - Link loss, for tests: stop the process (`SIGSTOP`) and continue it (`SIGCONT`); the field's
//!   time stands still meanwhile, as a robot whose software stalled.

use crate::sim::SplField;
use crate::types::{Datagram, RobotId, SimConfig, SimEvent};
use interfaces::msg::nao::{FieldPoint, FieldPose, FieldTruth};
use interfaces::node::Interface;
use interfaces::{Bus, Shutdown, topics};
use std::net::{IpAddr, SocketAddr};
use std::time::Duration;
use tokio::net::UdpSocket;

/// Where the simulated robots sit on the network.
#[derive(Debug, Clone)]
pub struct NetConfig {
    pub operator: IpAddr,
    pub debug_port: u16,
    pub gamecontroller_port: u16,
    pub controlled: IpAddr,
    pub teammate: IpAddr,
    pub command_port: u16,
    /// Simulated seconds per real second.
    pub time_scale: f64,
    /// Attacks to play one after another (at least 1), and the simulated seconds in FINISHED
    /// between two.
    pub attacks: u32,
    pub between_attacks_s: f64,
}

fn pose_of(field: &SplField, id: RobotId) -> FieldPose {
    field
        .robot(id)
        .map(|r| FieldPose {
            x_mm: r.pos.x as f32,
            y_mm: r.pos.y as f32,
            theta_rad: r.theta as f32,
        })
        .unwrap_or_default()
}

/// Attacks one after another: the one under way, how many, and when it finished.
struct Attacks {
    played: u32,
    of: u32,
    between_s: f64,
    finished_at: Option<f64>,
}

impl Attacks {
    /// After a step: a finished attack is said once, and the next one begins `between_s` later.
    fn after_step(&mut self, field: &mut SplField) {
        if field.game_state() != spl::GameState::Finished {
            return;
        }
        let now = field.time_s();
        let at = *self.finished_at.get_or_insert_with(|| {
            tracing::info!(
                "attack {} of {} finished: score {}",
                self.played,
                self.of,
                field.score()
            );
            now
        });
        if self.played < self.of && now - at >= self.between_s {
            self.played += 1;
            self.finished_at = None;
            field.next_attack();
            tracing::info!(
                "attack {} of {} begins: robots on their ready poses, INITIAL",
                self.played,
                self.of
            );
        }
    }
}

/// Run the field until shutdown.
pub async fn run(
    bus: Bus,
    net: NetConfig,
    sim: SimConfig,
    mut shutdown: Shutdown,
) -> anyhow::Result<()> {
    let bind = |addr: IpAddr, port: u16| async move {
        UdpSocket::bind(SocketAddr::new(addr, port))
            .await
            .map_err(|e| anyhow::anyhow!("cannot bind {addr}:{port}: {e}"))
    };
    let controlled = bind(net.controlled, net.command_port).await?;
    let teammate = bind(net.teammate, 0).await?;
    let gc = bind(net.operator, 0).await?;
    let debug_to = SocketAddr::new(net.operator, net.debug_port);
    let gc_to = SocketAddr::new(net.operator, net.gamecontroller_port);
    let truth = bus.publisher(&topics::SIM_FIELD_TRUTH).await?;
    let counters = bus.counters().clone();
    let mut field = SplField::new(sim);
    tracing::info!(
        "field: controlled robot on {}:{}, teammate on {}, sending to {debug_to} and {gc_to}",
        net.controlled,
        net.command_port,
        net.teammate
    );

    let step = Duration::from_millis(10);
    // The field's steps follow the bus clock; ticks missed (a stopped process) are skipped, so
    // the field's time stands still meanwhile.
    let mut tick = bus.clock().interval(step);
    let mut buf = vec![0u8; 1024];
    let (mut last_cmd, mut commands, mut passes) = (Vec::new(), 0u64, 0u32);
    let mut attacks = Attacks {
        played: 1,
        of: net.attacks.max(1),
        between_s: net.between_attacks_s,
        finished_at: None,
    };
    let mut since_truth = Duration::ZERO;
    use tokio::signal::unix::{SignalKind, signal};
    let mut knock_controlled = signal(SignalKind::user_defined1())?;
    let mut knock_teammate = signal(SignalKind::user_defined2())?;
    loop {
        tokio::select! {
            _ = shutdown.wait() => return Ok(()),
            _ = knock_controlled.recv() => {
                tracing::info!("SIGUSR1: knocking the controlled robot over");
                field.knock_over(RobotId::CONTROLLED);
            }
            _ = knock_teammate.recv() => {
                tracing::info!("SIGUSR2: knocking the autonomous teammate over");
                field.knock_over(RobotId::AUTONOMOUS);
            }
            r = controlled.recv_from(&mut buf) => {
                let (n, from) = r?;
                match field.receive_command(&buf[..n]) {
                    Ok(_) => {
                        commands += 1;
                        let b = &buf[..n];
                        let f = |i: usize| f32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
                        last_cmd = vec![b[0] as f32, b[1] as f32, b[2] as f32, f(3), f(7)];
                        tracing::info!("robot 2 obeys {:?} from {from}", field.controlled().body);
                    }
                    Err(e) => {
                        counters.incr("refused_packets");
                        tracing::warn!("robot 2 refused a packet from {from}: {e}");
                    }
                }
            }
            _ = tick.tick() => {
                for d in field.step(step.as_secs_f64() * net.time_scale) {
                    let sent = match d {
                        Datagram::Debug { player: 2, bytes } => controlled.send_to(&bytes, debug_to).await,
                        Datagram::Debug { bytes, .. } => teammate.send_to(&bytes, debug_to).await,
                        Datagram::GameController { bytes } => gc.send_to(&bytes, gc_to).await,
                    };
                    if let Err(e) = sent {
                        counters.incr("send_errors");
                        tracing::debug!("send failed: {e}");
                    }
                }
                for (t, e) in field.take_events() {
                    if matches!(e, SimEvent::PassCompleted { .. }) {
                        passes += 1;
                    }
                    tracing::info!("t={t:.1}s {e:?}");
                }
                attacks.after_step(&mut field);
                since_truth += step;
                if since_truth >= Duration::from_millis(100) {
                    since_truth = Duration::ZERO;
                    let ball = field.ball;
                    let mut msg = FieldTruth {
                        time_s: field.time_s(),
                        ball: FieldPoint { x_mm: ball.x as f32, y_mm: ball.y as f32 },
                        controlled: pose_of(&field, RobotId::CONTROLLED),
                        teammate: pose_of(&field, RobotId::AUTONOMOUS),
                        controlled_body: field.controlled().body.map_or("None".into(), |b| format!("{b:?}")),
                        last_command: last_cmd.clone(),
                        commands_received: commands,
                        score: field.score(),
                        passes,
                        game_state: field.game_state().wire_value(),
                        ..Default::default()
                    };
                    truth.publish(&mut msg).await?;
                }
            }
        }
    }
}

/// The component's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Flags {
    /// The operator PC (where the bridge listens).
    #[arg(long, default_value = "127.0.0.1")]
    pub operator: IpAddr,
    /// The bridge's debug port.
    #[arg(long, default_value_t = 65305)]
    pub debug_port: u16,
    /// The bridge's GameController port.
    #[arg(long, default_value_t = 3838)]
    pub gamecontroller_port: u16,
    /// Address of the simulated controlled robot (player 2).
    #[arg(long, default_value = "127.0.0.2")]
    pub controlled: IpAddr,
    /// Address of the simulated autonomous teammate (player 1).
    #[arg(long, default_value = "127.0.0.3")]
    pub teammate: IpAddr,
    /// The controlled robot's command port.
    #[arg(long, default_value_t = 65306)]
    pub command_port: u16,
    /// Random seed (falls, perception noise).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Simulated seconds per real second.
    #[arg(long, default_value_t = 1.0)]
    pub time_scale: f64,
    /// Seconds in INITIAL, READY and SET before the attack starts.
    #[arg(long)]
    pub pre_game_s: Option<f64>,
    /// Length of the attack (PLAYING, simulated s) before the game is FINISHED.
    #[arg(long, default_value_t = 90.0)]
    pub attack_s: f64,
    /// Falls per minute per robot (0: never).
    #[arg(long)]
    pub falls_per_min: Option<f64>,
    /// Whether the two opponents stand still in PLAYING (obstacles only; scripted scenarios).
    #[arg(long, default_value_t = false, action = clap::ArgAction::Set)]
    pub passive_opponents: bool,
    /// Whether the autonomous teammate stands still in PLAYING (scripted scenarios that must
    /// not end with its goal).
    #[arg(long, default_value_t = false, action = clap::ArgAction::Set)]
    pub passive_teammate: bool,
    /// Penalise the controlled robot this many simulated seconds into PLAYING (scripted
    /// scenarios): the GameController reports it, the robot stands out of play.
    #[arg(long)]
    pub penalty_at_s: Option<f64>,
    /// Length of that penalty (simulated s).
    #[arg(long, default_value_t = 45.0)]
    pub penalty_s: f64,
    /// Attacks to play one after another (a challenge's attempts, or a day of them): after
    /// each FINISHED, the field is set up again and the GameController starts from INITIAL.
    #[arg(long, default_value_t = 1)]
    pub attacks: u32,
    /// Simulated seconds in FINISHED before the next attack.
    #[arg(long, default_value_t = 5.0)]
    pub between_attacks_s: f64,
}

/// The `spl_field` component.
#[derive(Debug)]
pub struct SplFieldComponent;

impl interfaces::node::Component for SplFieldComponent {
    const NAME: &'static str = "spl_field";
    const ABOUT: &'static str = "A simulated RoboCup SPL field for the coach game: two robots of ours (one \
        controlled, one autonomous), two opponents, a ball and a GameController, \
        speaking the real UDP protocols.";
    type Config = Flags;
    type Prepared = (NetConfig, SimConfig);

    fn interface(config: &Flags) -> Interface {
        Interface {
            hardware: vec![format!("udp:{}:{}", config.controlled, config.command_port)],
            ..Interface::new("spl_field").publishes(&topics::SIM_FIELD_TRUTH)
        }
    }

    fn prepare(config: Flags) -> anyhow::Result<(NetConfig, SimConfig)> {
        let mut sim = SimConfig {
            seed: config.seed,
            ..SimConfig::default()
        };
        if let Some(p) = config.pre_game_s {
            let p = p.max(0.0) / 3.0;
            (sim.initial_s, sim.ready_s, sim.set_s) = (p, p, p);
        }
        anyhow::ensure!(
            config.attack_s.is_finite() && config.attack_s > 0.0,
            "--attack-s must be a positive number of seconds, got {}",
            config.attack_s
        );
        sim.attack_s = config.attack_s;
        if let Some(f) = config.falls_per_min {
            sim.falls_per_min = f.max(0.0);
        }
        anyhow::ensure!(
            config.attacks >= 1,
            "--attacks must be at least 1 (one attack is the challenge's), got {}",
            config.attacks
        );
        anyhow::ensure!(
            config.between_attacks_s.is_finite() && config.between_attacks_s >= 0.0,
            "--between-attacks-s must be a number of seconds (0 or more), got {}",
            config.between_attacks_s
        );
        sim.penalty_at_s = config.penalty_at_s.filter(|s| s.is_finite() && *s >= 0.0);
        sim.penalty_s = config.penalty_s.max(0.0);
        if config.passive_opponents {
            sim.passive_robots = vec![RobotId::KEEPER, RobotId::DEFENDER];
        }
        if config.passive_teammate {
            sim.passive_robots.push(RobotId::AUTONOMOUS);
        }
        let net = NetConfig {
            operator: config.operator,
            debug_port: config.debug_port,
            gamecontroller_port: config.gamecontroller_port,
            controlled: config.controlled,
            teammate: config.teammate,
            command_port: config.command_port,
            time_scale: config.time_scale.max(0.01),
            attacks: config.attacks,
            between_attacks_s: config.between_attacks_s,
        };
        Ok((net, sim))
    }

    async fn run(
        bus: Bus,
        prepared: (NetConfig, SimConfig),
        shutdown: Shutdown,
    ) -> anyhow::Result<()> {
        let (net, sim) = prepared;
        run(bus, net, sim, shutdown).await
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;
    use interfaces::node::Component;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        flags: Flags,
    }

    fn prepare(args: &[&str]) -> anyhow::Result<(NetConfig, SimConfig)> {
        let cli = Cli::try_parse_from(std::iter::once("spl_field").chain(args.iter().copied()))?;
        SplFieldComponent::prepare(cli.flags)
    }

    #[test]
    fn attack_counts_and_pauses_that_make_no_sense_are_refused_by_name() {
        let (net, _) = prepare(&["--attacks", "36", "--between-attacks-s", "2"]).unwrap();
        assert_eq!((net.attacks, net.between_attacks_s), (36, 2.0));
        let e = prepare(&["--attacks", "0"]).unwrap_err().to_string();
        assert!(e.contains("--attacks must be at least 1"), "{e}");
        for bad in ["-1", "NaN", "inf"] {
            let flag = format!("--between-attacks-s={bad}");
            let e = prepare(&[&flag]).unwrap_err().to_string();
            assert!(e.contains("--between-attacks-s"), "{bad}: {e}");
        }
        assert!(prepare(&["--attacks", "many"]).is_err());
    }
}
