//! Tests of the tracking handler and its messages on simulated frames.

use super::*;
use crate::hsv::rgb_to_hsv;
use camera::scenario::{BALL_DIAMETER_M, BALL_RED, CameraPose, Scenario, ScenarioSim};
use camera::sim::SensorModel;
use camera::{RgbdDriver, convert};

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

/// The game's ball (hue 52 deg, saturation 0.85, 7 cm; rendered RGB (230, 203, 34)) as the
/// tracker is told to look for it in `launch/eyes_game.toml`.
fn yellow_target() -> Target {
    Target {
        hue_deg: 51.7,
        saturation: 0.85,
        diameter_m: 0.07,
    }
}

#[test]
fn the_game_yellow_ball_is_tracked_from_half_a_metre_to_1_2_m_with_the_head_moving() {
    use camera::sim::look_at;
    use camera::world::{WorldSim, hsv_to_rgb};
    use interfaces::msg::tracking::SimBall;
    use nalgebra::{Point3, Vector3};
    // The tracker's own colour conversion agrees with the flags' hue and saturation.
    let [r, g, b] = hsv_to_rgb(52.0, 0.85, camera::world::BALL_VALUE);
    let (h, s, _) = rgb_to_hsv(r, g, b);
    assert!(
        (h - 51.7).abs() < 0.05 && (s - 0.85).abs() < 0.005,
        "{h} {s}"
    );
    // Loki's head camera (neck pitched down) and the ball on the table or held up.
    let eye = Point3::new(0.074, 0.0, 1.473);
    let places = [
        ([0.5, 0.0, 1.2], true),
        ([0.45, 0.1, 0.785], false),
        ([0.75, 0.05, 0.785], false),
        ([1.0, -0.25, 0.785], false),
    ];
    for (centre, held) in places {
        let mut sim = WorldSim::new(
            look_at(eye, Point3::from(centre), Vector3::z()),
            SensorModel::default(),
            3,
        );
        sim.set_ball(SimBall {
            present: true,
            centre_world_m: centre,
            diameter_m: 0.07,
            hue_deg: 52.0,
            saturation: 0.85,
            held,
            ..Default::default()
        });
        let mut h = Handler::new(TrackerConfig::default(), Some(yellow_target())).unwrap();
        let mut worst: f64 = 0.0;
        let mut distance = 0.0;
        for i in 0..30 {
            // The gaze sweeps 12 cm around the ball at about 1 rad/s.
            let a = i as f64 * 0.2;
            let target = Point3::from(centre) + Vector3::new(0.0, 0.06 * a.sin(), 0.04 * a.cos());
            sim.set_world_from_optical(look_at(eye, target, Vector3::z()));
            let f = sim.next_frame(1000.0 + i as f64 / 30.0).unwrap().unwrap();
            let truth = sim.truth().unwrap();
            assert!(truth.in_view);
            distance = Vector3::from(truth.centre_camera_m).norm();
            let mut m = convert::into_msg(f, "head_rgbd_optical_frame");
            m.header.seq = i;
            let (track, _) = h.process(&m).unwrap();
            assert!(
                track.found && track.has_centre_m,
                "{centre:?} frame {i}: {track:?}"
            );
            assert_eq!(track.state, BallTrackState::Tracking);
            let err = (0..3)
                .map(|k| (track.centre_m[k] - truth.centre_camera_m[k]).powi(2))
                .sum::<f64>()
                .sqrt();
            worst = worst.max(err);
        }
        assert!(
            worst < 0.01,
            "{centre:?} ({distance:.2} m): error up to {:.1} mm",
            worst * 1e3
        );
        assert!((0.45..=1.25).contains(&distance), "{distance}");
        eprintln!(
            "yellow ball at {centre:?}{} {distance:.2} m away, head moving: 3D error max {:.2} mm",
            if held { " (held)" } else { "" },
            worst * 1e3
        );
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

/// [`red_target`] as the Executive sends it (unstamped).
fn red_target_msg() -> BallTarget {
    let t = red_target();
    BallTarget {
        active: true,
        hue_deg: t.hue_deg,
        saturation: t.saturation,
        diameter_m: t.diameter_m,
        ..Default::default()
    }
}

#[test]
fn target_messages_set_and_clear_the_target() {
    let mut h = Handler::new(TrackerConfig::default(), None).unwrap();
    let frames = sim_frames(Scenario::Still, 2);
    let (track, _) = h.process(&frames[0].0).unwrap();
    assert_eq!(track.state, BallTrackState::Waiting);
    assert!(!track.found);
    let mut msg = red_target_msg();
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

#[test]
fn a_target_applies_from_the_frames_captured_after_it_was_given() {
    // Three frames 1/30 s apart; a target stamped between the first and the second arrives
    // before the first is processed (a replay, or a tracker behind): the first frame is
    // still tracked without it, the second with it.
    let frames = sim_frames(Scenario::Still, 6);
    let stamp = |i: usize| frames[i].0.header.stamp_ns;
    let mut target = red_target_msg();
    target.header.stamp_ns = stamp(0) + 1;
    let mut h = Handler::new(TrackerConfig::default(), None).unwrap();
    h.set_target(&target).unwrap();
    let (track, _) = h.process(&frames[0].0).unwrap();
    assert_eq!(
        (track.state, track.found),
        (BallTrackState::Waiting, false),
        "a frame captured before the target was given"
    );
    let (track, events) = h.process(&frames[1].0).unwrap();
    assert!(track.found, "the frame after the target's stamp");
    assert_eq!(events[0].kind, BallEventKind::Detected);

    // A clear stamped between frames 2 and 3: frame 2 is still tracked.
    let clear = BallTarget {
        header: Header {
            stamp_ns: stamp(2) + 1,
            ..Default::default()
        },
        ..Default::default()
    };
    h.set_target(&clear).unwrap();
    let (track, _) = h.process(&frames[2].0).unwrap();
    assert_eq!((track.state, track.found), (BallTrackState::Tracking, true));
    let (track, _) = h.process(&frames[3].0).unwrap();
    assert_eq!(track.state, BallTrackState::Waiting);
    assert_eq!(h.targets_ahead_of_frames(), 0);

    // A target stamped far ahead of the frames (another clock) applies at once, counted.
    target.header.stamp_ns = stamp(4) + TARGET_LEAD.as_nanos() as i64 + 1_000_000;
    h.set_target(&target).unwrap();
    let (track, _) = h.process(&frames[4].0).unwrap();
    assert!(track.found, "{track:?}");
    assert_eq!(h.targets_ahead_of_frames(), 1);

    // A bad stamped target is refused at once and changes nothing later.
    let mut bad = target.clone();
    bad.saturation = 2.0;
    assert!(h.set_target(&bad).is_err());
    let (track, _) = h.process(&frames[5].0).unwrap();
    assert!(track.found);
}
