//! The coach machine's status for the page: `coach/status` (a
//! [`interfaces::msg::nao::CoachStatus`]) turned into the `coach_status` WebSocket message.
//!
//! The page gets a shape of its own rather than the bus message: labels ready to show, `null`
//! for "never" and "none" (the bus message uses `-1` and `has_*` flags), and the reason a pending
//! command waits, derived from the same situation the Executive's coach rules look at (link,
//! penalty, game state, fall, in that order). Changing the bus message does not silently change
//! what the page reads.
//!
//! Ages are seconds **at the moment the Executive published the status**; `received_ms` (the
//! panel's clock, ms since the Unix epoch) says when the panel took it off the bus, so the page
//! keeps the ages counting between updates and greys the panel out when updates stop (the
//! Executive publishes on every change and at least once a second; see [`STALE_AFTER_MS`]).
//!
//! ```json
//! {"type": "coach_status", "received_ms": 1763721600000, "seq": 41,
//!  "state": "coach/playing", "game": "PLAYING", "link_up": true, "fallen": false,
//!  "penalised": false,
//!  "pending": {"label": "Kick", "source": "panel", "why": "the game is in READY, not PLAYING"},
//!  "last": {"label": "GoToPosition (-3000, 1500) mm", "source": "executive", "done": false},
//!  "last_answer": "I go to -3.0, 1.5 metres.",
//!  "ball_last_seen_s": 0.4, "obstacle_last_seen_s": null, "obstacles_tracked": 0}
//! ```
//!
//! `pending` and `last` are `null` when there is none; `game` is `null` when no GameController
//! state has arrived; the ages are `null` when never seen.

use crate::protocol::body_label;
use interfaces::msg::nao::{CoachStatus, GameState, NaoBody, NaoCommand, NaoHead};
use serde::Serialize;

/// The page greys the status out when no update arrived for this long (ms): three of the
/// Executive's once-a-second updates missed.
pub const STALE_AFTER_MS: u64 = 3000;

/// The `coach_status` message (see the module doc).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct CoachView {
    #[serde(rename = "type")]
    pub kind: &'static str,
    /// When the panel received it (ms since the Unix epoch, the panel's clock).
    pub received_ms: u64,
    /// The Executive's sequence number of the status (a gap: updates were throttled or lost).
    pub seq: u64,
    /// The machine's active state (`coach/playing`, `coach/robot_down`, ...).
    pub state: String,
    /// The GameController state's name (`PLAYING`), `None` before the first one.
    pub game: Option<String>,
    pub link_up: bool,
    pub fallen: bool,
    pub penalised: bool,
    /// A command kept for later.
    pub pending: Option<Pending>,
    /// The last command sent to the robot.
    pub last: Option<Last>,
    /// The last thing the coach machine said ("" before the first).
    pub last_answer: String,
    /// Seconds since any of our robots saw the ball, `None` when never.
    pub ball_last_seen_s: Option<f64>,
    /// Seconds since the most recently seen obstacle was seen, `None` when never.
    pub obstacle_last_seen_s: Option<f64>,
    pub obstacles_tracked: u32,
}

/// A command the coach machine keeps for later, and why it waits.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Pending {
    pub label: String,
    /// Who asked (`panel`, `voice`, ...).
    pub source: String,
    pub why: String,
}

/// The last command sent to the robot.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Last {
    pub label: String,
    /// The sender as on `nao/command` (normally `executive`: the coach machine sends every
    /// command itself; who asked for it is not in `coach/status`).
    pub source: String,
    /// Whether the coach machine believes it is done (reached, kicked, seen).
    pub done: bool,
}

