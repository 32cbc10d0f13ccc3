//! How ROS 2's rmw_zenoh puts a topic on zenoh (the format of ROS 2 Jazzy from rmw_zenoh_cpp
//! 0.2.4, and Kilted), written and read here without ROS 2:
//!
//! - **data**: samples are put on `<domain>/<topic>/<dds type>/<type hash>`, the topic without
//!   its leading `/` (`0/vision/ball/robocog_msgs::msg::dds_::BallTrack_/RIHS01_…`), payload
//!   CDR with its encapsulation header (robocog's payloads as they are);
//! - **graph**: liveliness tokens `@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<kind>/
//!   <enclave>/<namespace>/<node>[/<topic>/<dds type>/<type hash>/<qos>]`, every `/` inside a
//!   name written `%` (the root namespace and the default enclave are `%`); `NN` for a node,
//!   `MP` a publisher, `MS` a subscription;
//! - **attachment** of every sample: 33 bytes, the publisher's sequence number (i64 LE, from 1),
//!   the source time stamp (i64 LE, ns since the epoch), then the publisher's 16-byte GID with
//!   its length (a LEB128 `0x10`): zenoh-ext's serialization of `(i64, i64, [u8; 16])`;
//! - a publisher's **GID** is the XXH3-128 of its token, little-endian.
//!
//! (rmw_zenoh's `docs/design.md` and `liveliness_utils.cpp`; the attachment carried field names
//! before rmw_zenoh 0.2.4: such samples are refused here as malformed.)

use std::fmt::Write as _;

/// The liveliness prefix of ROS 2's graph.
pub const ADMIN_SPACE: &str = "@ros2_lv";

/// The QoS of a default ROS 2 publisher or subscription (reliable, volatile, keep last 10), as a
/// token writes it: rmw_zenoh leaves out every value equal to its own default.
pub const DEFAULT_QOS: &str = "::,10:,:,:,,";

/// `robocog_msgs/msg/BallTrack` -> `robocog_msgs::msg::dds_::BallTrack_`.
pub fn dds_type_name(ros_name: &str) -> Option<String> {
    let (pkg, rest) = ros_name.split_once("/msg/")?;
    if pkg.is_empty() || rest.is_empty() || rest.contains('/') {
        return None;
    }
    Some(format!("{pkg}::msg::dds_::{rest}_"))
}

/// `robocog_msgs::msg::dds_::BallTrack_` -> `robocog_msgs/msg/BallTrack`.
pub fn ros_type_name(dds: &str) -> Option<String> {
    let (pkg, rest) = dds.split_once("::msg::dds_::")?;
    let name = rest.strip_suffix('_')?;
    if pkg.is_empty() || name.is_empty() || name.contains(':') || pkg.contains(':') {
        return None;
    }
    Some(format!("{pkg}/msg/{name}"))
}

/// A robocog topic (`vision/ball`) as a ROS 2 topic name (`/vision/ball`), when ROS 2 allows it
/// (letters, digits and `_` in each part, a part not starting with a digit).
pub fn ros_topic(topic: &str) -> Option<String> {
    let ok = topic.split('/').all(|part| {
        !part.is_empty()
            && !part.as_bytes()[0].is_ascii_digit()
            && part.bytes().all(|c| c.is_ascii_alphanumeric() || c == b'_')
    });
    ok.then(|| format!("/{topic}"))
}

/// A name inside a token: `/` written `%`.
pub fn mangle(name: &str) -> String {
    name.replace('/', "%")
}

/// The key samples of `topic` (`/vision/ball`) are put on.
pub fn data_key(domain: u32, ros_topic: &str, dds_type: &str, hash: &str) -> String {
    let t = ros_topic.strip_prefix('/').unwrap_or(ros_topic);
    let t = t.strip_suffix('/').unwrap_or(t);
    format!("{domain}/{t}/{dds_type}/{hash}")
}

/// The token of node `node` (namespace `/`, default enclave).
pub fn node_token(domain: u32, zid: &str, node_id: u64, node: &str) -> String {
    format!(
        "{ADMIN_SPACE}/{domain}/{zid}/{node_id}/{node_id}/NN/%/%/{}",
        mangle(node)
    )
}

/// What an entity token announces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Kind {
    Publisher,
    Subscription,
}

impl Kind {
    fn code(self) -> &'static str {
        match self {
            Kind::Publisher => "MP",
            Kind::Subscription => "MS",
        }
    }
}

