//! [`BodyIk`]: IK requests on named body parts of one robot model, with self-collision checks
//! against the rest of the body.
//!
//! The joints outside the requested chain keep the values of the **posture**
//! ([`BodyIk::set_joint`], one value per model joint, initially 0 clamped into the limits): the
//! component keeps it up to date from the joint states, so that a reaching arm is checked against
//! where the other arm and the head really are.

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Isometry3, Quaternion, Translation3, UnitQuaternion, Vector3, Vector6};
use robot_model::ModelError;
use robot_model::{Chain, RobotModel};
use thiserror::Error;

use crate::collision::{CollidingPair, SelfCollision};
use crate::solver::{Deadline, Goal, IkSolver, MonotonicDeadline, SolverOptions, Tolerance};
use crate::types::{IkRequest, IkResult, IkTarget, UnreachableCause};

/// Errors of [`BodyIk`]: the request is refused before any solving.
#[derive(Debug, Error)]
pub enum IkError {
    /// The model or the body part could not be loaded (unknown name, not a chain, bad URDF).
    #[error(transparent)]
    Model(#[from] ModelError),
    /// A malformed request (non-finite numbers, zero quaternion, bad weights or tolerances).
    #[error("invalid IK request: {0}")]
    InvalidRequest(String),
    /// A joint vector of the wrong length.
    #[error("expected {expected} joint values, got {got}")]
    JointCount {
        /// The chain's number of joints.
        expected: usize,
        /// What was given.
        got: usize,
    },
}

#[derive(Debug, Clone)]
struct Part {
    solver: IkSolver,
    /// Model joint index of each chain joint.
    joint_index: Vec<usize>,
    /// Links moved by the chain.
    moving: Vec<bool>,
}

/// IK for every named body part of one robot (see the module docs).
#[derive(Debug, Clone)]
pub struct BodyIk {
    model: RobotModel,
    collision: SelfCollision,
    posture: Vec<f64>,
    parts: HashMap<String, Part>,
    options: SolverOptions,
    scratch: Vec<f64>,
}

fn finite(xs: &[f64]) -> bool {
    xs.iter().all(|x| x.is_finite())
}

impl BodyIk {
    /// Loads a URDF file.
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self, IkError> {
        Ok(Self::new(RobotModel::from_urdf_file(path)?))
    }

    /// IK for `model` with default solver options.
    pub fn new(model: RobotModel) -> Self {
        Self::with_options(model, SolverOptions::default())
    }

    /// IK for `model` with the given solver options.
    pub fn with_options(model: RobotModel, options: SolverOptions) -> Self {
        let collision = SelfCollision::new(&model);
        let posture: Vec<f64> = model
            .joints
            .iter()
            .map(|j| 0.0_f64.clamp(j.limits.lower, j.limits.upper))
            .collect();
        Self {
            scratch: posture.clone(),
            model,
            collision,
            posture,
            parts: HashMap::new(),
            options,
        }
    }

    /// The robot model.
    pub fn model(&self) -> &RobotModel {
        &self.model
    }

    /// The self-collision checker.
    pub fn collision(&mut self) -> &mut SelfCollision {
        &mut self.collision
    }

    /// Sets one joint of the posture (rad or m; clamped into its limits).
    pub fn set_joint(&mut self, name: &str, value: f64) -> Result<(), IkError> {
        if !value.is_finite() {
            return Err(IkError::InvalidRequest(format!("joint `{name}`: {value}")));
        }
        let i = self
            .model
            .joints
            .iter()
            .position(|j| j.name == name)
            .ok_or_else(|| ModelError::UnknownJoint(name.to_string()))?;
        let l = self.model.joints[i].limits;
        self.posture[i] = value.clamp(l.lower, l.upper);
        Ok(())
    }

    /// The posture: one value per model joint (`RobotModel::joints` order).
    pub fn posture(&self) -> &[f64] {
        &self.posture
    }

    fn part(&mut self, name: &str) -> Result<&mut Part, IkError> {
        if !self.parts.contains_key(name) {
            let chain = self.model.body_part(name)?;
            let joint_index: Vec<usize> = chain
                .joints
                .iter()
                .map(|cj| {
                    self.model
                        .joints
                        .iter()
                        .position(|j| j.name == cj.name)
                        .ok_or_else(|| ModelError::UnknownJoint(cj.name.clone()))
                })
                .collect::<Result<_, _>>()?;
            let moving = self.collision.moved_by(&joint_index);
            let solver = IkSolver::new(chain, self.options);
            self.parts.insert(
                name.to_string(),
                Part {
                    solver,
                    joint_index,
                    moving,
                },
            );
        }
        self.parts
            .get_mut(name)
            .ok_or_else(|| IkError::InvalidRequest(format!("body part `{name}`")))
    }

    /// The solver of a body part (built on first use).
    pub fn solver(&mut self, body_part: &str) -> Result<&IkSolver, IkError> {
        Ok(&self.part(body_part)?.solver)
    }

    /// The colliding pair, if any, when the body part `body_part` is at `q` (chain order) and the
    /// rest of the body at the posture.
    pub fn self_collision(
        &mut self,
        body_part: &str,
        q: &[f64],
    ) -> Result<Option<CollidingPair>, IkError> {
        let part = self.part(body_part)?;
        if q.len() != part.joint_index.len() {
            return Err(IkError::JointCount {
                expected: part.joint_index.len(),
                got: q.len(),
            });
        }
        let idx = part.joint_index.clone();
        self.scratch.copy_from_slice(&self.posture);
        for (k, &j) in idx.iter().enumerate() {
            self.scratch[j] = q[k];
        }
        let full = self.scratch.clone();
        Ok(self.collision.colliding_pair(&full))
    }

