//! Loki's "touch the ball" game (seed 001 §V) as a statechart on the [`crate::engine`], with no
//! bus: messages in, [`Output`]s out, time passed in.
//!
//! # The rules (seed 001 §V)
//!
//! The person shows the robot a ball and asks it to touch it with its hand; she moves the ball,
//! decides when the game starts and ends, when the robot must touch, and tells it when it did
//! (then the arm goes home). Commands arrive at any time; the robot speaks at every transition
//! and anomaly, and explains a command that makes no sense now.
//!
//! # States (machine `touch_the_ball`)
//!
//! ```text
//! game                          the game is on (Stop/Quit from anywhere -> finished)
//! ├── waiting                   initial: waiting for the person ("hello", "let's play"),
//! │                             looking at her face
//! └── playing                   PARALLEL: the two regions run together
//!     ├── eyes                  what the head does
//!     │   ├── idle              initial: no target yet; looking at her face
//!     │   ├── searching         target sent to the tracker; the neck sweeps the scan points,
//!     │   │   │                 from the first (where people hold a ball up) on
//!     │   │   ├── looking       initial: turning to the next scan point (the tracker sees all
//!     │   │   │                 along); the neck's reached/unreachable/failed -> holding, or
//!     │   │   │                 after scan_move_timeout_s -> the next point
//!     │   │   └── holding       still on the point; after scan_dwell_s -> looking (next point)
//!     │   ├── tracking          the ball is seen; the neck follows it (gaze, frame `ball`)
//!     │   └── out_of_sight      the ball left the image ("the ball is out of my sight")
//!     └── arm                   what the arm does
//!         ├── resting           initial: arm at rest
//!         ├── reaching          reach goal for the hand at the ball, following it; out of
//!         │   │                 the arm's reach, once: the base turns and the arm and base
//!         │   │                 reach again (arm_with_base), else "I can't reach it"
//!         │   ├── moving        initial: on the way
//!         │   ├── touching      reached; courtesy_delay_s after the robot's last word
//!         │   │                 (a sentence begun or ended enters it again) -> homing
//!         │   └── following     the ball moved while reaching: re-reaching
//!         └── homing            reach cancelled, arm to its rest posture (homing_s)
//! finished                      final: everything cancelled, robot at rest; "hello" or
//!                               "let's play" starts the next visitor's game in `waiting`
//! ```
//!
//! State names on the bus are these paths (`game/playing/arm/reaching/touching`).
//!
//! # Events
//!
//! `command:<name>` (greet, play, scan_ball, track_ball, touch_ball, you_touched_it, stop, quit),
//! `ball:<kind>` (detected, out_of_view, lost, detection_timed_out) from `vision/ball_events`,
//! `ball:moved` (the tracked centre in `world` moved more than `ball_moved_m` since the last
//! one), `reach:<state>` (moving, reached, unreachable, cancelled, failed) for the arm's current
//! goal, `gaze:<state>` for the neck's, `speech:<started|ended>` (the robot's own sentences, from
//! `speech/speaking`, sent only while touching), and `timer:<label>` (scan, dwell, courtesy,
//! homed).
//!
//! # The search
//!
//! The tracker looks at every frame, the head's moves included (it places the ball through the
//! camera's pose at the frame's stamp), and `ball:detected` ends the search whenever it comes. So
//! the head does not stop and stare: it turns from one scan point to the next, holding still only
//! `scan_dwell_s` once there, and the points start where people hold a ball up for the robot
//! (see [`crate::settings::default_scan_points`]).
//!
//! Every utterance is a constant of [`say`].

use std::sync::Arc;
use std::time::Duration;

use interfaces::msg::body::{JointGoal, ReachGoal, ReachState, ReachStatus};
use interfaces::msg::command::{Command, Game, GameCommand};
use interfaces::msg::speech::{Priority, SpeakingEvent, SpeakingState};
use interfaces::msg::tracking::{BallEvent, BallEventKind, BallTarget, BallTrack, BallTrackState};
use interfaces::outbox::Handled;

use crate::engine::{DefinitionError, Event, Machine, Step};
use crate::settings::TouchSettings;

mod context;
mod definition;
pub use crate::game_log::LogLine;
pub use context::TouchCtx;
pub use definition::definition;

