//! The buttons of the page and their keyboard shortcuts, built from the command catalog of
//! `interfaces::msg::command` and the Nao commands of `interfaces::msg::nao`, so that every command
//! has a button and the page never lists a command the server would refuse.
//!
//! Shortcuts are `KeyboardEvent.key` values, active in the view they belong to (the coach has
//! 90 s and their back to the field: one key per frequent command).

use crate::protocol::{
    NAO_BODIES, NAO_HEADS, NAO_STRATEGIES, body_needs_target, command_needs_target,
};
use interfaces::msg::command::{Command, Game};
use interfaces::msg::nao::{NaoBody, NaoHead};
use serde_json::{Value, json};

/// The coach view's shortcut for a coach game command.
pub fn coach_shortcut(c: Command) -> Option<&'static str> {
    use Command as C;
    Some(match c {
        C::GoToPosition => "g",
        C::Turn => "t",
        C::GoToBallAndDribble => "d",
        C::Kick => "k",
        C::Pass => "p",
        C::ClearBall => "c",
        C::SearchBall => "s",
        C::AskForBall => "a",
        C::Stop => " ",
        C::LookLeft => "ArrowLeft",
        C::LookRight => "ArrowRight",
        C::LookAtBall => "b",
        C::Yes => "y",
        C::No => "n",
        _ => return None,
    })
}

/// The touch view's shortcut for a touch game command.
pub fn touch_shortcut(c: Command) -> Option<&'static str> {
    use Command as C;
    Some(match c {
        C::Greet => "h",
        C::Play => "p",
        C::TrackBall => "f",
        C::ScanBall => "s",
        C::TouchBall => "t",
        C::YouTouchedIt => "w",
        C::Quit => "q",
        C::Stop => " ",
        C::Yes => "y",
        C::No => "n",
        _ => return None,
    })
}

/// The coach view's shortcut for the Nao's own body and head commands.
fn nao_shortcut(body: NaoBody, head: NaoHead) -> Option<&'static str> {
    match (body, head) {
        (NaoBody::Dribble, _) => Some("r"),
        (_, NaoHead::LookForward) => Some("ArrowUp"),
        (_, NaoHead::Scan) => Some("ArrowDown"),
        _ => None,
    }
}

/// The talk key, held while speaking to a recognizer in push-to-talk mode, in both views.
pub const TALK_SHORTCUT: &str = "v";

/// The catalog the page builds its buttons from (sent in the `hello` message).
pub fn catalog_json() -> Value {
    let game = |g: Game, shortcut: fn(Command) -> Option<&'static str>| -> Vec<Value> {
        Command::of_game(g)
            .map(|c| {
                json!({
                    "name": format!("{c:?}"),
                    "phrase": c.phrase(),
                    "answer": c.is_answer(),
                    "needs_target": g == Game::Coach && command_needs_target(c),
                    "shortcut": shortcut(c),
                })
            })
            .collect()
    };
    // The Nao's own commands that no spoken command covers get their own buttons.
    let covered_bodies: Vec<NaoBody> = Command::of_game(Game::Coach)
        .filter_map(crate::protocol::nao_of_command)
        .map(|(b, _)| b)
        .collect();
    let covered_heads: Vec<NaoHead> = Command::of_game(Game::Coach)
        .filter_map(crate::protocol::nao_of_command)
        .map(|(_, h)| h)
        .collect();
    let bodies: Vec<Value> = NAO_BODIES
        .into_iter()
        .filter(|b| *b != NaoBody::Keep && !covered_bodies.contains(b))
        .map(|b| {
            json!({
                "name": format!("{b:?}"),
                "needs_target": body_needs_target(b),
                "shortcut": nao_shortcut(b, NaoHead::Keep),
            })
        })
        .collect();
    let heads: Vec<Value> = NAO_HEADS
        .into_iter()
        .filter(|h| *h != NaoHead::Keep && !covered_heads.contains(h))
        .map(|h| json!({ "name": format!("{h:?}"), "shortcut": nao_shortcut(NaoBody::Keep, h) }))
        .collect();
    let strategies: Vec<String> = NAO_STRATEGIES.iter().map(|s| format!("{s:?}")).collect();
    json!({
        "coach": game(Game::Coach, coach_shortcut),
        "touch": game(Game::Touch, touch_shortcut),
        "nao_bodies": bodies,
        "nao_heads": heads,
        "strategies": strategies,
        "talk": { "shortcut": TALK_SHORTCUT },
        "field": {
            "half_length_mm": crate::protocol::FIELD_HALF_LENGTH_MM,
            "half_width_mm": crate::protocol::FIELD_HALF_WIDTH_MM,
            "border_mm": crate::protocol::FIELD_BORDER_MM,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    #[test]
    fn every_command_has_a_button_and_shortcuts_do_not_clash_within_a_view() {
        let cat = catalog_json();
        let names = |k: &str| -> Vec<String> {
            cat[k]
                .as_array()
                .map(|a| {
                    a.iter()
                        .filter_map(|v| v["name"].as_str().map(String::from))
                        .collect()
                })
                .unwrap_or_default()
        };
        assert_eq!(names("coach").len(), Command::of_game(Game::Coach).count());
        assert_eq!(names("touch").len(), Command::of_game(Game::Touch).count());
        // Every body and head of the Nao is reachable: by a coach command or its own button.
        let mut bodies: HashSet<String> = names("nao_bodies").into_iter().collect();
        let mut heads: HashSet<String> = names("nao_heads").into_iter().collect();
        for c in Command::of_game(Game::Coach) {
            if let Some((b, h)) = crate::protocol::nao_of_command(c) {
                bodies.insert(format!("{b:?}"));
                heads.insert(format!("{h:?}"));
            }
        }
        for b in NAO_BODIES {
            assert!(
                bodies.contains(&format!("{b:?}")) || b == NaoBody::Keep,
                "{b:?}"
            );
        }
        for h in NAO_HEADS {
            assert!(
                heads.contains(&format!("{h:?}")) || h == NaoHead::Keep,
                "{h:?}"
            );
        }
        assert_eq!(cat["strategies"].as_array().map(Vec::len), Some(2));
        for view in [&["coach", "nao_bodies", "nao_heads"][..], &["touch"][..]] {
            let mut seen = HashSet::from([TALK_SHORTCUT.to_string()]);
            for k in view {
                for v in cat[*k].as_array().into_iter().flatten() {
                    if let Some(s) = v["shortcut"].as_str() {
                        assert!(seen.insert(s.to_string()), "shortcut {s:?} used twice");
                    }
                }
            }
        }
    }
}
