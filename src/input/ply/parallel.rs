//! Parallel decoding of binary elements whose instances all have the same size.
//!
//! With a fixed stride, instance `i` starts at `start + i * stride`, so rayon workers decode
//! blocks independently straight into their slice of the output. Vertices qualify whenever
//! they have no list property. Faces never have a fixed stride in general, but nearly every
//! large mesh is all triangles; we *assume* a stride of three indices and let each block
//! confirm that every face it decodes has length 3. If any block finds another length, the
//! guess was wrong and the caller falls back to the sequential reader (which also produces
//! the proper error for faces shorter than 3), so the guess never changes results.
//!
//! Errors stay deterministic: each block stops at its first defect, and the first defect in
//! block order wins. All faces before it were triangles, so it is also the first defect a
//! sequential read would meet.
//!
//! The element may be a window of a larger one (see `input::stream`): `origin` and
//! `first_index` translate window-relative positions and indices back to the file's, so
//! errors read the same whichever way the element was mapped.

use std::path::Path;

use rayon::prelude::*;

use crate::geometry::Point;
use crate::input::error::InputError;

use super::binary::BinaryReader;
use super::elements::{
    narrow_coordinate, read_color_channel, read_normal_component, read_vertex_index, DEFAULT_COLOR,
};
use super::header::{Endian, FaceLayout, Property, Scalar, VertexLayout, VertexRole};
use super::values::{Defect, ValueReader};

const BLOCK: usize = 1 << 16;

/// A binary element of `count` fixed-size instances starting at `start` in `bytes`, with the
/// whole extent already known to lie inside `bytes`.
pub(crate) struct FixedStrideElement<'a> {
    pub path: &'a Path,
    pub name: &'a str,
    pub bytes: &'a [u8],
    /// File offset of `bytes[0]`.
    pub origin: u64,
    pub start: usize,
    /// Element index of the instance at `start`.
    pub first_index: u64,
    pub count: usize,
    pub endian: Endian,
}

impl FixedStrideElement<'_> {
    fn reader_at(&self, position: usize) -> BinaryReader<'_> {
        BinaryReader::new(self.bytes, position, self.endian).with_origin(self.origin)
    }

    fn error_at(&self, defect: Defect, index: usize) -> InputError {
        defect.at_element(self.path, self.name, self.first_index + index as u64)
    }
}

/// Offset within a vertex and type of x, y and z, of the normal and colour components the
/// file has, plus the vertex size, when it is fixed.
pub(crate) struct FixedVertex {
    stride: usize,
    coordinates: [(usize, Scalar); 3],
    normal: [Option<(usize, Scalar)>; 3],
    color: [Option<(usize, Scalar)>; 4],
}

impl FixedVertex {
    pub(crate) fn from_layout(layout: &VertexLayout) -> Option<FixedVertex> {
        let mut vertex = FixedVertex {
            stride: 0,
            coordinates: [(0, Scalar::F32); 3],
            normal: [None; 3],
            color: [None; 4],
        };
        for role in &layout.roles {
            let offset = vertex.stride;
            match *role {
                VertexRole::Coordinate { axis, scalar } => {
                    vertex.coordinates[axis] = (offset, scalar)
                }
                VertexRole::Normal { axis, scalar } => vertex.normal[axis] = Some((offset, scalar)),
                VertexRole::Color { channel, scalar } => {
                    vertex.color[channel] = Some((offset, scalar))
                }
                VertexRole::Skip(_) => {}
            }
            let Property::Scalar(scalar) = role.property() else {
                return None;
            };
            vertex.stride += scalar.size();
        }
        Some(vertex)
    }

    pub(crate) fn stride(&self) -> usize {
        self.stride
    }
}

/// Decodes every instance of `element` with `decode(element, index)`, in parallel blocks; the
/// first defect in element order wins.
pub(crate) fn decode_all<T, F>(
    element: &FixedStrideElement,
    decode: F,
) -> Result<Vec<T>, InputError>
where
    T: Clone + Default + Send,
    F: Fn(&FixedStrideElement, usize) -> Result<T, InputError> + Sync,
{
    let mut values = vec![T::default(); element.count];
    let outcomes: Vec<Result<(), InputError>> = values
        .par_chunks_mut(BLOCK)
        .enumerate()
        .map(|(block, out)| {
            let first = block * BLOCK;
            for (offset_in_block, value) in out.iter_mut().enumerate() {
                *value = decode(element, first + offset_in_block)?;
            }
            Ok(())
        })
        .collect();
    outcomes.into_iter().collect::<Result<(), _>>()?;
    Ok(values)
}

pub(crate) fn read_positions(
    element: &FixedStrideElement,
    vertex: &FixedVertex,
) -> Result<Vec<Point>, InputError> {
    decode_all(element, |element, index| {
        decode_vertex(element, vertex, index)
    })
}

