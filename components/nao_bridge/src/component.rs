//! The `nao_bridge` process: UDP on one side, the bus on the other.
//!
//! - `nao/command` messages are encoded to the 11-byte packet and sent to the controlled robot's
//!   command port; a command that cannot be encoded (no body and no head, no target for
//!   GoToPosition) is refused, counted (`refused_commands`) and logged.
//! - Debug packets from the configured robot addresses are decoded and published on
//!   `nao/local_model`, fused into `nao/world_model`; GameController packets become
//!   `nao/game_state`; link changes ("robot not responding") go on `nao/link`.
//! - With `dr_updates`, the team model and the game state are mirrored into the DR's coach scene
//!   (see [`crate::dr`]) at most every 200 ms, one request in flight; the obstacle tracks become
//!   nodes through structural proposals (`executive/propose`, or `dr/propose` straight with
//!   [`ProposeVia::Dr`]). Failures are counted (`dr/update_failed`, `dr/propose_failed`,
//!   `dr/propose_refused/<reason>`) and logged at most once every 5 s.
//! - Every dropped datagram is counted per kind and reason (`drop/<kind>/<reason>` on the
//!   component's `diagnostics`) and logged at most once a second per reason.

use crate::{ExpectedRobot, Inbound, InboundConfig};
use interfaces::msg::nao::{GameState, NaoWorldModel, TrackedObstacle};
use interfaces::node::Interface;
use interfaces::{Bus, Shutdown, topics};
use spl::{FusionConfig, PacketKind, WorldModelFusion, encode_command};
use std::net::{IpAddr, SocketAddr};
use std::time::{Duration, Instant};
use tokio::net::UdpSocket;

/// Where the robots and the GameController are.
#[derive(Debug, Clone)]
pub struct Config {
    /// The controlled robot (player 2): its address receives the commands.
    pub controlled: IpAddr,
    /// The autonomous teammate (player 1), whose debug packets are also accepted, if known.
    pub teammate: Option<IpAddr>,
    /// The robot's command port (65306).
    pub command_port: u16,
    /// Where this bridge listens for debug packets (65305) and GameController packets (3838).
    pub listen: IpAddr,
    pub debug_port: u16,
    pub gamecontroller_port: u16,
    pub team_number: u8,
    pub link_timeout_s: f64,
    /// Mirror the team model and the game state into the DR (`dr/update`).
    pub dr_updates: bool,
    /// Where the obstacle nodes' structural proposals go.
    pub propose_via: ProposeVia,
}

/// Where structural DR changes (obstacle nodes) are proposed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum ProposeVia {
    /// `executive/propose`: the Executive checks them against the game first (the seed's rule
    /// for structural changes), then forwards them to the DR.
    #[default]
    Executive,
    /// `dr/propose`: straight to the DR (graphs without an Executive).
    Dr,
}

impl ProposeVia {
    /// The service proposals are sent to.
    pub fn service(
        self,
    ) -> &'static interfaces::Service<
        interfaces::msg::dr::ProposeRequest,
        interfaces::msg::dr::ProposeReply,
    > {
        match self {
            ProposeVia::Executive => &topics::EXECUTIVE_PROPOSE,
            ProposeVia::Dr => &topics::DR_PROPOSE,
        }
    }
}

/// The latest fused model (bus form), game state and obstacle tracks (with their ids).
type Latest = (
    Option<NaoWorldModel>,
    Option<GameState>,
    Vec<TrackedObstacle>,
);

/// Logs at most once every 5 s.
struct RateLimited(Option<Instant>);

impl RateLimited {
    #[expect(
        clippy::disallowed_methods,
        reason = "the log limiter paces what a person reads, on the wall"
    )]
    fn ready(&mut self) -> bool {
        if self.0.is_none_or(|t| t.elapsed() > Duration::from_secs(5)) {
            self.0 = Some(Instant::now());
            true
        } else {
            false
        }
    }
}

