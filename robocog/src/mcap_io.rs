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

/// Where and how a recording is damaged. Every variant names the byte offset of the problem.
#[derive(Debug, thiserror::Error)]
pub enum Damage {
    #[error("cannot read the file at byte offset {offset}: {source}")]
    Io {
        offset: u64,
        #[source]
        source: std::io::Error,
    },
    #[error("not an MCAP file: it does not start with the MCAP magic bytes (at byte offset 0)")]
    NotMcap,
    #[error(
        "truncated: the {record} record at byte offset {offset} needs {needed} bytes but the file \
         ends {available} bytes later (the recording was cut short, or this record's length is corrupt)"
    )]
    Truncated {
        record: &'static str,
        offset: u64,
        needed: u64,
        available: u64,
    },
    #[error(
        "truncated: the file ends at byte offset {offset}, between two records, without the \
         summary and footer (the recorder was killed, or the file was cut)"
    )]
    NoFooter { offset: u64 },
    #[error(
        "corrupt: the chunk at byte offset {offset} fails its CRC check (stored {saved:08x}, \
         computed {calculated:08x}); none of its messages were used"
    )]
    ChunkCrc {
        offset: u64,
        saved: u32,
        calculated: u32,
    },
    #[error("corrupt: the {record} record at byte offset {offset} does not parse: {detail}")]
    Malformed {
        record: &'static str,
        offset: u64,
        detail: String,
    },
    #[error(
        "corrupt: unknown record opcode {opcode:#04x} at byte offset {offset} (a damaged file, \
         or one from a newer MCAP version)"
    )]
    UnknownOpcode { opcode: u8, offset: u64 },
    #[error(
        "the chunk at byte offset {offset} is compressed with {compression:?}, which this build \
         does not read (robocog writes uncompressed chunks)"
    )]
    Compressed { offset: u64, compression: String },
}

fn record_name(opcode: u8) -> &'static str {
    use mcap::records::op;
    match opcode {
        op::HEADER => "header",
        op::FOOTER => "footer",
        op::SCHEMA => "schema",
        op::CHANNEL => "channel",
        op::MESSAGE => "message",
        op::CHUNK => "chunk",
        op::MESSAGE_INDEX => "message index",
        op::CHUNK_INDEX => "chunk index",
        op::ATTACHMENT => "attachment",
        op::ATTACHMENT_INDEX => "attachment index",
        op::STATISTICS => "statistics",
        op::METADATA => "metadata",
        op::METADATA_INDEX => "metadata index",
        op::SUMMARY_OFFSET => "summary offset",
        op::DATA_END => "data end",
        0x80..=0xff => "private",
        _ => "unknown",
    }
}

/// What a reader knows about a channel.
#[derive(Debug, Clone)]
struct ChannelInfo {
    topic: String,
    type_name: String,
    message_encoding: String,
    wire_mismatch: Option<String>,
}

/// Reads a recording from its first byte to its last, in file order, without the summary.
///
/// An iterator of messages; after the last readable message it yields one `Err(Damage)` if the
/// file is damaged, then ends. It never panics on bad input.
pub struct RecordingReader {
    file: BufReader<File>,
    len: u64,
    offset: u64,
    started: bool,
    finished: bool,
    in_summary: bool,
    /// Name, encoding and data of each schema.
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    channels: HashMap<u16, ChannelInfo>,
    pending: VecDeque<Recorded>,
    /// An error to yield once `pending` is drained.
    pending_error: Option<Damage>,
    /// Messages yielded so far.
    pub messages_read: u64,
    /// Messages skipped because their channel was never declared before them.
    pub orphans: u64,
}

impl std::fmt::Debug for RecordingReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordingReader")
            .field("offset", &self.offset)
            .field("len", &self.len)
            .finish()
    }
}

/// Longest record the reader accepts outside chunks (chunks are bounded by the file size).
const MAX_RECORD: u64 = 1 << 32;

