//! Simulated RGB-D sensor: renders a small tabletop scene analytically.
//!
//! Frames and units:
//! - The **world** frame is z up (metres); the scene is a floor (`z = 0`), a textured wall (the
//!   vertical plane `x = wall_x_m`), an optional table top (horizontal rectangle), the ball, decoy
//!   spheres and optionally the person's forearm and hand.
//! - The camera pose is `world_from_camera`, an [`Isometry3`] to the camera's **optical** frame
//!   (z forward, x right, y down); [`look_at`] builds one.
//! - Output [`Frame`]s are RGB8 plus depth in millimetres along the optical axis.
//!
//! Rendering is a ray cast per pixel, but only where it matters: the static part (floor, wall,
//! table) is rendered once per camera pose and cached; spheres and the arm are intersected
//! analytically inside their projected bounding boxes. A sensor pass then adds what a
//! structured-light camera does to the ideal image: depth noise with standard deviation
//! `depth_noise_coeff_per_m * z^2`, holes (0) outside `[min_range_m, max_range_m]` and, with some
//! probability, at depth discontinuities, and colour noise. Optionally the ball is motion-blurred
//! over the exposure. All randomness comes from one seeded generator, so a renderer created with
//! the same seed and fed the same scenes produces identical frames.

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, UnitQuaternion, Vector3};
use rand::rngs::SmallRng;
use rand::{Rng, SeedableRng};

use crate::types::{Frame, Intrinsics};

/// A sphere of uniform colour (the ball, or a decoy).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    /// Centre in the world frame, m.
    pub centre_w: Point3<f64>,
    /// Diameter, m.
    pub diameter_m: f64,
    /// Albedo, RGB8 (the colour seen under full light).
    pub colour: [u8; 3],
    /// Velocity in the world frame, m/s; used only for motion blur.
    pub velocity_w_mps: Vector3<f64>,
}

impl Sphere {
    /// A still sphere.
    pub fn new(centre_w: Point3<f64>, diameter_m: f64, colour: [u8; 3]) -> Sphere {
        Sphere {
            centre_w,
            diameter_m,
            colour,
            velocity_w_mps: Vector3::zeros(),
        }
    }
}

/// The person's forearm (a capsule from elbow to hand) and hand (a sphere), skin coloured.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HandArm {
    /// Elbow position, world frame, m.
    pub elbow_w: Point3<f64>,
    /// Palm centre, world frame, m.
    pub hand_w: Point3<f64>,
    /// Forearm radius, m.
    pub forearm_radius_m: f64,
    /// Hand radius, m.
    pub hand_radius_m: f64,
    /// Skin albedo, RGB8.
    pub skin: [u8; 3],
}

/// A horizontal table top.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Table {
    /// Centre of the top surface, world frame, m.
    pub centre_w: Point3<f64>,
    /// Extent along world x, m.
    pub size_x_m: f64,
    /// Extent along world y, m.
    pub size_y_m: f64,
}

/// Everything the camera can see.
#[derive(Debug, Clone, PartialEq)]
pub struct Scene {
    /// The wall plane is `x = wall_x_m` (world), facing the camera.
    pub wall_x_m: f64,
    /// The table top, if any.
    pub table: Option<Table>,
    /// The ball, if any.
    pub ball: Option<Sphere>,
    /// Other spheres (e.g. a same-coloured object of the wrong size).
    pub decoys: Vec<Sphere>,
    /// The person's forearm and hand, if any.
    pub hand: Option<HandArm>,
    /// Direction *towards* the light, world frame (need not be unit).
    pub light_dir_w: Vector3<f64>,
}

impl Default for Scene {
    /// A wall 3 m ahead, a 1.2 x 0.8 m table top at 0.75 m centred 1.2 m ahead, nothing else.
    fn default() -> Scene {
        Scene {
            wall_x_m: 3.0,
            table: Some(Table {
                centre_w: Point3::new(1.2, 0.0, 0.75),
                size_x_m: 0.8,
                size_y_m: 1.2,
            }),
            ball: None,
            decoys: Vec::new(),
            hand: None,
            light_dir_w: Vector3::new(-0.4, 0.3, 1.0),
        }
    }
}

