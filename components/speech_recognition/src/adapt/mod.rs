//! Acoustic model adaptation: the stock PocketSphinx model re-estimated (MAP) on speech that
//! sounds like what the robot hears.
//!
//! The stock model was trained on clean read speech. In white noise at 10 dB it loses the weak
//! consonants, and the command accuracy drops to about 78 % (BENCHMARKS.md, speech). Maximum a
//! posteriori adaptation moves its Gaussians (means, variances), mixture weights and transitions
//! towards adaptation data, each in proportion to how much data it saw, so what the data does
//! not cover stays as it was. This module runs the CMU SphinxTrain recipe for it:
//!
//! 1. the stock model's files are copied, its `mdef` converted to text
//!    (`pocketsphinx_mdef_convert`) and its mixture weights recovered from the quantized
//!    `sendump` ([`sendump_to_mixture_weights`]), since SphinxTrain reads floats;
//! 2. a corpus is written as 16 kHz WAV files with their transcriptions: either synthesized
//!    ([`Corpus::Synthesized`]: every phrase of both games and a set of ordinary sentences, by
//!    espeak-ng voices that the evaluation never uses, at random speeds and pitches, clean or
//!    mixed with white or brown noise at 20 to 5 dB, and each command again in real rooms
//!    ([`ROOMS`]: reverberation, other people talking, a fan), or recordings ([`Corpus::Recordings`]:
//!    `NAME.wav` with the words in `NAME.txt`, e.g. the robot's users through its microphone);
//! 3. `sphinx_fe` computes the features with the model's `feat.params`;
//! 4. `bw` collects the Baum-Welch statistics along each transcription (utterances it cannot
//!    align are counted and skipped);
//! 5. `map_adapt` re-estimates the parameters from the stock ones and those statistics;
//! 6. steps 4 and 5 again ([`PASSES`]), the statistics now collected with the adapted model
//!    (better alignments in noise), and `mk_s2sendump` quantizes the mixture weights back into a
//!    `sendump`.
//!
//! The result is a complete model folder with a provenance file ([`PROVENANCE_FILE`]) holding
//! the recipe's fingerprint, so a build is skipped when its recipe has not changed.
//!
//! The synthesized corpus adapts the model to espeak-ng's speech as much as to the noise: it is
//! what the simulated person speaks. For people, adapt on recordings of them.

use crate::garbage::Dictionary;
use crate::model::{MODEL_FILES, PROVENANCE_FILE, check_model_dir};
use audio::signal::{
    NoiseKind, NoiseRng, babble, mix_at_snr, mix_with_noise, resample, reverberate,
};
use audio::synth::{Voice, synthesize_16k, talker};
use interfaces::msg::command::{Command, Game};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command as Process;
use std::time::Instant;

mod corpus;
use corpus::*;
mod formats;
pub use formats::*;

/// Bump when the recipe changes in a way the fingerprint does not see (tool options).
pub const RECIPE_VERSION: u32 = 2;

/// Baum-Welch and MAP passes: the second aligns the corpus with the first's model.
pub const PASSES: usize = 2;

/// The synthesized corpus' espeak-ng voices. None of them is an evaluation voice of
/// `scripts/bench speech` (which checks it), nor one of its tuning voices.
pub const VOICES: [&str; 14] = [
    "en-gb-x-gbclan",
    "en-gb-x-gbcwmd",
    "en-us-nyc",
    "en-us+m2",
    "en-us+m4",
    "en-us+m6",
    "en-us+f1",
    "en-us+f2",
    "en-gb+m2",
    "en-gb+m5",
    "en-gb+m6",
    "en-gb+f5",
    "en-gb-scotland+m5",
    "en-gb-scotland+f2",
];

/// Ordinary sentences said once per voice, for phones and contexts the commands lack.
pub const SENTENCES: &str = include_str!("../../adaptation/sentences.txt");

/// How many times each voice says each command phrase (each time at another speed, pitch and
/// noise).
pub const COMMAND_REPEATS: usize = 6;

