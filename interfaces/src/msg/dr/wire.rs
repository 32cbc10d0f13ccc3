//! The wire forms of the DR's types that ROS 2 has no form for as they are: a transform is a
//! `geometry_msgs/Transform`; a tagged union is a message with a `kind` (an integer with a
//! constant per variant) and the fields of every variant, of which those of `kind` count (the
//! others are empty). Sub-messages only one variant has are sequences of zero or one element,
//! so the others do not carry them.

use super::*;
use crate::msg::ros::{self, Vector3};
use crate::wire_form;

fn one<T>(what: &str, mut v: Vec<T>) -> Result<T, String> {
    match v.len() {
        1 => Ok(v.remove(0)),
        n => Err(format!(
            "{what}: {n} elements where its kind has exactly one"
        )),
    }
}

impl From<&Transform> for ros::Transform {
    fn from(t: &Transform) -> Self {
        ros::Transform {
            translation: t.translation_m.into(),
            rotation: t.rotation_xyzw.into(),
        }
    }
}
impl From<ros::Transform> for Transform {
    fn from(t: ros::Transform) -> Self {
        Transform {
            translation_m: t.translation.into(),
            rotation_xyzw: t.rotation.into(),
        }
    }
}
wire_form!(Transform, ros::Transform);

/// Which [`AttrValue`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum AttrKind {
    #[default]
    Bool,
    Int,
    Float,
    Text,
    Vec3,
}

/// [`AttrValue`] on the wire.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(rename = "AttrValue")]
pub struct AttrValueWire {
    pub kind: AttrKind,
    pub bool_value: bool,
    pub int_value: i64,
    pub float_value: f64,
    pub text_value: String,
    pub vec3_value: Vector3,
}

impl From<&AttrValue> for AttrValueWire {
    fn from(v: &AttrValue) -> Self {
        let mut w = AttrValueWire::default();
        match v {
            AttrValue::Bool(b) => w.bool_value = *b,
            AttrValue::Int(i) => (w.kind, w.int_value) = (AttrKind::Int, *i),
            AttrValue::Float(f) => (w.kind, w.float_value) = (AttrKind::Float, *f),
            AttrValue::Text(t) => (w.kind, w.text_value) = (AttrKind::Text, t.clone()),
            AttrValue::Vec3(v) => (w.kind, w.vec3_value) = (AttrKind::Vec3, (*v).into()),
        }
        w
    }
}
impl TryFrom<AttrValueWire> for AttrValue {
    type Error = String;
    fn try_from(w: AttrValueWire) -> Result<Self, String> {
        Ok(match w.kind {
            AttrKind::Bool => AttrValue::Bool(w.bool_value),
            AttrKind::Int => AttrValue::Int(w.int_value),
            AttrKind::Float => AttrValue::Float(w.float_value),
            AttrKind::Text => AttrValue::Text(w.text_value),
            AttrKind::Vec3 => AttrValue::Vec3(w.vec3_value.into()),
        })
    }
}
wire_form!(AttrValue, AttrValueWire);

/// Which [`Edge`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum EdgeKind {
    #[default]
    Fixed,
    Free,
    Joint,
}

/// [`Edge`] on the wire. `transform` is a fixed edge's `origin`, a free edge's `pose`, a
/// joint's `origin`.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(rename = "Edge")]
pub struct EdgeWire {
    pub kind: EdgeKind,
    pub transform: Transform,
    pub joint: String,
    pub joint_kind: JointKind,
    pub axis: Vector3,
    pub limits: JointLimits,
    pub value: f64,
}

impl From<&Edge> for EdgeWire {
    fn from(e: &Edge) -> Self {
        match e {
            Edge::Fixed { origin } => EdgeWire {
                kind: EdgeKind::Fixed,
                transform: *origin,
                ..Default::default()
            },
            Edge::Free { pose } => EdgeWire {
                kind: EdgeKind::Free,
                transform: *pose,
                ..Default::default()
            },
            Edge::Joint {
                joint,
                kind,
                origin,
                axis,
                limits,
                value,
            } => EdgeWire {
                kind: EdgeKind::Joint,
                transform: *origin,
                joint: joint.clone(),
                joint_kind: *kind,
                axis: (*axis).into(),
                limits: *limits,
                value: *value,
            },
        }
    }
}
impl TryFrom<EdgeWire> for Edge {
    type Error = String;
    fn try_from(w: EdgeWire) -> Result<Self, String> {
        Ok(match w.kind {
            EdgeKind::Fixed => Edge::Fixed {
                origin: w.transform,
            },
            EdgeKind::Free => Edge::Free { pose: w.transform },
            EdgeKind::Joint => Edge::Joint {
                joint: w.joint,
                kind: w.joint_kind,
                origin: w.transform,
                axis: w.axis.into(),
                limits: w.limits,
                value: w.value,
            },
        })
    }
}
wire_form!(Edge, EdgeWire);

