//! The description of a node of the deep representation: transforms, attribute values, joints
//! and their limits, edges, cameras, collision shapes, and [`NodeSpec`], which holds them all.

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
/// message with the variant's `kind` and a field per variant ([`super::wire::AttrValueWire`]).
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

/// How a node hangs from its parent. On the wire: [`super::wire::EdgeWire`].
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

/// The camera of a node, for `camera` nodes. On the wire: [`super::wire::CameraWire`].
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

/// Collision geometry, centred on its origin (m). On the wire: [`super::wire::ShapeWire`].
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
