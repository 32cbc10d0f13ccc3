//! The ball tracker: waiting → detecting → tracking (seed 001 §V.B).
//!
//! - **Waiting**: no [`Target`]; frames are ignored.
//! - **Detecting**: the image is sampled on a grid (every `detection_step_px` pixels); cells
//!   whose hue and saturation are within tolerance of the target's form a mask; 4-connected
//!   regions of the mask, split where depth jumps (so a ball in front of a same-coloured object
//!   is a region of its own), are measured in metres (equivalent-disk diameter in pixels, scaled
//!   by the region's median depth and the focal length) and the region whose size best matches
//!   the target's diameter, within `size_tolerance`, wins. Nothing for `detect_timeout_s`: back
//!   to waiting ([`TrackEvent::DetectionTimedOut`]), the target is dropped.
//! - **Tracking**: a hue-saturation-depth (HSD) histogram of the target window, restricted to
//!   HSD ranges, is back-projected onto a region of interest around the window predicted from
//!   the image velocity; CamShift moves the window to the probability mass (MeanShift) and sizes
//!   it from the second moments, repeating while the size still grows (when the ball reaches the
//!   edge of the region, once more from a region centred on it). On convergence the HSD ranges
//!   are re-centred on the window's mean ± `range_sigmas` standard deviations (hue and
//!   saturation clamped to the target's colour tolerance, depth at least two diameters either
//!   side) and the histogram rebuilt. The result is verified: the ball's pixels (its colour, at
//!   its depth) must measure the target's diameter within `size_tolerance`. After
//!   `max_failed_frames` consecutive rejections the ball is lost ([`TrackEvent::BallLost`]) and
//!   the tracker detects again; the region of interest grows with each rejection meanwhile.
//! - **Out of view**: when a rejection comes while the last good window touched the image
//!   border (within `border_margin_px`) or the predicted centre is outside the image,
//!   [`TrackEvent::BallOutOfView`] is emitted (once per track), before the `BallLost`. A ball
//!   hidden at the border, rather than leaving, is reported the same way.
//!
//! The 3D centre is estimated from depth: for every ball pixel with depth, its surface point
//! `P` gives the distance `t` along the ray `u` through the ball's image centroid at which a
//! sphere of the target's radius through `P` would be centred (`t = P·u + sqrt(r² − |P − (P·u)u|²)`,
//! "surface depth plus radius along the ray"); the median of `t` over the pixels is robust to
//! edge pixels and noise.

use camera::{Frame, FrameError};

use crate::types::{Target, TrackEvent, TrackOutput, TrackState, Window};

mod camshift;
mod detect;

pub use detect::equivalent_diameter_m;

/// Tuning of the tracker. Defaults suit a 640x480 Kinect-class camera and a 5–30 cm ball.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct TrackerConfig {
    /// Largest hue difference from the target accepted as "the same colour", degrees.
    pub hue_tolerance_deg: f32,
    /// Largest saturation difference from the target accepted.
    pub saturation_tolerance: f32,
    /// Pixels darker than this HSV value have unreliable hue and are ignored.
    pub min_value: f32,
    /// Grid step of the detection mask, pixels (1 = full resolution).
    pub detection_step_px: u32,
    /// Smallest detection region, grid cells.
    pub min_region_cells: usize,
    /// Accepted relative diameter error (0.35: measured within ±35 % of the target).
    pub size_tolerance: f64,
    /// Detecting this long without a match returns to waiting, s.
    pub detect_timeout_s: f64,
    /// Consecutive rejected tracking frames before the ball is lost.
    pub max_failed_frames: u32,
    /// Histogram bins for hue, saturation and depth.
    pub hist_bins: [usize; 3],
    /// MeanShift iteration limit per frame.
    pub meanshift_max_iterations: u32,
    /// MeanShift converges when the window moves less than this, pixels.
    pub meanshift_epsilon_px: f32,
    /// HSD ranges are mean ± this many standard deviations after convergence.
    pub range_sigmas: f32,
    /// A window closer than this to the image border counts as "at the border", pixels.
    pub border_margin_px: f32,
}

