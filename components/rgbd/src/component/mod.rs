//! The `rgbd` component: a driver's frames onto the bus.
//!
//! Publishes:
//! - `vision/rgbd` ([`RgbdFrame`]): every frame, colour RGB8 and depth u16 mm little-endian, in
//!   the camera's optical frame (`--frame-id`, default `head_rgbd_optical_frame` of
//!   `models/loki.urdf`). About 1.5 MB at 640x480, so the publisher puts it in shared memory.
//! - `sim/ball_truth` ([`BallTruth`], sim driver only): the ball's true centre for the frame
//!   just published (same stamp, `frame_seq` = the frame's sequence number), in the optical
//!   frame and the world; none for a frame without a ball (`--ball-from-topic`, ball absent).
//!
//! Subscribes (sim driver, with the flags above): `body/joint_states` ([`JointStates`](interfaces::msg::body::JointStates)) and
//! `sim/ball` ([`SimBall`](interfaces::msg::tracking::SimBall)), the newest of each before every frame. Joint values that are not
//! finite are ignored and counted (`joint_states_non_finite`), values beyond the URDF limits
//! clamped and counted (`joint_states_clamped`); chain joints a state does not name keep their
//! value (logged once); frames rendered while the newest joint state is older than
//! [`camera::world::MAX_JOINT_STATE_AGE_NS`] are counted (`joint_states_stale_frames`) and logged
//! at most once a second.
//!
//! Drivers (`--driver`), both behind the library's [`RgbdDriver`](camera::RgbdDriver) trait:
//! - `sim`: renders a simulated table scene at `--fps` (default 30 Hz) on the bus clock.
//!   - The camera: `--camera-pose` (fixed; default 1.5 m high, 30° down; see [`CameraPose`]), or
//!     with `--camera-from-joints` the pose of the URDF's optical frame `--frame-id` computed
//!     from `body/joint_states` ([`HeadCamera`]; the robot's `base_footprint` at `--robot-pose`,
//!     the world origin by default; the URDF is `--urdf`, else `models/loki.urdf` found as the
//!     deep representation finds it). Before the first joint state the camera is at the URDF's
//!     rest posture (all joints 0, clamped into their limits), which the log says once.
//!   - The ball: scripted by `--scenario` over the lab scene (a table 1.2 m ahead), or with
//!     `--ball-from-topic` the simulated world's ball on `sim/ball` ([`SimBall`](interfaces::msg::tracking::SimBall)) over the
//!     game's scene ([`camera::sim::Scene::game`]: a table 0.4 to 1.1 m ahead at 0.75 m, a
//!     textured wall), drawn with the person's hand and forearm when `held`; no ball before the
//!     first message nor while `present = false`.
//!   - Stamps: the bus clock when the frame is rendered; with `--camera-from-joints`, the stamp
//!     of the joint state the pose came from while joint states keep coming (so the DR's
//!     transform at the frame's stamp is the pose it was rendered from; see [`frame_stamp_ns`](camera::world::frame_stamp_ns)).
//! - `playback`: a TUM RGB-D folder (`--sequence DIR`), paced by the recorded timestamps divided
//!   by `--rate` (2 = twice as fast; 0 = as fast as the subscribers take them), once or with
//!   `--loop` forever. Frames keep their recorded stamps (so a track can be compared with a
//!   recording's ground truth) unless `--restamp` stamps them with the bus clock. A malformed
//!   folder stops the component before it joins the bus, with the error naming file and line.
//!   `--wait-for-subscriber-s` holds the first frame until something subscribes to `vision/rgbd`.

mod kinect_loop;
mod playback;
mod sim;

pub use sim::SimWorld;

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use interfaces::clock::{Clock, Moment};
use interfaces::msg::tracking::BallTruth;
use interfaces::msg::vision::{CameraStatus, RgbdFrame};
use interfaces::node::Interface;
use interfaces::{Bus, Shutdown, topics};
use robot_model::RobotModel;
use robot_model::find_model;

use crate::kinect::{DepthMode, KinectConfig, KinectSim, KinectSource, LibraryChoice};
use camera::playback::{OpenOptions, PlaybackDriver, PlaybackMode, TumSequence};
use camera::scenario::{CameraPose, Scenario, ScenarioSim};
use camera::sim::SensorModel;
use camera::world::{HeadCamera, RobotPose, WorldSim};

/// Which driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DriverKind {
    /// The simulated table scene.
    Sim,
    /// A recorded TUM RGB-D sequence.
    Playback,
    /// A Kinect v1 (or another camera libfreenect drives) through libfreenect; with
    /// `--freenect-library fakenect`, Debian's fakenect replaying the dump `FAKENECT_PATH` names.
    Freenect,
}

