//! The `body_inverse_kinematics` component: reach and gaze goals on the bus, solved with
//! [`BodyIk`] from the measured joints and executed through `joint_motor`.
//!
//! # Bus
//! - Subscribes `body/joint_states` (the measured joints: start of every solve, the posture of the
//!   rest of the body for the self-collision check, and the "reached" test) and `body/reach`
//!   ([`ReachGoal`]).
//! - Calls `dr/transform` (the target frame into the body part's root frame; the target and the
//!   root into `world` for the status) and `body/joint_goal` (the trajectory, as position goals).
//! - Publishes `body/reach_status` ([`ReachStatus`]).
//!
//! # One goal per body part
//! A new goal for a part replaces the previous one (which gets `Cancelled`); `active = false`
//! cancels it (`Cancelled`) and releases the part's joints in `joint_motor`, so another client
//! (the Executive's "home" goal) can take them. While a goal is active, its joints are owned by
//! the client `<component>/<part>` (`body_inverse_kinematics/left_arm_7`) at `--priority`: they
//! are commanded at `--stream-hz` while moving and every `1/--hold-hz` s once there, which keeps
//! the lease. Two active parts sharing joints (`left_arm_7` and `left_arm_13`) conflict: the
//! second fails with the owner named.
//!
//! # A goal's life
//! 1. The target (`position_m`, and `orientation_xyzw` for a pose, in `frame`) is moved into the
//!    chain's root frame with `dr/transform`; the IK solves it from the measured joints with a
//!    `--solve-budget-ms` budget (off the async reactor). Tolerance: the goal's `tolerance_m`, or
//!    `--tolerance-m` (1 cm); the IK itself aims at min(1 mm, tolerance).
//! 2. No solution within the tolerance: `Unreachable` with the best residual, and nothing moves.
//! 3. Otherwise `Moving` (with the residual), then a quintic trajectory from the measured joints
//!    to the solution (peak speed `--speed-fraction` of each joint's URDF limit, jerk at most
//!    `--max-joint-jerk`, the hand of a position or pose goal at most `--max-hand-speed-m-s`, at
//!    least `min_duration_s`), streamed as position goals. Its peak hand speed and jerk are
//!    logged and counted (`hand_speed_limited`).
//! 4. `Reached` once the trajectory is over and the tip, by forward kinematics of the measured
//!    joints, is within tolerance of the target (a gaze: the target within tolerance of the
//!    camera's optical axis; a pose: also within [`POSE_TOLERANCE_RAD`]). If it is not there
//!    [`SETTLE_TIMEOUT_S`] after the trajectory ended: `Failed`.
//! 5. `follow = true`: at `--follow-hz`, the target frame is looked up again; when it moved more
//!    than `--follow-threshold-m`, the goal is solved again from the current joints (`Moving`,
//!    then `Reached` again).
//!
//! The eyes (`--eyes`, on by default): a gaze of the `neck` or `head` moves the eyes too, with
//! the neck's own goals. At every goal sent they are aimed at the target from where the measured
//! joints put the head ([`crate::eyes::Eyes`]): the eyes get there first, at their top speed, and
//! turn back towards the middle as the head catches up. When the gaze ends (cancelled, replaced
//! by a goal that is not a gaze, over) the eyes go back to the middle before the joints are
//! released. Eyes that `body/joint_states` does not report (a servo map without them) stay
//! still from then on: logged, counted as `eyes_not_driven`.
//!
//! `Failed` carries a detail for: an unknown body part, an unknown frame, the DR or `joint_motor`
//! not answering, no joint states, a refused joint goal (with the joint, limit or owner).
//!
//! A peer that is away (the DR or `joint_motor` not answering, no joint states: killed and
//! restarting, its machine's link down) is ridden out for `--peer-grace-s`: the goal stays, the
//! arm holds where it is, and the goal goes on once the peer is back. Only past the grace is it
//! `Failed`.
//!
//! Frames and units: metres, radians; quaternions `[x, y, z, w]`; status positions in `world`.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use interfaces::Moment;

