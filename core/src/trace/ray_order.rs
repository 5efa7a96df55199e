//! Ray reordering for incoherent batches, after Garanzha and Loop, "Fast Ray Sorting and
//! Breadth-First Packet Traversal for GPU Ray Tracing" (Eurographics 2010): rays are sorted by a
//! key made of their direction octant and the cell of their origin, so that consecutive rays
//! start near each other and point the same way. Here the cells of a 64³ grid over the batch's
//! origins are ordered along a Morton curve, the octant is the key's most significant part (each
//! octant sweeps the model once, in cache order), and the sort is a two-pass stable radix sort.
//!
//! A batch whose rays already come in coherent runs (camera rays in tile order, the AO rays of
//! each hit point after one another) is left alone: the order costs work and gains nothing
//! there. In a random order every ray touches another part of the model, about four times the
//! work of the same rays sorted. The answers do not depend on the order (packets and single
//! rays give bit-identical results), and the caller returns them in input order.

use rayon::prelude::*;

use super::ray::Ray;

/// Bits per axis of an origin's cell: 64 cells per axis, a 18-bit Morton code.
const CELL_BITS: u32 = 6;

/// Bits of the sort key: the octant (3) above the Morton code of the cell.
const KEY_BITS: u32 = 3 + 3 * CELL_BITS;

/// Rays sampled to decide whether a batch is coherent (each with the next) and to bound its
/// origins, at a small cost per batch.
const SAMPLES: usize = 1 << 12;

/// Evenly spaced runs of consecutive rays the sample is drawn in: 64 rays (2 KiB) a run, so
/// that sampling a mapped ray file faults in 64 of its pages on the one thread that decides,
/// not one read-around window per sampled ray (the whole file), which the tracing threads
/// then fault in together instead.
const SAMPLE_RUNS: usize = 64;

/// Batches smaller than this are never reordered: the per-chunk octant grouping of the tracer
/// already forms their packets, and the sort would not pay for itself.
const MIN_RAYS: usize = 1 << 16;

/// A batch is left in its order when at least this fraction of the sampled neighbours (a ray
/// and the next) start in the same cell.
const COHERENT_NEIGHBOURS: f64 = 0.5;

/// The order to trace `rays` in (indices into `rays`), or `None` when their own order is
/// coherent enough.
pub fn coherent_order(rays: &[Ray]) -> Option<Vec<u32>> {
    if rays.len() < MIN_RAYS || u32::try_from(rays.len()).is_err() {
        return None;
    }
    let grid = CellGrid::around(sampled(rays.len()).map(|i| &rays[i]));
    let same_cell = sampled(rays.len())
        .filter(|&i| grid.cell(&rays[i]) == grid.cell(&rays[i + 1]))
        .count();
    if same_cell as f64 >= COHERENT_NEIGHBOURS * SAMPLES as f64 {
        return None;
    }
    let keys: Vec<u32> = rays.par_iter().map(|ray| grid.key(ray)).collect();
    Some(radix_order(&keys))
}

/// The indices of the sampled rays of a batch of `rays` rays ([`MIN_RAYS`] at least): runs of
/// [`SAMPLES`] / [`SAMPLE_RUNS`] consecutive rays, evenly spaced, each sampled ray followed by
/// another in the batch.
fn sampled(rays: usize) -> impl Iterator<Item = usize> {
    let run = SAMPLES / SAMPLE_RUNS;
    let spacing = rays / SAMPLE_RUNS;
    (0..SAMPLE_RUNS).flat_map(move |k| k * spacing..k * spacing + run)
}

/// The grid of [`CELL_BITS`] per axis over the sampled origins' bounds; origins outside the
/// sample's bounds fall in the border cells.
struct CellGrid {
    low: [f32; 3],
    cells_per_unit: [f32; 3],
}

impl CellGrid {
    fn around<'r>(sample: impl Iterator<Item = &'r Ray>) -> CellGrid {
        let mut low = [f32::INFINITY; 3];
        let mut high = [f32::NEG_INFINITY; 3];
        for ray in sample {
            for axis in 0..3 {
                low[axis] = low[axis].min(ray.origin[axis]);
                high[axis] = high[axis].max(ray.origin[axis]);
            }
        }
        let cells = (1u32 << CELL_BITS) as f32;
        let cells_per_unit = std::array::from_fn(|axis| {
            let extent = high[axis] - low[axis];
            if extent > 0.0 && extent.is_finite() {
                cells / extent
            } else {
                0.0
            }
        });
        CellGrid {
            low,
            cells_per_unit,
        }
    }

    /// The Morton code of the cell of `ray`'s origin.
    fn cell(&self, ray: &Ray) -> u32 {
        let max = (1u32 << CELL_BITS) - 1;
        // `as` saturates (NaN to 0), so every origin lands in a cell.
        let index = |axis: usize| {
            (((ray.origin[axis] - self.low[axis]) * self.cells_per_unit[axis]) as u32).min(max)
        };
        spread_bits(index(0)) | spread_bits(index(1)) << 1 | spread_bits(index(2)) << 2
    }

    /// The sort key of `ray`: its direction's octant above its origin's cell.
    fn key(&self, ray: &Ray) -> u32 {
        let [x, y, z] = ray.direction.map(|d| d.is_sign_negative() as u32);
        (x | y << 1 | z << 2) << (3 * CELL_BITS) | self.cell(ray)
    }
}

