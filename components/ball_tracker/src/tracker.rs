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

use camera::{Frame, FrameError, Intrinsics};

use crate::hsv::{hue_diff_deg, rgb_to_hsv};
use crate::types::{Target, TrackEvent, TrackOutput, TrackState, Window};

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

    /// Decodes the ROI `[x0, x1) x [y0, y1)` into `self.roi`.
    fn decode_roi(&mut self, frame: &Frame, target: &Target, roi: (usize, usize, usize, usize)) {
        let (x0, y0, x1, y1) = roi;
        let w = frame.width as usize;
        let c = &self.config;
        self.roi.clear();
        for y in y0..y1 {
            let row = y * w;
            for x in x0..x1 {
                let i = row + x;
                let (h, s, v) =
                    rgb_to_hsv(frame.rgb[i * 3], frame.rgb[i * 3 + 1], frame.rgb[i * 3 + 2]);
                let dh = hue_diff_deg(h, target.hue_deg);
                let colour_ok = v >= c.min_value
                    && dh.abs() <= c.hue_tolerance_deg
                    && (s - target.saturation).abs() <= c.saturation_tolerance;
                self.roi.push(Px {
                    dh,
                    s,
                    d: f32::from(frame.depth_mm[i]),
                    colour_ok,
                });
            }
        }
    }

    /// Histogram bin of a pixel, or `None` when outside the ranges.
    fn bin(&self, r: &Ranges, p: &Px) -> Option<usize> {
        if !p.colour_ok || p.d <= 0.0 {
            return None;
        }
        let [nh, ns, nd] = self.config.hist_bins;
        let idx = |x: f32, (lo, hi): (f32, f32), n: usize| -> Option<usize> {
            if x < lo || x > hi || hi <= lo {
                return None;
            }
            Some((((x - lo) / (hi - lo) * n as f32) as usize).min(n - 1))
        };
        let bh = idx(p.dh, r.h, nh.max(1))?;
        let bs = idx(p.s, r.s, ns.max(1))?;
        let bd = idx(p.d, r.d, nd.max(1))?;
        Some((bh * ns.max(1) + bs) * nd.max(1) + bd)
    }

    /// Builds the model histogram from the ROI pixels inside `win` (ROI-relative bounds),
    /// normalised to a maximum of 1.
    fn build_hist(&self, r: &Ranges, roi_w: usize, win: (usize, usize, usize, usize)) -> Vec<f32> {
        let [nh, ns, nd] = self.config.hist_bins;
        let mut hist = vec![0f32; nh.max(1) * ns.max(1) * nd.max(1)];
        let (x0, y0, x1, y1) = win;
        for y in y0..y1 {
            for x in x0..x1 {
                if let Some(p) = self.roi.get(y * roi_w + x)
                    && let Some(b) = self.bin(r, p)
                {
                    hist[b] += 1.0;
                }
            }
        }
        let max = hist.iter().copied().fold(0.0, f32::max);
        if max > 0.0 {
            hist.iter_mut().for_each(|v| *v /= max);
        }
        hist
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

    /// Runs CamShift from `start` (`attempt` 0; 1 for the one re-centred retry); returns the new window and its measurement, or `None` when
    /// there is no probability mass. Adapts the track's ranges and histogram on convergence.
    fn camshift(
        &mut self,
        frame: &Frame,
        target: &Target,
        track: &mut Track,
        start: FWin,
        attempt: u32,
    ) -> Option<(FWin, Measurement)> {
        let (w, h) = (frame.width as usize, frame.height as usize);
        // Region of interest: the window grown to cover fast motion and the moment window, and
        // more after each failed frame.
        let k = 2.0 + (track.failures as f32).min(4.0);
        let grow = FWin {
            hw: start.hw * k + 8.0,
            hh: start.hh * k + 8.0,
            ..start
        };
        let (rx0, ry0, rx1, ry1) = grow.clip(w, h);
        if rx1 <= rx0 || ry1 <= ry0 {
            return None;
        }
        let rw = rx1 - rx0;
        self.decode_roi(frame, target, (rx0, ry0, rx1, ry1));
        self.prob.clear();
        for i in 0..self.roi.len() {
            let p = self
                .bin(&track.ranges, &self.roi[i])
                .and_then(|b| track.hist.get(b).copied())
                .unwrap_or(0.0);
            self.prob.push(p);
        }
        // ROI-relative window bounds.
        let rel = |win: &FWin| {
            let (x0, y0, x1, y1) = win.clip(w, h);
            let cl = |a: usize, lo: usize, hi: usize| a.clamp(lo, hi) - lo;
            (
                cl(x0, rx0, rx1),
                cl(y0, ry0, ry1),
                cl(x1, rx0, rx1),
                cl(y1, ry0, ry1),
            )
        };
        let moments = |prob: &[f32], b: (usize, usize, usize, usize)| {
            let (mut m00, mut m10, mut m01, mut m20, mut m02) = (0f64, 0f64, 0f64, 0f64, 0f64);
            for y in b.1..b.3 {
                for x in b.0..b.2 {
                    let p = f64::from(prob[y * rw + x]);
                    if p > 0.0 {
                        let (xf, yf) = (x as f64, y as f64);
                        m00 += p;
                        m10 += p * xf;
                        m01 += p * yf;
                        m20 += p * xf * xf;
                        m02 += p * yf * yf;
                    }
                }
            }
            (m00, m10, m01, m20, m02)
        };
        // CamShift: MeanShift at a fixed size, then the size from the second moments over a
        // larger window (a uniform disk of radius R has sigma = R / 2 along each axis); repeat
        // while the size still changes (a window that caught only part of the ball grows by up
        // to 1.6x a round).
        let mut win = start;
        // Nothing under the start window (the ball moved more than its size): restart from the
        // centroid of the whole region of interest.
        if moments(&self.prob, rel(&win)).0 <= 0.0 {
            let (m00, m10, m01, _, _) = moments(&self.prob, (0, 0, rw, ry1 - ry0));
            if m00 <= 0.0 {
                return None;
            }
            win.cx = (m10 / m00) as f32 + rx0 as f32;
            win.cy = (m01 / m00) as f32 + ry0 as f32;
        }
        let mut converged = false;
        for _round in 0..4 {
            converged = false;
            for _ in 0..self.config.meanshift_max_iterations {
                let (m00, m10, m01, _, _) = moments(&self.prob, rel(&win));
                if m00 <= 0.0 {
                    return None;
                }
                let ncx = (m10 / m00) as f32 + rx0 as f32;
                let ncy = (m01 / m00) as f32 + ry0 as f32;
                let shift = ((ncx - win.cx).powi(2) + (ncy - win.cy).powi(2)).sqrt();
                win.cx = ncx;
                win.cy = ncy;
                if shift < self.config.meanshift_epsilon_px {
                    converged = true;
                    break;
                }
            }
            let (m00, m10, m01, m20, m02) = moments(&self.prob, rel(&win.scaled(1.6)));
            if m00 <= 0.0 {
                return None;
            }
            let (mx, my) = (m10 / m00, m01 / m00);
            let sx = (m20 / m00 - mx * mx).max(0.0).sqrt() as f32;
            let sy = (m02 / m00 - my * my).max(0.0).sqrt() as f32;
            let (old_hw, old_hh) = (win.hw, win.hh);
            win.cx = mx as f32 + rx0 as f32;
            win.cy = my as f32 + ry0 as f32;
            win.hw = (2.0 * sx * 1.1).max(3.0);
            win.hh = (2.0 * sy * 1.1).max(3.0);
            let growth = (win.hw / old_hw).max(win.hh / old_hh);
            if growth < 1.1 {
                break;
            }
        }
        // The ball reached the edge of the region of interest (it moved farther than
        // predicted): once, run again from there with a region centred on it.
        let (bx0, by0, bx1, by1) = win.scaled(1.6).clip(w, h);
        if attempt == 0 && (bx0 < rx0 || by0 < ry0 || bx1 > rx1 || by1 > ry1) {
            let again = FWin {
                cx: win.cx,
                cy: win.cy,
                ..start
            };
            return self.camshift(frame, target, track, again, 1);
        }
        let wb = rel(&win);
        // Measure over a slightly larger window so that a window a pixel too small does not
        // clip the ball's silhouette (which would bias the centroid and the size).
        let m = self.measure(
            frame.intrinsics,
            target,
            rw,
            (rx0, ry0),
            rel(&win.scaled(1.2)),
            track.ranges.d,
        );
        if converged && m.size_ok {
            if let Some(r) = self.adapted_ranges(target, &track.ranges, rw, wb) {
                track.ranges = r;
            }
            track.hist = self.build_hist(&track.ranges, rw, wb);
        }
        Some((win, m))
    }

    /// HSD mean ± `range_sigmas` sd over the window's in-range pixels, clamped to the target's
    /// colour tolerance; depth ranges at least one ball diameter each side.
    fn adapted_ranges(
        &self,
        target: &Target,
        cur: &Ranges,
        rw: usize,
        b: (usize, usize, usize, usize),
    ) -> Option<Ranges> {
        let mut n = 0f64;
        let mut sum = [0f64; 3];
        let mut sq = [0f64; 3];
        for y in b.1..b.3 {
            for x in b.0..b.2 {
                let Some(p) = self.roi.get(y * rw + x) else {
                    continue;
                };
                if self.bin(cur, p).is_none() {
                    continue;
                }
                let v = [f64::from(p.dh), f64::from(p.s), f64::from(p.d)];
                n += 1.0;
                for k in 0..3 {
                    sum[k] += v[k];
                    sq[k] += v[k] * v[k];
                }
            }
        }
        if n < 10.0 {
            return None;
        }
        let mean = sum.map(|s| s / n);
        let sd: Vec<f64> = (0..3)
            .map(|k| (sq[k] / n - mean[k] * mean[k]).max(0.0).sqrt())
            .collect();
        let k = f64::from(self.config.range_sigmas);
        let c = &self.config;
        let ht = f64::from(c.hue_tolerance_deg);
        let hw = (k * sd[0]).max(6.0);
        let st = f64::from(c.saturation_tolerance);
        let sw = (k * sd[1]).max(0.08);
        let dmin = target.diameter_m * 1000.0;
        let dw = (k * sd[2]).max(2.0 * dmin);
        let ts = f64::from(target.saturation);
        Some(Ranges {
            h: (
                (mean[0] - hw).max(-ht) as f32,
                (mean[0] + hw).min(ht) as f32,
            ),
            s: (
                (mean[1] - sw).max(ts - st) as f32,
                (mean[1] + sw).min(ts + st) as f32,
            ),
            d: ((mean[2] - dw).max(1.0) as f32, (mean[2] + dw) as f32),
        })
    }

    /// Measures the ball inside window `b` (ROI-relative): colour area, centroid, depth, size.
    fn measure(
        &self,
        k: Intrinsics,
        target: &Target,
        rw: usize,
        origin: (usize, usize),
        b: (usize, usize, usize, usize),
        band_mm: (f32, f32),
    ) -> Measurement {
        let (ox, oy) = origin;
        // The ball's surface depth: median over colour pixels in the given depth band; the
        // ball's pixels are then the colour pixels near that depth (or without depth).
        let mut in_band: Vec<f32> = Vec::new();
        for y in b.1..b.3 {
            for x in b.0..b.2 {
                if let Some(p) = self.roi.get(y * rw + x)
                    && p.colour_ok
                    && p.d >= band_mm.0
                    && p.d <= band_mm.1
                {
                    in_band.push(p.d);
                }
            }
        }
        if in_band.len() < 3 {
            return Measurement {
                centroid: [0.0, 0.0],
                centre_m: None,
                diameter_m: None,
                size_ok: false,
                confidence: 0.0,
            };
        }
        let mid = in_band.len() / 2;
        let (_, med, _) = in_band.select_nth_unstable_by(mid, f32::total_cmp);
        let band = ball_depth_band(*med, target);
        let mut area = 0usize;
        let (mut su, mut sv) = (0f64, 0f64);
        // Ball pixels with depth: (u, v, depth mm).
        let mut pts: Vec<(f64, f64, f64)> = Vec::new();
        for y in b.1..b.3 {
            for x in b.0..b.2 {
                let Some(p) = self.roi.get(y * rw + x) else {
                    continue;
                };
                if is_ball_pixel(p, band) {
                    let (u, v) = ((x + ox) as f64, (y + oy) as f64);
                    area += 1;
                    su += u;
                    sv += v;
                    if p.d > 0.0 {
                        pts.push((u, v, f64::from(p.d)));
                    }
                }
            }
        }
        let none = Measurement {
            centroid: [0.0, 0.0],
            centre_m: None,
            diameter_m: None,
            size_ok: false,
            confidence: 0.0,
        };
        if area == 0 || pts.len() < 3 {
            return none;
        }
        let centroid = [su / area as f64, sv / area as f64];
        let mut depths: Vec<f64> = pts.iter().map(|p| p.2).collect();
        let mid = depths.len() / 2;
        let (_, med, _) = depths.select_nth_unstable_by(mid, f64::total_cmp);
        let z_surface_m = *med / 1000.0;
        let f = (k.fx + k.fy) / 2.0;
        let diameter_m = equivalent_diameter_m(area as f64, z_surface_m, f);
        let ratio = diameter_m.map_or(f64::INFINITY, |d| d / target.diameter_m);
        let tol = self.config.size_tolerance;
        let size_ok = (ratio - 1.0).abs() <= tol;
        // Sphere centre along the centroid ray.
        let r = target.diameter_m / 2.0;
        let ray = k.back_project(centroid[0], centroid[1], 1.0);
        let norm = (ray[0] * ray[0] + ray[1] * ray[1] + ray[2] * ray[2]).sqrt();
        let u = ray.map(|c| c / norm);
        // Only pixels near the ball's surface depth (reject background seen through the window).
        let z_lo = z_surface_m - 2.0 * r - 0.02;
        let z_hi = z_surface_m + 2.0 * r + 0.02;
        let mut ts: Vec<f64> = Vec::with_capacity(pts.len());
        for &(pu, pv, dmm) in &pts {
            let z = dmm / 1000.0;
            if z < z_lo || z > z_hi {
                continue;
            }
            let p = k.back_project(pu, pv, z);
            let a = p[0] * u[0] + p[1] * u[1] + p[2] * u[2];
            let perp2 = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2] - a * a).max(0.0);
            ts.push(a + (r * r - perp2).max(0.0).sqrt());
        }
        let centre_m = if ts.len() >= 3 {
            let mid = ts.len() / 2;
            let (_, t, _) = ts.select_nth_unstable_by(mid, f64::total_cmp);
            Some(u.map(|c| c * *t))
        } else {
            None
        };
        let size_score = (1.0 - (ratio - 1.0).abs() / tol).clamp(0.0, 1.0);
        // Depth support: the share of ball pixels with a depth measurement (a sphere loses some
        // at its rim; 80 % counts as full support).
        let support = (pts.len() as f64 / area as f64 / 0.8).min(1.0);
        Measurement {
            centroid,
            centre_m,
            diameter_m,
            size_ok,
            confidence: if size_ok {
                (size_score * support).clamp(0.0, 1.0)
            } else {
                0.0
            },
        }
    }

    /// Detection over the whole frame; on success starts tracking and fills `out`.
    fn detect(
        &mut self,
        frame: &Frame,
        target: &Target,
        now_s: f64,
        out: &mut TrackOutput,
    ) -> bool {
        let (w, h) = (frame.width as usize, frame.height as usize);
        let step = (self.config.detection_step_px.max(1)) as usize;
        let (gw, gh) = (w.div_ceil(step), h.div_ceil(step));
        let c = self.config;
        // Grid mask: sample the pixel at the centre of each cell (clamped into the image).
        let mut mask = vec![false; gw * gh];
        let mut cell_depth = vec![0u16; gw * gh];
        for gy in 0..gh {
            let y = (gy * step + step / 2).min(h - 1);
            for gx in 0..gw {
                let x = (gx * step + step / 2).min(w - 1);
                let i = y * w + x;
                let (hh, s, v) =
                    rgb_to_hsv(frame.rgb[i * 3], frame.rgb[i * 3 + 1], frame.rgb[i * 3 + 2]);
                cell_depth[gy * gw + gx] = frame.depth_mm[i];
                mask[gy * gw + gx] = v >= c.min_value
                    && hue_diff_deg(hh, target.hue_deg).abs() <= c.hue_tolerance_deg
                    && (s - target.saturation).abs() <= c.saturation_tolerance;
            }
        }
        // 4-connected components by flood fill; keep the best-sized one.
        let mut label = vec![false; gw * gh];
        let jump_mm = ((target.diameter_m * 1000.0 * 0.5) as u16).max(40);
        let mut stack = Vec::new();
        let f = (frame.intrinsics.fx + frame.intrinsics.fy) / 2.0;
        // Best region so far: (size error, pixel bounds, median depth mm).
        type Candidate = (f64, (usize, usize, usize, usize), f32);
        let mut best: Option<Candidate> = None;
        for start in 0..gw * gh {
            if !mask[start] || label[start] {
                continue;
            }
            label[start] = true;
            stack.push((start, cell_depth[start]));
            let (mut n, mut bx0, mut by0, mut bx1, mut by1) = (0usize, gw, gh, 0usize, 0usize);
            let mut depths: Vec<u16> = Vec::new();
            // Each stacked cell carries the depth it was reached with: its own, or for a cell
            // without depth its parent's, so that depth holes do not bridge depth jumps.
            while let Some((j, carried)) = stack.pop() {
                let (gx, gy) = (j % gw, j / gw);
                n += 1;
                bx0 = bx0.min(gx);
                by0 = by0.min(gy);
                bx1 = bx1.max(gx + 1);
                by1 = by1.max(gy + 1);
                let d = if cell_depth[j] > 0 {
                    depths.push(cell_depth[j]);
                    cell_depth[j]
                } else {
                    carried
                };
                // Neighbours join when their depths are within `jump_mm` (a ball in front of a
                // same-coloured object is a separate region) or one has no depth.
                let mut push = |k: usize| {
                    let dk = cell_depth[k];
                    let continuous = d == 0 || dk == 0 || d.abs_diff(dk) <= jump_mm;
                    if mask[k] && !label[k] && continuous {
                        label[k] = true;
                        stack.push((k, if dk > 0 { dk } else { d }));
                    }
                };
                if gx > 0 {
                    push(j - 1);
                }
                if gx + 1 < gw {
                    push(j + 1);
                }
                if gy > 0 {
                    push(j - gw);
                }
                if gy + 1 < gh {
                    push(j + gw);
                }
            }
            if n < c.min_region_cells || depths.len() < 3 {
                continue;
            }
            let mid = depths.len() / 2;
            let (_, med, _) = depths.select_nth_unstable(mid);
            let area_px = (n * step * step) as f64;
            let Some(d_m) = equivalent_diameter_m(area_px, f64::from(*med) / 1000.0, f) else {
                continue;
            };
            let err = (d_m / target.diameter_m).ln().abs();
            if err <= (1.0 + c.size_tolerance).ln() && best.is_none_or(|b| err < b.0) {
                best = Some((
                    err,
                    (
                        bx0 * step,
                        by0 * step,
                        (bx1 * step).min(w),
                        (by1 * step).min(h),
                    ),
                    f32::from(*med),
                ));
            }
        }
        let Some((_, (x0, y0, x1, y1), med_mm)) = best else {
            return false;
        };
        let band = ball_depth_band(med_mm, target);
        // Refine at full resolution: decode the region (one cell of margin) and take the bounding
        // box of the colour pixels.
        let (ex0, ey0) = (x0.saturating_sub(step), y0.saturating_sub(step));
        let (ex1, ey1) = ((x1 + step).min(w), (y1 + step).min(h));
        self.decode_roi(frame, target, (ex0, ey0, ex1, ey1));
        let rw = ex1 - ex0;
        let (mut fx0, mut fy0, mut fx1, mut fy1) = (usize::MAX, usize::MAX, 0, 0);
        for (i, p) in self.roi.iter().enumerate() {
            if is_ball_pixel(p, band) {
                let (x, y) = (i % rw, i / rw);
                fx0 = fx0.min(x);
                fy0 = fy0.min(y);
                fx1 = fx1.max(x + 1);
                fy1 = fy1.max(y + 1);
            }
        }
        if fx1 <= fx0 || fy1 <= fy0 {
            return false;
        }
        let wb = (fx0, fy0, fx1, fy1);
        let m = self.measure(frame.intrinsics, target, rw, (ex0, ey0), wb, band);
        if !m.size_ok {
            return false;
        }
        let win = FWin {
            cx: (ex0 + fx0) as f32 + (fx1 - fx0) as f32 / 2.0 - 0.5,
            cy: (ey0 + fy0) as f32 + (fy1 - fy0) as f32 / 2.0 - 0.5,
            hw: (fx1 - fx0) as f32 / 2.0,
            hh: (fy1 - fy0) as f32 / 2.0,
        };
        // Initial HSD ranges: the colour tolerance, and the ball's depth band.
        let z_mm = m.centre_m.map_or(1000.0, |c| c[2] * 1000.0) as f32;
        let dmm = (target.diameter_m * 1000.0) as f32;
        let ranges = Ranges {
            h: (-c.hue_tolerance_deg, c.hue_tolerance_deg),
            s: (
                target.saturation - c.saturation_tolerance,
                target.saturation + c.saturation_tolerance,
            ),
            d: ((z_mm - 2.0 * dmm).max(1.0), z_mm + dmm),
        };
        let hist = self.build_hist(&ranges, rw, wb);
        self.track = Some(Track {
            win,
            ranges,
            hist,
            failures: 0,
            velocity_px_per_s: [0.0, 0.0],
            last_good_time_s: now_s,
            last_good_win: win,
            out_of_view_reported: false,
        });
        self.state = TrackState::Tracking;
        self.detect_since_s = None;
        out.window = Some(win.to_window(w, h));
        out.centre_px = Some(m.centroid);
        out.centre_m = m.centre_m;
        out.measured_diameter_m = m.diameter_m;
        out.confidence = m.confidence;
        true
    }
}

