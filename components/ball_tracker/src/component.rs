//! The `ball_tracker` component: the [`BallTracker`] between the camera and the bus.
//!
//! Subscribes:
//! - `vision/rgbd` ([`RgbdFrame`]): every frame is tracked, at the frame's own stamp as the
//!   tracker's clock (so a replayed recording tracks exactly as it did live). When frames queue
//!   up behind a slow tracker, it jumps to the newest and counts the others (`skipped_frames`),
//!   unless `--every-frame` (then a full queue holds the camera back, as the bus does). Frames
//!   are read in place (`Subscriber::recv_borrowed`): the pixels are copied once, from the
//!   camera's shared-memory buffer into the tracker's own frame ([`camera::convert::from_view`]),
//!   and a skipped frame is never copied at all.
//! - `vision/ball_target` ([`BallTarget`]): what to look for; `active = false` clears it. The
//!   flags `--target-hue --target-saturation --target-diameter` set one at start (a manifest's
//!   way to give it); a message replaces it from the first frame stamped at or after the
//!   message's own stamp (a frame captured before the target was given is tracked with the
//!   target it was captured under, however late it is processed: so a replay, where frames and
//!   targets arrive in another order than live, tracks each frame as it was tracked live). A
//!   target stamped more than [`TARGET_LEAD`] ahead of the frames (clocks that disagree) or
//!   unstamped applies at once; the former is counted (`targets_ahead_of_frames`).
//!
//! Publishes, per processed frame, in frame order:
//! - `vision/ball` ([`BallTrack`]): state, window, centroid, 3D centre in the camera optical
//!   frame (the frame's `frame_id`), measured diameter, confidence, and (through the DR) the
//!   centre in `world` and in the robot's base frame; stamped with the frame's stamp and carrying
//!   its sequence number (`frame_seq`).
//! - `vision/ball_events` ([`BallEvent`]): detected, out of view, lost, detection timed out.
//!
//! Calls (unless `--no-dr`): `dr/transform` (world and robot from the camera frame at each
//! frame's stamp) and `dr/update` (the ball node `--ball-node`, parent `world`, at the frame's
//! stamp, when the track's confidence reaches `--dr-update-confidence`); see [`crate::dr`].
//! The DR is asked in a second stage, a task fed by a bounded queue: tracking the next frame
//! never waits for the DR. A stage that falls behind (more than [`DR_BEHIND`] tracks queued)
//! publishes the queued tracks in the camera frame only (`dr_skipped_behind`); with no DR
//! (missing, or silent past `--dr-timeout-ms`), tracks are published in the camera frame only,
//! counted (`dr_unavailable`) and logged at most once a second, and the DR is asked again after
//! `--dr-retry-s`. `launch/eyes_sim.toml` runs without a DR and passes `--no-dr`.
//!
//! A frame that decodes but is inconsistent (sizes, intrinsics) is counted in the bus counter
//! `bad_frames` (published on `diagnostics`), logged at most once a second, and skipped; so is an
//! out-of-range target (`bad_targets`). Nothing panics on input.

use std::time::{Duration, Instant};

use interfaces::msg::tracking::{
    BallEvent, BallEventKind, BallTarget, BallTrack, BallTrackState, PixelWindow,
};
use interfaces::msg::vision::{RgbdFrame, RgbdFrameView};
use interfaces::node::Interface;
use interfaces::ratelimit::RateLimiter;
use interfaces::{Bus, Header, Shutdown, topics};

