//! Geometry files, their errors, and steering.

use std::path::{Path, PathBuf};

use super::*;

fn models_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../models")
}

/// A geometry file with the given `mics` line.
fn with_mics(mics: &str) -> String {
    format!("name = \"test\"\nsample_rate_hz = 16000\nmics = {mics}\n")
}

#[test]
fn every_shipped_geometry_parses_and_matches_its_builtin_copy() {
    let expected = [
        ("kinect_v1", 4, 0.226),
        ("circular_4", 4, 0.064),
        ("circular_6", 6, 0.0926),
        ("laptop_2", 2, 0.07),
    ];
    assert_eq!(
        expected.map(|(name, ..)| name),
        ArrayGeometry::BUILTIN_NAMES
    );
    for (name, channels, aperture_m) in expected {
        let path = models_dir().join(format!("arrays/{name}.toml"));
        let loaded = ArrayGeometry::load(&path).unwrap();
        assert_eq!(loaded, ArrayGeometry::builtin(name).unwrap());
        assert_eq!(
            loaded,
            ArrayGeometry::by_name_or_path(name, &models_dir()).unwrap()
        );
        assert_eq!(loaded.name(), name);
        assert!(!loaded.description().is_empty());
        assert_eq!(loaded.sample_rate_hz(), 16_000);
        assert_eq!(loaded.channels(), channels);
        assert!(
            (loaded.aperture_m() - aperture_m).abs() < 1e-4,
            "{name}: {}",
            loaded.aperture_m()
        );
    }
    let kinect = ArrayGeometry::builtin("kinect_v1").unwrap();
    assert_eq!(kinect.mic(0), [0.0, 0.113, 0.0]);
    assert_eq!(kinect.linear_axis().map(|u| u[1].abs()), Some(1.0));
    assert!(
        ArrayGeometry::builtin("laptop_2")
            .unwrap()
            .linear_axis()
            .is_some()
    );
    let six = ArrayGeometry::builtin("circular_6").unwrap();
    assert!(six.linear_axis().is_none());
    for p in six.mics() {
        assert!((p[0].hypot(p[1]) - 0.0463).abs() < 1e-5, "{p:?}");
    }
}

#[test]
fn a_name_or_a_path_finds_a_geometry() {
    // A path, relative or not.
    let path = models_dir().join("arrays/circular_4.toml");
    let by_path =
        ArrayGeometry::by_name_or_path(path.to_str().unwrap(), Path::new("/nowhere")).unwrap();
    assert_eq!(by_path.name(), "circular_4");
    // A bare name without a models folder falls back to the built-in copy.
    let builtin = ArrayGeometry::by_name_or_path("laptop_2", Path::new("/nowhere")).unwrap();
    assert_eq!(builtin, ArrayGeometry::builtin("laptop_2").unwrap());
    let err = ArrayGeometry::by_name_or_path("kinect_v2", &models_dir()).unwrap_err();
    let message = err.to_string();
    assert!(matches!(err, ArrayError::NotFound { .. }), "{message}");
    assert!(
        message.contains("kinect_v2.toml") && message.contains("kinect_v1"),
        "{message}"
    );
    let err = ArrayGeometry::load("/nowhere/kinect_v1.toml").unwrap_err();
    assert!(matches!(err, ArrayError::Read { .. }), "{err}");
    assert!(matches!(
        ArrayGeometry::builtin("matrix_voice"),
        Err(ArrayError::UnknownBuiltin { .. })
    ));
}

#[test]
fn a_source_with_the_wrong_number_of_channels_is_refused_by_name() {
    let kinect = ArrayGeometry::builtin("kinect_v1").unwrap();
    assert!(kinect.check_channels(4).is_ok());
    assert_eq!(
        kinect.check_channels(3).unwrap_err().to_string(),
        "the source has 3 channels but the geometry kinect_v1 has 4 microphones"
    );
}

#[test]
fn a_typo_in_a_key_is_an_error_that_names_it() {
    let text = "name = \"t\"\nsample_rate_hz = 16000\nmic = [[0.0, 0.0, 0.0], [0.0, 0.1, 0.0]]\n";
    let err = ArrayGeometry::from_toml_str(text).unwrap_err();
    let message = err.to_string();
    assert!(matches!(err, ArrayError::Parse { .. }), "{message}");
    assert!(message.contains("unknown field `mic`"), "{message}");
    // A position with two coordinates, a negative rate: malformed too.
    for bad in [
        with_mics("[[0.0, 0.0], [0.0, 0.1]]"),
        "name = \"t\"\nsample_rate_hz = -1\nmics = [[0, 0, 0], [0, 0.1, 0]]\n".to_owned(),
    ] {
        assert!(matches!(
            ArrayGeometry::from_toml_str(&bad),
            Err(ArrayError::Parse { .. })
        ));
    }
}

