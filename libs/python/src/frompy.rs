//! Python objects to a message, through its serde `Deserialize` as CDR sees it (the wire forms
//! the generated classes describe): a struct is read from a dataclass's attributes (or a
//! `dict`'s entries) by the field names serde asks for, a sequence from a `list` or `tuple`, a
//! byte block from `bytes` (borrowed) or anything with the buffer protocol (a NumPy array,
//! copied once), an enum from its variant's name or a one-entry `dict`.

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PyString, PyTuple};
use serde::de::{self, DeserializeSeed, Visitor};
use std::fmt;

/// Why Python values are not the message.
#[derive(Debug)]
pub struct Error(pub String);

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for Error {}

impl de::Error for Error {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        Error(msg.to_string())
    }
}

impl From<PyErr> for Error {
    fn from(e: PyErr) -> Self {
        Error(e.to_string())
    }
}

/// `obj` as a `T`.
pub fn from_py<T: de::DeserializeOwned>(obj: &Bound<'_, PyAny>) -> Result<T, Error> {
    let arena = Arena::default();
    T::deserialize(FromPy { obj, arena: &arena })
}

/// `obj` as a view of a `T` that borrows its byte blocks from the Python objects (a NumPy
/// array's memory, a `bytes`' own), handed to `f`: a frame is read straight from Python's
/// buffers into the publisher's shared memory. The buffers are read while `f` runs.
pub fn with_view<T: interfaces::msg::Borrowable, R>(
    obj: &Bound<'_, PyAny>,
    f: impl FnOnce(&mut T::View<'_>) -> R,
) -> Result<R, Error> {
    let arena = Arena::default();
    let mut view = <T::View<'_> as de::Deserialize>::deserialize(FromPy { obj, arena: &arena })?;
    Ok(f(&mut view))
}

/// What is kept while a message is read, so that its text and bytes are lent to the message's
/// deserializer (wire forms and views borrow them) rather than copied: every object met, and
/// the buffers (the buffer protocol) of byte blocks that are not `bytes`.
#[derive(Default)]
struct Arena<'py> {
    objects: typed_arena::Arena<Bound<'py, PyAny>>,
    buffers: typed_arena::Arena<pyo3::buffer::PyBuffer<u8>>,
}

impl<'py> Arena<'py> {
    fn alloc(&self, obj: Bound<'py, PyAny>) -> &Bound<'py, PyAny> {
        self.objects.alloc(obj)
    }
}

struct FromPy<'de, 'py> {
    obj: &'de Bound<'py, PyAny>,
    arena: &'de Arena<'py>,
}

impl<'de, 'py> FromPy<'de, 'py> {
    fn child(&self, obj: Bound<'py, PyAny>) -> FromPy<'de, 'py> {
        FromPy {
            obj: self.arena.alloc(obj),
            arena: self.arena,
        }
    }

    fn items(&self) -> Result<Vec<Bound<'py, PyAny>>, Error> {
        if let Ok(l) = self.obj.cast::<PyList>() {
            return Ok(l.iter().collect());
        }
        if let Ok(t) = self.obj.cast::<PyTuple>() {
            return Ok(t.iter().collect());
        }
        Err(Error(format!(
            "expected a list, found {}",
            type_of(self.obj)
        )))
    }

    fn int(&self) -> Result<i128, Error> {
        if self.obj.is_instance_of::<pyo3::types::PyFloat>() {
            return Err(Error(format!("expected an integer, found {}", self.obj)));
        }
        self.obj
            .extract::<i128>()
            .map_err(|_| Error(format!("expected an integer, found {}", type_of(self.obj))))
    }
}

fn type_of(obj: &Bound<'_, PyAny>) -> String {
    obj.get_type()
        .name()
        .map(|n| n.to_string())
        .unwrap_or_else(|_| "?".into())
}

macro_rules! ints {
    ($($f:ident => $visit:ident: $t:ty),*) => {
        $(fn $f<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
            let v = self.int()?;
            let v = <$t>::try_from(v).map_err(|_| {
                Error(format!("{v} is out of the range of {}", stringify!($t)))
            })?;
            visitor.$visit(v)
        })*
    };
}

