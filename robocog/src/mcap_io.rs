//! Recordings of the bus as MCAP files: what `robocog record` writes and `robocog replay` reads.
//!
//! # Layout of a recording
//!
//! - One **channel** per (topic, type): the channel's topic is the robocog topic name
//!   (`vision/ball`, not the zenoh key), its `message_encoding` is `cdr`, and its metadata holds
//!   the type name under [`TYPE_KEY`] and the namespace it was recorded from under
//!   [`NAMESPACE_KEY`].
//! - One **schema** per message type, as ROS 2's tools expect it (rosbag2's convention): named
//!   `robocog_msgs/msg/<Type>`, encoding [`ROS2_SCHEMA_ENCODING`] (`ros2msg`), its data the
//!   type's full ROS 2 definition with the messages it uses ([`ros_msgs`], written from the
//!   Rust types). Foxglove, `mcap-ros2-support` and `rosbags` decode these channels. A type no
//!   ROS 2 message can describe (an enum carrying data) keeps robocog's own schema instead:
//!   named by the type name, encoding [`SCHEMA_ENCODING`], a JSON document giving the type's
//!   field names, order and default values (see [`schema_data`]); it describes the shape for a
//!   reader, not a machine-readable CDR definition. Files written before the ROS 2 schemas
//!   have only these, and replay the same: what replay reads is the channel's metadata.
//! - One **message** per sample, its data exactly the bytes that were on the bus: CDR
//!   little-endian with the 4-byte encapsulation header `00 01 00 00`, as ROS 2 records. So a
//!   replay publishes identical bytes, and components decode them unchanged.
//!   - `log_time`: when the recorder received the sample, ns since the Unix epoch (system clock);
//!   - `publish_time`: the message header's `stamp_ns` (the publisher's clock), or the
//!     `log_time` when the header does not decode;
//!   - `sequence`: the publisher's sequence number from the sample's attachment, modulo 2^32
//!     (MCAP sequences are 32-bit); 0 for a sample without one.
//! - A **metadata** record named [`METADATA_NAME`] written when the recording finishes: the
//!   namespace, the recorder's counts, and the samples it dropped per topic (never silently).
//!
//! Chunks are written uncompressed, one at least every flush interval, so a recorder killed
//! without warning loses at most the last interval: [`RecordingReader`] reads a file from the
//! start, record by record, and needs neither the summary nor the end of the file. Damage (a
//! truncated file, a corrupt byte caught by a chunk CRC or a malformed record) ends the reading
//! with a [`Damage`] naming the problem and its byte offset; the messages before it were
//! delivered.

use interfaces::Header;
use std::collections::{BTreeMap, HashMap, VecDeque};
use std::fs::File;
use std::io::{BufReader, BufWriter, Read};
use std::path::Path;

/// The `message_encoding` of every channel: CDR with its encapsulation header.
pub const MESSAGE_ENCODING: &str = "cdr";
/// The encoding of the schemas of the types ROS 2 can describe: a ROS 2 `.msg` definition with
/// its dependencies.
pub const ROS2_SCHEMA_ENCODING: &str = "ros2msg";
/// The encoding of the schemas of the other types: a JSON document describing the shape of a
/// robocog message type (`{"type", "codec", "example"}`, see [`schema_data`]).
pub const SCHEMA_ENCODING: &str = "robocog.msg-shape+json";
/// Channel metadata key holding the message type name.
pub const TYPE_KEY: &str = "robocog.type";
/// Channel metadata key holding the namespace the topic was recorded from.
pub const NAMESPACE_KEY: &str = "robocog.namespace";
/// Name of the metadata record the recorder writes when it finishes.
pub const METADATA_NAME: &str = "robocog.record";
/// The `profile` of the file header.
pub const PROFILE: &str = "robocog";

/// The schema of a message type: its name, encoding and data (see the module's documentation).
pub fn schema_for(type_name: &str) -> (String, &'static str, Vec<u8>) {
    let defs = ros_msgs::definitions();
    match (defs.ros_name(type_name), defs.full_definition(type_name)) {
        (Ok(name), Ok(text)) => (name, ROS2_SCHEMA_ENCODING, text.into_bytes()),
        _ => (
            type_name.to_string(),
            SCHEMA_ENCODING,
            schema_data(type_name),
        ),
    }
}

/// The robocog schema data of a message type: JSON with the type name, how its payload is encoded and
/// the JSON of its default value from the registry (field names, order, nesting, default values).
/// For a type this build does not know, `example` is `null`.
pub fn schema_data(type_name: &str) -> Vec<u8> {
    let example = interfaces::msg::lookup(type_name)
        .map(|e| (e.example)())
        .unwrap_or(serde_json::Value::Null);
    let doc = serde_json::json!({
        "type": type_name,
        "codec": "CDR little-endian (encapsulation 00 01 00 00), fields in the order of `example`; \
                  byte buffers as sequences of octets; enums as a u32 variant index then its fields",
        "example": example,
    });
    serde_json::to_vec_pretty(&doc).unwrap_or_default()
}

/// The header every message starts with, decoded from a payload's first bytes.
pub fn header_of(payload: &[u8]) -> Option<Header> {
    interfaces::codec::decode::<Header>(payload, "robocog.Header").ok()
}

/// Why a recording could not be written.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    #[error("cannot create {path}: {source}")]
    Create {
        path: String,
        #[source]
        source: std::io::Error,
    },
    #[error("writing the MCAP file: {0}")]
    Mcap(#[from] mcap::McapError),
}

