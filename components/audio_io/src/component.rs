//! The `audio_io` component: a capture thread (microphone to `audio/in`) and a playback thread
//! (`audio/out` to the speaker) around the bus loop. See the crate doc for what is counted and
//! what happens when a device goes away.

use interfaces::msg::speech::{AudioChunk, SpeakingState};
use interfaces::node::{Component, Interface, config_error};
use interfaces::{Bus, Shutdown, topics};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// Where the sound devices are.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Driver {
    /// A PulseAudio server (or PipeWire's PulseAudio service), through libpulse.
    Pulse,
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
}

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
    capture: Option<pulse::Capture>,
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
        Some(open_capture(&config).map_err(config_error)?)
    };
    Ok(Prepared { config, capture })
}

fn open_capture(config: &Config) -> Result<pulse::Capture, pulse::Error> {
    pulse::Capture::open(
        config.server(),
        &config.source,
        config.rate_hz,
        1,
        config.chunk_frames(),
        "robot microphone",
    )
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
    /// The microphone failed (why).
    Lost(String),
    /// The microphone is open again.
    Back,
}

/// What the bus loop tells the playback thread.
#[derive(Debug)]
enum Play {
    Chunk(AudioChunk),
    /// Drop what is queued: the utterance was interrupted.
    Cut,
    /// The generator sent the last chunk of its sentence (what comes next starts another).
    SentenceEnded,
}

/// Capture and play until `shutdown`.
pub async fn run(bus: Bus, prepared: Prepared, mut shutdown: Shutdown) -> anyhow::Result<()> {
    let Prepared { config, capture } = prepared;
    let stop = Arc::new(AtomicBool::new(false));
    let presence = Arc::new(Presence::default());
    let watcher = {
        let (config, stop, presence) = (config.clone(), stop.clone(), presence.clone());
        std::thread::Builder::new()
            .name("device-watch".into())
            .spawn(move || watch_devices(&config, &stop, &presence))?
    };
    let (heard_tx, mut heard_rx) = tokio::sync::mpsc::channel::<Heard>(64);
    let mut capture_thread = None;
    if let Some(capture) = capture {
        let (config, stop, counters) = (config.clone(), stop.clone(), bus.counters().clone());
        let presence = presence.clone();
        capture_thread = Some(
            std::thread::Builder::new()
                .name("microphone".into())
                .spawn(move || {
                    capture_loop(capture, &config, &stop, &presence, &counters, &heard_tx)
                })?,
        );
    } else {
        drop(heard_tx);
    }
    let mut audio_in = match capture_thread {
        Some(_) => Some(bus.publisher(&topics::AUDIO_IN).await?),
        None => None,
    };
    let mut play_tx = None;
    let mut play_thread = None;
    let mut out_sub = None;
    let mut speaking_sub = None;
    if !config.no_playback {
        // A second of 100 ms chunks: the generator paces them in real time, so a full queue
        // means the server stopped taking audio.
        let (tx, rx) = std::sync::mpsc::sync_channel::<Play>(10);
        let (config, counters, presence) =
            (config.clone(), bus.counters().clone(), presence.clone());
        play_thread = Some(
            std::thread::Builder::new()
                .name("speaker".into())
                .spawn(move || playback_loop(&config, &presence, &counters, &rx))?,
        );
        play_tx = Some(tx);
        out_sub = Some(bus.subscriber(&topics::AUDIO_OUT).await?);
        speaking_sub = Some(bus.subscriber(&topics::SPEECH_SPEAKING).await?);
    }
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
                None => break Err(anyhow::anyhow!("the capture thread ended")),
            },
            chunk = next(&out_sub) => {
                let chunk = match chunk {
                    Ok(c) => c,
                    Err(e) => break Err(e.into()),
                };
                if let Some(tx) = &play_tx && let Err(e) = tx.try_send(Play::Chunk(chunk)) {
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
                let tell = match event.state {
                    SpeakingState::Interrupted => Some(Play::Cut),
                    SpeakingState::Finished | SpeakingState::Failed => Some(Play::SentenceEnded),
                    _ => None,
                };
                if let (Some(tell), Some(tx)) = (tell, &play_tx)
                    && let Err(std::sync::mpsc::TrySendError::Disconnected(_)) = tx.try_send(tell)
                {
                    break Err(anyhow::anyhow!("the playback thread ended"));
                }
            }
            _ = shutdown.wait() => break Ok(()),
        }
    };
    stop.store(true, Ordering::Relaxed);
    drop(play_tx);
    // Both threads notice within one chunk or one reopen attempt; they are not waited for longer
    // than that (a stuck server must not hold the shutdown).
    for t in [capture_thread, play_thread, Some(watcher)]
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

/// Read the microphone until `stop`, reopening it when it fails.
fn capture_loop(
    mut capture: pulse::Capture,
    config: &Config,
    stop: &AtomicBool,
    presence: &Presence,
    counters: &interfaces::bus::Counters,
    tx: &tokio::sync::mpsc::Sender<Heard>,
) {
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
                match tx.try_send(Heard::Chunk(std::mem::take(&mut samples), latency)) {
                    Ok(()) => {}
                    Err(tokio::sync::mpsc::error::TrySendError::Full(_)) => {
                        counters.incr("capture_overruns");
                    }
                    Err(tokio::sync::mpsc::error::TrySendError::Closed(_)) => return,
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
                        open_capture(config)
                    }
                };
                let Some(again) = reopen(config, stop, open) else {
                    return;
                };
                capture = again;
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
    /// latency); `None` before the first chunk and after a cut.
    queued_until: Option<Instant>,
    /// Whether a sentence is under way (a chunk written, and the generator has not said it
    /// ended): a chunk of it that finds the queue empty came too late, an under-run.
    in_sentence: bool,
}

