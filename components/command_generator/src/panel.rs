//! The panel's state, independent of HTTP and of the bus: it turns a checked [`Request`] into the
//! bus messages to publish, keeps the selected strategy, and keeps the command history with what
//! became of each command.
//!
//! History statuses:
//! - `accepted`: checked and published on the bus;
//! - `refused`: failed a check, with the reason; nothing was published;
//! - `replaced`: accepted, then overridden by a later Nao command on the same channel (a body
//!   command replaces the previous body command, a head command the previous head command: the
//!   robot executes one of each at a time);
//! - `pending`: a strategy choice, which travels with the next Nao command.
//!
//! The talk key (push-to-talk) is recorded as it goes down and comes up; the page's repeats of a
//! held key are forwarded and not recorded.
//!
//! Times are passed in (`now_ms`: milliseconds since the Unix epoch), so the logic is tested
//! without a clock.

use crate::protocol::{Request, RequestError, body_label, command_label, nao_of_command};
use interfaces::Header;
use interfaces::msg::command::{Answer, CommandSource, Game, GameCommand};
use interfaces::msg::nao::{FieldPoint, NaoBody, NaoCommand, NaoHead, NaoStrategy};
use interfaces::msg::speech::TalkKey;
use serde::Serialize;
use std::collections::VecDeque;

/// How many history entries are kept (oldest dropped first).
pub const HISTORY_LEN: usize = 40;

/// What became of a command.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    Accepted,
    Refused,
    Replaced,
    Pending,
}

/// One line of the command history, as the page shows it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Entry {
    /// Increasing number of the entry.
    pub seq: u64,
    /// When it was received (ms since the Unix epoch).
    pub at_ms: u64,
    /// What was asked (`GoToPosition (-1500, 1000)`, `answer: yes`).
    pub label: String,
    pub status: Status,
    /// Why it was refused or replaced ("" when accepted).
    pub reason: String,
    /// The field target, when the command has one.
    pub target: Option<FieldPoint>,
    /// Whether it was a Nao command (for `coach/request`; and so which channels it holds).
    #[serde(skip)]
    body: bool,
    #[serde(skip)]
    head: bool,
}

/// The bus messages one accepted request produces (all with `source` panel).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Outgoing {
    pub nao: Option<NaoCommand>,
    pub game: Option<GameCommand>,
    pub answer: Option<Answer>,
    pub talk: Option<TalkKey>,
}

impl Outgoing {
    /// Whether there is anything to publish.
    pub fn is_empty(&self) -> bool {
        self.nao.is_none() && self.game.is_none() && self.answer.is_none() && self.talk.is_none()
    }
}

/// The panel: strategy, history, and the request-to-message mapping.
#[derive(Debug)]
pub struct Panel {
    strategy: NaoStrategy,
    history: VecDeque<Entry>,
    next_seq: u64,
    /// Whether the talk key was last said to be held.
    talk_held: bool,
}

impl Default for Panel {
    fn default() -> Self {
        Self::new()
    }
}

impl Panel {
    pub fn new() -> Self {
        Self {
            strategy: NaoStrategy::Default,
            history: VecDeque::new(),
            next_seq: 1,
            talk_held: false,
        }
    }

    /// The strategy sent with the next Nao command.
    pub fn strategy(&self) -> NaoStrategy {
        self.strategy
    }

    /// The history, oldest first.
    pub fn history(&self) -> impl Iterator<Item = &Entry> {
        self.history.iter()
    }

    /// Record a refused request; returns its entry.
    pub fn refuse(&mut self, what: &str, error: &RequestError, now_ms: u64) -> Entry {
        let label = if what.is_empty() {
            "(unreadable request)".to_string()
        } else {
            what.to_string()
        };
        self.push(Entry {
            seq: 0,
            at_ms: now_ms,
            label,
            status: Status::Refused,
            reason: error.to_string(),
            target: None,
            body: false,
            head: false,
        })
    }

