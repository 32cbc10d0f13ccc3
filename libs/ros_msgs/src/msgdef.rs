//! ROS 2 message definitions (`.msg`) written from the shapes of [`crate::probe`].
//!
//! The mapping, chosen so that a ROS 2 CDR decoder reading our payloads with these definitions
//! reads exactly our bytes:
//! - `bool`, `i8`..`i64`, `u8`..`u64`, `f32`, `f64`, `String` become `bool`, `int8`..`int64`,
//!   `uint8`..`uint64`, `float32`, `float64`, `string`;
//! - byte blocks and `Vec<T>` become `uint8[]` and `T[]`, `[T; N]` becomes `T[N]`;
//! - a struct becomes a message of the `robocog_msgs` package, named as the Rust type, unless its
//!   serde name is a full ROS 2 name (`std_msgs/msg/Header`): then it is that standard message
//!   (`interfaces::msg::ros` has them), whose definition must be ROS 2's own;
//! - an enum whose variants carry nothing becomes `uint32` (serde writes the variant's index),
//!   with one integer constant per variant (`BALL_TRACK_STATE_LOST=0`) in each message using it.
//!
//! What ROS 2 messages cannot say is refused, with the reason: an enum whose variants carry data
//! (a tagged union: its layout depends on the variant), a sequence of sequences, an empty struct
//! (ROS 2 gives empty messages a hidden member that is on the wire), anything recursive, and the
//! few serde forms CDR messages of this project never use.

use crate::probe::{Catalog, Container, Shape, Variant};
use std::collections::BTreeMap;

/// The package every robocog message lives in.
pub const PACKAGE: &str = "robocog_msgs";

/// The full ROS 2 name of a message known by its serde name: `JointStates` is
/// `robocog_msgs/msg/JointStates`, `std_msgs/msg/Header` is itself.
pub fn full_name(name: &str) -> String {
    if name.contains('/') {
        name.to_string()
    } else {
        format!("{PACKAGE}/msg/{name}")
    }
}

/// How a `.msg` file refers to a message: `robocog_msgs/JointStates`, `std_msgs/Header`.
pub fn reference(name: &str) -> String {
    full_name(name).replacen("/msg/", "/", 1)
}

/// The package of a message known by its serde name.
pub fn package_of(name: &str) -> &str {
    name.split_once('/').map_or(PACKAGE, |(p, _)| p)
}

/// One message definition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MsgDef {
    /// The message's serde name: the Rust type's (`JointStates`, of `robocog_msgs`), or a
    /// standard message's full name (`std_msgs/msg/Header`).
    pub name: String,
    /// The `.msg` text.
    pub text: String,
    /// Its fields, in order.
    pub fields: Vec<Field>,
    /// The messages it uses directly, by name.
    pub uses: Vec<String>,
}

/// One field of a message.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Field {
    pub name: String,
    pub base: Base,
    pub array: Array,
}

/// The type of a field's values.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Base {
    /// A primitive, by its `.msg` name (`uint32`, `string`, ...).
    Primitive(&'static str),
    /// Another message, by its serde name (see [`MsgDef::name`]).
    Nested(String),
}

/// Whether a field holds one value, a fixed number, or a sequence.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Array {
    Single,
    Fixed(usize),
    Unbounded,
}

impl Field {
    /// The field's type as a `.msg` file writes it (`std_msgs/Header`, `robocog_msgs/Edge`, `float64[3]`).
    pub fn type_text(&self) -> String {
        let base = match &self.base {
            Base::Primitive(p) => p.to_string(),
            Base::Nested(n) => reference(n),
        };
        match self.array {
            Array::Single => base,
            Array::Fixed(n) => format!("{base}[{n}]"),
            Array::Unbounded => format!("{base}[]"),
        }
    }
}

/// Turns the shapes of a catalog into definitions, remembering each answer.
pub struct Writer<'a> {
    catalog: &'a Catalog,
    done: BTreeMap<String, Result<MsgDef, String>>,
    walking: Vec<String>,
}

impl<'a> Writer<'a> {
    pub fn new(catalog: &'a Catalog) -> Self {
        Writer {
            catalog,
            done: BTreeMap::new(),
            walking: Vec::new(),
        }
    }

    /// Every definition written so far (each type asked for, and what it uses).
    pub fn into_done(self) -> BTreeMap<String, Result<MsgDef, String>> {
        self.done
    }

    /// The definition of struct `name`, or why it has none.
    pub fn message(&mut self, name: &str) -> Result<MsgDef, String> {
        if let Some(d) = self.done.get(name) {
            return d.clone();
        }
        if self.walking.iter().any(|n| n == name) {
            return Err(format!("{name} contains itself (ROS 2 messages cannot)"));
        }
        self.walking.push(name.to_string());
        let result = self.write(name);
        self.walking.pop();
        self.done.insert(name.to_string(), result.clone());
        result
    }

