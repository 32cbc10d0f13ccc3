//! The Executive's settings file (TOML), every key optional.
//!
//! Units: metres, seconds, radians, degrees for hues. Points are in the deep representation's
//! `world` frame (z up; in the default scene the robot stands at the origin facing +x and the
//! table top is at z = 0.75 m).
//!
//! ```toml
//! [touch]
//! arm = "left_arm_7"
//! courtesy_delay_s = 5.0
//! tracker_restart_grace_s = 6.0
//! ball_hue_deg = 51.7
//! arm_rest = [{ joint = "left_elbow", position = -0.2 }]
//!
//! [propose]
//! protected = ["world", "ball", "base_footprint"]
//! ```

use std::path::Path;

use serde::Deserialize;

/// Why the settings could not be used.
#[derive(Debug, thiserror::Error)]
pub enum SettingsError {
    #[error("cannot read {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("{path}: {source}")]
    Parse {
        path: String,
        source: toml::de::Error,
    },
    #[error("{0}")]
    Invalid(String),
}

/// Everything in the settings file.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Settings {
    pub touch: TouchSettings,
    /// The coach game's settings (see [`crate::coach::CoachSettings`]).
    pub coach: crate::coach::CoachSettings,
    pub propose: ProposeSettings,
}

impl Settings {
    /// Reads and checks a settings file.
    pub fn load(path: &Path) -> Result<Settings, SettingsError> {
        let text = std::fs::read_to_string(path).map_err(|source| SettingsError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Settings::parse(&text, &path.display().to_string())
    }

    /// Parses and checks settings text (`origin` names it in errors).
    pub fn parse(text: &str, origin: &str) -> Result<Settings, SettingsError> {
        let s: Settings = toml::from_str(text).map_err(|source| SettingsError::Parse {
            path: origin.to_string(),
            source,
        })?;
        s.touch.check()?;
        Ok(s)
    }
}

/// One joint at a rest position.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct JointRest {
    pub joint: String,
    /// rad (or m for a prismatic joint).
    pub position: f64,
}

/// `joint_motor`'s rest posture (its `home` module): arms hanging beside the body, upper arms
/// 0.10 rad away from it, forearms 0.15 rad forward, head 0.30 rad down; every other joint 0.
const REST_POSTURE: &[(&str, f64)] = &[
    ("left_shoulder_roll", 0.10),
    ("right_shoulder_roll", -0.10),
    ("left_elbow", -0.15),
    ("right_elbow", -0.15),
    ("neck_pitch", 0.30),
];

fn rest(joints: &[&str]) -> Vec<JointRest> {
    joints
        .iter()
        .map(|j| JointRest {
            joint: j.to_string(),
            position: REST_POSTURE
                .iter()
                .find(|(n, _)| n == j)
                .map_or(0.0, |(_, q)| *q),
        })
        .collect()
}

/// The joints of the default arm (`left_arm_7`); at rest as `joint_motor --home rest` puts them
/// (inside every URDF limit: the elbow's range is [-2.4, 0]).
pub const LEFT_ARM_JOINTS: [&str; 7] = [
    "left_shoulder_pitch",
    "left_shoulder_roll",
    "left_shoulder_yaw",
    "left_elbow",
    "left_forearm_roll",
    "left_wrist_pitch",
    "left_wrist_roll",
];

/// The base's joints; at rest the robot faces ahead where it started.
pub const BASE_JOINTS: [&str; 2] = ["base_yaw", "base_forward"];

/// The neck's joints; at rest the head looks ahead, 0.30 rad down.
pub const NECK_JOINTS: [&str; 4] = ["neck_rotation", "neck_pitch", "neck_roll", "neck_yaw"];

