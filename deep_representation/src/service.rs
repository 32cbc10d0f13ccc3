//! The `deep_representation` component: the scene graph served over the bus.
//!
//! One live [`SceneGraph`] per process, behind a read-write lock: queries (node, transform,
//! predicate, fork, PDDL, snapshot) share it, changes (update, propose, restore) take it alone.
//!
//! | service (`interfaces::topics`) | does |
//! |---|---|
//! | `dr/get_node` | one node: type, parent, children, edge, pose, attributes, its full description |
//! | `dr/transform` | `target_T_source`, latest or at a past time (interpolated from the edge histories) |
//! | `dr/update` | attributes, free poses, joint values, straight in; the batch is checked first and applied whole or not at all |
//! | `dr/propose` | a structural change; accepted or rejected with the integrity rule that refused it |
//! | `dr/predicate` | whether a predicate holds, or every fact that holds |
//! | `dr/fork` | virtual actions on a private copy; predicate changes, joints changed, items moved (the live graph untouched) |
//! | `dr/pddl` | the state as a PDDL problem text |
//! | `dr/snapshot`, `dr/restore` | the state as a typed snapshot (every node's description, the body parts); replace the state with one |
//!
//! Every accepted change is published on `dr/changes` (in order, with a sequence number that
//! continues across restarts) and, with a state folder, appended to its change log before the
//! reply leaves (see [`world_model::persist`]).
//!
//! Bus messages and library types meet in `world_model::bus` (conversions both ways).
//!
//! Errors: an unknown node, frame or joint is a `NotFound` [`ServiceError`]; a malformed request
//! (a non-finite number, an attribute given twice, a wrong argument count, a negative stamp) is
//! `BadRequest`; a rejected proposal is a normal reply. Time: the stamp of a change is the
//! request's `header.stamp_ns`, or now on the bus clock when it is 0.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use interfaces::msg::dr as m;
use interfaces::node::Interface;
use interfaces::{Bus, ServiceError, Shutdown, topics};
use tokio::sync::{RwLock, mpsc};

use robot_model::RobotModel;
use world_model::bus::{reason_code, transform_from_iso};
use world_model::error::DrError;
use world_model::field::FieldModel;
use world_model::graph::{At, EdgeKind, SceneGraph};
use world_model::pddl::{Atom, export_problem};
use world_model::persist::{LogLine, RecoveryReport, Store, StoreOptions};
use world_model::predicates::{self, PredicateConfig, PredicateKind, fork_report};
use world_model::scenes;
use world_model::types::{self, NodeType, Pose, Proposal, Stamp};

/// The start scene used when the state folder holds no state (or there is none).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Scene {
    /// Loki, the player and the ball ([`scenes::touch_the_ball`]); needs the URDF.
    Touch,
    /// The SPL field, four robots, the ball, the coach ([`scenes::coach_game`]); needs the field.
    Coach,
    /// Only `world`.
    Empty,
}

/// How the service runs.
#[derive(Debug, Clone)]
pub struct ServiceConfig {
    /// State folder (snapshot + change log); `None`: in memory only.
    pub state_dir: Option<PathBuf>,
    /// Start scene.
    pub scene: Scene,
    /// The robot's URDF (for [`Scene::Touch`]).
    pub urdf: PathBuf,
    /// The SPL field model (for [`Scene::Coach`]).
    pub field: PathBuf,
    /// Persistence options.
    pub store: StoreOptions,
    /// Predicate thresholds.
    pub predicates: PredicateConfig,
    /// Samples kept per edge.
    pub history_len: usize,
    /// Follow the measured joints: subscribe `body/joint_states` and apply them to the robot's
    /// joint edges (see [`follow_joint_states`]).
    pub follow_joint_states: bool,
}

impl ServiceConfig {
    /// A config for `scene` with the repository's models (found as [`find_model`] does), in
    /// memory.
    pub fn new(scene: Scene) -> Self {
        Self {
            state_dir: None,
            scene,
            urdf: find_model(None, "loki.urdf"),
            field: find_model(None, "spl_field.toml"),
            store: StoreOptions::default(),
            predicates: PredicateConfig::default(),
            history_len: SceneGraph::DEFAULT_HISTORY_LEN,
            follow_joint_states: false,
        }
    }

    /// The start scene.
    pub fn start_scene(&self) -> world_model::Result<SceneGraph> {
        match self.scene {
            Scene::Touch => {
                let loki = RobotModel::from_urdf_file(&self.urdf)?;
                scenes::touch_the_ball(&loki, Stamp(0))
            }
            Scene::Coach => {
                let field = FieldModel::from_file(&self.field)?;
                scenes::coach_game(&field, Stamp(0))
            }
            Scene::Empty => Ok(SceneGraph::new()),
        }
    }
}

