//! The eyes during a gaze: where the head is going, the eyes are there first.
//!
//! People move their eyes to a new target first (a saccade, a few hundred degrees per second),
//! and the head follows more slowly while the eyes turn back towards the middle, keeping the
//! target in view (the vestibulo-ocular reflex). [`Eyes::aim`] gives that for free when it is
//! called at every step of the head's trajectory with the *measured* joints: it points both eyes'
//! optical axes at the target from where the head is now. At the start the head has not moved and
//! the eyes turn all the way (as fast as their joints allow); as the head catches up the angles
//! shrink, and once the head camera looks at the target the eyes are near their middle (the small
//! rest is the parallax between the camera and the eyes).
//!
//! The eyes are the URDF's `left_eye` and `right_eye` body parts (root `head`), two joints each
//! with a shared first one: a common tilt, then each eye's pan. The head's pose comes from the
//! `head` body part (root `torso`, the root of the `neck` part the gaze moves).
//!
//! A target beyond an eye's limits gets the eye as far as it goes (clamped, like a person's eyes
//! at the edge of their range); a target behind the eyes is aimed at as well as the limits let.

use std::collections::HashMap;

use nalgebra::{Point3, Vector3};
use robot_model::{Chain, RobotModel};

use crate::body::chain_q;

/// The eyes' chains and joints (see the module docs).
#[derive(Debug, Clone)]
pub struct Eyes {
    head: Chain,
    left: Chain,
    right: Chain,
    /// The common tilt, the left pan, the right pan.
    joints: [String; 3],
    /// Their limits (`lower`, `upper`) and top speeds (URDF).
    limits: [(f64, f64); 3],
    vmax: [f64; 3],
}

impl Eyes {
    /// The eyes of `model`, or why it has none this module can drive.
    pub fn from_model(model: &RobotModel) -> Result<Self, String> {
        let part = |name: &str| {
            model
                .body_part(name)
                .map_err(|e| format!("body part `{name}`: {e}"))
        };
        let (head, left, right) = (part("head")?, part("left_eye")?, part("right_eye")?);
        if left.dof() != 2 || right.dof() != 2 || left.joints[0].name != right.joints[0].name {
            return Err(format!(
                "the eyes must be a shared tilt then a pan each, got {:?} and {:?}",
                left.joint_names(),
                right.joint_names()
            ));
        }
        if left.root != head.tip {
            return Err(format!(
                "the eyes hang from `{}`, not from the head `{}`",
                left.root, head.tip
            ));
        }
        let joints = [&left.joints[0], &left.joints[1], &right.joints[1]];
        Ok(Self {
            limits: joints.map(|j| (j.limits.lower, j.limits.upper)),
            vmax: joints.map(|j| j.limits.velocity),
            joints: joints.map(|j| j.name.clone()),
            head,
            left,
            right,
        })
    }

    /// The frame targets are given in: the root of the head's chain (`torso`).
    pub fn root(&self) -> &str {
        &self.head.root
    }

    /// Whether `chain` moves the head (has every joint of the head's chain): a gaze of it is a
    /// gaze the eyes join.
    pub fn moves_head(&self, chain: &Chain) -> bool {
        self.head
            .joints
            .iter()
            .all(|h| chain.joints.iter().any(|j| j.name == h.name))
    }

    /// The tilt, left pan and right pan joints' names.
    pub fn joints(&self) -> &[String; 3] {
        &self.joints
    }

    /// Their top speeds (URDF), rad/s.
    pub fn max_speeds(&self) -> [f64; 3] {
        self.vmax
    }

    /// Tilt, left pan and right pan (rad, within their limits) that point both eyes at `target`
    /// (a point in [`Eyes::root`]'s frame), from the head where the `measured` joints put it.
    /// Errors: a joint of the head or the eyes missing from `measured` (named).
    pub fn aim(
        &self,
        measured: &HashMap<String, f64>,
        target: &Vector3<f64>,
    ) -> Result<[f64; 3], String> {
        let q = |c: &Chain| chain_q(c, measured);
        let head = self.head.fk(&q(&self.head)?).map_err(|e| e.to_string())?;
        let in_head = head.inverse() * Point3::from(*target);
        let start = q(&self.left)?;
        let right_pan = measured
            .get(&self.joints[2])
            .copied()
            .ok_or_else(|| self.joints[2].clone())?;
        let [tilt, left_pan] = aim_chain(
            &self.left,
            &in_head,
            [start[0], start[1]],
            [self.limits[0], self.limits[1]],
            [true, true],
        );
        let [_, right_pan] = aim_chain(
            &self.right,
            &in_head,
            [tilt, right_pan],
            [self.limits[0], self.limits[2]],
            [false, true],
        );
        Ok([tilt, left_pan, right_pan])
    }

