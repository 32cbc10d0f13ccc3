//! The header every message carries; its stamp comes from the component's [`Clock`].

use crate::msg::ros::{StdHeader, Time};
use serde::{Deserialize, Deserializer, Serialize, Serializer};

pub use crate::clock::{Clock, system_now_ns};

/// Every message starts with this: when it was stamped, its sequence number on its publisher, and
/// the coordinate frame its geometry is expressed in (empty when it has none).
///
/// On the wire it is a ROS 2 `std_msgs/Header` (`builtin_interfaces/Time stamp`, `string
/// frame_id`); `seq`, which `std_msgs/Header` has not, travels in the sample's attachment (as
/// rmw_zenoh's sequence number does) and the bus puts it back here on receipt. JSON shows all
/// three fields.
#[derive(Debug, Clone, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(remote = "Self")]
pub struct Header {
    /// Nanoseconds since the Unix epoch on the publishing component's [`Clock`] (system or virtual).
    pub stamp_ns: i64,
    /// Per-publisher sequence number, from 0; a gap on a subscriber means a lost message.
    pub seq: u64,
    /// Frame of the message's geometry, a link or sensor name of the robot model or `world`.
    pub frame_id: String,
}

impl Header {
    pub fn new(frame_id: impl Into<String>) -> Self {
        Self {
            stamp_ns: 0,
            seq: 0,
            frame_id: frame_id.into(),
        }
    }
    /// The stamp in seconds.
    pub fn stamp_s(&self) -> f64 {
        self.stamp_ns as f64 * 1e-9
    }
}

impl Serialize for Header {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        if s.is_human_readable() {
            Header::serialize(self, s)
        } else {
            StdHeader {
                stamp: Time::from_ns(self.stamp_ns),
                frame_id: self.frame_id.as_str(),
            }
            .serialize(s)
        }
    }
}

impl<'de> Deserialize<'de> for Header {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        if d.is_human_readable() {
            return Header::deserialize(d);
        }
        let h = StdHeader::<String>::deserialize(d)?;
        let stamp_ns = h.stamp.to_ns().ok_or_else(|| {
            serde::de::Error::custom(format!(
                "a stamp of {} ns in a second (at most 999999999)",
                h.stamp.nanosec
            ))
        })?;
        Ok(Header {
            stamp_ns,
            seq: 0,
            frame_id: h.frame_id,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::codec;

    #[test]
    fn on_the_wire_a_header_is_a_std_msgs_header_and_json_keeps_the_sequence() {
        let h = Header {
            stamp_ns: 1_700_000_000_123_456_789,
            seq: 7,
            frame_id: "cam".into(),
        };
        let bytes = codec::encode(&h, "header").unwrap();
        // Encapsulation, int32 sec, uint32 nanosec, string "cam".
        let mut want = vec![0, 1, 0, 0];
        want.extend(1_700_000_000i32.to_le_bytes());
        want.extend(123_456_789u32.to_le_bytes());
        want.extend(4u32.to_le_bytes());
        want.extend(b"cam\0");
        assert_eq!(bytes, want);
        let back: Header = codec::decode(&bytes, "header").unwrap();
        assert_eq!(
            back,
            Header {
                seq: 0,
                ..h.clone()
            }
        );
        let json = serde_json::to_value(&h).unwrap();
        assert_eq!(
            json,
            serde_json::json!({"stamp_ns": 1_700_000_000_123_456_789i64, "seq": 7, "frame_id": "cam"})
        );
        assert_eq!(serde_json::from_value::<Header>(json).unwrap(), h);
    }

    #[test]
    fn a_stamp_with_a_second_of_nanoseconds_or_more_is_an_error() {
        let mut bytes = vec![0, 1, 0, 0];
        bytes.extend(5i32.to_le_bytes());
        bytes.extend(1_000_000_000u32.to_le_bytes());
        bytes.extend(1u32.to_le_bytes());
        bytes.push(0);
        let e = codec::decode::<Header>(&bytes, "header").unwrap_err();
        assert!(e.to_string().contains("1000000000 ns"), "{e}");
    }
}