/// The low [`CELL_BITS`] bits of `x` spread to every third bit (bit `i` to bit `3 i`).
fn spread_bits(x: u32) -> u32 {
    let mut x = x & ((1 << CELL_BITS) - 1);
    x = (x | x << 8) & 0x0000_f00f;
    x = (x | x << 4) & 0x000c_30c3;
    (x | x << 2) & 0x0024_9249
}

/// The indices of `keys` in the stable order of their keys ([`KEY_BITS`] bits): a least
/// significant digit radix sort in two counting passes.
fn radix_order(keys: &[u32]) -> Vec<u32> {
    const LOW_BITS: u32 = KEY_BITS / 2;
    let low = |index: u32| (keys[index as usize] & ((1 << LOW_BITS) - 1)) as usize;
    let high = |index: u32| (keys[index as usize] >> LOW_BITS) as usize;
    let by_low = counting_pass(0..keys.len() as u32, 1 << LOW_BITS, low);
    counting_pass(by_low.iter().copied(), 1 << (KEY_BITS - LOW_BITS), high)
}

/// `indices` stably sorted by `digit` (below `digits`).
fn counting_pass(
    indices: impl Iterator<Item = u32> + Clone,
    digits: usize,
    digit: impl Fn(u32) -> usize,
) -> Vec<u32> {
    let mut starts = vec![0usize; digits + 1];
    for index in indices.clone() {
        starts[digit(index) + 1] += 1;
    }
    for i in 1..starts.len() {
        starts[i] += starts[i - 1];
    }
    let mut sorted = vec![0u32; starts[digits]];
    for index in indices {
        let slot = &mut starts[digit(index)];
        sorted[*slot] = index;
        *slot += 1;
    }
    sorted
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ray(origin: [f32; 3], direction: [f32; 3]) -> Ray {
        Ray {
            origin,
            direction,
            tmin: 0.0,
            tmax: 1.0,
        }
    }

    /// A pseudo-random value in [0, 1) from `i` (a fixed hash: the test needs no generator).
    fn unit(i: u32) -> f32 {
        (i.wrapping_mul(2_654_435_761) >> 8) as f32 / (1u32 << 24) as f32
    }

    fn scattered(count: u32) -> Vec<Ray> {
        (0..count)
            .map(|i| {
                let origin = [unit(3 * i), unit(3 * i + 1), unit(3 * i + 2)];
                let direction = [unit(7 * i) - 0.5, unit(7 * i + 1) - 0.5, 0.25];
                ray(origin, direction)
            })
            .collect()
    }

    /// A scattered batch is reordered into a permutation whose keys never decrease, rays of one
    /// key keeping their input order.
    #[test]
    fn a_scattered_batch_is_sorted_by_octant_and_cell_stably() {
        // The test checks the keys on the grid the sort used: over the same sample.
        let rays = scattered(MIN_RAYS as u32);
        let order = coherent_order(&rays).expect("a scattered batch is reordered");
        let mut seen = vec![false; rays.len()];
        for &index in &order {
            assert!(!std::mem::replace(&mut seen[index as usize], true));
        }
        assert!(seen.iter().all(|&seen| seen));
        let grid = CellGrid::around(sampled(rays.len()).map(|i| &rays[i]));
        let key = |index: u32| grid.key(&rays[index as usize]);
        for pair in order.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            assert!(key(a) < key(b) || (key(a) == key(b) && a < b));
        }
    }

    /// Rays that come in runs from one origin (a hit point's AO rays), and camera rays from
    /// one point, keep their order; so does a small batch.
    #[test]
    fn coherent_and_small_batches_keep_their_order() {
        let per_point: Vec<Ray> = scattered(MIN_RAYS as u32 / 4)
            .iter()
            .flat_map(|point| {
                (0..16).map(|k| ray(point.origin, [unit(k) - 0.5, unit(k + 9) - 0.5, 1.0]))
            })
            .collect();
        assert!(coherent_order(&per_point).is_none());
        let camera: Vec<Ray> = scattered(MIN_RAYS as u32 * 2)
            .iter()
            .map(|r| ray([0.5; 3], r.direction))
            .collect();
        assert!(coherent_order(&camera).is_none());
        assert!(coherent_order(&scattered(MIN_RAYS as u32 - 1)).is_none());
    }

    #[test]
    fn morton_bits_interleave() {
        assert_eq!(spread_bits(0b11_1111), 0x9249);
        assert_eq!(spread_bits(0b10_0001), 1 << 15 | 1);
    }
}
