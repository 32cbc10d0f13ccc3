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
//!   reported.
//! - **Obstacles** (the fusion's tracks: other robots, goalposts) come and go, so they are nodes
//!   added and removed by structural proposals ([`ObstacleMirror`]): a track becomes node
//!   `obstacle_<track id>` (type `object`, child of `field`, free pose at the carpet) once it is
//!   confirmed (`min_observations`), and is removed when the fusion drops it (unseen for the
//!   fusion's `obstacle_timeout_s`). Attributes: `obstacle_type` (text: `opponent`,
//!   `fallen_some_robot`, ... as [`spl::types::ObstacleKind::name`]), `seen_age_s` (float, s since any of
//!   our robots saw it), `last_seen_ns` (int, bus-clock time it was last seen) and
//!   `observations` (int). At most `max_changes_per_cycle` proposals go out per mirror cycle
//!   (removals first) and at most `max_nodes` obstacle nodes exist, so a flickering perception
//!   cannot flood the DR; a proposal the DR refuses (other than a duplicate name) is not retried
//!   for that track.
//!
//! The mappings are pure ([`update_request`], [`ObstacleMirror`]); the component sends them
//! (`dr/propose` or `executive/propose`, then `dr/update`) at most [`MIRROR_PERIOD`] apart, one
//! request in flight, counting what fails.

use interfaces::msg::dr::{
    AttrValue, Attribute, Edge, KeyValue, NodeSpec, PoseUpdate, StructuralChange, Transform,
    UpdateRequest,
};
use interfaces::msg::nao::{GameState, NaoWorldModel};
use spl::types::TrackedObstacle;
use std::collections::BTreeSet;
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

/// Tuning of [`ObstacleMirror`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObstacleMirrorConfig {
    /// Observations a track needs before it becomes a node (filters one-off false sightings).
    pub min_observations: u32,
    /// Structural proposals per mirror cycle at most.
    pub max_changes_per_cycle: usize,
    /// Obstacle nodes at most (an SPL field holds 10 robots and 4 goalposts).
    pub max_nodes: usize,
}

impl Default for ObstacleMirrorConfig {
    fn default() -> Self {
        Self {
            min_observations: 3,
            max_changes_per_cycle: 4,
            max_nodes: 16,
        }
    }
}

/// What became of a structural proposal.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ProposalOutcome {
    Accepted,
    /// Refused by a rule (`reason_code` of the reply).
    Refused(String),
    /// Not answered (no DR, time-out): tried again next cycle.
    Failed,
}

/// Keeps the fusion's obstacle tracks and the DR's obstacle nodes in step (see the module
/// docs). It only plans: the caller sends the changes, reports each outcome with
/// [`ObstacleMirror::outcome`], then adds [`ObstacleMirror::add_updates`] to its `dr/update`.
#[derive(Debug, Clone, Default)]
pub struct ObstacleMirror {
    config: ObstacleMirrorConfig,
    /// Track ids whose node exists in the DR.
    present: BTreeSet<u32>,
    /// Track ids whose addition was refused: not proposed again while the track lives.
    refused: BTreeSet<u32>,
}

/// The DR node name of obstacle track `id`.
pub fn obstacle_node(id: u32) -> String {
    format!("obstacle_{id}")
}

/// The track id of an obstacle node name, if it is one.
pub fn obstacle_id(node: &str) -> Option<u32> {
    node.strip_prefix("obstacle_")?.parse().ok()
}

impl ObstacleMirror {
    pub fn new(config: ObstacleMirrorConfig) -> Self {
        Self {
            config,
            ..Default::default()
        }
    }

