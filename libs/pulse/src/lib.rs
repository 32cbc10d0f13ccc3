//! # pulse: the sound server at the hardware boundary
//!
//! The robot's microphone and speaker, reached through a PulseAudio sound server with libpulse
//! (PipeWire's PulseAudio service speaks the same protocol, so PipeWire systems work unchanged).
//! The server owns the sound cards and does the conversions: a stream asks for the rate and the
//! channel count it wants (16 kHz mono for speech) and the server resamples and down-mixes
//! whatever the device runs at.
//!
//! - [`devices`] lists the server's sources (microphones, monitors of sinks) and sinks
//!   (speakers), with the server's defaults.
//! - [`Capture`] reads s16le PCM from a source by name, in chunks of a fixed size.
//! - [`Playback`] writes s16le PCM to a sink by name, with a bounded server-side buffer so that
//!   cutting the speech short ([`Playback::flush`]) takes effect within that buffer's length.
//!
//! Device names are the server's (`pactl list short sources`); [`DEFAULT_SOURCE`] and
//! [`DEFAULT_SINK`] stand for whatever the server's defaults are. A name the server does not
//! have is an [`Error::NoSuchDevice`] that lists the devices there are. The server address is
//! libpulse's (`unix:/path/to/socket`, `tcp:host:port`; `None` for the usual one, which honours
//! `PULSE_SERVER`).
//!
//! Every call blocks: the callers run them on threads of their own.

use libpulse_binding as pa;
use libpulse_simple_binding::Simple;
use pa::callbacks::ListResult;
use pa::context::{Context, FlagSet as ContextFlags, State as ContextState};
use pa::def::BufferAttr;
use pa::error::{Code, PAErr};
use pa::mainloop::standard::{IterateResult, Mainloop};
use pa::operation::State as OperationState;
use pa::sample::{Format, Spec};
use pa::stream::Direction;
use std::cell::RefCell;
use std::rc::Rc;
use std::time::{Duration, Instant};

/// The server's default source, whatever it is at the moment a stream opens.
pub const DEFAULT_SOURCE: &str = "@DEFAULT_SOURCE@";
/// The server's default sink.
pub const DEFAULT_SINK: &str = "@DEFAULT_SINK@";

/// How long [`devices`] waits for the server.
pub const LIST_TIMEOUT: Duration = Duration::from_secs(5);

/// A source or a sink.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    /// A device that records (a microphone, or the monitor of a sink).
    Source,
    /// A device that plays (a speaker).
    Sink,
}

impl std::fmt::Display for Kind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Kind::Source => "source (microphone)",
            Kind::Sink => "sink (speaker)",
        })
    }
}

/// One device of the server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Device {
    pub name: String,
    pub description: String,
    /// The rate and channel count the device runs at (streams are converted to and from it).
    pub rate_hz: u32,
    pub channels: u8,
    /// Whether this source is the monitor of a sink (what the sink plays).
    pub monitor: bool,
}

/// What a server has.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Devices {
    /// The server's name and version, e.g. `pulseaudio 16.1`.
    pub server: String,
    pub default_source: String,
    pub default_sink: String,
    pub sources: Vec<Device>,
    pub sinks: Vec<Device>,
}

impl Devices {
    /// The devices of `kind`.
    pub fn of(&self, kind: Kind) -> &[Device] {
        match kind {
            Kind::Source => &self.sources,
            Kind::Sink => &self.sinks,
        }
    }

    /// Whether `name` opens a device of `kind` here (the default names always do when the server
    /// has a default).
    pub fn has(&self, kind: Kind, name: &str) -> bool {
        match (kind, name) {
            (Kind::Source, DEFAULT_SOURCE) => !self.default_source.is_empty(),
            (Kind::Sink, DEFAULT_SINK) => !self.default_sink.is_empty(),
            _ => self.of(kind).iter().any(|d| d.name == name),
        }
    }