/// Noise conditions, drawn uniformly for each synthesized utterance (SNR in dB; infinite is
/// clean).
pub const CONDITIONS: [(f64, NoiseKind); 7] = [
    (f64::INFINITY, NoiseKind::White),
    (20.0, NoiseKind::White),
    (15.0, NoiseKind::White),
    (10.0, NoiseKind::White),
    (10.0, NoiseKind::Brown),
    (5.0, NoiseKind::White),
    (5.0, NoiseKind::Brown),
];

/// Seed of the synthesized corpus' speeds, pitches, conditions and noise: the corpus is the
/// same on every machine with the same espeak-ng.
const SEED: u64 = 424_242;

/// How many more times each voice says each command phrase in a real room ([`ROOMS`]), after
/// the [`COMMAND_REPEATS`] in steady noise.
pub const ROOM_REPEATS: usize = 2;

/// What a real room adds to a command of the synthesized corpus (see [`ROOMS`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Room {
    /// Reverberation, no noise: the RT60 drawn uniformly in [`ROOM_RT60_S`].
    Reverb,
    /// Three other voices of the corpus ([`BABBLE_VOICES`]) saying [`SENTENCES`] at this SNR
    /// (dB).
    Babble(f64),
    /// A fan's noise at this SNR (dB).
    Fan(f64),
}

/// The rooms, drawn uniformly for each of the [`ROOM_REPEATS`].
pub const ROOMS: [Room; 6] = [
    Room::Reverb,
    Room::Reverb,
    Room::Babble(5.0),
    Room::Babble(10.0),
    Room::Babble(15.0),
    Room::Fan(10.0),
];

/// The reverberation times of [`Room::Reverb`] (s): a uniform draw between the two.
pub const ROOM_RT60_S: (f64, f64) = (0.3, 0.8);

/// The voices of the corpus ([`VOICES`]) talking in the background of [`Room::Babble`]: three
/// at a time, all but the one saying the command, or all but one drawn at random.
pub const BABBLE_VOICES: [&str; 4] = ["en-us+m4", "en-us+f1", "en-gb+m5", "en-gb-scotland+f2"];

/// Seed of the rooms' draws, apart from [`SEED`], so the utterances in steady noise stay the
/// same whatever the rooms are.
const ROOM_SEED: u64 = 737_373;

/// Where SphinxTrain's programs are on Debian.
const SPHINXTRAIN_LIB: &str = "/usr/lib/sphinxtrain";

#[derive(Debug, thiserror::Error)]
pub enum AdaptError {
    #[error("{program} not found (install the Debian packages {package})")]
    MissingTool {
        program: String,
        package: &'static str,
    },
    #[error(transparent)]
    Model(#[from] crate::model::ModelError),
    #[error("{file}: {message}")]
    File { file: PathBuf, message: String },
    #[error("sendump {file}: {message}")]
    Sendump { file: PathBuf, message: String },
    #[error("recordings {dir}: {message}")]
    Recordings { dir: PathBuf, message: String },
    #[error("words not in the pronunciation dictionary {dict}: {words} (in {examples})")]
    UnknownWords {
        dict: PathBuf,
        words: String,
        examples: String,
    },
    #[error("speech synthesis: {0}")]
    Synth(#[from] audio::synth::SynthError),
    #[error("{step} failed (exit {status}); log {log}: {tail}")]
    Step {
        step: &'static str,
        status: String,
        log: PathBuf,
        tail: String,
    },
    #[error(
        "bw aligned only {aligned} of {total} utterances (log {log}): the transcriptions do not match the audio"
    )]
    Alignment {
        aligned: usize,
        total: usize,
        log: PathBuf,
    },
}

fn file_err(file: &Path, e: impl std::fmt::Display) -> AdaptError {
    AdaptError::File {
        file: file.to_path_buf(),
        message: e.to_string(),
    }
}

/// What to adapt on.
#[derive(Debug, Clone, PartialEq)]
pub enum Corpus {
    /// The synthesized corpus (module doc).
    Synthesized,
    /// `NAME.wav` files (16-bit PCM, any rate, mixed to mono) each with `NAME.txt` (its words).
    Recordings(PathBuf),
}

