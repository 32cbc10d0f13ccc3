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

use crate::types::{Frame, Intrinsics};

mod render;

pub use render::SimRenderer;

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
mod tests;
