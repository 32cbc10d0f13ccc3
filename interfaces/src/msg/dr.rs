//! The deep representation (DR) service: requests, replies and change events.
//!
//! The DR (crate `deep_representation`) is the world model: a scene graph whose nodes are frames
//! (`world`, robot links, cameras, the ball, humans, robots, the field and its landmarks) joined by
//! rigid transforms. These types carry it over the bus; the services and the change topic are in
//! [`crate::topics`] (`dr/...`).
//!
//! Conventions:
//! - Units: metres, radians, nanoseconds. Rotations are unit quaternions `[x, y, z, w]`.
//! - A transform `target_T_source` maps points of `source` into `target`:
//!   `p_target = target_T_source * p_source`.
//! - Time: `stamp_ns` fields are nanoseconds on the DR's clock (the bus clock, a replay's virtual
//!   clock); in queries 0 means "the latest state". Update requests take the measurement's time
//!   from `header.stamp_ns` (0 = now on the service's clock).
//! - Rich payloads the library describes with optional fields (a whole node description, a
//!   snapshot, a change event) travel as JSON text in `*_json` fields, in the library's own serde
//!   format; everything a hot path needs (transforms, poses, attribute updates) is typed.
//! - A structural proposal that breaks an integrity rule is a normal reply (`accepted = false`
//!   with the reason), not a transport error. Unknown names come back as a `NotFound`
//!   [`crate::ServiceError`], malformed requests as `BadRequest`.

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// A rigid transform or pose: translation (m) and unit quaternion `[x, y, z, w]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Transform {
    pub translation_m: [f64; 3],
    pub rotation_xyzw: [f64; 4],
}

impl Default for Transform {
    /// The identity.
    fn default() -> Self {
        Self {
            translation_m: [0.0; 3],
            rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
        }
    }
}

impl Transform {
    /// A pure translation (m).
    pub fn from_translation(x: f64, y: f64, z: f64) -> Self {
        Self {
            translation_m: [x, y, z],
            ..Self::default()
        }
    }
}

/// A typed attribute value. The attribute's key names the unit (`radius_m`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum AttrValue {
    Bool(bool),
    Int(i64),
    Float(f64),
    Text(String),
    /// A 3-vector (unit in the key, e.g. `velocity_mps`).
    Vec3([f64; 3]),
}

impl Default for AttrValue {
    fn default() -> Self {
        AttrValue::Bool(false)
    }
}

/// One attribute of a node: `node.key = value`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Attribute {
    pub node: String,
    pub key: String,
    pub value: AttrValue,
}

/// A new free pose `parent_T_node` for a node with a free edge (objects, agents).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PoseUpdate {
    pub node: String,
    pub pose: Transform,
}

/// A new joint value (rad or m).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointUpdate {
    pub joint: String,
    pub value: f64,
}

/// `dr/get_node` request: one node by name.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct GetNodeRequest {
    pub header: Header,
    pub name: String,
}

/// `dr/get_node` reply.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct NodeInfo {
    pub header: Header,
    pub name: String,
    /// Node type name (`ball`, `robot`, `link`, ...).
    pub node_type: String,
    /// Parent node (empty for `world`).
    pub parent: String,
    pub children: Vec<String>,
    /// `fixed`, `free`, `joint` (empty for `world`).
    pub edge: String,
    /// Joint name for a `joint` edge, else empty.
    pub joint: String,
    /// Joint value (rad or m) for a `joint` edge, else 0.
    pub joint_value: f64,
    /// Current `parent_T_node`.
    pub pose: Transform,
    /// Every attribute, sorted by key (`node` is this node).
    pub attributes: Vec<Attribute>,
    /// The library's full node description (`NodeSpec`: edge, limits, intrinsics, collision) as
    /// JSON; empty for `world`.
    pub spec_json: String,
}

/// `dr/transform` request: `target_T_source`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformRequest {
    pub header: Header,
    pub target: String,
    pub source: String,
    /// Query time (ns, DR clock), interpolated from the edge histories; 0 = latest.
    pub stamp_ns: u64,
}

/// `dr/transform` reply (`header.frame_id` is the target frame).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TransformReply {
    pub header: Header,
    pub target: String,
    pub source: String,
    /// The time the transform holds for (the request's, or the newest change for "latest").
    pub stamp_ns: u64,
    /// `target_T_source`.
    pub transform: Transform,
}

/// `dr/update` request: perception and odometry write straight in (no integrity vote). The batch
/// is checked first and applied only if every entry is valid; the measurement time is
/// `header.stamp_ns` (0 = now).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct UpdateRequest {
    pub header: Header,
    pub attributes: Vec<Attribute>,
    pub poses: Vec<PoseUpdate>,
    pub joints: Vec<JointUpdate>,
}

/// `dr/update` reply.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct UpdateReply {
    pub header: Header,
    /// Changes applied (= entries of the request).
    pub applied: u32,
    /// Sequence number of the last change (as on `dr/changes`).
    pub last_seq: u64,
}

