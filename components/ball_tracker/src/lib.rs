//! Ball detection and tracking in RGB-D frames (seed 001 §V.B, the "touch the ball" game).
//!
//! States: **waiting** (no target), **detecting** (colour regions sized against the target),
//! **tracking** (CamShift on a hue-saturation-depth histogram, verified by metric size). See
//! [`tracker`] for the algorithm, [`types`] for the bus-facing output.
//!
//! Conventions: frames are [`camera::Frame`]s (RGB8, depth in mm along the optical axis); 3D
//! output is in the camera optical frame (z forward, x right, y down), metres; time is passed in
//! (seconds), never read from a clock.
//!
//! The component ([`component`], the `ball_tracker` binary) runs the tracker on `vision/rgbd`
//! and publishes `vision/ball` and `vision/ball_events`; [`dr`] places the ball in the world and
//! robot frames through the deep representation and keeps its ball node up to date.

pub mod component;
pub mod dr;
pub mod hsv;
pub mod tracker;
pub mod types;

pub use tracker::{BallTracker, TrackError, TrackerConfig, TrackerStats, equivalent_diameter_m};
pub use types::{Target, TrackEvent, TrackOutput, TrackState, Window};
