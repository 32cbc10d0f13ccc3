//! The recognizer: end-pointer, decoder and command mapping over a continuous 16 kHz mono stream.
//!
//! Two PocketSphinx decoders on the same acoustic model: the command search (the game's JSGF
//! grammar) and the garbage search (a loop of filler words, [`crate::garbage`]). Both decode every
//! utterance, so their cepstral-mean state stays the same; the command comes from the first and
//! its confidence from the comparison of the two path scores ([`crate::confidence`]).

use crate::confidence::{ConfidenceConfig, Scores, estimate_snr_db, verdict};
use crate::denoise::{DenoiseConfig, Denoiser};
use crate::garbage::{
    Dictionary, GarbageError, garbage_jsgf, load_fillers, load_pronunciations,
    without_grammar_words,
};
use crate::grammar::{Grammar, GrammarError};
use crate::model::AcousticModel;
use crate::vad::{RATE_HZ, Segment, Vad, VadConfig};
use interfaces::msg::command::{Command, Game};
use pocketsphinx_sys_min::decoder::{Decoder, DecoderConfig, DecoderError, Hypothesis};
use std::path::{Path, PathBuf};

/// How many distinct N-best sentences of the command search are read by default: on the
/// tuning voices, enough to hold the best other command whenever the lattice has one.
pub const NBEST: usize = 10;

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
    /// The N-best margin over the best other command ([`crate::confidence::nbest_margin`]).
    pub margin_per_frame: Option<f64>,
    /// The utterance's estimated signal-to-noise ratio (dB).
    pub snr_db: f64,
    /// What the garbage search heard (filler words).
    pub garbage_text: String,
    /// Cut at the maximum utterance length.
    pub forced: bool,
    /// Cut over other people's talk (the confidence is calibrated for it, see
    /// [`crate::confidence`]).
    pub over_talk: bool,
    /// The command search's distinct N-best sentences and path scores (nats), best first (empty
    /// when [`RecognizerConfig::nbest`] is 0).
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
    /// Distinct N-best sentences of the command search to read, for the confidence's margin
    /// over other commands ([`crate::confidence::nbest_margin`]; 0: none, no margin).
    pub nbest: usize,
    /// Speech enhancement before decoding ([`crate::denoise`]); `None` decodes the raw audio.
    pub denoise: Option<DenoiseConfig>,
    /// Decoder settings for noise (see `with_grammar`): wider beams, no PocketSphinx voice
    /// detection. With the adapted model, +2 to +3 points of command accuracy at 10 dB on the
    /// corpus' tuning voices; on by default.
    pub noise_robust: bool,
    /// At most this much of the background just before each utterance's speech (the
    /// end-pointer's pre-roll) is taken as the noise the enhancement removes (s).
    pub noise_lead_s: f64,
    /// More pronunciations of grammar words (default: the shipped
    /// `grammars/pronunciations.dict`, [`crate::garbage::load_pronunciations`]); `None` uses the
    /// CMU dictionary's alone.
    pub pronunciations: Option<PathBuf>,
    /// The acoustic model both searches load ([`crate::model`]).
    pub acoustic_model: AcousticModel,
}

impl Default for RecognizerConfig {
    /// With the model [`AcousticModel::preferred`] picks.
    fn default() -> Self {
        Self::for_model(AcousticModel::preferred())
    }
}

