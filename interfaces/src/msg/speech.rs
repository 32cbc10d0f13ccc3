//! Audio and speech messages.
//!
//! - **Audio** ([`AudioChunk`]) is interleaved signed 16-bit little-endian PCM; the recognizer
//!   takes 16 000 Hz mono and drops anything else (counted). Chunks of 10–100 ms are typical.
//! - **Times** in seconds on the audio stream are counted from the first sample the recognizer
//!   received (`stream_*_s`); processing times are wall-clock durations (`*_duration_s`).
//! - **Confidence** is in [0, 1]; how the recognizer derives it is documented on
//!   [`Utterance::confidence`].

use crate::header::Header;
use crate::msg::command::{Command, Game};
use serde::{Deserialize, Serialize};

/// A chunk of PCM audio: microphone in (`audio/in`) or synthesized speech out (`audio/out`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AudioChunk {
    pub header: Header,
    /// Samples per second per channel (Hz).
    pub sample_rate_hz: u32,
    /// Interleaved channels (1 = mono).
    pub channels: u16,
    /// Interleaved s16le samples: `2 * channels` bytes per frame.
    #[serde(with = "serde_bytes")]
    pub pcm_s16le: Vec<u8>,
}

impl AudioChunk {
    /// A mono chunk from samples.
    pub fn mono(sample_rate_hz: u32, samples: &[i16]) -> Self {
        Self {
            header: Header::default(),
            sample_rate_hz,
            channels: 1,
            pcm_s16le: samples.iter().flat_map(|s| s.to_le_bytes()).collect(),
        }
    }
    /// A chunk of `channels` interleaved channels from samples.
    pub fn interleaved(sample_rate_hz: u32, channels: u16, samples: &[i16]) -> Self {
        Self {
            channels,
            ..Self::mono(sample_rate_hz, samples)
        }
    }
    /// The samples (interleaved), or `None` when the byte count is odd.
    pub fn samples(&self) -> Option<Vec<i16>> {
        if !self.pcm_s16le.len().is_multiple_of(2) {
            return None;
        }
        Some(
            self.pcm_s16le
                .chunks_exact(2)
                .map(|b| i16::from_le_bytes([b[0], b[1]]))
                .collect(),
        )
    }
    /// Duration in seconds (0 for a malformed chunk).
    pub fn duration_s(&self) -> f64 {
        let frame = 2 * self.channels as usize;
        if frame == 0 || self.sample_rate_hz == 0 {
            return 0.0;
        }
        (self.pcm_s16le.len() / frame) as f64 / self.sample_rate_hz as f64
    }
}

/// One utterance the recognizer cut from the audio stream and decoded (`speech/utterance`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Utterance {
    pub header: Header,
    /// The grammar (game) it was decoded with.
    pub game: Game,
    /// The words recognized, lowercase, space-separated ("" when nothing was recognized).
    pub text: String,
    /// Confidence in [0, 1] that `text` is what was said: see the recognizer's
    /// `speech_recognition::confidence` for the formula (the decoder's lattice posterior of the
    /// best path times a garbage-model acoustic ratio, both turned from log domain with `exp`).
    pub confidence: f64,
    /// The command `text` maps to, `Command::None` when out of grammar.
    pub command: Command,
    /// Whether `text` maps to a command of `game`.
    pub in_grammar: bool,
    /// Start and end of the speech on the input stream, seconds since its first sample.
    pub stream_start_s: f64,
    pub stream_end_s: f64,
    /// Wall-clock time the decoder took on this utterance (s).
    pub decode_duration_s: f64,
    /// Wall-clock delay from the end of speech being detected to this message (s).
    pub latency_s: f64,
}

/// What the recognizer's end-pointer hears on the microphone (`speech/activity`): someone
/// started speaking, or stopped. Published as the end-pointer decides, before any decoding, so a
/// robot talking over the person can yield at once (`audio_io --pause-on-speech`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct VoiceActivity {
    pub header: Header,
    pub state: VoiceState,
    /// When the speech started (for `Started`) or ended, seconds on the input stream as in
    /// [`Utterance::stream_start_s`].
    pub stream_s: f64,
}

