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

/// A rigid transform or pose: translation (m) and unit quaternion `[x, y, z, w]`. A
/// `geometry_msgs/Transform` on the wire.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self")]
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

    /// A planar pose: position on the z = 0 plane (m) and heading about z (rad).
    pub fn planar(x: f64, y: f64, theta: f64) -> Self {
        let (s, c) = (theta / 2.0).sin_cos();
        Self {
            translation_m: [x, y, 0.0],
            rotation_xyzw: [0.0, 0.0, s, c],
        }
    }

    /// Whether every number is finite and the quaternion is not zero (it is normalised where it
    /// is used).
    pub fn is_valid(&self) -> bool {
        self.translation_m
            .iter()
            .chain(&self.rotation_xyzw)
            .all(|v| v.is_finite())
            && self.rotation_xyzw.iter().map(|v| v * v).sum::<f64>() > 1e-12
    }
}

/// A typed attribute value. The attribute's key names the unit (`radius_m`). On the wire, a
/// message with the variant's `kind` and a field per variant ([`wire::AttrValueWire`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(
    remote = "Self",
    tag = "type",
    content = "value",
    rename_all = "snake_case"
)]
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

impl AttrValue {
    /// Whether every number in it is finite (flags, integers and text always are).
    pub fn is_finite(&self) -> bool {
        match self {
            AttrValue::Float(f) => f.is_finite(),
            AttrValue::Vec3(v) => v.iter().all(|x| x.is_finite()),
            AttrValue::Bool(_) | AttrValue::Int(_) | AttrValue::Text(_) => true,
        }
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

/// One attribute inside a [`NodeSpec`] (the node is the one the spec describes).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct KeyValue {
    pub key: String,
    pub value: AttrValue,
}

/// How a joint moves, which fixes the units of its position (rad or m). The one joint kind of the
/// workspace: the robot model, the joint drivers and the DR share it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointKind {
    /// Rotation about the axis, within position limits (rad).
    #[default]
    Revolute,
    /// Rotation about the axis without position limits (rad).
    Continuous,
    /// Translation along the axis (m).
    Prismatic,
    /// No motion (a model's fixed joint; never the edge of a node).
    Fixed,
}

impl JointKind {
    /// True for joints that take a value (all but [`JointKind::Fixed`]).
    pub fn is_movable(self) -> bool {
        !matches!(self, JointKind::Fixed)
    }
}

/// Limits of a joint: position (rad or m), velocity (rad/s or m/s), effort (N m or N). A limit
/// that does not exist is infinite (`lower` -inf, the others +inf; a continuous joint's position),
/// never NaN. JSON has no infinity: there such a limit is `null` (and `null` reads back as it).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct JointLimits {
    #[serde(with = "no_limit::lower")]
    pub lower: f64,
    #[serde(with = "no_limit::upper")]
    pub upper: f64,
    #[serde(with = "no_limit::upper")]
    pub velocity: f64,
    #[serde(with = "no_limit::upper")]
    pub effort: f64,
}

impl JointLimits {
    /// Whether position `q` is inside `[lower, upper]`.
    pub fn contains(&self, q: f64) -> bool {
        q >= self.lower && q <= self.upper
    }
    /// Position `q` clamped into `[lower, upper]`.
    pub fn clamp(&self, q: f64) -> f64 {
        q.clamp(self.lower, self.upper)
    }
}

/// A missing limit (an infinity) as `null` in human-readable forms (JSON); CDR carries the
/// number as it is.
mod no_limit {
    use serde::{Deserialize, Deserializer, Serializer};

    fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() && v.is_infinite() {
            s.serialize_none()
        } else {
            s.serialize_f64(*v)
        }
    }

    fn deserialize<'de, D: Deserializer<'de>>(d: D, none: f64) -> Result<f64, D::Error> {
        if d.is_human_readable() {
            Ok(Option::<f64>::deserialize(d)?.unwrap_or(none))
        } else {
            f64::deserialize(d)
        }
    }

    /// A lower limit: `null` is -inf.
    pub mod lower {
        use serde::{Deserializer, Serializer};
        pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
            super::serialize(v, s)
        }
        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
            super::deserialize(d, f64::NEG_INFINITY)
        }
    }

    /// An upper limit (position, velocity, effort): `null` is +inf.
    pub mod upper {
        use serde::{Deserializer, Serializer};
        pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
            super::serialize(v, s)
        }
        pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
            super::deserialize(d, f64::INFINITY)
        }
    }
}

/// How a node hangs from its parent. On the wire: [`wire::EdgeWire`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(
    remote = "Self",
    tag = "edge",
    rename_all = "snake_case",
    deny_unknown_fields
)]
pub enum Edge {
    /// A constant transform.
    Fixed {
        /// `parent_T_node`.
        origin: Transform,
    },
    /// A pose set by perception or odometry (objects, agents).
    Free {
        /// The current `parent_T_node`.
        pose: Transform,
    },
    /// A robot joint: `parent_T_node = origin * motion(value)`.
    Joint {
        /// Joint name (unique in the graph).
        joint: String,
        /// Not [`JointKind::Fixed`].
        kind: JointKind,
        /// `parent_T_jointframe`.
        origin: Transform,
        /// Axis in the joint frame.
        axis: [f64; 3],
        limits: JointLimits,
        /// Current value (rad or m).
        value: f64,
    },
}