/// The token of a publisher or subscription of node `node` on `ros_topic`.
#[allow(clippy::too_many_arguments)]
pub fn entity_token(
    domain: u32,
    zid: &str,
    node_id: u64,
    entity_id: u64,
    kind: Kind,
    node: &str,
    ros_topic: &str,
    dds_type: &str,
    hash: &str,
) -> String {
    format!(
        "{ADMIN_SPACE}/{domain}/{zid}/{node_id}/{entity_id}/{}/%/%/{}/{}/{}/{}/{DEFAULT_QOS}",
        kind.code(),
        mangle(node),
        mangle(ros_topic),
        mangle(dds_type),
        mangle(hash),
    )
}

/// A publisher or subscription read from a ROS 2 graph token.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Entity {
    pub domain: u32,
    pub zid: String,
    pub kind: Kind,
    pub node: String,
    /// `/vision/ball`.
    pub topic: String,
    pub dds_type: String,
    pub hash: String,
}

/// Read a publisher or subscription token; `None` for a node, a service, or anything that is not
/// a well-formed token (tokens with an empty part are invalid for rmw_zenoh too).
pub fn parse_entity(key: &str) -> Option<Entity> {
    let p: Vec<&str> = key.split('/').collect();
    if p.len() < 13 || p[0] != ADMIN_SPACE || p.iter().any(|s| s.is_empty()) {
        return None;
    }
    let kind = match p[5] {
        "MP" => Kind::Publisher,
        "MS" => Kind::Subscription,
        _ => return None,
    };
    Some(Entity {
        domain: p[1].parse().ok()?,
        zid: p[2].to_string(),
        kind,
        node: p[8].replace('%', "/"),
        topic: p[9].replace('%', "/"),
        dds_type: p[10].replace('%', "/"),
        hash: p[11].replace('%', "/"),
    })
}

/// The GID of the entity of token `token`: rmw_zenoh's XXH3-128 of it, little-endian.
pub use interfaces::attachment::gid;
/// What every sample of a ROS 2 publisher carries (robocog's samples carry the same).
pub use interfaces::attachment::{ATTACHMENT_LEN, Attachment};

/// Bytes as lowercase hex (for logs).
pub fn hex(bytes: &[u8]) -> String {
    let mut s = String::with_capacity(bytes.len() * 2);
    for b in bytes {
        let _ = write!(s, "{b:02x}");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const HASH: &str = "RIHS01_df668c740482bbd48fb39d76a70dfd4bd59db1288021743503259e948f6b1a18";

    #[test]
    fn tokens_and_keys_are_rmw_zenohs() {
        // The worked example of rmw_zenoh's design: the demo talker on domain 0.
        let zid = "fedcba9876543210efcdab8967452301";
        assert_eq!(
            node_token(0, zid, 0, "talker"),
            "@ros2_lv/0/fedcba9876543210efcdab8967452301/0/0/NN/%/%/talker"
        );
        let dds = dds_type_name("std_msgs/msg/String").unwrap();
        assert_eq!(dds, "std_msgs::msg::dds_::String_");
        let mp = entity_token(
            0,
            zid,
            0,
            1,
            Kind::Publisher,
            "talker",
            "/chatter",
            &dds,
            HASH,
        );
        assert_eq!(
            mp,
            format!(
                "@ros2_lv/0/fedcba9876543210efcdab8967452301/0/1/MP/%/%/talker/%chatter/std_msgs::msg::dds_::String_/{HASH}/::,10:,:,:,,"
            )
        );
        assert_eq!(
            data_key(0, "/chatter", &dds, HASH),
            format!("0/chatter/std_msgs::msg::dds_::String_/{HASH}")
        );
        assert_eq!(
            data_key(3, "/vision/ball", &dds, HASH),
            format!("3/vision/ball/std_msgs::msg::dds_::String_/{HASH}")
        );
        let e = parse_entity(&mp).unwrap();
        assert_eq!(e.topic, "/chatter");
        assert_eq!(e.kind, Kind::Publisher);
        assert_eq!(e.node, "talker");
        assert_eq!(e.hash, HASH);
        assert_eq!(ros_type_name(&e.dds_type).unwrap(), "std_msgs/msg/String");
        // Nodes, services, short or empty-part tokens are not entities.
        assert!(parse_entity(&node_token(0, zid, 0, "talker")).is_none());
        assert!(parse_entity(&mp.replace("/MP/", "/SS/")).is_none());
        assert!(parse_entity(&mp.replace("/%/%/", "//%/")).is_none());
        assert!(parse_entity("@ros2_lv/x/y").is_none());
    }

    #[test]
    fn names_ros_2_cannot_take_are_refused() {
        assert_eq!(ros_topic("vision/ball").unwrap(), "/vision/ball");
        assert!(ros_topic("audio-in").is_none());
        assert!(ros_topic("3d/points").is_none());
        assert!(ros_type_name("std_msgs::msg::String").is_none());
        assert!(dds_type_name("robocog.Text").is_none());
    }
}
