//! The confidence of a transcription, in [0, 1]: a posterior of the best command against a
//! garbage model.
//!
//! Each utterance is decoded twice on the same features ([`crate::recognizer`]):
//!
//! - by the **command search**, the game's JSGF grammar: its best path is the command hypothesis,
//!   with path score `S_cmd`;
//! - by the **garbage search**, a loop of filler words ([`crate::garbage`]): its best path, score
//!   `S_gar`, is the best explanation of the audio by "anything else".
//!
//! Scores are the decoders' Viterbi path scores as natural logs (acoustic log-likelihood plus the
//! weighted grammar log-probabilities and insertion penalties). Both decoders compute every
//! senone every frame (`-compallsen`), so their per-frame normalisation is the same and the two
//! scores of one utterance are comparable. (Without it PocketSphinx normalises each frame by the
//! best *active* senone, which differs between searches; that is why an earlier acoustic-score
//! ratio against a phone loop did not separate anything.)
//!
//! With `T` the utterance's frames (10 ms), the per-frame scores are `s = S / T` and their
//! difference, the per-frame log-likelihood ratio, is `d = s_cmd − s_gar`. The posterior of the
//! command among the two hypotheses, with an acoustic scale `a` and a per-frame garbage penalty
//! `β` (the prior against garbage), is
//!
//! ```text
//!     p = exp(a·s_cmd) / (exp(a·s_cmd) + exp(a·(s_gar − β)))
//!       = 1 / (1 + exp(−a · (d + β)))
//! ```
//!
//! Per frame, so that a long utterance is not more certain than a short one for the same match.
//! `a` and `β` are calibrated on the synthesized corpus
//! (`scripts/bench speech`): clean commands score above the dialog's high threshold (0.7),
//! commands in heavy noise fall between the thresholds, and out-of-grammar speech, which the
//! filler loop explains better than any command, falls under the low one (0.3).
//!
//! **Noise, and which command.** The garbage search suffers from noise as much as the command
//! search, so `p` says "this was one of the commands" but hardly drops when noise makes the
//! *wrong* command likely. `p` is therefore multiplied by `q`, how likely the hypothesis is the
//! right command ([`RightCalibration`]), a logistic of two scores:
//!
//! - the utterance's signal-to-noise ratio, estimated from its own samples
//!   ([`estimate_snr_db`]: the power of the loud frames over that of the quiet ones, which the
//!   end-pointer's pre-roll and tail provide);
//! - `d` itself: in noise, wrong commands are the ones the garbage loop explains better (on the
//!   tuning voices at 5 dB white noise, coach, right hypotheses scored a median `d` of 0.40
//!   nats per frame, 10th percentile −0.41; wrong ones −0.48, 90th percentile 0.15).
//!
//! ```text
//!     q(snr, d) = 1 / (1 + exp(−(bias + per_db · snr + per_nat · d)))        confidence = p · q
//! ```
//!
//! The calibration: bias −1.25, 0.25 per dB, 1 per nat per frame, chosen on the tuning voices
//! (every phrase, seven conditions, out-of-grammar sentences; `examples/speech_errors.rs`)
//! as the one that keeps the most right commands sure (`p · q` ≥ 0.7, the dialog's high
//! threshold) while no condition has over 4 % false accepts, with the SNR's slope kept at 0.25
//! per dB, so that at 0 dB commands are still asked about (between the dialog's thresholds)
//! rather than ignored. Against the SNR alone (bias −0.625, no `d`): wrong commands made sure
//! at 5 dB, coach 10.3 % → 3.5 % of the utterances heard, touch 4.1 % → 0.4 %.
//!
//! **Which command: the N-best margin.** Neither score tells *which* command: the SNR is the
//! room's, and `d` compares the hypothesis with garbage, not with the other commands. The
//! score for that is the margin `m` ([`nbest_margin`]): how much better per frame the
//! hypothesis scored than the best whole sentence of *another* command in the command search's
//! N-best list (10 sentences, read from the lattice the search builds anyway). On the tuning
//! voices at 5 dB (coach), right hypotheses had a median `m` of 2.4 nats per frame, wrong ones
//! 0.24. A hypothesis the lattice does not hold among its N best counts as `m` = 0 (most such
//! were wrong). A hypothesis less than `ambiguous_margin` (0.75 nats per frame) ahead of
//! another command is **ambiguous**: its confidence is [`AMBIGUOUS`] (0.5) at most, so the
//! dialog asks about it instead of carrying it out; its confidence is never lowered further,
//! so no command is ignored for having a rival. On the tuning voices (both games, seven
//! conditions, out-of-grammar sentences): the worst condition's false accepts 3.7 % → 1.25 %
//! of the utterances heard (coach at 5 dB: 11 → 2, at 10 and 20 dB 11 → 3, in rooms 11 → 3;
//! touch: 4 → 0 over all conditions), right commands made sure 2770 → 2566 (the rest are asked
//! about), right commands under the low threshold 23, as before. A margin folded into `q`
//! instead (a logistic term) did as well on false accepts and kept more commands sure, but
//! pushed 128 right commands under the low threshold (a "stop" at 6 dB, with "wrong" close
//! behind, was ignored): the dialog would not even have asked. What is left is half one tuning
//! voice's accent (en-029: "turn" heard as "no", ahead of every other command by 2 to 6 nats a
//! frame) and, at 5 dB and over talk, "search for the ball" heard as "turn" with no other
//! command in the N-best list at all: no score of these searches tells those apart.
//!
//! **Other people talking.** Over background talk (babble: the end-pointer says so when it cuts
//! the utterance, [`crate::vad`]) the garbage loop explains even a right command much better
//! than over quiet, since the other voices fill the command's frames with words of their own:
//! on the tuning voices at 10 dB, right commands scored a median `d` of −3.2 nats per frame,
//! wrong ones −3.7, out-of-grammar sentences −4 to −6. With the quiet room's `a` and `β`
//! half (coach) to three quarters (touch) of the right commands were rejected as out of
//! grammar. Such utterances get a posterior of their own, `a_talk` and `β_talk`
//! (`talk_acoustic_scale`, `talk_garbage_penalty`), fitted on the tuning voices so that a
//! command is heard (`p` ≥ 0.3) from `d` ≈ −3.3 on, where right commands outnumber wrong ones,
//! and `p` ≥ 0.7 only from `d` ≈ −1.2 on, where nearly all were right
//! (91 % between −1.5 and −1, all 51 above −1); between the two it is asked about.
//! Their `q` is of its own too (`talk_right`), of `d` alone (the estimated SNR says little over
//! talk): bias 2.5, 0.5 per nat per frame, chosen as above. On the acoustic model adapted on
//! rooms too, right commands over talk (tuning voices, 10 dB) scored a median `d` of −0.9
//! (coach) and −1.4 (touch), 90th percentile 0.65 and 0.0, wrong ones −2.4 (90th percentile
//! −0.8 and −1.8); with this `q` 1.2 % of the coach's utterances heard there were a wrong
//! command made sure (2.2 % with the SNR's), and 85 and 38 of 276 and 228 right commands sure
//! (117 and 59): most commands over talk are asked about.
//!
//! **The stock model.** The figures above are for the model adapted on the synthesized corpus.
//! The stock model, the default (it hears people better, [`crate::model`]), hears the tuning
//! voices worse: with the adapted model's calibration a third of its right commands under quiet
//! or steady noise were ignored and only 28 % made sure (both games; clean, 10 and 5 dB white
//! noise, rooms; 2016 commands). Its own calibration ([`ConfidenceConfig::STOCK`]) was fitted
//! on the same tuning voices (every utterance of `examples/speech_errors.rs` with `MODEL=stock
//! VERBOSE=all OOG=1`, judged again over a grid by `examples/fit_confidence.py`): the most
//! right commands sure with no more right commands ignored, no more out-of-grammar sentences
//! taken for a command, and no condition above 1.25 % false accepts. It takes `β` 1.2, `q`'s
//! bias −0.25 and 0.5 per nat, and an ambiguous margin of 0.5: 705 right commands sure instead
//! of 557, 597 ignored instead of 630, 5 out-of-grammar sentences of 192 taken instead of 6;
//! the worst condition, coach in rooms, 3 wrong commands made sure of 248 heard with either
//! calibration. Over talk the adapted model's `a_talk`, `β_talk` and `q_talk` are kept: the
//! best of the grid made 20 more right commands sure of 504 at the price of 3 wrong ones, where
//! there were none.
//!
//! The verdict: `p < reject_below` (default 0.3, the dialog's low threshold) is **out of
//! grammar** (`Command::None`, confidence `p · q`); otherwise the command of the hypothesis with
//! confidence `p · q` (at most [`AMBIGUOUS`] when ambiguous), which the dialog may still find too low (a command in heavy noise is asked
//! about or ignored). An empty hypothesis (no path of the grammar reached its end) is out of grammar
//! with confidence 0.

