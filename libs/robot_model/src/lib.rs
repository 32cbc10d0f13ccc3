//! # robot_model: robot models from URDF, kinematic chains, forward kinematics and geometric Jacobians
//!
//! Not a process: the deep representation, the IK, the joint motors, the camera and the viewer
//! share it. [`find_model`] locates a model file of the repository's `models/` folder.
//!
//! # Conventions
//! - Units: metres, radians, m/s and rad/s, as in URDF.
//! - A joint's transform is `parent_T_child(q) = origin * motion(q)`, where `origin` is the URDF
//!   `<origin xyz rpy>` (rpy = fixed-axis roll about x, then pitch about y, then yaw about z, i.e.
//!   `R = Rz(yaw) * Ry(pitch) * Rx(roll)`), and `motion(q)` is a rotation of `q` rad about the
//!   joint axis (revolute, continuous) or a translation of `q` m along it (prismatic).
//! - A [`Chain`] runs from a root link to a tip link that descends from it. Fixed joints in between
//!   are folded into the next movable joint's precomputed origin (`pre`) or into the chain's `tail`,
//!   so FK costs one isometry product per movable joint plus one for the tail, and allocates nothing.
//! - [`Chain::fk`] returns `root_T_tip`. [`Chain::jacobian`] is the geometric Jacobian expressed in
//!   the root frame, 6 rows: linear velocity of the tip origin (rows 0..3, m/s per unit joint speed)
//!   then angular velocity (rows 3..6, rad/s), one column per movable joint in chain order.
//!
//! # Named body parts
//! [`BodyPart`] names the chains that the IK and gaze controllers use on Loki (`models/loki.urdf`):
//!
//! | name | root | tip | joints |
//! |---|---|---|---|
//! | `left_arm_4`, `right_arm_4` | `torso` | `{side}_wrist_center` | shoulder pitch/roll/yaw, elbow |
//! | `left_arm_7`, `right_arm_7` | `torso` | `{side}_hand_center` | + forearm roll, wrist pitch/roll |
//! | `left_arm_9`, `right_arm_9` | `base_footprint` | `{side}_hand_center` | base yaw and base forward + the 7 |
//! | `left_arm_11`, `right_arm_11` | `torso` | `{side}_fingertip` | + the 4 finger joints |
//! | `left_arm_13`, `right_arm_13` | `base_footprint` | `{side}_fingertip` | + base yaw and base forward |
//! | `left_arm`, `right_arm` | = `{side}_arm_7` (the reaching arm of "touch the ball") | | |
//! | `neck` | `torso` | `head_rgbd_optical_frame` | neck rotation, pitch, roll, yaw |
//! | `head` | `torso` | `head` | the same 4 neck joints, tip at the head link |
//! | `left_eye`, `right_eye` | `head` | `{side}_eye_optical_frame` | eyes tilt, eye pan |
//! | `base` | `base_footprint` | `base_link` | base yaw, base forward |

use std::collections::HashMap;
use std::path::Path;

use nalgebra::{Isometry3, Matrix6xX, Translation3, Unit, UnitQuaternion, Vector3};

use std::path::PathBuf;
use thiserror::Error;

mod chain;
pub use chain::*;
mod urdf;
use urdf::*;

/// Errors of robot models: reading and checking a URDF, chains, joint vectors.
#[derive(Debug, Error)]
pub enum ModelError {
    /// The URDF text could not be parsed (bad XML, missing required attributes, bad numbers).
    #[error("malformed URDF: {0}")]
    MalformedUrdf(String),
    /// The URDF parsed but is not a tree (no single root, a link with two parents, a joint that
    /// names an undeclared link, an unsupported joint type, a zero axis).
    #[error("invalid URDF model: {0}")]
    InvalidModel(String),
    /// A model file could not be read.
    #[error("cannot read {path}: {source}")]
    Io {
        /// The path that was read.
        path: String,
        /// The cause.
        source: std::io::Error,
    },
    /// A link name that is not in the model.
    #[error("unknown frame `{0}`")]
    UnknownFrame(String),
    /// A joint name that is not in the model.
    #[error("unknown joint `{0}`")]
    UnknownJoint(String),
    /// A body part name that is not one of the documented names (see [`BodyPart`]).
    #[error("unknown body part `{0}` (known: {1})")]
    UnknownBodyPart(String, String),
    /// `root` is not an ancestor of `tip`, so there is no open chain from one to the other.
    #[error("no kinematic chain from `{root}` to `{tip}`: `{root}` is not an ancestor of `{tip}`")]
    NotAChain {
        /// Chain root link.
        root: String,
        /// Chain tip link.
        tip: String,
    },
    /// A joint vector has the wrong length for the chain.
    #[error("joint vector has {got} values, the chain has {expected} joints")]
    JointCount {
        /// Joints in the chain.
        expected: usize,
        /// Values passed.
        got: usize,
    },
    /// A joint value that is NaN or infinite.
    #[error("joint `{0}`: value is not finite")]
    NonFiniteValue(String),
}

