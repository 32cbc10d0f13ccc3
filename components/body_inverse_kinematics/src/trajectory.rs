//! Smooth, time-synchronised joint trajectories from a start to a goal configuration.
//!
//! Every joint follows the same quintic time law `s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`, `τ = t / T`, so all
//! joints start and stop together, with zero velocity and acceleration at both ends:
//! `q_i(t) = q0_i + (q1_i − q0_i) s(t / T)`. The peak speed of joint `i` is
//! `15/8 |Δ_i| / T` (at `τ = ½`) and its peak acceleration `10/√3 |Δ_i| / T²`, so the duration is the
//! smallest `T` that keeps every joint within its velocity limit (and acceleration limit, if
//! given), and at least `min_duration_s`. Units: rad or m, rad/s or m/s, s. Sampling is a pure
//! function of `t`; before 0 it holds the start, after `T` the goal.
//!
//! The jerk of joint `i` peaks at the ends, `60 |Δ_i| / T³`: [`Trajectory::jerk_limited`] makes
//! `T` long enough for a jerk limit. Stretching `T` keeps the path and scales every speed by
//! `1/T` and every jerk by `1/T³`, joints and any point they carry alike (the hand):
//! [`Trajectory::point_peaks`] measures a carried point's peak speed and jerk, and
//! [`Trajectory::stretched`] lengthens the trajectory to bring them within limits.

use thiserror::Error;

/// Peak of `ds/dτ`.
const PEAK_VEL: f64 = 15.0 / 8.0;
/// Peak of `|d²s/dτ²|` (at `τ = ½ ± √3/6`).
const PEAK_ACC: f64 = 5.773_502_691_896_258;

/// Peak of `|d³s/dτ³|` (at `τ = 0` and `τ = 1`).
const PEAK_JERK: f64 = 60.0;

/// Bad trajectory inputs.
#[derive(Debug, Error, PartialEq)]
pub enum TrajectoryError {
    /// Slices of different lengths.
    #[error("length mismatch: start has {start}, goal {goal}, velocity limits {limits}")]
    Length {
        /// Start length.
        start: usize,
        /// Goal length.
        goal: usize,
        /// Limits length.
        limits: usize,
    },
    /// A non-finite joint value, or a limit that is not > 0.
    #[error("joint {0}: non-finite value or non-positive limit")]
    Invalid(usize),
}

/// A quintic, time-synchronised point-to-point trajectory (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct Trajectory {
    start: Vec<f64>,
    goal: Vec<f64>,
    duration_s: f64,
}

impl Trajectory {
    /// The fastest trajectory from `start` to `goal` within `max_velocity` (per joint, > 0,
    /// may be infinite) and, if given, `max_acceleration` (per joint, > 0), lasting at least
    /// `min_duration_s`.
    pub fn quintic(
        start: &[f64],
        goal: &[f64],
        max_velocity: &[f64],
        max_acceleration: Option<&[f64]>,
        min_duration_s: f64,
    ) -> Result<Self, TrajectoryError> {
        let n = start.len();
        let acc_len = max_acceleration.map_or(n, <[f64]>::len);
        if goal.len() != n || max_velocity.len() != n || acc_len != n {
            return Err(TrajectoryError::Length {
                start: n,
                goal: goal.len(),
                limits: max_velocity.len(),
            });
        }
        let mut duration_s = if min_duration_s.is_finite() {
            min_duration_s.max(0.0)
        } else {
            0.0
        };
        for i in 0..n {
            let v = max_velocity[i];
            let a = max_acceleration.map_or(f64::INFINITY, |a| a[i]);
            if !start[i].is_finite()
                || !goal[i].is_finite()
                || v.is_nan()
                || v <= 0.0
                || a.is_nan()
                || a <= 0.0
            {
                return Err(TrajectoryError::Invalid(i));
            }
            let d = (goal[i] - start[i]).abs();
            duration_s = duration_s.max(PEAK_VEL * d / v);
            if a.is_finite() {
                duration_s = duration_s.max((PEAK_ACC * d / a).sqrt());
            }
        }
        Ok(Self {
            start: start.to_vec(),
            goal: goal.to_vec(),
            duration_s,
        })
    }

    /// Duration `T` (s).
    pub fn duration_s(&self) -> f64 {
        self.duration_s
    }

    /// Number of joints.
    pub fn dof(&self) -> usize {
        self.start.len()
    }

    /// The goal configuration.
    pub fn goal(&self) -> &[f64] {
        &self.goal
    }

