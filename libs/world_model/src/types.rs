//! The library's vocabulary: stamps, node types and well-known attribute keys; and the deep
//! representation's data types, which are the bus' own (`interfaces::msg::dr`, re-exported
//! here): transforms, attribute values, node descriptions, structural changes, change events,
//! snapshots. One definition serves the library, the service, the wire and the state folder
//! (their JSON form, [`crate::persist`]).
//!
//! Units: metres and radians; time as [`Stamp`] (u64 nanoseconds on the caller's clock), which
//! the data types carry as `stamp_ns`.

pub use interfaces::msg::dr::{
    AttrValue, BodyPart, Camera, CameraIntrinsics, ChangeEvent, CollisionShape, Edge, JointKind,
    JointLimits, KeyValue, NodeSpec, Shape, Snapshot, StructuralChange, Transform,
};
pub use robot_model::TransformIso;
use serde::{Deserialize, Serialize};

/// A time stamp: nanoseconds on the caller's clock (wall, monotonic or a replay's virtual clock;
/// the library never reads a clock itself).
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default, Serialize, Deserialize,
)]
#[serde(transparent)]
pub struct Stamp(pub u64);

impl Stamp {
    /// From seconds (f64); negative or NaN give 0, values past u64 saturate.
    pub fn from_secs_f64(s: f64) -> Self {
        Stamp((s * 1e9).round().max(0.0) as u64)
    }
    /// As seconds.
    pub fn as_secs_f64(self) -> f64 {
        self.0 as f64 * 1e-9
    }
}

/// Well-known attribute keys.
pub mod attr {
    /// `Float`, metres: radius of a ball or object, of a goalpost.
    pub const RADIUS_M: &str = "radius_m";
    /// `Int`: team number of an agent (robots of the same team share it).
    pub const TEAM: &str = "team";
    /// `Bool`: a robot reported as fallen by its own state estimation.
    pub const FALLEN: &str = "fallen";
    /// `Bool`: a link that is an end effector (a hand), used by `near`.
    pub const EFFECTOR: &str = "effector";
    /// `Text`: colour name of an object (`yellow`).
    pub const COLOR: &str = "color";
    /// `Float`, metres: field length / width on a `field` node.
    pub const LENGTH_M: &str = "length_m";
    /// See [`LENGTH_M`].
    pub const WIDTH_M: &str = "width_m";
}

/// The type of a node. Its snake_case name is what proposals and snapshots carry.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum NodeType {
    /// The root frame; exactly one, named `world`.
    World,
    /// A plain frame (no physical extent).
    Frame,
    /// A robot link (from URDF).
    Link,
    /// A camera sensor with intrinsics; its frame is an optical frame.
    Camera,
    /// A ball.
    Ball,
    /// Any other physical object.
    Object,
    /// A human agent (the player, the coach).
    Human,
    /// A robot agent (Loki, a Nao); its frame is the robot's base pose.
    Robot,
    /// The playing field; its frame is the field frame (centre spot, x towards the opponent goal).
    Field,
    /// A goalpost landmark.
    Goalpost,
    /// Any other landmark (spots, penalty marks).
    Landmark,
}

impl AsRef<str> for NodeType {
    fn as_ref(&self) -> &str {
        self.name()
    }
}

impl NodeType {
    /// All types, for listing the known names.
    pub const ALL: [NodeType; 11] = [
        NodeType::World,
        NodeType::Frame,
        NodeType::Link,
        NodeType::Camera,
        NodeType::Ball,
        NodeType::Object,
        NodeType::Human,
        NodeType::Robot,
        NodeType::Field,
        NodeType::Goalpost,
        NodeType::Landmark,
    ];

    /// The snake_case name.
    pub fn name(self) -> &'static str {
        match self {
            NodeType::World => "world",
            NodeType::Frame => "frame",
            NodeType::Link => "link",
            NodeType::Camera => "camera",
            NodeType::Ball => "ball",
            NodeType::Object => "object",
            NodeType::Human => "human",
            NodeType::Robot => "robot",
            NodeType::Field => "field",
            NodeType::Goalpost => "goalpost",
            NodeType::Landmark => "landmark",
        }
    }

    /// Parses a snake_case name.
    pub fn from_name(name: &str) -> Option<NodeType> {
        Self::ALL.into_iter().find(|t| t.name() == name)
    }

    /// Balls and objects: things that can be seen, reached and touched.
    pub fn is_item(self) -> bool {
        matches!(self, NodeType::Ball | NodeType::Object)
    }
    /// Humans and robots.
    pub fn is_agent(self) -> bool {
        matches!(self, NodeType::Human | NodeType::Robot)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stamps_convert_from_seconds() {
        assert_eq!(Stamp::from_secs_f64(1.5), Stamp(1_500_000_000));
        assert_eq!(Stamp::from_secs_f64(-3.0), Stamp(0));
        assert_eq!(Stamp::from_secs_f64(f64::NAN), Stamp(0));
        assert_eq!(Stamp(2_250_000_000).as_secs_f64(), 2.25);
    }

    #[test]
    fn transforms_round_trip_through_isometries_and_validate() {
        use nalgebra::{Isometry3, Vector3};
        let iso = Isometry3::new(Vector3::new(1.0, -2.0, 0.5), Vector3::new(0.1, 0.2, -0.3));
        let back = Transform::from_iso(&iso).to_iso();
        assert!((back.to_homogeneous() - iso.to_homogeneous()).abs().max() < 1e-15);
        assert!(
            !Transform {
                rotation_xyzw: [0.0; 4],
                ..Transform::default()
            }
            .is_valid()
        );
        assert!(!Transform::from_translation(f64::INFINITY, 0.0, 0.0).is_valid());
        let p = Transform::planar(1.0, 2.0, std::f64::consts::FRAC_PI_2).to_iso();
        assert!((p.rotation * Vector3::x() - Vector3::y()).norm() < 1e-15);
    }

    #[test]
    fn node_types_have_one_name_each() {
        for t in NodeType::ALL {
            assert_eq!(NodeType::from_name(t.name()), Some(t));
        }
        assert_eq!(NodeType::from_name("unicorn"), None);
    }
}
