//! The speech corpus shared by `bench_speech` (evaluation) and `speech_errors` (tuning): one
//! definition of the voices, so the two sets stay apart, and of how a voice is made.

// Each example uses part of it.
#![allow(dead_code)]

use audio::synth::Voice;

/// The evaluation voices: never used to tune anything.
pub const EVAL_VOICES: [&str; 6] = [
    "en-us",
    "en-gb",
    "en-us+f3",
    "en-gb-scotland",
    "en-us+m3",
    "en-gb+f4",
];
/// The tuning voices (`speech_errors tune`), none of them in [`EVAL_VOICES`].
pub const TUNE_VOICES: [&str; 4] = ["en-gb-x-rp", "en-029", "en-us+m1", "en-gb+f2"];
/// Speaking rates (words per minute); the `i`-th also sets the pitch (see [`voice`]).
pub const SPEEDS: [u32; 3] = [130, 175, 220];

/// Voice `name` at the `si`-th speed of [`SPEEDS`], pitch 35, 45 or 55.
pub fn voice(name: &str, si: usize) -> Voice {
    Voice {
        voice: name.to_string(),
        speed_wpm: SPEEDS[si],
        pitch: 35 + 10 * si as u8,
    }
}

/// Noise before and after each utterance of the corpus (s).
pub const LEAD_S: f64 = 0.6;
pub const TRAIL_S: f64 = 0.8;

/// Where the speech ends in the mixed stream (s): the last sample of the clean speech louder
/// than 300/32768, after the [`LEAD_S`] of noise.
pub fn speech_end_s(speech: &[i16]) -> f64 {
    LEAD_S
        + speech
            .iter()
            .rposition(|x| x.unsigned_abs() > 300)
            .unwrap_or(0) as f64
            / 16000.0
}
