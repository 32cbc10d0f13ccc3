//! The `sim` driver of the component: the head camera over the simulated table, and the ball
//! moved by a scripted [`Scenario`], with its ground truth.
//!
//! Frames and units (see [`crate::sim`]): world z up, metres; the default [`Scene`] has a
//! 1.2 m (y) x 0.8 m (x) table top at 0.75 m height centred 1.2 m ahead, and a wall 3 m ahead.
//!
//! **Camera pose.** [`CameraPose`] is the camera body (REP 103: x forward, y left, z up) in the
//! world: position (m) and roll / pitch / yaw (rad, `R = Rz(yaw) Ry(pitch) Rx(roll)`, positive
//! pitch looks *down*). [`CameraPose::HEAD_DEFAULT`] is Loki's head camera at rest: 1.5 m high
//! above the origin, looking straight ahead and 30° down, so the optical axis meets the table
//! top 1.3 m ahead, where the scenarios put the ball (about 1.48 m from the camera). The
//! component takes it from `--camera-pose`; the pose is a plain value set on the driver before
//! each frame ([`ScenarioSim::set_camera_pose`]), so when the neck moves, a joint-state
//! subscriber computes `world_from_camera` from the robot model and sets it the same way.
//!
//! **Scenarios** (time `t` in s since the first frame, the ball a 10 cm red sphere resting on the
//! table, centre 5 cm above the top):
//! - `still`: at (1.3, 0, 0.8) m.
//! - `moving`: a circle of radius 0.25 m around (1.25, 0, 0.8) m at 1 m/s (period 1.57 s).
//! - `leave-and-return`: still for 2 s at (1.3, 0, 0.8), then carried along -y at 1 m/s to
//!   y = -1.5 m (out of view from y ≈ -0.85 m), held there 2 s, brought back at 1 m/s and still
//!   again from t = 7 s.

use std::f64::consts::PI;

use nalgebra::{Isometry3, Matrix3, Point3, Rotation3, Translation3, UnitQuaternion, Vector3};

use crate::sim::{Scene, SensorModel, SimCamera, SimDriver, SimRenderer, Sphere};
use crate::{DriverError, Frame, RgbdDriver};

/// The camera body's pose in the world: position (m) and roll, pitch, yaw (rad). See the module
/// doc for the conventions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CameraPose {
    /// Position of the optical centre in the world, m.
    pub position_m: [f64; 3],
    /// Roll about the body's x axis, rad.
    pub roll_rad: f64,
    /// Pitch about the body's y axis, rad; positive looks down.
    pub pitch_rad: f64,
    /// Yaw about the world's z axis, rad; positive looks left.
    pub yaw_rad: f64,
}

impl CameraPose {
    /// Loki's head camera at rest: 1.5 m high, looking ahead and 30° down at the table.
    pub const HEAD_DEFAULT: CameraPose = CameraPose {
        position_m: [0.0, 0.0, 1.5],
        roll_rad: 0.0,
        pitch_rad: PI / 6.0,
        yaw_rad: 0.0,
    };

    /// Parses `x,y,z,roll,pitch,yaw` (m and degrees), as `--camera-pose` takes it.
    pub fn parse(s: &str) -> Result<CameraPose, String> {
        let v: Vec<f64> = s
            .split(',')
            .map(|p| p.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("camera pose {s:?}: {e} (expected x,y,z,roll,pitch,yaw)"))?;
        if v.len() != 6 || v.iter().any(|x| !x.is_finite()) {
            return Err(format!(
                "camera pose {s:?}: expected six finite numbers x,y,z (m),roll,pitch,yaw (deg)"
            ));
        }
        Ok(CameraPose {
            position_m: [v[0], v[1], v[2]],
            roll_rad: v[3].to_radians(),
            pitch_rad: v[4].to_radians(),
            yaw_rad: v[5].to_radians(),
        })
    }

