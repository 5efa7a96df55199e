//! Access to a strip's stored vertices whatever their encoding.
//!
//! [`VertexAccess`] is what traversal and decoding need: a vertex, or one coordinate of it. Code
//! generic over it is monomorphized per encoding, so the lossless path reads `&[Point]` exactly
//! as it would without the abstraction, and the quantized path decodes in place with no branch
//! per vertex. [`StripVertices`] is the one branch, per strip, between the two.

use wide::{f32x8, i32x8};

use super::quantized::GridVertices;
use crate::geometry::Point;

/// Read access to the vertices of one strip.
pub trait VertexAccess: Copy {
    fn point(&self, index: usize) -> Point;
    fn coordinate(&self, index: usize, axis: usize) -> f32;

    /// The coordinates on axes `KX`, `KY` and `KZ` of the vertices `references` name, one lane
    /// per reference (`N` at least 8). Bit-identical to [`VertexAccess::point`] in the first
    /// `used` lanes; later lanes may hold any value (an encoding whose vertices are costly to
    /// read skips them).
    fn gather<const KX: usize, const KY: usize, const KZ: usize, const N: usize>(
        &self,
        references: &[u8; N],
        used: usize,
    ) -> [[f32; N]; 3];

    /// The f32 vertices themselves when the encoding is lossless, for kernels that gather
    /// them straight into registers.
    fn lossless(&self) -> Option<&[Point]>;
}

/// What a reference beyond a strip's vertices reads: it can only come from a file changed
/// after it was validated (validation checks every reference), and a NaN vertex is missed by
/// every ray, where an index out of bounds would panic.
const BEYOND_THE_VERTICES: Point = [f32::NAN; 3];

impl VertexAccess for &[Point] {
    #[inline(always)]
    fn point(&self, index: usize) -> Point {
        self.get(index).copied().unwrap_or(BEYOND_THE_VERTICES)
    }

    #[inline(always)]
    fn coordinate(&self, index: usize, axis: usize) -> f32 {
        self.point(index)[axis]
    }

    /// Every lane: an f32 vertex is three loads, cheaper than a loop of unknown length.
    #[inline(always)]
    fn gather<const KX: usize, const KY: usize, const KZ: usize, const N: usize>(
        &self,
        references: &[u8; N],
        _used: usize,
    ) -> [[f32; N]; 3] {
        // A loop over a fixed count: unrolled, and the zero fill is overwritten entirely, so
        // it is never stored.
        let mut model = [[0.0f32; N]; 3];
        for (position, &reference) in references.iter().enumerate() {
            let vertex = self.point(reference as usize);
            for (k, axis) in [KX, KY, KZ].into_iter().enumerate() {
                model[k][position] = vertex[axis];
            }
        }
        model
    }

    #[inline(always)]
    fn lossless(&self) -> Option<&[Point]> {
        Some(self)
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

    /// Grid points first, then [`crate::format::grid::Grid::decode_axis`] eight lanes at a
    /// time: the same two IEEE operations (an exact conversion, a product, a sum), so the same
    /// bits as one vertex at a time. Only the `used` lanes are read: a grid vertex costs a
    /// dozen operations, and blocks at a leaf's end are short.
    #[inline(always)]
    fn gather<const KX: usize, const KY: usize, const KZ: usize, const N: usize>(
        &self,
        references: &[u8; N],
        used: usize,
    ) -> [[f32; N]; 3] {
        let points = self.grid_points(references, used);
        let grid = self.grid();
        let cell = f32x8::splat(grid.cell);
        let mut model = [[0.0f32; N]; 3];
        for (k, axis) in [KX, KY, KZ].into_iter().enumerate() {
            let origin = f32x8::splat(grid.origin[axis]);
            // Eight lanes at a time, the last eight overlapping the previous ones when `N` is not
            // a multiple of 8: decoding a lane twice writes the same bits twice.
            for start in (0..N).step_by(8).map(|start| start.min(N - 8)) {
                // Grid coordinates are below 2^24: exact as i32 and as f32.
                let q: [i32; 8] = std::array::from_fn(|lane| points[axis][start + lane] as i32);
                let decoded = origin + f32x8::from_i32x8(i32x8::from(q)) * cell;
                model[k][start..start + 8].copy_from_slice(decoded.as_array());
            }
        }
        model
    }

    #[inline(always)]
    fn lossless(&self) -> Option<&[Point]> {
        None
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
            StripVertices::F32(points) => points.point(index),
            StripVertices::Grid(grid) => grid.point(index),
        }
    }

    pub fn coordinate(&self, index: usize, axis: usize) -> f32 {
        match self {
            StripVertices::F32(points) => points.coordinate(index, axis),
            StripVertices::Grid(grid) => grid.coordinate(index, axis),
        }
    }

    /// Every vertex in stored order.
    pub fn iter(&self) -> impl Iterator<Item = Point> + '_ {
        (0..self.len()).map(|i| self.point(i))
    }
}
