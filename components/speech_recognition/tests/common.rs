#![allow(dead_code, clippy::expect_used)] // test support: a panic is how a test fails
//! Test audio: commands spoken by espeak-ng in several voices, speeds and pitches, mixed with
//! noise at a chosen SNR.

use audio::signal::{NoiseKind, NoiseRng, mix_at_snr};
use audio::synth::{Voice, synthesize_16k};

pub fn voice(name: &str, speed_wpm: u32, pitch: u8) -> Voice {
    Voice {
        voice: name.into(),
        speed_wpm,
        pitch,
    }
}

/// The voices of the tests: accents, a female variant, speeds, pitches.
pub fn voices() -> Vec<Voice> {
    vec![
        voice("en-us", 160, 50),
        voice("en-gb", 140, 40),
        voice("en-us+f3", 180, 60),
        voice("en-gb-scotland", 150, 50),
        voice("en-us", 220, 30),
    ]
}

/// `text` spoken by `v`, between 0.6 s of noise before and 0.8 s after, at `snr_db`.
pub fn spoken(text: &str, v: &Voice, snr_db: f64, seed: u64) -> Vec<i16> {
    let speech = synthesize_16k(text, v).expect("espeak-ng speaks");
    mix_at_snr(
        &speech,
        snr_db,
        NoiseKind::White,
        0.6,
        0.8,
        &mut NoiseRng::new(seed),
    )
}