/// Sends the latest team model and game state to the DR, at most every
/// [`crate::dr::MIRROR_PERIOD`]: first the obstacle nodes' structural changes (one proposal in
/// flight at a time), then one `dr/update` for everything that exists.
async fn mirror_to_dr(
    bus: Bus,
    mut latest: tokio::sync::watch::Receiver<Latest>,
    propose_via: ProposeVia,
) {
    use crate::dr::{ObstacleMirror, ObstacleMirrorConfig, ProposalOutcome};
    use interfaces::CallError;
    use std::sync::atomic::Ordering::Relaxed;
    let failed = bus.counters().counter("dr/update_failed");
    let sent = bus.counters().counter("dr/updates_sent");
    let propose_failed = bus.counters().counter("dr/propose_failed");
    let mut update_log = RateLimited(None);
    let mut propose_log = RateLimited(None);
    let mut mirror = ObstacleMirror::new(ObstacleMirrorConfig::default());
    let service = propose_via.service();
    while latest.changed().await.is_ok() {
        let (world, game, obstacles) = latest.borrow_and_update().clone();
        for change in mirror.changes(&obstacles) {
            let req = interfaces::msg::dr::ProposeRequest {
                change: change.clone(),
                ..Default::default()
            };
            let outcome = match bus.call(service, &req, Duration::from_millis(1500)).await {
                Ok(r) if r.accepted => {
                    tracing::info!("DR: {} {} (change {})", change.kind(), change.name(), r.seq);
                    ProposalOutcome::Accepted
                }
                Ok(r) => {
                    bus.counters()
                        .incr(&format!("dr/propose_refused/{}", r.reason_code));
                    if propose_log.ready() {
                        tracing::warn!(
                            "the DR refused {} {} ({}): {}",
                            change.kind(),
                            change.name(),
                            r.reason_code,
                            r.reason
                        );
                    }
                    ProposalOutcome::Refused(r.reason_code)
                }
                Err(e) => {
                    let n = propose_failed.fetch_add(1, Relaxed) + 1;
                    if propose_log.ready() {
                        tracing::warn!(
                            "cannot propose {} {} to {} ({n} failed so far): {e}",
                            change.kind(),
                            change.name(),
                            service.name()
                        );
                    }
                    ProposalOutcome::Failed
                }
            };
            mirror.outcome(&change, &outcome);
        }
        let mut req = crate::dr::update_request(
            world.as_ref().unwrap_or(&NaoWorldModel::default()),
            game.as_ref(),
        );
        let stamp_ns = world.as_ref().map_or(0, |w| w.header.stamp_ns);
        mirror.add_updates(&obstacles, stamp_ns, &mut req);
        match bus
            .call(&topics::DR_UPDATE, &req, Duration::from_millis(500))
            .await
        {
            Ok(_) => {
                sent.fetch_add(1, Relaxed);
            }
            Err(e) => {
                let n = failed.fetch_add(1, Relaxed) + 1;
                // A batch naming an obstacle node the DR no longer has (it restarted) fails as
                // a whole: propose the obstacles again.
                if matches!(&e, CallError::Remote(_)) && mirror.present().next().is_some() {
                    mirror.forget_nodes();
                }
                if update_log.ready() {
                    tracing::warn!("cannot update the DR ({n} failed so far): {e}");
                }
            }
        }
        bus.clock().sleep(crate::dr::MIRROR_PERIOD).await;
    }
}

