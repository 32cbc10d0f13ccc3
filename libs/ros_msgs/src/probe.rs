//! What a message type looks like on the wire, read from its serde `Deserialize` impl.
//!
//! A [`Probe`] is a serde deserializer that holds no data: asked for a value, it notes what was
//! asked for (a `u32`, a struct with these fields, a sequence of ...) and hands back a default.
//! Deserializing a type through it therefore walks the type's whole shape in wire order, which is
//! exactly the order CDR writes it in. Enums are walked one variant per pass: [`describe`] walks
//! the type again until every variant of every enum it met has been seen. A type reached again
//! inside itself (a tree of nodes) ends the sequence it is in, its shape already being known.

use serde::de::{self, DeserializeSeed, IntoDeserializer, Visitor};
use std::collections::BTreeMap;

/// The shape of a value.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Shape {
    Bool,
    I8,
    I16,
    I32,
    I64,
    U8,
    U16,
    U32,
    U64,
    F32,
    F64,
    Str,
    /// A block of bytes (`serde_bytes`).
    Bytes,
    /// A growable sequence.
    Seq(Box<Shape>),
    /// A fixed-size array (`[T; N]`, or a tuple of one type).
    Array(Box<Shape>, usize),
    /// A named struct or enum, described in the [`Catalog`].
    Named(String),
    /// Something CDR messages of this project do not use (an option, a map, a mixed tuple, a
    /// char, 128-bit integers, unit): what it was.
    Unsupported(&'static str),
}

/// The shape of a named type.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Container {
    /// Fields in wire order.
    Struct(Vec<(String, Shape)>),
    /// A newtype struct: the wire is its one field's.
    Newtype(Shape),
    /// Variants by index; `None` for a variant not seen yet.
    Enum(Vec<(String, Option<Variant>)>),
}

/// The shape of one enum variant.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Variant {
    Unit,
    /// Its fields, positional ones named `_0`, `_1`, ...
    Fields(Vec<(String, Shape)>),
}

/// Every named type met so far.
#[derive(Debug, Default, Clone)]
pub struct Catalog {
    pub types: BTreeMap<String, Container>,
    /// How often each enum was walked (once all its variants are seen, the walks take them in
    /// turn, so the enums inside each variant are walked again too).
    walks: BTreeMap<String, usize>,
}

impl Catalog {
    /// Note a struct's shape; another type of the same name is an error (the names are the
    /// messages' names).
    fn insert(&mut self, name: &str, c: Container) -> Result<(), ProbeError> {
        match self.types.get(name) {
            Some(old) if *old != c => Err(ProbeError::Custom(format!(
                "two different types are named {name}"
            ))),
            _ => {
                self.types.insert(name.to_string(), c);
                Ok(())
            }
        }
    }

    /// Enums with a variant not seen yet, and how many of those.
    fn unexplored(&self) -> usize {
        self.types
            .values()
            .map(|c| match c {
                Container::Enum(vs) => vs.iter().filter(|(_, v)| v.is_none()).count(),
                _ => 0,
            })
            .sum()
    }
}

/// Why a type could not be described.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ProbeError {
    #[error("{0}")]
    Custom(String),
    #[error("its Deserialize asks for a self-describing format (deserialize_any)")]
    Any,
    /// A type reached inside itself; caught by the sequence around it.
    #[error("{0} contains itself other than through a sequence")]
    Recursion(String),
}

impl de::Error for ProbeError {
    fn custom<T: std::fmt::Display>(msg: T) -> Self {
        ProbeError::Custom(msg.to_string())
    }
}

