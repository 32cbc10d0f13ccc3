#![allow(clippy::unwrap_used, clippy::expect_used)] // a test fails by panicking
//! The image-source room (`audio::array::room`) checked against pyroomacoustics, the reference
//! implementation it follows: for three rooms, reverberation times, sources and microphones, the
//! same inversion of Sabine's formula, and impulse responses that agree sample by sample (the
//! direct path on the same sample, the early and total energies, the correlation of the two).
//!
//! pyroomacoustics runs in a Python venv that `scripts/test` makes (ROBOCOG_PYROOM_PYTHON);
//! `tests/pyroom_reference.py` computes its impulse responses for the set-ups this test writes.
//! Its responses are compared as its documentation and source define them: sample 0 is time 0,
//! every arrival is late by the same global delay as ours (half the fractional-delay filter), and
//! a path of `r` metres has amplitude `1 / r`, where ours has `1 / (4 π r)` (so theirs are
//! scaled by `1 / (4 π)` before comparing). No lag is searched for.

use audio::array::SPEED_OF_SOUND_M_S;
use audio::array::room::{FRAC_DELAY_TAPS, HIGH_PASS_HZ, RIR_DELAY_SAMPLES, ShoeboxRoom};
use json::Read;
use std::f64::consts::PI;
use std::path::{Path, PathBuf};
use std::process::Command;

/// One room, source and microphone (metres, room frame).
struct Setup {
    dims_m: [f64; 3],
    rt60_s: f64,
    source_m: [f64; 3],
    mic_m: [f64; 3],
    rate_hz: f64,
}

const SETUPS: [Setup; 3] = [
    // A small office, dry.
    Setup {
        dims_m: [4.0, 3.5, 2.6],
        rt60_s: 0.2,
        source_m: [1.0, 2.5, 1.6],
        mic_m: [2.9, 1.2, 1.1],
        rate_hz: 16_000.0,
    },
    // A living room.
    Setup {
        dims_m: [7.0, 5.5, 3.0],
        rt60_s: 0.5,
        source_m: [5.2, 4.1, 1.7],
        mic_m: [2.3, 1.9, 1.25],
        rate_hz: 16_000.0,
    },
    // A classroom, live, at 48 kHz. Source and microphone are symmetric about the middle of
    // the room's length, so pairs of images arrive together: at 11.4 m, four of them outweigh
    // the direct path.
    Setup {
        dims_m: [9.0, 6.5, 3.2],
        rt60_s: 0.8,
        source_m: [2.2, 4.9, 1.5],
        mic_m: [6.8, 2.1, 1.3],
        rate_hz: 48_000.0,
    },
];

/// What the test requires of every set-up (measured: see the table the test prints).
const MAX_EARLY_DB: f64 = 0.05;
const MAX_TOTAL_DB: f64 = 0.05;
const MIN_CORRELATION: f64 = 0.9999;

/// The Python of the venv holding pyroomacoustics.
fn python() -> PathBuf {
    match std::env::var_os("ROBOCOG_PYROOM_PYTHON") {
        Some(p) => PathBuf::from(p),
        None => panic!(
            "ROBOCOG_PYROOM_PYTHON is not set: run this test through scripts/test, which installs \
             pyroomacoustics into a venv and sets it"
        ),
    }
}

fn vec3(v: [f64; 3]) -> String {
    format!("[{}, {}, {}]", v[0], v[1], v[2])
}

/// How our impulse response and the reference's compare.
#[derive(Debug)]
struct Figures {
    /// The sample of the largest magnitude before the first reflection (the direct path), ours
    /// and theirs.
    direct: (usize, usize),
    /// Our energy over theirs, in dB, over the first 50 ms after the direct path's arrival.
    early_db: f64,
    /// Our energy over theirs, in dB, over the whole response.
    total_db: f64,
    /// The normalised cross-correlation at lag 0.
    correlation: f64,
}