    /// Track ids whose node exists in the DR, ascending.
    pub fn present(&self) -> impl Iterator<Item = u32> + '_ {
        self.present.iter().copied()
    }

    /// The structural changes due now for the current tracks: removals of nodes whose track is
    /// gone, then additions of confirmed tracks (oldest track first), at most
    /// `max_changes_per_cycle` in all.
    pub fn changes(&mut self, obstacles: &[TrackedObstacle]) -> Vec<StructuralChange> {
        let live: BTreeSet<u32> = obstacles.iter().map(|o| o.id).collect();
        self.refused.retain(|id| live.contains(id));
        let mut out: Vec<StructuralChange> = self
            .present
            .iter()
            .filter(|id| !live.contains(id))
            .map(|id| StructuralChange::RemoveNode {
                name: obstacle_node(*id),
            })
            .take(self.config.max_changes_per_cycle)
            .collect();
        let mut room = self
            .config
            .max_nodes
            .saturating_sub(self.present.len() - out.len());
        let mut candidates: Vec<&TrackedObstacle> = obstacles
            .iter()
            .filter(|o| {
                o.observations >= self.config.min_observations
                    && !self.present.contains(&o.id)
                    && !self.refused.contains(&o.id)
                    && point_is_finite(o)
            })
            .collect();
        candidates.sort_by_key(|o| o.id);
        for o in candidates {
            if out.len() >= self.config.max_changes_per_cycle || room == 0 {
                break;
            }
            room -= 1;
            out.push(StructuralChange::AddNode(Box::new(NodeSpec {
                name: obstacle_node(o.id),
                node_type: "object".into(),
                parent: "field".into(),
                edge: Edge::Free {
                    pose: planar(o.center.x_mm, o.center.y_mm, 0.0, 0.0),
                },
                attributes: vec![KeyValue {
                    key: "obstacle_type".into(),
                    value: AttrValue::Text(o.kind.name().into()),
                }],
                ..Default::default()
            })));
        }
        out
    }

    /// Records what became of a change from [`ObstacleMirror::changes`]. An addition refused as
    /// a duplicate name counts as present (the node is there, e.g. after a bridge restart); a
    /// removal refused because the node is unknown counts as done.
    pub fn outcome(&mut self, change: &StructuralChange, outcome: &ProposalOutcome) {
        let Some(id) = obstacle_id(change.name()) else {
            return;
        };
        match (change, outcome) {
            (StructuralChange::AddNode(_), ProposalOutcome::Accepted) => {
                self.present.insert(id);
            }
            (StructuralChange::AddNode(_), ProposalOutcome::Refused(code))
                if code == "duplicate_name" =>
            {
                self.present.insert(id);
            }
            (StructuralChange::AddNode(_), ProposalOutcome::Refused(_)) => {
                self.refused.insert(id);
            }
            (StructuralChange::RemoveNode { .. }, ProposalOutcome::Accepted) => {
                self.present.remove(&id);
            }
            (StructuralChange::RemoveNode { .. }, ProposalOutcome::Refused(code))
                if code == "unknown_node" =>
            {
                self.present.remove(&id);
            }
            _ => {}
        }
    }

    /// The DR lost its nodes (a `dr/update` naming them failed, the DR restarted): every
    /// confirmed track is proposed again.
    pub fn forget_nodes(&mut self) {
        self.present.clear();
        self.refused.clear();
    }

    /// Pose and attribute updates of the obstacle nodes that exist. `now_ns` is the bus-clock
    /// time of the model (its header stamp), for `last_seen_ns`.
    pub fn add_updates(&self, obstacles: &[TrackedObstacle], now_ns: i64, req: &mut UpdateRequest) {
        for o in obstacles
            .iter()
            .filter(|o| self.present.contains(&o.id) && point_is_finite(o))
        {
            let node = obstacle_node(o.id);
            req.poses.push(PoseUpdate {
                node: node.clone(),
                pose: planar(o.center.x_mm, o.center.y_mm, 0.0, 0.0),
            });
            req.attributes.push(attr(
                &node,
                "obstacle_type",
                AttrValue::Text(o.kind.name().into()),
            ));
            req.attributes.push(attr(
                &node,
                "observations",
                AttrValue::Int(i64::from(o.observations)),
            ));
            if o.age_s.is_finite() && o.age_s >= 0.0 {
                req.attributes
                    .push(attr(&node, "seen_age_s", AttrValue::Float(o.age_s)));
                let seen_ns = now_ns.saturating_sub((o.age_s * 1e9) as i64);
                req.attributes
                    .push(attr(&node, "last_seen_ns", AttrValue::Int(seen_ns)));
            }
        }
    }
}

