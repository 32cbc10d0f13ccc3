//! The Kinect v1's depth geometry.
//!
//! The sensor sends an 11-bit disparity per pixel of its infrared (depth) camera, 2047 meaning
//! "no measurement". Depth along the optical axis follows the OpenKinect model
//! `z = 0.1236 m * tan(raw / 2842.5 + 1.1863)`, about 3 mm a step at 1 m and 3 cm at 3 m; it is
//! valid from about 0.4 m to 8 m. The depth camera sits beside the colour camera (about 2.5 cm to
//! its left as the camera sees), with a longer focal length, so a depth image is registered onto
//! the colour image's pixel grid before the two can be used together: each depth pixel is
//! back-projected with the depth camera's intrinsics, moved into the colour camera's frame and
//! projected with the colour camera's intrinsics, the nearest surface winning where several land
//! on one pixel. [`unregister`] is the inverse, for a simulated device that renders in the colour
//! camera and must send what the sensor would.

use crate::{PIXELS, Pinhole, WIDTH};

/// The raw value for "no measurement".
pub const RAW_NO_DATA: u16 = 2047;
/// Nearest depth the model is used for (mm); nearer raw values are dropped.
pub const MIN_MM: u16 = 400;
/// Farthest depth the model is used for (mm); farther raw values are dropped.
pub const MAX_MM: u16 = 8000;

/// Depth (mm) of an 11-bit raw disparity, or 0 for "no measurement" or out of range.
pub fn raw_to_mm(raw: u16) -> u16 {
    if raw >= RAW_NO_DATA {
        return 0;
    }
    let z_m = 0.1236 * (f64::from(raw) / 2842.5 + 1.1863).tan();
    let mm = z_m * 1000.0;
    if !(f64::from(MIN_MM)..=f64::from(MAX_MM)).contains(&mm) {
        return 0;
    }
    mm.round() as u16
}

/// The 11-bit raw disparity the sensor reports for a depth (mm), [`RAW_NO_DATA`] for 0 or out of
/// range. `raw_to_mm(mm_to_raw(d))` is within one disparity step of `d`.
pub fn mm_to_raw(mm: u16) -> u16 {
    if !(MIN_MM..=MAX_MM).contains(&mm) {
        return RAW_NO_DATA;
    }
    let raw = ((f64::from(mm) / 1000.0 / 0.1236).atan() - 1.1863) * 2842.5;
    let raw = raw.round();
    if !(0.0..f64::from(RAW_NO_DATA)).contains(&raw) {
        return RAW_NO_DATA;
    }
    raw as u16
}

/// A lookup table of [`raw_to_mm`] for every 11-bit value (the converter's inner loop).
#[derive(Debug, Clone)]
pub struct RawToMm {
    table: Vec<u16>,
}

impl Default for RawToMm {
    fn default() -> Self {
        RawToMm {
            table: (0..=RAW_NO_DATA).map(raw_to_mm).collect(),
        }
    }
}

impl RawToMm {
    /// Depth (mm) of a raw value; values above 11 bits are "no measurement" (0).
    pub fn get(&self, raw: u16) -> u16 {
        self.table.get(usize::from(raw)).copied().unwrap_or(0)
    }
}

/// How the depth camera sits relative to the colour camera. Both optical frames are taken as
/// parallel (the factory alignment of Kinect-class cameras).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DepthCalibration {
    /// The depth camera's intrinsics at 640x480.
    pub depth: Pinhole,
    /// The depth camera's origin in the colour camera's optical frame (m).
    pub depth_origin_in_rgb_m: [f64; 3],
}

impl Default for DepthCalibration {
    /// The Kinect v1's nominal values: depth fx = fy = 580, the depth camera 2.5 cm to the
    /// colour camera's left (negative x of its optical frame).
    fn default() -> Self {
        DepthCalibration {
            depth: Pinhole::KINECT_DEPTH,
            depth_origin_in_rgb_m: [-0.025, 0.0, 0.0],
        }
    }
}

/// What one registration did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct RegisterStats {
    /// Depth pixels with a measurement.
    pub measured: usize,
    /// Measured pixels that fell outside the colour image.
    pub outside: usize,
}

