//! What the page may ask, and the checks every request passes before anything reaches the bus.
//!
//! A request is one WebSocket text message holding one JSON object with a `type`:
//!
//! | `type` | fields | meaning |
//! |---|---|---|
//! | `command` | `id`, `game` (`"touch"`/`"coach"`), `command` (a [`Command`] name such as `"GoToPosition"`), `target` (`{"x_mm","y_mm"}`, only for GoToPosition and Turn) | a game command, as if spoken |
//! | `nao` | `id`, `body` (a [`NaoBody`] name), `head` (a [`NaoHead`] name), `target` | a raw body/head command for the Nao (the buttons without a spoken phrase: Dribble, LookForward, Scan) |
//! | `strategy` | `id`, `strategy` (a [`NaoStrategy`] name) | the strategy sent with every following Nao command |
//! | `answer` | `id`, `yes` (bool) | a yes/no answer to the robot's "Did you say ...?" |
//! | `talk` | `id`, `held` (bool) | the talk key for a recognizer in push-to-talk mode: sent when it goes down, every 0.5 s while held, and when it comes up (`speech/talk`) |
//!
//! `id` is the page's own number for the request, echoed in the reply. Unknown fields, unknown
//! names, a command of the other game, a missing or unneeded target, a target off the carpet, a
//! non-finite number, and text over [`MAX_MESSAGE_BYTES`] are all refused with a reason
//! ([`RequestError`]); nothing refused is ever forwarded.
//!
//! Field frame: millimetres, origin at the centre spot, x towards the opponent goal, y to the
//! left (the frame of `interfaces::msg::nao`). A target must lie on the carpet: the 9000 x 6000 mm
//! field plus its 700 mm border ([`FIELD_LIMIT_X_MM`], [`FIELD_LIMIT_Y_MM`]), where a robot may
//! still walk.

use interfaces::msg::command::{Command, Game};
use interfaces::msg::nao::{FieldPoint, NaoBody, NaoHead, NaoStrategy};
use serde::Deserialize;

/// The largest request the panel reads (bytes of JSON text); larger ones are refused unread.
pub const MAX_MESSAGE_BYTES: usize = 64 * 1024;
/// Half the field's length (goal line to centre), mm.
pub const FIELD_HALF_LENGTH_MM: f32 = 4500.0;
/// Half the field's width (touch line to centre), mm.
pub const FIELD_HALF_WIDTH_MM: f32 = 3000.0;
/// The carpet's border outside the lines, mm.
pub const FIELD_BORDER_MM: f32 = 700.0;
/// A target's largest |x| (field plus border), mm.
pub const FIELD_LIMIT_X_MM: f32 = FIELD_HALF_LENGTH_MM + FIELD_BORDER_MM;
/// A target's largest |y| (field plus border), mm.
pub const FIELD_LIMIT_Y_MM: f32 = FIELD_HALF_WIDTH_MM + FIELD_BORDER_MM;

/// Every Nao body command, in the robot's numbering order (`Keep` = 0).
pub const NAO_BODIES: [NaoBody; 11] = [
    NaoBody::Keep,
    NaoBody::GoToPosition,
    NaoBody::Dribble,
    NaoBody::GoToBallAndDribble,
    NaoBody::Kick,
    NaoBody::Spazza,
    NaoBody::Pass,
    NaoBody::AskForTheBall,
    NaoBody::Turn,
    NaoBody::SearchTheBall,
    NaoBody::Stop,
];
/// Every Nao head command, in the robot's numbering order (`Keep` = 0).
pub const NAO_HEADS: [NaoHead; 6] = [
    NaoHead::Keep,
    NaoHead::LookAtTheBall,
    NaoHead::LookForward,
    NaoHead::LookLeft,
    NaoHead::LookRight,
    NaoHead::Scan,
];
/// Every Nao strategy.
pub const NAO_STRATEGIES: [NaoStrategy; 2] = [NaoStrategy::Default, NaoStrategy::Passages];

