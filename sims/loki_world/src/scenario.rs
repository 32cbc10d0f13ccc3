//! Scenario files: what the simulated person does and expects, step by step.
//!
//! A scenario is TOML: a `[ball]` table (the ball's colour, size and start), a `[voice]` table
//! (how the person sounds), and a list of `[[step]]`s, each with exactly one action:
//!
//! ```toml
//! name = "touch a still ball"
//! [ball]
//! start = [0.45, 0.15, 0.80]     # world frame, m (z up, Loki at the origin facing +x)
//! [[step]]
//! say = "hello"
//! [[step]]
//! expect = { robot_said = "hello", timeout_s = 10, repeat = 2 }
//! [[step]]
//! ball = { to = [0.5, 0.0, 0.8], speed_mps = 0.2 }
//! [[step]]
//! expect = { hand_to_ball_m = 0.03, timeout_s = 20 }
//! ```
//!
//! - `say`: speak the words (espeak-ng, into `audio/in`, in real time); returns when the audio has
//!   been played.
//! - `ball`: move the ball to `to` at `speed_mps` (0 = put it there at once), `held` (the hand
//!   holds it; default true), `present` (false = put away, out of the scene). Moves run in the
//!   background unless `wait = true`.
//! - `pause_s`: do nothing for that long.
//! - `expect`: wait until a condition holds, at most `timeout_s` (default 20 s); on time-out the
//!   person repeats the last thing she said, `repeat` times (default 0), then the scenario fails.
//!   While she waits, a robot that asks "Did you say <her last words>?" gets a "yes", and the
//!   wait starts again (unless that question is what she waits for).
//!   Conditions, all of which must hold at once:
//!   - `robot_said`: the robot started saying something containing these words (case-insensitive)
//!     since the last `say` or `ball` step;
//!   - `state`: an Executive state whose path contains this text was entered since then (or is
//!     active);
//!   - `reach`: a reach status of the arm (`reached`, `unreachable`) since then;
//!   - `ball_event`: a tracker event (`detected`, `out_of_view`, `lost`) since then;
//!   - `hand_to_ball_m`: the robot's hand centre (from the DR) is this close to the ball's surface;
//!   - `gaze_on_ball_deg`: the head camera's optical axis (from the DR) is within this angle of the
//!     ball's centre.
//!
//! Every number is checked when the file is loaded; a bad file is an error naming the step.

use serde::Deserialize;

/// The scenarios that ship with the simulator (name, TOML).
pub const BUILT_IN: &[(&str, &str)] = &[
    ("still", include_str!("../scenarios/still.toml")),
    ("moving", include_str!("../scenarios/moving.toml")),
    ("out_of_view", include_str!("../scenarios/out_of_view.toml")),
    ("unreachable", include_str!("../scenarios/unreachable.toml")),
    ("confirm_yes", include_str!("../scenarios/confirm_yes.toml")),
    ("bench", include_str!("../scenarios/bench.toml")),
    ("barge_in", include_str!("../scenarios/barge_in.toml")),
    (
        "tracker_restart",
        include_str!("../scenarios/tracker_restart.toml"),
    ),
    (
        "tracker_restart_touching",
        include_str!("../scenarios/tracker_restart_touching.toml"),
    ),
    (
        "restart_mid_game",
        include_str!("../scenarios/restart_mid_game.toml"),
    ),
    (
        "machine_away",
        include_str!("../scenarios/machine_away.toml"),
    ),
    ("beside", include_str!("../scenarios/beside.toml")),
];

/// The built-in scenarios' names, comma-separated.
pub fn built_in_names() -> String {
    BUILT_IN
        .iter()
        .map(|(n, _)| *n)
        .collect::<Vec<_>>()
        .join(", ")
}