/// The component's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// Where frames come from.
    #[arg(long, value_enum, default_value_t = DriverKind::Sim)]
    pub driver: DriverKind,
    /// Name of the camera's optical frame, in every header.
    #[arg(long, default_value = "head_rgbd_optical_frame")]
    pub frame_id: String,
    /// sim: how the ball moves.
    #[arg(long, value_enum, default_value_t = Scenario::Still)]
    pub scenario: Scenario,
    /// sim: the camera body's pose in the world, `x,y,z,roll,pitch,yaw` (m, degrees; REP 103,
    /// positive pitch looks down).
    #[arg(long, value_parser = CameraPose::parse, default_value = "0,0,1.5,0,30,0")]
    pub camera_pose: CameraPose,
    /// sim: compute the camera pose from `body/joint_states` through the URDF (the optical
    /// frame `--frame-id`), instead of `--camera-pose`.
    #[arg(long)]
    pub camera_from_joints: bool,
    /// sim with --camera-from-joints: the robot's `base_footprint` in the world, `x,y,yaw` (m,
    /// degrees).
    #[arg(long, value_parser = RobotPose::parse, default_value = "0,0,0")]
    pub robot_pose: RobotPose,
    /// sim with --camera-from-joints: the robot's URDF (default: models/loki.urdf found above
    /// the binary or the working folder, as the deep representation finds it).
    #[arg(long, env = "ROBOCOG_URDF")]
    pub urdf: Option<PathBuf>,
    /// sim: draw the simulated world's ball from `sim/ball` over the game's scene, instead of
    /// `--scenario`.
    #[arg(long)]
    pub ball_from_topic: bool,
    /// sim: frames per second.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// sim: seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// sim: a perfect sensor (no depth noise, quantisation, edge holes or colour noise).
    #[arg(long)]
    pub ideal_sensor: bool,
    /// sim: the process's CPU niceness (0 to 19; 0 leaves it as started). A camera makes its
    /// images in its own hardware; the simulated one renders them on the robot's CPU, where at
    /// the default priority it would take the CPU from the robot's own processes.
    #[arg(long, default_value_t = SIM_NICENESS, value_parser = clap::value_parser!(i32).range(0..=19))]
    pub sim_niceness: i32,
    /// playback: the TUM RGB-D folder (rgb.txt, depth.txt, rgb/, depth/, intrinsics.txt).
    #[arg(long, required_if_eq("driver", "playback"))]
    pub sequence: Option<PathBuf>,
    /// playback: speed factor over the recorded timing (0: no pacing).
    #[arg(long, default_value_t = 1.0)]
    pub rate: f64,
    /// playback: start again at the end, forever (stamps keep increasing).
    #[arg(long = "loop")]
    pub looping: bool,
    /// playback: stamp frames with the bus clock instead of the recorded time.
    #[arg(long)]
    pub restamp: bool,
    /// playback: wait up to this long (s) for a subscriber of `vision/rgbd` before the first
    /// frame (0: start at once).
    #[arg(long, default_value_t = 0.0)]
    pub wait_for_subscriber_s: f64,
    /// sim: act as a simulated Kinect: send the frames, as the sensor would, into a live
    /// fakenect dump in this folder (created; its INDEX.txt is a FIFO) instead of onto the bus;
    /// an `rgbd --driver freenect --freenect-library fakenect` with `FAKENECT_PATH` set to the
    /// folder reads them through libfreenect's fakenect.
    #[arg(long, value_name = "DIR")]
    pub fakenect_out: Option<PathBuf>,
    /// freenect: the libfreenect to load: `system` (libfreenect.so.0.5, Debian's
    /// libfreenect0.5), `fakenect` (Debian's stand-in replaying `FAKENECT_PATH`), or a path.
    #[arg(long, value_parser = LibraryChoice::parse, default_value = "system")]
    pub freenect_library: LibraryChoice,
    /// freenect: which camera (0: the first libfreenect lists).
    #[arg(long, default_value_t = 0)]
    pub device_index: u32,
    /// freenect: depth registered by libfreenect (`registered`), by robocog from 11-bit
    /// disparities (`raw`), or the first where the library can (`auto`; fakenect cannot).
    #[arg(long, value_enum, default_value_t = DepthMode::Auto)]
    pub depth_mode: DepthMode,
    /// freenect: the colour camera's calibration, a ROS camera_info YAML file (default: the
    /// nominal fx = fy = 525 px, principal point at the centre).
    #[arg(long, value_name = "FILE")]
    pub rgb_camera_info: Option<PathBuf>,
    /// freenect, raw depth: the depth camera's calibration, a ROS camera_info YAML file
    /// (default: the nominal fx = fy = 580 px).
    #[arg(long, value_name = "FILE")]
    pub depth_camera_info: Option<PathBuf>,
    /// freenect, raw depth: the depth camera's origin in the colour camera's optical frame,
    /// `x,y,z` in metres (default: 2.5 cm to its left).
    #[arg(long, value_parser = parse_xyz, default_value = "-0.025,0,0")]
    pub depth_origin_m: [f64; 3],
    /// freenect: the camera counts as lost when no frame came for this long (s).
    #[arg(long, default_value_t = 1.0)]
    pub frame_timeout_s: f64,
}

