//! The one encode/decode pair of the bus: CDR little-endian with the standard 4-byte encapsulation
//! header (`00 01 00 00`), as ROS 2 writes its payloads.
//!
//! The `cdr` crate has no `Option`, no untagged or flattened enums and no `serde_json::Value`
//! (CDR is not self-describing); message types stick to plain structs, `Vec`s, `String`s and
//! externally tagged enums. A round-trip test over every registered type keeps that true.
//!
//! Encoding is the `cdr` crate's. Decoding is this module's own reader over the payload slice
//! (`de.rs`, the same format): it checks every length against the bytes left before allocating,
//! and hands byte blocks out as borrowed slices, so [`decode_borrowed`] can read a message's
//! borrowed view (its pixel buffers, say) in place, without a copy.

mod de;

use serde::{Deserialize, Serialize, de::DeserializeOwned};

/// The CDR little-endian encapsulation header every payload starts with.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Why a payload could not be encoded or decoded.
#[derive(Debug, thiserror::Error)]
pub enum CodecError {
    #[error("payload of {len} bytes is too short for a CDR encapsulation header")]
    TooShort { len: usize },
    #[error("payload does not start with the CDR little-endian header (got {got:02x?})")]
    BadEncapsulation { got: [u8; 4] },
    #[error("payload does not decode as {type_name}: {source}")]
    Decode {
        type_name: &'static str,
        #[source]
        source: cdr::Error,
    },
    #[error("cannot encode {type_name}: {source}")]
    Encode {
        type_name: &'static str,
        #[source]
        source: cdr::Error,
    },
}

/// The exact size of `value` once encoded, header included.
pub fn encoded_len<T: Serialize>(value: &T) -> usize {
    cdr::calc_serialized_size(value) as usize
}

/// Encode `value` as CDR little-endian, header included.
pub fn encode<T: Serialize>(value: &T, type_name: &'static str) -> Result<Vec<u8>, CodecError> {
    cdr::serialize::<_, _, cdr::CdrLe>(value, cdr::Infinite)
        .map_err(|source| CodecError::Encode { type_name, source })
}

/// Encode `value` into `out`, which must be exactly [`encoded_len`] bytes (a shared-memory
/// buffer, say), so the payload is written once, in place.
pub fn encode_into<T: Serialize>(
    value: &T,
    out: &mut [u8],
    type_name: &'static str,
) -> Result<(), CodecError> {
    let mut cursor = std::io::Cursor::new(out);
    cdr::serialize_into::<_, _, _, cdr::CdrLe>(&mut cursor, value, cdr::Infinite)
        .map_err(|source| CodecError::Encode { type_name, source })
}

/// Decode a CDR payload. Only the little-endian encapsulation is accepted: the bus never writes
/// anything else, so anything else is a foreign or corrupt payload.
pub fn decode<T: DeserializeOwned>(bytes: &[u8], type_name: &'static str) -> Result<T, CodecError> {
    decode_borrowed(bytes, type_name)
}