#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("cannot read scenario {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("scenario {origin}: {source}")]
    Parse {
        origin: String,
        source: toml::de::Error,
    },
    #[error("scenario {origin}, step {step}: {why}")]
    Invalid {
        origin: String,
        step: usize,
        why: String,
    },
    #[error("scenario {origin}: {why}")]
    InvalidBall { origin: String, why: String },
    #[error(
        "no scenario {0:?}: give a file path or one of the built-in names ({names})",
        names = built_in_names()
    )]
    Unknown(String),
}

/// A whole scenario.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    pub name: String,
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub ball: BallSpec,
    #[serde(default)]
    pub voice: VoiceSpec,
    #[serde(rename = "step")]
    pub steps: Vec<Step>,
}

/// The ball: colour, size, where it starts.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BallSpec {
    /// Diameter, m.
    pub diameter_m: f64,
    /// HSV hue, degrees `[0, 360)`.
    pub hue_deg: f32,
    /// HSV saturation, `[0, 1]`.
    pub saturation: f32,
    /// Start position, world frame, m.
    pub start: [f64; 3],
    /// In the scene at the start.
    pub present: bool,
    /// Held by the person's hand at the start.
    pub held: bool,
}

impl Default for BallSpec {
    fn default() -> Self {
        Self {
            diameter_m: 0.07,
            hue_deg: 52.0,
            saturation: 0.85,
            start: [0.45, 0.30, 1.20],
            present: true,
            held: false,
        }
    }
}

/// How the person sounds (espeak-ng voice) and how noisy the room is.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VoiceSpec {
    /// espeak-ng voice name.
    pub voice: String,
    /// Words per minute (80-450).
    pub speed_wpm: u32,
    /// 0-99.
    pub pitch: u8,
    /// Speech-to-room-noise ratio, dB.
    pub snr_db: f64,
}

impl Default for VoiceSpec {
    fn default() -> Self {
        Self {
            voice: "en-us".into(),
            speed_wpm: 150,
            pitch: 50,
            snr_db: 30.0,
        }
    }
}

/// One step (exactly one action).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum Step {
    /// Say it when the robot has finished what it is saying (people take turns).
    Say(String),
    /// Say it at once, over the robot if it is speaking (a barge-in).
    Interrupt(String),
    Ball(BallMove),
    PauseS(f64),
    Expect(Expect),
}

/// A ball motion.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BallMove {
    /// Where to (world frame, m).
    pub to: [f64; 3],
    /// Speed along the straight line, m/s; 0 = at once.
    #[serde(default)]
    pub speed_mps: f64,
    #[serde(default = "yes")]
    pub held: bool,
    #[serde(default = "yes")]
    pub present: bool,
    /// Wait for the move to end before the next step.
    #[serde(default)]
    pub wait: bool,
}

fn yes() -> bool {
    true
}

/// A condition to wait for.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Expect {
    #[serde(default)]
    pub robot_said: Option<String>,
    #[serde(default)]
    pub state: Option<String>,
    #[serde(default)]
    pub reach: Option<String>,
    #[serde(default)]
    pub ball_event: Option<String>,
    #[serde(default)]
    pub hand_to_ball_m: Option<f64>,
    #[serde(default)]
    pub gaze_on_ball_deg: Option<f64>,
    #[serde(default = "default_timeout_s")]
    pub timeout_s: f64,
    #[serde(default)]
    pub repeat: u32,
}

fn default_timeout_s() -> f64 {
    20.0
}

/// Reach states an `expect` may name.
pub const REACH_STATES: &[&str] = &["moving", "reached", "unreachable", "cancelled", "failed"];
/// Ball events an `expect` may name.
pub const BALL_EVENTS: &[&str] = &["detected", "out_of_view", "lost", "detection_timed_out"];