    fn write(&mut self, name: &str) -> Result<MsgDef, String> {
        if !is_message_name(name) {
            return Err(format!("{name} is not a ROS 2 message name"));
        }
        let fields = match self.catalog.types.get(name) {
            Some(Container::Struct(fields)) => fields,
            Some(Container::Newtype(_)) => {
                return Err(format!("{name} is a newtype, not a message"));
            }
            Some(Container::Enum(_)) => return Err(format!("{name} is an enum, not a message")),
            None => return Err(format!("{name} was never described")),
        };
        if fields.is_empty() {
            return Err(format!(
                "{name} has no fields (ROS 2 gives an empty message a hidden member on the wire)"
            ));
        }
        let mut constants: Vec<String> = Vec::new();
        let mut lines: Vec<String> = Vec::new();
        let mut uses: Vec<String> = Vec::new();
        let mut described = Vec::new();
        for (field, shape) in fields {
            if !is_field_name(field) {
                return Err(format!(
                    "{name}.{field} is not a ROS 2 field name (lowercase, digits, single underscores)"
                ));
            }
            let (base, array) = self
                .field_type(shape, &mut constants, &mut uses)
                .map_err(|why| format!("{name}.{field}: {why}"))?;
            let f = Field {
                name: field.clone(),
                base,
                array,
            };
            lines.push(format!("{} {field}", f.type_text()));
            described.push(f);
        }
        let mut text = String::new();
        for c in &constants {
            text.push_str(c);
            text.push('\n');
        }
        if !constants.is_empty() {
            text.push('\n');
        }
        for l in &lines {
            text.push_str(l);
            text.push('\n');
        }
        Ok(MsgDef {
            name: name.to_string(),
            text,
            fields: described,
            uses,
        })
    }

    /// The ROS 2 type of a field of this shape; constants of enums it uses are added once.
    fn field_type(
        &mut self,
        shape: &Shape,
        constants: &mut Vec<String>,
        uses: &mut Vec<String>,
    ) -> Result<(Base, Array), String> {
        Ok(match shape {
            Shape::Seq(inner) => (self.element_type(inner, constants, uses)?, Array::Unbounded),
            Shape::Array(inner, n) => {
                (self.element_type(inner, constants, uses)?, Array::Fixed(*n))
            }
            Shape::Bytes => (Base::Primitive("uint8"), Array::Unbounded),
            Shape::Named(n) => match self.catalog.types.get(n) {
                // A newtype is its field, arrays included.
                Some(Container::Newtype(inner)) => {
                    let inner = inner.clone();
                    self.field_type(&inner, constants, uses)?
                }
                _ => (self.element_type(shape, constants, uses)?, Array::Single),
            },
            other => (self.element_type(other, constants, uses)?, Array::Single),
        })
    }

    /// The ROS 2 type of one value (no sequences: ROS 2 has no sequence of sequences).
    fn element_type(
        &mut self,
        shape: &Shape,
        constants: &mut Vec<String>,
        uses: &mut Vec<String>,
    ) -> Result<Base, String> {
        Ok(match shape {
            Shape::Bool => Base::Primitive("bool"),
            Shape::I8 => Base::Primitive("int8"),
            Shape::I16 => Base::Primitive("int16"),
            Shape::I32 => Base::Primitive("int32"),
            Shape::I64 => Base::Primitive("int64"),
            Shape::U8 => Base::Primitive("uint8"),
            Shape::U16 => Base::Primitive("uint16"),
            Shape::U32 => Base::Primitive("uint32"),
            Shape::U64 => Base::Primitive("uint64"),
            Shape::F32 => Base::Primitive("float32"),
            Shape::F64 => Base::Primitive("float64"),
            Shape::Str => Base::Primitive("string"),
            Shape::Bytes | Shape::Seq(_) | Shape::Array(..) => {
                return Err(
                    "a sequence of sequences (ROS 2 needs a message around the inner one)".into(),
                );
            }
            Shape::Unsupported(what) => return Err(format!("uses {what}")),
            Shape::Named(n) => match self.catalog.types.get(n) {
                Some(Container::Newtype(inner)) => {
                    let inner = inner.clone();
                    return match self.field_type(&inner, constants, uses)? {
                        (base, Array::Single) => Ok(base),
                        _ => Err(format!(
                            "{n} wraps a sequence, inside a sequence (ROS 2 needs a message around the inner one)"
                        )),
                    };
                }
                Some(Container::Enum(variants)) => {
                    let mut names = Vec::new();
                    for (v, seen) in variants {
                        match seen {
                            Some(Variant::Unit) => names.push(v.clone()),
                            Some(Variant::Fields(_)) => {
                                return Err(format!(
                                    "enum {n} carries data in variant {v} (a tagged union, which no ROS 2 message describes)"
                                ));
                            }
                            None => return Err(format!("enum {n}: variant {v} never described")),
                        }
                    }
                    let prefix = upper_snake(n);
                    for (i, v) in names.iter().enumerate() {
                        let c = format!("uint32 {prefix}_{}={i}", upper_snake(v));
                        if !constants.contains(&c) {
                            constants.push(c);
                        }
                    }
                    Base::Primitive("uint32")
                }
                Some(Container::Struct(_)) => {
                    self.message(n)?;
                    if !uses.contains(n) {
                        uses.push(n.clone());
                    }
                    Base::Nested(n.clone())
                }
                None => return Err(format!("{n} was never described")),
            },
        })
    }
}

