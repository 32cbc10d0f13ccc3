//! The `dynamixel` driver's TOML configuration: the serial line and which servo moves which joint.
//!
//! ```toml
//! port = "/dev/ttyUSB0"     # serial device
//! baud = 57600              # 9600, 57600, 115200, 1000000, 2000000, 3000000 or 4000000
//! read_timeout_ms = 20      # wait for one status packet (1..=1000 ms)
//! retries = 3               # repeats after a missing or corrupt reply (0..=10)
//!
//! [joints.neck_yaw]         # a joint name from the URDF
//! id = 1                    # servo id, 0..=252, unique
//! sign = 1                  # +1 or -1: servo angle = sign · joint angle + offset_rad
//! offset_rad = 0.0          # servo angle (rad, 0 = tick 2048) at joint angle 0, |offset| ≤ π
//!
//! [joints.neck_leg_0]       # a prismatic joint (here a leg of the Stewart neck)
//! id = 2
//! m_per_rad = 0.008         # metres of travel per radian of the servo (lead screw, crank)
//! offset_rad = -2.0         # servo angle = sign · length / m_per_rad + offset_rad
//! ```
//! Every joint of the driver must be mapped, to a rotary servo, and its whole position range
//! must fit the servo's 0..=4095 ticks. A prismatic joint needs `m_per_rad` (a servo turning a
//! lead screw or a crank); a revolute joint must not have one. Errors name the offending key.

use std::collections::BTreeMap;

use serde::Deserialize;

use crate::dynamixel::transport::baud_rate;
use crate::dynamixel::units::rad_to_ticks;
use crate::error::JointError;
use crate::types::{JointKind, JointSpec};

/// How one joint maps to one servo.
#[derive(Debug, Clone, Copy, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ServoMapping {
    pub id: u8,
    #[serde(default = "one")]
    pub sign: i8,
    #[serde(default)]
    pub offset_rad: f64,
    /// Prismatic joints: metres of travel per radian of the servo.
    #[serde(default)]
    pub m_per_rad: Option<f64>,
}

fn one() -> i8 {
    1
}

impl ServoMapping {
    /// Joint units (rad or m) per servo radian: 1 for a revolute joint.
    fn scale(&self) -> f64 {
        self.m_per_rad.unwrap_or(1.0)
    }

    /// Servo angle (rad, 0 at tick 2048) for a joint position (rad, or m for a prismatic joint).
    pub fn servo_rad(&self, joint: f64) -> f64 {
        f64::from(self.sign) * joint / self.scale() + self.offset_rad
    }

    /// Joint position (rad, or m) for a servo angle (rad).
    pub fn joint_rad(&self, servo_rad: f64) -> f64 {
        f64::from(self.sign) * (servo_rad - self.offset_rad) * self.scale()
    }

    /// Servo speed (rad/s, or rad/s²) for a joint speed (rad/s or m/s, or their rates).
    pub fn servo_rate(&self, joint_rate: f64) -> f64 {
        joint_rate / self.scale()
    }
}

fn default_timeout_ms() -> u64 {
    20
}

fn default_retries() -> u32 {
    3
}

/// The parsed and checked configuration (see the module docs for the file format).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DynamixelConfig {
    pub port: String,
    pub baud: u32,
    #[serde(default = "default_timeout_ms")]
    pub read_timeout_ms: u64,
    #[serde(default = "default_retries")]
    pub retries: u32,
    /// Joint name → servo.
    pub joints: BTreeMap<String, ServoMapping>,
}

impl DynamixelConfig {
    /// Parses `text` and checks it against the driver's `joints`.
    pub fn from_toml(text: &str, joints: &[JointSpec]) -> Result<Self, JointError> {
        let c: Self = toml::from_str(text).map_err(|e| {
            let key = e.span().map_or_else(String::new, |s| {
                let line = text[..s.start.min(text.len())].matches('\n').count() + 1;
                format!("line {line}")
            });
            JointError::config(key, e.message().to_owned())
        })?;
        c.check(joints)?;
        Ok(c)
    }

