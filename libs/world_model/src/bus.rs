//! The one place where the library's types meet the bus messages of `interfaces::msg::dr`.
//!
//! Every DR message is typed on the bus: a node description, a structural change, a change
//! event and a snapshot each have a CDR-friendly mirror in `interfaces::msg::dr` (no `Option`,
//! no maps: an optional camera is an enum, attributes a list of key/value pairs, stamps u64 ns).
//! This module converts both ways, so the service, its mirror in the viewer and the tests all
//! read and write them alike:
//!
//! | library ([`crate::types`]) | bus (`interfaces::msg::dr`) |
//! |---|---|
//! | [`Pose`] | `Transform` |
//! | [`AttrValue`] | `AttrValue` |
//! | [`NodeSpec`] ([`EdgeSpec`], [`LimitsSpec`], camera, collision) | `NodeSpec` (`Edge`, `JointLimits`, `Camera`, `CollisionShape`) |
//! | [`Proposal`] | `StructuralChange` |
//! | [`ChangeEvent`] | `ChangeEvent` (plus `Restored`, which is no library event) |
//! | [`BodyPartSpec`] | `BodyPart` |
//! | [`Snapshot`] | `Snapshot` (the format tag and version are the library's constants) |
//! | [`predicates::Fact`] | `Fact` |
//!
//! Library to bus is total (`From`). Bus to library is `TryFrom`, with a [`FromBusError`] for
//! what the library's types or its state folder cannot hold: an attribute key given twice, a
//! number that is not finite where the library needs one (attributes, intrinsics, collision
//! shapes; NaN in a joint limit, where only infinity means "no limit"), and the `Restored`
//! event. Everything else (names, types, parents, poses, joint axes) is the integrity rules'
//! business: [`crate::SceneGraph::propose`] and [`crate::SceneGraph::restore`] check it.
//! Conversions copy numbers as they are (a collision origin's quaternion is not renormalised),
//! so library -> bus -> library gives back an equal value.

use std::collections::BTreeMap;

use interfaces::msg::dr as m;
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion};
use robot_model::{CameraIntrinsics, CollisionShape, JointKind, Shape};

use crate::graph::RejectReason;
use crate::predicates;
use crate::types::{
    AttrValue, BodyPartSpec, ChangeEvent, EdgeSpec, LimitsSpec, NodeSpec, Pose, Proposal,
    SNAPSHOT_FORMAT, SNAPSHOT_VERSION, Snapshot, Stamp,
};

/// Why a bus message does not convert into the library's type.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FromBusError {
    /// A node description names an attribute twice.
    #[error("node `{node}`: attribute `{key}` is given twice")]
    DuplicateAttribute {
        /// The node.
        node: String,
        /// The key.
        key: String,
    },
    /// A number that must be finite is not (NaN or infinite).
    #[error("node `{node}`: {what} is not finite")]
    NotFinite {
        /// The node.
        node: String,
        /// Which number (an attribute, a joint limit, an intrinsic, a collision shape).
        what: String,
    },
    /// `Restored` is not a change of the graph: the whole graph was replaced.
    #[error("a `restored` change replaces the whole graph; ask `dr/snapshot` for it")]
    Restored,
}

fn not_finite(node: &str, what: impl Into<String>) -> FromBusError {
    FromBusError::NotFinite {
        node: node.to_string(),
        what: what.into(),
    }
}

// ---------------------------------------------------------------- poses and values

impl From<&Pose> for m::Transform {
    fn from(p: &Pose) -> Self {
        m::Transform {
            translation_m: p.translation_m,
            rotation_xyzw: p.rotation_xyzw,
        }
    }
}

impl From<&m::Transform> for Pose {
    fn from(t: &m::Transform) -> Self {
        Pose {
            translation_m: t.translation_m,
            rotation_xyzw: t.rotation_xyzw,
        }
    }
}

/// A nalgebra isometry (a transform the graph computed) as a bus transform.
pub fn transform_from_iso(iso: &Isometry3<f64>) -> m::Transform {
    m::Transform::from(&Pose::from_iso(iso))
}

/// A bus transform as an isometry, the quaternion taken as it is (not renormalised), as the
/// library's serde does for collision origins.
fn iso_from_transform(t: &m::Transform) -> Isometry3<f64> {
    let [x, y, z, w] = t.rotation_xyzw;
    let [tx, ty, tz] = t.translation_m;
    Isometry3::from_parts(
        Translation3::new(tx, ty, tz),
        UnitQuaternion::new_unchecked(Quaternion::new(w, x, y, z)),
    )
}

