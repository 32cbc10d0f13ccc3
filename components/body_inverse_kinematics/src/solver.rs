//! The Levenberg-Marquardt solver for one open chain (seed 001 §V.C).
//!
//! # Algorithm
//! With `φ` the joint values of the chain, `J` the 6xN task Jacobian in the chain's root frame
//! (linear rows first) and `e` the weighted 6-vector error, one step is
//!
//! ```text
//! δφ = Jᵀ (J Jᵀ + λ I)⁻¹ e          (6x6 system, solved by Cholesky on the stack)
//! ```
//!
//! - **Damping** follows Sugihara (2011): `λ = μ (E + b)` with `E = |e|²` the weighted squared
//!   error and `b` a small bias ([`SolverOptions::damping_bias`]), so the step is Gauss-Newton close
//!   to the goal and gradient-descent-like far from it or near singularities. `μ` adapts: a step
//!   that lowers `E` is accepted and halves `μ` (down to [`SolverOptions::mu_min`]); a step that
//!   does not is rejected and multiplies `μ` by 4, then retried from the same point.
//! - **Joint limits**: every trial configuration is clamped into the limits before it is
//!   evaluated (projection), so every configuration the solver ever holds is within the limits.
//! - **Restarts**: the first attempt starts from the caller's configuration; when it stalls
//!   (no progress, or out of iterations: [`AttemptLimits`]) the solver restarts from a
//!   uniformly random configuration within the limits (seeded, deterministic) until the target is
//!   reached, the [`Deadline`] expires or [`SolverOptions::max_attempts`] is used up. Solutions
//!   that the caller's `accept` hook refuses (self-collision) also trigger a restart.
//! - **Gaze** (the paper's virtual stick): a segment from the tip origin `o` along the tip's +z axis
//!   `z`, as long as the current distance `d = |t - o|` to the target `t`; its end `s = o + d z`
//!   must reach `t`. Error rows `t - s`, Jacobian rows `J_v + d (J_ω × z)` (`d` held constant in
//!   a step). At convergence `z` points at `t` with `t` in front.
//!
//! # Cost
//! No allocation after [`IkSolver::new`]: the Jacobian and joint buffers are preallocated, the
//! 6x6 system lives on the stack.

use nalgebra::{Isometry3, Matrix6, Matrix6xX, Vector3, Vector6};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};
use robot_model::{Chain, JointKind};

/// What the solver minimises, in the chain's root frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Goal {
    /// Tip pose with per-axis weights `[x, y, z, rx, ry, rz]` (>= 0). Zero rotation weights make it
    /// a position target.
    Pose {
        /// Target `root_T_tip`.
        target: Isometry3<f64>,
        /// Per-axis weights.
        weights: Vector6<f64>,
    },
    /// The tip's +z axis through `point` (m), point in front.
    Gaze {
        /// The point to look at (m).
        point: Vector3<f64>,
    },
}

impl Goal {
    /// A position-only goal (rotation weights 0).
    pub fn position(p: Vector3<f64>) -> Self {
        Goal::Pose {
            target: Isometry3::translation(p.x, p.y, p.z),
            weights: Vector6::new(1.0, 1.0, 1.0, 0.0, 0.0, 0.0),
        }
    }
    /// A full-pose goal with unit weights.
    pub fn pose(target: Isometry3<f64>) -> Self {
        Goal::Pose {
            target,
            weights: Vector6::repeat(1.0),
        }
    }
}

/// Tolerances: position (m) and orientation (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tolerance {
    /// Position tolerance (m).
    pub m: f64,
    /// Orientation tolerance (rad).
    pub rad: f64,
}

impl Default for Tolerance {
    fn default() -> Self {
        Self {
            m: crate::types::DEFAULT_TOLERANCE_M,
            rad: crate::types::DEFAULT_TOLERANCE_RAD,
        }
    }
}

