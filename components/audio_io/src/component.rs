//! The `audio_io` component: a capture thread (microphone to `audio/in`) and a playback thread
//! (`audio/out` to the speaker) around the bus loop. See the crate doc for what is counted and
//! what happens when a device goes away.

mod capture;
mod devices;
mod playback;
mod shared;

use capture::{Detector, capture_loop, raw_microphone_loop};
pub use devices::{ArrayLayout, Echo};
use devices::{Presence, open_capture, watch_devices};
use interfaces::clock::Moment;
use playback::playback_loop;
use shared::{Shared, VoiceClock};

use interfaces::msg::speech::{AudioChunk, SpeakingState, VoiceState};
use interfaces::node::{Component, Interface, config_error};
use interfaces::{Bus, Shutdown, topics};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// Where the sound devices are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Driver {
    /// A PulseAudio server (or PipeWire's PulseAudio service), through libpulse.
    Pulse,
}

/// Taking the robot's own voice out of what the microphone hears.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum EchoCancel {
    /// None: the microphone hears the robot as loud as the room does (the dialog must then
    /// ignore what is heard while the robot speaks).
    None,
    /// The sound server's WebRTC canceller (`module-echo-cancel`), loaded between the microphone
    /// and the speaker for as long as this runs: the player can talk over the robot.
    Webrtc,
}

/// What is done with the robot's voice the echo canceller leaves in the microphone.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ResidualEcho {
    /// Tell the player's voice from the robot's (double-talk detection: the microphone captured
    /// as it is, beside the canceller's output, against what the robot played) and take what
    /// the canceller leaves of the robot out of audio/in; before the echo path is measured (the
    /// robot's first second of speech), everything heard while the robot speaks is taken out.
    Suppress,
    /// Leave audio/in as the canceller makes it.
    Keep,
}

/// The `audio_io` flags.
#[derive(Debug, Clone, clap::Args)]
pub struct Config {
    /// Where the microphone and the speaker are.
    #[arg(long, value_enum, default_value_t = Driver::Pulse)]
    pub driver: Driver,
    /// The sound server's address (`unix:/run/user/1000/pulse/native`, `tcp:host:4713`); empty:
    /// libpulse's usual one, which honours `PULSE_SERVER`.
    #[arg(long, default_value = "")]
    pub server: String,
    /// The microphone: a source of the server (`pactl list short sources`), or the server's
    /// default.
    #[arg(long, default_value = pulse::DEFAULT_SOURCE)]
    pub source: String,
    /// The speaker: a sink of the server (`pactl list short sinks`), or the server's default.
    #[arg(long, default_value = pulse::DEFAULT_SINK)]
    pub sink: String,
    /// Do not open the microphone (nothing is published on audio/in).
    #[arg(long)]
    pub no_capture: bool,
    /// Do not open the speaker (audio/out is not played).
    #[arg(long)]
    pub no_playback: bool,
    /// Sample rate of audio/in (Hz); the server converts the microphone to it.
    #[arg(long, default_value_t = 16_000)]
    pub rate_hz: u32,
    /// Length of the audio/in chunks (ms).
    #[arg(long, default_value_t = 20)]
    pub chunk_ms: u32,
    /// Audio the server keeps queued for the speaker (ms): the cushion against under-runs, and the
    /// most that plays after the voice is cut.
    #[arg(long, default_value_t = 200)]
    pub playback_buffer_ms: u32,
    /// How often a lost device is tried again (s).
    #[arg(long, default_value_t = 1.0)]
    pub reopen_s: f64,
    /// Acoustic echo cancellation between the microphone and the speaker (both must be open).
    #[arg(long, value_enum, default_value_t = EchoCancel::None)]
    pub echo_cancel: EchoCancel,
    /// Yield to the person: when the recognizer hears speech start (`speech/activity`) while the
    /// robot speaks, its voice stops at once and what it had left to say is held. It goes on
    /// `--resume-after-s` after the speech ended, unless the sentence was interrupted meanwhile
    /// (the dialog took a command said over it). Only with a microphone that does not hear the
    /// robot (`--echo-cancel webrtc`), or the robot pauses for its own voice.
    #[arg(long, value_name = "true|false", default_value_t = false, action = clap::ArgAction::Set)]
    pub pause_on_speech: bool,
    /// How long after the person stopped speaking a paused sentence goes on (s).
    #[arg(long, default_value_t = 0.8)]
    pub resume_after_s: f64,
    /// With `--echo-cancel webrtc`: what is done with what the canceller leaves of the robot's
    /// voice (the counters `echo_suppressed_frames` and `double_talk_frames` say how often).
    /// With `--pause-on-speech`, the robot also yields the moment the detector hears the player
    /// over it.
    #[arg(long, value_enum, default_value_t = ResidualEcho::Suppress)]
    pub residual_echo: ResidualEcho,
    /// The microphone is an array: every channel of the source goes onto audio/in as it is, in
    /// the source's order, for the recognizer to beamform. A geometry in `models/arrays/`
    /// (kinect_v1, circular_4, circular_6, laptop_2; found under ./models, else built in) or a
    /// geometry file of its own. A source with another channel count than the array's is
    /// captured in mono, said and counted (`array_channel_mismatch`); the game goes on. Empty:
    /// one microphone, as without the flag (a manifest's default).
    #[arg(long, value_name = "NAME|FILE")]
    pub array: Option<String>,
}