/// [`Camera`] on the wire: `pinhole` and its intrinsics (default ones when not a camera).
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(rename = "Camera")]
pub struct CameraWire {
    pub pinhole: bool,
    pub intrinsics: CameraIntrinsics,
}

impl From<&Camera> for CameraWire {
    fn from(c: &Camera) -> Self {
        match c {
            Camera::None => CameraWire::default(),
            Camera::Pinhole(i) => CameraWire {
                pinhole: true,
                intrinsics: i.clone(),
            },
        }
    }
}
impl TryFrom<CameraWire> for Camera {
    type Error = String;
    fn try_from(w: CameraWire) -> Result<Self, String> {
        Ok(if w.pinhole {
            Camera::Pinhole(w.intrinsics)
        } else {
            Camera::None
        })
    }
}
wire_form!(Camera, CameraWire);

/// Which [`Shape`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ShapeKind {
    #[default]
    Box,
    Cylinder,
    Capsule,
    Sphere,
    Mesh,
}

/// [`Shape`] on the wire.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(rename = "Shape")]
pub struct ShapeWire {
    pub kind: ShapeKind,
    /// Box.
    pub size_m: Vector3,
    /// Cylinder, capsule, sphere.
    pub radius_m: f64,
    /// Cylinder, capsule.
    pub length_m: f64,
    /// Mesh.
    pub filename: String,
}

impl From<&Shape> for ShapeWire {
    fn from(s: &Shape) -> Self {
        let mut w = ShapeWire::default();
        match s {
            Shape::Box { size_m } => w.size_m = (*size_m).into(),
            Shape::Cylinder { radius_m, length_m } => {
                (w.kind, w.radius_m, w.length_m) = (ShapeKind::Cylinder, *radius_m, *length_m)
            }
            Shape::Capsule { radius_m, length_m } => {
                (w.kind, w.radius_m, w.length_m) = (ShapeKind::Capsule, *radius_m, *length_m)
            }
            Shape::Sphere { radius_m } => (w.kind, w.radius_m) = (ShapeKind::Sphere, *radius_m),
            Shape::Mesh { filename } => (w.kind, w.filename) = (ShapeKind::Mesh, filename.clone()),
        }
        w
    }
}
impl TryFrom<ShapeWire> for Shape {
    type Error = String;
    fn try_from(w: ShapeWire) -> Result<Self, String> {
        Ok(match w.kind {
            ShapeKind::Box => Shape::Box {
                size_m: w.size_m.into(),
            },
            ShapeKind::Cylinder => Shape::Cylinder {
                radius_m: w.radius_m,
                length_m: w.length_m,
            },
            ShapeKind::Capsule => Shape::Capsule {
                radius_m: w.radius_m,
                length_m: w.length_m,
            },
            ShapeKind::Sphere => Shape::Sphere {
                radius_m: w.radius_m,
            },
            ShapeKind::Mesh => Shape::Mesh {
                filename: w.filename,
            },
        })
    }
}
wire_form!(Shape, ShapeWire);

/// Which [`StructuralChange`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum StructuralChangeKind {
    #[default]
    AddNode,
    RemoveNode,
    Reparent,
}

/// [`StructuralChange`] on the wire.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(rename = "StructuralChange")]
pub struct StructuralChangeWire {
    pub kind: StructuralChangeKind,
    /// Add node: the node (one element).
    pub node: Vec<NodeSpec>,
    /// Remove node, reparent: the node's name.
    pub name: String,
    /// Reparent.
    pub new_parent: String,
    /// Reparent: `new_parent_T_node`.
    pub pose: Transform,
}

impl From<&StructuralChange> for StructuralChangeWire {
    fn from(c: &StructuralChange) -> Self {
        match c {
            StructuralChange::AddNode(spec) => StructuralChangeWire {
                kind: StructuralChangeKind::AddNode,
                node: vec![(**spec).clone()],
                ..Default::default()
            },
            StructuralChange::RemoveNode { name } => StructuralChangeWire {
                kind: StructuralChangeKind::RemoveNode,
                name: name.clone(),
                ..Default::default()
            },
            StructuralChange::Reparent {
                name,
                new_parent,
                pose,
            } => StructuralChangeWire {
                kind: StructuralChangeKind::Reparent,
                name: name.clone(),
                new_parent: new_parent.clone(),
                pose: *pose,
                ..Default::default()
            },
        }
    }
}
impl TryFrom<StructuralChangeWire> for StructuralChange {
    type Error = String;
    fn try_from(w: StructuralChangeWire) -> Result<Self, String> {
        Ok(match w.kind {
            StructuralChangeKind::AddNode => {
                StructuralChange::AddNode(Box::new(one("add_node's node", w.node)?))
            }
            StructuralChangeKind::RemoveNode => StructuralChange::RemoveNode { name: w.name },
            StructuralChangeKind::Reparent => StructuralChange::Reparent {
                name: w.name,
                new_parent: w.new_parent,
                pose: w.pose,
            },
        })
    }
}
wire_form!(StructuralChange, StructuralChangeWire);