/// The machine's name (the `machine` field of the Executive's messages).
pub const MACHINE: &str = "touch_the_ball";

/// Every sentence the robot says in this game.
pub mod say {
    pub const GREETING: &str = "Hello, I am Loki. Nice to meet you!";
    pub const PLAY_ACK: &str = "Great, let's play! Show me the ball and ask me to scan it.";
    pub const ALREADY_PLAYING: &str = "We are already playing.";
    pub const LOOKING: &str = "I'm looking for the ball.";
    pub const ALREADY_LOOKING: &str = "I am already looking for the ball.";
    pub const SEE_IT: &str = "I see the ball.";
    pub const ALREADY_SEE_IT: &str = "I can already see the ball.";
    pub const CANNOT_FIND: &str = "I cannot find the ball. Please show it to me.";
    pub const OUT_OF_SIGHT: &str = "The ball is out of my sight.";
    pub const LOST: &str = "I lost the ball.";
    pub const GOING_TO_TOUCH: &str = "I'm going to touch the ball.";
    pub const TOUCHING: &str = "I'm touching the ball.";
    pub const FOLLOWING: &str = "I'm following the ball.";
    pub const THANKS: &str = "Thank you! I'm moving my arm back.";
    pub const COURTESY: &str = "I think I touched it. I'm moving my arm back.";
    pub const CANT_REACH: &str = "I can't reach it.";
    pub const TURNING: &str = "It's a bit far. I'm turning towards it.";
    pub const ARM_FAILED: &str = "Something is wrong with my arm.";
    pub const NOT_SEEN: &str = "I have not seen the ball yet.";
    pub const NOT_TOUCHING: &str = "I am not touching the ball.";
    pub const PLEASE_REPEAT: &str = "Please repeat.";
    pub const NOT_THIS_GAME: &str = "That is not a command of this game.";
    pub const GOODBYE: &str = "Thank you for playing. Goodbye!";
}

/// Every state path of the machine, for tests and tools.
pub mod state {
    pub const GAME: &str = "game";
    pub const WAITING: &str = "game/waiting";
    pub const PLAYING: &str = "game/playing";
    pub const EYES: &str = "game/playing/eyes";
    pub const EYES_IDLE: &str = "game/playing/eyes/idle";
    pub const SEARCHING: &str = "game/playing/eyes/searching";
    pub const LOOKING: &str = "game/playing/eyes/searching/looking";
    pub const HOLDING: &str = "game/playing/eyes/searching/holding";
    pub const TRACKING: &str = "game/playing/eyes/tracking";
    pub const OUT_OF_SIGHT: &str = "game/playing/eyes/out_of_sight";
    pub const ARM: &str = "game/playing/arm";
    pub const RESTING: &str = "game/playing/arm/resting";
    pub const REACHING: &str = "game/playing/arm/reaching";
    pub const MOVING: &str = "game/playing/arm/reaching/moving";
    pub const TOUCHING: &str = "game/playing/arm/reaching/touching";
    pub const FOLLOWING: &str = "game/playing/arm/reaching/following";
    pub const HOMING: &str = "game/playing/arm/homing";
    pub const FINISHED: &str = "finished";
}

/// The machine's actions (data; [`TouchCtx`] turns them into [`Output`]s).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Act {
    Say(&'static str, Priority),
    /// Send the ball's description to the tracker.
    SendTarget,
    /// Clear the tracker's target.
    ClearTarget,
    /// Start the scan pattern from its first point.
    ScanFromStart,
    /// Gaze at the next scan point.
    ScanNext,
    /// Gaze at the ball, following it.
    GazeAtBall,
    /// Gaze at the person's face, following her (she talks, the robot listens).
    GazeAtPerson,
    /// Cancel the neck's goal (it holds where it is).
    CancelGaze,
    /// Reach the ball with the hand, following it (with the arm, or the arm and the base after
    /// [`Act::UseBase`]).
    ReachBall,
    /// Cancel the arm's reach; the next reach uses the base too, until the arm is home.
    UseBase,
    /// Cancel the arm's reach, then send it to its rest posture.
    HomeArm,
    /// Cancel the gaze, then the head to its rest posture.
    HeadAhead,
    /// Whether the eyes have the ball now.
    BallSeen(bool),
    /// The game is over.
    Finish,
}

