//! The global (team) world model: the local models of the controlled robot and its teammate(s)
//! fused over time. Pure: every call takes the caller's time in seconds.
//!
//! # Ball
//!
//! A constant-velocity Kalman filter, state `[x, y, vx, vy]` (mm, mm/s, global frame), with
//! continuous white-acceleration process noise of spectral density `ball_accel_sigma_mm_s2²`.
//! Each debug packet carries the robot's last seen ball and its *ball age* (s since it was
//! seen), so the observation time is `received_s - ball_age_s`:
//!
//! - a robot that lost the ball keeps sending the same position with a growing age: such
//!   repeats (same position, age grown) are recognised and not fused again;
//! - observations older than `max_ball_measurement_age_s` are ignored;
//! - an observation older than the filter's time is carried forward to the filter's time with
//!   the filter's velocity, its noise inflated by the velocity uncertainty over the lag;
//! - fallen robots' observations are ignored;
//! - the measurement noise grows with the distance from the observing robot;
//! - a Mahalanobis gate rejects outliers; three rejections in a row (the ball was kicked or
//!   moved by hand) or a track older than `ball_reset_after_s` re-initialise the filter.
//!
//! The ball's `age_s` is the time since any robot last saw it; its confidence is
//! `exp(-age_s / ball_confidence_tau_s) / (1 + sigma_mm / 500)`.
//!
//! # Obstacles
//!
//! Obstacle timestamps are robot-clock milliseconds. Each robot's clock offset to ours is
//! estimated as the minimum over all its packets of `received_ms - last_seen_ms` (the freshest
//! sighting, up to the network latency), so each obstacle gets a time on our clock; the
//! estimate starts again when the robot's clock jumps back (a reboot) or after a silence longer
//! than `robot_timeout_s` (its software may have stalled with its clock). An
//! observation is associated with the nearest track within `obstacle_gate_mm` (greedy), moves
//! it by exponential smoothing and keeps the most specific kind; unassociated fresh
//! observations start tracks; tracks unseen for `obstacle_timeout_s` are dropped. Obstacles
//! within `own_robot_exclusion_mm` of one of our own robots are those robots and are not
//! listed.

use std::collections::BTreeMap;

use nalgebra::{Matrix2, Matrix2x4, Matrix4, Vector2, Vector4};
use serde::{Deserialize, Serialize};

use crate::types::{
    FieldPoint, NaoLocalModel, NaoWorldModel, ObstacleKind, TeamRobot, TrackedObstacle,
};

/// Two ball reports with the same position whose observation times differ by less than this
/// are one sighting sent twice (s): covers network jitter at the 100 ms packet period.
const REPEAT_TOLERANCE_S: f64 = 0.05;

/// Tuning of the fusion. Distances in mm, times in s.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FusionConfig {
    /// Player number of the operator-controlled robot.
    pub controlled_player: u8,
    /// Our team number: models of other teams are ignored (`None` accepts all).
    pub team_number: Option<u8>,
    /// Ball acceleration noise (mm/s²).
    pub ball_accel_sigma_mm_s2: f64,
    /// Ball measurement noise at the robot (mm).
    pub ball_sigma_base_mm: f64,
    /// Extra measurement noise per mm of distance from the observing robot.
    pub ball_sigma_per_mm: f64,
    /// Observations older than this are ignored (s).
    pub max_ball_measurement_age_s: f64,
    /// A track not updated for this long is re-initialised by the next observation (s).
    pub ball_reset_after_s: f64,
    /// The ball is no longer reported after this long without observation (s).
    pub ball_forget_after_s: f64,
    /// Longest extrapolation past the last observation (s).
    pub ball_max_prediction_s: f64,
    /// Confidence decay time (s).
    pub ball_confidence_tau_s: f64,
    /// Mahalanobis distance² gate (2 dof).
    pub ball_gate_chi2: f64,
    /// Obstacle association distance (mm).
    pub obstacle_gate_mm: f64,
    /// Obstacle track lifetime without observation (s).
    pub obstacle_timeout_s: f64,
    /// Weight of a new observation in the track position (0..1].
    pub obstacle_smoothing: f64,
    /// Obstacles this close to one of our robots are that robot (mm).
    pub own_robot_exclusion_mm: f64,
    /// A robot silent for this long has freshness 0 (s).
    pub robot_timeout_s: f64,
}