/// Unweighted residual of a configuration on the weighted axes: position (m), orientation (rad).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Residual {
    /// Position residual (m) (for a gaze: distance from the target to the optical-axis ray).
    pub m: f64,
    /// Orientation residual (rad) (for a gaze: angle between the axis and the target direction).
    pub rad: f64,
}

impl Residual {
    const WORST: Residual = Residual {
        m: f64::INFINITY,
        rad: f64::INFINITY,
    };
    /// Whether both parts are within tolerance.
    pub fn within(&self, tol: &Tolerance) -> bool {
        self.m <= tol.m && self.rad <= tol.rad
    }
    /// A scalar to rank residuals: the larger of the two parts in units of their tolerance.
    pub fn score(&self, tol: &Tolerance) -> f64 {
        (self.m / tol.m).max(self.rad / tol.rad)
    }
}

/// When to stop restarting: polled between attempts.
pub trait Deadline {
    /// True once the budget is spent.
    fn expired(&mut self) -> bool;
}

impl<F: FnMut() -> bool> Deadline for F {
    fn expired(&mut self) -> bool {
        self()
    }
}

/// A deadline on the monotonic clock (`std::time::Instant`): a compute-time budget, the only
/// clock read of this crate, kept out of the algorithm (which only polls [`Deadline`]).
#[derive(Debug, Clone, Copy)]
pub struct MonotonicDeadline {
    end: std::time::Instant,
}

impl MonotonicDeadline {
    /// Expires `budget_s` seconds from now (a non-finite or negative budget expires at once).
    #[expect(
        clippy::disallowed_methods,
        reason = "the solver's compute-time budget, on the wall as the CPU spends it"
    )]
    pub fn after_s(budget_s: f64) -> Self {
        let now = std::time::Instant::now();
        let d = if budget_s.is_finite() && budget_s > 0.0 {
            std::time::Duration::from_secs_f64(budget_s.min(3600.0))
        } else {
            std::time::Duration::ZERO
        };
        Self { end: now + d }
    }
}

impl Deadline for MonotonicDeadline {
    #[expect(
        clippy::disallowed_methods,
        reason = "the solver's compute-time budget, on the wall as the CPU spends it"
    )]
    fn expired(&mut self) -> bool {
        std::time::Instant::now() >= self.end
    }
}

/// When one descent (attempt) gives up: after `max_iterations` steps (accepted or rejected), or
/// when the weighted squared error `E` fell by less than `stall_fraction` over `stall_window`
/// accepted steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AttemptLimits {
    /// Steps per attempt.
    pub max_iterations: u32,
    /// Minimum relative decrease of `E` over [`AttemptLimits::stall_window`] accepted steps.
    pub stall_fraction: f64,
    /// Window of the stall test (accepted steps).
    pub stall_window: u32,
}

/// Tuning of the solver.
///
/// The first attempt (from the caller's configuration, usually the current one) is patient, so
/// that a solution close to the current posture is preferred (smooth tracking); most random
/// restarts give up early, since a fresh start is cheaper than a slow descent (on the 7-joint arm
/// this halves the 99th percentile of the solve time), but every 4th restart is patient again, for
/// solutions against a joint limit, where the clamped descent converges slowly.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolverOptions {
    /// Limits of the first attempt.
    pub first_attempt: AttemptLimits,
    /// Limits of each random restart.
    pub restart: AttemptLimits,
    /// Attempts in all (the first from the start configuration, the others random).
    pub max_attempts: u32,
    /// Bias `b` of the damping `λ = μ (E + b)` (m² scale).
    pub damping_bias: f64,
    /// Smallest `μ`.
    pub mu_min: f64,
}

impl Default for SolverOptions {
    fn default() -> Self {
        Self {
            first_attempt: AttemptLimits {
                max_iterations: 60,
                stall_fraction: 0.05,
                stall_window: 6,
            },
            restart: AttemptLimits {
                max_iterations: 25,
                stall_fraction: 0.2,
                stall_window: 2,
            },
            max_attempts: 100_000,
            damping_bias: 1e-6,
            mu_min: 1e-3,
        }
    }
}