/// Result alias of the crate.
pub type Result<T, E = ModelError> = std::result::Result<T, E>;

/// Path of a model file (`loki.urdf`, `spl_field.toml`): `explicit` if given, else the first
/// `models/<file>` found walking up from the executable's folder, then from the working folder,
/// else the repository's `models/` as seen from this crate's sources.
pub fn find_model(explicit: Option<&Path>, file: &str) -> PathBuf {
    if let Some(p) = explicit {
        return p.to_path_buf();
    }
    let starts = [
        std::env::current_exe()
            .ok()
            .and_then(|e| e.parent().map(Path::to_path_buf)),
        std::env::current_dir().ok(),
    ];
    for start in starts.into_iter().flatten() {
        for dir in start.ancestors() {
            let p = dir.join("models").join(file);
            if p.is_file() {
                return p;
            }
        }
    }
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../..")
        .join("models")
        .join(file)
}

/// Joint kinds and limits, cameras and collision shapes: the bus' own types (`interfaces::msg::dr`),
/// which the deep representation holds as they are.
pub use interfaces::msg::dr::{
    CameraIntrinsics, CollisionShape, JointKind, JointLimits, Shape, Transform,
};

/// A [`Transform`] (the bus' rigid transform) to and from a nalgebra isometry.
pub trait TransformIso {
    /// From an isometry.
    fn from_iso(iso: &Isometry3<f64>) -> Self;
    /// As an isometry, the quaternion normalised. Check [`Transform::is_valid`] first: a zero
    /// quaternion gives NaN.
    fn to_iso(&self) -> Isometry3<f64>;
}

impl TransformIso for Transform {
    fn from_iso(iso: &Isometry3<f64>) -> Self {
        let q = iso.rotation.coords;
        let t = iso.translation.vector;
        Transform {
            translation_m: [t.x, t.y, t.z],
            rotation_xyzw: [q.x, q.y, q.z, q.w],
        }
    }

    fn to_iso(&self) -> Isometry3<f64> {
        let [x, y, z, w] = self.rotation_xyzw;
        let [tx, ty, tz] = self.translation_m;
        Isometry3::from_parts(
            Translation3::new(tx, ty, tz),
            UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(w, x, y, z)),
        )
    }
}

/// The joint motion `motion(q)` for a joint kind and unit axis.
#[inline]
pub fn joint_motion(kind: JointKind, axis: &Unit<Vector3<f64>>, q: f64) -> Isometry3<f64> {
    match kind {
        JointKind::Revolute | JointKind::Continuous => Isometry3::from_parts(
            Translation3::identity(),
            UnitQuaternion::from_axis_angle(axis, q),
        ),
        JointKind::Prismatic => Isometry3::from_parts(
            Translation3::from(axis.into_inner() * q),
            UnitQuaternion::identity(),
        ),
        JointKind::Fixed => Isometry3::identity(),
    }
}

/// A link of a robot model.
#[derive(Debug, Clone)]
pub struct LinkModel {
    /// Link name.
    pub name: String,
    /// Index (into [`RobotModel::joints`]) of the joint whose child this link is; `None` for the root.
    pub parent_joint: Option<usize>,
    /// Collision elements.
    pub collision: Vec<CollisionShape>,
}