use anyhow::Context;
use interfaces::bus::{CallError, Publisher};
use interfaces::msg::body::{
    JointGoal, JointMode, JointStates, JointTarget, ReachGoal, ReachKind, ReachState, ReachStatus,
};
use interfaces::msg::dr::{Transform, TransformRequest};
use interfaces::node::Interface;
use interfaces::ratelimit::RateLimiter;
use interfaces::{Bus, ErrorCode, Header, Shutdown, topics};
use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3};
use robot_model::find_model;
use robot_model::{BODY_PARTS, BodyPart, Chain};

use crate::body::BodyIk;
use crate::trajectory::Trajectory;
use crate::types::{IkRequest, IkResult, IkTarget, UnreachableCause};

mod reach;

/// Orientation tolerance of a reached pose (rad), on the measured joints.
pub const POSE_TOLERANCE_RAD: f64 = 0.05;
/// How long after its trajectory ended a part may take to settle within tolerance (s).
pub const SETTLE_TIMEOUT_S: f64 = 3.0;
/// Joint states older than this (s) are not used to start a solve.
pub const STALE_JOINT_STATES_S: f64 = 0.5;

/// The component's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// The robot's URDF (default: models/loki.urdf, found above the binary or the working folder,
    /// as deep_representation does). Must be the one joint_motor and the DR use.
    #[arg(long, env = "ROBOCOG_URDF")]
    pub urdf: Option<PathBuf>,
    /// Default position tolerance (m) of a goal that gives none.
    #[arg(long, default_value_t = 0.01)]
    pub tolerance_m: f64,
    /// Compute-time budget of one IK solve (ms), random restarts included.
    #[arg(long, default_value_t = 20.0)]
    pub solve_budget_ms: f64,
    /// Rate (Hz) of the position goals streamed along a trajectory.
    #[arg(long, default_value_t = 50.0)]
    pub stream_hz: f64,
    /// Rate (Hz) of the goals that hold a part at its solution (keeps the joints' lease).
    #[arg(long, default_value_t = 5.0)]
    pub hold_hz: f64,
    /// Rate (Hz) at which a followed target frame is looked up.
    #[arg(long, default_value_t = 10.0)]
    pub follow_hz: f64,
    /// A followed target is solved again when it moved more than this (m).
    #[arg(long, default_value_t = 0.02)]
    pub follow_threshold_m: f64,
    /// Peak joint speed of a trajectory, as a fraction of each joint's URDF velocity limit.
    #[arg(long, default_value_t = 0.5)]
    pub speed_fraction: f64,
    /// Peak jerk of every joint along a trajectory (rad/s³, m/s³ for a prismatic joint): the
    /// quintic's jerk peaks as it starts and stops, so this softens the starts of short moves.
    #[arg(long, default_value_t = 50.0)]
    pub max_joint_jerk: f64,
    /// Peak speed of the hand (the tip of a position or pose goal, m/s): the arm reaches towards
    /// a person's hand, and fast arms frighten people (seed 001 §V.E). A trajectory whose tip
    /// would go faster is slowed down along the same path.
    #[arg(long, default_value_t = 0.5)]
    pub max_hand_speed_m_s: f64,
    /// Priority of this component's joint goals in joint_motor (higher preempts).
    #[arg(long, default_value_t = 0)]
    pub priority: u8,
    /// Time-out of each call to dr/transform and body/joint_goal (ms).
    #[arg(long, default_value_t = 250)]
    pub call_timeout_ms: u64,
    /// Move the eyes with a gaze of the neck or the head (eyes first, the head after them);
    /// `false`: the eyes stay still.
    #[arg(long, default_value_t = true, action = clap::ArgAction::Set)]
    pub eyes: bool,
    /// How long a goal rides out a peer that is away (the DR or joint_motor not answering, no
    /// joint states) before it fails (s): a restart by the launcher takes about a second.
    #[arg(long, default_value_t = 6.0)]
    pub peer_grace_s: f64,
    /// Narrows a joint's range for every solve: `JOINT=LOWER:UPPER` (rad, or m for a prismatic
    /// joint), inside the URDF's limits; repeatable. `base_forward=0:0.2` lets a reach that
    /// uses the base (`left_arm_9`, `left_arm_13`) move it 20 cm forward at most.
    #[arg(long = "joint-range", value_name = "JOINT=LOWER:UPPER", value_parser = parse_joint_range)]
    pub joint_ranges: Vec<(String, f64, f64)>,
}

