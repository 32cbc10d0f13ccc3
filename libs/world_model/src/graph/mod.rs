//! The scene graph: typed nodes joined by rigid-transform edges, with a short history per edge.
//!
//! See the crate docs for frames, node types and the time model. In short:
//! - Every node is a frame; its edge gives `parent_T_node` (fixed, free, or a robot joint).
//! - [`SceneGraph::transform`]`(target, source, at)` returns `target_T_source`, so that
//!   `p_target = target_T_source * p_source`.
//! - Edges keep up to [`SceneGraph::history_len`] timed samples; a query at a past time
//!   interpolates between the two samples around it (linear for joint values and translations,
//!   slerp for rotations), holds the newest sample for times after it, and fails with
//!   [`DrError::TimeOutOfHistory`] for times before the oldest one kept.
//! - Structural changes go through [`SceneGraph::propose`] and its integrity rules; joint values,
//!   poses and attributes go straight in.

use std::collections::{BTreeMap, HashMap, VecDeque};

use nalgebra::{Isometry3, Point3, Translation3, Unit, Vector3};

use crate::error::{DrError, Result};
use crate::types::{
    AttrValue, BodyPart, Camera, CameraIntrinsics, ChangeEvent, CollisionShape, Edge, JointKind,
    JointLimits, KeyValue, NodeSpec, NodeType, Snapshot, Stamp, StructuralChange, Transform,
    TransformIso, attr,
};
use robot_model::{Chain, RobotModel, joint_motion};

mod snapshot;
pub use snapshot::{SNAPSHOT_FORMAT, SNAPSHOT_VERSION};
mod structure;

/// Name of the root node.
pub const WORLD: &str = "world";

/// Index of a node in its graph (stable while the node exists; not reused within one graph's
/// lifetime except after a snapshot restore).
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId(pub u32);

/// Which time a transform query refers to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum At {
    /// The newest value of every edge.
    Latest,
    /// The state at this stamp (interpolated from the edge histories).
    Time(Stamp),
}

/// The kind of an edge.
#[derive(Debug, Clone, PartialEq)]
pub enum EdgeKind {
    /// Constant transform.
    Fixed,
    /// Transform set by perception / odometry.
    Free,
    /// Robot joint.
    Joint {
        /// Joint name.
        joint: String,
        /// Kind (never `Fixed`).
        kind: JointKind,
        /// Unit axis in the joint frame.
        axis: Unit<Vector3<f64>>,
        /// Limits.
        limits: JointLimits,
    },
}

#[derive(Debug, Clone, Copy)]
struct Sample {
    stamp: Stamp,
    value: f64,
    transform: Isometry3<f64>,
}

/// The edge from a node's parent to the node.
#[derive(Debug, Clone)]
pub struct EdgeState {
    /// Kind.
    pub kind: EdgeKind,
    /// Fixed part: for fixed edges the whole transform, for joints the origin, identity for free.
    pub origin: Isometry3<f64>,
    value: f64,
    current: Isometry3<f64>,
    history: VecDeque<Sample>,
}

impl EdgeState {
    /// Current `parent_T_node`.
    pub fn current(&self) -> &Isometry3<f64> {
        &self.current
    }
    /// Current joint value (rad or m); 0 for non-joint edges.
    pub fn value(&self) -> f64 {
        self.value
    }

    fn motion(&self, v: f64) -> Isometry3<f64> {
        match &self.kind {
            EdgeKind::Joint { kind, axis, .. } => self.origin * joint_motion(*kind, axis, v),
            _ => self.origin,
        }
    }

