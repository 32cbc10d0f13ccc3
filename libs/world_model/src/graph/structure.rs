//! Structural changes of the scene graph: proposals checked against the integrity rules, robots
//! added from a URDF, body parts declared.

use super::*;

impl SceneGraph {
    // ---------------------------------------------------------------- structure

    /// Applies a structural proposal if it keeps the graph consistent: names unique and valid,
    /// parent exists, type known, no cycles, no removal of nodes with children or of `world` and
    /// robot links, finite geometry.
    pub fn propose(
        &mut self,
        proposal: StructuralChange,
        stamp: Stamp,
    ) -> std::result::Result<(), Rejection> {
        let res = match &proposal {
            StructuralChange::AddNode(spec) => self.add_node(spec, stamp),
            StructuralChange::RemoveNode { name } => self.remove_node(name, stamp),
            StructuralChange::Reparent {
                name,
                new_parent,
                pose,
            } => self.reparent(name, new_parent, pose, stamp),
        };
        res.map_err(|reason| Rejection {
            proposal: Box::new(proposal),
            reason,
        })
    }

    pub(super) fn add_node(
        &mut self,
        spec: &NodeSpec,
        stamp: Stamp,
    ) -> std::result::Result<(), RejectReason> {
        check_name(&spec.name)?;
        crate::bus::check_node(spec)?;
        if self.names.contains_key(&spec.name) {
            return Err(RejectReason::DuplicateName(spec.name.clone()));
        }
        let node_type = NodeType::from_name(&spec.node_type)
            .filter(|t| *t != NodeType::World)
            .ok_or_else(|| {
                RejectReason::UnknownType(
                    spec.node_type.clone(),
                    NodeType::ALL[1..]
                        .iter()
                        .map(|t| t.name())
                        .collect::<Vec<_>>()
                        .join(", "),
                )
            })?;
        let parent = *self
            .names
            .get(&spec.parent)
            .ok_or_else(|| RejectReason::UnknownParent(spec.parent.clone()))?;
        let bad = |what: &str| RejectReason::InvalidGeometry(format!("{}: {what}", spec.name));
        let edge = match &spec.edge {
            Edge::Fixed { origin } => {
                if !origin.is_valid() {
                    return Err(bad("origin is not finite"));
                }
                let o = origin.to_iso();
                EdgeState {
                    kind: EdgeKind::Fixed,
                    origin: o,
                    value: 0.0,
                    current: o,
                    history: VecDeque::new(),
                }
            }
            Edge::Free { pose } => {
                if !pose.is_valid() {
                    return Err(bad("pose is not finite"));
                }
                let p = pose.to_iso();
                let mut e = EdgeState {
                    kind: EdgeKind::Free,
                    origin: Isometry3::identity(),
                    value: 0.0,
                    current: p,
                    history: VecDeque::new(),
                };
                e.push(self.history_len, stamp, 0.0, p);
                e
            }
            Edge::Joint {
                joint,
                kind,
                origin,
                axis,
                limits,
                value,
            } => {
                check_name(joint)?;
                if self.joints.contains_key(joint) {
                    return Err(RejectReason::DuplicateJoint(joint.clone()));
                }
                if !origin.is_valid() || !value.is_finite() || *kind == JointKind::Fixed {
                    return Err(bad("joint origin/value not finite, or kind fixed"));
                }
                let axis = Unit::try_new(Vector3::from(*axis), 1e-12)
                    .filter(|a| a.iter().all(|v| v.is_finite()))
                    .ok_or_else(|| bad("joint axis is zero or not finite"))?;
                let mut e = EdgeState {
                    kind: EdgeKind::Joint {
                        joint: joint.clone(),
                        kind: *kind,
                        axis,
                        limits: JointLimits {
                            lower: limits.lower,
                            upper: limits.upper,
                            velocity: limits.velocity,
                            effort: limits.effort,
                        },
                    },
                    origin: origin.to_iso(),
                    value: *value,
                    current: Isometry3::identity(),
                    history: VecDeque::new(),
                };
                let tf = e.motion(*value);
                e.current = tf;
                e.push(self.history_len, stamp, *value, tf);
                e
            }
        };
        let depth = self.node_by_id(parent).map_or(0, |p| p.depth + 1);
        let id = NodeId(self.nodes.len() as u32);
        if let EdgeKind::Joint { joint, .. } = &edge.kind {
            self.joints.insert(joint.clone(), id);
        }
        self.nodes.push(Some(Node {
            name: spec.name.clone(),
            node_type,
            parent: Some(parent),
            children: Vec::new(),
            attrs: spec
                .attributes
                .iter()
                .map(|a| (a.key.clone(), a.value.clone()))
                .collect(),
            camera: spec.camera.intrinsics().cloned(),
            collision: spec.collision.clone(),
            edge,
            depth,
        }));
        self.names.insert(spec.name.clone(), id);
        if let Some(p) = self.node_mut(parent) {
            p.children.push(id);
        }
        self.saw(stamp);
        self.record(|| ChangeEvent::NodeAdded {
            stamp_ns: stamp.0,
            spec: Box::new(spec.clone()),
        });
        Ok(())
    }

