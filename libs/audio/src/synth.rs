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
//!
//! A voice named `flite:<name>` (`flite:slt`, `flite:rms`, `flite:awb`, `flite:kal`; `flite -lv`
//! lists them) is spoken by the `flite` program instead (Debian's `flite`): voices of another
//! synthesizer family, built from recordings of real speakers, reserved for evaluation (the
//! speech model is adapted and tuned on espeak-ng alone). Its speed scales flite's durations
//! against 175 words per minute; its pitch moves flite's mean pitch (50: the voice's own).
//!
//! A voice named `festival:<name>` (`festival:kal_diphone`, `festival:ked_diphone`,
//! `festival:cmu_us_slt_arctic_hts`: Debian's `festival` with `festvox-kallpc16k`,
//! `festvox-kdlpc16k`, `festvox-us-slt-hts`) is spoken by festival's `text2wave`: a third family,
//! also for evaluation only, with speed and pitch as for flite.

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
    #[error(
        "cannot run the synthesizer (espeak-ng, flite or festival, Debian packages of those names): {0}"
    )]
    Spawn(std::io::Error),
    #[error("espeak-ng failed: {0}")]
    Failed(String),
    #[error("espeak-ng output: {0}")]
    Wav(#[from] WavError),
    #[error("nothing to say")]
    Empty,
}