/// Describe `T`: its shape, and every named type under it in `catalog`.
pub fn describe<T: de::DeserializeOwned>(catalog: &mut Catalog) -> Result<Shape, ProbeError> {
    for _ in 0..MAX_PASSES {
        let mut shape = None;
        let mut stack = Vec::new();
        T::deserialize(Probe {
            catalog,
            stack: &mut stack,
            out: &mut shape,
        })?;
        if catalog.unexplored() == 0 {
            return Ok(shape.unwrap_or(Shape::Unsupported("nothing")));
        }
    }
    // These variants hold a type that holds them: the walk never reaches them.
    let stuck: Vec<String> = catalog
        .types
        .iter()
        .flat_map(|(n, c)| match c {
            Container::Enum(vs) => vs
                .iter()
                .filter(|(_, v)| v.is_none())
                .map(|(v, _)| format!("{n}::{v}"))
                .collect(),
            _ => Vec::new(),
        })
        .collect();
    Err(ProbeError::Custom(format!(
        "enum variants {} hold a type that holds them (a recursive tagged union, which no ROS 2 message describes)",
        stuck.join(", ")
    )))
}

/// Walks of one type before the variants not reached yet are given up.
const MAX_PASSES: usize = 512;

struct Probe<'a> {
    catalog: &'a mut Catalog,
    /// Named types being walked, outermost first.
    stack: &'a mut Vec<String>,
    /// Where this value's shape goes.
    out: &'a mut Option<Shape>,
}

impl Probe<'_> {
    fn enter(&mut self, name: &str) -> Result<(), ProbeError> {
        if self.stack.iter().any(|n| n == name) {
            return Err(ProbeError::Recursion(name.to_string()));
        }
        self.stack.push(name.to_string());
        Ok(())
    }
}

/// Walk a list of values, each through its own probe, noting their shapes.
struct Fields<'a> {
    catalog: &'a mut Catalog,
    stack: &'a mut Vec<String>,
    shapes: Vec<Option<Shape>>,
    next: usize,
    len: usize,
}

impl<'de> de::SeqAccess<'de> for Fields<'_> {
    type Error = ProbeError;
    fn next_element_seed<S: DeserializeSeed<'de>>(
        &mut self,
        seed: S,
    ) -> Result<Option<S::Value>, ProbeError> {
        if self.next == self.len {
            return Ok(None);
        }
        let mut out = None;
        let v = seed.deserialize(Probe {
            catalog: self.catalog,
            stack: self.stack,
            out: &mut out,
        })?;
        self.shapes.push(out);
        self.next += 1;
        Ok(Some(v))
    }
}

/// A sequence of one element; of none when that element is the type being walked.
struct OneElement<'a> {
    catalog: &'a mut Catalog,
    stack: &'a mut Vec<String>,
    shape: Option<Shape>,
    done: bool,
}

impl<'de> de::SeqAccess<'de> for OneElement<'_> {
    type Error = ProbeError;
    fn next_element_seed<S: DeserializeSeed<'de>>(
        &mut self,
        seed: S,
    ) -> Result<Option<S::Value>, ProbeError> {
        if self.done {
            return Ok(None);
        }
        self.done = true;
        let mut out = None;
        let depth = self.stack.len();
        match seed.deserialize(Probe {
            catalog: self.catalog,
            stack: self.stack,
            out: &mut out,
        }) {
            Ok(v) => {
                self.shape = out;
                Ok(Some(v))
            }
            Err(ProbeError::Recursion(name)) => {
                self.stack.truncate(depth);
                self.shape = Some(Shape::Named(name));
                Ok(None)
            }
            Err(e) => Err(e),
        }
    }
}

/// Walk `len` values of a sequence through probes: what the visitor made of them, and their
/// shapes.
fn walk<'de, V: Visitor<'de>>(
    catalog: &mut Catalog,
    stack: &mut Vec<String>,
    len: usize,
    visitor: V,
) -> Result<(V::Value, Vec<Shape>), ProbeError> {
    let mut fields = Fields {
        catalog,
        stack,
        shapes: Vec::new(),
        next: 0,
        len,
    };
    let v = visitor.visit_seq(&mut fields)?;
    let shapes = fields
        .shapes
        .into_iter()
        .map(|s| s.unwrap_or(Shape::Unsupported("nothing")))
        .collect();
    Ok((v, shapes))
}