/// Outcome of [`IkSolver::solve`]; the joint values are in [`IkSolver::solution`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SolveReport {
    /// Whether an accepted configuration within tolerance was found.
    pub reached: bool,
    /// Residual of [`IkSolver::solution`].
    pub residual: Residual,
    /// Iterations over all attempts.
    pub iterations: u32,
    /// Attempts made.
    pub attempts: u32,
    /// Configurations within tolerance refused by the `accept` hook.
    pub refused: u32,
    /// Whether [`IkSolver::solution`] was refused by the `accept` hook (only when no accepted
    /// configuration was ever seen).
    pub solution_refused: bool,
}

/// Levenberg-Marquardt IK for one chain, with preallocated buffers (see the module docs).
#[derive(Debug, Clone)]
pub struct IkSolver {
    chain: Chain,
    opts: SolverOptions,
    lower: Vec<f64>,
    upper: Vec<f64>,
    sample_lower: Vec<f64>,
    sample_upper: Vec<f64>,
    jac: Matrix6xX<f64>,
    q: Vec<f64>,
    q_try: Vec<f64>,
    best: Vec<f64>,
    best_refused: Vec<f64>,
}

/// Weighted error vector and unweighted residual of a tip pose against a goal.
#[inline]
fn evaluate(goal: &Goal, tip: &Isometry3<f64>) -> (Vector6<f64>, Residual) {
    match goal {
        Goal::Pose { target, weights } => {
            let dp = target.translation.vector - tip.translation.vector;
            let dr = (target.rotation * tip.rotation.inverse()).scaled_axis();
            let mut e = Vector6::zeros();
            let (mut m2, mut r2) = (0.0, 0.0);
            for k in 0..3 {
                e[k] = weights[k] * dp[k];
                e[k + 3] = weights[k + 3] * dr[k];
                if weights[k] > 0.0 {
                    m2 += dp[k] * dp[k];
                }
                if weights[k + 3] > 0.0 {
                    r2 += dr[k] * dr[k];
                }
            }
            (
                e,
                Residual {
                    m: m2.sqrt(),
                    rad: r2.sqrt(),
                },
            )
        }
        Goal::Gaze { point } => {
            let o = tip.translation.vector;
            let z = tip.rotation * Vector3::z();
            let p = point - o;
            let d = p.norm();
            let stick = p - z * d;
            let along = p.dot(&z);
            let perp = if along > 0.0 {
                (p - z * along).norm()
            } else {
                d
            };
            let angle = p.cross(&z).norm().atan2(along);
            (
                Vector6::new(stick.x, stick.y, stick.z, 0.0, 0.0, 0.0),
                Residual {
                    m: perp,
                    rad: angle,
                },
            )
        }
    }
}

impl IkSolver {
    /// A solver for `chain`. Continuous joints are sampled in `[-π, π]` on restarts; prismatic or
    /// revolute joints with infinite limits in `[-1, 1]`.
    pub fn new(chain: Chain, opts: SolverOptions) -> Self {
        let n = chain.dof();
        let lims = chain.limits();
        let lower: Vec<f64> = lims.iter().map(|l| l.lower).collect();
        let upper: Vec<f64> = lims.iter().map(|l| l.upper).collect();
        let fallback = |j: usize| match chain.joints[j].kind {
            JointKind::Continuous | JointKind::Revolute => std::f64::consts::PI,
            _ => 1.0,
        };
        let sample_lower = (0..n)
            .map(|j| {
                if lower[j].is_finite() {
                    lower[j]
                } else {
                    -fallback(j)
                }
            })
            .collect();
        let sample_upper = (0..n)
            .map(|j| {
                if upper[j].is_finite() {
                    upper[j]
                } else {
                    fallback(j)
                }
            })
            .collect();
        Self {
            jac: Matrix6xX::zeros(n),
            q: vec![0.0; n],
            q_try: vec![0.0; n],
            best: vec![0.0; n],
            best_refused: vec![0.0; n],
            chain,
            opts,
            lower,
            upper,
            sample_lower,
            sample_upper,
        }
    }

