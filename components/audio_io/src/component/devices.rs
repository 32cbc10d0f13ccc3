//! The sound devices: the echo canceller both threads share, opening the microphone, watching
//! that the named devices are still on the server, and trying a lost one again.

use super::{Config, EchoCancel};
use interfaces::clock::{Clock, Moment};
use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

/// The server's echo canceller when `--echo-cancel` asks for one, shared by the capture and the
/// playback threads: the devices they open are the canceller's, not the named ones.
///
/// When a named device goes away the server unloads the canceller with it (or moves its
/// streams), so a thread that lost its device loads a fresh one before reopening, unless the
/// other thread already did since it opened its stream (the generation tells).
#[derive(Debug)]
pub struct Echo {
    config: Config,
    /// The microphone array (`--array`): the canceller keeps all its channels.
    array: Option<ArrayLayout>,
    loaded: Mutex<(Option<pulse::EchoCanceller>, u64)>,
}

/// The microphone array of `--array`, as the capture needs it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArrayLayout {
    /// The geometry's name.
    pub name: String,
    /// Its microphones: the channels audio/in carries when the source has as many.
    pub channels: usize,
}

impl Echo {
    pub(super) fn new(config: &Config, array: Option<ArrayLayout>) -> Self {
        Self {
            config: config.clone(),
            array,
            loaded: Mutex::new((None, 0)),
        }
    }

    /// The microphone array, if the microphone is one.
    pub(super) fn array(&self) -> Option<&ArrayLayout> {
        self.array.as_ref()
    }

    /// The source and the sink to open, and the canceller's generation. After the failure of a
    /// stream opened on generation `failed`, a fresh canceller unless a newer one is loaded;
    /// otherwise the loaded one, if it still is.
    pub(super) fn devices(
        &self,
        failed: Option<u64>,
    ) -> Result<(String, String, u64), pulse::Error> {
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
                let ec = pulse::EchoCanceller::load_with(
                    c.server(),
                    &c.source,
                    &c.sink,
                    self.array.is_some(),
                )?;
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

/// Open the microphone (the canceller's source with `--echo-cancel`; see [`Echo::devices`] for
/// `failed`); the stream and the canceller's generation.
pub(super) fn open_capture(
    config: &Config,
    echo: &Echo,
    failed: Option<u64>,
) -> Result<(pulse::Capture, u64), pulse::Error> {
    let (source, _, generation) = echo.devices(failed)?;
    let capture = match echo.array() {
        None => pulse::Capture::open(
            config.server(),
            &source,
            config.rate_hz,
            1,
            config.chunk_frames(),
            "robot microphone",
        )?,
        // Every channel of the source with its own map: the server neither mixes nor
        // reorders them (an array's `aux` channels would come out silent in a default map).
        Some(_) => {
            let devices = pulse::devices(config.server())?;
            let map = devices
                .find(pulse::Kind::Source, &source)
                .map(|d| d.channel_map.clone())
                .ok_or_else(|| gone(pulse::Kind::Source, &source))?;
            pulse::Capture::open_mapped(
                config.server(),
                &source,
                config.rate_hz,
                &map,
                config.chunk_frames(),
                "robot microphone array",
            )?
        }
    };
    Ok((capture, generation))
}

/// What audio/in carries of what `capture` reads: every channel when they are the array's
/// microphones, else one channel (a mono microphone; or an array's source with another channel
/// count than the array's, mixed down, said and counted as `array_channel_mismatch`).
pub(super) fn published_channels(
    capture: &pulse::Capture,
    array: Option<&ArrayLayout>,
    counters: &interfaces::bus::Counters,
) -> u16 {
    let got = usize::from(capture.channels());
    match array {
        Some(a) if a.channels == got => u16::from(capture.channels()),
        Some(a) => {
            counters.incr("array_channel_mismatch");
            tracing::error!(
                "the microphone {:?} has {got} channels, the array {} has {} microphones:                  audio/in goes on in mono (its channels mixed), without the array's hearing;                  is it the array's source, and is its geometry the right one?",
                capture.device(),
                a.name,
                a.channels
            );
            1
        }
        None => 1,
    }
}

/// Whether the named devices are on the server, as the device watcher last saw. A source or a
/// sink that goes away does not fail the streams on it: the server moves them to another device
/// (the built-in microphone, say), which would put the wrong microphone or speaker in the game
/// without a word. So the watcher asks the server for its devices every `--reopen-s`, and the
/// threads close a stream whose named device is gone. The server's defaults are not watched:
/// following the default is what they mean.
#[derive(Debug, Default)]
pub(super) struct Presence {
    pub(super) source_missing: AtomicBool,
    pub(super) sink_missing: AtomicBool,
}

/// Keep `presence` current until `stop`, asking every `--reopen-s` on `clock`.
pub(super) fn watch_devices(
    config: &Config,
    clock: &Clock,
    stop: &AtomicBool,
    presence: &Presence,
) {
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
        wait_until(clock, clock.now() + every, stop);
    }
}

pub(super) fn gone(kind: pulse::Kind, name: &str) -> pulse::Error {
    pulse::Error::Stream {
        kind,
        device: name.to_string(),
        reason: "the device is no longer on the sound server".into(),
    }
}

/// Try `open` every `--reopen-s` on `clock` until it works (`None` once `stop` is set).
pub(super) fn reopen<T>(
    config: &Config,
    clock: &Clock,
    stop: &AtomicBool,
    mut open: impl FnMut() -> Result<T, pulse::Error>,
) -> Option<T> {
    let every = Duration::from_secs_f64(config.reopen_s);
    let mut last_error = String::new();
    loop {
        if !wait_until(clock, clock.now() + every, stop) {
            return None;
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

/// How often a device thread waiting on its clock looks at it and at its stop flag.
const POLL: Duration = Duration::from_millis(20);

/// Wait on a device thread until `clock` reads `until`; `false` as soon as `stop` is set.
#[expect(
    clippy::disallowed_methods,
    reason = "a blocking device thread cannot await the clock: it looks at it and at its stop flag every 20 ms of real time"
)]
fn wait_until(clock: &Clock, until: Moment, stop: &AtomicBool) -> bool {
    while clock.now() < until {
        if stop.load(Ordering::Relaxed) {
            return false;
        }
        std::thread::sleep(POLL);
    }
    true
}
