//! The live scene graph the service handlers share, and the handlers: queries (node, transform,
//! predicate, fork, PDDL, snapshot) and changes (update, propose, restore), with the checks of
//! what a request carries.

use interfaces::msg::dr as m;
use interfaces::{Bus, ServiceError};
use tokio::sync::{RwLock, mpsc};

use world_model::bus::{check_change, check_snapshot, reason_code};
use world_model::error::DrError;
use world_model::graph::{At, EdgeKind, SceneGraph};
use world_model::pddl::{Atom, export_problem};
use world_model::persist::{LogLine, Store};
use world_model::predicates::{self, PredicateConfig, PredicateKind, fork_report};
use world_model::types::{self, NodeType, Stamp, StructuralChange, Transform, TransformIso};

fn dr_err(e: DrError) -> ServiceError {
    match e {
        DrError::UnknownFrame(_) | DrError::UnknownJoint(_) | DrError::UnknownBodyPart(..) => {
            ServiceError::not_found(e.to_string())
        }
        DrError::TimeOutOfHistory { .. } => ServiceError::not_found(e.to_string()),
        DrError::Io { .. } => ServiceError::new(interfaces::ErrorCode::Internal, e.to_string()),
        _ => ServiceError::bad_request(e.to_string()),
    }
}

fn internal(what: impl std::fmt::Display) -> ServiceError {
    ServiceError::new(interfaces::ErrorCode::Internal, what.to_string())
}

fn attr_checked(a: &m::Attribute) -> Result<types::AttrValue, ServiceError> {
    if a.key.is_empty() {
        return Err(ServiceError::bad_request(format!(
            "attribute of `{}`: empty key",
            a.node
        )));
    }
    if !a.value.is_finite() {
        return Err(ServiceError::bad_request(format!(
            "attribute `{}.{}`: value is not finite",
            a.node, a.key
        )));
    }
    Ok(a.value.clone())
}

fn pose_checked(what: &str, t: &Transform) -> Result<Transform, ServiceError> {
    if t.is_valid() {
        Ok(*t)
    } else {
        Err(ServiceError::bad_request(format!(
            "pose of `{what}`: not finite, or a zero quaternion"
        )))
    }
}

/// A structural change the graph can hold (`BadRequest` for an attribute given twice, a number
/// that is not finite).
fn proposal_checked(c: &StructuralChange) -> Result<StructuralChange, ServiceError> {
    check_change(c).map_err(|e| ServiceError::bad_request(e.to_string()))?;
    Ok(c.clone())
}

// ---------------------------------------------------------------- the live state

pub(super) struct Live {
    pub(super) graph: SceneGraph,
    pub(super) store: Option<Store>,
    pub(super) last_seq: u64,
}

/// The state shared by the service handlers.
pub struct Dr {
    pub(super) live: RwLock<Live>,
    pub(super) changes: mpsc::Sender<m::DrChange>,
    pub(super) predicates: PredicateConfig,
    pub(super) history_len: usize,
    pub(super) bus: Bus,
}

impl std::fmt::Debug for Dr {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Dr")
    }
}

impl Dr {
    fn stamp(&self, header: &interfaces::Header) -> Result<Stamp, ServiceError> {
        match header.stamp_ns {
            t if t < 0 => Err(ServiceError::bad_request(format!(
                "header.stamp_ns {t} is negative"
            ))),
            0 => Ok(Stamp(self.bus.clock().now_ns().max(0) as u64)),
            t => Ok(Stamp(t as u64)),
        }
    }

    /// Persists and publishes the graph's pending change events; returns the last sequence
    /// number. Called with the write lock held, so changes leave in order.
    async fn commit(&self, live: &mut Live) -> Result<u64, ServiceError> {
        let events = live.graph.take_log();
        if events.is_empty() {
            return Ok(live.last_seq);
        }
        let mut lines = Vec::with_capacity(events.len());
        for event in events {
            live.last_seq += 1;
            lines.push(LogLine {
                seq: live.last_seq,
                event: Some(event),
                restore: None,
            });
        }
        self.persist(live, &lines)?;
        for l in &lines {
            let Some(ev) = &l.event else { continue };
            let mut msg = m::DrChange {
                header: interfaces::Header::new("world"),
                seq: l.seq,
                event: ev.clone(),
            };
            msg.header.stamp_ns = ev.stamp_ns().min(i64::MAX as u64) as i64;
            if self.changes.send(msg).await.is_err() {
                self.bus.counters().incr("dr/changes_not_published");
            }
        }
        Ok(live.last_seq)
    }

