//! The speech corpus shared by `bench_speech` (evaluation) and `speech_errors` (tuning): one
//! definition of the voices, so the two sets stay apart, and of how a voice is made.

// Each example uses part of it.
#![allow(dead_code)]

use audio::synth::Voice;

/// The evaluation voices: never used to tune anything.
pub const EVAL_VOICES: [&str; 6] = [
    "en-us",
    "en-gb",
    "en-us+f3",
    "en-gb-scotland",
    "en-us+m3",
    "en-gb+f4",
];
/// Voices of two other synthesizer families, built from recordings of real speakers: flite's
/// and festival's (Debian's `flite`, `festival` and its `festvox-*` voices). Evaluation only:
/// nothing in the project is adapted, tuned or chosen on them.
pub const OTHER_FAMILY_VOICES: [&str; 7] = [
    "flite:slt",
    "flite:rms",
    "flite:awb",
    "flite:kal16",
    "festival:kal_diphone",
    "festival:ked_diphone",
    "festival:cmu_us_slt_arctic_hts",
];

/// The evaluation voices of a synthesizer family: `espeak` ([`EVAL_VOICES`]), `flite`,
/// `festival`, or `other` (flite's and festival's, [`OTHER_FAMILY_VOICES`]).
pub fn family_voices(family: &str) -> Option<Vec<&'static str>> {
    let of = |prefix: &str| {
        OTHER_FAMILY_VOICES
            .iter()
            .copied()
            .filter(|v| v.starts_with(prefix))
            .collect()
    };
    match family {
        "espeak" => Some(EVAL_VOICES.to_vec()),
        "flite" => Some(of("flite:")),
        "festival" => Some(of("festival:")),
        "other" => Some(OTHER_FAMILY_VOICES.to_vec()),
        _ => None,
    }
}

/// The tuning voices (`speech_errors tune`), none of them in [`EVAL_VOICES`].
pub const TUNE_VOICES: [&str; 4] = ["en-gb-x-rp", "en-029", "en-us+m1", "en-gb+f2"];
/// Speaking rates (words per minute); the `i`-th also sets the pitch (see [`voice`]).
pub const SPEEDS: [u32; 3] = [130, 175, 220];

/// Voice `name` at the `si`-th speed of [`SPEEDS`], pitch 35, 45 or 55.
pub fn voice(name: &str, si: usize) -> Voice {
    Voice {
        voice: name.to_string(),
        speed_wpm: SPEEDS[si],
        pitch: 35 + 10 * si as u8,
    }
}

/// Noise before and after each utterance of the corpus (s).
pub const LEAD_S: f64 = 0.6;
pub const TRAIL_S: f64 = 0.8;

/// Where the speech ends in the mixed stream (s): the last sample of the clean speech louder
/// than 300/32768, after the [`LEAD_S`] of noise.
pub fn speech_end_s(speech: &[i16]) -> f64 {
    LEAD_S
        + speech
            .iter()
            .rposition(|x| x.unsigned_abs() > 300)
            .unwrap_or(0) as f64
            / 16000.0
}

/// What the room adds to a command: the conditions of the benchmark (and of the tuning aid).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Condition {
    /// Digital silence around the speech.
    Clean,
    /// White noise at this SNR (dB).
    White(f64),
    /// A reverberant room, no noise: the RT60 cycles through [`ROOMS_RT60_S`] clip by clip.
    Reverb,
    /// Other people talking ([`BABBLE_TALKERS`] voices) at this SNR (dB), for
    /// [`BABBLE_LEAD_S`] before the command and [`TRAIL_S`] after.
    Babble(f64),
    /// A fan's noise (broadband rumble and blade tones) at this SNR (dB).
    Fan(f64),
}

/// The rooms' reverberation times (s).
pub const ROOMS_RT60_S: [f64; 3] = [0.3, 0.5, 0.8];
/// How many people talk in the background in [`Condition::Babble`].
pub const BABBLE_TALKERS: usize = 3;
/// Background talk heard before a command (s): long enough for the end-pointer to know the
/// room (it follows the last 3 s of background).
pub const BABBLE_LEAD_S: f64 = 2.5;

/// What the background talkers of the evaluation say: sentences of their own, never said in
/// the adaptation corpus nor in the tuning set's background.
pub const EVAL_BABBLE: &[&str] = &[
    "I think the train leaves at half past four on sunday",
    "we bought three kilos of apples at the market this morning",
    "the meeting was moved to the small room on the second floor",
    "have you seen the new film about the mountains in the south",
    "my neighbour repaired his bicycle in the garden all afternoon",
    "they say it will snow again before the end of the week",
    "the children painted a large picture of a ship and a lighthouse",
    "she has been learning to play the piano for two years now",
    "the soup needs a little more salt and some black pepper",
    "we could walk to the river if the weather stays dry",
];
/// What the background talkers of the tuning set say.
pub const TUNE_BABBLE: &[&str] = &[
    "the library closes early on friday evenings in winter",
    "he forgot his umbrella on the bus again yesterday",
    "the cat sleeps on the warm roof of the car every afternoon",
    "our flight was late because of the fog over the airport",
    "she wrote a long letter to her grandmother in spain",
    "the shop on the corner sells fresh bread and cheese",
];

impl Condition {
    /// The benchmark's conditions, in order: clean, white noise at 20, 10 and 5 dB, reverberant
    /// rooms, babble at 10 dB, a fan at 10 dB.
    pub const ALL: [Condition; 7] = [
        Condition::Clean,
        Condition::White(20.0),
        Condition::White(10.0),
        Condition::White(5.0),
        Condition::Reverb,
        Condition::Babble(10.0),
        Condition::Fan(10.0),
    ];

