//! The `executive` process: one game's machine between the bus and the robot.
//!
//! # `--game touch` (Loki's touch-the-ball game, [`crate::touch`])
//!
//! Subscribes: `game/command` (validated commands from `dialogs` and the command panel),
//! `vision/ball_events`, `vision/ball` (the tracked centre in `world`, for "the ball moved"),
//! `body/reach_status`, `speech/speaking` (failures are logged as anomalies).
//!
//! Publishes: `speech/say`, `vision/ball_target`, `body/reach` (gaze and reach goals and their
//! cancels), `executive/transitions` (every step of the machine with its triggering event),
//! `executive/log` (the game log: states, heard, said, ball, reach, anomaly, done; the same lines
//! go to the console at INFO).
//!
//! Serves: `executive/configuration` (active states and the Mermaid diagram),
//! `executive/propose` (a structural DR change checked against the game, see
//! [`crate::propose`], then forwarded to `dr/propose`).
//!
//! Calls: `body/joint_goal` (the rest postures; retried a few times while the reach component
//! still owns the joints), `dr/propose`, `dr/get_node`.
//!
//! Time: the machine's `now` is the bus clock (nanoseconds since the epoch as a duration), so
//! timers follow a replayed or virtual clock. A finished game stays up (answering the
//! configuration service) unless `--exit-when-finished`.
//!
//! # `--game coach`
//!
//! The Nao coach machine ([`crate::coach`]), with the same configuration and propose services.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use interfaces::bus::{CallError, ErrorCode, ServiceError};
use interfaces::msg::body::{JointGoal, JointRefusal};
use interfaces::msg::dr::{GetNodeRequest, ProposeReply, ProposeRequest};
use interfaces::msg::executive::{Configuration, ConfigurationRequest, GameLog, StateTransition};
use interfaces::msg::speech::{SayRequest, SpeakingState};
use interfaces::msg::tracking::{BallEvent, BallEventKind, BallTarget, BallTrackState};
use interfaces::node::Interface;
use interfaces::{Bus, Shutdown, topics};
use tokio::sync::mpsc;

use crate::engine::Step;
use crate::propose::{self, Facts};
use crate::settings::{ProposeSettings, Settings};
use crate::touch::{self, LogLine, Output, TouchGame};

/// Which game the Executive plays.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum GameKind {
    /// Loki's touch-the-ball game (seed 001).
    Touch,
    /// The Nao coach game (seed 000).
    Coach,
}

/// The component's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// The game to play.
    #[arg(long, value_enum, default_value = "touch")]
    pub game: GameKind,
    /// Settings file (TOML; every key optional, see the crate's README).
    #[arg(long)]
    pub settings: Option<PathBuf>,
    /// Print the game's machine as a Mermaid `stateDiagram-v2` and exit.
    #[arg(long)]
    pub print_diagram: bool,
    /// Print the game's machine as Graphviz DOT and exit.
    #[arg(long)]
    pub print_dot: bool,
    /// Exit (0) once the game reached its final state.
    #[arg(long)]
    pub exit_when_finished: bool,
}

impl Config {
    /// The settings file's content, or the defaults.
    pub fn load_settings(&self) -> anyhow::Result<Settings> {
        Ok(match &self.settings {
            Some(p) => Settings::load(p)?,
            None => Settings::default(),
        })
    }
}

/// What the process declares for `--describe` (depends on `--game`).
pub fn interface(game: GameKind) -> Interface {
    let i = Interface::new("executive");
    let i = match game {
        GameKind::Touch => i
            .subscribes(&topics::GAME_COMMAND)
            .subscribes(&topics::VISION_BALL_EVENTS)
            .subscribes(&topics::VISION_BALL)
            .subscribes(&topics::BODY_REACH_STATUS)
            .subscribes(&topics::SPEECH_SPEAKING)
            .subscribes(&topics::VISION_CAMERA_STATUS)
            .publishes(&topics::SPEECH_SAY)
            .publishes(&topics::VISION_BALL_TARGET)
            .publishes(&topics::BODY_REACH)
            .publishes(&topics::EXECUTIVE_TRANSITIONS)
            .publishes(&topics::EXECUTIVE_LOG)
            .calls(&topics::BODY_JOINT_GOAL),
        GameKind::Coach => crate::coach::interface(i),
    };
    i.serves(&topics::EXECUTIVE_CONFIGURATION)
        .serves(&topics::EXECUTIVE_PROPOSE)
        .calls(&topics::DR_PROPOSE)
        .calls(&topics::DR_GET_NODE)
}