impl Expect {
    /// A one-line description for logs ("robot said \"hello\" and state ~ searching").
    pub fn describe(&self) -> String {
        let mut parts = vec![];
        if let Some(s) = &self.robot_said {
            parts.push(format!("the robot says {s:?}"));
        }
        if let Some(s) = &self.state {
            parts.push(format!("state ~ {s:?}"));
        }
        if let Some(s) = &self.reach {
            parts.push(format!("arm {s}"));
        }
        if let Some(s) = &self.ball_event {
            parts.push(format!("ball {s}"));
        }
        if let Some(d) = self.hand_to_ball_m {
            parts.push(format!("hand within {:.1} cm of the ball", d * 100.0));
        }
        if let Some(a) = self.gaze_on_ball_deg {
            parts.push(format!("gaze within {a:.1} deg of the ball"));
        }
        parts.join(" and ")
    }
}

fn finite3(v: &[f64; 3]) -> bool {
    v.iter().all(|x| x.is_finite())
}

impl Scenario {
    /// Parse and check a scenario's text; `origin` names it in errors.
    pub fn parse(text: &str, origin: &str) -> Result<Self, ScenarioError> {
        let s: Scenario = toml::from_str(text).map_err(|source| ScenarioError::Parse {
            origin: origin.into(),
            source,
        })?;
        s.validate(origin)?;
        Ok(s)
    }

