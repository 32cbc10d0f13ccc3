//! The tracker on sequences rendered by the `rgbd` sim: accuracy, motion, leaving the view,
//! decoys, garbage input.
#![allow(clippy::expect_used)] // a test fails by panicking
#![allow(clippy::unwrap_used)] // tests may unwrap (helpers outside #[test] included)

use ball_tracker::hsv::rgb_to_hsv;
use ball_tracker::{BallTracker, Target, TrackEvent, TrackOutput, TrackState, TrackerConfig};
use camera::sim::{HandArm, Scene, SensorModel, SimCamera, SimRenderer, Sphere, look_at};
use camera::{Frame, Intrinsics};
use nalgebra::{Point3, Vector3};

const RED: [u8; 3] = [220, 40, 30];
const DT: f64 = 1.0 / 30.0;

fn camera() -> SimCamera {
    // The robot's head 1.3 m up, looking down at the table.
    SimCamera::vga(look_at(
        Point3::new(0.0, 0.0, 1.3),
        Point3::new(1.0, 0.0, 0.9),
        Vector3::z(),
    ))
}

fn target(colour: [u8; 3], diameter_m: f64) -> Target {
    let (h, s, _) = rgb_to_hsv(colour[0], colour[1], colour[2]);
    Target {
        hue_deg: h,
        saturation: s,
        diameter_m,
    }
}

fn tracker() -> BallTracker {
    let mut t = BallTracker::new(TrackerConfig::default());
    t.set_target(Some(target(RED, 0.1))).unwrap();
    t
}

fn ball(centre: Point3<f64>) -> Sphere {
    Sphere::new(centre, 0.1, RED)
}

/// Ball centre in the camera optical frame.
fn truth_c(cam: &SimCamera, p_w: &Point3<f64>) -> Vector3<f64> {
    cam.world_from_camera.inverse_transform_point(p_w).coords
}

fn err_m(out: &TrackOutput, truth: &Vector3<f64>) -> f64 {
    let c = out.centre_m.expect("a 3D centre");
    (Vector3::new(c[0], c[1], c[2]) - truth).norm()
}

#[test]
fn static_ball_centre_within_1cm_at_1m() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 11);
    let mut t = tracker();
    let centre = Point3::new(0.9, 0.1, 0.95);
    let truth = truth_c(&cam, &centre);
    assert!(
        (truth.norm() - 1.0).abs() < 0.05,
        "ball at {} m",
        truth.norm()
    );
    let scene = Scene {
        ball: Some(ball(centre)),
        ..Scene::default()
    };
    for i in 0..15 {
        let now = i as f64 * DT;
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}");
        if i == 0 {
            assert_eq!(out.events, vec![TrackEvent::BallDetected]);
        } else {
            assert!(out.events.is_empty(), "frame {i}: {:?}", out.events);
        }
        let e = err_m(&out, &truth);
        eprintln!(
            "static frame {i}: error {:.2} mm, diameter {:?} m, confidence {:.2}",
            e * 1e3,
            out.measured_diameter_m,
            out.confidence
        );
        assert!(e < 0.01, "frame {i}: centre error {:.1} mm", e * 1000.0);
        let d = out.measured_diameter_m.unwrap();
        assert!((d - 0.1).abs() < 0.02, "diameter {d}");
        assert!(
            out.confidence > 0.7 && out.confidence <= 1.0,
            "{}",
            out.confidence
        );
        let [u, v] = cam.project_world(&centre).unwrap();
        let [cu, cv] = out.centre_px.unwrap();
        assert!((cu - u).hypot(cv - v) < 2.0, "pixel centre off");
        let w = out.window.unwrap();
        assert!(
            (40..=75).contains(&w.width) && (40..=75).contains(&w.height),
            "{w:?}"
        );
    }
}