impl<'de, 'py> de::Deserializer<'de> for FromPy<'de, 'py> {
    type Error = Error;

    fn is_human_readable(&self) -> bool {
        false
    }

    fn deserialize_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let o = self.obj;
        if o.is_none() {
            visitor.visit_unit()
        } else if o.is_instance_of::<pyo3::types::PyBool>() {
            visitor.visit_bool(o.extract()?)
        } else if o.is_instance_of::<pyo3::types::PyInt>() {
            visitor.visit_i64(o.extract()?)
        } else if o.is_instance_of::<pyo3::types::PyFloat>() {
            visitor.visit_f64(o.extract()?)
        } else if let Ok(s) = o.cast::<PyString>() {
            visitor.visit_borrowed_str(s.to_str()?)
        } else if o.is_instance_of::<PyBytes>() {
            self.deserialize_bytes(visitor)
        } else if o.is_instance_of::<PyDict>() {
            self.deserialize_map(visitor)
        } else {
            self.deserialize_seq(visitor)
        }
    }

    fn deserialize_bool<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        if !self.obj.is_instance_of::<pyo3::types::PyBool>() {
            return Err(Error(format!(
                "expected a bool, found {}",
                type_of(self.obj)
            )));
        }
        visitor.visit_bool(self.obj.extract()?)
    }

    ints!(deserialize_i8 => visit_i8: i8, deserialize_i16 => visit_i16: i16,
        deserialize_i32 => visit_i32: i32, deserialize_i64 => visit_i64: i64,
        deserialize_u8 => visit_u8: u8, deserialize_u16 => visit_u16: u16,
        deserialize_u32 => visit_u32: u32, deserialize_u64 => visit_u64: u64);

    fn deserialize_f32<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_f64(visitor)
    }

    fn deserialize_f64<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let v: f64 = self
            .obj
            .extract()
            .map_err(|_| Error(format!("expected a number, found {}", type_of(self.obj))))?;
        visitor.visit_f64(v)
    }

    fn deserialize_char<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_str(visitor)
    }

    fn deserialize_str<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let s = self
            .obj
            .cast::<PyString>()
            .map_err(|_| Error(format!("expected text, found {}", type_of(self.obj))))?;
        visitor.visit_borrowed_str(s.to_str()?)
    }

    fn deserialize_string<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_str(visitor)
    }

    fn deserialize_bytes<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        if let Ok(b) = self.obj.cast::<PyBytes>() {
            return visitor.visit_borrowed_bytes(b.as_bytes());
        }
        // A bytearray, memoryview or NumPy array: its memory, through the buffer protocol, as
        // bytes (a memoryview cast to unsigned bytes, which any C-contiguous buffer allows).
        let py = self.obj.py();
        let not_bytes = || {
            Error(format!(
                "expected bytes (or a C-contiguous buffer: bytearray, memoryview, NumPy array), found {}",
                type_of(self.obj)
            ))
        };
        let view = py
            .import("builtins")?
            .getattr("memoryview")?
            .call1((self.obj,))
            .and_then(|m| m.call_method1("cast", ("B",)))
            .map_err(|_| not_bytes())?;
        let buffer = pyo3::buffer::PyBuffer::<u8>::get(&view).map_err(|_| not_bytes())?;
        if !buffer.is_c_contiguous() {
            return Err(not_bytes());
        }
        let buffer: &'de pyo3::buffer::PyBuffer<u8> = self.arena.buffers.alloc(buffer);
        // SAFETY: the exporter keeps this memory, unmoved, while the buffer is held, and the
        // arena holds it for all of 'de; it is C-contiguous, `len_bytes` long.
        let bytes: &'de [u8] = unsafe {
            std::slice::from_raw_parts(buffer.buf_ptr() as *const u8, buffer.len_bytes())
        };
        visitor.visit_borrowed_bytes(bytes)
    }

    fn deserialize_byte_buf<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_bytes(visitor)
    }

    fn deserialize_option<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        if self.obj.is_none() {
            visitor.visit_none()
        } else {
            visitor.visit_some(self)
        }
    }

    fn deserialize_unit<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_unit()
    }

    fn deserialize_unit_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Error> {
        visitor.visit_unit()
    }

    fn deserialize_newtype_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        visitor: V,
    ) -> Result<V::Value, Error> {
        visitor.visit_newtype_struct(self)
    }

    fn deserialize_seq<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let items = self.items()?;
        visitor.visit_seq(Seq {
            items: items.into_iter(),
            arena: self.arena,
        })
    }

    fn deserialize_tuple<V: Visitor<'de>>(self, len: usize, visitor: V) -> Result<V::Value, Error> {
        let items = self.items()?;
        if items.len() != len {
            return Err(Error(format!(
                "expected {len} values, found {}",
                items.len()
            )));
        }
        visitor.visit_seq(Seq {
            items: items.into_iter(),
            arena: self.arena,
        })
    }

    fn deserialize_tuple_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        len: usize,
        visitor: V,
    ) -> Result<V::Value, Error> {
        self.deserialize_tuple(len, visitor)
    }

    fn deserialize_map<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        let d = self
            .obj
            .cast::<PyDict>()
            .map_err(|_| Error(format!("expected a dict, found {}", type_of(self.obj))))?;
        let entries: Vec<_> = d.iter().collect();
        visitor.visit_map(Map {
            entries: entries.into_iter(),
            value: None,
            arena: self.arena,
        })
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        // The fields in serde's order, from a dict's entries or an object's attributes.
        let mut values = Vec::with_capacity(fields.len());
        let dict = self.obj.cast::<PyDict>().ok();
        for f in fields {
            let v = match dict {
                Some(d) => d.get_item(f)?,
                None => self.obj.getattr(*f).ok(),
            };
            let v = v.ok_or_else(|| {
                Error(format!(
                    "{name} needs a field {f:?}, and this {} has none",
                    type_of(self.obj)
                ))
            })?;
            values.push(v);
        }
        visitor
            .visit_seq(Seq {
                items: values.into_iter(),
                arena: self.arena,
            })
            .map_err(|e| Error(format!("{name}: {e}")))
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        if let Ok(s) = self.obj.cast::<PyString>() {
            let variant: String = s.to_cow()?.into_owned();
            return visitor.visit_enum(de::value::StringDeserializer::<Error>::new(variant));
        }
        let d = self.obj.cast::<PyDict>().map_err(|_| {
            Error(format!(
                "expected a variant's name or {{variant: value}}, found {}",
                type_of(self.obj)
            ))
        })?;
        if d.len() != 1 {
            return Err(Error(format!(
                "an enum is one variant: {{variant: value}} has {} entries",
                d.len()
            )));
        }
        let (k, v) = d.iter().next().ok_or_else(|| Error("empty".into()))?;
        let variant: String = k.extract()?;
        visitor.visit_enum(Enum {
            variant,
            value: self.child(v),
        })
    }

    fn deserialize_identifier<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        self.deserialize_str(visitor)
    }

    fn deserialize_ignored_any<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_unit()
    }
}