    /// The devices of `kind` as a readable list, one per line, the default marked.
    pub fn listing(&self, kind: Kind) -> String {
        let default = match kind {
            Kind::Source => &self.default_source,
            Kind::Sink => &self.default_sink,
        };
        let lines: Vec<String> = self
            .of(kind)
            .iter()
            .map(|d| {
                format!(
                    "  {}{} ({}, {} Hz, {} ch{})",
                    d.name,
                    if &d.name == default { " [default]" } else { "" },
                    d.description,
                    d.rate_hz,
                    d.channels,
                    if d.monitor { ", monitor of a sink" } else { "" },
                )
            })
            .collect();
        if lines.is_empty() {
            "  (none)".to_string()
        } else {
            lines.join("\n")
        }
    }
}

/// Why the sound server could not be used.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// No server answers at that address (not running, wrong socket, no permission).
    #[error("no sound server at {server}: {reason}")]
    NoServer { server: String, reason: String },
    /// The server has no device of that name.
    #[error("the sound server has no {kind} named {name:?}; it has:\n{listing}")]
    NoSuchDevice {
        kind: Kind,
        name: String,
        listing: String,
    },
    /// A parameter the server refuses (a rate or a channel count out of range).
    #[error("invalid {what}: {reason}")]
    Invalid { what: String, reason: String },
    /// A stream that was open failed: the device went away, the server stopped.
    #[error("the {kind} stream on {device:?} failed: {reason}")]
    Stream {
        kind: Kind,
        device: String,
        reason: String,
    },
}

impl Error {
    /// Whether waiting cannot fix it (a device name or a parameter that is wrong), as opposed to
    /// a server or a device that may come (back).
    pub fn is_configuration(&self) -> bool {
        matches!(self, Error::NoSuchDevice { .. } | Error::Invalid { .. })
    }
}

fn server_label(server: Option<&str>) -> String {
    match server {
        Some(s) => s.to_string(),
        None => match std::env::var("PULSE_SERVER") {
            Ok(s) if !s.is_empty() => format!("{s} (PULSE_SERVER)"),
            _ => "the default address".to_string(),
        },
    }
}

fn describe(e: PAErr) -> String {
    format!("{e}")
}

/// The devices of the server at `server` (`None`: the usual address), waiting at most
/// [`LIST_TIMEOUT`] for it.
pub fn devices(server: Option<&str>) -> Result<Devices, Error> {
    let no_server = |reason: String| Error::NoServer {
        server: server_label(server),
        reason,
    };
    let mut mainloop =
        Mainloop::new().ok_or_else(|| no_server("libpulse has no main loop".into()))?;
    let mut context = Context::new(&mainloop, "robocog")
        .ok_or_else(|| no_server("libpulse has no context".into()))?;
    context
        .connect(server, ContextFlags::NOAUTOSPAWN, None)
        .map_err(|e| no_server(describe(e)))?;
    let deadline = Instant::now() + LIST_TIMEOUT;
    let step = |mainloop: &mut Mainloop| -> Result<(), Error> {
        if Instant::now() > deadline {
            return Err(no_server(format!(
                "no answer within {} s",
                LIST_TIMEOUT.as_secs()
            )));
        }
        match mainloop.iterate(false) {
            IterateResult::Success(0) => std::thread::sleep(Duration::from_millis(2)),
            IterateResult::Success(_) => {}
            IterateResult::Quit(_) => return Err(no_server("the main loop quit".into())),
            IterateResult::Err(e) => return Err(no_server(describe(e))),
        }
        Ok(())
    };
    loop {
        match context.get_state() {
            ContextState::Ready => break,
            ContextState::Failed | ContextState::Terminated => {
                let reason = describe(context.errno());
                return Err(no_server(reason));
            }
            _ => step(&mut mainloop)?,
        }
    }
    let found = Rc::new(RefCell::new(Devices::default()));
    let introspect = context.introspect();
    let f = Rc::clone(&found);
    let op_server = introspect.get_server_info(move |info| {
        let mut d = f.borrow_mut();
        d.server = format!(
            "{} {}",
            info.server_name.as_deref().unwrap_or("?"),
            info.server_version.as_deref().unwrap_or("?")
        );
        d.default_source = info
            .default_source_name
            .as_deref()
            .unwrap_or("")
            .to_string();
        d.default_sink = info.default_sink_name.as_deref().unwrap_or("").to_string();
    });
    let f = Rc::clone(&found);
    let op_sources = introspect.get_source_info_list(move |r| {
        if let ListResult::Item(s) = r {
            f.borrow_mut().sources.push(Device {
                name: s.name.as_deref().unwrap_or("").to_string(),
                description: s.description.as_deref().unwrap_or("").to_string(),
                rate_hz: s.sample_spec.rate,
                channels: s.sample_spec.channels,
                monitor: s.monitor_of_sink.is_some(),
            });
        }
    });
    let f = Rc::clone(&found);
    let op_sinks = introspect.get_sink_info_list(move |r| {
        if let ListResult::Item(s) = r {
            f.borrow_mut().sinks.push(Device {
                name: s.name.as_deref().unwrap_or("").to_string(),
                description: s.description.as_deref().unwrap_or("").to_string(),
                rate_hz: s.sample_spec.rate,
                channels: s.sample_spec.channels,
                monitor: false,
            });
        }
    });
    while [
        op_server.get_state(),
        op_sources.get_state(),
        op_sinks.get_state(),
    ]
    .contains(&OperationState::Running)
    {
        step(&mut mainloop)?;
    }
    context.disconnect();
    let devices = found.borrow().clone();
    Ok(devices)
}