impl RecognizerConfig {
    /// The defaults, with `model` and the confidence calibration fitted for it
    /// ([`ConfidenceConfig::for_model`]).
    pub fn for_model(model: AcousticModel) -> Self {
        Self {
            vad: VadConfig::default(),
            confidence: ConfidenceConfig::for_model(&model),
            fillers: Some(crate::garbage::filler_file()),
            filler_weight: 1.0,
            nbest: NBEST,
            // Off by default: the adapted acoustic model never heard its output (adapting on
            // enhanced audio would be the way to evaluate it).
            denoise: None,
            noise_robust: true,
            noise_lead_s: 0.2,
            pronunciations: Some(crate::garbage::pronunciations_file()),
            acoustic_model: model,
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
    /// Utterances decoded so far (the first one is decoded whole, see `decode_segment`).
    decoded: u64,
    /// The utterance being decoded while it is spoken.
    live: Option<Live>,
    /// A microphone's constant offset, removed before anything else looks at the audio.
    dc: audio::signal::DcRemover,
    /// The audio without it (reused).
    centred: Vec<i16>,
}

/// An utterance under way, fed to both searches as it arrives (see [`Recognizer::push`]).
#[derive(Debug)]
struct Live {
    start_sample: u64,
    /// Samples of the end-pointer's segment consumed so far.
    consumed: usize,
    /// Whether a non-zero sample was seen (leading digital silence is skipped).
    begun: bool,
    /// A run of exact zeros, held back until a non-zero sample follows (trailing digital silence
    /// is dropped, as in the whole-utterance path).
    zeros: usize,
    /// Samples kept (after the zero trimming), for the SNR estimate.
    kept: Vec<i16>,
    /// The enhancement, with the noise of the utterance's lead (`None`: none, or no noise heard).
    denoiser: Option<Denoiser>,
}

impl Recognizer {
    /// A recognizer for `game` with the grammar file `grammar_path`, on the Debian dictionary
    /// and the configuration's acoustic model.
    pub fn new(
        game: Game,
        grammar_path: &Path,
        cfg: RecognizerConfig,
    ) -> Result<Self, RecognizerError> {
        let grammar = Grammar::load(grammar_path)?;
        let decoder = DecoderConfig {
            hmm_dir: cfg.acoustic_model.dir.clone(),
            ..DecoderConfig::debian()
        };
        Self::with_grammar(game, grammar, cfg, &decoder)
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
        let dict = Dictionary::load(&decoder.dict)?;
        let fillers = match &cfg.fillers {
            Some(path) => {
                let all = load_fillers(path, &dict)?;
                without_grammar_words(&all, &grammar.words()?, &dict)
            }
            None => Vec::new(),
        };
        // Every senone every frame: the two searches' scores must share one normalisation.
        let mut base = decoder.clone();
        if let Some(path) = &cfg.pronunciations {
            base.extra_words.extend(load_pronunciations(path, &dict)?);
        }
        base.extra_args.push(("-compallsen".into(), "yes".into()));
        base.extra_args.push(("-bestpath".into(), "no".into()));
        // The same dither noise in both (it is random): one seed.
        base.extra_args.push(("-seed".into(), "1".into()));
        // The end-pointer and the enhancement ([`crate::denoise`]) do PocketSphinx's own voice
        // detection and noise subtraction better on noisy commands (measured with the corpus'
        // tuning voices): its detector drops weak consonants in noise, and its subtraction on
        // top of the Wiener filter removes speech. Wider beams: the grammars are small, and the
        // default ones lose the right path in noise (no sentence reaches the grammar's end).
        let robust: &[(&str, &str)] = if cfg.noise_robust {
            &[
                ("-remove_silence", "no"),
                ("-beam", "1e-80"),
                ("-pbeam", "1e-80"),
                ("-wbeam", "1e-60"),
            ]
        } else {
            &[]
        };
        let noise = [(
            "-remove_noise",
            if cfg.denoise.is_some() { "no" } else { "yes" },
        )];
        for &(k, v) in robust.iter().chain(noise.iter()) {
            if !base.extra_args.iter().any(|(x, _)| x == k) {
                base.extra_args.push((k.into(), v.into()));
            }
        }
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
            decoded: 0,
            live: None,
            dc: audio::signal::DcRemover::default(),
            centred: Vec::new(),
        })
    }

    pub fn game(&self) -> Game {
        self.game
    }
    pub fn config(&self) -> &RecognizerConfig {
        &self.cfg
    }

    pub fn grammar(&self) -> &Grammar {
        &self.grammar
    }
    /// Utterances the end-pointer dropped as too short.
    pub fn dropped_short(&self) -> u64 {
        self.vad.dropped_short
    }

    /// The utterance the end-pointer has open, if any: the stream time it began and how much
    /// speech it holds so far (s).
    pub fn speech_open(&self) -> Option<(f64, f64)> {
        let (start, _, _) = self.vad.open_prefix()?;
        let loud = self.vad.open_loud_s()?;
        Some((start as f64 / crate::vad::RATE_HZ as f64, loud))
    }

    /// Feed stream samples (16 kHz mono); returns the utterances that ended in them.
    ///
    /// Once the end-pointer has opened an utterance, its samples go to both searches as they
    /// arrive (incremental decoding), so when it ends only the rest of the search remains. The
    /// first utterance after start is decoded whole instead (see [`Recognizer::decode_segment`]).
    pub fn push(&mut self, samples: &[i16]) -> Result<Vec<Recognized>, RecognizerError> {
        let mut centred = std::mem::take(&mut self.centred);
        self.dc.process(samples, &mut centred);
        let out = self.push_centred(&centred);
        self.centred = centred;
        out
    }

    /// [`Recognizer::push`] of samples that come from elsewhere than the person, or not
    /// ([`crate::vad::Vad::set_elsewhere`]: what comes from elsewhere never opens or stretches an
    /// utterance).
    pub fn push_from(
        &mut self,
        samples: &[i16],
        elsewhere: bool,
    ) -> Result<Vec<Recognized>, RecognizerError> {
        self.vad.set_elsewhere(elsewhere);
        self.push(samples)
    }