use interfaces::msg::command::{Command, Game};

/// The probability that a command hypothesis is the right command, a logistic of the
/// utterance's estimated SNR and per-frame ratio `d` (see the module doc):
/// `q = 1 / (1 + exp(−(bias + per_db · snr + per_nat · d)))`, `d` taken within ±[`D_SPAN`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RightCalibration {
    pub bias: f64,
    /// Per dB of estimated SNR.
    pub per_db: f64,
    /// Per nat per frame of `d`.
    pub per_nat: f64,
}

/// How far `d` counts in [`RightCalibration`] (nats per frame either side of 0): an utterance
/// without a garbage path has an infinite `d`.
pub const D_SPAN: f64 = 5.0;

/// The confidence of an ambiguous hypothesis at most ([`ConfidenceConfig::ambiguous_margin`]):
/// as likely as not, between the dialog's thresholds (0.3 and 0.7 by default), so it is asked
/// about, never carried out at once.
pub const AMBIGUOUS: f64 = 0.5;

impl RightCalibration {
    pub fn q(&self, snr_db: f64, d: f64) -> f64 {
        let x = self.bias + self.per_db * snr_db + self.per_nat * d.clamp(-D_SPAN, D_SPAN);
        1.0 / (1.0 + (-x).exp())
    }
}

