//! ROS 2's standard types, as robocog's payloads carry them.
//!
//! Robocog's Rust types stay as they are (`[f64; 3]` positions, `stamp_ns`, enums with data);
//! what goes on the wire is what ROS 2 would send, so a ROS 2 tool reads our payloads with ROS 2's
//! own definitions:
//! - [`crate::Header`] is a `std_msgs/Header` (its `stamp_ns` as a `builtin_interfaces/Time`; its
//!   sequence number travels beside the payload, in the sample's attachment, as rmw_zenoh does);
//! - the camera's frames hold a `sensor_msgs/CameraInfo` and two `sensor_msgs/Image`s, joint
//!   states a `sensor_msgs/JointState`;
//! - points, vectors and quaternions are `geometry_msgs/Point`, `Vector3` and `Quaternion`
//!   (field attributes [`point`], [`vector3`], [`quaternion`]), and the DR's transforms are
//!   `geometry_msgs/Transform`;
//! - an enum carrying data (a tagged union, which ROS 2 has not) is a message with a `kind` and
//!   the fields of every variant ([`wire_form!`]).
//!
//! Only CDR sees these forms: serde's `is_human_readable()` is false there. JSON (`robocog topic
//! echo`, `robocog service call`, the DR's state files) keeps robocog's own, readable form.
//!
//! The structs here are named by their ROS 2 name (`std_msgs/msg/Header`), which is how
//! `ros_msgs` knows them for standard types and writes their definitions; its tests check those
//! against ROS 2's (the type hashes of `rosbags`' Jazzy type store).

use serde::{Deserialize, Serialize};

/// `builtin_interfaces/Time`: seconds and nanoseconds since the Unix epoch.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename = "builtin_interfaces/msg/Time")]
pub struct Time {
    pub sec: i32,
    pub nanosec: u32,
}

impl Time {
    /// `ns` since the epoch, split as ROS 2 does (`nanosec` in 0..1e9, also before 1970). Times
    /// past what `int32` seconds hold (2038-01-19) saturate.
    pub fn from_ns(ns: i64) -> Time {
        let sec = ns.div_euclid(1_000_000_000);
        let nanosec = ns.rem_euclid(1_000_000_000) as u32;
        match i32::try_from(sec) {
            Ok(sec) => Time { sec, nanosec },
            Err(_) if sec > 0 => Time {
                sec: i32::MAX,
                nanosec: 999_999_999,
            },
            Err(_) => Time {
                sec: i32::MIN,
                nanosec: 0,
            },
        }
    }

    /// The time in nanoseconds since the epoch; `None` for a `nanosec` of a second or more.
    pub fn to_ns(self) -> Option<i64> {
        (self.nanosec < 1_000_000_000)
            .then(|| i64::from(self.sec) * 1_000_000_000 + i64::from(self.nanosec))
    }
}

/// `std_msgs/Header`, as robocog's [`crate::Header`] goes on the wire.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "std_msgs/msg/Header")]
pub struct StdHeader<S> {
    pub stamp: Time,
    pub frame_id: S,
}

