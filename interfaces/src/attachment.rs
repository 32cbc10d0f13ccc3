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
            sequence: 42,
            source_timestamp_ns: 1_700_000_000_000_000_001,
            gid: gid("x"),
        };
        let bytes = a.encode();
        assert_eq!(bytes[..8], 42i64.to_le_bytes());
        assert_eq!(bytes[16], 16);
        assert_eq!(Attachment::decode(&bytes), Ok(a));
        assert!(
            Attachment::decode(&bytes[..32])
                .unwrap_err()
                .contains("32 bytes")
        );
        let mut bad = bytes;
        bad[16] = 8;
        assert!(Attachment::decode(&bad).unwrap_err().contains("GID of 8"));
    }
}
