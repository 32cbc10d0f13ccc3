//! The adaptation corpus on disk (`wav/ID.wav`, `adapt.fileids`, `adapt.transcription`, its
//! dictionary): synthesized from the command catalog and sentences, or taken from recordings.

use super::*;

/// A corpus being written: `wav/ID.wav`, `adapt.fileids`, `adapt.transcription`.
pub(super) struct CorpusWriter {
    pub(super) dir: PathBuf,
    pub(super) ids: String,
    pub(super) transcription: String,
    pub(super) words: Vec<(String, String)>,
    pub(super) n: usize,
    pub(super) samples: usize,
}

impl CorpusWriter {
    pub(super) fn new(dir: &Path) -> Result<Self, AdaptError> {
        std::fs::create_dir_all(dir.join("wav")).map_err(|e| file_err(dir, e))?;
        Ok(Self {
            dir: dir.to_path_buf(),
            ids: String::new(),
            transcription: String::new(),
            words: Vec::new(),
            n: 0,
            samples: 0,
        })
    }

    /// Add one utterance (16 kHz mono); `source` names it in errors.
    pub(super) fn add(
        &mut self,
        words: &str,
        samples: Vec<i16>,
        source: &str,
    ) -> Result<(), AdaptError> {
        let id = format!("u{:05}", self.n);
        let path = self.dir.join("wav").join(format!("{id}.wav"));
        self.samples += samples.len();
        let pcm = audio::wav::Pcm {
            sample_rate_hz: crate::vad::RATE_HZ,
            channels: 1,
            samples,
        };
        std::fs::write(&path, audio::wav::encode(&pcm)).map_err(|e| file_err(&path, e))?;
        let _ = writeln!(self.ids, "{id}");
        let _ = writeln!(self.transcription, "<s> {words} </s> ({id})");
        self.words.push((words.to_string(), source.to_string()));
        self.n += 1;
        Ok(())
    }

    pub(super) fn finish(&self) -> Result<(), AdaptError> {
        for (name, text) in [
            ("adapt.fileids", &self.ids),
            ("adapt.transcription", &self.transcription),
        ] {
            let p = self.dir.join(name);
            std::fs::write(&p, text).map_err(|e| file_err(&p, e))?;
        }
        Ok(())
    }
}

pub(super) fn synthesize_corpus(
    w: &mut CorpusWriter,
    progress: &mut dyn FnMut(Progress),
) -> Result<(), AdaptError> {
    let sentences: Vec<&str> = SENTENCES
        .lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .collect();
    let phrases = command_phrases();
    let mut texts: Vec<&str> = Vec::new();
    for p in &phrases {
        texts.extend(std::iter::repeat_n(*p, COMMAND_REPEATS));
    }
    texts.extend(&sentences);
    let total = VOICES.len() * (texts.len() + phrases.len() * ROOM_REPEATS);
    let mut rng = NoiseRng::new(SEED);
    let mut room_rng = NoiseRng::new(ROOM_SEED);
    let talkers = BABBLE_VOICES
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let voice = Voice {
                voice: (*v).into(),
                speed_wpm: 150 + 20 * i as u32,
                pitch: 35 + 8 * i as u8,
            };
            talker(&voice, &sentences, i)
        })
        .collect::<Result<Vec<_>, _>>()?;
    // The background of each babble voice's commands: the other three.
    let backgrounds: Vec<Vec<Vec<i16>>> = (0..talkers.len())
        .map(|skip| {
            (0..talkers.len())
                .filter(|&i| i != skip)
                .map(|i| talkers[i].clone())
                .collect()
        })
        .collect();
    for v in VOICES {
        for t in &texts {
            let voice = Voice {
                voice: v.into(),
                speed_wpm: 120 + (rng.uniform() * 110.0) as u32,
                pitch: 30 + (rng.uniform() * 30.0) as u8,
            };
            let speech = synthesize_16k(t, &voice)?;
            let (snr, kind) =
                CONDITIONS[(rng.uniform() * CONDITIONS.len() as f64) as usize % CONDITIONS.len()];
            let audio = mix_at_snr(&speech, snr, kind, 0.3, 0.3, &mut rng);
            w.add(&normalize_words(t), audio, &format!("{v}: {t:?}"))?;
            if w.n.is_multiple_of(200) || w.n == total {
                progress(Progress::Corpus { done: w.n, total });
            }
        }
        for p in &phrases {
            for _ in 0..ROOM_REPEATS {
                let voice = Voice {
                    voice: v.into(),
                    speed_wpm: 120 + (room_rng.uniform() * 110.0) as u32,
                    pitch: 30 + (room_rng.uniform() * 30.0) as u8,
                };
                let speech = synthesize_16k(p, &voice)?;
                let room = ROOMS[(room_rng.uniform() * ROOMS.len() as f64) as usize % ROOMS.len()];
                let audio = in_room(&speech, room, v, &backgrounds, &mut room_rng);
                w.add(
                    &normalize_words(p),
                    audio,
                    &format!("{v} ({room:?}): {p:?}"),
                )?;
                if w.n.is_multiple_of(200) || w.n == total {
                    progress(Progress::Corpus { done: w.n, total });
                }
            }
        }
    }
    Ok(())
}