/// Field names paired with their shapes.
fn named(names: &[&str], shapes: Vec<Shape>) -> Vec<(String, Shape)> {
    names.iter().map(|n| n.to_string()).zip(shapes).collect()
}

macro_rules! primitive {
    ($($method:ident => $shape:expr, $visit:ident($value:expr);)*) => {
        $(fn $method<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ProbeError> {
            *self.out = Some($shape);
            visitor.$visit($value)
        })*
    };
}

macro_rules! unsupported {
    ($($method:ident => $what:literal;)*) => {
        $(fn $method<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, ProbeError> {
            *self.out = Some(Shape::Unsupported($what));
            Err(ProbeError::Custom(concat!("uses ", $what).to_string()))
        })*
    };
}

impl<'de> de::Deserializer<'de> for Probe<'_> {
    type Error = ProbeError;

    primitive! {
        deserialize_bool => Shape::Bool, visit_bool(false);
        deserialize_i8 => Shape::I8, visit_i8(0);
        deserialize_i16 => Shape::I16, visit_i16(0);
        deserialize_i32 => Shape::I32, visit_i32(0);
        deserialize_i64 => Shape::I64, visit_i64(0);
        deserialize_u8 => Shape::U8, visit_u8(0);
        deserialize_u16 => Shape::U16, visit_u16(0);
        deserialize_u32 => Shape::U32, visit_u32(0);
        deserialize_u64 => Shape::U64, visit_u64(0);
        deserialize_f32 => Shape::F32, visit_f32(0.0);
        deserialize_f64 => Shape::F64, visit_f64(0.0);
        deserialize_str => Shape::Str, visit_borrowed_str("");
        deserialize_string => Shape::Str, visit_string(String::new());
        deserialize_bytes => Shape::Bytes, visit_borrowed_bytes(&[]);
        deserialize_byte_buf => Shape::Bytes, visit_borrowed_bytes(&[]);
    }

    unsupported! {
        deserialize_i128 => "a 128-bit integer";
        deserialize_u128 => "a 128-bit integer";
        deserialize_char => "a char";
        deserialize_option => "an Option";
        deserialize_unit => "a unit value";
        deserialize_map => "a map";
        deserialize_identifier => "an identifier";
        deserialize_ignored_any => "an ignored value";
    }

    /// Messages are walked as CDR sees them: their wire forms.
    fn is_human_readable(&self) -> bool {
        false
    }

    fn deserialize_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, ProbeError> {
        Err(ProbeError::Any)
    }

    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _visitor: V,
    ) -> Result<V::Value, ProbeError> {
        *self.out = Some(Shape::Unsupported("a unit struct"));
        Err(ProbeError::Custom("uses a unit struct".into()))
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        mut self,
        name: &'static str,
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        self.enter(name)?;
        let mut inner = None;
        let v = visitor.visit_newtype_struct(Probe {
            catalog: self.catalog,
            stack: self.stack,
            out: &mut inner,
        })?;
        self.stack.pop();
        let inner = inner.unwrap_or(Shape::Unsupported("nothing"));
        self.catalog.insert(name, Container::Newtype(inner))?;
        *self.out = Some(Shape::Named(name.to_string()));
        Ok(v)
    }

    fn deserialize_seq<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, ProbeError> {
        let mut seq = OneElement {
            catalog: self.catalog,
            stack: self.stack,
            shape: None,
            done: false,
        };
        let v = visitor.visit_seq(&mut seq)?;
        *self.out = Some(Shape::Seq(Box::new(
            seq.shape
                .unwrap_or(Shape::Unsupported("an unknown element")),
        )));
        Ok(v)
    }

    fn deserialize_tuple<V: Visitor<'de>>(
        self,
        len: usize,
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        let (v, shapes) = walk(self.catalog, self.stack, len, visitor)?;
        *self.out = Some(match shapes.first() {
            Some(first) if shapes.iter().all(|s| s == first) => {
                Shape::Array(Box::new(first.clone()), len)
            }
            _ => Shape::Unsupported("a tuple of mixed types"),
        });
        Ok(v)
    }

    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        len: usize,
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        self.deserialize_tuple(len, visitor)
    }

    fn deserialize_struct<V: Visitor<'de>>(
        mut self,
        name: &'static str,
        field_names: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        self.enter(name)?;
        let (v, shapes) = walk(self.catalog, self.stack, field_names.len(), visitor)?;
        self.stack.pop();
        let described = named(field_names, shapes);
        self.catalog.insert(name, Container::Struct(described))?;
        *self.out = Some(Shape::Named(name.to_string()));
        Ok(v)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        mut self,
        name: &'static str,
        variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        if variants.is_empty() {
            return Err(ProbeError::Custom(format!("enum {name} has no variants")));
        }
        self.enter(name)?;
        let entry = self
            .catalog
            .types
            .entry(name.to_string())
            .or_insert_with(|| {
                Container::Enum(variants.iter().map(|v| (v.to_string(), None)).collect())
            });
        // The first variant not seen yet; once all are, each in turn.
        let walks = self.catalog.walks.entry(name.to_string()).or_default();
        *walks += 1;
        let turn = *walks % variants.len();
        let index = match entry {
            Container::Enum(vs)
                if vs.len() == variants.len()
                    && vs.iter().zip(variants).all(|((a, _), b)| a == b) =>
            {
                vs.iter().position(|(_, v)| v.is_none()).unwrap_or(turn)
            }
            _ => {
                return Err(ProbeError::Custom(format!(
                    "two different types are named {name}"
                )));
            }
        };
        let mut seen = None;
        let v = visitor.visit_enum(EnumProbe {
            catalog: self.catalog,
            stack: self.stack,
            index: index as u32,
            seen: &mut seen,
        })?;
        self.stack.pop();
        if let (Some(Container::Enum(vs)), Some(s)) = (self.catalog.types.get_mut(name), seen) {
            vs[index].1 = Some(s);
        }
        *self.out = Some(Shape::Named(name.to_string()));
        Ok(v)
    }
}

