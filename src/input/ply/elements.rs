//! Decoding single element instances — a vertex, a face, or any element to skip — from either
//! body encoding.
//!
//! Faces are triangulated as fans `(v0, vi, vi+1)` while they are read, so no per-face buffer
//! is needed and winding is kept. Every value is checked where it is read (index range,
//! finiteness, list lengths), so the defect points at the exact byte.

use crate::geometry::Point;
use crate::input::error::InputErrorKind;

use super::header::{FaceLayout, Property, Scalar, VertexLayout, VertexRole};
use super::values::{Defect, ValueReader};

const AXIS_LETTERS: [char; 3] = ['x', 'y', 'z'];

pub fn read_vertex<R: ValueReader>(reader: &mut R, layout: &VertexLayout) -> Result<Point, Defect> {
    let mut point = [0.0; 3];
    for role in &layout.roles {
        match *role {
            VertexRole::Coordinate { axis, scalar } => {
                let value = reader.read_float(scalar)?;
                point[axis] = narrow_coordinate(reader, axis, value)?;
            }
            VertexRole::Skip(property) => reader.skip_property(property)?,
        }
    }
    Ok(point)
}

/// Converts a coordinate to f32, rejecting NaN, infinities and magnitudes beyond
/// [`crate::geometry::MAX_COORDINATE`] (which the tracer's single-precision arithmetic cannot
/// take, and which doubles would otherwise turn into silent infinities).
pub fn narrow_coordinate<R: ValueReader>(
    reader: &R,
    axis: usize,
    value: f64,
) -> Result<f32, Defect> {
    let axis_letter = AXIS_LETTERS[axis];
    if !value.is_finite() {
        let kind = InputErrorKind::NonFiniteCoordinate {
            axis: axis_letter,
            value,
        };
        return Err(reader.defect_at_last_value(kind));
    }
    let narrowed = value as f32;
    if narrowed.abs() > crate::geometry::MAX_COORDINATE {
        let kind = InputErrorKind::CoordinateOutOfRange {
            axis: axis_letter,
            value,
        };
        return Err(reader.defect_at_last_value(kind));
    }
    Ok(narrowed)
}

/// Reads one face and emits its fan triangles.
pub fn read_face<R: ValueReader>(
    reader: &mut R,
    layout: &FaceLayout,
    vertex_count: u64,
    mut emit: impl FnMut([u32; 3]),
) -> Result<(), Defect> {
    skip_properties(reader, &layout.before)?;
    let length = reader.read_list_length(layout.length)?;
    if length < 3 {
        return Err(reader.defect_at_last_value(InputErrorKind::TooFewFaceVertices(length)));
    }
    let first = read_vertex_index(reader, layout.index, vertex_count)?;
    let mut previous = read_vertex_index(reader, layout.index, vertex_count)?;
    for _ in 2..length {
        let current = read_vertex_index(reader, layout.index, vertex_count)?;
        emit([first, previous, current]);
        previous = current;
    }
    skip_properties(reader, &layout.after)
}

/// Reads an index and checks it against the vertex count, which the caller guarantees is at
/// most 2^32 so that every in-range index fits in u32.
pub fn read_vertex_index<R: ValueReader>(
    reader: &mut R,
    scalar: Scalar,
    vertex_count: u64,
) -> Result<u32, Defect> {
    let index = reader.read_integer(scalar)?;
    match u32::try_from(index) {
        Ok(valid) if u64::from(valid) < vertex_count => Ok(valid),
        _ => Err(
            reader.defect_at_last_value(InputErrorKind::IndexOutOfRange {
                index,
                vertex_count,
            }),
        ),
    }
}

pub fn skip_properties<R: ValueReader>(
    reader: &mut R,
    properties: &[Property],
) -> Result<(), Defect> {
    properties
        .iter()
        .try_for_each(|&property| reader.skip_property(property))
}