impl RecordingReader {
    /// Open `path`. Only opening the file can fail here; damage shows up while iterating.
    pub fn open(path: &Path) -> std::io::Result<Self> {
        let file = File::open(path)?;
        let len = file.metadata()?.len();
        Ok(Self {
            file: BufReader::with_capacity(1 << 20, file),
            len,
            offset: 0,
            started: false,
            finished: false,
            in_summary: false,
            schemas: HashMap::new(),
            channels: HashMap::new(),
            pending: VecDeque::new(),
            pending_error: None,
            messages_read: 0,
            orphans: 0,
        })
    }

    /// The file's size in bytes.
    pub fn file_len(&self) -> u64 {
        self.len
    }

    /// Byte offset of the next record to read.
    pub fn offset(&self) -> u64 {
        self.offset
    }

    fn read_exact(&mut self, buf: &mut [u8]) -> Result<(), Damage> {
        let offset = self.offset;
        self.file
            .read_exact(buf)
            .map_err(|source| Damage::Io { offset, source })?;
        self.offset += buf.len() as u64;
        Ok(())
    }

    /// Take one parsed record (from the top level or from inside a chunk) into the state.
    fn absorb(&mut self, record: mcap::records::Record<'_>, offset: u64) -> Result<(), Damage> {
        use mcap::records::Record;
        match record {
            Record::Schema { header, data } => {
                self.schemas
                    .insert(header.id, (header.name, header.encoding, data.into_owned()));
            }
            Record::Channel(c) => {
                let type_name = c
                    .metadata
                    .get(TYPE_KEY)
                    .cloned()
                    .or_else(|| self.schemas.get(&c.schema_id).map(|s| s.0.clone()))
                    .unwrap_or_default();
                let wire_mismatch = self
                    .schemas
                    .get(&c.schema_id)
                    .and_then(|(_, encoding, data)| wire_mismatch(&type_name, encoding, data));
                self.channels.insert(
                    c.id,
                    ChannelInfo {
                        topic: c.topic,
                        type_name,
                        message_encoding: c.message_encoding,
                        wire_mismatch,
                    },
                );
            }
            Record::Message { header, data } => match self.channels.get(&header.channel_id) {
                Some(ch) => self.pending.push_back(Recorded {
                    topic: ch.topic.clone(),
                    type_name: ch.type_name.clone(),
                    message_encoding: ch.message_encoding.clone(),
                    log_time_ns: header.log_time,
                    publish_time_ns: header.publish_time,
                    sequence: header.sequence,
                    data: data.into_owned(),
                    wire_mismatch: ch.wire_mismatch.clone(),
                }),
                None => self.orphans += 1,
            },
            Record::Chunk { header, data } => {
                if !header.compression.is_empty() {
                    return Err(Damage::Compressed {
                        offset,
                        compression: header.compression,
                    });
                }
                if header.uncompressed_crc != 0 {
                    let calculated = crc32fast::hash(&data);
                    if calculated != header.uncompressed_crc {
                        return Err(Damage::ChunkCrc {
                            offset,
                            saved: header.uncompressed_crc,
                            calculated,
                        });
                    }
                }
                // The CRC held: parse every inner record before delivering any of them.
                let (records, damage) = chunk_records(&data);
                if let Some(detail) = damage {
                    return Err(Damage::Malformed {
                        record: "chunk",
                        offset,
                        detail,
                    });
                }
                for r in records {
                    self.absorb(r, offset)?;
                }
            }
            _ => {}
        }
        Ok(())
    }

