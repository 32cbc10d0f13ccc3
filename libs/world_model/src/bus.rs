//! What a node description, a structural change, a change event or a snapshot from outside (the
//! bus, a state folder) must hold before the graph takes it, beyond what the integrity rules of
//! [`crate::SceneGraph::propose`] check; and the bus forms of facts and rejections.
//!
//! The DR's data types are the bus' own (`interfaces::msg::dr`, see [`crate::types`]): there is
//! nothing to convert. What CDR can carry but the graph cannot hold is refused here with an
//! [`InvalidSpec`]: an attribute key given twice, a number that is not finite where the graph
//! needs one (attributes, intrinsics, collision shapes; NaN in a joint limit, where only
//! infinity means "no limit"), and the `Restored` event. Names, types, parents, poses and joint
//! axes are the integrity rules' business.

use std::collections::BTreeSet;

use interfaces::msg::dr as m;

use crate::graph::RejectReason;
use crate::predicates;
use crate::types::{AttrValue, Camera, ChangeEvent, Edge, NodeSpec, Shape, Snapshot};

/// Why a node description, change or snapshot is not one the graph can hold.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum InvalidSpec {
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

fn not_finite(node: &str, what: impl Into<String>) -> InvalidSpec {
    InvalidSpec::NotFinite {
        node: node.to_string(),
        what: what.into(),
    }
}

fn attribute(node: &str, key: &str, value: &AttrValue) -> Result<(), InvalidSpec> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(not_finite(node, format!("attribute `{key}`")))
    }
}

/// Checks a node description: attributes finite and each key once, no NaN joint limit, finite
/// intrinsics, collision shapes with finite sizes and a valid origin.
pub fn check_node(s: &NodeSpec) -> Result<(), InvalidSpec> {
    let node = s.name.as_str();
    let mut keys = BTreeSet::new();
    for a in &s.attributes {
        attribute(node, &a.key, &a.value)?;
        if !keys.insert(a.key.as_str()) {
            return Err(InvalidSpec::DuplicateAttribute {
                node: node.to_string(),
                key: a.key.clone(),
            });
        }
    }
    if let Edge::Joint { joint, limits, .. } = &s.edge {
        let l = [limits.lower, limits.upper, limits.velocity, limits.effort];
        if l.iter().any(|v| v.is_nan()) {
            return Err(not_finite(
                node,
                format!("a limit of joint `{joint}` (NaN)"),
            ));
        }
    }
    if let Camera::Pinhole(c) = &s.camera {
        let numbers = [c.fx, c.fy, c.cx, c.cy, c.min_range_m, c.max_range_m];
        if !numbers.iter().all(|v| v.is_finite()) {
            return Err(not_finite(node, "a camera intrinsic or range"));
        }
    }
    for c in &s.collision {
        let sizes: &[f64] = match &c.shape {
            Shape::Box { size_m } => size_m,
            Shape::Cylinder { radius_m, length_m } | Shape::Capsule { radius_m, length_m } => {
                &[*radius_m, *length_m]
            }
            Shape::Sphere { radius_m } => &[*radius_m],
            Shape::Mesh { .. } => &[],
        };
        if !c.origin.is_valid() || !sizes.iter().all(|v| v.is_finite()) {
            return Err(not_finite(
                node,
                "a collision shape (its origin or size; or a zero quaternion)",
            ));
        }
    }
    Ok(())
}

/// Checks a structural change (the node an `AddNode` adds).
pub fn check_change(c: &m::StructuralChange) -> Result<(), InvalidSpec> {
    match c {
        m::StructuralChange::AddNode(spec) => check_node(spec),
        m::StructuralChange::RemoveNode { .. } | m::StructuralChange::Reparent { .. } => Ok(()),
    }
}

/// Checks a change event before it is applied (a logged one, one seen on `dr/changes`).
pub fn check_event(e: &ChangeEvent) -> Result<(), InvalidSpec> {
    match e {
        ChangeEvent::NodeAdded { spec, .. } => check_node(spec),
        ChangeEvent::AttributeSet {
            node, key, value, ..
        } => attribute(node, key, value),
        ChangeEvent::Restored => Err(InvalidSpec::Restored),
        ChangeEvent::NodeRemoved { .. }
        | ChangeEvent::Reparented { .. }
        | ChangeEvent::JointSet { .. }
        | ChangeEvent::PoseSet { .. }
        | ChangeEvent::BodyPartDeclared { .. } => Ok(()),
    }
}

/// Checks every node of a snapshot; whether they make a graph is
/// [`crate::SceneGraph::restore`]'s to check.
pub fn check_snapshot(s: &Snapshot) -> Result<(), InvalidSpec> {
    s.nodes.iter().try_for_each(check_node)
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
        RejectReason::InvalidSpec(_) => "invalid_spec",
    }
}

#[cfg(test)]
mod tests;
