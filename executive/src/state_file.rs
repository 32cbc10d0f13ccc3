//! A game's resume record in the Executive's state folder (`ROBOCOG_STATE_DIR`, which the launcher
//! keeps across the component's restarts): rewritten atomically (a temporary file renamed over
//! it) whenever the record changes, read back at start. A file that is missing starts the game
//! afresh; one that cannot be read or used is logged (with its path and why) and starts it afresh
//! too: never a crash.

use std::path::{Path, PathBuf};

use interfaces::bus::Counters;

/// A record a game keeps: JSON (one line), and checked when read back: the machine it belongs
/// to, then the record's own [`Record::check`].
pub trait Record: Clone + PartialEq + serde::Serialize + serde::de::DeserializeOwned {
    /// The machine whose record this is.
    const MACHINE: &'static str;

    /// The machine the record says it belongs to.
    fn machine(&self) -> &str;

    /// What else a record read back must satisfy.
    fn check(&self) -> Result<(), String> {
        Ok(())
    }

    /// The record as JSON (one line).
    fn to_json(&self) -> String {
        serde_json::to_string(self).unwrap_or_default()
    }

    /// A record read back, or why it cannot be used.
    fn from_json(text: &str) -> Result<Self, String> {
        let r: Self = serde_json::from_str(text).map_err(|e| e.to_string())?;
        if r.machine() != Self::MACHINE {
            return Err(format!(
                "a record of machine {:?}, not {:?}",
                r.machine(),
                Self::MACHINE
            ));
        }
        r.check()?;
        Ok(r)
    }
}

/// One record file (`<dir>/<name>`); without a folder, nothing is kept.
#[derive(Debug)]
pub struct StateFile<R> {
    path: Option<PathBuf>,
    last: Option<R>,
    warned: bool,
}

impl<R: Record> StateFile<R> {
    pub fn new(dir: Option<&Path>, name: &str) -> StateFile<R> {
        StateFile {
            path: dir.map(|d| d.join(name)),
            last: None,
            warned: false,
        }
    }

    /// Where the record is kept.
    pub fn path(&self) -> Option<&Path> {
        self.path.as_deref()
    }

    /// The record an earlier process left, if any and usable (a bad one is logged and ignored).
    pub fn load(&mut self) -> Option<R> {
        let path = self.path.as_ref()?;
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
                tracing::info!("no game state in {}: starting afresh", path.display());
                return None;
            }
            Err(e) => {
                tracing::warn!(
                    "cannot read the game's state {}: {e}; starting afresh",
                    path.display()
                );
                return None;
            }
        };
        match R::from_json(&text) {
            Ok(r) => {
                tracing::info!(
                    "found the game's state in {}: {}",
                    path.display(),
                    text.trim()
                );
                self.last = Some(r.clone());
                Some(r)
            }
            Err(e) => {
                tracing::warn!(
                    "the game's state {} is unusable ({e}); starting afresh",
                    path.display()
                );
                None
            }
        }
    }

    /// Keeps `record` when it changed (`None`: the game is over, the file goes).
    pub fn save(&mut self, record: Option<R>, counters: &Counters) {
        let Some(path) = &self.path else { return };
        if record == self.last {
            return;
        }
        let result = match &record {
            Some(r) => interfaces::state::write_atomically(path, r.to_json().as_bytes()),
            None => match std::fs::remove_file(path) {
                Err(e) if e.kind() != std::io::ErrorKind::NotFound => Err(e),
                _ => Ok(()),
            },
        };
        match result {
            Ok(()) => self.last = record,
            Err(e) => {
                counters.incr("state_write_errors");
                if !self.warned {
                    self.warned = true;
                    tracing::warn!(
                        "cannot keep the game's state in {}: {e} (a restart would start afresh)",
                        path.display()
                    );
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::coach::machine::resume::Resume;
    use crate::coach::{CoachGame, CoachSettings};
    use std::time::Duration;

    fn dir(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!(
            "executive-state-{tag}-{}-{:?}",
            std::process::id(),
            std::thread::current().id()
        ));
        let _ = std::fs::remove_dir_all(&d);
        d
    }

    fn record() -> Resume {
        let mut g = CoachGame::new(CoachSettings::default()).unwrap();
        g.start(Duration::ZERO);
        g.resume_record()
    }

    #[test]
    fn a_record_is_written_atomically_read_back_and_removed() {
        let d = dir("roundtrip");
        let counters = Counters::default();
        let mut f = StateFile::<Resume>::new(Some(&d), "coach.json");
        assert_eq!(f.load(), None, "no file yet");
        let r = record();
        f.save(Some(r.clone()), &counters);
        let path = d.join("coach.json");
        assert!(path.is_file());
        let names: Vec<_> = std::fs::read_dir(&d)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        assert_eq!(names, ["coach.json"], "no temporary file left");
        // Unchanged: not rewritten.
        std::fs::write(&path, "overwritten by the test").unwrap();
        f.save(Some(r.clone()), &counters);
        assert_eq!(
            std::fs::read_to_string(&path).unwrap(),
            "overwritten by the test"
        );
        std::fs::write(&path, r.to_json()).unwrap();
        let mut again = StateFile::<Resume>::new(Some(&d), "coach.json");
        assert_eq!(again.load(), Some(r));
        again.save(None, &counters);
        assert!(!path.exists());
        assert!(counters.snapshot().is_empty(), "{:?}", counters.snapshot());
        let _ = std::fs::remove_dir_all(&d);
    }

    #[test]
    fn a_corrupt_foreign_or_unreadable_record_starts_afresh() {
        let d = dir("corrupt");
        std::fs::create_dir_all(&d).unwrap();
        let path = d.join("coach.json");
        let mut f = StateFile::<Resume>::new(Some(&d), "coach.json");
        for bad in [
            "",
            "{",
            "\u{0}\u{1}garbage",
            r#"{"machine":"coach"}"#,
            &record().to_json().replace("\"coach\"", "\"touch\""),
            &record()
                .to_json()
                .replace("coach/waiting_for_game", "coach/dancing"),
        ] {
            std::fs::write(&path, bad).unwrap();
            assert_eq!(f.load(), None, "{bad:?}");
        }
        // A touch record is no coach record, and the other way round.
        let touch = StateFile::<crate::touch::resume::Resume>::new(Some(&d), "coach.json");
        std::fs::write(&path, record().to_json()).unwrap();
        assert_eq!({ touch }.load(), None);
        // A folder where the file should be: unreadable, and unwritable.
        std::fs::remove_file(&path).unwrap();
        std::fs::create_dir_all(path.join("x")).unwrap();
        assert_eq!(f.load(), None);
        let counters = Counters::default();
        f.save(Some(record()), &counters);
        assert_eq!(
            counters.snapshot(),
            [("state_write_errors".to_string(), 1)],
            "counted, not fatal"
        );
        // No folder at all: nothing kept, nothing read.
        let mut none = StateFile::<Resume>::new(None, "coach.json");
        none.save(Some(record()), &counters);
        assert_eq!(none.load(), None);
        let _ = std::fs::remove_dir_all(&d);
    }
}