use crate::dr::{DrLink, DrOptions};
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
    /// Do not use the deep representation: tracks in the camera frame only, no ball node
    /// updates, and no `dr/*` calls declared (for graphs without a DR).
    #[arg(long)]
    pub no_dr: bool,
    /// The DR node of the ball, updated with its position (its parent must be `world`).
    #[arg(long, default_value = "ball")]
    pub ball_node: String,
    /// The robot's base frame in the DR, for `centre_robot_m`.
    #[arg(long, default_value = "base_footprint")]
    pub robot_frame: String,
    /// Smallest track confidence, [0, 1], that updates the DR's ball node.
    #[arg(long, default_value_t = 0.5)]
    pub dr_update_confidence: f64,
    /// Time-out of each DR call, ms.
    #[arg(long, default_value_t = 100)]
    pub dr_timeout_ms: u64,
    /// After the DR was missing or silent, ask again after this long, s.
    #[arg(long, default_value_t = 1.0)]
    pub dr_retry_s: f64,
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
pub fn interface(config: &Config) -> Interface {
    let i = Interface::new("ball_tracker")
        .subscribes(&topics::VISION_RGBD)
        .subscribes(&topics::VISION_BALL_TARGET)
        .publishes(&topics::VISION_BALL)
        .publishes(&topics::VISION_BALL_EVENTS);
    if config.no_dr {
        i
    } else {
        i.calls(&topics::DR_TRANSFORM).calls(&topics::DR_UPDATE)
    }
}

/// Tracks queued for the DR stage beyond which it stops asking the DR until it has caught up.
pub const DR_BEHIND: usize = 3;
/// Capacity of the queue between tracking and the DR stage.
const STAGE_QUEUE: usize = 16;