/// The error of opening a stream on `device`: a missing device names the ones there are.
fn open_error(server: Option<&str>, kind: Kind, device: &str, e: PAErr) -> Error {
    // The simple API reports its codes positive, the rest of libpulse negative.
    match Code::try_from(PAErr(-e.0.abs())) {
        Ok(Code::NoEntity) => match devices(server) {
            Ok(d) => Error::NoSuchDevice {
                kind,
                name: device.to_string(),
                listing: d.listing(kind),
            },
            Err(e) => e,
        },
        Ok(Code::ConnectionRefused | Code::InvalidServer | Code::Access | Code::Timeout) => {
            Error::NoServer {
                server: server_label(server),
                reason: describe(e),
            }
        }
        Ok(Code::Invalid | Code::NotSupported) => Error::Invalid {
            what: format!("stream on the {kind} {device:?}"),
            reason: describe(e),
        },
        _ => Error::Stream {
            kind,
            device: device.to_string(),
            reason: describe(e),
        },
    }
}

fn spec(rate_hz: u32, channels: u8) -> Result<Spec, Error> {
    let spec = Spec {
        format: Format::S16le,
        rate: rate_hz,
        channels,
    };
    if spec.is_valid() {
        Ok(spec)
    } else {
        Err(Error::Invalid {
            what: "sample format".into(),
            reason: format!(
                "{rate_hz} Hz with {channels} channels (rates 1 Hz to 384 kHz, 1 to 32 channels)"
            ),
        })
    }
}

fn to_bytes(samples: &[i16], out: &mut Vec<u8>) {
    out.clear();
    out.extend(samples.iter().flat_map(|s| s.to_le_bytes()));
}

/// One open stream of either direction, and what it was opened on.
struct Stream {
    simple: Simple,
    kind: Kind,
    device: String,
    rate_hz: u32,
    channels: u8,
}

impl std::fmt::Debug for Stream {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Stream")
            .field("kind", &self.kind)
            .field("device", &self.device)
            .field("rate_hz", &self.rate_hz)
            .field("channels", &self.channels)
            .finish()
    }
}