impl Scene {
    /// Loki's "touch the ball" scene, the robot's `base_footprint` at the world origin facing
    /// +x: a 0.7 m (x) x 1.2 m (y) table top at 0.75 m height from 0.4 m to 1.1 m ahead (within
    /// the arms' reach), and the textured wall 3 m ahead. No ball: the world puts it in.
    pub fn game() -> Scene {
        Scene {
            table: Some(Table {
                centre_w: Point3::new(0.75, 0.0, 0.75),
                size_x_m: 0.7,
                size_y_m: 1.2,
            }),
            ..Scene::default()
        }
    }
}

/// Sensor imperfections.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SensorModel {
    /// Depth noise standard deviation is `depth_noise_coeff_per_m * z^2` (z in m); 0 disables.
    /// The default, 0.0025 / m, is 2.5 mm at 1 m and 10 mm at 2 m, like a Kinect-class sensor.
    pub depth_noise_coeff_per_m: f64,
    /// Focal length times baseline of the structured-light pair, pixel·m (Kinect: 580 px ×
    /// 0.075 m = 43.5). Depth is quantised in disparity `d = fb / z` to steps of
    /// `disparity_step_px`, so the depth step grows as `z^2 * step / fb` (2.9 mm at 1 m, 11.5 mm
    /// at 2 m for the Kinect). 0 disables quantisation.
    pub disparity_focal_baseline_px_m: f64,
    /// Disparity quantum, pixels (Kinect: 1/8).
    pub disparity_step_px: f64,
    /// Closer than this gives depth 0, m.
    pub min_range_m: f64,
    /// Farther than this gives depth 0, m.
    pub max_range_m: f64,
    /// A depth jump larger than this between neighbours marks an edge pixel, m.
    pub edge_jump_m: f64,
    /// Probability that an edge pixel's depth is dropped (0).
    pub edge_hole_probability: f64,
    /// Colour noise standard deviation, RGB levels; 0 disables.
    pub colour_noise_std: f64,
    /// Number of sub-frame ball positions averaged for motion blur; 1 disables.
    pub motion_blur_samples: u32,
    /// Exposure time for motion blur, s.
    pub exposure_s: f64,
}

impl Default for SensorModel {
    fn default() -> SensorModel {
        SensorModel {
            depth_noise_coeff_per_m: 0.0025,
            disparity_focal_baseline_px_m: 43.5,
            disparity_step_px: 0.125,
            min_range_m: 0.4,
            max_range_m: 4.0,
            edge_jump_m: 0.05,
            edge_hole_probability: 0.6,
            colour_noise_std: 2.0,
            motion_blur_samples: 1,
            exposure_s: 0.01,
        }
    }
}

impl SensorModel {
    /// A perfect sensor: no noise, no edge holes, no blur (range limits still apply).
    pub fn ideal() -> SensorModel {
        SensorModel {
            depth_noise_coeff_per_m: 0.0,
            disparity_focal_baseline_px_m: 0.0,
            edge_hole_probability: 0.0,
            colour_noise_std: 0.0,
            ..SensorModel::default()
        }
    }
}

/// Pose and intrinsics of the simulated camera.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SimCamera {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Pinhole intrinsics.
    pub intrinsics: Intrinsics,
    /// World-from-camera (optical frame: z forward, x right, y down).
    pub world_from_camera: Isometry3<f64>,
}

impl SimCamera {
    /// A 640x480 Kinect-like camera at `world_from_camera`.
    pub fn vga(world_from_camera: Isometry3<f64>) -> SimCamera {
        SimCamera {
            width: 640,
            height: 480,
            intrinsics: Intrinsics::KINECT_640X480,
            world_from_camera,
        }
    }

    /// Projects a world point to pixel coordinates; `None` behind the camera.
    pub fn project_world(&self, p_w: &Point3<f64>) -> Option<[f64; 2]> {
        let p_c = self.world_from_camera.inverse_transform_point(p_w);
        self.intrinsics.project([p_c.x, p_c.y, p_c.z])
    }
}

