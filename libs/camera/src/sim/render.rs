//! The renderer: the cached static background, spheres and the arm cast analytically, and the
//! sensor pass (noise, holes, quantisation).

use nalgebra::Vector3;
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use super::{HandArm, Scene, SensorModel, SimCamera, Sphere, Table};
use crate::types::Frame;

/// The static part of the image for one camera pose: ideal colour and depth (m, optical z;
/// `f32::INFINITY` where no surface).
struct Background {
    key: (SimCamera, f64, Option<Table>),
    rgb: Vec<u8>,
    depth_m: Vec<f32>,
}

/// Number of precomputed standard-normal samples (a power of two).
const NORMAL_TABLE_LEN: usize = 1 << 16;

/// Renders [`Scene`]s as seen by a [`SimCamera`] through a [`SensorModel`]. Deterministic for a
/// given seed and sequence of calls.
pub struct SimRenderer {
    /// The camera; change its pose freely (the background cache follows).
    pub camera: SimCamera,
    /// Sensor imperfections.
    pub sensor: SensorModel,
    rng: SmallRng,
    normals: Vec<f32>,
    background: Option<Background>,
    rgb: Vec<u8>,
    depth_m: Vec<f32>,
    /// Quantised depth for each depth in mm up to the maximum range, and the sensor parameters
    /// it was made for.
    quant_mm: Vec<u16>,
    quant_key: (f64, f64, f64),
    /// Colour noise in RGB levels for each entry of `normals`, and the sd it was made for.
    colour_noise: (f64, Vec<i16>),
}

impl std::fmt::Debug for SimRenderer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SimRenderer")
            .field("camera", &self.camera)
            .field("sensor", &self.sensor)
            .finish_non_exhaustive()
    }
}

/// Cheap per-pixel random stream (SplitMix64), seeded from the renderer's generator each frame.
struct PixelRng(u64);

impl PixelRng {
    #[inline]
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
}

/// Deterministic hash of integer coordinates to [0, 1), for textures.
fn hash2(x: i64, y: i64) -> f64 {
    let mut h = (x as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15)
        ^ (y as u64).wrapping_mul(0xC2B2_AE3D_27D4_EB4F);
    h ^= h >> 29;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 32;
    (h >> 11) as f64 / (1u64 << 53) as f64
}

fn scale_colour(c: [f64; 3], k: f64) -> [u8; 3] {
    [
        (c[0] * k).clamp(0.0, 255.0) as u8,
        (c[1] * k).clamp(0.0, 255.0) as u8,
        (c[2] * k).clamp(0.0, 255.0) as u8,
    ]
}

/// Nearest intersection parameter `t > t_min` of the ray `t * d` (origin at 0) with a sphere.
#[inline]
fn ray_sphere(d: &Vector3<f64>, c: &Vector3<f64>, r: f64) -> Option<f64> {
    let a = d.dot(d);
    let b = d.dot(c);
    let k = c.dot(c) - r * r;
    let disc = b * b - a * k;
    if disc < 0.0 {
        return None;
    }
    let t = (b - disc.sqrt()) / a;
    (t > 1e-6).then_some(t)
}

/// Nearest intersection of the ray `t * d` (origin at 0) with a capsule from `pa` to `pb`.
fn ray_capsule(d: &Vector3<f64>, pa: &Vector3<f64>, pb: &Vector3<f64>, r: f64) -> Option<f64> {
    // Ray origin ro = 0, so oa = ro - pa = -pa.
    let ba = pb - pa;
    let oa = -pa;
    let baba = ba.dot(&ba);
    let bard = ba.dot(d);
    let baoa = ba.dot(&oa);
    let rdoa = d.dot(&oa);
    let oaoa = oa.dot(&oa);
    let dd = d.dot(d);
    let a = baba * dd - bard * bard;
    let b = baba * rdoa - baoa * bard;
    let c = baba * oaoa - baoa * baoa - r * r * baba;
    let h = b * b - a * c;
    if a.abs() > 1e-12 && h >= 0.0 {
        let t = (-b - h.sqrt()) / a;
        let y = baoa + t * bard;
        if y > 0.0 && y < baba && t > 1e-6 {
            return Some(t);
        }
    }
    let ta = ray_sphere(d, pa, r);
    let tb = ray_sphere(d, pb, r);
    match (ta, tb) {
        (Some(x), Some(y)) => Some(x.min(y)),
        (x, y) => x.or(y),
    }
}

