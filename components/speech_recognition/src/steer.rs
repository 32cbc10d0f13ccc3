//! Listening where the robot looks: the beam of a microphone array steered at the person the deep
//! representation holds (`--array-frame FRAME --listen-to NODES`).
//!
//! Five times a second the recognizer asks the deep representation (`dr/transform`) where each
//! node of `--listen-to` is in the array's frame (`--array-frame`: the robot's frame the array's
//! geometry is given in, such as Loki's `head_rgbd_link` for its Kinect), at the time of the
//! newest audio: the first node it knows is the aim, at `atan2(y, x)` of its position there (0
//! straight ahead, positive to the left, as the array's geometry). The neck, the base and the
//! person move; the transform at the audio's time follows them all. When it knows none of them,
//! or cannot be asked, the beam listens to the loudest talker ([`crate::beam::Aim::Loudest`]).
//!
//! Each change of what the beam listens to is logged; each failed ask is counted
//! (`steer_dr_failures`) and the first of a run of them logged.

use crate::beam::Aim;
use interfaces::msg::dr::TransformRequest;
use interfaces::{Bus, CallError, ErrorCode, Shutdown, topics};
use std::sync::Arc;
use std::sync::atomic::{AtomicI64, Ordering};
use std::time::Duration;

/// How often the deep representation is asked.
pub const STEER_EVERY: Duration = Duration::from_millis(200);

/// How long an ask may take.
const ASK_TIMEOUT: Duration = Duration::from_millis(500);

/// A node this close to the array's vertical axis has no azimuth worth steering at (m).
const MIN_HORIZONTAL_M: f64 = 0.05;

/// Where to ask for the aim.
#[derive(Debug, Clone)]
pub struct DrAim {
    /// The array's frame in the deep representation.
    pub frame: String,
    /// The nodes to listen to, the first known one first.
    pub nodes: Vec<String>,
}

/// Why no node gave an aim.
#[derive(Debug, Clone, PartialEq)]
enum Nobody {
    /// The deep representation knows none of the nodes (or not the array's frame).
    Unknown(String),
    /// It could not be asked.
    Unreachable(String),
}

/// The aim from the deep representation's answer: the node's azimuth in the array's frame, or
/// `None` when it is straight above or below the array.
fn azimuth_of(translation_m: [f64; 3]) -> Option<f64> {
    let [x, y, _] = translation_m;
    (x.hypot(y) >= MIN_HORIZONTAL_M && x.is_finite() && y.is_finite()).then(|| y.atan2(x))
}

impl DrAim {
    /// The first node the deep representation knows, at the time `stamp_ns` (the newest audio;
    /// the latest state when that time is not held, or `stamp_ns` is 0).
    async fn ask(&self, bus: &Bus, stamp_ns: i64) -> Result<Aim, Nobody> {
        let mut unknown = Vec::new();
        for node in &self.nodes {
            let mut req = TransformRequest {
                header: Default::default(),
                target: self.frame.clone(),
                source: node.clone(),
                stamp_ns: u64::try_from(stamp_ns).unwrap_or(0),
            };
            let mut reply = bus.call(&topics::DR_TRANSFORM, &req, ASK_TIMEOUT).await;
            if matches!(&reply, Err(CallError::Remote(e)) if e.code == ErrorCode::NotFound)
                && req.stamp_ns != 0
            {
                // A time the deep representation does not hold (another clock, or before its
                // history): its latest state.
                req.stamp_ns = 0;
                reply = bus.call(&topics::DR_TRANSFORM, &req, ASK_TIMEOUT).await;
            }
            match reply {
                Ok(rep) => match azimuth_of(rep.transform.translation_m) {
                    Some(azimuth_rad) => {
                        return Ok(Aim::Node {
                            name: node.clone(),
                            azimuth_rad,
                        });
                    }
                    None => unknown.push(format!("{node}: straight above or below the array")),
                },
                Err(CallError::Remote(e)) if e.code == ErrorCode::NotFound => {
                    unknown.push(format!("{node}: {}", e.message));
                }
                Err(e) => return Err(Nobody::Unreachable(e.to_string())),
            }
        }
        Err(Nobody::Unknown(unknown.join("; ")))
    }
}

/// Asks the deep representation for the aim every [`STEER_EVERY`] until `shutdown`, at the time
/// of the newest audio (`newest_audio_ns`), and hands it on `aim`.
pub async fn run(
    bus: Bus,
    dr: DrAim,
    newest_audio_ns: Arc<AtomicI64>,
    aim: tokio::sync::watch::Sender<Aim>,
    mut shutdown: Shutdown,
) {
    let mut tick = bus.clock().interval(STEER_EVERY);
    let mut last: Option<Result<String, Nobody>> = None;
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = shutdown.wait() => return,
        }
        let got = dr.ask(&bus, newest_audio_ns.load(Ordering::Relaxed)).await;
        let what = got
            .as_ref()
            .map(|a| a.label().to_string())
            .map_err(Clone::clone);
        if let Err(Nobody::Unreachable(_)) = &got {
            bus.counters().incr("steer_dr_failures");
        }
        // Logged as it changes: a node found, or lost, and why.
        let changed = match (&last, &what) {
            (Some(Ok(a)), Ok(b)) => a != b,
            (Some(Err(Nobody::Unknown(_))), Err(Nobody::Unknown(_)))
            | (Some(Err(Nobody::Unreachable(_))), Err(Nobody::Unreachable(_))) => false,
            _ => true,
        };
        if changed {
            match &got {
                Ok(Aim::Node { name, azimuth_rad }) => tracing::info!(
                    "listening to {name} (the deep representation), at {:.0} degrees of {}",
                    azimuth_rad.to_degrees(),
                    dr.frame
                ),
                Ok(_) => {}
                Err(Nobody::Unknown(why)) => tracing::info!(
                    "the deep representation knows none of {:?} in {} ({why}): listening to the \
                     loudest talker",
                    dr.nodes,
                    dr.frame
                ),
                Err(Nobody::Unreachable(why)) => tracing::warn!(
                    "cannot ask the deep representation where {:?} are ({why}): listening to the \
                     loudest talker until it answers",
                    dr.nodes
                ),
            }
        }
        last = Some(what);
        let next = got.unwrap_or(Aim::Loudest);
        aim.send_if_modified(|a| {
            let modified = *a != next;
            *a = next;
            modified
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_node_straight_ahead_left_or_behind_has_its_azimuth_one_above_the_array_none() {
        let deg = |t| azimuth_of(t).map(f64::to_degrees);
        assert_eq!(deg([1.5, 0.0, -0.4]), Some(0.0));
        assert!((deg([1.0, 1.0, 0.3]).unwrap() - 45.0).abs() < 1e-9);
        assert!((deg([-1.0, -0.01, 0.0]).unwrap() + 179.4).abs() < 0.1);
        assert_eq!(deg([0.01, 0.02, 1.0]), None);
        assert_eq!(deg([f64::NAN, 0.0, 0.0]), None);
    }
}
