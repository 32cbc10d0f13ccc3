//! The coach machine (machine `coach`) on the [`crate::engine`], with no bus: messages in,
//! [`Output`]s out, time passed in.
//!
//! # States
//!
//! ```text
//! coach
//! ├── waiting_for_game   initial: not PLAYING (or no GameController yet); motion refused, kept
//! ├── playing            PLAYING, robot up, unpenalised, link up: requests decided and sent;
//! │                      entering it does the kept request, or resumes the interrupted one
//! ├── robot_down         the robot reports it fell; requests kept; resumes when up
//! ├── penalised          the GameController penalises the robot; requests kept
//! └── link_lost          "robot not responding"; requests kept, sent when the link is back
//! ```
//!
//! Where the machine should be is a function of the situation ([`route`]: link, then penalty,
//! then fall, then the game state); every situation event (`game:<state>`, `robot:fell`,
//! `robot:up`, `penalty:on`, `penalty:off`, `link:lost`, `link:restored`) moves it there through
//! guarded transitions, so the diagram shows each way in and out. Requests are the events
//! `request:<body or head>`, decided by [`super::rules::decide`] in whatever state is active (the
//! rules know the situation too). Timers: `still_down` and `still_lost` repeat the alarm once.
//!
//! [`resume`]: the record a restarted Executive takes the game up from; commands go out only
//! while a bridge listens ([`CoachGame::bridge`]), and are held meanwhile.

use std::sync::Arc;
use std::time::Duration;

use interfaces::msg::command::{Command, Game, GameCommand};
use interfaces::msg::nao::{
    CoachRequest, CoachStatus, GameState, LinkChange, NaoBody, NaoCommand, NaoLinkEvent,
    NaoWorldModel,
};
use interfaces::msg::speech::Priority;
use interfaces::outbox::Handled;

use super::rules::{Ask, Memory, RulesConfig, Situation};
use crate::engine::{ANY_EVENT, Builder, Definition, DefinitionError, Event, Machine, Step};

mod context;
pub use crate::game_log::LogLine;
pub use context::CoachCtx;
use context::merge;

/// The machine's name (the `machine` field of the Executive's messages).
pub const MACHINE: &str = "coach";

/// Every state path of the machine.
pub mod state {
    pub const COACH: &str = "coach";
    pub const WAITING: &str = "coach/waiting_for_game";
    pub const PLAYING: &str = "coach/playing";
    pub const ROBOT_DOWN: &str = "coach/robot_down";
    pub const PENALISED: &str = "coach/penalised";
    pub const LINK_LOST: &str = "coach/link_lost";
    /// The five modes, in document order.
    pub const MODES: [&str; 5] = [WAITING, PLAYING, ROBOT_DOWN, PENALISED, LINK_LOST];
}

/// Sentences of the machine itself (the answers to requests come from [`rules`]).
pub mod say {
    pub const FELL: &str = "I fell. I will get up and carry on.";
    pub const STILL_DOWN: &str = "I am still on the ground.";
    pub const PENALISED: &str = "I am penalised.";
    pub const LINK_LOST: &str = "The robot is not responding.";
    pub const STILL_LOST: &str = "The robot is still not responding.";
    pub const BACK_UP: &str = "I am up again.";
    pub const UNPENALISED: &str = "My penalty is over.";
    pub const LINK_BACK: &str = "The robot is responding again.";
    pub const PLAY: &str = "We are playing.";
    /// The one line a restarted Executive says when it takes a game up again.
    pub const BACK: &str = "Sorry, I'm back.";
}

/// The coach settings: the `[coach]` table of the Executive's settings file (every key
/// optional), documented on [`RulesConfig`].
pub type CoachSettings = RulesConfig;

/// Where the machine should be in `s`.
pub fn route(s: &Situation, c: &RulesConfig) -> &'static str {
    if !s.link_up {
        state::LINK_LOST
    } else if s.penalised(c) {
        state::PENALISED
    } else if s.fallen(c) {
        state::ROBOT_DOWN
    } else if s.playing() {
        state::PLAYING
    } else {
        state::WAITING
    }
}

