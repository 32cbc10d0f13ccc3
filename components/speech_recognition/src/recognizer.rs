//! The recognizer: end-pointer, decoder and command mapping over a continuous 16 kHz mono stream.

use crate::confidence::{ConfidenceConfig, confidence};
use crate::grammar::{Grammar, GrammarError};
use crate::vad::{FRAME, RATE_HZ, Segment, Vad, VadConfig};
use interfaces::msg::command::{Command, Game};
use pocketsphinx_sys_min::decoder::{Decoder, DecoderConfig, DecoderError};
use std::path::Path;

#[derive(Debug, thiserror::Error)]
pub enum RecognizerError {
    #[error(transparent)]
    Grammar(#[from] GrammarError),
    #[error(transparent)]
    Decoder(#[from] DecoderError),
}

/// One decoded utterance.
#[derive(Debug, Clone, PartialEq)]
pub struct Recognized {
    pub game: Game,
    /// Words, lowercase ("" when the decoder found nothing).
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
    /// The raw scores behind the confidence (natural logs).
    pub posterior_ln: f64,
    pub garbage_per_frame_ln: f64,
    /// Cut at the maximum utterance length.
    pub forced: bool,
    /// The grammar decoder's distinct N-best sentences and path scores, best first.
    pub nbest: Vec<(String, f64)>,
}

/// The garbage model's decoder: the same acoustic model with a phone loop, beams narrowed
/// (`garbage_beam`, default 1e-8 instead of 1e-48, so it runs at a fraction of real time) and a
/// low phone-LM weight (`garbage_lw`) so it follows the acoustics rather than phone statistics.
pub fn phone_loop_config(base: &DecoderConfig, cfg: &RecognizerConfig) -> DecoderConfig {
    let mut c = base.clone();
    c.log_file = base.log_file.with_extension("phones.log");
    let beam = format!("{:e}", cfg.garbage_beam);
    let lw = format!("{}", cfg.garbage_lw);
    for (k, v) in [("-beam", &beam), ("-pbeam", &beam), ("-lw", &lw)] {
        c.extra_args.push((k.to_string(), v.to_string()));
    }
    c
}

/// Recognizer settings.
#[derive(Debug, Clone)]
pub struct RecognizerConfig {
    pub vad: VadConfig,
    pub confidence: ConfidenceConfig,
    /// Beam of the phone-loop (garbage) decoder, a probability ratio (smaller = wider, slower).
    pub garbage_beam: f64,
    /// Language weight of the phone loop.
    pub garbage_lw: f64,
}

impl Default for RecognizerConfig {
    fn default() -> Self {
        Self {
            vad: VadConfig::default(),
            confidence: ConfidenceConfig::default(),
            garbage_beam: 1e-8,
            garbage_lw: 2.0,
        }
    }
}

/// Grammar-constrained recognition for one game.
#[derive(Debug)]
pub struct Recognizer {
    game: Game,
    grammar: Grammar,
    decoder: Decoder,
    phones: Decoder,
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
        let phones = Decoder::new(&phone_loop_config(decoder, &cfg), &name, None)?;
        let decoder = Decoder::new(decoder, &name, Some(&grammar.text))?;
        Ok(Self {
            game,
            grammar,
            decoder,
            phones,
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
        let g = self.decoder.decode(samples)?;
        let p = if g.text.is_empty() {
            g.clone()
        } else {
            self.phones.decode(samples)?
        };
        let decode_s = t0.elapsed().as_secs_f64();
        let frames = g.n_frames.max((samples.len() / FRAME) as u32);
        let conf = confidence(
            &self.cfg.confidence,
            g.posterior_ln,
            g.acoustic_ln,
            p.acoustic_ln,
            frames,
            g.text.is_empty(),
        );
        Ok(Recognized {
            game: self.game,
            command: Command::from_phrase(self.game, &g.text),
            text: g.text,
            confidence: conf,
            start_s: seg.start_sample as f64 / RATE_HZ as f64,
            end_s: seg.end_sample as f64 / RATE_HZ as f64,
            decode_s,
            posterior_ln: g.posterior_ln,
            garbage_per_frame_ln: if frames > 0 {
                (g.acoustic_ln - p.acoustic_ln) / frames as f64
            } else {
                0.0
            },
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