    fn at(&self, frame: &str, t: Stamp) -> Result<Isometry3<f64>> {
        if matches!(self.kind, EdgeKind::Fixed) || self.history.is_empty() {
            return Ok(self.current);
        }
        let idx = self.history.partition_point(|s| s.stamp <= t);
        if idx == 0 {
            let oldest = self.history.front().map_or(0, |s| s.stamp.0);
            return Err(DrError::TimeOutOfHistory {
                frame: frame.to_string(),
                requested_ns: t.0,
                oldest_ns: oldest,
            });
        }
        let a = &self.history[idx - 1];
        let Some(b) = self.history.get(idx) else {
            return Ok(a.transform);
        };
        if a.stamp == t {
            return Ok(a.transform);
        }
        let f = (t.0 - a.stamp.0) as f64 / (b.stamp.0 - a.stamp.0) as f64;
        Ok(match &self.kind {
            EdgeKind::Joint { .. } => self.motion(a.value + f * (b.value - a.value)),
            _ => a.transform.lerp_slerp(&b.transform, f),
        })
    }

    fn push(&mut self, cap: usize, stamp: Stamp, value: f64, transform: Isometry3<f64>) {
        let s = Sample {
            stamp,
            value,
            transform,
        };
        let newest = self.history.back().is_none_or(|b| b.stamp <= stamp);
        if newest {
            self.value = value;
            self.current = transform;
            if self.history.back().is_some_and(|b| b.stamp == stamp) {
                self.history.pop_back();
            }
            self.history.push_back(s);
        } else {
            let idx = self.history.partition_point(|x| x.stamp <= stamp);
            if idx > 0 && self.history[idx - 1].stamp == stamp {
                self.history[idx - 1] = s;
            } else {
                self.history.insert(idx, s);
            }
        }
        while self.history.len() > cap.max(1) {
            self.history.pop_front();
        }
    }
}

/// A node: a frame with a type, attributes, and its edge from the parent.
#[derive(Debug, Clone)]
pub struct Node {
    /// Unique name.
    pub name: String,
    /// Type.
    pub node_type: NodeType,
    /// Parent (`None` only for `world`).
    pub parent: Option<NodeId>,
    /// Children.
    pub children: Vec<NodeId>,
    /// Typed attributes.
    pub attrs: BTreeMap<String, AttrValue>,
    /// Intrinsics of a camera node.
    pub camera: Option<CameraIntrinsics>,
    /// Collision geometry of a link node.
    pub collision: Vec<CollisionShape>,
    /// EdgeState from the parent.
    pub edge: EdgeState,
    depth: u32,
}

impl Node {
    /// A float attribute.
    pub fn float(&self, key: &str) -> Option<f64> {
        match self.attrs.get(key) {
            Some(AttrValue::Float(v)) => Some(*v),
            Some(AttrValue::Int(v)) => Some(*v as f64),
            _ => None,
        }
    }
    /// A boolean attribute.
    pub fn flag(&self, key: &str) -> Option<bool> {
        match self.attrs.get(key) {
            Some(AttrValue::Bool(v)) => Some(*v),
            _ => None,
        }
    }
    /// An integer attribute.
    pub fn int(&self, key: &str) -> Option<i64> {
        match self.attrs.get(key) {
            Some(AttrValue::Int(v)) => Some(*v),
            _ => None,
        }
    }
}