/// What an event carries.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Input {
    #[default]
    None,
    Command(GameCommand),
    Ball(BallEvent),
    Track(BallTrack),
    Reach(ReachStatus),
}

/// What the game asks of the rest of the robot, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// `speech/say`.
    Say { text: String, priority: Priority },
    /// `vision/ball_target` (`active = false` clears it).
    SetBallTarget(BallTarget),
    /// `body/reach`: a goal.
    Reach(ReachGoal),
    /// `body/reach`: a cancel (`active = false`) for a body part.
    CancelReach(ReachGoal),
    /// `body/joint_goal`: a rest posture.
    Home(JointGoal),
    /// `body/joint_goal` with `release = true`: the Executive gives back the joints its rest
    /// postures took, so the reach component can move them at once.
    Release(JointGoal),
    /// `executive/log` and the console.
    Log(LogLine),
    /// The machine reached its final state.
    Finish,
}

/// Whether a progress report of the speech generator begins a sentence (`Some(true)`), ends one
/// (`Some(false)`: said, cut, failed), or neither (queued, dropped before it began).
pub fn talking(ev: &SpeakingEvent) -> Option<bool> {
    match ev.state {
        SpeakingState::Started => Some(true),
        SpeakingState::Finished | SpeakingState::Interrupted | SpeakingState::Failed => Some(false),
        SpeakingState::Queued | SpeakingState::Dropped => None,
    }
}

/// The event name of a command.
pub fn command_event(c: Command) -> &'static str {
    match c {
        Command::None => "command:none",
        Command::Greet => "command:greet",
        Command::Play => "command:play",
        Command::ScanBall => "command:scan_ball",
        Command::TrackBall => "command:track_ball",
        Command::TouchBall => "command:touch_ball",
        Command::YouTouchedIt => "command:you_touched_it",
        Command::Quit => "command:quit",
        Command::Stop => "command:stop",
        Command::Yes => "command:yes",
        Command::No => "command:no",
        _ => "command:other_game",
    }
}

fn ball_event_name(k: BallEventKind) -> &'static str {
    match k {
        BallEventKind::Detected => "ball:detected",
        BallEventKind::OutOfView => "ball:out_of_view",
        BallEventKind::Lost => "ball:lost",
        BallEventKind::DetectionTimedOut => "ball:detection_timed_out",
    }
}

fn reach_state_name(s: ReachState) -> &'static str {
    match s {
        ReachState::Moving => "moving",
        ReachState::Reached => "reached",
        ReachState::Unreachable => "unreachable",
        ReachState::Cancelled => "cancelled",
        ReachState::Failed => "failed",
    }
}

/// A state path without the `game/playing/` (or `game/`) prefix, for the log.
fn short(path: &str) -> &str {
    path.strip_prefix("game/playing/")
        .or_else(|| path.strip_prefix("game/"))
        .unwrap_or(path)
}

/// The innermost states of a list (those no other state of the list is inside), shortened.
fn short_leaves(states: &[String]) -> String {
    let leaves: Vec<&str> = states
        .iter()
        .filter(|s| {
            !states.iter().any(|o| {
                o.len() > s.len() && o.starts_with(s.as_str()) && o.as_bytes()[s.len()] == b'/'
            })
        })
        .map(|s| short(s))
        .collect();
    if leaves.is_empty() {
        "-".into()
    } else {
        leaves.join(" + ")
    }
}

fn norm(v: [f64; 3]) -> f64 {
    (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt()
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]])
}

/// What one input did: the machine's steps (for `executive/transitions`) and the outputs, in
/// order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Outcome {
    pub steps: Vec<Step<Act>>,
    pub outputs: Vec<Output>,
}

impl Outcome {
    /// The texts said, in order.
    pub fn said(&self) -> Vec<&str> {
        self.outputs
            .iter()
            .filter_map(|o| match o {
                Output::Say { text, .. } => Some(text.as_str()),
                _ => None,
            })
            .collect()
    }
    fn extend(&mut self, other: Outcome) {
        self.steps.extend(other.steps);
        self.outputs.extend(other.outputs);
    }
}