impl Default for TrackerConfig {
    fn default() -> TrackerConfig {
        TrackerConfig {
            hue_tolerance_deg: 18.0,
            saturation_tolerance: 0.3,
            min_value: 0.12,
            detection_step_px: 4,
            min_region_cells: 4,
            size_tolerance: 0.35,
            detect_timeout_s: 10.0,
            max_failed_frames: 5,
            hist_bins: [16, 8, 8],
            meanshift_max_iterations: 10,
            meanshift_epsilon_px: 0.5,
            range_sigmas: 2.5,
            border_margin_px: 6.0,
        }
    }
}

/// The shortest time between two frames over which the image velocity is measured, s.
pub const MIN_VELOCITY_DT_S: f32 = 0.005;
/// Time since the ball was last held after which frames were dropped (three at 30 Hz): a ball
/// not where predicted is then looked for over the whole frame.
pub const FRAME_GAP_S: f32 = 0.1;
/// The fastest a tracked ball is taken to cross the image, px/s (a ball thrown across a 640 px
/// image in a fifth of a second).
pub const MAX_IMAGE_SPEED_PX_PER_S: f32 = 3200.0;

/// Errors of [`BallTracker::process`]; the tracker's state is unchanged by a rejected frame.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TrackError {
    /// The frame's sizes or intrinsics are inconsistent.
    #[error("invalid frame: {0}")]
    InvalidFrame(#[from] FrameError),
    /// The target description is out of range.
    #[error("invalid target: {0}")]
    InvalidTarget(String),
    /// The time passed in is not finite.
    #[error("invalid time {0} s")]
    InvalidTime(f64),
}

/// Counters of unusual input, for diagnostics.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct TrackerStats {
    /// Frames processed (valid ones).
    pub frames: u64,
    /// Frames rejected with [`TrackError::InvalidFrame`].
    pub invalid_frames: u64,
    /// Valid frames without a single depth measurement (processed as "ball not seen").
    pub frames_without_depth: u64,
    /// Tracking frames whose result was rejected.
    pub rejected_results: u64,
    /// Tracking frames after a frame gap ([`FRAME_GAP_S`]) where the ball was not where
    /// predicted and was looked for over the whole frame.
    pub gap_searches: u64,
}

/// A floating window: centre and half sizes, pixels.
#[derive(Debug, Clone, Copy, PartialEq)]
struct FWin {
    cx: f32,
    cy: f32,
    hw: f32,
    hh: f32,
}

impl FWin {
    /// Integer pixel bounds `[x0, x1) x [y0, y1)` clipped to the image; empty when outside.
    fn clip(&self, w: usize, h: usize) -> (usize, usize, usize, usize) {
        let x0 = (self.cx - self.hw).floor().max(0.0) as usize;
        let y0 = (self.cy - self.hh).floor().max(0.0) as usize;
        let x1 = ((self.cx + self.hw).ceil().max(0.0) as usize).min(w);
        let y1 = ((self.cy + self.hh).ceil().max(0.0) as usize).min(h);
        (x0.min(x1), y0.min(y1), x1, y1)
    }

    fn to_window(self, w: usize, h: usize) -> Window {
        let (x0, y0, x1, y1) = self.clip(w, h);
        Window {
            x: x0 as u32,
            y: y0 as u32,
            width: (x1 - x0) as u32,
            height: (y1 - y0) as u32,
        }
    }

    fn scaled(self, k: f32) -> FWin {
        FWin {
            hw: self.hw * k,
            hh: self.hh * k,
            ..self
        }
    }
}

/// HSD ranges of the model histogram: hue relative to the target hue (degrees), saturation,
/// depth (mm).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Ranges {
    h: (f32, f32),
    s: (f32, f32),
    d: (f32, f32),
}

/// One pixel of the region of interest, decoded.
#[derive(Debug, Clone, Copy, Default)]
struct Px {
    /// Hue relative to the target, degrees (−180, 180].
    dh: f32,
    s: f32,
    /// Depth, mm; 0 = none.
    d: f32,
    /// Bright enough and within the target's colour tolerance.
    colour_ok: bool,
}

