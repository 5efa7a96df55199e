//! Reading values from a binary (little or big endian) PLY body in a mapped file or window.
//!
//! The reader indexes its byte slice directly and knows the file offset of the slice's first
//! byte (its origin: 0 for a whole-file mapping, the window start for a windowed one), so a
//! defect's byte offset is always absolute in the file while positions stay cheap slice
//! indices. Parallel workers can each start a reader at their own block. Every read is bounds-checked and turns a short file into a `Truncated`
//! defect rather than a panic. Values are assembled with `from_le_bytes` after reversing
//! big-endian bytes, which keeps one code path per type.

use super::header::{Endian, Scalar};
use super::values::{Defect, ValueReader};
use crate::input::error::InputErrorKind;

pub(crate) struct BinaryReader<'a> {
    bytes: &'a [u8],
    origin: u64,
    position: usize,
    last_value: usize,
    endian: Endian,
}

impl<'a> BinaryReader<'a> {
    pub(crate) fn new(bytes: &'a [u8], position: usize, endian: Endian) -> BinaryReader<'a> {
        BinaryReader {
            bytes,
            origin: 0,
            position,
            last_value: position,
            endian,
        }
    }

    /// Declares that `bytes[0]` is at file offset `origin`, for readers over a window.
    pub(crate) fn with_origin(self, origin: u64) -> BinaryReader<'a> {
        BinaryReader { origin, ..self }
    }

    /// Position in the slice (not in the file).
    pub(crate) fn position(&self) -> usize {
        self.position
    }

    /// Skips `length` bytes, failing if fewer remain.
    pub(crate) fn skip_bytes(&mut self, length: u64) -> Result<(), Defect> {
        let remaining = self.bytes.len().saturating_sub(self.position) as u64;
        if length > remaining {
            return Err(self.truncated(length - remaining));
        }
        self.position += length as usize;
        Ok(())
    }

    /// The next `N` bytes in little-endian order.
    fn take<const N: usize>(&mut self) -> Result<[u8; N], Defect> {
        self.last_value = self.position;
        let rest = self.bytes.get(self.position..).unwrap_or_default();
        let Some(chunk) = rest.first_chunk::<N>() else {
            return Err(self.truncated((N - rest.len()) as u64));
        };
        self.position += N;
        let mut value = *chunk;
        if self.endian == Endian::Big {
            value.reverse();
        }
        Ok(value)
    }

    fn file_offset(&self, position: usize) -> u64 {
        self.origin + position as u64
    }

    fn truncated(&self, needed: u64) -> Defect {
        Defect {
            kind: InputErrorKind::Truncated { needed },
            byte_offset: self.file_offset(self.position),
            line: None,
        }
    }
}

impl ValueReader for BinaryReader<'_> {
    fn defect_at_last_value(&self, kind: InputErrorKind) -> Defect {
        Defect {
            kind,
            byte_offset: self.file_offset(self.last_value),
            line: None,
        }
    }

    fn read_integer(&mut self, scalar: Scalar) -> Result<i64, Defect> {
        Ok(match scalar {
            Scalar::I8 => i8::from_le_bytes(self.take()?).into(),
            Scalar::U8 => u8::from_le_bytes(self.take()?).into(),
            Scalar::I16 => i16::from_le_bytes(self.take()?).into(),
            Scalar::U16 => u16::from_le_bytes(self.take()?).into(),
            Scalar::I32 => i32::from_le_bytes(self.take()?).into(),
            Scalar::U32 => u32::from_le_bytes(self.take()?).into(),
            Scalar::F32 | Scalar::F64 => {
                return Err(Defect {
                    kind: InputErrorKind::UnsupportedProperty(
                        "floating-point value where an integer is required".into(),
                    ),
                    byte_offset: self.file_offset(self.position),
                    line: None,
                });
            }
        })
    }

    fn read_float(&mut self, scalar: Scalar) -> Result<f64, Defect> {
        match scalar {
            Scalar::F32 => Ok(f32::from_le_bytes(self.take()?).into()),
            Scalar::F64 => Ok(f64::from_le_bytes(self.take()?)),
            integer => self.read_integer(integer).map(|value| value as f64),
        }
    }

    fn skip_scalars(&mut self, scalar: Scalar, count: u64) -> Result<(), Defect> {
        let length = count.saturating_mul(scalar.size() as u64);
        self.skip_bytes(length)
    }
}