/// The diagram `--print-diagram` / `--print-dot` prints.
pub fn diagram(game: GameKind, settings: &Settings, dot: bool) -> anyhow::Result<String> {
    let (m, d) = match game {
        GameKind::Touch => {
            let def = touch::definition(&settings.touch)?;
            (def.mermaid(), def.dot())
        }
        GameKind::Coach => {
            let def = crate::coach::machine::definition(&settings.coach)?;
            (def.mermaid(), def.dot())
        }
    };
    Ok(if dot { d } else { m })
}

/// What the services read: the machine's configuration after the last step.
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    pub machine: String,
    pub active: Vec<String>,
    pub all_active: Vec<String>,
    pub step: u64,
    pub mermaid: String,
    /// Started and not finished.
    pub game_on: bool,
}

type Shared = Arc<Mutex<Snapshot>>;

fn lock(s: &Shared) -> std::sync::MutexGuard<'_, Snapshot> {
    s.lock().unwrap_or_else(|p| p.into_inner())
}

/// Serves `executive/configuration` and `executive/propose`; keep the handles alive.
pub async fn serve(
    bus: &Bus,
    snapshot: Shared,
    propose_settings: ProposeSettings,
) -> anyhow::Result<Vec<interfaces::bus::ServiceHandle>> {
    let snap = snapshot.clone();
    let config = bus
        .serve(
            &topics::EXECUTIVE_CONFIGURATION,
            move |req: ConfigurationRequest| {
                let s = lock(&snap).clone();
                async move {
                    if !req.machine.is_empty() && req.machine != s.machine {
                        return Err(ServiceError::not_found(format!(
                            "no machine `{}` here (this Executive runs `{}`)",
                            req.machine, s.machine
                        )));
                    }
                    Ok(Configuration {
                        machine: s.machine,
                        active: s.active,
                        all_active: s.all_active,
                        step: s.step,
                        mermaid: s.mermaid,
                        ..Default::default()
                    })
                }
            },
        )
        .await?;
    let b = bus.clone();
    let settings = Arc::new(propose_settings);
    let counters = bus.counters().clone();
    let propose = bus
        .serve(&topics::EXECUTIVE_PROPOSE, move |req: ProposeRequest| {
            let bus = b.clone();
            let settings = settings.clone();
            let game_on = lock(&snapshot).game_on;
            let counters = counters.clone();
            async move {
                let reply = propose_through(&bus, &settings, game_on, req).await;
                match &reply {
                    Ok(r) if !r.accepted => {
                        counters.incr(&format!("propose_refused/{}", r.reason_code));
                        tracing::info!("[propose] refused ({}): {}", r.reason_code, r.reason);
                    }
                    Ok(r) => tracing::info!("[propose] accepted as change {}", r.seq),
                    Err(e) => tracing::warn!("[propose] failed: {e}"),
                }
                reply
            }
        })
        .await?;
    Ok(vec![config, propose])
}

const DR_TIMEOUT: Duration = Duration::from_secs(2);

/// Whether a node exists in the DR (`Err` when the DR cannot say).
async fn node_exists(bus: &Bus, name: &str) -> Result<bool, ServiceError> {
    let req = GetNodeRequest {
        name: name.to_string(),
        ..Default::default()
    };
    match bus.call(&topics::DR_GET_NODE, &req, DR_TIMEOUT).await {
        Ok(_) => Ok(true),
        Err(CallError::Remote(e)) if e.code == ErrorCode::NotFound => Ok(false),
        Err(e) => Err(ServiceError::new(
            ErrorCode::Internal,
            format!("the deep representation cannot be asked: {e}"),
        )),
    }
}

