//! Plain serde data types that cross process boundaries: stamps, poses, attribute values, node
//! descriptions, structural proposals, change events and snapshots.
//!
//! They are kept in this one module, with no behaviour beyond conversions. They are the format
//! of the state folder ([`crate::persist`], JSON); on the bus their CDR mirrors in
//! `interfaces::msg::dr` travel, converted by [`crate::bus`].
//!
//! Units: metres and radians; time as [`Stamp`] (u64 nanoseconds on the caller's clock).

use std::collections::BTreeMap;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};

use robot_model::{CameraIntrinsics, CollisionShape, JointKind};

/// A time stamp: nanoseconds on the caller's clock (wall, monotonic or a replay's virtual clock;
/// the library never reads a clock itself).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Stamp(pub u64);

impl Stamp {
    /// From seconds (f64); negative or NaN give 0, values past u64 saturate.
    pub fn from_secs_f64(s: f64) -> Self {
        Stamp((s * 1e9).round().max(0.0) as u64)
    }
    /// As seconds.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }
}

/// A rigid pose (or transform) in a serde-friendly form: translation in metres, rotation as a unit
/// quaternion `[x, y, z, w]`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pose {
    /// Translation (m).
    pub translation_m: [f64; 3],
    /// Rotation quaternion `[x, y, z, w]` (normalised on conversion).
    pub rotation_xyzw: [f64; 4],
}

impl Default for Pose {
    fn default() -> Self {
        Self {
            translation_m: [0.0; 3],
            rotation_xyzw: [0.0, 0.0, 0.0, 1.0],
        }
    }
}

impl Pose {
    /// A pure translation (m).
    pub fn from_translation(x: f64, y: f64, z: f64) -> Self {
        Self {
            translation_m: [x, y, z],
            ..Self::default()
        }
    }
    /// A planar pose: position on the z = 0 plane (m) and heading about z (rad).
    pub fn planar(x: f64, y: f64, theta: f64) -> Self {
        Self::from_iso(&Isometry3::from_parts(
            Translation3::new(x, y, 0.0),
            UnitQuaternion::from_euler_angles(0.0, 0.0, theta),
        ))
    }
    /// From a nalgebra isometry.
    pub fn from_iso(iso: &Isometry3<f64>) -> Self {
        let q = iso.rotation.coords;
        let t = iso.translation.vector;
        Self {
            translation_m: [t.x, t.y, t.z],
            rotation_xyzw: [q.x, q.y, q.z, q.w],
        }
    }
    /// Whether every number is finite and the quaternion is not zero.
    pub fn is_valid(&self) -> bool {
        self.translation_m
            .iter()
            .chain(&self.rotation_xyzw)
            .all(|v| v.is_finite())
            && self.rotation_xyzw.iter().map(|v| v * v).sum::<f64>() > 1e-12
    }
    /// To a nalgebra isometry (the quaternion is normalised). Call [`Pose::is_valid`] first.
    pub fn to_iso(&self) -> Isometry3<f64> {
        let [x, y, z, w] = self.rotation_xyzw;
        let [tx, ty, tz] = self.translation_m;
        Isometry3::from_parts(
            Translation3::new(tx, ty, tz),
            UnitQuaternion::from_quaternion(Quaternion::new(w, x, y, z)),
        )
    }
}

/// A typed attribute value.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", content = "value", rename_all = "snake_case")]
pub enum AttrValue {
    /// A boolean flag (e.g. `fallen`).
    Bool(bool),
    /// An integer (e.g. `team`).
    Int(i64),
    /// A real number; the key names the unit (e.g. `radius_m`).
    Float(f64),
    /// Text (e.g. `color`).
    Text(String),
    /// A 3-vector; the key names the unit (e.g. `velocity_mps`).
    Vec3([f64; 3]),
}

/// Well-known attribute keys.
pub mod attr {
    /// `Float`, metres: radius of a ball or object, of a goalpost.
    pub const RADIUS_M: &str = "radius_m";
    /// `Int`: team number of an agent (robots of the same team share it).
    pub const TEAM: &str = "team";
    /// `Bool`: a robot reported as fallen by its own state estimation.
    pub const FALLEN: &str = "fallen";
    /// `Bool`: a link that is an end effector (a hand), used by `near`.
    pub const EFFECTOR: &str = "effector";
    /// `Text`: colour name of an object (`yellow`).
    pub const COLOR: &str = "color";
    /// `Float`, metres: field length / width on a `field` node.
    pub const LENGTH_M: &str = "length_m";
    /// See [`LENGTH_M`].
    pub const WIDTH_M: &str = "width_m";
}