/// The touch-the-ball game's settings.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct TouchSettings {
    /// The body part that touches (`left_arm_7`, `left_arm_11`, ...).
    pub arm: String,
    /// The same arm with the base's yaw and forward joints (`left_arm_9`): when `arm` alone
    /// cannot reach the ball, the robot turns (and moves a little, as far as the IK lets the base
    /// go) and reaches with this part. Empty: the base never moves.
    pub arm_with_base: String,
    /// The body part that gazes (and searches).
    pub neck: String,
    /// The client name on reach and joint goals.
    pub client: String,
    /// The ball's colour and size, sent to the tracker.
    pub ball_hue_deg: f32,
    pub ball_saturation: f32,
    pub ball_diameter_m: f64,
    /// The hand's target in the ball's frame (m): the hand centre on the ball's surface on the
    /// robot's side.
    pub touch_offset_m: [f64; 3],
    /// Reach tolerance (m).
    pub touch_tolerance_m: f64,
    /// After the hand reached the ball, how long the robot waits for "you touched it" before
    /// going home anyway (s).
    pub courtesy_delay_s: f64,
    /// How long the head holds still on a scan point once the neck reached it, before it turns
    /// to the next one (s). The tracker looks all along the sweep (it places what it sees through
    /// the camera's pose at each frame's stamp); the stop gives a real camera a sharp frame.
    pub scan_dwell_s: f64,
    /// The longest the head may take to a scan point: without the neck's `reached` (or
    /// `unreachable`, `failed`) by then the scan goes on to the next point (s).
    pub scan_move_timeout_s: f64,
    /// The search pattern: gaze points in `world` (m), visited in order, then again; every
    /// search starts at the first. Unset: [`default_scan_points`] for the side of `arm`
    /// (see [`TouchSettings::scan_pattern`]).
    pub scan_points: Option<Vec<[f64; 3]>>,
    /// The DR frame of the person the robot plays with (a `human` node); empty: the robot does
    /// not look at her.
    pub person_frame: String,
    /// Where her face is in that frame (m): the robot looks there while it waits for her and
    /// listens (before the game and while it has no ball to look at).
    pub face_m: [f64; 3],
    /// The ball moved this far (m) from where it was last reported: the game says it follows it.
    pub ball_moved_m: f64,
    /// How long the arm takes to go home before another touch is a fresh start (s).
    pub homing_s: f64,
    /// How long the game rides out a restart of the ball tracker while its eyes follow the ball
    /// (s): the tracker left the bus or came back as a new process, and the ball is taken to be
    /// where it was until the new tracker holds it again. Past this it is lost, as when the
    /// tracker falls silent with its camera. Longer than a restart (the launcher's back-off,
    /// the process's start) and a detection.
    pub tracker_restart_grace_s: f64,
    /// The arm's rest posture (JointGoal on `body/joint_goal`).
    pub arm_rest: Vec<JointRest>,
    /// The head's rest posture when the game ends.
    pub head_rest: Vec<JointRest>,
    /// The base's rest posture, where the arm goes home after a reach that moved the base.
    pub base_rest: Vec<JointRest>,
    /// Speed of the moves to rest (rad/s).
    pub rest_max_speed: f64,
    /// Speed of the base's move back to rest (rad/s for the turn, m/s forward): slower than the
    /// arm, since the whole robot moves, and within the base joints' limits (0.5 m/s forward).
    pub base_rest_max_speed: f64,
    /// Priority of the rest joint goals.
    pub rest_priority: u8,
}

/// The default search pattern, for a touching arm on the robot's `side` (+1: left, +y; -1:
/// right): where a person shows a ball to a seated robot, most likely first. She holds it up in
/// front of the robot at arm's length, about chest height (1.25 m; the head camera is about 1.47 m
/// high), toward the hand that is to touch it; so the head looks there first, then at the same
/// place on the other side, then higher (a person holding it up to the robot's face, a little
/// farther) on both sides, then wide on both sides. The camera sees about 62 x 49 degrees, so
/// these six views and the sweeps between them cover the space in front of the robot from the
/// table's edge to above its eyes; every point is within the neck's reach (it pitches down at
/// most 0.6 rad).
pub fn default_scan_points(side: f64) -> Vec<[f64; 3]> {
    let s = if side < 0.0 { -1.0 } else { 1.0 };
    vec![
        [0.50, 0.15 * s, 1.25],
        [0.50, -0.15 * s, 1.25],
        [0.70, -0.30 * s, 1.45],
        [0.70, 0.30 * s, 1.45],
        [0.55, 0.50 * s, 1.20],
        [0.55, -0.50 * s, 1.20],
    ]
}