/// Depth band (mm) of a ball's visible surface around the median surface depth `med_mm`: the
/// surface spans about one radius either side of the median, plus sensor noise.
fn ball_depth_band(med_mm: f32, target: &Target) -> (f32, f32) {
    let half = (target.diameter_m * 1000.0 * 0.75) as f32 + 20.0 + 0.01 * med_mm;
    ((med_mm - half).max(1.0), med_mm + half)
}

/// A pixel of the ball's colour at the ball's depth, or without depth (holes at the rim).
fn is_ball_pixel(p: &Px, band: (f32, f32)) -> bool {
    p.colour_ok && (p.d == 0.0 || (p.d >= band.0 && p.d <= band.1))
}

/// Metric diameter of a sphere whose silhouette covers `area_px` pixels, given the median depth
/// of its visible surface `z_surface_m` and focal length `f_px`. The silhouette's diameter in
/// pixels is `d = 2 sqrt(area / pi)`; the silhouette lies at the centre depth, about
/// `0.354 D` (`D/2 · 1/sqrt(2)`, the median of a hemisphere's depth) behind the median surface
/// depth, so `D = d (z_surface + 0.354 D) / f`, solved for `D`. `None` when degenerate.
pub fn equivalent_diameter_m(area_px: f64, z_surface_m: f64, f_px: f64) -> Option<f64> {
    if area_px <= 0.0 || z_surface_m <= 0.0 || f_px <= 0.0 {
        return None;
    }
    let d_px = 2.0 * (area_px / std::f64::consts::PI).sqrt();
    let k = 0.5 * std::f64::consts::FRAC_1_SQRT_2;
    let denom = f_px - k * d_px;
    (denom > 0.0).then(|| d_px * z_surface_m / denom)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn equivalent_diameter_of_a_sphere_silhouette() {
        // A 10 cm sphere centred 1 m away seen by f = 525 px: silhouette radius ~26.25 px, median
        // surface depth 1 - 0.05 / sqrt(2) m.
        let f = 525.0;
        let r_px: f64 = f * 0.05 / (1.0f64 - 0.05 * 0.05).sqrt();
        let area = std::f64::consts::PI * r_px * r_px;
        let z_med = 1.0 - 0.05 * std::f64::consts::FRAC_1_SQRT_2;
        let d = equivalent_diameter_m(area, z_med, f).unwrap();
        assert!((d - 0.1).abs() < 0.001, "{d}");
        assert!(equivalent_diameter_m(0.0, 1.0, f).is_none());
        assert!(equivalent_diameter_m(100.0, 0.0, f).is_none());
        // A silhouette wider than 2.8 focal lengths cannot be a sphere in front of the camera.
        assert!(equivalent_diameter_m(1e8, 1.0, f).is_none());
    }

    #[test]
    fn window_clipping_stays_inside_the_image() {
        let w = FWin {
            cx: -5.0,
            cy: 470.0,
            hw: 20.0,
            hh: 30.0,
        };
        assert_eq!(w.clip(640, 480), (0, 440, 15, 480));
        let out = FWin {
            cx: 1000.0,
            cy: 1000.0,
            hw: 5.0,
            hh: 5.0,
        };
        let (x0, y0, x1, y1) = out.clip(640, 480);
        assert!(x0 >= x1 && y0 >= y1, "empty when outside");
        let nan = FWin {
            cx: f32::NAN,
            cy: 10.0,
            hw: 5.0,
            hh: 5.0,
        };
        let (x0, _, x1, _) = nan.clip(640, 480);
        assert!(x0 <= x1 && x1 <= 640);
    }

    #[test]
    fn targets_and_times_are_validated() {
        let mut t = BallTracker::new(TrackerConfig::default());
        let good = Target {
            hue_deg: -10.0,
            saturation: 0.8,
            diameter_m: 0.1,
        };
        t.set_target(Some(good)).unwrap();
        assert_eq!(t.state(), TrackState::Detecting);
        assert_eq!(
            t.target().unwrap().hue_deg,
            350.0,
            "hue wrapped to [0, 360)"
        );
        for bad in [
            Target {
                saturation: 1.5,
                ..good
            },
            Target {
                diameter_m: 0.0,
                ..good
            },
            Target {
                diameter_m: f64::NAN,
                ..good
            },
            Target {
                hue_deg: f32::INFINITY,
                ..good
            },
        ] {
            assert!(matches!(
                t.set_target(Some(bad)),
                Err(TrackError::InvalidTarget(_))
            ));
        }
        let f = Frame::blank(8, 8, Intrinsics::KINECT_640X480, 0.0);
        assert!(matches!(
            t.process(&f, f64::NAN),
            Err(TrackError::InvalidTime(_))
        ));
        t.set_target(None).unwrap();
        assert_eq!(t.process(&f, 0.0).unwrap().state, TrackState::Waiting);
    }

    #[test]
    fn config_rejects_unknown_fields() {
        let c: TrackerConfig = serde_json::from_str(r#"{"hue_tolerance_deg": 12.0}"#).unwrap();
        assert_eq!(c.hue_tolerance_deg, 12.0);
        assert_eq!(
            c.max_failed_frames,
            TrackerConfig::default().max_failed_frames
        );
        assert!(serde_json::from_str::<TrackerConfig>(r#"{"hue_tolerence_deg": 12.0}"#).is_err());
    }
}