    /// World-from-optical-frame (optical: z forward, x right, y down).
    pub fn world_from_optical(&self) -> Isometry3<f64> {
        let body = UnitQuaternion::from_euler_angles(self.roll_rad, self.pitch_rad, self.yaw_rad);
        // Optical axes in the body frame: x = -y_body, y = -z_body, z = x_body.
        let body_from_optical = UnitQuaternion::from_rotation_matrix(
            &Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[
                Vector3::new(0.0, -1.0, 0.0),
                Vector3::new(0.0, 0.0, -1.0),
                Vector3::new(1.0, 0.0, 0.0),
            ])),
        );
        let [x, y, z] = self.position_m;
        Isometry3::from_parts(Translation3::new(x, y, z), body * body_from_optical)
    }
}

/// How the ball moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Scenario {
    /// Resting on the table in the middle of the image.
    Still,
    /// A circle of 0.25 m radius on the table at 1 m/s.
    Moving,
    /// Still, carried out of view, held there, brought back, still.
    LeaveAndReturn,
}

/// Height of the ball's centre: table top 0.75 m plus the radius of the 10 cm ball.
const BALL_Z_M: f64 = 0.80;
/// Where `still` (and `leave-and-return` at rest) puts the ball, world, m.
const REST_W: [f64; 3] = [1.3, 0.0, BALL_Z_M];

impl Scenario {
    /// Ball centre (world, m) and velocity (world, m/s) at `t_s` after the start.
    pub fn ball_at(self, t_s: f64) -> (Point3<f64>, Vector3<f64>) {
        let rest = Point3::from(REST_W);
        match self {
            Scenario::Still => (rest, Vector3::zeros()),
            Scenario::Moving => {
                let (r, v) = (0.25, 1.0);
                let w = v / r;
                let a = w * t_s;
                (
                    Point3::new(1.25 + r * a.cos(), r * a.sin(), BALL_Z_M),
                    Vector3::new(-v * a.sin(), v * a.cos(), 0.0),
                )
            }
            Scenario::LeaveAndReturn => {
                let (speed, far_y) = (1.0, -1.5);
                let travel_s = -far_y / speed;
                let leave_at = 2.0;
                let back_at = leave_at + travel_s + 2.0;
                let at_y = |y: f64, vy: f64| (Point3::new(rest.x, y, BALL_Z_M), Vector3::y() * vy);
                if t_s < leave_at {
                    at_y(0.0, 0.0)
                } else if t_s < leave_at + travel_s {
                    at_y(-speed * (t_s - leave_at), -speed)
                } else if t_s < back_at {
                    at_y(far_y, 0.0)
                } else if t_s < back_at + travel_s {
                    at_y(far_y + speed * (t_s - back_at), speed)
                } else {
                    at_y(0.0, 0.0)
                }
            }
        }
    }
}

/// The ground truth of one simulated frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BallGroundTruth {
    /// Ball centre in the camera optical frame, m.
    pub centre_camera_m: [f64; 3],
    /// Ball centre in the world frame, m.
    pub centre_world_m: [f64; 3],
    /// Ball diameter, m.
    pub diameter_m: f64,
    /// The whole ball projects inside the image, in front of the camera.
    pub in_view: bool,
}

/// The sim driver with a scenario: renders the scene with the ball where the scenario has it at
/// the time asked (time since the first frame), and keeps that frame's ground truth.
#[derive(Debug)]
pub struct ScenarioSim {
    driver: SimDriver,
    scenario: Scenario,
    ball_diameter_m: f64,
    ball_colour: [u8; 3],
    start_s: Option<f64>,
    truth: Option<BallGroundTruth>,
}

/// The ball's colour: the red of the shipped sequence, hue 3.2°, saturation 0.86.
pub const BALL_RED: [u8; 3] = [220, 40, 30];
/// The ball's diameter, m.
pub const BALL_DIAMETER_M: f64 = 0.10;