/// A joint of a robot model.
#[derive(Debug, Clone)]
pub struct JointModel {
    /// Joint name.
    pub name: String,
    /// Kind.
    pub kind: JointKind,
    /// Parent link index.
    pub parent: usize,
    /// Child link index.
    pub child: usize,
    /// Fixed `parent_T_jointframe` from the URDF `<origin>`.
    pub origin: Isometry3<f64>,
    /// Unit axis in the joint frame.
    pub axis: Unit<Vector3<f64>>,
    /// Limits (infinite position limits for continuous and fixed joints).
    pub limits: JointLimits,
}

impl JointModel {
    /// `parent_T_child` for joint value `q` (rad or m).
    #[inline]
    pub fn transform(&self, q: f64) -> Isometry3<f64> {
        self.origin * joint_motion(self.kind, &self.axis, q)
    }
}

/// A neck built as a Stewart platform, from the URDF's `<robocog_stewart_neck>` element: the
/// head turns about a central pivot, moved by three prismatic legs. The URDF models the neck as
/// three virtual revolute joints (`pitch`, `roll`, `yaw`); the legs are the actuators, not joints
/// of the tree. `joint_motor::stewart` has the geometry (anchor circles, twist) and the
/// kinematics. Lengths in m, angles in rad, speeds in m/s.
#[derive(Debug, Clone, PartialEq)]
pub struct StewartNeckSpec {
    /// The virtual joints the platform's pose is read as.
    pub pitch: String,
    pub roll: String,
    pub yaw: String,
    /// The legs' names (anchors at 90°, 210°, 330° on the base circle).
    pub legs: [String; 3],
    pub base_radius_m: f64,
    pub platform_radius_m: f64,
    /// Height of the central pivot above the base plate.
    pub pivot_height_m: f64,
    /// Angular offset of the platform anchors from the base anchors (the attribute is in
    /// degrees, `twist_deg`).
    pub twist_rad: f64,
    /// The legs' stroke.
    pub min_length_m: f64,
    pub max_length_m: f64,
    /// The legs' top speed.
    pub leg_velocity_m_s: f64,
}

/// A robot model: links, joints, cameras, loaded from URDF.
#[derive(Debug, Clone)]
pub struct RobotModel {
    /// Robot name (the URDF `<robot name>`).
    pub name: String,
    /// Links; index 0 is not necessarily the root (see [`RobotModel::root`]).
    pub links: Vec<LinkModel>,
    /// Joints in URDF order.
    pub joints: Vec<JointModel>,
    /// Index of the root link.
    pub root: usize,
    /// Cameras declared with `<robocog_camera>` elements.
    pub cameras: Vec<CameraIntrinsics>,
    /// The neck's Stewart platform, declared with a `<robocog_stewart_neck>` element (none: the
    /// neck's joints are ideal joints).
    pub stewart_neck: Option<StewartNeckSpec>,
    link_index: HashMap<String, usize>,
    joint_index: HashMap<String, usize>,
}