/// The game: the machine, its context, and the conversion of bus messages into events.
///
/// Every input method first fires the timers due at `now` (see [`TouchGame::advance`]), then
/// handles the input. `now` is the bus clock's time since its epoch.
#[derive(Debug)]
pub struct TouchGame {
    machine: Machine<TouchCtx, Input, Act>,
    ctx: TouchCtx,
    /// A "touch the ball" taken up from before a restart, carried out once the ball is seen
    /// (see [`resume`]).
    resume_touch: bool,
    /// The stamps of the commands acted on, kept in the resume record: a command its sender
    /// sends again after a restart (see `interfaces::outbox`) is carried out once.
    handled: Handled,
}

impl TouchGame {
    /// A game with `settings` (checked), not started.
    pub fn new(settings: TouchSettings) -> Result<TouchGame, DefinitionError> {
        let def = Arc::new(definition(&settings)?);
        Ok(TouchGame {
            machine: Machine::new(def),
            ctx: TouchCtx::new(Arc::new(settings)),
            resume_touch: false,
            handled: Handled::default(),
        })
    }

    /// The machine (configuration, counters, definition).
    pub fn machine(&self) -> &Machine<TouchCtx, Input, Act> {
        &self.machine
    }

    /// Whether the game is over.
    pub fn is_finished(&self) -> bool {
        self.machine.is_finished()
    }

    /// The next timer deadline, for the caller's sleep.
    pub fn next_deadline(&self) -> Option<Duration> {
        self.machine.next_deadline()
    }

    /// Enters the initial state.
    pub fn start(&mut self, now: Duration) -> Outcome {
        let mark = self.ctx.outputs.len();
        let step = self.machine.start(&mut self.ctx, now);
        self.finish_step(step, mark)
    }

    fn finish_step(&mut self, step: Step<Act>, mark: usize) -> Outcome {
        if !step.ignored && (!step.exited.is_empty() || !step.entered.is_empty()) {
            let text = format!(
                "{}: {} -> {}; now {}",
                step.event,
                short_leaves(&step.exited),
                short_leaves(&step.entered),
                step.active
                    .iter()
                    .map(|s| short(s))
                    .collect::<Vec<_>>()
                    .join(" + ")
            );
            self.ctx.outputs.insert(
                mark.min(self.ctx.outputs.len()),
                Output::Log(LogLine {
                    kind: "state",
                    text,
                    distance_m: -1.0,
                }),
            );
        }
        Outcome {
            steps: vec![step],
            outputs: std::mem::take(&mut self.ctx.outputs),
        }
    }

    fn send(&mut self, name: &str, payload: Input, now: Duration) -> Outcome {
        let mut out = self.advance(now);
        let mark = self.ctx.outputs.len();
        let step = self
            .machine
            .send(&mut self.ctx, Event::new(name, payload), now);
        out.extend(self.finish_step(step, mark));
        out
    }

    /// Fires the timers due at `now`.
    pub fn advance(&mut self, now: Duration) -> Outcome {
        let mut out = Outcome::default();
        // One timer at a time so each step's outputs follow its own state line.
        loop {
            match self.machine.next_deadline() {
                Some(d) if d <= now => {
                    let mark = self.ctx.outputs.len();
                    for step in self.machine.advance(&mut self.ctx, d) {
                        let o = self.finish_step(step, mark);
                        out.extend(o);
                    }
                }
                _ => break,
            }
        }
        self.machine.advance(&mut self.ctx, now);
        out
    }

    /// The next visitor: a finished game starts again from `waiting` (the robot plays with one
    /// person after another, a whole day). The goal ids go on counting, so that no status of the
    /// last game's goals is taken for the new game's, and the commands acted on are kept.
    fn next_visitor(&mut self, now: Duration) -> Outcome {
        let next_id = self.ctx.next_id;
        self.machine = Machine::new(self.machine.definition().clone());
        self.ctx = TouchCtx::new(self.ctx.settings.clone());
        self.ctx.next_id = next_id;
        self.resume_touch = false;
        let mut out = Outcome::default();
        out.outputs.push(Output::Log(LogLine {
            kind: "state",
            text: "a new visitor: a new game".into(),
            distance_m: -1.0,
        }));
        out.extend(self.start(now));
        out
    }

