#![allow(clippy::unwrap_used)]
//! Speech recognition benchmark: every command of both games (touch the ball, the Nao coach),
//! said by 6 espeak-ng voices at 3 speeds (and pitches), clean and mixed with white noise at 20,
//! 10 and 5 dB SNR, plus out-of-grammar sentences, through the recognizer as a live stream (20 ms
//! chunks: end-pointer, both searches fed while the person speaks), in the component's default
//! configuration: the adapted acoustic model when it is built (`--acoustic-model DIR|stock` to
//! choose), `--denoise` to add the enhancement.
//!
//! Figures per game and SNR: command accuracy (the right command, not rejected), the errors split
//! by cause (the end-pointer did not cut exactly one utterance / one utterance but wrong words /
//! right words rejected as out of grammar), false accepts (out-of-grammar speech mapped to a
//! command with confidence at or above the dialog's high threshold 0.7), real-time factor, and
//! the latency from the end of speech (the last sample of the clean speech louder than 300/32768)
//! to the result, counting the stream time until the chunk in which the end-pointer cut it plus
//! the processing of that chunk.
//!
//! Evaluation set only: these 6 voices and noise seeds 1.. were not used to tune anything; the
//! tuning (PocketSphinx options, enhancement, end-pointer, confidence calibration) used other
//! voices (en-gb-x-rp, en-029, en-us+m1, en-gb+f2) and noise seeds from 1000
//! (`examples/speech_errors.rs tune`), and the acoustic model's adaptation corpus yet other
//! voices (`speech_recognition::adapt::VOICES`, checked here). All are espeak-ng voices, so the
//! adapted model knows espeak-ng's speech: the figures are for the simulated person.
//!
//! With `--write-wav DIR` every test utterance is also written as `<n>.wav`, with
//! `<n> <game> <snr> <phrase>` lines in `DIR/truth.tsv`, for the `pocketsphinx_continuous`
//! comparison of `scripts/bench.d/speech.sh`. The last line printed is a JSON summary.

use audio::signal::{NoiseKind, NoiseRng, mix_at_snr};
use audio::synth::synthesize_16k;
use audio::wav::{Pcm, encode};
use interfaces::msg::command::{Command, Game};
use speech_recognition::model::AcousticModel;
use speech_recognition::{Recognized, Recognizer, RecognizerConfig};

mod corpus;
use corpus::{EVAL_VOICES as VOICES, LEAD_S, SPEEDS, TRAIL_S, speech_end_s, voice};

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

const SNRS: [f64; 4] = [f64::INFINITY, 20.0, 10.0, 5.0];
const HIGH: f64 = 0.7;
const CHUNK: usize = 320;

/// Feed `audio` as a live stream; the results with their end-of-speech-to-result latency (s)
/// given the speech ends at `speech_end_s` on this clip.
fn stream(rec: &mut Recognizer, audio: &[i16], speech_end_s: f64) -> Vec<(Recognized, f64)> {
    let mut out = vec![];
    let mut pos = 0;
    for chunk in audio.chunks(CHUNK) {
        pos += chunk.len();
        let t = std::time::Instant::now();
        let got = rec.push(chunk).unwrap();
        let done = t.elapsed().as_secs_f64();
        for r in got {
            out.push((r, pos as f64 / 16000.0 - speech_end_s + done));
        }
    }
    if let Some(r) = rec.flush().unwrap() {
        out.push((r, f64::NAN));
    }
    out
}

