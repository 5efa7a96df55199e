//! The one global fixed-point grid of the quantized vertex encoding.
//!
//! Every vertex of a quantized file is a grid point `q` (three integers below `2^bits`) of a
//! cubic grid fixed over the whole model: `origin + q * cell` per axis. Because the grid is
//! global, a vertex shared by two strips, or by two chunks converted on different machines,
//! becomes the same grid point everywhere, and [`Grid::decode_axis`] (the one decode expression
//! of the project: the reader, the tracer, `decode` and the tests all go through it) turns the
//! same grid point into the same f32 everywhere. Bit-identical shared vertices are what keeps the
//! watertight test watertight, exactly as for lossless files.
//!
//! Design choices:
//! * The cell is a power of two and the origin a multiple of it, so `q * cell` is exact and the
//!   sum rounds at most once (not at all while `origin / cell + q` stays below `2^24`, which is
//!   the common case); the error of a vertex is then at most half a cell per axis. The price is
//!   that the grid may be up to twice as coarse as `bits` over the model's largest extent would
//!   allow (at most one bit of precision).
//! * One cell size for all three axes (a cubic grid): the error is isotropic, and thin axes of a
//!   strip cost few offset bits (see [`super::quantized`]).
//! * Decoding is monotone in `q` (exact products, monotone rounding of the sum), so a split
//!   bound chosen on decoded values stays conservative for the decoded vertices it bounds.
//! * At most 24 bits: every `q` converts to f32 exactly, and a finer grid than the f32 mantissa
//!   over the model's extent would store noise.

use crate::geometry::{Aabb, Point};

/// Finest grid: grid coordinates must convert to f32 exactly.
pub const MAX_GRID_BITS: u32 = 24;

/// A cubic grid of `2^bits` points per axis from `origin` in steps of `cell`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Grid {
    pub bits: u32,
    pub origin: Point,
    /// A power of two.
    pub cell: f32,
}

impl Grid {
    /// The grid of `bits` (1..=[`MAX_GRID_BITS`]) bits per axis covering `bounds` with the
    /// smallest power-of-two cell: every point of `bounds` rounds to a grid point in range.
    pub fn over(bounds: &Aabb, bits: u32) -> Grid {
        let bits = bits.clamp(1, MAX_GRID_BITS);
        if bounds.is_empty() {
            return Grid {
                bits,
                origin: [0.0; 3],
                cell: 1.0,
            };
        }
        let last = ((1u64 << bits) - 1) as f64;
        let extent = (0..3).map(|a| bounds.extent(a) as f64).fold(0.0, f64::max);
        // Start one below the estimate, so rounding of the logarithm never skips the best cell;
        // a model of zero extent starts (and stays) at the finest normal cell.
        let estimate = (extent / last).log2().ceil() - 1.0;
        let mut exponent = estimate.clamp(-126.0, 127.0) as i32;
        loop {
            let grid = Grid::with_exponent(bounds, bits, exponent);
            let fits = (0..3).all(|a| grid.offset(bounds.max[a], a).round() <= last);
            if fits || exponent == 127 {
                return grid;
            }
            exponent += 1;
        }
    }

    /// The grid with cell `2^exponent` whose origin is the largest multiple of the cell at or
    /// below `bounds.min`. Such a multiple is an f32: it is a multiple of a power of two no
    /// finer than the ulp of `bounds.min` or else `bounds.min` itself.
    fn with_exponent(bounds: &Aabb, bits: u32, exponent: i32) -> Grid {
        let cell = 2f64.powi(exponent);
        Grid {
            bits,
            // `+ 0.0` keeps a -0.0 origin out of the header.
            origin: bounds
                .min
                .map(|m| ((m as f64 / cell).floor() * cell) as f32 + 0.0),
            cell: cell as f32,
        }
    }

    /// `(coordinate - origin) / cell` in f64 (exact for coordinates near the model).
    fn offset(&self, coordinate: f32, axis: usize) -> f64 {
        (coordinate as f64 - self.origin[axis] as f64) / self.cell as f64
    }

    /// The largest grid coordinate, `2^bits - 1`.
    pub fn last(&self) -> u32 {
        (1u32 << self.bits) - 1
    }