/// Calibration of the posterior (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ConfidenceConfig {
    /// Acoustic scale `a` on the per-frame log-likelihood ratio (per nat per frame).
    pub acoustic_scale: f64,
    /// Garbage penalty `β` (nats per frame) added in favour of the command.
    pub garbage_penalty: f64,
    /// Posterior under which the utterance is out of grammar.
    pub reject_below: f64,
    /// `q`, the probability that the command is the right one, over quiet or steady noise.
    pub right: RightCalibration,
    /// `a` for an utterance cut over other people's talk (see the module doc).
    pub talk_acoustic_scale: f64,
    /// `β` for an utterance cut over other people's talk.
    pub talk_garbage_penalty: f64,
    /// `q` for an utterance cut over other people's talk.
    pub talk_right: RightCalibration,
    /// A hypothesis less than this far ahead of another command in the N-best list ([`nbest_margin`],
    /// nats per frame) is ambiguous: its confidence is [`AMBIGUOUS`] at most.
    pub ambiguous_margin: f64,
}

impl ConfidenceConfig {
    /// The calibration for a model adapted on the synthesized corpus (the module doc's figures).
    /// A model adapted on recordings is given it too: its scores are as sharp.
    pub const ADAPTED: Self = Self {
        acoustic_scale: 2.5,
        garbage_penalty: 1.4,
        reject_below: 0.3,
        right: RightCalibration {
            bias: -1.25,
            per_db: 0.25,
            per_nat: 1.0,
        },
        talk_acoustic_scale: 0.8,
        talk_garbage_penalty: 2.25,
        talk_right: RightCalibration {
            bias: 2.5,
            per_db: 0.0,
            per_nat: 0.5,
        },
        ambiguous_margin: 0.75,
    };

    /// The calibration for the stock model (and any model without a provenance file), fitted
    /// on the same tuning voices (see the module doc, "The stock model").
    pub const STOCK: Self = Self {
        garbage_penalty: 1.2,
        right: RightCalibration {
            bias: -0.25,
            per_db: 0.25,
            per_nat: 0.5,
        },
        ambiguous_margin: 0.5,
        ..Self::ADAPTED
    };

    /// The calibration fitted for `model`.
    pub fn for_model(model: &crate::model::AcousticModel) -> Self {
        if model.stock || crate::model::adapted_on(&model.dir).is_none() {
            Self::STOCK
        } else {
            Self::ADAPTED
        }
    }
}