async fn propose_through(
    bus: &Bus,
    settings: &ProposeSettings,
    game_on: bool,
    req: ProposeRequest,
) -> Result<ProposeReply, ServiceError> {
    let c = &req.change;
    let adding = c.kind == interfaces::msg::dr::ChangeKind::AddNode;
    let facts = Facts {
        game_on,
        name_exists: adding && !c.name.trim().is_empty() && node_exists(bus, c.name.trim()).await?,
        type_present: adding
            && game_on
            && settings
                .unique_types
                .iter()
                .any(|t| t.eq_ignore_ascii_case(&c.node_type))
            && node_exists(bus, &c.node_type.to_lowercase()).await?,
    };
    if let Err(r) = propose::check(c, settings, &facts) {
        return Ok(ProposeReply {
            accepted: false,
            reason_code: r.code.to_string(),
            reason: r.reason,
            ..Default::default()
        });
    }
    bus.call(&topics::DR_PROPOSE, &req, DR_TIMEOUT)
        .await
        .map_err(|e| match e {
            CallError::Remote(e) => e,
            e => ServiceError::new(
                ErrorCode::Internal,
                format!("the deep representation did not take the change: {e}"),
            ),
        })
}

/// Runs the process until shutdown (or the end of the game with `--exit-when-finished`).
pub async fn run(
    bus: Bus,
    config: Config,
    settings: Settings,
    shutdown: Shutdown,
) -> anyhow::Result<()> {
    match config.game {
        GameKind::Touch => run_touch(bus, config, settings, shutdown).await,
        GameKind::Coach => {
            let mermaid = crate::coach::machine::definition(&settings.coach)?.mermaid();
            let snapshot = Arc::new(Mutex::new(Snapshot {
                machine: crate::coach::MACHINE.into(),
                mermaid: mermaid.clone(),
                game_on: true,
                ..Default::default()
            }));
            let _services = serve(&bus, snapshot.clone(), settings.propose.clone()).await?;
            // The live configuration after every input the machine handled.
            crate::coach::run_observed(bus, settings.coach, shutdown, move |game| {
                let m = game.machine();
                *lock(&snapshot) = Snapshot {
                    machine: crate::coach::MACHINE.into(),
                    active: m.active_leaves(),
                    all_active: m.configuration(),
                    step: m.steps(),
                    mermaid: mermaid.clone(),
                    game_on: !m.is_finished(),
                };
            })
            .await
        }
    }
}

/// One step of a machine as the `executive/transitions` message (both games publish the same).
pub(crate) fn transition_msg<A>(machine: &str, s: &Step<A>) -> StateTransition {
    StateTransition {
        machine: machine.into(),
        event: s.event.clone(),
        exited: s.exited.clone(),
        entered: s.entered.clone(),
        active: s.active.clone(),
        step: s.step,
        ..Default::default()
    }
}

/// The bus clock as the machine's time.
fn bus_now(bus: &Bus) -> Duration {
    Duration::from_nanos(u64::try_from(bus.clock().now_ns()).unwrap_or(0))
}

/// A finished home request, back to the main loop for the game log.
struct HomeResult {
    what: String,
    result: Result<(), String>,
}

/// How often a rest posture is retried while the joints are still owned (the reach component
/// releases them when its goal is cancelled), and how long apart.
const HOME_ATTEMPTS: usize = 5;
const HOME_RETRY: Duration = Duration::from_millis(300);

async fn send_home(bus: Bus, goal: JointGoal, results: mpsc::Sender<HomeResult>) {
    let what = if goal.release {
        "the release of the executive's joints".to_string()
    } else {
        format!("the rest posture of {} joints", goal.targets.len())
    };
    let mut last = String::new();
    for attempt in 1..=HOME_ATTEMPTS {
        match bus
            .call(&topics::BODY_JOINT_GOAL, &goal, Duration::from_secs(2))
            .await
        {
            Ok(r) if r.accepted => {
                if results
                    .try_send(HomeResult {
                        what,
                        result: Ok(()),
                    })
                    .is_err()
                {
                    bus.counters().incr("home_results_dropped");
                }
                return;
            }
            Ok(r) => {
                last = format!("refused: {}", r.detail);
                if r.refusal != JointRefusal::Owned {
                    break;
                }
            }
            Err(e) => last = e.to_string(),
        }
        if attempt < HOME_ATTEMPTS {
            tokio::time::sleep(HOME_RETRY).await;
        }
    }
    if results
        .try_send(HomeResult {
            what,
            result: Err(last),
        })
        .is_err()
    {
        bus.counters().incr("home_results_dropped");
    }
}