/// The simulated camera's default niceness ([`Config::sim_niceness`]).
pub const SIM_NICENESS: i32 = 10;

/// Lower this process's CPU priority to `niceness` (before the runtime starts its threads, which
/// inherit it). The simulated camera renders about 40 % of a core at 30 frames a second, which a
/// camera's own hardware would do; at the robot's priority it starved the speech recognizer on
/// a busy machine (two games on two cores: commands decoded 0.4 to 2.4 s after they ended, and
/// the barge-in test failed 8 runs of 8; with the camera at niceness 10, 1 of 14). At niceness
/// 10 the camera still gets its frames out whenever the robot's processes leave the CPU (about a
/// tenth of it when they want all of it). Lowering one's priority needs no privilege; a failure
/// is logged and changes nothing.
fn yield_the_cpu(niceness: i32) {
    if niceness == 0 {
        return;
    }
    match rustix::process::setpriority_process(None, niceness) {
        Ok(()) => tracing::info!(
            "the simulated camera runs at niceness {niceness}: it yields the CPU to the robot's \
             own processes (--sim-niceness 0 keeps the priority it was started with)"
        ),
        Err(e) => tracing::warn!(
            "cannot lower the simulated camera's priority to niceness {niceness}: {e}; it \
             competes with the robot's processes for the CPU"
        ),
    }
}

fn parse_xyz(s: &str) -> Result<[f64; 3], String> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| format!("{s:?}: {e} (want x,y,z in metres)"))?;
    match v[..] {
        [x, y, z] if v.iter().all(|c| c.is_finite()) => Ok([x, y, z]),
        _ => Err(format!("{s:?}: want three finite numbers x,y,z in metres")),
    }
}

/// What the component declares for `--describe`.
pub fn interface(config: &Config) -> Interface {
    let i = Interface::new("rgbd");
    let i = if config.fakenect_out.is_some() {
        i
    } else {
        i.publishes(&topics::VISION_RGBD)
            .publishes(&topics::VISION_CAMERA_STATUS)
    };
    match config.driver {
        DriverKind::Sim => {
            let mut i = i.publishes(&topics::SIM_BALL_TRUTH);
            if config.camera_from_joints {
                i = i.subscribes(&topics::BODY_JOINT_STATES);
            }
            if config.ball_from_topic {
                i = i.subscribes(&topics::SIM_BALL);
            }
            i
        }
        DriverKind::Playback | DriverKind::Freenect => i,
    }
}

/// A driver ready to run.
#[derive(Debug)]
pub enum Source {
    /// The simulated scene, paced at a fixed period.
    Sim {
        /// The scene and ball.
        world: SimWorld,
        /// The camera pose from joint states, with `--camera-from-joints`.
        head: Option<HeadCamera>,
        /// Frame period, s.
        period_s: f64,
    },
    /// A recording, paced by its timestamps.
    Playback {
        /// The reader.
        driver: PlaybackDriver,
        /// Speed factor (0: no pacing).
        rate: f64,
        /// Stamp with the bus clock.
        restamp: bool,
    },
    /// A camera through libfreenect.
    Kinect(Box<KinectSource>),
}