    /// Accept a checked request: the messages to publish, and its history entry (`seq` 0: not
    /// recorded, a held talk key sent again).
    pub fn accept(&mut self, request: Request, now_ms: u64) -> (Outgoing, Entry) {
        let mut out = Outgoing::default();
        let label;
        let mut target = None;
        let mut status = Status::Accepted;
        let mut reason = String::new();
        match request {
            Request::Game {
                game,
                command,
                target: t,
            } => {
                target = t;
                label = with_target(command_label(command), t);
                out.game = Some(GameCommand {
                    header: Header::default(),
                    game,
                    command,
                    source: CommandSource::Panel,
                    text: command.phrase().to_string(),
                    confidence: 1.0,
                    confirmed: false,
                });
                if game == Game::Coach
                    && let Some((body, head)) = nao_of_command(command)
                {
                    out.nao = Some(self.nao(body, head, t));
                }
            }
            Request::Nao {
                body,
                head,
                target: t,
            } => {
                target = t;
                let mut parts = Vec::new();
                if body != NaoBody::Keep {
                    parts.push(body_label(body).to_string());
                }
                if head != NaoHead::Keep {
                    parts.push(format!("head {head:?}"));
                }
                label = with_target(&parts.join(" + "), t);
                out.nao = Some(self.nao(body, head, t));
            }
            Request::Strategy(s) => {
                self.strategy = s;
                label = format!("strategy {s:?}");
                status = Status::Pending;
                reason = "sent with the next command".into();
            }
            Request::Answer(yes) => {
                label = format!("answer: {}", if yes { "yes" } else { "no" });
                out.answer = Some(Answer {
                    header: Header::default(),
                    yes,
                });
            }
            Request::Talk(held) => {
                out.talk = Some(talk_key(held));
                let entry = Entry {
                    seq: 0,
                    at_ms: now_ms,
                    label: format!("talk key {}", if held { "down" } else { "up" }),
                    status: Status::Accepted,
                    reason: String::new(),
                    target: None,
                    body: false,
                    head: false,
                };
                if held == self.talk_held {
                    return (out, entry);
                }
                self.talk_held = held;
                return (out, self.push(entry));
            }
        }
        let (body, head) = out
            .nao
            .as_ref()
            .map(|n| (n.body != NaoBody::Keep, n.head != NaoHead::Keep))
            .unwrap_or((false, false));
        if out.nao.is_some() {
            // This command replaces the previous one on each channel it sets; a pending
            // strategy has now been sent.
            for e in self.history.iter_mut() {
                match e.status {
                    Status::Accepted if (body && e.body) || (head && e.head) => {
                        e.status = Status::Replaced;
                        e.reason = format!("replaced by {label}");
                    }
                    Status::Pending => {
                        e.status = Status::Accepted;
                        e.reason = format!("sent with {label}");
                    }
                    _ => {}
                }
            }
        }
        let entry = self.push(Entry {
            seq: 0,
            at_ms: now_ms,
            label,
            status,
            reason,
            target,
            body,
            head,
        });
        (out, entry)
    }

    /// Mark an entry refused after the fact (it could not be sent); returns it.
    pub fn mark_refused(&mut self, seq: u64, reason: &str) -> Option<Entry> {
        let e = self.history.iter_mut().find(|e| e.seq == seq)?;
        e.status = Status::Refused;
        e.reason = reason.to_string();
        Some(e.clone())
    }

    fn nao(&self, body: NaoBody, head: NaoHead, target: Option<FieldPoint>) -> NaoCommand {
        NaoCommand {
            header: Header::default(),
            body,
            head,
            strategy: self.strategy,
            target: target.unwrap_or_default(),
            source: "panel".into(),
        }
    }

    fn push(&mut self, mut e: Entry) -> Entry {
        e.seq = self.next_seq;
        self.next_seq += 1;
        if self.history.len() == HISTORY_LEN {
            self.history.pop_front();
        }
        self.history.push_back(e.clone());
        e
    }
}

/// The talk key as the panel says it is.
pub fn talk_key(held: bool) -> TalkKey {
    TalkKey {
        header: Header::default(),
        held,
        source: "panel".into(),
    }
}