/// The touch game's publishers.
/// How long without `vision/ball` before a tracking game calls the ball lost.
const TRACKER_SILENCE: Duration = Duration::from_millis(1500);

/// Watches the tracker's heartbeat (`vision/ball` comes once per frame, found or not).
#[derive(Debug, Default)]
struct TrackerWatch {
    last: Option<tokio::time::Instant>,
    reported: bool,
    last_resend: Option<tokio::time::Instant>,
}

impl TrackerWatch {
    fn heard(&mut self, now: tokio::time::Instant) {
        self.last = Some(now);
        self.reported = false;
    }
    /// True once per silence longer than [`TRACKER_SILENCE`] (after the tracker was heard).
    fn silent(&mut self, now: tokio::time::Instant) -> bool {
        match self.last {
            Some(t) if !self.reported && now.duration_since(t) > TRACKER_SILENCE => {
                self.reported = true;
                true
            }
            _ => false,
        }
    }
    /// At most once a second.
    fn may_resend(&mut self, now: tokio::time::Instant) -> bool {
        if self
            .last_resend
            .is_some_and(|t| now.duration_since(t) < Duration::from_secs(1))
        {
            return false;
        }
        self.last_resend = Some(now);
        true
    }
}

/// Follows `vision/camera_status`: the robot says when its camera stops, and when it is back.
/// A camera that flaps (stops and comes back again and again) is announced once per
/// [`CAMERA_REPEAT`]; every change is logged.
#[derive(Debug, Default)]
struct CameraWatch {
    streaming: Option<bool>,
    /// When "cannot see" was last said; "see again" is said only after it.
    said_lost: Option<tokio::time::Instant>,
    lost_pending: bool,
}

/// At most one "I can't see" in this long.
const CAMERA_REPEAT: Duration = Duration::from_secs(20);

/// What the robot says when its camera stops delivering.
pub const CANNOT_SEE: &str = "I can't see: my camera stopped. Give me a moment.";
/// What it says when the camera is back.
pub const SEE_AGAIN: &str = "I can see again.";

impl CameraWatch {
    /// On a change of the camera's state at `now`: what to log, and what to say (if anything).
    fn update(
        &mut self,
        s: &interfaces::msg::vision::CameraStatus,
        now: tokio::time::Instant,
    ) -> Option<(Option<&'static str>, String)> {
        let before = self.streaming.replace(s.streaming);
        match (before, s.streaming) {
            (Some(true) | None, false) => {
                let log = format!("the camera stopped ({}): {}", s.driver, s.detail);
                let say = self
                    .said_lost
                    .is_none_or(|t| now.duration_since(t) >= CAMERA_REPEAT);
                if say {
                    self.said_lost = Some(now);
                    self.lost_pending = true;
                }
                Some((say.then_some(CANNOT_SEE), log))
            }
            (Some(false), true) => {
                let say = std::mem::take(&mut self.lost_pending);
                Some((
                    say.then_some(SEE_AGAIN),
                    format!("the camera is back: {}", s.detail),
                ))
            }
            _ => None,
        }
    }
}

/// Whether the game's eyes need the tracker to have a target.
fn wants_tracker(game: &TouchGame) -> bool {
    let m = game.machine();
    m.is_active(touch::state::SEARCHING) || m.is_active(touch::state::TRACKING)
}

fn ball_target(s: &crate::settings::TouchSettings) -> BallTarget {
    BallTarget {
        active: true,
        hue_deg: s.ball_hue_deg,
        saturation: s.ball_saturation,
        diameter_m: s.ball_diameter_m,
        ..BallTarget::default()
    }
}

struct TouchOut {
    bus: Bus,
    say: interfaces::Publisher<SayRequest>,
    target: interfaces::Publisher<interfaces::msg::tracking::BallTarget>,
    reach: interfaces::Publisher<interfaces::msg::body::ReachGoal>,
    transitions: interfaces::Publisher<StateTransition>,
    log: interfaces::Publisher<GameLog>,
    home: mpsc::Sender<HomeResult>,
    say_id: u64,
    finished: bool,
}