/// What a structural change does.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ChangeKind {
    /// Add node `name` of type `node_type` under `parent` at `pose` (free edge, or fixed when
    /// `fixed`), with `attributes`; or, when `spec_json` is not empty, the library `NodeSpec` it
    /// holds (cameras, links, joints), the other fields ignored.
    #[default]
    AddNode,
    /// Remove leaf node `name`.
    RemoveNode,
    /// Move `name` under `parent` with free pose `pose` (`parent_T_node`).
    Reparent,
}

/// A structural change of the graph, voted by the integrity rules.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct StructuralChange {
    pub kind: ChangeKind,
    pub name: String,
    pub node_type: String,
    pub parent: String,
    pub pose: Transform,
    pub fixed: bool,
    /// Attributes of an added node (their `node` field is ignored).
    pub attributes: Vec<Attribute>,
    pub spec_json: String,
}

/// `dr/propose` request (time of the change: `header.stamp_ns`, 0 = now).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ProposeRequest {
    pub header: Header,
    pub change: StructuralChange,
}

/// `dr/propose` reply: accepted, or rejected with the rule that refused it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ProposeReply {
    pub header: Header,
    pub accepted: bool,
    /// The rule that refused it, snake_case (`duplicate_name`, `unknown_parent`, `cycle`,
    /// `has_children`, `protected`, ...); empty when accepted.
    pub reason_code: String,
    /// Human-readable reason; empty when accepted.
    pub reason: String,
    /// Sequence number of the change when accepted (as on `dr/changes`).
    pub seq: u64,
}

/// A ground predicate: `predicate(args...)` (names as in the library: `visible`, `reachable`,
/// `near`, `in_field`, `fallen`, `closest_to_ball`).
#[derive(Debug, Clone, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Fact {
    pub predicate: String,
    pub args: Vec<String>,
}

/// `dr/predicate` request: whether `predicate(args)` holds; with an empty `predicate`, every fact
/// that holds.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PredicateRequest {
    pub header: Header,
    pub predicate: String,
    pub args: Vec<String>,
    /// Query time (ns); 0 = latest.
    pub stamp_ns: u64,
}

/// `dr/predicate` reply.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PredicateReply {
    pub header: Header,
    /// Whether the asked fact holds (false for the "every fact" query).
    pub holds: bool,
    /// Every fact that holds (only for the "every fact" query).
    pub facts: Vec<Fact>,
}

/// `dr/fork` request: apply virtual actions to a private copy of the graph and report what would
/// change. The live graph is untouched and nothing is logged or published.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ForkRequest {
    pub header: Header,
    pub joints: Vec<JointUpdate>,
    pub poses: Vec<PoseUpdate>,
    pub attributes: Vec<Attribute>,
    /// Structural changes, applied after the updates, in order.
    pub changes: Vec<StructuralChange>,
}

/// A joint whose value differs between the live graph and the fork.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointChange {
    pub joint: String,
    pub live: f64,
    pub fork: f64,
}

/// An item or agent that moved in the fork (world-position distance, m).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Moved {
    pub node: String,
    pub distance_m: f64,
}

/// `dr/fork` reply.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ForkReply {
    pub header: Header,
    pub became_true: Vec<Fact>,
    pub became_false: Vec<Fact>,
    pub joints_changed: Vec<JointChange>,
    pub moved: Vec<Moved>,
    /// Virtual structural changes the integrity rules refused (`index: reason`); the others
    /// were applied.
    pub rejected: Vec<String>,
}

/// `dr/pddl` request: the state as a PDDL problem for the robocog domain.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PddlRequest {
    pub header: Header,
    /// Problem name (default `robocog-state`).
    pub problem_name: String,
    /// Goal conjunction (PDDL predicate names, DR node names).
    pub goal: Vec<Fact>,
}

/// `dr/pddl` reply.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct PddlReply {
    pub header: Header,
    /// The problem file text.
    pub problem: String,
}

/// `dr/snapshot` request.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SnapshotRequest {
    pub header: Header,
}

/// `dr/snapshot` reply, and `dr/restore` request: the library's snapshot JSON (current state,
/// no history).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SnapshotData {
    pub header: Header,
    pub json: String,
    /// Nodes in the graph (including `world`).
    pub nodes: u32,
    /// Sequence number of the last change included.
    pub last_seq: u64,
}

/// A change of the live graph, published on `dr/changes` in order.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DrChange {
    pub header: Header,
    /// Change sequence number of the service (continues across restarts with a state dir).
    pub seq: u64,
    /// `node_added`, `node_removed`, `reparented`, `joint_set`, `pose_set`, `attribute_set`,
    /// `body_part_declared`, or `restored` (the whole graph was replaced).
    pub kind: String,
    /// The node (or joint) it concerns; empty for `restored`.
    pub node: String,
    /// The library's `ChangeEvent` as JSON (empty for `restored`).
    pub event_json: String,
}