/// What the two searches say about an utterance.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Verdict {
    /// The command, or `Command::None` when out of grammar or nothing was decoded.
    pub command: Command,
    /// The posterior `p` of the module doc (0 for an empty hypothesis).
    pub confidence: f64,
    /// The per-frame log-likelihood ratio `d` (nats per frame; 0 when undefined).
    pub llr_per_frame: f64,
    /// `p`, the command against garbage.
    pub p_in_grammar: f64,
    /// `q(snr, d)`, the probability that the command is the right one.
    pub p_right: f64,
    /// The N-best margin `m` ([`nbest_margin`]; `None` when unknown).
    pub margin_per_frame: Option<f64>,
}

/// The N-best margin `m` of the hypothesis `text` (nats per frame): how much better its path
/// scored in the command search's N-best list than the best *whole* sentence of another command
/// there; +∞ when no other command is in the list. Only whole sentences count: the lattice of a
/// grammar search also yields paths that stop inside a sentence ("look", "pass the"), which
/// often score better than any whole one and than the hypothesis itself. 0 when the list does
/// not hold the hypothesis (the lattice does not back the Viterbi path: on the tuning voices,
/// most such hypotheses were wrong); `None` when the list is empty (not read).
pub fn nbest_margin(game: Game, text: &str, nbest: &[(String, f64)], frames: u32) -> Option<f64> {
    if nbest.is_empty() {
        return None;
    }
    let Some(&(_, own)) = nbest.iter().find(|(t, _)| t == text) else {
        return Some(0.0);
    };
    let cmd = Command::from_phrase(game, text);
    Some(
        nbest
            .iter()
            .filter(|(t, _)| {
                let c = Command::from_phrase(game, t);
                c != Command::None && c != cmd
            })
            .map(|(_, s)| (own - s) / frames.max(1) as f64)
            .fold(f64::INFINITY, f64::min),
    )
}

/// The estimated signal-to-noise ratio (dB) of an utterance cut with some noise around the speech: the
/// mean power of the 10 ms frames at least 6 dB above the quietest tenth, less that noise power,
/// over the noise power. Clamped to [−20, 60] dB (60 for digital silence around the speech).
pub fn estimate_snr_db(samples: &[i16]) -> f64 {
    let mut p: Vec<f64> = samples
        .chunks_exact(160)
        .map(|f| f.iter().map(|&x| (x as f64) * (x as f64)).sum::<f64>() / 160.0)
        .collect();
    if p.len() < 4 {
        return 60.0;
    }
    p.sort_by(f64::total_cmp);
    let noise = p[p.len() / 10];
    let loud: Vec<f64> = p.iter().copied().filter(|&x| x >= 4.0 * noise).collect();
    if loud.is_empty() {
        return -20.0;
    }
    let speech = loud.iter().sum::<f64>() / loud.len() as f64 - noise;
    if noise <= 1.0 {
        return 60.0;
    }
    (10.0 * (speech.max(1e-9) / noise).log10()).clamp(-20.0, 60.0)
}

/// What the two searches made of one utterance: the input of [`verdict`]. Scores are natural
/// logs.
#[derive(Debug, Clone, Copy)]
pub struct Scores<'a> {
    /// The command search's hypothesis and its path score.
    pub text: &'a str,
    pub command_ln: f64,
    /// The garbage search's best path score (−∞ when it found nothing).
    pub garbage_ln: f64,
    /// Frames (10 ms) the searches decoded.
    pub frames: u32,
    /// The utterance's estimated SNR ([`estimate_snr_db`]).
    pub snr_db: f64,
    /// Cut over other people's talk ([`crate::vad::Segment::over_talk`]).
    pub over_talk: bool,
    /// The command search's N-best sentences and path scores, best first (empty: not read).
    pub nbest: &'a [(String, f64)],
}