/// The type of a node. Its snake_case name is what proposals and snapshots carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeType {
    /// The root frame; exactly one, named `world`.
    World,
    /// A plain frame (no physical extent).
    Frame,
    /// A robot link (from URDF).
    Link,
    /// A camera sensor with intrinsics; its frame is an optical frame.
    Camera,
    /// A ball.
    Ball,
    /// Any other physical object.
    Object,
    /// A human agent (the player, the coach).
    Human,
    /// A robot agent (Loki, a Nao); its frame is the robot's base pose.
    Robot,
    /// The playing field; its frame is the field frame (centre spot, x towards the opponent goal).
    Field,
    /// A goalpost landmark.
    Goalpost,
    /// Any other landmark (spots, penalty marks).
    Landmark,
}

impl NodeType {
    /// All types, for listing the known names.
    pub const ALL: [NodeType; 11] = [
        NodeType::World,
        NodeType::Frame,
        NodeType::Link,
        NodeType::Camera,
        NodeType::Ball,
        NodeType::Object,
        NodeType::Human,
        NodeType::Robot,
        NodeType::Field,
        NodeType::Goalpost,
        NodeType::Landmark,
    ];

    /// The snake_case name.
    pub fn name(self) -> &'static str {
        match self {
            NodeType::World => "world",
            NodeType::Frame => "frame",
            NodeType::Link => "link",
            NodeType::Camera => "camera",
            NodeType::Ball => "ball",
            NodeType::Object => "object",
            NodeType::Human => "human",
            NodeType::Robot => "robot",
            NodeType::Field => "field",
            NodeType::Goalpost => "goalpost",
            NodeType::Landmark => "landmark",
        }
    }

    /// Parses a snake_case name.
    pub fn from_name(name: &str) -> Option<NodeType> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Balls and objects: things that can be seen, reached and touched.
    pub fn is_item(self) -> bool {
        matches!(self, NodeType::Ball | NodeType::Object)
    }
    /// Humans and robots.
    pub fn is_agent(self) -> bool {
        matches!(self, NodeType::Human | NodeType::Robot)
    }
}

mod inf_as_null {
    use serde::{Deserialize, Deserializer, Serializer};
    pub fn serialize<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
        if v.is_finite() {
            s.serialize_f64(*v)
        } else {
            s.serialize_none()
        }
    }
    pub fn de_neg<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::NEG_INFINITY))
    }
    pub fn de_pos<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
        Ok(Option::<f64>::deserialize(d)?.unwrap_or(f64::INFINITY))
    }
}

/// Joint limits as carried in events and snapshots: infinite limits (continuous joints) are
/// written as `null`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct LimitsSpec {
    /// Lower limit (rad or m); `null` = none.
    #[serde(
        serialize_with = "inf_as_null::serialize",
        deserialize_with = "inf_as_null::de_neg"
    )]
    pub lower: f64,
    /// Upper limit (rad or m); `null` = none.
    #[serde(
        serialize_with = "inf_as_null::serialize",
        deserialize_with = "inf_as_null::de_pos"
    )]
    pub upper: f64,
    /// Velocity limit (rad/s or m/s); `null` = none.
    #[serde(
        serialize_with = "inf_as_null::serialize",
        deserialize_with = "inf_as_null::de_pos"
    )]
    pub velocity: f64,
    /// Effort limit (N m or N); `null` = none.
    #[serde(
        serialize_with = "inf_as_null::serialize",
        deserialize_with = "inf_as_null::de_pos"
    )]
    pub effort: f64,
}

