//! Text to speech with the `espeak-ng` program: it writes a 22 050 Hz mono 16-bit WAV on stdout,
//! which is parsed and (optionally) resampled here.
//!
//! - `voice`: an espeak-ng voice name (`en-us`, `en-gb`, `en-gb-scotland`, `en-us+f3` for a
//!   female variant, ...; `espeak-ng --voices=en` lists them).
//! - `speed_wpm`: words per minute (espeak-ng's default is 175, range 80–450).
//! - `pitch`: 0–99 (default 50).
//!
//! The text goes in on stdin, so a text starting with `-` is never taken for an option.
//! espeak-ng 1.51 falls back to its default voice for an unknown voice name without an error.

use crate::wav::{self, Pcm, WavError};
use std::io::Write;
use std::process::{Command, Stdio};

/// How to speak.
#[derive(Debug, Clone, PartialEq)]
pub struct Voice {
    pub voice: String,
    pub speed_wpm: u32,
    pub pitch: u8,
}

impl Default for Voice {
    fn default() -> Self {
        Self {
            voice: "en-us".into(),
            speed_wpm: 160,
            pitch: 50,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    #[error("cannot run espeak-ng (install the Debian package espeak-ng): {0}")]
    Spawn(std::io::Error),
    #[error("espeak-ng failed: {0}")]
    Failed(String),
    #[error("espeak-ng output: {0}")]
    Wav(#[from] WavError),
    #[error("nothing to say")]
    Empty,
}

/// Synthesize `text` with `voice`; the program's native rate (22 050 Hz mono).
pub fn synthesize(text: &str, voice: &Voice) -> Result<Pcm, SynthError> {
    if text.trim().is_empty() {
        return Err(SynthError::Empty);
    }
    let mut child = Command::new("espeak-ng")
        .args([
            "--stdout",
            "-v",
            &voice.voice,
            "-s",
            &voice.speed_wpm.clamp(80, 450).to_string(),
            "-p",
            &voice.pitch.min(99).to_string(),
        ])
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(SynthError::Spawn)?;
    if let Some(mut stdin) = child.stdin.take() {
        stdin
            .write_all(text.as_bytes())
            .map_err(SynthError::Spawn)?;
    }
    let out = child.wait_with_output().map_err(SynthError::Spawn)?;
    if !out.status.success() || !out.stderr.is_empty() && out.stdout.len() < 44 {
        return Err(SynthError::Failed(format!(
            "{}: {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    let pcm = wav::parse(&out.stdout)?;
    Ok(pcm)
}

/// Synthesize and convert to 16 kHz mono (what the recognizer takes).
pub fn synthesize_16k(text: &str, voice: &Voice) -> Result<Vec<i16>, SynthError> {
    let pcm = synthesize(text, voice)?;
    Ok(crate::signal::resample(
        &pcm.to_mono(),
        pcm.sample_rate_hz,
        16_000,
    ))
}

/// A background talker (for [`crate::signal::babble`]): `voice` says every one of `sentences`
/// in turn, starting at sentence `first`, with a breath (0.2 s of silence) after each; 16 kHz
/// mono.
pub fn talker(voice: &Voice, sentences: &[&str], first: usize) -> Result<Vec<i16>, SynthError> {
    let mut out = Vec::new();
    for i in 0..sentences.len() {
        out.extend(synthesize_16k(
            sentences[(i + first) % sentences.len()],
            voice,
        )?);
        out.extend(std::iter::repeat_n(0i16, 3200));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn espeak_speaks_at_the_asked_speed() {
        let slow = synthesize(
            "touch the ball",
            &Voice {
                speed_wpm: 100,
                ..Voice::default()
            },
        )
        .unwrap();
        let fast = synthesize(
            "touch the ball",
            &Voice {
                speed_wpm: 250,
                ..Voice::default()
            },
        )
        .unwrap();
        assert_eq!(slow.channels, 1);
        assert!(
            slow.duration_s() > 0.5 && slow.duration_s() < 4.0,
            "{}",
            slow.duration_s()
        );
        assert!(fast.duration_s() < slow.duration_s() * 0.75);
        let a = synthesize_16k("-- a dash first", &Voice::default()).unwrap();
        assert!(crate::signal::active_power(&a) > 1e-4);
        assert!(matches!(
            synthesize("  ", &Voice::default()),
            Err(SynthError::Empty)
        ));
    }
}
