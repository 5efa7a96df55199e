//! Reading values from an ASCII PLY body in the mapped file.
//!
//! The body is treated as a stream of whitespace-separated tokens rather than as lines, which
//! handles CRLF, trailing blanks and writers that wrap long lists without special cases; line
//! numbers are still counted while skipping whitespace so defects can name the line. Floats
//! declared `float` are parsed directly as f32 (not via f64) so that ASCII and binary files
//! describing the same values decode to identical bits.

use std::str::FromStr;

use super::header::Scalar;
use super::values::{Defect, ValueReader};
use crate::input::error::InputErrorKind;

pub(crate) struct AsciiReader<'a> {
    bytes: &'a [u8],
    position: usize,
    line: u64,
    last_token: (usize, u64),
}

impl<'a> AsciiReader<'a> {
    pub(crate) fn new(bytes: &'a [u8], position: usize, line: u64) -> AsciiReader<'a> {
        AsciiReader {
            bytes,
            position,
            line,
            last_token: (position, line),
        }
    }

    pub(crate) fn position(&self) -> usize {
        self.position
    }

    pub(crate) fn line(&self) -> u64 {
        self.line
    }

    fn next_token(&mut self) -> Result<&'a [u8], Defect> {
        let bytes = self.bytes;
        while let Some(&byte) = bytes.get(self.position) {
            if !byte.is_ascii_whitespace() {
                break;
            }
            if byte == b'\n' {
                self.line += 1;
            }
            self.position += 1;
        }
        let start = self.position;
        self.last_token = (start, self.line);
        if start >= bytes.len() {
            return Err(self.defect_at_last_value(InputErrorKind::UnexpectedEndOfText));
        }
        let length = bytes[start..]
            .iter()
            .position(|byte| byte.is_ascii_whitespace())
            .unwrap_or(bytes.len() - start);
        self.position = start + length;
        Ok(&bytes[start..self.position])
    }

    fn parse_token<T: FromStr>(&mut self, expected: &'static str) -> Result<T, Defect> {
        let token = self.next_token()?;
        std::str::from_utf8(token)
            .ok()
            .and_then(|text| text.parse().ok())
            .ok_or_else(|| {
                let kind = InputErrorKind::MalformedToken {
                    token: String::from_utf8_lossy(token).into_owned(),
                    expected,
                };
                self.defect_at_last_value(kind)
            })
    }
}

impl ValueReader for AsciiReader<'_> {
    fn defect_at_last_value(&self, kind: InputErrorKind) -> Defect {
        let (byte_offset, line) = self.last_token;
        Defect {
            kind,
            byte_offset: byte_offset as u64,
            line: Some(line),
        }
    }

    fn read_integer(&mut self, _scalar: Scalar) -> Result<i64, Defect> {
        self.parse_token("integer")
    }

    fn read_float(&mut self, scalar: Scalar) -> Result<f64, Defect> {
        match scalar {
            Scalar::F32 => self.parse_token::<f32>("float").map(f64::from),
            _ => self.parse_token("number"),
        }
    }

    fn skip_scalars(&mut self, _scalar: Scalar, count: u64) -> Result<(), Defect> {
        for _ in 0..count {
            self.next_token()?;
        }
        Ok(())
    }
}
