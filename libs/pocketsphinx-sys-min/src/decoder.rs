//! A safe PocketSphinx decoder: one acoustic model, one dictionary, a JSGF grammar search (and a
//! phone-loop search). `speech_recognition` runs two of them per game, the command grammar and
//! a filler-word loop, and compares their path scores for the confidence.
//!
//! Audio is 16 000 Hz mono signed 16-bit; the decoder works on 10 ms frames. Scores are in the
//! decoder's log base (`logmath`, base 1.0001 by default) and converted here to natural logs.
//!
//! Not `Sync`: one decoder per thread. `Send` is sound because PocketSphinx keeps no thread-local
//! or global mutable state per decoder; it is simply not re-entrant.

use crate as sys;
use std::ffi::{CStr, CString, c_char};
use std::path::{Path, PathBuf};

/// Where the Debian `pocketsphinx-en-us` package puts the US English model.
pub const DEBIAN_MODEL_DIR: &str = "/usr/share/pocketsphinx/model/en-us";

/// Decoder files and options.
#[derive(Debug, Clone)]
pub struct DecoderConfig {
    /// Acoustic model folder (`mdef`, `means`, ...).
    pub hmm_dir: PathBuf,
    /// Pronunciation dictionary.
    pub dict: PathBuf,
    /// Phone language model of the phone-loop search.
    pub phone_lm: PathBuf,
    /// Where PocketSphinx writes its log (it is chatty); read back on errors, removed when the
    /// decoder is dropped or fails to start (its errors are in the returned error).
    pub log_file: PathBuf,
    /// More `-name value` options for the decoder (beams, weights).
    pub extra_args: Vec<(String, String)>,
    /// Pronunciations added to the dictionary before the grammar is compiled: `(word, phones)`,
    /// `word(2)` for an alternative pronunciation of a word the dictionary has.
    pub extra_words: Vec<(String, String)>,
    /// Most distinct N-best sentences read after each utterance (0: none); at most 4 times as
    /// many lattice paths are visited to find them.
    pub nbest: usize,
}

