//! # speech_recognition: grammar-constrained recognition with a confidence score
//!
//! Audio is a continuous 16 000 Hz mono signed 16-bit stream. The end-pointer ([`vad`]) cuts
//! utterances out of it; each is decoded by PocketSphinx (the Debian `pocketsphinx-en-us` model,
//! or a copy MAP-adapted by [`adapt`]: [`model`] says which) twice, both searches fed while the
//! person still speaks so that only the end of the search remains after the end-pointer's cut:
//! constrained by the game's JSGF grammar ([`grammar`], files in `grammars/`), and by a loop of
//! filler words that stands for anything else (the garbage model, [`garbage`]). The
//! posterior of the command against the garbage path is the confidence ([`confidence`]). The
//! transcription is mapped to a command of the catalog (`interfaces::msg::command`), or marked
//! out of grammar when the confidence is under the rejection threshold.
//!
//! The component ([`component`]) reads `audio/in` (or `--wav FILE`) and publishes
//! `speech/utterance`. A microphone array's channels are beamformed first ([`beam`]), steered at
//! the person the deep representation holds ([`steer`]); in a hall
//! where everyone talks, only what is heard while the operator holds a talk key is speech
//! ([`talk`], `--push-to-talk`).
//!
//! The decoder runs with wider beams and without its own voice detection (`--noise-robust`, on
//! by default). Opt-in (`--denoise`): a Wiener filter ([`denoise`]) lowers the background noise
//! before decoding, its estimate taken from the quiet just before the speech; the adapted model
//! has not seen its output, so it is off by default.
//!
//! A second program, `speech_model` (`src/bin/`), builds the adapted acoustic model.

pub mod adapt;
pub mod array_wav;
pub mod beam;
pub mod component;
pub mod confidence;
pub mod denoise;
pub mod garbage;
pub mod grammar;
pub mod heard;
mod intake;
pub mod model;
pub mod recognizer;
pub mod steer;
pub mod talk;
pub mod vad;

pub use recognizer::{Recognized, Recognizer, RecognizerConfig, RecognizerError};