/// Registers an 11-bit raw depth image of the depth camera onto the colour camera's grid:
/// `out_mm[v * 640 + u]` is the depth (mm, along the colour camera's axis) seen at colour pixel
/// `(u, v)`, 0 where nothing landed. Both slices hold 640x480 values.
pub fn register(
    raw: &[u16],
    table: &RawToMm,
    calib: &DepthCalibration,
    rgb: &Pinhole,
    out_mm: &mut [u16],
) -> RegisterStats {
    out_mm.fill(0);
    let mut stats = RegisterStats::default();
    // f32 and precomputed rays: the inner loop is a handful of multiplies a pixel (this runs on
    // every frame, 307,200 pixels, 30 times a second).
    let [tx, ty, tz] = calib.depth_origin_in_rgb_m.map(|t| t as f32);
    let d = calib.depth;
    let (fx, fy, cx, cy) = (rgb.fx as f32, rgb.fy as f32, rgb.cx as f32, rgb.cy as f32);
    let ray_x: Vec<f32> = (0..WIDTH)
        .map(|u| ((u as f64 - d.cx) / d.fx) as f32)
        .collect();
    let height = raw.len().min(out_mm.len()).min(PIXELS) / WIDTH;
    let (w, h) = (WIDTH as f32, height as f32);
    for v in 0..height {
        let ray_y = ((v as f64 - d.cy) / d.fy) as f32;
        let row = &raw[v * WIDTH..(v + 1) * WIDTH];
        for (&r, &rx) in row.iter().zip(&ray_x) {
            let z_mm = table.get(r);
            if z_mm == 0 {
                continue;
            }
            stats.measured += 1;
            let z = f32::from(z_mm) * 1e-3;
            let zr = z + tz;
            if zr <= 0.0 {
                stats.outside += 1;
                continue;
            }
            let inv = 1.0 / zr;
            // Nearest pixel: +0.5 then truncation (negative values are rejected first).
            let ur = fx * (rx * z + tx) * inv + cx + 0.5;
            let vr = fy * (ray_y * z + ty) * inv + cy + 0.5;
            if !(0.0..w).contains(&ur) || !(0.0..h).contains(&vr) {
                stats.outside += 1;
                continue;
            }
            let i = vr as usize * WIDTH + ur as usize;
            let zr_mm = (zr * 1000.0 + 0.5).clamp(1.0, f32::from(u16::MAX)) as u16;
            let cell = &mut out_mm[i];
            if *cell == 0 || zr_mm < *cell {
                *cell = zr_mm;
            }
        }
    }
    stats
}

