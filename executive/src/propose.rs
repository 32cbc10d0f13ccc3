//! Structural changes of the deep representation pass through the Executive first (seed 001
//! §V: "for structural changes, such as the appearance of a new object, the Executive is notified
//! first and some comprobations are made"). This module is the check, with no bus: the facts it
//! needs about the DR are gathered by the caller (`executive/propose` in [`crate::component`]).
//!
//! Rules, in order (a refusal's `reason_code` in brackets):
//! 1. the change names a node (`invalid`);
//! 2. while a game runs, a protected node (the world, the robot's root, the ball: settings
//!    `[propose] protected`) is neither removed nor moved (`game_protected`);
//! 3. a node is not added under a name that exists (`duplicate_name`);
//! 4. while a game runs, a second object of a unique type (`[propose] unique_types`, the ball) is
//!    not added (`duplicate_object`); "exists" means a node named after the type exists.
//!
//! Everything else goes on to `dr/propose`, whose own integrity rules (links protected, parents
//! known, no cycles) still apply.

use interfaces::msg::dr::StructuralChange;

use crate::settings::ProposeSettings;

/// What the check needs to know about the world and the game.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Facts {
    /// A game is running (started, not finished).
    pub game_on: bool,
    /// A node named like the change's `name` exists.
    pub name_exists: bool,
    /// A node named after the change's `node_type` exists (a ball when adding a ball).
    pub type_present: bool,
}

/// Why a change is refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{code}: {reason}")]
pub struct Refusal {
    /// snake_case rule name (the reply's `reason_code`).
    pub code: &'static str,
    /// For people.
    pub reason: String,
}

fn refuse(code: &'static str, reason: String) -> Result<(), Refusal> {
    Err(Refusal { code, reason })
}

/// Whether the change may go on to the DR.
pub fn check(
    change: &StructuralChange,
    settings: &ProposeSettings,
    facts: &Facts,
) -> Result<(), Refusal> {
    let name = change.name().trim();
    if name.is_empty() {
        return refuse("invalid", "the change names no node".into());
    }
    let protected = settings.protected.iter().any(|p| p == name);
    match change {
        StructuralChange::RemoveNode { .. } | StructuralChange::Reparent { .. }
            if facts.game_on && protected =>
        {
            refuse(
                "game_protected",
                format!(
                    "`{name}` cannot be {} while a game is running",
                    if matches!(change, StructuralChange::RemoveNode { .. }) {
                        "removed"
                    } else {
                        "moved"
                    }
                ),
            )
        }
        StructuralChange::AddNode(_) if facts.name_exists => refuse(
            "duplicate_name",
            format!("a node called `{name}` already exists"),
        ),
        StructuralChange::AddNode(spec)
            if facts.game_on
                && facts.type_present
                && settings
                    .unique_types
                    .iter()
                    .any(|t| t.eq_ignore_ascii_case(&spec.node_type)) =>
        {
            refuse(
                "duplicate_object",
                format!(
                    "there is already a {} in the game; `{name}` would be a second one",
                    spec.node_type.to_lowercase()
                ),
            )
        }
        _ => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    use interfaces::msg::dr::{NodeSpec, Transform};

    fn add(name: &str, node_type: &str) -> StructuralChange {
        StructuralChange::AddNode(Box::new(NodeSpec {
            name: name.into(),
            node_type: node_type.into(),
            parent: "world".into(),
            ..Default::default()
        }))
    }

    fn remove(name: &str) -> StructuralChange {
        StructuralChange::RemoveNode { name: name.into() }
    }

    fn reparent(name: &str) -> StructuralChange {
        StructuralChange::Reparent {
            name: name.into(),
            new_parent: "world".into(),
            pose: Transform::default(),
        }
    }

    const ON: Facts = Facts {
        game_on: true,
        name_exists: false,
        type_present: false,
    };

    #[test]
    fn the_ball_and_the_robot_stay_during_a_game_and_not_after() {
        let s = ProposeSettings::default();
        for name in ["ball", "base_footprint", "world"] {
            for change in [remove(name), reparent(name)] {
                let e = check(&change, &s, &ON).unwrap_err();
                assert_eq!(e.code, "game_protected");
                assert!(e.reason.contains(name));
            }
        }
        let off = Facts {
            game_on: false,
            ..ON
        };
        assert!(check(&remove("ball"), &s, &off).is_ok());
        assert!(check(&remove("cup"), &s, &ON).is_ok());
    }

    #[test]
    fn duplicates_are_refused() {
        let s = ProposeSettings::default();
        let exists = Facts {
            name_exists: true,
            ..ON
        };
        let e = check(&add("cup", "object"), &s, &exists).unwrap_err();
        assert_eq!(e.code, "duplicate_name");
        let ball_there = Facts {
            type_present: true,
            ..ON
        };
        let e = check(&add("ball2", "Ball"), &s, &ball_there).unwrap_err();
        assert_eq!(e.code, "duplicate_object");
        assert!(check(&add("cup", "object"), &s, &ball_there).is_ok());
        assert!(check(&add("ball", "ball"), &s, &ON).is_ok());
        let e = check(&add(" ", "ball"), &s, &ON).unwrap_err();
        assert_eq!(e.code, "invalid");
    }
}
