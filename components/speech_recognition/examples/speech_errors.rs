#![allow(clippy::unwrap_used)]
//! Where the recognition errors come from (tuning aid): every command of a game said by a set of
//! voices at given SNRs, as one live stream (no flush between clips, as a microphone's), each
//! clip right when it gave the dialog one command, the right one (other utterances cut from it
//! out of grammar are background talk the dialog ignores), each error classified as an
//! end-pointer error (not exactly one utterance cut), a decoding error (one utterance, wrong
//! words) or a confidence rejection (right words, rejected as out of grammar).
//! `speech_errors <touch|coach> <tune|eval> <condition>...`, a condition as the benchmark names
//! it (`clean`, `10` for white noise at 10 dB, `reverb`, `babble_10`, `fan_10`).
//!
//! Environment: `MODEL` (`stock`, `adapted` or a folder: the acoustic model, with its confidence
//! calibration), `PS_ARGS` ("-name value ..." decoder options), `HANGOVER`, `MIN_SPEECH` (s),
//! `START_DB`, `START_FRAMES` (end-pointer),
//! `ROBUST=0` (PocketSphinx's own noise settings), `DENOISE=1` (the enhancement; `GFLOOR`,
//! `OVERSUB` tune it), `TALK_BETA`, `TALK_SCALE` (the confidence over talk), `VERBOSE` (list
//! every error; `VERBOSE=all` every utterance, with its ratio `d` and SNR), `OOG=1` (also
//! out-of-grammar sentences of the tuning set and, over babble, stretches of talk alone: how
//! many are taken for a command), `ORACLE=PAD` (no end-pointer: each clip is decoded as one
//! utterance cut where the clean speech starts and ends, `PAD` seconds wider on each side;
//! tells the end-pointer's share of the errors from the decoder's), `NBEST=N` (read the command
//! search's N best sentences, 10 by default, 0 for none and no margin in the confidence;
//! `VERBOSE=all` lists them and shows `m`, how much better per frame the hypothesis scored than
//! the best whole sentence of another command).
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

/// Out-of-grammar sentences of the tuning set (`OOG=1`): not the benchmark's.
const TUNE_OOG: &[&str] = &[
    "please close the window before you leave",
    "where did you put the red box",
    "I would like a glass of cold water",
    "the bus was completely full this morning",
    "tell me a story about the old castle",
    "my phone battery is almost empty",
];

/// The N best sentences and their path scores (nats), for `VERBOSE=all`.
fn nbest_list(r: &speech_recognition::Recognized) -> String {
    if r.nbest.is_empty() {
        return String::new();
    }
    let l: Vec<String> = r.nbest.iter().map(|(t, s)| format!("{t}:{s:.1}")).collect();
    format!(" nb={}", l.join("|"))
}

