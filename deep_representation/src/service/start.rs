//! Starting the service: loading or recovering the state, serving every DR service, publishing
//! the changes, and following the measured joints.

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use interfaces::msg::dr as m;
use interfaces::{Bus, topics};
use tokio::sync::{RwLock, mpsc};

use world_model::persist::{RecoveryReport, Store};
use world_model::types::Stamp;

use super::ServiceConfig;
use super::dr::{Dr, Live};

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
            #[expect(
                clippy::disallowed_methods,
                reason = "log lines are rate-limited on the wall: it bounds what reaches the console and the disk"
            )]
            let wall = std::time::Instant::now();
            if let Some(suppressed) = unknown_log.allow(wall) {
                tracing::warn!(
                    suppressed,
                    "joint states from `{}` name joints the model does not have (or non-finite values): {unknown:?}",
                    msg.driver
                );
            }
        }
    }
}