/// `BallTrackState` -> `BALL_TRACK_STATE`.
pub fn upper_snake(camel: &str) -> String {
    let mut out = String::new();
    let chars: Vec<char> = camel.chars().collect();
    for (i, &c) in chars.iter().enumerate() {
        if c.is_uppercase() && i > 0 {
            let prev = chars[i - 1];
            let next_lower = chars.get(i + 1).is_some_and(|n| n.is_lowercase());
            if prev.is_lowercase() || prev.is_ascii_digit() || (prev.is_uppercase() && next_lower) {
                out.push('_');
            }
        }
        out.extend(c.to_uppercase());
    }
    out
}

/// A ROS 2 message name: an uppercase letter, then letters and digits; or a full name,
/// `package/msg/Name`.
fn is_message_name(s: &str) -> bool {
    if let Some((package, rest)) = s.split_once("/msg/") {
        return is_field_name(package) && is_message_name(rest);
    }
    let mut c = s.chars();
    c.next().is_some_and(|f| f.is_ascii_uppercase()) && c.all(|x| x.is_ascii_alphanumeric())
}

/// A ROS 2 field name: a lowercase letter, then lowercase letters, digits and single
/// underscores, not ending in one.
fn is_field_name(s: &str) -> bool {
    let mut c = s.chars();
    c.next().is_some_and(|f| f.is_ascii_lowercase())
        && s.chars()
            .all(|x| x.is_ascii_lowercase() || x.is_ascii_digit() || x == '_')
        && !s.contains("__")
        && !s.ends_with('_')
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use crate::probe;
    use serde::Deserialize;
    use serde::de::DeserializeOwned;

    /// Why `T` has no definition.
    fn refusal<T: DeserializeOwned>() -> String {
        let mut catalog = Catalog::default();
        match probe::describe::<T>(&mut catalog) {
            Ok(Shape::Named(n)) => Writer::new(&catalog).message(&n).unwrap_err(),
            Ok(other) => panic!("not a struct: {other:?}"),
            Err(e) => e.to_string(),
        }
    }

    #[allow(dead_code)]
    #[derive(Deserialize)]
    enum Union {
        A(u8),
        B,
    }
    #[allow(dead_code)]
    #[derive(Deserialize)]
    struct WithUnion {
        u: Union,
    }
    #[allow(dead_code)]
    #[derive(Deserialize)]
    struct SeqOfSeq {
        v: Vec<Vec<f32>>,
    }
    #[derive(Deserialize)]
    struct Empty {}
    #[allow(dead_code)]
    #[derive(Deserialize)]
    struct Tree {
        x: u8,
        children: Vec<Tree>,
    }
    #[allow(dead_code)]
    #[derive(Deserialize)]
    struct WithOption {
        o: Option<u8>,
    }

    #[test]
    fn what_ros2_cannot_say_is_refused_with_the_reason() {
        let why = refusal::<WithUnion>();
        assert!(
            why.contains("tagged union") && why.contains("WithUnion.u"),
            "{why}"
        );
        let why = refusal::<SeqOfSeq>();
        assert!(why.contains("sequence of sequences"), "{why}");
        let why = refusal::<Empty>();
        assert!(why.contains("no fields"), "{why}");
        let why = refusal::<Tree>();
        assert!(why.contains("contains itself"), "{why}");
        let why = refusal::<WithOption>();
        assert!(why.to_lowercase().contains("option"), "{why}");
    }

    #[test]
    fn names() {
        assert_eq!(upper_snake("BallTrackState"), "BALL_TRACK_STATE");
        assert_eq!(upper_snake("Lost"), "LOST");
        assert_eq!(upper_snake("RGBDFrame"), "RGBD_FRAME");
        assert_eq!(upper_snake("Vec3"), "VEC3");
        assert!(is_field_name("stamp_ns"));
        assert!(!is_field_name("_0"));
        assert!(!is_field_name("a__b"));
        assert!(!is_field_name("Stamp"));
        assert!(is_message_name("JointStates"));
        assert!(is_message_name("std_msgs/msg/Header"));
        assert!(!is_message_name("std_msgs/Header"));
        assert_eq!(reference("std_msgs/msg/Header"), "std_msgs/Header");
        assert_eq!(reference("Text"), "robocog_msgs/Text");
        assert_eq!(full_name("Text"), "robocog_msgs/msg/Text");
        assert_eq!(package_of("geometry_msgs/msg/Point"), "geometry_msgs");
        assert!(!is_message_name("joint_states"));
    }
}
