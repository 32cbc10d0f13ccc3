//! Tests of the tracker's geometry helpers, input validation and configuration.

use super::*;
use camera::Intrinsics;

#[test]
fn equivalent_diameter_of_a_sphere_silhouette() {
    // A 10 cm sphere centred 1 m away seen by f = 525 px: silhouette radius ~26.25 px, median
    // surface depth 1 - 0.05 / sqrt(2) m.
    let f = 525.0;
    let r_px: f64 = f * 0.05 / (1.0f64 - 0.05 * 0.05).sqrt();
    let area = std::f64::consts::PI * r_px * r_px;
    let z_med = 1.0 - 0.05 * std::f64::consts::FRAC_1_SQRT_2;
    let d = equivalent_diameter_m(area, z_med, f).unwrap();
    assert!((d - 0.1).abs() < 0.001, "{d}");
    assert!(equivalent_diameter_m(0.0, 1.0, f).is_none());
    assert!(equivalent_diameter_m(100.0, 0.0, f).is_none());
    // A silhouette wider than 2.8 focal lengths cannot be a sphere in front of the camera.
    assert!(equivalent_diameter_m(1e8, 1.0, f).is_none());
}

#[test]
fn window_clipping_stays_inside_the_image() {
    let w = FWin {
        cx: -5.0,
        cy: 470.0,
        hw: 20.0,
        hh: 30.0,
    };
    assert_eq!(w.clip(640, 480), (0, 440, 15, 480));
    let out = FWin {
        cx: 1000.0,
        cy: 1000.0,
        hw: 5.0,
        hh: 5.0,
    };
    let (x0, y0, x1, y1) = out.clip(640, 480);
    assert!(x0 >= x1 && y0 >= y1, "empty when outside");
    let nan = FWin {
        cx: f32::NAN,
        cy: 10.0,
        hw: 5.0,
        hh: 5.0,
    };
    let (x0, _, x1, _) = nan.clip(640, 480);
    assert!(x0 <= x1 && x1 <= 640);
}

#[test]
fn targets_and_times_are_validated() {
    let mut t = BallTracker::new(TrackerConfig::default());
    let good = Target {
        hue_deg: -10.0,
        saturation: 0.8,
        diameter_m: 0.1,
    };
    t.set_target(Some(good)).unwrap();
    assert_eq!(t.state(), TrackState::Detecting);
    assert_eq!(
        t.target().unwrap().hue_deg,
        350.0,
        "hue wrapped to [0, 360)"
    );
    for bad in [
        Target {
            saturation: 1.5,
            ..good
        },
        Target {
            diameter_m: 0.0,
            ..good
        },
        Target {
            diameter_m: f64::NAN,
            ..good
        },
        Target {
            hue_deg: f32::INFINITY,
            ..good
        },
    ] {
        assert!(matches!(
            t.set_target(Some(bad)),
            Err(TrackError::InvalidTarget(_))
        ));
    }
    let f = Frame::blank(8, 8, Intrinsics::KINECT_640X480, 0.0);
    assert!(matches!(
        t.process(&f, f64::NAN),
        Err(TrackError::InvalidTime(_))
    ));
    t.set_target(None).unwrap();
    assert_eq!(t.process(&f, 0.0).unwrap().state, TrackState::Waiting);
}

#[test]
fn config_rejects_unknown_fields() {
    let c: TrackerConfig = serde_json::from_str(r#"{"hue_tolerance_deg": 12.0}"#).unwrap();
    assert_eq!(c.hue_tolerance_deg, 12.0);
    assert_eq!(
        c.max_failed_frames,
        TrackerConfig::default().max_failed_frames
    );
    assert!(serde_json::from_str::<TrackerConfig>(r#"{"hue_tolerence_deg": 12.0}"#).is_err());
}
