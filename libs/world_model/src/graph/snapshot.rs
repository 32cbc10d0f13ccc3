//! Snapshots and the change log of the scene graph: describing nodes, saving and restoring,
//! applying logged events.

use serde::{Deserialize, Serialize};

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
            attributes: key_values(&n.attrs),
            camera: n.camera.clone().into(),
            collision: n.collision.clone(),
        })
    }

    /// The node's current edge as a spec.
    pub(super) fn edge_spec(n: &Node) -> Edge {
        match &n.edge.kind {
            EdgeKind::Fixed => Edge::Fixed {
                origin: Transform::from_iso(&n.edge.origin),
            },
            EdgeKind::Free => Edge::Free {
                pose: Transform::from_iso(&n.edge.current),
            },
            EdgeKind::Joint {
                joint,
                kind,
                axis,
                limits,
            } => Edge::Joint {
                joint: joint.clone(),
                kind: *kind,
                origin: Transform::from_iso(&n.edge.origin),
                axis: [axis.x, axis.y, axis.z],
                limits: JointLimits {
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
                attributes: key_values(&n.attrs),
                camera: n.camera.clone().into(),
                collision: n.collision.clone(),
            });
        }
        Snapshot {
            stamp_ns: self.newest.0,
            nodes,
            body_parts: self.body_parts.values().cloned().collect(),
        }
    }

    /// The snapshot as pretty JSON, tagged with [`SNAPSHOT_FORMAT`] and [`SNAPSHOT_VERSION`].
    pub fn snapshot_json(&self) -> String {
        #[derive(Serialize)]
        struct File<'a> {
            format: &'a str,
            version: u32,
            snapshot: &'a Snapshot,
        }
        // Serialising plain structs of strings and finite numbers cannot fail; NaN cannot enter
        // the graph (every update checks finiteness), and a missing limit is written `null`.
        serde_json::to_string_pretty(&File {
            format: SNAPSHOT_FORMAT,
            version: SNAPSHOT_VERSION,
            snapshot: &self.snapshot(),
        })
        .unwrap_or_default()
    }

    /// Rebuilds a graph from a snapshot, checking every node with the integrity rules. EdgeState
    /// histories start with one sample at the snapshot stamp.
    pub fn restore(snapshot: &Snapshot) -> Result<SceneGraph> {
        let stamp = Stamp(snapshot.stamp_ns);
        let mut g = SceneGraph::new();
        for (i, spec) in snapshot.nodes.iter().enumerate() {
            g.add_node(spec, stamp)
                .map_err(|r| DrError::CorruptSnapshot(format!("node #{i} `{}`: {r}", spec.name)))?;
        }
        for b in &snapshot.body_parts {
            g.declare_body_part(b.clone(), stamp)
                .map_err(|e| DrError::CorruptSnapshot(format!("body part `{}`: {e}", b.name)))?;
        }
        g.newest = stamp;
        Ok(g)
    }

    /// Parses and restores a JSON snapshot. Bad JSON, a wrong format tag or version, and an
    /// inconsistent graph all give [`DrError::CorruptSnapshot`] with the position or the node.
    pub fn restore_json(text: &str) -> Result<SceneGraph> {
        #[derive(Deserialize)]
        struct Head {
            format: Option<String>,
            version: Option<u32>,
        }
        #[derive(Deserialize)]
        struct File {
            snapshot: Snapshot,
        }
        let corrupt =
            |e: serde_json::Error| DrError::CorruptSnapshot(format!("not a valid snapshot: {e}"));
        let head: Head = serde_json::from_str(text).map_err(corrupt)?;
        if head.format.as_deref() != Some(SNAPSHOT_FORMAT) {
            return Err(DrError::CorruptSnapshot(format!(
                "format is {:?}, expected `{SNAPSHOT_FORMAT}`",
                head.format.unwrap_or_default()
            )));
        }
        match head.version {
            Some(SNAPSHOT_VERSION) => {}
            Some(v) if v < SNAPSHOT_VERSION => {
                return Err(DrError::CorruptSnapshot(format!(
                    "version {v} was written by an older robocog; this one reads version \
                     {SNAPSHOT_VERSION} (move the state folder away: the DR starts from its \
                     scene, and perception fills it again)"
                )));
            }
            v => {
                return Err(DrError::CorruptSnapshot(format!(
                    "version {} is not supported (expected {SNAPSHOT_VERSION})",
                    v.map_or("(none)".into(), |v| v.to_string())
                )));
            }
        }
        let file: File = serde_json::from_str(text).map_err(corrupt)?;
        Self::restore(&file.snapshot)
    }

    /// Replays one change event (for recovery: restore the snapshot, then apply the log).
    pub fn apply(&mut self, event: &ChangeEvent) -> Result<()> {
        crate::bus::check_event(event).map_err(|e| DrError::BadEvent(e.to_string()))?;
        let rejected = |r: Rejection| DrError::BadEvent(r.to_string());
        let stamp = Stamp(event.stamp_ns());
        match event {
            ChangeEvent::NodeAdded { spec, .. } => self
                .propose(StructuralChange::AddNode(spec.clone()), stamp)
                .map_err(rejected),
            ChangeEvent::NodeRemoved { name, .. } => self
                .propose(StructuralChange::RemoveNode { name: name.clone() }, stamp)
                .map_err(rejected),
            ChangeEvent::Reparented {
                name,
                new_parent,
                pose,
                ..
            } => self
                .propose(
                    StructuralChange::Reparent {
                        name: name.clone(),
                        new_parent: new_parent.clone(),
                        pose: *pose,
                    },
                    stamp,
                )
                .map_err(rejected),
            ChangeEvent::JointSet { joint, value, .. } => self.set_joint(joint, *value, stamp),
            ChangeEvent::PoseSet { node, pose, .. } => {
                if !pose.is_valid() {
                    return Err(DrError::BadEvent(format!("pose of `{node}` is not finite")));
                }
                self.set_pose(node, &pose.to_iso(), stamp)
            }
            ChangeEvent::AttributeSet {
                node, key, value, ..
            } => self.set_attr(node, key, value.clone(), stamp),
            ChangeEvent::BodyPartDeclared { part, .. } => {
                self.declare_body_part(part.clone(), stamp)
            }
            // Refused by the check above.
            ChangeEvent::Restored => Ok(()),
        }
    }
}

/// Attributes as a snapshot lists them: each key once, sorted by key.
fn key_values(attrs: &BTreeMap<String, AttrValue>) -> Vec<KeyValue> {
    attrs
        .iter()
        .map(|(key, value)| KeyValue {
            key: key.clone(),
            value: value.clone(),
        })
        .collect()
}

/// Tag of the snapshot file format ([`SceneGraph::snapshot_json`]).
pub const SNAPSHOT_FORMAT: &str = "robocog-dr-snapshot";
/// Version of the snapshot file format: 2 since the DR's data types are the bus' own.
pub const SNAPSHOT_VERSION: u32 = 2;
