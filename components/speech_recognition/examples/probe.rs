#![allow(clippy::unwrap_used)]
//! Decode synthesized sentences and print the verdict, the N-best list and timings (calibration
//! aid): `probe <game> <sentence>...`. Environment: `VOICE` (espeak-ng voice, default en-us),
//! `SPEED` (words per minute), `SNR` (dB of white noise, default none), `SCALE` (the confidence's
//! acoustic scale), `NBEST` (print the N-best list).
use audio::signal::{NoiseKind, NoiseRng, mix_at_snr};
use audio::synth::{Voice, synthesize_16k};
use interfaces::msg::command::Game;
use speech_recognition::confidence::ConfidenceConfig;
use speech_recognition::{Recognizer, RecognizerConfig};

fn env<T: std::str::FromStr>(k: &str) -> Option<T> {
    std::env::var(k).ok().and_then(|s| s.parse().ok())
}

fn main() {
    let mut args = std::env::args().skip(1);
    let game = Game::from_name(&args.next().unwrap()).unwrap();
    let mut cfg = RecognizerConfig::default();
    if let Some(a) = env("SCALE") {
        cfg.confidence = ConfidenceConfig {
            acoustic_scale: a,
            ..cfg.confidence
        };
    }
    if let Some(w) = env("FILLER_W") {
        cfg.filler_weight = w;
    }
    if let Some(n) = env("NBEST_N") {
        cfg.nbest = n;
    }
    let mut rec = Recognizer::shipped(game, cfg).unwrap();
    let voice = Voice {
        voice: env("VOICE").unwrap_or_else(|| "en-us".into()),
        speed_wpm: env("SPEED").unwrap_or(Voice::default().speed_wpm),
        ..Voice::default()
    };
    for (i, s) in args.enumerate() {
        let mut a = synthesize_16k(&s, &voice).unwrap();
        if let Some(snr) = env::<f64>("SNR") {
            a = mix_at_snr(
                &a,
                snr,
                NoiseKind::White,
                0.6,
                0.8,
                &mut NoiseRng::new(i as u64 + 1),
            );
        }
        if std::env::var("PIPE").is_ok() {
            // Through the end-pointer, as the component does.
            let mut got = rec.push(&a).unwrap();
            got.extend(rec.flush().unwrap());
            for r in got {
                println!(
                    "{s:?} -> {:?} {:?} conf {:.3} llr/frame {:.3} p_in {:.3} snr {:.1} decode {:.3}s",
                    r.text,
                    r.command,
                    r.confidence,
                    r.llr_per_frame,
                    r.p_in_grammar,
                    r.snr_db,
                    r.decode_s
                );
            }
            continue;
        }
        if let Ok(f) = std::env::var("DECODER_JSGF") {
            // Calibration of raw decoder texts: decode with the given JSGF text.
            let mut line = format!("{s:?}");
            let mut scores = vec![];
            for f in f.split(',') {
                let text = std::fs::read_to_string(f).unwrap();
                let mut d = pocketsphinx_sys_min::decoder::Decoder::new(
                    &pocketsphinx_sys_min::decoder::DecoderConfig {
                        nbest: env("NBEST_N").unwrap_or(0),
                        extra_args: std::env::var("EXTRA")
                            .unwrap_or_default()
                            .split_whitespace()
                            .collect::<Vec<_>>()
                            .chunks(2)
                            .map(|c| (c[0].to_string(), c.get(1).unwrap_or(&"").to_string()))
                            .collect(),
                        ..pocketsphinx_sys_min::decoder::DecoderConfig::debian()
                    },
                    f,
                    Some(&text),
                )
                .unwrap();
                let h = d.decode(&a).unwrap();
                line += &format!(" | {:?} {:.4}", h.text, h.path_score_ln);
                scores.push(h.path_score_ln);
            }
            if scores.len() == 2 {
                line += &format!(" | diff {:.4}", scores[0] - scores[1]);
            }
            println!("{line}");
            continue;
        }
        let r = rec.decode_all(&a).unwrap();
        println!(
            "{s:?} ({:.2}s) -> {:?} {:?} conf {:.3} llr/frame {:.3} decode {:.3}s",
            a.len() as f64 / 16000.0,
            r.text,
            r.command,
            r.confidence,
            r.llr_per_frame,
            r.decode_s
        );
        if std::env::var("NBEST").is_ok() {
            for (t, sc) in r.nbest.iter().take(8) {
                println!("      {sc:>10.2} {t}");
            }
        }
    }
}