/// The machine's actions (data; [`CoachCtx`] runs them).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Act {
    Say(&'static str, Priority),
    /// Decide the request carried by the event, answer, send.
    Decide,
    /// Remember that the current command was interrupted and why (said when resuming).
    Interrupted(&'static str),
    /// Entering PLAYING: do the kept request, or resume the interrupted command.
    Resume,
    /// Log why the machine waits.
    Waiting,
}

/// What an event carries.
#[derive(Debug, Clone, Default, PartialEq)]
pub enum Input {
    #[default]
    None,
    Request(Ask),
}

/// What the machine asks of the rest of the system, in order.
#[derive(Debug, Clone, PartialEq)]
pub enum Output {
    /// `speech/say`.
    Say { text: String, priority: Priority },
    /// `nao/command`.
    Command(NaoCommand),
    /// `executive/log`.
    Log(LogLine),
}

type Def = Definition<CoachCtx, Input, Act>;

fn is_request(e: &Event<Input>) -> bool {
    e.name.starts_with("request:")
}

/// The coach machine (see the module docs for the states).
pub fn definition(settings: &CoachSettings) -> Result<Def, DefinitionError> {
    use state::*;
    let mut b = Builder::<CoachCtx, Input, Act>::new(MACHINE);
    b.root_initial("coach");
    b.compound(COACH, "waiting_for_game");
    b.atomic(WAITING).entry(Act::Waiting);
    b.atomic(PLAYING).entry(Act::Resume);
    b.atomic(ROBOT_DOWN)
        .entry(Act::Say(say::FELL, Priority::High))
        .entry(Act::Interrupted(say::BACK_UP));
    b.atomic(PENALISED)
        .entry(Act::Say(say::PENALISED, Priority::High))
        .entry(Act::Interrupted(say::UNPENALISED));
    b.atomic(LINK_LOST)
        .entry(Act::Say(say::LINK_LOST, Priority::Urgent))
        .entry(Act::Interrupted(say::LINK_BACK));
    // Every situation event moves the machine where the situation says, from any mode.
    for from in MODES {
        for to in MODES {
            if from == to {
                continue;
            }
            let leaf = to.rsplit('/').next().unwrap_or(to);
            b.on(from, ANY_EVENT)
                .guard(&format!("route = {leaf}"), move |c: &CoachCtx, e| {
                    !is_request(e) && route(&c.situation, &c.settings) == to
                })
                .to(to);
        }
    }
    b.on(COACH, ANY_EVENT)
        .guard("request", |_, e| is_request(e))
        .action(Act::Decide);
    let secs = |s: f64| Duration::from_secs_f64(s.max(0.001));
    b.after(ROBOT_DOWN, secs(settings.still_down_s), "still_down")
        .action(Act::Say(say::STILL_DOWN, Priority::High));
    b.after(LINK_LOST, secs(settings.still_lost_s), "still_lost")
        .action(Act::Say(say::STILL_LOST, Priority::Urgent));
    b.build()
}

/// What one input did: the machine's steps (for `executive/transitions`) and the outputs.
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
    /// The commands sent, in order.
    pub fn commands(&self) -> Vec<&NaoCommand> {
        self.outputs
            .iter()
            .filter_map(|o| match o {
                Output::Command(c) => Some(c),
                _ => None,
            })
            .collect()
    }
    /// Appends `other`'s steps and outputs.
    pub fn extend(&mut self, other: Outcome) {
        self.steps.extend(other.steps);
        self.outputs.extend(other.outputs);
    }
}

/// The game: the machine, its context, and the conversion of bus messages into events.
/// `now` is the caller's clock (time since its epoch); every input first fires due timers.
#[derive(Debug)]
pub struct CoachGame {
    machine: Machine<CoachCtx, Input, Act>,
    ctx: CoachCtx,
    /// After a resume: the mode the old process was in, entered again without its announcement.
    resumed_mode: Option<&'static str>,
    /// After a resume with the link lost: a fresh packet of our robot in a world model says it
    /// is back (its return was announced on `nao/link` to nobody).
    await_link: bool,
    /// The stamps of the requests and commands acted on, kept in the resume record: one its
    /// sender sends again after a restart (see `interfaces::outbox`) is carried out once.
    handled: Handled,
}

