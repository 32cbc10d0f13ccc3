//! Microphone arrays, for a robot that listens where it looks.
//!
//! - [`ArrayGeometry`]: where the microphones are, from `models/arrays/<name>.toml` or the copies
//!   built into the library ([`ArrayGeometry::builtin`]).
//! - [`direction`] and [`ArrayGeometry::delays_s`]: steering, far field.
//! - [`DelayAndSum`] and [`Mvdr`]: beamformers that turn the array's channels into one enhanced
//!   channel, stream-wise, steered at a direction that may change as the stream goes on.
//! - [`SrpPhat`]: where a sound comes from, over a block of 100-200 ms.
//! - [`sim`]: the channels a plane wave gives, and a room of talkers (plane waves, or a
//!   reverberant room), for tests and simulators.
//! - [`room`]: the channels talkers in a reverberant shoebox room give (image-source method).
//!
//! Frame: x forward, y left, z up (right-handed, ROS REP 103), metres. Azimuth 0 is straight ahead
//! (+x), positive to the left (+y); elevation is positive upwards; angles in radians. All
//! processing is in the far field (a plane wave) at [`SPEED_OF_SOUND_M_S`].

mod beamformer;
mod error;
mod geometry;
mod linalg;
pub mod room;
pub mod sim;
mod srp;
mod stft;

pub use beamformer::{DelayAndSum, Mvdr};
pub use error::ArrayError;
pub use geometry::ArrayGeometry;
pub use srp::{Localization, SrpPhat};

/// The speed of sound in air at about 20 °C (m/s), the one value all of the module uses.
pub const SPEED_OF_SOUND_M_S: f64 = 343.0;

/// The unit vector towards a source at `azimuth_rad` (0 straight ahead, positive to the left) and
/// `elevation_rad` (positive upwards), in the array frame.
pub fn direction(azimuth_rad: f64, elevation_rad: f64) -> [f64; 3] {
    let (sin_az, cos_az) = azimuth_rad.sin_cos();
    let (sin_el, cos_el) = elevation_rad.sin_cos();
    [cos_el * cos_az, cos_el * sin_az, sin_el]
}

/// The audio of an array, one channel per microphone in the geometry's order.
#[derive(Debug, Clone, Copy)]
pub enum Multichannel<'a> {
    /// Signed 16-bit samples, interleaved frame after frame (all channels of the first instant,
    /// then of the next), as PulseAudio gives them. Its length must be a whole number of frames.
    Interleaved(&'a [i16]),
    /// One slice per channel, all of the same length, finite, in any unit.
    Planar(&'a [&'a [f32]]),
}

#[cfg(test)]
mod tests;