/// Which [`ChangeEvent`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum ChangeEventKind {
    #[default]
    NodeAdded,
    NodeRemoved,
    Reparented,
    JointSet,
    PoseSet,
    AttributeSet,
    BodyPartDeclared,
    Restored,
}

/// [`ChangeEvent`] on the wire.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(rename = "ChangeEvent")]
pub struct ChangeEventWire {
    pub kind: ChangeEventKind,
    /// Every kind but restored.
    pub stamp_ns: u64,
    /// Node added: its spec (one element).
    pub spec: Vec<NodeSpec>,
    /// Node removed, reparented.
    pub name: String,
    /// Reparented.
    pub new_parent: String,
    /// Reparented (`new_parent_T_node`), pose set (`parent_T_node`).
    pub pose: Transform,
    /// Joint set.
    pub joint: String,
    /// Joint set (rad or m).
    pub value: f64,
    /// Pose set, attribute set.
    pub node: String,
    /// Attribute set.
    pub key: String,
    /// Attribute set (one element).
    pub attribute: Vec<AttrValue>,
    /// Body part declared (one element).
    pub part: Vec<BodyPart>,
}

impl From<&ChangeEvent> for ChangeEventWire {
    fn from(e: &ChangeEvent) -> Self {
        let mut w = ChangeEventWire::default();
        match e {
            ChangeEvent::NodeAdded { stamp_ns, spec } => {
                (w.stamp_ns, w.spec) = (*stamp_ns, vec![(**spec).clone()]);
            }
            ChangeEvent::NodeRemoved { stamp_ns, name } => {
                w.kind = ChangeEventKind::NodeRemoved;
                (w.stamp_ns, w.name) = (*stamp_ns, name.clone());
            }
            ChangeEvent::Reparented {
                stamp_ns,
                name,
                new_parent,
                pose,
            } => {
                w.kind = ChangeEventKind::Reparented;
                (w.stamp_ns, w.name, w.new_parent, w.pose) =
                    (*stamp_ns, name.clone(), new_parent.clone(), *pose);
            }
            ChangeEvent::JointSet {
                stamp_ns,
                joint,
                value,
            } => {
                w.kind = ChangeEventKind::JointSet;
                (w.stamp_ns, w.joint, w.value) = (*stamp_ns, joint.clone(), *value);
            }
            ChangeEvent::PoseSet {
                stamp_ns,
                node,
                pose,
            } => {
                w.kind = ChangeEventKind::PoseSet;
                (w.stamp_ns, w.node, w.pose) = (*stamp_ns, node.clone(), *pose);
            }
            ChangeEvent::AttributeSet {
                stamp_ns,
                node,
                key,
                value,
            } => {
                w.kind = ChangeEventKind::AttributeSet;
                (w.stamp_ns, w.node, w.key, w.attribute) =
                    (*stamp_ns, node.clone(), key.clone(), vec![value.clone()]);
            }
            ChangeEvent::BodyPartDeclared { stamp_ns, part } => {
                w.kind = ChangeEventKind::BodyPartDeclared;
                (w.stamp_ns, w.part) = (*stamp_ns, vec![part.clone()]);
            }
            ChangeEvent::Restored => w.kind = ChangeEventKind::Restored,
        }
        w
    }
}
impl TryFrom<ChangeEventWire> for ChangeEvent {
    type Error = String;
    fn try_from(w: ChangeEventWire) -> Result<Self, String> {
        let stamp_ns = w.stamp_ns;
        Ok(match w.kind {
            ChangeEventKind::NodeAdded => ChangeEvent::NodeAdded {
                stamp_ns,
                spec: Box::new(one("node_added's spec", w.spec)?),
            },
            ChangeEventKind::NodeRemoved => ChangeEvent::NodeRemoved {
                stamp_ns,
                name: w.name,
            },
            ChangeEventKind::Reparented => ChangeEvent::Reparented {
                stamp_ns,
                name: w.name,
                new_parent: w.new_parent,
                pose: w.pose,
            },
            ChangeEventKind::JointSet => ChangeEvent::JointSet {
                stamp_ns,
                joint: w.joint,
                value: w.value,
            },
            ChangeEventKind::PoseSet => ChangeEvent::PoseSet {
                stamp_ns,
                node: w.node,
                pose: w.pose,
            },
            ChangeEventKind::AttributeSet => ChangeEvent::AttributeSet {
                stamp_ns,
                node: w.node,
                key: w.key,
                value: one("attribute_set's attribute", w.attribute)?,
            },
            ChangeEventKind::BodyPartDeclared => ChangeEvent::BodyPartDeclared {
                stamp_ns,
                part: one("body_part_declared's part", w.part)?,
            },
            ChangeEventKind::Restored => ChangeEvent::Restored,
        })
    }
}
wire_form!(ChangeEvent, ChangeEventWire);
