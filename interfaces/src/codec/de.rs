//! The CDR little-endian decoder: a serde deserializer over a byte slice.
//!
//! It reads exactly what the `cdr` crate writes (and what `cdr::deserialize` reads): primitives
//! aligned to their size from the end of the encapsulation header, strings and byte blocks as a
//! `u32` length then the bytes (strings with a trailing NUL), sequences as a `u32` count then the
//! elements, structs and tuples as their fields in order, enums as a `u32` variant index then the
//! variant's fields. Two differences, both about bad input:
//!
//! - Every length is checked against the bytes left before anything is allocated, so a length
//!   field of 2^32-1 is an error, not a 4 GiB allocation; a sequence cannot announce more
//!   elements than there are bytes left.
//! - Byte blocks and strings are handed to serde as borrowed slices of the payload, so a type with
//!   `&'a [u8]` fields (a message's borrowed view) reads them in place, and an owned `Vec<u8>`
//!   costs one copy.

use cdr::Error;
use serde::de::{self, IntoDeserializer, Visitor};

/// Reads one value from `data`, the payload after its 4-byte encapsulation header.
pub(crate) struct Deserializer<'de> {
    data: &'de [u8],
    pos: usize,
}

fn ends_early(need: usize, at: usize, len: usize) -> Error {
    Error::Io(std::io::Error::new(
        std::io::ErrorKind::UnexpectedEof,
        format!(
            "the payload ends early: {need} bytes wanted at offset {at}, {} left",
            len.saturating_sub(at)
        ),
    ))
}

impl<'de> Deserializer<'de> {
    pub(crate) fn new(data: &'de [u8]) -> Self {
        Self { data, pos: 0 }
    }

    fn left(&self) -> usize {
        self.data.len().saturating_sub(self.pos)
    }

    /// The next `n` bytes, in place.
    fn take(&mut self, n: usize) -> Result<&'de [u8], Error> {
        let data = self.data;
        let out = self
            .pos
            .checked_add(n)
            .and_then(|end| data.get(self.pos..end))
            .ok_or_else(|| ends_early(n, self.pos, data.len()))?;
        self.pos += n;
        Ok(out)
    }

    /// A primitive of `N` bytes, after the padding that aligns it to `N`.
    fn array<const N: usize>(&mut self) -> Result<[u8; N], Error> {
        let misalign = self.pos & (N - 1);
        if misalign != 0 {
            self.take(N - misalign)?;
        }
        let mut out = [0u8; N];
        out.copy_from_slice(self.take(N)?);
        Ok(out)
    }

    fn u32(&mut self) -> Result<u32, Error> {
        Ok(u32::from_le_bytes(self.array()?))
    }

    /// A `u32` length or count, checked against the bytes left (each element takes at least one).
    fn length(&mut self) -> Result<usize, Error> {
        let at = self.pos;
        let n = self.u32()? as usize;
        if n > self.left() {
            return Err(Error::Message(format!(
                "a length of {n} at offset {at} is more than the {} bytes left",
                self.left()
            )));
        }
        Ok(n)
    }

    fn bytes(&mut self) -> Result<&'de [u8], Error> {
        let n = self.length()?;
        self.take(n)
    }

    /// A string: its bytes without the terminating NUL the encoder writes.
    fn str(&mut self) -> Result<&'de str, Error> {
        let raw = self.bytes()?;
        let text = raw.split_last().map_or(raw, |(_, rest)| rest);
        std::str::from_utf8(text).map_err(Error::InvalidUtf8Encoding)
    }
}

/// The elements of a sequence, tuple or struct, `left` of them still to read.
struct Elements<'a, 'de> {
    de: &'a mut Deserializer<'de>,
    left: usize,
}

impl<'de> de::SeqAccess<'de> for Elements<'_, 'de> {
    type Error = Error;

    fn next_element_seed<T: de::DeserializeSeed<'de>>(
        &mut self,
        seed: T,
    ) -> Result<Option<T::Value>, Error> {
        if self.left == 0 {
            return Ok(None);
        }
        self.left -= 1;
        seed.deserialize(&mut *self.de).map(Some)
    }

    fn size_hint(&self) -> Option<usize> {
        Some(self.left)
    }
}