/// The SphinxTrain and SphinxBase programs the recipe runs.
#[derive(Debug, Clone)]
pub struct Tools {
    pub sphinx_fe: PathBuf,
    pub mdef_convert: PathBuf,
    pub bw: PathBuf,
    pub map_adapt: PathBuf,
    pub mk_s2sendump: PathBuf,
}

impl Tools {
    /// Find them (`PATH`, then SphinxTrain's library folder).
    pub fn find() -> Result<Self, AdaptError> {
        let find = |name: &str, package: &'static str| -> Result<PathBuf, AdaptError> {
            let dirs = std::env::var_os("PATH")
                .map(|p| std::env::split_paths(&p).collect::<Vec<_>>())
                .unwrap_or_default();
            dirs.into_iter()
                .chain([PathBuf::from(SPHINXTRAIN_LIB)])
                .map(|d| d.join(name))
                .find(|p| p.is_file())
                .ok_or_else(|| AdaptError::MissingTool {
                    program: name.into(),
                    package,
                })
        };
        Ok(Self {
            sphinx_fe: find("sphinx_fe", "sphinxbase-utils")?,
            mdef_convert: find("pocketsphinx_mdef_convert", "pocketsphinx")?,
            bw: find("bw", "sphinxtrain")?,
            map_adapt: find("map_adapt", "sphinxtrain")?,
            mk_s2sendump: find("mk_s2sendump", "sphinxtrain")?,
        })
    }
}

/// What to build.
#[derive(Debug, Clone)]
pub struct Recipe {
    pub corpus: Corpus,
    /// The model adapted (a complete PocketSphinx model folder).
    pub base: PathBuf,
    /// The pronunciation dictionary of the transcriptions.
    pub dict: PathBuf,
}

impl Recipe {
    /// The synthesized corpus on the stock model.
    pub fn synthesized() -> Self {
        let dict = pocketsphinx_sys_min::decoder::DecoderConfig::debian().dict;
        Self {
            corpus: Corpus::Synthesized,
            base: crate::model::stock_model_dir(),
            dict,
        }
    }

    /// A fingerprint of everything the result depends on: the recipe's constants, the phrases,
    /// the base model's and dictionary's files (size and modification time), and for recordings
    /// every file's name, size and modification time. Hex FNV-1a, stable across builds.
    pub fn fingerprint(&self) -> String {
        let mut h = Fnv::default();
        h.add(&RECIPE_VERSION.to_le_bytes());
        h.add(SENTENCES.as_bytes());
        for t in command_phrases() {
            h.add(t.as_bytes());
        }
        for v in VOICES {
            h.add(v.as_bytes());
        }
        h.add(&COMMAND_REPEATS.to_le_bytes());
        for (snr, kind) in CONDITIONS {
            h.add(format!("{snr}{kind:?}").as_bytes());
        }
        h.add(&SEED.to_le_bytes());
        h.add(&ROOM_REPEATS.to_le_bytes());
        for room in ROOMS {
            h.add(format!("{room:?}").as_bytes());
        }
        h.add(format!("{ROOM_RT60_S:?}{BABBLE_VOICES:?}").as_bytes());
        h.add(&ROOM_SEED.to_le_bytes());
        h.add(&PASSES.to_le_bytes());
        let mut files: Vec<PathBuf> = MODEL_FILES
            .iter()
            .chain(["sendump", "mixture_weights"].iter())
            .map(|f| self.base.join(f))
            .collect();
        files.push(self.dict.clone());
        if let Corpus::Recordings(dir) = &self.corpus {
            let mut list: Vec<PathBuf> = std::fs::read_dir(dir)
                .map(|rd| rd.flatten().map(|e| e.path()).collect())
                .unwrap_or_default();
            list.sort();
            files.extend(list);
        }
        for f in files {
            h.add(f.to_string_lossy().as_bytes());
            if let Ok(m) = std::fs::metadata(&f) {
                h.add(&m.len().to_le_bytes());
                if let Ok(t) = m.modified()
                    && let Ok(d) = t.duration_since(std::time::UNIX_EPOCH)
                {
                    h.add(&d.as_secs().to_le_bytes());
                }
            }
        }
        format!("{:016x}", h.0)
    }

