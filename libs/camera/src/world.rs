//! The `sim` driver inside the simulated Loki world: the camera where the robot's joints put it,
//! and the ball where the simulated person has it.
//!
//! Frames and units: world z up, metres (the deep representation's `world`); the robot's
//! `base_footprint` sits at `world_from_base` (the world origin by default, as in the DR's touch
//! scene); joint values in rad (revolute) or m (prismatic), named as in `models/loki.urdf`.
//!
//! - [`HeadCamera`]: `world_T_optical = world_T_base_footprint * base_footprint_T_optical(q)`,
//!   the forward kinematics of the URDF chain from the root link to the camera's optical frame
//!   (`head_rgbd_optical_frame`: base yaw and forward, neck rotation, pitch, roll, yaw). Joint
//!   values come from `body/joint_states` ([`HeadCamera::apply`]); until the first one, and for
//!   any chain joint a state never names, the rest posture: 0 clamped into the joint's limits.
//!   At rest Loki's head camera is 1.55 m high, looking straight ahead (the table is below the
//!   image); the neck must pitch down (about 0.5 rad) to see the table.
//! - [`Scene::game`](crate::sim::Scene::game) is the game's scene: a table in front of the
//!   robot, a textured wall behind it.
//! - [`ball_sphere`] and [`holding_hand`] turn the simulated world's ball (`sim/ball`, a
//!   [`SimBall`]) into what the renderer draws: a sphere of the ball's hue and saturation and,
//!   when the person holds it, their hand under it and forearm towards them.

use interfaces::msg::body::JointStates;
use interfaces::msg::tracking::SimBall;
use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use robot_model::{Chain, JointLimits, RobotModel};

use crate::scenario::{BallGroundTruth, ball_truth};
use crate::sim::{HandArm, Scene, SensorModel, SimCamera, SimDriver, SimRenderer, Sphere};
use crate::{DriverError, Frame, RgbdDriver};

/// Why a [`HeadCamera`] cannot be built.
#[derive(Debug, thiserror::Error)]
pub enum HeadCameraError {
    /// The URDF has no chain from its root to the camera frame.
    #[error("the robot model has no chain from its root to the camera frame `{frame}`: {source}")]
    NoChain {
        /// The camera's optical frame asked for.
        frame: String,
        /// The model's error.
        source: robot_model::ModelError,
    },
}

/// What [`HeadCamera::apply`] did with one joint-state message.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ApplyReport {
    /// Chain joints the message set.
    pub set: usize,
    /// Chain joints the message does not name (they keep their previous value).
    pub missing: Vec<String>,
    /// Chain joints whose value was not finite (ignored).
    pub non_finite: Vec<String>,
    /// Chain joints whose value was outside the URDF limits (clamped).
    pub clamped: Vec<String>,
}

/// The head camera's pose from the robot's joints through the URDF.
#[derive(Debug, Clone)]
pub struct HeadCamera {
    chain: Chain,
    limits: Vec<JointLimits>,
    q: Vec<f64>,
    world_from_base: Isometry3<f64>,
}

impl HeadCamera {
    /// The chain from `model`'s root link (`base_footprint` for Loki) to `optical_frame`, at the
    /// rest posture, with the root at `world_from_base`.
    pub fn new(
        model: &RobotModel,
        optical_frame: &str,
        world_from_base: Isometry3<f64>,
    ) -> Result<HeadCamera, HeadCameraError> {
        let chain = model
            .chain(&model.root_link().name, optical_frame)
            .map_err(|source| HeadCameraError::NoChain {
                frame: optical_frame.to_string(),
                source,
            })?;
        let limits = chain.limits();
        let q = limits.iter().map(|l| l.clamp(0.0)).collect();
        Ok(HeadCamera {
            chain,
            limits,
            q,
            world_from_base,
        })
    }

    /// The chain's joint names, root to camera.
    pub fn joint_names(&self) -> Vec<&str> {
        self.chain.joint_names()
    }

    /// The joint values now, chain order (rad or m).
    pub fn joint_values(&self) -> &[f64] {
        &self.q
    }