/// How a node hangs from its parent.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "edge", rename_all = "snake_case", deny_unknown_fields)]
pub enum EdgeSpec {
    /// A constant transform `parent_T_child`.
    Fixed {
        /// `parent_T_child`.
        origin: Pose,
    },
    /// A transform updated by perception or odometry (objects, agents).
    Free {
        /// Current `parent_T_child`.
        pose: Pose,
    },
    /// A robot joint: `parent_T_child = origin * motion(value)`.
    Joint {
        /// Joint name (unique in the graph).
        joint: String,
        /// Joint kind (not `fixed`).
        kind: JointKind,
        /// `parent_T_jointframe`.
        origin: Pose,
        /// Axis in the joint frame (normalised on load).
        axis: [f64; 3],
        /// Limits.
        limits: LimitsSpec,
        /// Current value (rad or m).
        value: f64,
    },
}

/// A complete description of one node: what an `AddNode` proposal carries, what a snapshot and a
/// `NodeAdded` event hold.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NodeSpec {
    /// Unique name (also the frame name).
    pub name: String,
    /// A [`NodeType`] name; validated (an unknown type is rejected, not dropped).
    pub node_type: String,
    /// Name of the parent node.
    pub parent: String,
    /// The edge from the parent.
    pub edge: EdgeSpec,
    /// Typed attributes (see [`attr`] for well-known keys).
    #[serde(default)]
    pub attrs: BTreeMap<String, AttrValue>,
    /// Intrinsics, for `camera` nodes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub camera: Option<CameraIntrinsics>,
    /// Collision geometry in the node frame, for `link` nodes.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub collision: Vec<CollisionShape>,
}

impl NodeSpec {
    /// A node with a free pose under `parent` and no attributes.
    pub fn free(name: &str, node_type: NodeType, parent: &str, pose: Pose) -> Self {
        Self {
            name: name.into(),
            node_type: node_type.name().into(),
            parent: parent.into(),
            edge: EdgeSpec::Free { pose },
            attrs: BTreeMap::new(),
            camera: None,
            collision: Vec::new(),
        }
    }
    /// Builder: adds an attribute.
    pub fn with_attr(mut self, key: &str, value: AttrValue) -> Self {
        self.attrs.insert(key.into(), value);
        self
    }
}

/// A structural change, accepted or rejected by the graph's integrity rules.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "proposal", rename_all = "snake_case", deny_unknown_fields)]
pub enum Proposal {
    /// Add a node.
    AddNode {
        /// The node.
        spec: Box<NodeSpec>,
    },
    /// Remove a leaf node (not `world`, not a robot link).
    RemoveNode {
        /// Its name.
        name: String,
    },
    /// Move a node (not `world`, not a robot link) under another parent with a free pose.
    Reparent {
        /// The node.
        name: String,
        /// The new parent.
        new_parent: String,
        /// `new_parent_T_node`.
        pose: Pose,
    },
}

impl Proposal {
    /// `AddNode` for a spec.
    pub fn add(spec: NodeSpec) -> Self {
        Proposal::AddNode {
            spec: Box::new(spec),
        }
    }
}

/// A body part declared for predicates: a chain from a shoulder-like frame to a tip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodyPartSpec {
    /// Name (e.g. `left_arm`).
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

/// One change of the graph, as persisted in the change log. Replaying the events from a snapshot
/// reproduces the graph.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case", deny_unknown_fields)]
pub enum ChangeEvent {
    /// A node was added.
    NodeAdded {
        /// When.
        stamp: Stamp,
        /// The node.
        spec: Box<NodeSpec>,
    },
    /// A node was removed.
    NodeRemoved {
        /// When.
        stamp: Stamp,
        /// Its name.
        name: String,
    },
    /// A node moved under another parent.
    Reparented {
        /// When.
        stamp: Stamp,
        /// The node.
        name: String,
        /// The new parent.
        new_parent: String,
        /// `new_parent_T_node`.
        pose: Pose,
    },
    /// A joint value was set.
    JointSet {
        /// Stamp of the measurement.
        stamp: Stamp,
        /// Joint name.
        joint: String,
        /// Value (rad or m).
        value: f64,
    },
    /// A free pose was set.
    PoseSet {
        /// Stamp of the measurement.
        stamp: Stamp,
        /// Node name.
        node: String,
        /// `parent_T_node`.
        pose: Pose,
    },
    /// An attribute was set.
    AttributeSet {
        /// When.
        stamp: Stamp,
        /// Node name.
        node: String,
        /// Key.
        key: String,
        /// Value.
        value: AttrValue,
    },
    /// A body part was declared.
    BodyPartDeclared {
        /// When.
        stamp: Stamp,
        /// The body part.
        part: BodyPartSpec,
    },
}