impl TouchOut {
    /// Says `text` at once (outside the game's machine: what the robot tells about itself).
    async fn say_now(&mut self, text: &str) -> anyhow::Result<()> {
        self.say_id += 1;
        let mut r = SayRequest {
            id: self.say_id,
            text: text.into(),
            priority: interfaces::msg::speech::Priority::High,
            ..Default::default()
        };
        self.say.publish(&mut r).await?;
        Ok(())
    }

    async fn log_line(&mut self, l: LogLine) -> anyhow::Result<()> {
        if l.distance_m >= 0.0 {
            tracing::info!("[{}] {} ({:.3} m)", l.kind, l.text, l.distance_m);
        } else {
            tracing::info!("[{}] {}", l.kind, l.text);
        }
        if l.kind == "anomaly" {
            self.bus.counters().incr("anomalies");
        }
        let mut g = GameLog {
            machine: touch::MACHINE.into(),
            kind: l.kind.into(),
            text: l.text,
            distance_m: l.distance_m,
            ..Default::default()
        };
        self.log.publish(&mut g).await?;
        Ok(())
    }

    async fn step(&mut self, s: &Step<touch::Act>) -> anyhow::Result<()> {
        if s.ignored {
            self.bus.counters().incr("ignored_events");
            tracing::debug!("{} ignored in {:?}", s.event, s.active);
            return Ok(());
        }
        self.transitions
            .publish(&mut transition_msg(touch::MACHINE, s))
            .await?;
        Ok(())
    }

    /// Publishes an outcome: the transitions, then the outputs in order.
    async fn emit(&mut self, o: touch::Outcome) -> anyhow::Result<()> {
        for s in &o.steps {
            self.step(s).await?;
        }
        for out in o.outputs {
            match out {
                Output::Say { text, priority } => {
                    self.say_id += 1;
                    let mut r = SayRequest {
                        id: self.say_id,
                        text,
                        priority,
                        ..Default::default()
                    };
                    self.say.publish(&mut r).await?;
                }
                Output::SetBallTarget(mut t) => self.target.publish(&mut t).await?,
                Output::Reach(mut g) | Output::CancelReach(mut g) => {
                    self.reach.publish(&mut g).await?
                }
                Output::Home(goal) | Output::Release(goal) => {
                    tokio::spawn(send_home(self.bus.clone(), goal, self.home.clone()));
                }
                Output::Log(l) => self.log_line(l).await?,
                Output::Finish => self.finished = true,
            }
        }
        Ok(())
    }
}

fn snapshot_of(game: &TouchGame, mermaid: &str) -> Snapshot {
    let m = game.machine();
    Snapshot {
        machine: touch::MACHINE.into(),
        active: m.active_leaves(),
        all_active: m.configuration(),
        step: m.steps(),
        mermaid: mermaid.to_string(),
        game_on: !m.is_finished(),
    }
}

