//! The PCM streams: a capture from a source and a playback to a sink, over libpulse's simple API.

use crate::server::devices;
use crate::{Error, Kind, describe, server_label};
use libpulse_binding as pa;
use libpulse_simple_binding::Simple;
use pa::channelmap::Map;
use pa::def::BufferAttr;
use pa::error::{Code, PAErr};
use pa::sample::{Format, Spec};
use pa::stream::Direction;
use std::time::Duration;

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

pub(crate) fn spec(rate_hz: u32, channels: u8) -> Result<Spec, Error> {
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
        spec: Spec,
        map: Option<&Map>,
        attr: &BufferAttr,
        stream_name: &str,
    ) -> Result<Self, Error> {
        let (rate_hz, channels) = (spec.rate, spec.channels);
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
            map,
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
        Self::open_with(
            server,
            source,
            rate_hz,
            channels,
            None,
            chunk_frames,
            stream_name,
        )
    }

    /// Open `source` as [`Capture::open`] does, with the channel map `channel_map` (the
    /// server's words, as [`crate::Device::channel_map`] has them): a stream with the source's
    /// own map gets each of its channels as they are, in their order. (With another map the
    /// server mixes channels by their positions, and those it cannot place, such as a
    /// microphone array's `aux0`..`aux7` into a default 4-channel map, come out silent.)
    pub fn open_mapped(
        server: Option<&str>,
        source: &str,
        rate_hz: u32,
        channel_map: &str,
        chunk_frames: usize,
        stream_name: &str,
    ) -> Result<Self, Error> {
        let map = Map::new_from_string(channel_map)
            .ok()
            .filter(|m| m.is_valid())
            .ok_or_else(|| Error::Invalid {
                what: "channel map".into(),
                reason: format!("{channel_map:?} is not a channel map of the server's"),
            })?;
        let channels = map.len();
        Self::open_with(
            server,
            source,
            rate_hz,
            channels,
            Some(&map),
            chunk_frames,
            stream_name,
        )
    }

    fn open_with(
        server: Option<&str>,
        source: &str,
        rate_hz: u32,
        channels: u8,
        map: Option<&Map>,
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
            spec(rate_hz, channels)?,
            map,
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
            spec(rate_hz, channels)?,
            None,
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