    /// Whether what is pushed from now on is known to be the person's, a talk key held
    /// ([`crate::vad::Vad::set_hers`]).
    pub fn set_hers(&mut self, hers: bool) {
        self.vad.set_hers(hers);
    }

    /// [`Recognizer::push`] after the offset is removed.
    fn push_centred(&mut self, samples: &[i16]) -> Result<Vec<Recognized>, RecognizerError> {
        let segs = self.vad.push(samples);
        let mut out = Vec::with_capacity(segs.len());
        for seg in segs {
            #[expect(
                clippy::disallowed_methods,
                reason = "the decoding time of an utterance (its `decode_s`): a measurement of compute, on the wall"
            )]
            let t0 = std::time::Instant::now();
            match self.live.take() {
                Some(live) if live.start_sample == seg.start_sample => {
                    out.push(self.finish_live(live, &seg, t0)?);
                }
                other => {
                    if let Some(l) = other {
                        self.abandon_live(l)?;
                    }
                    out.push(self.decode_segment(&seg)?);
                }
            }
        }
        match self.vad.open_prefix().map(|(start, _, lead)| (start, lead)) {
            Some((start, lead_len)) => {
                if self.live.as_ref().is_some_and(|l| l.start_sample != start)
                    && let Some(l) = self.live.take()
                {
                    self.abandon_live(l)?;
                }
                if self.live.is_none() && (self.warmed || self.decoded >= 2) {
                    self.decoder.start()?;
                    if let Some(g) = self.garbage.as_mut() {
                        g.start()?;
                    }
                    let denoiser = self
                        .vad
                        .open_prefix()
                        .and_then(|(_, p, _)| self.denoiser_for(p.get(..lead_len).unwrap_or(p)));
                    self.live = Some(Live {
                        start_sample: start,
                        consumed: 0,
                        begun: false,
                        zeros: 0,
                        kept: Vec::new(),
                        denoiser,
                    });
                }
                if let Some(mut live) = self.live.take() {
                    let fresh = self
                        .vad
                        .open_prefix()
                        .map(|(_, p, _)| p.get(live.consumed..).unwrap_or(&[]).to_vec())
                        .unwrap_or_default();
                    live.consumed += fresh.len();
                    let r = self.feed_live(&mut live, &fresh);
                    self.live = Some(live);
                    r?;
                }
            }
            None => {
                // The end-pointer dropped the utterance (too short).
                if let Some(l) = self.live.take() {
                    self.abandon_live(l)?;
                }
            }
        }
        Ok(out)
    }

    /// End of stream: decode an utterance still open.
    pub fn flush(&mut self) -> Result<Option<Recognized>, RecognizerError> {
        #[expect(
            clippy::disallowed_methods,
            reason = "the decoding time of an utterance (its `decode_s`): a measurement of compute, on the wall"
        )]
        let t0 = std::time::Instant::now();
        let seg = self.vad.flush();
        let live = self.live.take();
        match (seg, live) {
            (Some(seg), Some(live)) if live.start_sample == seg.start_sample => {
                Ok(Some(self.finish_live(live, &seg, t0)?))
            }
            (seg, live) => {
                if let Some(l) = live {
                    self.abandon_live(l)?;
                }
                match seg {
                    Some(s) => Ok(Some(self.decode_segment(&s)?)),
                    None => Ok(None),
                }
            }
        }
    }

    /// Feed the new samples of a live utterance: digital-silence trimming, then enhancement,
    /// then both searches.
    fn feed_live(&mut self, live: &mut Live, fresh: &[i16]) -> Result<(), RecognizerError> {
        let mut kept = Vec::with_capacity(fresh.len());
        for &x in fresh {
            if x == 0 {
                if live.begun {
                    live.zeros += 1;
                }
                continue;
            }
            live.begun = true;
            kept.extend(std::iter::repeat_n(0i16, live.zeros));
            live.zeros = 0;
            kept.push(x);
        }
        live.kept.extend_from_slice(&kept);
        let audio = self.enhance_live(live, &kept, false);
        self.feed_searches(&audio)
    }

    fn enhance_live(&self, live: &mut Live, kept: &[i16], end: bool) -> Vec<i16> {
        let Some(d) = live.denoiser.as_mut() else {
            return kept.to_vec();
        };
        let mut y = d.push(kept);
        if end {
            y.extend(d.flush());
        }
        y
    }

    /// The enhancement for an utterance whose background before the speech is `lead`: `None`
    /// when it is off or the lead holds less than one analysis frame of non-zero samples (digital
    /// silence: nothing to remove, and an estimate from the speech would remove the speech).
    fn denoiser_for(&self, lead: &[i16]) -> Option<Denoiser> {
        let cfg = self.cfg.denoise?;
        let max = (self.cfg.noise_lead_s * RATE_HZ as f64) as usize;
        let noise: Vec<i16> = lead
            .iter()
            .rev()
            .take(max)
            .copied()
            .filter(|&x| x != 0)
            .collect();
        if noise.len() < crate::denoise::N {
            return None;
        }
        let mut d = Denoiser::new(cfg);
        d.set_noise(&noise);
        Some(d)
    }

    fn feed_searches(&mut self, audio: &[i16]) -> Result<(), RecognizerError> {
        if audio.is_empty() {
            return Ok(());
        }
        self.decoder.feed(audio)?;
        if let Some(g) = self.garbage.as_mut() {
            g.feed(audio)?;
        }
        Ok(())
    }

    /// End a live utterance the end-pointer dropped: the searches' results are not used.
    fn abandon_live(&mut self, _live: Live) -> Result<(), RecognizerError> {
        self.decoder.finish()?;
        if let Some(g) = self.garbage.as_mut() {
            g.finish()?;
        }
        Ok(())
    }

    /// The end-pointer closed the live utterance as `seg`: feed its last samples, end both
    /// searches (on two threads) and make the verdict. `t0`: when the segment was cut.
    fn finish_live(
        &mut self,
        mut live: Live,
        seg: &Segment,
        t0: std::time::Instant,
    ) -> Result<Recognized, RecognizerError> {
        let rest = seg.samples.get(live.consumed..).unwrap_or(&[]).to_vec();
        live.consumed += rest.len();
        self.feed_live(&mut live, &rest)?;
        let tail = self.enhance_live(&mut live, &[], true);
        self.feed_searches(&tail)?;
        let (decoder, garbage) = (&mut self.decoder, &mut self.garbage);
        let (g, gar) = std::thread::scope(|scope| {
            let gar = garbage.as_mut().map(|d| scope.spawn(move || d.finish()));
            let g = decoder.finish();
            let gar = gar.map(|j| {
                j.join()
                    .unwrap_or(Err(DecoderError::Decode("garbage search thread")))
            });
            (g, gar)
        });
        let snr_db = estimate_snr_db(&live.kept);
        self.verdict_of(seg, g?, gar.transpose()?, snr_db, t0)
    }

    /// Decode one already-cut utterance (no end-pointing).
    pub fn decode_segment(&mut self, seg: &Segment) -> Result<Recognized, RecognizerError> {
        #[expect(
            clippy::disallowed_methods,
            reason = "the decoding time of an utterance (its `decode_s`): a measurement of compute, on the wall"
        )]
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
        let trimmed = &seg.samples[first..last.max(first)];
        let enhanced;
        let samples = match self.denoiser_for(seg.samples.get(..seg.lead_len).unwrap_or(&[])) {
            Some(mut d) => {
                let mut y = d.push(trimmed);
                y.extend(d.flush());
                enhanced = y;
                &enhanced[..]
            }
            None => trimmed,
        };
        // PocketSphinx's live cepstral mean starts from a fixed prior and adapts at the end of
        // each utterance; until then the features are off and the first utterance after start
        // often decodes to nothing. So the first utterance with a background (not digital
        // silence, whose speech-only mean would mislead it) is decoded twice, and the first pass
        // only warms the mean up.
        let snr_db = estimate_snr_db(trimmed);
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
        self.verdict_of(seg, g?, gar.transpose()?, snr_db, t0)
    }

    fn verdict_of(
        &mut self,
        seg: &Segment,
        g: Hypothesis,
        gar: Option<Hypothesis>,
        snr_db: f64,
        t0: std::time::Instant,
    ) -> Result<Recognized, RecognizerError> {
        self.decoded += 1;
        let decode_s = t0.elapsed().as_secs_f64();
        let frames = g.n_frames;
        let s_gar = match &gar {
            Some(h) if !h.text.is_empty() => h.path_score_ln,
            _ => f64::NEG_INFINITY,
        };
        let v = verdict(
            &self.cfg.confidence,
            self.game,
            &Scores {
                text: &g.text,
                command_ln: g.path_score_ln,
                garbage_ln: s_gar,
                frames,
                snr_db,
                over_talk: seg.over_talk,
                nbest: &g.nbest,
            },
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
            margin_per_frame: v.margin_per_frame,
            snr_db,
            garbage_text: gar.map(|h| h.text).unwrap_or_default(),
            forced: seg.forced,
            over_talk: seg.over_talk,
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
            // A whole recording: which part is background is unknown, so no enhancement.
            lead_len: 0,
            over_talk: false,
        })
    }
}
