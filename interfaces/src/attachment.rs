//! What travels beside every sample's payload: its publisher's sequence number, its source time
//! stamp and the publisher's GID, in the 33 bytes rmw_zenoh puts on every ROS 2 sample (its
//! `attachment_helpers.cpp`: `int64` sequence number, `int64` source time stamp, both
//! little-endian, then the GID's length, 16, as one LEB128 byte, and the 16 bytes).
//!
//! The sequence number lives here, not in the payload, because the payload's header is a ROS 2
//! `std_msgs/Header`, which has none; the bus puts it back into [`crate::Header::seq`] on receipt.

/// What a sample carries beside its payload.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Attachment {
    /// The publisher's sequence number of the sample.
    pub sequence: i64,
    /// When it was stamped at its source (ns since the epoch).
    pub source_timestamp_ns: i64,
    /// The publisher's id.
    pub gid: [u8; 16],
}

/// The length of an encoded [`Attachment`].
pub const ATTACHMENT_LEN: usize = 33;

impl Attachment {
    pub fn encode(&self) -> [u8; ATTACHMENT_LEN] {
        let mut out = [0u8; ATTACHMENT_LEN];
        out[..8].copy_from_slice(&self.sequence.to_le_bytes());
        out[8..16].copy_from_slice(&self.source_timestamp_ns.to_le_bytes());
        out[16] = 16;
        out[17..].copy_from_slice(&self.gid);
        out
    }

    /// Read an attachment, or say what is wrong with it.
    pub fn decode(bytes: &[u8]) -> Result<Attachment, String> {
        if bytes.len() != ATTACHMENT_LEN {
            return Err(format!(
                "{} bytes where rmw_zenoh writes {ATTACHMENT_LEN} (sequence, time stamp, GID)",
                bytes.len()
            ));
        }
        if bytes[16] != 16 {
            return Err(format!(
                "a GID of {} bytes where rmw_zenoh's has 16",
                bytes[16]
            ));
        }
        let i64_at = |i: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&bytes[i..i + 8]);
            i64::from_le_bytes(b)
        };
        let mut gid = [0u8; 16];
        gid.copy_from_slice(&bytes[17..]);
        Ok(Attachment {
            sequence: i64_at(0),
            source_timestamp_ns: i64_at(8),
            gid,
        })
    }

    /// The sequence number of a sample's attachment, if it has a well-formed one.
    pub fn sequence_of(attachment: Option<&zenoh::bytes::ZBytes>) -> Option<u64> {
        let a = Attachment::decode(&attachment?.to_bytes()).ok()?;
        Some(a.sequence as u64)
    }
}

/// A GID: rmw_zenoh's XXH3-128 of `id` (its entity's liveliness token), little-endian.
pub fn gid(id: &str) -> [u8; 16] {
    xxhash_rust::xxh3::xxh3_128(id.as_bytes()).to_le_bytes()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn attachments_round_trip_and_bad_ones_say_why() {
        let a = Attachment {
            sequence: 1,
            source_timestamp_ns: 0x17F0_A1B2_C3D4_E5F6,
            gid: gid("some token"),
        };
        let bytes = a.encode();
        assert_eq!(
            &bytes[..17],
            &[
                1, 0, 0, 0, 0, 0, 0, 0, 0xf6, 0xe5, 0xd4, 0xc3, 0xb2, 0xa1, 0xf0, 0x17, 0x10
            ]
        );
        assert_eq!(Attachment::decode(&bytes).unwrap(), a);
        assert!(
            Attachment::decode(&bytes[..32])
                .unwrap_err()
                .contains("32 bytes")
        );
        let mut wrong = bytes;
        wrong[16] = 15;
        assert!(
            Attachment::decode(&wrong)
                .unwrap_err()
                .contains("GID of 15")
        );
        // The format before rmw_zenoh 0.2.4 (field names first) is not taken for this one.
        assert!(Attachment::decode(b"\x0fsequence_number\x01\0\0\0\0\0\0\0").is_err());
        assert_ne!(gid("a"), gid("b"));
    }
}