/// Optical-frame camera pose at `eye` looking at `target`, with `up_w` (world) pointing up in the
/// image. Returns world-from-camera. Degenerate input (target at the eye, or view along `up_w`)
/// falls back to a camera looking along world +x.
pub fn look_at(eye: Point3<f64>, target: Point3<f64>, up_w: Vector3<f64>) -> Isometry3<f64> {
    let fallback = || {
        Matrix3::from_columns(&[
            Vector3::new(0.0, -1.0, 0.0),
            Vector3::new(0.0, 0.0, -1.0),
            Vector3::new(1.0, 0.0, 0.0),
        ])
    };
    let m = (target - eye)
        .try_normalize(1e-9)
        .and_then(|z| {
            let x = z.cross(&up_w).try_normalize(1e-9)?;
            let y = z.cross(&x);
            Some(Matrix3::from_columns(&[x, y, z]))
        })
        .unwrap_or_else(fallback);
    let rot = UnitQuaternion::from_rotation_matrix(&Rotation3::from_matrix_unchecked(m));
    Isometry3::from_parts(eye.coords.into(), rot)
}

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

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> SimCamera {
        SimCamera::vga(look_at(
            Point3::new(0.0, 0.0, 1.2),
            Point3::new(1.0, 0.0, 0.9),
            Vector3::z(),
        ))
    }

    fn ball_scene(centre: Point3<f64>) -> Scene {
        Scene {
            ball: Some(Sphere::new(centre, 0.1, [220, 60, 20])),
            ..Scene::default()
        }
    }

    #[test]
    fn look_at_points_optical_axis_at_target() {
        let pose = look_at(
            Point3::new(0.0, 0.0, 1.0),
            Point3::new(2.0, 0.0, 1.0),
            Vector3::z(),
        );
        let z = pose.rotation * Vector3::z();
        let x = pose.rotation * Vector3::x();
        let y = pose.rotation * Vector3::y();
        assert!((z - Vector3::x()).norm() < 1e-12, "z forward {z}");
        assert!((x + Vector3::y()).norm() < 1e-12, "x right (world -y) {x}");
        assert!((y + Vector3::z()).norm() < 1e-12, "y down {y}");
    }

    #[test]
    fn ideal_ball_depth_matches_geometry() {
        let cam = camera();
        let centre = Point3::new(1.0, 0.05, 0.95);
        let mut r = SimRenderer::new(cam, SensorModel::ideal(), 1);
        let f = r.render(&ball_scene(centre), 0.0);
        assert_eq!(f.validate(), Ok(()));
        let [u, v] = cam.project_world(&centre).unwrap();
        let i = (v.round() as usize) * 640 + u.round() as usize;
        let c_c = cam.world_from_camera.inverse_transform_point(&centre);
        // The pixel through the centre sees the front of the sphere, ~radius closer than the centre.
        let expected_mm = (c_c.z - 0.05) * 1000.0;
        assert!(
            (f64::from(f.depth_mm[i]) - expected_mm).abs() < 3.0,
            "depth {} vs {expected_mm}",
            f.depth_mm[i]
        );
        // The colour there is the ball's hue: red dominant.
        let px = &f.rgb[i * 3..i * 3 + 3];
        assert!(px[0] > 2 * px[1] && px[0] > 3 * px[2], "{px:?}");
        // Pixels far from the ball keep the background.
        let far = 10 * 640 + 10;
        assert_ne!(&f.rgb[far * 3..far * 3 + 3], px);
    }

    #[test]
    fn range_limits_give_holes() {
        let cam = camera();
        let mut r = SimRenderer::new(cam, SensorModel::ideal(), 1);
        // Ball 0.2 m in front of the camera: closer than min range.
        let near = cam.world_from_camera * Point3::new(0.0, 0.0, 0.25);
        let f = r.render(&ball_scene(near), 0.0);
        assert_eq!(f.depth_mm[240 * 640 + 320], 0);
        // Sky above the wall (if any) and the wall beyond 4 m are holes too.
        let far_scene = Scene {
            wall_x_m: 6.0,
            table: None,
            ..Scene::default()
        };
        let f = r.render(&far_scene, 0.0);
        assert!(f.depth_mm.iter().filter(|&&d| d == 0).count() > 1000);
        assert!(
            f.depth_mm
                .iter()
                .all(|&d| d == 0 || (400..=4000).contains(&d))
        );
    }

    #[test]
    fn depth_noise_grows_with_distance_squared() {
        // Camera facing the wall head on; measure per-pixel std over frames at 1 m and 2 m.
        let std_at = |dist: f64| {
            let cam = SimCamera::vga(look_at(
                Point3::new(3.0 - dist, 0.0, 1.5),
                Point3::new(3.0, 0.0, 1.5),
                Vector3::z(),
            ));
            let mut r = SimRenderer::new(cam, SensorModel::default(), 7);
            let scene = Scene {
                table: None,
                ..Scene::default()
            };
            let ideal = dist * 1000.0;
            let f = r.render(&scene, 0.0);
            let (mut s2, mut n) = (0.0, 0.0);
            for v in 200..280 {
                for u in 280..360 {
                    let d = f64::from(f.depth_mm[v * 640 + u]);
                    s2 += (d - ideal) * (d - ideal);
                    n += 1.0;
                }
            }
            (s2 / n).sqrt()
        };
        let (s1, s2) = (std_at(1.0), std_at(2.0));
        // Noise (2.5 mm at 1 m) plus disparity quantisation (2.9 mm steps at 1 m, uniform
        // error of sd step / sqrt(12) = 0.8 mm), both growing with z^2.
        assert!((s1 - 2.6).abs() < 0.6, "sigma at 1 m {s1} mm");
        assert!((s2 / s1 - 4.0).abs() < 0.7, "sigma ratio {}", s2 / s1);
    }

    #[test]
    fn depth_is_quantised_in_disparity() {
        let cam = SimCamera::vga(look_at(
            Point3::new(1.0, 0.0, 1.5),
            Point3::new(3.0, 0.0, 1.5),
            Vector3::z(),
        ));
        let sensor = SensorModel {
            depth_noise_coeff_per_m: 0.0,
            ..SensorModel::default()
        };
        let scene = Scene {
            table: None,
            ..Scene::default()
        };
        let f = SimRenderer::new(cam, sensor, 1).render(&scene, 0.0);
        let mut values: Vec<u16> = f.depth_mm.iter().copied().filter(|&d| d > 0).collect();
        values.sort_unstable();
        values.dedup();
        // The wall is seen at optical depth exactly 2 m: one quantised value, within half a
        // step (11.5 mm / 2) of 2000 mm.
        assert_eq!(values.len(), 1, "{values:?}");
        assert!((i32::from(values[0]) - 2000).abs() <= 6, "{values:?}");
    }

    #[test]
    fn edges_get_holes_and_render_is_deterministic() {
        let cam = camera();
        let scene = ball_scene(Point3::new(1.0, 0.0, 0.95));
        let mut a = SimRenderer::new(cam, SensorModel::default(), 42);
        let mut b = SimRenderer::new(cam, SensorModel::default(), 42);
        let fa = a.render(&scene, 0.5);
        let fb = b.render(&scene, 0.5);
        assert_eq!(fa, fb);
        let [u, v] = cam.project_world(&Point3::new(1.0, 0.0, 0.95)).unwrap();
        // Walk right from the ball centre across its rim; some rim pixels must be holes.
        let row = v.round() as usize;
        let holes = (u as usize..640)
            .take(60)
            .filter(|&x| fa.depth_mm[row * 640 + x] == 0)
            .count();
        assert!(holes >= 1, "no hole at the ball's edge");
        let mut c = SimRenderer::new(cam, SensorModel::default(), 43);
        assert_ne!(c.render(&scene, 0.5).depth_mm, fa.depth_mm);
    }

    #[test]
    fn hand_and_motion_blur_render() {
        let cam = camera();
        let mut scene = ball_scene(Point3::new(1.0, 0.0, 0.95));
        scene.hand = Some(HandArm {
            elbow_w: Point3::new(1.1, -0.35, 0.85),
            hand_w: Point3::new(1.02, -0.08, 0.93),
            forearm_radius_m: 0.035,
            hand_radius_m: 0.05,
            skin: [225, 175, 145],
        });
        let mut r = SimRenderer::new(cam, SensorModel::ideal(), 1);
        let f = r.render(&scene, 0.0);
        let [u, v] = cam.project_world(&Point3::new(1.1, -0.35, 0.85)).unwrap();
        let i = v.round() as usize * 640 + u.round() as usize;
        let px = &f.rgb[i * 3..i * 3 + 3];
        assert!(
            px[0] > px[1] && px[1] > px[2],
            "skin-ish at the elbow {px:?}"
        );
        // Motion blur widens the ball's smear along the motion.
        let mut blurred = scene.clone();
        blurred.hand = None;
        if let Some(b) = blurred.ball.as_mut() {
            b.velocity_w_mps = Vector3::new(0.0, -3.0, 0.0);
        }
        let mut sensor = SensorModel::ideal();
        sensor.motion_blur_samples = 5;
        sensor.exposure_s = 0.03;
        let mut rb = SimRenderer::new(cam, sensor, 1);
        let mut rs = SimRenderer::new(cam, SensorModel::ideal(), 1);
        let fb = rb.render(&blurred, 0.0);
        if let Some(b) = blurred.ball.as_mut() {
            b.velocity_w_mps = Vector3::zeros();
        }
        let fs = rs.render(&blurred, 0.0);
        let mut empty = blurred.clone();
        empty.ball = None;
        let fe = SimRenderer::new(cam, SensorModel::ideal(), 1).render(&empty, 0.0);
        let touched = |f: &Frame| {
            f.rgb
                .chunks_exact(3)
                .zip(fe.rgb.chunks_exact(3))
                .filter(|(a, b)| a != b)
                .count()
        };
        assert!(
            touched(&fb) > touched(&fs) + 200,
            "{} vs {}",
            touched(&fb),
            touched(&fs)
        );
    }
}

