#![allow(clippy::unwrap_used)]
//! Speech recognition benchmark: every command of the touch game said by espeak-ng voices at
//! several speeds and SNRs, plus out-of-grammar sentences, through the recognizer (end-pointer and
//! decoders); accuracy, false accepts (out-of-grammar speech mapped to a command with confidence
//! at or above the dialog's high threshold 0.7), real-time factor and decode latency. With
//! `--write-wav DIR` every test utterance is also written as `<n>.wav` with the expected command in
//! `DIR/truth.tsv`, for the `pocketsphinx_continuous` comparison of `scripts/bench.d/speech.sh`.
//! The last line printed is a JSON summary.

use interfaces::msg::command::{Command, Game};
use speech_generator::audio::{NoiseKind, NoiseRng, mix_at_snr};
use speech_generator::synth::{Voice, synthesize_16k};
use speech_generator::wav::{Pcm, encode};
use speech_recognition::{Recognizer, RecognizerConfig};

const OOG: &[&str] = &[
    "what a lovely day it is today",
    "the weather is cold in the mountains",
    "can you bring me a cup of coffee",
    "seven hundred and twenty three",
    "my brother lives in barcelona",
    "please open the window",
    "good morning",
    "thank you very much",
    "where is the kitchen",
    "I would like some tea",
    "it is raining outside",
    "how old are you",
];

