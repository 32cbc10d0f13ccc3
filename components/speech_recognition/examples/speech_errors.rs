#![allow(clippy::unwrap_used)]
//! Where the recognition errors come from (tuning aid): every command of a game said by a set of
//! voices at given SNRs, each error classified as an end-pointer error (not exactly one
//! utterance cut), a decoding error (one utterance, wrong words) or a confidence rejection (right
//! words, rejected as out of grammar). `speech_errors <touch|coach> <tune|eval> <condition>...`,
//! a condition as the benchmark names it (`clean`, `10` for white noise at 10 dB, `reverb`,
//! `babble_10`, `fan_10`).
//! Environment: `PS_ARGS` ("-name value ..." decoder options, e.g. `-hmm DIR` for another
//! acoustic model), `HANGOVER`, `MIN_SPEECH` (s), `START_DB`, `START_FRAMES` (end-pointer),
//! `ROBUST=0` (PocketSphinx's own noise settings), `DENOISE=1` (the enhancement; `GFLOOR`,
//! `OVERSUB` tune it), `VERBOSE` (list every error).
use audio::synth::synthesize_16k;
use interfaces::msg::command::{Command, Game};
use pocketsphinx_sys_min::decoder::DecoderConfig;
use speech_recognition::grammar::{Grammar, grammar_dir};
use speech_recognition::{Recognizer, RecognizerConfig};

mod corpus;
use corpus::{
    BABBLE_TALKERS, Condition, EVAL_BABBLE, EVAL_VOICES, SPEEDS, TUNE_BABBLE, TUNE_VOICES,
    babble_talkers, in_condition, speech_end_in, voice,
};

fn main() {
    let mut args = std::env::args().skip(1);
    let game = Game::from_name(&args.next().unwrap()).unwrap();
    let set = args.next().unwrap();
    let conditions: Vec<Condition> = args
        .map(|s| Condition::parse(&s).unwrap_or_else(|| panic!("no condition {s:?}")))
        .collect();
    let (voices, background): (&[&str], _) = if set == "tune" {
        (&TUNE_VOICES, TUNE_BABBLE)
    } else {
        (&EVAL_VOICES, EVAL_BABBLE)
    };
    let talkers = babble_talkers(voices, background);
    let seed0 = if set == "tune" { 1000 } else { 1 };
    let mut dc = DecoderConfig::debian();
    if let Ok(a) = std::env::var("PS_ARGS") {
        let w: Vec<&str> = a.split_whitespace().collect();
        for p in w.chunks(2) {
            dc.extra_args.push((p[0].into(), p[1].into()));
        }
    }
    let mut cfg = RecognizerConfig {
        noise_robust: std::env::var("ROBUST").as_deref() != Ok("0"),
        denoise: (std::env::var("DENOISE").as_deref() == Ok("1")).then(Default::default),
        ..RecognizerConfig::default()
    };
    if let Some(h) = std::env::var("HANGOVER").ok().and_then(|s| s.parse().ok()) {
        cfg.vad.hangover_s = h;
    }
    if let Some(h) = std::env::var("MIN_SPEECH")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        cfg.vad.min_speech_s = h;
    }
    if let Some(h) = std::env::var("START_DB").ok().and_then(|s| s.parse().ok()) {
        cfg.vad.start_db = h;
    }
    if let Some(h) = std::env::var("START_FRAMES")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        cfg.vad.start_frames = h;
    }
    if let Some(f) = std::env::var("GFLOOR").ok().and_then(|s| s.parse().ok()) {
        cfg.denoise.get_or_insert_with(Default::default).gain_floor = f;
    }
    if let Some(f) = std::env::var("OVERSUB").ok().and_then(|s| s.parse().ok()) {
        cfg.denoise
            .get_or_insert_with(Default::default)
            .over_subtraction = f;
    }
    let g = Grammar::load(&grammar_dir().join(format!("{}.gram", game.name()))).unwrap();
    // The configured acoustic model (a `-hmm` in `PS_ARGS` wins).
    dc.hmm_dir = cfg.acoustic_model.dir.clone();
    let mut rec = Recognizer::with_grammar(game, g, cfg, &dc).unwrap();
    for cond in conditions {
        let (mut n, mut ok, mut vad, mut dec, mut rej) = (0, 0, 0, 0, 0);
        let mut lines = vec![];
        let mut lat: Vec<f64> = vec![];
        for (vi, v) in voices.iter().enumerate() {
            for (si, s) in SPEEDS.iter().enumerate() {
                let voice = voice(v, si);
                for c in Command::of_game(game) {
                    for ph in c.phrases() {
                        let speech = synthesize_16k(ph, &voice).unwrap();
                        let others: Vec<Vec<i16>> = (0..talkers.len())
                            .filter(|&i| i != vi)
                            .take(BABBLE_TALKERS)
                            .map(|i| talkers[i].clone())
                            .collect();
                        let a =
                            in_condition(&speech, cond, n, &others, seed0 + (vi * 7 + si) as u64);
                        let end = speech_end_in(&speech, cond);
                        let mut got = vec![];
                        let mut pos = 0;
                        for chunk in a.chunks(if std::env::var("WHOLE").is_ok() {
                            a.len()
                        } else {
                            320
                        }) {
                            pos += chunk.len();
                            let t = std::time::Instant::now();
                            let r = rec.push(chunk).unwrap();
                            if !r.is_empty() {
                                lat.push(pos as f64 / 16000.0 - end + t.elapsed().as_secs_f64());
                            }
                            got.extend(r);
                        }
                        got.extend(rec.flush().unwrap());
                        n += 1;
                        let kind = if got.len() != 1 {
                            vad += 1;
                            "vad"
                        } else if Command::from_phrase(game, &got[0].text) != c {
                            dec += 1;
                            "decode"
                        } else if got[0].command != c {
                            rej += 1;
                            "reject"
                        } else {
                            ok += 1;
                            continue;
                        };
                        lines.push(format!(
                            "  {kind:6} {v} {s} {ph:?} -> {:?}",
                            got.iter()
                                .map(|r| format!(
                                    "{:?} p={:.2} {:.2}-{:.2}s",
                                    r.text, r.p_in_grammar, r.start_s, r.end_s
                                ))
                                .collect::<Vec<_>>()
                        ));
                    }
                }
            }
        }
        if std::env::var("VERBOSE").is_ok() {
            for l in &lines {
                println!("{l}");
            }
        }
        lat.sort_by(f64::total_cmp);
        println!(
            "{game:?} {set} {}: {ok}/{n} = {:.3}; end-pointer {vad}, decoding {dec}, rejected {rej}; end of speech to result p50 {:.3} s p90 {:.3} s",
            cond.name(),
            ok as f64 / n as f64,
            lat.get(lat.len() / 2).copied().unwrap_or(f64::NAN),
            lat.get(lat.len() * 9 / 10).copied().unwrap_or(f64::NAN),
        );
    }
}
