//! Access to a strip's stored vertices whatever their encoding.
//!
//! [`VertexAccess`] is what traversal and decoding need: a vertex, or one coordinate of it. Code
//! generic over it is monomorphized per encoding, so the lossless path reads `&[Point]` exactly
//! as it would without the abstraction, and the quantized path decodes in place with no branch
//! per vertex. [`StripVertices`] is the one branch, per strip, between the two.

use super::quantized::GridVertices;
use crate::geometry::Point;

/// Read access to the vertices of one strip.
pub trait VertexAccess: Copy {
    fn point(&self, index: usize) -> Point;
    fn coordinate(&self, index: usize, axis: usize) -> f32;
}

impl VertexAccess for &[Point] {
    #[inline(always)]
    fn point(&self, index: usize) -> Point {
        self[index]
    }

    #[inline(always)]
    fn coordinate(&self, index: usize, axis: usize) -> f32 {
        self[index][axis]
    }
}

impl VertexAccess for GridVertices<'_> {
    #[inline(always)]
    fn point(&self, index: usize) -> Point {
        GridVertices::point(self, index)
    }

    #[inline(always)]
    fn coordinate(&self, index: usize, axis: usize) -> f32 {
        GridVertices::coordinate(self, index, axis)
    }
}

/// A strip's vertices in the file's encoding.
#[derive(Clone, Copy, Debug)]
pub enum StripVertices<'a> {
    /// Lossless f32 copies, viewed in place.
    F32(&'a [Point]),
    /// Grid points decoded on access.
    Grid(GridVertices<'a>),
}

impl StripVertices<'_> {
    pub fn len(&self) -> usize {
        match self {
            StripVertices::F32(points) => points.len(),
            StripVertices::Grid(grid) => grid.len(),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Vertex `index` (below [`StripVertices::len`]) as the tracer sees it.
    pub fn point(&self, index: usize) -> Point {
        match self {
            StripVertices::F32(points) => points[index],
            StripVertices::Grid(grid) => grid.point(index),
        }
    }

    pub fn coordinate(&self, index: usize, axis: usize) -> f32 {
        match self {
            StripVertices::F32(points) => points[index][axis],
            StripVertices::Grid(grid) => grid.coordinate(index, axis),
        }
    }

    /// Every vertex in stored order.
    pub fn iter(&self) -> impl Iterator<Item = Point> + '_ {
        (0..self.len()).map(|i| self.point(i))
    }
}