/// A `--joint-range` value: `JOINT=LOWER:UPPER`.
fn parse_joint_range(s: &str) -> Result<(String, f64, f64), String> {
    let bad = || format!("`{s}`: expected JOINT=LOWER:UPPER, e.g. base_forward=0:0.2");
    let (joint, range) = s.split_once('=').ok_or_else(bad)?;
    let (lo, hi) = range.split_once(':').ok_or_else(bad)?;
    let lo: f64 = lo.trim().parse().map_err(|_| bad())?;
    let hi: f64 = hi.trim().parse().map_err(|_| bad())?;
    if joint.trim().is_empty() {
        return Err(bad());
    }
    Ok((joint.trim().to_string(), lo, hi))
}

impl Config {
    fn check(&self) -> anyhow::Result<()> {
        let positive = [
            ("--tolerance-m", self.tolerance_m),
            ("--stream-hz", self.stream_hz),
            ("--hold-hz", self.hold_hz),
            ("--follow-hz", self.follow_hz),
            ("--follow-threshold-m", self.follow_threshold_m),
            ("--speed-fraction", self.speed_fraction),
            ("--max-joint-jerk", self.max_joint_jerk),
            ("--max-hand-speed-m-s", self.max_hand_speed_m_s),
            ("--peer-grace-s", self.peer_grace_s),
        ];
        for (flag, v) in positive {
            anyhow::ensure!(v.is_finite() && v > 0.0, "{flag} must be > 0, got {v}");
        }
        anyhow::ensure!(
            self.solve_budget_ms.is_finite() && self.solve_budget_ms >= 0.0,
            "--solve-budget-ms must be >= 0"
        );
        anyhow::ensure!(
            self.speed_fraction <= 1.0,
            "--speed-fraction must be at most 1"
        );
        Ok(())
    }
}

/// What the component declares for `--describe`.
pub fn interface() -> Interface {
    Interface::new("body_inverse_kinematics")
        .subscribes(&topics::BODY_JOINT_STATES)
        .subscribes(&topics::BODY_REACH)
        .publishes(&topics::BODY_REACH_STATUS)
        .calls(&topics::DR_TRANSFORM)
        .calls(&topics::BODY_JOINT_GOAL)
}

// ---------------------------------------------------------------- pure helpers

/// `target_T_source` of a DR transform message (the quaternion is normalised; a zero one is the
/// identity).
pub fn iso_from_msg(t: &Transform) -> Isometry3<f64> {
    let [x, y, z, w] = t.rotation_xyzw;
    let q = Quaternion::new(w, x, y, z);
    let r = if q.norm() > 1e-12 {
        UnitQuaternion::from_quaternion(q)
    } else {
        UnitQuaternion::identity()
    };
    let [tx, ty, tz] = t.translation_m;
    Isometry3::from_parts(Translation3::new(tx, ty, tz), r)
}

/// How far the tip frame `tip` is from the target (both in the same frame): for a position or a
/// pose, the distance between origins (m) and, for a pose, the rotation angle between them (rad,
/// else 0); for a gaze, the distance from the target point to the tip's optical axis (+z) ray
/// (m; to the camera centre when the point is behind it) and the angle between the axis and the
/// direction to the point (rad).
pub fn tip_error(kind: ReachKind, tip: &Isometry3<f64>, target: &Isometry3<f64>) -> (f64, f64) {
    let p = target.translation.vector;
    let o = tip.translation.vector;
    match kind {
        ReachKind::Position => ((p - o).norm(), 0.0),
        ReachKind::Pose => ((p - o).norm(), tip.rotation.angle_to(&target.rotation)),
        ReachKind::Gaze => {
            let axis = tip.rotation * Vector3::z();
            let v = p - o;
            let along = v.dot(&axis);
            let angle = if v.norm() > 1e-12 {
                axis.angle(&v)
            } else {
                0.0
            };
            if along <= 0.0 {
                (v.norm(), angle)
            } else {
                ((v - axis * along).norm(), angle)
            }
        }
    }
}

pub use crate::body::chain_q;

