//! Ball tracking messages (the "touch the ball" game, seed 001 §V.B) and the sim's ground truth.
//!
//! Conventions:
//! - Pixel coordinates `(u, v)` = (column right, row down), pixel centres at integer coordinates.
//! - 3D points in the camera **optical** frame (z forward, x right, y down), metres, unless the
//!   field name says `world` (world frame: z up, metres).
//! - Colour as HSV: hue in degrees `[0, 360)`, saturation in `[0, 1]`.
//! - Every per-frame message carries the stamp and frame of the [`super::vision::RgbdFrame`] it
//!   was computed from (`header.stamp_ns`, `header.frame_id`) and that frame's sequence number
//!   (`frame_seq`), so consumers can pair a track with its image or with the sim's ground truth.

use crate::header::Header;
use serde::{Deserialize, Serialize};

/// What the ball tracker looks for: an untextured ball of one colour and size. On
/// `vision/ball_target`; `active = false` clears the target (the tracker goes back to waiting).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BallTarget {
    pub header: Header,
    /// `false`: no target (the other fields are ignored).
    pub active: bool,
    /// HSV hue of the ball's colour, degrees `[0, 360)`.
    pub hue_deg: f32,
    /// HSV saturation of the ball's colour, `[0, 1]`.
    pub saturation: f32,
    /// Ball diameter, m.
    pub diameter_m: f64,
}

/// The tracker's state (seed 001 §V.B).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BallTrackState {
    /// No target: frames are ignored.
    #[default]
    Waiting,
    /// Searching the whole image for the target.
    Detecting,
    /// Following the ball.
    Tracking,
}

/// An axis-aligned image window, pixels: columns `x .. x + width`, rows `y .. y + height`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct PixelWindow {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

/// The tracker's result for one frame, on `vision/ball` (one per processed frame, found or not).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BallTrack {
    /// Stamp and frame (the camera's optical frame) of the source image.
    pub header: Header,
    /// `header.seq` of the source [`super::vision::RgbdFrame`].
    pub frame_seq: u64,
    /// State after this frame.
    pub state: BallTrackState,
    /// Whether the ball was found in this frame (`window`, `centre_px`, `diameter_m` valid).
    pub found: bool,
    /// Tracking window, pixels.
    pub window: PixelWindow,
    /// Centroid of the ball's pixels `(u, v)`, pixels.
    pub centre_px: [f64; 2],
    /// Whether `centre_m` is valid (found, and depth was available).
    pub has_centre_m: bool,
    /// Ball centre in the camera optical frame, m.
    #[serde(with = "crate::msg::ros::point")]
    pub centre_m: [f64; 3],
    /// Diameter measured from colour area and depth, m (0 when not found).
    pub diameter_m: f64,
    /// How sure the tracker is that this is the ball, `[0, 1]`; 0 when not found.
    pub confidence: f64,
    /// Whether `centre_world_m` and `centre_robot_m` are valid (the centre was measured and the
    /// DR knew the camera's pose at the frame's stamp).
    pub has_centre_world: bool,
    /// Ball centre in the DR's `world` frame (z up), m.
    #[serde(with = "crate::msg::ros::point")]
    pub centre_world_m: [f64; 3],
    /// Ball centre in the robot's base frame (`base_footprint`: x forward, z up), m.
    #[serde(with = "crate::msg::ros::point")]
    pub centre_robot_m: [f64; 3],
}

/// What happened to the track.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum BallEventKind {
    /// Detection found the ball; tracking starts.
    #[default]
    Detected,
    /// The ball left the image (the track was at the border when it stopped matching). Comes
    /// once per track, before [`BallEventKind::Lost`].
    OutOfView,
    /// Tracking failed for too many frames; the tracker detects again.
    Lost,
    /// Detection found nothing for too long; the target was dropped (back to waiting).
    DetectionTimedOut,
}

/// A change of the track, on `vision/ball_events`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BallEvent {
    /// Stamp and frame of the image where it happened.
    pub header: Header,
    /// `header.seq` of that [`super::vision::RgbdFrame`].
    pub frame_seq: u64,
    pub kind: BallEventKind,
    /// The tracker's state after the frame.
    pub state: BallTrackState,
}

/// Ground truth of the simulated ball, one per simulated frame, on `sim/ball_truth` (published
/// by the `rgbd` sim driver right after the frame it describes).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BallTruth {
    /// Stamp and frame (the camera's optical frame) of the frame it describes.
    pub header: Header,
    /// `header.seq` of that [`super::vision::RgbdFrame`].
    pub frame_seq: u64,
    /// Ball centre in the camera optical frame, m.
    #[serde(with = "crate::msg::ros::point")]
    pub centre_m: [f64; 3],
    /// Ball centre in the world frame (z up), m.
    #[serde(with = "crate::msg::ros::point")]
    pub centre_world_m: [f64; 3],
    /// Ball diameter, m.
    pub diameter_m: f64,
    /// Whether the whole ball projects inside the image, in front of the camera.
    pub in_view: bool,
}

/// The simulated world's ball (topic `sim/ball`), published by the simulated person at the
/// camera's rate or faster: where the person holds or puts the ball. The `rgbd` sim driver
/// renders it; tests compare the tracker's output with it.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SimBall {
    pub header: Header,
    /// `false`: the ball is not in the scene (put away).
    pub present: bool,
    /// Centre in the world frame (z up), m.
    #[serde(with = "crate::msg::ros::point")]
    pub centre_world_m: [f64; 3],
    /// Velocity in the world frame, m/s.
    #[serde(with = "crate::msg::ros::vector3")]
    pub velocity_world_mps: [f64; 3],
    /// Diameter, m.
    pub diameter_m: f64,
    /// HSV hue of its colour, degrees `[0, 360)`.
    pub hue_deg: f32,
    /// HSV saturation of its colour, `[0, 1]`.
    pub saturation: f32,
    /// Whether the person's hand holds it (the renderer draws the hand and arm).
    pub held: bool,
}
