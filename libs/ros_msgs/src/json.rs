//! A message as a ROS 2 decoder reads it, as JSON: robocog's value serialized the way CDR sees it
//! (serde's `is_human_readable()` false), so the wire forms of [`interfaces::msg::ros`] apply
//! (`std_msgs/Header` with `stamp.sec` and `stamp.nanosec`, `geometry_msgs/Point` with `x`, `y`,
//! `z`, tagged unions with their `kind`), enums are their integer values, byte blocks arrays of
//! numbers. `robocog topic echo --ros` prints it; the tests compare it with what ROS 2's decoders
//! make of the same payload.

use serde::Serialize;
use serde::ser::{self, Impossible};
use serde_json::{Map, Value};

/// Why a value has no ROS 2 view (a form CDR messages of robocog never use).
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Error(String);

impl ser::Error for Error {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        Error(msg.to_string())
    }
}

/// `value` as a ROS 2 decoder reads it.
pub fn to_value<T: Serialize + ?Sized>(value: &T) -> Result<Value, Error> {
    value.serialize(Wire)
}

struct Wire;

/// A sequence, tuple or struct being built.
pub struct Compound {
    items: Vec<Value>,
    fields: Map<String, Value>,
}

impl Compound {
    fn new() -> Self {
        Compound {
            items: Vec::new(),
            fields: Map::new(),
        }
    }
}

macro_rules! number {
    ($($method:ident: $t:ty),*) => {
        $(fn $method(self, v: $t) -> Result<Value, Error> {
            Ok(Value::from(v))
        })*
    };
}

impl ser::Serializer for Wire {
    type Ok = Value;
    type Error = Error;
    type SerializeSeq = Compound;
    type SerializeTuple = Compound;
    type SerializeTupleStruct = Compound;
    type SerializeTupleVariant = Impossible<Value, Error>;
    type SerializeMap = Impossible<Value, Error>;
    type SerializeStruct = Compound;
    type SerializeStructVariant = Impossible<Value, Error>;

    fn is_human_readable(&self) -> bool {
        false
    }

    number!(serialize_bool: bool, serialize_i8: i8, serialize_i16: i16, serialize_i32: i32,
        serialize_i64: i64, serialize_u8: u8, serialize_u16: u16, serialize_u32: u32,
        serialize_u64: u64, serialize_f32: f32, serialize_f64: f64, serialize_str: &str);

    fn serialize_char(self, v: char) -> Result<Value, Error> {
        Ok(Value::from(v.to_string()))
    }
    fn serialize_bytes(self, v: &[u8]) -> Result<Value, Error> {
        Ok(Value::Array(v.iter().map(|b| Value::from(*b)).collect()))
    }
    fn serialize_none(self) -> Result<Value, Error> {
        Err(Error("an Option (CDR messages have none)".into()))
    }
    fn serialize_some<T: Serialize + ?Sized>(self, _: &T) -> Result<Value, Error> {
        Err(Error("an Option (CDR messages have none)".into()))
    }
    fn serialize_unit(self) -> Result<Value, Error> {
        Ok(Value::Null)
    }
    fn serialize_unit_struct(self, _: &'static str) -> Result<Value, Error> {
        Ok(Value::Null)
    }
    fn serialize_unit_variant(
        self,
        _: &'static str,
        index: u32,
        _: &'static str,
    ) -> Result<Value, Error> {
        Ok(Value::from(index))
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _: &'static str,
        v: &T,
    ) -> Result<Value, Error> {
        v.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        name: &'static str,
        _: u32,
        variant: &'static str,
        _: &T,
    ) -> Result<Value, Error> {
        Err(Error(format!(
            "{name}::{variant} carries data (a tagged union with no wire form)"
        )))
    }
    fn serialize_seq(self, _: Option<usize>) -> Result<Compound, Error> {
        Ok(Compound::new())
    }
    fn serialize_tuple(self, _: usize) -> Result<Compound, Error> {
        Ok(Compound::new())
    }
    fn serialize_tuple_struct(self, _: &'static str, _: usize) -> Result<Compound, Error> {
        Ok(Compound::new())
    }
    fn serialize_tuple_variant(
        self,
        name: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Self::SerializeTupleVariant, Error> {
        Err(Error(format!(
            "{name}::{variant} carries data (a tagged union with no wire form)"
        )))
    }
    fn serialize_map(self, _: Option<usize>) -> Result<Self::SerializeMap, Error> {
        Err(Error("a map (CDR messages have none)".into()))
    }
    fn serialize_struct(self, _: &'static str, _: usize) -> Result<Compound, Error> {
        Ok(Compound::new())
    }
    fn serialize_struct_variant(
        self,
        name: &'static str,
        _: u32,
        variant: &'static str,
        _: usize,
    ) -> Result<Self::SerializeStructVariant, Error> {
        Err(Error(format!(
            "{name}::{variant} carries data (a tagged union with no wire form)"
        )))
    }
}

impl ser::SerializeSeq for Compound {
    type Ok = Value;
    type Error = Error;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        self.items.push(v.serialize(Wire)?);
        Ok(())
    }
    fn end(self) -> Result<Value, Error> {
        Ok(Value::Array(self.items))
    }
}

impl ser::SerializeTuple for Compound {
    type Ok = Value;
    type Error = Error;
    fn serialize_element<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        ser::SerializeSeq::serialize_element(self, v)
    }
    fn end(self) -> Result<Value, Error> {
        ser::SerializeSeq::end(self)
    }
}

impl ser::SerializeTupleStruct for Compound {
    type Ok = Value;
    type Error = Error;
    fn serialize_field<T: Serialize + ?Sized>(&mut self, v: &T) -> Result<(), Error> {
        ser::SerializeSeq::serialize_element(self, v)
    }
    fn end(self) -> Result<Value, Error> {
        ser::SerializeSeq::end(self)
    }
}

impl ser::SerializeStruct for Compound {
    type Ok = Value;
    type Error = Error;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        v: &T,
    ) -> Result<(), Error> {
        self.fields.insert(key.to_string(), v.serialize(Wire)?);
        Ok(())
    }
    fn end(self) -> Result<Value, Error> {
        Ok(Value::Object(self.fields))
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use interfaces::msg::dr::{AttrValue, Attribute};
    use interfaces::msg::tracking::BallTrack;

    #[test]
    fn the_ros_view_shows_the_wire_forms() {
        let mut t = BallTrack::default();
        t.header.stamp_ns = 1_500_000_000;
        t.header.seq = 9;
        t.centre_world_m = [1.0, 2.0, 3.0];
        let v = to_value(&t).unwrap();
        assert_eq!(
            v["header"]["stamp"],
            serde_json::json!({"sec": 1, "nanosec": 500_000_000})
        );
        assert!(v["header"].get("seq").is_none(), "{v}");
        assert_eq!(
            v["centre_world_m"],
            serde_json::json!({"x": 1.0, "y": 2.0, "z": 3.0})
        );
        assert!(v["state"].is_u64(), "{v}");
        let a = Attribute {
            node: "ball".into(),
            key: "radius_m".into(),
            value: AttrValue::Float(0.1),
        };
        let v = to_value(&a).unwrap();
        assert_eq!(v["value"]["kind"], 2);
        assert_eq!(v["value"]["float_value"], 0.1);
    }
}
