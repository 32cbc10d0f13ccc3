#![allow(clippy::unwrap_used)]
#![expect(
    clippy::disallowed_methods,
    reason = "a benchmark: it measures the recognizer's compute time on the wall"
)]
//! Speech recognition benchmark: every command of both games (touch the ball, the Nao coach),
//! said by 6 espeak-ng voices at 3 speeds (and pitches), in seven conditions (`corpus::Condition`):
//! clean; white noise at 20, 10 and 5 dB SNR; reverberant rooms (RT60 0.3, 0.5, 0.8 s); three
//! other people talking at 10 dB (babble, heard for 2.5 s before the command); a fan at 10 dB.
//! Each condition also has out-of-grammar sentences, and babble also stretches of talk with no
//! command. Everything goes through the recognizer as a live stream (20 ms chunks: end-pointer,
//! both searches fed while the person speaks), in the component's default configuration: the
//! adapted acoustic model when it is built (`--acoustic-model DIR|stock` to choose), `--denoise`
//! to add the enhancement. `--conditions clean,babble_10` measures some conditions only.
//! `--family flite|festival|other` has the commands said by voices of another synthesizer family
//! (`corpus::OTHER_FAMILY_VOICES`, built from recordings of real speakers) instead of espeak-ng's;
//! the background talk stays espeak-ng's. `--speeds 175` says every command at that speed only
//! (of 130, 175, 220 words per minute).
//!
//! Figures per game and condition: command accuracy (the clip gave the dialog one command, the
//! right one, not rejected; other utterances cut from it out of grammar, background talk the
//! dialog ignores, are counted apart), the errors split by cause (the end-pointer did not cut
//! exactly one utterance / one utterance but wrong words / right words rejected as out of
//! grammar), false accepts (a command the dialog would take at once, confidence at or above
//! its high threshold 0.7, that nobody gave: wrong words, out-of-grammar speech or background
//! talk taken for a command; per utterance heard), real-time factor, and the latency from the
//! end of speech (the last sample of the clean speech louder than 300/32768) to the result,
//! counting the stream time until the chunk in which the end-pointer cut it plus the processing
//! of that chunk.
//!
//! Evaluation set only: these 6 voices, their background talk (`corpus::EVAL_BABBLE`, said by
//! the other evaluation voices) and noise seeds 1.. were not used to tune anything; the tuning
//! (PocketSphinx options, enhancement, end-pointer, confidence calibration) used other voices
//! (en-gb-x-rp, en-029, en-us+m1, en-gb+f2), other background sentences and noise seeds from
//! 1000 (`examples/speech_errors.rs tune`), and the acoustic model's adaptation corpus yet other
//! voices and sentences (`speech_recognition::adapt::VOICES`, checked here). All are espeak-ng
//! voices, so the adapted model knows espeak-ng's speech: the figures are for the simulated
//! person.
//!
//! With `--write-wav DIR` every test command is also written as `<n>.wav`, with
//! `<n> <game> <condition> <phrase>` lines in `DIR/truth.tsv`, and every phrase of the grammars
//! as `<game> <phrase> <command>` lines in `DIR/phrases.tsv` (a synonym is the same command),
//! for the `pocketsphinx_continuous` comparison of `scripts/bench.d/speech.sh`. The last line
//! printed is a JSON summary.

use audio::signal::{NoiseRng, babble};
use audio::synth::synthesize_16k;
use audio::wav::{Pcm, encode};
use interfaces::msg::command::{Command, Game};
use speech_recognition::model::AcousticModel;
use speech_recognition::{Recognized, Recognizer, RecognizerConfig};

mod corpus;
use corpus::{
    BABBLE_TALKERS, Condition, EVAL_BABBLE, EVAL_VOICES, SPEEDS, babble_talkers, family_voices,
    in_condition, speech_end_in, voice,
};

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

/// Stretches of background talk with no command, per game (babble conditions).
const TALK_ALONE: usize = 24;
/// How long each is (s).
const TALK_ALONE_S: f64 = 6.0;
const HIGH: f64 = 0.7;
const CHUNK: usize = 320;

/// Feed `audio` as a live stream; the results with their end-of-speech-to-result latency (s)
/// given the speech ends at `speech_end_s` on this clip. The stream goes on into the next clip
/// (no flush), as a microphone's does: an utterance still open at a clip's end is the next
/// clip's. (Ending the stream after each clip kept talk that had opened an utterance from ever
/// becoming the end-pointer's background, which no microphone does; it also decoded whole
/// clips that the end-pointer had not cut.)
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
    out
}