    /// Read the next top-level record; `Ok(false)` at the clean end of the file.
    fn step(&mut self) -> Result<bool, Damage> {
        use mcap::records::op;
        if !self.started {
            self.started = true;
            if self.len < mcap::MAGIC.len() as u64 {
                return Err(Damage::NotMcap);
            }
            let mut magic = [0u8; 8];
            self.read_exact(&mut magic)?;
            if magic != mcap::MAGIC {
                return Err(Damage::NotMcap);
            }
        }
        let start = self.offset;
        let remaining = self.len - start;
        if remaining == 0 {
            return Err(Damage::NoFooter { offset: start });
        }
        if remaining < 9 {
            return Err(Damage::Truncated {
                record: "next",
                offset: start,
                needed: 9,
                available: remaining,
            });
        }
        let mut head = [0u8; 9];
        self.read_exact(&mut head)?;
        let opcode = head[0];
        let mut len_bytes = [0u8; 8];
        len_bytes.copy_from_slice(&head[1..]);
        let len = u64::from_le_bytes(len_bytes);
        let name = record_name(opcode);
        if opcode == 0 || (opcode > op::DATA_END && opcode < 0x80) {
            return Err(Damage::UnknownOpcode {
                opcode,
                offset: start,
            });
        }
        let available = remaining - 9;
        if len > available {
            if opcode == op::CHUNK && !self.in_summary {
                self.salvage_cut_chunk(start, available);
            }
            return Err(Damage::Truncated {
                record: name,
                offset: start,
                needed: len.saturating_add(9),
                available: remaining,
            });
        }
        if opcode != op::CHUNK && len > MAX_RECORD {
            return Err(Damage::Malformed {
                record: name,
                offset: start,
                detail: format!("implausible length {len}"),
            });
        }
        let mut body = vec![0u8; len as usize];
        self.read_exact(&mut body)?;
        match opcode {
            op::FOOTER => {
                let rest = self.len - self.offset;
                let mut magic = [0u8; 8];
                if rest < 8 {
                    return Err(Damage::Truncated {
                        record: "end magic",
                        offset: self.offset,
                        needed: 8,
                        available: rest,
                    });
                }
                self.read_exact(&mut magic)?;
                if magic != mcap::MAGIC {
                    return Err(Damage::Malformed {
                        record: "end magic",
                        offset: self.offset - 8,
                        detail: "the file does not end with the MCAP magic bytes".into(),
                    });
                }
                return Ok(false);
            }
            op::DATA_END => {
                self.in_summary = true;
                return Ok(true);
            }
            _ => {}
        }
        if self.in_summary {
            // Summary records repeat what the data section held; check they parse, no more.
            parse_record(opcode, &body).map_err(|detail| Damage::Malformed {
                record: name,
                offset: start,
                detail,
            })?;
            return Ok(true);
        }
        let record = parse_record(opcode, &body).map_err(|detail| Damage::Malformed {
            record: name,
            offset: start,
            detail,
        })?;
        self.absorb(record, start)?;
        Ok(true)
    }

    /// The file ends inside a chunk (the recorder died while writing it, or the file was cut):
    /// deliver the complete records at its start. Nothing here was damaged, only cut short, so
    /// the records that are whole are trustworthy; no CRC can be checked, the rest is lost.
    fn salvage_cut_chunk(&mut self, start: u64, available: u64) {
        let mut rest = Vec::with_capacity(available.min(1 << 30) as usize);
        if (&mut self.file)
            .take(available)
            .read_to_end(&mut rest)
            .is_err()
        {
            return;
        }
        self.offset += rest.len() as u64;
        // Chunk header: start u64, end u64, uncompressed size u64, uncompressed crc u32,
        // compression (u32 length + bytes), records length u64, then the records.
        let mut at = 8 + 8 + 8 + 4;
        let Some(clen) = le_u32(&rest, at) else {
            return;
        };
        at += 4;
        if clen != 0 {
            return; // a compressed stream cannot be cut and resumed
        }
        at += 8;
        // What is whole at the chunk's start; the cut record and anything after it is lost.
        let (found, _cut) = chunk_records(rest.get(at..).unwrap_or_default());
        for r in found {
            if self.absorb(r, start).is_err() {
                break;
            }
        }
    }
}

