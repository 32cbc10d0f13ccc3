//! The simulated joints' posture, kept in the component's state folder: real servos hold where
//! they are while the process driving them restarts, and a restarted `joint_motor --driver sim`
//! must do the same, or the head would snap back to its start posture (the ball gone from the
//! camera's view) and the arm drop mid-reach. A new launch starts from a fresh state folder, so
//! from the start posture.

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Duration;

use interfaces::Moment;
use interfaces::msg::body::JointStates;

/// The file in the state folder.
pub const FILE: &str = "sim_joints.json";
/// How often the posture is written.
pub const EVERY: Duration = Duration::from_millis(200);

#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct Posture {
    version: u32,
    joints: HashMap<String, f64>,
}

const VERSION: u32 = 1;

/// Writes the posture at most every [`EVERY`] (`interfaces::state::write_atomically`).
#[derive(Debug)]
pub struct Keeper {
    path: PathBuf,
    last: Option<Moment>,
    last_written: Option<Moment>,
    failed: bool,
}

impl Keeper {
    pub fn new(dir: &Path) -> Self {
        Self {
            path: dir.join(FILE),
            last: None,
            last_written: None,
            failed: false,
        }
    }

    /// Keeps `states` if the last write is [`EVERY`] old (or there was none).
    pub fn offer(&mut self, states: &JointStates, now: Moment) {
        if self.last.is_some_and(|t| now.duration_since(t) < EVERY) {
            return;
        }
        self.last = Some(now);
        let posture = Posture {
            version: VERSION,
            joints: states
                .joints
                .iter()
                .filter(|j| j.position.is_finite())
                .map(|j| (j.name.clone(), j.position))
                .collect(),
        };
        let written = serde_json::to_vec(&posture)
            .map_err(std::io::Error::other)
            .and_then(|bytes| interfaces::state::write_atomically(&self.path, &bytes));
        match written {
            Ok(()) => {
                self.failed = false;
                self.last_written = Some(now);
            }
            Err(e) if !self.failed => {
                self.failed = true;
                tracing::warn!(
                    "cannot keep the simulated joints' posture in {}: {e} (a restart will start \
                     from the start posture)",
                    self.path.display()
                );
            }
            Err(_) => {}
        }
    }
}

/// The posture an earlier run of this component kept in `dir`, if any (joint name to position).
/// A file that does not read is set aside and said, not an error: the joints start from the
/// start posture.
pub fn load(dir: &Path) -> Option<HashMap<String, f64>> {
    let path = dir.join(FILE);
    let text = match std::fs::read_to_string(&path) {
        Ok(t) => t,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
        Err(e) => {
            tracing::warn!(
                "cannot read {}: {e}; starting from the start posture",
                path.display()
            );
            return None;
        }
    };
    match serde_json::from_str::<Posture>(&text) {
        Ok(p) if p.version == VERSION => Some(p.joints),
        Ok(p) => {
            tracing::warn!(
                "{} is version {}, not {VERSION}; starting from the start posture",
                path.display(),
                p.version
            );
            None
        }
        Err(e) => {
            let aside = path.with_extension("json.corrupt");
            let _ = std::fs::rename(&path, &aside);
            tracing::warn!(
                "{} does not read ({e}): set aside as {}; starting from the start posture",
                path.display(),
                aside.display()
            );
            None
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use interfaces::msg::body::JointState;

    /// A fresh folder of the test's own.
    fn dir(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("joint-motor-kept-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    fn at(ms: u64) -> Moment {
        Moment::from_duration(Duration::from_millis(ms))
    }

    fn states(neck: f64) -> JointStates {
        JointStates {
            joints: vec![
                JointState {
                    name: "neck_yaw".into(),
                    position: neck,
                    ..Default::default()
                },
                JointState {
                    name: "broken".into(),
                    position: f64::NAN,
                    ..Default::default()
                },
            ],
            ..Default::default()
        }
    }

    #[test]
    fn a_kept_posture_reads_back_and_is_written_at_most_every_200_ms() {
        // The component's state folder does not exist before its first write.
        let dir = dir("read-back").join("joint_motor");
        assert_eq!(load(&dir), None, "nothing kept yet");
        let mut k = Keeper::new(&dir);
        k.offer(&states(0.3), at(0));
        k.offer(&states(0.5), at(199));
        assert_eq!(load(&dir).unwrap()["neck_yaw"], 0.3);
        k.offer(&states(0.5), at(200));
        let p = load(&dir).unwrap();
        assert_eq!(p["neck_yaw"], 0.5);
        assert!(!p.contains_key("broken"), "no NaN kept");
    }

    #[test]
    fn a_file_that_does_not_read_is_set_aside() {
        let dir = dir("corrupt");
        std::fs::write(dir.join(FILE), "{ not json").unwrap();
        assert_eq!(load(&dir), None);
        assert!(dir.join("sim_joints.json.corrupt").exists());
        assert!(!dir.join(FILE).exists());
    }
}
