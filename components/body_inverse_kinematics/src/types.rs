//! Bus-facing data types of BodyInverseKinematics: plain serde structs, meant to move into the
//! `interfaces` crate once the bus is in place.
//!
//! # Frames and units
//! - Every target is expressed in the **root frame of the requested body part's chain** (for
//!   example `torso` for `left_arm_7` and `neck`, `base_footprint` for `left_arm_13`; see
//!   `robot_model::BODY_PARTS`). The caller transforms world targets into that
//!   frame with the deep representation before asking.
//! - Positions in metres, angles in radians, times in seconds, joint values in radians (revolute)
//!   or metres (prismatic), in chain order (root to tip).
//! - Orientations are unit quaternions written `[x, y, z, w]`.
//! - Per-axis weights are `[x, y, z, rx, ry, rz]` in the root frame: the solver minimises
//!   `Σ (w_k e_k)²` where `e` is the position error (m) followed by the rotation error (the rotation
//!   vector of `R_target R_tip⁻¹`, rad). An axis of weight 0 is free and is not part of the
//!   reported residual.

use serde::{Deserialize, Serialize};

/// Default position tolerance (m): 1 mm.
pub const DEFAULT_TOLERANCE_M: f64 = 1e-3;
/// Default orientation tolerance (rad): 0.01 rad.
pub const DEFAULT_TOLERANCE_RAD: f64 = 0.01;
/// Default time budget of one request (s), restarts included.
pub const DEFAULT_MAX_TIME_S: f64 = 0.02;

/// What the tip of the chain must do.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum IkTarget {
    /// The tip origin at `position_m` (root frame); its orientation is free.
    Position {
        /// Target position (m, root frame).
        position_m: [f64; 3],
    },
    /// The tip frame at a full pose (root frame).
    Pose {
        /// Target position (m, root frame).
        position_m: [f64; 3],
        /// Target orientation, unit quaternion `[x, y, z, w]` (normalised on use; must not be 0).
        orientation_xyzw: [f64; 4],
    },
    /// Gaze: the tip's +z axis (the optical axis of an optical frame such as
    /// `head_rgbd_optical_frame`) must pass through `point_m`, with the point in front of the
    /// camera. Solved as the paper's virtual stick: a segment along the optical axis, as long as the
    /// current distance to the target, whose end must touch the target. The residual is the
    /// perpendicular distance from the point to the axis ray (m) and the angle between the axis and
    /// the direction to the point (rad).
    Gaze {
        /// The point to look at (m, root frame).
        point_m: [f64; 3],
    },
}

/// One IK request for a named body part.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IkRequest {
    /// A named body part (`left_arm_7`, `neck`, ...; see `robot_model`).
    pub body_part: String,
    /// The target, in the chain's root frame.
    pub target: IkTarget,
    /// Per-axis weights `[x, y, z, rx, ry, rz]` (>= 0, not all 0). `None`: all 1 for a pose;
    /// a position target always has its rotation weights set to 0; a gaze ignores weights.
    #[serde(default)]
    pub weights: Option<[f64; 6]>,
    /// Position tolerance (m, > 0).
    #[serde(default = "default_tolerance_m")]
    pub tolerance_m: f64,
    /// Orientation tolerance (rad, > 0).
    #[serde(default = "default_tolerance_rad")]
    pub tolerance_rad: f64,
    /// Time budget (s, >= 0) for the whole request, random restarts included. The first attempt
    /// always runs to its iteration limit.
    #[serde(default = "default_max_time_s")]
    pub max_time_s: f64,
    /// Seed of the random restarts: the same request gives the same answer.
    #[serde(default)]
    pub seed: u64,
    /// Joint values to start from (chain order), usually the current ones; `None`: the middle of
    /// each joint's range. Values outside the limits are clamped into them first.
    #[serde(default)]
    pub q_start: Option<Vec<f64>>,
    /// Reject solutions in which two non-adjacent links intersect (and keep searching).
    #[serde(default = "default_true")]
    pub check_self_collision: bool,
}

fn default_tolerance_m() -> f64 {
    DEFAULT_TOLERANCE_M
}
fn default_tolerance_rad() -> f64 {
    DEFAULT_TOLERANCE_RAD
}
fn default_max_time_s() -> f64 {
    DEFAULT_MAX_TIME_S
}
fn default_true() -> bool {
    true
}

