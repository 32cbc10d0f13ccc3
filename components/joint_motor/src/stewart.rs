//! The neck of the *Muecas* head: a 3-leg Stewart platform turned into pitch, roll and yaw.
//!
//! # Geometry (all lengths in m, angles in rad)
//! Neck frame: origin at the centre of the base plate, x forward, y left, z up. The head
//! platform turns about a central spherical joint (a passive ball-and-socket on a rigid post) at
//! `c = (0, 0, h)`, `h` = [`NeckGeometry::pivot_height_m`]; it cannot translate. Three prismatic
//! legs join base anchors `b_i` to platform anchors `p_i` through spherical joints:
//! - `b_i = r_b (cos θ_i, sin θ_i, 0)`, θ_i = 90°, 210°, 330°, r_b = [`NeckGeometry::base_radius_m`];
//! - `p_i = r_p (cos(θ_i + φ), sin(θ_i + φ), 0)` in the platform frame (origin at the pivot),
//!   r_p = [`NeckGeometry::platform_radius_m`], φ = [`NeckGeometry::twist_rad`]. The twist makes the
//!   legs skew, so that yaw changes their lengths; with φ = 0 yaw would be unobservable.
//!
//! The head orientation is `R = Rz(yaw) · Ry(pitch) · Rx(roll)` (intrinsic z-y'-x''): pitch about
//! y (positive = nose down), roll about x (positive = left side up), yaw about z (positive = look
//! left). The legs' lengths are `l_i = ‖c + R p_i − b_i‖` (the closed-form inverse kinematics, as
//! in the paper); the forward direction (lengths to angles) solves those three equations by Newton
//! iteration with the analytic Jacobian `∂l_i/∂α = (d_i / l_i) · (∂R/∂α p_i)`.
//!
//! Requests outside the angle limits or the legs' stroke are refused with a typed error.

use nalgebra::{Matrix3, Rotation3, Vector3};
use thiserror::Error;

/// Pitch, roll and yaw of the head platform (rad), see the module docs for conventions.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct NeckAngles {
    pub pitch: f64,
    pub roll: f64,
    pub yaw: f64,
}

impl NeckAngles {
    /// Head straight ahead: all angles 0.
    pub const HOME: Self = Self {
        pitch: 0.0,
        roll: 0.0,
        yaw: 0.0,
    };

    fn to_vector(self) -> Vector3<f64> {
        Vector3::new(self.pitch, self.roll, self.yaw)
    }
    fn from_vector(v: Vector3<f64>) -> Self {
        Self {
            pitch: v[0],
            roll: v[1],
            yaw: v[2],
        }
    }
}

/// Why a neck conversion failed.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum NeckError {
    #[error("neck {axis} {value} rad is outside [{lower}, {upper}] rad")]
    AngleOutOfRange {
        axis: &'static str,
        value: f64,
        lower: f64,
        upper: f64,
    },
    #[error("neck leg {leg} length {value} m is outside its stroke [{lower}, {upper}] m")]
    LengthOutOfRange {
        leg: usize,
        value: f64,
        lower: f64,
        upper: f64,
    },
    #[error("neck forward kinematics did not converge (residual {residual_m} m)")]
    NoConvergence { residual_m: f64 },
    #[error("the neck platform's geometry is inconsistent: {0}")]
    Inconsistent(String),
}

/// Dimensions and limits of the neck (see the module docs for the geometry).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NeckGeometry {
    /// r_b: radius of the base anchors' circle (m).
    pub base_radius_m: f64,
    /// r_p: radius of the platform anchors' circle (m).
    pub platform_radius_m: f64,
    /// h: height of the central pivot above the base plate (m).
    pub pivot_height_m: f64,
    /// φ: angular offset of the platform anchors from the base anchors (rad).
    pub twist_rad: f64,
    /// Largest |pitch| (rad).
    pub max_pitch_rad: f64,
    /// Largest |roll| (rad).
    pub max_roll_rad: f64,
    /// Largest |yaw| (rad).
    pub max_yaw_rad: f64,
    /// Shortest leg (m).
    pub min_length_m: f64,
    /// Longest leg (m).
    pub max_length_m: f64,
}