fn with_target(label: &str, t: Option<FieldPoint>) -> String {
    match t {
        Some(p) => format!("{label} ({:.0}, {:.0}) mm", p.x_mm, p.y_mm),
        None => label.to_string(),
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::protocol::parse_request;
    use interfaces::msg::command::Command;

    fn req(text: &str) -> Request {
        parse_request(text).unwrap().1
    }

    #[test]
    fn a_coach_command_goes_on_both_topics_with_the_panel_as_source() {
        let mut p = Panel::new();
        let (out, e) = p.accept(
            req(r#"{"type":"command","game":"coach","command":"GoToPosition","target":{"x_mm":-1500,"y_mm":1000}}"#),
            5,
        );
        let nao = out.nao.unwrap();
        assert_eq!(nao.body, NaoBody::GoToPosition);
        assert_eq!(nao.head, NaoHead::Keep);
        assert_eq!(
            nao.target,
            FieldPoint {
                x_mm: -1500.0,
                y_mm: 1000.0
            }
        );
        assert_eq!(nao.source, "panel");
        let g = out.game.unwrap();
        assert_eq!(g.command, Command::GoToPosition);
        assert_eq!(g.game, Game::Coach);
        assert_eq!(g.source, CommandSource::Panel);
        assert_eq!(g.text, "go to your position");
        assert_eq!(g.confidence, 1.0);
        assert!(out.answer.is_none());
        assert_eq!(e.status, Status::Accepted);
        assert_eq!(e.label, "GoToPosition (-1500, 1000) mm");
        assert_eq!(e.at_ms, 5);

        // A touch game command goes on game/command only.
        let (out, _) = p.accept(
            req(r#"{"type":"command","game":"touch","command":"TouchBall"}"#),
            6,
        );
        assert!(out.nao.is_none());
        assert_eq!(out.game.unwrap().game, Game::Touch);
        // An answer goes on game/answer only.
        let (out, e) = p.accept(req(r#"{"type":"answer","yes":true}"#), 7);
        assert!(out.answer.unwrap().yes);
        assert!(out.game.is_none() && out.nao.is_none());
        assert_eq!(e.label, "answer: yes");
    }

    #[test]
    fn later_commands_replace_earlier_ones_per_channel() {
        let mut p = Panel::new();
        let (_, kick) = p.accept(
            req(r#"{"type":"command","game":"coach","command":"Kick"}"#),
            1,
        );
        let (_, look) = p.accept(
            req(r#"{"type":"command","game":"coach","command":"LookLeft"}"#),
            2,
        );
        let (_, pass) = p.accept(
            req(r#"{"type":"command","game":"coach","command":"Pass"}"#),
            3,
        );
        let status = |p: &Panel, seq| p.history().find(|e| e.seq == seq).unwrap().clone();
        assert_eq!(status(&p, kick.seq).status, Status::Replaced);
        assert_eq!(status(&p, kick.seq).reason, "replaced by Pass");
        // The head command is not replaced by a body command.
        assert_eq!(status(&p, look.seq).status, Status::Accepted);
        assert_eq!(status(&p, pass.seq).status, Status::Accepted);
        p.accept(req(r#"{"type":"nao","head":"Scan"}"#), 4);
        assert_eq!(status(&p, look.seq).status, Status::Replaced);
        assert_eq!(status(&p, pass.seq).status, Status::Accepted);
    }

    #[test]
    fn a_strategy_is_pending_until_the_next_nao_command_carries_it() {
        let mut p = Panel::new();
        let (out, s) = p.accept(req(r#"{"type":"strategy","strategy":"Passages"}"#), 1);
        assert_eq!(out, Outgoing::default());
        assert_eq!(s.status, Status::Pending);
        let (out, _) = p.accept(
            req(r#"{"type":"command","game":"coach","command":"Kick"}"#),
            2,
        );
        assert_eq!(out.nao.unwrap().strategy, NaoStrategy::Passages);
        let s = p.history().find(|e| e.seq == s.seq).unwrap();
        assert_eq!(s.status, Status::Accepted);
        assert_eq!(s.reason, "sent with Kick");
    }

    #[test]
    fn refusals_are_kept_with_their_reason_and_history_is_bounded() {
        let mut p = Panel::new();
        let e = parse_request(r#"{"type":"command","game":"coach","command":"Fly"}"#).unwrap_err();
        let r = p.refuse("", &e, 1);
        assert_eq!(r.status, Status::Refused);
        assert_eq!(r.reason, "unknown command \"Fly\"");
        for i in 0..100 {
            p.accept(req(r#"{"type":"answer","yes":false}"#), i);
        }
        assert_eq!(p.history().count(), HISTORY_LEN);
        assert_eq!(p.history().last().unwrap().seq, 101);
    }

    #[test]
    fn the_talk_key_is_forwarded_every_time_and_recorded_as_it_goes_down_and_up() {
        let mut p = Panel::new();
        let held = |p: &mut Panel, h: bool, at: u64| {
            let text = format!(r#"{{"type":"talk","held":{h}}}"#);
            p.accept(req(&text), at)
        };
        let (out, e) = held(&mut p, true, 1);
        assert!(out.talk.as_ref().unwrap().held);
        assert_eq!((e.seq, e.label.as_str()), (1, "talk key down"));
        for at in 2..10 {
            let (out, e) = held(&mut p, true, at);
            assert!(out.talk.unwrap().held);
            assert_eq!(e.seq, 0, "a repeat is not recorded");
        }
        let (out, e) = held(&mut p, false, 10);
        assert!(!out.talk.unwrap().held);
        assert_eq!((e.seq, e.label.as_str()), (2, "talk key up"));
        let labels: Vec<&str> = p.history().map(|e| e.label.as_str()).collect();
        assert_eq!(labels, ["talk key down", "talk key up"]);
    }
}