    pub(super) fn protected(n: &Node) -> Option<&'static str> {
        match n.node_type {
            NodeType::World => Some("the root"),
            NodeType::Link => Some("a robot link"),
            _ => None,
        }
    }

    /// The node `name`, when it exists and may be changed structurally.
    pub(super) fn unprotected_node(
        &self,
        name: &str,
    ) -> std::result::Result<(NodeId, &Node), RejectReason> {
        let id = *self
            .names
            .get(name)
            .ok_or_else(|| RejectReason::UnknownNode(name.to_string()))?;
        let n = self
            .node_by_id(id)
            .ok_or_else(|| RejectReason::UnknownNode(name.to_string()))?;
        match Self::protected(n) {
            Some(why) => Err(RejectReason::Protected(name.to_string(), why)),
            None => Ok((id, n)),
        }
    }

    pub(super) fn remove_node(
        &mut self,
        name: &str,
        stamp: Stamp,
    ) -> std::result::Result<(), RejectReason> {
        let (id, n) = self.unprotected_node(name)?;
        if !n.children.is_empty() {
            let kids: Vec<&str> = n
                .children
                .iter()
                .filter_map(|c| self.node_by_id(*c).map(|c| c.name.as_str()))
                .collect();
            return Err(RejectReason::HasChildren(name.to_string(), kids.join(", ")));
        }
        let parent = n.parent;
        if let EdgeKind::Joint { joint, .. } = &n.edge.kind {
            let joint = joint.clone();
            self.joints.remove(&joint);
        }
        self.body_parts.retain(|_, b| b.robot != name);
        if let Some(p) = parent.and_then(|p| self.node_mut(p)) {
            p.children.retain(|c| *c != id);
        }
        self.nodes[id.0 as usize] = None;
        self.names.remove(name);
        self.saw(stamp);
        self.record(|| ChangeEvent::NodeRemoved {
            stamp_ns: stamp.0,
            name: name.to_string(),
        });
        Ok(())
    }

    pub(super) fn reparent(
        &mut self,
        name: &str,
        new_parent: &str,
        pose: &Transform,
        stamp: Stamp,
    ) -> std::result::Result<(), RejectReason> {
        let (id, n) = self.unprotected_node(name)?;
        let np = *self
            .names
            .get(new_parent)
            .ok_or_else(|| RejectReason::UnknownParent(new_parent.to_string()))?;
        if matches!(n.edge.kind, EdgeKind::Joint { .. }) {
            return Err(RejectReason::Protected(name.to_string(), "a joint child"));
        }
        // Cycle: the new parent is the node itself or one of its descendants.
        let mut cur = Some(np);
        while let Some(c) = cur {
            if c == id {
                return Err(RejectReason::Cycle {
                    node: name.to_string(),
                    new_parent: new_parent.to_string(),
                });
            }
            cur = self.node_by_id(c).and_then(|n| n.parent);
        }
        if !pose.is_valid() {
            return Err(RejectReason::InvalidGeometry(format!(
                "{name}: pose is not finite"
            )));
        }
        let old_parent = n.parent;
        if let Some(p) = old_parent.and_then(|p| self.node_mut(p)) {
            p.children.retain(|c| *c != id);
        }
        if let Some(p) = self.node_mut(np) {
            p.children.push(id);
        }
        let cap = self.history_len;
        let iso = pose.to_iso();
        if let Some(n) = self.node_mut(id) {
            n.parent = Some(np);
            // The old history is relative to the old parent: restart it.
            n.edge = EdgeState {
                kind: EdgeKind::Free,
                origin: Isometry3::identity(),
                value: 0.0,
                current: iso,
                history: VecDeque::new(),
            };
            n.edge.push(cap, stamp, 0.0, iso);
        }
        self.update_depths(id);
        self.saw(stamp);
        self.record(|| ChangeEvent::Reparented {
            stamp_ns: stamp.0,
            name: name.to_string(),
            new_parent: new_parent.to_string(),
            pose: *pose,
        });
        Ok(())
    }

    pub(super) fn update_depths(&mut self, root: NodeId) {
        let mut stack = vec![root];
        while let Some(id) = stack.pop() {
            let pd = self
                .node_by_id(id)
                .and_then(|n| n.parent)
                .and_then(|p| self.node_by_id(p))
                .map_or(0, |p| p.depth + 1);
            if let Some(n) = self.node_mut(id) {
                n.depth = pd;
                stack.extend(n.children.iter().copied());
            }
        }
    }

    /// Declares a body part for the `reachable` predicate.
    pub fn declare_body_part(&mut self, part: BodyPart, stamp: Stamp) -> Result<()> {
        for f in [&part.robot, &part.base_frame, &part.tip_frame] {
            self.id(f)?;
        }
        self.body_parts.insert(part.name.clone(), part.clone());
        self.saw(stamp);
        self.record(|| ChangeEvent::BodyPartDeclared {
            stamp_ns: stamp.0,
            part,
        });
        Ok(())
    }

    /// Adds a robot: an agent node `agent` (type `robot`) with a free pose under `parent`, the
    /// URDF root link fixed under it, every link under its parent link through its joint, one
    /// `camera` node per `<robocog_camera>` (fixed, identity, under its optical frame), and the
    /// Loki arm body parts (`left_arm`, `right_arm`: shoulder to hand centre) when the model has
    /// them; hand centres get `effector = true`. Link names are used as they are, so two robots
    /// with the same link names cannot share a graph (the second load is rejected).
    pub fn add_robot(
        &mut self,
        model: &RobotModel,
        agent: &str,
        parent: &str,
        pose: &Isometry3<f64>,
        stamp: Stamp,
    ) -> Result<()> {
        let mut specs = vec![NodeSpec::free(
            agent,
            NodeType::Robot,
            parent,
            Transform::from_iso(pose),
        )];
        // Links parents-first: BFS from the root.
        let mut queue = VecDeque::from([model.root]);
        let mut children: HashMap<usize, Vec<usize>> = HashMap::new();
        for (ji, j) in model.joints.iter().enumerate() {
            children.entry(j.parent).or_default().push(ji);
        }
        let root = &model.links[model.root];
        specs.push(NodeSpec {
            name: root.name.clone(),
            node_type: NodeType::Link.name().into(),
            parent: agent.into(),
            edge: Edge::Fixed {
                origin: Transform::default(),
            },
            attributes: Vec::new(),
            camera: Camera::None,
            collision: root.collision.clone(),
        });
        while let Some(li) = queue.pop_front() {
            for &ji in children.get(&li).map(Vec::as_slice).unwrap_or(&[]) {
                let j = &model.joints[ji];
                let child = &model.links[j.child];
                let edge = if j.kind.is_movable() {
                    Edge::Joint {
                        joint: j.name.clone(),
                        kind: j.kind,
                        origin: Transform::from_iso(&j.origin),
                        axis: [j.axis.x, j.axis.y, j.axis.z],
                        limits: JointLimits {
                            lower: j.limits.lower,
                            upper: j.limits.upper,
                            velocity: j.limits.velocity,
                            effort: j.limits.effort,
                        },
                        value: 0.0_f64.clamp(j.limits.lower, j.limits.upper),
                    }
                } else {
                    Edge::Fixed {
                        origin: Transform::from_iso(&j.origin),
                    }
                };
                specs.push(NodeSpec {
                    name: child.name.clone(),
                    node_type: NodeType::Link.name().into(),
                    parent: model.links[j.parent].name.clone(),
                    edge,
                    attributes: Vec::new(),
                    camera: Camera::None,
                    collision: child.collision.clone(),
                });
                queue.push_back(j.child);
            }
        }
        for c in &model.cameras {
            specs.push(NodeSpec {
                name: c.name.clone(),
                node_type: NodeType::Camera.name().into(),
                parent: c.frame.clone(),
                edge: Edge::Fixed {
                    origin: Transform::default(),
                },
                attributes: Vec::new(),
                camera: Camera::Pinhole(c.clone()),
                collision: Vec::new(),
            });
        }
        // Validate the whole batch on a copy first, so a rejected robot leaves no half-added nodes.
        let mut trial = self.clone();
        trial.log = None;
        for s in &specs {
            trial.add_node(s, stamp).map_err(|reason| {
                DrError::Rejected(Box::new(Rejection {
                    proposal: Box::new(StructuralChange::AddNode(Box::new(s.clone()))),
                    reason,
                }))
            })?;
        }
        for s in &specs {
            self.add_node(s, stamp).map_err(|reason| {
                DrError::Rejected(Box::new(Rejection {
                    proposal: Box::new(StructuralChange::AddNode(Box::new(s.clone()))),
                    reason,
                }))
            })?;
        }
        for part in ["left_arm", "right_arm"] {
            if let Ok(chain) = model.body_part(part) {
                let Some(first) = chain.joints.first() else {
                    continue;
                };
                let base = model.joint(&first.name)?;
                let base_frame = model.links[base.child].name.clone();
                let tip = chain.tip.clone();
                self.set_attr(&tip, attr::EFFECTOR, AttrValue::Bool(true), stamp)?;
                self.declare_body_part(
                    BodyPart {
                        name: part.to_string(),
                        robot: agent.to_string(),
                        base_frame,
                        tip_frame: tip,
                        reach_m: chain.reach_m(),
                    },
                    stamp,
                )?;
            }
        }
        Ok(())
    }
}
