//! A message to Python objects, through its serde `Serialize` (the same walk the CDR encoder
//! makes): structs become the generated dataclasses of `robocog.msg` (looked up by their serde
//! name; a `dict` when none is registered), sequences `list`s, enums serde's external tagging.
//!
//! Byte blocks that lie inside the received payload become `memoryview`s of it (no copy: the
//! view keeps the sample alive); others become `bytes`.

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList, PySlice, PyString};
use serde::ser::{self, Serialize};
use std::fmt;

/// Why a value could not be made into Python objects.
#[derive(Debug)]
pub struct Error(pub PyErr);

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

impl std::error::Error for Error {}

impl ser::Error for Error {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        Error(PyValueError::new_err(msg.to_string()))
    }
}

impl From<PyErr> for Error {
    fn from(e: PyErr) -> Self {
        Error(e)
    }
}

/// The payload the value was decoded from, and the Python object that owns it: byte blocks
/// inside it are lent, not copied.
#[derive(Clone, Copy)]
pub struct Lender<'a, 'py> {
    pub bytes: &'a [u8],
    pub owner: &'a Bound<'py, PyAny>,
}

/// The serializer: `classes` maps serde struct names to Python classes.
#[derive(Clone, Copy)]
pub struct ToPy<'a, 'py> {
    pub py: Python<'py>,
    pub classes: Option<&'a Bound<'py, PyDict>>,
    pub lender: Option<Lender<'a, 'py>>,
}

/// `value` as Python objects.
pub fn to_py<'py, T: Serialize + ?Sized>(
    value: &T,
    cx: ToPy<'_, 'py>,
) -> PyResult<Bound<'py, PyAny>> {
    value.serialize(cx).map_err(|e| e.0)
}

impl<'py> ToPy<'_, 'py> {
    fn bytes(&self, v: &[u8]) -> PyResult<Bound<'py, PyAny>> {
        if let Some(l) = self.lender {
            let base = l.bytes.as_ptr() as usize;
            let start = v.as_ptr() as usize;
            if start >= base && start + v.len() <= base + l.bytes.len() && !v.is_empty() {
                let offset = start - base;
                let view = self
                    .py
                    .import("builtins")?
                    .getattr("memoryview")?
                    .call1((l.owner,))?;
                return view.get_item(PySlice::new(
                    self.py,
                    offset as isize,
                    (offset + v.len()) as isize,
                    1,
                ));
            }
        }
        Ok(PyBytes::new(self.py, v).into_any())
    }

    fn structure(
        &self,
        name: &'static str,
        fields: Bound<'py, PyDict>,
    ) -> PyResult<Bound<'py, PyAny>> {
        match self
            .classes
            .map(|c| c.get_item(name))
            .transpose()?
            .flatten()
        {
            Some(class) => class.call((), Some(&fields)),
            None => Ok(fields.into_any()),
        }
    }

    fn tagged(&self, variant: &str, value: Bound<'py, PyAny>) -> PyResult<Bound<'py, PyAny>> {
        let d = PyDict::new(self.py);
        d.set_item(variant, value)?;
        Ok(d.into_any())
    }
}

macro_rules! scalar {
    ($($f:ident: $t:ty),*) => {
        $(fn $f(self, v: $t) -> Result<Self::Ok, Error> {
            Ok(pyo3::IntoPyObjectExt::into_bound_py_any(v, self.py)?)
        })*
    };
}

impl<'a, 'py> ser::Serializer for ToPy<'a, 'py> {
    type Ok = Bound<'py, PyAny>;
    type Error = Error;
    type SerializeSeq = Seq<'a, 'py>;
    type SerializeTuple = Seq<'a, 'py>;
    type SerializeTupleStruct = Seq<'a, 'py>;
    type SerializeTupleVariant = Seq<'a, 'py>;
    type SerializeMap = Map<'a, 'py>;
    type SerializeStruct = Map<'a, 'py>;
    type SerializeStructVariant = Map<'a, 'py>;

    /// The wire forms (as CDR sees them), which the generated classes describe.
    fn is_human_readable(&self) -> bool {
        false
    }

    scalar!(serialize_bool: bool, serialize_i8: i8, serialize_i16: i16, serialize_i32: i32,
        serialize_i64: i64, serialize_u8: u8, serialize_u16: u16, serialize_u32: u32,
        serialize_u64: u64, serialize_f64: f64);