/// Synthesize `text` with `voice`; the program's native rate (22 050 Hz mono for espeak-ng,
/// 16 000 or 8 000 Hz for flite's voices).
pub fn synthesize(text: &str, voice: &Voice) -> Result<Pcm, SynthError> {
    if text.trim().is_empty() {
        return Err(SynthError::Empty);
    }
    if let Some(name) = voice.voice.strip_prefix("flite:") {
        return flite(text, name, voice);
    }
    if let Some(name) = voice.voice.strip_prefix("festival:") {
        return festival(text, name, voice);
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

/// `text` said by flite's voice `name` (see the module doc).
fn flite(text: &str, name: &str, voice: &Voice) -> Result<Pcm, SynthError> {
    // flite speaks an unknown voice's text in its default voice, without a word.
    check_known("flite", name, &flite_voices()?, "flite -lv")?;
    let stretch = stretch(voice);
    let pcm = through_file("flite", "flite", name, text, |text_file, wav_file| {
        let mut c = Command::new("flite");
        c.args(["-voice", name, "--setf"])
            .arg(format!("duration_stretch={stretch:.3}"))
            .arg("-f")
            .arg(text_file)
            .arg("-o")
            .arg(wav_file);
        c
    })?;
    Ok(shift_pitch(pcm, voice.pitch))
}

/// `text` said by festival's voice `name` (see the module doc), through `text2wave`.
fn festival(text: &str, name: &str, voice: &Voice) -> Result<Pcm, SynthError> {
    // Festival too speaks an unknown voice's text in its default voice, and exits 0.
    check_known(
        "festival",
        name,
        &festival_voices()?,
        "festival's voice.list",
    )?;
    let stretch = stretch(voice);
    let pcm = through_file(
        "festival",
        "text2wave",
        name,
        text,
        |text_file, wav_file| {
            let mut c = Command::new("text2wave");
            c.arg("-o")
                .arg(wav_file)
                .arg("-eval")
                .arg(format!("(voice_{name})"))
                .arg("-eval")
                .arg(format!("(Parameter.set 'Duration_Stretch {stretch:.3})"))
                .arg(text_file);
            c
        },
    )?;
    Ok(shift_pitch(pcm, voice.pitch))
}

/// How much longer than at 175 words per minute `voice` speaks.
fn stretch(voice: &Voice) -> f64 {
    175.0 / f64::from(voice.speed_wpm.clamp(80, 450))
}

fn check_known(family: &str, name: &str, known: &[String], how: &str) -> Result<(), SynthError> {
    if known.iter().any(|v| v == name) {
        return Ok(());
    }
    Err(SynthError::Failed(format!(
        "{family} has no voice {name:?} (it has: {}; {how} lists them)",
        known.join(", ")
    )))
}

/// Runs `program` (made by `command` from a text file and the WAV file to write) on `text`,
/// through files of its own (flite writes its header after the samples, which a pipe cannot
/// take; festival's `text2wave` reads a file), and reads the WAV it wrote. `package` is the
/// Debian package that has the program.
fn through_file(
    package: &str,
    program: &str,
    name: &str,
    text: &str,
    command: impl FnOnce(&std::path::Path, &std::path::Path) -> Command,
) -> Result<Pcm, SynthError> {
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let dir = std::env::temp_dir();
    let stem = format!("robocog-{program}-{}-{n}", std::process::id());
    let file = dir.join(format!("{stem}.wav"));
    let text_file = dir.join(format!("{stem}.txt"));
    std::fs::write(&text_file, text).map_err(SynthError::Spawn)?;
    let out = command(&text_file, &file).stdin(Stdio::null()).output();
    let _ = std::fs::remove_file(&text_file);
    let out = out.map_err(|e| {
        SynthError::Spawn(std::io::Error::new(
            e.kind(),
            format!("cannot run {program} (install the Debian package {package}): {e}"),
        ))
    })?;
    let bytes = std::fs::read(&file);
    let _ = std::fs::remove_file(&file);
    if !out.status.success() {
        return Err(SynthError::Failed(format!(
            "{program} (voice {name}): {}: {}",
            out.status,
            String::from_utf8_lossy(&out.stderr).trim()
        )));
    }
    let bytes = bytes.map_err(|e| {
        SynthError::Failed(format!("{program} (voice {name}) wrote no sound ({e})"))
    })?;
    Ok(wav::parse(&bytes)?)
}

/// Flite and festival have no pitch setting for every voice: the speech is resampled by the
/// pitch's ratio (50: unchanged) and played at the voice's rate, which moves the pitch (and the
/// formants with it, as a smaller or larger speaker's) and the speed by the same ratio.
fn shift_pitch(mut pcm: Pcm, pitch: u8) -> Pcm {
    if pitch == 50 {
        return pcm;
    }
    let ratio = 2f64.powf((f64::from(pitch.min(99)) - 50.0) / 100.0);
    let rate = pcm.sample_rate_hz;
    pcm.samples = crate::signal::resample(
        &pcm.to_mono(),
        (f64::from(rate) * ratio).round() as u32,
        rate,
    );
    pcm.channels = 1;
    pcm
}

/// What `program` (from the Debian package `package`) prints on its standard output.
fn ask(program: &str, package: &str, args: &[&str]) -> Result<String, SynthError> {
    let out = Command::new(program)
        .args(args)
        .stdin(Stdio::null())
        .output()
        .map_err(|e| {
            SynthError::Spawn(std::io::Error::new(
                e.kind(),
                format!("cannot run {program} (install the Debian package {package}): {e}"),
            ))
        })?;
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// The voices festival has (`(voice.list)`), asked once.
fn festival_voices() -> Result<Vec<String>, SynthError> {
    static VOICES: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
    if let Some(v) = VOICES.get() {
        return Ok(v.clone());
    }
    let out = ask("festival", "festival", &["--batch", "(print (voice.list))"])?;
    let voices: Vec<String> = out
        .trim()
        .trim_start_matches('(')
        .trim_end_matches(')')
        .split_whitespace()
        .map(str::to_string)
        .collect();
    Ok(VOICES.get_or_init(|| voices).clone())
}

/// The voices the `flite` program has (`flite -lv`), asked once.
fn flite_voices() -> Result<Vec<String>, SynthError> {
    static VOICES: std::sync::OnceLock<Vec<String>> = std::sync::OnceLock::new();
    if let Some(v) = VOICES.get() {
        return Ok(v.clone());
    }
    let out = ask("flite", "flite", &["-lv"])?;
    let voices: Vec<String> = out
        .split_once(':')
        .map(|(_, list)| list.split_whitespace().map(str::to_string).collect())
        .unwrap_or_default();
    Ok(VOICES.get_or_init(|| voices).clone())
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

    /// Flite's voices speak (at the asked speed, a higher pitch shorter), each at its own rate,
    /// and a voice flite does not have is a clear error.
    #[test]
    fn flite_speaks_its_voices_and_refuses_one_it_has_not() {
        let slt = |speed_wpm, pitch| Voice {
            voice: "flite:slt".into(),
            speed_wpm,
            pitch,
        };
        let normal = synthesize("-- touch the ball", &slt(175, 50)).unwrap();
        assert_eq!((normal.sample_rate_hz, normal.channels), (16_000, 1));
        assert!(
            normal.duration_s() > 0.5 && normal.duration_s() < 4.0,
            "{}",
            normal.duration_s()
        );
        let slow = synthesize("touch the ball", &slt(100, 50)).unwrap();
        assert!(slow.duration_s() > normal.duration_s() * 1.3);
        let high = synthesize("touch the ball", &slt(175, 80)).unwrap();
        assert!(high.duration_s() < normal.duration_s() * 0.95);
        let kal = synthesize_16k(
            "touch the ball",
            &Voice {
                voice: "flite:kal".into(),
                ..slt(175, 50)
            },
        )
        .unwrap();
        assert!(crate::signal::active_power(&kal) > 1e-4);
        let e = synthesize(
            "touch the ball",
            &Voice {
                voice: "flite:nobody".into(),
                ..slt(175, 50)
            },
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("nobody"), "{e}");
    }

    /// Festival speaks its voices at the asked speed and at 16 kHz once resampled; a voice it
    /// does not have is a clear error, not its default voice.
    #[test]
    fn festival_speaks_its_voices_and_refuses_one_it_has_not() {
        let kal = |speed_wpm, name: &str| Voice {
            voice: format!("festival:{name}"),
            speed_wpm,
            pitch: 50,
        };
        let normal = synthesize_16k("touch the ball", &kal(175, "kal_diphone")).unwrap();
        let slow = synthesize_16k("touch the ball", &kal(100, "kal_diphone")).unwrap();
        assert!(
            slow.len() as f64 > normal.len() as f64 * 1.3,
            "{} {}",
            slow.len(),
            normal.len()
        );
        assert!(crate::signal::active_power(&normal) > 1e-4);
        let slt = synthesize("touch the ball", &kal(175, "cmu_us_slt_arctic_hts")).unwrap();
        assert!(slt.duration_s() > 0.5 && slt.duration_s() < 4.0);
        let e = synthesize("touch the ball", &kal(175, "nobody"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("nobody") && e.contains("kal_diphone"), "{e}");
    }
}
