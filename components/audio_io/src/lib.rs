//! # audio_io: the robot's microphone and speaker
//!
//! One process owns the sound devices. It captures the microphone into `audio/in` (16 kHz mono
//! s16le by default, in 20 ms chunks), the topic the speech recognizer hears, and plays
//! `audio/out`, the robot's voice from the speech generator, on the speaker. The devices are
//! reached through a sound server ([`pulse`]: PulseAudio, or PipeWire's PulseAudio service),
//! chosen by name; the server converts from and to whatever rate and channels the device runs
//! at.
//!
//! - **Drivers** (`--driver`): `pulse`, the only one today. The simulated graphs have no
//!   `audio_io`: the simulated person speaks onto `audio/in` herself, or into a sound server
//!   (`loki_world --voice pulse`) that this component then captures.
//! - **A missing device** at the start is a configuration error (exit 78, no restart) naming the
//!   device and listing the ones the server has.
//! - **A device lost while running** (unplugged, the server restarted) is logged and counted
//!   (`microphone_lost`, `speaker_lost`), and opened again every `--reopen-s` until it is back.
//!   A device that leaves the server does not fail the streams on it (the server moves them to
//!   another device, which would put the wrong microphone in the game without a word), so the
//!   named devices are looked for on the server every `--reopen-s` as well.
//!   While the microphone is away, this component does not publish `audio/in` at all (its
//!   publisher is withdrawn), so the dialog, which watches who writes `audio/in` when told to
//!   (`dialogs --microphones audio_io`), says it cannot hear.
//! - **Counted on `diagnostics`**: `capture_chunks`, `capture_overruns` (chunks dropped because
//!   the bus fell behind the device), `playback_chunks`, `playback_underruns` (the speaker's
//!   buffer ran dry in the middle of an utterance), `playback_malformed` (an `audio/out` chunk
//!   with an odd byte count, no channels or no rate), `playback_dropped_device_lost`,
//!   `playback_dropped_queue_full`, `playback_cut` (speech cut short by an interruption),
//!   `playback_paused` (stopped for someone speaking), `playback_control_dropped`.
//! - **Cutting the voice short**: when `speech/speaking` says an utterance was interrupted (the
//!   player said "stop" over it), what is still queued in the server is dropped at once, not
//!   played out. Audio goes to the server in 20 ms slices, so a cut (or a pause) waits for one
//!   slice at most.
//! - **Echo cancellation** (`--echo-cancel webrtc`): the sound server's WebRTC canceller
//!   (`module-echo-cancel`, without gain control) is loaded between the named microphone and
//!   speaker while this runs; the streams open its source and sink, so the robot's voice is
//!   taken out of `audio/in` and anything else in the room stays. A canceller left by a killed
//!   `audio_io` is replaced; one the server unloaded with a lost device is loaded again when the
//!   device is back. What the canceller leaves of the robot's voice is taken out of `audio/in`
//!   by a double-talk detector ([`double_talk`], `--residual-echo suppress`, the default), which
//!   also captures the microphone as it is and compares it with what the robot played: counted
//!   as `echo_suppressed_frames`, the frames taken for the player over the robot as
//!   `double_talk_frames` (of those, the ones whose microphone samples were not held, passed
//!   as the canceller left them, as `double_talk_unheld_frames`), the player's starts as
//!   `double_talk_onsets`; the echo path it measures is logged.
//! - **Yielding to the person** (`--pause-on-speech true`, behind an echo canceller): when the
//!   double-talk detector hears the player start over the robot, or `speech/activity` says
//!   someone started speaking while the robot speaks, its voice stops at once (what the server
//!   had not played is taken back) and goes on `--resume-after-s` after the speech ended (1.5 s
//!   after the detector's pause if the recognizer heard no speech), unless the sentence was
//!   interrupted meanwhile (a command said over it).
//! - **A microphone array** (`--array NAME|FILE`, a geometry of `models/arrays/`): every
//!   channel of the source goes onto `audio/in` as it is, in the source's order (the stream is
//!   opened with the source's own channel map: with the server's default map an array's `aux`
//!   channels would be remixed, or come out silent), for the recognizer to beamform
//!   (`speech_recognition --array`). Behind `--echo-cancel webrtc` the canceller keeps all the
//!   channels (`use_master_format`), each with the robot's voice taken out; the residual-echo
//!   suppressor works on one channel, so an array there needs `--residual-echo keep`. A source
//!   whose channel count is not the array's (the wrong source or geometry; a device that came
//!   back with fewer channels) is said at every opening, counted as `array_channel_mismatch`,
//!   and `audio/in` goes on in mono, its channels mixed.

pub mod component;
pub mod double_talk;