/// A request that passed every check.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Request {
    /// A game command (never Yes/No: those become [`Request::Answer`]). `target` is set exactly
    /// for the coach's GoToPosition and Turn.
    Game {
        game: Game,
        command: Command,
        target: Option<FieldPoint>,
    },
    /// A raw Nao command: at least one of body and head is not `Keep`; `target` is set exactly
    /// when the body needs one.
    Nao {
        body: NaoBody,
        head: NaoHead,
        target: Option<FieldPoint>,
    },
    /// Use this strategy from the next Nao command on.
    Strategy(NaoStrategy),
    /// Yes (`true`) or no to the dialog's question.
    Answer(bool),
    /// The talk key is held (`true`) or came up.
    Talk(bool),
}

/// Why a request was refused. The message is shown on the page as it is.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RequestError {
    #[error("message too large: {bytes} bytes (at most {max})", max = MAX_MESSAGE_BYTES)]
    TooLarge { bytes: usize },
    #[error("binary messages are not accepted: send JSON text")]
    Binary,
    #[error("malformed message: {0}")]
    Malformed(String),
    #[error("unknown request type {0:?} (expected command, nao, strategy, answer or talk)")]
    UnknownType(String),
    #[error("missing field {0:?}")]
    MissingField(&'static str),
    #[error("unknown game {0:?} (expected touch or coach)")]
    UnknownGame(String),
    #[error("unknown command {0:?}")]
    UnknownCommand(String),
    #[error("{command:?} is not a command of the {game} game")]
    WrongGame {
        command: Command,
        game: &'static str,
    },
    #[error("unknown {what} {name:?}")]
    UnknownName { what: &'static str, name: String },
    #[error("{0} needs a target: click a point of the field")]
    MissingTarget(&'static str),
    #[error("{0} takes no target")]
    UnexpectedTarget(&'static str),
    #[error("target is not a finite number")]
    NonFiniteTarget,
    #[error(
        "target ({x_mm:.0}, {y_mm:.0}) mm is outside the field (|x| <= {lx:.0}, |y| <= {ly:.0} mm with the border)",
        lx = FIELD_LIMIT_X_MM,
        ly = FIELD_LIMIT_Y_MM
    )]
    TargetOutsideField { x_mm: f32, y_mm: f32 },
    #[error("an empty command: give a body or a head command")]
    Empty,
}

impl RequestError {
    /// Short stable name, for the diagnostics counter `rejected/<name>`.
    pub fn name(&self) -> &'static str {
        match self {
            RequestError::TooLarge { .. } => "too_large",
            RequestError::Binary => "binary",
            RequestError::Malformed(_) => "malformed",
            RequestError::UnknownType(_) => "unknown_type",
            RequestError::MissingField(_) => "missing_field",
            RequestError::UnknownGame(_) => "unknown_game",
            RequestError::UnknownCommand(_) => "unknown_command",
            RequestError::WrongGame { .. } => "wrong_game",
            RequestError::UnknownName { .. } => "unknown_name",
            RequestError::MissingTarget(_) => "missing_target",
            RequestError::UnexpectedTarget(_) => "unexpected_target",
            RequestError::NonFiniteTarget => "non_finite_target",
            RequestError::TargetOutsideField { .. } => "target_outside_field",
            RequestError::Empty => "empty",
        }
    }
}

/// The wire shape, before the checks. Numbers arrive as f64 so that 1e300 is caught as "outside
/// the field" rather than as a parse error.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct Raw {
    #[serde(rename = "type")]
    kind: String,
    #[serde(default)]
    id: u64,
    game: Option<String>,
    command: Option<String>,
    body: Option<String>,
    head: Option<String>,
    strategy: Option<String>,
    target: Option<RawTarget>,
    yes: Option<bool>,
    held: Option<bool>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTarget {
    x_mm: f64,
    y_mm: f64,
}

/// The `id` of a request, if the text is a JSON object with a numeric `id` (so a refusal can
/// still be matched to its button); 0 otherwise.
pub fn request_id(text: &str) -> u64 {
    if text.len() > MAX_MESSAGE_BYTES {
        return 0;
    }
    serde_json::from_str::<serde_json::Value>(text)
        .ok()
        .and_then(|v| v.get("id").and_then(serde_json::Value::as_u64))
        .unwrap_or(0)
}

