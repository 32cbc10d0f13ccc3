//! Taking a coach game up again after the Executive restarts.
//!
//! After every input that changes it, the Executive keeps a [`Resume`] record in its state folder:
//! the mode it was in, the command under way (the request and the command the robot got, which
//! carries the strategy) and whether it is done, a request kept for later (refused in SET, while
//! penalised, down or unlinked), what interrupted the command (a fall, a penalty, a lost link:
//! said when it is resumed), the last clicked point, whether the link was up, and what the robot
//! may not have yet (held while no bridge listened, or published just before the process died).
//!
//! The situation (GameController state, penalty, fall) is not kept: the bridge publishes it
//! again within half a second. A restarted Executive ([`CoachGame::resume`]) starts a fresh
//! machine with that memory, says one line ([`say::BACK`]), and the first GameController state
//! moves it where the game is: into the mode it was in without announcing it again (no second
//! "I am penalised."), or, when the game moved on meanwhile, as any change is (PLAYING does the
//! kept request; the end of a penalty resumes). A command the robot has is not sent again (the
//! robot keeps its last command; the link has no heartbeat to keep up); one it may not have is
//! sent once a bridge listens. Times are not kept (a process's clock starts with it): the
//! command under way counts as sent at the restart.

use interfaces::msg::nao::FieldPoint;
use serde::{Deserialize, Serialize};

use super::*;

/// What interrupted the command under way (said when it is resumed).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Interruption {
    Fell,
    Penalised,
    LinkLost,
}

impl Interruption {
    /// What the robot says when it carries on.
    pub fn said(self) -> &'static str {
        match self {
            Interruption::Fell => say::BACK_UP,
            Interruption::Penalised => say::UNPENALISED,
            Interruption::LinkLost => say::LINK_BACK,
        }
    }
    fn of(text: &str) -> Option<Interruption> {
        [
            Interruption::Fell,
            Interruption::Penalised,
            Interruption::LinkLost,
        ]
        .into_iter()
        .find(|i| i.said() == text)
    }
}

/// The command under way: what was asked and what the robot got.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sent {
    pub ask: Ask,
    pub command: NaoCommand,
    /// Whether it is believed done (arrived, kicked, ball seen).
    pub done: bool,
}

/// The coach game as a restarted Executive needs it, written after every change.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Resume {
    /// The machine it belongs to ([`MACHINE`]).
    pub machine: String,
    /// The active mode (a path of [`state::MODES`]).
    pub mode: String,
    pub last: Option<Sent>,
    /// A request kept for later.
    pub pending: Option<Ask>,
    pub interrupted: Option<Interruption>,
    /// The panel's last clicked point (voice "go to position" goes there).
    pub clicked: Option<FieldPoint>,
    pub link_up: bool,
    /// What the robot may not have (see [`CoachGame::undelivered`]).
    pub undelivered: Option<NaoCommand>,
    pub last_answer: String,
    /// The stamps of the last commands acted on (`interfaces::outbox::Handled`): one sent again
    /// after a restart is known and not carried out twice.
    #[serde(default)]
    pub handled: Vec<i64>,
}

impl crate::state_file::Record for Resume {
    const MACHINE: &'static str = MACHINE;
    fn machine(&self) -> &str {
        &self.machine
    }
    fn check(&self) -> Result<(), String> {
        match self.mode_path() {
            Some(_) => Ok(()),
            None => Err(format!("no mode {:?} in the coach machine", self.mode)),
        }
    }
}

impl Resume {
    /// The mode's path in the machine.
    fn mode_path(&self) -> Option<&'static str> {
        state::MODES.into_iter().find(|m| *m == self.mode)
    }

    /// Whether there was a game to take up: anything but waiting with nothing asked.
    pub fn game_on(&self) -> bool {
        self.mode != state::WAITING || self.last.is_some() || self.pending.is_some()
    }

    /// One line for the log.
    pub fn summary(&self) -> String {
        let last = match &self.last {
            Some(s) => format!(
                "{:?}{}",
                s.command.body,
                if s.done { " (done)" } else { " (under way)" }
            ),
            None => "none".into(),
        };
        let pending = self
            .pending
            .as_ref()
            .map_or("none".into(), |a| format!("{:?}", a.body));
        format!(
            "mode {}, last command {last}, kept request {pending}, interrupted by {:?}, link {}{}",
            self.mode,
            self.interrupted,
            if self.link_up { "up" } else { "lost" },
            match &self.undelivered {
                Some(c) => format!(", {:?} head {:?} not delivered", c.body, c.head),
                None => String::new(),
            }
        )
    }
}

impl CoachGame {
    /// The record to keep now.
    pub fn resume_record(&self) -> Resume {
        let m = &self.ctx.memory;
        let mode = state::MODES
            .into_iter()
            .find(|s| self.machine.is_active(s))
            .unwrap_or(state::WAITING);
        Resume {
            machine: MACHINE.into(),
            mode: mode.into(),
            last: m.last.as_ref().map(|(ask, command)| Sent {
                ask: ask.clone(),
                command: command.clone(),
                done: m.last_done,
            }),
            pending: m.pending.clone(),
            interrupted: self.ctx.interrupted.and_then(Interruption::of),
            clicked: m.clicked,
            link_up: self.ctx.situation.link_up,
            undelivered: self.ctx.undelivered.clone(),
            last_answer: self.ctx.last_answer.clone(),
            handled: self.handled.stamps(),
        }
    }

    /// Starts the game with the memory of `record` (instead of [`CoachGame::start`]). Until
    /// the process reports a listening bridge ([`CoachGame::bridge`]), commands are held.
    pub fn resume(&mut self, record: &Resume, now: Duration) -> Outcome {
        let c = &mut self.ctx;
        c.memory.last = record
            .last
            .as_ref()
            .map(|s| (s.ask.clone(), s.command.clone()));
        c.memory.last_done = record.last.as_ref().is_some_and(|s| s.done);
        c.memory.last_sent_s = now.as_secs_f64();
        c.memory.pending = record.pending.clone();
        c.memory.clicked = record.clicked;
        c.interrupted = record.interrupted.map(Interruption::said);
        c.situation.link_up = record.link_up;
        c.undelivered = record.undelivered.clone();
        c.last_answer = record.last_answer.clone();
        c.bridge_up = false;
        self.resumed_mode = record.mode_path();
        self.await_link = !record.link_up;
        self.handled = Handled::from_stamps(&record.handled);
        let mut out = self.start(now);
        self.ctx.log(
            "resumed",
            format!(
                "the Executive restarted: taking the game up again ({})",
                record.summary()
            ),
        );
        if record.game_on() {
            self.ctx.say(say::BACK.into(), Priority::High);
        }
        out.outputs.append(&mut self.ctx.outputs);
        out
    }
}
