#![allow(clippy::unwrap_used)]
//! Decode synthesized sentences and print the raw scores and timings (calibration aid):
//! `probe <game> <sentence>...`.
use interfaces::msg::command::Game;
use speech_generator::synth::{Voice, synthesize_16k};
use speech_recognition::{Recognizer, RecognizerConfig};

fn main() {
    let mut args = std::env::args().skip(1);
    let game = Game::from_name(&args.next().unwrap()).unwrap();
    let beam: f64 = std::env::var("GARBAGE_BEAM")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1e-8);
    let lw: f64 = std::env::var("GARBAGE_LW")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(2.0);
    let mut rec = Recognizer::shipped(
        game,
        RecognizerConfig {
            garbage_beam: beam,
            garbage_lw: lw,
            ..RecognizerConfig::default()
        },
    )
    .unwrap();
    for s in args {
        let a = synthesize_16k(&s, &Voice::default()).unwrap();
        let r = rec.decode_all(&a).unwrap();
        println!(
            "{s:?} ({:.2}s) -> {:?} {:?} conf {:.3} garbage/frame {:.4} decode {:.3}s",
            a.len() as f64 / 16000.0,
            r.text,
            r.command,
            r.confidence,
            r.garbage_per_frame_ln,
            r.decode_s
        );
        if std::env::var("NBEST").is_ok() {
            println!(
                "   nbest {:?}",
                r.nbest
                    .iter()
                    .take(5)
                    .map(|(t, s)| format!("{t}:{:.4}", s))
                    .collect::<Vec<_>>()
            );
        }
    }
}