/// One utterance for `VERBOSE` (times from `clip_s`): its words, command, scores, `m`, the N-best
/// margin ([`speech_recognition::confidence::nbest_margin`]), and
/// the N-best list.
fn utterance(r: &speech_recognition::Recognized, clip_s: f64) -> String {
    format!(
        "{:?} {:?} p={:.2} conf={:.2} llr={:.3} snr={:.1} talk={} m={:.3} {:.2}-{:.2}s{}",
        r.text,
        r.command,
        r.p_in_grammar,
        r.confidence,
        r.llr_per_frame,
        r.snr_db,
        r.over_talk,
        r.margin_per_frame.unwrap_or(f64::NAN),
        r.start_s - clip_s,
        r.end_s - clip_s,
        nbest_list(r)
    )
}

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
    let model =
        speech_recognition::model::AcousticModel::resolve(std::env::var("MODEL").ok().as_deref())
            .unwrap();
    let mut cfg = RecognizerConfig {
        noise_robust: std::env::var("ROBUST").as_deref() != Ok("0"),
        denoise: (std::env::var("DENOISE").as_deref() == Ok("1")).then(Default::default),
        ..RecognizerConfig::for_model(model)
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
    if let Some(b) = std::env::var("TALK_BETA").ok().and_then(|s| s.parse().ok()) {
        cfg.confidence.talk_garbage_penalty = b;
    }
    if let Some(a) = std::env::var("TALK_SCALE")
        .ok()
        .and_then(|s| s.parse().ok())
    {
        cfg.confidence.talk_acoustic_scale = a;
    }
    if let Some(k) = std::env::var("NBEST").ok().and_then(|s| s.parse().ok()) {
        cfg.nbest = k;
    }
    if let Some(f) = std::env::var("OVERSUB").ok().and_then(|s| s.parse().ok()) {
        cfg.denoise
            .get_or_insert_with(Default::default)
            .over_subtraction = f;
    }
    let g = Grammar::load(&grammar_dir().join(format!("{}.gram", game.name()))).unwrap();
    // The configured acoustic model (a `-hmm` in `PS_ARGS` wins).
    dc.hmm_dir = cfg.acoustic_model.dir.clone();

    for cond in conditions {
        // A recognizer per condition: a room the robot listens in from the start.
        let mut rec = Recognizer::with_grammar(game, g.clone(), cfg.clone(), &dc).unwrap();
        // Samples streamed so far: the recognizer's times count from the first clip's start.
        let mut streamed = 0usize;
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
                        // Where the speech starts in the clip (s), as `end` is found.
                        let begin = cond.lead_s()
                            + speech
                                .iter()
                                .position(|x| x.unsigned_abs() > 300)
                                .unwrap_or(0) as f64
                                / 16000.0;
                        let mut got = vec![];
                        // Where this clip starts in the recognizer's stream time (s).
                        let mut clip_s = 0.0;
                        if let Some(pad) = std::env::var("ORACLE")
                            .ok()
                            .and_then(|s| s.parse::<f64>().ok())
                        {
                            let from = (((begin - pad) * 16000.0).max(0.0)) as usize;
                            let to = (((end + pad) * 16000.0) as usize).min(a.len());
                            got.push(rec.decode_all(&a[from..to]).unwrap());
                        } else {
                            clip_s = streamed as f64 / 16000.0;
                            streamed += a.len();
                            let mut pos = 0;
                            for chunk in a.chunks(if std::env::var("WHOLE").is_ok() {
                                a.len()
                            } else {
                                320
                            }) {
                                pos += chunk.len();
                                #[expect(
                                    clippy::disallowed_methods,
                                    reason = "a tuning aid measuring the decoder's compute latency"
                                )]
                                let t = std::time::Instant::now();
                                let r = rec.push(chunk).unwrap();
                                if !r.is_empty() {
                                    lat.push(
                                        pos as f64 / 16000.0 - end + t.elapsed().as_secs_f64(),
                                    );
                                }
                                got.extend(r);
                            }
                            // No flush: the stream goes on into the next clip, as a
                            // microphone's does (an utterance open at a clip's end is the
                            // next clip's).
                        }
                        n += 1;
                        // What the dialog acts on: the utterances not out of grammar.
                        let commands: Vec<_> =
                            got.iter().filter(|r| r.command != Command::None).collect();
                        let kind = if let [r] = commands[..]
                            && r.command == c
                        {
                            ok += 1;
                            if std::env::var("VERBOSE").as_deref() != Ok("all") {
                                continue;
                            }
                            "ok"
                        } else if got.len() != 1 {
                            vad += 1;
                            "vad"
                        } else if Command::from_phrase(game, &got[0].text) != c {
                            dec += 1;
                            "decode"
                        } else {
                            rej += 1;
                            "reject"
                        };
                        lines.push(format!(
                            "  {kind:6} {v} {s} {ph:?} {c:?} said {begin:.2}-{end:.2}s -> {:?}",
                            got.iter().map(|r| utterance(r, clip_s)).collect::<Vec<_>>()
                        ));
                    }
                }
            }
        }
        if let Some(r) = rec.flush().unwrap() {
            lines.push(format!("  open at the end of the commands: {:?}", r.text));
        }
        // What must not be taken for a command: out-of-grammar sentences of the set's voices,
        // and (over babble) stretches of the talk alone.
        let (mut other, mut taken, mut sure) = (0, 0, 0);
        if std::env::var("OOG").is_ok() {
            let mut clips: Vec<(String, Vec<i16>)> = vec![];
            for (i, sentence) in TUNE_OOG.iter().enumerate() {
                for (vi, v) in voices.iter().enumerate() {
                    let speech = synthesize_16k(sentence, &voice(v, i % SPEEDS.len())).unwrap();
                    let others: Vec<Vec<i16>> = (0..talkers.len())
                        .filter(|&k| k != vi)
                        .take(BABBLE_TALKERS)
                        .map(|k| talkers[k].clone())
                        .collect();
                    let seed = seed0 + 300 + (i * voices.len() + vi) as u64;
                    let clip = in_condition(&speech, cond, 10_000 + i, &others, seed);
                    clips.push((format!("oog {v} {sentence:?}"), clip));
                }
            }
            if let Condition::Babble(_) = cond {
                for k in 0..8u64 {
                    let mut rng = audio::signal::NoiseRng::new(seed0 + 700 + k);
                    // The talk at the level it has under the commands.
                    let power = 10f64.powf(corpus::NOISE_DBFS / 10.0);
                    let others: Vec<Vec<i16>> = talkers
                        .iter()
                        .skip(k as usize % talkers.len())
                        .chain(talkers.iter())
                        .take(BABBLE_TALKERS)
                        .cloned()
                        .collect();
                    let talk = audio::signal::babble(&others, 6 * 16_000, power, &mut rng)
                        .iter()
                        .map(|x| x.round().clamp(-32768.0, 32767.0) as i16)
                        .collect();
                    clips.push((format!("talk alone {k}"), talk));
                }
            }
            for (what, clip) in clips {
                let clip_s = streamed as f64 / 16000.0;
                streamed += clip.len();
                let mut got = vec![];
                for chunk in clip.chunks(320) {
                    got.extend(rec.push(chunk).unwrap());
                }
                other += 1;
                let cmd: Vec<_> = got.iter().filter(|r| r.command != Command::None).collect();
                taken += usize::from(!cmd.is_empty());
                sure += usize::from(cmd.iter().any(|r| r.confidence >= 0.7));
                lines.push(format!(
                    "  {what} -> {:?}",
                    got.iter().map(|r| utterance(r, clip_s)).collect::<Vec<_>>()
                ));
            }
        }
        if let Some(r) = rec.flush().unwrap() {
            lines.push(format!("  open at the end of the condition: {:?}", r.text));
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
        if other > 0 {
            println!(
                "  not commands: {other} clips, {taken} taken for a command, {sure} of them sure (>= 0.7)"
            );
        }
    }
}