/// The longest a sentence stays paused for speech whose end is never heard (the recognizer
/// went away): longer than the end-pointer's longest utterance.
const PAUSED_AT_MOST: Duration = Duration::from_secs(10);

/// How long a sentence paused by the double-talk detector waits for the recognizer to say speech
/// started before it goes on.
const DETECTED_PAUSE: Duration = Duration::from_millis(1500);

impl Config {
    fn server(&self) -> Option<&str> {
        (!self.server.is_empty()).then_some(self.server.as_str())
    }
    fn chunk_frames(&self) -> usize {
        (self.rate_hz as usize * self.chunk_ms as usize) / 1000
    }
}

/// The checked flags, with the microphone already open (so the first chunk is not late).
#[derive(Debug)]
pub struct Prepared {
    config: Config,
    echo: Arc<Echo>,
    /// The microphone and the echo canceller's generation it was opened on.
    capture: Option<(pulse::Capture, u64)>,
}

/// The `audio_io` component.
#[derive(Debug)]
pub struct AudioIo;

impl Component for AudioIo {
    const NAME: &'static str = "audio_io";
    const ABOUT: &'static str = "The robot's microphone onto audio/in and its voice (audio/out) \
        onto the speaker, through a sound server.";
    type Config = Config;
    type Prepared = Prepared;

    fn interface(config: &Config) -> Interface {
        let mut i = Interface::new(Self::NAME);
        if !config.no_capture {
            i = i.publishes(&topics::AUDIO_IN);
        }
        if !config.no_playback {
            i = i
                .subscribes(&topics::AUDIO_OUT)
                .subscribes(&topics::SPEECH_SPEAKING);
            if config.pause_on_speech {
                i = i.subscribes(&topics::SPEECH_ACTIVITY);
            }
        }
        i
    }

    fn prepare(config: Config) -> anyhow::Result<Prepared> {
        prepare(config)
    }

    async fn run(bus: Bus, prepared: Prepared, shutdown: Shutdown) -> anyhow::Result<()> {
        run(bus, prepared, shutdown).await
    }
}