/// A short description of a request for the history, even of one that fails the checks
/// (`GoToPosition (5390, 8) mm`); "(unreadable request)" when it is not a JSON object.
pub fn describe(text: &str) -> String {
    if text.len() > MAX_MESSAGE_BYTES {
        return "(unreadable request)".into();
    }
    let Ok(serde_json::Value::Object(m)) = serde_json::from_str::<serde_json::Value>(text) else {
        return "(unreadable request)".into();
    };
    let s = |k: &str| m.get(k).and_then(serde_json::Value::as_str);
    let mut label: String = ["command", "body", "head", "strategy", "type"]
        .iter()
        .find_map(|k| s(k))
        .unwrap_or("(request)")
        .chars()
        .take(40)
        .collect();
    if let Some(t) = m.get("target") {
        let n = |k: &str| t.get(k).and_then(serde_json::Value::as_f64);
        if let (Some(x), Some(y)) = (n("x_mm"), n("y_mm")) {
            label.push_str(&format!(" ({x:.0}, {y:.0}) mm"));
        }
    }
    label
}

/// Check one request: see the module doc for the rules.
pub fn parse_request(text: &str) -> Result<(u64, Request), RequestError> {
    if text.len() > MAX_MESSAGE_BYTES {
        return Err(RequestError::TooLarge { bytes: text.len() });
    }
    let raw: Raw =
        serde_json::from_str(text).map_err(|e| RequestError::Malformed(e.to_string()))?;
    let id = raw.id;
    let target = raw.target.as_ref().map(check_target).transpose()?;
    let request = match raw.kind.as_str() {
        "command" => {
            let game_name = raw
                .game
                .as_deref()
                .ok_or(RequestError::MissingField("game"))?;
            let game = Game::from_name(game_name)
                .ok_or_else(|| RequestError::UnknownGame(game_name.to_string()))?;
            let name = raw
                .command
                .as_deref()
                .ok_or(RequestError::MissingField("command"))?;
            let command = command_by_name(name)
                .ok_or_else(|| RequestError::UnknownCommand(name.to_string()))?;
            if !command.in_game(game) {
                return Err(RequestError::WrongGame {
                    command,
                    game: game.name(),
                });
            }
            if command.is_answer() {
                if target.is_some() {
                    return Err(RequestError::UnexpectedTarget(command_label(command)));
                }
                Request::Answer(command == Command::Yes)
            } else {
                let needs = game == Game::Coach && command_needs_target(command);
                Request::Game {
                    game,
                    command,
                    target: check_target_presence(command_label(command), needs, target)?,
                }
            }
        }
        "nao" => {
            let body = match raw.body.as_deref() {
                None => NaoBody::Keep,
                Some(n) => name_of(&NAO_BODIES, n).ok_or_else(|| RequestError::UnknownName {
                    what: "body command",
                    name: n.to_string(),
                })?,
            };
            let head = match raw.head.as_deref() {
                None => NaoHead::Keep,
                Some(n) => name_of(&NAO_HEADS, n).ok_or_else(|| RequestError::UnknownName {
                    what: "head command",
                    name: n.to_string(),
                })?,
            };
            if body == NaoBody::Keep && head == NaoHead::Keep {
                return Err(RequestError::Empty);
            }
            let label = body_label(body);
            Request::Nao {
                body,
                head,
                target: check_target_presence(label, body_needs_target(body), target)?,
            }
        }
        "strategy" => {
            let n = raw
                .strategy
                .as_deref()
                .ok_or(RequestError::MissingField("strategy"))?;
            let s = name_of(&NAO_STRATEGIES, n).ok_or_else(|| RequestError::UnknownName {
                what: "strategy",
                name: n.to_string(),
            })?;
            if target.is_some() {
                return Err(RequestError::UnexpectedTarget("a strategy"));
            }
            Request::Strategy(s)
        }
        "answer" => {
            let yes = raw.yes.ok_or(RequestError::MissingField("yes"))?;
            if target.is_some() {
                return Err(RequestError::UnexpectedTarget("an answer"));
            }
            Request::Answer(yes)
        }
        "talk" => {
            let held = raw.held.ok_or(RequestError::MissingField("held"))?;
            if target.is_some() {
                return Err(RequestError::UnexpectedTarget("the talk key"));
            }
            Request::Talk(held)
        }
        other => return Err(RequestError::UnknownType(other.to_string())),
    };
    Ok((id, request))
}