struct Seq<'de, 'py, I: Iterator<Item = Bound<'py, PyAny>>> {
    items: I,
    arena: &'de Arena<'py>,
}

impl<'de, 'py, I: Iterator<Item = Bound<'py, PyAny>>> de::SeqAccess<'de> for Seq<'de, 'py, I> {
    type Error = Error;
    fn next_element_seed<T: DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Error> {
        match self.items.next() {
            Some(obj) => seed
                .deserialize(FromPy {
                    obj: self.arena.alloc(obj),
                    arena: self.arena,
                })
                .map(Some),
            None => Ok(None),
        }
    }
}

struct Map<'de, 'py, I: Iterator<Item = (Bound<'py, PyAny>, Bound<'py, PyAny>)>> {
    entries: I,
    value: Option<Bound<'py, PyAny>>,
    arena: &'de Arena<'py>,
}

impl<'de, 'py, I: Iterator<Item = (Bound<'py, PyAny>, Bound<'py, PyAny>)>> de::MapAccess<'de>
    for Map<'de, 'py, I>
{
    type Error = Error;
    fn next_key_seed<K: DeserializeSeed<'de>>(
        &mut self,
        seed: K,
    ) -> Result<Option<K::Value>, Error> {
        match self.entries.next() {
            Some((k, v)) => {
                self.value = Some(v);
                seed.deserialize(FromPy {
                    obj: self.arena.alloc(k),
                    arena: self.arena,
                })
                .map(Some)
            }
            None => Ok(None),
        }
    }
    fn next_value_seed<T: DeserializeSeed<'de>>(&mut self, seed: T) -> Result<T::Value, Error> {
        let obj = self
            .value
            .take()
            .ok_or_else(|| Error("a map value without its key".into()))?;
        seed.deserialize(FromPy {
            obj: self.arena.alloc(obj),
            arena: self.arena,
        })
    }
}

struct Enum<'de, 'py> {
    variant: String,
    value: FromPy<'de, 'py>,
}

impl<'de, 'py> de::EnumAccess<'de> for Enum<'de, 'py> {
    type Error = Error;
    type Variant = FromPy<'de, 'py>;
    fn variant_seed<V: DeserializeSeed<'de>>(
        self,
        seed: V,
    ) -> Result<(V::Value, FromPy<'de, 'py>), Error> {
        let v = seed.deserialize(de::value::StringDeserializer::<Error>::new(self.variant))?;
        Ok((v, self.value))
    }
}

impl<'de, 'py> de::VariantAccess<'de> for FromPy<'de, 'py> {
    type Error = Error;
    fn unit_variant(self) -> Result<(), Error> {
        Ok(())
    }
    fn newtype_variant_seed<T: DeserializeSeed<'de>>(self, seed: T) -> Result<T::Value, Error> {
        seed.deserialize(self)
    }
    fn tuple_variant<V: Visitor<'de>>(self, len: usize, visitor: V) -> Result<V::Value, Error> {
        de::Deserializer::deserialize_tuple(self, len, visitor)
    }
    fn struct_variant<V: Visitor<'de>>(
        self,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        de::Deserializer::deserialize_struct(self, "variant", fields, visitor)
    }
}