#[test]
fn frames_stamped_nanoseconds_apart_do_not_throw_the_track_off_a_still_ball() {
    // The game's camera stamps a frame with the joint state it was rendered from; when the joint
    // states come slower than the frames (a busy machine), frames a few nanoseconds apart follow
    // each other. At epoch-scale stamps a few ns are below an f64's resolution, so the frames'
    // times in seconds are equal or one ulp (about 0.24 us) apart: the pixel jitter between two
    // such frames is no speed, and the still ball stays found in every frame. The stamps below
    // are chosen so that each pair lands one ulp apart, as the header's `stamp_s()` converts them.
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 5);
    let mut t = tracker();
    let scene = Scene {
        ball: Some(ball(Point3::new(0.9, 0.1, 0.95))),
        ..Scene::default()
    };
    let base_ns: i64 = 1_795_470_140_000_000_000;
    for i in 0..60 {
        // Two frames per joint state: 33 ms apart, then 2 ns later.
        let joint_ns = (base_ns + (i / 2) * 33_333_333) / 256 * 256 + 127;
        let stamp_ns = joint_ns + (i % 2) * 2;
        let now = interfaces::Header {
            stamp_ns,
            ..Default::default()
        }
        .stamp_s();
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}");
        assert!(
            out.window.is_some(),
            "frame {i}: the still ball was not found"
        );
    }
}

/// Position on an ellipse (world y-z plane, 0.3 x 0.18 m) around (0.95, 0, 1.0), at about
/// `speed` m/s.
fn circle(t_s: f64, speed: f64) -> (Point3<f64>, Vector3<f64>) {
    let rad = 0.3;
    let w = speed / rad;
    let a = w * t_s;
    (
        Point3::new(0.95, rad * a.cos(), 1.0 + rad * a.sin() * 0.6),
        Vector3::new(0.0, -rad * w * a.sin(), rad * w * a.cos() * 0.6),
    )
}

fn run_moving(sensor: SensorModel, seed: u64, speed: f64) -> (f64, f64) {
    let cam = camera();
    let mut r = SimRenderer::new(cam, sensor, seed);
    let mut t = tracker();
    let mut scene = Scene::default();
    let (mut sum, mut max) = (0.0, 0.0f64);
    let n = 90;
    for i in 0..n {
        let now = i as f64 * DT;
        let (p, v) = circle(now, speed);
        let mut b = ball(p);
        b.velocity_w_mps = v;
        scene.ball = Some(b);
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}: {out:?}");
        assert!(
            !out.events.contains(&TrackEvent::BallLost),
            "frame {i}: {:?}",
            out.events
        );
        let e = err_m(&out, &truth_c(&cam, &p));
        sum += e;
        max = max.max(e);
    }
    (sum / n as f64, max)
}

#[test]
fn moving_ball_1mps_tracked_without_loss() {
    let (mean, max) = run_moving(SensorModel::default(), 5, 1.0);
    eprintln!("1 m/s: mean {:.2} mm, max {:.2} mm", mean * 1e3, max * 1e3);
    assert!(mean < 0.005, "mean error {:.1} mm", mean * 1000.0);
    assert!(max < 0.01, "max error {:.1} mm", max * 1000.0);
}

/// A loaded machine drops camera frames: right after the detection (no velocity known yet) a
/// gap of 200 ms, then gaps of 2 to 4 frames. The ball, moving at 1 m/s, is found in every frame
/// that arrives.
#[test]
fn frame_gaps_of_a_loaded_machine_do_not_lose_a_moving_ball() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 7);
    let mut t = tracker();
    let mut scene = Scene::default();
    let mut i = 0;
    let mut gaps = [15, 2, 3, 4, 1, 1, 3, 2, 4, 1, 2, 3].iter().cycle();
    let mut frames = 0;
    while i < 150 {
        let now = i as f64 * DT;
        let (p, v) = circle(now, 1.0);
        let mut b = ball(p);
        b.velocity_w_mps = v;
        scene.ball = Some(b);
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}: {out:?}");
        assert!(out.window.is_some(), "frame {i}: not found: {out:?}");
        assert!(err_m(&out, &truth_c(&cam, &p)) < 0.02, "frame {i}: {out:?}");
        frames += 1;
        i += gaps.next().unwrap();
    }
    assert!(frames > 40);
}

#[test]
fn moving_ball_with_motion_blur_tracked_without_loss() {
    let sensor = SensorModel {
        motion_blur_samples: 5,
        exposure_s: 0.015,
        ..SensorModel::default()
    };
    let (mean, max) = run_moving(sensor, 6, 1.0);
    eprintln!(
        "1 m/s blurred: mean {:.2} mm, max {:.2} mm",
        mean * 1e3,
        max * 1e3
    );
    assert!(mean < 0.006, "mean error {:.1} mm", mean * 1000.0);
    assert!(max < 0.015, "max error {:.1} mm", max * 1000.0);
}

