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
//! The Nao coach machine ([`crate::coach`]), with the same configuration and propose services;
//! with a state folder it keeps its record there (`coach.json`) and a restarted process takes
//! the game up from it.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::Duration;

use interfaces::bus::{CallError, ErrorCode, ServiceError};
use interfaces::msg::body::{JointGoal, JointRefusal};
use interfaces::msg::dr::{GetNodeRequest, ProposeReply, ProposeRequest, StructuralChange};
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

mod touch_loop;
use touch_loop::*;

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
    /// Keep the game's state here after every step and take the game up from it at start, so a
    /// restarted Executive goes on where it was (under `robocog launch`: the component's state
    /// folder, ROBOCOG_STATE_DIR): `touch.json` or `coach.json`.
    #[arg(long, env = "ROBOCOG_STATE_DIR")]
    pub state_dir: Option<PathBuf>,
    /// The components that bring the person's voice to the game as commands on `game/command`
    /// (comma-separated; the touch game's `dialogs`). When none of them has published there for
    /// `--hearing-grace-s` (its machine dropped off the network, or it is gone for longer than a
    /// restart), the robot says it cannot hear, and that it can again once one is back. Empty:
    /// never said.
    #[arg(long, value_delimiter = ',')]
    pub hearing_from: Vec<String>,
    /// How long the voice's components may be away before the robot says it cannot hear (s):
    /// longer than a restart of theirs (which they announce themselves).
    #[arg(long, default_value_t = 5.0)]
    pub hearing_grace_s: f64,
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
    // The type of an added node (`None` for a removal or a move).
    let added_type = match c {
        StructuralChange::AddNode(spec) => Some(spec.node_type.as_str()),
        _ => None,
    };
    let name = c.name().trim();
    let facts = Facts {
        game_on,
        name_exists: added_type.is_some() && !name.is_empty() && node_exists(bus, name).await?,
        type_present: match added_type {
            Some(t)
                if game_on
                    && settings
                        .unique_types
                        .iter()
                        .any(|u| u.eq_ignore_ascii_case(t)) =>
            {
                node_exists(bus, &t.to_lowercase()).await?
            }
            _ => false,
        },
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
            let state_dir = config.state_dir.as_deref();
            crate::coach::run_observed(bus, settings.coach, state_dir, shutdown, move |game| {
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
        Ok((config, settings))
    }

    /// `--print-diagram`, `--print-dot`: a drawing of the machine on stdout, and no bus.
    fn without_bus((config, settings): &(Config, Settings)) -> Option<anyhow::Result<()>> {
        (config.print_diagram || config.print_dot).then(|| {
            print!("{}", diagram(config.game, settings, config.print_dot)?);
            Ok(())
        })
    }

    async fn run(bus: Bus, prepared: (Config, Settings), shutdown: Shutdown) -> anyhow::Result<()> {
        let (config, settings) = prepared;
        run(bus, config, settings, shutdown).await
    }
}

#[cfg(test)]
#[expect(
    clippy::disallowed_methods,
    reason = "the tests' guards wait for a real bus and a spawned Executive on the wall"
)]
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
            state_dir: None,
            hearing_from: vec![],
            hearing_grace_s: 5.0,
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