impl<'de> de::EnumAccess<'de> for &mut Deserializer<'de> {
    type Error = Error;
    type Variant = Self;

    fn variant_seed<V: de::DeserializeSeed<'de>>(self, seed: V) -> Result<(V::Value, Self), Error> {
        let index = self.u32()?;
        let value = seed.deserialize(IntoDeserializer::<Error>::into_deserializer(index))?;
        Ok((value, self))
    }
}

impl<'de> de::VariantAccess<'de> for &mut Deserializer<'de> {
    type Error = Error;

    fn unit_variant(self) -> Result<(), Error> {
        Ok(())
    }

    fn newtype_variant_seed<T: de::DeserializeSeed<'de>>(self, seed: T) -> Result<T::Value, Error> {
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
        de::Deserializer::deserialize_tuple(self, fields.len(), visitor)
    }
}

macro_rules! primitive {
    ($method:ident, $visit:ident, $ty:ty) => {
        fn $method<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
            visitor.$visit(<$ty>::from_le_bytes(self.array()?))
        }
    };
}

impl<'de> de::Deserializer<'de> for &mut Deserializer<'de> {
    type Error = Error;

    primitive!(deserialize_u8, visit_u8, u8);
    primitive!(deserialize_u16, visit_u16, u16);
    primitive!(deserialize_u32, visit_u32, u32);
    primitive!(deserialize_u64, visit_u64, u64);
    primitive!(deserialize_i8, visit_i8, i8);
    primitive!(deserialize_i16, visit_i16, i16);
    primitive!(deserialize_i32, visit_i32, i32);
    primitive!(deserialize_i64, visit_i64, i64);
    primitive!(deserialize_f32, visit_f32, f32);
    primitive!(deserialize_f64, visit_f64, f64);

    fn deserialize_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, Error> {
        Err(Error::DeserializeAnyNotSupported)
    }

    fn deserialize_bool<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        match self.array::<1>()?[0] {
            0 => visitor.visit_bool(false),
            1 => visitor.visit_bool(true),
            other => Err(Error::InvalidBoolEncoding(other)),
        }
    }

    fn deserialize_char<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        // One byte, ASCII only, as the encoder writes it.
        let b = self.array::<1>()?[0];
        if b.is_ascii() {
            visitor.visit_char(char::from(b))
        } else {
            Err(Error::InvalidCharEncoding)
        }
    }

    fn deserialize_str<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_borrowed_str(self.str()?)
    }

    fn deserialize_string<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_borrowed_str(self.str()?)
    }

    fn deserialize_bytes<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_borrowed_bytes(self.bytes()?)
    }

    fn deserialize_byte_buf<V: Visitor<'de>>(self, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_borrowed_bytes(self.bytes()?)
    }

    fn deserialize_option<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, Error> {
        Err(Error::TypeNotSupported)
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
        let left = self.length()?;
        visitor.visit_seq(Elements { de: self, left })
    }

    fn deserialize_tuple<V: Visitor<'de>>(self, len: usize, visitor: V) -> Result<V::Value, Error> {
        visitor.visit_seq(Elements {
            de: self,
            left: len,
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

    fn deserialize_map<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, Error> {
        Err(Error::TypeNotSupported)
    }

    fn deserialize_struct<V: Visitor<'de>>(
        self,
        _name: &'static str,
        fields: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        self.deserialize_tuple(fields.len(), visitor)
    }

    fn deserialize_enum<V: Visitor<'de>>(
        self,
        _name: &'static str,
        _variants: &'static [&'static str],
        visitor: V,
    ) -> Result<V::Value, Error> {
        visitor.visit_enum(self)
    }

    fn deserialize_identifier<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, Error> {
        Err(Error::TypeNotSupported)
    }

    fn deserialize_ignored_any<V: Visitor<'de>>(self, _visitor: V) -> Result<V::Value, Error> {
        Err(Error::TypeNotSupported)
    }

    fn is_human_readable(&self) -> bool {
        false
    }
}
