//! The one driver trait, goal validation shared by all drivers, and choosing a driver by name.

use crate::error::{JointError, LimitKind};
use crate::types::{JointCommand, JointSpec, JointState, JointTarget, LinkStats};

/// A set of joints that can be commanded and read.
///
/// Drivers know nothing about clients or ownership (that is [`crate::JointMotor`]'s job); they
/// refuse targets for unknown joints or beyond the [`JointSpec`] limits with a typed error, never
/// clamping, and accept a list of targets all-or-nothing. `now_s` is the caller's clock (s), which
/// must not go backwards.
pub trait JointDriver: Send {
    /// The driver's name as used to choose it (`sim`, `dynamixel`).
    fn name(&self) -> &'static str;
    /// The joints this driver moves, in the order [`JointDriver::read_state`] reports them.
    fn joints(&self) -> &[JointSpec];
    /// Applies the targets (all or none) at time `now_s`.
    fn command(&mut self, targets: &[JointTarget], now_s: f64) -> Result<(), JointError>;
    /// The joints' states at time `now_s` (owner left `None`), one per [`JointDriver::joints`].
    fn read_state(&mut self, now_s: f64) -> Result<Vec<JointState>, JointError>;
    /// Bus health counters (all zero for drivers without a bus).
    fn link_stats(&self) -> LinkStats {
        LinkStats::default()
    }
    /// The driver's own event counters since it opened, as `(name, total)` (the component
    /// publishes them on `diagnostics`): e.g. the neck's goals clamped into its reach.
    fn counters(&self) -> Vec<(&'static str, u64)> {
        Vec::new()
    }
    /// What happened since the last call that a person should read in the log (the component
    /// logs each line, paced).
    fn take_warnings(&mut self) -> Vec<String> {
        Vec::new()
    }
}

/// A target checked against its joint's spec: the joint's index and the command.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CheckedTarget {
    pub index: usize,
    pub command: JointCommand,
}

/// Checks targets against the specs: known joints, each at most once, finite values, positions
/// within `[lower, upper]`, speeds within `(0, max_velocity]`. Returns the first problem found.
pub fn check_targets(
    specs: &[JointSpec],
    targets: &[JointTarget],
) -> Result<Vec<CheckedTarget>, JointError> {
    let mut out: Vec<CheckedTarget> = Vec::with_capacity(targets.len());
    for t in targets {
        let index = specs
            .iter()
            .position(|s| s.name == t.joint)
            .ok_or_else(|| JointError::UnknownJoint(t.joint.clone()))?;
        if out.iter().any(|c| c.index == index) {
            return Err(JointError::DuplicateTarget {
                joint: t.joint.clone(),
            });
        }
        let spec = &specs[index];
        let invalid = |what: &'static str, value: f64| JointError::InvalidValue {
            joint: spec.name.clone(),
            what,
            value,
        };
        let beyond = |limit: LimitKind, limit_value: f64, requested: f64| JointError::OutOfLimits {
            joint: spec.name.clone(),
            limit,
            limit_value,
            requested,
        };
        match t.command {
            JointCommand::Position {
                position,
                max_speed,
            } => {
                if !position.is_finite() {
                    return Err(invalid("position", position));
                }
                if position < spec.lower {
                    return Err(beyond(LimitKind::Lower, spec.lower, position));
                }
                if position > spec.upper {
                    return Err(beyond(LimitKind::Upper, spec.upper, position));
                }
                if !(max_speed.is_finite() && max_speed > 0.0) {
                    return Err(invalid("max_speed", max_speed));
                }
                if max_speed > spec.max_velocity {
                    return Err(beyond(LimitKind::MaxVelocity, spec.max_velocity, max_speed));
                }
            }
            JointCommand::Velocity { velocity } => {
                if !velocity.is_finite() {
                    return Err(invalid("velocity", velocity));
                }
                if velocity.abs() > spec.max_velocity {
                    return Err(beyond(LimitKind::MaxVelocity, spec.max_velocity, velocity));
                }
            }
        }
        out.push(CheckedTarget {
            index,
            command: t.command,
        });
    }
    Ok(out)
}

/// Checks a joint list: unique non-empty names, `lower < upper`, positive finite limits.
pub fn check_specs(specs: &[JointSpec]) -> Result<(), JointError> {
    for (i, s) in specs.iter().enumerate() {
        let key = format!("joints.{}", s.name);
        if s.name.is_empty() {
            return Err(JointError::config(
                format!("joints[{i}]"),
                "empty joint name",
            ));
        }
        if specs[..i].iter().any(|o| o.name == s.name) {
            return Err(JointError::config(key, "joint named twice"));
        }
        if !(s.lower.is_finite() && s.upper.is_finite() && s.lower < s.upper) {
            return Err(JointError::config(key, "needs finite lower < upper"));
        }
        if !(s.max_velocity.is_finite() && s.max_velocity > 0.0) {
            return Err(JointError::config(
                key,
                "max_velocity must be finite and > 0",
            ));
        }
        if !(s.max_acceleration.is_finite() && s.max_acceleration > 0.0) {
            return Err(JointError::config(
                key,
                "max_acceleration must be finite and > 0",
            ));
        }
    }
    Ok(())
}

/// The drivers that can be chosen by name.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DriverKind {
    /// [`crate::sim::SimDriver`]: first-order joints with limits, no hardware.
    Sim,
    /// [`crate::dynamixel::DynamixelDriver`]: X-series servos, Protocol 2.0 over a serial port.
    Dynamixel,
}