/// The IK target for a goal whose target pose is `target` in the chain's root frame.
pub fn ik_target(kind: ReachKind, target: &Isometry3<f64>) -> IkTarget {
    let p = target.translation.vector;
    let position_m = [p.x, p.y, p.z];
    match kind {
        ReachKind::Position => IkTarget::Position { position_m },
        ReachKind::Pose => {
            let q = target.rotation.coords;
            IkTarget::Pose {
                position_m,
                orientation_xyzw: [q.x, q.y, q.z, q.w],
            }
        }
        ReachKind::Gaze => IkTarget::Gaze {
            point_m: position_m,
        },
    }
}

/// The pose of a goal's target in its own `frame` (a pose goal's orientation; identity otherwise).
pub fn goal_pose(goal: &ReachGoal) -> Result<Isometry3<f64>, String> {
    let [x, y, z] = goal.position_m;
    if ![x, y, z].iter().all(|v| v.is_finite()) {
        return Err(format!("position_m {:?} is not finite", goal.position_m));
    }
    let rotation = if goal.kind == ReachKind::Pose {
        let [qx, qy, qz, qw] = goal.orientation_xyzw;
        let q = Quaternion::new(qw, qx, qy, qz);
        if !(q.norm().is_finite() && q.norm() > 1e-9) {
            return Err(format!(
                "orientation_xyzw {:?} is not a rotation",
                goal.orientation_xyzw
            ));
        }
        UnitQuaternion::from_quaternion(q)
    } else {
        UnitQuaternion::identity()
    };
    Ok(Isometry3::from_parts(Translation3::new(x, y, z), rotation))
}