impl Stream {
    fn open(
        server: Option<&str>,
        kind: Kind,
        device: &str,
        rate_hz: u32,
        channels: u8,
        attr: &BufferAttr,
        stream_name: &str,
    ) -> Result<Self, Error> {
        let spec = spec(rate_hz, channels)?;
        let direction = match kind {
            Kind::Source => Direction::Record,
            Kind::Sink => Direction::Playback,
        };
        let simple = Simple::new(
            server,
            "robocog",
            direction,
            Some(device),
            stream_name,
            &spec,
            None,
            Some(attr),
        )
        .map_err(|e| open_error(server, kind, device, e))?;
        Ok(Self {
            simple,
            kind,
            device: device.to_string(),
            rate_hz,
            channels,
        })
    }

    fn failed(&self, e: PAErr) -> Error {
        Error::Stream {
            kind: self.kind,
            device: self.device.clone(),
            reason: describe(e),
        }
    }

    fn latency_us(&self) -> Option<u64> {
        self.simple.get_latency().ok().map(|l| l.0)
    }
}

/// A capture stream: s16le PCM from one source, read in chunks of a fixed number of frames.
#[derive(Debug)]
pub struct Capture {
    stream: Stream,
    chunk_frames: usize,
    bytes: Vec<u8>,
}

impl Capture {
    /// Open `source` on the server at `server`, converted to `rate_hz` and `channels`, delivered
    /// in chunks of `chunk_frames` frames (the server sends each chunk as soon as it is full).
    pub fn open(
        server: Option<&str>,
        source: &str,
        rate_hz: u32,
        channels: u8,
        chunk_frames: usize,
        stream_name: &str,
    ) -> Result<Self, Error> {
        if chunk_frames == 0 {
            return Err(Error::Invalid {
                what: "chunk".into(),
                reason: "a chunk needs at least one frame".into(),
            });
        }
        let chunk_bytes = chunk_frames * 2 * channels as usize;
        let attr = BufferAttr {
            maxlength: u32::MAX,
            tlength: u32::MAX,
            prebuf: u32::MAX,
            minreq: u32::MAX,
            fragsize: u32::try_from(chunk_bytes).unwrap_or(u32::MAX),
        };
        let stream = Stream::open(
            server,
            Kind::Source,
            source,
            rate_hz,
            channels,
            &attr,
            stream_name,
        )?;
        Ok(Self {
            stream,
            chunk_frames,
            bytes: vec![0; chunk_bytes],
        })
    }

    /// The next chunk, interleaved, blocking until it is complete.
    pub fn read(&mut self, out: &mut Vec<i16>) -> Result<(), Error> {
        if let Err(e) = self.stream.simple.read(&mut self.bytes) {
            return Err(self.stream.failed(e));
        }
        out.clear();
        out.extend(
            self.bytes
                .chunks_exact(2)
                .map(|b| i16::from_le_bytes([b[0], b[1]])),
        );
        Ok(())
    }

    /// How long the audio waits between the device and this reader (µs), when the server says.
    pub fn latency_us(&self) -> Option<u64> {
        self.stream.latency_us()
    }

    pub fn rate_hz(&self) -> u32 {
        self.stream.rate_hz
    }
    pub fn channels(&self) -> u8 {
        self.stream.channels
    }
    pub fn chunk_frames(&self) -> usize {
        self.chunk_frames
    }
    pub fn device(&self) -> &str {
        &self.stream.device
    }
}

/// A playback stream: s16le PCM to one sink.
#[derive(Debug)]
pub struct Playback {
    stream: Stream,
    bytes: Vec<u8>,
}