impl SimRenderer {
    /// A renderer with its own seeded random generator.
    pub fn new(camera: SimCamera, sensor: SensorModel, seed: u64) -> SimRenderer {
        let mut rng = SmallRng::seed_from_u64(seed);
        let mut normals = Vec::with_capacity(NORMAL_TABLE_LEN);
        while normals.len() < NORMAL_TABLE_LEN {
            // Box-Muller.
            let u1: f64 = rng.random::<f64>().max(1e-12);
            let u2: f64 = rng.random::<f64>();
            let r = (-2.0 * u1.ln()).sqrt();
            let th = std::f64::consts::TAU * u2;
            normals.push((r * th.cos()) as f32);
            normals.push((r * th.sin()) as f32);
        }
        SimRenderer {
            camera,
            sensor,
            rng,
            normals,
            background: None,
            rgb: Vec::new(),
            depth_m: Vec::new(),
            quant_mm: Vec::new(),
            quant_key: (f64::NAN, f64::NAN, f64::NAN),
            colour_noise: (0.0, Vec::new()),
        }
    }

    /// Rebuilds the mm → quantised mm table when the sensor's disparity parameters change.
    fn update_quantisation_table(&mut self) {
        let s = &self.sensor;
        let key = (
            s.disparity_focal_baseline_px_m,
            s.disparity_step_px,
            s.max_range_m,
        );
        if key == self.quant_key {
            return;
        }
        self.quant_key = key;
        let (fb, step) = (s.disparity_focal_baseline_px_m, s.disparity_step_px);
        if !(fb > 0.0 && step > 0.0 && fb.is_finite() && step.is_finite()) {
            self.quant_mm = Vec::new();
            return;
        }
        let top = (s.max_range_m.clamp(0.0, 65.0) * 1000.0).ceil() as usize + 1;
        self.quant_mm = (0..=top)
            .map(|mm| {
                let z = (mm.max(1)) as f64 / 1000.0;
                let steps = (fb / (z * step)).round().max(1.0);
                (fb / (steps * step) * 1000.0).round().clamp(1.0, 65535.0) as u16
            })
            .collect();
    }

    /// Ray direction in the camera frame for pixel (u, v), scaled so that its z is 1 (then the
    /// ray parameter is the optical depth).
    #[inline]
    fn ray(&self, u: usize, v: usize) -> Vector3<f64> {
        let k = &self.camera.intrinsics;
        Vector3::new((u as f64 - k.cx) / k.fx, (v as f64 - k.cy) / k.fy, 1.0)
    }

    fn render_background(&self, scene: &Scene) -> Background {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        let pose = self.camera.world_from_camera;
        let o = pose.translation.vector;
        let mut rgb = vec![0u8; w * h * 3];
        let mut depth_m = vec![f32::INFINITY; w * h];
        for v in 0..h {
            for u in 0..w {
                let d = pose.rotation * self.ray(u, v);
                let mut best = f64::INFINITY;
                let mut colour = [40u8, 40, 45];
                // Floor z = 0: grey tiles of 0.5 m.
                if d.z < -1e-9 {
                    let t = -o.z / d.z;
                    if t > 0.0 && t < best {
                        let p = o + d * t;
                        let tile = ((p.x / 0.5).floor() as i64 + (p.y / 0.5).floor() as i64) & 1;
                        let g = if tile == 0 { 120.0 } else { 105.0 };
                        let n =
                            1.0 + 0.08 * (hash2((p.x * 40.0) as i64, (p.y * 40.0) as i64) - 0.5);
                        best = t;
                        colour = scale_colour([g, g * 0.98, g * 0.95], n);
                    }
                }
                // Wall x = wall_x_m: muted posters on a beige wall, fine plaster noise.
                if d.x.abs() > 1e-9 {
                    let t = (scene.wall_x_m - o.x) / d.x;
                    if t > 0.0 && t < best {
                        let p = o + d * t;
                        let cell = ((p.y / 0.7).floor() as i64, (p.z / 0.6).floor() as i64);
                        let r = hash2(cell.0, cell.1);
                        let base = if r < 0.25 {
                            [150.0, 165.0, 180.0] // grey-blue poster
                        } else if r < 0.4 {
                            [140.0, 160.0, 135.0] // grey-green poster
                        } else {
                            [200.0, 190.0, 170.0] // beige wall
                        };
                        let n = 1.0 + 0.1 * (hash2((p.y * 60.0) as i64, (p.z * 60.0) as i64) - 0.5);
                        best = t;
                        colour = scale_colour(base, n);
                    }
                }
                // Table top: wood grain.
                if let Some(tab) = &scene.table
                    && d.z.abs() > 1e-9
                {
                    let t = (tab.centre_w.z - o.z) / d.z;
                    if t > 0.0 && t < best {
                        let p = o + d * t;
                        if (p.x - tab.centre_w.x).abs() <= tab.size_x_m / 2.0
                            && (p.y - tab.centre_w.y).abs() <= tab.size_y_m / 2.0
                        {
                            let grain = 0.5 + 0.5 * (p.y * 60.0 + 3.0 * (p.x * 5.0).sin()).sin();
                            best = t;
                            colour = scale_colour([150.0, 110.0, 75.0], 0.85 + 0.15 * grain);
                        }
                    }
                }
                // The ray's world parameter t equals the optical depth because ray z = 1.
                let i = v * w + u;
                depth_m[i] = best as f32;
                rgb[i * 3..i * 3 + 3].copy_from_slice(&colour);
            }
        }
        Background {
            key: (self.camera, scene.wall_x_m, scene.table),
            rgb,
            depth_m,
        }
    }