fn xyz(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

// ---------------------------------------------------------------- the component

/// A solved goal in motion (or holding at its solution).
#[derive(Debug)]
struct Plan {
    trajectory: Trajectory,
    started: Moment,
    residual_m: f64,
    reached: bool,
    settle_failed: bool,
    last_sent: Option<Moment>,
}

/// The active goal of one body part.
#[derive(Debug)]
struct Active {
    goal: ReachGoal,
    part: &'static BodyPart,
    chain: Chain,
    /// URDF velocity limits of the chain's joints (rad/s or m/s).
    vmax: Vec<f64>,
    tolerance_m: f64,
    /// The target in the chain's root frame (as last solved).
    target_root: Isometry3<f64>,
    target_world: Isometry3<f64>,
    world_t_root: Isometry3<f64>,
    plan: Option<Plan>,
    last_follow: Moment,
    /// Set while the goal waits for fresh joint states (just after start, or joint_motor away):
    /// it fails after `--peer-grace-s`.
    waiting_since: Option<Moment>,
    /// Whether the target was looked up in the DR (a goal that arrives while the DR is away is
    /// looked up once it is back).
    located: bool,
    /// Since when a peer has been away (ridden out for `--peer-grace-s`).
    peer_away_since: Option<Moment>,
    /// Whether this goal moves the eyes (a gaze of the head, see the module docs).
    eyes: bool,
}

/// Why a goal could not run. `peer_away`: the DR or joint_motor did not answer (no server, a
/// time-out), which a restart fixes; the goal rides it out for a while.
struct Failure {
    detail: String,
    peer_away: bool,
}

impl Failure {
    fn new(detail: String) -> Self {
        Failure {
            detail,
            peer_away: false,
        }
    }
}

impl From<String> for Failure {
    fn from(s: String) -> Self {
        Failure::new(s)
    }
}

struct Ik {
    bus: Bus,
    config: Config,
    /// `None` only while a solve runs on the blocking pool.
    body: Option<BodyIk>,
    measured: HashMap<String, f64>,
    measured_at: Option<Moment>,
    parts: HashMap<String, Active>,
    status: Publisher<ReachStatus>,
    timeout: Duration,
    warn: RateLimiter,
    /// The eyes, if the model has eyes this component can drive and `--eyes` is on.
    eyes: Option<crate::eyes::Eyes>,
}

fn call_failure(what: &str, e: &CallError) -> Failure {
    match e {
        CallError::NoServer(_) | CallError::Timeout { .. } => Failure {
            detail: format!("{what}: unreachable ({e})"),
            peer_away: true,
        },
        other => Failure::new(format!("{what}: {other}")),
    }
}

impl Ik {
    fn client(&self, part: &str) -> String {
        format!("{}/{part}", self.bus.component())
    }

    async fn publish(&self, status: ReachStatus) {
        let mut status = status;
        if let Err(e) = self.status.publish(&mut status).await {
            tracing::warn!("could not publish a reach status: {e}");
        }
    }

    fn status(goal: &ReachGoal, state: ReachState, detail: impl Into<String>) -> ReachStatus {
        ReachStatus {
            header: Header::new("world"),
            id: goal.id,
            body_part: goal.body_part.clone(),
            state,
            residual_m: 0.0,
            distance_m: -1.0,
            target_world_m: [0.0; 3],
            tip_world_m: [0.0; 3],
            detail: detail.into(),
        }
    }

    /// A status of an active goal, with the tip and its distance from the measured joints.
    fn active_status(
        &self,
        a: &Active,
        state: ReachState,
        detail: impl Into<String>,
    ) -> ReachStatus {
        let mut s = Self::status(&a.goal, state, detail);
        s.target_world_m = xyz(&a.target_world.translation.vector);
        s.residual_m = a.plan.as_ref().map_or(0.0, |p| p.residual_m);
        if let Some((tip_root, dist)) = self.measured_tip(a) {
            s.distance_m = dist;
            s.tip_world_m = xyz(&(a.world_t_root * tip_root).translation.vector);
        }
        s
    }

    /// The tip in the root frame from the measured joints, and its error to the target (m).
    fn measured_tip(&self, a: &Active) -> Option<(Isometry3<f64>, f64)> {
        let q = chain_q(&a.chain, &self.measured).ok()?;
        let tip = a.chain.fk(&q).ok()?;
        Some((tip, tip_error(a.goal.kind, &tip, &a.target_root).0))
    }

    async fn transform(&self, target: &str, source: &str) -> Result<Isometry3<f64>, Failure> {
        let req = TransformRequest {
            header: Header::default(),
            target: target.to_owned(),
            source: source.to_owned(),
            stamp_ns: 0,
        };
        match self
            .bus
            .call(&topics::DR_TRANSFORM, &req, self.timeout)
            .await
        {
            Ok(rep) => Ok(iso_from_msg(&rep.transform)),
            Err(CallError::Remote(e)) if e.code == ErrorCode::NotFound => {
                Err(Failure::new(format!(
                    "unknown frame: the deep representation has no transform {target} <- {source} ({})",
                    e.message
                )))
            }
            Err(e) => Err(call_failure("deep_representation (dr/transform)", &e)),
        }
    }

    async fn send(&self, goal: &JointGoal) -> Result<(), Failure> {
        match self
            .bus
            .call(&topics::BODY_JOINT_GOAL, goal, self.timeout)
            .await
        {
            Ok(rep) if rep.accepted => Ok(()),
            Ok(rep) => {
                self.bus.counters().incr("joint_goals_refused");
                Err(Failure::new(format!(
                    "joint_motor refused the joints: {}",
                    rep.detail
                )))
            }
            Err(e) => Err(call_failure("joint_motor (body/joint_goal)", &e)),
        }
    }

    /// Gives a finished goal's joints back, the eyes first sent back to the middle if it moved
    /// them.
    async fn release_goal(&self, a: &Active) {
        if let (true, Some(eyes)) = (a.eyes, &self.eyes) {
            let centre = JointGoal {
                client: self.client(&a.goal.body_part),
                priority: self.config.priority,
                targets: eyes
                    .joints()
                    .iter()
                    .zip(eyes.max_speeds())
                    .map(|(j, max_speed)| JointTarget {
                        joint: j.clone(),
                        mode: JointMode::Position,
                        position: 0.0,
                        max_speed,
                        velocity: 0.0,
                    })
                    .collect(),
                ..Default::default()
            };
            if let Err(f) = self.send(&centre).await {
                tracing::warn!("could not bring the eyes back to the middle: {}", f.detail);
            }
        }
        self.release(&a.goal.body_part).await;
    }

    async fn release(&self, part: &str) {
        let goal = JointGoal {
            client: self.client(part),
            release: true,
            ..Default::default()
        };
        if let Err(f) = self.send(&goal).await {
            tracing::warn!("could not release the joints of {part}: {}", f.detail);
        }
    }

    /// A reach goal arrived.
    async fn on_goal(&mut self, goal: ReachGoal) {
        self.bus.counters().incr("goals");
        let mut old_eyes = None;
        if let Some(old) = self.parts.remove(&goal.body_part) {
            let detail = if goal.active {
                format!("replaced by goal {}", goal.id)
            } else {
                "cancelled".to_owned()
            };
            tracing::info!(part = %goal.body_part, id = old.goal.id, "{detail}");
            let s = self.active_status(&old, ReachState::Cancelled, detail);
            self.publish(s).await;
            old_eyes = Some(old);
        }
        // A gaze that moved the eyes, replaced by a goal that does not: the eyes to the middle.
        match old_eyes {
            Some(old) if old.eyes && (!goal.active || goal.kind != ReachKind::Gaze) => {
                self.release_goal(&old).await;
            }
            _ if !goal.active => self.release(&goal.body_part).await,
            _ => {}
        }
        if !goal.active {
            return;
        }
        let part = match BodyPart::find(&goal.body_part) {
            Ok(p) => p,
            Err(_) => {
                let known: Vec<&str> = BODY_PARTS.iter().map(|p| p.name).collect();
                let detail = format!("unknown body part `{}` (known: {known:?})", goal.body_part);
                self.fail(&goal, detail).await;
                return;
            }
        };
        let chain = match self.body.as_ref().map(|b| b.model().body_part(part.name)) {
            Some(Ok(c)) => c,
            Some(Err(e)) => {
                self.fail(&goal, format!("body part `{}`: {e}", part.name))
                    .await;
                return;
            }
            None => return,
        };
        let tolerance_m = if goal.tolerance_m > 0.0 && goal.tolerance_m.is_finite() {
            goal.tolerance_m
        } else {
            self.config.tolerance_m
        };
        let vmax = chain.limits().iter().map(|l| l.velocity).collect();
        let eyes = goal.kind == ReachKind::Gaze
            && self
                .eyes
                .as_ref()
                .is_some_and(|e| part.root == e.root() && e.moves_head(&chain));
        let mut active = Active {
            goal,
            part,
            chain,
            vmax,
            tolerance_m,
            target_root: Isometry3::identity(),
            target_world: Isometry3::identity(),
            world_t_root: Isometry3::identity(),
            plan: None,
            last_follow: self.bus.clock().now(),
            waiting_since: None,
            located: false,
            peer_away_since: None,
            eyes,
        };
        tracing::info!(
            part = %active.goal.body_part,
            id = active.goal.id,
            client = %active.goal.client,
            kind = ?active.goal.kind,
            frame = %active.goal.frame,
            position = ?active.goal.position_m,
            follow = active.goal.follow,
            "new goal"
        );
        match self.locate(&mut active).await {
            Ok(()) => active.located = true,
            Err(f) if f.peer_away => {
                // Looked up by a tick once the DR is back (or failed after the grace).
                self.peer_away(&mut active, &f.detail);
                self.parts.insert(active.goal.body_part.clone(), active);
                return;
            }
            Err(f) => {
                self.fail(&active.goal, f.detail).await;
                return;
            }
        }
        if !self.fresh() {
            // Solved by a tick once joint states arrive (or failed after a while).
            active.waiting_since = Some(self.bus.clock().now());
            self.parts.insert(active.goal.body_part.clone(), active);
            return;
        }
        if self.solve(&mut active).await {
            self.parts.insert(active.goal.body_part.clone(), active);
        } else {
            // Over (unreachable or failed): nothing of this part stays owned.
            self.release_goal(&active).await;
        }
    }

    async fn fail(&self, goal: &ReachGoal, detail: String) {
        self.bus.counters().incr("goals_failed");
        tracing::warn!(part = %goal.body_part, id = goal.id, "failed: {detail}");
        self.publish(Self::status(goal, ReachState::Failed, detail))
            .await;
    }

    fn on_states(&mut self, states: &JointStates) {
        for j in &states.joints {
            if j.position.is_finite() {
                self.measured.insert(j.name.clone(), j.position);
            } else {
                self.bus.counters().incr("non_finite_joint_states");
                #[expect(
                    clippy::disallowed_methods,
                    reason = "the log limiter paces what a person reads, on the wall"
                )]
                let allowed = self.warn.allow(Instant::now());
                if let Some(suppressed) = allowed {
                    tracing::warn!(suppressed, "joint `{}` reported {}", j.name, j.position);
                }
            }
        }
        self.measured_at = Some(self.bus.clock().now());
    }
}