/// The end of a stream of clips (commands, out-of-grammar sentences, talk alone: each kind is
/// a stream of its own, so that what one kind leaves open is not scored as the next's): an
/// utterance still open is heard too, and counted among the false accepts if it is a sure
/// command.
fn end_stream(rec: &mut Recognizer, t: &mut Tally) {
    if let Some(r) = rec.flush().unwrap() {
        t.heard += 1;
        if r.command != Command::None && r.confidence >= HIGH {
            t.false_accepts += 1;
        }
    }
}

fn pct(p: &[f64], q: f64) -> f64 {
    p.get(((p.len() as f64 - 1.0) * q).round() as usize)
        .copied()
        .unwrap_or(f64::NAN)
}

/// The background talkers for a command said by voice `vi`: the first [`BABBLE_TALKERS`] others.
fn others(talkers: &[Vec<i16>], vi: usize) -> Vec<Vec<i16>> {
    talkers
        .iter()
        .enumerate()
        .filter(|(i, _)| *i != vi)
        .take(BABBLE_TALKERS)
        .map(|(_, t)| t.clone())
        .collect()
}

/// Counts of one game in one condition.
#[derive(Default)]
struct Tally {
    n: usize,
    ok: usize,
    /// Right, with other utterances cut from the clip too, all out of grammar (background
    /// talk, which the dialog ignores).
    ok_with_talk: usize,
    vad: usize,
    dec: usize,
    rej: usize,
    right_sure: usize,
    /// Commands taken at once that nobody gave, and the utterances they were taken among.
    false_accepts: usize,
    heard: usize,
    oog: usize,
    oog_false: usize,
    oog_asked: usize,
    alone: usize,
    alone_false: usize,
    alone_utterances: usize,
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
    let family = args
        .iter()
        .position(|a| a == "--family")
        .and_then(|i| args.get(i + 1))
        .map_or("espeak", String::as_str);
    let voices = family_voices(family)
        .unwrap_or_else(|| panic!("no voice family {family:?} (espeak, flite, festival or other)"));
    // The speeds (indices into SPEEDS) every voice says every command at.
    let speeds: Vec<usize> = match args.iter().position(|a| a == "--speeds") {
        None => (0..SPEEDS.len()).collect(),
        Some(i) => args
            .get(i + 1)
            .map(String::as_str)
            .unwrap_or("")
            .split(',')
            .map(|w| {
                SPEEDS
                    .iter()
                    .position(|s| s.to_string() == w)
                    .unwrap_or_else(|| panic!("--speeds: {w:?} is not one of {SPEEDS:?}"))
            })
            .collect(),
    };
    // The adaptation corpus never says a word in an evaluation or tuning voice.
    for v in speech_recognition::adapt::VOICES {
        assert!(
            !EVAL_VOICES.contains(&v)
                && !corpus::TUNE_VOICES.contains(&v)
                && !corpus::OTHER_FAMILY_VOICES.contains(&v),
            "adaptation voice {v} is an evaluation or tuning voice"
        );
    }
    println!(
        "configuration: the component's default{}; acoustic model {}; the player's voices: {family} ({}) at {:?} words per minute",
        if denoise { " plus --denoise" } else { "" },
        model.describe(),
        voices.join(", "),
        speeds.iter().map(|&i| SPEEDS[i]).collect::<Vec<_>>()
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
    let only: Option<Vec<Condition>> = args
        .iter()
        .position(|a| a == "--conditions")
        .and_then(|i| args.get(i + 1))
        .map(|l| {
            l.split(',')
                .map(|c| Condition::parse(c).unwrap_or_else(|| panic!("no condition {c:?}")))
                .collect()
        });
    let conditions: Vec<Condition> = only.unwrap_or_else(|| Condition::ALL.to_vec());
    println!(
        "conditions: {}",
        conditions
            .iter()
            .map(Condition::name)
            .collect::<Vec<_>>()
            .join(", ")
    );
    // The background talkers: each espeak-ng evaluation voice saying the evaluation's
    // background sentences (a command's babble is the other voices; for another family's
    // player, the first three).
    let talkers = babble_talkers(&EVAL_VOICES, EVAL_BABBLE);
    // (ok, n) over both games per condition.
    let mut both: std::collections::BTreeMap<String, (usize, usize)> = Default::default();
    let mut worst_false = (0.0f64, String::new());
    for game in Game::ALL {
        // The component's default configuration (see `RecognizerConfig`), with the chosen
        // acoustic model and optionally the enhancement.
        let cfg = RecognizerConfig {
            denoise: denoise.then(Default::default),
            ..RecognizerConfig::for_model(model.clone())
        };
        // The clean speech of every (voice, speed, command), synthesized once.
        let mut said = vec![];
        for (vi, v) in voices.iter().enumerate() {
            for &si in &speeds {
                let voice = voice(v, si);
                for c in Command::of_game(game) {
                    let speech = synthesize_16k(c.phrase(), &voice).unwrap();
                    said.push((vi, si, c, speech));
                }
            }
        }
        for &cond in &conditions {
            // Each condition is a room the robot listens in from the start: a recognizer of its
            // own (its end-pointer learns that room's noise), fed one continuous stream.
            let mut rec = Recognizer::shipped(game, cfg.clone()).unwrap();
            let mut t = Tally::default();
            let mut lat = vec![];
            for (clip, (vi, si, c, speech)) in said.iter().enumerate() {
                let seed = (vi * 7 + si) as u64 + 1;
                let a = in_condition(speech, cond, clip, &others(&talkers, *vi), seed);
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
                        cond.name(),
                        c.phrase()
                    ));
                    n_wav += 1;
                }
                let end = speech_end_in(speech, cond);
                let started = std::time::Instant::now();
                let got = stream(&mut rec, &a, end);
                busy_s += started.elapsed().as_secs_f64();
                audio_s += a.len() as f64 / 16000.0;
                t.n += 1;
                t.heard += got.len().max(1);
                t.false_accepts += got
                    .iter()
                    .filter(|g| {
                        g.0.command != Command::None && g.0.command != *c && g.0.confidence >= HIGH
                    })
                    .count();
                // What the dialog acts on: the utterances not out of grammar.
                let commands: Vec<&Recognized> = got
                    .iter()
                    .map(|g| &g.0)
                    .filter(|r| r.command != Command::None)
                    .collect();
                if let [r] = commands[..]
                    && r.command == *c
                {
                    t.ok += 1;
                    if got.len() > 1 {
                        t.ok_with_talk += 1;
                    }
                    if r.confidence >= HIGH {
                        t.right_sure += 1;
                    }
                } else if got.len() != 1 {
                    t.vad += 1;
                } else if Command::from_phrase(game, &got[0].0.text) != *c {
                    t.dec += 1;
                } else {
                    t.rej += 1;
                }
                lat.extend(got.iter().map(|g| g.1).filter(|l| l.is_finite()));
            }
            end_stream(&mut rec, &mut t);
            // Out-of-grammar sentences, each voice, in the same condition.
            for (i, s) in OOG.iter().enumerate() {
                for (vi, v) in voices.iter().enumerate() {
                    let voice = audio::synth::Voice {
                        voice: v.to_string(),
                        ..Default::default()
                    };
                    let speech = synthesize_16k(s, &voice).unwrap();
                    let a = in_condition(
                        &speech,
                        cond,
                        i * voices.len() + vi,
                        &others(&talkers, vi),
                        i as u64 + 100,
                    );
                    let got = stream(&mut rec, &a, f64::NAN);
                    t.oog += 1;
                    t.heard += got.len().max(1);
                    let cmd = |r: &&(Recognized, f64)| r.0.command != Command::None;
                    let sure = got
                        .iter()
                        .filter(cmd)
                        .filter(|r| r.0.confidence >= HIGH)
                        .count();
                    t.false_accepts += sure;
                    if sure > 0 {
                        t.oog_false += 1;
                    } else if got.iter().filter(cmd).any(|r| r.0.confidence >= 0.3) {
                        t.oog_asked += 1;
                    }
                }
            }
            end_stream(&mut rec, &mut t);
            // Background talk and nothing else: no command may come of it.
            if let Condition::Babble(_) = cond {
                for k in 0..TALK_ALONE {
                    let mut rng =
                        NoiseRng::new((k as u64 + 500).wrapping_mul(0x9E37_79B9_7F4A_7C15));
                    let n = (TALK_ALONE_S * 16_000.0) as usize;
                    // The talk at the level it has under the commands.
                    let p = 10f64.powf(corpus::NOISE_DBFS / 10.0);
                    let a: Vec<i16> =
                        babble(&others(&talkers, k % EVAL_VOICES.len()), n, p, &mut rng)
                            .iter()
                            .map(|x| x.round().clamp(-32768.0, 32767.0) as i16)
                            .collect();
                    let got = stream(&mut rec, &a, f64::NAN);
                    t.alone += 1;
                    t.alone_utterances += got.len();
                    t.heard += got.len();
                    let sure = got
                        .iter()
                        .filter(|r| r.0.command != Command::None && r.0.confidence >= HIGH)
                        .count();
                    t.false_accepts += sure;
                    if sure > 0 {
                        t.alone_false += 1;
                    }
                }
            }
            end_stream(&mut rec, &mut t);
            lat.sort_by(f64::total_cmp);
            lat_all.extend(&lat);
            let e = both.entry(cond.name()).or_default();
            e.0 += t.ok;
            e.1 += t.n;
            let fa = t.false_accepts as f64 / t.heard.max(1) as f64;
            if fa >= worst_false.0 {
                worst_false = (fa, format!("{} {}", game.name(), cond.name()));
            }
            eprintln!(
                "{:5} {:>9}: {}/{} = {:.3} right command ({} with confidence >= {HIGH}, {} with other utterances cut beside it, out of grammar); errors: end-pointer {}, wrong words {}, rejected {}; end of speech -> result p50 {:.3} s p90 {:.3} s",
                game.name(),
                cond.name(),
                t.ok,
                t.n,
                t.ok as f64 / t.n as f64,
                t.right_sure,
                t.ok_with_talk,
                t.vad,
                t.dec,
                t.rej,
                pct(&lat, 0.5),
                pct(&lat, 0.9),
            );
            eprintln!(
                "{:5} {:>9}: false accepts {}/{} utterances = {:.4}; out of grammar: {} of {} taken, {} would be asked \"Did you say ...?\"{}",
                game.name(),
                cond.name(),
                t.false_accepts,
                t.heard,
                fa,
                t.oog_false,
                t.oog,
                t.oog_asked,
                if t.alone > 0 {
                    format!(
                        "; talk alone: {} stretches of {TALK_ALONE_S} s, {} utterances cut, {} taken for a command",
                        t.alone, t.alone_utterances, t.alone_false
                    )
                } else {
                    String::new()
                }
            );
            json.push(format!(
                "\"{g}_accuracy_{c}\": {:.4}, \"{g}_sure_right_{c}\": {:.4}, \"{g}_false_accept_rate_{c}\": {:.4}",
                t.ok as f64 / t.n as f64,
                t.right_sure as f64 / t.n as f64,
                fa,
                g = game.name(),
                c = cond.name(),
            ));
        }
    }
    // The targets' aggregates, over both games.
    let share = |names: &[&str]| {
        let (ok, n) = names
            .iter()
            .filter_map(|c| both.get(*c))
            .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
        if n == 0 {
            f64::NAN
        } else {
            ok as f64 / n as f64
        }
    };
    for (key, names) in [
        ("accuracy_10db_both", &["10"][..]),
        (
            "accuracy_clean_reverb_babble_both",
            &["clean", "reverb", "babble_10"][..],
        ),
        ("accuracy_babble_10_both", &["babble_10"][..]),
    ] {
        let v = share(names);
        eprintln!("both games, {}: {v:.3}", names.join(" + "));
        if v.is_finite() {
            json.push(format!("\"{key}\": {v:.4}"));
        }
    }
    eprintln!(
        "the most false accepts: {:.4} ({})",
        worst_false.0, worst_false.1
    );
    json.push(format!("\"false_accept_rate_max\": {:.4}", worst_false.0));
    lat_all.sort_by(f64::total_cmp);
    eprintln!(
        "real-time factor {:.3}; end of speech -> result p50 {:.3} s p90 {:.3} s p99 {:.3} s (end-pointer hangover {} s)",
        busy_s / audio_s,
        pct(&lat_all, 0.5),
        pct(&lat_all, 0.9),
        pct(&lat_all, 0.99),
        speech_recognition::vad::VadConfig::default().hangover_s
    );
    if let Some(d) = &wav_dir {
        std::fs::write(d.join("truth.tsv"), truth).unwrap();
        let mut phrases = String::new();
        for game in [Game::Touch, Game::Coach] {
            for c in Command::of_game(game) {
                for ph in c.phrases() {
                    phrases.push_str(&format!("{}\t{ph}\t{c:?}\n", game.name()));
                }
            }
        }
        std::fs::write(d.join("phrases.tsv"), phrases).unwrap();
    }
    println!(
        "{{{}, \"rtf\": {:.4}, \"end_of_speech_to_result_p50_s\": {:.4}, \"end_of_speech_to_result_p90_s\": {:.4}, \"endpoint_hangover_s\": {}, \"acoustic_model_adapted\": {}, \"voice_family\": \"{family}\"}}",
        json.join(", "),
        busy_s / audio_s,
        pct(&lat_all, 0.5),
        pct(&lat_all, 0.9),
        speech_recognition::vad::VadConfig::default().hangover_s,
        !model.stock
    );
}
