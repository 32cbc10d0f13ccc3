//! Kinematic chains: named body parts, their joints, forward kinematics and the geometric
//! Jacobian, without allocating.

use super::*;

/// A named body part: a documented chain of Loki (see the module docs for the table).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BodyPart {
    /// The name, e.g. `left_arm_7`.
    pub name: &'static str,
    /// Root link of the chain.
    pub root: &'static str,
    /// Tip link of the chain.
    pub tip: &'static str,
    /// Number of movable joints in the chain.
    pub dof: usize,
}

/// The named body parts of Loki (see the module docs).
pub const BODY_PARTS: &[BodyPart] = &[
    BodyPart {
        name: "left_arm_4",
        root: "torso",
        tip: "left_wrist_center",
        dof: 4,
    },
    BodyPart {
        name: "left_arm_7",
        root: "torso",
        tip: "left_hand_center",
        dof: 7,
    },
    BodyPart {
        name: "left_arm_9",
        root: "base_footprint",
        tip: "left_hand_center",
        dof: 9,
    },
    BodyPart {
        name: "left_arm_11",
        root: "torso",
        tip: "left_fingertip",
        dof: 11,
    },
    BodyPart {
        name: "left_arm_13",
        root: "base_footprint",
        tip: "left_fingertip",
        dof: 13,
    },
    BodyPart {
        name: "left_arm",
        root: "torso",
        tip: "left_hand_center",
        dof: 7,
    },
    BodyPart {
        name: "right_arm_4",
        root: "torso",
        tip: "right_wrist_center",
        dof: 4,
    },
    BodyPart {
        name: "right_arm_7",
        root: "torso",
        tip: "right_hand_center",
        dof: 7,
    },
    BodyPart {
        name: "right_arm_9",
        root: "base_footprint",
        tip: "right_hand_center",
        dof: 9,
    },
    BodyPart {
        name: "right_arm_11",
        root: "torso",
        tip: "right_fingertip",
        dof: 11,
    },
    BodyPart {
        name: "right_arm_13",
        root: "base_footprint",
        tip: "right_fingertip",
        dof: 13,
    },
    BodyPart {
        name: "right_arm",
        root: "torso",
        tip: "right_hand_center",
        dof: 7,
    },
    BodyPart {
        name: "neck",
        root: "torso",
        tip: "head_rgbd_optical_frame",
        dof: 4,
    },
    BodyPart {
        name: "head",
        root: "torso",
        tip: "head",
        dof: 4,
    },
    BodyPart {
        name: "left_eye",
        root: "head",
        tip: "left_eye_optical_frame",
        dof: 2,
    },
    BodyPart {
        name: "right_eye",
        root: "head",
        tip: "right_eye_optical_frame",
        dof: 2,
    },
    BodyPart {
        name: "base",
        root: "base_footprint",
        tip: "base_link",
        dof: 2,
    },
];

impl BodyPart {
    /// Looks a body part up by name.
    pub fn find(name: &str) -> Result<&'static BodyPart> {
        BODY_PARTS.iter().find(|b| b.name == name).ok_or_else(|| {
            ModelError::UnknownBodyPart(
                name.to_string(),
                BODY_PARTS
                    .iter()
                    .map(|b| b.name)
                    .collect::<Vec<_>>()
                    .join(", "),
            )
        })
    }
}

/// One movable joint of a [`Chain`].
#[derive(Debug, Clone)]
pub struct ChainJoint {
    /// Joint name.
    pub name: String,
    /// Kind (never `Fixed`).
    pub kind: JointKind,
    /// Fixed transform from the previous movable joint's frame (or the chain root) to this
    /// joint's frame: the product of the fixed joints in between and this joint's origin.
    pub pre: Isometry3<f64>,
    /// Unit axis in this joint's frame.
    pub axis: Unit<Vector3<f64>>,
    /// Limits.
    pub limits: JointLimits,
}

/// An open kinematic chain from a root link to a tip link, ready for FK and Jacobians.
#[derive(Debug, Clone)]
pub struct Chain {
    /// Root link name.
    pub root: String,
    /// Tip link name.
    pub tip: String,
    /// Movable joints, root to tip.
    pub joints: Vec<ChainJoint>,
    /// Fixed transform from the last movable joint's frame (or the root if none) to the tip.
    pub tail: Isometry3<f64>,
}

impl Chain {
    /// Number of movable joints.
    pub fn dof(&self) -> usize {
        self.joints.len()
    }