pub use robot_model::find_model;

/// The component's interface (what `--describe` prints).
pub fn interface() -> Interface {
    interface_with(false)
}

/// The interface, with the `body/joint_states` subscription when `follow_joint_states`.
pub fn interface_with(follow_joint_states: bool) -> Interface {
    let i = Interface::new("deep_representation");
    let i = if follow_joint_states {
        i.subscribes(&topics::BODY_JOINT_STATES)
    } else {
        i
    };
    i.publishes(&topics::DR_CHANGES)
        .serves(&topics::DR_GET_NODE)
        .serves(&topics::DR_TRANSFORM)
        .serves(&topics::DR_UPDATE)
        .serves(&topics::DR_PROPOSE)
        .serves(&topics::DR_PREDICATE)
        .serves(&topics::DR_FORK)
        .serves(&topics::DR_PDDL)
        .serves(&topics::DR_SNAPSHOT)
        .serves(&topics::DR_RESTORE)
}

// ---------------------------------------------------------------- conversions

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
    Ok((&a.value).into())
}

fn pose_checked(what: &str, t: &m::Transform) -> Result<Pose, ServiceError> {
    let p = Pose::from(t);
    if p.is_valid() {
        Ok(p)
    } else {
        Err(ServiceError::bad_request(format!(
            "pose of `{what}`: not finite, or a zero quaternion"
        )))
    }
}

/// A bus structural change as a library proposal (`BadRequest` for what the library cannot
/// hold: an attribute given twice, a number that is not finite).
fn proposal_checked(c: &m::StructuralChange) -> Result<Proposal, ServiceError> {
    Proposal::try_from(c).map_err(|e| ServiceError::bad_request(e.to_string()))
}

// ---------------------------------------------------------------- the live state

struct Live {
    graph: SceneGraph,
    store: Option<Store>,
    last_seq: u64,
}

/// The state shared by the service handlers.
pub struct Dr {
    live: RwLock<Live>,
    changes: mpsc::Sender<m::DrChange>,
    predicates: PredicateConfig,
    history_len: usize,
    bus: Bus,
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
                event: ev.into(),
            };
            msg.header.stamp_ns = ev.stamp().0.min(i64::MAX as u64) as i64;
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
        let spec = g
            .node_spec(&req.name)
            .map(|s| m::NodeSpec::from(&s))
            .unwrap_or_default();
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
            pose: transform_from_iso(n.edge.current()),
            attributes: n
                .attrs
                .iter()
                .map(|(k, v)| m::Attribute {
                    node: n.name.clone(),
                    key: k.clone(),
                    value: v.into(),
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
            transform: transform_from_iso(&iso),
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
            g.set_pose(&p.node, &Pose::from(&p.pose).to_iso(), stamp)?;
        }
        for a in attributes {
            g.set_attr(&a.node, &a.key, (&a.value).into(), stamp)?;
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
            snapshot: (&live.graph.snapshot()).into(),
            last_seq: live.last_seq,
        })
    }

    /// `dr/restore`: replace the live graph with a snapshot (`BadRequest` if it does not
    /// restore); persisted as a `restore` line, then compacted; published as `restored`.
    pub async fn restore(&self, req: m::SnapshotData) -> Result<m::SnapshotData, ServiceError> {
        let snap = types::Snapshot::try_from(&req.snapshot)
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
            snapshot: (&live.graph.snapshot()).into(),
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

/// A started service: dropping it stops serving.
pub struct Running {
    /// The shared state (handlers can be called directly, without the bus).
    pub dr: Arc<Dr>,
    /// What recovery did (`None` without a state folder).
    pub recovery: Option<RecoveryReport>,
    _services: Vec<interfaces::bus::ServiceHandle>,
    publisher: tokio::task::JoinHandle<()>,
    joints: Option<tokio::task::JoinHandle<()>>,
}

impl std::fmt::Debug for Running {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Running")
            .field("recovery", &self.recovery)
            .finish()
    }
}

impl Drop for Running {
    fn drop(&mut self) {
        self.publisher.abort();
        if let Some(j) = &self.joints {
            j.abort();
        }
    }
}

fn log_recovery(dir: &Path, r: &RecoveryReport) {
    for p in &r.problems {
        tracing::warn!("{p}");
    }
    match &r.snapshot {
        Some(s) => tracing::info!(
            "recovered the state from {}: snapshot {}, {} changes replayed, {} bad log lines skipped, {} changes no longer applied, last change #{}",
            dir.display(),
            s.display(),
            r.replayed,
            r.bad_lines,
            r.failed_events,
            r.last_seq
        ),
        None => tracing::info!(
            "no state in {}: started from the scene ({} changes replayed)",
            dir.display(),
            r.replayed
        ),
    }
}