    /// Conservative pixel bounding box `(u0, v0, u1, v1)` (exclusive ends) of a sphere with centre
    /// `c` (camera frame) and radius `r`; `None` when it is entirely behind the camera.
    fn sphere_bbox(&self, c: &Vector3<f64>, r: f64) -> Option<(usize, usize, usize, usize)> {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        if c.z + r <= 1e-6 {
            return None;
        }
        if c.z - r <= 1e-3 {
            return Some((0, 0, w, h));
        }
        let k = &self.camera.intrinsics;
        let (zn, zf) = (c.z - r, c.z + r);
        let xs = [
            (c.x - r) / zn,
            (c.x - r) / zf,
            (c.x + r) / zn,
            (c.x + r) / zf,
        ];
        let ys = [
            (c.y - r) / zn,
            (c.y - r) / zf,
            (c.y + r) / zn,
            (c.y + r) / zf,
        ];
        let (xmin, xmax) = xs
            .iter()
            .fold((f64::MAX, f64::MIN), |a, &x| (a.0.min(x), a.1.max(x)));
        let (ymin, ymax) = ys
            .iter()
            .fold((f64::MAX, f64::MIN), |a, &y| (a.0.min(y), a.1.max(y)));
        let u0 = (k.fx * xmin + k.cx).floor().max(0.0);
        let u1 = (k.fx * xmax + k.cx).ceil() + 1.0;
        let v0 = (k.fy * ymin + k.cy).floor().max(0.0);
        let v1 = (k.fy * ymax + k.cy).ceil() + 1.0;
        let u1 = u1.min(w as f64);
        let v1 = v1.min(h as f64);
        if u0 >= u1 || v0 >= v1 {
            return None;
        }
        Some((u0 as usize, v0 as usize, u1 as usize, v1 as usize))
    }