    /// Joint names, root to tip.
    pub fn joint_names(&self) -> Vec<&str> {
        self.joints.iter().map(|j| j.name.as_str()).collect()
    }

    /// Joint limits, root to tip.
    pub fn limits(&self) -> Vec<JointLimits> {
        self.joints.iter().map(|j| j.limits).collect()
    }

    fn check(&self, q: &[f64]) -> Result<()> {
        if q.len() != self.joints.len() {
            return Err(ModelError::JointCount {
                expected: self.joints.len(),
                got: q.len(),
            });
        }
        for (j, v) in self.joints.iter().zip(q) {
            if !v.is_finite() {
                return Err(ModelError::NonFiniteValue(j.name.clone()));
            }
        }
        Ok(())
    }

    /// Forward kinematics: `root_T_tip` for joint values `q` (rad or m, chain order).
    ///
    /// Errors if `q` has the wrong length or a non-finite value. Limits are not enforced here
    /// (see [`Chain::within_limits`]). Allocation-free.
    pub fn fk(&self, q: &[f64]) -> Result<Isometry3<f64>> {
        self.check(q)?;
        Ok(self.fk_unchecked(q))
    }

    /// [`Chain::fk`] without the length and finiteness checks (extra values are ignored, missing
    /// ones are taken as 0). For hot loops that validated `q` once.
    #[inline]
    pub fn fk_unchecked(&self, q: &[f64]) -> Isometry3<f64> {
        let mut t = Isometry3::identity();
        for (i, j) in self.joints.iter().enumerate() {
            let v = q.get(i).copied().unwrap_or(0.0);
            t = t * j.pre * joint_motion(j.kind, &j.axis, v);
        }
        t * self.tail
    }

    /// Whether every value of `q` is within its joint's position limits.
    pub fn within_limits(&self, q: &[f64]) -> bool {
        q.len() == self.joints.len()
            && self
                .joints
                .iter()
                .zip(q)
                .all(|(j, v)| j.limits.contains(*v))
    }

    /// Geometric Jacobian (6 x dof, linear rows then angular rows, root frame) and `root_T_tip`.
    pub fn jacobian(&self, q: &[f64]) -> Result<(Isometry3<f64>, Matrix6xX<f64>)> {
        let mut jac = Matrix6xX::zeros(self.joints.len());
        let tip = self.jacobian_into(q, &mut jac)?;
        Ok((tip, jac))
    }

    /// [`Chain::jacobian`] into a caller-owned matrix (resized only if its column count differs),
    /// for allocation-free IK loops. Returns `root_T_tip`.
    pub fn jacobian_into(&self, q: &[f64], jac: &mut Matrix6xX<f64>) -> Result<Isometry3<f64>> {
        self.check(q)?;
        if jac.ncols() != self.joints.len() {
            *jac = Matrix6xX::zeros(self.joints.len());
        }
        // First pass: tip position. Second pass: joint frames and columns.
        let tip = self.fk_unchecked(q);
        let p_tip = tip.translation.vector;
        let mut t = Isometry3::identity();
        for (i, j) in self.joints.iter().enumerate() {
            t *= j.pre;
            let z = t.rotation * j.axis.into_inner();
            match j.kind {
                JointKind::Revolute | JointKind::Continuous => {
                    let lin = z.cross(&(p_tip - t.translation.vector));
                    jac.fixed_view_mut::<3, 1>(0, i).copy_from(&lin);
                    jac.fixed_view_mut::<3, 1>(3, i).copy_from(&z);
                }
                JointKind::Prismatic => {
                    jac.fixed_view_mut::<3, 1>(0, i).copy_from(&z);
                    jac.fixed_view_mut::<3, 1>(3, i).fill(0.0);
                }
                JointKind::Fixed => jac.column_mut(i).fill(0.0),
            }
            t *= joint_motion(j.kind, &j.axis, q[i]);
        }
        Ok(tip)
    }

    /// Upper bound of the distance from the first joint's origin to the tip, over all joint
    /// values (m): the sum of the lengths of the fixed offsets after the first joint. Prismatic
    /// joints add the larger magnitude of their limits. Used by the `reachable` predicate.
    pub fn reach_m(&self) -> f64 {
        let mut reach = 0.0;
        for (i, j) in self.joints.iter().enumerate() {
            if i > 0 {
                reach += j.pre.translation.vector.norm();
            }
            if j.kind == JointKind::Prismatic {
                reach += j.limits.lower.abs().max(j.limits.upper.abs());
            }
        }
        reach + self.tail.translation.vector.norm()
    }
}