    /// Solves a request with its own time budget (`max_time_s`, on the monotonic clock).
    pub fn solve(&mut self, req: &IkRequest) -> Result<IkResult, IkError> {
        if !(req.max_time_s.is_finite() && req.max_time_s >= 0.0) {
            return Err(IkError::InvalidRequest(format!(
                "max_time_s must be finite and >= 0, got {}",
                req.max_time_s
            )));
        }
        let mut deadline = MonotonicDeadline::after_s(req.max_time_s);
        self.solve_with_deadline(req, &mut deadline)
    }

    /// Solves a request, restarting until `deadline` expires (`req.max_time_s` is not used).
    pub fn solve_with_deadline(
        &mut self,
        req: &IkRequest,
        deadline: &mut dyn Deadline,
    ) -> Result<IkResult, IkError> {
        let goal = goal_of(req)?;
        let tol = Tolerance {
            m: req.tolerance_m,
            rad: req.tolerance_rad,
        };
        if !(tol.m > 0.0 && tol.rad > 0.0) {
            return Err(IkError::InvalidRequest(
                "tolerances must be > 0".to_string(),
            ));
        }
        self.part(&req.body_part)?;
        let Self {
            parts,
            collision,
            posture,
            scratch,
            ..
        } = self;
        let part = parts
            .get_mut(&req.body_part)
            .ok_or_else(|| IkError::InvalidRequest(req.body_part.clone()))?;
        let n = part.solver.dof();
        let start = match &req.q_start {
            Some(q) if q.len() != n => {
                return Err(IkError::JointCount {
                    expected: n,
                    got: q.len(),
                });
            }
            Some(q) if !finite(q) => {
                return Err(IkError::InvalidRequest("q_start is not finite".into()));
            }
            Some(q) => q.clone(),
            None => part.solver.mid_range(),
        };
        scratch.copy_from_slice(posture);
        let check = req.check_self_collision;
        let Part {
            solver,
            joint_index,
            moving,
        } = part;
        let mut accept = |q: &[f64]| {
            if !check {
                return true;
            }
            for (k, &j) in joint_index.iter().enumerate() {
                scratch[j] = q[k];
            }
            collision.first_collision(scratch, Some(moving)).is_none()
        };
        let report = solver.solve(&goal, &tol, &start, req.seed, deadline, &mut accept);
        let q = solver.solution().to_vec();
        Ok(if report.reached {
            IkResult::Reached {
                q,
                residual_m: report.residual.m,
                residual_rad: report.residual.rad,
                iterations: report.iterations,
            }
        } else {
            IkResult::Unreachable {
                best_q: q,
                residual_m: report.residual.m,
                residual_rad: report.residual.rad,
                iterations: report.iterations,
                cause: if report.refused > 0 {
                    UnreachableCause::SelfCollision
                } else {
                    UnreachableCause::OutOfTolerance
                },
            }
        })
    }
}

/// The solver goal of a request (validated).
pub fn goal_of(req: &IkRequest) -> Result<Goal, IkError> {
    let bad = |what: &str| Err(IkError::InvalidRequest(what.to_string()));
    let weights = match req.weights {
        Some(w) if !w.iter().all(|x| x.is_finite() && *x >= 0.0) => {
            return bad("weights must be finite and >= 0");
        }
        Some(w) => Vector6::from_row_slice(&w),
        None => Vector6::repeat(1.0),
    };
    match &req.target {
        IkTarget::Position { position_m } => {
            if !finite(position_m) {
                return bad("position_m is not finite");
            }
            let mut w = weights;
            w.fixed_rows_mut::<3>(3).fill(0.0);
            if w.iter().all(|x| *x == 0.0) {
                return bad("all position weights are 0");
            }
            Ok(Goal::Pose {
                target: Isometry3::translation(position_m[0], position_m[1], position_m[2]),
                weights: w,
            })
        }
        IkTarget::Pose {
            position_m,
            orientation_xyzw: [x, y, z, w],
        } => {
            let qn = Quaternion::new(*w, *x, *y, *z);
            if !finite(position_m) || !finite(&[*x, *y, *z, *w]) || qn.norm() < 1e-9 {
                return bad("pose is not finite or its quaternion is 0");
            }
            if weights.iter().all(|x| *x == 0.0) {
                return bad("all weights are 0");
            }
            Ok(Goal::Pose {
                target: Isometry3::from_parts(
                    Translation3::new(position_m[0], position_m[1], position_m[2]),
                    UnitQuaternion::from_quaternion(qn),
                ),
                weights,
            })
        }
        IkTarget::Gaze { point_m } => {
            if !finite(point_m) {
                return bad("point_m is not finite");
            }
            Ok(Goal::Gaze {
                point: Vector3::new(point_m[0], point_m[1], point_m[2]),
            })
        }
    }
}

/// The chain's joint values from measured positions, or the first joint missing.
pub fn chain_q(chain: &Chain, measured: &HashMap<String, f64>) -> Result<Vec<f64>, String> {
    chain
        .joints
        .iter()
        .map(|j| measured.get(&j.name).copied().ok_or_else(|| j.name.clone()))
        .collect()
}
