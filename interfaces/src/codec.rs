//! The one encode/decode pair of the bus: CDR little-endian with the standard 4-byte encapsulation
//! header (`00 01 00 00`), as ROS 2 writes its payloads.
//!
//! The `cdr` crate has no `Option`, no untagged or flattened enums and no `serde_json::Value`
//! (CDR is not self-describing); message types stick to plain structs, `Vec`s, `String`s and
//! externally tagged enums. A round-trip test over every registered type keeps that true.

use serde::{Serialize, de::DeserializeOwned};

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
    if bytes.len() < 4 {
        return Err(CodecError::TooShort { len: bytes.len() });
    }
    let got = [bytes[0], bytes[1], bytes[2], bytes[3]];
    if got != CDR_LE_HEADER {
        return Err(CodecError::BadEncapsulation { got });
    }
    cdr::deserialize::<T>(bytes).map_err(|source| CodecError::Decode { type_name, source })
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
}
