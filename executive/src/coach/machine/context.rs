//! The coach machine's context: the situation, the memory, the commands held or sent, and how
//! the machine's actions become [`Output`]s.

use std::sync::Arc;

use interfaces::msg::nao::{CoachStatus, GameState, NaoBody, NaoCommand};
use interfaces::msg::speech::Priority;

use super::{Act, Input, LogLine, Output, RESEND_WINDOW_S, say};
use crate::coach::rules::{self, Ask, Memory, RulesConfig, Situation, Verdict};
use crate::engine::{Context, Event};

/// The machine's context: the situation, the memory, the outputs.
#[derive(Debug)]
pub struct CoachCtx {
    pub(super) settings: Arc<RulesConfig>,
    pub(super) situation: Situation,
    pub(super) memory: Memory,
    /// Set by an interruption; said and cleared when the command is resumed.
    pub(super) interrupted: Option<&'static str>,
    pub(super) last_answer: String,
    pub(super) now_s: f64,
    pub(super) outputs: Vec<Output>,
    /// While set, the machine's own announcements ([`Act::Say`]) are logged, not said: a
    /// restarted Executive entering the mode it was in has said them already.
    pub(super) quiet: bool,
    /// Whether a bridge subscribes to `nao/command` (see [`RulesConfig::bridges`]).
    pub(super) bridge_up: bool,
    /// What the robot should have but may not: commands held while no bridge listens, or
    /// published and not yet confirmed ([`CoachGame::delivered`]), merged as the robot merges
    /// them (a body replaces body and target, a head the head).
    pub(super) undelivered: Option<NaoCommand>,
    /// What was published last (merged within [`RESEND_WINDOW_S`]) and when: a bridge that
    /// went away just after may have died with it.
    pub(super) published: Option<(NaoCommand, f64)>,
}

impl CoachCtx {
    pub(super) fn log(&mut self, kind: &'static str, text: String) {
        self.outputs.push(Output::Log(LogLine::new(kind, text)));
    }

    pub(super) fn say(&mut self, text: String, priority: Priority) {
        self.log("said", text.clone());
        self.last_answer = text.clone();
        self.outputs.push(Output::Say { text, priority });
    }

    /// Sends `c` to the robot, or holds it while no bridge listens. Either way it is kept as
    /// undelivered until the process says it went out ([`CoachGame::delivered`]).
    fn command(&mut self, c: NaoCommand) {
        self.undelivered = Some(merge(self.undelivered.take(), &c));
        if self.bridge_up {
            let recent = self
                .published
                .take()
                .filter(|(_, t)| self.now_s - t <= RESEND_WINDOW_S)
                .map(|(p, _)| p);
            self.published = Some((merge(recent, &c), self.now_s));
            self.outputs.push(Output::Command(c));
        } else {
            self.log(
                "held",
                format!(
                    "{:?} head {:?}: no bridge listens on nao/command, sent when one does",
                    c.body, c.head
                ),
            );
        }
    }

    /// Decides `ask`, says the answer, then sends the command (or keeps the request).
    fn decide(&mut self, ask: &Ask, preface: Option<&str>) {
        let rules = &*self.settings;
        let verdict = rules::decide(ask, &self.situation, rules);
        let mut text = verdict.say().to_string();
        if let Some(p) = preface {
            text = format!("{p} {text}");
        }
        match &verdict {
            Verdict::Execute { command, .. } | Verdict::Replace { command, .. } => {
                self.say(text, Priority::Normal);
                if let Verdict::Replace { asked, .. } = &verdict {
                    self.log(
                        "replaced",
                        format!("{asked:?} from {} became {:?}", ask.source, command.body),
                    );
                }
                self.log(
                    "sent",
                    format!(
                        "{:?} head {:?} target ({:.0}, {:.0}) mm",
                        command.body, command.head, command.target.x_mm, command.target.y_mm
                    ),
                );
                self.memory.sent(ask, command, self.now_s);
                if ask.is_motion() || ask.body == NaoBody::Stop {
                    // A new body command replaces whatever was kept.
                    self.memory.pending = None;
                }
                self.command(command.clone());
            }
            Verdict::Refuse { reason, keep, .. } => {
                self.say(text, Priority::High);
                self.log(
                    "refused",
                    format!(
                        "{:?} from {}: {reason:?}{}",
                        ask.body,
                        ask.source,
                        if *keep { ", kept for later" } else { "" }
                    ),
                );
                if *keep {
                    self.memory.pending = Some(ask.clone());
                }
            }
        }
    }