/// Decodes instance `index` (counted from `element.start`, which must be below `element.count`).
pub(crate) fn decode_vertex(
    element: &FixedStrideElement,
    vertex: &FixedVertex,
    index: usize,
) -> Result<Point, InputError> {
    let base = element.start + index * vertex.stride;
    let mut point = [0.0; 3];
    for (axis, &(offset, scalar)) in vertex.coordinates.iter().enumerate() {
        let mut reader = element.reader_at(base + offset);
        point[axis] = reader
            .read_float(scalar)
            .and_then(|value| narrow_coordinate(&reader, axis, value))
            .map_err(|defect| element.error_at(defect, index))?;
    }
    Ok(point)
}

/// The normal of instance `index`; the caller checked that the file has all three components.
pub(crate) fn decode_normal(
    element: &FixedStrideElement,
    vertex: &FixedVertex,
    index: usize,
) -> Result<[f32; 3], InputError> {
    let base = element.start + index * vertex.stride;
    let mut normal = [0.0; 3];
    for (axis, component) in vertex.normal.iter().enumerate() {
        let Some((offset, scalar)) = *component else {
            continue;
        };
        let mut reader = element.reader_at(base + offset);
        normal[axis] = read_normal_component(&mut reader, axis, scalar)
            .map_err(|defect| element.error_at(defect, index))?;
    }
    Ok(normal)
}

/// The colour of instance `index`, alpha opaque when the file has none.
pub(crate) fn decode_color(
    element: &FixedStrideElement,
    vertex: &FixedVertex,
    index: usize,
) -> Result<[u8; 4], InputError> {
    let base = element.start + index * vertex.stride;
    let mut color = DEFAULT_COLOR;
    for (channel, component) in vertex.color.iter().enumerate() {
        let Some((offset, scalar)) = *component else {
            continue;
        };
        let mut reader = element.reader_at(base + offset);
        color[channel] = read_color_channel(&mut reader, channel, scalar)
            .map_err(|defect| element.error_at(defect, index))?;
    }
    Ok(color)
}

/// Face layout under the all-triangles assumption.
pub(crate) struct TriangleFaces {
    length_offset: usize,
    length: Scalar,
    index: Scalar,
    stride: usize,
}

impl TriangleFaces {
    pub(crate) fn from_layout(layout: &FaceLayout) -> Option<TriangleFaces> {
        let before = fixed_size(&layout.before)?;
        let after = fixed_size(&layout.after)?;
        Some(TriangleFaces {
            length_offset: before,
            length: layout.length,
            index: layout.index,
            stride: before + layout.length.size() + 3 * layout.index.size() + after,
        })
    }

    pub(crate) fn stride(&self) -> usize {
        self.stride
    }
}

fn fixed_size(properties: &[Property]) -> Option<usize> {
    properties
        .iter()
        .map(|property| match property {
            Property::Scalar(scalar) => Some(scalar.size()),
            Property::List { .. } => None,
        })
        .sum()
}

enum BlockOutcome {
    Decoded,
    NotAllTriangles,
    Failed(InputError),
}

/// Decodes all faces as triangles; `None` when some face is not a triangle.
pub(crate) fn read_triangles(
    element: &FixedStrideElement,
    faces: &TriangleFaces,
    vertex_count: u64,
) -> Option<Result<Vec<[u32; 3]>, InputError>> {
    let mut triangles = vec![[0; 3]; element.count];
    let outcomes: Vec<BlockOutcome> = triangles
        .par_chunks_mut(BLOCK)
        .enumerate()
        .map(|(block, out)| decode_triangle_block(element, faces, vertex_count, block * BLOCK, out))
        .collect();
    for outcome in outcomes {
        match outcome {
            BlockOutcome::Decoded => {}
            BlockOutcome::NotAllTriangles => return None,
            BlockOutcome::Failed(error) => return Some(Err(error)),
        }
    }
    Some(Ok(triangles))
}

fn decode_triangle_block(
    element: &FixedStrideElement,
    faces: &TriangleFaces,
    vertex_count: u64,
    first: usize,
    out: &mut [[u32; 3]],
) -> BlockOutcome {
    for (offset_in_block, triangle) in out.iter_mut().enumerate() {
        let index = first + offset_in_block;
        let base = element.start + index * faces.stride + faces.length_offset;
        let mut reader = element.reader_at(base);
        let decoded = reader.read_list_length(faces.length).and_then(|length| {
            if length != 3 {
                return Ok(None);
            }
            let mut corners = [0; 3];
            for corner in &mut corners {
                *corner = read_vertex_index(&mut reader, faces.index, vertex_count)?;
            }
            Ok(Some(corners))
        });
        match decoded {
            Ok(Some(corners)) => *triangle = corners,
            Ok(None) => return BlockOutcome::NotAllTriangles,
            Err(defect) => return BlockOutcome::Failed(element.error_at(defect, index)),
        }
    }
    BlockOutcome::Decoded
}