/// The page's view of `status`, received at `received_ms`.
pub fn view(status: &CoachStatus, received_ms: u64) -> CoachView {
    CoachView {
        kind: "coach_status",
        received_ms,
        seq: status.header.seq,
        state: status.state.clone(),
        game: status
            .game_known
            .then(|| game_state_name(status.game_state)),
        link_up: status.link_up,
        fallen: status.fallen,
        penalised: status.penalised,
        pending: status.has_pending.then(|| Pending {
            label: command_label(&status.pending),
            source: status.pending.source.clone(),
            why: pending_reason(status),
        }),
        last: status.has_last.then(|| Last {
            label: command_label(&status.last_command),
            source: status.last_command.source.clone(),
            done: status.last_done,
        }),
        last_answer: status.last_answer.clone(),
        ball_last_seen_s: age(status.ball_last_seen_s),
        obstacle_last_seen_s: age(status.obstacle_last_seen_s),
        obstacles_tracked: status.obstacles_tracked,
    }
}

/// `-1` (never) and anything not a finite non-negative number become `None`.
fn age(s: f64) -> Option<f64> {
    (s.is_finite() && s >= 0.0).then_some(s)
}

/// The GameController state's name (`PLAYING`), or `state N` for one this panel does not know.
pub fn game_state_name(state: u8) -> String {
    match state {
        GameState::INITIAL => "INITIAL".into(),
        GameState::READY => "READY".into(),
        GameState::SET => "SET".into(),
        GameState::PLAYING => "PLAYING".into(),
        GameState::FINISHED => "FINISHED".into(),
        n => format!("state {n}"),
    }
}

/// Why the pending command waits, from the situation in the status, checked in the order of the
/// coach rules (link, penalty, game state, fall). When none of them holds any more the machine
/// is about to send it, or something the status does not carry (the world model) holds it: the
/// last answer is then the best explanation.
pub fn pending_reason(status: &CoachStatus) -> String {
    if !status.link_up {
        "the robot is not responding: sent when the link is back".into()
    } else if status.penalised {
        "the robot is penalised: sent when it is back".into()
    } else if !status.game_known {
        "no GameController state yet: sent when the game is PLAYING".into()
    } else if status.game_state != GameState::PLAYING {
        format!(
            "the game is in {}: sent when it is PLAYING",
            game_state_name(status.game_state)
        )
    } else if status.fallen {
        "the robot is on the ground: sent when it is up".into()
    } else if !status.last_answer.is_empty() {
        format!("about to be sent (last answer: \"{}\")", status.last_answer)
    } else {
        "about to be sent".into()
    }
}

