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
use pa::error::PAErr;
use std::time::Duration;

mod echo;
mod server;
mod stream;

pub use echo::{ECHO_CANCEL_MODULE, EchoCanceller};
pub use server::{Module, devices, load_module, modules, unload_module};
pub use stream::{Capture, Playback};

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
    /// Its channels' positions in the server's own words (`front-left,front-right`,
    /// `aux0,aux1,aux2,aux3`): a stream opened with the same map gets every channel as it is.
    pub channel_map: String,
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

    /// The device `name` of `kind` (the default names stand for the server's default device).
    pub fn find(&self, kind: Kind, name: &str) -> Option<&Device> {
        let name = match (kind, name) {
            (Kind::Source, DEFAULT_SOURCE) => self.default_source.as_str(),
            (Kind::Sink, DEFAULT_SINK) => self.default_sink.as_str(),
            _ => name,
        };
        self.of(kind).iter().find(|d| d.name == name)
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

pub(crate) fn server_label(server: Option<&str>) -> String {
    match server {
        Some(s) => s.to_string(),
        None => match std::env::var("PULSE_SERVER") {
            Ok(s) if !s.is_empty() => format!("{s} (PULSE_SERVER)"),
            _ => "the default address".to_string(),
        },
    }
}

pub(crate) fn describe(e: PAErr) -> String {
    format!("{e}")
}

#[cfg(test)]
mod tests;