    /// The chain.
    pub fn chain(&self) -> &Chain {
        &self.chain
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.chain.dof()
    }

    /// The options.
    pub fn options(&self) -> &SolverOptions {
        &self.opts
    }

    /// The middle of each joint's sampling range (a neutral start).
    pub fn mid_range(&self) -> Vec<f64> {
        self.sample_lower
            .iter()
            .zip(&self.sample_upper)
            .map(|(l, u)| 0.5 * (l + u))
            .collect()
    }

    /// Writes a uniformly random configuration within the limits into `out` (chain order).
    pub fn random_configuration(&self, rng: &mut impl Rng, out: &mut [f64]) {
        for (j, v) in out.iter_mut().enumerate().take(self.dof()) {
            *v = rng.random_range(self.sample_lower[j]..=self.sample_upper[j]);
        }
    }

    /// The joint values of the last [`IkSolver::solve`]: the accepted solution if one was
    /// reached, otherwise the best configuration seen (preferring accepted ones). Always within
    /// the limits.
    pub fn solution(&self) -> &[f64] {
        &self.best
    }

    /// Residual of configuration `q` (chain order) against `goal`. `q` must have `dof` finite
    /// values (missing ones count as 0).
    pub fn residual(&self, goal: &Goal, q: &[f64]) -> Residual {
        evaluate(goal, &self.chain.fk_unchecked(q)).1
    }

    /// Solves `goal` from `q_start` (clamped into the limits; `dof` finite values, checked by the
    /// caller). `accept` may refuse a configuration within tolerance (self-collision); the
    /// search then goes on. Deterministic for a given `seed` and deadline outcome.
    pub fn solve(
        &mut self,
        goal: &Goal,
        tol: &Tolerance,
        q_start: &[f64],
        seed: u64,
        deadline: &mut dyn Deadline,
        accept: &mut dyn FnMut(&[f64]) -> bool,
    ) -> SolveReport {
        let n = self.dof();
        let mut rng = SmallRng::seed_from_u64(seed);
        for j in 0..n {
            let v = q_start.get(j).copied().unwrap_or(0.0);
            let v = if v.is_finite() { v } else { 0.0 };
            self.q[j] = v.clamp(self.lower[j], self.upper[j]);
        }
        let mut report = SolveReport {
            reached: false,
            residual: Residual::WORST,
            iterations: 0,
            attempts: 0,
            refused: 0,
            solution_refused: false,
        };
        let mut best_refused = Residual::WORST;
        loop {
            if report.attempts > 0 {
                if report.attempts >= self.opts.max_attempts || deadline.expired() {
                    break;
                }
                let (lo, hi) = (&self.sample_lower, &self.sample_upper);
                for j in 0..n {
                    self.q[j] = rng.random_range(lo[j]..=hi[j]);
                }
            }
            report.attempts += 1;
            // The first attempt and every 4th restart are patient (solutions at joint limits
            // converge slowly under clamping); the others give up early.
            let limits = if report.attempts % 4 == 1 {
                self.opts.first_attempt
            } else {
                self.opts.restart
            };
            let (res, iters) = self.attempt(goal, tol, &limits);
            report.iterations += iters;
            let ok = res.within(tol);
            if ok && accept(&self.q) {
                self.best.copy_from_slice(&self.q);
                report.residual = res;
                report.reached = true;
                report.solution_refused = false;
                return report;
            }
            if ok {
                report.refused += 1;
                if res.score(tol) < best_refused.score(tol) {
                    best_refused = res;
                    self.best_refused.copy_from_slice(&self.q);
                }
            } else if res.score(tol) < report.residual.score(tol) && accept(&self.q) {
                report.residual = res;
                self.best.copy_from_slice(&self.q);
            }
        }
        if !report.residual.m.is_finite() {
            // Nothing acceptable was seen: fall back on the best refused configuration, or the
            // clamped start.
            report.solution_refused = best_refused.m.is_finite();
            if report.solution_refused {
                self.best.copy_from_slice(&self.best_refused);
                report.residual = best_refused;
            } else {
                for j in 0..n {
                    let v = q_start.get(j).copied().unwrap_or(0.0);
                    let v = if v.is_finite() { v } else { 0.0 };
                    self.best[j] = v.clamp(self.lower[j], self.upper[j]);
                }
                report.residual = self.residual(goal, &self.best);
                report.solution_refused = !accept(&self.best);
            }
        }
        report
    }