fn check_target(t: &RawTarget) -> Result<FieldPoint, RequestError> {
    if !t.x_mm.is_finite() || !t.y_mm.is_finite() {
        return Err(RequestError::NonFiniteTarget);
    }
    if t.x_mm.abs() > f64::from(FIELD_LIMIT_X_MM) || t.y_mm.abs() > f64::from(FIELD_LIMIT_Y_MM) {
        return Err(RequestError::TargetOutsideField {
            x_mm: t.x_mm as f32,
            y_mm: t.y_mm as f32,
        });
    }
    Ok(FieldPoint {
        x_mm: t.x_mm as f32,
        y_mm: t.y_mm as f32,
    })
}

fn check_target_presence(
    label: &'static str,
    needs: bool,
    target: Option<FieldPoint>,
) -> Result<Option<FieldPoint>, RequestError> {
    match (needs, target) {
        (true, None) => Err(RequestError::MissingTarget(label)),
        (false, Some(_)) => Err(RequestError::UnexpectedTarget(label)),
        (_, t) => Ok(t),
    }
}

/// The [`Command`] whose variant name is `name` (`"GoToPosition"`), `None` for `"None"` too.
pub fn command_by_name(name: &str) -> Option<Command> {
    Command::ALL.into_iter().find(|c| format!("{c:?}") == name)
}

fn name_of<T: std::fmt::Debug + Copy>(all: &[T], name: &str) -> Option<T> {
    all.iter().copied().find(|v| format!("{v:?}") == name)
}

/// Whether the coach's `command` needs a field target (GoToPosition, Turn).
pub fn command_needs_target(command: Command) -> bool {
    matches!(command, Command::GoToPosition | Command::Turn)
}

/// Whether a Nao body command needs a field target.
pub fn body_needs_target(body: NaoBody) -> bool {
    matches!(body, NaoBody::GoToPosition | NaoBody::Turn)
}

/// The Nao command a coach game command becomes; `None` for commands the Nao does not take
/// (Yes, No, and the touch game's). Each sets either the body or the head.
pub fn nao_of_command(command: Command) -> Option<(NaoBody, NaoHead)> {
    use Command as C;
    let body = |b| Some((b, NaoHead::Keep));
    let head = |h| Some((NaoBody::Keep, h));
    match command {
        C::Stop => body(NaoBody::Stop),
        C::GoToBallAndDribble => body(NaoBody::GoToBallAndDribble),
        C::Pass => body(NaoBody::Pass),
        C::Kick => body(NaoBody::Kick),
        C::ClearBall => body(NaoBody::Spazza),
        C::GoToPosition => body(NaoBody::GoToPosition),
        C::SearchBall => body(NaoBody::SearchTheBall),
        C::Turn => body(NaoBody::Turn),
        C::AskForBall => body(NaoBody::AskForTheBall),
        C::LookLeft => head(NaoHead::LookLeft),
        C::LookRight => head(NaoHead::LookRight),
        C::LookAtBall => head(NaoHead::LookAtTheBall),
        _ => None,
    }
}

/// A static label for a command (its variant name).
pub fn command_label(command: Command) -> &'static str {
    use Command as C;
    match command {
        C::None => "None",
        C::Greet => "Greet",
        C::Play => "Play",
        C::TrackBall => "TrackBall",
        C::ScanBall => "ScanBall",
        C::TouchBall => "TouchBall",
        C::YouTouchedIt => "YouTouchedIt",
        C::Quit => "Quit",
        C::Stop => "Stop",
        C::Yes => "Yes",
        C::No => "No",
        C::GoToBallAndDribble => "GoToBallAndDribble",
        C::Pass => "Pass",
        C::Kick => "Kick",
        C::ClearBall => "ClearBall",
        C::LookLeft => "LookLeft",
        C::LookRight => "LookRight",
        C::LookAtBall => "LookAtBall",
        C::GoToPosition => "GoToPosition",
        C::SearchBall => "SearchBall",
        C::Turn => "Turn",
        C::AskForBall => "AskForBall",
    }
}