    /// A built-in scenario by name, or a file.
    pub fn load(name_or_path: &str) -> Result<Self, ScenarioError> {
        if let Some((_, text)) = BUILT_IN.iter().find(|(n, _)| *n == name_or_path) {
            return Self::parse(text, name_or_path);
        }
        let path = std::path::Path::new(name_or_path);
        if !path.exists() {
            return Err(ScenarioError::Unknown(name_or_path.into()));
        }
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
            path: path.display().to_string(),
            source,
        })?;
        Self::parse(&text, &path.display().to_string())
    }

    fn validate(&self, origin: &str) -> Result<(), ScenarioError> {
        let b = &self.ball;
        let ball_err = |why: String| ScenarioError::InvalidBall {
            origin: origin.into(),
            why,
        };
        if !(b.diameter_m.is_finite() && b.diameter_m > 0.005 && b.diameter_m < 1.0) {
            return Err(ball_err(format!(
                "diameter_m {} is not between 0.005 and 1",
                b.diameter_m
            )));
        }
        if !(0.0..360.0).contains(&b.hue_deg) || !(0.0..=1.0).contains(&b.saturation) {
            return Err(ball_err(
                "hue_deg must be in [0, 360) and saturation in [0, 1]".into(),
            ));
        }
        if !finite3(&b.start) {
            return Err(ball_err("start must be finite".into()));
        }
        let v = &self.voice;
        if !(80..=450).contains(&v.speed_wpm) || v.pitch > 99 || !v.snr_db.is_finite() {
            return Err(ScenarioError::InvalidBall {
                origin: origin.into(),
                why: "voice: speed_wpm must be 80-450, pitch 0-99, snr_db finite".into(),
            });
        }
        if self.steps.is_empty() {
            return Err(ScenarioError::Invalid {
                origin: origin.into(),
                step: 0,
                why: "no steps".into(),
            });
        }
        for (i, step) in self.steps.iter().enumerate() {
            let bad = |why: String| ScenarioError::Invalid {
                origin: origin.into(),
                step: i + 1,
                why,
            };
            match step {
                Step::Say(text) | Step::Interrupt(text) => {
                    if text.trim().is_empty() {
                        return Err(bad("say: nothing to say".into()));
                    }
                }
                Step::Ball(m) => {
                    if !(finite3(&m.to) && m.speed_mps.is_finite() && m.speed_mps >= 0.0) {
                        return Err(bad("ball: `to` must be finite and speed_mps >= 0".into()));
                    }
                }
                Step::PauseS(s) => {
                    if !(s.is_finite() && *s >= 0.0 && *s <= 600.0) {
                        return Err(bad(format!("pause_s {s} is not in [0, 600]")));
                    }
                }
                Step::Expect(e) => {
                    if e.describe().is_empty() {
                        return Err(bad("expect: no condition".into()));
                    }
                    if !(e.timeout_s.is_finite() && e.timeout_s > 0.0 && e.timeout_s <= 600.0) {
                        return Err(bad(format!("timeout_s {} is not in (0, 600]", e.timeout_s)));
                    }
                    if let Some(r) = &e.reach
                        && !REACH_STATES.contains(&r.as_str())
                    {
                        return Err(bad(format!(
                            "reach {r:?} is not one of {}",
                            REACH_STATES.join(", ")
                        )));
                    }
                    if let Some(r) = &e.ball_event
                        && !BALL_EVENTS.contains(&r.as_str())
                    {
                        return Err(bad(format!(
                            "ball_event {r:?} is not one of {}",
                            BALL_EVENTS.join(", ")
                        )));
                    }
                    for (what, x) in [
                        ("hand_to_ball_m", e.hand_to_ball_m),
                        ("gaze_on_ball_deg", e.gaze_on_ball_deg),
                    ] {
                        if let Some(x) = x
                            && !(x.is_finite() && x > 0.0)
                        {
                            return Err(bad(format!("{what} must be positive, got {x}")));
                        }
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_built_in_scenario_loads() {
        for (name, _) in BUILT_IN {
            let s = Scenario::load(name).unwrap_or_else(|e| panic!("{e}"));
            assert!(!s.steps.is_empty(), "{name}");
        }
    }

    #[test]
    fn steps_parse_with_one_action_each() {
        let s = Scenario::parse(
            r#"
name = "t"
[[step]]
say = "hello"
[[step]]
ball = { to = [0.5, 0.0, 0.8], speed_mps = 0.2 }
[[step]]
pause_s = 1.5
[[step]]
expect = { robot_said = "hello", timeout_s = 5, repeat = 2 }
"#,
            "t",
        )
        .unwrap();
        assert_eq!(s.steps[0], Step::Say("hello".into()));
        assert!(matches!(&s.steps[1], Step::Ball(m) if m.held && m.present && !m.wait));
        assert_eq!(s.steps[2], Step::PauseS(1.5));
        assert!(matches!(&s.steps[3], Step::Expect(e) if e.repeat == 2 && e.timeout_s == 5.0));
        assert_eq!(s.ball, BallSpec::default());
    }

    #[test]
    fn bad_files_name_the_step_and_the_problem() {
        let err = |t: &str| Scenario::parse(t, "f").unwrap_err().to_string();
        let e = err("name = \"t\"\n[[step]]\nexpect = { timeout_s = 3 }\n");
        assert!(e.contains("step 1") && e.contains("no condition"), "{e}");
        let e = err(
            "name = \"t\"\n[[step]]\nsay = \"hi\"\n[[step]]\nexpect = { reach = \"touched\" }\n",
        );
        assert!(e.contains("step 2") && e.contains("touched"), "{e}");
        let e = err("name = \"t\"\n[[step]]\nsay = \"hi\"\nball = { to = [0,0,0] }\n");
        assert!(
            e.contains("f"),
            "two actions in one step must not parse: {e}"
        );
        let e = err("name = \"t\"\n[[step]]\nshout = \"hi\"\n");
        assert!(e.contains("shout") || e.contains("unknown"), "{e}");
        let e = err("name = \"t\"\n[ball]\ndiameter_m = -1\n[[step]]\nsay = \"hi\"\n");
        assert!(e.contains("diameter_m"), "{e}");
        let e = err("name = \"t\"\n[[step]]\npause_s = nan\n");
        assert!(e.contains("pause_s"), "{e}");
        let e = Scenario::load("no-such-scenario").unwrap_err();
        assert!(matches!(e, ScenarioError::Unknown(_)));
        // The message lists every built-in name.
        let e = e.to_string();
        assert!(BUILT_IN.iter().all(|(n, _)| e.contains(n)), "{e}");
    }
}
