//! The head RGB-D camera component.
//!
//! The component ([`component`], the `rgbd` binary) wraps a driver of the `camera` library (the
//! simulated camera, TUM playback) or the Kinect driver ([`kinect`], libfreenect) and publishes its
//! frames on `vision/rgbd`, the camera's state on `vision/camera_status`, and with the simulated
//! camera the ground truth on `sim/ball_truth`.

pub mod component;
pub mod kinect;