/// Run the bridge until shutdown.
pub async fn run(bus: Bus, config: Config, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let debug_addr = SocketAddr::new(config.listen, config.debug_port);
    let debug_sock = UdpSocket::bind(debug_addr)
        .await
        .map_err(|e| interfaces::node::bind_error("listen for debug packets", debug_addr, e))?;
    let gc_addr = SocketAddr::new(config.listen, config.gamecontroller_port);
    let gc_sock = UdpSocket::bind(gc_addr).await.map_err(|e| {
        interfaces::node::bind_error("listen for GameController packets", gc_addr, e)
    })?;
    let unspecified: IpAddr = if config.controlled.is_ipv4() {
        [0, 0, 0, 0].into()
    } else {
        [0u16; 8].into()
    };
    let cmd_sock = UdpSocket::bind(SocketAddr::new(unspecified, 0)).await?;
    let robot = SocketAddr::new(config.controlled, config.command_port);

    // Packet times, link time-outs and the fusion's ages are on the component's clock.
    let clock = bus.clock().clone();
    let started = clock.now();
    let now_s = move || clock.elapsed(started).as_secs_f64();
    let mut robots = vec![ExpectedRobot {
        address: config.controlled,
        player_number: 2,
    }];
    if let Some(t) = config.teammate {
        robots.push(ExpectedRobot {
            address: t,
            player_number: 1,
        });
    }
    let mut inbound = Inbound::new(
        InboundConfig {
            robots,
            link_timeout_s: config.link_timeout_s,
            ..Default::default()
        },
        now_s(),
    );
    let mut fusion = WorldModelFusion::new(FusionConfig {
        controlled_player: 2,
        team_number: Some(config.team_number),
        ..Default::default()
    });

    let local_pub = bus.publisher(&topics::NAO_LOCAL_MODEL).await?;
    let world_pub = bus.publisher(&topics::NAO_WORLD_MODEL).await?;
    let game_pub = bus.publisher(&topics::NAO_GAME_STATE).await?;
    let link_pub = bus.publisher(&topics::NAO_LINK).await?;
    let commands = bus.subscriber(&topics::NAO_COMMAND).await?;
    let counters = bus.counters().clone();
    let (latest_tx, latest_rx) = tokio::sync::watch::channel::<Latest>((None, None, Vec::new()));
    if config.dr_updates {
        tokio::spawn(mirror_to_dr(bus.clone(), latest_rx, config.propose_via));
        tracing::info!(
            "mirroring the team model and the game state into the DR (obstacle nodes through {})",
            config.propose_via.service().name()
        );
    }
    tracing::info!(
        "bridge: commands to {robot}, debug packets on {}:{}, GameController on {}:{}",
        config.listen,
        config.debug_port,
        config.listen,
        config.gamecontroller_port
    );

    let mut debug_buf = vec![0u8; 2048];
    let mut gc_buf = vec![0u8; 2048];
    let mut tick = bus.clock().interval(Duration::from_millis(100));
    let mut last_counts = Vec::new();
    loop {
        tokio::select! {
            _ = shutdown.wait() => return Ok(()),
            cmd = commands.recv() => {
                let cmd = cmd?;
                match encode_command(&cmd) {
                    Ok(packet) => {
                        if let Err(e) = cmd_sock.send_to(&packet, robot).await {
                            counters.incr("send_errors");
                            tracing::warn!("cannot send a command to {robot}: {e}");
                        } else {
                            counters.incr("commands_sent");
                        }
                    }
                    Err(e) => {
                        counters.incr("refused_commands");
                        tracing::warn!("refused a command from {:?}: {e}", cmd.source);
                    }
                }
            }
            r = debug_sock.recv_from(&mut debug_buf) => {
                let (n, from) = r?;
                let t = now_s();
                if let Some((mut model, event)) = inbound.on_debug(&debug_buf[..n], from, t) {
                    local_pub.publish(&mut model).await?;
                    fusion.ingest(&model, t);
                    let mut w = fusion.snapshot(t);
                    world_pub.publish(&mut w).await?;
                    if config.dr_updates {
                        latest_tx.send_modify(|l| {
                            l.2 = w.obstacles.clone();
                            l.0 = Some(w);
                        });
                    }
                    if let Some((player, e)) = event {
                        let mut l = e.message(player);
                        link_pub.publish(&mut l).await?;
                    }
                }
            }
            r = gc_sock.recv_from(&mut gc_buf) => {
                let (n, from) = r?;
                if let Some(state) = inbound.on_gamecontroller(&gc_buf[..n], from, now_s()) {
                    let mut g = state.message(config.team_number);
                    game_pub.publish(&mut g).await?;
                    if config.dr_updates {
                        latest_tx.send_modify(|l| l.1 = Some(g));
                    }
                }
            }
            _ = tick.tick() => {
                let t = now_s();
                // Obstacles expire without packets too (a silent field): keep the mirror's
                // track list current.
                if config.dr_updates {
                    let obstacles = fusion.snapshot(t).obstacles;
                    latest_tx.send_if_modified(|l| {
                        let ids = |v: &[TrackedObstacle]| {
                            v.iter().map(|o| o.id).collect::<Vec<_>>()
                        };
                        let changed = ids(&l.2) != ids(&obstacles);
                        if changed {
                            l.2 = obstacles;
                        }
                        changed
                    });
                }
                for (player, e) in inbound.poll(t) {
                    tracing::warn!("robot {player} not responding");
                    let mut l = e.message(player);
                    link_pub.publish(&mut l).await?;
                }
                // Mirror the per-reason drop counters into the bus counters (diagnostics).
                let drops = inbound.drops().counters();
                let mut counts = Vec::new();
                for kind in [PacketKind::Debug, PacketKind::GameController] {
                    for reason in spl::DropReason::ALL {
                        let n = drops.get(kind, reason);
                        if n > 0 {
                            counts.push((format!("drop/{kind}/{}", reason.name()), n));
                        }
                    }
                }
                if counts != last_counts {
                    for (name, n) in &counts {
                        counters.counter(name).store(*n, std::sync::atomic::Ordering::Relaxed);
                    }
                    last_counts = counts;
                }
            }
        }
    }
}