impl Default for FusionConfig {
    fn default() -> Self {
        Self {
            controlled_player: 2,
            team_number: None,
            ball_accel_sigma_mm_s2: 150.0,
            ball_sigma_base_mm: 40.0,
            ball_sigma_per_mm: 0.03,
            max_ball_measurement_age_s: 1.0,
            ball_reset_after_s: 2.0,
            ball_forget_after_s: 10.0,
            ball_max_prediction_s: 1.0,
            ball_confidence_tau_s: 2.0,
            ball_gate_chi2: 16.0,
            obstacle_gate_mm: 500.0,
            obstacle_timeout_s: 3.0,
            obstacle_smoothing: 0.3,
            own_robot_exclusion_mm: 350.0,
            robot_timeout_s: 2.0,
        }
    }
}

/// What [`BallFilter::update`] did with a measurement.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum BallUpdate {
    /// Started a new track.
    Initialised,
    /// Fused.
    Fused,
    /// Outside the gate, not fused.
    Rejected,
}

/// Constant-velocity Kalman filter for the ball (mm, mm/s, s).
#[derive(Debug, Clone)]
pub struct BallFilter {
    accel_sigma: f64,
    gate_chi2: f64,
    reset_after_s: f64,
    x: Vector4<f64>,
    p: Matrix4<f64>,
    /// Time of the state (s).
    t_s: f64,
    /// Time of the last fused observation (s), `None` before the first.
    last_obs_s: Option<f64>,
    rejections: u32,
}

impl BallFilter {
    /// A filter with acceleration noise `accel_sigma_mm_s2`, a Mahalanobis² gate and a reset
    /// time (s).
    pub fn new(accel_sigma_mm_s2: f64, gate_chi2: f64, reset_after_s: f64) -> Self {
        Self {
            accel_sigma: accel_sigma_mm_s2,
            gate_chi2,
            reset_after_s,
            x: Vector4::zeros(),
            p: Matrix4::identity(),
            t_s: 0.0,
            last_obs_s: None,
            rejections: 0,
        }
    }

    fn transition(&self, dt: f64) -> (Matrix4<f64>, Matrix4<f64>) {
        let f = Matrix4::new(
            1.0, 0.0, dt, 0.0, //
            0.0, 1.0, 0.0, dt, //
            0.0, 0.0, 1.0, 0.0, //
            0.0, 0.0, 0.0, 1.0,
        );
        let q = self.accel_sigma * self.accel_sigma;
        let (a, b, c) = (dt.powi(3) / 3.0 * q, dt.powi(2) / 2.0 * q, dt * q);
        let qm = Matrix4::new(
            a, 0.0, b, 0.0, //
            0.0, a, 0.0, b, //
            b, 0.0, c, 0.0, //
            0.0, b, 0.0, c,
        );
        (f, qm)
    }

    fn predicted(&self, t_s: f64) -> (Vector4<f64>, Matrix4<f64>) {
        let dt = t_s - self.t_s;
        if dt <= 0.0 {
            return (self.x, self.p);
        }
        let (f, q) = self.transition(dt);
        (f * self.x, f * self.p * f.transpose() + q)
    }

    /// Move the state forward to `t_s` (no-op for earlier times).
    pub fn predict(&mut self, t_s: f64) {
        if t_s > self.t_s {
            let (x, p) = self.predicted(t_s);
            self.x = x;
            self.p = p;
            self.t_s = t_s;
        }
    }

    fn initialise(&mut self, z: Vector2<f64>, sigma_mm: f64, t_obs_s: f64) {
        let r = sigma_mm * sigma_mm;
        self.x = Vector4::new(z.x, z.y, 0.0, 0.0);
        // Velocity unknown: up to ~2 m/s.
        self.p = Matrix4::from_diagonal(&Vector4::new(r, r, 2000.0f64.powi(2), 2000.0f64.powi(2)));
        self.t_s = t_obs_s;
        self.last_obs_s = Some(t_obs_s);
        self.rejections = 0;
    }