    fn persist(&self, live: &mut Live, lines: &[LogLine]) -> Result<(), ServiceError> {
        let Some(store) = live.store.as_mut() else {
            return Ok(());
        };
        if let Err(e) = store.append(lines) {
            self.bus.counters().incr("dr/persist_errors");
            tracing::error!("change applied but NOT persisted: {e}");
            return Err(internal(format!(
                "the change was applied but not persisted: {e}"
            )));
        }
        if store.compaction_due() {
            match store.compact(&live.graph, live.last_seq) {
                Ok(()) => tracing::debug!(seq = live.last_seq, "compacted the state folder"),
                Err(e) => {
                    // The log still holds every change; compaction is retried on the next one.
                    self.bus.counters().incr("dr/compaction_errors");
                    tracing::warn!("compaction failed (the change log keeps growing): {e}");
                }
            }
        }
        Ok(())
    }

    // ------------------------------------------------------------ handlers

    /// `dr/get_node`.
    pub async fn get_node(&self, req: m::GetNodeRequest) -> Result<m::NodeInfo, ServiceError> {
        let live = self.live.read().await;
        let g = &live.graph;
        let n = g.node(&req.name).map_err(dr_err)?;
        let parent = n
            .parent
            .and_then(|p| g.node_by_id(p))
            .map(|p| p.name.clone())
            .unwrap_or_default();
        let (edge, joint) = match (&n.edge.kind, n.parent) {
            (_, None) => ("", String::new()),
            (EdgeKind::Fixed, _) => ("fixed", String::new()),
            (EdgeKind::Free, _) => ("free", String::new()),
            (EdgeKind::Joint { joint, .. }, _) => ("joint", joint.clone()),
        };
        // `world` has no description (no parent): the default.
        let spec = g.node_spec(&req.name).unwrap_or_default();
        Ok(m::NodeInfo {
            header: interfaces::Header::new(parent.clone()),
            name: n.name.clone(),
            node_type: n.node_type.name().into(),
            parent,
            children: n
                .children
                .iter()
                .filter_map(|c| g.node_by_id(*c).map(|c| c.name.clone()))
                .collect(),
            edge: edge.into(),
            joint_value: if joint.is_empty() {
                0.0
            } else {
                n.edge.value()
            },
            joint,
            pose: Transform::from_iso(n.edge.current()),
            attributes: n
                .attrs
                .iter()
                .map(|(k, v)| m::Attribute {
                    node: n.name.clone(),
                    key: k.clone(),
                    value: v.clone(),
                })
                .collect(),
            spec,
        })
    }

    /// `dr/transform`.
    pub async fn transform(
        &self,
        req: m::TransformRequest,
    ) -> Result<m::TransformReply, ServiceError> {
        let live = self.live.read().await;
        let g = &live.graph;
        let at = match req.stamp_ns {
            0 => At::Latest,
            t => At::Time(Stamp(t)),
        };
        let iso = g.transform(&req.target, &req.source, at).map_err(dr_err)?;
        let stamp_ns = match at {
            At::Latest => g.newest_stamp().0,
            At::Time(t) => t.0,
        };
        let mut header = interfaces::Header::new(req.target.clone());
        header.stamp_ns = stamp_ns.min(i64::MAX as u64) as i64;
        Ok(m::TransformReply {
            header,
            target: req.target,
            source: req.source,
            stamp_ns,
            transform: Transform::from_iso(&iso),
        })
    }

    fn check_updates(
        g: &SceneGraph,
        attributes: &[m::Attribute],
        poses: &[m::PoseUpdate],
        joints: &[m::JointUpdate],
    ) -> Result<(), ServiceError> {
        for a in attributes {
            g.node(&a.node).map_err(dr_err)?;
            attr_checked(a)?;
        }
        for p in poses {
            let n = g.node(&p.node).map_err(dr_err)?;
            if !matches!(n.edge.kind, EdgeKind::Free) || n.parent.is_none() {
                return Err(ServiceError::bad_request(format!(
                    "`{}` has no free pose (its edge is fixed or a joint)",
                    p.node
                )));
            }
            pose_checked(&p.node, &p.pose)?;
        }
        for j in joints {
            g.joint_node(&j.joint).map_err(dr_err)?;
            if !j.value.is_finite() {
                return Err(ServiceError::bad_request(format!(
                    "joint `{}`: value is not finite",
                    j.joint
                )));
            }
        }
        Ok(())
    }

