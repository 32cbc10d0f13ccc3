//! The ball in the world and the robot frames, through the deep representation (DR).
//!
//! Frames and time: a track's `centre_m` is in the camera's optical frame (`header.frame_id`,
//! e.g. `head_rgbd_optical_frame`) at the frame's stamp. The DR knows that frame's pose at any
//! recent stamp (it interpolates the joint values it was given), so for each track with a
//! measured centre the [`DrLink`] asks `dr/transform` for `world_T_camera` and
//! `robot_T_camera` (`robot` = `base_footprint` by default) at the frame's stamp, both calls at
//! once, and fills `centre_world_m` and `centre_robot_m` ([`locate`]). When the track is
//! confident, it also writes the ball node's pose (`dr/update`, a `PoseUpdate` of `--ball-node`
//! whose parent is `world`) at the frame's stamp, one update in flight at most (a newer track
//! while one is in flight is not sent, and counted).
//!
//! Failure handling: the DR missing (no server) or not answering within the time-out makes the
//! link rest for a while (`retry`, on the component's clock): tracks are published in the camera frame only
//! (`has_centre_world = false`), counted (`dr_unavailable`) and logged at most once a second.
//! A DR that answers with an error (an unknown frame, a stamp older than its history) costs that
//! one track its world position (`dr_transform_errors`). Updates that fail are counted
//! (`dr_update_errors`); accepted ones too (`dr_updates`).

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use interfaces::msg::dr::{PoseUpdate, Transform, TransformRequest, UpdateRequest};
use interfaces::msg::tracking::BallTrack;
use interfaces::ratelimit::RateLimiter;
use interfaces::{Bus, CallError, Header, Moment, topics};
use nalgebra::{Isometry3, Point3, Quaternion, Translation3, UnitQuaternion};

/// How the tracker uses the DR.
#[derive(Debug, Clone)]
pub struct DrOptions {
    /// The robot's base frame for `centre_robot_m`.
    pub robot_frame: String,
    /// The DR node of the ball (its parent must be `world`).
    pub ball_node: String,
    /// Each call's time-out.
    pub timeout: Duration,
    /// How long to rest after the DR was missing or silent.
    pub retry: Duration,
    /// Smallest track confidence that updates the ball node.
    pub update_confidence: f64,
}

/// `target_T_source` of a DR transform; `None` when its numbers are unusable.
pub fn isometry(t: &Transform) -> Option<Isometry3<f64>> {
    let [x, y, z] = t.translation_m;
    let [qx, qy, qz, qw] = t.rotation_xyzw;
    let q = Quaternion::new(qw, qx, qy, qz);
    let n = q.norm();
    let finite = [x, y, z, qx, qy, qz, qw].iter().all(|v| v.is_finite());
    // A unit quaternion on the wire; far from unit means garbage, not rounding.
    if !(finite && n > 0.5 && n < 1.5) {
        return None;
    }
    Some(Isometry3::from_parts(
        Translation3::new(x, y, z),
        UnitQuaternion::from_quaternion(q),
    ))
}

/// Fills `track`'s world and robot positions from its camera-frame centre and the camera's
/// pose in the world (`world_T_camera`) and the robot's base frame (`robot_T_camera`). A track
/// without a measured centre is left as it is.
pub fn locate(
    track: &mut BallTrack,
    world_t_camera: &Isometry3<f64>,
    robot_t_camera: &Isometry3<f64>,
) {
    if !track.has_centre_m {
        return;
    }
    let c = Point3::from(track.centre_m);
    let w = world_t_camera * c;
    let r = robot_t_camera * c;
    track.has_centre_world = true;
    track.centre_world_m = [w.x, w.y, w.z];
    track.centre_robot_m = [r.x, r.y, r.z];
}

/// Whether a located track is good enough to move the DR's ball node.
pub fn should_update(track: &BallTrack, min_confidence: f64) -> bool {
    track.found && track.has_centre_world && track.confidence >= min_confidence
}

/// The DR client of the tracker: see the module doc.
#[derive(Debug)]
pub struct DrLink {
    bus: Bus,
    options: DrOptions,
    /// Until when (on the component's clock) the DR is not asked, after it did not answer.
    resting_until: Option<Moment>,
    update_in_flight: Arc<AtomicBool>,
    warn_limit: RateLimiter,
    update_warn_limit: Arc<std::sync::Mutex<RateLimiter>>,
}

impl DrLink {
    /// A link on `bus`.
    pub fn new(bus: Bus, options: DrOptions) -> DrLink {
        DrLink {
            bus,
            options,
            resting_until: None,
            update_in_flight: Arc::new(AtomicBool::new(false)),
            warn_limit: RateLimiter::new(Duration::from_secs(1)),
            update_warn_limit: Arc::new(std::sync::Mutex::new(RateLimiter::new(
                Duration::from_secs(1),
            ))),
        }
    }

