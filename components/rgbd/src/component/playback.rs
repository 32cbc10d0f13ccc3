//! The playback of a recording: paced by its timestamps on the component's clock.

use std::time::Duration;

use interfaces::{Bus, Shutdown, topics};

use super::{Config, Outputs};
use camera::RgbdDriver;
use camera::convert::{into_msg, seconds_to_ns};
use camera::playback::PlaybackDriver;

#[expect(
    clippy::disallowed_methods,
    reason = "waits for a subscriber to appear on the transport (zenoh's discovery), before the \
              first frame: a virtual clock that no one moves yet must not hold the start forever"
)]
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

/// Plays the recording until its end (without `--loop`) or shutdown.
pub(super) async fn run_playback(
    bus: &Bus,
    config: &Config,
    mut driver: PlaybackDriver,
    rate: f64,
    restamp: bool,
    out: Outputs,
    shutdown: &mut Shutdown,
) -> anyhow::Result<()> {
    let Outputs {
        frames, mut status, ..
    } = out;
    let clock = bus.clock().clone();
    let now_s = move || clock.now_ns() as f64 * 1e-9;
    wait_for_subscriber(bus, config.wait_for_subscriber_s, shutdown).await;
    // The pacing is on the component's clock.
    let mut prev: Option<(f64, interfaces::clock::Moment)> = None;
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
                _ = bus.clock().sleep_until(due) => {}
            }
            prev = Some((frame.timestamp_s, due));
        } else {
            prev = Some((frame.timestamp_s, bus.clock().now()));
        }
        let mut msg = into_msg(frame, &config.frame_id);
        if restamp {
            msg.header.stamp_ns = seconds_to_ns(now_s());
        }
        if let Some(frames) = &frames {
            frames.publish(&mut msg).await?;
        }
        if let Some(s) = status.as_mut() {
            s.frame(true, "a recorded sequence").await?;
        }
        published += 1;
    }
}