impl std::str::FromStr for DriverKind {
    type Err = JointError;
    fn from_str(s: &str) -> Result<Self, JointError> {
        match s {
            "sim" => Ok(Self::Sim),
            "dynamixel" => Ok(Self::Dynamixel),
            other => Err(JointError::UnknownDriver(other.to_owned())),
        }
    }
}

/// Opens the driver called `name` (`sim` or `dynamixel`) for `joints`.
///
/// `config_toml` is the driver's configuration file text: for `sim` optional
/// ([`crate::sim::SimParams`]), for `dynamixel` required ([`crate::dynamixel::DynamixelConfig`],
/// whose `port` is opened as a serial line).
pub fn open_driver(
    name: &str,
    joints: Vec<JointSpec>,
    config_toml: Option<&str>,
) -> Result<Box<dyn JointDriver>, JointError> {
    match name.parse::<DriverKind>()? {
        DriverKind::Sim => {
            let params = match config_toml {
                Some(text) => crate::sim::SimParams::from_toml(text)?,
                None => crate::sim::SimParams::default(),
            };
            Ok(Box::new(crate::sim::SimDriver::new(joints, params)?))
        }
        DriverKind::Dynamixel => {
            let text = config_toml.ok_or_else(|| {
                JointError::config("dynamixel", "a configuration file is required")
            })?;
            let config = crate::dynamixel::DynamixelConfig::from_toml(text, &joints)?;
            let port = crate::dynamixel::SerialPort::open(&config.port, config.baud)?;
            Ok(Box::new(crate::dynamixel::DynamixelDriver::new(
                joints,
                config,
                Box::new(port),
            )?))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn specs() -> Vec<JointSpec> {
        vec![
            JointSpec::revolute("a", -1.0, 1.0, 2.0, 10.0),
            JointSpec::prismatic("b", 0.0, 0.05, 0.1, 1.0),
        ]
    }

    fn pos(joint: &str, position: f64, max_speed: f64) -> JointTarget {
        JointTarget {
            joint: joint.into(),
            command: JointCommand::Position {
                position,
                max_speed,
            },
        }
    }

    #[test]
    fn targets_beyond_limits_name_joint_and_limit() {
        let e = check_targets(&specs(), &[pos("a", 0.0, 1.0), pos("b", 0.06, 0.1)]).unwrap_err();
        assert_eq!(
            e,
            JointError::OutOfLimits {
                joint: "b".into(),
                limit: LimitKind::Upper,
                limit_value: 0.05,
                requested: 0.06
            }
        );
        assert!(e.to_string().contains("`b`") && e.to_string().contains("upper"));
        let e = check_targets(&specs(), &[pos("a", -1.5, 1.0)]).unwrap_err();
        assert!(matches!(
            e,
            JointError::OutOfLimits {
                limit: LimitKind::Lower,
                ..
            }
        ));
        let e = check_targets(&specs(), &[pos("a", 0.0, 2.5)]).unwrap_err();
        assert!(matches!(
            e,
            JointError::OutOfLimits {
                limit: LimitKind::MaxVelocity,
                ..
            }
        ));
        let v = JointTarget {
            joint: "a".into(),
            command: JointCommand::Velocity { velocity: -2.1 },
        };
        assert!(check_targets(&specs(), &[v]).is_err());
    }

    #[test]
    fn unknown_duplicate_and_nan_targets_refused() {
        assert_eq!(
            check_targets(&specs(), &[pos("zz", 0.0, 1.0)]),
            Err(JointError::UnknownJoint("zz".into()))
        );
        assert!(matches!(
            check_targets(&specs(), &[pos("a", 0.0, 1.0), pos("a", 0.1, 1.0)]),
            Err(JointError::DuplicateTarget { .. })
        ));
        assert!(matches!(
            check_targets(&specs(), &[pos("a", f64::NAN, 1.0)]),
            Err(JointError::InvalidValue { .. })
        ));
        assert!(matches!(
            check_targets(&specs(), &[pos("a", 0.0, 0.0)]),
            Err(JointError::InvalidValue { .. })
        ));
        assert_eq!(
            check_targets(&specs(), &[pos("b", 0.05, 0.1)])
                .unwrap()
                .len(),
            1
        );
    }

    #[test]
    fn drivers_chosen_by_name() {
        assert_eq!("sim".parse::<DriverKind>(), Ok(DriverKind::Sim));
        assert_eq!("dynamixel".parse::<DriverKind>(), Ok(DriverKind::Dynamixel));
        assert!(matches!(
            open_driver("schunk", specs(), None),
            Err(JointError::UnknownDriver(_))
        ));
        let d = open_driver("sim", specs(), None).unwrap();
        assert_eq!(d.name(), "sim");
        assert_eq!(d.joints().len(), 2);
        assert!(matches!(
            open_driver("dynamixel", specs(), None),
            Err(JointError::Config { .. })
        ));
    }

    #[test]
    fn bad_specs_refused() {
        let mut s = specs();
        s[1].lower = 0.1;
        assert!(check_specs(&s).is_err());
        let mut s = specs();
        s[1].name = "a".into();
        assert!(check_specs(&s).is_err());
        assert!(check_specs(&specs()).is_ok());
    }
}