impl Source {
    /// Checks the flags and opens the driver: a playback folder is read and checked here, so a
    /// malformed one is an error naming the file (and line) before the component joins the bus.
    pub fn open(config: &Config) -> anyhow::Result<Source> {
        match config.driver {
            DriverKind::Sim => {
                anyhow::ensure!(
                    config.fps.is_finite() && config.fps > 0.0 && config.fps <= 1000.0,
                    "--fps {} is not in (0, 1000]",
                    config.fps
                );
                let sensor = if config.ideal_sensor {
                    SensorModel::ideal()
                } else {
                    SensorModel::default()
                };
                let head = if config.camera_from_joints {
                    let urdf = find_model(config.urdf.as_deref(), "loki.urdf");
                    let model = RobotModel::from_urdf_file(&urdf).with_context(|| {
                        format!("cannot load the robot model {}", urdf.display())
                    })?;
                    let head = HeadCamera::new(
                        &model,
                        &config.frame_id,
                        config.robot_pose.world_from_base(),
                    )
                    .with_context(|| format!("in {}", urdf.display()))?;
                    let p = head.world_from_optical().translation.vector;
                    tracing::info!(
                        "the camera follows body/joint_states through {} (chain {}); no joint \
                         state yet: rendering from the rest posture, camera at ({:.3}, {:.3}, \
                         {:.3}) m in the world",
                        urdf.display(),
                        head.joint_names().join(", "),
                        p.x,
                        p.y,
                        p.z
                    );
                    Some(head)
                } else {
                    None
                };
                let world = if config.ball_from_topic {
                    let pose = head
                        .as_ref()
                        .map(HeadCamera::world_from_optical)
                        .unwrap_or_else(|| config.camera_pose.world_from_optical());
                    tracing::info!(
                        "the game's scene; the ball comes from sim/ball (none drawn until then)"
                    );
                    SimWorld::Topic(Box::new(WorldSim::new(pose, sensor, config.seed)))
                } else {
                    let mut sim =
                        ScenarioSim::new(config.scenario, config.camera_pose, sensor, config.seed);
                    if let Some(h) = &head {
                        sim.set_world_from_optical(h.world_from_optical());
                    }
                    SimWorld::Scenario(Box::new(sim))
                };
                Ok(Source::Sim {
                    world,
                    head,
                    period_s: 1.0 / config.fps,
                })
            }
            DriverKind::Freenect => {
                anyhow::ensure!(
                    !config.camera_from_joints
                        && !config.ball_from_topic
                        && config.fakenect_out.is_none(),
                    "--camera-from-joints, --ball-from-topic and --fakenect-out need --driver sim"
                );
                anyhow::ensure!(
                    config.frame_timeout_s.is_finite() && config.frame_timeout_s > 0.0,
                    "--frame-timeout-s {} must be a positive number of seconds",
                    config.frame_timeout_s
                );
                let source = KinectSource::open(&KinectConfig {
                    library: config.freenect_library.clone(),
                    index: config.device_index,
                    depth_mode: config.depth_mode,
                    rgb_camera_info: config.rgb_camera_info.clone(),
                    depth_camera_info: config.depth_camera_info.clone(),
                    depth_origin_m: config.depth_origin_m,
                })?;
                Ok(Source::Kinect(Box::new(source)))
            }
            DriverKind::Playback => {
                anyhow::ensure!(
                    !config.camera_from_joints
                        && !config.ball_from_topic
                        && config.fakenect_out.is_none(),
                    "--camera-from-joints, --ball-from-topic and --fakenect-out need --driver sim"
                );
                let dir = config
                    .sequence
                    .as_ref()
                    .context("--driver playback needs --sequence DIR")?;
                anyhow::ensure!(
                    config.rate.is_finite() && config.rate >= 0.0,
                    "--rate {} must be a finite speed factor >= 0",
                    config.rate
                );
                let sequence = TumSequence::open(dir, OpenOptions::default())
                    .with_context(|| format!("cannot play back {}", dir.display()))?;
                // Decode the first pair now too: a broken PNG is a start-up error, not a crash later.
                sequence
                    .load(0)
                    .with_context(|| format!("cannot play back {}", dir.display()))?;
                if sequence.unpaired_count() > 0 {
                    tracing::warn!(
                        "{}: {} colour images have no depth image close enough in time; skipped",
                        dir.display(),
                        sequence.unpaired_count()
                    );
                }
                tracing::info!(
                    "playing back {} ({} frames{})",
                    dir.display(),
                    sequence.len(),
                    if config.looping { ", looping" } else { "" }
                );
                let mode = match (config.looping, config.rate == 0.0) {
                    (true, _) => PlaybackMode::Looping,
                    (false, true) => PlaybackMode::AsFastAsAsked,
                    (false, false) => PlaybackMode::Recorded,
                };
                Ok(Source::Playback {
                    driver: PlaybackDriver::new(sequence, mode),
                    rate: config.rate,
                    restamp: config.restamp,
                })
            }
        }
    }
}

/// Where the frames go: the bus (frames, the camera's state, the sim's ground truth), or with
/// `--fakenect-out` the simulated Kinect.
struct Outputs {
    kinect_sim: Option<KinectSim>,
    frames: Option<interfaces::Publisher<RgbdFrame>>,
    truths: Option<interfaces::Publisher<BallTruth>>,
    status: Option<StatusOut>,
}