/// The inverse of [`register`], for a simulated device: from a depth image in the colour
/// camera's grid (mm) to the 11-bit raw image the depth camera would send. Each colour pixel is
/// splatted over the 2x2 depth pixels around where it lands (the depth camera's pixels are
/// smaller), nearest surface first; pixels nothing lands on read [`RAW_NO_DATA`], as the shadows
/// of a real sensor do.
pub fn unregister(depth_mm: &[u16], calib: &DepthCalibration, rgb: &Pinhole, out_raw: &mut [u16]) {
    let height = depth_mm.len().min(out_raw.len()).min(PIXELS) / WIDTH;
    let mut zbuf = vec![u16::MAX; height * WIDTH];
    let [tx, ty, tz] = calib.depth_origin_in_rgb_m.map(|t| t as f32);
    let d = calib.depth;
    let (fx, fy, cx, cy) = (d.fx as f32, d.fy as f32, d.cx as f32, d.cy as f32);
    let ray_x: Vec<f32> = (0..WIDTH)
        .map(|u| ((u as f64 - rgb.cx) / rgb.fx) as f32)
        .collect();
    // Splat corners must land in [0, last]: the top-left corner in [-1, last].
    let (w, h) = (WIDTH as f32, height as f32);
    for v in 0..height {
        let ray_y = ((v as f64 - rgb.cy) / rgb.fy) as f32;
        let row = &depth_mm[v * WIDTH..(v + 1) * WIDTH];
        for (&z_mm, &rx) in row.iter().zip(&ray_x) {
            if z_mm == 0 {
                continue;
            }
            let z = f32::from(z_mm) * 1e-3;
            let zd = z - tz;
            if zd <= 0.0 {
                continue;
            }
            let inv = 1.0 / zd;
            // +1 keeps the value positive for the truncation below (a floor shifted by one).
            let ud = fx * (rx * z - tx) * inv + cx + 1.0;
            let vd = fy * (ray_y * z - ty) * inv + cy + 1.0;
            if !(0.0..w + 1.0).contains(&ud) || !(0.0..h + 1.0).contains(&vd) {
                continue;
            }
            let zd_mm = (zd * 1000.0 + 0.5).min(f32::from(u16::MAX - 1)) as u16;
            let (u1, v1) = (ud as usize, vd as usize);
            for vv in v1.saturating_sub(1)..(v1 + 1).min(height) {
                for uu in u1.saturating_sub(1)..(u1 + 1).min(WIDTH) {
                    let cell = &mut zbuf[vv * WIDTH + uu];
                    if zd_mm < *cell {
                        *cell = zd_mm;
                    }
                }
            }
        }
    }
    let to_raw: Vec<u16> = (0..=MAX_MM).map(mm_to_raw).collect();
    for (out, z) in out_raw.iter_mut().zip(zbuf) {
        *out = to_raw.get(usize::from(z)).copied().unwrap_or(RAW_NO_DATA);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::HEIGHT;

    #[test]
    fn raw_and_mm_agree_within_one_step() {
        for mm in (MIN_MM..=4000).step_by(7) {
            let raw = mm_to_raw(mm);
            assert!(raw < RAW_NO_DATA, "{mm} mm has a raw value");
            let back = raw_to_mm(raw);
            let step = raw_to_mm(raw + 1).saturating_sub(raw_to_mm(raw)).max(1);
            assert!(
                back.abs_diff(mm) <= step,
                "{mm} mm -> raw {raw} -> {back} mm (step {step})"
            );
        }
        assert_eq!(raw_to_mm(RAW_NO_DATA), 0);
        assert_eq!(raw_to_mm(u16::MAX), 0);
        assert_eq!(mm_to_raw(0), RAW_NO_DATA);
        assert_eq!(mm_to_raw(100), RAW_NO_DATA, "too near for the sensor");
        // The model's well-known anchor: about 3 mm a disparity step at 1 m.
        let r = mm_to_raw(1000);
        let step = raw_to_mm(r + 1) - raw_to_mm(r);
        assert!((2..=4).contains(&step), "step at 1 m is {step} mm");
    }

    #[test]
    fn table_matches_the_formula_and_ignores_bits_above_11() {
        let t = RawToMm::default();
        for raw in [0, 300, 700, 900, 1000, 1050, 2046, 2047] {
            assert_eq!(t.get(raw), raw_to_mm(raw));
        }
        assert_eq!(t.get(4000), 0);
    }

    /// A plane 1.2 m away with a box 0.8 m away: unregistered to the depth camera and registered
    /// back, depth is where it was (within a disparity step) on all but the box's edges.
    #[test]
    fn register_inverts_unregister() {
        let rgb = Pinhole::KINECT_RGB;
        let calib = DepthCalibration::default();
        let mut depth = vec![1200u16; PIXELS];
        for v in 200..300 {
            for u in 280..380 {
                depth[v * WIDTH + u] = 800;
            }
        }
        let mut raw = vec![0u16; PIXELS];
        unregister(&depth, &calib, &rgb, &mut raw);
        let no_data = raw.iter().filter(|&&r| r == RAW_NO_DATA).count();
        assert!(no_data < PIXELS / 10, "{no_data} depth pixels without data");
        let mut back = vec![0u16; PIXELS];
        let stats = register(&raw, &RawToMm::default(), &calib, &rgb, &mut back);
        assert!(stats.measured > PIXELS / 2);
        let (mut compared, mut bad, mut holes) = (0, 0, 0);
        // The depth camera sees less than the colour camera (longer focal length) and from 2.5 cm
        // to its left: the image's borders and the box's shadow on the wall have no depth.
        for v in 30..HEIGHT - 30 {
            for u in 50..WIDTH - 50 {
                let near_edge = (265..=285).contains(&u)
                    || (375..=385).contains(&u)
                    || (195..=205).contains(&v)
                    || (295..=305).contains(&v);
                if near_edge {
                    continue;
                }
                let (want, got) = (depth[v * WIDTH + u], back[v * WIDTH + u]);
                if got == 0 {
                    holes += 1;
                    continue;
                }
                compared += 1;
                if want.abs_diff(got) > 6 {
                    bad += 1;
                }
            }
        }
        assert!(holes * 100 < compared, "{holes} holes of {compared}");
        assert_eq!(bad, 0, "{bad} of {compared} pixels off by more than 6 mm");
    }

    /// The registration moves a near object sideways by the baseline's parallax: an object at
    /// 0.6 m seen at the depth image's centre lands fx_rgb * 0.025 / 0.6 ≈ 22 px to the left.
    #[test]
    fn register_applies_the_parallax() {
        let rgb = Pinhole::KINECT_RGB;
        let calib = DepthCalibration::default();
        let mut raw = vec![RAW_NO_DATA; PIXELS];
        let c = 240 * WIDTH + 320;
        raw[c] = mm_to_raw(600);
        let mut out = vec![0u16; PIXELS];
        let stats = register(&raw, &RawToMm::default(), &calib, &rgb, &mut out);
        assert_eq!(stats.measured, 1);
        let i = out
            .iter()
            .position(|&z| z != 0)
            .expect("one pixel registered");
        let (u, v) = (i % WIDTH, i / WIDTH);
        assert_eq!(v, 240);
        let expected = 320.0 + rgb.fx * -0.025 / 0.6;
        assert!(
            (u as f64 - expected).abs() <= 1.0,
            "landed at u = {u}, want {expected:.1}"
        );
    }

    #[test]
    fn short_buffers_do_not_panic() {
        let mut out = vec![0u16; 10];
        let stats = register(
            &[5u16; 3],
            &RawToMm::default(),
            &DepthCalibration::default(),
            &Pinhole::KINECT_RGB,
            &mut out,
        );
        assert_eq!(stats, RegisterStats::default());
        unregister(
            &[900u16; 7],
            &DepthCalibration::default(),
            &Pinhole::KINECT_RGB,
            &mut out,
        );
    }
}