#[test]
fn bad_geometries_get_specific_errors() {
    let parse = |mics: &str| ArrayGeometry::from_toml_str(&with_mics(mics)).unwrap_err();
    let err = parse("[[0.0, 0.05, 0.0], [0.0, -0.05, 0.0], [0.0, 0.052, 0.0]]");
    assert!(
        matches!(
            err,
            ArrayError::Coincident {
                first: 0,
                second: 2,
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("2.0 mm apart"), "{err}");
    let err = parse("[[0.0, 0.0, 0.0]]");
    assert!(
        matches!(err, ArrayError::MicCount { count: 1, .. }),
        "{err}"
    );
    let nine: Vec<String> = (0..9)
        .map(|i| format!("[0.0, {}, 0.0]", i as f64 * 0.01))
        .collect();
    let err = parse(&format!("[{}]", nine.join(", ")));
    assert!(
        matches!(err, ArrayError::MicCount { count: 9, .. }),
        "{err}"
    );
    let err = parse("[[0.0, 0.05, 0.0], [nan, -0.05, 0.0]]");
    assert!(
        matches!(err, ArrayError::NonFinitePosition { index: 1, .. }),
        "{err}"
    );
    let err = parse("[[0.0, 0.8, 0.0], [0.0, -0.8, 0.0]]");
    assert!(matches!(err, ArrayError::Aperture { .. }), "{err}");
    let err =
        ArrayGeometry::new("t", "", 4000, vec![[0.0, 0.1, 0.0], [0.0, -0.1, 0.0]]).unwrap_err();
    assert!(
        matches!(err, ArrayError::SampleRate { rate_hz: 4000, .. }),
        "{err}"
    );
}

#[test]
fn directions_follow_rep_103() {
    let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-12);
    assert!(close(direction(0.0, 0.0), [1.0, 0.0, 0.0]));
    assert!(close(direction(90f64.to_radians(), 0.0), [0.0, 1.0, 0.0]));
    assert!(close(direction(-90f64.to_radians(), 0.0), [0.0, -1.0, 0.0]));
    assert!(close(direction(0.3, 90f64.to_radians()), [0.0, 0.0, 1.0]));
}

#[test]
fn a_wave_from_the_left_reaches_the_leftmost_microphone_first() {
    let kinect = ArrayGeometry::builtin("kinect_v1").unwrap();
    let delays = kinect.delays_s(direction(90f64.to_radians(), 0.0));
    // Earliest first: from the left (+y) to the right.
    for pair in delays.windows(2) {
        assert!(pair[0] < pair[1], "{delays:?}");
    }
    assert!((delays[0] + 0.113 / SPEED_OF_SOUND_M_S).abs() < 1e-12);
    // From straight ahead, the line of microphones hears it all at once.
    assert!(
        kinect
            .delays_s(direction(0.0, 0.0))
            .iter()
            .all(|d| d.abs() < 1e-12)
    );
}

#[test]
fn delays_on_a_circular_array_are_symmetric() {
    for name in ["circular_4", "circular_6"] {
        let geometry = ArrayGeometry::builtin(name).unwrap();
        let half = geometry.channels() / 2;
        for azimuth_deg in [-150.0, -60.0, 0.0, 17.0, 90.0] {
            let delays = geometry.delays_s(direction(f64::to_radians(azimuth_deg), 0.2));
            // Around the centre: they sum to zero, and opposite microphones are opposite.
            assert!(
                delays.iter().sum::<f64>().abs() < 1e-9,
                "{name}: {delays:?}"
            );
            for i in 0..half {
                assert!(
                    (delays[i] + delays[i + half]).abs() < 1e-9,
                    "{name}: {delays:?}"
                );
            }
            let largest = delays.iter().fold(0.0f64, |m, d| m.max(d.abs()));
            assert!(largest <= geometry.aperture_m() / 2.0 / SPEED_OF_SOUND_M_S + 1e-12);
        }
    }
}