/// Runs the component until the source is exhausted (playback without `--loop`) or shutdown.
pub async fn run(
    bus: Bus,
    config: Config,
    source: Source,
    mut shutdown: Shutdown,
) -> anyhow::Result<()> {
    let kinect_sim = match (&config.fakenect_out, &source) {
        (Some(dir), Source::Sim { .. }) => Some(KinectSim::create(
            dir,
            freenect::kinect::DepthCalibration::default(),
        )?),
        _ => None,
    };
    let frames = match kinect_sim {
        Some(_) => None,
        None => Some(bus.publisher(&topics::VISION_RGBD).await?),
    };
    let truths = match source {
        Source::Sim { .. } => Some(bus.publisher(&topics::SIM_BALL_TRUTH).await?),
        Source::Playback { .. } | Source::Kinect(_) => None,
    };
    let mut status = match &frames {
        Some(_) => Some(StatusOut::new(
            bus.publisher(&topics::VISION_CAMERA_STATUS).await?,
            bus.clock().clone(),
        )),
        None => None,
    };
    let driver_name = match source {
        Source::Sim { .. } => "sim",
        Source::Playback { .. } => "playback",
        Source::Kinect(_) => "freenect",
    };
    if let Some(s) = status.as_mut() {
        s.status.driver = driver_name.into();
    }
    let out = Outputs {
        kinect_sim,
        frames,
        truths,
        status,
    };
    match source {
        Source::Sim {
            world,
            head,
            period_s,
        } => sim::run_sim(&bus, &config, world, head, period_s, out, &mut shutdown).await,
        Source::Playback {
            driver,
            rate,
            restamp,
        } => playback::run_playback(&bus, &config, driver, rate, restamp, out, &mut shutdown).await,
        Source::Kinect(mut src) => {
            let (Some(frames), Some(mut status)) = (out.frames, out.status) else {
                anyhow::bail!("--fakenect-out needs --driver sim");
            };
            kinect_loop::run_kinect(&bus, &config, &mut src, &frames, &mut status, &mut shutdown)
                .await
        }
    }
}

/// `vision/camera_status`: published on every change, and once a second while nothing changes.
struct StatusOut {
    publisher: interfaces::Publisher<CameraStatus>,
    status: CameraStatus,
    /// When it was last published, on the component's clock.
    last: Option<Moment>,
    clock: Clock,
    /// What streams, said while frames come.
    streaming_detail: String,
}

impl StatusOut {
    fn new(publisher: interfaces::Publisher<CameraStatus>, clock: Clock) -> StatusOut {
        StatusOut {
            publisher,
            clock,
            status: CameraStatus::default(),
            last: None,
            streaming_detail: String::new(),
        }
    }

    /// Sets the state; publishes when it changed or a second has passed.
    async fn change(&mut self, streaming: bool, detail: &str) -> anyhow::Result<()> {
        let changed = self.last.is_none()
            || self.status.streaming != streaming
            || self.status.detail != detail;
        self.status.streaming = streaming;
        if changed {
            self.status.detail = detail.to_string();
        }
        let due = self
            .last
            .is_none_or(|t| self.clock.elapsed(t) >= Duration::from_secs(1));
        if changed || due {
            self.last = Some(self.clock.now());
            self.status.header.stamp_ns = 0;
            self.publisher.publish(&mut self.status).await?;
        }
        Ok(())
    }

    /// A frame was published.
    async fn frame(&mut self, streaming: bool, detail: &str) -> anyhow::Result<()> {
        self.status.frames += 1;
        self.change(streaming, detail).await
    }
}

/// The `rgbd` component.
#[derive(Debug)]
pub struct Rgbd;

impl interfaces::node::Component for Rgbd {
    const NAME: &'static str = "rgbd";
    const ABOUT: &'static str = "The head RGB-D camera: publishes `vision/rgbd` from the `sim`, `playback` or \
        `freenect` driver.";
    type Config = Config;
    type Prepared = (Config, Source);

    fn interface(config: &Config) -> Interface {
        interface(config)
    }

    fn prepare(config: Config) -> anyhow::Result<(Config, Source)> {
        if config.driver == DriverKind::Sim {
            yield_the_cpu(config.sim_niceness);
        }
        // Open the driver before joining the bus: a bad recording is reported at once.
        let source = Source::open(&config)?;
        Ok((config, source))
    }

    async fn run(bus: Bus, prepared: (Config, Source), shutdown: Shutdown) -> anyhow::Result<()> {
        let (config, source) = prepared;
        run(bus, config, source, shutdown).await
    }
}