    /// A command from `game/command`. Yes/No are the dialog's business (logged, not acted on).
    pub fn command(&mut self, cmd: &GameCommand, now: Duration) -> Outcome {
        let name = command_event(cmd.command);
        let mut out = self.advance(now);
        if !self.handled.first_time(cmd.header.stamp_ns) {
            out.outputs.push(Output::Log(LogLine {
                kind: "heard",
                text: format!(
                    "\"{}\" again: sent again after a restart, and already carried out",
                    cmd.text
                ),
                distance_m: -1.0,
            }));
            return out;
        }
        out.outputs.push(Output::Log(LogLine {
            kind: "heard",
            text: format!(
                "\"{}\" -> {} ({:?}, confidence {:.2}{})",
                cmd.text,
                name,
                cmd.source,
                cmd.confidence,
                if cmd.confirmed { ", confirmed" } else { "" }
            ),
            distance_m: -1.0,
        }));
        if cmd.command.is_answer() {
            return out;
        }
        if self.is_finished() && matches!(cmd.command, Command::Greet | Command::Play) {
            out.extend(self.next_visitor(now));
        }
        let name = if cmd.command != Command::None && !cmd.command.in_game(Game::Touch) {
            "command:other_game"
        } else {
            name
        };
        let o = self.send(name, Input::Command(cmd.clone()), now);
        let ignored = o.steps.last().is_some_and(|s| s.ignored);
        out.extend(o);
        if ignored {
            out.outputs.push(Output::Log(LogLine {
                kind: "anomaly",
                text: format!(
                    "{name} ignored in {}",
                    self.machine.active_leaves().join(" + ")
                ),
                distance_m: -1.0,
            }));
        }
        out
    }

    /// The robot began (`talking`) or ended a sentence (from `speech/speaking`, see
    /// [`talking`]; a speech generator that left ended its sentence). The arm touching the ball
    /// waits for the robot's silence: its courtesy delay counts from the robot's last word, and
    /// does not run out while the robot talks.
    pub fn speaking(&mut self, talking: bool, now: Duration) -> Outcome {
        let mut out = self.advance(now);
        let was = std::mem::replace(&mut self.ctx.robot_talking, talking);
        if self.machine.is_active(state::TOUCHING) && (talking || was) {
            let name = if talking {
                "speech:started"
            } else {
                "speech:ended"
            };
            out.extend(self.send(name, Input::None, now));
        }
        out
    }

    /// An event from `vision/ball_events`.
    pub fn ball_event(&mut self, ev: &BallEvent, now: Duration) -> Outcome {
        let mut out = self.advance(now);
        let (text, d) = match (ev.kind, self.ctx.ball_camera_distance) {
            (BallEventKind::Detected, Some(d)) => {
                (format!("ball detected, {d:.2} m from the camera"), d)
            }
            (k, _) => (
                format!("ball {}", &ball_event_name(k)[5..].replace('_', " ")),
                -1.0,
            ),
        };
        out.outputs.push(Output::Log(LogLine {
            kind: "ball",
            text,
            distance_m: d,
        }));
        if ev.kind != BallEventKind::Detected {
            // A new track starts from scratch.
            self.ctx.ball_reported = None;
        }
        out.extend(self.send(ball_event_name(ev.kind), Input::Ball(ev.clone()), now));
        out.extend(self.resume_pending(now));
        out
    }

    /// A track from `vision/ball`: raises `ball:moved` when the ball's `world` centre moved more
    /// than `ball_moved_m` since the last report (the first position is only recorded).
    ///
    /// Out of sight, a ball the tracker still holds is followed again (`ball:in_view`) once it
    /// is well inside the image, or once it has been held for [`STILL_HELD_S`] wherever it is:
    /// reported at the border while the head turned, and held there by a head that stopped, it
    /// never left.
    pub fn ball_track(&mut self, track: &BallTrack, now: Duration) -> Outcome {
        let mut out = self.ball_track_moved(track, now);
        let held = self.machine.is_active(state::OUT_OF_SIGHT) && held(track);
        if !held {
            self.ctx.held_out_of_sight_since = None;
            return out;
        }
        let since = *self.ctx.held_out_of_sight_since.get_or_insert(now);
        if well_in_view(track) || now.saturating_sub(since) >= Duration::from_secs_f64(STILL_HELD_S)
        {
            self.ctx.held_out_of_sight_since = None;
            out.extend(self.send("ball:in_view", Input::Track(track.clone()), now));
        }
        out
    }