/// A short label of a Nao command: `GoToPosition (-3000, 1500) mm`, `head LookLeft`,
/// `Kick + head LookAtTheBall`.
pub fn command_label(c: &NaoCommand) -> String {
    let mut parts = Vec::new();
    if c.body != NaoBody::Keep {
        let mut b = body_label(c.body).to_string();
        if matches!(c.body, NaoBody::GoToPosition | NaoBody::Turn) {
            b.push_str(&format!(" ({:.0}, {:.0}) mm", c.target.x_mm, c.target.y_mm));
        }
        parts.push(b);
    }
    if c.head != NaoHead::Keep {
        parts.push(format!("head {:?}", c.head));
    }
    if parts.is_empty() {
        "keep (no change)".into()
    } else {
        parts.join(" + ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::msg::nao::FieldPoint;

    fn playing() -> CoachStatus {
        CoachStatus {
            state: "coach/playing".into(),
            game_state: GameState::PLAYING,
            game_known: true,
            link_up: true,
            ball_last_seen_s: 0.5,
            obstacle_last_seen_s: -1.0,
            ..Default::default()
        }
    }

    fn go_to(x_mm: f32, y_mm: f32) -> NaoCommand {
        NaoCommand {
            body: NaoBody::GoToPosition,
            target: FieldPoint { x_mm, y_mm },
            source: "panel".into(),
            ..Default::default()
        }
    }

    #[test]
    fn the_page_gets_labels_nulls_for_never_and_the_documented_keys() {
        let mut s = playing();
        s.header.seq = 41;
        s.has_last = true;
        s.last_command = go_to(-3000.0, 1500.0);
        s.last_answer = "I go there.".into();
        let v = view(&s, 1_000);
        assert_eq!(v.game.as_deref(), Some("PLAYING"));
        assert_eq!(
            v.last,
            Some(Last {
                label: "GoToPosition (-3000, 1500) mm".into(),
                source: "panel".into(),
                done: false
            })
        );
        assert_eq!(v.pending, None);
        assert_eq!(v.ball_last_seen_s, Some(0.5));
        assert_eq!(v.obstacle_last_seen_s, None);
        let json: serde_json::Value =
            serde_json::from_str(&serde_json::to_string(&v).expect("json")).expect("json");
        let mut keys: Vec<&str> = json
            .as_object()
            .expect("object")
            .keys()
            .map(String::as_str)
            .collect();
        keys.sort_unstable();
        assert_eq!(
            keys,
            [
                "ball_last_seen_s",
                "fallen",
                "game",
                "last",
                "last_answer",
                "link_up",
                "obstacle_last_seen_s",
                "obstacles_tracked",
                "penalised",
                "pending",
                "received_ms",
                "seq",
                "state",
                "type"
            ]
        );
        assert_eq!(json["type"], "coach_status");
        assert_eq!(json["seq"], 41);
        assert_eq!(json["received_ms"], 1_000);
        assert!(json["pending"].is_null() && json["obstacle_last_seen_s"].is_null());
        assert_eq!(json["last"]["label"], "GoToPosition (-3000, 1500) mm");
    }

    #[test]
    fn unknown_game_and_nonsense_ages_are_null() {
        let s = CoachStatus {
            ball_last_seen_s: f64::NAN,
            obstacle_last_seen_s: f64::INFINITY,
            ..Default::default()
        };
        let v = view(&s, 0);
        assert_eq!(v.game, None);
        assert_eq!((v.ball_last_seen_s, v.obstacle_last_seen_s), (None, None));
        assert_eq!(game_state_name(5), "state 5");
    }

    #[test]
    fn a_pending_command_says_why_it_waits_in_the_rules_order() {
        let mut s = playing();
        s.has_pending = true;
        s.pending = NaoCommand {
            body: NaoBody::Kick,
            source: "voice".into(),
            ..Default::default()
        };
        s.game_state = GameState::READY;
        let p = view(&s, 0).pending.expect("pending");
        assert_eq!(p.label, "Kick");
        assert_eq!(p.source, "voice");
        assert_eq!(p.why, "the game is in READY: sent when it is PLAYING");
        // Fallen and not playing: the game state is checked first, as by the rules.
        s.fallen = true;
        assert!(pending_reason(&s).starts_with("the game is in READY"));
        s.game_state = GameState::PLAYING;
        assert!(pending_reason(&s).contains("on the ground"));
        s.penalised = true;
        assert!(pending_reason(&s).contains("penalised"));
        s.link_up = false;
        assert!(pending_reason(&s).contains("not responding"));
        s.link_up = true;
        s.penalised = false;
        s.game_known = false;
        assert!(pending_reason(&s).contains("no GameController state"));
        s.game_known = true;
        s.fallen = false;
        s.last_answer = "Wait.".into();
        assert_eq!(
            pending_reason(&s),
            "about to be sent (last answer: \"Wait.\")"
        );
    }

    #[test]
    fn labels_name_body_target_and_head() {
        let mut c = go_to(-1499.6, 1000.2);
        assert_eq!(command_label(&c), "GoToPosition (-1500, 1000) mm");
        c.head = NaoHead::LookLeft;
        assert_eq!(
            command_label(&c),
            "GoToPosition (-1500, 1000) mm + head LookLeft"
        );
        c.body = NaoBody::Keep;
        assert_eq!(command_label(&c), "head LookLeft");
        c.head = NaoHead::Keep;
        assert_eq!(command_label(&c), "keep (no change)");
        c.body = NaoBody::Spazza;
        assert_eq!(command_label(&c), "Spazza");
    }
}
