//! Bus-facing data types of the ball tracker (plain serde structs, meant to move to `interfaces`).
//!
//! Conventions: pixel coordinates `(u, v)` = (column right, row down), pixel centres at integer
//! coordinates; 3D points in the camera **optical** frame (z forward, x right, y down), metres;
//! hue in degrees `[0, 360)`, saturation in `[0, 1]` (HSV); time in seconds.

use serde::{Deserialize, Serialize};

use crate::tracker::TrackError;

/// What to look for: an untextured ball of one colour and size (seed 001 §V.B).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Target {
    /// HSV hue of the ball's albedo, degrees `[0, 360)`.
    pub hue_deg: f32,
    /// HSV saturation of the ball's albedo, `[0, 1]`.
    pub saturation: f32,
    /// Ball diameter, m.
    pub diameter_m: f64,
}

impl Target {
    /// The target with its hue brought into `[0, 360)`, or why it cannot be tracked.
    pub fn checked(self) -> Result<Target, TrackError> {
        if !(self.hue_deg.is_finite() && (0.0..=1.0).contains(&self.saturation)) {
            return Err(TrackError::InvalidTarget(format!(
                "hue {} deg, saturation {} (needs finite hue, saturation in [0, 1])",
                self.hue_deg, self.saturation
            )));
        }
        if !(self.diameter_m.is_finite() && self.diameter_m > 0.0) {
            return Err(TrackError::InvalidTarget(format!(
                "diameter {} m (needs > 0)",
                self.diameter_m
            )));
        }
        Ok(Target {
            hue_deg: self.hue_deg.rem_euclid(360.0),
            ..self
        })
    }
}

/// The tracker's state (seed 001 §V.B).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackState {
    /// No target description: nothing is searched.
    Waiting,
    /// Searching the whole image for a region matching the target's colour and size.
    Detecting,
    /// Following the ball with CamShift on an HSD histogram.
    Tracking,
}

/// An axis-aligned image window, pixels: columns `x .. x + width`, rows `y .. y + height`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct Window {
    /// First column.
    pub x: u32,
    /// First row.
    pub y: u32,
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
}

/// Something that happened this frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TrackEvent {
    /// Detection found the ball; tracking starts.
    BallDetected,
    /// The track was near the image border when it stopped matching: the ball left the view.
    /// Emitted once per track, before [`TrackEvent::BallLost`].
    BallOutOfView,
    /// Tracking failed for too many frames; back to detecting.
    BallLost,
    /// Detection found nothing for too long; back to waiting for a new target.
    DetectionTimedOut,
}

/// The tracker's result for one frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TrackOutput {
    /// The time passed in with the frame, s.
    pub time_s: f64,
    /// State after processing the frame.
    pub state: TrackState,
    /// The tracking window, when the ball was found in this frame.
    pub window: Option<Window>,
    /// Centroid of the ball's pixels, pixels `(u, v)`, when found.
    pub centre_px: Option<[f64; 2]>,
    /// Ball centre in the camera optical frame, m, when found and depth was available.
    pub centre_m: Option<[f64; 3]>,
    /// Diameter measured from colour area and depth, m, when found.
    pub measured_diameter_m: Option<f64>,
    /// How sure the tracker is that this is the ball, `[0, 1]`, 0 when not found: the size match
    /// (1 at the target's diameter, 0 at the size tolerance) times the depth support (share of
    /// the ball's pixels with depth, full from 80 %).
    pub confidence: f64,
    /// Events of this frame, in order.
    pub events: Vec<TrackEvent>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn output_serialises_with_snake_case_enums() {
        let out = TrackOutput {
            time_s: 1.5,
            state: TrackState::Tracking,
            window: Some(Window {
                x: 1,
                y: 2,
                width: 3,
                height: 4,
            }),
            centre_px: Some([10.0, 20.0]),
            centre_m: Some([0.1, 0.2, 1.0]),
            measured_diameter_m: Some(0.1),
            confidence: 0.9,
            events: vec![TrackEvent::BallOutOfView, TrackEvent::BallLost],
        };
        let json = serde_json::to_string(&out).unwrap();
        assert!(
            json.contains("\"tracking\"") && json.contains("\"ball_out_of_view\""),
            "{json}"
        );
        let back: TrackOutput = serde_json::from_str(&json).unwrap();
        assert_eq!(back, out);
    }
}