    /// Ray-casts a sphere into the working buffers (z-buffered), Lambert shaded.
    fn draw_sphere(&mut self, s: &Sphere, light_c: &Vector3<f64>) {
        let r = s.diameter_m / 2.0;
        if r <= 0.0 || !r.is_finite() {
            return;
        }
        let w = self.camera.width as usize;
        let pose = self.camera.world_from_camera;
        let n_samples = if s.velocity_w_mps.norm() > 0.0 {
            self.sensor.motion_blur_samples.max(1)
        } else {
            1
        };
        let centres: Vec<Vector3<f64>> = (0..n_samples)
            .map(|i| {
                let f = if n_samples == 1 {
                    0.0
                } else {
                    i as f64 / (n_samples - 1) as f64 - 0.5
                };
                let p_w = s.centre_w + s.velocity_w_mps * (f * self.sensor.exposure_s);
                pose.inverse_transform_point(&p_w).coords
            })
            .collect();
        let mut bbox: Option<(usize, usize, usize, usize)> = None;
        for c in &centres {
            if let Some(b) = self.sphere_bbox(c, r) {
                bbox = Some(match bbox {
                    None => b,
                    Some(a) => (a.0.min(b.0), a.1.min(b.1), a.2.max(b.2), a.3.max(b.3)),
                });
            }
        }
        let Some((u0, v0, u1, v1)) = bbox else {
            return;
        };
        let albedo = s.colour.map(f64::from);
        let mid = n_samples as usize / 2;
        for v in v0..v1 {
            for u in u0..u1 {
                let d = self.ray(u, v);
                let i = v * w + u;
                let under = self.depth_m[i] as f64;
                let under_rgb = [
                    f64::from(self.rgb[i * 3]),
                    f64::from(self.rgb[i * 3 + 1]),
                    f64::from(self.rgb[i * 3 + 2]),
                ];
                let mut acc = [0.0f64; 3];
                let mut hits = 0usize;
                let mut mid_t = None;
                for (k, c) in centres.iter().enumerate() {
                    match ray_sphere(&d, c, r).filter(|&t| t < under) {
                        Some(t) => {
                            let n = (d * t - c) / r;
                            let shade = 0.35 + 0.65 * n.dot(light_c).max(0.0);
                            for ch in 0..3 {
                                acc[ch] += albedo[ch] * shade;
                            }
                            hits += 1;
                            if k == mid {
                                mid_t = Some(t);
                            }
                        }
                        None => {
                            for ch in 0..3 {
                                acc[ch] += under_rgb[ch];
                            }
                        }
                    }
                }
                if hits == 0 {
                    continue;
                }
                let inv = 1.0 / n_samples as f64;
                let c = scale_colour(acc, inv);
                self.rgb[i * 3..i * 3 + 3].copy_from_slice(&c);
                if let Some(t) = mid_t {
                    self.depth_m[i] = t as f32;
                }
            }
        }
    }

    /// Ray-casts the forearm and hand into the working buffers.
    fn draw_hand(&mut self, hand: &HandArm, light_c: &Vector3<f64>) {
        let pose = self.camera.world_from_camera;
        let pe = pose.inverse_transform_point(&hand.elbow_w).coords;
        let ph = pose.inverse_transform_point(&hand.hand_w).coords;
        let ra = hand.forearm_radius_m.max(0.0);
        let rh = hand.hand_radius_m.max(0.0);
        let mid = (pe + ph) / 2.0;
        let bound = (pe - ph).norm() / 2.0 + ra.max(rh);
        let Some((u0, v0, u1, v1)) = self.sphere_bbox(&mid, bound) else {
            return;
        };
        let w = self.camera.width as usize;
        let skin = hand.skin.map(f64::from);
        for v in v0..v1 {
            for u in u0..u1 {
                let d = self.ray(u, v);
                let i = v * w + u;
                let under = self.depth_m[i] as f64;
                let arm = ray_capsule(&d, &pe, &ph, ra).map(|t| (t, None));
                let palm = ray_sphere(&d, &ph, rh).map(|t| (t, Some(())));
                let hit = match (arm, palm) {
                    (Some(a), Some(b)) => Some(if a.0 <= b.0 { a } else { b }),
                    (a, b) => a.or(b),
                };
                let Some((t, is_palm)) = hit.filter(|h| h.0 < under) else {
                    continue;
                };
                let p = d * t;
                let n = if is_palm.is_some() {
                    (p - ph) / rh.max(1e-9)
                } else {
                    // Normal of the capsule: from the closest axis point.
                    let ba = ph - pe;
                    let s = ((p - pe).dot(&ba) / ba.dot(&ba).max(1e-12)).clamp(0.0, 1.0);
                    (p - (pe + ba * s))
                        .try_normalize(1e-12)
                        .unwrap_or(-d.normalize())
                };
                let shade = 0.4 + 0.6 * n.dot(light_c).max(0.0);
                let c = scale_colour(skin, shade);
                self.rgb[i * 3..i * 3 + 3].copy_from_slice(&c);
                self.depth_m[i] = t as f32;
            }
        }
    }