    /// The nearest grid point (clamped to the grid).
    pub fn quantize(&self, p: &Point) -> [u32; 3] {
        let last = self.last() as f64;
        [0, 1, 2].map(|a| self.offset(p[a], a).round().clamp(0.0, last) as u32)
    }

    /// The position of grid coordinate `q` on `axis`: the one decode expression.
    #[inline(always)]
    pub fn decode_axis(&self, q: u32, axis: usize) -> f32 {
        self.origin[axis] + q as f32 * self.cell
    }

    pub fn decode(&self, q: &[u32; 3]) -> Point {
        [0, 1, 2].map(|a| self.decode_axis(q[a], a))
    }

    /// The farthest grid point from the origin, decoded.
    pub fn far_corner(&self) -> Point {
        self.decode(&[self.last(); 3])
    }
}

/// Largest coordinate of the [`NodeGrid`]: node boxes are stored as u16.
pub const NODE_GRID_LAST: u16 = u16::MAX;

/// The grid of the top-level node boxes of a grid file (format 2.2): the model grid's origin
/// with its cell scaled by `2^shift`, the smallest scale whose 2^16 points cover the model.
///
/// A coarser grid of the same origin keeps the one decode expression (`origin + q * cell`, an
/// exact product and one rounded sum, see [`Grid::decode_axis`]), so a box decodes to the same
/// f32 in the writer's rounding and in every traversal lane; boxes are rounded outward to it,
/// which decoding being monotone in `q` makes conservative.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NodeGrid {
    pub origin: Point,
    /// `grid.cell * 2^shift`, a power of two.
    pub cell: f32,
    pub shift: u32,
}

impl NodeGrid {
    /// The node grid of `grid` with cell `grid.cell * 2^shift`; `None` when that cell or the
    /// grid's far corner is not a finite normal f32.
    pub fn new(grid: &Grid, shift: u32) -> Option<NodeGrid> {
        let cell = (grid.cell as f64 * 2f64.powi(shift.min(300) as i32)) as f32;
        let node = NodeGrid {
            origin: grid.origin,
            cell,
            shift,
        };
        let far = [0, 1, 2].map(|a| node.decode_axis(NODE_GRID_LAST, a));
        (cell.is_normal() && far.iter().all(|c| c.is_finite())).then_some(node)
    }

    /// The finest node grid of `grid` whose far corner is at or beyond `bounds.max` (the
    /// model's decoded bounds, which hold every strip box); `None` when no finite one is (only
    /// for grids ending near `f32::MAX`).
    pub fn over(grid: &Grid, bounds: &Aabb) -> Option<NodeGrid> {
        (0..=u8::MAX as u32)
            .filter_map(|shift| NodeGrid::new(grid, shift))
            .find(|node| {
                let covers = |a: usize| node.decode_axis(NODE_GRID_LAST, a) >= bounds.max[a];
                bounds.is_empty() || (0..3).all(covers)
            })
    }

    /// The position of node grid coordinate `q` on `axis`: the decode expression of
    /// [`Grid::decode_axis`] with the node cell.
    #[inline(always)]
    pub fn decode_axis(&self, q: u16, axis: usize) -> f32 {
        self.origin[axis] + q as f32 * self.cell
    }

    /// The largest coordinate decoding at or below `value`, or `None` when even 0 is above it.
    pub fn floor(&self, value: f32, axis: usize) -> Option<u16> {
        let mut q = self.estimate(value, axis);
        while q > 0 && self.decode_axis(q, axis) > value {
            q -= 1;
        }
        while q < NODE_GRID_LAST && self.decode_axis(q + 1, axis) <= value {
            q += 1;
        }
        (self.decode_axis(q, axis) <= value).then_some(q)
    }

    /// The smallest coordinate decoding at or above `value`, or `None` when even the last is
    /// below it.
    pub fn ceil(&self, value: f32, axis: usize) -> Option<u16> {
        let mut q = self.estimate(value, axis);
        while q < NODE_GRID_LAST && self.decode_axis(q, axis) < value {
            q += 1;
        }
        while q > 0 && self.decode_axis(q - 1, axis) >= value {
            q -= 1;
        }
        (self.decode_axis(q, axis) >= value).then_some(q)
    }