    /// The status for the panel.
    pub fn status(&self, active: &str) -> CoachStatus {
        let c = &*self.settings;
        let s = &self.situation;
        let (has_last, last_command) = match &self.memory.last {
            Some((_, cmd)) => (true, cmd.clone()),
            None => (false, NaoCommand::default()),
        };
        let (has_pending, pending) = match &self.memory.pending {
            Some(a) => (
                true,
                NaoCommand {
                    body: a.body,
                    head: a.head,
                    strategy: a.strategy,
                    target: a.target.unwrap_or_default(),
                    source: a.source.clone(),
                    ..Default::default()
                },
            ),
            None => (false, NaoCommand::default()),
        };
        CoachStatus {
            state: active.to_string(),
            game_state: s.game.as_ref().map_or(0, |g| g.state),
            game_known: s.game.is_some(),
            link_up: s.link_up,
            fallen: s.fallen(c),
            penalised: s.penalised(c),
            last_command,
            has_last,
            last_done: self.memory.last_done,
            pending,
            has_pending,
            last_answer: self.last_answer.clone(),
            ball_last_seen_s: self.memory.ball_age(self.now_s).unwrap_or(-1.0),
            obstacle_last_seen_s: self.memory.obstacle_age(self.now_s).unwrap_or(-1.0),
            obstacles_tracked: self.memory.obstacles_tracked,
            ..Default::default()
        }
    }
}

impl Context<Act, Input> for CoachCtx {
    fn run(&mut self, action: &Act, event: &Event<Input>) {
        match *action {
            Act::Say(text, _) if self.quiet => {
                self.log(
                    "resumed",
                    format!("said before the restart, not again: {text}"),
                );
            }
            Act::Say(text, priority) => self.say(text.to_string(), priority),
            Act::Decide => {
                if let Input::Request(ask) = &event.payload {
                    self.decide(ask, None);
                }
            }
            Act::Interrupted(why) => {
                // The first cause is what the coach hears when the robot carries on. Only a
                // game under way is interrupted: a fall after FINISHED resumes nothing in the
                // next attack.
                if self
                    .situation
                    .game
                    .as_ref()
                    .is_some_and(|g| g.state == GameState::PLAYING)
                {
                    self.interrupted.get_or_insert(why);
                }
            }
            Act::Resume => {
                let interrupted = self.interrupted.take();
                if let Some(ask) = self.memory.pending.take() {
                    let preface = interrupted.unwrap_or(say::PLAY);
                    self.decide(&ask, Some(preface));
                } else if let Some(why) = interrupted {
                    match self.memory.to_resume() {
                        Some(ask) if ask.body != NaoBody::Stop => {
                            self.log("resumed", format!("{:?} after: {why}", ask.body));
                            self.decide(&ask, Some(&format!("{why} Resuming.")));
                        }
                        _ => self.say(why.to_string(), Priority::Normal),
                    }
                }
            }
            Act::Waiting => {
                let why = match &self.situation.game {
                    None => "no GameController state yet".to_string(),
                    Some(g) => format!("game state {}", g.state),
                };
                self.log("state", format!("waiting for PLAYING ({why})"));
            }
        }
    }
}

/// `c` applied after `held`, as the robot applies commands: a body replaces the body and the
/// target, a head the head; the strategy is always replaced.
pub(super) fn merge(held: Option<NaoCommand>, c: &NaoCommand) -> NaoCommand {
    let Some(mut h) = held else {
        return c.clone();
    };
    if c.body != NaoBody::Keep {
        h.body = c.body;
        h.target = c.target;
    }
    if c.head != interfaces::msg::nao::NaoHead::Keep {
        h.head = c.head;
    }
    h.strategy = c.strategy;
    h.source = c.source.clone();
    h
}