    fn serialize_f32(self, v: f32) -> Result<Self::Ok, Error> {
        self.serialize_f64(f64::from(v))
    }
    fn serialize_char(self, v: char) -> Result<Self::Ok, Error> {
        Ok(PyString::new(self.py, &v.to_string()).into_any())
    }
    fn serialize_str(self, v: &str) -> Result<Self::Ok, Error> {
        Ok(PyString::new(self.py, v).into_any())
    }
    fn serialize_bytes(self, v: &[u8]) -> Result<Self::Ok, Error> {
        Ok(self.bytes(v)?)
    }
    fn serialize_none(self) -> Result<Self::Ok, Error> {
        Ok(self.py.None().into_bound(self.py))
    }
    fn serialize_some<T: Serialize + ?Sized>(self, value: &T) -> Result<Self::Ok, Error> {
        value.serialize(self)
    }
    fn serialize_unit(self) -> Result<Self::Ok, Error> {
        self.serialize_none()
    }
    fn serialize_unit_struct(self, _name: &'static str) -> Result<Self::Ok, Error> {
        self.serialize_none()
    }
    fn serialize_unit_variant(
        self,
        _name: &'static str,
        _index: u32,
        variant: &'static str,
    ) -> Result<Self::Ok, Error> {
        self.serialize_str(variant)
    }
    fn serialize_newtype_struct<T: Serialize + ?Sized>(
        self,
        _name: &'static str,
        value: &T,
    ) -> Result<Self::Ok, Error> {
        value.serialize(self)
    }
    fn serialize_newtype_variant<T: Serialize + ?Sized>(
        self,
        _name: &'static str,
        _index: u32,
        variant: &'static str,
        value: &T,
    ) -> Result<Self::Ok, Error> {
        let v = value.serialize(self)?;
        Ok(self.tagged(variant, v)?)
    }
    fn serialize_seq(self, len: Option<usize>) -> Result<Seq<'a, 'py>, Error> {
        Ok(Seq {
            cx: self,
            items: Vec::with_capacity(len.unwrap_or(0)),
            variant: None,
        })
    }
    fn serialize_tuple(self, len: usize) -> Result<Seq<'a, 'py>, Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_struct(
        self,
        _name: &'static str,
        len: usize,
    ) -> Result<Seq<'a, 'py>, Error> {
        self.serialize_seq(Some(len))
    }
    fn serialize_tuple_variant(
        self,
        _name: &'static str,
        _index: u32,
        variant: &'static str,
        len: usize,
    ) -> Result<Seq<'a, 'py>, Error> {
        let mut s = self.serialize_seq(Some(len))?;
        s.variant = Some(variant);
        Ok(s)
    }
    fn serialize_map(self, _len: Option<usize>) -> Result<Map<'a, 'py>, Error> {
        Ok(Map {
            cx: self,
            dict: PyDict::new(self.py),
            key: None,
            name: None,
            variant: None,
        })
    }
    fn serialize_struct(self, name: &'static str, _len: usize) -> Result<Map<'a, 'py>, Error> {
        let mut m = self.serialize_map(None)?;
        m.name = Some(name);
        Ok(m)
    }
    fn serialize_struct_variant(
        self,
        _name: &'static str,
        _index: u32,
        variant: &'static str,
        _len: usize,
    ) -> Result<Map<'a, 'py>, Error> {
        let mut m = self.serialize_map(None)?;
        m.variant = Some(variant);
        Ok(m)
    }
}

/// A sequence, tuple or tuple variant being built.
pub struct Seq<'a, 'py> {
    cx: ToPy<'a, 'py>,
    items: Vec<Bound<'py, PyAny>>,
    variant: Option<&'static str>,
}

impl<'py> Seq<'_, 'py> {
    fn push<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Error> {
        self.items.push(value.serialize(self.cx)?);
        Ok(())
    }
    fn done(self) -> Result<Bound<'py, PyAny>, Error> {
        let list = PyList::new(self.cx.py, self.items)?.into_any();
        Ok(match self.variant {
            Some(v) => self.cx.tagged(v, list)?,
            None => list,
        })
    }
}

macro_rules! seq_impl {
    ($($tr:ident: $f:ident),*) => {
        $(impl<'a, 'py> ser::$tr for Seq<'a, 'py> {
            type Ok = Bound<'py, PyAny>;
            type Error = Error;
            fn $f<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Error> {
                self.push(value)
            }
            fn end(self) -> Result<Self::Ok, Error> {
                self.done()
            }
        })*
    };
}

seq_impl!(SerializeSeq: serialize_element, SerializeTuple: serialize_element,
    SerializeTupleStruct: serialize_field, SerializeTupleVariant: serialize_field);

/// A map, struct or struct variant being built.
pub struct Map<'a, 'py> {
    cx: ToPy<'a, 'py>,
    dict: Bound<'py, PyDict>,
    key: Option<Bound<'py, PyAny>>,
    name: Option<&'static str>,
    variant: Option<&'static str>,
}

impl<'a, 'py> ser::SerializeMap for Map<'a, 'py> {
    type Ok = Bound<'py, PyAny>;
    type Error = Error;
    fn serialize_key<T: Serialize + ?Sized>(&mut self, key: &T) -> Result<(), Error> {
        self.key = Some(key.serialize(self.cx)?);
        Ok(())
    }
    fn serialize_value<T: Serialize + ?Sized>(&mut self, value: &T) -> Result<(), Error> {
        let key = self
            .key
            .take()
            .ok_or_else(|| Error(PyValueError::new_err("a map value without its key")))?;
        self.dict.set_item(key, value.serialize(self.cx)?)?;
        Ok(())
    }
    fn end(self) -> Result<Self::Ok, Error> {
        Ok(self.dict.into_any())
    }
}

impl<'a, 'py> ser::SerializeStruct for Map<'a, 'py> {
    type Ok = Bound<'py, PyAny>;
    type Error = Error;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), Error> {
        self.dict.set_item(key, value.serialize(self.cx)?)?;
        Ok(())
    }
    fn end(self) -> Result<Self::Ok, Error> {
        match self.name {
            Some(name) => Ok(self.cx.structure(name, self.dict)?),
            None => Ok(self.dict.into_any()),
        }
    }
}

impl<'a, 'py> ser::SerializeStructVariant for Map<'a, 'py> {
    type Ok = Bound<'py, PyAny>;
    type Error = Error;
    fn serialize_field<T: Serialize + ?Sized>(
        &mut self,
        key: &'static str,
        value: &T,
    ) -> Result<(), Error> {
        self.dict.set_item(key, value.serialize(self.cx)?)?;
        Ok(())
    }
    fn end(self) -> Result<Self::Ok, Error> {
        let variant = self.variant.unwrap_or_default();
        Ok(self.cx.tagged(variant, self.dict.into_any())?)
    }
}