/// Decode a CDR payload into a type that may borrow from it: its `&'a [u8]` and `&'a str` fields
/// point into `bytes` (no copy). Same checks as [`decode`].
pub fn decode_borrowed<'a, T: Deserialize<'a>>(
    bytes: &'a [u8],
    type_name: &'static str,
) -> Result<T, CodecError> {
    let Some((head, body)) = bytes.split_first_chunk::<4>() else {
        return Err(CodecError::TooShort { len: bytes.len() });
    };
    if *head != CDR_LE_HEADER {
        return Err(CodecError::BadEncapsulation { got: *head });
    }
    T::deserialize(&mut de::Deserializer::new(body))
        .map_err(|source| CodecError::Decode { type_name, source })
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde::Deserialize;

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Sample {
        a: u8,
        b: f64,
        s: String,
        #[serde(with = "serde_bytes")]
        raw: Vec<u8>,
    }

    #[test]
    fn round_trip_is_little_endian_with_header() {
        let v = Sample {
            a: 7,
            b: 1.5,
            s: "hi".into(),
            raw: vec![1, 2, 3],
        };
        let bytes = encode(&v, "Sample").unwrap();
        assert_eq!(&bytes[..4], &CDR_LE_HEADER);
        assert_eq!(bytes[4], 7);
        // f64 is aligned to 8 from the start of the data (after the header).
        assert_eq!(&bytes[12..20], &1.5f64.to_le_bytes());
        assert_eq!(bytes.len(), encoded_len(&v));
        let back: Sample = decode(&bytes, "Sample").unwrap();
        assert_eq!(back, v);
        let mut buf = vec![0u8; bytes.len()];
        encode_into(&v, &mut buf, "Sample").unwrap();
        assert_eq!(buf, bytes);
    }

    #[test]
    fn garbage_is_an_error_not_a_panic() {
        assert!(matches!(
            decode::<Sample>(&[], "Sample"),
            Err(CodecError::TooShort { .. })
        ));
        assert!(matches!(
            decode::<Sample>(&[0, 0, 0, 0, 1], "Sample"),
            Err(CodecError::BadEncapsulation { .. })
        ));
        // A valid header with a truncated body, and a string length pointing past the end.
        assert!(decode::<Sample>(&[0, 1, 0, 0, 7], "Sample").is_err());
        let mut huge = vec![0, 1, 0, 0, 7, 0, 0, 0];
        huge.extend_from_slice(&1.0f64.to_le_bytes());
        huge.extend_from_slice(&u32::MAX.to_le_bytes());
        assert!(decode::<Sample>(&huge, "Sample").is_err());
    }
    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    enum Shape {
        Empty,
        Point(f32),
        Pair(i16, u64),
        Named { id: u32, tag: String },
    }

    #[derive(Debug, PartialEq, Serialize, Deserialize)]
    struct Wide {
        flag: bool,
        c: char,
        small: i16,
        shapes: Vec<Shape>,
        names: Vec<String>,
        grid: [[u8; 3]; 2],
        pair: (u8, f64),
        #[serde(with = "serde_bytes")]
        raw: Vec<u8>,
        tail: i64,
    }

    fn wide() -> Wide {
        Wide {
            flag: true,
            c: 'x',
            small: -3,
            shapes: vec![
                Shape::Empty,
                Shape::Point(2.5),
                Shape::Pair(-7, 1 << 40),
                Shape::Named {
                    id: 9,
                    tag: "héllo".into(),
                },
            ],
            names: vec![String::new(), "a".into(), "abcdefg".into()],
            grid: [[1, 2, 3], [4, 5, 6]],
            pair: (8, -0.25),
            raw: (0..=255).collect(),
            tail: i64::MIN,
        }
    }

    #[test]
    fn the_decoder_reads_what_the_cdr_crate_reads() {
        let bytes = encode(&wide(), "Wide").unwrap();
        let ours: Wide = decode(&bytes, "Wide").unwrap();
        let theirs: Wide = cdr::deserialize(&bytes).unwrap();
        assert_eq!(ours, theirs);
        assert_eq!(ours, wide());
        // Every truncation is an error for both, never a panic.
        for cut in 0..bytes.len() {
            let short = &bytes[..cut];
            assert!(decode::<Wide>(short, "Wide").is_err(), "cut at {cut}");
            assert!(cdr::deserialize::<Wide>(short).is_err(), "cut at {cut}");
        }
        // Any single-byte corruption decodes to something or fails, never panics. (No
        // comparison with the cdr crate here: a corrupt length makes it allocate first.)
        for at in 4..bytes.len() {
            for flip in [0x01u8, 0x80, 0xff] {
                let mut bad = bytes.clone();
                bad[at] ^= flip;
                let _ = decode::<Wide>(&bad, "Wide");
            }
        }
    }

    #[test]
    fn lengths_past_the_end_are_errors_before_any_allocation() {
        // A string, a byte block and a sequence each announcing 2^32-1 items: rejected on the
        // length alone (the cdr crate would first allocate and zero 4 GiB).
        #[derive(Debug, Deserialize)]
        #[allow(dead_code)]
        struct Seq {
            v: Vec<u64>,
        }
        let mut payload = CDR_LE_HEADER.to_vec();
        payload.extend_from_slice(&u32::MAX.to_le_bytes());
        payload.extend_from_slice(&[1, 2, 3, 4]);
        let e = decode::<String>(&payload, "String").unwrap_err();
        assert!(e.to_string().contains("4294967295"), "{e}");
        assert!(decode::<serde_bytes::ByteBuf>(&payload, "Bytes").is_err());
        assert!(decode::<Seq>(&payload, "Seq").is_err());
        // One past the end is an error too; exactly to the end is fine.
        let mut exact = CDR_LE_HEADER.to_vec();
        exact.extend_from_slice(&4u32.to_le_bytes());
        exact.extend_from_slice(b"abc\0");
        assert_eq!(decode::<String>(&exact, "String").unwrap(), "abc");
        exact[4] = 5;
        assert!(decode::<String>(&exact, "String").is_err());
    }

    #[test]
    fn borrowed_fields_point_into_the_payload() {
        #[derive(Debug, Deserialize)]
        struct View<'a> {
            a: u8,
            #[serde(borrow)]
            raw: &'a [u8],
            s: &'a str,
        }
        #[derive(Serialize)]
        struct Owned {
            a: u8,
            #[serde(with = "serde_bytes")]
            raw: Vec<u8>,
            s: String,
        }
        let bytes = encode(
            &Owned {
                a: 1,
                raw: vec![9; 100],
                s: "frame".into(),
            },
            "Owned",
        )
        .unwrap();
        let v: View<'_> = decode_borrowed(&bytes, "View").unwrap();
        assert_eq!((v.a, v.raw.len(), v.s), (1, 100, "frame"));
        let range = bytes.as_ptr_range();
        assert!(range.contains(&v.raw.as_ptr()) && range.contains(&v.s.as_ptr()));
    }
}