impl From<&AttrValue> for m::AttrValue {
    fn from(v: &AttrValue) -> Self {
        match v {
            AttrValue::Bool(b) => m::AttrValue::Bool(*b),
            AttrValue::Int(i) => m::AttrValue::Int(*i),
            AttrValue::Float(f) => m::AttrValue::Float(*f),
            AttrValue::Text(t) => m::AttrValue::Text(t.clone()),
            AttrValue::Vec3(v) => m::AttrValue::Vec3(*v),
        }
    }
}

/// Any value converts; whether its numbers are finite is `m::AttrValue::is_finite`, which the
/// conversions of whole nodes and events check.
impl From<&m::AttrValue> for AttrValue {
    fn from(v: &m::AttrValue) -> Self {
        match v {
            m::AttrValue::Bool(b) => AttrValue::Bool(*b),
            m::AttrValue::Int(i) => AttrValue::Int(*i),
            m::AttrValue::Float(f) => AttrValue::Float(*f),
            m::AttrValue::Text(t) => AttrValue::Text(t.clone()),
            m::AttrValue::Vec3(v) => AttrValue::Vec3(*v),
        }
    }
}

// ---------------------------------------------------------------- node descriptions

// (robot_model's types: free functions, not `From`, which the orphan rule forbids here.)

fn joint_kind_to_msg(k: JointKind) -> m::JointKind {
    match k {
        JointKind::Revolute => m::JointKind::Revolute,
        JointKind::Continuous => m::JointKind::Continuous,
        JointKind::Prismatic => m::JointKind::Prismatic,
        JointKind::Fixed => m::JointKind::Fixed,
    }
}

fn joint_kind(k: m::JointKind) -> JointKind {
    match k {
        m::JointKind::Revolute => JointKind::Revolute,
        m::JointKind::Continuous => JointKind::Continuous,
        m::JointKind::Prismatic => JointKind::Prismatic,
        m::JointKind::Fixed => JointKind::Fixed,
    }
}

impl From<&EdgeSpec> for m::Edge {
    fn from(e: &EdgeSpec) -> Self {
        match e {
            EdgeSpec::Fixed { origin } => m::Edge::Fixed {
                origin: origin.into(),
            },
            EdgeSpec::Free { pose } => m::Edge::Free { pose: pose.into() },
            EdgeSpec::Joint {
                joint,
                kind,
                origin,
                axis,
                limits,
                value,
            } => m::Edge::Joint {
                joint: joint.clone(),
                kind: joint_kind_to_msg(*kind),
                origin: origin.into(),
                axis: *axis,
                limits: m::JointLimits {
                    lower: limits.lower,
                    upper: limits.upper,
                    velocity: limits.velocity,
                    effort: limits.effort,
                },
                value: *value,
            },
        }
    }
}

fn edge_from_msg(node: &str, e: &m::Edge) -> Result<EdgeSpec, FromBusError> {
    Ok(match e {
        m::Edge::Fixed { origin } => EdgeSpec::Fixed {
            origin: origin.into(),
        },
        m::Edge::Free { pose } => EdgeSpec::Free { pose: pose.into() },
        m::Edge::Joint {
            joint,
            kind,
            origin,
            axis,
            limits,
            value,
        } => {
            let l = [limits.lower, limits.upper, limits.velocity, limits.effort];
            if l.iter().any(|v| v.is_nan()) {
                return Err(not_finite(
                    node,
                    format!("a limit of joint `{joint}` (NaN)"),
                ));
            }
            EdgeSpec::Joint {
                joint: joint.clone(),
                kind: joint_kind(*kind),
                origin: origin.into(),
                axis: *axis,
                limits: LimitsSpec {
                    lower: limits.lower,
                    upper: limits.upper,
                    velocity: limits.velocity,
                    effort: limits.effort,
                },
                value: *value,
            }
        }
    })
}

fn camera_to_msg(c: &CameraIntrinsics) -> m::CameraIntrinsics {
    m::CameraIntrinsics {
        name: c.name.clone(),
        frame: c.frame.clone(),
        width: c.width,
        height: c.height,
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
        min_range_m: c.min_range_m,
        max_range_m: c.max_range_m,
    }
}