impl Default for Edge {
    /// A free edge at the identity.
    fn default() -> Self {
        Edge::Free {
            pose: Transform::default(),
        }
    }
}

/// Pinhole intrinsics of a camera (px) and its valid depth range (m). The camera frame is an
/// optical frame (z forward, x right, y down): `u = fx x / z + cx`, `v = fy y / z + cy`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CameraIntrinsics {
    /// Camera name (`head_rgbd`).
    pub name: String,
    /// Its optical frame (a node).
    pub frame: String,
    pub width: u32,
    pub height: u32,
    pub fx: f64,
    pub fy: f64,
    pub cx: f64,
    pub cy: f64,
    pub min_range_m: f64,
    pub max_range_m: f64,
}

impl CameraIntrinsics {
    /// The camera's pinhole model.
    pub fn pinhole(&self) -> crate::msg::vision::Intrinsics {
        crate::msg::vision::Intrinsics {
            fx: self.fx,
            fy: self.fy,
            cx: self.cx,
            cy: self.cy,
        }
    }

    /// Pixel `(u, v)` of a point in the optical frame, or `None` if it is behind the camera.
    pub fn project(&self, p: [f64; 3]) -> Option<(f64, f64)> {
        self.pinhole().project(p).map(|[u, v]| (u, v))
    }

    /// Whether a point in the optical frame is in the frustum: inside the image and within range.
    pub fn sees(&self, p: [f64; 3]) -> bool {
        if p[2] < self.min_range_m || p[2] > self.max_range_m {
            return false;
        }
        match self.project(p) {
            Some((u, v)) => {
                u >= -0.5
                    && u < f64::from(self.width) - 0.5
                    && v >= -0.5
                    && v < f64::from(self.height) - 0.5
            }
            None => false,
        }
    }
}

/// The camera of a node, for `camera` nodes. On the wire: [`wire::CameraWire`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self", rename_all = "snake_case")]
pub enum Camera {
    /// Not a camera.
    #[default]
    None,
    /// A pinhole camera.
    Pinhole(CameraIntrinsics),
}

impl Camera {
    /// The intrinsics, for a pinhole camera.
    pub fn intrinsics(&self) -> Option<&CameraIntrinsics> {
        match self {
            Camera::None => None,
            Camera::Pinhole(c) => Some(c),
        }
    }
}

impl From<Option<CameraIntrinsics>> for Camera {
    fn from(c: Option<CameraIntrinsics>) -> Self {
        c.map_or(Camera::None, Camera::Pinhole)
    }
}

/// Collision geometry, centred on its origin (m). On the wire: [`wire::ShapeWire`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(
    remote = "Self",
    tag = "type",
    rename_all = "snake_case",
    deny_unknown_fields
)]
pub enum Shape {
    /// A box; full side lengths along x, y, z.
    Box {
        size_m: [f64; 3],
    },
    /// A cylinder along its local z axis.
    Cylinder {
        radius_m: f64,
        length_m: f64,
    },
    /// A capsule along its local z axis (`length_m`: the cylindrical part).
    Capsule {
        radius_m: f64,
        length_m: f64,
    },
    Sphere {
        radius_m: f64,
    },
    /// A mesh, by its URDF file name (robocog does no mesh collision).
    Mesh {
        filename: String,
    },
}

/// One collision element of a node: a shape placed by `origin` in the node frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CollisionShape {
    pub origin: Transform,
    pub shape: Shape,
}

/// A complete description of one node: what `dr/propose` adds, what a snapshot and a
/// `NodeAdded` change hold, what `dr/get_node` reports in full.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeSpec {
    /// Unique name (also the frame name).
    pub name: String,
    /// Node type name (`ball`, `object`, `robot`, `link`, `camera`, `landmark`, ...).
    pub node_type: String,
    /// The parent node.
    pub parent: String,
    /// The edge from the parent, with its current pose or joint value.
    pub edge: Edge,
    /// Typed attributes, each key once (sorted by key in what the DR sends).
    pub attributes: Vec<KeyValue>,
    /// Intrinsics, for `camera` nodes.
    pub camera: Camera,
    /// Collision geometry in the node frame, for `link` nodes.
    pub collision: Vec<CollisionShape>,
}

impl NodeSpec {
    /// A node with a free pose `parent_T_node` under `parent`, no attributes.
    pub fn free(name: &str, node_type: impl AsRef<str>, parent: &str, pose: Transform) -> Self {
        Self {
            name: name.into(),
            node_type: node_type.as_ref().into(),
            parent: parent.into(),
            edge: Edge::Free { pose },
            ..Self::default()
        }
    }

    /// Builder: sets an attribute (replacing one of the same key).
    pub fn with_attr(mut self, key: &str, value: AttrValue) -> Self {
        match self.attributes.iter_mut().find(|a| a.key == key) {
            Some(a) => a.value = value,
            None => self.attributes.push(KeyValue {
                key: key.into(),
                value,
            }),
        }
        self
    }

    /// The value of an attribute, if the node has it.
    pub fn attribute(&self, key: &str) -> Option<&AttrValue> {
        self.attributes
            .iter()
            .find(|a| a.key == key)
            .map(|a| &a.value)
    }
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
