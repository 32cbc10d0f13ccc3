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
//! - Everything is typed, down to a whole node description ([`NodeSpec`]: its edge with the
//!   joint's limits, attributes, camera intrinsics, collision shapes), a snapshot ([`Snapshot`])
//!   and a change event ([`ChangeEvent`]). They are the `world_model` library's own types too
//!   (one definition: the library builds, stores and restores these), so a snapshot taken, sent
//!   and restored loses nothing. Their JSON form (the DR's state folder, `robocog topic echo`) is
//!   tagged and snake_case; their CDR form is the ROS 2 one of [`wire`].
//! - A structural proposal that breaks an integrity rule is a normal reply (`accepted = false`
//!   with the reason), not a transport error. Unknown names come back as a `NotFound`
//!   [`crate::ServiceError`], malformed requests as `BadRequest`.

use crate::header::Header;
use serde::{Deserialize, Serialize};

mod node;
pub use node::*;

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
    /// The full node description (edge with limits, intrinsics, collision); for `world`, which
    /// has no parent and so no description, the default (an empty `name`).
    pub spec: NodeSpec,
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

/// A structural change of the graph, voted by the integrity rules. On the wire:
/// [`wire::StructuralChangeWire`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self")]
pub enum StructuralChange {
    /// Add a node: a free or fixed one, or a link with its joint, a camera with its intrinsics.
    AddNode(Box<NodeSpec>),
    /// Remove leaf node `name`.
    RemoveNode { name: String },
    /// Move `name` under `new_parent` with free pose `pose` (`new_parent_T_node`).
    Reparent {
        name: String,
        new_parent: String,
        pose: Transform,
    },
}

impl Default for StructuralChange {
    /// Adding a default (invalid, nameless) node.
    fn default() -> Self {
        StructuralChange::AddNode(Box::default())
    }
}

impl StructuralChange {
    /// Adding a node.
    pub fn add(spec: NodeSpec) -> Self {
        StructuralChange::AddNode(Box::new(spec))
    }

    /// The snake_case name of the change: `add_node`, `remove_node` or `reparent`.
    pub fn kind(&self) -> &'static str {
        match self {
            StructuralChange::AddNode(_) => "add_node",
            StructuralChange::RemoveNode { .. } => "remove_node",
            StructuralChange::Reparent { .. } => "reparent",
        }
    }

    /// The node the change is about.
    pub fn name(&self) -> &str {
        match self {
            StructuralChange::AddNode(spec) => &spec.name,
            StructuralChange::RemoveNode { name } | StructuralChange::Reparent { name, .. } => name,
        }
    }
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

/// A body part declared for predicates: a chain from a shoulder-like frame to a tip.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyPart {
    /// Name (`left_arm`).
    pub name: String,
    /// The robot agent it belongs to.
    pub robot: String,
    /// Frame at the first joint of the chain (the shoulder).
    pub base_frame: String,
    /// Tip frame (the hand).
    pub tip_frame: String,
    /// Upper bound of the shoulder-to-tip distance over all joint values (m).
    pub reach_m: f64,
}

/// The state of the graph, without history.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Snapshot {
    /// Time of the newest change included (ns, DR clock).
    pub stamp_ns: u64,
    /// Every node except `world`, each after its parent, with its edge (pose, joint value),
    /// attributes, intrinsics and collision shapes.
    pub nodes: Vec<NodeSpec>,
    /// Declared body parts.
    pub body_parts: Vec<BodyPart>,
}

/// `dr/snapshot` reply, and `dr/restore` request: the current state (no history).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SnapshotData {
    pub header: Header,
    pub snapshot: Snapshot,
    /// Sequence number of the last change included (ignored in a `dr/restore` request).
    pub last_seq: u64,
}

/// One change of the live graph. Times are ns on the DR clock. On the wire:
/// [`wire::ChangeEventWire`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(
    remote = "Self",
    tag = "event",
    rename_all = "snake_case",
    deny_unknown_fields
)]
pub enum ChangeEvent {
    /// A node was added.
    NodeAdded { stamp_ns: u64, spec: Box<NodeSpec> },
    /// A node was removed.
    NodeRemoved { stamp_ns: u64, name: String },
    /// A node moved under another parent (`pose` = `new_parent_T_node`).
    Reparented {
        stamp_ns: u64,
        name: String,
        new_parent: String,
        pose: Transform,
    },
    /// A joint value was set (rad or m).
    JointSet {
        stamp_ns: u64,
        joint: String,
        value: f64,
    },
    /// A free pose was set (`parent_T_node`).
    PoseSet {
        stamp_ns: u64,
        node: String,
        pose: Transform,
    },
    /// An attribute was set.
    AttributeSet {
        stamp_ns: u64,
        node: String,
        key: String,
        value: AttrValue,
    },
    /// A body part was declared.
    BodyPartDeclared { stamp_ns: u64, part: BodyPart },
    /// The whole graph was replaced (`dr/restore`): a copy of it asks `dr/snapshot` again.
    #[default]
    Restored,
}

impl ChangeEvent {
    /// The snake_case name of the change: `node_added`, `node_removed`, `reparented`,
    /// `joint_set`, `pose_set`, `attribute_set`, `body_part_declared` or `restored`.
    pub fn kind(&self) -> &'static str {
        match self {
            ChangeEvent::NodeAdded { .. } => "node_added",
            ChangeEvent::NodeRemoved { .. } => "node_removed",
            ChangeEvent::Reparented { .. } => "reparented",
            ChangeEvent::JointSet { .. } => "joint_set",
            ChangeEvent::PoseSet { .. } => "pose_set",
            ChangeEvent::AttributeSet { .. } => "attribute_set",
            ChangeEvent::BodyPartDeclared { .. } => "body_part_declared",
            ChangeEvent::Restored => "restored",
        }
    }

    /// When it happened (ns on the DR's clock); 0 for `restored`.
    pub fn stamp_ns(&self) -> u64 {
        match self {
            ChangeEvent::NodeAdded { stamp_ns, .. }
            | ChangeEvent::NodeRemoved { stamp_ns, .. }
            | ChangeEvent::Reparented { stamp_ns, .. }
            | ChangeEvent::JointSet { stamp_ns, .. }
            | ChangeEvent::PoseSet { stamp_ns, .. }
            | ChangeEvent::AttributeSet { stamp_ns, .. }
            | ChangeEvent::BodyPartDeclared { stamp_ns, .. } => *stamp_ns,
            ChangeEvent::Restored => 0,
        }
    }

    /// The node (the joint, the body part) it concerns; empty for `restored`.
    pub fn node(&self) -> &str {
        match self {
            ChangeEvent::NodeAdded { spec, .. } => &spec.name,
            ChangeEvent::NodeRemoved { name, .. } | ChangeEvent::Reparented { name, .. } => name,
            ChangeEvent::JointSet { joint, .. } => joint,
            ChangeEvent::PoseSet { node, .. } | ChangeEvent::AttributeSet { node, .. } => node,
            ChangeEvent::BodyPartDeclared { part, .. } => &part.name,
            ChangeEvent::Restored => "",
        }
    }
}

/// A change of the live graph, published on `dr/changes` in order (`header.stamp_ns` is the
/// change's time).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct DrChange {
    pub header: Header,
    /// Change sequence number of the service (continues across restarts with a state dir).
    pub seq: u64,
    pub event: ChangeEvent,
}

pub mod wire;