    /// Whether `out` holds a model built from this recipe.
    pub fn is_built_in(&self, out: &Path) -> bool {
        check_model_dir(out).is_ok()
            && crate::model::provenance(out, "recipe").is_some_and(|r| r == self.fingerprint())
    }
}

/// 64-bit FNV-1a.
struct Fnv(u64);
impl Default for Fnv {
    fn default() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }
}
impl Fnv {
    fn add(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 ^= b as u64;
            self.0 = self.0.wrapping_mul(0x0100_0000_01b3);
        }
        // A separator, so ("ab", "c") and ("a", "bc") differ.
        self.0 = self.0.wrapping_mul(0x0100_0000_01b3) ^ 0xff;
    }
}

/// Every phrase of both games, once.
pub fn command_phrases() -> Vec<&'static str> {
    let mut v: Vec<&'static str> = Vec::new();
    for g in Game::ALL {
        for c in Command::of_game(g) {
            for p in c.phrases() {
                if !v.contains(p) {
                    v.push(p);
                }
            }
        }
    }
    v
}

/// Words of a transcription as the dictionary spells them: lowercase, punctuation other than
/// the apostrophe removed.
pub fn normalize_words(text: &str) -> String {
    text.to_lowercase()
        .chars()
        .map(|c| {
            if c.is_alphanumeric() || c == '\'' {
                c
            } else {
                ' '
            }
        })
        .collect::<String>()
        .split_whitespace()
        .collect::<Vec<_>>()
        .join(" ")
}

/// Progress of a build, for the user.
#[derive(Debug, Clone, PartialEq)]
pub enum Progress {
    Step(String),
    Corpus { done: usize, total: usize },
}

/// What a build did.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    pub utterances: usize,
    pub audio_s: f64,
    /// Utterances `bw` could not align to their transcription (skipped).
    pub not_aligned: usize,
    pub seconds: f64,
    pub summary: String,
}

/// Run one step, its output into `log`.
fn run(step: &'static str, cmd: &mut Process, log: &Path) -> Result<String, AdaptError> {
    let out = cmd.output().map_err(|e| AdaptError::Step {
        step,
        status: "not started".into(),
        log: log.to_path_buf(),
        tail: e.to_string(),
    })?;
    let mut text = String::from_utf8_lossy(&out.stdout).into_owned();
    text.push_str(&String::from_utf8_lossy(&out.stderr));
    std::fs::write(log, &text).map_err(|e| file_err(log, e))?;
    if !out.status.success() {
        let tail: Vec<&str> = text
            .lines()
            .filter(|l| l.contains("ERROR") || l.contains("FATAL"))
            .collect();
        let tail = tail[tail.len().saturating_sub(3)..].join(" | ");
        return Err(AdaptError::Step {
            step,
            status: out.status.code().map_or("signal".into(), |c| c.to_string()),
            log: log.to_path_buf(),
            tail,
        });
    }
    Ok(text)
}

