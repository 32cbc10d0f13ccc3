//! Predicates computed from the graph's geometry and attributes, and the comparison of a fork
//! with the live graph.
//!
//! Every predicate is a typed [`Fact`] (a [`PredicateKind`] and node-name arguments). The true
//! facts of a state are a sorted set, so two states compare with [`diff_states`].
//!
//! | predicate | args | true when (approximation) |
//! |---|---|---|
//! | `visible` | item or agent, camera | its origin is in the camera frustum: depth in `[min_range_m, max_range_m]` and its pinhole projection inside the image (origin only: a partly visible ball counts only if its centre is in the image) |
//! | `reachable` | item, body part | distance from the body part's base frame (shoulder) to the item centre `<= reach_m + radius_m`, where `reach_m` is the chain's maximal extension (sum of link offsets): a sphere around the shoulder, ignoring joint limits and self-collision, so it over-approximates the real workspace |
//! | `near` | effector or robot, item | centre distance `<= near_effector_m` (hands) or `near_robot_m` (robots), plus the item's radius |
//! | `in_field` | item or agent | a `field` node exists and the origin, in the field frame, is within the outer line edges (`|x| <= L/2 + line_width/2`, same for y; the line belongs to the field) enlarged by the item's radius: a ball is out only when wholly past the line |
//! | `fallen` | robot | attribute `fallen = true`, or the robot frame's z axis is tilted more than `fallen_tilt_rad` from world z |
//! | `closest_to_ball` | robot | among robots with the same `team` attribute (missing = team 0), the one whose origin is nearest (on the floor plane) to the node named `ball_name` |

use std::collections::BTreeSet;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use crate::error::{DrError, Result};
use crate::graph::{At, NodeId, SceneGraph};
use crate::types::{NodeType, attr};

/// The predicates the DR computes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PredicateKind {
    /// `visible(thing, camera)`.
    Visible,
    /// `reachable(item, body_part)`.
    Reachable,
    /// `near(effector_or_robot, item)`.
    Near,
    /// `in_field(thing)`.
    InField,
    /// `fallen(robot)`.
    Fallen,
    /// `closest_to_ball(robot)`.
    ClosestToBall,
}

impl PredicateKind {
    /// All predicates.
    pub const ALL: [PredicateKind; 6] = [
        PredicateKind::Visible,
        PredicateKind::Reachable,
        PredicateKind::Near,
        PredicateKind::InField,
        PredicateKind::Fallen,
        PredicateKind::ClosestToBall,
    ];
    /// The snake_case name.
    pub fn name(self) -> &'static str {
        match self {
            PredicateKind::Visible => "visible",
            PredicateKind::Reachable => "reachable",
            PredicateKind::Near => "near",
            PredicateKind::InField => "in_field",
            PredicateKind::Fallen => "fallen",
            PredicateKind::ClosestToBall => "closest_to_ball",
        }
    }
    /// The PDDL name (hyphens).
    pub fn pddl_name(self) -> &'static str {
        match self {
            PredicateKind::Visible => "visible",
            PredicateKind::Reachable => "reachable",
            PredicateKind::Near => "near",
            PredicateKind::InField => "in-field",
            PredicateKind::Fallen => "fallen",
            PredicateKind::ClosestToBall => "closest-to-ball",
        }
    }
    /// Parses a snake_case or PDDL name.
    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|k| k.name() == s || k.pddl_name() == s)
    }
}

/// A ground predicate that holds: kind and argument node names.
#[derive(Debug, Clone, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct Fact {
    /// Which predicate.
    pub kind: PredicateKind,
    /// Arguments: node or body part names.
    pub args: Vec<String>,
}

impl Fact {
    /// A fact from a kind and arguments.
    pub fn new(kind: PredicateKind, args: &[&str]) -> Self {
        Self {
            kind,
            args: args.iter().map(|s| s.to_string()).collect(),
        }
    }
}

impl std::fmt::Display for Fact {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}({})", self.kind.name(), self.args.join(", "))
    }
}

/// Thresholds of the predicates.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PredicateConfig {
    /// `near` for an effector (hand) and an item (m, between centres, plus the item radius).
    pub near_effector_m: f64,
    /// `near` for a robot and an item (m, on the robot origin).
    pub near_robot_m: f64,
    /// Tilt of a robot's z axis beyond which it counts as fallen (rad).
    pub fallen_tilt_rad: f64,
    /// The ball node used by `closest_to_ball`.
    pub ball_name: String,
    /// Line width of the field (m), for `in_field`.
    pub field_line_width_m: f64,
}