#[test]
fn fast_ball_2_5mps_tracked_without_loss() {
    // Up to 2.5 m/s at 30 Hz: 8 cm (about 45 px, almost a ball diameter) between frames.
    let (mean, max) = run_moving(SensorModel::default(), 8, 2.5);
    eprintln!(
        "2.5 m/s: mean {:.2} mm, max {:.2} mm",
        mean * 1e3,
        max * 1e3
    );
    assert!(mean < 0.005, "mean error {:.1} mm", mean * 1000.0);
    assert!(max < 0.015, "max error {:.1} mm", max * 1000.0);
}

#[test]
fn ball_leaving_view_gives_out_of_view_then_lost_then_redetected() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 3);
    let mut t = tracker();
    let mut scene = Scene::default();
    let mut events: Vec<(usize, TrackEvent)> = Vec::new();
    let mut states = Vec::new();
    // 0-0.3 s still; then 1 m/s towards the robot's right (world -y) until 1.2 s, out of view
    // until 2.0 s, then back at 1 m/s and still again from 2.9 s.
    let y_at = |t_s: f64| -> f64 {
        if t_s < 0.3 {
            0.2
        } else if t_s < 1.2 {
            0.2 - (t_s - 0.3)
        } else if t_s < 2.0 {
            -0.7
        } else if t_s < 2.8 {
            -0.7 + (t_s - 2.0)
        } else {
            0.1
        }
    };
    let n = 110;
    let mut last = None;
    for i in 0..n {
        let now = i as f64 * DT;
        let p = Point3::new(0.9, y_at(now), 0.95);
        scene.ball = Some(ball(p));
        let out = t.process(&r.render(&scene, now), now).unwrap();
        for e in &out.events {
            events.push((i, *e));
        }
        states.push(out.state);
        last = Some((out, p));
    }
    eprintln!("events {events:?}");
    let kinds: Vec<TrackEvent> = events.iter().map(|e| e.1).collect();
    assert_eq!(
        kinds,
        vec![
            TrackEvent::BallDetected,
            TrackEvent::BallOutOfView,
            TrackEvent::BallLost,
            TrackEvent::BallDetected
        ],
        "{events:?}"
    );
    // Out of view is reported while the ball leaves (between 0.9 s and 1.3 s), lost after.
    let t_oov = events[1].0 as f64 * DT;
    assert!((0.8..1.4).contains(&t_oov), "out of view at {t_oov} s");
    assert!(events[2].0 > events[1].0);
    let (out, p) = last.unwrap();
    assert_eq!(out.state, TrackState::Tracking);
    assert!(err_m(&out, &truth_c(&cam, &p)) < 0.01);
    assert!(states.contains(&TrackState::Detecting));
}

#[test]
fn same_coloured_object_of_wrong_size_is_not_the_ball() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 9);
    let mut t = tracker();
    let big = Sphere::new(Point3::new(1.1, 0.25, 1.0), 0.25, RED);
    let small = Sphere::new(Point3::new(0.85, -0.25, 0.8), 0.035, RED);
    let mut scene = Scene {
        decoys: vec![big, small],
        ..Scene::default()
    };
    for i in 0..20 {
        let now = i as f64 * DT;
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Detecting, "frame {i}: {out:?}");
        assert!(out.centre_m.is_none());
    }
    // With the real ball added, the ball is found, not the decoys.
    let centre = Point3::new(0.9, -0.05, 1.0);
    scene.ball = Some(ball(centre));
    for i in 20..40 {
        let now = i as f64 * DT;
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}");
        assert!(err_m(&out, &truth_c(&cam, &centre)) < 0.01, "frame {i}");
    }
}

#[test]
fn ball_held_in_hand_is_tracked() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 4);
    let mut t = tracker();
    let mut scene = Scene::default();
    for i in 0..30 {
        let now = i as f64 * DT;
        let centre = Point3::new(0.9, 0.15 - 0.3 * now, 1.0);
        scene.ball = Some(ball(centre));
        scene.hand = Some(HandArm {
            elbow_w: centre + Vector3::new(0.2, 0.3, -0.15),
            hand_w: centre + Vector3::new(0.03, 0.07, -0.05),
            forearm_radius_m: 0.035,
            hand_radius_m: 0.045,
            skin: [225, 175, 145],
        });
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}");
        assert!(err_m(&out, &truth_c(&cam, &centre)) < 0.015, "frame {i}");
    }
}