struct EnumProbe<'a> {
    catalog: &'a mut Catalog,
    stack: &'a mut Vec<String>,
    index: u32,
    seen: &'a mut Option<Variant>,
}

impl<'de, 'a> de::EnumAccess<'de> for EnumProbe<'a> {
    type Error = ProbeError;
    type Variant = Self;
    fn variant_seed<S: DeserializeSeed<'de>>(
        self,
        seed: S,
    ) -> Result<(S::Value, Self), ProbeError> {
        let id: de::value::U32Deserializer<ProbeError> = self.index.into_deserializer();
        Ok((seed.deserialize(id)?, self))
    }
}

impl<'de> de::VariantAccess<'de> for EnumProbe<'_> {
    type Error = ProbeError;

    fn unit_variant(self) -> Result<(), ProbeError> {
        *self.seen = Some(Variant::Unit);
        Ok(())
    }

    fn newtype_variant_seed<S: DeserializeSeed<'de>>(
        self,
        seed: S,
    ) -> Result<S::Value, ProbeError> {
        let mut out = None;
        let v = seed.deserialize(Probe {
            catalog: self.catalog,
            stack: self.stack,
            out: &mut out,
        })?;
        *self.seen = Some(Variant::Fields(vec![(
            "_0".into(),
            out.unwrap_or(Shape::Unsupported("nothing")),
        )]));
        Ok(v)
    }

    fn tuple_variant<V: Visitor<'de>>(
        self,
        len: usize,
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        let (v, shapes) = walk(self.catalog, self.stack, len, visitor)?;
        let names: Vec<String> = (0..len).map(|i| format!("_{i}")).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        *self.seen = Some(Variant::Fields(named(&names, shapes)));
        Ok(v)
    }

    fn struct_variant<V: Visitor<'de>>(
        self,
        field_names: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, ProbeError> {
        let (v, shapes) = walk(self.catalog, self.stack, field_names.len(), visitor)?;
        *self.seen = Some(Variant::Fields(named(field_names, shapes)));
        Ok(v)
    }
}