/// The component's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Flags {
    /// Address of the controlled robot (player 2), which receives the commands.
    #[arg(long, default_value = "127.0.0.2")]
    pub robot: IpAddr,
    /// Address of the autonomous teammate (player 1), whose debug packets are also accepted.
    #[arg(long)]
    pub teammate: Option<IpAddr>,
    /// The robot's command port.
    #[arg(long, default_value_t = spl::COMMAND_PORT)]
    pub command_port: u16,
    /// Address to listen on for debug and GameController packets (UDP).
    #[arg(long, default_value = "127.0.0.1")]
    pub udp_listen: IpAddr,
    /// Port of the robots' debug packets.
    #[arg(long, default_value_t = spl::DEBUG_PORT)]
    pub debug_port: u16,
    /// Port of the GameController's packets.
    #[arg(long, default_value_t = spl::GAMECONTROLLER_PORT)]
    pub gamecontroller_port: u16,
    /// Our team number (finds our block in the GameController packet).
    #[arg(long, default_value_t = 19)]
    pub team_number: u8,
    /// No packet from a robot for this long: "robot not responding" (s).
    #[arg(long, default_value_t = 1.0)]
    pub link_timeout_s: f64,
    /// Mirror the team model (our robots, the ball, the obstacles) and the game state into the
    /// deep representation's coach scene with `dr/update` (needs `deep_representation --scene
    /// coach`). Obstacles come and go, so their nodes are added and removed by structural
    /// proposals (see --dr-propose-via).
    #[arg(long)]
    pub dr_updates: bool,
    /// Where the obstacle nodes' structural proposals go with --dr-updates: `executive` (checked
    /// against the game by the Executive first, as every structural change should be) or `dr`
    /// (straight to the DR, for graphs without an Executive).
    #[arg(long, value_enum, default_value_t = ProposeVia::Executive)]
    pub dr_propose_via: ProposeVia,
}

/// The `nao_bridge` component.
#[derive(Debug)]
pub struct NaoBridge;

impl interfaces::node::Component for NaoBridge {
    const NAME: &'static str = "nao_bridge";
    const ABOUT: &'static str = "The operator-side end of the Nao coach link: commands out on UDP, the robots' \
        world models and the GameController's state in, all on the bus.";
    type Config = Flags;
    type Prepared = Config;

    fn interface(config: &Flags) -> Interface {
        let mut base = Interface::new("nao_bridge")
            .subscribes(&topics::NAO_COMMAND)
            .publishes(&topics::NAO_LOCAL_MODEL)
            .publishes(&topics::NAO_WORLD_MODEL)
            .publishes(&topics::NAO_GAME_STATE)
            .publishes(&topics::NAO_LINK);
        if config.dr_updates {
            base = base
                .calls(&topics::DR_UPDATE)
                .calls(config.dr_propose_via.service());
        }
        Interface {
            hardware: vec![
                format!("udp:{}", config.debug_port),
                format!("udp:{}", config.gamecontroller_port),
            ],
            ..base
        }
    }

    fn prepare(config: Flags) -> anyhow::Result<Config> {
        Ok(Config {
            controlled: config.robot,
            teammate: config.teammate,
            command_port: config.command_port,
            listen: config.udp_listen,
            debug_port: config.debug_port,
            gamecontroller_port: config.gamecontroller_port,
            team_number: config.team_number,
            link_timeout_s: config.link_timeout_s,
            dr_updates: config.dr_updates,
            propose_via: config.dr_propose_via,
        })
    }

    async fn run(bus: Bus, prepared: Config, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}