impl Default for TouchSettings {
    fn default() -> Self {
        TouchSettings {
            arm: "left_arm_7".into(),
            arm_with_base: "left_arm_9".into(),
            neck: "neck".into(),
            client: "executive".into(),
            ball_hue_deg: 51.7,
            ball_saturation: 0.85,
            ball_diameter_m: 0.07,
            touch_offset_m: [-0.03, 0.0, 0.0],
            touch_tolerance_m: 0.02,
            courtesy_delay_s: 5.0,
            scan_dwell_s: 0.3,
            scan_move_timeout_s: 3.0,
            scan_points: None,
            person_frame: "player".into(),
            face_m: [0.0, 0.0, 1.55],
            ball_moved_m: 0.05,
            homing_s: 2.0,
            tracker_restart_grace_s: 6.0,
            arm_rest: rest(&LEFT_ARM_JOINTS),
            head_rest: rest(&NECK_JOINTS),
            base_rest: rest(&BASE_JOINTS),
            rest_max_speed: 0.6,
            base_rest_max_speed: 0.25,
            rest_priority: 10,
        }
    }
}

impl TouchSettings {
    /// The side of the robot the touching arm is on: -1 for a `right_*` arm, else +1 (left).
    pub fn arm_side(&self) -> f64 {
        if self.arm.starts_with("right") {
            -1.0
        } else {
            1.0
        }
    }

    /// The search pattern: `scan_points` when given, else [`default_scan_points`] for the
    /// touching arm's side.
    pub fn scan_pattern(&self) -> Vec<[f64; 3]> {
        self.scan_points
            .clone()
            .unwrap_or_else(|| default_scan_points(self.arm_side()))
    }

    /// Checks ranges (positive durations and sizes, a hue in [0, 360), at least one scan point).
    pub fn check(&self) -> Result<(), SettingsError> {
        let bad = |m: String| Err(SettingsError::Invalid(format!("[touch] {m}")));
        for (k, v) in [
            ("courtesy_delay_s", self.courtesy_delay_s),
            ("scan_dwell_s", self.scan_dwell_s),
            ("scan_move_timeout_s", self.scan_move_timeout_s),
            ("homing_s", self.homing_s),
            ("tracker_restart_grace_s", self.tracker_restart_grace_s),
            ("ball_diameter_m", self.ball_diameter_m),
            ("ball_moved_m", self.ball_moved_m),
            ("touch_tolerance_m", self.touch_tolerance_m),
            ("rest_max_speed", self.rest_max_speed),
            ("base_rest_max_speed", self.base_rest_max_speed),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(format!("{k} must be a positive number, not {v}"));
            }
        }
        if !(0.0..360.0).contains(&self.ball_hue_deg) {
            return bad(format!(
                "ball_hue_deg {} is outside [0, 360)",
                self.ball_hue_deg
            ));
        }
        if !(0.0..=1.0).contains(&self.ball_saturation) {
            return bad(format!(
                "ball_saturation {} is outside [0, 1]",
                self.ball_saturation
            ));
        }
        if self.scan_points.as_ref().is_some_and(|v| v.is_empty()) {
            return bad("scan_points is empty".into());
        }
        let finite = |p: &[f64]| p.iter().all(|x| x.is_finite());
        if !self.scan_pattern().iter().all(|p| finite(p))
            || !finite(&self.touch_offset_m)
            || !finite(&self.face_m)
        {
            return bad("a point has a non-finite coordinate".into());
        }
        for r in self
            .arm_rest
            .iter()
            .chain(&self.head_rest)
            .chain(&self.base_rest)
        {
            if !r.position.is_finite() {
                return bad(format!("rest position of {} is not finite", r.joint));
            }
        }
        if self.arm.is_empty() || self.neck.is_empty() || self.client.is_empty() {
            return bad("arm, neck and client must not be empty".into());
        }
        Ok(())
    }
}

/// What `executive/propose` protects while a game runs.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProposeSettings {
    /// Nodes that cannot be removed or moved while a game runs (the robot's root, the ball).
    pub protected: Vec<String>,
    /// Node types of which one node at most may exist while a game runs.
    pub unique_types: Vec<String>,
}

