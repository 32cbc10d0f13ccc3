//! The server's acoustic echo canceller (`module-echo-cancel`) between a microphone and a speaker.

use crate::server::{load_module, modules, unload_module};
use crate::{DEFAULT_SINK, DEFAULT_SOURCE, Error};

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
pub(crate) fn module_value(what: &str, name: &str) -> Result<String, Error> {
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
pub(crate) fn derived_name(device: &str) -> String {
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
        Self::load_with(server, source_master, sink_master, false)
    }

    /// [`EchoCanceller::load`], with `all_channels`: its source keeps every channel of the
    /// microphone (a microphone array's, in its order and with its channel map) instead of the
    /// server's default layout; each channel has the speaker's voice taken out.
    pub fn load_with(
        server: Option<&str>,
        source_master: &str,
        sink_master: &str,
        all_channels: bool,
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
        if all_channels {
            argument += " use_master_format=1";
        }
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
