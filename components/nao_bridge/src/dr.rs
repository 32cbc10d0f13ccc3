//! The coach game's world in the deep representation: the bridge mirrors its fused team model and
//! the GameController's state into the DR's coach scene (`deep_representation --scene coach`).
//!
//! - **Nodes** (already in the scene, children of `field`): our robots `nao_<player number>`
//!   (`nao_1` the autonomous teammate, `nao_2` the controlled robot) and `ball`. Their free poses
//!   are set from `nao/world_model`: field frame, millimetres turned into metres, heading as a
//!   rotation about z; the ball at its radius above the carpet (`BALL_CENTRE_Z_M`).
//! - **Attributes**: `nao_<n>.fallen` (bool), `ball.seen_age_s` and `ball.confidence` (float);
//!   on `field`: `game_state` (`INITIAL`..`FINISHED`), `secs_remaining`, `score_ours`,
//!   `score_theirs`, `set_play` (int), `our_penalised` (the penalised player numbers, text).
//! - The ball is written only once it has been seen (`ball_known`); robots only once they have
//!   reported. Obstacles are not mirrored (they come and go; they stay on `nao/world_model`).
//!
//! The mapping is a pure function ([`update_request`]); the component sends it with `dr/update`
//! at most [`MIRROR_PERIOD`] apart, one request in flight, counting what fails.

use interfaces::msg::dr::{AttrValue, Attribute, PoseUpdate, Transform, UpdateRequest};
use interfaces::msg::nao::{GameState, NaoWorldModel};
use std::time::Duration;

/// How often the DR is updated at most.
pub const MIRROR_PERIOD: Duration = Duration::from_millis(200);
/// Height of the ball's centre above the carpet (m): an SPL ball has a 100 mm diameter.
pub const BALL_CENTRE_Z_M: f64 = 0.05;

fn state_name(s: u8) -> &'static str {
    match s {
        GameState::INITIAL => "INITIAL",
        GameState::READY => "READY",
        GameState::SET => "SET",
        GameState::PLAYING => "PLAYING",
        GameState::FINISHED => "FINISHED",
        5 => "STANDBY",
        _ => "UNKNOWN",
    }
}

fn planar(x_mm: f32, y_mm: f32, z_m: f64, theta_rad: f32) -> Transform {
    let half = theta_rad as f64 / 2.0;
    Transform {
        translation_m: [x_mm as f64 / 1000.0, y_mm as f64 / 1000.0, z_m],
        rotation_xyzw: [0.0, 0.0, half.sin(), half.cos()],
    }
}

fn attr(node: &str, key: &str, value: AttrValue) -> Attribute {
    Attribute {
        node: node.into(),
        key: key.into(),
        value,
    }
}

