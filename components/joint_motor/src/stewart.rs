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
    #[cfg(test)]
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
