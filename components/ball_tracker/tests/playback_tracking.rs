//! The tracker on the recorded sequence shipped with `rgbd` (TUM layout, read back from PNG):
//! the ball is found in the first frame and its 3D centre stays within 1 cm of `ball.txt`.

#![allow(clippy::unwrap_used)] // tests may unwrap

use std::path::Path;

use ball_tracker::hsv::rgb_to_hsv;
use ball_tracker::{BallTracker, Target, TrackEvent, TrackState, TrackerConfig};
use camera::RgbdDriver;
use camera::playback::{OpenOptions, PlaybackDriver, PlaybackMode, TumSequence};

fn shipped() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../rgbd/tests/data/sim_ball_seq")
}

fn red_tracker() -> BallTracker {
    let (h, s, _) = rgb_to_hsv(220, 40, 30);
    let mut tracker = BallTracker::new(TrackerConfig::default());
    tracker
        .set_target(Some(Target {
            hue_deg: h,
            saturation: s,
            diameter_m: 0.1,
        }))
        .unwrap();
    tracker
}

#[test]
fn replaying_gives_identical_outputs() {
    let seq = TumSequence::open(shipped(), OpenOptions::default()).unwrap();
    let run = || {
        let mut t = red_tracker();
        (0..seq.len())
            .map(|i| {
                let f = seq.load(i).unwrap();
                t.process(&f, f.timestamp_s).unwrap()
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(run(), run());
}

#[test]
fn tracks_the_shipped_sequence() {
    let dir = shipped();
    let truth: Vec<Vec<f64>> = std::fs::read_to_string(dir.join("ball.txt"))
        .unwrap()
        .lines()
        .filter(|l| !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
        .collect();
    let seq = TumSequence::open(&dir, OpenOptions::default()).unwrap();
    let mut driver = PlaybackDriver::new(seq, PlaybackMode::AsFastAsAsked);
    let mut tracker = red_tracker();
    let mut i = 0;
    while let Some(frame) = driver.next_frame(0.0).unwrap() {
        let out = tracker.process(&frame, frame.timestamp_s).unwrap();
        assert_eq!(out.state, TrackState::Tracking, "frame {i}");
        if i == 0 {
            assert_eq!(out.events, vec![TrackEvent::BallDetected]);
        }
        let c = out.centre_m.unwrap();
        let t = &truth[i];
        let err = ((c[0] - t[1]).powi(2) + (c[1] - t[2]).powi(2) + (c[2] - t[3]).powi(2)).sqrt();
        assert!(err < 0.01, "frame {i}: {:.1} mm", err * 1000.0);
        i += 1;
    }
    assert_eq!(i, 10);
}