    /// Takes the chain's joints from a joint-state message (other joints are ignored).
    pub fn apply(&mut self, states: &JointStates) -> ApplyReport {
        let mut report = ApplyReport::default();
        for (i, j) in self.chain.joints.iter().enumerate() {
            match states.get(&j.name) {
                None => report.missing.push(j.name.clone()),
                Some(s) if !s.position.is_finite() => report.non_finite.push(j.name.clone()),
                Some(s) => {
                    let v = self.limits[i].clamp(s.position);
                    if v != s.position {
                        report.clamped.push(j.name.clone());
                    }
                    self.q[i] = v;
                    report.set += 1;
                }
            }
        }
        report
    }

    /// Where the robot's root link is in the world.
    pub fn set_world_from_base(&mut self, pose: Isometry3<f64>) {
        self.world_from_base = pose;
    }

    /// `world_T_optical` for the joint values now.
    pub fn world_from_optical(&self) -> Isometry3<f64> {
        self.world_from_base * self.chain.fk_unchecked(&self.q)
    }
}

/// A planar robot pose in the world: `x,y` (m) and `yaw` (rad, about z).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RobotPose {
    /// Position of `base_footprint` in the world, m.
    pub x_m: f64,
    /// Position of `base_footprint` in the world, m.
    pub y_m: f64,
    /// Heading, rad (0: the robot faces world +x).
    pub yaw_rad: f64,
}

impl RobotPose {
    /// Parses `x,y,yaw` (m, m, degrees), as `--robot-pose` takes it.
    pub fn parse(s: &str) -> Result<RobotPose, String> {
        let v: Vec<f64> = s
            .split(',')
            .map(|p| p.trim().parse::<f64>())
            .collect::<Result<_, _>>()
            .map_err(|e| format!("robot pose {s:?}: {e} (expected x,y,yaw)"))?;
        if v.len() != 3 || v.iter().any(|x| !x.is_finite()) {
            return Err(format!(
                "robot pose {s:?}: expected three finite numbers x,y (m),yaw (deg)"
            ));
        }
        Ok(RobotPose {
            x_m: v[0],
            y_m: v[1],
            yaw_rad: v[2].to_radians(),
        })
    }

    /// `world_T_base_footprint`.
    pub fn world_from_base(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(self.x_m, self.y_m, 0.0),
            UnitQuaternion::from_axis_angle(&Vector3::z_axis(), self.yaw_rad),
        )
    }
}