/// `geometry_msgs/Point` (m).
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "geometry_msgs/msg/Point")]
pub struct Point {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/Vector3`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "geometry_msgs/msg/Vector3")]
pub struct Vector3 {
    pub x: f64,
    pub y: f64,
    pub z: f64,
}

/// `geometry_msgs/Quaternion`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename = "geometry_msgs/msg/Quaternion")]
pub struct Quaternion {
    pub x: f64,
    pub y: f64,
    pub z: f64,
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        }
    }
}

/// `geometry_msgs/Transform`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "geometry_msgs/msg/Transform")]
pub struct Transform {
    pub translation: Vector3,
    pub rotation: Quaternion,
}

/// `sensor_msgs/RegionOfInterest`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "sensor_msgs/msg/RegionOfInterest")]
pub struct RegionOfInterest {
    pub x_offset: u32,
    pub y_offset: u32,
    pub height: u32,
    pub width: u32,
    pub do_rectify: bool,
}

/// `sensor_msgs/CameraInfo`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "sensor_msgs/msg/CameraInfo")]
pub struct CameraInfo {
    pub header: crate::Header,
    pub height: u32,
    pub width: u32,
    pub distortion_model: String,
    pub d: Vec<f64>,
    pub k: [f64; 9],
    pub r: [f64; 9],
    pub p: [f64; 12],
    pub binning_x: u32,
    pub binning_y: u32,
    pub roi: RegionOfInterest,
}

impl CameraInfo {
    /// A distortion-free pinhole camera: `plumb_bob` with zero coefficients, `R` the identity.
    pub fn pinhole(
        header: crate::Header,
        width: u32,
        height: u32,
        [fx, fy, cx, cy]: [f64; 4],
    ) -> Self {
        CameraInfo {
            header,
            height,
            width,
            distortion_model: "plumb_bob".into(),
            d: vec![0.0; 5],
            k: [fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0],
            r: [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0],
            p: [fx, 0.0, cx, 0.0, 0.0, fy, cy, 0.0, 0.0, 0.0, 1.0, 0.0],
            binning_x: 0,
            binning_y: 0,
            roi: RegionOfInterest::default(),
        }
    }

    /// `[fx, fy, cx, cy]` of `K`.
    pub fn focal_and_centre(&self) -> [f64; 4] {
        [self.k[0], self.k[4], self.k[2], self.k[5]]
    }
}

/// `sensor_msgs/Image`, its pixels borrowed (from the payload when decoded, from the owner's
/// buffers when encoded).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "sensor_msgs/msg/Image")]
pub struct Image<'a> {
    pub header: crate::Header,
    pub height: u32,
    pub width: u32,
    #[serde(borrow)]
    pub encoding: &'a str,
    pub is_bigendian: u8,
    pub step: u32,
    #[serde(borrow, with = "serde_bytes")]
    pub data: &'a [u8],
}

/// `sensor_msgs/JointState`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(rename = "sensor_msgs/msg/JointState")]
pub struct JointState {
    pub header: crate::Header,
    pub name: Vec<String>,
    pub position: Vec<f64>,
    pub velocity: Vec<f64>,
    pub effort: Vec<f64>,
}

impl From<[f64; 3]> for Point {
    fn from([x, y, z]: [f64; 3]) -> Self {
        Point { x, y, z }
    }
}
impl From<Point> for [f64; 3] {
    fn from(p: Point) -> Self {
        [p.x, p.y, p.z]
    }
}
impl From<[f64; 3]> for Vector3 {
    fn from([x, y, z]: [f64; 3]) -> Self {
        Vector3 { x, y, z }
    }
}
impl From<Vector3> for [f64; 3] {
    fn from(v: Vector3) -> Self {
        [v.x, v.y, v.z]
    }
}
impl From<[f64; 4]> for Quaternion {
    fn from([x, y, z, w]: [f64; 4]) -> Self {
        Quaternion { x, y, z, w }
    }
}
impl From<Quaternion> for [f64; 4] {
    fn from(q: Quaternion) -> Self {
        [q.x, q.y, q.z, q.w]
    }
}

/// Field attributes for arrays that are a standard geometry type on the wire and stay an array
/// in JSON: `#[serde(with = "crate::msg::ros::point")] position_m: [f64; 3]`.
macro_rules! array_as {
    ($(#[$doc:meta])* $module:ident, $array:ty, $wire:ty) => {
        $(#[$doc])*
        pub mod $module {
            use serde::{Deserialize, Deserializer, Serialize, Serializer};

            pub fn serialize<S: Serializer>(v: &$array, s: S) -> Result<S::Ok, S::Error> {
                if s.is_human_readable() {
                    v.serialize(s)
                } else {
                    <$wire>::from(*v).serialize(s)
                }
            }

            pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<$array, D::Error> {
                if d.is_human_readable() {
                    <$array>::deserialize(d)
                } else {
                    <$wire>::deserialize(d).map(<$array>::from)
                }
            }
        }
    };
}

array_as!(
    /// `[x, y, z]` (m) as a `geometry_msgs/Point`.
    point,
    [f64; 3],
    super::Point
);
array_as!(
    /// `[x, y, z]` as a `geometry_msgs/Vector3`.
    vector3,
    [f64; 3],
    super::Vector3
);
array_as!(
    /// `[x, y, z, w]` as a `geometry_msgs/Quaternion`.
    quaternion,
    [f64; 4],
    super::Quaternion
);

/// Gives a type another form on the wire (CDR) than in JSON. The type derives its serde impls
/// with `#[serde(remote = "Self")]`, which JSON keeps; on the wire it goes as `$wire`, made with
/// `From<&$ty>` and read back with `TryFrom<$wire>` (whose error is a decoding error).
#[macro_export]
macro_rules! wire_form {
    ($ty:ty, $wire:ty) => {
        impl serde::Serialize for $ty {
            fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
                if s.is_human_readable() {
                    <$ty>::serialize(self, s)
                } else {
                    serde::Serialize::serialize(&<$wire>::from(self), s)
                }
            }
        }
        impl<'de> serde::Deserialize<'de> for $ty {
            fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
                if d.is_human_readable() {
                    <$ty>::deserialize(d)
                } else {
                    let wire = <$wire as serde::Deserialize>::deserialize(d)?;
                    <$ty>::try_from(wire).map_err(serde::de::Error::custom)
                }
            }
        }
    };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn times_split_as_ros2_does() {
        for ns in [
            0,
            1,
            999_999_999,
            1_000_000_000,
            1_700_000_000_123_456_789,
            -1,
            -1_500_000_000,
        ] {
            let t = Time::from_ns(ns);
            assert!(t.nanosec < 1_000_000_000);
            assert_eq!(t.to_ns(), Some(ns), "{ns}");
        }
        assert_eq!(
            Time::from_ns(-1),
            Time {
                sec: -1,
                nanosec: 999_999_999
            }
        );
        assert_eq!(Time::from_ns(i64::MAX).sec, i32::MAX);
        assert_eq!(Time::from_ns(i64::MIN).sec, i32::MIN);
        assert_eq!(
            Time {
                sec: 0,
                nanosec: 1_000_000_000
            }
            .to_ns(),
            None
        );
    }
}