/// The `sim` driver: renders [`SimDriver::scene`] (set it before each call) at the time asked.
#[derive(Debug)]
pub struct SimDriver {
    /// The renderer (camera pose, sensor model, random state).
    pub renderer: SimRenderer,
    /// The scene rendered by the next call.
    pub scene: Scene,
}

impl crate::RgbdDriver for SimDriver {
    fn next_frame(&mut self, now_s: f64) -> Result<Option<Frame>, crate::DriverError> {
        Ok(Some(self.renderer.render(&self.scene, now_s)))
    }
}

#[cfg(test)]
mod driver_tests {
    use super::*;
    use crate::RgbdDriver;

    #[test]
    fn sim_driver_renders_the_current_scene_at_the_time_asked() {
        let cam = SimCamera::vga(look_at(
            Point3::new(0.0, 0.0, 1.3),
            Point3::new(1.0, 0.0, 0.9),
            Vector3::z(),
        ));
        let mut d = SimDriver {
            renderer: SimRenderer::new(cam, SensorModel::ideal(), 3),
            scene: Scene::default(),
        };
        let empty = d.next_frame(1.5).unwrap().unwrap();
        assert_eq!(empty.timestamp_s, 1.5);
        d.scene.ball = Some(Sphere::new(Point3::new(0.9, 0.0, 0.9), 0.1, [20, 30, 220]));
        let with_ball = d.next_frame(1.6).unwrap().unwrap();
        assert_ne!(empty.rgb, with_ball.rgb);
        let changed = empty
            .depth_mm
            .iter()
            .zip(&with_ball.depth_mm)
            .filter(|(a, b)| a != b)
            .count();
        // A 10 cm ball ~0.95 m away covers about pi * 27^2 = 2300 pixels.
        assert!((1800..2900).contains(&changed), "{changed}");
    }
}