impl Default for NeckGeometry {
    /// A plausible head-sized neck: 60 mm base circle, 40 mm platform circle, pivot 100 mm up,
    /// 40° twist; ±25° pitch, ±20° roll, ±30° yaw; legs 70–145 mm (covers that whole range).
    fn default() -> Self {
        Self {
            base_radius_m: 0.060,
            platform_radius_m: 0.040,
            pivot_height_m: 0.100,
            twist_rad: 40f64.to_radians(),
            max_pitch_rad: 25f64.to_radians(),
            max_roll_rad: 20f64.to_radians(),
            max_yaw_rad: 30f64.to_radians(),
            min_length_m: 0.070,
            max_length_m: 0.145,
        }
    }
}

const ANCHOR_ANGLES_DEG: [f64; 3] = [90.0, 210.0, 330.0];

impl NeckGeometry {
    fn base_anchor(&self, i: usize) -> Vector3<f64> {
        let t = ANCHOR_ANGLES_DEG[i].to_radians();
        Vector3::new(t.cos(), t.sin(), 0.0) * self.base_radius_m
    }

    fn platform_anchor(&self, i: usize) -> Vector3<f64> {
        let t = ANCHOR_ANGLES_DEG[i].to_radians() + self.twist_rad;
        Vector3::new(t.cos(), t.sin(), 0.0) * self.platform_radius_m
    }

    fn pivot(&self) -> Vector3<f64> {
        Vector3::new(0.0, 0.0, self.pivot_height_m)
    }

    /// The geometry of a URDF's `<robocog_stewart_neck>`, with the angle limits of its pitch, roll
    /// and yaw joints (`[lower, upper]` each; the platform's limits are the largest of the two
    /// magnitudes, the joints keep their own). Checked with [`NeckGeometry::check_consistent`].
    pub fn from_spec(
        spec: &robot_model::StewartNeckSpec,
        limits: [(f64, f64); 3],
    ) -> Result<Self, NeckError> {
        let max = |(lo, hi): (f64, f64)| lo.abs().max(hi.abs());
        let g = Self {
            base_radius_m: spec.base_radius_m,
            platform_radius_m: spec.platform_radius_m,
            pivot_height_m: spec.pivot_height_m,
            twist_rad: spec.twist_rad,
            max_pitch_rad: max(limits[0]),
            max_roll_rad: max(limits[1]),
            max_yaw_rad: max(limits[2]),
            min_length_m: spec.min_length_m,
            max_length_m: spec.max_length_m,
        };
        g.check_consistent()?;
        Ok(g)
    }