/// Check the flags and the devices: a device the server does not have is an error naming the
/// ones it has.
pub fn prepare(config: Config) -> anyhow::Result<Prepared> {
    anyhow::ensure!(
        !(config.no_capture && config.no_playback),
        "--no-capture and --no-playback together leave nothing to do"
    );
    anyhow::ensure!(
        (8_000..=48_000).contains(&config.rate_hz),
        "--rate-hz must be in 8000..=48000, got {}",
        config.rate_hz
    );
    anyhow::ensure!(
        (5..=200).contains(&config.chunk_ms),
        "--chunk-ms must be in 5..=200, got {}",
        config.chunk_ms
    );
    anyhow::ensure!(
        (20..=2000).contains(&config.playback_buffer_ms),
        "--playback-buffer-ms must be in 20..=2000, got {}",
        config.playback_buffer_ms
    );
    anyhow::ensure!(
        config.echo_cancel == EchoCancel::None || !(config.no_capture || config.no_playback),
        "--echo-cancel needs both the microphone and the speaker (no --no-capture or \
         --no-playback)"
    );
    anyhow::ensure!(
        config.resume_after_s.is_finite() && (0.0..=10.0).contains(&config.resume_after_s),
        "--resume-after-s must be in 0..=10, got {}",
        config.resume_after_s
    );
    anyhow::ensure!(
        config.reopen_s.is_finite() && config.reopen_s > 0.0,
        "--reopen-s must be > 0, got {}",
        config.reopen_s
    );
    let Driver::Pulse = config.driver;
    let devices = pulse::devices(config.server()).map_err(config_error)?;
    tracing::info!("sound server: {}", devices.server);
    if !config.no_playback && !devices.has(pulse::Kind::Sink, &config.sink) {
        return Err(config_error(pulse::Error::NoSuchDevice {
            kind: pulse::Kind::Sink,
            name: config.sink.clone(),
            listing: devices.listing(pulse::Kind::Sink),
        }));
    }
    let array = match config.array.as_deref().map(str::trim) {
        Some(name) if !name.is_empty() => Some(array_layout(&config, name, &devices)?),
        Some(_) => None,
        None => None,
    };
    let echo = Arc::new(Echo::new(&config, array));
    let capture = if config.no_capture {
        None
    } else {
        if !devices.has(pulse::Kind::Source, &config.source) {
            return Err(config_error(pulse::Error::NoSuchDevice {
                kind: pulse::Kind::Source,
                name: config.source.clone(),
                listing: devices.listing(pulse::Kind::Source),
            }));
        }
        Some(open_capture(&config, &echo, None).map_err(config_error)?)
    };
    Ok(Prepared {
        config,
        echo,
        capture,
    })
}

/// The array `--array` names, checked against the flags: its rate must be audio/in's, and the
/// echo canceller's residual suppression works on one channel only.
fn array_layout(
    config: &Config,
    name: &str,
    devices: &pulse::Devices,
) -> anyhow::Result<ArrayLayout> {
    let geometry =
        audio::array::ArrayGeometry::by_name_or_path(name, std::path::Path::new("models"))
            .map_err(|e| config_error(anyhow::anyhow!("--array {name}: {e}")))?;
    anyhow::ensure!(
        !config.no_capture,
        "--array is the microphone's: it has no meaning with --no-capture"
    );
    anyhow::ensure!(
        geometry.sample_rate_hz() == config.rate_hz,
        "--array {name}: the array's geometry is for {} Hz, audio/in is at --rate-hz {}: give          the same rate to both",
        geometry.sample_rate_hz(),
        config.rate_hz
    );
    anyhow::ensure!(
        !(config.echo_cancel == EchoCancel::Webrtc
            && config.residual_echo == ResidualEcho::Suppress),
        "--array with --echo-cancel webrtc needs --residual-echo keep: the residual echo          suppressor works on one channel, and would leave the array's channels out of step"
    );
    let layout = ArrayLayout {
        name: geometry.name().to_string(),
        channels: geometry.channels(),
    };
    if let Some(d) = devices.find(pulse::Kind::Source, &config.source) {
        tracing::info!(
            "microphone array {}: {} microphones; the source {:?} has {} channels ({})",
            layout.name,
            layout.channels,
            d.name,
            d.channels,
            d.channel_map
        );
    }
    Ok(layout)
}