    fn apply_updates(
        g: &mut SceneGraph,
        attributes: &[m::Attribute],
        poses: &[m::PoseUpdate],
        joints: &[m::JointUpdate],
        stamp: Stamp,
    ) -> world_model::Result<()> {
        for j in joints {
            g.set_joint(&j.joint, j.value, stamp)?;
        }
        for p in poses {
            g.set_pose(&p.node, &p.pose.to_iso(), stamp)?;
        }
        for a in attributes {
            g.set_attr(&a.node, &a.key, a.value.clone(), stamp)?;
        }
        Ok(())
    }

    /// `dr/update`.
    pub async fn update(&self, req: m::UpdateRequest) -> Result<m::UpdateReply, ServiceError> {
        let stamp = self.stamp(&req.header)?;
        let mut live = self.live.write().await;
        Self::check_updates(&live.graph, &req.attributes, &req.poses, &req.joints)?;
        let applied = Self::apply_updates(
            &mut live.graph,
            &req.attributes,
            &req.poses,
            &req.joints,
            stamp,
        );
        // The checks above make a failure here a bug; what was applied is still committed.
        let last_seq = self.commit(&mut live).await?;
        applied.map_err(|e| internal(format!("update partly applied: {e}")))?;
        Ok(m::UpdateReply {
            header: Default::default(),
            applied: (req.attributes.len() + req.poses.len() + req.joints.len()) as u32,
            last_seq,
        })
    }

    /// `dr/propose`.
    pub async fn propose(&self, req: m::ProposeRequest) -> Result<m::ProposeReply, ServiceError> {
        let stamp = self.stamp(&req.header)?;
        let proposal = proposal_checked(&req.change)?;
        let mut live = self.live.write().await;
        match live.graph.propose(proposal, stamp) {
            Ok(()) => {
                let seq = self.commit(&mut live).await?;
                Ok(m::ProposeReply {
                    accepted: true,
                    seq,
                    ..Default::default()
                })
            }
            Err(rejection) => {
                self.bus.counters().incr("dr/proposals_rejected");
                tracing::info!("rejected a proposal: {}", rejection.reason);
                Ok(m::ProposeReply {
                    accepted: false,
                    reason_code: reason_code(&rejection.reason).into(),
                    reason: rejection.reason.to_string(),
                    ..Default::default()
                })
            }
        }
    }

    /// `dr/predicate`.
    pub async fn predicate(
        &self,
        req: m::PredicateRequest,
    ) -> Result<m::PredicateReply, ServiceError> {
        let live = self.live.read().await;
        let g = &live.graph;
        let cfg = &self.predicates;
        let at = match req.stamp_ns {
            0 => At::Latest,
            t => At::Time(Stamp(t)),
        };
        if req.predicate.is_empty() {
            let facts = predicates::evaluate(g, cfg, at).map_err(dr_err)?;
            return Ok(m::PredicateReply {
                facts: facts.iter().map(Into::into).collect(),
                ..Default::default()
            });
        }
        let kind = PredicateKind::from_name(&req.predicate).ok_or_else(|| {
            ServiceError::bad_request(format!(
                "unknown predicate `{}` (known: {})",
                req.predicate,
                PredicateKind::ALL.map(|k| k.name()).join(", ")
            ))
        })?;
        let arity = match kind {
            PredicateKind::Visible | PredicateKind::Reachable | PredicateKind::Near => 2,
            _ => 1,
        };
        if req.args.len() != arity {
            return Err(ServiceError::bad_request(format!(
                "`{}` takes {arity} argument(s), got {}",
                kind.name(),
                req.args.len()
            )));
        }
        let a = |i: usize| req.args[i].as_str();
        let holds = match kind {
            PredicateKind::Visible => predicates::visible(g, a(0), a(1), at),
            PredicateKind::Reachable => predicates::reachable(g, a(0), a(1), at),
            PredicateKind::Near => {
                let threshold = if g.node(a(0)).map_err(dr_err)?.node_type == NodeType::Robot {
                    cfg.near_robot_m
                } else {
                    cfg.near_effector_m
                };
                predicates::near(g, a(0), a(1), threshold, at)
            }
            PredicateKind::InField => predicates::in_field(g, a(0), cfg, at),
            PredicateKind::Fallen => predicates::fallen(g, a(0), cfg, at),
            PredicateKind::ClosestToBall => g.node(a(0)).and_then(|_| {
                predicates::closest_to_ball(g, cfg, at).map(|v| v.iter().any(|r| r == a(0)))
            }),
        }
        .map_err(dr_err)?;
        Ok(m::PredicateReply {
            holds,
            ..Default::default()
        })
    }