    /// A coordinate near `value`, which [`NodeGrid::floor`] and [`NodeGrid::ceil`] adjust by
    /// the decode expression itself (a step or two).
    fn estimate(&self, value: f32, axis: usize) -> u16 {
        let offset = (value as f64 - self.origin[axis] as f64) / self.cell as f64;
        offset.round().clamp(0.0, NODE_GRID_LAST as f64) as u16
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn bounds(min: Point, max: Point) -> Aabb {
        Aabb { min, max }
    }

    #[test]
    fn unit_box_at_eight_bits_takes_the_cell_just_above_extent_over_255() {
        let grid = Grid::over(&bounds([0.0; 3], [1.0; 3]), 8);
        assert_eq!(grid.cell, 1.0 / 128.0);
        assert_eq!(grid.origin, [0.0; 3]);
        assert_eq!(grid.quantize(&[1.0; 3]), [128; 3]);
    }

    #[test]
    fn every_point_of_the_bounds_lands_in_range_within_half_a_cell() {
        let b = bounds([-3.7, 10.25, -0.001], [12.9, 10.5, 0.002]);
        for bits in [1, 2, 7, 16, 20, 24] {
            let grid = Grid::over(&b, bits);
            assert_eq!(grid.cell.to_bits() & 0x7f_ffff, 0, "power of two");
            for t in 0..=64 {
                let t = t as f32 / 64.0;
                let p = [0, 1, 2].map(|a| b.min[a] + t * (b.max[a] - b.min[a]));
                let q = grid.quantize(&p);
                assert!(q.iter().all(|&c| c <= grid.last()), "bits {bits}: {q:?}");
                let d = grid.decode(&q);
                for a in 0..3 {
                    assert!(
                        (d[a] - p[a]).abs() <= grid.cell / 2.0,
                        "bits {bits} axis {a}"
                    );
                }
            }
        }
    }

    #[test]
    fn the_cell_is_the_smallest_power_of_two_that_fits() {
        let b = bounds([0.0; 3], [1000.0, 1.0, 1.0]);
        let grid = Grid::over(&b, 16);
        let finer = Grid::with_exponent(&b, 16, grid.cell.log2() as i32 - 1);
        assert!(finer.offset(1000.0, 0).round() > finer.last() as f64);
    }

    #[test]
    fn decoding_is_monotone_far_from_the_origin() {
        let grid = Grid::over(&bounds([1.0e6; 3], [1.0e6 + 1.0; 3]), 24);
        let mut previous = f32::NEG_INFINITY;
        for q in (0..grid.last()).step_by(4099) {
            let x = grid.decode_axis(q, 0);
            assert!(x >= previous);
            previous = x;
        }
    }

    #[test]
    fn a_flat_or_empty_model_still_has_a_valid_grid() {
        let flat = Grid::over(&bounds([5.0, 5.0, 5.0], [5.0, 5.0, 5.0]), 20);
        assert_eq!(flat.decode(&flat.quantize(&[5.0; 3])), [5.0; 3]);
        let empty = Grid::over(&Aabb::EMPTY, 20);
        assert_eq!(empty.cell, 1.0);
    }

    #[test]
    fn node_grid_covers_the_model_and_rounds_outward() {
        let b = bounds([-3.7, 10.25, -0.001], [12.9, 10.5, 0.002]);
        for bits in [1, 8, 16, 17, 20, 24] {
            let grid = Grid::over(&b, bits);
            let node = NodeGrid::over(&grid, &b).unwrap();
            assert!(node.shift <= bits.saturating_sub(15), "bits {bits}");
            for t in 0..=64 {
                let t = t as f32 / 64.0;
                for a in 0..3 {
                    let v = b.min[a] + t * (b.max[a] - b.min[a]);
                    let (lo, hi) = (node.floor(v, a).unwrap(), node.ceil(v, a).unwrap());
                    assert!(node.decode_axis(lo, a) <= v && node.decode_axis(hi, a) >= v);
                    assert!(hi - lo <= 1 && (lo == 0 || node.decode_axis(lo + 1, a) > v));
                }
            }
        }
    }
}