    /// Fuse a position measurement `z` (mm) with standard deviation `sigma_mm`, observed at
    /// `t_obs_s`. A measurement older than the state is carried forward with the estimated
    /// velocity and its noise inflated accordingly.
    pub fn update(&mut self, z: FieldPoint, sigma_mm: f64, t_obs_s: f64) -> BallUpdate {
        let z = Vector2::new(f64::from(z.x_mm), f64::from(z.y_mm));
        let stale = self
            .last_obs_s
            .is_none_or(|t| t_obs_s - t > self.reset_after_s);
        if stale || self.rejections >= 3 {
            self.initialise(z, sigma_mm, t_obs_s.max(self.t_s));
            return BallUpdate::Initialised;
        }
        let mut r = Matrix2::identity() * sigma_mm * sigma_mm;
        let mut z = z;
        if t_obs_s < self.t_s {
            let lag = self.t_s - t_obs_s;
            z += Vector2::new(self.x[2], self.x[3]) * lag;
            r += Matrix2::new(
                self.p[(2, 2)],
                self.p[(2, 3)],
                self.p[(3, 2)],
                self.p[(3, 3)],
            ) * lag
                * lag;
        } else {
            self.predict(t_obs_s);
        }
        let h = Matrix2x4::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0);
        let y = z - h * self.x;
        let s = h * self.p * h.transpose() + r;
        let Some(s_inv) = s.try_inverse() else {
            return BallUpdate::Rejected;
        };
        let d2 = (y.transpose() * s_inv * y)[(0, 0)];
        if d2 > self.gate_chi2 {
            self.rejections += 1;
            return BallUpdate::Rejected;
        }
        let k = self.p * h.transpose() * s_inv;
        self.x += k * y;
        // Joseph form keeps P symmetric positive definite.
        let i_kh = Matrix4::identity() - k * h;
        self.p = i_kh * self.p * i_kh.transpose() + k * r * k.transpose();
        self.rejections = 0;
        self.last_obs_s = Some(self.last_obs_s.map_or(t_obs_s, |t| t.max(t_obs_s)));
        BallUpdate::Fused
    }

    /// Position, velocity and position sigma (mm, root mean of the two variances) at `t_s`,
    /// without changing the filter; `None` before the first observation.
    pub fn estimate_at(&self, t_s: f64) -> Option<(FieldPoint, FieldPoint, f64)> {
        self.last_obs_s?;
        let (x, p) = self.predicted(t_s);
        let sigma = ((p[(0, 0)] + p[(1, 1)]) / 2.0).max(0.0).sqrt();
        Some((
            FieldPoint::new(x[0] as f32, x[1] as f32),
            FieldPoint::new(x[2] as f32, x[3] as f32),
            sigma,
        ))
    }

    /// Time of the last fused observation (s).
    pub fn last_observation_s(&self) -> Option<f64> {
        self.last_obs_s
    }
}

#[derive(Debug, Clone)]
struct RobotEntry {
    model: NaoLocalModel,
    received_s: f64,
    /// min(received_ms - last_seen_ms) over all sightings; robot clock -> ours.
    clock_offset_ms: Option<f64>,
    max_last_seen_ms: u32,
    /// Last ball observation fused from this robot: position and observation time (s).
    last_ball: Option<(FieldPoint, f64)>,
}

#[derive(Debug, Clone)]
struct Track {
    /// Stable identity for the track's lifetime (never reused by this fusion).
    id: u32,
    kind: ObstacleKind,
    x: f64,
    y: f64,
    last_seen_s: f64,
    observations: u32,
}

/// The ball estimate of a snapshot, before it is laid out flat in the message.
struct Ball {
    position: FieldPoint,
    velocity: FieldPoint,
    age_s: f64,
    sigma_mm: f64,
    confidence: f64,
}

/// Fuses robots' local models into a [`NaoWorldModel`].
#[derive(Debug, Clone)]
pub struct WorldModelFusion {
    config: FusionConfig,
    robots: BTreeMap<u8, RobotEntry>,
    ball: BallFilter,
    tracks: Vec<Track>,
    next_track_id: u32,
    ball_updates: u64,
}