    /// Checks the values and the mapping against `joints`.
    pub fn check(&self, joints: &[JointSpec]) -> Result<(), JointError> {
        if self.port.is_empty() {
            return Err(JointError::config("port", "empty"));
        }
        if baud_rate(self.baud).is_none() {
            return Err(JointError::config(
                "baud",
                format!("unsupported {}", self.baud),
            ));
        }
        if !(1..=1000).contains(&self.read_timeout_ms) {
            return Err(JointError::config("read_timeout_ms", "must be in 1..=1000"));
        }
        if self.retries > 10 {
            return Err(JointError::config("retries", "must be at most 10"));
        }
        let mut by_id: BTreeMap<u8, &str> = BTreeMap::new();
        for (name, m) in &self.joints {
            let key = format!("joints.{name}");
            let Some(spec) = joints.iter().find(|s| &s.name == name) else {
                return Err(JointError::config(key, "unknown joint"));
            };
            if m.id > 252 {
                return Err(JointError::config(
                    format!("{key}.id"),
                    "must be in 0..=252",
                ));
            }
            if let Some(other) = by_id.insert(m.id, name) {
                return Err(JointError::config(
                    format!("{key}.id"),
                    format!("id {} already used by joints.{other}", m.id),
                ));
            }
            if m.sign != 1 && m.sign != -1 {
                return Err(JointError::config(format!("{key}.sign"), "must be 1 or -1"));
            }
            if !(m.offset_rad.is_finite() && m.offset_rad.abs() <= std::f64::consts::PI) {
                return Err(JointError::config(
                    format!("{key}.offset_rad"),
                    "must be finite, |offset| ≤ π",
                ));
            }
            match (spec.kind, m.m_per_rad) {
                (JointKind::Revolute, None) => {}
                (JointKind::Revolute, Some(_)) => {
                    return Err(JointError::config(
                        format!("{key}.m_per_rad"),
                        "only for a prismatic joint",
                    ));
                }
                (JointKind::Prismatic, Some(k)) if k.is_finite() && k > 0.0 => {}
                (JointKind::Prismatic, Some(_)) => {
                    return Err(JointError::config(
                        format!("{key}.m_per_rad"),
                        "must be finite and > 0",
                    ));
                }
                (JointKind::Prismatic, None) => {
                    return Err(JointError::config(
                        key,
                        "a prismatic joint needs m_per_rad (metres per servo radian)",
                    ));
                }
                _ => {
                    return Err(JointError::config(
                        key,
                        "X-series servos move revolute and prismatic joints only",
                    ));
                }
            }
            for limit in [spec.lower, spec.upper] {
                let t = rad_to_ticks(m.servo_rad(limit));
                if !(0..=4095).contains(&t) {
                    return Err(JointError::config(
                        key,
                        format!("joint limit {limit} is servo tick {t}, outside 0..=4095"),
                    ));
                }
            }
        }
        if let Some(s) = joints.iter().find(|s| !self.joints.contains_key(&s.name)) {
            return Err(JointError::config(
                format!("joints.{}", s.name),
                "joint has no servo",
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn specs() -> Vec<JointSpec> {
        vec![
            JointSpec::revolute("neck_yaw", -1.0, 1.0, 3.0, 20.0),
            JointSpec::revolute("eye_tilt", -0.5, 0.5, 3.0, 20.0),
        ]
    }

    const GOOD: &str = r#"
port = "/dev/ttyUSB0"
baud = 1000000
[joints.neck_yaw]
id = 1
[joints.eye_tilt]
id = 2
sign = -1
offset_rad = 0.1
"#;

    fn err_key(text: &str) -> String {
        match DynamixelConfig::from_toml(text, &specs()) {
            Err(JointError::Config { key, .. }) => key,
            other => panic!("expected a config error, got {other:?}"),
        }
    }

    #[test]
    fn good_config_parses_with_defaults() {
        let c = DynamixelConfig::from_toml(GOOD, &specs()).unwrap();
        assert_eq!(c.retries, 3);
        assert_eq!(c.read_timeout_ms, 20);
        let m = c.joints["eye_tilt"];
        assert_eq!((m.id, m.sign), (2, -1));
        assert!((m.joint_rad(m.servo_rad(0.3)) - 0.3).abs() < 1e-15);
        assert!((m.servo_rad(0.3) - (-0.2)).abs() < 1e-15);
    }

    #[test]
    fn a_prismatic_leg_is_a_servo_turning_a_lead_screw() {
        let specs = vec![JointSpec::prismatic("leg", 0.08, 0.155, 0.1, 0.4)];
        let text = "port = \"/dev/ttyUSB0\"\nbaud = 1000000\n[joints.leg]\nid = 5\n";
        let key = |t: &str| match DynamixelConfig::from_toml(t, &specs) {
            Err(JointError::Config { key, reason }) => format!("{key}: {reason}"),
            other => panic!("expected a config error, got {other:?}"),
        };
        assert!(key(text).contains("needs m_per_rad"), "{}", key(text));
        assert!(key(&format!("{text}m_per_rad = -0.01\n")).starts_with("joints.leg.m_per_rad"));
        // 0.155 m at 0.01 m/rad is 15.5 rad: more than a turn of the servo.
        assert!(key(&format!("{text}m_per_rad = 0.01\n")).contains("outside 0..=4095"));
        let c = DynamixelConfig::from_toml(
            &format!("{text}m_per_rad = 0.04\noffset_rad = -2.9\n"),
            &specs,
        )
        .unwrap();
        let m = c.joints["leg"];
        assert!((m.servo_rad(0.12) - (3.0 - 2.9)).abs() < 1e-12);
        assert!((m.joint_rad(m.servo_rad(0.1)) - 0.1).abs() < 1e-15);
        assert!((m.servo_rate(0.1) - 2.5).abs() < 1e-12);
        let revolute = GOOD.replace("id = 1", "id = 1\nm_per_rad = 0.01");
        assert_eq!(err_key(&revolute), "joints.neck_yaw.m_per_rad");
    }

    #[test]
    fn errors_name_the_key() {
        assert_eq!(
            err_key(&GOOD.replace("id = 2", "id = 1")),
            "joints.neck_yaw.id"
        );
        assert_eq!(
            err_key(&format!("{GOOD}[joints.knee]\nid = 3\n")),
            "joints.knee"
        );
        assert_eq!(
            err_key(&GOOD.replace(
                "[joints.eye_tilt]\nid = 2\nsign = -1\noffset_rad = 0.1\n",
                ""
            )),
            "joints.eye_tilt"
        );
        assert_eq!(
            err_key(&GOOD.replace("sign = -1", "sign = 2")),
            "joints.eye_tilt.sign"
        );
        assert_eq!(
            err_key(&GOOD.replace("id = 2", "id = 253")),
            "joints.eye_tilt.id"
        );
        assert_eq!(err_key(&GOOD.replace("1000000", "250000")), "baud");
        // Offset pushing the range beyond the ticks.
        assert_eq!(
            err_key(&GOOD.replace("offset_rad = 0.1", "offset_rad = 3.0")),
            "joints.eye_tilt"
        );
        // Unknown key, with its line.
        assert_eq!(
            err_key(&GOOD.replace("id = 2", "id = 2\nspeed = 3")),
            "line 8"
        );
    }
}