    /// Renders `scene` at `timestamp_s` through the sensor model.
    pub fn render(&mut self, scene: &Scene, timestamp_s: f64) -> Frame {
        let (w, h) = (self.camera.width as usize, self.camera.height as usize);
        let key = (self.camera, scene.wall_x_m, scene.table);
        if self.background.as_ref().is_none_or(|b| b.key != key) {
            self.background = Some(self.render_background(scene));
        }
        if let Some(bg) = &self.background {
            self.rgb.clear();
            self.rgb.extend_from_slice(&bg.rgb);
            self.depth_m.clear();
            self.depth_m.extend_from_slice(&bg.depth_m);
        }
        let light_c = (self.camera.world_from_camera.rotation.inverse() * scene.light_dir_w)
            .try_normalize(1e-12)
            .unwrap_or(Vector3::new(0.0, 0.0, -1.0));
        // Draw far objects first is unnecessary: every draw is z-buffered.
        if let Some(hand) = &scene.hand {
            self.draw_hand(hand, &light_c);
        }
        for s in &scene.decoys {
            self.draw_sphere(s, &light_c);
        }
        if let Some(ball) = &scene.ball {
            self.draw_sphere(ball, &light_c);
        }
        self.sensor_pass(w, h, timestamp_s)
    }

    /// Applies noise, range limits and edge holes; produces the output frame.
    fn sensor_pass(&mut self, w: usize, h: usize, timestamp_s: f64) -> Frame {
        let s = self.sensor;
        let mut prng = PixelRng(self.rng.random());
        let mask = NORMAL_TABLE_LEN - 1;
        let mut depth_mm = vec![0u16; w * h];
        let (zmin, zmax) = (s.min_range_m as f32, s.max_range_m as f32);
        let coeff = s.depth_noise_coeff_per_m as f32;
        let jump = s.edge_jump_m as f32;
        self.update_quantisation_table();
        let quant = std::mem::take(&mut self.quant_mm);
        let (mut bits, mut bits_left) = (0u64, 0u32);
        let hole_threshold = (s.edge_hole_probability.clamp(0.0, 1.0) * u32::MAX as f64) as u64;
        for v in 0..h {
            for u in 0..w {
                let i = v * w + u;
                let z = self.depth_m[i];
                if !(z >= zmin && z <= zmax) {
                    continue;
                }
                if hole_threshold > 0 {
                    let right = if u + 1 < w { self.depth_m[i + 1] } else { z };
                    let down = if v + 1 < h { self.depth_m[i + w] } else { z };
                    let left = if u > 0 { self.depth_m[i - 1] } else { z };
                    let up = if v > 0 { self.depth_m[i - w] } else { z };
                    let edge = (right - z).abs() > jump
                        || (down - z).abs() > jump
                        || (left - z).abs() > jump
                        || (up - z).abs() > jump;
                    if edge && (prng.next() & 0xFFFF_FFFF) < hole_threshold {
                        continue;
                    }
                }
                let zn = if coeff > 0.0 {
                    // One 64-bit draw gives four table indices.
                    if bits_left == 0 {
                        bits = prng.next();
                        bits_left = 4;
                    }
                    let n = self.normals[(bits as usize) & mask];
                    bits >>= 16;
                    bits_left -= 1;
                    z + coeff * z * z * n
                } else {
                    z
                };
                let mm = (zn * 1000.0).round().clamp(1.0, 65535.0) as u16;
                depth_mm[i] = match quant.get(usize::from(mm)) {
                    Some(&q) => q,
                    None => mm,
                };
            }
        }
        self.quant_mm = quant;
        let mut rgb = std::mem::take(&mut self.rgb);
        if s.colour_noise_std > 0.0 {
            if self.colour_noise.0 != s.colour_noise_std {
                let sd = s.colour_noise_std as f32;
                let table = self
                    .normals
                    .iter()
                    .map(|n| (sd * n).round().clamp(-255.0, 255.0) as i16)
                    .collect();
                self.colour_noise = (s.colour_noise_std, table);
            }
            let table = &self.colour_noise.1;
            for quad in rgb.chunks_mut(4) {
                let mut b = prng.next();
                for px in quad {
                    let n = table[(b as usize) & mask];
                    b >>= 16;
                    *px = (i16::from(*px) + n).clamp(0, 255) as u8;
                }
            }
        }
        let frame = Frame {
            width: w as u32,
            height: h as u32,
            rgb: rgb.clone(),
            depth_mm,
            intrinsics: self.camera.intrinsics,
            timestamp_s,
        };
        self.rgb = rgb;
        frame
    }
}