#[test]
fn detection_times_out_to_waiting() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 1);
    let mut t = BallTracker::new(TrackerConfig {
        detect_timeout_s: 1.0,
        ..TrackerConfig::default()
    });
    let scene = Scene::default();
    let out = t.process(&r.render(&scene, 0.0), 0.0).unwrap();
    assert_eq!(out.state, TrackState::Waiting, "no target yet");
    t.set_target(Some(target(RED, 0.1))).unwrap();
    let mut timed_out_at = None;
    for i in 0..40 {
        let now = 1.0 + i as f64 * DT;
        let out = t.process(&r.render(&scene, now), now).unwrap();
        if out.events.contains(&TrackEvent::DetectionTimedOut) {
            timed_out_at = Some(now);
            assert_eq!(out.state, TrackState::Waiting);
            break;
        }
        assert_eq!(out.state, TrackState::Detecting);
    }
    let at = timed_out_at.expect("timed out");
    assert!((at - 2.0).abs() < 0.05, "timed out at {at}");
    assert_eq!(t.target(), None);
}

#[test]
fn garbage_frames_do_not_panic() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 2);
    let mut t = tracker();
    let scene = Scene {
        ball: Some(ball(Point3::new(0.9, 0.0, 0.95))),
        ..Scene::default()
    };
    let good = r.render(&scene, 0.0);
    assert_eq!(t.process(&good, 0.0).unwrap().state, TrackState::Tracking);
    let k = Intrinsics::KINECT_640X480;

    // Typed errors: zero size, buffer sizes disagreeing with width * height, bad intrinsics.
    let zero = Frame::blank(0, 0, k, 0.1);
    assert!(t.process(&zero, 0.1).is_err());
    let mut short = good.clone();
    short.depth_mm.truncate(1000);
    assert!(t.process(&short, 0.1).is_err());
    let mut lying = good.clone();
    lying.width = 641;
    assert!(t.process(&lying, 0.1).is_err());
    let mut nan = good.clone();
    nan.intrinsics.fx = f64::NAN;
    assert!(t.process(&nan, 0.1).is_err());
    assert_eq!(t.stats().invalid_frames, 4);
    assert_eq!(
        t.state(),
        TrackState::Tracking,
        "rejected frames leave the state alone"
    );

    // Counted skips: all zeros, colour without depth, noise, tiny and odd-sized frames.
    let mut now = 0.2;
    let mut frames = vec![Frame::blank(640, 480, k, 0.0)];
    let mut no_depth = good.clone();
    no_depth.depth_mm.iter_mut().for_each(|d| *d = 0);
    frames.push(no_depth);
    let mut noise = good.clone();
    let mut x = 12345u32;
    for b in noise.rgb.iter_mut() {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *b = x as u8;
    }
    for d in noise.depth_mm.iter_mut() {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        *d = x as u16;
    }
    frames.push(noise);
    frames.push(Frame::blank(1, 1, k, 0.0));
    let mut red_1x1 = Frame::blank(1, 1, k, 0.0);
    red_1x1.rgb = RED.to_vec();
    red_1x1.depth_mm = vec![1000];
    frames.push(red_1x1);
    let mut all_red = Frame::blank(17, 5, k, 0.0);
    all_red.rgb = RED.repeat(17 * 5);
    all_red.depth_mm = vec![u16::MAX; 17 * 5];
    frames.push(all_red);
    for _ in 0..3 {
        for f in &frames {
            t.process(f, now).unwrap();
            now += DT;
        }
    }
    assert!(t.stats().frames_without_depth >= 6);
    // And it still finds the ball afterwards.
    let mut found = false;
    for _ in 0..5 {
        let out = t.process(&r.render(&scene, now), now).unwrap();
        now += DT;
        found |= out.state == TrackState::Tracking && out.centre_m.is_some();
    }
    assert!(found);
}