/// Why a frame was skipped.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FrameRejected {
    /// The message's buffers or intrinsics are inconsistent.
    #[error("malformed frame {seq}: {source}")]
    Malformed {
        /// The frame's sequence number.
        seq: u64,
        /// What is wrong.
        source: camera::convert::ConvertError,
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

/// How far a target's stamp may lead the frames before it is taken for a clock disagreement and
/// applied at once.
pub const TARGET_LEAD: Duration = Duration::from_secs(1);
/// Targets held for later frames beyond which the oldest applies at once.
const PENDING_TARGETS: usize = 16;

/// The tracker with its bus-side conversions: one frame message in, one track and its events
/// out. No bus here, so it is tested directly.
#[derive(Debug)]
pub struct Handler {
    tracker: BallTracker,
    /// Checked targets (stamp, target) given for frames not yet seen, oldest first.
    pending: std::collections::VecDeque<(i64, Option<Target>)>,
    /// Targets applied at once because their stamp led the frames by more than [`TARGET_LEAD`].
    targets_ahead: u64,
}

impl Handler {
    /// A tracker with `config`, looking for `target` if given.
    pub fn new(config: TrackerConfig, target: Option<Target>) -> Result<Handler, TrackError> {
        let mut tracker = BallTracker::new(config);
        tracker.set_target(target)?;
        Ok(Handler {
            tracker,
            pending: Default::default(),
            targets_ahead: 0,
        })
    }

    /// The tracker.
    pub fn tracker(&self) -> &BallTracker {
        &self.tracker
    }

    /// Takes a target message (`active = false` clears the target): checked now, applied from
    /// the first frame stamped at or after its stamp (at once if unstamped). A bad target is
    /// refused and changes nothing.
    pub fn set_target(&mut self, msg: &BallTarget) -> Result<(), TrackError> {
        let target = msg
            .active
            .then_some(Target {
                hue_deg: msg.hue_deg,
                saturation: msg.saturation,
                diameter_m: msg.diameter_m,
            })
            .map(Target::checked)
            .transpose()?;
        if msg.header.stamp_ns == 0 {
            self.pending.clear();
            return self.tracker.set_target(target);
        }
        if self.pending.len() == PENDING_TARGETS
            && let Some((_, oldest)) = self.pending.pop_front()
        {
            self.tracker.set_target(oldest)?;
        }
        self.pending.push_back((msg.header.stamp_ns, target));
        Ok(())
    }

    /// Targets applied at once because their stamp led the frames by more than [`TARGET_LEAD`].
    pub fn targets_ahead_of_frames(&self) -> u64 {
        self.targets_ahead
    }

    /// Applies the pending targets due for a frame stamped `stamp_ns`.
    fn apply_targets_due(&mut self, stamp_ns: i64) -> Result<(), TrackError> {
        let lead_ns = TARGET_LEAD.as_nanos() as i64;
        while let Some(&(at, target)) = self.pending.front() {
            let ahead = at.saturating_sub(stamp_ns) > lead_ns;
            if at > stamp_ns && !ahead {
                break;
            }
            self.targets_ahead += u64::from(ahead);
            self.pending.pop_front();
            self.tracker.set_target(target)?;
        }
        Ok(())
    }

    /// Tracks one frame message.
    pub fn process(
        &mut self,
        frame: &RgbdFrame,
    ) -> Result<(BallTrack, Vec<BallEvent>), FrameRejected> {
        self.process_view(&frame.view())
    }

    /// Tracks one frame read in place from the bus (its buffers borrowed from the payload).
    pub fn process_view(
        &mut self,
        frame: &RgbdFrameView<'_>,
    ) -> Result<(BallTrack, Vec<BallEvent>), FrameRejected> {
        let seq = frame.header.seq;
        let image = camera::convert::from_view(frame)
            .map_err(|source| FrameRejected::Malformed { seq, source })?;
        self.apply_targets_due(frame.header.stamp_ns)
            .map_err(|source| FrameRejected::Refused { seq, source })?;
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
    anyhow::ensure!(
        (0.0..=1.0).contains(&config.dr_update_confidence),
        "--dr-update-confidence {} is not in [0, 1]",
        config.dr_update_confidence
    );
    anyhow::ensure!(
        config.dr_retry_s.is_finite() && config.dr_retry_s >= 0.0,
        "--dr-retry-s {} must be a finite time >= 0",
        config.dr_retry_s
    );
    let frames = bus
        .subscriber_named::<RgbdFrame>(topics::VISION_RGBD.name(), FRAME_QUEUE)
        .await?;
    let targets = bus.subscriber(&topics::VISION_BALL_TARGET).await?;
    let tracks = bus.publisher(&topics::VISION_BALL).await?;
    let events = bus.publisher(&topics::VISION_BALL_EVENTS).await?;
    let counters = bus.counters().clone();
    let dr = (!config.no_dr).then(|| {
        DrLink::new(
            bus.clone(),
            DrOptions {
                robot_frame: config.robot_frame.clone(),
                ball_node: config.ball_node.clone(),
                timeout: Duration::from_millis(config.dr_timeout_ms.max(1)),
                retry: Duration::from_secs_f64(config.dr_retry_s),
                update_confidence: config.dr_update_confidence,
            },
        )
    });
    // The second stage: the DR, then publishing, in frame order.
    let (to_stage, stage_rx) =
        tokio::sync::mpsc::channel::<(BallTrack, Vec<BallEvent>)>(STAGE_QUEUE);
    let stage = tokio::spawn(output_stage(stage_rx, dr, tracks, events, counters.clone()));
    let result = track_frames(
        &config,
        &mut handler,
        &frames,
        &targets,
        &to_stage,
        &counters,
        &mut shutdown,
    )
    .await;
    drop(to_stage);
    // Let the stage publish what is queued (it ends when the queue is empty and closed).
    // Its error, if any, is the cause of the tracking loop's.
    #[expect(
        clippy::disallowed_methods,
        reason = "a grace for the process's exit: a virtual clock that stopped with its replay must not hold the exit"
    )]
    let drained = tokio::time::timeout(Duration::from_secs(2), stage).await;
    match drained {
        Ok(Ok(Err(e))) => Err(e.context("publishing the tracks")),
        Ok(Err(e)) => anyhow::bail!("the output stage failed: {e}"),
        Ok(Ok(Ok(()))) | Err(_) => result,
    }
}