impl ScenarioSim {
    /// A 640x480 Kinect-like camera at `pose` over the default scene, `sensor` imperfections,
    /// random stream `seed`.
    pub fn new(scenario: Scenario, pose: CameraPose, sensor: SensorModel, seed: u64) -> Self {
        let camera = SimCamera::vga(pose.world_from_optical());
        ScenarioSim {
            driver: SimDriver {
                renderer: SimRenderer::new(camera, sensor, seed),
                scene: Scene::default(),
            },
            scenario,
            ball_diameter_m: BALL_DIAMETER_M,
            ball_colour: BALL_RED,
            start_s: None,
            truth: None,
        }
    }

    /// Moves the camera (the next frame is rendered from there).
    pub fn set_camera_pose(&mut self, pose: CameraPose) {
        self.driver.renderer.camera.world_from_camera = pose.world_from_optical();
    }

    /// Moves the camera to `world_from_optical` (optical frame: z forward, x right, y down), as
    /// computed from the robot's joints.
    pub fn set_world_from_optical(&mut self, pose: Isometry3<f64>) {
        self.driver.renderer.camera.world_from_camera = pose;
    }

    /// The camera (pose, intrinsics, size).
    pub fn camera(&self) -> &SimCamera {
        &self.driver.renderer.camera
    }

    /// Ground truth of the last frame rendered.
    pub fn truth(&self) -> Option<BallGroundTruth> {
        self.truth
    }

    fn truth_for(&self, centre_w: &Point3<f64>) -> BallGroundTruth {
        ball_truth(self.camera(), centre_w, self.ball_diameter_m)
    }
}

/// The ground truth of a ball of `diameter_m` centred at `centre_w` (world) seen by `cam`.
pub fn ball_truth(cam: &SimCamera, centre_w: &Point3<f64>, diameter_m: f64) -> BallGroundTruth {
    let c = cam.world_from_camera.inverse_transform_point(centre_w);
    let r = diameter_m / 2.0;
    let in_view = cam
        .intrinsics
        .project([c.x, c.y, c.z])
        .is_some_and(|[u, v]| {
            let r_px = cam.intrinsics.fx * r / (c.z - r).max(1e-6);
            c.z > r
                && u - r_px >= 0.0
                && v - r_px >= 0.0
                && u + r_px <= f64::from(cam.width) - 1.0
                && v + r_px <= f64::from(cam.height) - 1.0
        });
    BallGroundTruth {
        centre_camera_m: [c.x, c.y, c.z],
        centre_world_m: [centre_w.x, centre_w.y, centre_w.z],
        diameter_m,
        in_view,
    }
}