/// Play what the bus loop sends until it hangs up.
///
/// The server starts a stream only once it holds `--playback-buffer-ms` of it, and the speech
/// generator sends its chunks in real time: so the first chunk of a sentence is preceded by
/// enough silence to fill that buffer at once. The sentence starts at once (after the silence),
/// short sounds play without waiting for more, and the buffer keeps its cushion against late
/// chunks for the whole sentence.
fn playback_loop(
    config: &Config,
    presence: &Presence,
    counters: &interfaces::bus::Counters,
    rx: &std::sync::mpsc::Receiver<Play>,
) {
    let mut speaker: Option<Speaker> = None;
    // After a failure, the next attempt to open the speaker is not before this.
    let mut retry_at = Instant::now();
    let mut lost = false;
    let buffer = Duration::from_millis(u64::from(config.playback_buffer_ms));
    loop {
        let missing = presence.sink_missing.load(Ordering::Relaxed);
        if missing && speaker.is_some() {
            speaker_failed(
                config,
                counters,
                &mut speaker,
                &mut lost,
                &gone(pulse::Kind::Sink, &config.sink),
            );
        }
        let cmd = match rx.recv_timeout(Duration::from_millis(200)) {
            Ok(cmd) => cmd,
            Err(std::sync::mpsc::RecvTimeoutError::Timeout) => continue,
            Err(std::sync::mpsc::RecvTimeoutError::Disconnected) => return,
        };
        match cmd {
            Play::SentenceEnded => {
                if let Some(s) = speaker.as_mut() {
                    s.in_sentence = false;
                }
            }
            Play::Cut => {
                if let Some(s) = speaker.as_mut()
                    && s.queued_until.take().is_some()
                {
                    s.in_sentence = false;
                    counters.incr("playback_cut");
                    if let Err(e) = s.stream.flush() {
                        speaker_failed(config, counters, &mut speaker, &mut lost, &e);
                        retry_at = Instant::now() + Duration::from_secs_f64(config.reopen_s);
                    }
                }
            }
            Play::Chunk(chunk) => {
                let (Some(samples), Ok(channels)) = (chunk.samples(), u8::try_from(chunk.channels))
                else {
                    counters.incr("playback_malformed");
                    continue;
                };
                if channels == 0
                    || chunk.sample_rate_hz == 0
                    || !samples.len().is_multiple_of(channels as usize)
                {
                    counters.incr("playback_malformed");
                    continue;
                }
                // (Re)open the speaker for this chunk's format.
                let fits = speaker.as_ref().is_some_and(|s| {
                    s.stream.rate_hz() == chunk.sample_rate_hz && s.stream.channels() == channels
                });
                if !fits {
                    if let Some(mut old) = speaker.take()
                        && old.queued_until.is_some_and(|t| t > Instant::now())
                    {
                        let _ = old.stream.drain();
                    }
                    if Instant::now() < retry_at || missing {
                        counters.incr("playback_dropped_device_lost");
                        continue;
                    }
                    match pulse::Playback::open(
                        config.server(),
                        &config.sink,
                        chunk.sample_rate_hz,
                        channels,
                        buffer,
                        "robot voice",
                    ) {
                        Ok(stream) => {
                            if lost {
                                tracing::info!("the speaker {:?} is back", config.sink);
                                lost = false;
                            }
                            speaker = Some(Speaker {
                                stream,
                                queued_until: None,
                                in_sentence: false,
                            });
                        }
                        Err(e) => {
                            if !lost {
                                tracing::warn!(
                                    "cannot open the speaker {:?}: {e}; the robot's voice is \
                                     dropped until it opens (tried every {} s)",
                                    config.sink,
                                    config.reopen_s
                                );
                                counters.incr("speaker_lost");
                                lost = true;
                            }
                            counters.incr("playback_dropped_device_lost");
                            retry_at = Instant::now() + Duration::from_secs_f64(config.reopen_s);
                            continue;
                        }
                    }
                }
                let Some(s) = speaker.as_mut() else { continue };
                let now = Instant::now();
                let duration = Duration::from_secs_f64(chunk.duration_s());
                let written = match s.queued_until {
                    Some(until) if until > now => s.stream.write(&samples).map(|()| until),
                    _ => {
                        if s.in_sentence {
                            counters.incr("playback_underruns");
                            tracing::debug!("the speaker ran dry in the middle of a sentence");
                        }
                        // A sentence starts: silence first, up to the server's start threshold.
                        let pad = buffer.saturating_sub(duration);
                        let frames = (pad.as_secs_f64() * f64::from(chunk.sample_rate_hz)) as usize;
                        let mut padded = vec![0i16; frames * channels as usize];
                        padded.extend_from_slice(&samples);
                        s.stream.write(&padded).map(|()| now + pad)
                    }
                };
                match written {
                    Ok(from) => {
                        counters.incr("playback_chunks");
                        s.queued_until = Some(from + duration);
                        s.in_sentence = true;
                    }
                    Err(e) => {
                        speaker_failed(config, counters, &mut speaker, &mut lost, &e);
                        retry_at = Instant::now() + Duration::from_secs_f64(config.reopen_s);
                    }
                }
            }
        }
    }
}

fn speaker_failed(
    config: &Config,
    counters: &interfaces::bus::Counters,
    speaker: &mut Option<Speaker>,
    lost: &mut bool,
    e: &pulse::Error,
) {
    tracing::warn!(
        "lost the speaker {:?}: {e}; opening it again every {} s",
        config.sink,
        config.reopen_s
    );
    counters.incr("speaker_lost");
    *speaker = None;
    *lost = true;
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