impl CoachGame {
    /// A coach with `settings`, not started. The link is taken as up until told otherwise.
    pub fn new(settings: CoachSettings) -> Result<CoachGame, DefinitionError> {
        let def = Arc::new(definition(&settings)?);
        Ok(CoachGame {
            machine: Machine::new(def),
            ctx: CoachCtx {
                settings: Arc::new(settings),
                situation: Situation {
                    link_up: true,
                    ..Default::default()
                },
                memory: Memory::default(),
                interrupted: None,
                last_answer: String::new(),
                now_s: 0.0,
                outputs: Vec::new(),
                quiet: false,
                bridge_up: true,
                undelivered: None,
                published: None,
            },
            resumed_mode: None,
            await_link: false,
            handled: Handled::default(),
        })
    }

    /// The machine (configuration, counters, definition).
    pub fn machine(&self) -> &Machine<CoachCtx, Input, Act> {
        &self.machine
    }
    /// The next timer deadline, for the caller's sleep.
    pub fn next_deadline(&self) -> Option<Duration> {
        self.machine.next_deadline()
    }
    /// The active mode (`coach/playing`, ...).
    pub fn mode(&self) -> String {
        self.machine.active_leaves().join(" + ")
    }
    /// The status for the panel at `now`.
    pub fn status(&mut self, now: Duration) -> CoachStatus {
        self.ctx.now_s = now.as_secs_f64();
        self.ctx.status(&self.mode())
    }
    /// The memory (last and pending command, last-seen times).
    pub fn memory(&self) -> &Memory {
        &self.ctx.memory
    }

    /// Enters the initial state.
    pub fn start(&mut self, now: Duration) -> Outcome {
        self.ctx.now_s = now.as_secs_f64();
        let mark = self.ctx.outputs.len();
        let step = self.machine.start(&mut self.ctx, now);
        self.finish_step(step, mark)
    }

