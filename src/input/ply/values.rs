//! The interface between element decoding and the two body encodings.
//!
//! Element logic (which property is a coordinate, fan triangulation, skipping) is written once
//! against [`ValueReader`] and monomorphised for binary and ASCII bodies, so both encodings
//! behave identically by construction. Readers report a [`Defect`] that knows only its byte
//! position; the element loop, which knows the element name and index, turns it into an
//! `InputError`.

use std::path::Path;

use super::header::{Property, Scalar};
use crate::input::error::{InputError, InputErrorKind, Location};

/// A defect at a byte position, not yet attributed to an element.
#[derive(Debug)]
pub(crate) struct Defect {
    pub kind: InputErrorKind,
    pub byte_offset: u64,
    pub line: Option<u64>,
}

impl Defect {
    pub(crate) fn at_element(self, path: &Path, element: &str, index: u64) -> InputError {
        let location = Location::Element {
            element: element.to_string(),
            index,
            byte_offset: self.byte_offset,
            line: self.line,
        };
        InputError::new(path, location, self.kind)
    }
}

/// Sequential access to the values of a PLY body.
pub(crate) trait ValueReader {
    /// A defect located at the start of the value read last.
    fn defect_at_last_value(&self, kind: InputErrorKind) -> Defect;
    fn read_integer(&mut self, scalar: Scalar) -> Result<i64, Defect>;
    fn read_float(&mut self, scalar: Scalar) -> Result<f64, Defect>;
    fn skip_scalars(&mut self, scalar: Scalar, count: u64) -> Result<(), Defect>;

    /// Reads a list length, rejecting negative ones (possible with signed count types).
    fn read_list_length(&mut self, count: Scalar) -> Result<u64, Defect> {
        let length = self.read_integer(count)?;
        u64::try_from(length)
            .map_err(|_| self.defect_at_last_value(InputErrorKind::NegativeListLength(length)))
    }

    fn skip_property(&mut self, property: Property) -> Result<(), Defect> {
        match property {
            Property::Scalar(scalar) => self.skip_scalars(scalar, 1),
            Property::List { count, item } => {
                let length = self.read_list_length(count)?;
                self.skip_scalars(item, length)
            }
        }
    }
}