impl Playback {
    /// Open `sink` on the server at `server` for PCM at `rate_hz` with `channels`, the server
    /// keeping about `buffer` of it queued (the longest that [`Playback::flush`] cuts). The
    /// server starts playing once it holds that much.
    pub fn open(
        server: Option<&str>,
        sink: &str,
        rate_hz: u32,
        channels: u8,
        buffer: Duration,
        stream_name: &str,
    ) -> Result<Self, Error> {
        let frames = (buffer.as_secs_f64() * rate_hz as f64).ceil().max(1.0) as usize;
        let target = u32::try_from(frames * 2 * channels as usize).unwrap_or(u32::MAX);
        let attr = BufferAttr {
            maxlength: u32::MAX,
            tlength: target,
            prebuf: u32::MAX,
            minreq: u32::MAX,
            fragsize: u32::MAX,
        };
        let stream = Stream::open(
            server,
            Kind::Sink,
            sink,
            rate_hz,
            channels,
            &attr,
            stream_name,
        )?;
        Ok(Self {
            stream,
            bytes: Vec::new(),
        })
    }

    /// Queue interleaved samples, blocking while the server's buffer is full.
    pub fn write(&mut self, samples: &[i16]) -> Result<(), Error> {
        to_bytes(samples, &mut self.bytes);
        self.stream
            .simple
            .write(&self.bytes)
            .map_err(|e| self.stream.failed(e))
    }

    /// Drop what is queued and not yet played.
    pub fn flush(&mut self) -> Result<(), Error> {
        self.stream
            .simple
            .flush()
            .map_err(|e| self.stream.failed(e))
    }

    /// Block until what is queued has played.
    pub fn drain(&mut self) -> Result<(), Error> {
        self.stream
            .simple
            .drain()
            .map_err(|e| self.stream.failed(e))
    }

    /// How long a sample written now waits before it is heard (µs), when the server says.
    pub fn latency_us(&self) -> Option<u64> {
        self.stream.latency_us()
    }

    pub fn rate_hz(&self) -> u32 {
        self.stream.rate_hz
    }
    pub fn channels(&self) -> u8 {
        self.stream.channels
    }
    pub fn device(&self) -> &str {
        &self.stream.device
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Devices {
        Devices {
            server: "pulseaudio 16.1".into(),
            default_source: "mic".into(),
            default_sink: "room".into(),
            sources: vec![
                Device {
                    name: "room.monitor".into(),
                    description: "Monitor of Room".into(),
                    rate_hz: 48_000,
                    channels: 2,
                    monitor: true,
                },
                Device {
                    name: "mic".into(),
                    description: "Microphone".into(),
                    rate_hz: 48_000,
                    channels: 2,
                    monitor: false,
                },
            ],
            sinks: vec![],
        }
    }

    #[test]
    fn names_and_defaults_are_found_and_listed() {
        let d = sample();
        assert!(d.has(Kind::Source, "mic"));
        assert!(d.has(Kind::Source, DEFAULT_SOURCE));
        assert!(!d.has(Kind::Source, "usb-mic"));
        let l = d.listing(Kind::Source);
        assert!(
            l.contains("mic [default] (Microphone, 48000 Hz, 2 ch)"),
            "{l}"
        );
        assert!(
            l.contains("room.monitor (Monitor of Room, 48000 Hz, 2 ch, monitor of a sink)"),
            "{l}"
        );
        assert_eq!(d.listing(Kind::Sink), "  (none)");
    }

    #[test]
    fn bad_formats_are_refused_before_the_server_is_asked() {
        assert!(matches!(spec(0, 1), Err(Error::Invalid { .. })));
        assert!(matches!(spec(16_000, 0), Err(Error::Invalid { .. })));
        assert!(spec(16_000, 1).is_ok());
        let e =
            Capture::open(Some("unix:/nonexistent/socket"), "mic", 16_000, 1, 0, "t").unwrap_err();
        assert!(e.is_configuration(), "{e}");
    }

    #[test]
    fn no_server_is_an_error_that_names_the_address() {
        let e = devices(Some("unix:/nonexistent/robocog-test-socket")).unwrap_err();
        assert!(matches!(e, Error::NoServer { .. }), "{e}");
        assert!(
            e.to_string().contains("/nonexistent/robocog-test-socket"),
            "{e}"
        );
        assert!(!e.is_configuration());
    }
}