impl WorldModelFusion {
    /// An empty model.
    pub fn new(config: FusionConfig) -> Self {
        let ball = BallFilter::new(
            config.ball_accel_sigma_mm_s2,
            config.ball_gate_chi2,
            config.ball_reset_after_s,
        );
        Self {
            config,
            robots: BTreeMap::new(),
            ball,
            tracks: Vec::new(),
            next_track_id: 0,
            ball_updates: 0,
        }
    }

    /// Number of ball observations fused or used to initialise so far.
    pub fn ball_updates(&self) -> u64 {
        self.ball_updates
    }

    /// Fuse one robot's local model received at `received_s`. Returns false (and ignores it)
    /// when it is from another team.
    pub fn ingest(&mut self, model: &NaoLocalModel, received_s: f64) -> bool {
        if self
            .config
            .team_number
            .is_some_and(|t| t != model.team_number)
        {
            return false;
        }
        let player = model.player_number;
        let entry = self.robots.entry(player).or_insert_with(|| RobotEntry {
            model: model.clone(),
            received_s,
            clock_offset_ms: None,
            max_last_seen_ms: 0,
            last_ball: None,
        });
        // Back after a silence longer than the robot time-out: the robot may have rebooted or
        // its software stalled (its clock stood still), so its clock offset is estimated anew.
        if received_s - entry.received_s > self.config.robot_timeout_s {
            entry.clock_offset_ms = None;
        }
        entry.model = model.clone();
        entry.received_s = received_s;

        // Ball.
        let age = f64::from(model.ball_age_s);
        let t_obs = received_s - age;
        // The same sighting sent again: same position, same observation time (up to jitter).
        let repeat = entry
            .last_ball
            .is_some_and(|(p, t)| p == model.ball && (t_obs - t).abs() < REPEAT_TOLERANCE_S);
        if !model.fallen && !repeat && (0.0..=self.config.max_ball_measurement_age_s).contains(&age)
        {
            let dist = f64::from(model.pose.position().distance_to(&model.ball));
            let sigma = self.config.ball_sigma_base_mm + self.config.ball_sigma_per_mm * dist;
            if self.ball.update(model.ball, sigma, t_obs) != BallUpdate::Rejected {
                self.ball_updates += 1;
            }
            entry.last_ball = Some((model.ball, t_obs));
        } else if !repeat {
            entry.last_ball = None;
        }

        // Robot clock offset (reset when the robot's clock jumped back: a reboot).
        let rx_ms = received_s * 1000.0;
        let newest = model.obstacles.iter().map(|o| o.last_seen_ms).max();
        if let Some(newest) = newest {
            if newest.saturating_add(10_000) < entry.max_last_seen_ms {
                entry.clock_offset_ms = None;
            }
            entry.max_last_seen_ms = newest;
            let off = rx_ms - f64::from(newest);
            entry.clock_offset_ms = Some(entry.clock_offset_ms.map_or(off, |o: f64| o.min(off)));
        }
        let offset = entry.clock_offset_ms;

        // Obstacles.
        let own: Vec<FieldPoint> = self
            .robots
            .values()
            .map(|r| r.model.pose.position())
            .collect();
        // Expired tracks go before association: a sighting never revives one.
        let timeout = self.config.obstacle_timeout_s;
        self.tracks
            .retain(|t| received_s - t.last_seen_s <= timeout);
        let mut taken = vec![false; self.tracks.len()];
        for o in &model.obstacles {
            let Some(offset) = offset else { break };
            let t_obs = (f64::from(o.last_seen_ms) + offset) / 1000.0;
            if received_s - t_obs > self.config.obstacle_timeout_s {
                continue;
            }
            if own
                .iter()
                .any(|p| f64::from(p.distance_to(&o.center)) < self.config.own_robot_exclusion_mm)
            {
                continue;
            }
            let (ox, oy) = (f64::from(o.center.x_mm), f64::from(o.center.y_mm));
            let nearest = self
                .tracks
                .iter()
                .enumerate()
                .filter(|(i, _)| !taken.get(*i).copied().unwrap_or(true))
                .map(|(i, t)| (i, (t.x - ox).hypot(t.y - oy)))
                .filter(|(_, d)| *d < self.config.obstacle_gate_mm)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match nearest {
                Some((i, _)) => {
                    if let Some(slot) = taken.get_mut(i) {
                        *slot = true;
                    }
                    if let Some(t) = self.tracks.get_mut(i)
                        && t_obs > t.last_seen_s
                    {
                        let a = self.config.obstacle_smoothing;
                        t.x += a * (ox - t.x);
                        t.y += a * (oy - t.y);
                        t.last_seen_s = t_obs;
                        t.observations += 1;
                        if o.kind.specificity() >= t.kind.specificity() {
                            t.kind = o.kind;
                        }
                    }
                }
                None => {
                    let id = self.next_track_id;
                    self.next_track_id = self.next_track_id.wrapping_add(1);
                    self.tracks.push(Track {
                        id,
                        kind: o.kind,
                        x: ox,
                        y: oy,
                        last_seen_s: t_obs,
                        observations: 1,
                    })
                }
            }
        }
        true
    }

