//! The `ball_tracker` component: the [`BallTracker`] between the camera and the bus.
//!
//! Subscribes:
//! - `vision/rgbd` ([`RgbdFrame`]): every frame is tracked, at the frame's own stamp as the
//!   tracker's clock (so a replayed recording tracks exactly as it did live). When frames queue
//!   up behind a slow tracker, it jumps to the newest and counts the others (`skipped_frames`),
//!   unless `--every-frame` (then a full queue holds the camera back, as the bus does).
//! - `vision/ball_target` ([`BallTarget`]): what to look for; `active = false` clears it. The
//!   flags `--target-hue --target-saturation --target-diameter` set one at start (a manifest's
//!   way to give it); a message replaces it.
//!
//! Publishes, per processed frame:
//! - `vision/ball` ([`BallTrack`]): state, window, centroid, 3D centre in the camera optical
//!   frame (the frame's `frame_id`), measured diameter, confidence; stamped with the frame's stamp
//!   and carrying its sequence number (`frame_seq`).
//! - `vision/ball_events` ([`BallEvent`]): detected, out of view, lost, detection timed out.
//!
//! A frame that decodes but is inconsistent (sizes, intrinsics) is counted in the bus counter
//! `bad_frames` (published on `diagnostics`), logged at most once a second, and skipped; so is an
//! out-of-range target (`bad_targets`). Nothing panics on input.
//!
//! Not yet: the ball's position in the robot frame and its update in the deep representation
//! (they need the camera pose from joint states and the DR client).

use std::time::{Duration, Instant};

use interfaces::msg::tracking::{
    BallEvent, BallEventKind, BallTarget, BallTrack, BallTrackState, PixelWindow,
};
use interfaces::msg::vision::RgbdFrame;
use interfaces::node::Interface;
use interfaces::ratelimit::RateLimiter;
use interfaces::{Bus, Header, Shutdown, topics};

use crate::{BallTracker, Target, TrackError, TrackEvent, TrackOutput, TrackState, TrackerConfig};

/// The component's flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// Target hue, degrees [0, 360) (with --target-saturation and --target-diameter).
    #[arg(long, requires_all = ["target_saturation", "target_diameter"])]
    pub target_hue: Option<f32>,
    /// Target saturation, [0, 1].
    #[arg(long, requires_all = ["target_hue", "target_diameter"])]
    pub target_saturation: Option<f32>,
    /// Target diameter, m.
    #[arg(long, requires_all = ["target_hue", "target_saturation"])]
    pub target_diameter: Option<f64>,
    /// Detecting this long without a match drops the target (back to waiting), s.
    #[arg(long, default_value_t = TrackerConfig::default().detect_timeout_s)]
    pub detect_timeout_s: f64,
    /// Track every frame, in order, even when behind (offline evaluation); by default a tracker
    /// that falls behind jumps to the newest frame and counts the others (`skipped_frames`).
    #[arg(long)]
    pub every_frame: bool,
}

impl Config {
    /// The target the flags give, if any.
    pub fn target(&self) -> Option<Target> {
        match (
            self.target_hue,
            self.target_saturation,
            self.target_diameter,
        ) {
            (Some(hue_deg), Some(saturation), Some(diameter_m)) => Some(Target {
                hue_deg,
                saturation,
                diameter_m,
            }),
            _ => None,
        }
    }
}

/// What the component declares for `--describe`.
pub fn interface() -> Interface {
    Interface::new("ball_tracker")
        .subscribes(&topics::VISION_RGBD)
        .subscribes(&topics::VISION_BALL_TARGET)
        .publishes(&topics::VISION_BALL)
        .publishes(&topics::VISION_BALL_EVENTS)
}

/// Why a frame was skipped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameRejected {
    /// The message's buffers or intrinsics are inconsistent.
    #[error("malformed frame {seq}: {source}")]
    Malformed {
        /// The frame's sequence number.
        seq: u64,
        /// What is wrong.
        source: rgbd::convert::ConvertError,
    },
    /// The tracker refused it (a non-finite stamp, an invalid frame).
    #[error("frame {seq} refused by the tracker: {source}")]
    Refused {
        /// The frame's sequence number.
        seq: u64,
        /// What is wrong.
        source: TrackError,
    },
}

/// The tracker with its bus-side conversions: one frame message in, one track and its events
/// out. No bus here, so it is tested directly.
#[derive(Debug)]
pub struct Handler {
    tracker: BallTracker,
}

impl Handler {
    /// A tracker with `config`, looking for `target` if given.
    pub fn new(config: TrackerConfig, target: Option<Target>) -> Result<Handler, TrackError> {
        let mut tracker = BallTracker::new(config);
        tracker.set_target(target)?;
        Ok(Handler { tracker })
    }

    /// The tracker.
    pub fn tracker(&self) -> &BallTracker {
        &self.tracker
    }

    /// Applies a target message (`active = false` clears the target).
    pub fn set_target(&mut self, msg: &BallTarget) -> Result<(), TrackError> {
        let target = msg.active.then_some(Target {
            hue_deg: msg.hue_deg,
            saturation: msg.saturation,
            diameter_m: msg.diameter_m,
        });
        self.tracker.set_target(target)
    }