    /// How far (rad) each eye's optical axis is from `target` (in [`Eyes::root`]'s frame) at the
    /// `measured` joints: left, right.
    pub fn off_axis_rad(
        &self,
        measured: &HashMap<String, f64>,
        target: &Vector3<f64>,
    ) -> Option<[f64; 2]> {
        let q = |c: &Chain| chain_q(c, measured).ok();
        let head = self.head.fk(&q(&self.head)?).ok()?;
        let p = head.inverse() * Point3::from(*target);
        let off = |c: &Chain| -> Option<f64> {
            let tip = c.fk(&q(c)?).ok()?;
            let v = tip.inverse() * p;
            Some(Vector3::z().angle(&v.coords))
        };
        Some([off(&self.left)?, off(&self.right)?])
    }
}

/// The direction error of `target` seen from the chain's tip at `q`: its angles off the optical
/// (+z) axis about the tip's y and x (rad), well defined all around.
fn angles_off(chain: &Chain, q: &[f64; 2], target: &Point3<f64>) -> [f64; 2] {
    let v = chain.fk_unchecked(q).inverse() * target;
    [v.x.atan2(v.z), v.y.atan2(v.z)]
}

/// Newton on the chain's two joints (those with `free` set; the others stay at `q`), within
/// `limits`, until the target is on the optical axis or the joints are at their limits.
fn aim_chain(
    chain: &Chain,
    target: &Point3<f64>,
    mut q: [f64; 2],
    limits: [(f64, f64); 2],
    free: [bool; 2],
) -> [f64; 2] {
    const H: f64 = 1e-6;
    for k in 0..2 {
        q[k] = q[k].clamp(limits[k].0, limits[k].1);
    }
    for _ in 0..12 {
        let e = angles_off(chain, &q, target);
        if e[0].abs().max(e[1].abs()) < 1e-9 {
            break;
        }
        // Numerical Jacobian of the error over the free joints.
        let mut cols: Vec<(usize, [f64; 2])> = Vec::with_capacity(2);
        for k in (0..2).filter(|&k| free[k]) {
            let mut qh = q;
            qh[k] += H;
            let eh = angles_off(chain, &qh, target);
            cols.push((k, [(eh[0] - e[0]) / H, (eh[1] - e[1]) / H]));
        }
        // Least-squares step: solve J · dq = -e (J is 2 x cols).
        let step: Vec<(usize, f64)> = match cols.as_slice() {
            [(a, ja), (b, jb)] => {
                let det = ja[0] * jb[1] - jb[0] * ja[1];
                if det.abs() < 1e-12 {
                    break;
                }
                vec![
                    (*a, (-e[0] * jb[1] + jb[0] * e[1]) / det),
                    (*b, (-ja[0] * e[1] + e[0] * ja[1]) / det),
                ]
            }
            [(a, ja)] => {
                let n = ja[0] * ja[0] + ja[1] * ja[1];
                if n < 1e-12 {
                    break;
                }
                vec![(*a, -(ja[0] * e[0] + ja[1] * e[1]) / n)]
            }
            _ => break,
        };
        let mut moved = 0.0_f64;
        for (k, dq) in step {
            let before = q[k];
            q[k] = (q[k] + dq.clamp(-0.5, 0.5)).clamp(limits[k].0, limits[k].1);
            moved = moved.max((q[k] - before).abs());
        }
        if moved < 1e-12 {
            break; // at a limit
        }
    }
    q
}

#[cfg(test)]
mod tests {
    use super::*;

    fn loki() -> RobotModel {
        RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap()
    }