    /// Writes `q(t)` into `q` and, if given, `q̇(t)` into `qd` (`t` in s from the start; slices of
    /// at least `dof` values). Allocation-free.
    pub fn sample_into(&self, t_s: f64, q: &mut [f64], mut qd: Option<&mut [f64]>) {
        let (s, ds) = if self.duration_s <= 0.0 || t_s >= self.duration_s {
            (1.0, 0.0)
        } else if t_s <= 0.0 || t_s.is_nan() {
            (0.0, 0.0)
        } else {
            let tau = t_s / self.duration_s;
            let t2 = tau * tau;
            let s = t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
            let ds = 30.0 * t2 * (1.0 - tau) * (1.0 - tau) / self.duration_s;
            (s, ds)
        };
        for i in 0..self.start.len().min(q.len()) {
            let d = self.goal[i] - self.start[i];
            q[i] = if s >= 1.0 {
                self.goal[i]
            } else {
                self.start[i] + d * s
            };
            if let Some(v) = qd.as_deref_mut()
                && let Some(slot) = v.get_mut(i)
            {
                *slot = d * ds;
            }
        }
    }

    /// The same path over at least `duration_s` (s): every speed scaled by `T / duration_s`,
    /// every jerk by its cube. A shorter or non-finite `duration_s` changes nothing.
    pub fn stretched(mut self, duration_s: f64) -> Self {
        if duration_s.is_finite() && duration_s > self.duration_s {
            self.duration_s = duration_s;
        }
        self
    }

    /// Lengthened so that no joint's jerk exceeds `max_jerk` (per joint, rad/s³ or m/s³; a
    /// limit that is not > 0 or is infinite is no limit).
    pub fn jerk_limited(self, max_jerk: &[f64]) -> Self {
        let mut t = self.duration_s;
        for ((a, b), &j) in self.start.iter().zip(&self.goal).zip(max_jerk) {
            if j.is_finite() && j > 0.0 {
                t = t.max((PEAK_JERK * (b - a).abs() / j).cbrt());
            }
        }
        self.stretched(t)
    }

    /// Each joint's peak jerk (rad/s³ or m/s³).
    pub fn peak_jerk(&self) -> Vec<f64> {
        self.start
            .iter()
            .zip(&self.goal)
            .map(|(a, b)| {
                if self.duration_s > 0.0 {
                    PEAK_JERK * (b - a).abs() / self.duration_s.powi(3)
                } else {
                    0.0
                }
            })
            .collect()
    }

