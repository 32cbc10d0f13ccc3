#![allow(clippy::unwrap_used)]
use super::reader::{le_u64, lengths_fit};
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
    let crash = include_bytes!("../../../tests/fuzz/regressions/mcap/short-attachment");
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
        include_bytes!("../../../tests/fuzz/regressions/mcap/chunk-index-map-between-entries");
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
