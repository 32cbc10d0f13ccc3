//! # body_inverse_kinematics: Loki's generalized inverse kinematics
//!
//! The *BodyInverseKinematics* module of RoboCog (seed 001 §III and §V.C): one algorithm,
//! Levenberg-Marquardt damped least squares, for **any open chain** of the robot's kinematic tree,
//! chosen per request by naming a body part (`left_arm_4`, `left_arm_7`, `left_arm_11`,
//! `left_arm_13`, `neck`, `left_eye`, ...; see `robot_model`), plus gaze for
//! the head through the paper's virtual stick. This crate is the pure library: no bus, no clock
//! except the compute-time budget of [`solver::MonotonicDeadline`].
//!
//! ## Frames and units
//! Targets are in the chain's root frame (`torso` for arms, neck and head; `base_footprint` for the
//! 13-joint arms; `head` for the eyes). Metres, radians, seconds; joint values in chain order.
//! Orientation errors are rotation vectors (axis × angle, rad) in the root frame; the Jacobian is
//! the geometric one of `deep_representation` (linear rows first).
//!
//! ## Modules
//! - [`solver`]: [`solver::IkSolver`], the allocation-free LM solver for one chain (position, pose
//!   with per-axis weights, gaze), adaptive damping, clamped joint limits, seeded random restarts
//!   within a deadline.
//! - [`body`]: [`body::BodyIk`], requests on named body parts of one URDF model, with the rest of
//!   the body at a posture, and self-collision rejection.
//! - [`collision`]: [`collision::SelfCollision`], capsule/box approximations of the URDF collision
//!   geometry and the list of link pairs checked.
//! - [`trajectory`]: [`trajectory::Trajectory`], quintic time-synchronised joint trajectories
//!   within velocity (and acceleration) limits, sampled as a pure function of time.
//! - [`eyes`]: [`eyes::Eyes`], the eyes during a gaze of the head: on the target first, back
//!   to the middle as the head catches up.
//! - [`component`]: the `body_inverse_kinematics` process (`body/reach` in,
//!   `body/reach_status` out, `dr/transform` and `body/joint_goal` called).
//! - [`types`]: the serde request/result types ([`types::IkRequest`], [`types::IkResult`]), meant
//!   to move into `interfaces`.
//!
//! ## Guarantees
//! Every joint vector returned is within the joint limits. `Reached` means within both tolerances
//! (default 1 mm and 0.01 rad, on the weighted axes) and, if asked, free of self-collision;
//! otherwise `Unreachable` carries the best configuration found and its residual.

pub mod body;
pub mod collision;
pub mod component;
pub mod eyes;
pub mod solver;
pub mod trajectory;
pub mod types;

pub use body::{BodyIk, IkError};
pub use solver::{
    AttemptLimits, Deadline, Goal, IkSolver, MonotonicDeadline, Residual, SolverOptions, Tolerance,
};
pub use trajectory::Trajectory;
pub use types::{IkRequest, IkResult, IkTarget, UnreachableCause};