/// Where a recognizer that hears through a microphone array listens, and where the sound it hears
/// comes from (`speech/listening`), in the array's own frame (`header.frame_id`: the array's
/// name): azimuths in radians, 0 straight ahead, positive to the left. Sent for the beam's blocks
/// (0.1 s) at most five times a second, and at once when the talker is placed elsewhere or back.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ListeningDirection {
    pub header: Header,
    /// Where the beam listens.
    pub beam_azimuth_rad: f64,
    /// What it is steered at: a node of the deep representation (`player`, `ball`: the person
    /// it holds, through the array's transform at the audio's time), `loudest` (nobody is
    /// known: the loudest talker the localizer finds), or `fixed` (a set azimuth).
    pub listening_to: String,
    /// Whether the localizer placed a sound in the last block (over the stream's floor).
    pub located: bool,
    /// Where it placed it (0 when `located` is false).
    pub talker_azimuth_rad: f64,
    /// Whether that sound was someone else's (away from the beam, and not just after hers):
    /// the end-pointer opened and stretched no utterance on it.
    pub elsewhere: bool,
}

/// The operator's talk key (`speech/talk`), for a recognizer in push-to-talk mode
/// (`speech_recognition --push-to-talk`): only what the microphone hears while the key is held
/// is speech to it; the rest is the room's. Sent when the key goes down, every
/// [`TALK_KEY_REPEAT_S`] while it is held, and when it comes up. The header's stamp is when the
/// key was in that state (the microphone's clock: the bus's wall time).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct TalkKey {
    pub header: Header,
    /// Whether the key is held.
    pub held: bool,
    /// Who holds it (`panel`, a keyboard tool's name), for the logs.
    pub source: String,
}

/// How often a held talk key is sent again (s).
pub const TALK_KEY_REPEAT_S: f64 = 0.5;
/// A held talk key not sent again for this long is taken as released (s): the panel that held
/// it is gone, or its page.
pub const TALK_KEY_EXPIRY_S: f64 = 1.5;

/// The end-pointer's decision.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum VoiceState {
    /// Speech started: an utterance is open and has held speech long enough not to be a
    /// click or a cough (0.15 s of it).
    #[default]
    Started,
    /// The utterance ended; its decoding follows on `speech/utterance`.
    Ended,
    /// The utterance was too short to be speech (a click, a cough): nothing follows.
    Dropped,
}

/// How urgent a request to speak is.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, PartialOrd, Ord, Serialize, Deserialize)]
pub enum Priority {
    Low,
    #[default]
    Normal,
    High,
    /// Interrupts what is being said and jumps the queue.
    Urgent,
}

/// A request to say something (`speech/say`). An [`Priority::Urgent`] request with no text
/// silences the robot: it cuts what is being said and says nothing (the dialog sends one when
/// the player talks over the robot).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SayRequest {
    pub header: Header,
    /// Caller-chosen id, echoed in the [`SpeakingEvent`]s of this utterance.
    pub id: u64,
    pub text: String,
    pub priority: Priority,
}

/// What happened to a [`SayRequest`].
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum SpeakingState {
    #[default]
    Queued,
    Started,
    Finished,
    /// Cut short by an urgent request.
    Interrupted,
    /// Dropped from the queue by an urgent request before it started.
    Dropped,
    /// The synthesizer failed (`detail` says why).
    Failed,
}

/// The generator's progress on a request (`speech/speaking`).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct SpeakingEvent {
    pub header: Header,
    pub id: u64,
    pub text: String,
    pub state: SpeakingState,
    /// Audio duration of the utterance (s), 0 before synthesis.
    pub duration_s: f64,
    pub detail: String,
}