    /// One damped least-squares descent from `self.q`; leaves the result in `self.q` and returns
    /// its residual and the number of iterations.
    fn attempt(&mut self, goal: &Goal, tol: &Tolerance, lim: &AttemptLimits) -> (Residual, u32) {
        let n = self.dof();
        let opts = self.opts;
        let mut tip = self.chain.fk_unchecked(&self.q);
        let (mut e, mut res) = evaluate(goal, &tip);
        let mut energy = e.norm_squared();
        let mut mu = 1.0;
        let mut iters = 0;
        let mut window_start = energy;
        let mut window_len = 0;
        let mut need_jacobian = true;
        let mut a = Matrix6::<f64>::zeros();
        while iters < lim.max_iterations {
            if res.within(tol) {
                break;
            }
            if need_jacobian {
                if self.chain.jacobian_into(&self.q, &mut self.jac).is_err() {
                    break;
                }
                self.task_jacobian(goal, &tip);
                a.fill(0.0);
                for i in 0..n {
                    let c = self.jac.fixed_view::<6, 1>(0, i);
                    a += c * c.transpose();
                }
                need_jacobian = false;
            }
            iters += 1;
            let lambda = mu * (energy + opts.damping_bias);
            let mut m = a;
            for k in 0..6 {
                m[(k, k)] += lambda;
            }
            let Some(chol) = m.cholesky() else {
                mu *= 4.0;
                continue;
            };
            let y = chol.solve(&e);
            for i in 0..n {
                let c = self.jac.fixed_view::<6, 1>(0, i);
                let v = self.q[i] + c.dot(&y);
                self.q_try[i] = v.clamp(self.lower[i], self.upper[i]);
            }
            let tip_try = self.chain.fk_unchecked(&self.q_try);
            let (e_try, res_try) = evaluate(goal, &tip_try);
            let energy_try = e_try.norm_squared();
            if energy_try < energy {
                std::mem::swap(&mut self.q, &mut self.q_try);
                tip = tip_try;
                e = e_try;
                res = res_try;
                energy = energy_try;
                mu = (mu * 0.5).max(opts.mu_min);
                need_jacobian = true;
                window_len += 1;
                if window_len >= lim.stall_window {
                    if energy > window_start * (1.0 - lim.stall_fraction) && !res.within(tol) {
                        break;
                    }
                    window_start = energy;
                    window_len = 0;
                }
            } else {
                mu *= 4.0;
                if mu > 1e6 {
                    break;
                }
            }
        }
        (res, iters)
    }

