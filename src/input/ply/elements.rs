//! Decoding single element instances — a vertex, a face, or any element to skip — from either
//! body encoding.
//!
//! Faces are triangulated as fans `(v0, vi, vi+1)` while they are read, so no per-face buffer
//! is needed and winding is kept. Every value is checked where it is read (index range,
//! finiteness, list lengths), so the defect points at the exact byte.

use crate::geometry::Point;
use crate::input::error::InputErrorKind;

use crate::input::AttributeRequest;

use super::header::{FaceLayout, Property, Scalar, VertexLayout, VertexRole, COLOR_NAMES};
use super::values::{Defect, ValueReader};

const AXIS_LETTERS: [char; 3] = ['x', 'y', 'z'];

/// One vertex as read: its position and, when asked for, its normal and colour (opaque
/// black and a zero normal when not).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct VertexValues {
    pub position: Point,
    pub normal: [f32; 3],
    pub color: [u8; 4],
}

/// The colour of a vertex without one in the file, or before its channels are read: alpha is
/// opaque when the file has no `alpha`.
pub(crate) const DEFAULT_COLOR: [u8; 4] = [0, 0, 0, 255];

pub(crate) fn read_vertex<R: ValueReader>(
    reader: &mut R,
    layout: &VertexLayout,
    request: AttributeRequest,
) -> Result<VertexValues, Defect> {
    let mut vertex = VertexValues {
        position: [0.0; 3],
        normal: [0.0; 3],
        color: DEFAULT_COLOR,
    };
    for role in &layout.roles {
        match *role {
            VertexRole::Coordinate { axis, scalar } => {
                let value = reader.read_float(scalar)?;
                vertex.position[axis] = narrow_coordinate(reader, axis, value)?;
            }
            VertexRole::Normal { axis, scalar } if request.normals => {
                vertex.normal[axis] = read_normal_component(reader, axis, scalar)?;
            }
            VertexRole::Color { channel, scalar } if request.colors => {
                vertex.color[channel] = read_color_channel(reader, channel, scalar)?;
            }
            other => reader.skip_property(other.property())?,
        }
    }
    Ok(vertex)
}

/// Reads a normal component (float or double) and narrows it to f32, rejecting NaN and
/// infinities (also doubles beyond the f32 range, which would become infinities).
pub(crate) fn read_normal_component<R: ValueReader>(
    reader: &mut R,
    axis: usize,
    scalar: Scalar,
) -> Result<f32, Defect> {
    let value = reader.read_float(scalar)?;
    let narrowed = value as f32;
    if !narrowed.is_finite() {
        let kind = InputErrorKind::NonFiniteNormal {
            axis: AXIS_LETTERS[axis],
            value,
        };
        return Err(reader.defect_at_last_value(kind));
    }
    Ok(narrowed)
}

/// Reads a colour channel: uchar as it is, float or double in 0..1 scaled to 0..255 and
/// rounded to the nearest.
pub(crate) fn read_color_channel<R: ValueReader>(
    reader: &mut R,
    channel: usize,
    scalar: Scalar,
) -> Result<u8, Defect> {
    if scalar == Scalar::U8 {
        // An uchar read as an integer is within 0..=255.
        return Ok(reader.read_integer(scalar)? as u8);
    }
    let value = reader.read_float(scalar)?;
    unit_to_u8(value).ok_or_else(|| {
        let kind = InputErrorKind::ColorOutOfRange {
            channel: COLOR_NAMES[channel],
            value,
        };
        reader.defect_at_last_value(kind)
    })
}

/// A colour component in 0..1 as 0..255, rounded to the nearest; `None` outside 0..1 or NaN.
pub(crate) fn unit_to_u8(value: f64) -> Option<u8> {
    (0.0..=1.0)
        .contains(&value)
        .then(|| (value * 255.0).round() as u8)
}

/// Converts a coordinate to f32, rejecting NaN, infinities and magnitudes beyond
/// [`crate::geometry::MAX_COORDINATE`] (which the tracer's single-precision arithmetic cannot
/// take, and which doubles would otherwise turn into silent infinities).
pub(crate) fn narrow_coordinate<R: ValueReader>(
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
pub(crate) fn read_face<R: ValueReader>(
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
pub(crate) fn read_vertex_index<R: ValueReader>(
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

pub(crate) fn skip_properties<R: ValueReader>(
    reader: &mut R,
    properties: &[Property],
) -> Result<(), Defect> {
    properties
        .iter()
        .try_for_each(|&property| reader.skip_property(property))
}