    /// Tracks one frame message.
    pub fn process(
        &mut self,
        frame: &RgbdFrame,
    ) -> Result<(BallTrack, Vec<BallEvent>), FrameRejected> {
        let seq = frame.header.seq;
        let image = rgbd::convert::from_msg(frame)
            .map_err(|source| FrameRejected::Malformed { seq, source })?;
        let out = self
            .tracker
            .process(&image, image.timestamp_s)
            .map_err(|source| FrameRejected::Refused { seq, source })?;
        Ok(to_msgs(&out, &frame.header))
    }
}

fn state_msg(s: TrackState) -> BallTrackState {
    match s {
        TrackState::Waiting => BallTrackState::Waiting,
        TrackState::Detecting => BallTrackState::Detecting,
        TrackState::Tracking => BallTrackState::Tracking,
    }
}

fn event_msg(e: TrackEvent) -> BallEventKind {
    match e {
        TrackEvent::BallDetected => BallEventKind::Detected,
        TrackEvent::BallOutOfView => BallEventKind::OutOfView,
        TrackEvent::BallLost => BallEventKind::Lost,
        TrackEvent::DetectionTimedOut => BallEventKind::DetectionTimedOut,
    }
}

/// The messages of one tracker output for the frame with header `frame`: stamped with the
/// frame's stamp, in the frame's `frame_id`, carrying its sequence number.
pub fn to_msgs(out: &TrackOutput, frame: &Header) -> (BallTrack, Vec<BallEvent>) {
    let header = Header {
        stamp_ns: frame.stamp_ns,
        seq: 0,
        frame_id: frame.frame_id.clone(),
    };
    let state = state_msg(out.state);
    let track = BallTrack {
        has_centre_world: false,
        centre_world_m: [0.0; 3],
        centre_robot_m: [0.0; 3],
        header: header.clone(),
        frame_seq: frame.seq,
        state,
        found: out.window.is_some(),
        window: out
            .window
            .map(|w| PixelWindow {
                x: w.x,
                y: w.y,
                width: w.width,
                height: w.height,
            })
            .unwrap_or_default(),
        centre_px: out.centre_px.unwrap_or_default(),
        has_centre_m: out.centre_m.is_some(),
        centre_m: out.centre_m.unwrap_or_default(),
        diameter_m: out.measured_diameter_m.unwrap_or(0.0),
        confidence: out.confidence,
    };
    let events = out
        .events
        .iter()
        .map(|&e| BallEvent {
            header: header.clone(),
            frame_seq: frame.seq,
            kind: event_msg(e),
            state,
        })
        .collect();
    (track, events)
}

/// Queue depth for frames: a few, the tracker keeps up with 30 Hz by a wide margin.
const FRAME_QUEUE: usize = 4;

