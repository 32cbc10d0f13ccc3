//! The errors of the microphone-array module.

use std::path::PathBuf;

/// What can go wrong with a microphone-array geometry, or with the audio given to a beamformer or
/// a localizer.
#[derive(Debug, thiserror::Error)]
pub enum ArrayError {
    #[error("cannot read the array geometry {path}: {source}")]
    Read {
        path: PathBuf,
        source: std::io::Error,
    },
    /// Not TOML, a missing or unknown key (named in the message), a value of the wrong type.
    #[error("the array geometry {origin} is malformed: {source}")]
    Parse {
        origin: String,
        source: Box<toml::de::Error>,
    },
    #[error("no array geometry {name}: no file {path} and no built-in one (built-in: {builtin})")]
    NotFound {
        name: String,
        path: PathBuf,
        builtin: String,
    },
    #[error("no built-in array geometry {name} (built-in: {builtin})")]
    UnknownBuiltin { name: String, builtin: String },
    #[error("the geometry {name} has {count} microphones: an array has 2 to 8")]
    MicCount { name: String, count: usize },
    #[error("microphone {index} of the geometry {name} has a non-finite coordinate: {position:?}")]
    NonFinitePosition {
        name: String,
        index: usize,
        position: [f64; 3],
    },
    #[error(
        "microphones {first} and {second} of the geometry {name} are {distance_mm:.1} mm apart: \
         two microphones must be at least 5 mm apart"
    )]
    Coincident {
        name: String,
        first: usize,
        second: usize,
        distance_mm: f64,
    },
    #[error("the geometry {name} is {aperture_m:.3} m across: an array is at most 1 m across")]
    Aperture { name: String, aperture_m: f64 },
    #[error("the geometry {name} has a sample rate of {rate_hz} Hz: expected 8000 to 192000 Hz")]
    SampleRate { name: String, rate_hz: u32 },
    #[error("the source has {channels} channels but the geometry {name} has {mics} microphones")]
    ChannelMismatch {
        name: String,
        channels: usize,
        mics: usize,
    },
    #[error(
        "an interleaved buffer of {len} samples is not a whole number of {channels}-channel frames"
    )]
    PartialFrame { len: usize, channels: usize },
    #[error("channel {channel} has {len} samples but channel 0 has {expected}")]
    RaggedChannels {
        channel: usize,
        len: usize,
        expected: usize,
    },
    #[error("sample {index} of channel {channel} is not finite")]
    NonFiniteSample { channel: usize, index: usize },
    #[error("the direction {0:?} is not a finite non-zero vector")]
    BadDirection([f64; 3]),
    #[error("the grid of azimuths is empty or has a non-finite azimuth")]
    BadGrid,
    #[error("the sample rate {0} Hz is not a positive finite number")]
    BadRate(f64),
}