    /// The peak speed (m/s) and jerk (m/s³) of a point the joints carry, `point(q)` (e.g. the
    /// hand's position by forward kinematics), by finite differences over `steps` samples.
    pub fn point_peaks(&self, point: impl Fn(&[f64]) -> [f64; 3], steps: usize) -> (f64, f64) {
        if self.duration_s <= 0.0 || steps < 4 {
            return (0.0, 0.0);
        }
        let h = self.duration_s / steps as f64;
        let mut q = vec![0.0; self.dof()];
        let mut at = |t: f64| {
            self.sample_into(t, &mut q, None);
            point(&q)
        };
        // Samples from -2h to T + 2h: the ends are at rest.
        let p: Vec<[f64; 3]> = (-2..=steps as i64 + 2).map(|k| at(k as f64 * h)).collect();
        let norm = |v: [f64; 3]| (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        let (mut speed, mut jerk) = (0.0_f64, 0.0_f64);
        for k in 1..p.len() - 2 {
            let d1: [f64; 3] = std::array::from_fn(|i| (p[k + 1][i] - p[k - 1][i]) / (2.0 * h));
            let d3: [f64; 3] = std::array::from_fn(|i| {
                (p[k + 2][i] - 3.0 * p[k + 1][i] + 3.0 * p[k][i] - p[k - 1][i]) / h.powi(3)
            });
            speed = speed.max(norm(d1));
            jerk = jerk.max(norm(d3));
        }
        (speed, jerk)
    }

    /// `q(t)` as a new vector.
    pub fn sample(&self, t_s: f64) -> Vec<f64> {
        let mut q = vec![0.0; self.dof()];
        self.sample_into(t_s, &mut q, None);
        q
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn respects_velocity_limits_is_synchronised_and_ends_at_goal() {
        let start = [0.0, 1.0, -0.5, 0.2];
        let goal = [1.5, -1.0, -0.5, 0.25];
        let vmax = [1.0, 3.0, 1.0, 0.01];
        let tr = Trajectory::quintic(&start, &goal, &vmax, None, 0.0).unwrap();
        // The slowest joint: the 4th (0.05 / 0.01 * 15/8 = 9.375 s).
        assert!((tr.duration_s() - 9.375).abs() < 1e-12);
        let (mut q, mut qd) = ([0.0; 4], [0.0; 4]);
        let steps = 2000;
        let mut peak = [0.0_f64; 4];
        let mut prev = start;
        let dt = tr.duration_s() / steps as f64;
        for k in 0..=steps {
            let t = k as f64 * dt;
            tr.sample_into(t, &mut q, Some(&mut qd));
            for i in 0..4 {
                assert!(qd[i].abs() <= vmax[i] * (1.0 + 1e-9), "joint {i} at {t}");
                peak[i] = peak[i].max(qd[i].abs());
                if k > 0 {
                    // Finite differences agree with the analytic velocity (within one step).
                    let fd = (q[i] - prev[i]) / dt;
                    assert!((fd - qd[i]).abs() < 1e-2 * vmax[i].max(1.0), "joint {i}");
                }
            }
            prev = q;
        }
        // The limiting joint reaches its limit; joints start and end together.
        assert!((peak[3] - 0.01).abs() < 1e-6);
        assert_eq!(tr.sample(tr.duration_s()), goal.to_vec());
        assert_eq!(tr.sample(1e9), goal.to_vec());
        assert_eq!(tr.sample(-1.0), start.to_vec());
        assert!(
            tr.sample(0.5 * tr.duration_s())[0] > 0.7 && tr.sample(0.5 * tr.duration_s())[0] < 0.8
        );
    }

    #[test]
    fn acceleration_limit_and_min_duration_lengthen_it() {
        let tr = Trajectory::quintic(&[0.0], &[1.0], &[10.0], Some(&[1.0]), 0.0).unwrap();
        assert!((tr.duration_s() - PEAK_ACC.sqrt()).abs() < 1e-12);
        let tr = Trajectory::quintic(&[0.0], &[1.0], &[10.0], None, 5.0).unwrap();
        assert_eq!(tr.duration_s(), 5.0);
        let still = Trajectory::quintic(&[0.3], &[0.3], &[1.0], None, 0.0).unwrap();
        assert_eq!(still.duration_s(), 0.0);
        assert_eq!(still.sample(0.0), vec![0.3]);
    }

    #[test]
    fn a_jerk_limit_or_a_point_speed_limit_lengthens_it_along_the_same_path() {
        let tr = Trajectory::quintic(&[0.0, 0.0], &[0.2, -0.1], &[1.0, 1.0], None, 0.0).unwrap();
        assert!((tr.duration_s() - 0.375).abs() < 1e-12);
        // 60 · 0.2 / 0.375³ = 227.6 rad/s³: over a limit of 30 the duration grows to ∛(12/30).
        assert!((tr.peak_jerk()[0] - 60.0 * 0.2 / 0.375f64.powi(3)).abs() < 1e-9);
        let limited = tr.clone().jerk_limited(&[30.0, f64::INFINITY]);
        assert!((limited.duration_s() - 0.4f64.cbrt()).abs() < 1e-12);
        assert!(limited.peak_jerk()[0] <= 30.0 * (1.0 + 1e-12));
        assert_eq!(limited.goal(), tr.goal());
        // A carried point: (q0, q1, 0) m. Its jerk peaks at the ends, as the joints' do.
        let point = |q: &[f64]| [q[0], q[1], 0.0];
        let (speed, jerk) = tr.point_peaks(point, 400);
        let d = 0.2f64.hypot(0.1);
        assert!(
            (speed - PEAK_VEL * d / 0.375).abs() < 1e-3 * speed,
            "{speed}"
        );
        assert!(
            (jerk - PEAK_JERK * d / 0.375f64.powi(3)).abs() < 0.05 * jerk,
            "{jerk}"
        );
        // Twice as long: half the speed, an eighth of the jerk.
        let slow = tr.clone().stretched(0.75);
        let (s2, j2) = slow.point_peaks(point, 400);
        assert!((s2 - speed / 2.0).abs() < 1e-3 * speed && (j2 - jerk / 8.0).abs() < 0.05 * j2);
        assert_eq!(
            tr.clone().stretched(0.1).duration_s(),
            0.375,
            "never shortened"
        );
    }

    #[test]
    fn bad_inputs_are_typed_errors() {
        assert!(matches!(
            Trajectory::quintic(&[0.0], &[1.0, 2.0], &[1.0], None, 0.0),
            Err(TrajectoryError::Length { .. })
        ));
        assert_eq!(
            Trajectory::quintic(&[0.0], &[1.0], &[0.0], None, 0.0),
            Err(TrajectoryError::Invalid(0))
        );
        assert_eq!(
            Trajectory::quintic(&[f64::NAN], &[1.0], &[1.0], None, 0.0),
            Err(TrajectoryError::Invalid(0))
        );
    }
}