/// The component ready to run: its checked flags and the robot model, loaded.
#[derive(Debug)]
pub struct Prepared {
    config: Config,
    urdf: std::path::PathBuf,
    body: BodyIk,
    eyes: Option<crate::eyes::Eyes>,
}

/// Checks the flags and loads the robot model: what a restart could not fix fails here.
pub fn prepare(config: Config) -> anyhow::Result<Prepared> {
    config.check()?;
    let urdf = find_model(config.urdf.as_deref(), "loki.urdf");
    let mut model = robot_model::RobotModel::from_urdf_file(&urdf)
        .with_context(|| format!("loading the robot model {}", urdf.display()))?;
    for (joint, lo, hi) in &config.joint_ranges {
        model
            .narrow_limits(joint, *lo, *hi)
            .with_context(|| format!("--joint-range {joint}={lo}:{hi}"))?;
        tracing::info!("{joint} limited to [{lo}, {hi}] in every solve");
    }
    let body = BodyIk::new(model);
    let eyes = if config.eyes {
        match crate::eyes::Eyes::from_model(body.model()) {
            Ok(e) => Some(e),
            Err(why) => {
                tracing::info!("the eyes stay still: {why}");
                None
            }
        }
    } else {
        None
    };
    Ok(Prepared {
        config,
        urdf,
        body,
        eyes,
    })
}