/// `speech` said by `voice` in `room`, with 0.3 s of the room before and after it (the
/// reverberant tail rings into the 0.3 s after). Over babble the background talkers are
/// `backgrounds[i]`, [`BABBLE_VOICES`] but the `i`-th: but `voice`, or but one drawn at random.
fn in_room(
    speech: &[i16],
    room: Room,
    voice: &str,
    backgrounds: &[Vec<Vec<i16>>],
    rng: &mut NoiseRng,
) -> Vec<i16> {
    const AROUND_S: f64 = 0.3;
    match room {
        Room::Reverb => {
            let (lo, hi) = ROOM_RT60_S;
            let wet = reverberate(speech, lo + (hi - lo) * rng.uniform(), rng);
            let mut out = mix_at_snr(&wet, f64::INFINITY, NoiseKind::White, AROUND_S, 0.0, rng);
            out.resize(speech.len() + (2.0 * AROUND_S * 16_000.0) as usize, 0);
            out
        }
        Room::Fan(snr) => mix_at_snr(speech, snr, NoiseKind::Fan, AROUND_S, AROUND_S, rng),
        Room::Babble(snr) => {
            let skip = BABBLE_VOICES
                .iter()
                .position(|&b| b == voice)
                .unwrap_or((rng.uniform() * backgrounds.len() as f64) as usize % backgrounds.len());
            let n = speech.len() + (2.0 * AROUND_S * 16_000.0) as usize;
            let b = babble(&backgrounds[skip], n, 1e-2, rng);
            mix_with_noise(speech, snr, &b, AROUND_S, AROUND_S)
        }
    }
}

pub(super) fn recordings_corpus(
    dir: &Path,
    w: &mut CorpusWriter,
    progress: &mut dyn FnMut(Progress),
) -> Result<(), AdaptError> {
    let rec_err = |message: String| AdaptError::Recordings {
        dir: dir.to_path_buf(),
        message,
    };
    let mut wavs: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| rec_err(e.to_string()))?
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.extension().is_some_and(|e| e.eq_ignore_ascii_case("wav")))
        .collect();
    wavs.sort();
    if wavs.is_empty() {
        return Err(rec_err("no .wav files".into()));
    }
    let total = wavs.len();
    for wav in wavs {
        let txt = wav.with_extension("txt");
        let text = std::fs::read_to_string(&txt).map_err(|e| {
            rec_err(format!(
                "{} has no transcription {} ({e})",
                wav.display(),
                txt.display()
            ))
        })?;
        let words = normalize_words(&text);
        if words.is_empty() {
            return Err(rec_err(format!("{} is empty", txt.display())));
        }
        let bytes = std::fs::read(&wav).map_err(|e| file_err(&wav, e))?;
        let pcm = audio::wav::parse(&bytes).map_err(|e| file_err(&wav, e))?;
        let samples = resample(&pcm.to_mono(), pcm.sample_rate_hz, crate::vad::RATE_HZ);
        if samples.len() < crate::vad::RATE_HZ as usize / 5 {
            return Err(rec_err(format!("{} is shorter than 0.2 s", wav.display())));
        }
        w.add(&words, samples, &wav.display().to_string())?;
        if w.n.is_multiple_of(50) || w.n == total {
            progress(Progress::Corpus { done: w.n, total });
        }
    }
    Ok(())
}

/// The dictionary of the corpus' words (every pronunciation), or which words it lacks.
pub(super) fn corpus_dictionary(
    w: &CorpusWriter,
    dict_path: &Path,
    out: &Path,
) -> Result<(), AdaptError> {
    let dict = Dictionary::load(dict_path).map_err(|e| file_err(dict_path, e))?;
    let mut words: Vec<&str> = w.words.iter().flat_map(|(t, _)| t.split(' ')).collect();
    words.sort_unstable();
    words.dedup();
    let unknown: Vec<&str> = words
        .iter()
        .copied()
        .filter(|x| !dict.contains(x))
        .collect();
    if !unknown.is_empty() {
        let examples: Vec<&str> = w
            .words
            .iter()
            .filter(|(t, _)| t.split(' ').any(|x| unknown.contains(&x)))
            .take(3)
            .map(|(_, s)| s.as_str())
            .collect();
        return Err(AdaptError::UnknownWords {
            dict: dict_path.to_path_buf(),
            words: unknown.join(", "),
            examples: examples.join("; "),
        });
    }
    let mut text = String::new();
    for word in words {
        for (i, pron) in dict.pronunciations(word).iter().enumerate() {
            if i == 0 {
                let _ = writeln!(text, "{word} {pron}");
            } else {
                let _ = writeln!(text, "{word}({}) {pron}", i + 1);
            }
        }
    }
    std::fs::write(out, text).map_err(|e| file_err(out, e))
}
