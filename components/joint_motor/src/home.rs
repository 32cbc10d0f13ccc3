//! Start postures of Loki's joints (`joint_motor --home`).
//!
//! # The rest posture ([`Home::Rest`])
//! Frames as in `models/loki.urdf` (REP 103: x forward, y left, z up). With every joint at 0 the
//! arms hang straight down along the body (-z) and the head looks straight ahead. The rest posture
//! keeps that, with three small changes that keep the joints off their limits and the arms off the
//! torso:
//! - `{left,right}_shoulder_roll` = ±0.10 rad: each upper arm 6° away from the body (left +, right −);
//! - `{left,right}_elbow` = −0.15 rad: forearms 9° forward (0 is the elbow's upper limit);
//! - `neck_pitch` = 0.30 rad: the head, and its RGB-D camera, 17° down (positive pitch looks down);
//! - every other joint at 0 (clamped into its limits if 0 is outside them).

/// The rest posture's non-zero joints (rad); see the module docs.
pub const REST: &[(&str, f64)] = &[
    ("left_shoulder_roll", 0.10),
    ("right_shoulder_roll", -0.10),
    ("left_elbow", -0.15),
    ("right_elbow", -0.15),
    ("neck_pitch", 0.30),
];

/// Which posture the joints start in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum Home {
    /// The rest posture (module docs): arms hanging beside the body, head ahead slightly down.
    #[default]
    Rest,
    /// Every joint at 0 (clamped into its limits).
    Zero,
    /// Do not command anything at start: the sim starts at zero, real servos stay where they are.
    None,
}

impl Home {
    /// The start position of joint `name` with limits `[lower, upper]`, or `None` for
    /// [`Home::None`].
    pub fn position(self, name: &str, lower: f64, upper: f64) -> Option<f64> {
        let q = match self {
            Home::None => return None,
            Home::Zero => 0.0,
            Home::Rest => REST
                .iter()
                .find(|(n, _)| *n == name)
                .map_or(0.0, |(_, q)| *q),
        };
        Some(q.clamp(lower, upper))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rest_is_within_loki_limits_and_zero_elsewhere() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap();
        let model = robot_model::RobotModel::from_urdf_str(&text).unwrap();
        for (name, q) in REST {
            let j = model.joint(name).unwrap();
            assert!(j.limits.lower < *q && *q < j.limits.upper, "{name} {q}");
            assert_eq!(
                Home::Rest.position(name, j.limits.lower, j.limits.upper),
                Some(*q)
            );
        }
        assert_eq!(
            Home::Rest.position("left_wrist_pitch", -0.8, 0.8),
            Some(0.0)
        );
        assert_eq!(Home::Zero.position("neck_pitch", 0.1, 0.6), Some(0.1));
        assert_eq!(Home::None.position("neck_pitch", -0.5, 0.6), None);
    }
}