/// Why a structural proposal was rejected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RejectReason {
    /// The name is already used by another node.
    #[error("name `{0}` is already used")]
    DuplicateName(String),
    /// The name is empty or contains whitespace or parentheses.
    #[error("name `{0}` is not valid (non-empty, no whitespace, no parentheses)")]
    InvalidName(String),
    /// The parent named in the proposal does not exist.
    #[error("parent `{0}` does not exist")]
    UnknownParent(String),
    /// The node named in the proposal does not exist.
    #[error("node `{0}` does not exist")]
    UnknownNode(String),
    /// The node type is not a known [`NodeType`] (or `world`, which is unique).
    #[error("node type `{0}` is not known (known: {1})")]
    UnknownType(String, String),
    /// The change would make a node its own ancestor.
    #[error("moving `{node}` under `{new_parent}` would create a cycle")]
    Cycle {
        /// The node moved.
        node: String,
        /// The proposed parent.
        new_parent: String,
    },
    /// The node still has children; remove them first.
    #[error("`{0}` still has children ({1})")]
    HasChildren(String, String),
    /// `world` and robot links cannot be removed or moved by proposals.
    #[error("`{0}` is structural ({1}) and cannot be removed or moved")]
    Protected(String, &'static str),
    /// A pose, joint axis or value that is not finite.
    #[error("invalid geometry: {0}")]
    InvalidGeometry(String),
    /// A joint name that is already used.
    #[error("joint `{0}` already exists")]
    DuplicateJoint(String),
    /// A description the graph cannot hold (an attribute given twice, a number not finite).
    #[error(transparent)]
    InvalidSpec(#[from] crate::bus::InvalidSpec),
}

/// A rejected structural proposal and its reason.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("proposal rejected: {reason}")]
pub struct Rejection {
    /// The proposal.
    pub proposal: Box<StructuralChange>,
    /// Why.
    pub reason: RejectReason,
}

/// The scene graph. Cloning is a deep copy (see [`SceneGraph::fork`]).
#[derive(Debug, Clone)]
pub struct SceneGraph {
    nodes: Vec<Option<Node>>,
    names: HashMap<String, NodeId>,
    joints: HashMap<String, NodeId>,
    body_parts: BTreeMap<String, BodyPart>,
    history_len: usize,
    log: Option<Vec<ChangeEvent>>,
    newest: Stamp,
    forked: bool,
}

impl Default for SceneGraph {
    fn default() -> Self {
        Self::new()
    }
}

fn check_name(name: &str) -> std::result::Result<(), RejectReason> {
    if name.is_empty()
        || name
            .chars()
            .any(|c| c.is_whitespace() || c == '(' || c == ')')
    {
        Err(RejectReason::InvalidName(name.to_string()))
    } else {
        Ok(())
    }
}

impl SceneGraph {
    /// Default number of samples kept per edge.
    pub const DEFAULT_HISTORY_LEN: usize = 128;

    /// A graph with only the `world` node; the change log is off.
    pub fn new() -> Self {
        let world = Node {
            name: WORLD.into(),
            node_type: NodeType::World,
            parent: None,
            children: Vec::new(),
            attrs: BTreeMap::new(),
            camera: None,
            collision: Vec::new(),
            edge: EdgeState {
                kind: EdgeKind::Fixed,
                origin: Isometry3::identity(),
                value: 0.0,
                current: Isometry3::identity(),
                history: VecDeque::new(),
            },
            depth: 0,
        };
        let mut names = HashMap::new();
        names.insert(WORLD.to_string(), NodeId(0));
        Self {
            nodes: vec![Some(world)],
            names,
            joints: HashMap::new(),
            body_parts: BTreeMap::new(),
            history_len: Self::DEFAULT_HISTORY_LEN,
            log: None,
            newest: Stamp(0),
            forked: false,
        }
    }

    /// Samples kept per edge.
    pub fn history_len(&self) -> usize {
        self.history_len
    }
    /// Sets the samples kept per edge (at least 1); applies from the next update.
    pub fn set_history_len(&mut self, n: usize) {
        self.history_len = n.max(1);
    }

    /// Starts recording every change as a [`ChangeEvent`] (see [`SceneGraph::take_log`]).
    pub fn enable_log(&mut self) {
        if self.log.is_none() {
            self.log = Some(Vec::new());
        }
    }
    /// Takes the events recorded since the last call (empty if the log is off).
    pub fn take_log(&mut self) -> Vec<ChangeEvent> {
        self.log.as_mut().map(std::mem::take).unwrap_or_default()
    }
    fn record(&mut self, f: impl FnOnce() -> ChangeEvent) {
        if let Some(log) = self.log.as_mut() {
            log.push(f());
        }
    }
    fn saw(&mut self, stamp: Stamp) {
        self.newest = self.newest.max(stamp);
    }

    /// Whether this graph is a fork (a private what-if copy).
    pub fn is_fork(&self) -> bool {
        self.forked
    }

    /// A private deep copy for virtual actions: changes to it never reach this graph, and it
    /// records no change log. Compare it with [`crate::predicates::diff_states`] /
    /// [`crate::predicates::fork_report`], then drop it.
    ///
    /// The fork keeps only the newest sample of each edge's history (a what-if starts from the
    /// current state), which keeps forking cheap; use `clone()` for a copy with full history.
    pub fn fork(&self) -> SceneGraph {
        let nodes = self
            .nodes
            .iter()
            .map(|slot| {
                slot.as_ref().map(|n| Node {
                    name: n.name.clone(),
                    node_type: n.node_type,
                    parent: n.parent,
                    children: n.children.clone(),
                    attrs: n.attrs.clone(),
                    camera: n.camera.clone(),
                    collision: n.collision.clone(),
                    edge: EdgeState {
                        kind: n.edge.kind.clone(),
                        origin: n.edge.origin,
                        value: n.edge.value,
                        current: n.edge.current,
                        history: n.edge.history.back().copied().into_iter().collect(),
                    },
                    depth: n.depth,
                })
            })
            .collect();
        SceneGraph {
            nodes,
            names: self.names.clone(),
            joints: self.joints.clone(),
            body_parts: self.body_parts.clone(),
            history_len: self.history_len,
            log: None,
            newest: self.newest,
            forked: true,
        }
    }

    // ---------------------------------------------------------------- lookups

    /// The id of a node by name.
    pub fn id(&self, name: &str) -> Result<NodeId> {
        self.names
            .get(name)
            .copied()
            .ok_or_else(|| DrError::UnknownFrame(name.to_string()))
    }
    /// A node by id.
    pub fn node_by_id(&self, id: NodeId) -> Option<&Node> {
        self.nodes.get(id.0 as usize).and_then(Option::as_ref)
    }
    /// A node by name.
    pub fn node(&self, name: &str) -> Result<&Node> {
        let id = self.id(name)?;
        self.node_by_id(id)
            .ok_or_else(|| DrError::UnknownFrame(name.to_string()))
    }
    fn node_mut(&mut self, id: NodeId) -> Option<&mut Node> {
        self.nodes.get_mut(id.0 as usize).and_then(Option::as_mut)
    }
    /// Whether a node exists.
    pub fn contains(&self, name: &str) -> bool {
        self.names.contains_key(name)
    }
    /// All nodes (ids and nodes), in id order.
    pub fn nodes(&self) -> impl Iterator<Item = (NodeId, &Node)> {
        self.nodes
            .iter()
            .enumerate()
            .filter_map(|(i, n)| n.as_ref().map(|n| (NodeId(i as u32), n)))
    }
    /// Number of nodes, `world` included.
    pub fn len(&self) -> usize {
        self.names.len()
    }
    /// Never true: `world` always exists.
    pub fn is_empty(&self) -> bool {
        false
    }
    /// The node that carries joint `joint` on its edge.
    pub fn joint_node(&self, joint: &str) -> Result<NodeId> {
        self.joints
            .get(joint)
            .copied()
            .ok_or_else(|| DrError::UnknownJoint(joint.to_string()))
    }
    /// Current value of a joint (rad or m).
    pub fn joint_value(&self, joint: &str) -> Result<f64> {
        let id = self.joint_node(joint)?;
        Ok(self.node_by_id(id).map_or(0.0, |n| n.edge.value))
    }
    /// Declared body parts.
    pub fn body_parts(&self) -> impl Iterator<Item = &BodyPart> {
        self.body_parts.values()
    }
    /// A declared body part.
    pub fn body_part(&self, name: &str) -> Option<&BodyPart> {
        self.body_parts.get(name)
    }
    /// The newest stamp seen in any change.
    pub fn newest_stamp(&self) -> Stamp {
        self.newest
    }

    // ---------------------------------------------------------------- transforms

    fn edge_tf(&self, n: &Node, at: At) -> Result<Isometry3<f64>> {
        match at {
            At::Latest => Ok(n.edge.current),
            At::Time(t) => n.edge.at(&n.name, t),
        }
    }

    /// `target_T_source` between two nodes by id. Allocation-free: walks both nodes up to their
    /// common ancestor.
    pub fn transform_ids(&self, target: NodeId, source: NodeId, at: At) -> Result<Isometry3<f64>> {
        let missing = |id: NodeId| DrError::UnknownFrame(format!("#{}", id.0));
        let mut a = self.node_by_id(source).ok_or_else(|| missing(source))?;
        let mut b = self.node_by_id(target).ok_or_else(|| missing(target))?;
        let mut ta = Isometry3::identity(); // ancestor_T_source
        let mut tb = Isometry3::identity(); // ancestor_T_target
        let up = |n: &Node| n.parent.and_then(|p| self.node_by_id(p));
        while a.depth > b.depth {
            ta = self.edge_tf(a, at)? * ta;
            a = up(a).ok_or_else(|| missing(source))?;
        }
        while b.depth > a.depth {
            tb = self.edge_tf(b, at)? * tb;
            b = up(b).ok_or_else(|| missing(target))?;
        }
        while !std::ptr::eq(a, b) {
            ta = self.edge_tf(a, at)? * ta;
            tb = self.edge_tf(b, at)? * tb;
            a = up(a).ok_or_else(|| missing(source))?;
            b = up(b).ok_or_else(|| missing(target))?;
        }
        Ok(tb.inv_mul(&ta))
    }

    /// `target_T_source`: the pose of frame `source` expressed in frame `target`, so that
    /// `p_target = target_T_source * p_source`.
    pub fn transform(&self, target: &str, source: &str, at: At) -> Result<Isometry3<f64>> {
        self.transform_ids(self.id(target)?, self.id(source)?, at)
    }

    /// A point given in frame `source` (m), expressed in frame `target`.
    pub fn transform_point(
        &self,
        target: &str,
        source: &str,
        p: &Point3<f64>,
        at: At,
    ) -> Result<Point3<f64>> {
        Ok(self.transform(target, source, at)? * p)
    }

    /// A pose given in frame `source`, expressed in frame `target`.
    pub fn transform_pose(
        &self,
        target: &str,
        source: &str,
        pose: &Isometry3<f64>,
        at: At,
    ) -> Result<Isometry3<f64>> {
        Ok(self.transform(target, source, at)? * pose)
    }

    /// Origin of frame `node` in `world` (m).
    pub fn world_position(&self, node: NodeId, at: At) -> Result<Vector3<f64>> {
        Ok(self.transform_ids(NodeId(0), node, at)?.translation.vector)
    }

    // ---------------------------------------------------------------- updates (no proposal)

    /// Sets a joint value (rad or m) measured at `stamp`. Out-of-limit values are stored as
    /// measured (limits are for controllers); non-finite values are an error.
    pub fn set_joint(&mut self, joint: &str, value: f64, stamp: Stamp) -> Result<()> {
        let id = self.joint_node(joint)?;
        self.set_joint_id(id, value, stamp)?;
        self.record(|| ChangeEvent::JointSet {
            stamp_ns: stamp.0,
            joint: joint.to_string(),
            value,
        });
        Ok(())
    }

    /// [`SceneGraph::set_joint`] by the id of the joint's child node (see
    /// [`SceneGraph::joint_node`]); records nothing in the change log. For hot loops.
    pub fn set_joint_id(&mut self, id: NodeId, value: f64, stamp: Stamp) -> Result<()> {
        let cap = self.history_len;
        let n = self
            .node_mut(id)
            .ok_or_else(|| DrError::UnknownJoint(format!("#{}", id.0)))?;
        if !matches!(n.edge.kind, EdgeKind::Joint { .. }) {
            return Err(DrError::WrongEdgeKind(n.name.clone(), "not a joint"));
        }
        if !value.is_finite() {
            return Err(DrError::NonFiniteValue(n.name.clone()));
        }
        let tf = n.edge.motion(value);
        n.edge.push(cap, stamp, value, tf);
        self.saw(stamp);
        Ok(())
    }

    /// Sets the free pose `parent_T_node` of an object, agent or other free node.
    pub fn set_pose(&mut self, node: &str, pose: &Isometry3<f64>, stamp: Stamp) -> Result<()> {
        let id = self.id(node)?;
        let cap = self.history_len;
        let n = self
            .node_mut(id)
            .ok_or_else(|| DrError::UnknownFrame(node.to_string()))?;
        if !matches!(n.edge.kind, EdgeKind::Free) {
            return Err(DrError::WrongEdgeKind(node.to_string(), "not a free pose"));
        }
        let p = Transform::from_iso(pose);
        if !p.is_valid() {
            return Err(DrError::BadEvent(format!("pose of `{node}` is not finite")));
        }
        n.edge.push(cap, stamp, 0.0, *pose);
        self.saw(stamp);
        self.record(|| ChangeEvent::PoseSet {
            stamp_ns: stamp.0,
            node: node.to_string(),
            pose: p,
        });
        Ok(())
    }

    /// Sets the free pose of `node` from a measurement expressed in another frame
    /// (`frame_T_node`, e.g. a ball seen in the camera's optical frame), taken at `stamp`: the
    /// frame is placed where it was at `stamp` (edge histories), so a late measurement lands where
    /// the object was, even if the head moved since.
    pub fn set_pose_in(
        &mut self,
        node: &str,
        frame: &str,
        pose: &Isometry3<f64>,
        stamp: Stamp,
    ) -> Result<()> {
        let parent = self
            .node(node)?
            .parent
            .ok_or_else(|| DrError::WrongEdgeKind(node.to_string(), "world has no pose"))?;
        let parent_t_frame = self.transform_ids(parent, self.id(frame)?, At::Time(stamp))?;
        self.set_pose(node, &(parent_t_frame * pose), stamp)
    }

    /// Current values of a chain's joints, in chain order (rad or m), e.g. the IK's start point.
    pub fn chain_values(&self, chain: &Chain) -> Result<Vec<f64>> {
        chain
            .joints
            .iter()
            .map(|j| self.joint_value(&j.name))
            .collect()
    }

    /// Sets a chain's joints (chain order) at `stamp`; checks the length first.
    pub fn set_chain_values(&mut self, chain: &Chain, q: &[f64], stamp: Stamp) -> Result<()> {
        if q.len() != chain.dof() {
            return Err(DrError::JointCount {
                expected: chain.dof(),
                got: q.len(),
            });
        }
        for (j, v) in chain.joints.iter().zip(q) {
            self.set_joint(&j.name, *v, stamp)?;
        }
        Ok(())
    }

    /// Sets an attribute (perception updates go straight in).
    pub fn set_attr(
        &mut self,
        node: &str,
        key: &str,
        value: AttrValue,
        stamp: Stamp,
    ) -> Result<()> {
        let id = self.id(node)?;
        let n = self
            .node_mut(id)
            .ok_or_else(|| DrError::UnknownFrame(node.to_string()))?;
        n.attrs.insert(key.to_string(), value.clone());
        self.saw(stamp);
        self.record(|| ChangeEvent::AttributeSet {
            stamp_ns: stamp.0,
            node: node.to_string(),
            key: key.to_string(),
            value,
        });
        Ok(())
    }
}

/// Translation helper for tests and callers: an isometry from a translation (m).
pub fn translation(x: f64, y: f64, z: f64) -> Isometry3<f64> {
    Isometry3::from_parts(
        Translation3::new(x, y, z),
        nalgebra::UnitQuaternion::identity(),
    )
}