    fn finish_step(&mut self, step: Step<Act>, mark: usize) -> Outcome {
        if !step.ignored && (!step.exited.is_empty() || !step.entered.is_empty()) {
            let mut text = format!("{}:", step.event);
            if !step.exited.is_empty() {
                text.push_str(&format!(" left {}", step.exited.join(", ")));
            }
            if !step.entered.is_empty() {
                text.push_str(&format!(" entered {}", step.entered.join(", ")));
            }
            text.push_str(&format!(" -> now {}", step.active.join(" + ")));
            self.ctx.outputs.insert(
                mark.min(self.ctx.outputs.len()),
                Output::Log(LogLine::new("state", text)),
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
        loop {
            match self.machine.next_deadline() {
                Some(d) if d <= now => {
                    self.ctx.now_s = d.as_secs_f64();
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
        self.ctx.now_s = now.as_secs_f64();
        out
    }

    /// Sends a situation event when the situation now routes elsewhere than the active mode.
    /// After a resume, the mode the old process was in is entered without its announcement.
    fn reroute(&mut self, cause: &str, now: Duration) -> Outcome {
        let want = route(&self.ctx.situation, &self.ctx.settings);
        if self.ctx.situation.game.is_some() && !self.machine.is_active(want) {
            // The situation is known: whatever the first move is, later ones are news.
            self.ctx.quiet = self.resumed_mode.take() == Some(want);
        }
        let out = if self.machine.is_active(want) {
            self.advance(now)
        } else {
            self.send(cause, Input::None, now)
        };
        self.ctx.quiet = false;
        out
    }

    /// Whether a bridge listens on `nao/command` (the process follows its subscribers).
    /// Taken as listening until told otherwise.
    pub fn bridge_listening(&self) -> bool {
        self.ctx.bridge_up
    }

    /// Whether a bridge listens on `nao/command` now. When one does, what the robot may not
    /// have ([`CoachGame::undelivered`]) is sent.
    pub fn bridge(&mut self, listening: bool, now: Duration) -> Outcome {
        let mut out = self.advance(now);
        let was = std::mem::replace(&mut self.ctx.bridge_up, listening);
        if was && !listening {
            self.ctx.log(
                "anomaly",
                "no bridge listens on nao/command (restarting?): commands are held".into(),
            );
            // What went out just before may have gone with the bridge: sent again.
            if let Some((c, t)) = self.ctx.published.take()
                && now.as_secs_f64() - t <= RESEND_WINDOW_S
            {
                self.ctx.undelivered = Some(match self.ctx.undelivered.take() {
                    Some(held) => merge(Some(c), &held),
                    None => c,
                });
            }
        }
        if listening && let Some(c) = self.ctx.undelivered.clone() {
            self.ctx.log(
                "sent",
                format!(
                    "{:?} head {:?} target ({:.0}, {:.0}) mm, held until a bridge listened",
                    c.body, c.head, c.target.x_mm, c.target.y_mm
                ),
            );
            self.ctx.outputs.push(Output::Command(c));
        }
        out.outputs.append(&mut self.ctx.outputs);
        out
    }

    /// The commands of the outcomes so far went out on the bus (to a listening bridge).
    pub fn delivered(&mut self) {
        self.ctx.undelivered = None;
    }

    /// Commands the robot may not have: held, or sent and not confirmed by [`Self::delivered`].
    pub fn undelivered(&self) -> Option<&NaoCommand> {
        self.ctx.undelivered.as_ref()
    }

    /// A request made from the panel (`coach/request`). A GoToPosition target is remembered as
    /// the clicked point (voice "go to position" goes there next).
    pub fn request(&mut self, r: &CoachRequest, now: Duration) -> Outcome {
        if !self.handled.first_time(r.header.stamp_ns) {
            self.ctx.log(
                "heard",
                format!(
                    "{:?} again: sent again after a restart, and already carried out",
                    r.command.body
                ),
            );
            let mut out = self.advance(now);
            out.outputs.append(&mut self.ctx.outputs);
            return out;
        }
        let ask = Ask::from_panel(r);
        if ask.body == NaoBody::GoToPosition {
            self.ctx.memory.clicked = ask.target;
        }
        self.ask(ask, now)
    }

    /// A command from `game/command` (voice after the dialog, or a panel button). Other games'
    /// commands and the dialog's yes/no are logged and ignored.
    pub fn command(&mut self, cmd: &GameCommand, now: Duration) -> Outcome {
        if !self.handled.first_time(cmd.header.stamp_ns) {
            self.ctx.log(
                "heard",
                format!(
                    "{:?} \"{}\" again: sent again after a restart, and already carried out",
                    cmd.command, cmd.text
                ),
            );
            let mut out = self.advance(now);
            out.outputs.append(&mut self.ctx.outputs);
            return out;
        }
        let mut out = self.advance(now);
        let heard = format!(
            "{:?} \"{}\" ({:?}, confidence {:.2})",
            cmd.command, cmd.text, cmd.source, cmd.confidence
        );
        self.ctx.log("heard", heard);
        let ask = (cmd.game == Game::Coach && cmd.command != Command::None)
            .then(|| {
                Ask::from_voice(
                    cmd.command,
                    self.ctx.memory.clicked,
                    self.ctx.situation.world.as_ref(),
                    &self.ctx.settings,
                )
            })
            .flatten();
        match ask {
            Some(mut a) => {
                if cmd.source == interfaces::msg::command::CommandSource::Panel {
                    a.source = "panel".into();
                }
                out.extend(self.ask(a, now));
            }
            None if cmd.command.is_answer() => {
                // The dialog's yes/no: its business, logged as heard above.
                out.outputs.append(&mut self.ctx.outputs);
            }
            None => {
                self.ctx.log(
                    "anomaly",
                    format!(
                        "{:?} of {:?} is no robot command: ignored",
                        cmd.command, cmd.game
                    ),
                );
                out.outputs.append(&mut self.ctx.outputs);
            }
        }
        out
    }

    fn ask(&mut self, ask: Ask, now: Duration) -> Outcome {
        let name = if ask.body != NaoBody::Keep {
            format!("request:{}", snake(&format!("{:?}", ask.body)))
        } else {
            format!("request:{}", snake(&format!("{:?}", ask.head)))
        };
        self.send(&name, Input::Request(ask), now)
    }

    /// A world model (`nao/world_model`): memory, and `robot:fell` / `robot:up`.
    /// After a resume with the link lost, one with a fresh packet of our robot (at most
    /// [`LINK_FRESH_S`] old) says the link is back: its return may have been announced on
    /// `nao/link` while no Executive ran.
    pub fn world_model(&mut self, w: &NaoWorldModel, now: Duration) -> Outcome {
        let c = (*self.ctx.settings).clone();
        let was = self.ctx.situation.fallen(&c);
        self.ctx.memory.observe(w, now.as_secs_f64(), &c);
        self.ctx.situation.world = Some(w.clone());
        let is = self.ctx.situation.fallen(&c);
        if self.await_link
            && w.robots
                .iter()
                .any(|r| r.player_number == c.controlled_player && r.age_s <= LINK_FRESH_S)
        {
            self.await_link = false;
            self.ctx.log(
                "anomaly",
                "the robot's link, lost before the restart, is up again".into(),
            );
            self.ctx.situation.link_up = true;
            let mut out = Outcome::default();
            out.outputs.append(&mut self.ctx.outputs);
            out.extend(self.reroute("link:restored", now));
            return out;
        }
        match (was, is) {
            (false, true) => self.reroute("robot:fell", now),
            (true, false) => self.reroute("robot:up", now),
            _ => self.advance(now),
        }
    }

    /// A GameController state (`nao/game_state`): `game:<state>`, `penalty:on` / `penalty:off`.
    pub fn game_state(&mut self, g: &GameState, now: Duration) -> Outcome {
        let c = (*self.ctx.settings).clone();
        let was_pen = self.ctx.situation.penalised(&c);
        let was_state = self.ctx.situation.game.as_ref().map(|g| g.state);
        self.ctx.situation.game = Some(g.clone());
        let pen = self.ctx.situation.penalised(&c);
        if pen != was_pen {
            return self.reroute(if pen { "penalty:on" } else { "penalty:off" }, now);
        }
        if was_state != Some(g.state) {
            if g.state == GameState::FINISHED {
                // The attack is over: what interrupted its last command resumes nothing in
                // the next one.
                self.ctx.interrupted = None;
            }
            let name = match g.state {
                0 => "game:initial",
                1 => "game:ready",
                2 => "game:set",
                3 => "game:playing",
                4 => "game:finished",
                5 => "game:standby",
                _ => "game:unknown",
            };
            return self.reroute(name, now);
        }
        self.advance(now)
    }

    /// A link event (`nao/link`) about the controlled robot: `link:lost` / `link:restored`.
    pub fn link(&mut self, e: &NaoLinkEvent, now: Duration) -> Outcome {
        if e.player_number != self.ctx.settings.controlled_player {
            return self.advance(now);
        }
        let up = e.change != LinkChange::RobotNotResponding;
        self.await_link = false;
        if up == self.ctx.situation.link_up {
            return self.advance(now);
        }
        self.ctx.situation.link_up = up;
        self.reroute(if up { "link:restored" } else { "link:lost" }, now)
    }
}

/// A robot whose last packet is at most this old (s) has its link up (the bridge's default
/// time-out).
pub const LINK_FRESH_S: f64 = 1.0;

/// A bridge that goes away this soon (s) after a command was published may not have passed it
/// on (its going is seen a few milliseconds late): the command is sent again to the next one.
pub const RESEND_WINDOW_S: f64 = 0.25;

/// `GoToBallAndDribble` -> `go_to_ball_and_dribble`.
fn snake(s: &str) -> String {
    let mut out = String::new();
    for (i, ch) in s.chars().enumerate() {
        if ch.is_uppercase() {
            if i > 0 {
                out.push('_');
            }
            out.extend(ch.to_lowercase());
        } else {
            out.push(ch);
        }
    }
    out
}

pub mod resume;

#[cfg(test)]
mod tests;