/// RGB8 of HSV colour `hue_deg` (degrees, any value, wrapped), `saturation` and `value` (both
/// clamped to `[0, 1]`).
pub fn hsv_to_rgb(hue_deg: f64, saturation: f64, value: f64) -> [u8; 3] {
    let h = hue_deg.rem_euclid(360.0) / 60.0;
    let s = if saturation.is_finite() {
        saturation.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let v = if value.is_finite() {
        value.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let c = v * s;
    let x = c * (1.0 - (h % 2.0 - 1.0).abs());
    let (r, g, b) = match h as u32 {
        0 => (c, x, 0.0),
        1 => (x, c, 0.0),
        2 => (0.0, c, x),
        3 => (0.0, x, c),
        4 => (x, 0.0, c),
        _ => (c, 0.0, x),
    };
    let m = v - c;
    let to8 = |f: f64| ((f + m) * 255.0).round().clamp(0.0, 255.0) as u8;
    [to8(r), to8(g), to8(b)]
}

/// The HSV value of the rendered ball's albedo (its brightest, fully lit colour is 0.9 of white).
pub const BALL_VALUE: f64 = 0.9;

/// The sphere to draw for the simulated world's ball, extrapolated `dt_s` ahead with its velocity
/// (`dt_s` is clamped to `[0, 0.1]` s: the renderer never guesses further); `None` when it is
/// not present or its numbers are unusable.
pub fn ball_sphere(ball: &SimBall, dt_s: f64) -> Option<Sphere> {
    let usable = ball.present
        && ball.diameter_m.is_finite()
        && ball.diameter_m > 0.0
        && ball.centre_world_m.iter().all(|x| x.is_finite());
    if !usable {
        return None;
    }
    let v = Vector3::from(ball.velocity_world_mps);
    let v = if v.iter().all(|x| x.is_finite()) {
        v
    } else {
        Vector3::zeros()
    };
    let dt = if dt_s.is_finite() {
        dt_s.clamp(0.0, 0.1)
    } else {
        0.0
    };
    let centre = Point3::from(ball.centre_world_m) + v * dt;
    let colour = hsv_to_rgb(
        f64::from(ball.hue_deg),
        f64::from(ball.saturation),
        BALL_VALUE,
    );
    let mut s = Sphere::new(centre, ball.diameter_m, colour);
    s.velocity_w_mps = v;
    Some(s)
}

/// The person's hand holding `ball` from below and behind (as seen from `camera`), the forearm
/// running away from the camera and down, towards the person facing the robot.
pub fn holding_hand(ball: &Sphere, camera: &SimCamera) -> HandArm {
    let r = ball.diameter_m / 2.0;
    let hand_radius_m = 0.045;
    // Horizontal direction from the camera to the ball: the person stands beyond the ball.
    let eye = camera.world_from_camera.translation.vector;
    let mut away = ball.centre_w.coords - eye;
    away.z = 0.0;
    let away = away.try_normalize(1e-9).unwrap_or_else(Vector3::x);
    // Palm under the ball and a little behind it, so the hand never covers the ball's front.
    let hand_w = ball.centre_w + away * (0.35 * r) - Vector3::z() * (r + 0.6 * hand_radius_m);
    let elbow_w = hand_w + away * 0.26 - Vector3::z() * 0.12;
    HandArm {
        elbow_w,
        hand_w,
        forearm_radius_m: 0.035,
        hand_radius_m,
        skin: [225, 175, 145],
    }
}

/// The oldest joint state a frame still takes its stamp from: older ones (a stalled or dead
/// publisher, another clock) leave the frame on the bus clock. Long enough that a busy machine's
/// hiccups do not break the frame/pose pairing, short enough that frames keep moving in time.
pub const MAX_JOINT_STATE_AGE_NS: i64 = 1_000_000_000;

/// Whether a joint state stamped `joint_stamp_ns` may stamp a frame rendered at `now_ns`.
pub fn joint_state_fresh(now_ns: i64, joint_stamp_ns: i64) -> bool {
    joint_stamp_ns <= now_ns && now_ns - joint_stamp_ns <= MAX_JOINT_STATE_AGE_NS
}

/// The stamp of the next frame, ns. The camera pose of a frame rendered from joint states is the
/// pose at the stamp of the newest joint state received (`joint_stamp_ns`), so the frame takes
/// that stamp: then the DR's transform at the frame's stamp, interpolated from the same joint
/// values, is the pose the frame was rendered from. Two frames rendered from the same joint state
/// get stamps 1 ns apart (the DR's interpolation over 1 ns is the same pose to well below a
/// micrometre). A joint state from the future or more than [`MAX_JOINT_STATE_AGE_NS`] old (a
/// stalled publisher, another clock) leaves the frame on the bus clock `now_ns`: the posture is
/// then held, and the DR holds its newest value too. Always after the previous frame's `last_ns`.
pub fn frame_stamp_ns(now_ns: i64, joint_stamp_ns: Option<i64>, last_ns: i64) -> i64 {
    let next = last_ns.saturating_add(1);
    match joint_stamp_ns {
        Some(t) if joint_state_fresh(now_ns, t) => t.max(next),
        _ => now_ns.max(next),
    }
}

/// The sim driver in the game's world: [`Scene::game`], the camera where it is told to be, and
/// the simulated world's ball ([`SimBall`], from `sim/ball`) with the person's hand when held.
/// No ball is drawn before the first [`WorldSim::set_ball`] nor while it is not present.
#[derive(Debug)]
pub struct WorldSim {
    driver: SimDriver,
    ball: Option<(SimBall, f64)>,
    truth: Option<BallGroundTruth>,
}

impl WorldSim {
    /// A 640x480 Kinect-like camera at `world_from_optical` over the game scene.
    pub fn new(world_from_optical: Isometry3<f64>, sensor: SensorModel, seed: u64) -> WorldSim {
        WorldSim {
            driver: SimDriver {
                renderer: SimRenderer::new(SimCamera::vga(world_from_optical), sensor, seed),
                scene: Scene::game(),
            },
            ball: None,
            truth: None,
        }
    }

    /// Moves the camera (the next frame is rendered from there).
    pub fn set_world_from_optical(&mut self, pose: Isometry3<f64>) {
        self.driver.renderer.camera.world_from_camera = pose;
    }

    /// The simulated world's ball now (its header stamp is when it was there).
    pub fn set_ball(&mut self, ball: SimBall) {
        let stamp_s = ball.header.stamp_ns as f64 * 1e-9;
        self.ball = Some((ball, stamp_s));
    }

    /// The camera (pose, intrinsics, size).
    pub fn camera(&self) -> &SimCamera {
        &self.driver.renderer.camera
    }

    /// Ground truth of the last frame rendered; `None` when it showed no ball.
    pub fn truth(&self) -> Option<BallGroundTruth> {
        self.truth
    }
}

impl RgbdDriver for WorldSim {
    fn next_frame(&mut self, now_s: f64) -> Result<Option<Frame>, DriverError> {
        let sphere = self
            .ball
            .as_ref()
            .and_then(|(b, t)| ball_sphere(b, now_s - t).map(|s| (s, b.held)));
        let camera = *self.camera();
        self.driver.scene.hand = sphere
            .as_ref()
            .filter(|(_, held)| *held)
            .map(|(s, _)| holding_hand(s, &camera));
        self.driver.scene.ball = sphere.map(|(s, _)| s);
        self.truth = self
            .driver
            .scene
            .ball
            .map(|s| ball_truth(&camera, &s.centre_w, s.diameter_m));
        self.driver.next_frame(now_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use interfaces::msg::body::JointState;

    fn loki() -> RobotModel {
        RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap()
    }

    fn states(joints: &[(&str, f64)]) -> JointStates {
        JointStates {
            joints: joints
                .iter()
                .map(|(n, p)| JointState {
                    name: n.to_string(),
                    position: *p,
                    ..Default::default()
                })
                .collect(),
            ..Default::default()
        }
    }

    #[test]
    fn rest_posture_camera_is_1_55_m_high_looking_ahead() {
        let cam =
            HeadCamera::new(&loki(), "head_rgbd_optical_frame", Isometry3::identity()).unwrap();
        assert_eq!(
            cam.joint_names(),
            [
                "base_yaw",
                "base_forward",
                "neck_rotation",
                "neck_pitch",
                "neck_roll",
                "neck_yaw"
            ]
        );
        assert!(cam.joint_values().iter().all(|&q| q == 0.0));
        let p = cam.world_from_optical();
        assert!((p.translation.vector - Vector3::new(0.0, 0.0, 1.55)).norm() < 1e-9);
        // Optical z forward (world +x), x right (world -y), y down (world -z).
        assert!((p.rotation * Vector3::z() - Vector3::x()).norm() < 1e-9);
        assert!((p.rotation * Vector3::x() + Vector3::y()).norm() < 1e-9);
        assert!((p.rotation * Vector3::y() + Vector3::z()).norm() < 1e-9);
    }

    #[test]
    fn joint_states_move_the_camera_and_bad_values_are_reported() {
        let mut cam =
            HeadCamera::new(&loki(), "head_rgbd_optical_frame", Isometry3::identity()).unwrap();
        let r = cam.apply(&states(&[
            ("neck_pitch", 0.5),
            ("neck_yaw", 9.0),
            ("neck_roll", f64::NAN),
            ("left_elbow", -1.0),
        ]));
        assert_eq!(r.set, 2);
        assert_eq!(r.clamped, ["neck_yaw"]);
        assert_eq!(r.non_finite, ["neck_roll"]);
        assert_eq!(r.missing, ["base_yaw", "base_forward", "neck_rotation"]);
        // Pitch 0.5 rad down, yaw clamped to its 0.8 rad limit (left).
        let z = cam.world_from_optical().rotation * Vector3::z();
        assert!(z.z < -0.3 && z.y > 0.3, "{z}");
        // The base pose moves the camera with it.
        let before = cam.world_from_optical();
        cam.set_world_from_base(
            RobotPose {
                x_m: 1.0,
                y_m: 2.0,
                yaw_rad: 0.0,
            }
            .world_from_base(),
        );
        let moved = cam.world_from_optical().translation.vector - before.translation.vector;
        assert!((moved - Vector3::new(1.0, 2.0, 0.0)).norm() < 1e-9);
    }

    #[test]
    fn an_unknown_camera_frame_is_an_error() {
        let e = HeadCamera::new(&loki(), "no_such_frame", Isometry3::identity()).unwrap_err();
        assert!(e.to_string().contains("no_such_frame"), "{e}");
    }

    #[test]
    fn robot_pose_flag_parses_degrees_and_rejects_garbage() {
        let p = RobotPose::parse("1,-2,90").unwrap();
        assert_eq!((p.x_m, p.y_m), (1.0, -2.0));
        assert!((p.yaw_rad - std::f64::consts::FRAC_PI_2).abs() < 1e-12);
        assert!(RobotPose::parse("1,2").is_err());
        assert!(RobotPose::parse("1,2,nan").is_err());
    }

    #[test]
    fn hsv_round_trips_through_the_trackers_conversion() {
        // The game's yellow ball: hue 52 deg, saturation 0.85.
        assert_eq!(hsv_to_rgb(52.0, 0.85, 0.9), [230, 203, 34]);
        assert_eq!(hsv_to_rgb(0.0, 1.0, 1.0), [255, 0, 0]);
        assert_eq!(hsv_to_rgb(240.0, 1.0, 1.0), [0, 0, 255]);
        assert_eq!(hsv_to_rgb(-120.0, 1.0, 1.0), [0, 0, 255]);
        assert_eq!(hsv_to_rgb(10.0, f64::NAN, 0.5), [128, 128, 128]);
    }

    #[test]
    fn sim_balls_become_spheres_only_when_present_and_sane() {
        let ball = SimBall {
            present: true,
            centre_world_m: [0.6, 0.0, 0.785],
            velocity_world_mps: [1.0, 0.0, 0.0],
            diameter_m: 0.07,
            hue_deg: 52.0,
            saturation: 0.85,
            ..Default::default()
        };
        let s = ball_sphere(&ball, 0.05).unwrap();
        assert!((s.centre_w - Point3::new(0.65, 0.0, 0.785)).norm() < 1e-12);
        assert_eq!(s.colour, [230, 203, 34]);
        // Never extrapolated backwards nor far.
        let s = ball_sphere(&ball, 5.0).unwrap();
        assert!((s.centre_w.x - 0.7).abs() < 1e-12);
        let s = ball_sphere(&ball, -1.0).unwrap();
        assert!((s.centre_w.x - 0.6).abs() < 1e-12);
        assert!(
            ball_sphere(
                &SimBall {
                    present: false,
                    ..ball.clone()
                },
                0.0
            )
            .is_none()
        );
        assert!(
            ball_sphere(
                &SimBall {
                    diameter_m: 0.0,
                    ..ball.clone()
                },
                0.0
            )
            .is_none()
        );
        assert!(
            ball_sphere(
                &SimBall {
                    centre_world_m: [f64::NAN, 0.0, 0.0],
                    ..ball
                },
                0.0
            )
            .is_none()
        );
    }
}

#[cfg(test)]
mod world_tests {
    use super::*;

    #[test]
    fn frame_stamps_follow_fresh_joint_states_and_always_increase() {
        let now = 10_000_000_000;
        // A fresh joint state gives its stamp; used again, 1 ns later.
        let t = now - 5_000_000;
        assert_eq!(frame_stamp_ns(now, Some(t), 0), t);
        assert_eq!(frame_stamp_ns(now + 33_000_000, Some(t), t), t + 1);
        // None, stale, or from the future: the bus clock.
        assert_eq!(frame_stamp_ns(now, None, 0), now);
        assert_eq!(frame_stamp_ns(now, Some(now - 1_500_000_000), 0), now);
        assert_eq!(frame_stamp_ns(now, Some(now + 1), 0), now);
        // Never back in time, even if the clock is.
        assert_eq!(frame_stamp_ns(now, None, now + 7), now + 8);
    }

    fn yellow(centre: [f64; 3], held: bool) -> SimBall {
        SimBall {
            header: interfaces::Header {
                stamp_ns: 1_000_000_000,
                ..Default::default()
            },
            present: true,
            centre_world_m: centre,
            diameter_m: 0.07,
            hue_deg: 52.0,
            saturation: 0.85,
            held,
            ..Default::default()
        }
    }

    fn looking_down() -> Isometry3<f64> {
        let model = RobotModel::from_urdf_file(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../models/loki.urdf"
        ))
        .unwrap();
        let mut head =
            HeadCamera::new(&model, "head_rgbd_optical_frame", Isometry3::identity()).unwrap();
        head.apply(&JointStates {
            joints: vec![interfaces::msg::body::JointState {
                name: "neck_pitch".into(),
                position: 0.55,
                ..Default::default()
            }],
            ..Default::default()
        });
        head.world_from_optical()
    }

    #[test]
    fn the_world_ball_is_drawn_on_the_game_table_with_its_truth() {
        let mut sim = WorldSim::new(looking_down(), SensorModel::ideal(), 1);
        // No ball before the first message: no truth, and the table is in view.
        let empty = sim.next_frame(1.0).unwrap().unwrap();
        assert!(sim.truth().is_none());
        let centre = [0.7, 0.05, 0.785];
        sim.set_ball(yellow(centre, false));
        let f = sim.next_frame(1.0).unwrap().unwrap();
        let t = sim.truth().unwrap();
        assert!(t.in_view);
        assert_eq!(t.centre_world_m, centre);
        let d = Vector3::from(t.centre_camera_m).norm();
        assert!((0.5..1.2).contains(&d), "{d} m from the camera");
        let [u, v] = f.intrinsics.project(t.centre_camera_m).unwrap();
        let i = v.round() as usize * 640 + u.round() as usize;
        let px = &f.rgb[i * 3..i * 3 + 3];
        // Yellow: red and green high, blue low.
        assert!(px[0] > 150 && px[1] > 130 && px[2] < 60, "{px:?}");
        // The table is under the ball: depth just below it is the table's, not the floor's.
        let below = (v.round() as usize + 40) * 640 + u.round() as usize;
        assert!(
            f.depth_mm[below] > 0 && f.depth_mm[below] < 1400,
            "{}",
            f.depth_mm[below]
        );
        assert_ne!(empty.rgb, f.rgb);
        // Held up in the air: the hand and arm appear under it, the ball's centre pixel is
        // unchanged.
        let up = [0.7, 0.05, 0.95];
        sim.set_ball(yellow(up, false));
        let free = sim.next_frame(1.0).unwrap().unwrap();
        let [u, v] = f
            .intrinsics
            .project(sim.truth().unwrap().centre_camera_m)
            .unwrap();
        let j = v.round() as usize * 640 + u.round() as usize;
        sim.set_ball(yellow(up, true));
        let h = sim.next_frame(1.0).unwrap().unwrap();
        assert_eq!(&h.rgb[j * 3..j * 3 + 3], &free.rgb[j * 3..j * 3 + 3]);
        let skin = h
            .rgb
            .chunks_exact(3)
            .zip(free.rgb.chunks_exact(3))
            .filter(|(a, b)| a != b && a[0] > a[1] && a[1] > a[2] && a[2] > 60)
            .count();
        assert!(skin > 1500, "{skin} pixels of hand and arm");
        // Put away: no ball, no truth.
        sim.set_ball(SimBall {
            present: false,
            ..yellow(centre, false)
        });
        let gone = sim.next_frame(1.0).unwrap().unwrap();
        assert!(sim.truth().is_none());
        assert_eq!(gone.rgb, empty.rgb);
    }
}
