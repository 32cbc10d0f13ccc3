//! Snapshots and the change log of the scene graph: describing nodes, saving and restoring,
//! applying logged events.

use super::*;

impl SceneGraph {
    // ---------------------------------------------------------------- snapshot / log

    /// The description of one node as a snapshot holds it (current edge, attributes, intrinsics,
    /// collision); `world` has none (it has no parent) and gives [`DrError::UnknownFrame`] too.
    pub fn node_spec(&self, name: &str) -> Result<NodeSpec> {
        let n = self.node(name)?;
        let parent = n
            .parent
            .and_then(|p| self.node_by_id(p))
            .ok_or_else(|| DrError::UnknownFrame(format!("{name} (the root has no spec)")))?;
        Ok(NodeSpec {
            name: n.name.clone(),
            node_type: n.node_type.name().into(),
            parent: parent.name.clone(),
            edge: Self::edge_spec(n),
            attrs: n.attrs.clone(),
            camera: n.camera.clone(),
            collision: n.collision.clone(),
        })
    }

    /// The node's current edge as a spec.
    pub(super) fn edge_spec(n: &Node) -> EdgeSpec {
        match &n.edge.kind {
            EdgeKind::Fixed => EdgeSpec::Fixed {
                origin: Pose::from_iso(&n.edge.origin),
            },
            EdgeKind::Free => EdgeSpec::Free {
                pose: Pose::from_iso(&n.edge.current),
            },
            EdgeKind::Joint {
                joint,
                kind,
                axis,
                limits,
            } => EdgeSpec::Joint {
                joint: joint.clone(),
                kind: *kind,
                origin: Pose::from_iso(&n.edge.origin),
                axis: [axis.x, axis.y, axis.z],
                limits: LimitsSpec {
                    lower: limits.lower,
                    upper: limits.upper,
                    velocity: limits.velocity,
                    effort: limits.effort,
                },
                value: n.edge.value,
            },
        }
    }

    /// The current state (no history), nodes parents-first.
    pub fn snapshot(&self) -> Snapshot {
        let mut nodes = Vec::with_capacity(self.len());
        let mut queue: VecDeque<NodeId> = VecDeque::from([NodeId(0)]);
        while let Some(id) = queue.pop_front() {
            let Some(n) = self.node_by_id(id) else {
                continue;
            };
            queue.extend(n.children.iter().copied());
            let Some(parent) = n.parent.and_then(|p| self.node_by_id(p)) else {
                continue;
            };
            nodes.push(NodeSpec {
                name: n.name.clone(),
                node_type: n.node_type.name().into(),
                parent: parent.name.clone(),
                edge: Self::edge_spec(n),
                attrs: n.attrs.clone(),
                camera: n.camera.clone(),
                collision: n.collision.clone(),
            });
        }
        Snapshot {
            format: SNAPSHOT_FORMAT.into(),
            version: SNAPSHOT_VERSION,
            stamp: self.newest,
            nodes,
            body_parts: self.body_parts.values().cloned().collect(),
        }
    }

    /// The snapshot as pretty JSON.
    pub fn snapshot_json(&self) -> String {
        // Serialising plain structs of strings and finite numbers cannot fail; NaN cannot enter
        // the graph (every update checks finiteness).
        serde_json::to_string_pretty(&self.snapshot()).unwrap_or_default()
    }

    /// Rebuilds a graph from a snapshot, checking every node with the integrity rules. Edge
    /// histories start with one sample at the snapshot stamp.
    pub fn restore(snapshot: &Snapshot) -> Result<SceneGraph> {
        if snapshot.format != SNAPSHOT_FORMAT {
            return Err(DrError::CorruptSnapshot(format!(
                "format is `{}`, expected `{SNAPSHOT_FORMAT}`",
                snapshot.format
            )));
        }
        if snapshot.version != SNAPSHOT_VERSION {
            return Err(DrError::CorruptSnapshot(format!(
                "version {} is not supported (expected {SNAPSHOT_VERSION})",
                snapshot.version
            )));
        }
        let mut g = SceneGraph::new();
        for (i, spec) in snapshot.nodes.iter().enumerate() {
            g.add_node(spec, snapshot.stamp)
                .map_err(|r| DrError::CorruptSnapshot(format!("node #{i} `{}`: {r}", spec.name)))?;
        }
        for b in &snapshot.body_parts {
            g.declare_body_part(b.clone(), snapshot.stamp)
                .map_err(|e| DrError::CorruptSnapshot(format!("body part `{}`: {e}", b.name)))?;
        }
        g.newest = snapshot.stamp;
        Ok(g)
    }

    /// Parses and restores a JSON snapshot. Bad JSON, a wrong format tag or version, and an
    /// inconsistent graph all give [`DrError::CorruptSnapshot`] with the position or the node.
    pub fn restore_json(text: &str) -> Result<SceneGraph> {
        let snap: Snapshot = serde_json::from_str(text)
            .map_err(|e| DrError::CorruptSnapshot(format!("not a valid snapshot: {e}")))?;
        Self::restore(&snap)
    }

    /// Replays one change event (for recovery: restore the snapshot, then apply the log).
    pub fn apply(&mut self, event: &ChangeEvent) -> Result<()> {
        let rejected = |r: Rejection| DrError::BadEvent(r.to_string());
        match event {
            ChangeEvent::NodeAdded { stamp, spec } => self
                .propose(Proposal::AddNode { spec: spec.clone() }, *stamp)
                .map_err(rejected),
            ChangeEvent::NodeRemoved { stamp, name } => self
                .propose(Proposal::RemoveNode { name: name.clone() }, *stamp)
                .map_err(rejected),
            ChangeEvent::Reparented {
                stamp,
                name,
                new_parent,
                pose,
            } => self
                .propose(
                    Proposal::Reparent {
                        name: name.clone(),
                        new_parent: new_parent.clone(),
                        pose: *pose,
                    },
                    *stamp,
                )
                .map_err(rejected),
            ChangeEvent::JointSet {
                stamp,
                joint,
                value,
            } => self.set_joint(joint, *value, *stamp),
            ChangeEvent::PoseSet { stamp, node, pose } => {
                if !pose.is_valid() {
                    return Err(DrError::BadEvent(format!("pose of `{node}` is not finite")));
                }
                self.set_pose(node, &pose.to_iso(), *stamp)
            }
            ChangeEvent::AttributeSet {
                stamp,
                node,
                key,
                value,
            } => self.set_attr(node, key, value.clone(), *stamp),
            ChangeEvent::BodyPartDeclared { stamp, part } => {
                self.declare_body_part(part.clone(), *stamp)
            }
        }
    }
}
