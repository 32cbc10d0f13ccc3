//! Reading a recording back: record by record from the first byte, without the summary, every
//! damage (a truncated file, a bad CRC, a malformed record) named with its byte offset.

use super::*;

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
pub(super) fn lengths_fit(opcode: u8, body: &[u8]) -> Result<(), String> {
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

pub(super) fn le_u64(b: &[u8], at: usize) -> Option<u64> {
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