    /// The fused model at `now_s` (the `nao/world_model` message; the header is left for the
    /// publisher to stamp).
    pub fn snapshot(&self, now_s: f64) -> NaoWorldModel {
        let c = &self.config;
        let robots: Vec<TeamRobot> = self
            .robots
            .iter()
            .map(|(n, r)| TeamRobot {
                player_number: *n,
                role: r.model.role,
                pose: r.model.pose,
                fallen: r.model.fallen,
                age_s: now_s - r.received_s,
            })
            .collect();
        let ball = self.ball.last_observation_s().and_then(|t_last| {
            let age = (now_s - t_last).max(0.0);
            if age > c.ball_forget_after_s {
                return None;
            }
            let (position, velocity, sigma) = self
                .ball
                .estimate_at(now_s.min(t_last + c.ball_max_prediction_s))?;
            Some(Ball {
                position,
                velocity,
                age_s: age,
                sigma_mm: sigma,
                confidence: (-age / c.ball_confidence_tau_s).exp() / (1.0 + sigma / 500.0),
            })
        });
        let own: Vec<FieldPoint> = robots.iter().map(|r| r.pose.position()).collect();
        let obstacles = self
            .tracks
            .iter()
            .filter(|t| now_s - t.last_seen_s <= c.obstacle_timeout_s)
            .filter(|t| {
                let p = FieldPoint::new(t.x as f32, t.y as f32);
                own.iter()
                    .all(|o| f64::from(o.distance_to(&p)) >= c.own_robot_exclusion_mm)
            })
            .map(|t| TrackedObstacle {
                id: t.id,
                kind: t.kind,
                center: FieldPoint::new(t.x as f32, t.y as f32),
                age_s: (now_s - t.last_seen_s).max(0.0),
                observations: t.observations,
            })
            .collect();
        let controlled = robots
            .iter()
            .find(|r| r.player_number == c.controlled_player);
        let autonomous = robots
            .iter()
            .find(|r| r.player_number != c.controlled_player);
        let autonomous_is_striker = match (controlled, autonomous, &ball) {
            (Some(ctl), Some(aut), Some(b)) => Some(
                aut.pose.position().distance_to(&b.position)
                    < ctl.pose.position().distance_to(&b.position),
            ),
            _ => None,
        };
        let freshness =
            controlled.map_or(0.0, |r| (1.0 - r.age_s / c.robot_timeout_s).clamp(0.0, 1.0));
        let confidence = ball.as_ref().map_or(0.0, |b| b.confidence) * freshness;
        let mut model = NaoWorldModel {
            robots,
            obstacles,
            striker_known: autonomous_is_striker.is_some(),
            autonomous_is_striker: autonomous_is_striker.unwrap_or(false),
            confidence,
            ..Default::default()
        };
        if let Some(b) = ball {
            model.ball_known = true;
            model.ball = b.position;
            model.ball_velocity = b.velocity;
            model.ball_age_s = b.age_s;
            model.ball_sigma_mm = b.sigma_mm;
            model.ball_confidence = b.confidence;
        }
        model
    }
}

#[cfg(test)]
mod tests;
