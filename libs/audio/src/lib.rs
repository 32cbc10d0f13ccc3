//! # audio: sound for robocog's speech processes, simulators and tools
//!
//! Not a process: the speech generator, the speech recognizer (and its adaptation tools), the
//! simulated person of `loki_world` and the benchmarks share it.
//! - [`wav`]: reading and writing PCM WAV files ([`wav::Pcm`]).
//! - [`signal`]: resampling, mono mixdown helpers, noise of several colours (and a fan), babble
//!   of other talkers, reverberant rooms, SNR mixing, power.
//! - [`synth`]: speech synthesis with the espeak-ng program, at its rate or at 16 kHz.
//! - [`array`]: microphone arrays: their geometries (`models/arrays/`), delay-and-sum and MVDR
//!   beamforming, SRP-PHAT sound source localization, and a plane-wave simulator.

pub mod array;
pub mod signal;
pub mod synth;
pub mod wav;