/// Writes a recording: channels and schemas are added as topics and types first appear.
pub struct RecordWriter {
    writer: mcap::Writer<BufWriter<File>>,
    namespace: String,
    schemas: HashMap<String, u16>,
    /// Channel ids by topic, then type (a topic nearly always carries one type).
    channels: HashMap<String, Vec<(String, u16)>>,
    /// Messages whose header did not decode (their publish_time is their log_time).
    pub headerless: u64,
}

impl std::fmt::Debug for RecordWriter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordWriter")
            .field("channels", &self.channels.len())
            .finish()
    }
}

/// Target size of a chunk before it is closed (it is also closed at every flush).
const CHUNK_BYTES: u64 = 4 * 1024 * 1024;

impl RecordWriter {
    /// Create (or truncate) `path` and write the file header.
    pub fn create(path: &Path, namespace: &str) -> Result<Self, WriteError> {
        let file = File::create(path).map_err(|source| WriteError::Create {
            path: path.display().to_string(),
            source,
        })?;
        // Chunks are assembled in memory and written whole (`disable_seeking`): a killed recorder
        // leaves whole chunks behind, never a chunk whose header was still a placeholder.
        let writer = mcap::WriteOptions::new()
            .compression(None)
            .profile(PROFILE)
            .library(concat!("robocog/", env!("CARGO_PKG_VERSION")))
            .chunk_size(Some(CHUNK_BYTES))
            .disable_seeking(true)
            .create(BufWriter::with_capacity(1 << 20, file))?;
        Ok(Self {
            writer,
            namespace: namespace.to_string(),
            schemas: HashMap::new(),
            channels: HashMap::new(),
            headerless: 0,
        })
    }

    fn channel(&mut self, topic: &str, type_name: &str) -> Result<u16, WriteError> {
        if let Some(id) = self
            .channels
            .get(topic)
            .and_then(|v| v.iter().find(|(t, _)| t == type_name))
            .map(|(_, id)| *id)
        {
            return Ok(id);
        }
        let schema = match self.schemas.get(type_name) {
            Some(&id) => id,
            None => {
                let (name, encoding, data) = schema_for(type_name);
                let id = self.writer.add_schema(&name, encoding, &data)?;
                self.schemas.insert(type_name.to_string(), id);
                id
            }
        };
        let metadata = BTreeMap::from([
            (TYPE_KEY.to_string(), type_name.to_string()),
            (NAMESPACE_KEY.to_string(), self.namespace.clone()),
        ]);
        let id = self
            .writer
            .add_channel(schema, topic, MESSAGE_ENCODING, &metadata)?;
        self.channels
            .entry(topic.to_string())
            .or_default()
            .push((type_name.to_string(), id));
        Ok(id)
    }

    /// Append one sample received at `log_time_ns`.
    pub fn write(
        &mut self,
        topic: &str,
        type_name: &str,
        log_time_ns: u64,
        seq: Option<u64>,
        payload: &[u8],
    ) -> Result<(), WriteError> {
        let channel_id = self.channel(topic, type_name)?;
        let publish_time = match header_of(payload) {
            Some(h) => u64::try_from(h.stamp_ns).unwrap_or(0),
            None => {
                self.headerless += 1;
                log_time_ns
            }
        };
        let sequence = seq.unwrap_or(0) as u32;
        let header = mcap::records::MessageHeader {
            channel_id,
            sequence,
            log_time: log_time_ns,
            publish_time,
        };
        self.writer.write_to_known_channel(&header, payload)?;
        Ok(())
    }

    /// Close the current chunk and push everything written so far to the operating system.
    pub fn flush(&mut self) -> Result<(), WriteError> {
        self.writer.flush()?;
        Ok(())
    }

    /// Write the metadata record, the summary (statistics, chunk and message indexes) and the
    /// footer.
    pub fn finish(mut self, metadata: BTreeMap<String, String>) -> Result<(), WriteError> {
        self.writer.write_metadata(&mcap::records::Metadata {
            name: METADATA_NAME.to_string(),
            metadata,
        })?;
        self.writer.finish()?;
        Ok(())
    }
}

/// One message read back from a recording.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Recorded {
    pub topic: String,
    pub type_name: String,
    pub message_encoding: String,
    pub log_time_ns: u64,
    pub publish_time_ns: u64,
    pub sequence: u32,
    pub data: Vec<u8>,
    /// Why this build would misread the channel's payloads, if it would: they were recorded
    /// with another wire form of the type than this build's (an older robocog). `None`: same
    /// definition, or a channel without a schema to tell.
    pub wire_mismatch: Option<String>,
}

/// Why payloads recorded under this schema would not read as `type_name` of this build: the
/// schema is the type's ROS 2 definition of another build, or robocog's JSON shape for a type
/// this build records with its ROS 2 definition (so an older robocog wrote it, before the
/// payloads carried ROS 2's standard types, `std_msgs/Header` first).
pub fn wire_mismatch(type_name: &str, encoding: &str, data: &[u8]) -> Option<String> {
    let ours = ros_msgs::definitions().full_definition(type_name).ok()?;
    match encoding {
        ROS2_SCHEMA_ENCODING => (ours.as_bytes() != data).then(|| {
            format!(
                "recorded with another definition of {type_name} than this build's (see `robocog interface show {type_name}`): replay it with the robocog that recorded it"
            )
        }),
        SCHEMA_ENCODING => Some(format!(
            "recorded before robocog's payloads carried ROS 2's standard types (its {type_name} header is not a std_msgs/Header): replay it with the robocog that recorded it"
        )),
        _ => None,
    }
}

mod reader;
pub use reader::{Damage, RecordingReader};

#[cfg(test)]
mod tests;