/// `before` is a sample between the direct path's arrival and the first reflection's (a later
/// reflection may be larger than the direct path, where several images arrive together).
fn compare(ours: &[f64], theirs: &[f64], before: usize, rate_hz: f64) -> Figures {
    let peak = |h: &[f64]| {
        (0..before)
            .max_by(|&i, &j| h[i].abs().total_cmp(&h[j].abs()))
            .unwrap()
    };
    let energy = |h: &[f64]| h.iter().map(|v| v * v).sum::<f64>();
    let direct = (peak(ours), peak(theirs));
    let early = (direct.1 + (0.05 * rate_hz).round() as usize).min(ours.len().min(theirs.len()));
    let db = |a: f64, b: f64| 10.0 * (a / b).log10();
    let dot: f64 = ours.iter().zip(theirs).map(|(a, b)| a * b).sum();
    Figures {
        direct,
        early_db: db(energy(&ours[..early]), energy(&theirs[..early])),
        total_db: db(energy(ours), energy(theirs)),
        correlation: dot / (energy(ours) * energy(theirs)).sqrt(),
    }
}

#[test]
fn image_source_rooms_agree_with_pyroomacoustics() {
    let python = python();
    let dir = std::env::temp_dir().join(format!("audio-room-reference-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let rooms: Vec<ShoeboxRoom> = SETUPS
        .iter()
        .map(|s| ShoeboxRoom::for_rt60(s.dims_m, s.rt60_s).unwrap())
        .collect();
    let setups: Vec<String> = SETUPS
        .iter()
        .zip(&rooms)
        .map(|(s, room)| {
            format!(
                r#"{{"dims_m": {}, "rt60_s": {}, "absorption": {}, "max_order": {}, "source_m": {}, "mic_m": {}, "rate_hz": {}}}"#,
                vec3(s.dims_m),
                s.rt60_s,
                room.absorption,
                room.max_order,
                vec3(s.source_m),
                vec3(s.mic_m),
                s.rate_hz
            )
        })
        .collect();
    let input = dir.join("setups.json");
    let output = dir.join("reference.json");
    std::fs::write(&input, format!(r#"{{"setups": [{}]}}"#, setups.join(", "))).unwrap();
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/pyroom_reference.py");
    let run = Command::new(&python)
        .arg(&script)
        .arg(&input)
        .arg(&output)
        .output()
        .unwrap_or_else(|e| panic!("cannot run {}: {e}", python.display()));
    assert!(
        run.status.success(),
        "{} failed:\n{}",
        script.display(),
        String::from_utf8_lossy(&run.stderr)
    );
    let reference = json::parse(&std::fs::read_to_string(&output).unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
    println!(
        "pyroomacoustics {}, numpy {}, scipy {}",
        reference.field("pyroomacoustics").str(),
        reference.field("numpy").str(),
        reference.field("scipy").str()
    );
    // The constants ours are built on are the reference's defaults.
    assert_eq!(
        reference.field("frac_delay_length").num(),
        FRAC_DELAY_TAPS as f64
    );
    assert_eq!(reference.field("rir_hpf_fc").num(), HIGH_PASS_HZ);

    let expected = reference.field("setups").arr();
    assert_eq!(expected.len(), SETUPS.len());
    let mut failures = Vec::new();
    for (i, ((setup, room), theirs)) in SETUPS.iter().zip(&rooms).zip(expected).enumerate() {
        assert_eq!(theirs.field("c").num(), SPEED_OF_SOUND_M_S, "set-up {i}");
        let absorption = theirs.field("absorption").num();
        assert!(
            (room.absorption - absorption).abs() <= 1e-12 * absorption,
            "set-up {i}: absorption {} here, {absorption} in pyroomacoustics",
            room.absorption
        );
        assert_eq!(
            room.max_order as f64,
            theirs.field("max_order").num(),
            "set-up {i}"
        );
        let delay = |to: [f64; 3]| {
            let distance = to
                .iter()
                .zip(setup.mic_m)
                .map(|(a, b)| (a - b).powi(2))
                .sum::<f64>()
                .sqrt();
            distance / SPEED_OF_SOUND_M_S * setup.rate_hz + RIR_DELAY_SAMPLES as f64
        };
        let arrival = delay(setup.source_m);
        // The six images of one reflection: the source mirrored in each wall.
        let first_reflection = (0..6)
            .map(|wall| {
                let (axis, far) = (wall / 2, wall % 2 == 1);
                let mut image = setup.source_m;
                image[axis] = if far {
                    2.0 * setup.dims_m[axis] - image[axis]
                } else {
                    -image[axis]
                };
                delay(image)
            })
            .fold(f64::INFINITY, f64::min);
        let before = ((arrival + first_reflection) / 2.0) as usize;
        for (name, ours) in [
            ("rir", room.rir(setup.source_m, setup.mic_m, setup.rate_hz)),
            (
                "image_rir",
                room.image_rir(setup.source_m, setup.mic_m, setup.rate_hz),
            ),
        ] {
            let ours = ours.unwrap();
            // Their amplitude is 1 / r where ours is 1 / (4 π r).
            let theirs: Vec<f64> = theirs
                .field(name)
                .nums()
                .iter()
                .map(|v| v / (4.0 * PI))
                .collect();
            let f = compare(&ours, &theirs, before, setup.rate_hz);
            println!(
                "set-up {i} (RT60 {} s, {:?} m, order {}, {} Hz) {name}: {} samples here, {} in \
                 pyroomacoustics; direct path at sample {} here, {} there (arrival {arrival:.2}, \
                 first reflection {first_reflection:.2}); early energy {:+.5} dB, total {:+.5} dB; correlation {:.7}",
                setup.rt60_s,
                setup.dims_m,
                room.max_order,
                setup.rate_hz,
                ours.len(),
                theirs.len(),
                f.direct.0,
                f.direct.1,
                f.early_db,
                f.total_db,
                f.correlation
            );
            let good = ours.len() == theirs.len()
                && f.direct.0 == f.direct.1
                && (f.direct.0 as f64 - arrival).abs() < 1.0
                && f.early_db.abs() <= MAX_EARLY_DB
                && f.total_db.abs() <= MAX_TOTAL_DB
                && f.correlation >= MIN_CORRELATION;
            if !good {
                failures.push(format!("set-up {i} {name}: {f:?}"));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "not as pyroomacoustics (lengths equal, direct path on the same sample, early energy \
         within {MAX_EARLY_DB} dB, total within {MAX_TOTAL_DB} dB, correlation at least \
         {MIN_CORRELATION}):\n{}",
        failures.join("\n")
    );
}

/// The reference's JSON, read as the test needs it (a missing or mistyped field fails the test,
/// naming it).
mod json {
    pub use serde_json::Value;

    pub fn parse(text: &str) -> Value {
        serde_json::from_str(text).unwrap_or_else(|e| panic!("the reference's output: {e}"))
    }

    pub trait Read {
        fn field(&self, key: &str) -> &Value;
        fn arr(&self) -> &[Value];
        fn num(&self) -> f64;
        fn nums(&self) -> Vec<f64>;
        fn str(&self) -> &str;
    }

    impl Read for Value {
        fn field(&self, key: &str) -> &Value {
            self.get(key)
                .unwrap_or_else(|| panic!("no {key:?} in the reference's output"))
        }
        fn arr(&self) -> &[Value] {
            self.as_array()
                .unwrap_or_else(|| panic!("not a list: {self}"))
        }
        fn num(&self) -> f64 {
            self.as_f64()
                .unwrap_or_else(|| panic!("not a number: {self}"))
        }
        fn nums(&self) -> Vec<f64> {
            self.arr().iter().map(Read::num).collect()
        }
        fn str(&self) -> &str {
            self.as_str()
                .unwrap_or_else(|| panic!("not a string: {self}"))
        }
    }
}