/// The verdict on an utterance's command hypothesis against the garbage search's.
pub fn verdict(cfg: &ConfidenceConfig, game: Game, u: &Scores) -> Verdict {
    let Scores {
        text,
        command_ln: s_cmd,
        garbage_ln: s_gar,
        frames,
        snr_db,
        over_talk,
        nbest,
    } = *u;
    let (scale, penalty, right) = if over_talk {
        (
            cfg.talk_acoustic_scale,
            cfg.talk_garbage_penalty,
            cfg.talk_right,
        )
    } else {
        (cfg.acoustic_scale, cfg.garbage_penalty, cfg.right)
    };
    let none = Verdict {
        command: Command::None,
        confidence: 0.0,
        llr_per_frame: 0.0,
        p_in_grammar: 0.0,
        p_right: 0.0,
        margin_per_frame: None,
    };
    if text.trim().is_empty() || frames == 0 || !s_cmd.is_finite() {
        return none;
    }
    // No garbage path (its search found nothing): nothing competes with the command.
    let d = if s_gar.is_finite() {
        (s_cmd - s_gar) / frames as f64
    } else {
        f64::INFINITY
    };
    let p = if d.is_finite() {
        1.0 / (1.0 + (-scale * (d + penalty)).exp())
    } else {
        1.0
    };
    let command = Command::from_phrase(game, text);
    let margin = nbest_margin(game, text, nbest, frames);
    let q = right.q(snr_db, d);
    let mut confidence = (p * q).clamp(0.0, 1.0);
    if margin.is_some_and(|m| m < cfg.ambiguous_margin) {
        confidence = confidence.min(AMBIGUOUS);
    }
    Verdict {
        command: if p < cfg.reject_below {
            Command::None
        } else {
            command
        },
        confidence,
        llr_per_frame: if d.is_finite() { d } else { 0.0 },
        p_in_grammar: p,
        p_right: q,
        margin_per_frame: margin,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// q = 1/2 at 0.5 dB, 0.155 per dB, whatever `d`.
    const BY_SNR: RightCalibration = RightCalibration {
        bias: -0.155 * 0.5,
        per_db: 0.155,
        per_nat: 0.0,
    };
    const C: ConfidenceConfig = ConfidenceConfig {
        acoustic_scale: 2.0,
        garbage_penalty: 1.0,
        reject_below: 0.3,
        right: BY_SNR,
        talk_acoustic_scale: 1.0,
        talk_garbage_penalty: 3.0,
        talk_right: BY_SNR,
        ambiguous_margin: 0.75,
    };
    /// So clean that q = 1 to 1e-4.
    const CLEAN: f64 = 1000.0;

    /// A touch-game utterance heard over quiet (clean, no talk).
    fn heard(text: &str, command_ln: f64, garbage_ln: f64, frames: u32) -> Scores<'_> {
        Scores {
            text,
            command_ln,
            garbage_ln,
            frames,
            snr_db: CLEAN,
            over_talk: false,
            nbest: &[],
        }
    }

    fn judge(u: Scores) -> Verdict {
        verdict(&C, Game::Touch, &u)
    }

    #[test]
    fn the_posterior_is_a_logistic_of_the_per_frame_ratio() {
        // Garbage 1 nat/frame better than the command, penalty 1: even odds.
        let v = judge(heard("touch the ball", -300.0, -200.0, 100));
        assert_eq!(v.command, Command::TouchBall);
        assert!((v.confidence - 0.5).abs() < 1e-12, "{v:?}");
        assert!((v.llr_per_frame + 1.0).abs() < 1e-12);
        // Command as good as garbage: 1 / (1 + e^-2).
        let v = judge(heard("touch the ball", -200.0, -200.0, 100));
        assert!((v.confidence - 1.0 / (1.0 + (-2.0f64).exp())).abs() < 1e-12);
        // Monotone in the ratio.
        let w = judge(heard("touch the ball", -250.0, -200.0, 100));
        assert!(w.confidence < v.confidence && w.confidence > 0.5);
    }

    #[test]
    fn speech_the_garbage_explains_much_better_is_out_of_grammar() {
        // 2 nats/frame worse than garbage: p = 1 / (1 + e^2) = 0.12 < 0.3.
        let v = judge(heard("well done", -400.0, -200.0, 100));
        assert_eq!(v.command, Command::None);
        assert!(v.confidence < 0.3 && v.confidence > 0.0, "{v:?}");
    }

    #[test]
    fn nothing_decoded_is_zero_and_no_garbage_is_certain() {
        let v = judge(heard("", -1.0, -1.0, 10));
        assert_eq!((v.command, v.confidence), (Command::None, 0.0));
        let v = judge(heard("stop", -1.0, -1.0, 0));
        assert_eq!((v.command, v.confidence), (Command::None, 0.0));
        let v = judge(heard("stop", -100.0, f64::NEG_INFINITY, 10));
        assert_eq!((v.command, v.confidence), (Command::Stop, 1.0));
    }

    #[test]
    fn noise_lowers_the_confidence_but_not_the_command() {
        let clean = judge(heard("stop", -100.0, -100.0, 10));
        let noisy = judge(Scores {
            snr_db: 5.0,
            ..heard("stop", -100.0, -100.0, 10)
        });
        assert_eq!(noisy.command, Command::Stop);
        assert!((noisy.p_in_grammar - clean.p_in_grammar).abs() < 1e-12);
        let q = 1.0 / (1.0 + (-0.155f64 * 4.5).exp());
        assert!(
            (noisy.confidence - clean.confidence * q).abs() < 1e-9,
            "{noisy:?}"
        );
    }

    /// With a weight on the ratio, two hypotheses at the same SNR and in grammar alike differ
    /// in how sure they are: the one the garbage loop explains better is the likelier wrong.
    #[test]
    fn in_noise_the_ratio_also_says_how_likely_the_command_is_right() {
        let cfg = ConfidenceConfig {
            right: RightCalibration {
                bias: -1.0,
                per_db: 0.2,
                per_nat: 4.0,
            },
            ..C
        };
        let at = |d: f64| {
            verdict(
                &cfg,
                Game::Touch,
                &Scores {
                    snr_db: 9.0,
                    ..heard("stop", -100.0 + 10.0 * d, -100.0, 10)
                },
            )
        };
        let (behind, ahead) = (at(-0.5), at(0.5));
        assert_eq!(
            (behind.command, ahead.command),
            (Command::Stop, Command::Stop)
        );
        // q = 1 / (1 + e^-(−1 + 1.8 ∓ 2)).
        let q = |x: f64| 1.0 / (1.0 + (-x).exp());
        assert!((behind.p_right - q(-1.2)).abs() < 1e-9, "{behind:?}");
        assert!((ahead.p_right - q(2.8)).abs() < 1e-9, "{ahead:?}");
        assert!(
            behind.confidence < 0.3 && ahead.confidence > 0.7,
            "{behind:?} {ahead:?}"
        );
        // No garbage path: d counts as D_SPAN.
        let v = verdict(
            &cfg,
            Game::Touch,
            &Scores {
                snr_db: 9.0,
                ..heard("stop", -100.0, f64::NEG_INFINITY, 10)
            },
        );
        assert!(
            (v.confidence - q(-1.0 + 1.8 + 4.0 * D_SPAN)).abs() < 1e-9,
            "{v:?}"
        );
    }

    /// Over other people's talk the garbage loop explains a right command better than over
    /// quiet, and the ratio tells right from wrong less sharply: a command 2 nats a frame behind
    /// garbage is still heard (the talk's penalty), and the posterior rises more slowly with the
    /// ratio (the talk's scale).
    #[test]
    fn over_talk_a_command_behind_garbage_is_heard() {
        let quiet = judge(heard("stop", -300.0, -100.0, 100));
        assert_eq!(quiet.command, Command::None, "{quiet:?}");
        let talk = judge(Scores {
            over_talk: true,
            ..heard("stop", -300.0, -100.0, 100)
        });
        assert_eq!(talk.command, Command::Stop, "{talk:?}");
        // p = 1 / (1 + e^-(1 · (-2 + 3))).
        let p = 1.0 / (1.0 + (-1.0f64).exp());
        assert!((talk.p_in_grammar - p).abs() < 1e-12, "{talk:?}");
        assert!((talk.confidence - p).abs() < 1e-4, "{talk:?}");
        // A command the garbage explains far better is out of grammar over talk too.
        let v = judge(Scores {
            over_talk: true,
            ..heard("stop", -600.0, -100.0, 100)
        });
        assert_eq!(v.command, Command::None, "{v:?}");
        // As good as garbage: surer over quiet (scale 2, penalty 1) than over talk (scale 1,
        // penalty 3) at the same ratio: e^-2 against e^-3.
        let quiet = judge(heard("stop", -100.0, -100.0, 10));
        let talk = judge(Scores {
            over_talk: true,
            ..heard("stop", -100.0, -100.0, 10)
        });
        assert!(talk.p_in_grammar > quiet.p_in_grammar, "{talk:?} {quiet:?}");
    }

    /// The margin is taken against whole sentences of *other* commands only: a path that stops
    /// inside a sentence ("please", "look") or another phrase of the same command does not
    /// compete.
    #[test]
    fn the_margin_is_over_whole_sentences_of_other_commands() {
        let list = |l: &[(&str, f64)]| -> Vec<(String, f64)> {
            l.iter().map(|(t, s)| (t.to_string(), *s)).collect()
        };
        let nb = list(&[
            ("look", -90.0),
            ("turn", -116.5),
            ("correct", -238.5),
            ("yes", -250.0),
        ]);
        let m = nbest_margin(Game::Coach, "correct", &nb, 100).unwrap();
        assert!((m - (-238.5 + 116.5) / 100.0).abs() < 1e-12, "{m}");
        let nb = list(&[("yes", -100.0), ("correct", -120.0), ("no", -160.0)]);
        assert_eq!(nbest_margin(Game::Coach, "yes", &nb, 20), Some(3.0));
        // No other command in the list; the hypothesis not in it; no list read.
        let nb = list(&[("yes", -100.0), ("correct", -120.0)]);
        assert_eq!(
            nbest_margin(Game::Coach, "yes", &nb, 20),
            Some(f64::INFINITY)
        );
        assert_eq!(nbest_margin(Game::Coach, "no", &nb, 20), Some(0.0));
        assert_eq!(nbest_margin(Game::Coach, "yes", &[], 20), None);
    }

    /// A hypothesis barely ahead of another command is asked about, never carried out at once:
    /// its confidence is [`AMBIGUOUS`] at most; one clearly ahead, alone in its N-best list, or
    /// without a list keeps its own; and an unsure one is not made surer.
    #[test]
    fn a_hypothesis_barely_ahead_of_another_command_is_ambiguous() {
        let judge_with = |nbest: &[(String, f64)], garbage_ln: f64| {
            verdict(
                &C,
                Game::Coach,
                &Scores {
                    nbest,
                    ..heard("no", -100.0, garbage_ln, 10)
                },
            )
        };
        let list = |other: f64| vec![("no".to_string(), -100.0), ("turn".to_string(), other)];
        // 0.05 nats a frame ahead of "turn": ambiguous.
        let v = judge_with(&list(-100.5), f64::NEG_INFINITY);
        assert_eq!(v.command, Command::No);
        assert_eq!(v.margin_per_frame, Some(0.05));
        assert_eq!(v.confidence, AMBIGUOUS);
        // 1 nat a frame ahead, alone, no list: as sure as without the margin (1 here).
        for nbest in [list(-110.0), vec![("no".to_string(), -100.0)], vec![]] {
            let v = judge_with(&nbest, f64::NEG_INFINITY);
            assert!((v.confidence - 1.0).abs() < 1e-4, "{nbest:?}: {v:?}");
        }
        // An ambiguous hypothesis already under AMBIGUOUS keeps its confidence.
        let unsure = judge_with(&list(-100.5), -80.0);
        assert!(unsure.confidence < AMBIGUOUS, "{unsure:?}");
        assert_eq!(unsure.confidence, judge_with(&[], -80.0).confidence);
    }

    #[test]
    fn the_snr_estimate_follows_the_mix() {
        // A 1 kHz tone of amplitude 3000 in 0.5 s of uniform noise on both sides.
        let mut x: u64 = 12345;
        let mut noise = |amp: f64| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((x >> 33) as f64 / (1u64 << 31) as f64 - 1.0) * amp
        };
        for snr in [5.0, 10.0, 20.0] {
            // Tone power 3000²/2; uniform noise power amp²/3.
            let amp = (3.0 * 3000.0f64.powi(2) / 2.0 / 10f64.powf(snr / 10.0)).sqrt();
            let s: Vec<i16> = (0..32000)
                .map(|i| {
                    let tone = if (8000..24000).contains(&i) {
                        3000.0 * (2.0 * std::f64::consts::PI * 1000.0 * i as f64 / 16000.0).sin()
                    } else {
                        0.0
                    };
                    (tone + noise(amp)) as i16
                })
                .collect();
            let est = estimate_snr_db(&s);
            assert!((est - snr).abs() < 1.5, "{snr} dB estimated {est}");
        }
        assert_eq!(estimate_snr_db(&[0; 3200]), 60.0);
        assert_eq!(estimate_snr_db(&[]), 60.0);
    }
}
