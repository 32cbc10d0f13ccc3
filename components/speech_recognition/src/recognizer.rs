//! The recognizer: end-pointer, decoder and command mapping over a continuous 16 kHz mono stream.
//!
//! Two PocketSphinx decoders on the same acoustic model: the command search (the game's JSGF
//! grammar) and the garbage search (a loop of filler words, [`crate::garbage`]). Both decode every
//! utterance, so their cepstral-mean state stays the same; the command comes from the first and
//! its confidence from the comparison of the two path scores ([`crate::confidence`]).

use crate::confidence::{ConfidenceConfig, estimate_snr_db, verdict};
use crate::garbage::{Dictionary, GarbageError, garbage_jsgf, load_fillers, without_grammar_words};
use crate::grammar::{Grammar, GrammarError};
use crate::vad::{RATE_HZ, Segment, Vad, VadConfig};
use interfaces::msg::command::{Command, Game};
use pocketsphinx_sys_min::decoder::{Decoder, DecoderConfig, DecoderError};
use std::path::{Path, PathBuf};

#[derive(Debug, thiserror::Error)]
pub enum RecognizerError {
    #[error(transparent)]
    Grammar(#[from] GrammarError),
    #[error(transparent)]
    Garbage(#[from] GarbageError),
    #[error(transparent)]
    Decoder(#[from] DecoderError),
}

/// One decoded utterance.
#[derive(Debug, Clone, PartialEq)]
pub struct Recognized {
    pub game: Game,
    /// Words, lowercase, of the best path ("" when the decoder found nothing). For an
    /// out-of-grammar utterance these are filler words (what it sounded like).
    pub text: String,
    /// In [0, 1], see [`crate::confidence`].
    pub confidence: f64,
    /// `Command::None` when out of grammar.
    pub command: Command,
    /// Stream times of the speech (s since the first sample).
    pub start_s: f64,
    pub end_s: f64,
    /// Decoder time on this utterance (s, wall clock).
    pub decode_s: f64,
    /// Per-frame log-likelihood ratio of the command path against the garbage path (nats per
    /// 10 ms frame), see [`crate::confidence`].
    pub llr_per_frame: f64,
    /// The command-against-garbage posterior, before the SNR factor ([`crate::confidence`]).
    pub p_in_grammar: f64,
    /// The utterance's estimated signal-to-noise ratio (dB).
    pub snr_db: f64,
    /// What the garbage search heard (filler words).
    pub garbage_text: String,
    /// Cut at the maximum utterance length.
    pub forced: bool,
    /// The command search's distinct N-best sentences and path scores (nats), best first (empty
    /// unless [`RecognizerConfig::nbest`] is set; a debugging aid).
    pub nbest: Vec<(String, f64)>,
}

/// Recognizer settings.
#[derive(Debug, Clone)]
pub struct RecognizerConfig {
    pub vad: VadConfig,
    pub confidence: ConfidenceConfig,
    /// Filler words of the garbage model (default: the shipped `grammars/filler.words`); `None`
    /// runs no garbage search, so every decoded sentence has confidence 1.
    pub fillers: Option<PathBuf>,
    /// Grammar probability of each filler word of a garbage path (a word insertion penalty of
    /// the garbage search).
    pub filler_weight: f64,
    /// Distinct N-best sentences of the command search to read (0: none; costs decode time).
    pub nbest: usize,
}

impl Default for RecognizerConfig {
    fn default() -> Self {
        Self {
            vad: VadConfig::default(),
            confidence: ConfidenceConfig::default(),
            fillers: Some(crate::garbage::filler_file()),
            filler_weight: 1.0,
            nbest: 0,
        }
    }
}

/// Grammar-constrained recognition for one game.
#[derive(Debug)]
pub struct Recognizer {
    game: Game,
    grammar: Grammar,
    decoder: Decoder,
    garbage: Option<Decoder>,
    /// Whether the decoders' cepstral mean has adapted to this audio yet (see `decode_segment`).
    warmed: bool,
    vad: Vad,
    cfg: RecognizerConfig,
}

impl Recognizer {
    /// A recognizer for `game` with the grammar file `grammar_path`, on the Debian model.
    pub fn new(
        game: Game,
        grammar_path: &Path,
        cfg: RecognizerConfig,
    ) -> Result<Self, RecognizerError> {
        let grammar = Grammar::load(grammar_path)?;
        Self::with_grammar(game, grammar, cfg, &DecoderConfig::debian())
    }

    /// A recognizer for `game` with the shipped grammar (`grammars/<game>.gram`).
    pub fn shipped(game: Game, cfg: RecognizerConfig) -> Result<Self, RecognizerError> {
        Self::new(
            game,
            &crate::grammar::grammar_dir().join(format!("{}.gram", game.name())),
            cfg,
        )
    }

    pub fn with_grammar(
        game: Game,
        grammar: Grammar,
        cfg: RecognizerConfig,
        decoder: &DecoderConfig,
    ) -> Result<Self, RecognizerError> {
        let name = grammar.origin.display().to_string();
        let fillers = match &cfg.fillers {
            Some(path) => {
                let dict = Dictionary::load(&decoder.dict)?;
                let all = load_fillers(path, &dict)?;
                without_grammar_words(&all, &grammar.words()?, &dict)
            }
            None => Vec::new(),
        };
        // Every senone every frame: the two searches' scores must share one normalisation.
        let mut base = decoder.clone();
        base.extra_args.push(("-compallsen".into(), "yes".into()));
        base.extra_args.push(("-bestpath".into(), "no".into()));
        // The same dither noise in both (it is random): one seed.
        base.extra_args.push(("-seed".into(), "1".into()));
        let garbage = if fillers.is_empty() {
            None
        } else {
            let mut g = base.clone();
            g.log_file = base.log_file.with_extension("garbage.log");
            g.nbest = 0;
            Some(Decoder::new(
                &g,
                "garbage filler loop",
                Some(&garbage_jsgf(&fillers, cfg.filler_weight)),
            )?)
        };
        let decoder = Decoder::new(
            &DecoderConfig {
                nbest: cfg.nbest,
                ..base
            },
            &name,
            Some(&grammar.text),
        )?;
        Ok(Self {
            game,
            grammar,
            decoder,
            garbage,
            warmed: false,
            vad: Vad::new(cfg.vad.clone()),
            cfg,
        })
    }

    pub fn game(&self) -> Game {
        self.game
    }
    pub fn grammar(&self) -> &Grammar {
        &self.grammar
    }
    /// Utterances the end-pointer dropped as too short.
    pub fn dropped_short(&self) -> u64 {
        self.vad.dropped_short
    }

    /// Feed stream samples (16 kHz mono); returns the utterances that ended in them.
    pub fn push(&mut self, samples: &[i16]) -> Result<Vec<Recognized>, RecognizerError> {
        let segs = self.vad.push(samples);
        segs.into_iter().map(|s| self.decode_segment(&s)).collect()
    }

    /// End of stream: decode an utterance still open.
    pub fn flush(&mut self) -> Result<Option<Recognized>, RecognizerError> {
        match self.vad.flush() {
            Some(s) => Ok(Some(self.decode_segment(&s)?)),
            None => Ok(None),
        }
    }

    /// Decode one already-cut utterance (no end-pointing).
    pub fn decode_segment(&mut self, seg: &Segment) -> Result<Recognized, RecognizerError> {
        let t0 = std::time::Instant::now();
        // Runs of digital silence (exact zeros: a muted or gated microphone) at the ends upset the
        // decoder's cepstral mean, which carries over to the next utterances: cut them.
        let first = seg
            .samples
            .iter()
            .position(|&s| s != 0)
            .unwrap_or(seg.samples.len());
        let last = seg
            .samples
            .iter()
            .rposition(|&s| s != 0)
            .map(|i| i + 1)
            .unwrap_or(first);
        let samples = &seg.samples[first..last.max(first)];
        // PocketSphinx's live cepstral mean starts from a fixed prior and adapts at the end of
        // each utterance; until then the features are off and the first utterance after start
        // often decodes to nothing. So the first utterance with a background (not digital
        // silence, whose speech-only mean would mislead it) is decoded twice, and the first pass
        // only warms the mean up.
        let snr_db = estimate_snr_db(samples);
        let digital_silence = first > 0 || last < seg.samples.len();
        let passes = if !self.warmed && !samples.is_empty() && !digital_silence {
            self.warmed = true;
            2
        } else {
            1
        };
        // The garbage search runs on every utterance, even when the command search found
        // nothing, so both decoders see the same audio history (cepstral mean). The two searches
        // are independent: they run on two threads, so the wait after the end of speech is the
        // slower of the two rather than their sum.
        let (decoder, garbage) = (&mut self.decoder, &mut self.garbage);
        let (g, gar) = std::thread::scope(|scope| {
            let gar = garbage.as_mut().map(|d| {
                scope.spawn(move || {
                    let mut h = d.decode(samples);
                    if passes == 2 {
                        h = d.decode(samples);
                    }
                    h
                })
            });
            let mut g = decoder.decode(samples);
            if passes == 2 {
                g = decoder.decode(samples);
            }
            let gar = gar.map(|j| {
                j.join()
                    .unwrap_or(Err(DecoderError::Decode("garbage search thread")))
            });
            (g, gar)
        });
        let g = g?;
        let gar = gar.transpose()?;
        let decode_s = t0.elapsed().as_secs_f64();
        let frames = g.n_frames;
        let s_gar = match &gar {
            Some(h) if !h.text.is_empty() => h.path_score_ln,
            _ => f64::NEG_INFINITY,
        };
        let v = verdict(
            &self.cfg.confidence,
            self.game,
            &g.text,
            g.path_score_ln,
            s_gar,
            frames,
            snr_db,
        );
        Ok(Recognized {
            game: self.game,
            command: v.command,
            text: g.text,
            confidence: v.confidence,
            start_s: seg.start_sample as f64 / RATE_HZ as f64,
            end_s: seg.end_sample as f64 / RATE_HZ as f64,
            decode_s,
            llr_per_frame: v.llr_per_frame,
            p_in_grammar: v.p_in_grammar,
            snr_db,
            garbage_text: gar.map(|h| h.text).unwrap_or_default(),
            forced: seg.forced,
            nbest: g.nbest,
        })
    }

    /// Decode a whole recording as one utterance (no end-pointing), stream time from 0.
    pub fn decode_all(&mut self, samples: &[i16]) -> Result<Recognized, RecognizerError> {
        self.decode_segment(&Segment {
            start_sample: 0,
            end_sample: samples.len() as u64,
            samples: samples.to_vec(),
            forced: false,
        })
    }
}
