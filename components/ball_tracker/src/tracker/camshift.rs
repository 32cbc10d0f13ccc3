//! The region of interest, the hue-saturation-depth histogram and CamShift: how a tracked
//! window follows the ball from frame to frame.

use camera::Frame;

use super::{BallTracker, FWin, Measurement, Px, Ranges, Track};
use crate::hsv::{hue_diff_deg, rgb_to_hsv};
use crate::types::Target;

impl BallTracker {
    /// Decodes the ROI `[x0, x1) x [y0, y1)` into `self.roi`.
    pub(super) fn decode_roi(
        &mut self,
        frame: &Frame,
        target: &Target,
        roi: (usize, usize, usize, usize),
    ) {
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
    pub(super) fn build_hist(
        &self,
        r: &Ranges,
        roi_w: usize,
        win: (usize, usize, usize, usize),
    ) -> Vec<f32> {
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

    /// Runs CamShift from `start` (`attempt` 0; 1 for the one re-centred retry); returns the new window and its measurement, or `None` when
    /// there is no probability mass. Adapts the track's ranges and histogram on convergence.
    pub(super) fn camshift(
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
}