    /// `dr/fork`.
    pub async fn fork(&self, req: m::ForkRequest) -> Result<m::ForkReply, ServiceError> {
        let live = self.live.read().await;
        let g = &live.graph;
        Self::check_updates(g, &req.attributes, &req.poses, &req.joints)?;
        let proposals = req
            .changes
            .iter()
            .map(proposal_checked)
            .collect::<Result<Vec<_>, _>>()?;
        let mut f = g.fork();
        // After every kept sample, so the virtual actions become the fork's current state.
        let stamp = Stamp(g.newest_stamp().0.saturating_add(1));
        Self::apply_updates(&mut f, &req.attributes, &req.poses, &req.joints, stamp)
            .map_err(dr_err)?;
        let mut rejected = Vec::new();
        for (i, p) in proposals.into_iter().enumerate() {
            if let Err(r) = f.propose(p, stamp) {
                rejected.push(format!("{i}: {}", r.reason));
            }
        }
        let report = fork_report(g, &f, &self.predicates).map_err(dr_err)?;
        Ok(m::ForkReply {
            header: Default::default(),
            became_true: report.facts.became_true.iter().map(Into::into).collect(),
            became_false: report.facts.became_false.iter().map(Into::into).collect(),
            joints_changed: report
                .joints_changed
                .into_iter()
                .map(|(joint, live, fork)| m::JointChange { joint, live, fork })
                .collect(),
            moved: report
                .moved
                .into_iter()
                .map(|(node, distance_m)| m::Moved { node, distance_m })
                .collect(),
            rejected,
        })
    }

    /// `dr/pddl`.
    pub async fn pddl(&self, req: m::PddlRequest) -> Result<m::PddlReply, ServiceError> {
        let live = self.live.read().await;
        let name = if req.problem_name.is_empty() {
            "robocog-state"
        } else {
            req.problem_name.as_str()
        };
        let goal: Vec<Atom> = req
            .goal
            .iter()
            .map(|f| Atom {
                predicate: f.predicate.clone(),
                args: f.args.clone(),
            })
            .collect();
        let problem = export_problem(&live.graph, &self.predicates, At::Latest, name, &goal)
            .map_err(dr_err)?;
        Ok(m::PddlReply {
            header: Default::default(),
            problem: problem.to_pddl(),
        })
    }

    /// `dr/snapshot`.
    pub async fn snapshot(
        &self,
        _req: m::SnapshotRequest,
    ) -> Result<m::SnapshotData, ServiceError> {
        let live = self.live.read().await;
        Ok(m::SnapshotData {
            header: Default::default(),
            snapshot: live.graph.snapshot(),
            last_seq: live.last_seq,
        })
    }

    /// `dr/restore`: replace the live graph with a snapshot (`BadRequest` if it does not
    /// restore); persisted as a `restore` line, then compacted; published as `restored`.
    pub async fn restore(&self, req: m::SnapshotData) -> Result<m::SnapshotData, ServiceError> {
        let snap = req.snapshot;
        check_snapshot(&snap)
            .map_err(|e| ServiceError::bad_request(format!("not a valid snapshot: {e}")))?;
        let mut graph = SceneGraph::restore(&snap).map_err(dr_err)?;
        graph.set_history_len(self.history_len);
        graph.enable_log();
        let mut live = self.live.write().await;
        live.last_seq += 1;
        let seq = live.last_seq;
        live.graph = graph;
        let line = LogLine {
            seq,
            event: None,
            restore: Some(snap),
        };
        self.persist(&mut live, std::slice::from_ref(&line))?;
        let live = &mut *live;
        if let Some(store) = live.store.as_mut()
            && let Err(e) = store.compact(&live.graph, seq)
        {
            tracing::warn!("compaction after a restore failed (the log holds it): {e}");
        }
        tracing::info!(
            nodes = live.graph.len(),
            seq,
            "state replaced by a snapshot"
        );
        let msg = m::DrChange {
            header: interfaces::Header::new("world"),
            seq,
            event: m::ChangeEvent::Restored,
        };
        if self.changes.send(msg).await.is_err() {
            self.bus.counters().incr("dr/changes_not_published");
        }
        Ok(m::SnapshotData {
            header: Default::default(),
            snapshot: live.graph.snapshot(),
            last_seq: seq,
        })
    }

    /// Writes a final snapshot (clean stop).
    pub async fn checkpoint(&self) {
        let mut live = self.live.write().await;
        let live = &mut *live;
        if let Some(store) = live.store.as_mut()
            && store.since_compaction() > 0
            && let Err(e) = store.compact(&live.graph, live.last_seq)
        {
            tracing::warn!("final snapshot failed (the change log holds everything): {e}");
        }
    }
}