    /// Checks that the platform can be driven: positive finite dimensions, the home pose (all
    /// angles 0) within the legs' stroke, and the three axes observable there (the legs'
    /// Jacobian well conditioned; a twist of 0 makes yaw unobservable).
    pub fn check_consistent(&self) -> Result<(), NeckError> {
        let bad = |what: String| Err(NeckError::Inconsistent(what));
        for (name, v) in [
            ("base_radius_m", self.base_radius_m),
            ("platform_radius_m", self.platform_radius_m),
            ("pivot_height_m", self.pivot_height_m),
            ("min_length_m", self.min_length_m),
            ("max_length_m", self.max_length_m),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{name} must be finite and > 0, got {v}"));
            }
        }
        if self.min_length_m >= self.max_length_m {
            return bad(format!(
                "the stroke {}..{} m is empty",
                self.min_length_m, self.max_length_m
            ));
        }
        let (l, units) = self.legs(NeckAngles::HOME);
        if self.check_lengths(&l).is_err() {
            return bad(format!(
                "at the home pose the legs are {:.4} m, outside the stroke {}..{} m",
                l[0], self.min_length_m, self.max_length_m
            ));
        }
        let sv = self.jacobian(NeckAngles::HOME, &units).singular_values();
        let (lo, hi) = (sv.min(), sv.max());
        if lo.is_nan() || lo <= 1e-3 * hi {
            return bad(format!(
                "pitch, roll and yaw cannot all be told apart from the legs at the home pose (twist {:.1}°; singular values {lo:.2e}..{hi:.2e})",
                self.twist_rad.to_degrees()
            ));
        }
        Ok(())
    }

    /// Whether `a` is within the angle limits and its legs within their stroke.
    pub fn reachable(&self, a: NeckAngles) -> bool {
        self.check_angles(a).is_ok() && self.check_lengths(&self.legs(a).0).is_ok()
    }

    /// The reachable pose nearest `goal` (which must be within the angle limits), in angle
    /// space: `goal` itself if its legs are within their stroke; else the last reachable pose on
    /// the segment from home to `goal` (bisection), slid along the stroke's boundary towards
    /// `goal` (gradient projection: the step towards `goal` less its part across the legs at
    /// their limits, then Newton back onto those limits) while that brings it nearer. `None` if
    /// the home pose itself is out of reach (an inconsistent geometry).
    pub fn nearest_reachable(&self, goal: NeckAngles) -> Option<NeckAngles> {
        if self.reachable(goal) {
            return Some(goal);
        }
        if !self.reachable(NeckAngles::HOME) {
            return None;
        }
        let g = goal.to_vector();
        // The last reachable point from `from` (reachable) towards `to`.
        let along = |from: Vector3<f64>, to: Vector3<f64>| {
            let (mut lo, mut hi) = (0.0_f64, 1.0_f64);
            for _ in 0..50 {
                let mid = 0.5 * (lo + hi);
                if self.reachable(NeckAngles::from_vector(from + (to - from) * mid)) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            from + (to - from) * lo
        };
        let radial = along(Vector3::zeros(), g);
        let slid = self.slide_towards(radial, g);
        let best = if self.reachable(NeckAngles::from_vector(slid))
            && (slid - g).norm() < (radial - g).norm()
        {
            slid
        } else {
            radial
        };
        Some(NeckAngles::from_vector(best))
    }

    /// From `x` (reachable, on the stroke's boundary), slides along the boundary towards `g`
    /// while the distance to `g` shrinks (see [`NeckGeometry::nearest_reachable`]).
    fn slide_towards(&self, mut x: Vector3<f64>, g: Vector3<f64>) -> Vector3<f64> {
        // Legs at a limit, and the length each is held at (a hair inside the stroke).
        let active = |x: Vector3<f64>, d: Vector3<f64>| {
            let a = NeckAngles::from_vector(x);
            let (l, units) = self.legs(a);
            let j = self.jacobian(a, &units);
            let mut rows: Vec<(usize, f64)> = Vec::with_capacity(3);
            for (i, &li) in l.iter().enumerate() {
                let rate = j.row(i).transpose().dot(&d);
                if li >= self.max_length_m - 1e-8 && rate > 0.0 {
                    rows.push((i, self.max_length_m - 1e-10));
                } else if li <= self.min_length_m + 1e-8 && rate < 0.0 {
                    rows.push((i, self.min_length_m + 1e-10));
                }
            }
            (rows, j)
        };
        let mut step = 1.0_f64;
        for _ in 0..200 {
            let d = g - x;
            let (rows, j) = active(x, d);
            if rows.is_empty() || rows.len() >= 3 {
                break;
            }
            let n = nalgebra::DMatrix::from_fn(rows.len(), 3, |r, c| j[(rows[r].0, c)]);
            let Some(inv) = (&n * n.transpose()).try_inverse() else {
                break;
            };
            let dv = nalgebra::DVector::from_column_slice(d.as_slice());
            let across = n.transpose() * (inv * (&n * &dv));
            let tangent = Vector3::new(d[0] - across[0], d[1] - across[1], d[2] - across[2]);
            if tangent.norm() < 1e-9 {
                break; // the step towards the goal is all across the limits: nearest
            }
            // A step along the boundary, then Newton back onto the active legs' limits.
            let mut y = x + tangent * step;
            for _ in 0..4 {
                let a = NeckAngles::from_vector(y);
                let (l, units) = self.legs(a);
                let jy = self.jacobian(a, &units);
                let ny = nalgebra::DMatrix::from_fn(rows.len(), 3, |r, c| jy[(rows[r].0, c)]);
                let Some(inv) = (&ny * ny.transpose()).try_inverse() else {
                    break;
                };
                let resid = nalgebra::DVector::from_iterator(
                    rows.len(),
                    rows.iter().map(|&(i, b)| b - l[i]),
                );
                let fix = ny.transpose() * (inv * resid);
                y += Vector3::new(fix[0], fix[1], fix[2]);
            }
            if self.reachable(NeckAngles::from_vector(y)) && (y - g).norm() < (x - g).norm() - 1e-12
            {
                x = y;
                step = (step * 2.0).min(1.0);
            } else {
                step *= 0.5;
                if step < 1e-6 {
                    break;
                }
            }
        }
        x
    }

    /// Checks the angles against the limits.
    pub fn check_angles(&self, a: NeckAngles) -> Result<(), NeckError> {
        self.check_angles_within(a, 0.0)
    }

    /// Checks the angles against the limits widened by `tolerance_rad`.
    fn check_angles_within(&self, a: NeckAngles, tolerance_rad: f64) -> Result<(), NeckError> {
        for (axis, value, max) in [
            ("pitch", a.pitch, self.max_pitch_rad),
            ("roll", a.roll, self.max_roll_rad),
            ("yaw", a.yaw, self.max_yaw_rad),
        ] {
            if !(value.is_finite() && value.abs() <= max + tolerance_rad) {
                return Err(NeckError::AngleOutOfRange {
                    axis,
                    value,
                    lower: -max,
                    upper: max,
                });
            }
        }
        Ok(())
    }

    /// Leg lengths and their unit vectors for any angles (no limit checks).
    fn legs(&self, a: NeckAngles) -> ([f64; 3], [Vector3<f64>; 3]) {
        let r = rotation(a);
        let mut l = [0.0; 3];
        let mut d = [Vector3::zeros(); 3];
        for i in 0..3 {
            let v = self.pivot() + r * self.platform_anchor(i) - self.base_anchor(i);
            l[i] = v.norm();
            d[i] = v / l[i];
        }
        (l, d)
    }

    /// ∂l_i/∂(pitch, roll, yaw), row i.
    fn jacobian(&self, a: NeckAngles, units: &[Vector3<f64>; 3]) -> Matrix3<f64> {
        let (rz, ry, rx) = factors(a);
        let (dz, dy, dx) = (d_rot_z(a.yaw), d_rot_y(a.pitch), d_rot_x(a.roll));
        let d_pitch = rz * dy * rx;
        let d_roll = rz * ry * dx;
        let d_yaw = dz * ry * rx;
        let mut j = Matrix3::zeros();
        for i in 0..3 {
            let p = self.platform_anchor(i);
            j[(i, 0)] = units[i].dot(&(d_pitch * p));
            j[(i, 1)] = units[i].dot(&(d_roll * p));
            j[(i, 2)] = units[i].dot(&(d_yaw * p));
        }
        j
    }

    fn check_lengths(&self, l: &[f64; 3]) -> Result<(), NeckError> {
        for (leg, &value) in l.iter().enumerate() {
            if !(value.is_finite() && value >= self.min_length_m && value <= self.max_length_m) {
                return Err(NeckError::LengthOutOfRange {
                    leg,
                    value,
                    lower: self.min_length_m,
                    upper: self.max_length_m,
                });
            }
        }
        Ok(())
    }

    /// Inverse kinematics: the three leg lengths (m) that put the head at `angles`.
    pub fn inverse(&self, angles: NeckAngles) -> Result<[f64; 3], NeckError> {
        self.check_angles(angles)?;
        let (l, _) = self.legs(angles);
        self.check_lengths(&l)?;
        Ok(l)
    }

    /// Forward kinematics: the angles that give leg `lengths` (m), by Newton iteration from the
    /// home pose. Refused if the lengths are outside the stroke, or the solution outside the
    /// angle limits.
    pub fn forward(&self, lengths: [f64; 3]) -> Result<NeckAngles, NeckError> {
        let a = self.solve_angles(lengths)?;
        // Rounding may put a pose exactly on a limit a hair beyond it.
        self.check_angles_within(a, 1e-9)?;
        Ok(a)
    }

    /// Angle rates (rad/s) for leg rates (m/s) at `angles`: `J⁻¹ · l̇`; `None` at a singularity.
    pub fn angle_rates(&self, angles: NeckAngles, leg_rates: [f64; 3]) -> Option<NeckAngles> {
        let (_, units) = self.legs(angles);
        let j = self.jacobian(angles, &units);
        j.lu()
            .solve(&Vector3::from(leg_rates))
            .map(NeckAngles::from_vector)
    }

    /// Like [`NeckGeometry::forward`] but without the angle-limit check (for measured legs,
    /// whose transient poses may graze the limits).
    pub fn solve_angles(&self, lengths: [f64; 3]) -> Result<NeckAngles, NeckError> {
        self.check_lengths(&lengths)?;
        let target = Vector3::from(lengths);
        let mut x = Vector3::zeros();
        let mut residual = f64::INFINITY;
        for _ in 0..50 {
            let a = NeckAngles::from_vector(x);
            let (l, units) = self.legs(a);
            let e = target - Vector3::from(l);
            residual = e.amax();
            if residual < 1e-15 {
                break;
            }
            let j = self.jacobian(a, &units);
            let Some(step) = j.lu().solve(&e) else {
                return Err(NeckError::NoConvergence {
                    residual_m: residual,
                });
            };
            // Keep iterates in a sane range: a step beyond a radian means divergence.
            x += step.map(|s| s.clamp(-0.5, 0.5));
            if step.amax() < 1e-15 {
                break;
            }
        }
        if residual > 1e-12 {
            return Err(NeckError::NoConvergence {
                residual_m: residual,
            });
        }
        Ok(NeckAngles::from_vector(x))
    }
}