/// The records of an uncompressed chunk's record area, in order, up to the first that is cut
/// short or malformed; with that one's damage, if any.
fn chunk_records(area: &[u8]) -> (Vec<mcap::records::Record<'static>>, Option<String>) {
    let mut found = Vec::new();
    let mut at = 0usize;
    while at < area.len() {
        let (Some(&opcode), Some(len)) = (area.get(at), le_u64(area, at + 1)) else {
            return (
                found,
                Some(format!("a record header cut short at offset {at}")),
            );
        };
        let body_start = at + 9;
        let Some(body) = usize::try_from(len)
            .ok()
            .and_then(|l| body_start.checked_add(l))
            .and_then(|end| area.get(body_start..end))
        else {
            return (
                found,
                Some(format!(
                    "a record of {len} bytes at offset {at}, {} left",
                    area.len() - body_start.min(area.len())
                )),
            );
        };
        match parse_record(opcode, body) {
            Ok(r) => found.push(r.into_owned()),
            Err(e) => return (found, Some(format!("at offset {at}: {e}"))),
        }
        at = body_start + body.len();
    }
    (found, None)
}

/// `mcap::parse_record`, after checking that every length-prefixed string (and a schema's data)
/// fits in the record: the `mcap` crate allocates the length a string announces before it reads
/// it, so a corrupt length of 2^32-1 would be a 4 GiB allocation.
fn parse_record(opcode: u8, body: &[u8]) -> Result<mcap::records::Record<'_>, String> {
    lengths_fit(opcode, body)?;
    mcap::parse_record(opcode, body).map_err(|e| e.to_string())
}

/// The check of [`parse_record`], record by record as the MCAP specification lays them out.
fn lengths_fit(opcode: u8, body: &[u8]) -> Result<(), String> {
    use mcap::records::op;
    let mut w = Walk { body, at: 0 };
    match opcode {
        op::HEADER => {
            w.block("profile")?;
            w.block("library")?;
        }
        op::SCHEMA => {
            w.skip(2)?;
            w.block("schema name")?;
            w.block("schema encoding")?;
            w.block("schema data")?;
        }
        op::CHANNEL => {
            w.skip(4)?;
            w.block("topic")?;
            w.block("message encoding")?;
            w.string_map("channel metadata")?;
        }
        op::CHUNK => {
            w.skip(28)?;
            w.block("compression")?;
        }
        op::CHUNK_INDEX => {
            w.skip(32)?;
            // Entries of a u16 channel id and a u64 offset: a length between two entries makes
            // the `mcap` crate read on past the map, and take other bytes for the compression
            // string's length (4 GB, found by the fuzzer).
            w.entries("message index offsets", 10)?;
            w.skip(8)?;
            w.block("compression")?;
        }
        op::MESSAGE_INDEX => {
            w.skip(2)?;
            // Entries of a u64 time and a u64 offset.
            w.entries("message index", 16)?;
        }
        op::ATTACHMENT => {
            w.skip(16)?;
            w.block("attachment name")?;
            w.block("media type")?;
            // The data (u64 length) and its CRC: the `mcap` crate slices them unchecked.
            let len = le_u64(body, w.at).ok_or("no length for the attachment data")?;
            w.skip(8)?;
            w.skip(usize::try_from(len).unwrap_or(usize::MAX))?;
            w.skip(4)?;
        }
        op::ATTACHMENT_INDEX => {
            w.skip(40)?;
            w.block("attachment name")?;
            w.block("media type")?;
        }
        op::METADATA => {
            w.block("metadata name")?;
            w.string_map("metadata")?;
        }
        op::METADATA_INDEX => {
            w.skip(16)?;
            w.block("metadata name")?;
        }
        _ => {}
    }
    Ok(())
}

/// A cursor over a record body for [`lengths_fit`].
struct Walk<'a> {
    body: &'a [u8],
    at: usize,
}