impl Default for PredicateConfig {
    fn default() -> Self {
        Self {
            near_effector_m: 0.05,
            near_robot_m: 0.30,
            fallen_tilt_rad: 1.0,
            ball_name: "ball".into(),
            field_line_width_m: 0.05,
        }
    }
}

fn radius(g: &SceneGraph, id: NodeId) -> f64 {
    g.node_by_id(id)
        .and_then(|n| n.float(attr::RADIUS_M))
        .unwrap_or(0.0)
}

/// `visible(thing, camera)`.
pub fn visible(g: &SceneGraph, thing: &str, camera: &str, at: At) -> Result<bool> {
    let cam = g.node(camera)?;
    let intr = cam
        .camera
        .as_ref()
        .ok_or_else(|| DrError::WrongEdgeKind(camera.into(), "not a camera"))?;
    let p = g.transform(camera, thing, at)?.translation.vector;
    Ok(intr.sees(p.into()))
}

/// `reachable(item, body_part)`.
pub fn reachable(g: &SceneGraph, item: &str, part: &str, at: At) -> Result<bool> {
    let bp = g
        .body_part(part)
        .ok_or_else(|| DrError::UnknownFrame(part.into()))?;
    let d = g
        .transform(&bp.base_frame, item, at)?
        .translation
        .vector
        .norm();
    Ok(d <= bp.reach_m + radius(g, g.id(item)?))
}

/// Distance between the origins of two frames (m).
pub fn distance(g: &SceneGraph, a: &str, b: &str, at: At) -> Result<f64> {
    Ok(g.transform(a, b, at)?.translation.vector.norm())
}

/// `near(a, item)` with an explicit threshold (m, plus the item radius).
pub fn near(g: &SceneGraph, a: &str, item: &str, threshold_m: f64, at: At) -> Result<bool> {
    Ok(distance(g, a, item, at)? <= threshold_m + radius(g, g.id(item)?))
}

/// `in_field(thing)`; false if there is no `field` node.
pub fn in_field(g: &SceneGraph, thing: &str, cfg: &PredicateConfig, at: At) -> Result<bool> {
    let Ok(field) = g.node("field") else {
        return Ok(false);
    };
    let hx = field.float(attr::LENGTH_M).unwrap_or(0.0) / 2.0;
    let hy = field.float(attr::WIDTH_M).unwrap_or(0.0) / 2.0;
    let p = g.transform("field", thing, at)?.translation.vector;
    let m = cfg.field_line_width_m / 2.0 + radius(g, g.id(thing)?);
    Ok(p.x.abs() <= hx + m && p.y.abs() <= hy + m)
}

/// `fallen(robot)`.
pub fn fallen(g: &SceneGraph, robot: &str, cfg: &PredicateConfig, at: At) -> Result<bool> {
    if g.node(robot)?.flag(attr::FALLEN) == Some(true) {
        return Ok(true);
    }
    let up = g.transform("world", robot, at)?.rotation * Vector3::z();
    Ok(up.z.clamp(-1.0, 1.0).acos() > cfg.fallen_tilt_rad)
}

/// The robot of each team closest to the ball (see the module table); empty without a ball.
pub fn closest_to_ball(g: &SceneGraph, cfg: &PredicateConfig, at: At) -> Result<Vec<String>> {
    let Ok(ball) = g.id(&cfg.ball_name) else {
        return Ok(Vec::new());
    };
    let bp = g.world_position(ball, at)?;
    let mut best: std::collections::BTreeMap<i64, (f64, String)> = Default::default();
    for (id, n) in g.nodes().filter(|(_, n)| n.node_type == NodeType::Robot) {
        let p = g.world_position(id, at)?;
        let d = ((p.x - bp.x).powi(2) + (p.y - bp.y).powi(2)).sqrt();
        let team = n.int(attr::TEAM).unwrap_or(0);
        let e = best.entry(team).or_insert((f64::INFINITY, String::new()));
        if d < e.0 || (d == e.0 && n.name < e.1) {
            *e = (d, n.name.clone());
        }
    }
    Ok(best.into_values().map(|(_, n)| n).collect())
}