fn camera_from_msg(node: &str, c: &m::Camera) -> Result<Option<CameraIntrinsics>, FromBusError> {
    let m::Camera::Pinhole(c) = c else {
        return Ok(None);
    };
    let numbers = [c.fx, c.fy, c.cx, c.cy, c.min_range_m, c.max_range_m];
    if !numbers.iter().all(|v| v.is_finite()) {
        return Err(not_finite(node, "a camera intrinsic or range"));
    }
    Ok(Some(CameraIntrinsics {
        name: c.name.clone(),
        frame: c.frame.clone(),
        width: c.width,
        height: c.height,
        fx: c.fx,
        fy: c.fy,
        cx: c.cx,
        cy: c.cy,
        min_range_m: c.min_range_m,
        max_range_m: c.max_range_m,
    }))
}

fn shape_to_msg(s: &Shape) -> m::Shape {
    match s {
        Shape::Box { size_m } => m::Shape::Box { size_m: *size_m },
        Shape::Cylinder { radius_m, length_m } => m::Shape::Cylinder {
            radius_m: *radius_m,
            length_m: *length_m,
        },
        Shape::Capsule { radius_m, length_m } => m::Shape::Capsule {
            radius_m: *radius_m,
            length_m: *length_m,
        },
        Shape::Sphere { radius_m } => m::Shape::Sphere {
            radius_m: *radius_m,
        },
        Shape::Mesh { filename } => m::Shape::Mesh {
            filename: filename.clone(),
        },
    }
}

fn collision_to_msg(c: &CollisionShape) -> m::CollisionShape {
    m::CollisionShape {
        origin: transform_from_iso(&c.origin),
        shape: shape_to_msg(&c.shape),
    }
}

fn collision_from_msg(node: &str, c: &m::CollisionShape) -> Result<CollisionShape, FromBusError> {
    let (shape, numbers): (Shape, Vec<f64>) = match &c.shape {
        m::Shape::Box { size_m } => (Shape::Box { size_m: *size_m }, size_m.to_vec()),
        m::Shape::Cylinder { radius_m, length_m } => (
            Shape::Cylinder {
                radius_m: *radius_m,
                length_m: *length_m,
            },
            vec![*radius_m, *length_m],
        ),
        m::Shape::Capsule { radius_m, length_m } => (
            Shape::Capsule {
                radius_m: *radius_m,
                length_m: *length_m,
            },
            vec![*radius_m, *length_m],
        ),
        m::Shape::Sphere { radius_m } => (
            Shape::Sphere {
                radius_m: *radius_m,
            },
            vec![*radius_m],
        ),
        m::Shape::Mesh { filename } => (
            Shape::Mesh {
                filename: filename.clone(),
            },
            Vec::new(),
        ),
    };
    if !Pose::from(&c.origin).is_valid() || !numbers.iter().all(|v| v.is_finite()) {
        return Err(not_finite(
            node,
            "a collision shape (its origin or size; or a zero quaternion)",
        ));
    }
    Ok(CollisionShape {
        origin: iso_from_transform(&c.origin),
        shape,
    })
}

impl From<&NodeSpec> for m::NodeSpec {
    fn from(s: &NodeSpec) -> Self {
        m::NodeSpec {
            name: s.name.clone(),
            node_type: s.node_type.clone(),
            parent: s.parent.clone(),
            edge: (&s.edge).into(),
            attributes: s
                .attrs
                .iter()
                .map(|(key, value)| m::KeyValue {
                    key: key.clone(),
                    value: value.into(),
                })
                .collect(),
            camera: s
                .camera
                .as_ref()
                .map_or(m::Camera::None, |c| m::Camera::Pinhole(camera_to_msg(c))),
            collision: s.collision.iter().map(collision_to_msg).collect(),
        }
    }
}

impl TryFrom<&m::NodeSpec> for NodeSpec {
    type Error = FromBusError;

