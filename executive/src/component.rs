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
//! Time: the machine's `now` is the component clock's monotonic reading ([`interfaces::clock`]),
//! and the loop sleeps on that clock until the machine's next timer or the tracker watchdog's
//! deadline; so with `--clock bus` the timers, the watchdog and the camera announcements follow
//! a replay's clock, at whatever rate it is replayed. A clock that follows the bus has no time
//! before the first `clock` message: the game starts then. A finished game stays up (answering
//! the configuration service) unless `--exit-when-finished`.
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
use interfaces::{Bus, Clock, Moment, Shutdown, topics};
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

/// The bus clock as the machine's time: its monotonic reading (system or virtual).
fn bus_now(bus: &Bus) -> Duration {
    bus.clock().now().as_duration()
}

/// Waits on `clock` until `deadline`, or for ever when there is none.
pub(crate) async fn sleep_until(clock: &Clock, deadline: Option<Moment>) {
    match deadline {
        Some(d) => clock.sleep_until(d).await,
        None => std::future::pending().await,
    }
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
            bus.clock().sleep(HOME_RETRY).await;
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

/// Watches the tracker's heartbeat (`vision/ball` comes once per frame, found or not), on the
/// component's clock.
#[derive(Debug, Default)]
struct TrackerWatch {
    last: Option<Moment>,
    reported: bool,
    last_resend: Option<Moment>,
}

impl TrackerWatch {
    fn heard(&mut self, now: Moment) {
        self.last = Some(now);
        self.reported = false;
    }
    /// When the watchdog is due (a silence of [`TRACKER_SILENCE`] since the tracker was last
    /// heard, not reported yet), for the loop's sleep.
    fn deadline(&self) -> Option<Moment> {
        self.last
            .filter(|_| !self.reported)
            .map(|t| t + TRACKER_SILENCE)
    }
    /// True once per silence of [`TRACKER_SILENCE`] or more (after the tracker was heard).
    fn silent(&mut self, now: Moment) -> bool {
        match self.deadline() {
            Some(d) if now >= d => {
                self.reported = true;
                true
            }
            _ => false,
        }
    }
    /// At most once a second.
    fn may_resend(&mut self, now: Moment) -> bool {
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
    /// When "cannot see" was last said (on the component's clock); "see again" is said only
    /// after it.
    said_lost: Option<Moment>,
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
        now: Moment,
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
    // A clock that follows a replay has no time before the replay's first `clock` message.
    let clock = bus.clock().clone();
    tokio::select! {
        _ = shutdown.wait() => return Ok(()),
        _ = clock.started() => {}
    }
    let o = game.start(bus_now(&bus));
    out.emit(o).await?;
    *lock(&snapshot) = snapshot_of(&game, &mermaid);
    let mut watch = TrackerWatch::default();
    loop {
        // Wake on the clock for the machine's next timer, or the tracker watchdog's.
        let deadline = [
            game.next_deadline().map(Moment::from_duration),
            watch
                .deadline()
                .filter(|_| game.machine().is_active(touch::state::TRACKING)),
        ]
        .into_iter()
        .flatten()
        .min();
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
                watch.heard(clock.now());
                if t.state == BallTrackState::Waiting && wants_tracker(&game) && watch.may_resend(clock.now()) {
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
                if let Some((said, log)) = camera.update(&c, clock.now()) {
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
            _ = sleep_until(&clock, deadline) => game.advance(bus_now(&bus)),
        };
        out.emit(outcome).await?;
        // A tracker that falls silent while the eyes follow the ball (it crashed, its camera
        // stopped): the ball is lost, said so, and searched for again once it is back.
        if game.machine().is_active(touch::state::TRACKING) && watch.silent(clock.now()) {
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
            // Let the last messages and the rest postures go out (on the wall clock: this waits
            // for the bus, and a replay's clock may never move again).
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

    /// The touch game's process loop on a virtual clock: its timers and the tracker watchdog
    /// fire when the clock is moved to their deadline, never before, and never from the wall.
    /// Every input first fires the timers due, so an input sent just before a deadline is
    /// stepped alone and the timer's step follows when the clock reaches it: no sleeps.
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn the_touch_loop_runs_its_timers_and_watchdog_on_a_virtual_clock() {
        use interfaces::bus::BusOptions;
        use interfaces::msg::command::{Command, CommandSource, Game, GameCommand};
        use interfaces::msg::tracking::BallTrack;

        let (_router, endpoint) = interfaces::router::open_router("tcp/127.0.0.1:0")
            .await
            .unwrap();
        let args = interfaces::ConnectArgs::to_router(
            &endpoint,
            &format!("unit-exec-clock-{}", std::process::id()),
        );
        let clock = Clock::virtual_unset();
        let options = BusOptions {
            announce: true,
            clock: clock.clone(),
            ..Default::default()
        };
        let exec_bus = Bus::open_with(&args, "executive", options).await.unwrap();
        let bus = Bus::open(&args, "unit-test").await.unwrap();
        let steps = bus
            .subscriber(&topics::EXECUTIVE_TRANSITIONS)
            .await
            .unwrap();
        let commands = bus.publisher(&topics::GAME_COMMAND).await.unwrap();
        let events = bus.publisher(&topics::VISION_BALL_EVENTS).await.unwrap();
        let tracks = bus.publisher(&topics::VISION_BALL).await.unwrap();
        let config = Config {
            game: GameKind::Touch,
            settings: None,
            print_diagram: false,
            print_dot: false,
            exit_when_finished: false,
        };
        let (stop, shutdown) = Shutdown::new();
        let exec = tokio::spawn(run_touch(exec_bus, config, Settings::default(), shutdown));
        let next = || async {
            let t = tokio::time::timeout(Duration::from_secs(20), steps.recv())
                .await
                .expect("a step within 20 s")
                .unwrap();
            (t.event, t.active)
        };
        let command = |c: Command| {
            let commands = &commands;
            async move {
                let mut m = GameCommand {
                    game: Game::Touch,
                    command: c,
                    source: CommandSource::Panel,
                    text: c.phrase().into(),
                    confidence: 1.0,
                    ..Default::default()
                };
                commands.publish(&mut m).await.unwrap();
            }
        };
        let event = |kind: BallEventKind| {
            let events = &events;
            async move {
                let mut e = BallEvent {
                    kind,
                    ..Default::default()
                };
                events.publish(&mut e).await.unwrap();
            }
        };
        // The subscriptions meet before the game starts: it starts once the clock has a time.
        interfaces::Clock::system()
            .sleep(Duration::from_millis(500))
            .await;
        clock.set_ns(1_700_000_000_000_000_000);
        let s = next().await;
        assert_eq!(s.1, [touch::state::WAITING]);
        command(Command::Play).await;
        assert_eq!(next().await.0, "command:play");
        command(Command::ScanBall).await;
        let (e, active) = next().await;
        assert_eq!(e, "command:scan_ball");
        assert!(
            active.iter().any(|a| a == touch::state::LOOKING),
            "{active:?}"
        );

        // The scan's move time-out (3 s): not at 2.999 s, at 3 s.
        clock.advance(Duration::from_millis(2_999));
        command(Command::Greet).await;
        assert_eq!(
            next().await.0,
            "command:greet",
            "no timer before its deadline"
        );
        clock.advance(Duration::from_millis(1));
        assert_eq!(next().await.0, "timer:scan");

        // The tracker watchdog (1.5 s without a track while tracking): the clock's, too.
        event(BallEventKind::Detected).await;
        assert_eq!(next().await.0, "ball:detected");
        event(BallEventKind::OutOfView).await;
        assert_eq!(next().await.0, "ball:out_of_view");
        let mut t = BallTrack {
            found: true,
            state: BallTrackState::Tracking,
            has_centre_m: true,
            centre_m: [0.0, 0.0, 0.8],
            ..Default::default()
        };
        tracks.publish(&mut t).await.unwrap();
        let (e, active) = next().await;
        assert_eq!(e, "ball:in_view", "the track was heard at this time");
        assert!(
            active.iter().any(|a| a == touch::state::TRACKING),
            "{active:?}"
        );
        clock.advance(Duration::from_millis(1_499));
        command(Command::Greet).await;
        assert_eq!(
            next().await.0,
            "command:greet",
            "the tracker is not silent yet"
        );
        clock.advance(Duration::from_millis(1));
        let (e, active) = next().await;
        assert_eq!(e, "ball:lost", "silent for 1.5 s on the clock");
        assert!(
            active.iter().any(|a| a == touch::state::LOOKING),
            "{active:?}"
        );

        // A jump of a minute: every move time-out of the scan, each at its own deadline.
        clock.advance(Duration::from_secs(60));
        for i in 0..20 {
            assert_eq!(next().await.0, "timer:scan", "time-out #{i} of 20");
        }
        stop.send(true).unwrap();
        exec.await.unwrap().unwrap();
    }

    #[test]
    fn the_robot_says_once_when_its_camera_stops_and_once_when_it_is_back() {
        let t0 = Moment::from_duration(Duration::from_secs(1_000));
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
