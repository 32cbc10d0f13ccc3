//! How far into the microphone's stream the recognizer has heard everything, kept in its state
//! folder. A recognizer killed in the middle of a word is started again and catches up
//! ([`interfaces::Bus::recent`]) on the audio after that mark: the word is heard, not lost, and
//! no word it had already decoded is heard twice. The mark moves only while no speech is open
//! and no utterance waits for a reader. What the microphone no longer keeps
//! ([`interfaces::topics::AUDIO_IN_KEPT`]) is lost, and said so. A new launch starts with a fresh
//! state folder, so from the live stream.

use std::path::{Path, PathBuf};

/// The file in the state folder.
pub const FILE: &str = "heard.json";
/// The mark is written when it moved this far (ns of stream time), or at an utterance's end.
pub const EVERY_NS: i64 = 250_000_000;

#[derive(Debug, serde::Serialize, serde::Deserialize)]
struct Mark {
    version: u32,
    /// Every chunk stamped up to this (the publisher's clock, ns) was heard.
    heard_until_ns: i64,
}

const VERSION: u32 = 1;

/// The mark kept in `dir`, if any (a file that does not read is left alone, and said).
pub fn load(dir: &Path) -> Option<i64> {
    let path = dir.join(FILE);
    let bytes = std::fs::read(&path).ok()?;
    match serde_json::from_slice::<Mark>(&bytes) {
        Ok(m) if m.version == VERSION => Some(m.heard_until_ns),
        Ok(m) => {
            tracing::warn!(
                "{}: version {} (want {VERSION}), ignored",
                path.display(),
                m.version
            );
            None
        }
        Err(e) => {
            tracing::warn!("{}: {e}; starting from the live stream", path.display());
            None
        }
    }
}

/// Writes the mark (`interfaces::state::write_atomically`).
#[derive(Debug)]
pub struct Keeper {
    path: PathBuf,
    written: Option<i64>,
    failed: bool,
}

impl Keeper {
    pub fn new(dir: &Path) -> Self {
        Self {
            path: dir.join(FILE),
            written: None,
            failed: false,
        }
    }

    /// Everything up to `mark_ns` was heard: written when it moved [`EVERY_NS`] since the last
    /// write, or at once when `now` (an utterance just ended).
    pub fn offer(&mut self, mark_ns: i64, now: bool) {
        if self
            .written
            .is_some_and(|w| mark_ns <= w || (!now && mark_ns - w < EVERY_NS))
        {
            return;
        }
        let mark = Mark {
            version: VERSION,
            heard_until_ns: mark_ns,
        };
        let done = serde_json::to_vec(&mark)
            .map_err(std::io::Error::other)
            .and_then(|bytes| interfaces::state::write_atomically(&self.path, &bytes));
        match done {
            Ok(()) => {
                self.failed = false;
                self.written = Some(mark_ns);
            }
            Err(e) if !self.failed => {
                self.failed = true;
                tracing::warn!(
                    "cannot keep how far the stream was heard in {}: {e} (a restart will not \
                     catch up on what was said meanwhile)",
                    self.path.display()
                );
            }
            Err(_) => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mark_is_kept_as_it_moves_and_read_back() {
        let dir = std::env::temp_dir().join(format!("heard-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let state = dir.join("speech_recognition");
        assert_eq!(load(&state), None, "a fresh state folder: the live stream");
        let mut k = Keeper::new(&state);
        k.offer(1_000_000_000, false);
        assert_eq!(
            load(&state),
            Some(1_000_000_000),
            "the first mark makes the folder"
        );
        // Small moves wait; a larger one, or an utterance's end, is written.
        k.offer(1_100_000_000, false);
        assert_eq!(load(&state), Some(1_000_000_000));
        k.offer(1_200_000_000, true);
        assert_eq!(load(&state), Some(1_200_000_000));
        k.offer(1_500_000_000, false);
        assert_eq!(load(&state), Some(1_500_000_000));
        // Never back.
        k.offer(1_400_000_000, true);
        assert_eq!(load(&state), Some(1_500_000_000));
        // A file that does not read is no mark.
        std::fs::write(state.join(FILE), b"{not json").unwrap();
        assert_eq!(load(&state), None);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