/// The DR update for the latest team model and game state (see the module docs). Values that
/// are not finite are left out.
pub fn update_request(world: &NaoWorldModel, game: Option<&GameState>) -> UpdateRequest {
    let mut req = UpdateRequest::default();
    for r in &world.robots {
        let p = r.pose;
        if !(p.x_mm.is_finite() && p.y_mm.is_finite() && p.theta_rad.is_finite()) {
            continue;
        }
        let node = format!("nao_{}", r.player_number);
        req.poses.push(PoseUpdate {
            node: node.clone(),
            pose: planar(p.x_mm, p.y_mm, 0.0, p.theta_rad),
        });
        req.attributes
            .push(attr(&node, "fallen", AttrValue::Bool(r.fallen)));
    }
    if world.ball_known && world.ball.x_mm.is_finite() && world.ball.y_mm.is_finite() {
        req.poses.push(PoseUpdate {
            node: "ball".into(),
            pose: planar(world.ball.x_mm, world.ball.y_mm, BALL_CENTRE_Z_M, 0.0),
        });
        if world.ball_age_s.is_finite() {
            req.attributes.push(attr(
                "ball",
                "seen_age_s",
                AttrValue::Float(world.ball_age_s),
            ));
        }
        if world.ball_confidence.is_finite() {
            req.attributes.push(attr(
                "ball",
                "confidence",
                AttrValue::Float(world.ball_confidence),
            ));
        }
    }
    if let Some(g) = game {
        let f = |k: &str, v: AttrValue| attr("field", k, v);
        req.attributes
            .push(f("game_state", AttrValue::Text(state_name(g.state).into())));
        req.attributes
            .push(f("secs_remaining", AttrValue::Int(g.secs_remaining as i64)));
        req.attributes
            .push(f("set_play", AttrValue::Int(g.set_play as i64)));
        if g.our_team_found {
            req.attributes
                .push(f("score_ours", AttrValue::Int(g.our_team.score as i64)));
            req.attributes
                .push(f("score_theirs", AttrValue::Int(g.opponent.score as i64)));
            let penalised: Vec<String> = g
                .our_team
                .players
                .iter()
                .enumerate()
                .filter(|(_, p)| p.penalty != 0)
                .map(|(i, _)| (i + 1).to_string())
                .collect();
            req.attributes
                .push(f("our_penalised", AttrValue::Text(penalised.join(","))));
        }
    }
    req
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::msg::nao::{FieldPoint, FieldPose, PlayerPenalty, TeamRobot, TeamStatus};

    fn world() -> NaoWorldModel {
        NaoWorldModel {
            robots: vec![
                TeamRobot {
                    player_number: 2,
                    pose: FieldPose {
                        x_mm: -1500.0,
                        y_mm: 500.0,
                        theta_rad: std::f32::consts::FRAC_PI_2,
                    },
                    fallen: true,
                    ..Default::default()
                },
                TeamRobot {
                    player_number: 1,
                    pose: FieldPose {
                        x_mm: f32::NAN,
                        ..Default::default()
                    },
                    ..Default::default()
                },
            ],
            ball_known: true,
            ball: FieldPoint {
                x_mm: 250.0,
                y_mm: -100.0,
            },
            ball_age_s: 0.4,
            ball_confidence: 0.9,
            ..Default::default()
        }
    }

    #[test]
    fn robots_and_ball_become_poses_in_metres_and_bad_values_are_left_out() {
        let r = update_request(&world(), None);
        let nao2 = r.poses.iter().find(|p| p.node == "nao_2").unwrap();
        assert_eq!(nao2.pose.translation_m, [-1.5, 0.5, 0.0]);
        let q = nao2.pose.rotation_xyzw;
        assert!((q[2] - (0.25f64 * std::f64::consts::PI).sin()).abs() < 1e-6);
        assert!((q[3] - (0.25f64 * std::f64::consts::PI).cos()).abs() < 1e-6);
        assert!(
            !r.poses.iter().any(|p| p.node == "nao_1"),
            "a NaN pose is not written"
        );
        let ball = r.poses.iter().find(|p| p.node == "ball").unwrap();
        assert_eq!(ball.pose.translation_m, [0.25, -0.1, BALL_CENTRE_Z_M]);
        assert!(
            r.attributes.iter().any(|a| a.node == "nao_2"
                && a.key == "fallen"
                && a.value == AttrValue::Bool(true))
        );
        // No game state yet: nothing on the field node.
        assert!(!r.attributes.iter().any(|a| a.node == "field"));
        // An unseen ball is not written.
        let mut w = world();
        w.ball_known = false;
        assert!(
            !update_request(&w, None)
                .poses
                .iter()
                .any(|p| p.node == "ball")
        );
    }

    #[test]
    fn the_game_state_goes_on_the_field_node() {
        let g = GameState {
            state: GameState::PLAYING,
            secs_remaining: 73,
            our_team_found: true,
            our_team: TeamStatus {
                score: 2,
                players: vec![
                    PlayerPenalty::default(),
                    PlayerPenalty {
                        penalty: 5,
                        secs_till_unpenalised: 20,
                    },
                ],
                ..Default::default()
            },
            opponent: TeamStatus {
                score: 1,
                ..Default::default()
            },
            ..Default::default()
        };
        let r = update_request(&NaoWorldModel::default(), Some(&g));
        let get = |k: &str| {
            r.attributes
                .iter()
                .find(|a| a.node == "field" && a.key == k)
                .map(|a| a.value.clone())
        };
        assert_eq!(get("game_state"), Some(AttrValue::Text("PLAYING".into())));
        assert_eq!(get("secs_remaining"), Some(AttrValue::Int(73)));
        assert_eq!(get("score_ours"), Some(AttrValue::Int(2)));
        assert_eq!(get("score_theirs"), Some(AttrValue::Int(1)));
        assert_eq!(get("our_penalised"), Some(AttrValue::Text("2".into())));
    }
}
