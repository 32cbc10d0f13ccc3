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
//! The tracker watchdog: with the eyes on the ball, 1.5 s without `vision/ball` from a tracker
//! still on the bus (its camera stalled, it hangs) is a lost ball. A tracker that left the bus
//! (its writer token on `vision/ball` went: killed, crashed) or came back as a new process (its
//! track numbers start again, or it has no target) is an anomaly ridden out for
//! `tracker_restart_grace_s`: nothing said, the states kept, the target sent again, the ball
//! taken to be where it was until the new tracker holds it (a ball that moved meanwhile is
//! `ball:moved`); past the grace it is lost.
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
use interfaces::msg::body::{JointGoal, JointRefusal, ReachGoal};
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
mod tracker_watch;
use tracker_watch::*;

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
    /// Whether the robot may turn (and move) its base to reach a ball its arm alone cannot
    /// reach (the touch game's `arm_with_base`). `false` for a robot whose base joint_motor does
    /// not drive: the base's joints would be refused.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub base: bool,
}

impl Config {
    /// The settings file's content, or the defaults.
    pub fn load_settings(&self) -> anyhow::Result<Settings> {
        let mut settings = match &self.settings {
            Some(p) => Settings::load(p)?,
            None => Settings::default(),
        };
        if !self.base {
            settings.touch.arm_with_base.clear();
        }
        Ok(settings)
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
mod tests;
