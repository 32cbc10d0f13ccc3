//! Where this crate's goal types meet the `body/joint_goal` service of `interfaces::msg::body`.
//!
//! The joint states are the bus message itself ([`interfaces::msg::body::JointStates`]); the
//! goal is checked and read into the library's [`JointGoal`] / [`JointRelease`] here (not a copy:
//! the checked form of the request, see [`JointGoal`]). A refused goal
//! becomes a [`JointGoalReply`] with a typed [`JointRefusal`], the joint, the limit, the value
//! requested and the owner, plus the library's human-readable message.

use interfaces::msg::body as m;
use interfaces::msg::body::{JointGoalReply, JointRefusal};

use crate::error::{JointError, LimitKind};
use crate::ownership::Preempted;
use crate::types::{JointCommand, JointGoal, JointRelease, JointTarget};

/// What a `body/joint_goal` request asks for.
#[derive(Debug, Clone, PartialEq)]
pub enum Request {
    /// Command joints.
    Goal(JointGoal),
    /// Give joints back.
    Release(JointRelease),
}

/// The library request for a goal message. A malformed message (no client, nothing to command)
/// is refused here with [`JointError::InvalidValue`].
pub fn request_from_msg(msg: &m::JointGoal) -> Result<Request, JointError> {
    if msg.client.is_empty() {
        return Err(JointError::InvalidValue {
            joint: String::new(),
            what: "client (must not be empty)",
            value: f64::NAN,
        });
    }
    if msg.release {
        return Ok(Request::Release(JointRelease {
            client: msg.client.clone(),
            joints: msg.targets.iter().map(|t| t.joint.clone()).collect(),
        }));
    }
    if msg.targets.is_empty() {
        return Err(JointError::InvalidValue {
            joint: String::new(),
            what: "targets (a goal needs at least one)",
            value: 0.0,
        });
    }
    Ok(Request::Goal(JointGoal {
        client: msg.client.clone(),
        priority: msg.priority,
        targets: msg
            .targets
            .iter()
            .map(|t| JointTarget {
                joint: t.joint.clone(),
                command: match t.mode {
                    m::JointMode::Position => JointCommand::Position {
                        position: t.position,
                        max_speed: t.max_speed,
                    },
                    m::JointMode::Velocity => JointCommand::Velocity {
                        velocity: t.velocity,
                    },
                },
            })
            .collect(),
    }))
}

/// The reply to an accepted goal.
pub fn accepted(preempted: &[Preempted]) -> JointGoalReply {
    JointGoalReply {
        accepted: true,
        preempted: preempted.iter().map(|p| p.joint.clone()).collect(),
        ..Default::default()
    }
}

/// The reply to a refused goal: the typed reason with its joint, limit, value and owner.
pub fn refused(e: &JointError) -> JointGoalReply {
    let mut r = JointGoalReply {
        accepted: false,
        refusal: refusal(e),
        detail: e.to_string(),
        ..Default::default()
    };
    match e {
        JointError::UnknownJoint(j) => r.joint = j.clone(),
        JointError::OutOfLimits {
            joint,
            limit_value,
            requested,
            ..
        } => {
            r.joint = joint.clone();
            r.limit = *limit_value;
            r.requested = *requested;
        }
        JointError::InvalidValue { joint, value, .. } => {
            r.joint = joint.clone();
            r.requested = *value;
        }
        JointError::DuplicateTarget { joint } => r.joint = joint.clone(),
        JointError::Owned { joint, owner, .. } => {
            r.joint = joint.clone();
            r.owner = owner.clone();
        }
        JointError::Unsupported { joint, .. } => r.joint = joint.clone(),
        _ => {}
    }
    r
}