    #[expect(
        clippy::disallowed_methods,
        reason = "the log limiter paces what a person reads, on the wall"
    )]
    fn warn(&mut self, message: std::fmt::Arguments<'_>) {
        if let Some(suppressed) = self.warn_limit.allow(Instant::now()) {
            tracing::warn!(suppressed, "{message}");
        }
    }

    async fn transform(
        &self,
        target: &str,
        source: &str,
        stamp_ns: i64,
    ) -> Result<Transform, CallError> {
        let req = TransformRequest {
            header: Header::default(),
            target: target.to_string(),
            source: source.to_string(),
            stamp_ns: stamp_ns.max(1) as u64,
        };
        self.bus
            .call(&topics::DR_TRANSFORM, &req, self.options.timeout)
            .await
            .map(|r| r.transform)
    }

    /// Fills the world and robot positions of `track` (when it has a centre and the DR can tell),
    /// then updates the ball node when the track is confident. Never waits longer than the
    /// time-out; while the DR rests, returns at once.
    pub async fn process(&mut self, track: &mut BallTrack) {
        if !track.has_centre_m {
            return;
        }
        let counters = self.bus.counters().clone();
        if let Some(until) = self.resting_until {
            if self.bus.clock().now() < until {
                counters.incr("dr_unavailable");
                return;
            }
            self.resting_until = None;
        }
        let stamp = track.header.stamp_ns;
        let frame = track.header.frame_id.clone();
        let (world, robot) = tokio::join!(
            self.transform("world", &frame, stamp),
            self.transform(&self.options.robot_frame, &frame, stamp)
        );
        match (world, robot) {
            (Ok(w), Ok(r)) => match (isometry(&w), isometry(&r)) {
                (Some(w), Some(r)) => locate(track, &w, &r),
                _ => {
                    counters.incr("dr_transform_errors");
                    self.warn(format_args!(
                        "the DR gave a transform that is not a rigid motion for {frame} at {stamp} ns"
                    ));
                }
            },
            (Err(e), _) | (_, Err(e)) => match e {
                CallError::NoServer(_) | CallError::Timeout { .. } | CallError::Zenoh(_) => {
                    counters.incr("dr_unavailable");
                    self.resting_until = Some(self.bus.clock().now() + self.options.retry);
                    self.warn(format_args!(
                        "no deep representation ({e}): publishing the ball in the camera frame \
                         only, asking again in {:.1} s",
                        self.options.retry.as_secs_f64()
                    ));
                }
                e => {
                    counters.incr("dr_transform_errors");
                    self.warn(format_args!(
                        "the DR cannot place {frame} at {stamp} ns ({e}): this track has no \
                         world position"
                    ));
                }
            },
        }
        if should_update(track, self.options.update_confidence) {
            self.update(track);
        }
    }

    /// Sends the ball node's new pose without waiting for the reply (one in flight at most).
    fn update(&self, track: &BallTrack) {
        let counters = self.bus.counters().clone();
        if self.update_in_flight.swap(true, Ordering::AcqRel) {
            counters.incr("dr_updates_skipped");
            return;
        }
        let [x, y, z] = track.centre_world_m;
        let req = UpdateRequest {
            header: Header {
                stamp_ns: track.header.stamp_ns,
                seq: 0,
                frame_id: "world".into(),
            },
            poses: vec![PoseUpdate {
                node: self.options.ball_node.clone(),
                pose: Transform::from_translation(x, y, z),
            }],
            ..Default::default()
        };
        let bus = self.bus.clone();
        let timeout = self.options.timeout;
        let in_flight = self.update_in_flight.clone();
        let limiter = self.update_warn_limit.clone();
        let node = self.options.ball_node.clone();
        tokio::spawn(async move {
            match bus.call(&topics::DR_UPDATE, &req, timeout).await {
                Ok(_) => counters.incr("dr_updates"),
                Err(e) => {
                    counters.incr("dr_update_errors");
                    #[expect(
                        clippy::disallowed_methods,
                        reason = "the log limiter paces what a person reads, on the wall"
                    )]
                    let allowed = limiter
                        .lock()
                        .map(|mut l| l.allow(Instant::now()))
                        .unwrap_or(None);
                    if let Some(suppressed) = allowed {
                        tracing::warn!(suppressed, "could not update the DR's `{node}`: {e}");
                    }
                }
            }
            in_flight.store(false, Ordering::Release);
        });
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    #[test]
    fn the_centre_goes_through_both_transforms() {
        let mut t = BallTrack {
            found: true,
            has_centre_m: true,
            centre_m: [0.1, -0.2, 1.0],
            confidence: 0.9,
            ..Default::default()
        };
        // A camera 1.5 m up looking along world +x (optical z = world x, x = -y, y = -z).
        let rot =
            UnitQuaternion::from_basis_unchecked(&[-Vector3::y(), -Vector3::z(), Vector3::x()]);
        let world = Isometry3::from_parts(Translation3::new(0.0, 0.0, 1.5), rot);
        let robot = Isometry3::from_parts(Translation3::new(-1.0, 0.0, 1.5), rot);
        locate(&mut t, &world, &robot);
        assert!(t.has_centre_world);
        let w = Vector3::from(t.centre_world_m);
        assert!((w - Vector3::new(1.0, -0.1, 1.7)).norm() < 1e-12, "{w}");
        let r = Vector3::from(t.centre_robot_m);
        assert!((r - Vector3::new(0.0, -0.1, 1.7)).norm() < 1e-12, "{r}");
        assert!(should_update(&t, 0.5));
        assert!(!should_update(&t, 0.95));
        // No centre: nothing to locate, nothing to update.
        let mut none = BallTrack::default();
        locate(&mut none, &world, &robot);
        assert!(!none.has_centre_world && !should_update(&none, 0.0));
    }

    #[test]
    fn dr_transforms_with_bad_numbers_are_refused() {
        let ok = Transform {
            translation_m: [1.0, 2.0, 3.0],
            rotation_xyzw: [
                0.0,
                0.0,
                std::f64::consts::FRAC_1_SQRT_2,
                std::f64::consts::FRAC_1_SQRT_2,
            ],
        };
        let iso = isometry(&ok).unwrap();
        assert!((iso * Point3::new(1.0, 0.0, 0.0) - Point3::new(1.0, 3.0, 3.0)).norm() < 1e-12);
        let mut bad = ok;
        bad.translation_m[0] = f64::NAN;
        assert!(isometry(&bad).is_none());
        let mut bad = ok;
        bad.rotation_xyzw = [0.0; 4];
        assert!(isometry(&bad).is_none());
    }
}