impl Walk<'_> {
    fn left(&self) -> usize {
        self.body.len().saturating_sub(self.at)
    }

    fn skip(&mut self, n: usize) -> Result<(), String> {
        if n > self.left() {
            return Err(format!(
                "the record ends early: {n} bytes wanted at {}, {} left",
                self.at,
                self.left()
            ));
        }
        self.at += n;
        Ok(())
    }

    /// A `u32` length and that many bytes.
    fn block(&mut self, what: &str) -> Result<usize, String> {
        let len = le_u32(self.body, self.at).ok_or_else(|| format!("no length for the {what}"))?;
        self.at += 4;
        let len = len as usize;
        if len > self.left() {
            return Err(format!(
                "the {what} claims {len} bytes, {} left in the record",
                self.left()
            ));
        }
        self.at += len;
        Ok(len)
    }

    /// A `u32` byte length and that many bytes, a whole number of `size`-byte entries.
    fn entries(&mut self, what: &str, size: usize) -> Result<(), String> {
        let len = self.block(what)?;
        if len % size != 0 {
            return Err(format!(
                "the {what} take {len} bytes, not a whole number of {size}-byte entries"
            ));
        }
        Ok(())
    }

    /// A `u32` byte length, then string pairs filling exactly that many bytes.
    fn string_map(&mut self, what: &str) -> Result<(), String> {
        let len = le_u32(self.body, self.at).ok_or_else(|| format!("no length for the {what}"))?;
        self.at += 4;
        let end = self.at.saturating_add(len as usize);
        if end > self.body.len() {
            return Err(format!(
                "the {what} claims {len} bytes, {} left in the record",
                self.left()
            ));
        }
        while self.at < end {
            self.block(what)?;
            self.block(what)?;
        }
        if self.at != end {
            return Err(format!("the {what} overruns its {len} bytes"));
        }
        Ok(())
    }
}

fn le_u32(b: &[u8], at: usize) -> Option<u32> {
    let s = b.get(at..at.checked_add(4)?)?;
    Some(u32::from_le_bytes(s.try_into().ok()?))
}

fn le_u64(b: &[u8], at: usize) -> Option<u64> {
    let s = b.get(at..at.checked_add(8)?)?;
    Some(u64::from_le_bytes(s.try_into().ok()?))
}

impl Iterator for RecordingReader {
    type Item = Result<Recorded, Damage>;