async fn run_touch(
    bus: Bus,
    config: Config,
    settings: Settings,
    mut shutdown: Shutdown,
) -> anyhow::Result<()> {
    let mut game = TouchGame::new(settings.touch.clone())?;
    let mermaid = game.machine().definition().mermaid();
    let snapshot: Shared = Arc::new(Mutex::new(snapshot_of(&game, &mermaid)));
    let commands = bus.subscriber(&topics::GAME_COMMAND).await?;
    let ball_events = bus.subscriber(&topics::VISION_BALL_EVENTS).await?;
    let tracks = bus.subscriber(&topics::VISION_BALL).await?;
    let statuses = bus.subscriber(&topics::BODY_REACH_STATUS).await?;
    let speaking = bus.subscriber(&topics::SPEECH_SPEAKING).await?;
    let cameras = bus.subscriber(&topics::VISION_CAMERA_STATUS).await?;
    let mut camera = CameraWatch::default();
    let (home_tx, mut home_rx) = mpsc::channel(16);
    let mut out = TouchOut {
        bus: bus.clone(),
        say: bus.publisher(&topics::SPEECH_SAY).await?,
        target: bus.publisher(&topics::VISION_BALL_TARGET).await?,
        reach: bus.publisher(&topics::BODY_REACH).await?,
        transitions: bus.publisher(&topics::EXECUTIVE_TRANSITIONS).await?,
        log: bus.publisher(&topics::EXECUTIVE_LOG).await?,
        home: home_tx,
        say_id: 0,
        finished: false,
    };
    let _services = serve(&bus, snapshot.clone(), settings.propose.clone()).await?;
    tracing::info!(
        "touch the ball: arm {}, courtesy delay {} s, ball hue {} deg saturation {} diameter {} m",
        settings.touch.arm,
        settings.touch.courtesy_delay_s,
        settings.touch.ball_hue_deg,
        settings.touch.ball_saturation,
        settings.touch.ball_diameter_m
    );
    let o = game.start(bus_now(&bus));
    out.emit(o).await?;
    *lock(&snapshot) = snapshot_of(&game, &mermaid);
    let mut watch = TrackerWatch::default();
    loop {
        // Wake for the next timer; poll at least every 200 ms in case the clock is virtual.
        let now = bus_now(&bus);
        let sleep_for = game
            .next_deadline()
            .map_or(Duration::from_millis(200), |d| d.saturating_sub(now))
            .min(Duration::from_millis(200));
        let outcome = tokio::select! {
            _ = shutdown.wait() => return Ok(()),
            c = commands.recv() => {
                let c = c?;
                game.command(&c, bus_now(&bus))
            }
            e = ball_events.recv() => game.ball_event(&e?, bus_now(&bus)),
            t = tracks.recv() => {
                let mut t = t?;
                // Only the newest track matters.
                while let Some(newer) = tracks.try_recv() {
                    t = newer;
                }
                watch.heard(tokio::time::Instant::now());
                if t.state == BallTrackState::Waiting && wants_tracker(&game) && watch.may_resend(tokio::time::Instant::now()) {
                    // A tracker without a target while the game needs one: it was restarted.
                    out.log_line(LogLine {
                        kind: "anomaly",
                        text: "the ball tracker has no target (was it restarted?): sending it again".into(),
                        distance_m: -1.0,
                    }).await?;
                    let mut target = ball_target(&settings.touch);
                    out.target.publish(&mut target).await?;
                    if game.machine().is_active(touch::state::TRACKING) {
                        // It forgot the ball it was tracking: lost, said so, searched again.
                        let lost = BallEvent {
                            kind: BallEventKind::Lost,
                            ..BallEvent::default()
                        };
                        let o = game.ball_event(&lost, bus_now(&bus));
                        out.emit(o).await?;
                    }
                }
                game.ball_track(&t, bus_now(&bus))
            }
            s = statuses.recv() => game.reach_status(&s?, bus_now(&bus)),
            c = cameras.recv() => {
                let c = c?;
                if let Some((said, log)) = camera.update(&c, tokio::time::Instant::now()) {
                    out.log_line(LogLine { kind: "anomaly", text: log, distance_m: -1.0 }).await?;
                    if let Some(said) = said {
                        out.say_now(said).await?;
                    }
                }
                game.advance(bus_now(&bus))
            }
            s = speaking.recv() => {
                let s = s?;
                match s.state {
                    SpeakingState::Failed | SpeakingState::Dropped | SpeakingState::Interrupted => {
                        out.log_line(LogLine {
                            kind: "anomaly",
                            text: format!("speech {:?}: \"{}\" {}", s.state, s.text, s.detail),
                            distance_m: -1.0,
                        }).await?;
                    }
                    _ => tracing::debug!("speech {:?}: {}", s.state, s.text),
                }
                game.advance(bus_now(&bus))
            }
            h = home_rx.recv() => {
                if let Some(h) = h {
                    let line = match h.result {
                        Ok(()) => LogLine { kind: "reach", text: format!("{} was accepted", h.what), distance_m: -1.0 },
                        Err(e) => LogLine { kind: "anomaly", text: format!("{} failed: {e}", h.what), distance_m: -1.0 },
                    };
                    out.log_line(line).await?;
                }
                game.advance(bus_now(&bus))
            }
            _ = tokio::time::sleep(sleep_for) => game.advance(bus_now(&bus)),
        };
        out.emit(outcome).await?;
        // A tracker that falls silent while the eyes follow the ball (it crashed, its camera
        // stopped): the ball is lost, said so, and searched for again once it is back.
        if game.machine().is_active(touch::state::TRACKING)
            && watch.silent(tokio::time::Instant::now())
        {
            out.log_line(LogLine {
                kind: "anomaly",
                text: format!(
                    "no ball track for {:.1} s: the ball tracker is silent",
                    TRACKER_SILENCE.as_secs_f64()
                ),
                distance_m: -1.0,
            })
            .await?;
            let lost = BallEvent {
                kind: BallEventKind::Lost,
                ..BallEvent::default()
            };
            let o = game.ball_event(&lost, bus_now(&bus));
            out.emit(o).await?;
        }
        *lock(&snapshot) = snapshot_of(&game, &mermaid);
        if out.finished && config.exit_when_finished {
            // Let the last messages and the rest postures go out.
            tokio::time::sleep(Duration::from_millis(500)).await;
            while let Ok(h) = home_rx.try_recv() {
                if let Err(e) = h.result {
                    tracing::warn!("rest posture failed: {e}");
                }
            }
            tracing::info!("the game is over: exiting");
            return Ok(());
        }
    }
}

