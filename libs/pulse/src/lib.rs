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
//! - [`EchoCanceller`] loads the server's acoustic echo canceller between a microphone and a
//!   speaker ([`modules`], [`load_module`] and [`unload_module`] underneath).
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

/// A connection to the server for asking it things (its devices, its modules), every wait
/// bounded by [`LIST_TIMEOUT`] from the moment it was made.
struct Session {
    mainloop: Mainloop,
    context: Context,
    server: Option<String>,
    deadline: Instant,
}

impl Session {
    fn connect(server: Option<&str>) -> Result<Self, Error> {
        let no_server = |reason: String| Error::NoServer {
            server: server_label(server),
            reason,
        };
        let mainloop =
            Mainloop::new().ok_or_else(|| no_server("libpulse has no main loop".into()))?;
        let mut context = Context::new(&mainloop, "robocog")
            .ok_or_else(|| no_server("libpulse has no context".into()))?;
        context
            .connect(server, ContextFlags::NOAUTOSPAWN, None)
            .map_err(|e| no_server(describe(e)))?;
        let mut session = Session {
            mainloop,
            context,
            server: server.map(str::to_string),
            deadline: Instant::now() + LIST_TIMEOUT,
        };
        loop {
            match session.context.get_state() {
                ContextState::Ready => return Ok(session),
                ContextState::Failed | ContextState::Terminated => {
                    let reason = describe(session.context.errno());
                    return Err(session.no_server(reason));
                }
                _ => session.step()?,
            }
        }
    }

    fn no_server(&self, reason: String) -> Error {
        Error::NoServer {
            server: server_label(self.server.as_deref()),
            reason,
        }
    }

    /// Run the main loop once (or sleep briefly when it had nothing to do).
    fn step(&mut self) -> Result<(), Error> {
        if Instant::now() > self.deadline {
            return Err(self.no_server(format!("no answer within {} s", LIST_TIMEOUT.as_secs())));
        }
        match self.mainloop.iterate(false) {
            IterateResult::Success(0) => std::thread::sleep(Duration::from_millis(2)),
            IterateResult::Success(_) => {}
            IterateResult::Quit(_) => return Err(self.no_server("the main loop quit".into())),
            IterateResult::Err(e) => return Err(self.no_server(describe(e))),
        }
        Ok(())
    }

    /// Wait until none of `states` says running.
    fn wait(&mut self, states: impl Fn() -> bool) -> Result<(), Error> {
        while states() {
            self.step()?;
        }
        Ok(())
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        self.context.disconnect();
    }
}

/// The devices of the server at `server` (`None`: the usual address), waiting at most
/// [`LIST_TIMEOUT`] for it.
pub fn devices(server: Option<&str>) -> Result<Devices, Error> {
    let mut session = Session::connect(server)?;
    let found = Rc::new(RefCell::new(Devices::default()));
    let introspect = session.context.introspect();
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
    session.wait(|| {
        [
            op_server.get_state(),
            op_sources.get_state(),
            op_sinks.get_state(),
        ]
        .contains(&OperationState::Running)
    })?;
    let devices = found.borrow().clone();
    Ok(devices)
}

/// A module loaded in the server.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Module {
    pub index: u32,
    pub name: String,
    pub argument: String,
}

/// The modules loaded in the server at `server`.
pub fn modules(server: Option<&str>) -> Result<Vec<Module>, Error> {
    let mut session = Session::connect(server)?;
    let found = Rc::new(RefCell::new(Vec::new()));
    let f = Rc::clone(&found);
    let op = session.context.introspect().get_module_info_list(move |r| {
        if let ListResult::Item(m) = r {
            f.borrow_mut().push(Module {
                index: m.index,
                name: m.name.as_deref().unwrap_or("").to_string(),
                argument: m.argument.as_deref().unwrap_or("").to_string(),
            });
        }
    });
    session.wait(|| op.get_state() == OperationState::Running)?;
    let modules = found.borrow().clone();
    Ok(modules)
}

/// Load the module `name` with `argument` (`key=value` pairs separated by spaces) into the
/// server; its index. A module the server refuses (a bad argument, a master device it does not
/// have) is an [`Error::Invalid`] (the server's log says why).
pub fn load_module(server: Option<&str>, name: &str, argument: &str) -> Result<u32, Error> {
    if name.contains('\0') || argument.contains('\0') {
        return Err(Error::Invalid {
            what: format!("module {name:?}"),
            reason: "a NUL byte in its name or argument".into(),
        });
    }
    let mut session = Session::connect(server)?;
    let index = Rc::new(RefCell::new(None));
    let i = Rc::clone(&index);
    let op = session
        .context
        .introspect()
        .load_module(name, argument, move |n| *i.borrow_mut() = Some(n));
    session.wait(|| op.get_state() == OperationState::Running)?;
    let loaded = *index.borrow();
    match loaded {
        Some(n) if n != u32::MAX => Ok(n),
        _ => Err(Error::Invalid {
            what: format!("module {name} ({argument})"),
            reason: format!(
                "the sound server refused it: {}",
                describe(session.context.errno())
            ),
        }),
    }
}

/// Unload the module `index` from the server (one already gone is not an error).
pub fn unload_module(server: Option<&str>, index: u32) -> Result<(), Error> {
    let mut session = Session::connect(server)?;
    let op = session.context.introspect().unload_module(index, |_| {});
    session.wait(|| op.get_state() == OperationState::Running)
}