impl DecoderConfig {
    /// The Debian model, logging into a file of the temp folder unique to this decoder
    /// configuration (removed when the decoder is dropped).
    pub fn debian() -> Self {
        static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
        let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let m = Path::new(DEBIAN_MODEL_DIR);
        Self {
            hmm_dir: m.join("en-us"),
            dict: m.join("cmudict-en-us.dict"),
            phone_lm: m.join("en-us-phone.lm.bin"),
            log_file: std::env::temp_dir()
                .join(format!("pocketsphinx-{}-{n}.log", std::process::id())),
            extra_args: Vec::new(),
            extra_words: Vec::new(),
            nbest: NBEST,
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum DecoderError {
    #[error("model file {0} is missing (install pocketsphinx-en-us)")]
    MissingModel(PathBuf),
    #[error("PocketSphinx rejected its configuration: {0}")]
    Config(String),
    #[error("PocketSphinx could not start (log: {log})")]
    Init { log: String },
    #[error("grammar {name}: PocketSphinx cannot compile it: {log}")]
    Grammar { name: String, log: String },
    #[error("pronunciation {word} [{phones}] refused by PocketSphinx: {log}")]
    Word {
        word: String,
        phones: String,
        log: String,
    },
    #[error("{0} contains a NUL byte")]
    Nul(String),
    #[error("decoding failed in {0}")]
    Decode(&'static str),
}

/// What one search made of one utterance.
#[derive(Debug, Clone, PartialEq)]
pub struct Hypothesis {
    /// Words (grammar search) or phones (phone loop), space-separated; may be empty.
    pub text: String,
    /// Viterbi path score (natural log, ≤ 0): acoustic log-likelihood plus weighted
    /// grammar log-probability and insertion penalties. Comparable between two decoders on the
    /// same audio only when both compute all senones (`-compallsen yes`), see
    /// `speech_recognition::confidence`.
    pub path_score_ln: f64,
    /// Acoustic part of the path score (sum over the word or phone segments of the best path),
    /// natural log.
    pub acoustic_ln: f64,
    /// Lattice posterior of the best path (natural log, ≤ 0). PocketSphinx 5prealpha returns 0
    /// (probability 1) for grammar searches, so it only matters with other versions.
    pub posterior_ln: f64,
    /// Frames decoded (10 ms each).
    pub n_frames: u32,
    /// Distinct sentences of the lattice's N best paths (up to [`DecoderConfig::nbest`]) with their path
    /// scores, best first (empty for the phone loop).
    pub nbest: Vec<(String, f64)>,
}

/// PocketSphinx keeps acoustic (senone) scores, hence path scores, right-shifted by this many
/// bits (`SENSCR_SHIFT`): one unit of a path score is 2^10 units of the logmath base.
pub const SENSCR_SHIFT: u32 = 10;

/// How many distinct N-best sentences are read by default.
pub const NBEST: usize = 20;

/// A PocketSphinx decoder with a grammar search named `grammar` and a phone loop named `phones`.
pub struct Decoder {
    ps: *mut sys::Decoder,
    log_file: PathBuf,
    grammar_name: String,
    phones_only: bool,
    nbest: usize,
}

// SAFETY: see the module doc; the raw pointer is owned and only used through &mut self.
unsafe impl Send for Decoder {}

impl std::fmt::Debug for Decoder {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Decoder({})", self.grammar_name)
    }
}

const SCALE: f64 = (1u32 << SENSCR_SHIFT) as f64;
const GRAMMAR_SEARCH: &str = "grammar";
const PHONE_SEARCH: &str = "phones";
/// Samples per `ps_process_raw` call (128 ms).
const BLOCK: usize = 2048;

fn cstring(s: &str) -> Result<CString, DecoderError> {
    CString::new(s).map_err(|_| DecoderError::Nul(s.to_string()))
}

fn log_tail(path: &Path) -> String {
    let text = std::fs::read_to_string(path).unwrap_or_default();
    let lines: Vec<&str> = text
        .lines()
        .filter(|l| l.contains("ERROR") || l.contains("FATAL"))
        .collect();
    let start = lines.len().saturating_sub(4);
    lines[start..].join(" | ")
}

impl Decoder {
    /// Load the model and compile `jsgf` (the text of a JSGF grammar called `grammar_name` in
    /// errors) as the grammar search; `jsgf` `None` makes a phone-loop-only decoder.
    pub fn new(
        config: &DecoderConfig,
        grammar_name: &str,
        jsgf: Option<&str>,
    ) -> Result<Self, DecoderError> {
        for p in [&config.hmm_dir, &config.dict, &config.phone_lm] {
            if !p.exists() {
                return Err(DecoderError::MissingModel(p.clone()));
            }
        }
        let _ = std::fs::write(&config.log_file, b"");
        let defaults: Vec<(&str, String)> = vec![
            ("-hmm", config.hmm_dir.display().to_string()),
            ("-dict", config.dict.display().to_string()),
            ("-logfn", config.log_file.display().to_string()),
            ("-bestpath", "yes".into()),
            // Digital silence (exact zeros) breaks the log-energy features: add ±1 LSB dither.
            ("-dither", "yes".into()),
        ];
        // `extra_args` override the defaults of the same name (the parser refuses duplicates).
        let mut args: Vec<String> = Vec::new();
        for (k, v) in defaults {
            if !config.extra_args.iter().any(|(x, _)| x == k) {
                args.push(k.to_string());
                args.push(v);
            }
        }
        for (k, v) in &config.extra_args {
            args.push(k.clone());
            args.push(v.clone());
        }
        let cargs = args
            .iter()
            .map(|a| cstring(a))
            .collect::<Result<Vec<_>, _>>()?;
        let mut argv: Vec<*mut c_char> = cargs.iter().map(|c| c.as_ptr() as *mut c_char).collect();
        // SAFETY: argv points to NUL-terminated strings that outlive the call; cmd_ln copies them.
        let cfg = unsafe {
            sys::cmd_ln_parse_r(
                std::ptr::null_mut(),
                sys::ps_args(),
                argv.len() as i32,
                argv.as_mut_ptr(),
                1,
            )
        };
        if cfg.is_null() {
            return Err(DecoderError::Config(args.join(" ")));
        }
        // SAFETY: cfg is a valid config; ps_init retains it, so we release our reference after.
        let ps = unsafe { sys::ps_init(cfg) };
        unsafe { sys::cmd_ln_free_r(cfg) };
        if ps.is_null() {
            let log = log_tail(&config.log_file);
            let _ = std::fs::remove_file(&config.log_file);
            return Err(DecoderError::Init { log });
        }
        let mut me = Decoder {
            ps,
            log_file: config.log_file.clone(),
            grammar_name: grammar_name.to_string(),
            phones_only: false,
            nbest: config.nbest,
        };
        for (word, pron) in &config.extra_words {
            let (w, p) = (cstring(word)?, cstring(pron)?);
            // SAFETY: valid decoder and C strings; the dictionary copies them.
            if unsafe { sys::ps_add_word(me.ps, w.as_ptr(), p.as_ptr(), 0) } < 0 {
                return Err(DecoderError::Word {
                    word: word.clone(),
                    phones: pron.clone(),
                    log: log_tail(&me.log_file),
                });
            }
        }
        let phones = cstring(PHONE_SEARCH)?;
        let lm = cstring(&config.phone_lm.display().to_string())?;
        // SAFETY: valid decoder and C strings.
        if unsafe { sys::ps_set_allphone_file(me.ps, phones.as_ptr(), lm.as_ptr()) } < 0 {
            return Err(DecoderError::Init {
                log: log_tail(&me.log_file),
            });
        }
        match jsgf {
            Some(j) => me.set_grammar(j)?,
            None => {
                let n = cstring(PHONE_SEARCH)?;
                // SAFETY: valid decoder, search added above.
                if unsafe { sys::ps_set_search(me.ps, n.as_ptr()) } < 0 {
                    return Err(DecoderError::Decode("ps_set_search"));
                }
                me.phones_only = true;
            }
        }
        // Started: errors from now on do not read the log, so it goes now (PocketSphinx keeps
        // writing to the open, unlinked file). A process that is killed leaves nothing behind.
        let _ = std::fs::remove_file(&me.log_file);
        Ok(me)
    }

    /// Replace the grammar (between utterances).
    pub fn set_grammar(&mut self, jsgf: &str) -> Result<(), DecoderError> {
        let name = cstring(GRAMMAR_SEARCH)?;
        let text = cstring(jsgf)?;
        // SAFETY: valid decoder and C strings; the decoder copies the grammar.
        if unsafe { sys::ps_set_jsgf_string(self.ps, name.as_ptr(), text.as_ptr()) } < 0 {
            return Err(DecoderError::Grammar {
                name: self.grammar_name.clone(),
                log: log_tail(&self.log_file),
            });
        }
        Ok(())
    }

    fn run(
        &mut self,
        search: &str,
        samples: &[i16],
        want_posterior: bool,
    ) -> Result<Hypothesis, DecoderError> {
        self.start_search(search)?;
        // In blocks, as a live stream would come (`full_utt` batch mode is much slower in
        // this version and no more accurate on short commands).
        for block in samples.chunks(BLOCK) {
            self.feed(block)?;
        }
        self.finish_search(want_posterior)
    }

    fn start_search(&mut self, search: &str) -> Result<(), DecoderError> {
        let name = cstring(search)?;
        // SAFETY: valid decoder and C string.
        unsafe {
            if sys::ps_set_search(self.ps, name.as_ptr()) < 0 {
                return Err(DecoderError::Decode("ps_set_search"));
            }
            if sys::ps_start_utt(self.ps) < 0 {
                return Err(DecoderError::Decode("ps_start_utt"));
            }
        }
        Ok(())
    }

    /// Start an utterance that is fed as it arrives ([`Decoder::feed`]) and ended by
    /// [`Decoder::finish`]: the search runs while the person still speaks, so only the final
    /// step remains after the end of speech.
    pub fn start(&mut self) -> Result<(), DecoderError> {
        self.start_search(if self.phones_only {
            PHONE_SEARCH
        } else {
            GRAMMAR_SEARCH
        })
    }

    /// Feed samples of the utterance begun by [`Decoder::start`].
    pub fn feed(&mut self, samples: &[i16]) -> Result<(), DecoderError> {
        for block in samples.chunks(BLOCK) {
            // SAFETY: valid decoder in an utterance; block is a live slice of that length.
            if unsafe { sys::ps_process_raw(self.ps, block.as_ptr(), block.len(), 0, 0) } < 0 {
                // SAFETY: as above; ends the utterance so the decoder can start another.
                let _ = unsafe { sys::ps_end_utt(self.ps) };
                return Err(DecoderError::Decode("ps_process_raw"));
            }
        }
        Ok(())
    }

    /// End the utterance begun by [`Decoder::start`] and read its hypothesis.
    pub fn finish(&mut self) -> Result<Hypothesis, DecoderError> {
        let p = !self.phones_only;
        self.finish_search(p)
    }

    fn finish_search(&mut self, want_posterior: bool) -> Result<Hypothesis, DecoderError> {
        // SAFETY: valid decoder in an utterance; the hypothesis string is copied before the next
        // call into the decoder.
        unsafe {
            if sys::ps_end_utt(self.ps) < 0 {
                return Err(DecoderError::Decode("ps_end_utt"));
            }
            let mut score: i32 = 0;
            let hyp = sys::ps_get_hyp(self.ps, &mut score);
            let text = if hyp.is_null() {
                String::new()
            } else {
                CStr::from_ptr(hyp).to_string_lossy().trim().to_string()
            };
            let lmath = sys::ps_get_logmath(self.ps);
            let post = if want_posterior && !hyp.is_null() {
                sys::logmath_log_to_ln(lmath, sys::ps_get_prob(self.ps))
            } else {
                0.0
            };
            let mut acoustic: f64 = 0.0;
            let mut seg = sys::ps_seg_iter(self.ps);
            while !seg.is_null() {
                let (mut a, mut l, mut b) = (0i32, 0i32, 0i32);
                sys::ps_seg_prob(seg, &mut a, &mut l, &mut b);
                acoustic += sys::logmath_log_to_ln(lmath, a) * SCALE;
                seg = sys::ps_seg_next(seg);
            }
            let mut nbest: Vec<(String, f64)> = Vec::new();
            if want_posterior && !text.is_empty() && self.nbest > 0 {
                let mut nb = sys::ps_nbest(self.ps);
                let mut read = 0;
                while !nb.is_null() {
                    nb = sys::ps_nbest_next(nb);
                    if nb.is_null() {
                        break;
                    }
                    let mut sc: i32 = 0;
                    let h = sys::ps_nbest_hyp(nb, &mut sc);
                    if !h.is_null() {
                        let t = CStr::from_ptr(h).to_string_lossy().trim().to_string();
                        let sc = sys::logmath_log_to_ln(lmath, sc) * SCALE;
                        if !nbest.iter().any(|(x, _)| *x == t) {
                            nbest.push((t, sc));
                        }
                    }
                    read += 1;
                    if read >= 4 * self.nbest || nbest.len() >= self.nbest {
                        sys::ps_nbest_free(nb);
                        break;
                    }
                }
            }
            Ok(Hypothesis {
                nbest,
                acoustic_ln: acoustic,
                text,
                path_score_ln: sys::logmath_log_to_ln(lmath, score) * SCALE,
                posterior_ln: post.min(0.0),
                n_frames: sys::ps_get_n_frames(self.ps).max(0) as u32,
            })
        }
    }

    /// Decode one whole utterance with the grammar (or the phone loop for a phone-loop decoder).
    pub fn decode(&mut self, samples: &[i16]) -> Result<Hypothesis, DecoderError> {
        if self.phones_only {
            self.run(PHONE_SEARCH, samples, false)
        } else {
            self.run(GRAMMAR_SEARCH, samples, true)
        }
    }
}

impl Drop for Decoder {
    fn drop(&mut self) {
        // SAFETY: ps is the decoder ps_init returned, freed once.
        unsafe {
            sys::ps_free(self.ps);
        }
        let _ = std::fs::remove_file(&self.log_file);
    }
}