/// One test utterance: hypothesis right, confidence, log-likelihood ratio per frame.
type Scored = (bool, f64, f64);

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let wav_dir = args
        .iter()
        .position(|a| a == "--write-wav")
        .and_then(|i| args.get(i + 1))
        .map(std::path::PathBuf::from);
    if let Some(d) = &wav_dir {
        std::fs::create_dir_all(d).unwrap();
    }
    let mut truth = String::new();
    let voices = [
        "en-us",
        "en-gb",
        "en-us+f3",
        "en-gb-scotland",
        "en-us+m3",
        "en-gb+f4",
    ];
    let speeds = [130, 175, 220];
    let snrs = [30.0, 20.0, 10.0, 5.0];
    let mut rec = Recognizer::shipped(Game::Touch, RecognizerConfig::default()).unwrap();
    let (mut audio_s, mut decode_s) = (0.0, 0.0);
    let mut lat = vec![];
    let mut n_wav = 0;
    let mut per_snr = vec![];
    // Per SNR: (hypothesis right, confidence, llr per frame) of every utterance.
    let mut detail: Vec<(f64, Vec<Scored>)> = vec![];
    let (high, low) = (0.7, 0.3);
    for snr in snrs {
        let (mut ok, mut n) = (0, 0);
        let mut d = vec![];
        for (vi, v) in voices.iter().enumerate() {
            for (si, s) in speeds.iter().enumerate() {
                let voice = Voice {
                    voice: v.to_string(),
                    speed_wpm: *s,
                    pitch: 35 + 10 * si as u8,
                };
                for c in Command::of_game(Game::Touch) {
                    let speech = synthesize_16k(c.phrase(), &voice).unwrap();
                    let a = mix_at_snr(
                        &speech,
                        snr,
                        NoiseKind::White,
                        0.6,
                        0.8,
                        &mut NoiseRng::new((vi * 7 + si) as u64 + 1),
                    );
                    if let Some(d) = &wav_dir {
                        std::fs::write(
                            d.join(format!("{n_wav}.wav")),
                            encode(&Pcm {
                                sample_rate_hz: 16000,
                                channels: 1,
                                samples: a.clone(),
                            }),
                        )
                        .unwrap();
                        truth.push_str(&format!("{n_wav}\t{snr}\t{}\n", c.phrase()));
                        n_wav += 1;
                    }
                    audio_s += a.len() as f64 / 16000.0;
                    let mut got = rec.push(&a).unwrap();
                    got.extend(rec.flush().unwrap());
                    for r in &got {
                        decode_s += r.decode_s;
                        lat.push(r.decode_s);
                    }
                    n += 1;
                    if got.len() == 1 && got[0].command == c {
                        ok += 1;
                    }
                    let right =
                        got.len() == 1 && Command::from_phrase(Game::Touch, &got[0].text) == c;
                    match got.first() {
                        Some(r) => d.push((right, r.confidence, r.llr_per_frame)),
                        None => d.push((false, 0.0, f64::NAN)),
                    }
                }
            }
        }
        let share = |f: &dyn Fn(&Scored) -> bool| {
            d.iter().filter(|x| f(x)).count() as f64 / d.len().max(1) as f64
        };
        eprintln!(
            "SNR {snr:>4} dB: {ok}/{n} = {:.3} command (confidence >= {low}); hypothesis right {:.3}; right and >= {high} {:.3}, right and in [{low}, {high}) {:.3}; wrong but >= {high} {:.3}",
            ok as f64 / n as f64,
            share(&|x| x.0),
            share(&|x| x.0 && x.1 >= high),
            share(&|x| x.0 && x.1 >= low && x.1 < high),
            share(&|x| !x.0 && x.1 >= high),
        );
        per_snr.push((snr, ok as f64 / n as f64));
        detail.push((snr, d));
    }
    if std::env::var("SPEECH_BENCH_DETAIL").is_ok() {
        for (snr, d) in &detail {
            for (right, c, l) in d {
                println!(
                    "detail\t{snr}\t{}\t{c:.4}\t{l:.4}",
                    if *right { "right" } else { "wrong" }
                );
            }
        }
    }
    let (mut fa, mut n_oog, mut asked) = (0, 0, 0);
    for (i, s) in OOG.iter().enumerate() {
        for v in voices {
            let voice = Voice {
                voice: v.to_string(),
                ..Voice::default()
            };
            let a = mix_at_snr(
                &synthesize_16k(s, &voice).unwrap(),
                20.0,
                NoiseKind::White,
                0.6,
                0.8,
                &mut NoiseRng::new(i as u64 + 100),
            );
            let mut got = rec.push(&a).unwrap();
            got.extend(rec.flush().unwrap());
            n_oog += 1;
            for r in &got {
                if std::env::var("SPEECH_BENCH_DETAIL").is_ok() {
                    println!(
                        "detail\toog\t{:?}\t{:.4}\t{:.4}",
                        r.text, r.confidence, r.llr_per_frame
                    );
                }
            }
            if got
                .iter()
                .any(|r| r.command != Command::None && r.confidence >= low && r.confidence < high)
            {
                asked += 1;
            }
            if got
                .iter()
                .any(|r| r.command != Command::None && r.confidence >= 0.7)
            {
                fa += 1;
            }
        }
    }
    lat.sort_by(f64::total_cmp);
    let p = |q: f64| {
        lat.get(((lat.len() as f64 - 1.0) * q).round() as usize)
            .copied()
            .unwrap_or(0.0)
    };
    eprintln!(
        "false accepts {fa}/{n_oog} (and {asked} would be asked \"Did you say ...?\"); RTF {:.3}; decode p50 {:.3} s p99 {:.3} s",
        decode_s / audio_s,
        p(0.5),
        p(0.99)
    );
    if let Some(d) = &wav_dir {
        std::fs::write(d.join("truth.tsv"), truth).unwrap();
    }
    let acc: Vec<String> = per_snr
        .iter()
        .map(|(s, a)| format!("\"accuracy_snr{s}\": {a:.4}"))
        .collect();
    println!(
        "{{{}, \"false_accept_rate\": {:.4}, \"oog_confirm_rate\": {:.4}, \"rtf\": {:.4}, \"decode_p50_s\": {:.4}, \"decode_p99_s\": {:.4}, \"endpoint_hangover_s\": {}}}",
        acc.join(", "),
        fa as f64 / n_oog as f64,
        asked as f64 / n_oog as f64,
        decode_s / audio_s,
        p(0.5),
        p(0.99),
        speech_recognition::vad::VadConfig::default().hangover_s
    );
}
