//! Taking a touch game up again after the Executive restarts.
//!
//! After every step the Executive writes a [`Resume`] record (what the game is doing, in the
//! person's terms) into its state folder. A restarted Executive reads it and brings a fresh
//! machine to the same place by its own transitions, with the person's commands that are still
//! in force: playing ("let's play"), looking for or at the ball ("scan the ball": the target goes
//! to the tracker again, which finds the ball again within a few frames), and the arm at the ball
//! ("touch the ball", carried out again once the ball is seen). What the robot would say on the
//! way is left out: it says one short line, [`say::BACK`], and only if a game was on.
//!
//! Goal ids go on from where they were, so a status of the old process's goals is never taken
//! for one of the new goals.

use serde::{Deserialize, Serialize};

use super::*;

/// What the robot says when it takes a game up again.
pub const BACK: &str = "Sorry, I'm back.";

/// Where the eyes were.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Eyes {
    Idle,
    /// Searching, tracking, or the ball out of sight: looking for or at the ball.
    OnTheBall,
}

/// Where the arm was.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Arm {
    /// Resting or going home.
    AtRest,
    /// Reaching, touching or following the ball.
    AtTheBall,
}

/// The game as the person sees it, written after every step.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Resume {
    /// The machine it belongs to ([`MACHINE`]).
    pub machine: String,
    /// The game is on (the person said "let's play" and not "quit").
    pub playing: bool,
    pub eyes: Eyes,
    pub arm: Arm,
    /// The last goal id used.
    pub last_goal_id: u64,
    /// The reach under way moves the base too (the arm alone could not reach the ball): taken
    /// up, it goes on with the base, and the base goes home with the arm. (Absent from the
    /// records of older releases: false.)
    #[serde(default)]
    pub with_base: bool,
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
}

impl TouchGame {
    /// The record to keep after this step: `None` once the game is over (nothing to take up).
    pub fn resume_record(&self) -> Option<Resume> {
        let m = &self.machine;
        if m.is_finished() {
            return None;
        }
        let on = |s: &str| m.is_active(s);
        Some(Resume {
            machine: MACHINE.into(),
            playing: on(state::PLAYING),
            eyes: if on(state::SEARCHING) || on(state::TRACKING) || on(state::OUT_OF_SIGHT) {
                Eyes::OnTheBall
            } else {
                Eyes::Idle
            },
            arm: if on(state::REACHING) {
                Arm::AtTheBall
            } else {
                Arm::AtRest
            },
            last_goal_id: self.ctx.next_id,
            with_base: self.ctx.with_base,
            handled: self.handled.stamps(),
        })
    }

    /// Starts the game where `record` says it was (instead of [`TouchGame::start`]). A record of
    /// a game that was waiting starts it as new, silently.
    pub fn resume(&mut self, record: &Resume, now: Duration) -> Outcome {
        self.ctx.next_id = self.ctx.next_id.max(record.last_goal_id);
        self.handled = Handled::from_stamps(&record.handled);
        let mut out = self.start(now);
        if !record.playing {
            return out;
        }
        out.outputs.push(Output::Log(LogLine {
            kind: "anomaly",
            text: format!(
                "the Executive restarted: taking the game up again (eyes {:?}, arm {:?})",
                record.eyes, record.arm
            ),
            distance_m: -1.0,
        }));
        out.extend(quiet(self.send("command:play", Input::None, now)));
        if record.eyes == Eyes::OnTheBall {
            out.extend(quiet(self.send("command:scan_ball", Input::None, now)));
        }
        self.resume_touch = record.arm == Arm::AtTheBall;
        self.ctx.with_base = self.resume_touch && record.with_base;
        out.outputs.push(Output::Say {
            text: BACK.into(),
            priority: Priority::High,
        });
        out
    }

    /// Carries out a "touch the ball" taken up from before a restart, once the ball is seen.
    pub(super) fn resume_pending(&mut self, now: Duration) -> Outcome {
        if !(self.resume_touch && self.ctx.ball_seen) {
            return Outcome::default();
        }
        self.resume_touch = false;
        if !self.machine.is_active(state::PLAYING) {
            return Outcome::default();
        }
        quiet(self.send("command:touch_ball", Input::None, now))
    }
}

/// An outcome without what the robot would have said: the steps a resumed game retakes are not
/// announced again.
fn quiet(o: Outcome) -> Outcome {
    Outcome {
        steps: o.steps,
        outputs: o
            .outputs
            .into_iter()
            .filter(|x| !matches!(x, Output::Say { .. }))
            .collect(),
    }
}
