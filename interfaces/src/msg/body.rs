//! Loki's body on the bus: joint states and goals (`joint_motor`), and reach/gaze goals with their
//! outcome (`body_inverse_kinematics`). Seed 001 §V.A and §V.C.
//!
//! Conventions:
//! - Joints are named as in the URDF (`models/loki.urdf`). Revolute joints in rad, rad/s;
//!   prismatic joints in m, m/s.
//! - A **body part** is a named chain of the URDF (`left_arm_7`, `left_arm_11`, `left_arm_13`,
//!   `neck`, ...; `robot_model::BODY_PARTS`).
//! - Reach targets name a frame of the deep representation (`world`, `torso`, `ball`, ...): the
//!   IK component asks the DR for the target in the chain's root frame. A target that names a
//!   moving node (`ball`) can be **followed**: re-solved as the node moves.
//! - Orientations are unit quaternions `[x, y, z, w]`.

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// How one joint is commanded.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointMode {
    /// Go to `position` no faster than `max_speed`, then hold it.
    #[default]
    Position,
    /// Move at `velocity` until another goal (still stopping at the position limits).
    Velocity,
}

/// One joint's target inside a [`JointGoal`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointTarget {
    pub joint: String,
    pub mode: JointMode,
    /// Target position (rad or m), for [`JointMode::Position`].
    pub position: f64,
    /// Largest speed on the way (rad/s or m/s, > 0, at most the joint's maximum velocity), for
    /// [`JointMode::Position`].
    pub max_speed: f64,
    /// Velocity (rad/s or m/s), for [`JointMode::Velocity`].
    pub velocity: f64,
}

/// A goal from one client for some joints (service `body/joint_goal`). Accepted or refused as a
/// whole: see [`JointGoalReply`]. The ownership rule is the `joint_motor` crate's: an accepted goal
/// makes `client` the owner of its joints until it releases them or stays silent longer than the
/// lease; another client takes them only with a strictly higher priority.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointGoal {
    pub header: Header,
    /// Who sends it (e.g. the component name).
    pub client: String,
    /// Higher wins; equal priority never preempts.
    pub priority: u8,
    pub targets: Vec<JointTarget>,
    /// `true`: give the named joints back instead (empty `targets` = every joint `client` owns).
    pub release: bool,
}

/// Why a goal was refused.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum JointRefusal {
    /// Accepted.
    #[default]
    None,
    UnknownJoint,
    /// A position beyond the lower limit (`limit` is that limit).
    BelowLowerLimit,
    /// A position beyond the upper limit.
    AboveUpperLimit,
    /// A speed or velocity above the joint's maximum velocity.
    AboveMaxVelocity,
    /// Not finite, not positive, or a joint named twice.
    InvalidValue,
    /// Owned by another client of equal or higher priority (`owner` names it).
    Owned,
    /// The driver cannot do it (e.g. velocity mode on a position-only servo) or failed.
    Driver,
}

/// The reply to a [`JointGoal`].
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointGoalReply {
    pub header: Header,
    pub accepted: bool,
    pub refusal: JointRefusal,
    /// The joint the refusal is about.
    pub joint: String,
    /// The limit broken (rad, m, rad/s or m/s), when `refusal` is a limit.
    pub limit: f64,
    /// The value requested.
    pub requested: f64,
    /// The owner, for [`JointRefusal::Owned`].
    pub owner: String,
    /// Human-readable reason ("joint `left_elbow`: requested 0.3 is beyond its upper position
    /// limit 0"), empty when accepted.
    pub detail: String,
    /// Joints taken from a lower-priority owner by this goal.
    pub preempted: Vec<String>,
}

/// One joint's measured state.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct JointState {
    pub name: String,
    /// rad or m.
    pub position: f64,
    /// rad/s or m/s.
    pub velocity: f64,
    /// Whether `effort` was measured.
    pub has_effort: bool,
    /// N·m or N.
    pub effort: f64,
    /// The client that owns the joint now (empty: nobody).
    pub owner: String,
}

/// Every joint at one instant (topic `body/joint_states`, 100 Hz or more).
///
/// On the wire (`robocog_msgs/JointStates`): a `sensor_msgs/JointState` (its header is this
/// message's; `effort` is 0 where none was measured), then `driver`, and per joint whether its
/// effort was measured and its owner.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(remote = "Self")]
pub struct JointStates {
    pub header: Header,
    /// Which driver produced it (`sim`, `dynamixel`).
    pub driver: String,
    pub joints: Vec<JointState>,
}

/// [`JointStates`] on the wire.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
#[serde(rename = "JointStates")]
pub struct JointStatesWire {
    pub joint_state: crate::msg::ros::JointState,
    pub driver: String,
    pub has_effort: Vec<bool>,
    pub owner: Vec<String>,
}

impl From<&JointStates> for JointStatesWire {
    fn from(m: &JointStates) -> Self {
        let js = &m.joints;
        JointStatesWire {
            joint_state: crate::msg::ros::JointState {
                header: m.header.clone(),
                name: js.iter().map(|j| j.name.clone()).collect(),
                position: js.iter().map(|j| j.position).collect(),
                velocity: js.iter().map(|j| j.velocity).collect(),
                effort: js.iter().map(|j| j.effort).collect(),
            },
            driver: m.driver.clone(),
            has_effort: js.iter().map(|j| j.has_effort).collect(),
            owner: js.iter().map(|j| j.owner.clone()).collect(),
        }
    }
}