impl Default for ProposeSettings {
    fn default() -> Self {
        ProposeSettings {
            protected: ["world", "base_footprint", "ball"]
                .map(String::from)
                .to_vec(),
            unique_types: vec!["ball".into()],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_empty_file_gives_the_defaults() {
        let s = Settings::parse("", "test").unwrap();
        assert_eq!(s.touch.arm, "left_arm_7");
        assert_eq!(s.touch.courtesy_delay_s, 5.0);
        assert_eq!(s.touch.tracker_restart_grace_s, 6.0);
        assert_eq!(s.touch.arm_rest.len(), 7);
        // The default scan: six points in front of the robot, within the neck's reach, the
        // first at chest height at arm's length in front of the touching (left) arm, the second
        // its mirror image.
        assert_eq!(s.touch.scan_points, None);
        let p = s.touch.scan_pattern();
        assert_eq!(p.len(), 6);
        assert!(
            p.iter().all(|p| (1.1..=1.5).contains(&p[2])
                && (0.45..=0.75).contains(&p[0])
                && (-0.5..=0.5).contains(&p[1])),
            "{p:?}"
        );
        assert!(p[0][1] > 0.0 && (1.2..=1.3).contains(&p[0][2]), "{p:?}");
        assert_eq!(p[1], [p[0][0], -p[0][1], p[0][2]]);
        // Both sides are looked at, as often.
        assert_eq!(
            p.iter().filter(|p| p[1] > 0.0).count(),
            p.iter().filter(|p| p[1] < 0.0).count()
        );
    }

    #[test]
    fn the_default_scan_starts_on_the_touching_arms_side_and_given_points_win() {
        let right = Settings::parse("[touch]\narm = \"right_arm_7\"\n", "f").unwrap();
        let left = TouchSettings::default().scan_pattern();
        let mirrored: Vec<[f64; 3]> = left.iter().map(|p| [p[0], -p[1], p[2]]).collect();
        assert_eq!(right.touch.scan_pattern(), mirrored);
        assert!(right.touch.scan_pattern()[0][1] < 0.0);
        let given = Settings::parse(
            "[touch]\narm = \"right_arm_7\"\nscan_points = [[0.6, 0.1, 1.3]]\n",
            "f",
        )
        .unwrap();
        assert_eq!(given.touch.scan_pattern(), [[0.6, 0.1, 1.3]]);
        assert!(Settings::parse("[touch]\nscan_move_timeout_s = 0.0\n", "f").is_err());
    }

    #[test]
    fn keys_override_and_typos_and_bad_values_are_errors() {
        let s = Settings::parse(
            "[touch]\ncourtesy_delay_s = 2.5\narm_rest = [{ joint = \"left_elbow\", position = -0.2 }]\n",
            "test",
        )
        .unwrap();
        assert_eq!(s.touch.courtesy_delay_s, 2.5);
        assert_eq!(s.touch.arm_rest.len(), 1);
        let e = Settings::parse("[touch]\ncourtesy_delay = 2.5\n", "f.toml").unwrap_err();
        assert!(e.to_string().contains("courtesy_delay"), "{e}");
        let e = Settings::parse("[touch]\ncourtesy_delay_s = -1.0\n", "f.toml").unwrap_err();
        assert!(e.to_string().contains("courtesy_delay_s"), "{e}");
        assert!(Settings::parse("[touch]\nscan_points = []\n", "f").is_err());
        // The coach's table belongs to the same file.
        assert!(Settings::parse("[coach]\n[propose]\nprotected = []\n", "f").is_ok());
        assert!(Settings::parse("[touch]\nball_hue_deg = 400.0\n", "f").is_err());
        let e = Settings::parse("[touch]\ntracker_restart_grace_s = 0.0\n", "f").unwrap_err();
        assert!(e.to_string().contains("tracker_restart_grace_s"), "{e}");
        let s = Settings::parse("[touch]\ntracker_restart_grace_s = 10.0\n", "f").unwrap();
        assert_eq!(s.touch.tracker_restart_grace_s, 10.0);
    }
}