fn factors(a: NeckAngles) -> (Matrix3<f64>, Matrix3<f64>, Matrix3<f64>) {
    (
        *Rotation3::from_axis_angle(&Vector3::z_axis(), a.yaw).matrix(),
        *Rotation3::from_axis_angle(&Vector3::y_axis(), a.pitch).matrix(),
        *Rotation3::from_axis_angle(&Vector3::x_axis(), a.roll).matrix(),
    )
}

/// `R = Rz(yaw) · Ry(pitch) · Rx(roll)`.
pub fn rotation(a: NeckAngles) -> Matrix3<f64> {
    let (rz, ry, rx) = factors(a);
    rz * ry * rx
}

fn d_rot_z(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(-s, -c, 0.0, c, -s, 0.0, 0.0, 0.0, 0.0)
}

fn d_rot_y(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(-s, 0.0, c, 0.0, 0.0, 0.0, -c, 0.0, -s)
}

fn d_rot_x(t: f64) -> Matrix3<f64> {
    let (s, c) = t.sin_cos();
    Matrix3::new(0.0, 0.0, 0.0, 0.0, -s, -c, 0.0, c, -s)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(g: &NeckGeometry, n: usize) -> Vec<NeckAngles> {
        let lin =
            |max: f64, k: usize| (-max + 2.0 * max * k as f64 / (n - 1) as f64).clamp(-max, max);
        let mut out = Vec::new();
        for i in 0..n {
            for j in 0..n {
                for k in 0..n {
                    out.push(NeckAngles {
                        pitch: lin(g.max_pitch_rad, i),
                        roll: lin(g.max_roll_rad, j),
                        yaw: lin(g.max_yaw_rad, k),
                    });
                }
            }
        }
        out
    }

    #[test]
    fn home_pose_has_equal_legs() {
        let g = NeckGeometry::default();
        let z = NeckAngles {
            pitch: 0.0,
            roll: 0.0,
            yaw: 0.0,
        };
        let l = g.inverse(z).unwrap();
        // |c + p - b|² = h² + r_p² + r_b² - 2 r_p r_b cos φ.
        let expected = (0.1f64.powi(2) + 0.04f64.powi(2) + 0.06f64.powi(2)
            - 2.0 * 0.04 * 0.06 * 40f64.to_radians().cos())
        .sqrt();
        for li in l {
            assert!((li - expected).abs() < 1e-15);
        }
        assert_eq!(g.forward(l).unwrap(), z);
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let g = NeckGeometry::default();
        let a = NeckAngles {
            pitch: 0.2,
            roll: -0.15,
            yaw: 0.3,
        };
        let (_, units) = g.legs(a);
        let j = g.jacobian(a, &units);
        let h = 1e-6;
        for k in 0..3 {
            let mut xp = a.to_vector();
            let mut xm = a.to_vector();
            xp[k] += h;
            xm[k] -= h;
            let (lp, _) = g.legs(NeckAngles::from_vector(xp));
            let (lm, _) = g.legs(NeckAngles::from_vector(xm));
            for i in 0..3 {
                let fd = (lp[i] - lm[i]) / (2.0 * h);
                assert!((fd - j[(i, k)]).abs() < 1e-9, "d l{i}/d x{k}");
            }
        }
    }

    #[test]
    fn round_trip_over_the_whole_range() {
        let g = NeckGeometry::default();
        let mut worst = 0.0_f64;
        let poses = grid(&g, 11);
        assert_eq!(poses.len(), 1331);
        for a in poses {
            let l = g.inverse(a).unwrap();
            let b = g.forward(l).unwrap();
            let err = (a.to_vector() - b.to_vector()).amax();
            worst = worst.max(err);
        }
        assert!(worst < 1e-9, "worst round-trip error {worst} rad");
        eprintln!("neck round trip over 11³ poses: worst error {worst:e} rad");
    }

    #[test]
    fn angle_rates_invert_leg_rates() {
        let g = NeckGeometry::default();
        let a = NeckAngles {
            pitch: -0.3,
            roll: 0.2,
            yaw: 0.4,
        };
        let w = NeckAngles {
            pitch: 0.5,
            roll: -0.2,
            yaw: 1.0,
        };
        let h = 1e-6;
        let plus = g
            .legs(NeckAngles::from_vector(a.to_vector() + w.to_vector() * h))
            .0;
        let minus = g
            .legs(NeckAngles::from_vector(a.to_vector() - w.to_vector() * h))
            .0;
        let rates: [f64; 3] = std::array::from_fn(|i| (plus[i] - minus[i]) / (2.0 * h));
        let back = g.angle_rates(a, rates).unwrap();
        assert!((back.to_vector() - w.to_vector()).amax() < 1e-7, "{back:?}");
    }

    #[test]
    fn stroke_covers_the_angle_box_with_margin() {
        let g = NeckGeometry::default();
        let (mut lo, mut hi) = (f64::INFINITY, 0.0_f64);
        for a in grid(&g, 21) {
            for l in g.legs(a).0 {
                lo = lo.min(l);
                hi = hi.max(l);
            }
        }
        assert!(
            lo > g.min_length_m && hi < g.max_length_m,
            "legs {lo}..{hi} m"
        );
        eprintln!("neck legs over the angle box: {lo:.4}..{hi:.4} m");
    }

    #[test]
    fn yaw_pitch_and_roll_each_change_the_legs() {
        let g = NeckGeometry::default();
        let home = g
            .inverse(NeckAngles {
                pitch: 0.0,
                roll: 0.0,
                yaw: 0.0,
            })
            .unwrap();
        for a in [
            NeckAngles {
                pitch: 0.1,
                roll: 0.0,
                yaw: 0.0,
            },
            NeckAngles {
                pitch: 0.0,
                roll: 0.1,
                yaw: 0.0,
            },
            NeckAngles {
                pitch: 0.0,
                roll: 0.0,
                yaw: 0.1,
            },
        ] {
            let l = g.inverse(a).unwrap();
            let change = (0..3).map(|i| (l[i] - home[i]).abs()).fold(0.0, f64::max);
            assert!(change > 1e-3, "{a:?} moves legs by only {change} m");
        }
    }

    /// Loki's neck (models/loki.urdf): a 60° twist, legs 80–155 mm, the URDF's angle box.
    fn loki() -> NeckGeometry {
        let model = robot_model::RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap();
        let spec = model.stewart_neck.clone().unwrap();
        let limits = [&spec.pitch, &spec.roll, &spec.yaw].map(|j| {
            let l = model.joint(j).unwrap().limits;
            (l.lower, l.upper)
        });
        NeckGeometry::from_spec(&spec, limits).unwrap()
    }

    #[test]
    fn lokis_neck_reaches_its_joints_box_at_zero_roll_and_clamps_the_far_corners() {
        let g = loki();
        assert!((g.max_pitch_rad - 0.6).abs() < 1e-12 && (g.max_yaw_rad - 0.8).abs() < 1e-12);
        let (mut inside, mut outside) = (0, 0);
        for a in grid(&g, 9) {
            if a.pitch < -0.5 {
                continue; // beyond neck_pitch's lower limit
            }
            if a.roll == 0.0 {
                assert!(g.reachable(a), "{a:?}");
            }
            let near = g.nearest_reachable(a).unwrap();
            assert!(g.reachable(near), "{a:?} -> {near:?}");
            if g.reachable(a) {
                assert_eq!(near, a);
                inside += 1;
            } else {
                outside += 1;
                // Never further than the plain radial clamp, and on the stroke's boundary.
                let l = g.legs(near).0;
                let edge = l
                    .iter()
                    .map(|x| (x - g.min_length_m).abs().min((x - g.max_length_m).abs()))
                    .fold(f64::INFINITY, f64::min);
                assert!(edge < 1e-6, "{near:?} legs {l:?}");
            }
        }
        assert!(
            outside > 0 && outside * 20 < inside,
            "{inside} in, {outside} out"
        );
    }

    #[test]
    fn the_clamp_keeps_what_the_stroke_allows_of_each_axis() {
        let g = loki();
        // Far in pitch, roll and yaw at once: out of the stroke.
        let goal = NeckAngles {
            pitch: -0.5,
            roll: -0.4,
            yaw: -0.8,
        };
        assert!(!g.reachable(goal));
        let near = g.nearest_reachable(goal).unwrap();
        let radial = {
            let (mut lo, mut hi) = (0.0, 1.0);
            for _ in 0..40 {
                let mid = 0.5 * (lo + hi);
                if g.reachable(NeckAngles::from_vector(goal.to_vector() * mid)) {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            NeckAngles::from_vector(goal.to_vector() * lo)
        };
        let d = |a: NeckAngles| (a.to_vector() - goal.to_vector()).norm();
        assert!(d(near) < d(radial) - 1e-3, "{near:?} vs radial {radial:?}");
        eprintln!(
            "neck clamp of {goal:?}: {:.4} rad from the goal (radial clamp {:.4})",
            d(near),
            d(radial)
        );
    }

    #[test]
    fn inconsistent_geometries_are_named() {
        let mut g = loki();
        g.twist_rad = 0.0;
        let e = g.check_consistent().unwrap_err().to_string();
        assert!(e.contains("cannot all be told apart"), "{e}");
        let mut g = loki();
        g.max_length_m = 0.1;
        let e = g.check_consistent().unwrap_err().to_string();
        assert!(e.contains("at the home pose the legs are"), "{e}");
        assert_eq!(
            g.nearest_reachable(NeckAngles {
                pitch: 0.3,
                ..NeckAngles::HOME
            }),
            None
        );
        let mut g = loki();
        g.pivot_height_m = f64::NAN;
        assert!(g.check_consistent().is_err());
    }

    #[test]
    fn out_of_range_requests_rejected() {
        let g = NeckGeometry::default();
        let e = g
            .inverse(NeckAngles {
                pitch: 0.5,
                roll: 0.0,
                yaw: 0.0,
            })
            .unwrap_err();
        assert!(
            matches!(e, NeckError::AngleOutOfRange { axis: "pitch", .. }),
            "{e}"
        );
        assert!(
            g.inverse(NeckAngles {
                pitch: 0.0,
                roll: f64::NAN,
                yaw: 0.0
            })
            .is_err()
        );
        assert!(
            g.inverse(NeckAngles {
                pitch: 0.0,
                roll: 0.0,
                yaw: -0.6
            })
            .is_err()
        );
        assert!(matches!(
            g.forward([0.05, 0.1, 0.1]),
            Err(NeckError::LengthOutOfRange { leg: 0, .. })
        ));
        // Lengths inside the stroke but reachable only beyond the angle limits.
        let far = g
            .legs(NeckAngles {
                pitch: 0.0,
                roll: 0.0,
                yaw: 0.7,
            })
            .0;
        g.check_lengths(&far).unwrap();
        assert!(matches!(
            g.forward(far),
            Err(NeckError::AngleOutOfRange { axis: "yaw", .. })
        ));
    }
}