/// Loads or recovers the graph, serves every DR service and starts publishing changes.
pub async fn start(bus: Bus, config: ServiceConfig) -> anyhow::Result<Running> {
    let (mut graph, store, recovery, last_seq) = match &config.state_dir {
        Some(dir) => {
            let (store, graph, report) = Store::open(dir, config.store, || config.start_scene())?;
            log_recovery(dir, &report);
            let counters = bus.counters();
            counters.counter("dr/recovery_bad_log_lines").fetch_add(
                report.bad_lines as u64,
                std::sync::atomic::Ordering::Relaxed,
            );
            counters.counter("dr/recovery_corrupt_snapshots").fetch_add(
                report.corrupt_snapshots as u64,
                std::sync::atomic::Ordering::Relaxed,
            );
            let seq = report.last_seq;
            (graph, Some(store), Some(report), seq)
        }
        None => {
            let g = config.start_scene().map_err(|e| {
                anyhow::anyhow!("cannot build the {:?} start scene: {e}", config.scene)
            })?;
            tracing::info!("no state folder: the state lives in memory only");
            (g, None, None, 0)
        }
    };
    graph.set_history_len(config.history_len);
    graph.enable_log();
    let nodes = graph.len();

    let (tx, mut rx) = mpsc::channel::<m::DrChange>(4096);
    let publisher = bus.publisher(&topics::DR_CHANGES).await?;
    let publisher = tokio::spawn(async move {
        while let Some(mut msg) = rx.recv().await {
            if let Err(e) = publisher.publish(&mut msg).await {
                tracing::warn!("cannot publish a change: {e}");
            }
        }
    });
    let dr = Arc::new(Dr {
        live: RwLock::new(Live {
            graph,
            store,
            last_seq,
        }),
        changes: tx,
        predicates: config.predicates.clone(),
        history_len: config.history_len,
        bus: bus.clone(),
    });

    macro_rules! serve {
        ($svc:expr, $method:ident) => {{
            let dr = dr.clone();
            bus.serve(&$svc, move |req| {
                let dr = dr.clone();
                async move { dr.$method(req).await }
            })
            .await?
        }};
    }
    let services = vec![
        serve!(topics::DR_GET_NODE, get_node),
        serve!(topics::DR_TRANSFORM, transform),
        serve!(topics::DR_UPDATE, update),
        serve!(topics::DR_PROPOSE, propose),
        serve!(topics::DR_PREDICATE, predicate),
        serve!(topics::DR_FORK, fork),
        serve!(topics::DR_PDDL, pddl),
        serve!(topics::DR_SNAPSHOT, snapshot),
        serve!(topics::DR_RESTORE, restore),
    ];
    let joints = if config.follow_joint_states {
        let sub = bus.subscriber(&topics::BODY_JOINT_STATES).await?;
        tracing::info!(
            "following the measured joints on {} (at most every {:?})",
            topics::BODY_JOINT_STATES.name(),
            JOINT_STATES_MIN_INTERVAL
        );
        Some(tokio::spawn(follow_joint_states(dr.clone(), sub)))
    } else {
        None
    };
    tracing::info!(
        nodes,
        last_seq,
        "serving the deep representation ({} services, changes on {})",
        services.len(),
        topics::DR_CHANGES.name()
    );
    Ok(Running {
        dr,
        recovery,
        _services: services,
        publisher,
        joints,
    })
}

/// Joint states are applied at most this often by their stamps (50 Hz); the ones in between are
/// skipped (by stamp, so a replay at any rate applies the same ones).
pub const JOINT_STATES_MIN_INTERVAL: Duration = Duration::from_millis(20);