impl IkRequest {
    /// A request with the default tolerances (1 mm, 0.01 rad), time budget, seed 0, no start
    /// configuration and self-collision checking on.
    pub fn new(body_part: impl Into<String>, target: IkTarget) -> Self {
        Self {
            body_part: body_part.into(),
            target,
            weights: None,
            tolerance_m: DEFAULT_TOLERANCE_M,
            tolerance_rad: DEFAULT_TOLERANCE_RAD,
            max_time_s: DEFAULT_MAX_TIME_S,
            seed: 0,
            q_start: None,
            check_self_collision: true,
        }
    }
}

/// Why a request ended [`IkResult::Unreachable`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnreachableCause {
    /// No configuration within the limits got the residual within tolerance in the time budget.
    OutOfTolerance,
    /// Configurations within tolerance were found, but every one had two links intersecting.
    SelfCollision,
}

/// The answer to an [`IkRequest`]. Every joint vector is within the joint limits.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "status", rename_all = "snake_case")]
pub enum IkResult {
    /// A configuration within tolerance (and collision-free if that was asked).
    Reached {
        /// Joint values (chain order, rad or m).
        q: Vec<f64>,
        /// Position residual (m): weighted axes only.
        residual_m: f64,
        /// Orientation residual (rad): weighted axes only (0 for a position target).
        residual_rad: f64,
        /// Levenberg-Marquardt iterations over all attempts.
        iterations: u32,
    },
    /// No acceptable configuration: the best one found and its residual.
    Unreachable {
        /// The best configuration found (collision-free if any collision-free one was seen).
        best_q: Vec<f64>,
        /// Its position residual (m).
        residual_m: f64,
        /// Its orientation residual (rad).
        residual_rad: f64,
        /// Iterations over all attempts.
        iterations: u32,
        /// Why no configuration was accepted.
        cause: UnreachableCause,
    },
}

impl IkResult {
    /// The joint values of the answer (the solution, or the best configuration found).
    pub fn q(&self) -> &[f64] {
        match self {
            IkResult::Reached { q, .. } => q,
            IkResult::Unreachable { best_q, .. } => best_q,
        }
    }
    /// Whether the target was reached.
    pub fn is_reached(&self) -> bool {
        matches!(self, IkResult::Reached { .. })
    }
    /// `(residual_m, residual_rad)`.
    pub fn residual(&self) -> (f64, f64) {
        match self {
            IkResult::Reached {
                residual_m,
                residual_rad,
                ..
            }
            | IkResult::Unreachable {
                residual_m,
                residual_rad,
                ..
            } => (*residual_m, *residual_rad),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_defaults_from_minimal_json() {
        let r: IkRequest = serde_json::from_str(
            r#"{"body_part":"neck","target":{"kind":"gaze","point_m":[1.0,0.0,0.5]}}"#,
        )
        .unwrap();
        assert_eq!(r.tolerance_m, 1e-3);
        assert_eq!(r.tolerance_rad, 0.01);
        assert!(r.check_self_collision);
        assert_eq!(r, {
            let mut n = IkRequest::new(
                "neck",
                IkTarget::Gaze {
                    point_m: [1.0, 0.0, 0.5],
                },
            );
            n.max_time_s = DEFAULT_MAX_TIME_S;
            n
        });
        // Typos are errors, not silently ignored.
        assert!(
            serde_json::from_str::<IkRequest>(
                r#"{"body_part":"neck","target":{"kind":"gaze","point_m":[1,0,0]},"tolerence_m":1}"#
            )
            .is_err()
        );
    }

    #[test]
    fn result_round_trips_with_status_tag() {
        let r = IkResult::Unreachable {
            best_q: vec![0.1, 0.2],
            residual_m: 2.5,
            residual_rad: 0.0,
            iterations: 40,
            cause: UnreachableCause::OutOfTolerance,
        };
        let s = serde_json::to_string(&r).unwrap();
        assert!(s.contains(r#""status":"unreachable""#), "{s}");
        assert!(s.contains(r#""cause":"out_of_tolerance""#), "{s}");
        assert_eq!(serde_json::from_str::<IkResult>(&s).unwrap(), r);
    }
}
