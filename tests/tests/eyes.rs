#![allow(clippy::unwrap_used)]
//! Loki's eyes between real processes: the `rgbd` component (sim and playback drivers) and the
//! `ball_tracker` component, launched from the shipped manifests on a fresh namespace; this test
//! listens on the bus and compares the tracks with the ground truth.

use interfaces::msg::tracking::{BallEvent, BallEventKind, BallTrack, BallTrackState, BallTruth};
use interfaces::msg::vision::{Intrinsics, RgbdFrame};
use interfaces::{Bus, topics};
use robocog_tests::*;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::time::Instant;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap()
        .to_path_buf()
}

fn shipped_sequence() -> PathBuf {
    repo().join("components/rgbd/tests/data/sim_ball_seq")
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (0..3).map(|k| (a[k] - b[k]).powi(2)).sum::<f64>().sqrt()
}

/// Launches `launch/eyes_sim.toml` with `scenario` and a test bus joined to it.
async fn eyes_sim(tag: &str, scenario: &str) -> (Launch, Bus) {
    let ns = unique_namespace(tag);
    let set = format!("scenario={scenario}");
    let launch = Launch::start(&repo().join("launch/eyes_sim.toml"), &ns, &["--set", &set]);
    let bus = Bus::open(&launch.connect_args(), "test-eyes")
        .await
        .unwrap();
    (launch, bus)
}