/// Runs the component until shutdown.
pub async fn run(bus: Bus, prepared: Prepared, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let Prepared {
        config,
        urdf,
        body,
        eyes,
    } = prepared;
    let states = bus.subscriber(&topics::BODY_JOINT_STATES).await?;
    let goals = bus.subscriber(&topics::BODY_REACH).await?;
    let status = bus.publisher(&topics::BODY_REACH_STATUS).await?;
    // The stream and every time of a goal's lifecycle (trajectory time, hold, stale joint
    // states, follow, settle) run on the component's clock: a replay's with `--clock bus`.
    let mut tick = bus
        .clock()
        .interval(Duration::from_secs_f64(1.0 / config.stream_hz));
    tracing::info!(
        urdf = %urdf.display(),
        "body_inverse_kinematics ready: goals on {}, status on {}",
        topics::BODY_REACH.name(),
        topics::BODY_REACH_STATUS.name()
    );
    let mut ik = Ik {
        timeout: Duration::from_millis(config.call_timeout_ms),
        bus,
        config,
        body: Some(body),
        measured: HashMap::new(),
        measured_at: None,
        parts: HashMap::new(),
        status,
        warn: RateLimiter::new(Duration::from_secs(1)),
        eyes,
    };
    loop {
        tokio::select! {
            biased;
            _ = shutdown.wait() => break,
            g = goals.recv() => ik.on_goal(g?).await,
            s = states.recv() => {
                let mut s = s?;
                while let Some(newer) = states.try_recv() {
                    s = newer;
                }
                ik.on_states(&s);
            }
            _ = tick.tick() => ik.tick().await,
        }
    }
    // Give the joints back so that nothing stays owned by a component that is gone.
    let parts: Vec<Active> = ik.parts.drain().map(|(_, a)| a).collect();
    for a in &parts {
        ik.release_goal(a).await;
    }
    tracing::info!("stopped");
    Ok(())
}

/// The `body_inverse_kinematics` component.
#[derive(Debug)]
pub struct BodyInverseKinematics;

impl interfaces::node::Component for BodyInverseKinematics {
    const NAME: &'static str = "body_inverse_kinematics";
    const ABOUT: &'static str = "Reach and gaze for Loki's body parts: takes goals on body/reach (a DR frame and \
        a point in it, for a named chain such as left_arm_7 or neck), solves them with \
        Levenberg-Marquardt IK from the measured joints (body/joint_states), drives \
        joint_motor along a smooth trajectory (body/joint_goal) and reports Moving, \
        Reached, Unreachable, Cancelled or Failed on body/reach_status. `follow` goals \
        track a moving DR frame (the ball).";
    type Config = Config;
    type Prepared = Prepared;

    fn interface(_: &Config) -> Interface {
        interface()
    }

    fn prepare(config: Config) -> anyhow::Result<Prepared> {
        prepare(config)
    }

    async fn run(bus: Bus, prepared: Prepared, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}

#[cfg(test)]
mod tests;