    /// Loki at `q` for the named joints, 0 elsewhere.
    fn posture(m: &RobotModel, q: &[(&str, f64)]) -> HashMap<String, f64> {
        let mut out: HashMap<String, f64> = m
            .movable_joint_names()
            .into_iter()
            .map(|n| (n.to_owned(), 0.0))
            .collect();
        for (n, v) in q {
            out.insert((*n).to_owned(), *v);
        }
        out
    }

    fn with(mut measured: HashMap<String, f64>, eyes: &Eyes, q: [f64; 3]) -> HashMap<String, f64> {
        for (name, v) in eyes.joints().iter().zip(q) {
            measured.insert(name.clone(), v);
        }
        measured
    }

    #[test]
    fn the_eyes_look_at_a_target_the_head_does_not_face_yet() {
        let m = loki();
        let eyes = Eyes::from_model(&m).unwrap();
        assert_eq!(eyes.root(), "torso");
        assert_eq!(
            eyes.joints(),
            &["eyes_tilt", "left_eye_pan", "right_eye_pan"].map(String::from)
        );
        let head = posture(&m, &[("neck_pitch", 0.3)]);
        // A ball ahead, to the left and low: 1 m away in the torso frame.
        let target = Vector3::new(0.9, 0.35, 0.2);
        let q = eyes.aim(&head, &target).unwrap();
        assert!(q[1] > 0.2 && q[2] > 0.2, "both eyes turn left: {q:?}");
        assert!(
            q[2] > q[1],
            "the right eye turns more than the left (they converge): {q:?}"
        );
        let off = eyes.off_axis_rad(&with(head, &eyes, q), &target).unwrap();
        assert!(off[0] < 1e-6 && off[1] < 1e-4, "{off:?}");
    }

    #[test]
    fn once_the_head_faces_the_target_the_eyes_are_back_near_the_middle() {
        let m = loki();
        let eyes = Eyes::from_model(&m).unwrap();
        let gaze = crate::BodyIk::new(m.clone());
        let target = Vector3::new(0.9, 0.35, 0.2);
        // The head's camera on the target (the neck's gaze solution).
        let mut body = gaze;
        let r = body
            .solve(&crate::IkRequest::new(
                "neck",
                crate::IkTarget::Gaze {
                    point_m: [target.x, target.y, target.z],
                },
            ))
            .unwrap();
        let crate::IkResult::Reached { q: neck, .. } = r else {
            panic!("{r:?}")
        };
        let names = m.body_part("neck").unwrap();
        let pairs: Vec<(&str, f64)> = names.joint_names().into_iter().zip(neck).collect();
        let head = posture(&m, &pairs);
        let q = eyes.aim(&head, &target).unwrap();
        // Only the parallax between the camera and the eyes is left (a few degrees).
        assert!(q.iter().all(|v| v.abs() < 0.12), "{q:?}");
        let off = eyes.off_axis_rad(&with(head, &eyes, q), &target).unwrap();
        assert!(off[0] < 1e-6 && off[1] < 1e-4, "{off:?}");
    }

    #[test]
    fn a_target_beyond_the_eyes_range_gets_them_to_their_limit_and_missing_joints_are_named() {
        let m = loki();
        let eyes = Eyes::from_model(&m).unwrap();
        let head = posture(&m, &[]);
        // Far to the left, beside the robot: past the eyes' 0.7 rad pan.
        let q = eyes.aim(&head, &Vector3::new(0.1, 1.0, 0.5)).unwrap();
        assert!(
            (q[1] - 0.7).abs() < 1e-9 && (q[2] - 0.7).abs() < 1e-9,
            "{q:?}"
        );
        // Behind: aimed as well as the limits let, never out of them.
        let q = eyes.aim(&head, &Vector3::new(-1.0, 0.0, 0.5)).unwrap();
        assert!(
            q[0].abs() <= 0.6 && q[1].abs() <= 0.7 && q[2].abs() <= 0.7,
            "{q:?}"
        );
        let mut no_eyes = head.clone();
        no_eyes.remove("right_eye_pan");
        assert_eq!(
            eyes.aim(&no_eyes, &Vector3::new(1.0, 0.0, 0.5)),
            Err("right_eye_pan".to_owned())
        );
    }
}