    fn try_from(s: &m::NodeSpec) -> Result<Self, FromBusError> {
        let node = s.name.as_str();
        let mut attrs = BTreeMap::new();
        for a in &s.attributes {
            if !a.value.is_finite() {
                return Err(not_finite(node, format!("attribute `{}`", a.key)));
            }
            if attrs.insert(a.key.clone(), (&a.value).into()).is_some() {
                return Err(FromBusError::DuplicateAttribute {
                    node: node.to_string(),
                    key: a.key.clone(),
                });
            }
        }
        Ok(NodeSpec {
            name: s.name.clone(),
            node_type: s.node_type.clone(),
            parent: s.parent.clone(),
            edge: edge_from_msg(node, &s.edge)?,
            attrs,
            camera: camera_from_msg(node, &s.camera)?,
            collision: s
                .collision
                .iter()
                .map(|c| collision_from_msg(node, c))
                .collect::<Result<_, _>>()?,
        })
    }
}

// ---------------------------------------------------------------- changes

impl From<&Proposal> for m::StructuralChange {
    fn from(p: &Proposal) -> Self {
        match p {
            Proposal::AddNode { spec } => {
                m::StructuralChange::AddNode(Box::new(spec.as_ref().into()))
            }
            Proposal::RemoveNode { name } => m::StructuralChange::RemoveNode { name: name.clone() },
            Proposal::Reparent {
                name,
                new_parent,
                pose,
            } => m::StructuralChange::Reparent {
                name: name.clone(),
                new_parent: new_parent.clone(),
                pose: pose.into(),
            },
        }
    }
}

impl TryFrom<&m::StructuralChange> for Proposal {
    type Error = FromBusError;

    fn try_from(c: &m::StructuralChange) -> Result<Self, FromBusError> {
        Ok(match c {
            m::StructuralChange::AddNode(spec) => Proposal::add(spec.as_ref().try_into()?),
            m::StructuralChange::RemoveNode { name } => Proposal::RemoveNode { name: name.clone() },
            m::StructuralChange::Reparent {
                name,
                new_parent,
                pose,
            } => Proposal::Reparent {
                name: name.clone(),
                new_parent: new_parent.clone(),
                pose: pose.into(),
            },
        })
    }
}

impl From<&BodyPartSpec> for m::BodyPart {
    fn from(b: &BodyPartSpec) -> Self {
        m::BodyPart {
            name: b.name.clone(),
            robot: b.robot.clone(),
            base_frame: b.base_frame.clone(),
            tip_frame: b.tip_frame.clone(),
            reach_m: b.reach_m,
        }
    }
}

impl From<&m::BodyPart> for BodyPartSpec {
    fn from(b: &m::BodyPart) -> Self {
        BodyPartSpec {
            name: b.name.clone(),
            robot: b.robot.clone(),
            base_frame: b.base_frame.clone(),
            tip_frame: b.tip_frame.clone(),
            reach_m: b.reach_m,
        }
    }
}

impl From<&ChangeEvent> for m::ChangeEvent {
    fn from(e: &ChangeEvent) -> Self {
        match e {
            ChangeEvent::NodeAdded { stamp, spec } => m::ChangeEvent::NodeAdded {
                stamp_ns: stamp.0,
                spec: Box::new(spec.as_ref().into()),
            },
            ChangeEvent::NodeRemoved { stamp, name } => m::ChangeEvent::NodeRemoved {
                stamp_ns: stamp.0,
                name: name.clone(),
            },
            ChangeEvent::Reparented {
                stamp,
                name,
                new_parent,
                pose,
            } => m::ChangeEvent::Reparented {
                stamp_ns: stamp.0,
                name: name.clone(),
                new_parent: new_parent.clone(),
                pose: pose.into(),
            },
            ChangeEvent::JointSet {
                stamp,
                joint,
                value,
            } => m::ChangeEvent::JointSet {
                stamp_ns: stamp.0,
                joint: joint.clone(),
                value: *value,
            },
            ChangeEvent::PoseSet { stamp, node, pose } => m::ChangeEvent::PoseSet {
                stamp_ns: stamp.0,
                node: node.clone(),
                pose: pose.into(),
            },
            ChangeEvent::AttributeSet {
                stamp,
                node,
                key,
                value,
            } => m::ChangeEvent::AttributeSet {
                stamp_ns: stamp.0,
                node: node.clone(),
                key: key.clone(),
                value: value.into(),
            },
            ChangeEvent::BodyPartDeclared { stamp, part } => m::ChangeEvent::BodyPartDeclared {
                stamp_ns: stamp.0,
                part: part.into(),
            },
        }
    }
}

