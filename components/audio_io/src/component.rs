//! The `audio_io` component: a capture thread (microphone to `audio/in`) and a playback thread
//! (`audio/out` to the speaker) around the bus loop. See the crate doc for what is counted and
//! what happens when a device goes away.

use crate::double_talk::{self, DoubleTalk};
use interfaces::msg::speech::{AudioChunk, SpeakingState, VoiceState};
use interfaces::node::{Component, Interface, config_error};
use interfaces::{Bus, Shutdown, topics};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

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
    /// Sample rate of audio/in (Hz, mono); the server converts the microphone to it.
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

/// The server's echo canceller when `--echo-cancel` asks for one, shared by the capture and the
/// playback threads: the devices they open are the canceller's, not the named ones.
///
/// When a named device goes away the server unloads the canceller with it (or moves its
/// streams), so a thread that lost its device loads a fresh one before reopening, unless the
/// other thread already did since it opened its stream (the generation tells).
#[derive(Debug)]
pub struct Echo {
    config: Config,
    loaded: Mutex<(Option<pulse::EchoCanceller>, u64)>,
}

impl Echo {
    fn new(config: &Config) -> Self {
        Self {
            config: config.clone(),
            loaded: Mutex::new((None, 0)),
        }
    }

    /// The source and the sink to open, and the canceller's generation. After the failure of a
    /// stream opened on generation `failed`, a fresh canceller unless a newer one is loaded;
    /// otherwise the loaded one, if it still is.
    fn devices(&self, failed: Option<u64>) -> Result<(String, String, u64), pulse::Error> {
        let c = &self.config;
        if c.echo_cancel == EchoCancel::None {
            return Ok((c.source.clone(), c.sink.clone(), 0));
        }
        let mut loaded = self.loaded.lock().unwrap_or_else(|p| p.into_inner());
        let (canceller, generation) = &mut *loaded;
        let fresh = match canceller {
            Some(ec) if failed.is_none_or(|g| *generation > g) => ec.loaded()?,
            _ => false,
        };
        let ec = match canceller {
            Some(ec) if fresh => ec,
            _ => {
                // The old one first: the new one takes its devices' names.
                *canceller = None;
                let ec = pulse::EchoCanceller::load(c.server(), &c.source, &c.sink)?;
                tracing::info!(
                    "echo cancellation: the sound server's WebRTC canceller between the microphone \
                 {:?} and the speaker {:?} (module {}: source {:?}, sink {:?})",
                    c.source,
                    c.sink,
                    ec.index(),
                    ec.source(),
                    ec.sink()
                );
                *generation += 1;
                canceller.insert(ec)
            }
        };
        Ok((ec.source().to_string(), ec.sink().to_string(), *generation))
    }
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
    let echo = Arc::new(Echo::new(&config));
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

/// Open the microphone (the canceller's source with `--echo-cancel`; see [`Echo::devices`] for
/// `failed`); the stream and the canceller's generation.
fn open_capture(
    config: &Config,
    echo: &Echo,
    failed: Option<u64>,
) -> Result<(pulse::Capture, u64), pulse::Error> {
    let (source, _, generation) = echo.devices(failed)?;
    let capture = pulse::Capture::open(
        config.server(),
        &source,
        config.rate_hz,
        1,
        config.chunk_frames(),
        "robot microphone",
    )?;
    Ok((capture, generation))
}

/// Whether the named devices are on the server, as the device watcher last saw. A source or a
/// sink that goes away does not fail the streams on it: the server moves them to another device
/// (the built-in microphone, say), which would put the wrong microphone or speaker in the game
/// without a word. So the watcher asks the server for its devices every `--reopen-s`, and the
/// threads close a stream whose named device is gone. The server's defaults are not watched:
/// following the default is what they mean.
#[derive(Debug, Default)]
struct Presence {
    source_missing: AtomicBool,
    sink_missing: AtomicBool,
}

/// Keep `presence` current until `stop`.
fn watch_devices(config: &Config, stop: &AtomicBool, presence: &Presence) {
    let named_source = !config.no_capture && config.source != pulse::DEFAULT_SOURCE;
    let named_sink = !config.no_playback && config.sink != pulse::DEFAULT_SINK;
    if !named_source && !named_sink {
        return;
    }
    let every = Duration::from_secs_f64(config.reopen_s);
    while !stop.load(Ordering::Relaxed) {
        // (A server that cannot be asked fails the streams by itself.)
        if let Ok(d) = pulse::devices(config.server()) {
            presence.source_missing.store(
                named_source && !d.has(pulse::Kind::Source, &config.source),
                Ordering::Relaxed,
            );
            presence.sink_missing.store(
                named_sink && !d.has(pulse::Kind::Sink, &config.sink),
                Ordering::Relaxed,
            );
        }
        let next = Instant::now() + every;
        while Instant::now() < next && !stop.load(Ordering::Relaxed) {
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

fn gone(kind: pulse::Kind, name: &str) -> pulse::Error {
    pulse::Error::Stream {
        kind,
        device: name.to_string(),
        reason: "the device is no longer on the sound server".into(),
    }
}

/// What the capture thread tells the bus loop.
#[derive(Debug)]
enum Heard {
    /// A chunk, and how long its last sample waited before it was read (µs).
    Chunk(Vec<i16>, u64),
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
        std::thread::Builder::new()
            .name("device-watch".into())
            .spawn(move || watch_devices(&config, &stop, &presence))?
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
        echo: echo.clone(),
        presence: presence.clone(),
        counters: bus.counters().clone(),
        voice: Arc::new(VoiceClock {
            origin: Instant::now(),
            played: played_tx,
        }),
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
        Some(_) => Some(bus.publisher(&topics::AUDIO_IN).await?),
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
    // While paused for someone speaking: when to go on if the sentence was not cut.
    let mut resume_at: Option<tokio::time::Instant> = None;
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
                "microphone {:?} onto audio/in ({} Hz mono, {} ms chunks)",
                config.source, config.rate_hz, config.chunk_ms
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
                Some(Heard::Chunk(samples, latency_us)) => {
                    if let Some(publisher) = &audio_in {
                        let mut msg = AudioChunk::mono(config.rate_hz, &samples);
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
                    match bus.publisher(&topics::AUDIO_IN).await {
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
                        let until = tokio::time::Instant::now() + DETECTED_PAUSE;
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
                let now = tokio::time::Instant::now();
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
                    Some(t) => tokio::time::sleep_until(t).await,
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
    for t in [capture_thread, raw_thread, play_thread, Some(watcher)]
        .into_iter()
        .flatten()
    {
        let deadline = Instant::now() + Duration::from_secs(2);
        while !t.is_finished() && Instant::now() < deadline {
            tokio::time::sleep(Duration::from_millis(10)).await;
        }
    }
    result
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

/// What the capture and the playback threads share.
struct Loops<'a> {
    config: &'a Config,
    echo: &'a Echo,
    presence: &'a Presence,
    counters: &'a interfaces::bus::Counters,
    voice: &'a VoiceClock,
}

/// What the capture and the playback threads are started with (owned, for [`Loops`]).
#[derive(Clone)]
struct Shared {
    config: Config,
    echo: Arc<Echo>,
    presence: Arc<Presence>,
    counters: Arc<interfaces::bus::Counters>,
    voice: Arc<VoiceClock>,
}

impl Shared {
    /// Run `f` on a thread named `name`, over a [`Loops`] of its own copy of these.
    fn spawn(
        &self,
        name: &str,
        f: impl FnOnce(&Loops) + Send + 'static,
    ) -> std::io::Result<std::thread::JoinHandle<()>> {
        let shared = self.clone();
        std::thread::Builder::new()
            .name(name.into())
            .spawn(move || {
                f(&Loops {
                    config: &shared.config,
                    echo: &shared.echo,
                    presence: &shared.presence,
                    counters: &shared.counters,
                    voice: &shared.voice,
                })
            })
    }
}

/// The clock the capture threads and the playback thread share (ns since `origin`), and what
/// the playback thread tells the double-talk detector: what the robot played, and when.
#[derive(Debug)]
struct VoiceClock {
    origin: Instant,
    /// To the capture thread's detector; `None` without one.
    played: Option<std::sync::mpsc::SyncSender<Played>>,
}

/// What the speaker played, for the double-talk detector.
#[derive(Debug)]
enum Played {
    /// Mono samples at a rate, the first playing at a time (ns).
    Voice(i64, u32, Vec<i16>),
    /// What was queued from this time (ns) on was thrown away.
    DroppedFrom(i64),
}

impl VoiceClock {
    fn ns(&self, t: Instant) -> i64 {
        i64::try_from(t.saturating_duration_since(self.origin).as_nanos()).unwrap_or(i64::MAX)
    }

    /// When the first sample of a chunk of `frames` at `rate_hz` just read was heard, the stream
    /// saying its last one waited `latency_us`.
    fn heard_ns(&self, frames: usize, rate_hz: u32, latency_us: u64) -> i64 {
        let chunk = frames as i64 * 1_000_000_000 / i64::from(rate_hz.max(1));
        self.ns(Instant::now()) - chunk - latency_us as i64 * 1000
    }

    /// `samples` (interleaved, `channels`) play from `at` on.
    fn played(
        &self,
        at: Instant,
        (rate_hz, channels): (u32, usize),
        samples: &[i16],
        counters: &interfaces::bus::Counters,
    ) {
        let Some(tx) = &self.played else {
            return;
        };
        let mono: Vec<i16> = samples
            .chunks(channels.max(1))
            .map(|f| (f.iter().map(|&x| i32::from(x)).sum::<i32>() / f.len() as i32) as i16)
            .collect();
        if tx
            .try_send(Played::Voice(self.ns(at), rate_hz, mono))
            .is_err()
        {
            counters.incr("double_talk_reference_dropped");
        }
    }

    /// What the server held was thrown away.
    fn stopped(&self, counters: &interfaces::bus::Counters) {
        if let Some(tx) = &self.played
            && tx
                .try_send(Played::DroppedFrom(self.ns(Instant::now())))
                .is_err()
        {
            counters.incr("double_talk_reference_dropped");
        }
    }
}

/// The microphone as it is (the canceller's master source), for the double-talk detector: what
/// it hears, with when, until `stop`. A failure is retried every `--reopen-s` without a word
/// beyond a log line: the detector then takes everything heard while the robot speaks for the
/// robot's, which is safe.
fn raw_microphone_loop(
    loops: &Loops,
    stop: &AtomicBool,
    tx: &std::sync::mpsc::SyncSender<(i64, Vec<i16>)>,
) {
    let config = loops.config;
    let open = || {
        pulse::Capture::open(
            config.server(),
            &config.source,
            config.rate_hz,
            1,
            config.chunk_frames(),
            "robot microphone, as heard (double-talk detection)",
        )
    };
    let mut capture = match open() {
        Ok(c) => c,
        Err(e) => {
            tracing::warn!(
                "cannot open the microphone {:?} beside the echo canceller: {e}; until it opens, \
                 what is heard while the robot speaks is taken for the robot's voice",
                config.source
            );
            match reopen(config, stop, open) {
                Some(c) => c,
                None => return,
            }
        }
    };
    let mut samples = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        match capture.read(&mut samples) {
            Ok(()) => {
                let latency = capture.latency_us().unwrap_or(0);
                let t = loops.voice.heard_ns(samples.len(), config.rate_hz, latency);
                match tx.try_send((t, std::mem::take(&mut samples))) {
                    Ok(()) => {}
                    Err(std::sync::mpsc::TrySendError::Full(_)) => {
                        loops.counters.incr("double_talk_microphone_overruns");
                    }
                    Err(std::sync::mpsc::TrySendError::Disconnected(_)) => return,
                }
            }
            Err(e) => {
                tracing::warn!(
                    "lost the microphone {:?} beside the echo canceller: {e}; opening it again",
                    config.source
                );
                match reopen(config, stop, open) {
                    Some(c) => capture = c,
                    None => return,
                }
            }
        }
    }
}

/// The double-talk detector of the capture thread, and what it is fed: the microphone's frames
/// and what the speaker played.
struct Detector {
    dt: DoubleTalk,
    raw: std::sync::mpsc::Receiver<(i64, Vec<i16>)>,
    played: std::sync::mpsc::Receiver<Played>,
    /// The time of the end of the microphone's last frame given to `dt`.
    raw_until_ns: i64,
    /// The canceller's output held back (first sample's time, samples), while the robot's voice
    /// may be in the room, until the microphone's frames of the next `holdback_ns` are known.
    held: std::collections::VecDeque<(i64, Vec<i16>)>,
    /// The counters `echo_suppressed_frames`, `double_talk_frames` and
    /// `double_talk_unheld_frames`.
    suppressed: Arc<std::sync::atomic::AtomicU64>,
    player: Arc<std::sync::atomic::AtomicU64>,
    unheld: Arc<std::sync::atomic::AtomicU64>,
}

impl Detector {
    fn new(
        raw: std::sync::mpsc::Receiver<(i64, Vec<i16>)>,
        played: std::sync::mpsc::Receiver<Played>,
        counters: &interfaces::bus::Counters,
    ) -> Self {
        Self {
            dt: DoubleTalk::new(double_talk::Config::default()),
            raw,
            played,
            raw_until_ns: i64::MIN,
            held: Default::default(),
            suppressed: counters.counter("echo_suppressed_frames"),
            player: counters.counter("double_talk_frames"),
            unheld: counters.counter("double_talk_unheld_frames"),
        }
    }

    /// A chunk of the canceller's output heard at `t_ns`; the chunks held back long enough,
    /// the robot's residue in them taken out, with when their first samples were heard.
    fn process(&mut self, loops: &Loops, t_ns: i64, samples: Vec<i16>) -> Vec<(i64, Vec<i16>)> {
        let rate = loops.config.rate_hz;
        let ns = |n: usize, rate: u32| n as i64 * 1_000_000_000 / i64::from(rate.max(1));
        while let Ok(p) = self.played.try_recv() {
            match p {
                Played::Voice(t, r, mono) => self.dt.reference(t, r, &mono),
                Played::DroppedFrom(t) => self.dt.reference_dropped_from(t),
            }
        }
        // The microphone's frames up to this chunk's end: they were heard at the same time (the
        // canceller's output comes later), but their thread may not have run yet, on a busy
        // machine for tens of milliseconds. (Not waited for when that stream is not
        // delivering: lost, or not open yet.)
        let end = t_ns + ns(samples.len(), rate);
        let delivering = self.raw_until_ns > t_ns - 500_000_000;
        let deadline = Instant::now() + Duration::from_millis(if delivering { 100 } else { 0 });
        loop {
            while let Ok((t, raw)) = self.raw.try_recv() {
                self.raw_until_ns = t + ns(raw.len(), rate);
                self.dt.mic(t, rate, &raw);
            }
            if self.raw_until_ns >= end || Instant::now() >= deadline {
                break;
            }
            std::thread::sleep(Duration::from_millis(2));
        }
        self.dt.canceller(t_ns, rate, &samples);
        self.held.push_back((t_ns, samples));
        let lookback = self.dt.holdback_ns();
        let mut ready = Vec::new();
        // Held back only while the robot's voice may be in the room, where the player's first
        // sounds may come before they are known to be hers.
        while self.held.front().is_some_and(|(t, s)| {
            t + ns(s.len(), rate) + lookback <= end || !self.dt.robot_may_be_heard(*t)
        }) {
            let Some((t, mut s)) = self.held.pop_front() else {
                break;
            };
            let o = self.dt.process(t, rate, &mut s);
            self.suppressed
                .fetch_add(u64::from(o.suppressed_frames), Ordering::Relaxed);
            self.player
                .fetch_add(u64::from(o.player_frames), Ordering::Relaxed);
            if o.unheld_frames > 0 {
                let before = self
                    .unheld
                    .fetch_add(u64::from(o.unheld_frames), Ordering::Relaxed);
                if before == 0 {
                    tracing::warn!(
                        "the player's frames at {t} ns passed as the canceller left them: the \
                         microphone's samples of their time were not held (a gap in its stream \
                         or a rate change); counted as double_talk_unheld_frames"
                    );
                }
            }
            ready.push((t, s));
        }
        if let Some(p) = self.dt.path_changed() {
            tracing::info!(
                "the robot's voice reaches the microphone {} ms after it is played, {:+.0} dB \
                 (levels correlated {:.2}), and dies away at {:.0} dB/s: the player can talk \
                 over it {:.0} dB louder than that",
                p.delay_frames * 10,
                p.gain_db,
                p.correlation,
                p.decay_db_per_s,
                p.margin_db
            );
        }
        ready
    }
}

/// Read the microphone until `stop`, reopening it when it fails; with a detector, the robot's
/// voice the canceller left in is taken out first.
fn capture_loop(
    (mut capture, mut generation): (pulse::Capture, u64),
    loops: &Loops,
    stop: &AtomicBool,
    tx: &tokio::sync::mpsc::Sender<Heard>,
    mut detector: Option<Detector>,
) {
    let Loops {
        config,
        echo,
        presence,
        counters,
        ..
    } = *loops;
    let mut samples = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        let read = match capture.read(&mut samples) {
            Ok(()) if presence.source_missing.load(Ordering::Relaxed) => {
                Err(gone(pulse::Kind::Source, &config.source))
            }
            other => other,
        };
        match read {
            Ok(()) => {
                counters.incr("capture_chunks");
                let latency = capture.latency_us().unwrap_or(0);
                let chunks = match detector.as_mut() {
                    Some(d) => {
                        let t = loops.voice.heard_ns(samples.len(), config.rate_hz, latency);
                        let ready = d.process(loops, t, std::mem::take(&mut samples));
                        if d.dt.player_started() {
                            counters.incr("double_talk_onsets");
                            let _ = tx.try_send(Heard::PlayerOverRobot);
                        }
                        // Held back: how long their last samples waited by now.
                        let now = loops.voice.ns(Instant::now());
                        ready
                            .into_iter()
                            .map(|(t, s)| {
                                let end = t + s.len() as i64 * 1_000_000_000
                                    / i64::from(config.rate_hz.max(1));
                                (s, u64::try_from((now - end) / 1000).unwrap_or(0))
                            })
                            .collect()
                    }
                    None => vec![(std::mem::take(&mut samples), latency)],
                };
                for (chunk, waited_us) in chunks {
                    match tx.try_send(Heard::Chunk(chunk, waited_us)) {
                        Ok(()) => {}
                        Err(tokio::sync::mpsc::error::TrySendError::Full(_)) => {
                            counters.incr("capture_overruns");
                        }
                        Err(tokio::sync::mpsc::error::TrySendError::Closed(_)) => return,
                    }
                }
            }
            Err(e) => {
                if tx.blocking_send(Heard::Lost(e.to_string())).is_err() {
                    return;
                }
                let open = || {
                    if presence.source_missing.load(Ordering::Relaxed) {
                        Err(gone(pulse::Kind::Source, &config.source))
                    } else {
                        open_capture(config, echo, Some(generation))
                    }
                };
                let Some(again) = reopen(config, stop, open) else {
                    return;
                };
                (capture, generation) = again;
                if tx.blocking_send(Heard::Back).is_err() {
                    return;
                }
            }
        }
    }
}

/// Try `open` every `--reopen-s` until it works (`None` once `stop` is set).
fn reopen<T>(
    config: &Config,
    stop: &AtomicBool,
    mut open: impl FnMut() -> Result<T, pulse::Error>,
) -> Option<T> {
    let every = Duration::from_secs_f64(config.reopen_s);
    let mut last_error = String::new();
    loop {
        let next = Instant::now() + every;
        while Instant::now() < next {
            if stop.load(Ordering::Relaxed) {
                return None;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        match open() {
            Ok(t) => return Some(t),
            Err(e) => {
                let e = e.to_string();
                if e != last_error {
                    tracing::debug!("still cannot open it: {e}");
                    last_error = e;
                }
            }
        }
    }
}

/// The speaker's stream and what this thread knows of it.
struct Speaker {
    stream: pulse::Playback,
    /// When what was written so far has played (this thread's count, without the device's own
    /// latency); `None` before the first chunk, after a cut and while paused.
    queued_until: Option<Instant>,
    /// Whether a sentence is under way (a chunk written, and the generator has not said it
    /// ended): a chunk of it that finds the queue empty came too late, an under-run.
    in_sentence: bool,
    /// The last samples written (interleaved), enough to cover the server's buffer: what a
    /// pause takes back from the server is played from here when the robot goes on.
    recent: std::collections::VecDeque<i16>,
    /// While paused: the samples to play when the robot goes on (what the server had not
    /// played, then what came since).
    held: Option<Vec<i16>>,
}

/// The playback thread's state: the speaker (opened for the format of the chunks that come),
/// and what the bus loop said.
struct Player<'a> {
    loops: &'a Loops<'a>,
    ctl: &'a std::sync::mpsc::Receiver<Ctl>,
    speaker: Option<Speaker>,
    /// After a failure, the next attempt to open the speaker is not before this.
    retry_at: Instant,
    lost: bool,
    /// The echo canceller's generation the last stream was opened on.
    generation: u64,
    buffer: Duration,
    /// Chunks numbered up to this were cut: they are not played.
    cut_upto: u64,
}

/// Play what the bus loop sends until it hangs up.
///
/// The server starts a stream only once it holds `--playback-buffer-ms` of it, and the speech
/// generator sends its chunks in real time: so the first chunk of a sentence is preceded by
/// enough silence to fill that buffer at once. The sentence starts at once (after the silence),
/// short sounds play without waiting for more, and the buffer keeps its cushion against late
/// chunks for the whole sentence. Audio is written in slices of [`SLICE`], and the bus loop's
/// control messages (cut, pause, go on) are looked at between two slices: a write that waits for
/// room in the server's buffer never holds them up for longer than a slice.
fn playback_loop(
    loops: &Loops,
    rx: &std::sync::mpsc::Receiver<Play>,
    ctl: &std::sync::mpsc::Receiver<Ctl>,
) {
    let mut p = Player {
        loops,
        ctl,
        speaker: None,
        retry_at: Instant::now(),
        lost: false,
        generation: 0,
        buffer: Duration::from_millis(u64::from(loops.config.playback_buffer_ms)),
        cut_upto: 0,
    };
    loop {
        p.control(&mut Vec::new());
        if p.loops.presence.sink_missing.load(Ordering::Relaxed) && p.speaker.is_some() {
            let e = gone(pulse::Kind::Sink, &p.loops.config.sink);
            p.failed(&e);
        }
        let cmd = match rx.recv_timeout(SLICE) {
            Ok(cmd) => cmd,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => continue,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => return,
        };
        match cmd {
            Play::SentenceEnded => {
                if let Some(s) = p.speaker.as_mut() {
                    s.in_sentence = false;
                }
            }
            Play::Chunk(seq, _) if seq <= p.cut_upto => {}
            Play::Chunk(_, chunk) => p.chunk(&chunk),
        }
    }
}

/// How much is written to the server at once.
const SLICE: Duration = Duration::from_millis(20);

impl Player<'_> {
    /// Act on the control messages that came; `rest` is what the caller has not written yet of
    /// what it is writing (a pause holds it, a cut drops it). Whether to stop writing.
    fn control(&mut self, rest: &mut Vec<i16>) -> bool {
        let mut stop = false;
        while let Ok(c) = self.ctl.try_recv() {
            match c {
                Ctl::Cut(upto) => {
                    self.cut_upto = self.cut_upto.max(upto);
                    rest.clear();
                    stop = true;
                    self.cut();
                }
                Ctl::Pause => {
                    let taken = std::mem::take(rest);
                    stop = true;
                    self.pause(taken);
                }
                Ctl::Resume => self.resume(),
            }
        }
        stop
    }

    fn failed(&mut self, e: &pulse::Error) {
        let config = self.loops.config;
        tracing::warn!(
            "lost the speaker {:?}: {e}; opening it again every {} s",
            config.sink,
            config.reopen_s
        );
        self.loops.counters.incr("speaker_lost");
        self.speaker = None;
        self.lost = true;
        self.retry_at = Instant::now() + Duration::from_secs_f64(config.reopen_s);
    }

    /// Drop what is queued and held: the sentence was interrupted.
    fn cut(&mut self) {
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        let playing = s.queued_until.take().is_some();
        let held = s.held.take().is_some();
        if playing || held {
            s.in_sentence = false;
            self.loops.counters.incr("playback_cut");
            self.loops.voice.stopped(self.loops.counters);
            if let Err(e) = s.stream.flush() {
                self.failed(&e);
            }
        }
    }

    /// Stop playing at once, keeping what was not played (and `unwritten`) for [`Self::resume`].
    fn pause(&mut self, unwritten: Vec<i16>) {
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        if let Some(held) = s.held.as_mut() {
            held.extend(unwritten);
            return;
        }
        if s.queued_until.is_none() && unwritten.is_empty() {
            return;
        }
        // What the server holds and has not played yet, taken back.
        let queued_us = s.stream.latency_us().unwrap_or(0);
        self.loops.voice.stopped(self.loops.counters);
        if let Err(e) = s.stream.flush() {
            self.failed(&e);
            return;
        }
        let channels = usize::from(s.stream.channels());
        let frames = (queued_us as f64 * 1e-6 * f64::from(s.stream.rate_hz())) as usize;
        let n = (frames * channels).min(s.recent.len());
        let mut held: Vec<i16> = s.recent.iter().skip(s.recent.len() - n).copied().collect();
        held.extend(unwritten);
        s.recent.clear();
        s.queued_until = None;
        s.held = Some(held);
        self.loops.counters.incr("playback_paused");
    }

    /// Go on with what a pause held.
    fn resume(&mut self) {
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        let Some(held) = s.held.take() else {
            return;
        };
        // The server's buffer is empty: it starts again like a sentence (not an under-run).
        s.in_sentence = false;
        if !held.is_empty() {
            self.write(held);
        }
    }

    /// A chunk of the robot's voice: played, or held while paused.
    fn chunk(&mut self, chunk: &AudioChunk) {
        let counters = self.loops.counters;
        let (Some(samples), Ok(channels)) = (chunk.samples(), u8::try_from(chunk.channels)) else {
            counters.incr("playback_malformed");
            return;
        };
        if channels == 0
            || chunk.sample_rate_hz == 0
            || !samples.len().is_multiple_of(channels as usize)
        {
            counters.incr("playback_malformed");
            return;
        }
        // (Re)open the speaker for this chunk's format.
        let fits = self.speaker.as_ref().is_some_and(|s| {
            s.stream.rate_hz() == chunk.sample_rate_hz && s.stream.channels() == channels
        });
        if !fits && !self.open(chunk.sample_rate_hz, channels) {
            counters.incr("playback_dropped_device_lost");
            return;
        }
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        if let Some(held) = s.held.as_mut() {
            held.extend(samples);
            return;
        }
        self.write(samples);
    }

    /// Open the speaker for a format (closing the one open, after it played what it holds).
    fn open(&mut self, rate_hz: u32, channels: u8) -> bool {
        let config = self.loops.config;
        if let Some(mut old) = self.speaker.take()
            && old.queued_until.is_some_and(|t| t > Instant::now())
        {
            let _ = old.stream.drain();
        }
        if Instant::now() < self.retry_at
            || self.loops.presence.sink_missing.load(Ordering::Relaxed)
        {
            return false;
        }
        let failed = self.lost.then_some(self.generation);
        let opened = self.loops.echo.devices(failed).and_then(|(_, sink, g)| {
            self.generation = g;
            pulse::Playback::open(
                config.server(),
                &sink,
                rate_hz,
                channels,
                self.buffer,
                "robot voice",
            )
        });
        match opened {
            Ok(stream) => {
                if self.lost {
                    tracing::info!("the speaker {:?} is back", config.sink);
                    self.lost = false;
                }
                self.speaker = Some(Speaker {
                    stream,
                    queued_until: None,
                    in_sentence: false,
                    recent: Default::default(),
                    held: None,
                });
                true
            }
            Err(e) => {
                if !self.lost {
                    tracing::warn!(
                        "cannot open the speaker {:?}: {e}; the robot's voice is dropped until \
                         it opens (tried every {} s)",
                        config.sink,
                        config.reopen_s
                    );
                    self.loops.counters.incr("speaker_lost");
                    self.lost = true;
                }
                self.retry_at = Instant::now() + Duration::from_secs_f64(config.reopen_s);
                false
            }
        }
    }

    /// Write samples of the open speaker's format, slice by slice, a sentence's start padded
    /// with silence; a control message between two slices may stop it.
    fn write(&mut self, samples: Vec<i16>) {
        let counters = self.loops.counters;
        let buffer = self.buffer;
        let Some(s) = self.speaker.as_mut() else {
            return;
        };
        let (rate, channels) = (s.stream.rate_hz(), usize::from(s.stream.channels()));
        let duration = |n: usize| Duration::from_secs_f64((n / channels) as f64 / f64::from(rate));
        let now = Instant::now();
        let (mut until, mut data) = match s.queued_until {
            Some(until) if until > now => (until, samples),
            _ => {
                if s.in_sentence {
                    counters.incr("playback_underruns");
                    tracing::debug!("the speaker ran dry in the middle of a sentence");
                }
                // A sentence starts: silence first, up to the server's start threshold.
                let pad = buffer.saturating_sub(duration(samples.len()));
                let frames = (pad.as_secs_f64() * f64::from(rate)) as usize;
                let mut padded = vec![0i16; frames * channels];
                padded.extend(samples);
                (now, padded)
            }
        };
        s.in_sentence = true;
        counters.incr("playback_chunks");
        let slice = ((SLICE.as_secs_f64() * f64::from(rate)) as usize).max(1) * channels;
        let keep = ((buffer + SLICE * 5).as_secs_f64() * f64::from(rate)) as usize * channels;
        while !data.is_empty() {
            let mut rest = data.split_off(slice.min(data.len()));
            let Some(s) = self.speaker.as_mut() else {
                return;
            };
            if let Err(e) = s.stream.write(&data) {
                self.failed(&e);
                return;
            }
            let now = Instant::now();
            let starts = until.max(now);
            until = starts + duration(data.len());
            s.queued_until = Some(until);
            // When the slice plays, as the server says (it knows of late writes and of the
            // device's own delay; a busy machine's count of what was written does not).
            let plays = s
                .stream
                .latency_us()
                .and_then(|l| (now + Duration::from_micros(l)).checked_sub(duration(data.len())))
                .unwrap_or(starts);
            self.loops
                .voice
                .played(plays, (rate, channels), &data, self.loops.counters);
            s.recent.extend(data.iter().copied());
            let excess = s.recent.len().saturating_sub(keep);
            s.recent.drain(..excess);
            if self.control(&mut rest) {
                return;
            }
            data = rest;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn config(args: &[&str]) -> Config {
        #[derive(clap::Parser)]
        struct Cli {
            #[command(flatten)]
            config: Config,
        }
        let mut all = vec!["audio_io"];
        all.extend_from_slice(args);
        <Cli as clap::Parser>::parse_from(all).config
    }

    #[test]
    fn flags_out_of_range_are_refused_before_any_device_is_opened() {
        for (args, needle) in [
            (&["--no-capture", "--no-playback"][..], "nothing to do"),
            (&["--rate-hz", "100"][..], "--rate-hz"),
            (&["--chunk-ms", "0"][..], "--chunk-ms"),
            (&["--playback-buffer-ms", "5"][..], "--playback-buffer-ms"),
            (&["--reopen-s", "0"][..], "--reopen-s"),
            (&["--resume-after-s=-1"][..], "--resume-after-s"),
            (&["--resume-after-s", "11"][..], "--resume-after-s"),
            (
                &["--echo-cancel", "webrtc", "--no-playback"][..],
                "--echo-cancel needs both",
            ),
        ] {
            let e = prepare(config(args)).unwrap_err().to_string();
            assert!(e.contains(needle), "{args:?}: {e}");
        }
    }

    #[test]
    fn no_sound_server_is_a_configuration_error_naming_the_address() {
        let e = prepare(config(&["--server", "unix:/nonexistent/robocog-audio"])).unwrap_err();
        assert!(
            e.downcast_ref::<interfaces::node::ConfigError>().is_some(),
            "{e:#}"
        );
        assert!(e.to_string().contains("/nonexistent/robocog-audio"), "{e}");
    }

    #[test]
    fn chunks_hold_the_rate_times_the_length() {
        assert_eq!(config(&[]).chunk_frames(), 320);
        assert_eq!(
            config(&["--rate-hz", "48000", "--chunk-ms", "10"]).chunk_frames(),
            480
        );
    }
}