    /// The name in the benchmark's figures and files (`clean`, `20`, `reverb`, `babble_10`,
    /// `fan_10`: white noise keeps its bare SNR, as in earlier figures).
    pub fn name(&self) -> String {
        match self {
            Condition::Clean => "clean".into(),
            Condition::White(s) => format!("{s}"),
            Condition::Reverb => "reverb".into(),
            Condition::Babble(s) => format!("babble_{s}"),
            Condition::Fan(s) => format!("fan_{s}"),
        }
    }

    pub fn parse(s: &str) -> Option<Condition> {
        if let Some(c) = Self::ALL.iter().find(|c| c.name() == s) {
            return Some(*c);
        }
        let snr = |p: &str| s.strip_prefix(p).and_then(|x| x.parse::<f64>().ok());
        if let Some(x) = snr("babble_") {
            Some(Condition::Babble(x))
        } else if let Some(x) = snr("fan_") {
            Some(Condition::Fan(x))
        } else {
            s.parse().ok().map(Condition::White)
        }
    }

    /// Noise heard before the speech (s).
    pub fn lead_s(&self) -> f64 {
        match self {
            Condition::Babble(_) => BABBLE_LEAD_S,
            _ => LEAD_S,
        }
    }
}

/// The background talkers of a set: each of `voices` says every sentence of `sentences` in
/// turn (starting at a different one), concatenated (16 kHz mono).
pub fn babble_talkers(voices: &[&str], sentences: &[&str]) -> Vec<Vec<i16>> {
    voices
        .iter()
        .enumerate()
        .map(|(vi, v)| {
            let voice = Voice {
                voice: v.to_string(),
                speed_wpm: 160 + 15 * vi as u32,
                pitch: 40 + 5 * vi as u8,
            };
            audio::synth::talker(&voice, sentences, vi).unwrap()
        })
        .collect()
}

/// The level of the room's noise or talk in every clip of a noisy condition (dBFS). A room's
/// noise is steady: the clips of a condition are streamed one after another, as one
/// microphone's signal, and keep it, while each command is said at the condition's SNR over it.
/// (Mixing at an SNR scales the noise to each command's level, so the noise jumped by a few dB
/// from one clip to the next, which no room's noise does.)
pub const NOISE_DBFS: f64 = -45.0;

/// `clip` scaled so that its first `lead_s` (noise or talk only) stand at [`NOISE_DBFS`].
fn at_noise_level(clip: Vec<i16>, lead_s: f64) -> Vec<i16> {
    let lead = &clip[..((lead_s * 16_000.0) as usize).min(clip.len())];
    let p = audio::signal::power(lead);
    if p <= 0.0 {
        return clip;
    }
    audio::signal::gain_clipped(&clip, (10f64.powf(NOISE_DBFS / 10.0) / p).sqrt())
}

/// `speech` in condition `cond`: noise or room before and after it (noise and talk at
/// [`NOISE_DBFS`]). `seed` draws the noise (as
/// it always has for white noise); for the rooms, babble and the fan it is mixed with `clip`,
/// the clip's number (which also picks the room), so every clip has a room and a stretch of talk
/// of its own. `talkers` are the background talkers (for babble).
pub fn in_condition(
    speech: &[i16],
    cond: Condition,
    clip: usize,
    talkers: &[Vec<i16>],
    seed: u64,
) -> Vec<i16> {
    use audio::signal::{NoiseKind, NoiseRng, babble, mix_at_snr, mix_with_noise, reverberate};
    let mut rng = NoiseRng::new(seed);
    let mut own = NoiseRng::new(
        (seed ^ (clip as u64).wrapping_mul(0xD1B5_4A32_D192_ED03))
            .wrapping_mul(0x9E37_79B9_7F4A_7C15),
    );
    let silence = |s: &[i16], lead: f64, trail: f64, rng: &mut NoiseRng| {
        mix_at_snr(s, f64::INFINITY, NoiseKind::White, lead, trail, rng)
    };
    match cond {
        Condition::Clean => silence(speech, LEAD_S, TRAIL_S, &mut rng),
        Condition::White(snr) => at_noise_level(
            mix_at_snr(speech, snr, NoiseKind::White, LEAD_S, TRAIL_S, &mut rng),
            LEAD_S,
        ),
        Condition::Fan(snr) => at_noise_level(
            mix_at_snr(speech, snr, NoiseKind::Fan, LEAD_S, TRAIL_S, &mut own),
            LEAD_S,
        ),
        Condition::Reverb => {
            let rt60 = ROOMS_RT60_S[clip % ROOMS_RT60_S.len()];
            let wet = reverberate(speech, rt60, &mut own);
            // The tail rings into the trailing silence (cut to the usual trail if longer).
            let tail_s = (wet.len() - speech.len()) as f64 / 16_000.0;
            let mut out = silence(&wet, LEAD_S, (TRAIL_S - tail_s).max(0.0), &mut own);
            out.truncate(((LEAD_S + TRAIL_S) * 16_000.0) as usize + speech.len());
            out
        }
        Condition::Babble(snr) => {
            let n = ((BABBLE_LEAD_S + TRAIL_S) * 16_000.0) as usize + speech.len();
            let b = babble(talkers, n, 1e-2, &mut own);
            at_noise_level(
                mix_with_noise(speech, snr, &b, BABBLE_LEAD_S, TRAIL_S),
                BABBLE_LEAD_S,
            )
        }
    }
}

/// Where the speech ends in a clip of condition `cond` (s): as [`speech_end_s`], after that
/// condition's lead.
pub fn speech_end_in(speech: &[i16], cond: Condition) -> f64 {
    speech_end_s(speech) - LEAD_S + cond.lead_s()
}