    fn ball_track_moved(&mut self, track: &BallTrack, now: Duration) -> Outcome {
        if track.has_centre_m {
            self.ctx.ball_camera_distance = Some(norm(track.centre_m));
        }
        if !track.has_centre_world {
            return self.advance(now);
        }
        let p = track.centre_world_m;
        self.ctx.ball_world = Some(p);
        match self.ctx.ball_reported {
            None => {
                self.ctx.ball_reported = Some(p);
                self.advance(now)
            }
            Some(last) if dist(last, p) > self.ctx.settings.ball_moved_m => {
                self.ctx.ball_reported = Some(p);
                let mut out = self.advance(now);
                out.outputs.push(Output::Log(LogLine {
                    kind: "ball",
                    text: format!(
                        "ball moved {:.2} m to ({:.2}, {:.2}, {:.2}) in world",
                        dist(last, p),
                        p[0],
                        p[1],
                        p[2]
                    ),
                    distance_m: self.ctx.ball_camera_distance.unwrap_or(-1.0),
                }));
                out.extend(self.send("ball:moved", Input::Track(track.clone()), now));
                out
            }
            Some(_) => self.advance(now),
        }
    }

    /// A status from `body/reach_status`: the arm's current goal becomes `reach:<state>`, the
    /// neck's `gaze:<state>`; other goals' statuses are ignored (not counted).
    pub fn reach_status(&mut self, st: &ReachStatus, now: Duration) -> Outcome {
        let state = reach_state_name(st.state);
        let prefix = if st.id != 0 && st.id == self.ctx.arm_goal {
            "reach"
        } else if st.id != 0 && st.id == self.ctx.gaze_goal {
            "gaze"
        } else {
            return self.advance(now);
        };
        let mut out = self.advance(now);
        if prefix == "reach" && st.state != ReachState::Moving {
            out.outputs.push(Output::Log(LogLine {
                kind: "reach",
                text: format!(
                    "hand {state}: {:.3} m from the ball{}",
                    st.distance_m,
                    if st.detail.is_empty() {
                        String::new()
                    } else {
                        format!(" ({})", st.detail)
                    }
                ),
                distance_m: st.distance_m,
            }));
        }
        if prefix == "gaze" && matches!(st.state, ReachState::Unreachable | ReachState::Failed) {
            out.outputs.push(Output::Log(LogLine {
                kind: "anomaly",
                text: format!("gaze goal {} {state}: {}", st.id, st.detail),
                distance_m: st.distance_m,
            }));
        }
        out.extend(self.send(&format!("{prefix}:{state}"), Input::Reach(st.clone()), now));
        out
    }

    /// The ball's last tracked centre in `world`.
    pub fn ball_world(&self) -> Option<[f64; 3]> {
        self.ctx.ball_world
    }
}

pub mod resume;
#[cfg(test)]
mod tests;

/// Largest angle off the camera's axis (degrees) at which a tracked ball counts as well inside
/// the image (the head camera sees about 31 degrees to either side, 24 up and down).
const WELL_IN_VIEW_DEG: f64 = 18.0;

/// How long a ball reported out of view must stay held by the tracker, wherever in the image,
/// to be followed again (s).
const STILL_HELD_S: f64 = 1.0;

/// A ball the tracker holds (found, tracking, with a centre).
pub(crate) fn held(track: &BallTrack) -> bool {
    track.found && track.state == BallTrackState::Tracking && track.has_centre_m
}

/// A ball the tracker holds within [`WELL_IN_VIEW_DEG`] of the camera's axis.
fn well_in_view(track: &BallTrack) -> bool {
    let [x, y, z] = track.centre_m;
    held(track) && z > 0.0 && x.hypot(y).atan2(z).to_degrees() < WELL_IN_VIEW_DEG
}