impl RobotModel {
    /// Loads a model from a URDF file.
    pub fn from_urdf_file(path: impl AsRef<Path>) -> Result<Self> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| ModelError::Io {
            path: path.display().to_string(),
            source,
        })?;
        Self::from_urdf_str(&text)
    }

    /// Loads a model from URDF text.
    ///
    /// Errors: [`ModelError::MalformedUrdf`] if urdf-rs cannot parse it, [`ModelError::InvalidModel`] if
    /// it is not a single tree of known links with supported joints.
    pub fn from_urdf_str(text: &str) -> Result<Self> {
        let robot = urdf_rs::read_from_string(text).map_err(|e| match xml_syntax_error(text) {
            Some(xml) => ModelError::MalformedUrdf(format!("XML error at {xml} ({e})")),
            None => ModelError::MalformedUrdf(e.to_string()),
        })?;
        let mut links = Vec::with_capacity(robot.links.len());
        let mut link_index = HashMap::new();
        for l in &robot.links {
            if link_index.insert(l.name.clone(), links.len()).is_some() {
                return Err(ModelError::InvalidModel(format!(
                    "duplicate link `{}`",
                    l.name
                )));
            }
            links.push(LinkModel {
                name: l.name.clone(),
                parent_joint: None,
                collision: l
                    .collision
                    .iter()
                    .map(|c| CollisionShape {
                        origin: Transform::from_iso(&pose_to_iso(&c.origin)),
                        shape: convert_geometry(&c.geometry),
                    })
                    .collect(),
            });
        }
        if links.is_empty() {
            return Err(ModelError::InvalidModel("the robot has no links".into()));
        }
        let mut joints = Vec::with_capacity(robot.joints.len());
        let mut joint_index = HashMap::new();
        for j in &robot.joints {
            let kind = match j.joint_type {
                urdf_rs::JointType::Revolute => JointKind::Revolute,
                urdf_rs::JointType::Continuous => JointKind::Continuous,
                urdf_rs::JointType::Prismatic => JointKind::Prismatic,
                urdf_rs::JointType::Fixed => JointKind::Fixed,
                ref other => {
                    return Err(ModelError::InvalidModel(format!(
                        "joint `{}`: unsupported type {other:?}",
                        j.name
                    )));
                }
            };
            let find = |name: &str, role: &str| {
                link_index.get(name).copied().ok_or_else(|| {
                    ModelError::InvalidModel(format!(
                        "joint `{}`: {role} link `{name}` is not declared",
                        j.name
                    ))
                })
            };
            let parent = find(&j.parent.link, "parent")?;
            let child = find(&j.child.link, "child")?;
            let axis_v = Vector3::new(j.axis.xyz[0], j.axis.xyz[1], j.axis.xyz[2]);
            let axis = if kind.is_movable() {
                Unit::try_new(axis_v, 1e-12).ok_or_else(|| {
                    ModelError::InvalidModel(format!("joint `{}`: zero axis", j.name))
                })?
            } else {
                Vector3::x_axis()
            };
            let limits = match kind {
                JointKind::Revolute | JointKind::Prismatic => {
                    let l = &j.limit;
                    let ordered = l.lower <= l.upper && l.velocity > 0.0;
                    if !ordered {
                        return Err(ModelError::InvalidModel(format!(
                            "joint `{}`: limits need lower <= upper and velocity > 0 (got {}..{}, {})",
                            j.name, l.lower, l.upper, l.velocity
                        )));
                    }
                    JointLimits {
                        lower: l.lower,
                        upper: l.upper,
                        velocity: l.velocity,
                        effort: l.effort,
                    }
                }
                JointKind::Continuous => JointLimits {
                    lower: f64::NEG_INFINITY,
                    upper: f64::INFINITY,
                    velocity: if j.limit.velocity > 0.0 {
                        j.limit.velocity
                    } else {
                        f64::INFINITY
                    },
                    effort: j.limit.effort,
                },
                JointKind::Fixed => JointLimits {
                    lower: 0.0,
                    upper: 0.0,
                    velocity: 0.0,
                    effort: 0.0,
                },
            };
            if links[child].parent_joint.is_some() {
                return Err(ModelError::InvalidModel(format!(
                    "link `{}` has two parent joints",
                    j.child.link
                )));
            }
            links[child].parent_joint = Some(joints.len());
            if joint_index.insert(j.name.clone(), joints.len()).is_some() {
                return Err(ModelError::InvalidModel(format!(
                    "duplicate joint `{}`",
                    j.name
                )));
            }
            joints.push(JointModel {
                name: j.name.clone(),
                kind,
                parent,
                child,
                origin: pose_to_iso(&j.origin),
                axis,
                limits,
            });
        }
        let roots: Vec<usize> = (0..links.len())
            .filter(|i| links[*i].parent_joint.is_none())
            .collect();
        let root = match roots.as_slice() {
            [r] => *r,
            [] => {
                return Err(ModelError::InvalidModel(
                    "no root link (the joints form a cycle)".into(),
                ));
            }
            many => {
                return Err(ModelError::InvalidModel(format!(
                    "{} root links ({}); a robot must be one tree",
                    many.len(),
                    many.iter()
                        .map(|i| links[*i].name.as_str())
                        .collect::<Vec<_>>()
                        .join(", ")
                )));
            }
        };
        // Every link must reach the root (detects cycles disconnected from the root).
        for start in 0..links.len() {
            let mut cur = start;
            let mut steps = 0;
            while let Some(j) = links[cur].parent_joint {
                cur = joints[j].parent;
                steps += 1;
                if steps > links.len() {
                    return Err(ModelError::InvalidModel(format!(
                        "link `{}` is in a cycle of joints",
                        links[start].name
                    )));
                }
            }
        }
        let cameras = parse_cameras(text)?;
        for c in &cameras {
            if !link_index.contains_key(&c.frame) {
                return Err(ModelError::InvalidModel(format!(
                    "camera `{}`: frame `{}` is not a link",
                    c.name, c.frame
                )));
            }
        }
        let stewart_neck = parse_stewart_neck(text, &joints)?;
        Ok(Self {
            name: robot.name,
            links,
            joints,
            root,
            cameras,
            stewart_neck,
            link_index,
            joint_index,
        })
    }

    /// The root link.
    pub fn root_link(&self) -> &LinkModel {
        &self.links[self.root]
    }

    /// Index of a link by name.
    pub fn link_index(&self, name: &str) -> Result<usize> {
        self.link_index
            .get(name)
            .copied()
            .ok_or_else(|| ModelError::UnknownFrame(name.to_string()))
    }

    /// A link by name.
    pub fn link(&self, name: &str) -> Result<&LinkModel> {
        Ok(&self.links[self.link_index(name)?])
    }

    /// A joint by name.
    pub fn joint(&self, name: &str) -> Result<&JointModel> {
        self.joint_index
            .get(name)
            .map(|i| &self.joints[*i])
            .ok_or_else(|| ModelError::UnknownJoint(name.to_string()))
    }

    /// Names of the movable joints, in URDF order.
    pub fn movable_joint_names(&self) -> Vec<&str> {
        self.joints
            .iter()
            .filter(|j| j.kind.is_movable())
            .map(|j| j.name.as_str())
            .collect()
    }

    /// Narrows a movable joint's position range to `[lower, upper]`, which must lie inside the
    /// URDF's limits: what a component lets itself use of a joint (a short move of the base, say),
    /// not what the joint can do. Chains made after this have the narrowed limits.
    ///
    /// Errors: an unknown or fixed joint ([`ModelError::UnknownJoint`]), a range that is not
    /// finite, empty or outside the URDF's ([`ModelError::InvalidModel`]).
    pub fn narrow_limits(&mut self, joint: &str, lower: f64, upper: f64) -> Result<()> {
        let i = *self
            .joint_index
            .get(joint)
            .ok_or_else(|| ModelError::UnknownJoint(joint.to_string()))?;
        let j = &mut self.joints[i];
        if !j.kind.is_movable() {
            return Err(ModelError::UnknownJoint(format!("{joint} (a fixed joint)")));
        }
        let (lo, hi) = (j.limits.lower, j.limits.upper);
        if !(lower.is_finite() && upper.is_finite() && lower <= upper) {
            return Err(ModelError::InvalidModel(format!(
                "joint `{joint}`: the range [{lower}, {upper}] is not a finite, non-empty range"
            )));
        }
        if lower < lo || upper > hi {
            return Err(ModelError::InvalidModel(format!(
                "joint `{joint}`: the range [{lower}, {upper}] is outside its limits [{lo}, {hi}]"
            )));
        }
        j.limits.lower = lower;
        j.limits.upper = upper;
        Ok(())
    }

    /// A camera by name.
    pub fn camera(&self, name: &str) -> Option<&CameraIntrinsics> {
        self.cameras.iter().find(|c| c.name == name)
    }

    /// The chain from link `root` down to link `tip`.
    ///
    /// Errors: unknown link names ([`ModelError::UnknownFrame`]), or `root` not an ancestor of `tip`
    /// ([`ModelError::NotAChain`]). `root == tip` gives an empty chain (identity).
    pub fn chain(&self, root: &str, tip: &str) -> Result<Chain> {
        let r = self.link_index(root)?;
        let t = self.link_index(tip)?;
        let mut path = Vec::new();
        let mut cur = t;
        while cur != r {
            match self.links[cur].parent_joint {
                Some(j) => {
                    path.push(j);
                    cur = self.joints[j].parent;
                }
                None => {
                    return Err(ModelError::NotAChain {
                        root: root.into(),
                        tip: tip.into(),
                    });
                }
            }
        }
        path.reverse();
        let mut joints = Vec::new();
        let mut acc = Isometry3::identity();
        for j in path {
            let jm = &self.joints[j];
            acc *= jm.origin;
            if jm.kind.is_movable() {
                joints.push(ChainJoint {
                    name: jm.name.clone(),
                    kind: jm.kind,
                    pre: acc,
                    axis: jm.axis,
                    limits: jm.limits,
                });
                acc = Isometry3::identity();
            }
        }
        Ok(Chain {
            root: root.into(),
            tip: tip.into(),
            joints,
            tail: acc,
        })
    }

    /// The chain of a named body part (see [`BODY_PARTS`]).
    pub fn body_part(&self, name: &str) -> Result<Chain> {
        let part = BodyPart::find(name)?;
        self.chain(part.root, part.tip)
    }
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

    #[test]
    fn loki_has_31_movable_joints_and_collision_everywhere() {
        let m = loki();
        assert_eq!(m.name, "loki");
        assert_eq!(m.movable_joint_names().len(), 31);
        assert_eq!(m.root_link().name, "base_footprint");
        for l in &m.links {
            assert!(!l.collision.is_empty(), "link {} has no collision", l.name);
        }
        for j in m.joints.iter().filter(|j| j.kind.is_movable()) {
            assert!(
                j.limits.velocity > 0.0 && j.limits.lower < j.limits.upper,
                "{}",
                j.name
            );
        }
    }

    #[test]
    fn a_narrowed_joint_range_reaches_the_chains_and_bad_ranges_are_refused() {
        let mut m = loki();
        m.narrow_limits("base_forward", 0.0, 0.2).unwrap();
        let c = m.body_part("left_arm_13").unwrap();
        let l = c
            .joints
            .iter()
            .find(|j| j.name == "base_forward")
            .unwrap()
            .limits;
        assert_eq!((l.lower, l.upper), (0.0, 0.2));
        for (joint, lo, hi, why) in [
            ("base_forward", -3.0, 0.1, "outside its limits"),
            ("base_forward", 0.2, 0.1, "non-empty"),
            ("base_forward", f64::NAN, 0.1, "finite"),
            ("no_such_joint", 0.0, 0.1, "unknown joint"),
            ("torso_fixed", 0.0, 0.1, "fixed joint"),
        ] {
            let e = m.narrow_limits(joint, lo, hi).unwrap_err().to_string();
            assert!(e.contains(why), "{joint} [{lo}, {hi}]: {e}");
        }
    }

    #[test]
    fn body_parts_have_documented_dof() {
        let m = loki();
        for part in BODY_PARTS {
            let c = m.body_part(part.name).unwrap();
            assert_eq!(c.dof(), part.dof, "{}", part.name);
        }
        let c = m.body_part("left_arm_13").unwrap();
        assert_eq!(c.joint_names()[..2], ["base_yaw", "base_forward"]);
        assert_eq!(c.joint_names()[12], "left_finger_distal_joint");
    }

    #[test]
    fn camera_intrinsics_are_read_from_custom_element() {
        let m = loki();
        let c = m.camera("head_rgbd").unwrap();
        assert_eq!((c.width, c.height), (640, 480));
        assert_eq!((c.fx, c.fy, c.cx, c.cy), (525.0, 525.0, 319.5, 239.5));
        assert_eq!(c.frame, "head_rgbd_optical_frame");
        // A point 1 m straight ahead projects onto the principal point.
        assert_eq!(c.project([0.0, 0.0, 1.0]), Some((319.5, 239.5)));
        assert!(c.sees([0.0, 0.0, 1.0]));
        assert!(!c.sees([0.0, 0.0, 0.2]), "closer than min range");
        assert!(!c.sees([1.0, 0.0, 1.0]), "u = 844.5 is outside 640 px");
    }

    #[test]
    fn jacobian_matches_finite_differences() {
        let m = loki();
        for part in ["left_arm_13", "neck", "right_arm_7"] {
            let c = m.body_part(part).unwrap();
            let q: Vec<f64> = (0..c.dof()).map(|i| 0.1 + 0.07 * i as f64).collect();
            let (tip, jac) = c.jacobian(&q).unwrap();
            let h = 1e-6;
            for i in 0..c.dof() {
                let mut qp = q.clone();
                qp[i] += h;
                let tp = c.fk(&qp).unwrap();
                let dp = (tp.translation.vector - tip.translation.vector) / h;
                let dr = (tp.rotation * tip.rotation.inverse()).scaled_axis() / h;
                for k in 0..3 {
                    assert!((jac[(k, i)] - dp[k]).abs() < 1e-5, "{part} lin col {i}");
                    assert!((jac[(k + 3, i)] - dr[k]).abs() < 1e-5, "{part} ang col {i}");
                }
            }
        }
    }

    #[test]
    fn bad_inputs_give_typed_errors() {
        let m = loki();
        assert!(
            matches!(m.chain("torso", "no_such_link"), Err(ModelError::UnknownFrame(n)) if n == "no_such_link")
        );
        assert!(matches!(
            m.chain("left_hand", "torso"),
            Err(ModelError::NotAChain { .. })
        ));
        assert!(matches!(
            m.joint("left_knee"),
            Err(ModelError::UnknownJoint(_))
        ));
        assert!(matches!(
            m.body_part("tail"),
            Err(ModelError::UnknownBodyPart(..))
        ));
        let c = m.body_part("left_arm_4").unwrap();
        assert!(matches!(
            c.fk(&[0.0; 3]),
            Err(ModelError::JointCount {
                expected: 4,
                got: 3
            })
        ));
        assert!(matches!(
            c.fk(&[0.0, f64::NAN, 0.0, 0.0]),
            Err(ModelError::NonFiniteValue(_))
        ));
    }

    #[test]
    fn malformed_and_invalid_urdf_are_rejected() {
        let e = RobotModel::from_urdf_str("<robot name='x'>\n<link name='a'>").unwrap_err();
        assert!(matches!(e, ModelError::MalformedUrdf(_)), "{e}");
        assert!(e.to_string().contains("XML error at 2:"), "{e}");
        let e = RobotModel::from_urdf_str("<robot name='x'><link name='a'/></robt>").unwrap_err();
        assert!(e.to_string().contains("XML error at 1:"), "{e}");
        // Well-formed XML that is not a valid URDF: urdf-rs's own message.
        let e =
            RobotModel::from_urdf_str("<robot name='x'><joint name='j' type='revolute'/></robot>")
                .unwrap_err();
        assert!(
            matches!(e, ModelError::MalformedUrdf(ref s) if !s.contains("XML error")),
            "{e}"
        );
        let e = RobotModel::from_urdf_str("not xml at all").unwrap_err();
        assert!(matches!(e, ModelError::MalformedUrdf(_)), "{e}");
        let dangling = r#"<robot name="x"><link name="a"/>
            <joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint></robot>"#;
        let e = RobotModel::from_urdf_str(dangling).unwrap_err();
        assert!(
            matches!(e, ModelError::InvalidModel(ref s) if s.contains("`b`")),
            "{e}"
        );
        let two_roots = r#"<robot name="x"><link name="a"/><link name="b"/></robot>"#;
        assert!(matches!(
            RobotModel::from_urdf_str(two_roots),
            Err(ModelError::InvalidModel(_))
        ));
        let bad_limits = r#"<robot name="x"><link name="a"/><link name="b"/>
            <joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
            <limit lower="1" upper="-1" velocity="1" effort="1"/></joint></robot>"#;
        assert!(matches!(
            RobotModel::from_urdf_str(bad_limits),
            Err(ModelError::InvalidModel(_))
        ));
        let bad_cam = r#"<robot name="x"><link name="a"/>
            <robocog_camera name="c" frame="nowhere" width="640" height="480" fx="1" fy="1" cx="0" cy="0" min_range_m="0" max_range_m="1"/></robot>"#;
        assert!(matches!(
            RobotModel::from_urdf_str(bad_cam),
            Err(ModelError::InvalidModel(_))
        ));
        let missing = RobotModel::from_urdf_file("/nonexistent/robot.urdf").unwrap_err();
        assert!(matches!(missing, ModelError::Io { .. }));
    }
}
