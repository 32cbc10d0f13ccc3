use super::*;
use crate::types::{FieldPose, NaoObstacle, PlayerRole, WhistleState};

/// The snapshot's ball, when known: position, velocity, age (s), confidence.
struct SeenBall {
    position: FieldPoint,
    velocity: FieldPoint,
    age_s: f64,
    confidence: f64,
}

fn ball(m: &NaoWorldModel) -> Option<SeenBall> {
    m.ball_known.then_some(SeenBall {
        position: m.ball,
        velocity: m.ball_velocity,
        age_s: m.ball_age_s,
        confidence: m.ball_confidence,
    })
}

/// Deterministic Gaussian noise for tests (SplitMix64 + Box-Muller).
struct Noise(u64);
impl Noise {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn gauss(&mut self, sigma: f64) -> f64 {
        let u1 = self.uniform().max(1e-12);
        let u2 = self.uniform();
        sigma * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

fn local(player: u8, pose: (f32, f32), ball: (f32, f32), ball_age_s: f32) -> NaoLocalModel {
    NaoLocalModel {
        header: Default::default(),
        player_number: player,
        team_number: 5,
        fallen: false,
        pose: FieldPose {
            x_mm: pose.0,
            y_mm: pose.1,
            theta_rad: 0.0,
        },
        ball_age_s,
        ball: FieldPoint::new(ball.0, ball.1),
        role: if player == 2 {
            PlayerRole::Controlled
        } else {
            PlayerRole::Autonomous
        },
        obstacles_seen: 0,
        obstacles: vec![],
        message_budget: 1200,
        secs_remaining: 90,
        arm_contact: [false; 2],
        arm_push_direction: [0; 2],
        arm_last_contact_ms: [0; 2],
        time_since_whistle_ms: 0,
        whistle: WhistleState::NotDetected,
        team_ball: FieldPoint::default(),
        team_ball_velocity: FieldPoint::default(),
        battery: 1.0,
        cpu_temperature_c: 40.0,
        referee_gesture: 0,
    }
}

#[test]
fn kalman_converges_on_a_moving_ball_with_noise() {
    let mut noise = Noise(7);
    let mut f = BallFilter::new(FusionConfig::default().ball_accel_sigma_mm_s2, 16.0, 2.0);
    let (v_x, v_y) = (600.0, -250.0); // mm/s
    let truth = |t: f64| (-2000.0 + v_x * t, 1000.0 + v_y * t);
    let sigma = 60.0; // mm per axis: ~85 mm radial rms for a raw measurement
    let (mut pos_sq, mut vel_sq, mut raw_sq, mut n) = (0.0, 0.0, 0.0, 0.0);
    for i in 0..=100 {
        let t = f64::from(i) * 0.1;
        let (x, y) = truth(t);
        let (zx, zy) = (x + noise.gauss(sigma), y + noise.gauss(sigma));
        let z = FieldPoint::new(zx as f32, zy as f32);
        assert_ne!(f.update(z, sigma, t), BallUpdate::Rejected);
        if i >= 30 {
            let (p, v, _) = f.estimate_at(t).unwrap();
            pos_sq += (f64::from(p.x_mm) - x).powi(2) + (f64::from(p.y_mm) - y).powi(2);
            vel_sq += (f64::from(v.x_mm) - v_x).powi(2) + (f64::from(v.y_mm) - v_y).powi(2);
            raw_sq += (zx - x).powi(2) + (zy - y).powi(2);
            n += 1.0;
        }
    }
    let (pos_rms, vel_rms, raw_rms) = (
        (pos_sq / n).sqrt(),
        (vel_sq / n).sqrt(),
        (raw_sq / n).sqrt(),
    );
    eprintln!(
        "after 3 s: position rms {pos_rms:.1} mm (raw {raw_rms:.1} mm), velocity rms {vel_rms:.1} mm/s"
    );
    assert!(
        pos_rms < 0.7 * raw_rms,
        "filtered {pos_rms} vs raw {raw_rms}"
    );
    assert!(vel_rms < 150.0, "velocity rms {vel_rms} mm/s");
    // Prediction 1 s ahead follows the motion and is less certain.
    let (_, _, s0) = f.estimate_at(10.0).unwrap();
    let (p1, _, s1) = f.estimate_at(11.0).unwrap();
    let (x1, y1) = truth(11.0);
    assert!((f64::from(p1.x_mm) - x1).hypot(f64::from(p1.y_mm) - y1) < 250.0);
    assert!(s1 > s0, "uncertainty grows when predicting");
}

#[test]
fn kicked_ball_reinitialises_after_three_rejections() {
    let mut f = BallFilter::new(1000.0, 16.0, 2.0);
    for i in 0..20 {
        f.update(FieldPoint::new(0.0, 0.0), 40.0, f64::from(i) * 0.1);
    }
    let jump = FieldPoint::new(3000.0, 0.0);
    assert_eq!(f.update(jump, 40.0, 2.0), BallUpdate::Rejected);
    assert_eq!(f.update(jump, 40.0, 2.1), BallUpdate::Rejected);
    assert_eq!(f.update(jump, 40.0, 2.2), BallUpdate::Rejected);
    assert_eq!(f.update(jump, 40.0, 2.3), BallUpdate::Initialised);
    assert_eq!(f.estimate_at(2.3).unwrap().0, jump);
}

#[test]
fn repeated_stale_ball_reports_are_not_fused_again() {
    let mut w = WorldModelFusion::new(FusionConfig::default());
    // Seen fresh at t = 1.0 at (1000, 0).
    w.ingest(&local(2, (0.0, 0.0), (1000.0, 0.0), 0.0), 1.0);
    assert_eq!(w.ball_updates(), 1);
    // Then lost: the same position with a growing age, every 100 ms for 3 s.
    for i in 1..=30 {
        let age = i as f32 * 0.1;
        w.ingest(
            &local(2, (0.0, 0.0), (1000.0, 0.0), age),
            1.0 + f64::from(i) * 0.1,
        );
    }
    assert_eq!(
        w.ball_updates(),
        1,
        "repeats of one sighting are one observation"
    );
    let m = w.snapshot(4.0);
    let b = ball(&m).unwrap();
    assert!((b.age_s - 3.0).abs() < 1e-6, "ball age {}", b.age_s);
    assert!(
        b.confidence < 0.25,
        "old ball has low confidence: {}",
        b.confidence
    );
    // Forgotten after 10 s.
    assert!(!w.snapshot(11.5).ball_known);
}

#[test]
fn delayed_observation_is_dated_by_its_age() {
    let cfg = FusionConfig::default();
    let mut w = WorldModelFusion::new(cfg);
    // A ball rolling at +500 mm/s along x, seen by the robot at t - 0.4 s each time
    // (ball age 0.4 s in every packet): the fused estimate at t is the current position.
    for i in 0..40 {
        let t = f64::from(i) * 0.1;
        let seen_at = t - 0.4;
        let x = 500.0 * seen_at;
        w.ingest(&local(2, (0.0, 500.0), (x as f32, 0.0), 0.4), t);
    }
    let t = 3.9;
    let b = ball(&w.snapshot(t)).unwrap();
    assert!(
        (f64::from(b.position.x_mm) - 500.0 * t).abs() < 60.0,
        "x {}",
        b.position.x_mm
    );
    assert!((f64::from(b.velocity.x_mm) - 500.0).abs() < 60.0);
    assert!((b.age_s - 0.4).abs() < 1e-6);
    // Too old observations (> 1 s) are not used at all.
    let mut w = WorldModelFusion::new(FusionConfig::default());
    w.ingest(&local(2, (0.0, 0.0), (100.0, 0.0), 1.5), 5.0);
    assert!(!w.snapshot(5.0).ball_known);
}

#[test]
fn teammate_ball_is_fused_and_fallen_robot_is_ignored() {
    let mut w = WorldModelFusion::new(FusionConfig::default());
    // The controlled robot is down and reports a wrong ball; the teammate sees it.
    let mut down = local(2, (-1000.0, 0.0), (-4000.0, 2000.0), 0.0);
    down.fallen = true;
    for i in 0..10 {
        let t = f64::from(i) * 0.1;
        w.ingest(&down, t);
        w.ingest(&local(1, (1500.0, 0.0), (2000.0, 300.0), 0.0), t);
    }
    let m = w.snapshot(1.0);
    let b = ball(&m).unwrap();
    assert!(b.position.distance_to(&FieldPoint::new(2000.0, 300.0)) < 30.0);
    // Another team's robot is ignored when our team number is configured.
    let mut ours = WorldModelFusion::new(FusionConfig {
        team_number: Some(5),
        ..FusionConfig::default()
    });
    let mut stranger = local(3, (0.0, 0.0), (0.0, 0.0), 0.0);
    stranger.team_number = 6;
    assert!(!ours.ingest(&stranger, 0.0));
    assert!(ours.ingest(&local(2, (0.0, 0.0), (0.0, 0.0), 0.0), 0.0));
    assert_eq!(ours.snapshot(0.0).robots.len(), 1);
    assert!(m.striker_known && m.autonomous_is_striker);
    assert_eq!(m.robots.len(), 2);
    assert!(
        m.confidence > 0.5 && m.confidence <= 1.0,
        "{} {:?}",
        m.confidence,
        m
    );
    // The controlled robot silent for > 2 s: confidence drops to 0.
    assert_eq!(w.snapshot(3.5).confidence, 0.0);
}

#[test]
fn obstacles_are_associated_aged_and_dropped() {
    let mut w = WorldModelFusion::new(FusionConfig::default());
    // Robot clock starts at 50 s when our clock is at 0.
    let robot_ms = |t: f64| (50_000.0 + t * 1000.0) as u32;
    for i in 0..10 {
        let t = f64::from(i) * 0.1;
        let mut m = local(2, (0.0, 0.0), (500.0, 0.0), 0.0);
        let noise = if i % 2 == 0 { 40.0 } else { -40.0 };
        m.obstacles = vec![
            // An opponent at (2000, 1000), first seen as "some robot".
            NaoObstacle {
                kind: if i < 3 {
                    ObstacleKind::SomeRobot
                } else {
                    ObstacleKind::Opponent
                },
                center: FieldPoint::new(2000.0 + noise, 1000.0),
                last_seen_ms: robot_ms(t),
            },
            // A second opponent far from the first.
            NaoObstacle {
                kind: ObstacleKind::Opponent,
                center: FieldPoint::new(-2500.0, -1500.0 + noise),
                last_seen_ms: robot_ms(t),
            },
            // Our teammate (robot 1 stands there): not an obstacle.
            NaoObstacle {
                kind: ObstacleKind::Teammate,
                center: FieldPoint::new(1000.0, -2000.0),
                last_seen_ms: robot_ms(t),
            },
        ];
        m.obstacles_seen = 3;
        w.ingest(&m, t);
        w.ingest(&local(1, (1050.0, -2000.0), (500.0, 0.0), 0.0), t);
    }
    let s = w.snapshot(0.9);
    assert_eq!(s.obstacles.len(), 2, "{:?}", s.obstacles);
    let first = s.obstacles.iter().find(|o| o.center.x_mm > 0.0).unwrap();
    assert_eq!(first.kind, ObstacleKind::Opponent);
    assert_eq!(first.observations, 10);
    assert!(first.center.distance_to(&FieldPoint::new(2000.0, 1000.0)) < 40.0);
    assert!(first.age_s < 0.05);
    // The second obstacle disappears from view: it keeps its last-seen time and ages.
    for i in 10..50 {
        let t = f64::from(i) * 0.1;
        let mut m = local(2, (0.0, 0.0), (500.0, 0.0), 0.0);
        m.obstacles = vec![NaoObstacle {
            kind: ObstacleKind::Opponent,
            center: FieldPoint::new(2000.0, 1000.0),
            last_seen_ms: robot_ms(t),
        }];
        m.obstacles_seen = 1;
        w.ingest(&m, t);
    }
    let s = w.snapshot(4.9);
    assert_eq!(s.obstacles.len(), 1, "the unseen one is dropped after 3 s");
    assert_eq!(s.obstacles[0].id, first.id, "a track keeps its identity");
    // The robot goes silent for 10 s with its clock stopped (its software stalled): once it
    // is back, its sightings are fresh again (the clock offset is estimated anew), and the
    // track that expired meanwhile comes back under a new identity.
    let frozen = robot_ms(4.9);
    for i in 0..3 {
        let t = 15.0 + f64::from(i) * 0.1;
        let mut m = local(2, (0.0, 0.0), (500.0, 0.0), 0.0);
        m.obstacles = vec![NaoObstacle {
            kind: ObstacleKind::Opponent,
            center: FieldPoint::new(2000.0, 1000.0),
            last_seen_ms: frozen + 100 * (i + 1),
        }];
        m.obstacles_seen = 1;
        w.ingest(&m, t);
    }
    let s = w.snapshot(15.2);
    assert_eq!(s.obstacles.len(), 1, "{s:?}");
    assert!(s.obstacles[0].age_s < 0.05, "{s:?}");
    assert_ne!(s.obstacles[0].id, first.id);
    // Aged in between: at 2.9 s the second one was 2 s old.
    let mut w2 = WorldModelFusion::new(FusionConfig::default());
    let mut m = local(2, (0.0, 0.0), (0.0, 0.0), 0.0);
    m.obstacles = vec![NaoObstacle {
        kind: ObstacleKind::Opponent,
        center: FieldPoint::new(3000.0, 0.0),
        last_seen_ms: 10_000,
    }];
    m.obstacles_seen = 1;
    w2.ingest(&m, 100.0);
    let s = w2.snapshot(102.0);
    assert!((s.obstacles[0].age_s - 2.0).abs() < 1e-6);
}
