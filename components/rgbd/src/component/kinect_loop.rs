//! The freenect driver's side on the bus: the camera thread's frames, losses and returns.

use std::time::Duration;

use interfaces::msg::vision::RgbdFrame;
use interfaces::ratelimit::RateLimiter;
use interfaces::{Bus, Shutdown};

use super::{Config, StatusOut};
use crate::kinect::{Event, KinectSource};
use camera::convert::into_msg;

/// Share of the pixels below which a frame counts as having no depth, or above which as
/// saturated.
const FRAME_SHARE: usize = 20;

/// The freenect driver's loop: its thread's frames onto the bus, its losses and returns on
/// `diagnostics` and in the log.
pub(super) async fn run_kinect(
    bus: &Bus,
    config: &Config,
    src: &mut KinectSource,
    frames: &interfaces::Publisher<RgbdFrame>,
    status: &mut StatusOut,
    shutdown: &mut Shutdown,
) -> anyhow::Result<()> {
    let counters = bus.counters().clone();
    let dropped = counters.counter("camera_frames_dropped");
    let timeout = Duration::from_secs_f64(config.frame_timeout_s);
    let mut warn_limit = RateLimiter::new(Duration::from_secs(5));
    let (mut stalled, mut opened_once, mut tilt_logged, mut frames_seen) =
        (false, false, false, 0u64);
    loop {
        #[expect(
            clippy::disallowed_methods,
            reason = "a device watchdog: a real camera's USB stall, on the wall its thread \
                      delivers frames on"
        )]
        let next = tokio::time::timeout(timeout, src.events.recv());
        let event = tokio::select! {
            biased;
            _ = shutdown.wait() => return Ok(()),
            e = next => e,
        };
        dropped.store(
            src.dropped.load(std::sync::atomic::Ordering::Relaxed),
            std::sync::atomic::Ordering::Relaxed,
        );
        match event {
            Err(_) => {
                if !stalled && opened_once {
                    stalled = true;
                    counters.incr("camera_stalled");
                    status.status.losses += 1;
                    tracing::warn!(
                        "no frame from the camera for {:.1} s (unplugged, or its USB link \
                         stalled): waiting for it",
                        timeout.as_secs_f64()
                    );
                }
                if stalled {
                    status
                        .change(false, "no frame from the camera: waiting for it")
                        .await?;
                }
            }
            Ok(None) => anyhow::bail!("the camera thread ended"),
            Ok(Some(Event::Frame(frame, at, stats))) => {
                if stalled {
                    stalled = false;
                    tracing::info!("frames from the camera again");
                }
                frames_seen += 1;
                counters.incr("camera_frames");
                let n = frame.pixel_count();
                if stats.depth_pixels * FRAME_SHARE < n {
                    counters.incr("frames_no_depth");
                    #[expect(
                        clippy::disallowed_methods,
                        reason = "the log limiter paces what a person reads, on the wall"
                    )]
                    let allowed = warn_limit.allow(std::time::Instant::now());
                    if let Some(suppressed) = allowed {
                        tracing::warn!(
                            suppressed,
                            "frame {frames_seen}: depth on {} of {n} pixels only (too near, too \
                             far, sunlight, or a covered projector)",
                            stats.depth_pixels
                        );
                    }
                }
                if stats.saturated_pixels * FRAME_SHARE > n {
                    counters.incr("frames_saturated");
                }
                let age_ns = i64::try_from(at.elapsed().as_nanos()).unwrap_or(0);
                let mut msg = into_msg(*frame, &config.frame_id);
                msg.header.stamp_ns = bus.clock().now_ns() - age_ns;
                frames.publish(&mut msg).await?;
                let detail = status.streaming_detail.clone();
                status.frame(true, &detail).await?;
            }
            Ok(Some(Event::Opened { description })) => {
                status.streaming_detail = description.clone();
                if opened_once {
                    counters.incr("camera_reopened");
                    tracing::info!("camera back: {description}");
                } else {
                    tracing::info!(
                        "streaming {description}; intrinsics fx {:.1} fy {:.1} cx {:.1} cy {:.1}",
                        src.intrinsics.fx,
                        src.intrinsics.fy,
                        src.intrinsics.cx,
                        src.intrinsics.cy
                    );
                }
                opened_once = true;
            }
            Ok(Some(Event::Lost { reason })) => {
                counters.incr("camera_lost");
                if !stalled {
                    status.status.losses += 1;
                }
                stalled = true;
                tracing::warn!("camera lost: {reason}; reopening it every second");
                status
                    .change(false, &format!("camera lost: {reason}"))
                    .await?;
            }
            Ok(Some(Event::StillAway { reason })) => {
                tracing::warn!("camera not back yet: {reason}");
            }
            Ok(Some(Event::Tilt(t))) => {
                let level = if tilt_logged {
                    tracing::Level::DEBUG
                } else {
                    tracing::Level::INFO
                };
                tilt_logged = true;
                if level == tracing::Level::INFO {
                    tracing::info!(
                        "tilt motor {:.1} deg (status {}), accelerometer ({:.2}, {:.2}, {:.2}) m/s2",
                        t.angle_deg,
                        t.status,
                        t.accel_mps2[0],
                        t.accel_mps2[1],
                        t.accel_mps2[2]
                    );
                } else {
                    tracing::debug!(
                        "tilt motor {:.1} deg, accelerometer {:?} m/s2",
                        t.angle_deg,
                        t.accel_mps2
                    );
                }
            }
        }
    }
}