/// The `executive` component.
#[derive(Debug)]
pub struct Executive;

impl interfaces::node::Component for Executive {
    const NAME: &'static str = "executive";
    const ABOUT: &'static str = "The Executive: plays a game's state machine (touch the ball, or the Nao coach \
        game) between the person's commands, the robot's perception and its body. Prints \
        a readable game log; `--print-diagram` draws the machine.";
    type Config = Config;
    type Prepared = (Config, Settings);

    fn interface(config: &Config) -> Interface {
        interface(config.game)
    }

    fn prepare(config: Config) -> anyhow::Result<(Config, Settings)> {
        let settings = config.load_settings()?;
        if config.print_diagram || config.print_dot {
            // A drawing of the machine on stdout, and no bus.
            print!("{}", diagram(config.game, &settings, config.print_dot)?);
            std::process::exit(0);
        }
        Ok((config, settings))
    }

    async fn run(bus: Bus, prepared: (Config, Settings), shutdown: Shutdown) -> anyhow::Result<()> {
        let (config, settings) = prepared;
        run(bus, config, settings, shutdown).await
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::msg::vision::CameraStatus;

    fn status(streaming: bool) -> CameraStatus {
        CameraStatus {
            driver: "freenect".into(),
            streaming,
            detail: "camera lost: unplugged".into(),
            ..Default::default()
        }
    }

    #[test]
    fn the_robot_says_once_when_its_camera_stops_and_once_when_it_is_back() {
        let t0 = tokio::time::Instant::now();
        let at = |s: u64| t0 + Duration::from_secs(s);
        let mut w = CameraWatch::default();
        assert_eq!(
            w.update(&status(true), at(0)),
            None,
            "streaming from the start"
        );
        assert_eq!(w.update(&status(true), at(1)), None);
        let (said, log) = w.update(&status(false), at(2)).expect("stopped");
        assert_eq!(said, Some(CANNOT_SEE));
        assert!(log.contains("unplugged"), "{log}");
        assert_eq!(w.update(&status(false), at(3)), None, "said once");
        assert_eq!(w.update(&status(true), at(4)).unwrap().0, Some(SEE_AGAIN));
        assert_eq!(w.update(&status(true), at(5)), None);
        // A flapping camera: logged every time, said again only after CAMERA_REPEAT.
        let (said, _) = w.update(&status(false), at(6)).unwrap();
        assert_eq!(said, None);
        assert_eq!(w.update(&status(true), at(7)).unwrap().0, None);
        let (said, _) = w.update(&status(false), at(2 + 20)).unwrap();
        assert_eq!(said, Some(CANNOT_SEE));
        assert_eq!(w.update(&status(true), at(23)).unwrap().0, Some(SEE_AGAIN));
    }
}
