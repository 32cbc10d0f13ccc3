//! Detection over the whole frame, and the measurement of the ball in a window (its pixels,
//! centroid, size and 3D centre).

use camera::{Frame, Intrinsics};

use super::{BallTracker, FWin, Measurement, Px, Ranges, Track};
use crate::hsv::{hue_diff_deg, rgb_to_hsv};
use crate::types::{Target, TrackOutput, TrackState};

impl BallTracker {
    /// Measures the ball inside window `b` (ROI-relative): colour area, centroid, depth, size.
    pub(super) fn measure(
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
    pub(super) fn detect(
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