impl ChangeEvent {
    /// When it happened.
    pub fn stamp(&self) -> Stamp {
        match self {
            ChangeEvent::NodeAdded { stamp, .. }
            | ChangeEvent::NodeRemoved { stamp, .. }
            | ChangeEvent::Reparented { stamp, .. }
            | ChangeEvent::JointSet { stamp, .. }
            | ChangeEvent::PoseSet { stamp, .. }
            | ChangeEvent::AttributeSet { stamp, .. }
            | ChangeEvent::BodyPartDeclared { stamp, .. } => *stamp,
        }
    }
}

/// Tag of the snapshot format.
pub const SNAPSHOT_FORMAT: &str = "robocog-dr-snapshot";
/// Version of the snapshot format.
pub const SNAPSHOT_VERSION: u32 = 1;

/// The current state of a graph (no history): nodes parents-first, and body parts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Snapshot {
    /// Always [`SNAPSHOT_FORMAT`].
    pub format: String,
    /// [`SNAPSHOT_VERSION`].
    pub version: u32,
    /// Stamp of the newest change included.
    pub stamp: Stamp,
    /// Every node except `world`, each after its parent.
    pub nodes: Vec<NodeSpec>,
    /// Declared body parts.
    #[serde(default)]
    pub body_parts: Vec<BodyPartSpec>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_convert_from_seconds() {
        assert_eq!(Stamp::from_secs_f64(1.5), Stamp(1_500_000_000));
        assert_eq!(Stamp::from_secs_f64(-3.0), Stamp(0));
        assert_eq!(Stamp::from_secs_f64(f64::NAN), Stamp(0));
        assert_eq!(Stamp(2_250_000_000).as_secs_f64(), 2.25);
    }

    #[test]
    fn pose_round_trips_and_validates() {
        let iso = Isometry3::new(
            nalgebra::Vector3::new(1.0, -2.0, 0.5),
            nalgebra::Vector3::new(0.1, 0.2, -0.3),
        );
        let back = Pose::from_iso(&iso).to_iso();
        assert!((back.to_homogeneous() - iso.to_homogeneous()).abs().max() < 1e-15);
        assert!(
            !Pose {
                rotation_xyzw: [0.0; 4],
                ..Pose::default()
            }
            .is_valid()
        );
        assert!(!Pose::from_translation(f64::INFINITY, 0.0, 0.0).is_valid());
        let p = Pose::planar(1.0, 2.0, std::f64::consts::FRAC_PI_2).to_iso();
        assert!((p.rotation * nalgebra::Vector3::x() - nalgebra::Vector3::y()).norm() < 1e-15);
    }

    #[test]
    fn infinite_limits_survive_json_as_null() {
        let l = LimitsSpec {
            lower: f64::NEG_INFINITY,
            upper: f64::INFINITY,
            velocity: 2.0,
            effort: f64::INFINITY,
        };
        let j = serde_json::to_string(&l).unwrap();
        assert_eq!(
            j,
            r#"{"lower":null,"upper":null,"velocity":2.0,"effort":null}"#
        );
        assert_eq!(serde_json::from_str::<LimitsSpec>(&j).unwrap(), l);
    }

    #[test]
    fn change_events_are_tagged_json() {
        let e = ChangeEvent::JointSet {
            stamp: Stamp(5),
            joint: "left_elbow".into(),
            value: -1.0,
        };
        let j = serde_json::to_string(&e).unwrap();
        assert_eq!(
            j,
            r#"{"event":"joint_set","stamp":5,"joint":"left_elbow","value":-1.0}"#
        );
        assert_eq!(serde_json::from_str::<ChangeEvent>(&j).unwrap(), e);
        let typo = r#"{"event":"joint_set","stamp":5,"joint":"a","value":1.0,"vaule":2}"#;
        assert!(
            serde_json::from_str::<ChangeEvent>(typo).is_err(),
            "unknown fields rejected"
        );
    }
}