    /// Turns the geometric Jacobian in `self.jac` into the weighted task Jacobian of `goal` at
    /// `tip`.
    #[inline]
    fn task_jacobian(&mut self, goal: &Goal, tip: &Isometry3<f64>) {
        match goal {
            Goal::Pose { weights, .. } => {
                for i in 0..self.dof() {
                    let mut c = self.jac.column_mut(i);
                    c.component_mul_assign(weights);
                }
            }
            Goal::Gaze { point } => {
                let o = tip.translation.vector;
                let z = tip.rotation * Vector3::z();
                let d = (point - o).norm();
                for i in 0..self.dof() {
                    let v = self.jac.fixed_view::<3, 1>(0, i).into_owned();
                    let w = self.jac.fixed_view::<3, 1>(3, i).into_owned();
                    let s = v + w.cross(&z) * d;
                    self.jac.fixed_view_mut::<3, 1>(0, i).copy_from(&s);
                    self.jac.fixed_view_mut::<3, 1>(3, i).fill(0.0);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use robot_model::RobotModel;

    fn loki() -> RobotModel {
        RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap()
    }

    #[test]
    fn gaze_stick_jacobian_matches_finite_differences() {
        let chain = loki().body_part("neck").unwrap();
        let mut s = IkSolver::new(chain.clone(), SolverOptions::default());
        let q = [0.3, -0.2, 0.1, 0.4];
        let point = Vector3::new(1.2, 0.5, 0.3);
        let goal = Goal::Gaze { point };
        let tip = chain.jacobian_into(&q, &mut s.jac).unwrap();
        s.task_jacobian(&goal, &tip);
        let d = (point - tip.translation.vector).norm();
        let stick = |q: &[f64]| {
            let t = chain.fk(q).unwrap();
            t.translation.vector + (t.rotation * Vector3::z()) * d
        };
        let h = 1e-7;
        for i in 0..4 {
            let mut qp = q;
            qp[i] += h;
            let fd = (stick(&qp) - stick(&q)) / h;
            for k in 0..3 {
                assert!((s.jac[(k, i)] - fd[k]).abs() < 1e-5, "col {i} row {k}");
                assert_eq!(s.jac[(k + 3, i)], 0.0);
            }
        }
    }

    #[test]
    fn weighted_pose_error_and_residual() {
        let target = Isometry3::translation(1.0, 2.0, 3.0);
        let tip = Isometry3::identity();
        let w = Vector6::new(2.0, 0.0, 1.0, 0.0, 0.0, 0.0);
        let (e, r) = evaluate(&Goal::Pose { target, weights: w }, &tip);
        assert_eq!(e, Vector6::new(2.0, 0.0, 3.0, 0.0, 0.0, 0.0));
        // The residual is unweighted, over the weighted axes only (x and z).
        assert!((r.m - 10f64.sqrt()).abs() < 1e-12);
        assert_eq!(r.rad, 0.0);
    }

    #[test]
    fn damping_handles_a_nearly_singular_arm_and_restarts_escape_a_singular_one() {
        // Arm hanging nearly straight (elbow at -0.05 rad, close to the singularity for vertical
        // motion) and a target 5 cm above the hand: the damped steps converge in one attempt.
        let chain = loki().body_part("left_arm_4").unwrap();
        let mut s = IkSolver::new(chain.clone(), SolverOptions::default());
        let straight = [0.0, 0.0, 0.0, 0.0];
        let p = chain.fk(&straight).unwrap().translation.vector + Vector3::new(0.0, 0.0, 0.05);
        let goal = Goal::position(p);
        let tol = Tolerance::default();
        let no_restart = &mut || true;
        let r = s.solve(
            &goal,
            &tol,
            &[0.0, 0.0, 0.0, -0.05],
            0,
            no_restart,
            &mut |_: &[f64]| true,
        );
        assert!(r.reached, "{r:?}");
        assert_eq!(r.attempts, 1);
        assert!(chain.within_limits(s.solution()));
        // Exactly straight, the gradient towards the target is zero (a stationary point): the
        // first attempt cannot leave it, a random restart does.
        let r = s.solve(
            &goal,
            &tol,
            &straight,
            0,
            &mut || true,
            &mut |_: &[f64]| true,
        );
        assert!(!r.reached);
        let mut budget = 0;
        let r = s.solve(
            &goal,
            &tol,
            &straight,
            0,
            &mut || {
                budget += 1;
                budget > 20
            },
            &mut |_: &[f64]| true,
        );
        assert!(r.reached && r.attempts > 1, "{r:?}");
    }
}