#[derive(Debug, Clone)]
struct Track {
    win: FWin,
    ranges: Ranges,
    hist: Vec<f32>,
    failures: u32,
    velocity_px_per_s: [f32; 2],
    last_good_time_s: f64,
    last_good_win: FWin,
    out_of_view_reported: bool,
}

/// What was found in the window of one frame.
#[derive(Debug, Clone, Copy)]
struct Measurement {
    centroid: [f64; 2],
    centre_m: Option<[f64; 3]>,
    diameter_m: Option<f64>,
    size_ok: bool,
    confidence: f64,
}

/// The tracker. Feed it frames with [`BallTracker::process`]; give it a target with
/// [`BallTracker::set_target`].
#[derive(Debug, Clone)]
pub struct BallTracker {
    config: TrackerConfig,
    target: Option<Target>,
    state: TrackState,
    detect_since_s: Option<f64>,
    track: Option<Track>,
    stats: TrackerStats,
    roi: Vec<Px>,
    prob: Vec<f32>,
}

impl BallTracker {
    /// A tracker in the waiting state.
    pub fn new(config: TrackerConfig) -> BallTracker {
        BallTracker {
            config,
            target: None,
            state: TrackState::Waiting,
            detect_since_s: None,
            track: None,
            stats: TrackerStats::default(),
            roi: Vec::new(),
            prob: Vec::new(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &TrackerConfig {
        &self.config
    }

    /// Current state.
    pub fn state(&self) -> TrackState {
        self.state
    }

    /// Input counters.
    pub fn stats(&self) -> TrackerStats {
        self.stats
    }

    /// The current target, if any.
    pub fn target(&self) -> Option<Target> {
        self.target
    }

    /// Sets (or with `None` clears) the target. A new target starts detecting; clearing it
    /// returns to waiting.
    pub fn set_target(&mut self, target: Option<Target>) -> Result<(), TrackError> {
        self.target = target.map(|t| t.checked()).transpose()?;
        self.track = None;
        self.detect_since_s = None;
        self.state = if self.target.is_some() {
            TrackState::Detecting
        } else {
            TrackState::Waiting
        };
        Ok(())
    }

    /// Processes one frame observed at `now_s` (s, the caller's clock).
    pub fn process(&mut self, frame: &Frame, now_s: f64) -> Result<TrackOutput, TrackError> {
        if !now_s.is_finite() {
            return Err(TrackError::InvalidTime(now_s));
        }
        if let Err(e) = frame.validate() {
            self.stats.invalid_frames += 1;
            return Err(e.into());
        }
        self.stats.frames += 1;
        let has_depth = frame.depth_mm.iter().any(|&d| d > 0);
        if !has_depth {
            self.stats.frames_without_depth += 1;
        }
        let mut out = TrackOutput {
            time_s: now_s,
            state: self.state,
            window: None,
            centre_px: None,
            centre_m: None,
            measured_diameter_m: None,
            confidence: 0.0,
            events: Vec::new(),
        };
        let Some(target) = self.target else {
            self.state = TrackState::Waiting;
            out.state = self.state;
            return Ok(out);
        };
        if self.state == TrackState::Tracking {
            self.track_step(frame, &target, now_s, has_depth, &mut out);
        }
        // Detect in the same frame when not tracking (including right after a loss).
        if self.state == TrackState::Detecting {
            let since = *self.detect_since_s.get_or_insert(now_s);
            if has_depth && self.detect(frame, &target, now_s, &mut out) {
                out.events.push(TrackEvent::BallDetected);
            } else if now_s - since >= self.config.detect_timeout_s {
                out.events.push(TrackEvent::DetectionTimedOut);
                self.target = None;
                self.detect_since_s = None;
                self.state = TrackState::Waiting;
            }
        }
        out.state = self.state;
        Ok(out)
    }

    /// One tracking frame: CamShift, verification, adaptation, events.
    fn track_step(
        &mut self,
        frame: &Frame,
        target: &Target,
        now_s: f64,
        has_depth: bool,
        out: &mut TrackOutput,
    ) {
        let Some(mut track) = self.track.take() else {
            self.state = TrackState::Detecting;
            return;
        };
        let (w, h) = (frame.width as usize, frame.height as usize);
        let dt = (now_s - track.last_good_time_s).clamp(0.0, 1.0) as f32;
        let predicted = FWin {
            cx: track.last_good_win.cx + track.velocity_px_per_s[0] * dt,
            cy: track.last_good_win.cy + track.velocity_px_per_s[1] * dt,
            ..track.win
        };
        let result = if has_depth {
            self.camshift(frame, target, &mut track, predicted, 0)
        } else {
            None
        };
        // Not where predicted, and long enough since it was last held that it can be anywhere
        // the search did not cover (a frame gap on a loaded machine, a turn the velocity did not
        // foresee): look for it over the whole frame, in this frame. Found, the track goes on
        // from there (no event: it was never lost).
        let searched = predicted.hw.max(predicted.hh) * (2.0 + (track.failures as f32).min(4.0));
        if has_depth
            && !matches!(result, Some((_, m)) if m.size_ok)
            && dt >= FRAME_GAP_S
            && MAX_IMAGE_SPEED_PX_PER_S * dt > searched
        {
            self.stats.gap_searches += 1;
            if self.detect(frame, target, now_s, out) {
                return;
            }
        }
        match result {
            Some((win, m)) if m.size_ok => {
                // Frames closer in time than MIN_VELOCITY_DT_S (two frames rendered from one
                // joint state are stamped 1 ns apart, below an f64 second's resolution) would
                // turn a sub-pixel jitter into an enormous speed, and the next prediction far
                // off the ball: they leave the velocity as it is.
                if dt >= MIN_VELOCITY_DT_S {
                    let vx = (win.cx - track.last_good_win.cx) / dt;
                    let vy = (win.cy - track.last_good_win.cy) / dt;
                    // Light smoothing of the velocity estimate, bounded.
                    let v = [
                        0.5 * track.velocity_px_per_s[0] + 0.5 * vx,
                        0.5 * track.velocity_px_per_s[1] + 0.5 * vy,
                    ];
                    let speed = v[0].hypot(v[1]);
                    let k = if speed > MAX_IMAGE_SPEED_PX_PER_S {
                        MAX_IMAGE_SPEED_PX_PER_S / speed
                    } else {
                        1.0
                    };
                    track.velocity_px_per_s = [v[0] * k, v[1] * k];
                }
                track.win = win;
                track.last_good_win = win;
                track.last_good_time_s = now_s;
                track.failures = 0;
                out.window = Some(win.to_window(w, h));
                out.centre_px = Some(m.centroid);
                out.centre_m = m.centre_m;
                out.measured_diameter_m = m.diameter_m;
                out.confidence = m.confidence;
                self.track = Some(track);
            }
            _ => {
                self.stats.rejected_results += 1;
                track.failures += 1;
                let lw = track.last_good_win;
                let margin = self.config.border_margin_px;
                let pred_outside = predicted.cx < 0.0
                    || predicted.cy < 0.0
                    || predicted.cx >= w as f32
                    || predicted.cy >= h as f32;
                let at_border = lw.cx - lw.hw <= margin
                    || lw.cy - lw.hh <= margin
                    || lw.cx + lw.hw >= w as f32 - margin
                    || lw.cy + lw.hh >= h as f32 - margin;
                if (at_border || pred_outside) && !track.out_of_view_reported {
                    track.out_of_view_reported = true;
                    out.events.push(TrackEvent::BallOutOfView);
                }
                if track.failures >= self.config.max_failed_frames {
                    out.events.push(TrackEvent::BallLost);
                    self.state = TrackState::Detecting;
                    self.detect_since_s = Some(now_s);
                } else {
                    self.track = Some(track);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests;