impl TryFrom<&m::ChangeEvent> for ChangeEvent {
    type Error = FromBusError;

    fn try_from(e: &m::ChangeEvent) -> Result<Self, FromBusError> {
        Ok(match e {
            m::ChangeEvent::NodeAdded { stamp_ns, spec } => ChangeEvent::NodeAdded {
                stamp: Stamp(*stamp_ns),
                spec: Box::new(spec.as_ref().try_into()?),
            },
            m::ChangeEvent::NodeRemoved { stamp_ns, name } => ChangeEvent::NodeRemoved {
                stamp: Stamp(*stamp_ns),
                name: name.clone(),
            },
            m::ChangeEvent::Reparented {
                stamp_ns,
                name,
                new_parent,
                pose,
            } => ChangeEvent::Reparented {
                stamp: Stamp(*stamp_ns),
                name: name.clone(),
                new_parent: new_parent.clone(),
                pose: pose.into(),
            },
            m::ChangeEvent::JointSet {
                stamp_ns,
                joint,
                value,
            } => ChangeEvent::JointSet {
                stamp: Stamp(*stamp_ns),
                joint: joint.clone(),
                value: *value,
            },
            m::ChangeEvent::PoseSet {
                stamp_ns,
                node,
                pose,
            } => ChangeEvent::PoseSet {
                stamp: Stamp(*stamp_ns),
                node: node.clone(),
                pose: pose.into(),
            },
            m::ChangeEvent::AttributeSet {
                stamp_ns,
                node,
                key,
                value,
            } => {
                if !value.is_finite() {
                    return Err(not_finite(node, format!("attribute `{key}`")));
                }
                ChangeEvent::AttributeSet {
                    stamp: Stamp(*stamp_ns),
                    node: node.clone(),
                    key: key.clone(),
                    value: value.into(),
                }
            }
            m::ChangeEvent::BodyPartDeclared { stamp_ns, part } => ChangeEvent::BodyPartDeclared {
                stamp: Stamp(*stamp_ns),
                part: part.into(),
            },
            m::ChangeEvent::Restored => return Err(FromBusError::Restored),
        })
    }
}

// ---------------------------------------------------------------- snapshots and facts

impl From<&Snapshot> for m::Snapshot {
    fn from(s: &Snapshot) -> Self {
        m::Snapshot {
            stamp_ns: s.stamp.0,
            nodes: s.nodes.iter().map(Into::into).collect(),
            body_parts: s.body_parts.iter().map(Into::into).collect(),
        }
    }
}

/// The library snapshot, tagged with [`SNAPSHOT_FORMAT`] and [`SNAPSHOT_VERSION`]; whether its
/// nodes make a graph is [`crate::SceneGraph::restore`]'s to check.
impl TryFrom<&m::Snapshot> for Snapshot {
    type Error = FromBusError;

    fn try_from(s: &m::Snapshot) -> Result<Self, FromBusError> {
        Ok(Snapshot {
            format: SNAPSHOT_FORMAT.into(),
            version: SNAPSHOT_VERSION,
            stamp: Stamp(s.stamp_ns),
            nodes: s
                .nodes
                .iter()
                .map(NodeSpec::try_from)
                .collect::<Result<_, _>>()?,
            body_parts: s.body_parts.iter().map(Into::into).collect(),
        })
    }
}

impl From<&predicates::Fact> for m::Fact {
    fn from(f: &predicates::Fact) -> Self {
        m::Fact {
            predicate: f.kind.name().into(),
            args: f.args.clone(),
        }
    }
}

/// The snake_case code of a rejection (a `dr/propose` reply's `reason_code`).
pub fn reason_code(r: &RejectReason) -> &'static str {
    match r {
        RejectReason::DuplicateName(_) => "duplicate_name",
        RejectReason::InvalidName(_) => "invalid_name",
        RejectReason::UnknownParent(_) => "unknown_parent",
        RejectReason::UnknownNode(_) => "unknown_node",
        RejectReason::UnknownType(..) => "unknown_type",
        RejectReason::Cycle { .. } => "cycle",
        RejectReason::HasChildren(..) => "has_children",
        RejectReason::Protected(..) => "protected",
        RejectReason::InvalidGeometry(_) => "invalid_geometry",
        RejectReason::DuplicateJoint(_) => "duplicate_joint",
    }
}

#[cfg(test)]
mod tests;