/// Applies the measured joints of `body/joint_states` to the robot's joint edges, so that
/// `dr/transform` of a hand or of the head camera follows the body. Each value enters the edge's
/// history at the message's stamp (the bus clock of `joint_motor`; now if 0). Measurements are
/// telemetry, not decisions: they are neither persisted nor published on `dr/changes`.
/// Counters: `dr/joint_states_applied`, `dr/joint_states_skipped` (rate limit),
/// `dr/unknown_joints` (a joint the model does not have, logged once a second).
pub async fn follow_joint_states(
    dr: Arc<Dr>,
    sub: interfaces::bus::Subscriber<interfaces::msg::body::JointStates>,
) {
    let counters = dr.bus.counters().clone();
    let mut last: Option<Stamp> = None;
    let mut unknown_log = interfaces::ratelimit::RateLimiter::new(Duration::from_secs(1));
    let min_interval = JOINT_STATES_MIN_INTERVAL.as_nanos() as u64;
    while let Ok(msg) = sub.recv().await {
        let stamp = match msg.header.stamp_ns {
            t if t > 0 => Stamp(t as u64),
            _ => Stamp(dr.bus.clock().now_ns().max(0) as u64),
        };
        // Thinned by the stamps, not by the arrival: a replay at any rate keeps the same ones.
        if last.is_some_and(|l| stamp.0 >= l.0 && stamp.0 - l.0 < min_interval) {
            counters.incr("dr/joint_states_skipped");
            continue;
        }
        last = Some(stamp);
        let mut unknown: Vec<&str> = Vec::new();
        {
            let mut live = dr.live.write().await;
            for j in &msg.joints {
                let applied = live
                    .graph
                    .joint_node(&j.name)
                    .and_then(|id| live.graph.set_joint_id(id, j.position, stamp));
                if applied.is_err() {
                    unknown.push(&j.name);
                }
            }
        }
        counters.incr("dr/joint_states_applied");
        if !unknown.is_empty() {
            counters
                .counter("dr/unknown_joints")
                .fetch_add(unknown.len() as u64, std::sync::atomic::Ordering::Relaxed);
            if let Some(suppressed) = unknown_log.allow(std::time::Instant::now()) {
                tracing::warn!(
                    suppressed,
                    "joint states from `{}` name joints the model does not have (or non-finite values): {unknown:?}",
                    msg.driver
                );
            }
        }
    }
}

/// The component: [`start`], serve until `shutdown`, write a final snapshot.
pub async fn run(bus: Bus, config: ServiceConfig, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let running = start(bus, config).await?;
    shutdown.wait().await;
    running.dr.checkpoint().await;
    // Let queued change events leave before the process ends.
    tokio::time::sleep(Duration::from_millis(50)).await;
    tracing::info!("stopped");
    Ok(())
}

/// The service's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Flags {
    /// Keep the state here (snapshot + change log) and recover it on start. Under `robocog
    /// launch` it defaults to the component's state folder (ROBOCOG_STATE_DIR), so a restarted
    /// DR takes up the world where it was; without either the state lives in memory only.
    #[arg(long, env = "ROBOCOG_STATE_DIR")]
    pub state_dir: Option<PathBuf>,
    /// Start scene when there is no saved state.
    #[arg(long, value_enum, default_value_t = Scene::Touch)]
    pub scene: Scene,
    /// The robot's URDF (default: models/loki.urdf found above the binary or the working folder).
    #[arg(long, env = "ROBOCOG_URDF")]
    pub urdf: Option<PathBuf>,
    /// The SPL field model (default: models/spl_field.toml, found like the URDF).
    #[arg(long, env = "ROBOCOG_FIELD")]
    pub field: Option<PathBuf>,
    /// Write a fresh snapshot every this many changes.
    #[arg(long, default_value_t = 1000)]
    pub compact_every: usize,
    /// fdatasync the change log after every change (survives a power loss, costs a disk flush).
    #[arg(long)]
    pub fsync: bool,
    /// Follow the measured joints: subscribe body/joint_states (from joint_motor) and apply them
    /// to the robot's joints, so transforms of the hands and the head camera follow the body.
    #[arg(long)]
    pub follow_joint_states: bool,
}

/// The `deep_representation` component.
#[derive(Debug)]
pub struct DeepRepresentation;

impl interfaces::node::Component for DeepRepresentation {
    const NAME: &'static str = "deep_representation";
    const ABOUT: &'static str =
        "The deep representation: robocog's world model, served on the bus.";
    type Config = Flags;
    type Prepared = ServiceConfig;

    fn interface(config: &Flags) -> Interface {
        interface_with(config.follow_joint_states)
    }

    fn prepare(config: Flags) -> anyhow::Result<ServiceConfig> {
        Ok(ServiceConfig {
            state_dir: config.state_dir,
            scene: config.scene,
            urdf: find_model(config.urdf.as_deref(), "loki.urdf"),
            field: find_model(config.field.as_deref(), "spl_field.toml"),
            store: StoreOptions {
                compact_every: config.compact_every.max(1),
                fsync: config.fsync,
            },
            follow_joint_states: config.follow_joint_states,
            ..ServiceConfig::new(config.scene)
        })
    }

    async fn run(bus: Bus, prepared: ServiceConfig, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}