/// Track/truth pairs matched by stamp, until `n` pairs or `timeout`; panics on time-out.
async fn matched_pairs(
    bus: &Bus,
    launch: &Launch,
    n: usize,
    timeout: Duration,
) -> Vec<(BallTrack, BallTruth)> {
    let tracks = bus.subscriber(&topics::VISION_BALL).await.unwrap();
    let truths = bus.subscriber(&topics::SIM_BALL_TRUTH).await.unwrap();
    let mut pending_tracks: HashMap<i64, BallTrack> = HashMap::new();
    let mut pending_truths: HashMap<i64, BallTruth> = HashMap::new();
    let mut pairs = Vec::new();
    let deadline = Instant::now() + timeout;
    while pairs.len() < n {
        tokio::select! {
            t = tracks.recv() => {
                let t = t.unwrap();
                match pending_truths.remove(&t.header.stamp_ns) {
                    Some(truth) => pairs.push((t, truth)),
                    None => { pending_tracks.insert(t.header.stamp_ns, t); }
                }
            }
            t = truths.recv() => {
                let t = t.unwrap();
                match pending_tracks.remove(&t.header.stamp_ns) {
                    Some(track) => pairs.push((track, t)),
                    None => { pending_truths.insert(t.header.stamp_ns, t); }
                }
            }
            _ = tokio::time::sleep_until(deadline) => panic!(
                "only {} track/truth pairs after {timeout:?} ({} tracks, {} truths unmatched); output:\n{}",
                pairs.len(), pending_tracks.len(), pending_truths.len(), launch.lines.all().join("\n")
            ),
        }
    }
    pairs
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_still_ball_is_tracked_within_1cm_of_the_sim_truth() {
    let (launch, bus) = eyes_sim("eyes-still", "still").await;
    let pairs = matched_pairs(&bus, &launch, 45, Duration::from_secs(40)).await;
    let mut errors = Vec::new();
    for (track, truth) in &pairs {
        assert_eq!(track.frame_seq, truth.frame_seq, "same source frame");
        assert_eq!(track.header.frame_id, "head_rgbd_optical_frame");
        assert!(truth.in_view);
        assert_eq!(track.state, BallTrackState::Tracking, "{track:?}");
        assert!(track.found && track.has_centre_m, "{track:?}");
        assert!(track.confidence > 0.5, "{track:?}");
        assert!((track.diameter_m - 0.1).abs() < 0.02, "{track:?}");
        errors.push(dist(track.centre_m, truth.centre_m));
    }
    let max = errors.iter().cloned().fold(0.0, f64::max);
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    eprintln!(
        "still ball, {} frames: 3D error mean {:.2} mm, max {:.2} mm",
        errors.len(),
        mean * 1e3,
        max * 1e3
    );
    assert!(max < 0.01, "max error {max} m");
    // The sim camera runs at 30 Hz on the bus clock.
    let (a, b) = (&pairs[0].1, &pairs[pairs.len() - 1].1);
    let rate_hz = (b.frame_seq - a.frame_seq) as f64
        / ((b.header.stamp_ns - a.header.stamp_ns) as f64 * 1e-9);
    assert!((rate_hz - 30.0).abs() < 3.0, "{rate_hz} Hz");
    // The sim ball rests 1.3 m ahead on the 0.75 m table, seen from 1.5 m high: ~1.48 m away.
    let d = dist(pairs[0].1.centre_m, [0.0; 3]);
    assert!((d - 1.476).abs() < 0.01, "{d}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ball_moving_at_1mps_stays_tracked() {
    let (launch, bus) = eyes_sim("eyes-moving", "moving").await;
    let events = bus.subscriber(&topics::VISION_BALL_EVENTS).await.unwrap();
    // Three seconds of frames: almost two turns of the circle.
    let pairs = matched_pairs(&bus, &launch, 90, Duration::from_secs(40)).await;
    let mut errors = Vec::new();
    let mut speeds = Vec::new();
    for w in pairs.windows(2) {
        let (a, b) = (&w[0].1, &w[1].1);
        let dt = (b.header.stamp_ns - a.header.stamp_ns) as f64 * 1e-9;
        if dt > 0.0 {
            speeds.push(dist(a.centre_world_m, b.centre_world_m) / dt);
        }
    }
    for (track, truth) in &pairs {
        assert_eq!(track.state, BallTrackState::Tracking, "{track:?}");
        assert!(track.found && track.has_centre_m, "{track:?}");
        errors.push(dist(track.centre_m, truth.centre_m));
    }
    let max = errors.iter().cloned().fold(0.0, f64::max);
    let mean = errors.iter().sum::<f64>() / errors.len() as f64;
    let mean_speed = speeds.iter().sum::<f64>() / speeds.len() as f64;
    eprintln!(
        "moving ball ({mean_speed:.2} m/s), {} frames: 3D error mean {:.2} mm, max {:.2} mm",
        errors.len(),
        mean * 1e3,
        max * 1e3
    );
    assert!((mean_speed - 1.0).abs() < 0.05, "{mean_speed} m/s");
    assert!(mean < 0.01, "mean error {mean} m");
    assert!(max < 0.03, "max error {max} m");
    // No loss while it moved.
    while let Some(e) = events.try_recv() {
        assert_ne!(e.kind, BallEventKind::Lost, "{e:?}");
        assert_ne!(e.kind, BallEventKind::OutOfView, "{e:?}");
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_ball_leaving_the_view_is_reported_out_of_view_lost_then_detected_again() {
    let (launch, bus) = eyes_sim("eyes-leave", "leave-and-return").await;
    let events = bus.subscriber(&topics::VISION_BALL_EVENTS).await.unwrap();
    let truths = bus.subscriber(&topics::SIM_BALL_TRUTH).await.unwrap();
    let mut seen: Vec<BallEvent> = Vec::new();
    let mut truth_by_seq: HashMap<u64, bool> = HashMap::new();
    let want = [
        BallEventKind::OutOfView,
        BallEventKind::Lost,
        BallEventKind::Detected,
    ];
    let deadline = Instant::now() + Duration::from_secs(40);
    loop {
        let kinds: Vec<BallEventKind> = seen.iter().map(|e| e.kind).collect();
        if kinds.windows(3).any(|w| w == want) {
            break;
        }
        tokio::select! {
            e = events.recv() => seen.push(e.unwrap()),
            t = truths.recv() => { let t = t.unwrap(); truth_by_seq.insert(t.frame_seq, t.in_view); }
            _ = tokio::time::sleep_until(deadline) => panic!(
                "events so far: {:?}; output:\n{}",
                seen.iter().map(|e| e.kind).collect::<Vec<_>>(),
                launch.lines.all().join("\n")
            ),
        }
    }
    while let Some(t) = truths.try_recv() {
        truth_by_seq.insert(t.frame_seq, t.in_view);
    }
    let kinds: Vec<BallEventKind> = seen.iter().map(|e| e.kind).collect();
    let i = kinds.windows(3).position(|w| w == want).unwrap();
    // "Out of view" comes while the truth says the ball is (nearly) leaving, "detected again"
    // once it is back in view.
    // The ball really left the view between "out of view" and "detected again" (it may be
    // re-detected while still partly outside the image).
    let (out, lost, back) = (&seen[i], &seen[i + 1], &seen[i + 2]);
    assert!(out.frame_seq <= lost.frame_seq && lost.frame_seq < back.frame_seq);
    assert!(
        (out.frame_seq..back.frame_seq).any(|s| truth_by_seq.get(&s) == Some(&false)),
        "the truth never left the view between frames {} and {}",
        out.frame_seq,
        back.frame_seq
    );
    assert!(
        (back.frame_seq..back.frame_seq + 30).any(|s| truth_by_seq.get(&s) == Some(&true))
            || truth_by_seq.keys().all(|&s| s < back.frame_seq + 30),
        "re-detected long before the ball came back into view"
    );
    eprintln!(
        "events: {kinds:?} (out of view at frame {}, lost at {}, detected again at {})",
        out.frame_seq, lost.frame_seq, back.frame_seq
    );
}

/// `ball.txt` of a sequence: timestamp (s) -> centre in the camera optical frame (m).
fn ball_txt(dir: &Path) -> Vec<(f64, [f64; 3])> {
    std::fs::read_to_string(dir.join("ball.txt"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#') && !l.trim().is_empty())
        .map(|l| {
            let v: Vec<f64> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            (v[0], [v[1], v[2], v[3]])
        })
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn playback_of_the_shipped_sequence_yields_tracks_on_the_recorded_truth() {
    let ns = unique_namespace("eyes-playback");
    let seq = shipped_sequence();
    let set = format!("sequence={}", seq.display());
    let launch = Launch::start(
        &repo().join("launch/eyes_playback.toml"),
        &ns,
        &["--set", &set],
    );
    let bus = Bus::open(&launch.connect_args(), "test-eyes")
        .await
        .unwrap();
    let tracks = bus.subscriber(&topics::VISION_BALL).await.unwrap();
    let truth = ball_txt(&seq);
    let (t0, n) = (truth[0].0, truth.len());
    // Looped stamps are the recorded ones plus whole passes of (last - first + one frame).
    let period = truth[n - 1].0 - t0 + (truth[1].0 - t0);
    let mut matched = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(40);
    while matched.len() < 15 {
        let t = tokio::time::timeout_at(deadline, tracks.recv())
            .await
            .unwrap_or_else(|_| {
                panic!(
                    "{} matched tracks; output:\n{}",
                    matched.len(),
                    launch.lines.all().join("\n")
                )
            })
            .unwrap();
        if !t.has_centre_m {
            continue;
        }
        let s = t.header.stamp_s() - t0;
        let in_pass = s - (s / period).floor() * period;
        let (_, c) = truth
            .iter()
            .find(|(ts, _)| ((ts - t0) - in_pass).abs() < 1e-3)
            .unwrap_or_else(|| panic!("no recorded frame at {}", t.header.stamp_s()));
        matched.push(dist(t.centre_m, *c));
    }
    let max = matched.iter().cloned().fold(0.0, f64::max);
    eprintln!(
        "playback: {} tracks, 3D error vs ball.txt max {:.2} mm",
        matched.len(),
        max * 1e3
    );
    assert!(max < 0.01, "max error {max} m");
}

/// A copy of the shipped sequence in the test's scratch folder.
fn copy_sequence(dst: &Path) {
    for sub in ["rgb", "depth"] {
        std::fs::create_dir_all(dst.join(sub)).unwrap();
        for e in std::fs::read_dir(shipped_sequence().join(sub)).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), dst.join(sub).join(e.file_name())).unwrap();
        }
    }
    for f in ["rgb.txt", "depth.txt", "intrinsics.txt"] {
        std::fs::copy(shipped_sequence().join(f), dst.join(f)).unwrap();
    }
}

#[test]
fn a_malformed_sequence_stops_rgbd_with_the_file_and_line() {
    let ns = unique_namespace("eyes-bad-seq");
    let dir = scratch(&ns).join("seq");
    copy_sequence(&dir);
    // Line 5 of rgb.txt (after three comment lines and one good entry) becomes garbage.
    let rgb = std::fs::read_to_string(dir.join("rgb.txt")).unwrap();
    let mut lines: Vec<&str> = rgb.lines().collect();
    lines[4] = "not-a-timestamp rgb/nothing.png";
    std::fs::write(dir.join("rgb.txt"), lines.join("\n")).unwrap();
    let args: Vec<String> = ["--driver", "playback", "--sequence"]
        .iter()
        .map(|s| s.to_string())
        .chain([dir.display().to_string()])
        .collect();
    let out = run(&bin("rgbd"), &args, Duration::from_secs(20));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    let want = format!("{}:5", dir.join("rgb.txt").display());
    assert!(stderr.contains(&want), "no {want:?} in:\n{stderr}");

    // A missing depth image: the error names the image and the index line naming it.
    let dir2 = scratch(&ns).join("seq2");
    copy_sequence(&dir2);
    std::fs::remove_file(dir2.join("depth/1700000000.100000.png")).unwrap();
    let args: Vec<String> = ["--driver", "playback", "--sequence"]
        .iter()
        .map(|s| s.to_string())
        .chain([dir2.display().to_string()])
        .collect();
    let out = run(&bin("rgbd"), &args, Duration::from_secs(20));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("depth.txt:7") && stderr.contains("1700000000.100000.png"),
        "{stderr}"
    );
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn malformed_frames_are_counted_and_the_tracker_carries_on() {
    let ns = unique_namespace("eyes-bad-frames");
    let m = scratch(&ns).join("graph.toml");
    std::fs::write(
        &m,
        format!(
            r#"
[[component]]
name = "ball_tracker"
binary = "{}"
args = ["--target-hue", "3.2", "--target-saturation", "0.86", "--target-diameter", "0.1"]
external_inputs = ["vision/rgbd", "vision/ball_target"]
"#,
            bin("ball_tracker").display()
        ),
    )
    .unwrap();
    let launch = Launch::start(&m, &ns, &[]);
    launch
        .lines
        .wait_for("the tracker up", Duration::from_secs(20), |l| {
            l.contains("ball_tracker is up")
        });
    let bus = Bus::open(&launch.connect_args(), "test-eyes")
        .await
        .unwrap();
    let diag = bus.subscriber(&topics::DIAGNOSTICS).await.unwrap();
    let tracks = bus.subscriber(&topics::VISION_BALL).await.unwrap();
    let frames = bus.publisher(&topics::VISION_RGBD).await.unwrap();
    // Wait until the tracker's subscription is known (its liveliness token).
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        let graph = bus.graph(Duration::from_millis(300)).await.unwrap();
        if graph.iter().any(|t| {
            matches!(t, interfaces::liveliness::Token::Subscriber { topic, .. } if topic == "vision/rgbd")
        }) {
            break;
        }
        assert!(Instant::now() < deadline, "the tracker never subscribed");
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    tokio::time::sleep(Duration::from_millis(300)).await;

    let k = Intrinsics {
        fx: 525.0,
        fy: 525.0,
        cx: 319.5,
        cy: 239.5,
    };
    // Decodable but inconsistent: sizes that disagree, garbage sizes, bad intrinsics, empty.
    let mut short = RgbdFrame::blank(640, 480, k);
    short.depth_mm.truncate(1000);
    let mut huge = RgbdFrame::blank(4, 4, k);
    huge.width = u32::MAX;
    huge.height = u32::MAX;
    let mut bad_k = RgbdFrame::blank(64, 48, k);
    bad_k.intrinsics.fx = f64::NAN;
    let mut odd = RgbdFrame::blank(64, 48, k);
    odd.depth_mm.push(1);
    // One at a time: a tracker that falls behind jumps to the newest frame (and counts the
    // others as skipped), which would hide some of them.
    for mut f in [short, huge, bad_k, odd, RgbdFrame::default()] {
        f.header.stamp_ns = 1;
        frames.publish(&mut f).await.unwrap();
        tokio::time::sleep(Duration::from_millis(150)).await;
    }
    // Undecodable bytes: counted by the bus as decode errors.
    bus.session()
        .put(&bus.topic_key("vision/rgbd"), vec![0u8, 1, 0, 0, 9, 9])
        .await
        .unwrap();
    // Then a good (empty) frame: the tracker answers it.
    let mut good = RgbdFrame::blank(64, 48, k);
    good.header.stamp_ns = 42_000_000_000;
    frames.publish(&mut good).await.unwrap();
    let track = tokio::time::timeout(Duration::from_secs(10), tracks.recv())
        .await
        .expect("a track for the good frame")
        .unwrap();
    assert_eq!(track.header.stamp_ns, 42_000_000_000);
    assert_eq!(track.state, BallTrackState::Detecting);
    assert!(!track.found);

    let deadline = Instant::now() + Duration::from_secs(10);
    let mut last = None;
    loop {
        let d = tokio::time::timeout_at(deadline, diag.recv())
            .await
            .unwrap_or_else(|_| {
                panic!(
                    "no diagnostics of the tracker counting 5 bad frames and 1 decode error; last: {last:?}; output:\n{}",
                    launch.lines.all().join("\n")
                )
            })
            .unwrap();
        if d.component != "ball_tracker" {
            continue;
        }
        last = Some(d.clone());
        // Older snapshots may still be queued: wait for one taken after the garbage.
        assert!(d.get("bad_frames") <= 5, "{d:?}");
        if d.get("bad_frames") == 5 && d.get("decode_errors/vision/rgbd") == 1 {
            assert_eq!(d.get("skipped_frames"), 0);
            break;
        }
    }
    assert!(
        launch.lines.count(|l| l.contains("skipped a frame")) >= 1,
        "a warning was logged"
    );
}
