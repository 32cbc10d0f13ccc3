//! The head RGB-D camera: frame type, drivers and a TUM RGB-D sequence reader/writer.
//!
//! Concepts:
//! - A [`Frame`] is registered colour (RGB8) and depth (`u16` millimetres along the optical
//!   axis, 0 = no measurement) on one pixel grid, with pinhole [`Intrinsics`] and a timestamp in
//!   seconds. The camera frame is the optical frame: z forward, x right, y down.
//! - A driver ([`RgbdDriver`]) yields frames: [`sim::SimDriver`] renders a simulated tabletop
//!   scene (ball, decoys, table, wall, the person's arm) with a structured-light sensor model;
//!   [`playback::PlaybackDriver`] replays a recorded sequence in the TUM RGB-D layout.
//! - Time is always passed in; nothing here reads the wall clock.
//! - The component ([`component`], the `rgbd` binary) wraps a driver and publishes its frames on
//!   `vision/rgbd` ([`convert`] maps [`Frame`] to the bus message); its sim driver moves the ball
//!   by a scripted [`scenario`], or takes it from the simulated world (`sim/ball`) over the
//!   game's scene, with the camera fixed or placed by the robot's joint states through the URDF
//!   ([`world`]), and publishes the ground truth on `sim/ball_truth`.

pub mod component;
pub mod convert;
pub mod kinect;
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