/// The typed reason of a refusal.
pub fn refusal(e: &JointError) -> JointRefusal {
    match e {
        JointError::UnknownJoint(_) => JointRefusal::UnknownJoint,
        JointError::OutOfLimits { limit, .. } => match limit {
            LimitKind::Lower => JointRefusal::BelowLowerLimit,
            LimitKind::Upper => JointRefusal::AboveUpperLimit,
            LimitKind::MaxVelocity => JointRefusal::AboveMaxVelocity,
        },
        JointError::InvalidValue { .. } | JointError::DuplicateTarget { .. } => {
            JointRefusal::InvalidValue
        }
        JointError::Owned { .. } => JointRefusal::Owned,
        _ => JointRefusal::Driver,
    }
}

/// The diagnostics counter name for a refusal (`refused/<reason>`).
pub fn refusal_counter(r: JointRefusal) -> &'static str {
    match r {
        JointRefusal::None => "refused/none",
        JointRefusal::UnknownJoint => "refused/unknown_joint",
        JointRefusal::BelowLowerLimit => "refused/below_lower_limit",
        JointRefusal::AboveUpperLimit => "refused/above_upper_limit",
        JointRefusal::AboveMaxVelocity => "refused/above_max_velocity",
        JointRefusal::InvalidValue => "refused/invalid_value",
        JointRefusal::Owned => "refused/owned",
        JointRefusal::Driver => "refused/driver",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn target(joint: &str, position: f64) -> m::JointTarget {
        m::JointTarget {
            joint: joint.into(),
            mode: m::JointMode::Position,
            position,
            max_speed: 0.5,
            velocity: 0.0,
        }
    }

    #[test]
    fn goals_and_releases_convert() {
        let mut msg = m::JointGoal {
            client: "ik".into(),
            priority: 3,
            targets: vec![
                target("a", 0.2),
                m::JointTarget {
                    joint: "b".into(),
                    mode: m::JointMode::Velocity,
                    velocity: -0.1,
                    ..Default::default()
                },
            ],
            ..Default::default()
        };
        let Request::Goal(g) = request_from_msg(&msg).unwrap() else {
            panic!("not a goal")
        };
        assert_eq!(g.priority, 3);
        assert_eq!(
            g.targets[0].command,
            JointCommand::Position {
                position: 0.2,
                max_speed: 0.5
            }
        );
        assert_eq!(
            g.targets[1].command,
            JointCommand::Velocity { velocity: -0.1 }
        );
        msg.release = true;
        assert_eq!(
            request_from_msg(&msg).unwrap(),
            Request::Release(JointRelease {
                client: "ik".into(),
                joints: vec!["a".into(), "b".into()]
            })
        );
        msg.client.clear();
        assert!(request_from_msg(&msg).is_err());
        let empty = m::JointGoal {
            client: "x".into(),
            ..Default::default()
        };
        assert!(matches!(
            request_from_msg(&empty),
            Err(JointError::InvalidValue { .. })
        ));
    }

    #[test]
    fn refusals_name_joint_limit_value_and_owner() {
        let r = refused(&JointError::OutOfLimits {
            joint: "left_elbow".into(),
            limit: LimitKind::Upper,
            limit_value: 0.0,
            requested: 0.3,
        });
        assert!(!r.accepted);
        assert_eq!(r.refusal, JointRefusal::AboveUpperLimit);
        assert_eq!(
            (r.joint.as_str(), r.limit, r.requested),
            ("left_elbow", 0.0, 0.3)
        );
        assert!(
            r.detail.contains("left_elbow") && r.detail.contains("upper"),
            "{}",
            r.detail
        );
        let r = refused(&JointError::Owned {
            joint: "neck_yaw".into(),
            owner: "executive".into(),
            owner_priority: 5,
        });
        assert_eq!(r.refusal, JointRefusal::Owned);
        assert_eq!(r.owner, "executive");
        assert_eq!(
            refused(&JointError::Bus("x".into())).refusal,
            JointRefusal::Driver
        );
        assert_eq!(
            refusal_counter(refusal(&JointError::UnknownJoint("z".into()))),
            "refused/unknown_joint"
        );
    }
}