/// Every fact that holds in the graph at `at`.
pub fn evaluate(g: &SceneGraph, cfg: &PredicateConfig, at: At) -> Result<BTreeSet<Fact>> {
    let mut out = BTreeSet::new();
    let names = |pred: &dyn Fn(NodeType, &crate::graph::Node) -> bool| -> Vec<String> {
        g.nodes()
            .filter(|(_, n)| pred(n.node_type, n))
            .map(|(_, n)| n.name.clone())
            .collect()
    };
    let items = names(&|t, _| t.is_item());
    let things = names(&|t, _| t.is_item() || t.is_agent());
    let cameras = names(&|t, n| t == NodeType::Camera && n.camera.is_some());
    let robots = names(&|t, _| t == NodeType::Robot);
    let effectors = names(&|_, n| n.flag(attr::EFFECTOR) == Some(true));
    for t in &things {
        for c in &cameras {
            if visible(g, t, c, at)? {
                out.insert(Fact::new(PredicateKind::Visible, &[t, c]));
            }
        }
        if in_field(g, t, cfg, at)? {
            out.insert(Fact::new(PredicateKind::InField, &[t]));
        }
    }
    let parts: Vec<String> = g.body_parts().map(|b| b.name.clone()).collect();
    for i in &items {
        for p in &parts {
            if reachable(g, i, p, at)? {
                out.insert(Fact::new(PredicateKind::Reachable, &[i, p]));
            }
        }
        for e in &effectors {
            if near(g, e, i, cfg.near_effector_m, at)? {
                out.insert(Fact::new(PredicateKind::Near, &[e, i]));
            }
        }
        for r in &robots {
            if near(g, r, i, cfg.near_robot_m, at)? {
                out.insert(Fact::new(PredicateKind::Near, &[r, i]));
            }
        }
    }
    for r in &robots {
        if fallen(g, r, cfg, at)? {
            out.insert(Fact::new(PredicateKind::Fallen, &[r]));
        }
    }
    for r in closest_to_ball(g, cfg, at)? {
        out.insert(Fact {
            kind: PredicateKind::ClosestToBall,
            args: vec![r],
        });
    }
    Ok(out)
}

/// The change between two sets of facts.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct FactDiff {
    /// Facts true in the second state only.
    pub became_true: Vec<Fact>,
    /// Facts true in the first state only.
    pub became_false: Vec<Fact>,
}

impl FactDiff {
    /// Whether nothing changed.
    pub fn is_empty(&self) -> bool {
        self.became_true.is_empty() && self.became_false.is_empty()
    }
}

/// `after - before` and `before - after`.
pub fn diff_states(before: &BTreeSet<Fact>, after: &BTreeSet<Fact>) -> FactDiff {
    FactDiff {
        became_true: after.difference(before).cloned().collect(),
        became_false: before.difference(after).cloned().collect(),
    }
}

/// What a fork's virtual actions changed compared with the live graph.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ForkReport {
    /// Predicate changes (live -> fork).
    pub facts: FactDiff,
    /// Joints whose values differ: (joint, live value, fork value).
    pub joints_changed: Vec<(String, f64, f64)>,
    /// Items and agents whose world position differs by more than 1 mm: (node, distance m).
    pub moved: Vec<(String, f64)>,
}

/// Compares a fork with the live graph (latest state of both).
pub fn fork_report(
    live: &SceneGraph,
    fork: &SceneGraph,
    cfg: &PredicateConfig,
) -> Result<ForkReport> {
    let facts = diff_states(
        &evaluate(live, cfg, At::Latest)?,
        &evaluate(fork, cfg, At::Latest)?,
    );
    let mut joints_changed = Vec::new();
    let mut moved = Vec::new();
    for (id, n) in live.nodes() {
        let Ok(fid) = fork.id(&n.name) else { continue };
        if let crate::graph::EdgeKind::Joint { joint, .. } = &n.edge.kind {
            let (a, b) = (n.edge.value(), fork.joint_value(joint)?);
            if a != b {
                joints_changed.push((joint.clone(), a, b));
            }
        }
        if n.node_type.is_item() || n.node_type.is_agent() {
            let d = (live.world_position(id, At::Latest)?
                - fork.world_position(fid, At::Latest)?)
            .norm();
            if d > 1e-3 {
                moved.push((n.name.clone(), d));
            }
        }
    }
    joints_changed.sort_by(|a, b| a.0.cmp(&b.0));
    Ok(ForkReport {
        facts,
        joints_changed,
        moved,
    })
}