/// A static label for a body command (its variant name).
pub fn body_label(body: NaoBody) -> &'static str {
    match body {
        NaoBody::Keep => "Keep",
        NaoBody::GoToPosition => "GoToPosition",
        NaoBody::Dribble => "Dribble",
        NaoBody::GoToBallAndDribble => "GoToBallAndDribble",
        NaoBody::Kick => "Kick",
        NaoBody::Spazza => "Spazza",
        NaoBody::Pass => "Pass",
        NaoBody::AskForTheBall => "AskForTheBall",
        NaoBody::Turn => "Turn",
        NaoBody::SearchTheBall => "SearchTheBall",
        NaoBody::Stop => "Stop",
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn ok(text: &str) -> Request {
        parse_request(text).unwrap().1
    }
    fn err(text: &str) -> RequestError {
        parse_request(text).unwrap_err()
    }

    #[test]
    fn every_coach_command_parses_and_maps_to_one_nao_command() {
        for c in Command::of_game(Game::Coach) {
            let target = if command_needs_target(c) {
                r#","target":{"x_mm":100,"y_mm":-200}"#
            } else {
                ""
            };
            let text =
                format!(r#"{{"type":"command","id":3,"game":"coach","command":"{c:?}"{target}}}"#);
            let (id, r) = parse_request(&text).unwrap();
            assert_eq!(id, 3);
            match r {
                Request::Answer(yes) => assert_eq!(yes, c == Command::Yes, "{c:?}"),
                Request::Game {
                    command, target, ..
                } => {
                    assert_eq!(command, c);
                    assert_eq!(target.is_some(), command_needs_target(c));
                    let (b, h) = nao_of_command(c).expect("every coach action maps");
                    assert!((b == NaoBody::Keep) != (h == NaoHead::Keep), "{c:?}");
                }
                other => panic!("{c:?}: {other:?}"),
            }
            assert_eq!(command_label(c), format!("{c:?}"));
        }
        for c in Command::of_game(Game::Touch) {
            let text = format!(r#"{{"type":"command","game":"touch","command":"{c:?}"}}"#);
            assert!(parse_request(&text).is_ok(), "{c:?}");
        }
        for b in NAO_BODIES {
            assert_eq!(body_label(b), format!("{b:?}"));
        }
    }

    #[test]
    fn go_to_position_carries_its_target() {
        assert_eq!(
            ok(
                r#"{"type":"command","game":"coach","command":"GoToPosition","target":{"x_mm":-1500,"y_mm":1000}}"#
            ),
            Request::Game {
                game: Game::Coach,
                command: Command::GoToPosition,
                target: Some(FieldPoint {
                    x_mm: -1500.0,
                    y_mm: 1000.0
                })
            }
        );
        // On the border is still on the carpet.
        assert!(matches!(
            ok(r#"{"type":"nao","body":"Turn","target":{"x_mm":5200,"y_mm":-3700}}"#),
            Request::Nao {
                body: NaoBody::Turn,
                ..
            }
        ));
    }

    #[test]
    fn targets_off_the_carpet_missing_or_not_numbers_are_refused() {
        let e = err(
            r#"{"type":"command","game":"coach","command":"GoToPosition","target":{"x_mm":5201,"y_mm":0}}"#,
        );
        assert!(matches!(e, RequestError::TargetOutsideField { .. }), "{e}");
        assert!(e.to_string().contains("outside the field"), "{e}");
        let e = err(
            r#"{"type":"command","game":"coach","command":"GoToPosition","target":{"x_mm":0,"y_mm":-1e300}}"#,
        );
        assert_eq!(e.name(), "target_outside_field");
        assert_eq!(
            err(r#"{"type":"command","game":"coach","command":"GoToPosition"}"#),
            RequestError::MissingTarget("GoToPosition")
        );
        assert_eq!(
            err(
                r#"{"type":"command","game":"coach","command":"Kick","target":{"x_mm":0,"y_mm":0}}"#
            ),
            RequestError::UnexpectedTarget("Kick")
        );
        assert_eq!(
            err(r#"{"type":"command","game":"coach","command":"Turn","target":{"x_mm":"a","y_mm":0}}"#)
                .name(),
            "malformed"
        );
        assert_eq!(
            err(r#"{"type":"command","game":"coach","command":"Turn","target":{"x_mm":1}}"#).name(),
            "malformed"
        );
    }

    #[test]
    fn unknown_names_other_games_and_garbage_are_refused_with_reasons() {
        assert_eq!(
            err(r#"{"type":"command","game":"coach","command":"Fly"}"#),
            RequestError::UnknownCommand("Fly".into())
        );
        assert_eq!(
            err(r#"{"type":"command","game":"coach","command":"None"}"#),
            RequestError::UnknownCommand("None".into())
        );
        assert_eq!(
            err(r#"{"type":"command","game":"coach","command":"TouchBall"}"#).name(),
            "wrong_game"
        );
        assert_eq!(
            err(r#"{"type":"command","game":"chess","command":"Kick"}"#).name(),
            "unknown_game"
        );
        assert_eq!(
            err(r#"{"type":"command","command":"Kick"}"#).name(),
            "missing_field"
        );
        assert_eq!(err(r#"{"type":"launch_missiles"}"#).name(), "unknown_type");
        assert_eq!(err(r#"{"type":"nao","body":"Fly"}"#).name(), "unknown_name");
        assert_eq!(err(r#"{"type":"nao","head":"Keep"}"#), RequestError::Empty);
        assert_eq!(
            err(r#"{"type":"strategy","strategy":"Tiki"}"#).name(),
            "unknown_name"
        );
        assert_eq!(err(r#"{"type":"answer"}"#).name(), "missing_field");
        for garbage in [
            "",
            "{",
            "null",
            "[1,2]",
            "\"kick\"",
            "{\"type\":1}",
            "{\"id\":1}",
        ] {
            assert_eq!(err(garbage).name(), "malformed", "{garbage:?}");
        }
        // Extra fields are not silently ignored.
        assert_eq!(
            err(r#"{"type":"answer","yes":true,"sudo":true}"#).name(),
            "malformed"
        );
        let huge = format!(
            r#"{{"type":"answer","yes":true,"pad":"{}"}}"#,
            "x".repeat(70_000)
        );
        assert_eq!(err(&huge).name(), "too_large");
        assert_eq!(request_id(&huge), 0);
        assert_eq!(request_id(r#"{"id":42,"type":"bogus"}"#), 42);
        assert_eq!(describe(&huge), "(unreadable request)");
        assert_eq!(describe("{"), "(unreadable request)");
        assert_eq!(
            describe(
                r#"{"type":"command","command":"GoToPosition","target":{"x_mm":5390.4,"y_mm":8}}"#
            ),
            "GoToPosition (5390, 8) mm"
        );
        assert_eq!(describe(r#"{"type":"launch"}"#), "launch");
    }

    #[test]
    fn answers_strategies_and_raw_nao_commands() {
        assert_eq!(
            ok(r#"{"type":"answer","yes":false}"#),
            Request::Answer(false)
        );
        assert_eq!(
            ok(r#"{"type":"command","game":"touch","command":"Yes"}"#),
            Request::Answer(true)
        );
        assert_eq!(
            ok(r#"{"type":"strategy","strategy":"Passages"}"#),
            Request::Strategy(NaoStrategy::Passages)
        );
        assert_eq!(
            ok(r#"{"type":"nao","head":"Scan"}"#),
            Request::Nao {
                body: NaoBody::Keep,
                head: NaoHead::Scan,
                target: None
            }
        );
        assert_eq!(
            err(r#"{"type":"nao","body":"GoToPosition"}"#),
            RequestError::MissingTarget("GoToPosition")
        );
    }

    #[test]
    fn the_talk_key_goes_down_and_up_and_nothing_else() {
        assert_eq!(
            ok(r#"{"type":"talk","id":4,"held":true}"#),
            Request::Talk(true)
        );
        assert_eq!(ok(r#"{"type":"talk","held":false}"#), Request::Talk(false));
        assert_eq!(
            err(r#"{"type":"talk"}"#),
            RequestError::MissingField("held")
        );
        assert_eq!(err(r#"{"type":"talk","held":"yes"}"#).name(), "malformed");
        assert_eq!(
            err(r#"{"type":"talk","held":true,"target":{"x_mm":0,"y_mm":0}}"#),
            RequestError::UnexpectedTarget("the talk key")
        );
    }
}