    fn next(&mut self) -> Option<Self::Item> {
        loop {
            if let Some(m) = self.pending.pop_front() {
                self.messages_read += 1;
                return Some(Ok(m));
            }
            if let Some(e) = self.pending_error.take() {
                return Some(Err(e));
            }
            if self.finished {
                return None;
            }
            match self.step() {
                Ok(true) => {}
                Ok(false) => self.finished = true,
                Err(e) => {
                    self.finished = true;
                    self.pending_error = Some(e);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use interfaces::msg::std_msgs::Text;

    fn text(seq: u64, stamp_ns: i64, s: &str) -> Vec<u8> {
        let mut m = Text {
            text: s.into(),
            ..Default::default()
        };
        m.header.seq = seq;
        m.header.stamp_ns = stamp_ns;
        interfaces::codec::encode(&m, "robocog.Text").unwrap()
    }

    fn write_file(path: &Path, n: u64, flush_every: u64) -> Vec<Vec<u8>> {
        let mut w = RecordWriter::create(path, "ns").unwrap();
        let mut payloads = vec![];
        for i in 0..n {
            let p = text(i, 1_000 + i as i64, &format!("hello {i}"));
            w.write("chatter", "robocog.Text", 5_000 + i, Some(i), &p)
                .unwrap();
            payloads.push(p);
            if (i + 1) % flush_every == 0 {
                w.flush().unwrap();
            }
        }
        w.finish(BTreeMap::new()).unwrap();
        payloads
    }

    /// A scratch file of this process in the system's temporary folder, removed when dropped.
    struct Tmp(std::path::PathBuf);

    impl std::ops::Deref for Tmp {
        type Target = Path;
        fn deref(&self) -> &Path {
            &self.0
        }
    }

    impl AsRef<Path> for Tmp {
        fn as_ref(&self) -> &Path {
            &self.0
        }
    }

    impl Drop for Tmp {
        fn drop(&mut self) {
            let _ = std::fs::remove_file(&self.0);
        }
    }

    fn tmp(name: &str) -> Tmp {
        Tmp(std::env::temp_dir().join(format!("robocog-mcap-io-{}-{name}", std::process::id())))
    }

    #[test]
    fn round_trip_keeps_bytes_times_and_types() {
        let p = tmp("round.mcap");
        let payloads = write_file(&p, 50, 10);
        let mut r = RecordingReader::open(&p).unwrap();
        let got: Vec<Recorded> = r.by_ref().map(|m| m.unwrap()).collect();
        assert_eq!(got.len(), 50);
        for (i, m) in got.iter().enumerate() {
            assert_eq!(m.data, payloads[i]);
            assert_eq!(m.topic, "chatter");
            assert_eq!(m.type_name, "robocog.Text");
            assert_eq!(m.message_encoding, "cdr");
            assert_eq!(m.log_time_ns, 5_000 + i as u64);
            assert_eq!(m.publish_time_ns, 1_000 + i as u64);
            assert_eq!(m.sequence, i as u32);
        }
        // The file is a valid MCAP for the mcap crate's own (summary-based) reader too.
        let bytes = std::fs::read(&p).unwrap();
        let summary = mcap::Summary::read(&bytes).unwrap().unwrap();
        let schema = summary.schemas.values().next().unwrap();
        assert_eq!(schema.name, "robocog_msgs/msg/Text");
        assert_eq!(schema.encoding, ROS2_SCHEMA_ENCODING);
        let text = std::str::from_utf8(&schema.data).unwrap();
        assert!(
            text.starts_with("std_msgs/Header header\nstring text\n"),
            "{text}"
        );
        assert!(text.contains("\nMSG: std_msgs/Header\n"), "{text}");
        assert!(text.contains("\nMSG: builtin_interfaces/Time\n"), "{text}");
    }

    /// Recordings made before the ROS 2 schemas (robocog's shape schema, named by the type) read
    /// as they did: the type comes from the channel's metadata, or else the schema's name. Their
    /// payloads are of the wire before `std_msgs/Header`, which replay is told (it skips them,
    /// saying why, rather than publish what this build would misread).
    #[test]
    fn recordings_of_the_earlier_layout_still_read_with_their_types() {
        let p = tmp("earlier.mcap");
        {
            let file = BufWriter::new(File::create(&p).unwrap());
            let mut w = mcap::WriteOptions::new()
                .compression(None)
                .profile(PROFILE)
                .create(file)
                .unwrap();
            let schema = w
                .add_schema(
                    "robocog.Text",
                    SCHEMA_ENCODING,
                    &schema_data("robocog.Text"),
                )
                .unwrap();
            let with_meta = BTreeMap::from([(TYPE_KEY.to_string(), "robocog.Text".to_string())]);
            let a = w
                .add_channel(schema, "chatter", MESSAGE_ENCODING, &with_meta)
                .unwrap();
            let b = w
                .add_channel(schema, "other", MESSAGE_ENCODING, &BTreeMap::new())
                .unwrap();
            for (i, ch) in [a, b].into_iter().enumerate() {
                let header = mcap::records::MessageHeader {
                    channel_id: ch,
                    sequence: i as u32,
                    log_time: 10 + i as u64,
                    publish_time: 10 + i as u64,
                };
                w.write_to_known_channel(&header, &text(i as u64, 10, "old"))
                    .unwrap();
            }
            w.finish().unwrap();
        }
        let got: Vec<Recorded> = RecordingReader::open(&p)
            .unwrap()
            .map(|m| m.unwrap())
            .collect();
        assert_eq!(got.len(), 2);
        assert!(got.iter().all(|m| m.type_name == "robocog.Text"), "{got:?}");
        for m in &got {
            let why = m.wire_mismatch.as_deref().unwrap_or_default();
            assert!(why.contains("std_msgs/Header"), "{why}");
        }
    }

    /// A ROS 2 schema of another build's definition (the header before `std_msgs/Header`) is a
    /// mismatch; this build's own is none.
    #[test]
    fn a_schema_of_another_definition_is_a_wire_mismatch() {
        let ours = ros_msgs::definitions()
            .full_definition("robocog.Text")
            .unwrap();
        assert_eq!(
            wire_mismatch("robocog.Text", ROS2_SCHEMA_ENCODING, ours.as_bytes()),
            None
        );
        let old = "robocog_msgs/Header header\nstring text\n";
        let why = wire_mismatch("robocog.Text", ROS2_SCHEMA_ENCODING, old.as_bytes()).unwrap();
        assert!(why.contains("another definition of robocog.Text"), "{why}");
        assert_eq!(wire_mismatch("robocog.Text", "jsonschema", b"{}"), None);
        // A type this build does not know: nothing to compare with.
        assert_eq!(wire_mismatch("robocog.Nope", SCHEMA_ENCODING, b"{}"), None);
    }

    #[test]
    fn every_truncation_and_corruption_is_an_error_never_a_panic() {
        let p = tmp("damage.mcap");
        write_file(&p, 40, 8);
        let good = std::fs::read(&p).unwrap();
        for cut in (0..good.len()).step_by(7) {
            let q = tmp("cut.mcap");
            std::fs::write(&q, &good[..cut]).unwrap();
            let mut r = RecordingReader::open(&q).unwrap();
            let mut ok = 0;
            let mut err = None;
            for m in r.by_ref() {
                match m {
                    Ok(_) => ok += 1,
                    Err(e) => err = Some(e),
                }
            }
            assert!(err.is_some(), "a cut at {cut} must be reported");
            assert!(ok <= 40);
        }
        for at in (8..good.len()).step_by(5) {
            let mut bad = good.clone();
            bad[at] ^= 0x5a;
            let q = tmp("flip.mcap");
            std::fs::write(&q, &bad).unwrap();
            // Reading must end (no panic, no endless loop); a flip may land in a padding or
            // index field that nothing checks, so an error is not required for every byte.
            let n = RecordingReader::open(&q).unwrap().count();
            assert!(n <= 41);
        }
    }

    /// A string length of 2^32-1 inside a record (a channel's topic, here in a cut chunk, and
    /// in a whole one with its CRC cleared) is damage reported at once, never a 4 GiB
    /// allocation (the fuzz target `mcap` found this).
    #[test]
    fn a_huge_string_length_is_damage_not_an_allocation() {
        let p = tmp("huge.mcap");
        write_file(&p, 5, 1000);
        let mut bytes = std::fs::read(&p).unwrap();
        let topic = b"chatter";
        let pos = bytes.windows(topic.len()).position(|w| w == topic).unwrap();
        bytes[pos - 4..pos].copy_from_slice(&u32::MAX.to_le_bytes());
        // Clear the first chunk's CRC (0: not computed) so the reader parses what it holds.
        let mut at = 8;
        while bytes[at] != mcap::records::op::CHUNK {
            at += 9 + le_u64(&bytes, at + 1).unwrap() as usize;
        }
        bytes[at + 9 + 24..at + 9 + 28].fill(0);
        let q = tmp("huge_bad.mcap");
        std::fs::write(&q, &bytes).unwrap();
        let results: Vec<_> = RecordingReader::open(&q).unwrap().collect();
        assert!(results.iter().all(|r| r.is_err()), "{results:?}");
        let Some(Err(e)) = results.last() else {
            panic!("no damage reported");
        };
        assert!(e.to_string().contains("4294967295"), "{e}");
        assert_eq!(
            lengths_fit(
                mcap::records::op::CHANNEL,
                &[0, 0, 0, 0, 0xff, 0xff, 0xff, 0xff]
            ),
            Err("the topic claims 4294967295 bytes, 0 left in the record".to_string())
        );
    }

    /// An attachment shorter than its own header and CRC (the fuzz target `mcap` found that the
    /// `mcap` crate slices it and panics) is damage, not a panic.
    #[test]
    fn a_short_attachment_is_damage_not_a_panic() {
        let mut body = vec![0u8; 16];
        body.extend_from_slice(&1u32.to_le_bytes());
        body.push(b'a');
        body.extend_from_slice(&0u32.to_le_bytes());
        assert!(lengths_fit(mcap::records::op::ATTACHMENT, &body).is_err());
        body.extend_from_slice(&2u64.to_le_bytes());
        body.extend_from_slice(b"xy");
        assert!(
            lengths_fit(mcap::records::op::ATTACHMENT, &body).is_err(),
            "no CRC"
        );
        body.extend_from_slice(&0u32.to_le_bytes());
        assert_eq!(lengths_fit(mcap::records::op::ATTACHMENT, &body), Ok(()));
        // The file the fuzzer made, whole.
        let crash = include_bytes!("../../tests/fuzz/regressions/mcap/short-attachment");
        let p = tmp("short_attachment.mcap");
        std::fs::write(&p, crash).unwrap();
        let results: Vec<_> = RecordingReader::open(&p).unwrap().collect();
        assert!(results.last().is_some_and(|r| r.is_err()), "{results:?}");
    }

    /// A chunk index whose offset map stops between two 10-byte entries: the `mcap` crate read
    /// on past it and took other bytes for a string's length (4 GB). Refused as damage.
    #[test]
    fn a_map_length_between_entries_is_damage_not_an_allocation() {
        let mut body = vec![0u8; 32];
        body.extend_from_slice(&28u32.to_le_bytes());
        body.extend_from_slice(&[0; 28]);
        body.extend_from_slice(&[0; 8]);
        body.extend_from_slice(&0u32.to_le_bytes());
        body.extend_from_slice(&[0; 16]);
        let e = lengths_fit(mcap::records::op::CHUNK_INDEX, &body).unwrap_err();
        assert!(e.contains("not a whole number of 10-byte entries"), "{e}");
        let mut index = 7u16.to_le_bytes().to_vec();
        index.extend_from_slice(&24u32.to_le_bytes());
        index.extend_from_slice(&[0; 24]);
        assert!(lengths_fit(mcap::records::op::MESSAGE_INDEX, &index).is_err());
        // The file the fuzzer made, whole.
        let oom =
            include_bytes!("../../tests/fuzz/regressions/mcap/chunk-index-map-between-entries");
        let p = tmp("map_between_entries.mcap");
        std::fs::write(&p, oom).unwrap();
        if let Ok(reader) = RecordingReader::open(&p) {
            let results: Vec<_> = reader.collect();
            assert!(results.iter().any(|r| r.is_err()), "{results:?}");
        }
    }

    #[test]
    fn a_cut_chunk_keeps_its_whole_messages() {
        let p = tmp("one_chunk.mcap");
        write_file(&p, 30, 1000);
        let good = std::fs::read(&p).unwrap();
        // Find the first message's payload, then cut in the middle of the 20th message.
        let needle = text(19, 1_019, "hello 19");
        let pos = good
            .windows(needle.len())
            .position(|w| w == needle.as_slice())
            .unwrap();
        let q = tmp("one_chunk_cut.mcap");
        std::fs::write(&q, &good[..pos + 3]).unwrap();
        let results: Vec<_> = RecordingReader::open(&q).unwrap().collect();
        let ok = results.iter().filter(|r| r.is_ok()).count();
        assert_eq!(ok, 19, "the 19 whole messages before the cut are kept");
        let last = results.last().unwrap().as_ref().unwrap_err().to_string();
        assert!(
            last.contains("truncated") && last.contains("chunk"),
            "{last}"
        );
    }

    #[test]
    fn a_flipped_payload_byte_fails_the_chunk_crc() {
        let p = tmp("crc.mcap");
        write_file(&p, 30, 10);
        let mut bytes = std::fs::read(&p).unwrap();
        let needle = b"hello 25";
        let pos = bytes.windows(8).position(|w| w == needle).unwrap();
        bytes[pos] = b'j';
        let q = tmp("crc_bad.mcap");
        std::fs::write(&q, &bytes).unwrap();
        let results: Vec<_> = RecordingReader::open(&q).unwrap().collect();
        let ok = results.iter().filter(|r| r.is_ok()).count();
        assert_eq!(
            ok, 20,
            "the two chunks before the damaged one are delivered"
        );
        let e = results.last().unwrap().as_ref().unwrap_err();
        assert!(matches!(e, Damage::ChunkCrc { .. }), "{e}");
        assert!(e.to_string().contains("byte offset"));
    }
}
