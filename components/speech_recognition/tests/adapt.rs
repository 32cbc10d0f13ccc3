#![allow(clippy::unwrap_used, clippy::expect_used)] // a test fails by panicking
//! `speech_model`: adapting the acoustic model on a folder of recordings, which model the
//! recognizer then loads by default, and what bad recordings get. The synthesized corpus is
//! built by `scripts/test` itself (it is the model the other tests use); these tests use small
//! corpora so they run in seconds.

mod common;

use audio::wav::{Pcm, encode};
use common::{spoken, voice};
use interfaces::msg::command::{Command, Game};
use speech_recognition::model::{AcousticModel, PROVENANCE_FILE};
use speech_recognition::{Recognizer, RecognizerConfig};
use std::path::Path;
use std::process::{Command as Process, Output};

/// A fresh folder of this test's own under the system's temporary folder (emptied first).
fn scratch(name: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join("robocog-speech-tests").join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch folder");
    d
}

fn speech_model(args: &[&str]) -> Output {
    Process::new(env!("CARGO_BIN_EXE_speech_model"))
        .args(args)
        .output()
        .expect("speech_model runs")
}

fn write_recording(dir: &Path, name: &str, text: &str, samples: Vec<i16>) {
    let pcm = Pcm {
        sample_rate_hz: 16000,
        channels: 1,
        samples,
    };
    std::fs::write(dir.join(format!("{name}.wav")), encode(&pcm)).unwrap();
    std::fs::write(dir.join(format!("{name}.txt")), text).unwrap();
}

#[test]
fn recordings_adapt_a_model_the_recognizer_loads() {
    let dir = scratch("adapt-recordings");
    let rec = dir.join("recordings");
    std::fs::create_dir_all(&rec).unwrap();
    let mut i = 0;
    for v in [voice("en-us+m2", 150, 45), voice("en-gb+f5", 170, 55)] {
        for c in Command::of_game(Game::Touch) {
            // Punctuation and case as people type them.
            let text = format!("{}!", c.phrase().to_uppercase());
            write_recording(
                &rec,
                &format!("r{i:02}"),
                &text,
                spoken(c.phrase(), &v, 15.0, i),
            );
            i += 1;
        }
    }
    let out = dir.join("model");
    let (o, r) = (out.to_str().unwrap(), rec.to_str().unwrap());
    let run = speech_model(&["--out", o, "--recordings", r]);
    let err = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{err}");
    assert!(err.contains("Baum-Welch") && err.contains("done"), "{err}");
    let prov: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join(PROVENANCE_FILE)).unwrap()).unwrap();
    assert_eq!(prov["utterances"], i);
    assert!(prov["summary"].as_str().unwrap().contains("recordings"));
    assert_eq!(prov["corpus"], "recordings");
    // Built from the same recordings: up to date, nothing to do.
    assert!(
        speech_model(&["--out", o, "--recordings", r, "--check"])
            .status
            .success()
    );
    let again = speech_model(&["--out", o, "--recordings", r]);
    assert!(String::from_utf8_lossy(&again.stderr).contains("up to date"));
    // Another recipe (the synthesized corpus) is not what is there.
    assert!(!speech_model(&["--out", o, "--check"]).status.success());

    // In the cache, the model adapted on people is the recognizer's default, unless the
    // environment asks for the stock one; one adapted on the synthesized voices is not (it hears
    // people worse than the stock model); a folder without a whole model is no default.
    let cache = dir.join("cache");
    let cached = cache.join("robocog/speech/en-us-adapted");
    std::fs::create_dir_all(&cached).unwrap();
    for f in std::fs::read_dir(&out).unwrap() {
        let f = f.unwrap().path();
        std::fs::copy(&f, cached.join(f.file_name().unwrap())).unwrap();
    }
    let which = |env: &str| {
        let out = Process::new(env!("CARGO_BIN_EXE_speech_model"))
            .arg("--which")
            .env("XDG_CACHE_HOME", &cache)
            .env("ROBOCOG_ACOUSTIC_MODEL", env)
            .output()
            .expect("speech_model runs");
        String::from_utf8_lossy(&out.stdout).trim().to_string()
    };
    assert_eq!(which(""), "adapted");
    assert_eq!(which("stock"), "stock");
    let mut synthesized = prov.clone();
    synthesized["corpus"] = "synthesized".into();
    std::fs::write(cached.join(PROVENANCE_FILE), synthesized.to_string()).unwrap();
    assert_eq!(which(""), "stock");
    assert_eq!(which("adapted"), "adapted");
    std::fs::remove_file(cached.join("means")).unwrap();
    assert_eq!(which(""), "stock");
    // Asked for by name where there is none, the adapted model is a clear error at start.
    let empty = dir.join("empty-cache");
    let asked = Process::new(env!("CARGO_BIN_EXE_speech_recognition"))
        .args(["--acoustic-model", "adapted", "--wav", "/nonexistent.wav"])
        .env("XDG_CACHE_HOME", &empty)
        .output()
        .expect("speech_recognition runs");
    let err = String::from_utf8_lossy(&asked.stderr);
    assert_eq!(asked.status.code(), Some(78), "{err}");
    assert!(
        err.contains("no adapted acoustic model") && err.contains("speech_model"),
        "{err}"
    );

    let model = AcousticModel::resolve(Some(o)).unwrap();
    assert!(!model.stock);
    let mut recognizer =
        Recognizer::shipped(Game::Touch, RecognizerConfig::for_model(model)).unwrap();
    let mut got = recognizer
        .push(&spoken("touch the ball", &voice("en-us", 160, 50), 30.0, 7))
        .unwrap();
    got.extend(recognizer.flush().unwrap());
    assert_eq!(got.len(), 1, "{got:?}");
    assert_eq!(got[0].command, Command::TouchBall, "{got:?}");
}

#[test]
fn bad_recordings_get_clear_errors() {
    let dir = scratch("adapt-bad");
    let out = dir.join("model");
    let o = out.to_str().unwrap();
    let case = |name: &str, setup: &dyn Fn(&Path)| -> String {
        let rec = dir.join(name);
        std::fs::create_dir_all(&rec).unwrap();
        setup(&rec);
        let run = speech_model(&["--out", o, "--recordings", rec.to_str().unwrap()]);
        assert!(!run.status.success(), "{name} was accepted");
        String::from_utf8_lossy(&run.stderr).into_owned()
    };
    let e = case("empty", &|_| {});
    assert!(e.contains("no .wav files"), "{e}");
    let e = case("no-transcription", &|d| {
        write_recording(
            d,
            "a",
            "stop",
            spoken("stop", &voice("en-us", 160, 50), 20.0, 1),
        );
        std::fs::remove_file(d.join("a.txt")).unwrap();
    });
    assert!(e.contains("a.wav has no transcription"), "{e}");
    let e = case("unknown-word", &|d| {
        let s = spoken("stop", &voice("en-us", 160, 50), 20.0, 1);
        write_recording(d, "a", "stop zzxqv", s);
    });
    assert!(e.contains("zzxqv") && e.contains("a.wav"), "{e}");
    let e = case("not-audio", &|d| {
        std::fs::write(d.join("a.wav"), b"hello").unwrap();
        std::fs::write(d.join("a.txt"), b"stop").unwrap();
    });
    assert!(e.contains("a.wav") && e.contains("RIFF"), "{e}");
    // Nothing was written where the model goes.
    assert!(!out.exists());
}