/// Acoustic echo cancellation in the server: PulseAudio's `module-echo-cancel` with the WebRTC
/// canceller (PipeWire's PulseAudio service has the same module) between one microphone and one
/// speaker. It makes a source ([`EchoCanceller::source`]: the microphone with what was played on
/// the speaker taken out) and a sink ([`EchoCanceller::sink`]: the speaker, whose stream is the
/// canceller's reference). Capture from the one and play to the other; anything else played into
/// the room (a person) stays in the microphone's signal.
///
/// The module is unloaded when this is dropped. One left behind by a process that was killed is
/// found by its source's name and replaced when the next one loads.
#[derive(Debug)]
pub struct EchoCanceller {
    server: Option<String>,
    index: u32,
    source: String,
    sink: String,
}

/// The module and its canceller.
pub const ECHO_CANCEL_MODULE: &str = "module-echo-cancel";

/// A device name as a module argument's value: one word, without quotes.
fn module_value(what: &str, name: &str) -> Result<String, Error> {
    if name.is_empty()
        || name
            .chars()
            .any(|c| c.is_whitespace() || "\"'\\\0".contains(c))
    {
        return Err(Error::Invalid {
            what: what.to_string(),
            reason: format!("{name:?} cannot be given to a module (empty, spaces or quotes)"),
        });
    }
    Ok(name.to_string())
}

/// A name derived from a device's, for the canceller's own devices.
fn derived_name(device: &str) -> String {
    device
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '.' || c == '-' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

impl EchoCanceller {
    /// Cancel what `sink_master` plays out of what `source_master` hears ([`DEFAULT_SOURCE`] and
    /// [`DEFAULT_SINK`] stand for the server's defaults).
    pub fn load(
        server: Option<&str>,
        source_master: &str,
        sink_master: &str,
    ) -> Result<Self, Error> {
        // No gain control: the canceller would change the microphone's volume (analog) or the
        // signal's level (digital) as people and the robot speak, under the recognizer's
        // end-pointer, which follows the room's level itself. No noise suppression either: it
        // took the room 19 dB under the microphone's, so the canceller's output and the
        // microphone as it is (what the player's words over the robot are) were two rooms, and
        // it clipped the soft first sounds of words ("s"); the recognizer's model is adapted to
        // noisy speech as the microphone hears it.
        let mut argument = String::from(
            "aec_method=webrtc aec_args=\"analog_gain_control=0 digital_gain_control=0 \
             noise_suppression=0\"",
        );
        let mut tag = String::new();
        if source_master != DEFAULT_SOURCE {
            let m = module_value("echo canceller's microphone", source_master)?;
            argument += &format!(" source_master={m}");
            tag += &derived_name(&m);
        }
        if sink_master != DEFAULT_SINK {
            let m = module_value("echo canceller's speaker", sink_master)?;
            argument += &format!(" sink_master={m}");
            tag += &format!("_{}", derived_name(&m));
        }
        if tag.is_empty() {
            tag = "default".into();
        }
        let source = format!("robocog_aec_mic.{tag}");
        let sink = format!("robocog_aec_speaker.{tag}");
        argument += &format!(" source_name={source} sink_name={sink}");
        // A canceller of the same devices left by a process that did not unload it.
        let ours = format!("source_name={source} ");
        for m in modules(server)? {
            if m.name == ECHO_CANCEL_MODULE && format!("{} ", m.argument).contains(&ours) {
                unload_module(server, m.index)?;
            }
        }
        let index = load_module(server, ECHO_CANCEL_MODULE, &argument)?;
        Ok(Self {
            server: server.map(str::to_string),
            index,
            source,
            sink,
        })
    }

    /// The echo-cancelled microphone.
    pub fn source(&self) -> &str {
        &self.source
    }

    /// The speaker as the canceller's reference.
    pub fn sink(&self) -> &str {
        &self.sink
    }

    /// The module's index in the server.
    pub fn index(&self) -> u32 {
        self.index
    }

    /// Whether the module is still loaded (the server unloads it when a master device goes).
    pub fn loaded(&self) -> Result<bool, Error> {
        Ok(modules(self.server.as_deref())?
            .iter()
            .any(|m| m.index == self.index && m.name == ECHO_CANCEL_MODULE))
    }
}

impl Drop for EchoCanceller {
    fn drop(&mut self) {
        let _ = unload_module(self.server.as_deref(), self.index);
    }
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
    fn an_echo_canceller_takes_one_word_device_names_and_names_its_own_after_them() {
        assert_eq!(
            module_value("m", "alsa_input.usb-1").unwrap(),
            "alsa_input.usb-1"
        );
        for bad in ["", "two words", "quo\"te", "back\\slash"] {
            assert!(
                matches!(module_value("m", bad), Err(Error::Invalid { .. })),
                "{bad:?}"
            );
        }
        assert_eq!(derived_name("room.monitor"), "room.monitor");
        assert_eq!(derived_name("a:b/c"), "a_b_c");
        // Refused before the server is asked.
        let e = EchoCanceller::load(Some("unix:/nonexistent/socket"), "two words", DEFAULT_SINK)
            .unwrap_err();
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