fn point_is_finite(o: &TrackedObstacle) -> bool {
    o.center.x_mm.is_finite() && o.center.y_mm.is_finite()
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

    fn track(id: u32, observations: u32, age_s: f64) -> TrackedObstacle {
        TrackedObstacle {
            id,
            kind: spl::types::ObstacleKind::Opponent,
            center: spl::types::FieldPoint::new(1000.0 + id as f32, -500.0),
            age_s,
            observations,
        }
    }

    #[test]
    fn confirmed_tracks_become_nodes_and_vanished_ones_are_removed() {
        let mut m = ObstacleMirror::new(ObstacleMirrorConfig::default());
        // One sighting is not enough; three are.
        assert!(m.changes(&[track(7, 1, 0.0)]).is_empty());
        let c = m.changes(&[track(7, 3, 0.0)]);
        assert_eq!(c.len(), 1);
        let StructuralChange::AddNode(spec) = &c[0] else {
            panic!("an addition: {c:?}");
        };
        assert_eq!(spec.name, "obstacle_7");
        assert_eq!(spec.node_type, "object");
        assert_eq!(spec.parent, "field");
        assert!(
            matches!(&spec.edge, Edge::Free { pose } if pose.translation_m == [1.007, -0.5, 0.0]),
            "{spec:?}"
        );
        assert_eq!(spec.attributes[0].key, "obstacle_type");
        assert_eq!(spec.attributes[0].value, AttrValue::Text("opponent".into()));
        // Until the DR accepts it, it is neither updated nor proposed twice... unless it failed.
        let mut req = UpdateRequest::default();
        m.add_updates(&[track(7, 3, 0.0)], 5_000_000_000, &mut req);
        assert!(req.poses.is_empty(), "no update before the node exists");
        m.outcome(&c[0], &ProposalOutcome::Failed);
        assert_eq!(
            m.changes(&[track(7, 3, 0.0)]).len(),
            1,
            "retried after a failure"
        );
        m.outcome(&c[0], &ProposalOutcome::Accepted);
        assert!(m.changes(&[track(7, 4, 0.0)]).is_empty(), "added once");
        // Updates carry the pose, the type and the last-seen time.
        let mut req = UpdateRequest::default();
        m.add_updates(&[track(7, 4, 1.5)], 5_000_000_000, &mut req);
        assert_eq!(req.poses.len(), 1);
        let get = |k: &str| {
            req.attributes
                .iter()
                .find(|a| a.node == "obstacle_7" && a.key == k)
                .map(|a| a.value.clone())
        };
        assert_eq!(get("seen_age_s"), Some(AttrValue::Float(1.5)));
        assert_eq!(get("last_seen_ns"), Some(AttrValue::Int(3_500_000_000)));
        assert_eq!(get("observations"), Some(AttrValue::Int(4)));
        // The track expires: the node is removed.
        let c = m.changes(&[]);
        assert_eq!(
            c,
            [StructuralChange::RemoveNode {
                name: "obstacle_7".into()
            }]
        );
        m.outcome(&c[0], &ProposalOutcome::Accepted);
        assert!(m.changes(&[]).is_empty());
        assert_eq!(m.present().count(), 0);
    }

    #[test]
    fn proposals_are_rate_limited_and_capped_and_refusals_not_retried() {
        let cfg = ObstacleMirrorConfig {
            min_observations: 1,
            max_changes_per_cycle: 2,
            max_nodes: 3,
        };
        let mut m = ObstacleMirror::new(cfg);
        let tracks: Vec<_> = (0..6).map(|i| track(i, 5, 0.0)).collect();
        let mut added = Vec::new();
        for _ in 0..5 {
            let c = m.changes(&tracks);
            assert!(c.len() <= 2, "at most two proposals per cycle");
            for ch in &c {
                m.outcome(ch, &ProposalOutcome::Accepted);
                added.push(ch.name().to_string());
            }
        }
        assert_eq!(
            added,
            ["obstacle_0", "obstacle_1", "obstacle_2"],
            "capped at 3 nodes"
        );
        // A refusal other than a duplicate is not proposed again for that track.
        let mut m = ObstacleMirror::new(cfg);
        let c = m.changes(&[track(9, 5, 0.0)]);
        m.outcome(&c[0], &ProposalOutcome::Refused("unknown_parent".into()));
        assert!(m.changes(&[track(9, 5, 0.0)]).is_empty());
        // A duplicate name means the node is there: it is updated, and removed later.
        let c = m.changes(&[track(10, 5, 0.0)]);
        m.outcome(&c[0], &ProposalOutcome::Refused("duplicate_name".into()));
        assert_eq!(m.present().collect::<Vec<_>>(), [10]);
        // A removal of a node the DR does not know counts as done.
        let c = m.changes(&[]);
        m.outcome(&c[0], &ProposalOutcome::Refused("unknown_node".into()));
        assert_eq!(m.present().count(), 0);
        // Non-finite positions are never proposed.
        let mut bad = track(11, 5, 0.0);
        bad.center.x_mm = f32::NAN;
        assert!(m.changes(&[bad]).is_empty());
    }
}
