//! The `rgbd` component: a driver's frames onto the bus.
//!
//! Publishes:
//! - `vision/rgbd` ([`RgbdFrame`]): every frame, colour RGB8 and depth u16 mm little-endian, in
//!   the camera's optical frame (`--frame-id`, default `head_rgbd_optical_frame` of
//!   `models/loki.urdf`). About 1.5 MB at 640x480, so the publisher puts it in shared memory.
//! - `sim/ball_truth` ([`BallTruth`], sim driver only): the ball's true centre for the frame
//!   just published (same stamp, `frame_seq` = the frame's sequence number).
//!
//! Drivers (`--driver`), both behind the library's [`RgbdDriver`] trait:
//! - `sim`: renders the simulated table scene ([`crate::scenario`]) at `--fps` (default 30 Hz) on
//!   the bus clock; frames are stamped with the clock time they were rendered at. The camera
//!   pose is `--camera-pose` (default: 1.5 m high, 30° down; see [`CameraPose`]); the ball
//!   follows `--scenario`.
//! - `playback`: a TUM RGB-D folder (`--sequence DIR`), paced by the recorded timestamps divided
//!   by `--rate` (2 = twice as fast; 0 = as fast as the subscribers take them), once or with
//!   `--loop` forever. Frames keep their recorded stamps (so a track can be compared with a
//!   recording's ground truth) unless `--restamp` stamps them with the bus clock. A malformed
//!   folder stops the component before it joins the bus, with the error naming file and line.
//!   `--wait-for-subscriber-s` holds the first frame until something subscribes to `vision/rgbd`.

use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use interfaces::msg::tracking::BallTruth;
use interfaces::msg::vision::RgbdFrame;
use interfaces::node::Interface;
use interfaces::{Bus, Header, Shutdown, topics};

use crate::RgbdDriver;
use crate::convert::{into_msg, seconds_to_ns};
use crate::playback::{OpenOptions, PlaybackDriver, PlaybackMode, TumSequence};
use crate::scenario::{BallGroundTruth, CameraPose, Scenario, ScenarioSim};
use crate::sim::SensorModel;

/// Which driver.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DriverKind {
    /// The simulated table scene.
    Sim,
    /// A recorded TUM RGB-D sequence.
    Playback,
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
    /// sim: frames per second.
    #[arg(long, default_value_t = 30.0)]
    pub fps: f64,
    /// sim: seed of the sensor noise.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// sim: a perfect sensor (no depth noise, quantisation, edge holes or colour noise).
    #[arg(long)]
    pub ideal_sensor: bool,
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
}

/// What the component declares for `--describe`.
pub fn interface(config: &Config) -> Interface {
    let i = Interface::new("rgbd").publishes(&topics::VISION_RGBD);
    match config.driver {
        DriverKind::Sim => i.publishes(&topics::SIM_BALL_TRUTH),
        DriverKind::Playback => i,
    }
}

/// A driver ready to run.
#[derive(Debug)]
pub enum Source {
    /// The simulated scene, paced at a fixed period.
    Sim {
        /// The scenario driver.
        sim: Box<ScenarioSim>,
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
                Ok(Source::Sim {
                    sim: Box::new(ScenarioSim::new(
                        config.scenario,
                        config.camera_pose,
                        sensor,
                        config.seed,
                    )),
                    period_s: 1.0 / config.fps,
                })
            }
            DriverKind::Playback => {
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

fn truth_msg(t: &BallGroundTruth, frame: &RgbdFrame) -> BallTruth {
    BallTruth {
        header: Header {
            stamp_ns: frame.header.stamp_ns,
            seq: 0,
            frame_id: frame.header.frame_id.clone(),
        },
        frame_seq: frame.header.seq,
        centre_m: t.centre_camera_m,
        centre_world_m: t.centre_world_m,
        diameter_m: t.diameter_m,
        in_view: t.in_view,
    }
}

async fn wait_for_subscriber(bus: &Bus, wait_s: f64, shutdown: &mut Shutdown) {
    if wait_s <= 0.0 {
        return;
    }
    let deadline = tokio::time::Instant::now() + Duration::from_secs_f64(wait_s);
    while tokio::time::Instant::now() < deadline && !shutdown.is_requested() {
        let graph = bus
            .graph(Duration::from_millis(300))
            .await
            .unwrap_or_default();
        let found = graph.iter().any(|t| {
            matches!(t, interfaces::liveliness::Token::Subscriber { topic, .. }
                if topic == topics::VISION_RGBD.name())
        });
        if found {
            // The subscription reaches the router just before its token: a moment more.
            tokio::time::sleep(Duration::from_millis(100)).await;
            return;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    tracing::warn!("no subscriber of vision/rgbd after {wait_s} s; playing anyway");
}

/// Runs the component until the source is exhausted (playback without `--loop`) or shutdown.
pub async fn run(
    bus: Bus,
    config: Config,
    source: Source,
    mut shutdown: Shutdown,
) -> anyhow::Result<()> {
    let frames = bus.publisher(&topics::VISION_RGBD).await?;
    let truths = match source {
        Source::Sim { .. } => Some(bus.publisher(&topics::SIM_BALL_TRUTH).await?),
        Source::Playback { .. } => None,
    };
    let clock = bus.clock().clone();
    let now_s = move || clock.now_ns() as f64 * 1e-9;
    match source {
        Source::Sim { mut sim, period_s } => {
            let mut tick = tokio::time::interval(Duration::from_secs_f64(period_s));
            tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
            loop {
                tokio::select! {
                    biased;
                    _ = shutdown.wait() => return Ok(()),
                    _ = tick.tick() => {}
                }
                let Some(frame) = sim.next_frame(now_s())? else {
                    return Ok(());
                };
                let mut msg = into_msg(frame, &config.frame_id);
                frames.publish(&mut msg).await?;
                if let (Some(p), Some(t)) = (&truths, sim.truth()) {
                    p.publish(&mut truth_msg(&t, &msg)).await?;
                }
            }
        }
        Source::Playback {
            mut driver,
            rate,
            restamp,
        } => {
            wait_for_subscriber(&bus, config.wait_for_subscriber_s, &mut shutdown).await;
            let mut prev: Option<(f64, tokio::time::Instant)> = None;
            let mut published = 0u64;
            loop {
                if shutdown.is_requested() {
                    return Ok(());
                }
                let Some(frame) = driver.next_frame(now_s())? else {
                    tracing::info!("end of the sequence after {published} frames");
                    return Ok(());
                };
                // Pace: the recorded gap since the previous frame, scaled by the rate, measured
                // from when the previous frame was due (so publishing time does not accumulate).
                if let Some((prev_s, prev_due)) = prev
                    && rate > 0.0
                {
                    let gap_s = driver.mode().delay_s(prev_s, frame.timestamp_s) / rate;
                    let due = prev_due + Duration::from_secs_f64(gap_s.min(3600.0));
                    tokio::select! {
                        biased;
                        _ = shutdown.wait() => return Ok(()),
                        _ = tokio::time::sleep_until(due) => {}
                    }
                    prev = Some((frame.timestamp_s, due));
                } else {
                    prev = Some((frame.timestamp_s, tokio::time::Instant::now()));
                }
                let mut msg = into_msg(frame, &config.frame_id);
                if restamp {
                    msg.header.stamp_ns = seconds_to_ns(now_s());
                }
                frames.publish(&mut msg).await?;
                published += 1;
            }
        }
    }
}