impl TryFrom<JointStatesWire> for JointStates {
    type Error = String;
    fn try_from(w: JointStatesWire) -> Result<Self, String> {
        let s = w.joint_state;
        let n = s.name.len();
        for (what, len) in [
            ("positions", s.position.len()),
            ("velocities", s.velocity.len()),
            ("efforts", s.effort.len()),
            ("effort flags", w.has_effort.len()),
            ("owners", w.owner.len()),
        ] {
            if len != n {
                return Err(format!("{len} {what} for {n} joints"));
            }
        }
        let mut joints = Vec::with_capacity(n);
        let rest = s.position.into_iter().zip(s.velocity).zip(s.effort);
        let flags = w.has_effort.into_iter().zip(w.owner);
        for ((name, ((position, velocity), effort)), (has_effort, owner)) in
            s.name.into_iter().zip(rest).zip(flags)
        {
            joints.push(JointState {
                name,
                position,
                velocity,
                has_effort,
                effort,
                owner,
            });
        }
        Ok(JointStates {
            header: s.header,
            driver: w.driver,
            joints,
        })
    }
}

crate::wire_form!(JointStates, JointStatesWire);

impl JointStates {
    /// The state of the joint called `name`.
    pub fn get(&self, name: &str) -> Option<&JointState> {
        self.joints.iter().find(|j| j.name == name)
    }
}

/// What a reach goal asks of the body part's tip.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReachKind {
    /// The tip at the target's origin, orientation free.
    #[default]
    Position,
    /// The tip frame at the target pose (`orientation_xyzw`).
    Pose,
    /// The tip's optical axis through the target (the virtual stick): neck and eyes.
    Gaze,
}

/// A goal for `body_inverse_kinematics` (topic `body/reach`): move a body part so its tip
/// reaches, or looks at, a target. A new goal for a body part replaces the previous one for that
/// part; `active = false` cancels it (the part holds where it is).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ReachGoal {
    pub header: Header,
    /// Caller-chosen id, echoed in every [`ReachStatus`] of this goal.
    pub id: u64,
    /// Who asks: logged with the goal. The joints are owned on `body/joint_goal` by the IK
    /// process per body part (`<ik component>/<body_part>`, e.g.
    /// `body_inverse_kinematics/left_arm_7`), whoever the client is.
    pub client: String,
    pub active: bool,
    /// Body part (`left_arm_7`, `neck`, ...).
    pub body_part: String,
    pub kind: ReachKind,
    /// The DR frame the target is given in (`world`, `torso`) or tracked by (`ball`).
    pub frame: String,
    /// Target position in `frame` (m); `[0, 0, 0]` with `frame = "ball"` is the ball's centre.
    #[serde(with = "crate::msg::ros::point")]
    pub position_m: [f64; 3],
    /// Target orientation in `frame`, for [`ReachKind::Pose`].
    #[serde(with = "crate::msg::ros::quaternion")]
    pub orientation_xyzw: [f64; 4],
    /// Position tolerance (m); 0 = the component's default.
    pub tolerance_m: f64,
    /// Keep re-solving as `frame` moves, until cancelled or replaced.
    pub follow: bool,
    /// How long the motion to the goal should take at least (s); 0 = the component's default.
    pub min_duration_s: f64,
}

/// Where a reach goal is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum ReachState {
    /// Solved; the joints are moving along the trajectory.
    #[default]
    Moving,
    /// The measured joints reached the solution within tolerance (once per solution; again after
    /// a followed target moved and was reached anew).
    Reached,
    /// No solution: `residual_m` is the best one's distance to the target.
    Unreachable,
    /// Replaced by a newer goal for the part, or cancelled.
    Cancelled,
    /// Could not run: unknown body part or frame, DR or joint_motor unavailable, joints refused
    /// (`detail` says which).
    Failed,
}

/// The outcome of a [`ReachGoal`] (topic `body/reach_status`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ReachStatus {
    pub header: Header,
    pub id: u64,
    pub body_part: String,
    pub state: ReachState,
    /// IK residual of the solution (or best attempt), m.
    pub residual_m: f64,
    /// Measured distance from the tip to the target now, m (`-1` when unknown).
    pub distance_m: f64,
    /// The target in `world` at the time of this status (m).
    #[serde(with = "crate::msg::ros::point")]
    pub target_world_m: [f64; 3],
    /// The tip in `world` at the time of this status (m).
    #[serde(with = "crate::msg::ros::point")]
    pub tip_world_m: [f64; 3],
    pub detail: String,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec;
    use crate::msg::Message;

    #[test]
    fn joint_states_go_as_a_sensor_msgs_joint_state_and_come_back_whole() {
        let m = JointStates {
            header: Header::new("base_link"),
            driver: "sim".into(),
            joints: vec![
                JointState {
                    name: "neck_yaw".into(),
                    position: 0.5,
                    velocity: -0.25,
                    has_effort: true,
                    effort: 1.5,
                    owner: "ik".into(),
                },
                JointState {
                    name: "left_elbow".into(),
                    position: -1.0,
                    ..Default::default()
                },
            ],
        };
        let bytes = codec::encode(&m, JointStates::TYPE_NAME).unwrap();
        let wire: JointStatesWire = codec::decode(&bytes, "wire").unwrap();
        assert_eq!(wire.joint_state.name, ["neck_yaw", "left_elbow"]);
        assert_eq!(wire.joint_state.position, [0.5, -1.0]);
        assert_eq!(wire.has_effort, [true, false]);
        assert_eq!(codec::decode::<JointStates>(&bytes, "js").unwrap(), m);
        // Arrays of other lengths than the names: an error that says so.
        let mut bad = wire;
        bad.owner.pop();
        let bytes = codec::encode(&bad, "wire").unwrap();
        let e = codec::decode::<JointStates>(&bytes, "js").unwrap_err();
        assert!(e.to_string().contains("1 owners for 2 joints"), "{e}");
        // JSON keeps robocog's form.
        let json = serde_json::to_value(&m).unwrap();
        assert_eq!(json["joints"][0]["owner"], "ik");
    }
}