impl RgbdDriver for ScenarioSim {
    fn next_frame(&mut self, now_s: f64) -> Result<Option<Frame>, DriverError> {
        let start = *self.start_s.get_or_insert(now_s);
        let (centre, velocity) = self.scenario.ball_at(now_s - start);
        let mut ball = Sphere::new(centre, self.ball_diameter_m, self.ball_colour);
        ball.velocity_w_mps = velocity;
        self.driver.scene.ball = Some(ball);
        self.truth = Some(self.truth_for(&centre));
        self.driver.next_frame(now_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn default_pose_looks_down_30_degrees_at_the_ball_on_the_table() {
        let pose = CameraPose::HEAD_DEFAULT.world_from_optical();
        // The optical axis (z) points forward and 30° down.
        let z = pose.rotation * Vector3::z();
        assert!((z - Vector3::new(30f64.to_radians().cos(), 0.0, -0.5)).norm() < 1e-12);
        // Image right (x) is world -y, image down (y) is below the horizon.
        let x = pose.rotation * Vector3::x();
        assert!((x - Vector3::new(0.0, -1.0, 0.0)).norm() < 1e-12);
        assert!((pose.rotation * Vector3::y()).z < 0.0);
        // The resting ball is near the image centre, about 1.48 m away.
        let sim = ScenarioSim::new(
            Scenario::Still,
            CameraPose::HEAD_DEFAULT,
            SensorModel::ideal(),
            1,
        );
        let t = sim.truth_for(&Point3::from(REST_W));
        assert!(t.in_view);
        let [u, v] = sim.camera().intrinsics.project(t.centre_camera_m).unwrap();
        assert!(
            (u - 319.5).abs() < 1.0 && (v - 239.5).abs() < 30.0,
            "{u} {v}"
        );
        let d = Vector3::from(t.centre_camera_m).norm();
        assert!((d - 1.476).abs() < 0.01, "{d}");
    }

    #[test]
    fn camera_pose_flag_parses_degrees_and_rejects_garbage() {
        let p = CameraPose::parse("0,0,1.5,0,30,0").unwrap();
        assert!((p.pitch_rad - CameraPose::HEAD_DEFAULT.pitch_rad).abs() < 1e-12);
        assert_eq!(p.position_m, [0.0, 0.0, 1.5]);
        assert!(CameraPose::parse("0,0,1.5").is_err());
        assert!(CameraPose::parse("0,0,x,0,0,0").is_err());
        assert!(CameraPose::parse("0,0,inf,0,0,0").is_err());
    }

    #[test]
    fn moving_is_1_mps_on_the_table_and_stays_in_view() {
        let sim = ScenarioSim::new(
            Scenario::Moving,
            CameraPose::HEAD_DEFAULT,
            SensorModel::ideal(),
            1,
        );
        let dt = 1.0 / 30.0;
        for i in 0..100 {
            let t = i as f64 * dt;
            let (p, v) = Scenario::Moving.ball_at(t);
            let (q, _) = Scenario::Moving.ball_at(t + 1e-4);
            assert!((v.norm() - 1.0).abs() < 1e-9);
            assert!(((q - p).norm() / 1e-4 - 1.0).abs() < 1e-3);
            assert!((0.8..=1.6).contains(&p.x) && p.y.abs() <= 0.6 && p.z == BALL_Z_M);
            assert!(sim.truth_for(&p).in_view, "t = {t}");
        }
    }

    #[test]
    fn leave_and_return_leaves_the_view_and_comes_back() {
        let sim = ScenarioSim::new(
            Scenario::LeaveAndReturn,
            CameraPose::HEAD_DEFAULT,
            SensorModel::ideal(),
            1,
        );
        let in_view = |t: f64| {
            sim.truth_for(&Scenario::LeaveAndReturn.ball_at(t).0)
                .in_view
        };
        assert!(in_view(0.0) && in_view(1.9));
        assert!(!in_view(3.5) && !in_view(4.5) && !in_view(5.4));
        assert!(in_view(7.0) && in_view(20.0));
        // Continuous: no jumps between frames.
        for i in 0..300 {
            let t = i as f64 / 30.0;
            let a = Scenario::LeaveAndReturn.ball_at(t).0;
            let b = Scenario::LeaveAndReturn.ball_at(t + 1.0 / 30.0).0;
            assert!((b - a).norm() <= 1.0 / 30.0 + 1e-9);
        }
    }

    #[test]
    fn frames_show_the_ball_where_the_truth_says() {
        let mut sim = ScenarioSim::new(
            Scenario::Still,
            CameraPose::HEAD_DEFAULT,
            SensorModel::ideal(),
            1,
        );
        let f = sim.next_frame(100.0).unwrap().unwrap();
        assert_eq!(f.timestamp_s, 100.0);
        let truth = sim.truth().unwrap();
        let [u, v] = f.intrinsics.project(truth.centre_camera_m).unwrap();
        let i = v.round() as usize * f.width as usize + u.round() as usize;
        let (r, g, b) = (f.rgb[i * 3], f.rgb[i * 3 + 1], f.rgb[i * 3 + 2]);
        assert!(r > 100 && g < 60 && b < 60, "centre pixel {r} {g} {b}");
        // Depth at the centre pixel is the ball's front surface: centre z minus about a radius.
        let z_mm = f64::from(f.depth_mm[i]);
        let expect = truth.centre_camera_m[2] * 1000.0 - 50.0;
        assert!((z_mm - expect).abs() < 15.0, "{z_mm} vs {expect}");
    }
}