#[test]
fn ball_vanishing_mid_image_is_lost_but_not_out_of_view() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 21);
    let mut t = tracker();
    let mut scene = Scene {
        ball: Some(ball(Point3::new(0.9, 0.0, 0.95))),
        ..Scene::default()
    };
    let mut events = Vec::new();
    for i in 0..20 {
        let now = i as f64 * DT;
        if i == 5 {
            scene.ball = None;
        }
        let out = t.process(&r.render(&scene, now), now).unwrap();
        if (5..9).contains(&i) {
            assert_eq!(out.state, TrackState::Tracking, "still tracking, frame {i}");
            assert!(out.centre_m.is_none() && out.confidence == 0.0);
        }
        events.extend(out.events);
    }
    assert_eq!(events, vec![TrackEvent::BallDetected, TrackEvent::BallLost]);
    assert_eq!(t.state(), TrackState::Detecting);
}

#[test]
fn short_occlusion_does_not_lose_the_ball() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 22);
    let mut t = tracker();
    let centre = Point3::new(0.9, 0.05, 0.95);
    let mut scene = Scene::default();
    for i in 0..20 {
        let now = i as f64 * DT;
        // Hidden for 3 frames (fewer than max_failed_frames = 5).
        scene.ball = (!(6..9).contains(&i)).then(|| ball(centre));
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}");
        assert!(!out.events.contains(&TrackEvent::BallLost));
        if i >= 9 {
            assert!(err_m(&out, &truth_c(&cam, &centre)) < 0.01, "frame {i}");
        }
    }
}

#[test]
fn ball_passing_in_front_of_a_same_coloured_decoy_keeps_its_track() {
    let cam = camera();
    let mut r = SimRenderer::new(cam, SensorModel::default(), 23);
    let mut t = tracker();
    // A big red sphere 0.65 m behind the ball's path, on the line of sight through the middle
    // of the path (the ball's silhouette crosses the decoy's).
    let eye = cam.world_from_camera.translation.vector;
    let mid = Point3::new(0.9, 0.0, 0.95);
    let decoy = Point3::from(eye + (mid.coords - eye) * (1.65 / (mid.coords - eye).norm()));
    let mut scene = Scene {
        table: None,
        decoys: vec![Sphere::new(decoy, 0.3, RED)],
        ..Scene::default()
    };
    let (pd, pm) = (
        cam.project_world(&decoy).unwrap(),
        cam.project_world(&mid).unwrap(),
    );
    assert!((pd[0] - pm[0]).hypot(pd[1] - pm[1]) < 1.0);
    for i in 0..40 {
        let now = i as f64 * DT;
        // 0.5 m/s across, passing right in front of the decoy.
        let centre = Point3::new(0.9, 0.3 - 0.5 * now, 0.95);
        scene.ball = Some(ball(centre));
        let out = t.process(&r.render(&scene, now), now).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}: {out:?}");
        assert!(!out.events.contains(&TrackEvent::BallLost), "frame {i}");
        let e = err_m(&out, &truth_c(&cam, &centre));
        assert!(e < 0.015, "frame {i}: {:.1} mm", e * 1000.0);
    }
    // Detection from scratch while the ball is right in front of the decoy: colour regions are
    // split where depth jumps, so the ball is found on its own.
    let mut fresh = tracker();
    scene.ball = Some(ball(mid));
    let out = fresh.process(&r.render(&scene, 2.0), 2.0).unwrap();
    assert_eq!(out.events, vec![TrackEvent::BallDetected]);
    assert!(err_m(&out, &truth_c(&cam, &mid)) < 0.01);
}

#[test]
fn static_ball_at_near_and_far_range() {
    // Depth noise and quantisation grow with z^2: the centre error bound grows with it.
    for (dist, bound_m) in [(0.6, 0.005), (1.5, 0.015), (2.0, 0.03)] {
        let cam = camera();
        let mut r = SimRenderer::new(cam, SensorModel::default(), 24);
        let mut t = tracker();
        // On the camera's optical axis, `dist` metres away.
        let centre = cam.world_from_camera * Point3::new(0.0, 0.0, dist);
        let scene = Scene {
            table: None,
            ball: Some(ball(centre)),
            ..Scene::default()
        };
        let mut sum = 0.0;
        for i in 0..10 {
            let now = i as f64 * DT;
            let out = t.process(&r.render(&scene, now), now).unwrap();
            assert_eq!(out.state, TrackState::Tracking, "{dist} m frame {i}");
            sum += err_m(&out, &truth_c(&cam, &centre));
        }
        let mean = sum / 10.0;
        eprintln!("ball at {dist} m: mean centre error {:.2} mm", mean * 1e3);
        assert!(mean < bound_m, "{dist} m: {:.1} mm", mean * 1e3);
    }
}