fn pct(p: &[f64], q: f64) -> f64 {
    p.get(((p.len() as f64 - 1.0) * q).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

fn snr_name(snr: f64) -> String {
    if snr.is_finite() {
        format!("{snr}")
    } else {
        "clean".into()
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let denoise = args.iter().any(|a| a == "--denoise");
    let model_arg = args
        .iter()
        .position(|a| a == "--acoustic-model")
        .and_then(|i| args.get(i + 1))
        .cloned();
    let model = AcousticModel::resolve(model_arg.as_deref()).unwrap();
    // The adaptation corpus never says a word in an evaluation or tuning voice.
    for v in speech_recognition::adapt::VOICES {
        assert!(
            !VOICES.contains(&v) && !corpus::TUNE_VOICES.contains(&v),
            "adaptation voice {v} is an evaluation or tuning voice"
        );
    }
    println!(
        "configuration: the component's default{}; acoustic model {}",
        if denoise { " plus --denoise" } else { "" },
        model.describe()
    );
    let wav_dir = args
        .iter()
        .position(|a| a == "--write-wav")
        .and_then(|i| args.get(i + 1))
        .map(std::path::PathBuf::from);
    if let Some(d) = &wav_dir {
        std::fs::create_dir_all(d).unwrap();
    }
    let mut truth = String::new();
    let mut n_wav = 0;
    let (mut audio_s, mut busy_s) = (0.0, 0.0);
    let mut lat_all: Vec<f64> = vec![];
    let mut json: Vec<String> = vec![];
    let (mut all_ok10, mut all_n10) = (0, 0);
    for game in Game::ALL {
        // The component's default configuration (see `RecognizerConfig`), with the chosen
        // acoustic model and optionally the enhancement.
        let cfg = RecognizerConfig {
            denoise: denoise.then(Default::default),
            acoustic_model: model.clone(),
            ..RecognizerConfig::default()
        };
        let mut rec = Recognizer::shipped(game, cfg).unwrap();
        // The clean speech of every (voice, speed, command), synthesized once.
        let mut said = vec![];
        for (vi, v) in VOICES.iter().enumerate() {
            for si in 0..SPEEDS.len() {
                let voice = voice(v, si);
                for c in Command::of_game(game) {
                    let speech = synthesize_16k(c.phrase(), &voice).unwrap();
                    said.push((vi, si, c, speech));
                }
            }
        }
        for snr in SNRS {
            let (mut ok, mut n, mut vad, mut dec, mut rej, mut right_sure) = (0, 0, 0, 0, 0, 0);
            let mut lat = vec![];
            for (vi, si, c, speech) in &said {
                let a = mix_at_snr(
                    speech,
                    snr,
                    NoiseKind::White,
                    LEAD_S,
                    TRAIL_S,
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
                    truth.push_str(&format!(
                        "{n_wav}\t{}\t{}\t{}\n",
                        game.name(),
                        snr_name(snr),
                        c.phrase()
                    ));
                    n_wav += 1;
                }
                let end = speech_end_s(speech);
                let t = std::time::Instant::now();
                let got = stream(&mut rec, &a, end);
                busy_s += t.elapsed().as_secs_f64();
                audio_s += a.len() as f64 / 16000.0;
                n += 1;
                if got.len() != 1 {
                    vad += 1;
                } else if Command::from_phrase(game, &got[0].0.text) != *c {
                    dec += 1;
                } else if got[0].0.command != *c {
                    rej += 1;
                } else {
                    ok += 1;
                    if got[0].0.confidence >= HIGH {
                        right_sure += 1;
                    }
                }
                lat.extend(got.iter().map(|g| g.1).filter(|l| l.is_finite()));
            }
            lat.sort_by(f64::total_cmp);
            lat_all.extend(&lat);
            if snr == 10.0 {
                all_ok10 += ok;
                all_n10 += n;
            }
            eprintln!(
                "{:5} SNR {:>5}: {ok}/{n} = {:.3} right command ({right_sure} with confidence >= {HIGH}); errors: end-pointer {vad}, wrong words {dec}, rejected {rej}; end of speech -> result p50 {:.3} s p90 {:.3} s",
                game.name(),
                snr_name(snr),
                ok as f64 / n as f64,
                pct(&lat, 0.5),
                pct(&lat, 0.9),
            );
            json.push(format!(
                "\"{}_accuracy_{}\": {:.4}",
                game.name(),
                snr_name(snr),
                ok as f64 / n as f64
            ));
        }
        let (mut fa, mut n_oog, mut asked) = (0, 0, 0);
        for (i, s) in OOG.iter().enumerate() {
            for v in VOICES {
                let voice = audio::synth::Voice {
                    voice: v.to_string(),
                    ..Default::default()
                };
                let speech = synthesize_16k(s, &voice).unwrap();
                let a = mix_at_snr(
                    &speech,
                    20.0,
                    NoiseKind::White,
                    LEAD_S,
                    TRAIL_S,
                    &mut NoiseRng::new(i as u64 + 100),
                );
                let got = stream(&mut rec, &a, f64::NAN);
                n_oog += 1;
                let cmd = |r: &&(Recognized, f64)| r.0.command != Command::None;
                if got.iter().filter(cmd).any(|r| r.0.confidence >= HIGH) {
                    fa += 1;
                } else if got.iter().filter(cmd).any(|r| r.0.confidence >= 0.3) {
                    asked += 1;
                }
            }
        }
        eprintln!(
            "{:5} out of grammar: false accepts {fa}/{n_oog}, {asked} would be asked \"Did you say ...?\"",
            game.name()
        );
        json.push(format!(
            "\"{}_false_accept_rate\": {:.4}, \"{}_oog_confirm_rate\": {:.4}",
            game.name(),
            fa as f64 / n_oog as f64,
            game.name(),
            asked as f64 / n_oog as f64
        ));
    }
    lat_all.sort_by(f64::total_cmp);
    eprintln!(
        "both games, 10 dB: {all_ok10}/{all_n10} = {:.3}; real-time factor {:.3}; end of speech -> result p50 {:.3} s p90 {:.3} s p99 {:.3} s (end-pointer hangover {} s)",
        all_ok10 as f64 / all_n10 as f64,
        busy_s / audio_s,
        pct(&lat_all, 0.5),
        pct(&lat_all, 0.9),
        pct(&lat_all, 0.99),
        speech_recognition::vad::VadConfig::default().hangover_s
    );
    if let Some(d) = &wav_dir {
        std::fs::write(d.join("truth.tsv"), truth).unwrap();
    }
    println!(
        "{{{}, \"accuracy_10db_both\": {:.4}, \"rtf\": {:.4}, \"end_of_speech_to_result_p50_s\": {:.4}, \"end_of_speech_to_result_p90_s\": {:.4}, \"endpoint_hangover_s\": {}, \"acoustic_model_adapted\": {}}}",
        json.join(", "),
        all_ok10 as f64 / all_n10 as f64,
        busy_s / audio_s,
        pct(&lat_all, 0.5),
        pct(&lat_all, 0.9),
        speech_recognition::vad::VadConfig::default().hangover_s,
        !model.stock
    );
}