/// Publishes tracks and their events in order, each track placed in the world by the DR first
/// (when there is one and the stage is not behind).
async fn output_stage(
    mut queue: tokio::sync::mpsc::Receiver<(BallTrack, Vec<BallEvent>)>,
    mut dr: Option<DrLink>,
    tracks: interfaces::Publisher<BallTrack>,
    events: interfaces::Publisher<BallEvent>,
    counters: std::sync::Arc<interfaces::bus::Counters>,
) -> anyhow::Result<()> {
    while let Some((mut track, evs)) = queue.recv().await {
        if let Some(dr) = dr.as_mut() {
            if queue.len() > DR_BEHIND {
                if track.has_centre_m {
                    counters.incr("dr_skipped_behind");
                }
            } else {
                dr.process(&mut track).await;
            }
        }
        tracks.publish(&mut track).await?;
        for mut e in evs {
            tracing::info!(frame_seq = e.frame_seq, "ball {:?}", e.kind);
            events.publish(&mut e).await?;
        }
    }
    Ok(())
}

/// The tracking loop: frames and targets in, tracks to the output stage.
async fn track_frames(
    config: &Config,
    handler: &mut Handler,
    frames: &interfaces::Subscriber<RgbdFrame>,
    targets: &interfaces::Subscriber<BallTarget>,
    to_stage: &tokio::sync::mpsc::Sender<(BallTrack, Vec<BallEvent>)>,
    counters: &std::sync::Arc<interfaces::bus::Counters>,
    shutdown: &mut Shutdown,
) -> anyhow::Result<()> {
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
            frame = frames.recv_borrowed() => {
                let mut frame = frame?;
                // Behind? Track the newest frame, count the others.
                while !config.every_frame && let Some(newer) = frames.try_recv_borrowed() {
                    counters.incr("skipped_frames");
                    frame = newer;
                }
                let ahead = handler.targets_ahead_of_frames();
                let view = frame.view();
                let seq = view.header.seq;
                let result = handler.process_view(&view);
                if handler.targets_ahead_of_frames() > ahead {
                    counters.incr("targets_ahead_of_frames");
                    tracing::warn!(
                        "a target stamped more than {:?} after frame {} applied at once: do the clocks of the camera and the target's sender agree?",
                        TARGET_LEAD,
                        seq
                    );
                }
                // The shared-memory buffer goes back to the camera's pool.
                drop(frame);
                match result {
                    Ok(out) if config.every_frame => {
                        // Offline evaluation: wait for the stage rather than drop a track.
                        to_stage.send(out).await?;
                    }
                    Ok(out) => {
                        if let Err(e) = to_stage.try_send(out) {
                            if matches!(e, tokio::sync::mpsc::error::TrySendError::Closed(_)) {
                                anyhow::bail!("the output stage stopped");
                            }
                            counters.incr("dropped_tracks");
                            #[expect(
                                clippy::disallowed_methods,
                                reason = "the log limiter paces what a person reads, on the wall"
                            )]
                            let allowed = warn_limit.allow(Instant::now());
                            if let Some(suppressed) = allowed {
                                tracing::warn!(suppressed, "the output stage is stuck, a track was dropped: {e}");
                            }
                        }
                    }
                    Err(e) => {
                        counters.incr("bad_frames");
                        #[expect(
                            clippy::disallowed_methods,
                            reason = "the log limiter paces what a person reads, on the wall"
                        )]
                        let allowed = warn_limit.allow(Instant::now());
                        if let Some(suppressed) = allowed {
                            tracing::warn!(suppressed, "skipped a frame: {e}");
                        }
                    }
                }
            }
        }
    }
}

/// The `ball_tracker` component.
#[derive(Debug)]
pub struct BallTrackerComponent;

impl interfaces::node::Component for BallTrackerComponent {
    const NAME: &'static str = "ball_tracker";
    const ABOUT: &'static str = "Tracks a coloured ball in `vision/rgbd`; publishes `vision/ball` and \
        `vision/ball_events`.";
    type Config = Config;
    type Prepared = Config;

    fn interface(config: &Config) -> Interface {
        interface(config)
    }

    fn prepare(config: Config) -> anyhow::Result<Config> {
        Ok(config)
    }

    async fn run(bus: Bus, prepared: Config, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}

#[cfg(test)]
mod tests;
