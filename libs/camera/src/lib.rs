//! RGB-D frames for robocog: not a process, the code the camera component, the ball tracker, the
//! simulators and the benchmarks share.
//!
//! Concepts:
//! - A [`Frame`] is registered colour (RGB8) and depth (`u16` millimetres along the optical
//!   axis, 0 = no measurement) on one pixel grid, with pinhole [`Intrinsics`] and a timestamp in
//!   seconds. The camera frame is the optical frame: z forward, x right, y down. [`convert`] maps
//!   a [`Frame`] to the bus message and reads one in place.
//! - A driver ([`RgbdDriver`]) yields frames: [`sim::SimDriver`] renders a simulated tabletop
//!   scene (ball, decoys, table, wall, the person's arm) with a structured-light sensor model;
//!   [`playback::PlaybackDriver`] replays a recorded sequence in the TUM RGB-D layout. The ball
//!   moves by a scripted [`scenario`], or comes from the simulated world over the game's scene,
//!   with the camera placed by the robot's joint states through the URDF ([`world`]).
//! - Time is always passed in; nothing here reads the wall clock.

pub mod convert;
pub mod playback;
pub mod scenario;
pub mod sim;
pub mod types;
pub mod world;

pub use types::{Frame, FrameError, Intrinsics};

/// A source of RGB-D frames.
pub trait RgbdDriver {
    /// The next frame, or `Ok(None)` when the source is exhausted. `now_s` is the caller's clock
    /// (s): the sim renders the scene at that time; playback ignores it and returns recorded
    /// timestamps (pacing is the caller's job, see [`playback::PlaybackMode`]).
    fn next_frame(&mut self, now_s: f64) -> Result<Option<Frame>, DriverError>;
}

/// Errors from a driver.
#[derive(Debug, thiserror::Error)]
pub enum DriverError {
    /// Reading a recorded sequence failed.
    #[error(transparent)]
    Playback(#[from] playback::PlaybackError),
}