/// Build the adapted model of `recipe` into `out` (replacing what is there, only once the new
/// one is complete). The work folder `<out>.work` is removed on success and kept on failure
/// (its logs say what went wrong).
pub fn build(
    recipe: &Recipe,
    out: &Path,
    progress: &mut dyn FnMut(Progress),
) -> Result<Report, AdaptError> {
    #[expect(
        clippy::disallowed_methods,
        reason = "how long an offline model build took (its report): a measurement of compute"
    )]
    let t0 = Instant::now();
    let tools = Tools::find()?;
    check_model_dir(&recipe.base)?;
    let work = out.with_extension("work");
    let _ = std::fs::remove_dir_all(&work);
    let base = work.join("base");
    std::fs::create_dir_all(&base).map_err(|e| file_err(&base, e))?;
    for f in MODEL_FILES.iter().chain(["noisedict"].iter()) {
        let from = recipe.base.join(f);
        if from.is_file() {
            std::fs::copy(&from, base.join(f)).map_err(|e| file_err(&from, e))?;
        }
    }
    progress(Progress::Step("preparing the base model".into()));
    run(
        "pocketsphinx_mdef_convert",
        Process::new(&tools.mdef_convert)
            .arg("-text")
            .arg(base.join("mdef"))
            .arg(base.join("mdef.txt")),
        &work.join("mdef_convert.log"),
    )?;
    let mixw = base.join("mixture_weights");
    if recipe.base.join("mixture_weights").is_file() {
        std::fs::copy(recipe.base.join("mixture_weights"), &mixw)
            .map_err(|e| file_err(&mixw, e))?;
    } else {
        let sd = recipe.base.join("sendump");
        let bytes = std::fs::read(&sd).map_err(|e| file_err(&sd, e))?;
        let m = sendump_to_mixture_weights(&bytes).map_err(|message| AdaptError::Sendump {
            file: sd.clone(),
            message,
        })?;
        std::fs::write(&mixw, m.to_s3_bytes()).map_err(|e| file_err(&mixw, e))?;
    }

    let corpus_dir = work.join("corpus");
    let mut w = CorpusWriter::new(&corpus_dir)?;
    match &recipe.corpus {
        Corpus::Synthesized => {
            progress(Progress::Step("synthesizing the corpus (espeak-ng)".into()));
            synthesize_corpus(&mut w, progress)?;
        }
        Corpus::Recordings(dir) => {
            progress(Progress::Step(format!("reading {}", dir.display())));
            recordings_corpus(dir, &mut w, progress)?;
        }
    }
    w.finish()?;
    let dict = work.join("adapt.dict");
    corpus_dictionary(&w, &recipe.dict, &dict)?;
    let audio_s = w.samples as f64 / crate::vad::RATE_HZ as f64;

    progress(Progress::Step(format!(
        "features of {} utterances ({:.0} min of audio)",
        w.n,
        audio_s / 60.0
    )));
    let fileids = corpus_dir.join("adapt.fileids");
    run(
        "sphinx_fe",
        Process::new(&tools.sphinx_fe)
            .arg("-argfile")
            .arg(base.join("feat.params"))
            .args(["-samprate", "16000", "-c"])
            .arg(&fileids)
            .arg("-di")
            .arg(corpus_dir.join("wav"))
            .arg("-do")
            .arg(corpus_dir.join("mfc"))
            .args(["-ei", "wav", "-eo", "mfc", "-mswav", "yes"]),
        &work.join("sphinx_fe.log"),
    )?;

    let params = FeatParams::read(&base.join("feat.params"))?;
    // Pass 1 aligns the corpus with the stock model, pass 2 with pass 1's result; each
    // re-estimates from the stock model (the prior) with its statistics.
    let mut align_dir = base.clone();
    let mut not_aligned = 0;
    for pass in 1..=PASSES {
        progress(Progress::Step(format!(
            "Baum-Welch statistics, pass {pass} of {PASSES} (bw; about a minute per hour of audio)"
        )));
        let acc = work.join(format!("acc{pass}"));
        std::fs::create_dir_all(&acc).map_err(|e| file_err(&acc, e))?;
        let bw_log = work.join(format!("bw{pass}.log"));
        let mut bw = Process::new(&tools.bw);
        bw.arg("-hmmdir")
            .arg(&align_dir)
            .arg("-moddeffn")
            .arg(base.join("mdef.txt"))
            .args(["-ts2cbfn", params.ts2cb()])
            .args(["-feat", &params.feat])
            .args(["-cmn", &params.cmn, "-agc", &params.agc])
            .arg("-dictfn")
            .arg(&dict)
            .arg("-fdictfn")
            .arg(base.join("noisedict"))
            .arg("-ctlfn")
            .arg(&fileids)
            .arg("-lsnfn")
            .arg(corpus_dir.join("adapt.transcription"))
            .arg("-cepdir")
            .arg(corpus_dir.join("mfc"))
            .arg("-accumdir")
            .arg(&acc);
        if !params.svspec.is_empty() {
            bw.args(["-svspec", &params.svspec]);
        }
        let bw_out = run("bw", &mut bw, &bw_log)?;
        not_aligned = bw_out.lines().filter(|l| l.contains("ignored")).count();
        let aligned = w.n - not_aligned.min(w.n);
        if aligned * 2 < w.n {
            return Err(AdaptError::Alignment {
                aligned,
                total: w.n,
                log: bw_log,
            });
        }
        progress(Progress::Step(format!(
            "MAP re-estimation, pass {pass} of {PASSES} (map_adapt)"
        )));
        let target = work.join(format!("pass{pass}"));
        std::fs::create_dir_all(&target).map_err(|e| file_err(&target, e))?;
        run(
            "map_adapt",
            Process::new(&tools.map_adapt)
                .arg("-moddeffn")
                .arg(base.join("mdef.txt"))
                .args(["-ts2cbfn", params.ts2cb()])
                .arg("-meanfn")
                .arg(base.join("means"))
                .arg("-varfn")
                .arg(base.join("variances"))
                .arg("-mixwfn")
                .arg(&mixw)
                .arg("-tmatfn")
                .arg(base.join("transition_matrices"))
                .arg("-accumdir")
                .arg(&acc)
                .arg("-mapmeanfn")
                .arg(target.join("means"))
                .arg("-mapvarfn")
                .arg(target.join("variances"))
                .arg("-mapmixwfn")
                .arg(target.join("mixture_weights"))
                .arg("-maptmatfn")
                .arg(target.join("transition_matrices")),
            &work.join(format!("map_adapt{pass}.log")),
        )?;
        align_dir = target;
    }

    let new = out.with_extension("new");
    let _ = std::fs::remove_dir_all(&new);
    std::fs::create_dir_all(&new).map_err(|e| file_err(&new, e))?;
    for f in ["means", "variances", "transition_matrices"] {
        let from = align_dir.join(f);
        std::fs::copy(&from, new.join(f)).map_err(|e| file_err(&from, e))?;
    }
    run(
        "mk_s2sendump",
        Process::new(&tools.mk_s2sendump)
            .args(["-pocketsphinx", "yes", "-moddeffn"])
            .arg(base.join("mdef.txt"))
            .arg("-mixwfn")
            .arg(align_dir.join("mixture_weights"))
            .arg("-sendumpfn")
            .arg(new.join("sendump")),
        &work.join("mk_s2sendump.log"),
    )?;
    for f in ["mdef", "feat.params", "noisedict"] {
        let from = base.join(f);
        if from.is_file() {
            std::fs::copy(&from, new.join(f)).map_err(|e| file_err(&from, e))?;
        }
    }
    let summary = match &recipe.corpus {
        Corpus::Synthesized => format!(
            "MAP-adapted stock en-us on {} synthesized utterances ({} espeak-ng voices, clean to 5 dB SNR, reverberant rooms, other people talking, a fan), {} not aligned",
            w.n,
            VOICES.len(),
            not_aligned
        ),
        Corpus::Recordings(dir) => format!(
            "MAP-adapted stock en-us on {} recordings of {}, {} not aligned",
            w.n,
            dir.display(),
            not_aligned
        ),
    };
    let provenance = serde_json::json!({
        "recipe": recipe.fingerprint(),
        // What `model::adapted_on` reads: only a model adapted on people is the default.
        "corpus": match &recipe.corpus {
            Corpus::Synthesized => "synthesized",
            Corpus::Recordings(_) => "recordings",
        },
        "recipe_version": RECIPE_VERSION,
        "summary": summary,
        "base": recipe.base.display().to_string(),
        "utterances": w.n,
        "audio_s": audio_s,
        "not_aligned": not_aligned,
    });
    let prov = new.join(PROVENANCE_FILE);
    std::fs::write(
        &prov,
        serde_json::to_string_pretty(&provenance).unwrap_or_default(),
    )
    .map_err(|e| file_err(&prov, e))?;
    check_model_dir(&new)?;
    let _ = std::fs::remove_dir_all(out);
    std::fs::rename(&new, out).map_err(|e| file_err(out, e))?;
    let _ = std::fs::remove_dir_all(&work);
    Ok(Report {
        utterances: w.n,
        audio_s,
        not_aligned,
        seconds: t0.elapsed().as_secs_f64(),
        summary,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stock_sendump_becomes_normalized_weights_that_quantize_back() {
        let path = crate::model::stock_model_dir().join("sendump");
        let bytes = std::fs::read(&path).unwrap();
        let m = sendump_to_mixture_weights(&bytes).unwrap();
        assert_eq!((m.n_streams, m.n_densities), (3, 128));
        assert!(m.n_senones > 5000, "{}", m.n_senones);
        for row in m.weights.chunks(m.n_densities) {
            let s: f32 = row.iter().sum();
            assert!((s - 1.0).abs() < 1e-4, "{s}");
        }
        // Quantized again as PocketSphinx does on load, each weight is its byte again (±1:
        // the normalization moves the rounding).
        let data = &bytes[bytes.len() - m.weights.len()..];
        for f in 0..m.n_streams {
            for d in 0..m.n_densities {
                for s in (0..m.n_senones).step_by(97) {
                    let v = data[(f * m.n_densities + d) * m.n_senones + s] as f64;
                    let w = m.weights[(s * m.n_streams + f) * m.n_densities + d] as f64;
                    let q = (-w.ln() / SENDUMP_UNIT_LN).round().min(255.0);
                    assert!((q - v).abs() <= 1.0, "{v} -> {w} -> {q}");
                }
            }
        }
        let s3 = m.to_s3_bytes();
        assert_eq!(s3.len(), 22 + 4 + 16 + 4 * m.weights.len());
    }

    #[test]
    fn a_damaged_sendump_is_an_error() {
        assert!(sendump_to_mixture_weights(&[]).is_err());
        assert!(sendump_to_mixture_weights(&[0xff; 64]).is_err());
        let path = crate::model::stock_model_dir().join("sendump");
        let bytes = std::fs::read(&path).unwrap();
        let e = sendump_to_mixture_weights(&bytes[..bytes.len() - 7]).unwrap_err();
        assert!(e.contains("expected"), "{e}");
    }

    #[test]
    fn transcriptions_are_normalized_to_dictionary_words() {
        assert_eq!(
            normalize_words("Let's play!  Robot,\tplease."),
            "let's play robot please"
        );
        assert_eq!(normalize_words(" ... "), "");
    }

    #[test]
    fn the_fingerprint_follows_the_recipe() {
        let a = Recipe::synthesized();
        assert_eq!(a.fingerprint(), Recipe::synthesized().fingerprint());
        let b = Recipe {
            corpus: Corpus::Recordings(std::env::temp_dir()),
            ..Recipe::synthesized()
        };
        assert_ne!(a.fingerprint(), b.fingerprint());
    }

    #[test]
    fn feat_params_give_the_training_options() {
        let p = FeatParams::parse(
            "-lowerf 130\n-feat 1s_c_d_dd\n-svspec 0-12/13-25/26-38\n-cmn batch\n-model ptm\n",
        );
        assert_eq!(p.feat, "1s_c_d_dd");
        assert_eq!(p.svspec, "0-12/13-25/26-38");
        assert_eq!(p.cmn, "batch");
        assert_eq!(p.agc, "none");
        assert_eq!(p.ts2cb(), ".ptm.");
    }

    #[test]
    fn the_corpus_has_phrases_and_distinct_voices() {
        assert!(!command_phrases().is_empty());
        let v = VOICES;
        let mut sorted = v.to_vec();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), v.len(), "a voice twice");
        for b in BABBLE_VOICES {
            assert!(
                VOICES.contains(&b),
                "{b} talks in the background but is no corpus voice"
            );
        }
    }
}