/// Runs the component until shutdown.
pub async fn run(bus: Bus, config: Config, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let tracker_config = TrackerConfig {
        detect_timeout_s: config.detect_timeout_s,
        ..TrackerConfig::default()
    };
    let mut handler = Handler::new(tracker_config, config.target())
        .map_err(|e| anyhow::anyhow!("the target flags: {e}"))?;
    if let Some(t) = handler.tracker().target() {
        tracing::info!(
            "looking for a ball of hue {:.1} deg, saturation {:.2}, diameter {:.3} m",
            t.hue_deg,
            t.saturation,
            t.diameter_m
        );
    }
    let frames = bus
        .subscriber_named::<RgbdFrame>(topics::VISION_RGBD.name(), FRAME_QUEUE)
        .await?;
    let targets = bus.subscriber(&topics::VISION_BALL_TARGET).await?;
    let tracks = bus.publisher(&topics::VISION_BALL).await?;
    let events = bus.publisher(&topics::VISION_BALL_EVENTS).await?;
    let counters = bus.counters().clone();
    let mut warn_limit = RateLimiter::new(Duration::from_secs(1));
    loop {
        tokio::select! {
            biased;
            _ = shutdown.wait() => return Ok(()),
            target = targets.recv() => {
                let target = target?;
                match handler.set_target(&target) {
                    Ok(()) if target.active => tracing::info!(
                        "new target: hue {:.1} deg, saturation {:.2}, diameter {:.3} m",
                        target.hue_deg, target.saturation, target.diameter_m
                    ),
                    Ok(()) => tracing::info!("target cleared: waiting"),
                    Err(e) => {
                        counters.incr("bad_targets");
                        tracing::warn!("ignored a target: {e}");
                    }
                }
            }
            frame = frames.recv() => {
                let mut frame = frame?;
                // Behind? Track the newest frame, count the others.
                while !config.every_frame && let Some(newer) = frames.try_recv() {
                    counters.incr("skipped_frames");
                    frame = newer;
                }
                match handler.process(&frame) {
                    Ok((mut track, evs)) => {
                        tracks.publish(&mut track).await?;
                        for mut e in evs {
                            tracing::info!(frame_seq = e.frame_seq, "ball {:?}", e.kind);
                            events.publish(&mut e).await?;
                        }
                    }
                    Err(e) => {
                        counters.incr("bad_frames");
                        if let Some(suppressed) = warn_limit.allow(Instant::now()) {
                            tracing::warn!(suppressed, "skipped a frame: {e}");
                        }
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::hsv::rgb_to_hsv;
    use rgbd::scenario::{BALL_DIAMETER_M, BALL_RED, CameraPose, Scenario, ScenarioSim};
    use rgbd::sim::SensorModel;
    use rgbd::{RgbdDriver, convert};

    fn red_target() -> Target {
        let (h, s, _) = rgb_to_hsv(BALL_RED[0], BALL_RED[1], BALL_RED[2]);
        Target {
            hue_deg: h,
            saturation: s,
            diameter_m: BALL_DIAMETER_M,
        }
    }

    fn sim_frames(scenario: Scenario, n: usize) -> Vec<(RgbdFrame, [f64; 3])> {
        let mut sim = ScenarioSim::new(
            scenario,
            CameraPose::HEAD_DEFAULT,
            SensorModel::default(),
            7,
        );
        (0..n)
            .map(|i| {
                let t = 1_700_000_000.0 + i as f64 / 30.0;
                let f = sim.next_frame(t).unwrap().unwrap();
                let mut m = convert::into_msg(f, "head_rgbd_optical_frame");
                m.header.seq = i as u64;
                (m, sim.truth().unwrap().centre_camera_m)
            })
            .collect()
    }

    #[test]
    fn the_red_ball_target_matches_the_flags_in_the_manifest() {
        // launch/eyes_sim.toml gives --target-hue 3.2 --target-saturation 0.86.
        let t = red_target();
        assert!(
            (t.hue_deg - 3.2).abs() < 0.1 && (t.saturation - 0.86).abs() < 0.01,
            "{t:?}"
        );
    }

    #[test]
    fn tracks_the_still_sim_ball_within_1cm_from_the_head_camera() {
        let mut h = Handler::new(TrackerConfig::default(), Some(red_target())).unwrap();
        for (i, (frame, truth)) in sim_frames(Scenario::Still, 10).iter().enumerate() {
            let (track, events) = h.process(frame).unwrap();
            assert_eq!(track.state, BallTrackState::Tracking, "frame {i}");
            assert_eq!(track.frame_seq, i as u64);
            assert_eq!(track.header.stamp_ns, frame.header.stamp_ns);
            assert_eq!(track.header.frame_id, "head_rgbd_optical_frame");
            assert!(track.found && track.has_centre_m && track.confidence > 0.5);
            let err: f64 = (0..3)
                .map(|k| (track.centre_m[k] - truth[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            assert!(err < 0.01, "frame {i}: error {err} m");
            if i == 0 {
                assert_eq!(events.len(), 1);
                assert_eq!(events[0].kind, BallEventKind::Detected);
            } else {
                assert!(events.is_empty());
            }
        }
    }

    #[test]
    fn malformed_frames_are_rejected_and_tracking_carries_on() {
        let mut h = Handler::new(TrackerConfig::default(), Some(red_target())).unwrap();
        let frames = sim_frames(Scenario::Moving, 4);
        h.process(&frames[0].0).unwrap();
        let mut bad = frames[1].0.clone();
        bad.depth_mm.truncate(1001);
        assert!(matches!(
            h.process(&bad),
            Err(FrameRejected::Malformed { seq: 1, .. })
        ));
        let mut bad = frames[1].0.clone();
        bad.rgb = vec![7; 5];
        assert!(h.process(&bad).is_err());
        let mut bad = frames[1].0.clone();
        bad.width = 3;
        assert!(h.process(&bad).is_err());
        assert!(h.process(&RgbdFrame::default()).is_err());
        let (track, _) = h.process(&frames[2].0).unwrap();
        assert!(track.found && track.state == BallTrackState::Tracking);
    }

    #[test]
    fn target_messages_set_and_clear_the_target() {
        let mut h = Handler::new(TrackerConfig::default(), None).unwrap();
        let frames = sim_frames(Scenario::Still, 2);
        let (track, _) = h.process(&frames[0].0).unwrap();
        assert_eq!(track.state, BallTrackState::Waiting);
        assert!(!track.found);
        let t = red_target();
        let mut msg = BallTarget {
            active: true,
            hue_deg: t.hue_deg,
            saturation: t.saturation,
            diameter_m: t.diameter_m,
            ..Default::default()
        };
        h.set_target(&msg).unwrap();
        let (track, events) = h.process(&frames[1].0).unwrap();
        assert!(track.found);
        assert_eq!(events[0].kind, BallEventKind::Detected);
        msg.diameter_m = -1.0;
        assert!(h.set_target(&msg).is_err());
        assert_eq!(
            h.tracker().state(),
            TrackState::Tracking,
            "a bad target changes nothing"
        );
        h.set_target(&BallTarget::default()).unwrap();
        assert_eq!(h.tracker().state(), TrackState::Waiting);
    }
}