/// What the capture thread tells the bus loop.
#[derive(Debug)]
enum Heard {
    /// A chunk (its channels interleaved), and how long its last sample waited before it was
    /// read (µs).
    Chunk(Vec<i16>, u16, u64),
    /// The double-talk detector heard the player start speaking over the robot.
    PlayerOverRobot,
    /// The microphone failed (why).
    Lost(String),
    /// The microphone is open again.
    Back,
}

/// What the bus loop tells the playback thread.
#[derive(Debug)]
enum Play {
    /// A chunk of the robot's voice, numbered.
    Chunk(u64, AudioChunk),
    /// The generator sent the last chunk of its sentence (what comes next starts another).
    SentenceEnded,
}

/// What the bus loop tells the playback thread at once (on a channel of its own, looked at
/// between two slices of a write).
#[derive(Debug)]
enum Ctl {
    /// Drop what is queued and held, and the chunks numbered up to this: the utterance was
    /// interrupted.
    Cut(u64),
    /// Stop playing at once and hold the rest: someone speaks (`--pause-on-speech`).
    Pause,
    /// Go on with what was held.
    Resume,
}

/// Capture and play until `shutdown`.
pub async fn run(bus: Bus, prepared: Prepared, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let Prepared {
        config,
        echo,
        capture,
    } = prepared;
    let stop = Arc::new(AtomicBool::new(false));
    let presence = Arc::new(Presence::default());
    let watcher = {
        let (config, stop, presence) = (config.clone(), stop.clone(), presence.clone());
        let clock = bus.clock().clone();
        std::thread::Builder::new()
            .name("device-watch".into())
            .spawn(move || watch_devices(&config, &clock, &stop, &presence))?
    };
    let (heard_tx, mut heard_rx) = tokio::sync::mpsc::channel::<Heard>(64);
    let detecting = capture.is_some()
        && !config.no_playback
        && config.echo_cancel != EchoCancel::None
        && config.residual_echo == ResidualEcho::Suppress;
    // What the speaker plays, for the detector: a few seconds of 20 ms slices.
    let (played_tx, played_rx) = match detecting {
        true => {
            let (tx, rx) = std::sync::mpsc::sync_channel(256);
            (Some(tx), Some(rx))
        }
        false => (None, None),
    };
    let shared = Shared {
        config: config.clone(),
        clock: bus.clock().clone(),
        echo: echo.clone(),
        presence: presence.clone(),
        counters: bus.counters().clone(),
        voice: Arc::new(VoiceClock::new(played_tx)),
    };
    let mut capture_thread = None;
    let mut raw_thread = None;
    if let Some(capture) = capture {
        let detector = if let Some(played_rx) = played_rx {
            // Half a second of the microphone's chunks: the capture thread takes them every
            // chunk.
            let depth = (500 / config.chunk_ms.max(1)).max(4) as usize;
            let (raw_tx, raw_rx) = std::sync::mpsc::sync_channel(depth);
            let stop = stop.clone();
            raw_thread = Some(shared.spawn("microphone-raw", move |loops| {
                raw_microphone_loop(loops, &stop, &raw_tx)
            })?);
            Some(Detector::new(raw_rx, played_rx, bus.counters()))
        } else {
            None
        };
        let stop = stop.clone();
        capture_thread = Some(shared.spawn("microphone", move |loops| {
            capture_loop(capture, loops, &stop, &heard_tx, detector)
        })?);
    } else {
        drop(heard_tx);
    }
    let mut audio_in = match capture_thread {
        Some(_) => Some(
            bus.recent_publisher(&topics::AUDIO_IN, topics::AUDIO_IN_KEPT)
                .await?,
        ),
        None => None,
    };
    let mut play_tx = None;
    let mut ctl_tx = None;
    let mut play_thread = None;
    let mut out_sub = None;
    let mut speaking_sub = None;
    if !config.no_playback {
        // A second of 100 ms chunks: the generator paces them in real time, so a full queue
        // means the server stopped taking audio.
        let (tx, rx) = std::sync::mpsc::sync_channel::<Play>(10);
        // Control messages are few (one per sentence cut, per pause, per going on) and looked
        // at every slice: a full queue would be a stuck playback thread.
        let (ctx, crx) = std::sync::mpsc::sync_channel::<Ctl>(64);
        play_thread = Some(shared.spawn("speaker", move |loops| playback_loop(loops, &rx, &crx))?);
        play_tx = Some(tx);
        ctl_tx = Some(ctx);
        out_sub = Some(bus.subscriber(&topics::AUDIO_OUT).await?);
        speaking_sub = Some(bus.subscriber(&topics::SPEECH_SPEAKING).await?);
    }
    let activity_sub = match config.pause_on_speech && !config.no_playback {
        true => Some(bus.subscriber(&topics::SPEECH_ACTIVITY).await?),
        false => None,
    };
    // Chunks of the robot's voice are numbered: a cut drops those sent before it.
    let mut seq: u64 = 0;
    // While paused for someone speaking: when to go on if the sentence was not cut (on the
    // component's clock).
    let mut resume_at: Option<Moment> = None;
    let resume_after = Duration::from_secs_f64(config.resume_after_s);
    let tell = |ctl: Ctl| -> anyhow::Result<()> {
        match &ctl_tx {
            Some(tx) => match tx.try_send(ctl) {
                Ok(()) => Ok(()),
                Err(std::sync::mpsc::TrySendError::Full(c)) => {
                    bus.counters().incr("playback_control_dropped");
                    tracing::warn!("the playback thread is stuck: dropped {c:?}");
                    Ok(())
                }
                Err(std::sync::mpsc::TrySendError::Disconnected(_)) => {
                    Err(anyhow::anyhow!("the playback thread ended"))
                }
            },
            None => Ok(()),
        }
    };
    tracing::info!(
        "{}{}",
        if config.no_capture {
            String::new()
        } else {
            format!(
                "microphone {:?} onto audio/in ({} Hz {}, {} ms chunks)",
                config.source,
                config.rate_hz,
                match echo.array() {
                    Some(a) => format!("{} channels of the array {}", a.channels, a.name),
                    None => "mono".to_string(),
                },
                config.chunk_ms
            )
        },
        if config.no_playback {
            String::new()
        } else {
            format!(
                "{}audio/out onto the speaker {:?}",
                if config.no_capture { "" } else { "; " },
                config.sink
            )
        }
    );
    let chunk_ns = i64::from(config.chunk_ms) * 1_000_000;
    let result = loop {
        tokio::select! {
            heard = heard_rx.recv(), if capture_thread.is_some() => match heard {
                Some(Heard::Chunk(samples, channels, latency_us)) => {
                    if let Some(publisher) = &audio_in {
                        let mut msg = AudioChunk::interleaved(config.rate_hz, channels, &samples);
                        // The time of the chunk's first sample.
                        let at = bus.clock().now_ns() - chunk_ns - (latency_us as i64) * 1000;
                        msg.header.stamp_ns = at.max(1);
                        if let Err(e) = publisher.publish(&mut msg).await {
                            break Err(e.into());
                        }
                    }
                }
                Some(Heard::Lost(why)) => {
                    tracing::warn!(
                        "lost the microphone {:?}: {why}; audio/in is withdrawn until it is back \
                         (trying every {} s)",
                        config.source, config.reopen_s
                    );
                    bus.counters().incr("microphone_lost");
                    audio_in = None;
                }
                Some(Heard::Back) => {
                    tracing::info!("the microphone {:?} is back", config.source);
                    match bus.recent_publisher(&topics::AUDIO_IN, topics::AUDIO_IN_KEPT).await {
                        Ok(p) => audio_in = Some(p),
                        Err(e) => break Err(e.into()),
                    }
                }
                Some(Heard::PlayerOverRobot) => {
                    // The robot yields at once: the recognizer's word that speech started comes
                    // 0.15 s of speech later, and the canceller attenuates the player while the
                    // robot speaks. It goes on when the recognizer says the speech ended, or
                    // after DETECTED_PAUSE if the recognizer never heard speech.
                    if config.pause_on_speech {
                        tracing::debug!("the player speaks over the robot: pausing it");
                        if let Err(e) = tell(Ctl::Pause) {
                            break Err(e);
                        }
                        let until = bus.clock().now() + DETECTED_PAUSE;
                        resume_at = Some(resume_at.map_or(until, |r| r.max(until)));
                    }
                }
                None => break Err(anyhow::anyhow!("the capture thread ended")),
            },
            chunk = next(&out_sub) => {
                let chunk = match chunk {
                    Ok(c) => c,
                    Err(e) => break Err(e.into()),
                };
                seq += 1;
                if let Some(tx) = &play_tx && let Err(e) = tx.try_send(Play::Chunk(seq, chunk)) {
                    match e {
                        std::sync::mpsc::TrySendError::Full(_) => {
                            bus.counters().incr("playback_dropped_queue_full");
                        }
                        std::sync::mpsc::TrySendError::Disconnected(_) => {
                            break Err(anyhow::anyhow!("the playback thread ended"));
                        }
                    }
                }
            }
            event = next(&speaking_sub) => {
                let event = match event {
                    Ok(e) => e,
                    Err(e) => break Err(e.into()),
                };
                if event.state == SpeakingState::Interrupted {
                    resume_at = None;
                    if let Err(e) = tell(Ctl::Cut(seq)) {
                        break Err(e);
                    }
                }
                if matches!(event.state, SpeakingState::Finished | SpeakingState::Failed)
                    && let Some(tx) = &play_tx
                    && let Err(std::sync::mpsc::TrySendError::Disconnected(_)) =
                        tx.try_send(Play::SentenceEnded)
                {
                    break Err(anyhow::anyhow!("the playback thread ended"));
                }
            }
            a = next(&activity_sub) => {
                let a = match a {
                    Ok(a) => a,
                    Err(e) => break Err(e.into()),
                };
                // Someone speaks: the robot stops at once, and goes on `--resume-after-s` after
                // they stopped unless what they said cut its sentence (a command taken over it).
                let now = bus.clock().now();
                resume_at = Some(match a.state {
                    VoiceState::Started => {
                        if let Err(e) = tell(Ctl::Pause) {
                            break Err(e);
                        }
                        now + PAUSED_AT_MOST
                    }
                    VoiceState::Ended => now + resume_after,
                    VoiceState::Dropped => now,
                });
            }
            _ = async {
                match resume_at {
                    Some(t) => bus.clock().sleep_until(t).await,
                    None => std::future::pending().await,
                }
            } => {
                resume_at = None;
                if let Err(e) = tell(Ctl::Resume) {
                    break Err(e);
                }
            }
            _ = shutdown.wait() => break Ok(()),
        }
    };
    stop.store(true, Ordering::Relaxed);
    drop(play_tx);
    drop(ctl_tx);
    // Both threads notice within one chunk or one reopen attempt; they are not waited for longer
    // than that (a stuck server must not hold the shutdown).
    let threads = [capture_thread, raw_thread, play_thread, Some(watcher)];
    await_threads(threads.into_iter().flatten(), Duration::from_secs(2)).await;
    result
}

/// Wait for each of `threads` to end, at most `within` each.
#[expect(
    clippy::disallowed_methods,
    reason = "bounds the shutdown's wait for threads blocked on the real sound server: real time, so a stopped virtual clock cannot hold the shutdown"
)]
async fn await_threads(
    threads: impl Iterator<Item = std::thread::JoinHandle<()>>,
    within: Duration,
) {
    for t in threads {
        let deadline = std::time::Instant::now() + within;
        while !t.is_finished() && std::time::Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    }
}

/// The next message of `sub`, or never when there is none.
async fn next<T: interfaces::Message>(
    sub: &Option<interfaces::Subscriber<T>>,
) -> Result<T, interfaces::BusError> {
    match sub {
        Some(s) => s.recv().await,
        None => std::future::pending().await,
    }
}

#[cfg(test)]
mod tests;
