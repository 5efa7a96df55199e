//! The order `cast_rays` and `test_occlusions` trace a batch in. Answers do not depend on it
//! (packets and single rays give bit-identical hits); the work does:
//! * A row-major pinhole camera (one origin, directions stepping evenly along each row, as
//!   Open3D's `create_rays_pinhole` and an `(H, W, 6)` grid give them) is traced in bands of
//!   whole rows, each band tile by tile in the packet blocks `reducem render` traces
//!   ([`reducem::render::tiles`]): packets of compact blocks stay together deeper in the
//!   hierarchy than packets of eight rays of one row.
//! * An incoherent batch is traced in the order `reducem query` traces it
//!   ([`coherent_order`]: by direction octant and origin cell), its answers put back in place.
//! * Anything else in its own order, chunk by chunk.

use std::ops::Range;

use reducem_core::trace::{coherent_order, Ray};

use crate::rays::{self, Components, Gathered, Rays};

/// Rays traced by one task in input order: the chunk size of `reducem query` (large enough to
/// amortize scheduling and keep packets of consecutive rays, small enough to balance).
pub const CHUNK: usize = 4096;

/// Rows of a band: the height of `reducem render`'s tiles.
const BAND_ROWS: usize = 8;

/// Rays sampled to tell a camera: their origins must all be the first ray's.
const ORIGIN_SAMPLES: usize = 64;

/// Rows sampled to confirm a row width found in a flat batch.
const ROW_SAMPLES: usize = 16;

/// Rays searched for the end of a flat batch's first row.
const LONGEST_ROW: usize = 1 << 16;

/// How a batch of rays is cut into chunks and in which order a chunk's rays are traced.
pub enum ChunkOrder {
    /// Consecutive rays, [`CHUNK`] at a time, in their order.
    Input,
    /// Bands of [`BAND_ROWS`] rows of an image `width` rays wide; `band` and `last_band` list
    /// a full band's and the last band's rays (offsets in the band) tile by tile.
    Image {
        width: usize,
        band: Vec<u32>,
        last_band: Vec<u32>,
    },
}

impl ChunkOrder {
    /// Bands for rays that are a pinhole camera's in row-major order, else input order.
    pub fn of(rays: &Rays, shape: &[usize]) -> ChunkOrder {
        let Rays::All { components, .. } = rays else {
            return ChunkOrder::Input;
        };
        let Some(width) = camera_width(*components, shape) else {
            return ChunkOrder::Input;
        };
        let rows = components.len() / width;
        let last_rows = match rows % BAND_ROWS {
            0 => BAND_ROWS,
            rest => rest,
        };
        ChunkOrder::Image {
            width,
            band: band_order(width, BAND_ROWS),
            last_band: band_order(width, last_rows),
        }
    }

    /// Rays per chunk (the last may have fewer).
    pub fn chunk_rays(&self) -> usize {
        match self {
            ChunkOrder::Input => CHUNK,
            ChunkOrder::Image { width, .. } => BAND_ROWS * width,
        }
    }

    /// The rays of chunk `range` of `rays`, in the order they are traced, into `chunk`; or
    /// the index of the chunk's first invalid ray.
    pub fn read(&self, rays: &Rays, range: Range<usize>, chunk: &mut Chunk) -> Option<usize> {
        chunk.places.clear();
        let ChunkOrder::Image {
            band, last_band, ..
        } = self
        else {
            chunk.places.extend(0..range.len() as u32);
            return rays.chunk_into(range, &mut chunk.rays);
        };
        let order = if range.len() == band.len() {
            band
        } else {
            last_band
        };
        let invalid = rays.gather_into(range.start, order, &mut chunk.rays);
        if invalid.is_some() {
            return invalid;
        }
        chunk.places.extend_from_slice(order);
        None
    }
}

/// The rays of one chunk as they are traced, and each one's offset in the chunk; buffers a
/// thread reuses from chunk to chunk.
#[derive(Default)]
pub struct Chunk {
    pub rays: Vec<Ray>,
    pub places: Vec<u32>,
}

/// `rays` to be traced in the order `reducem query` traces an incoherent batch
/// ([`coherent_order`]), each with its position among the caller's rays; `rays` as they are
/// when their order is coherent enough (or too few to reorder), `Err` with the first invalid
/// ray's index.
pub fn sorted(rays: Rays) -> Result<Rays, usize> {
    match rays {
        Rays::All {
            components,
            tnear,
            tfar,
        } => {
            let all = rays::read_all(components, (tnear, tfar))?;
            Ok(match coherent_order(&all) {
                Some(order) => Rays::Gathered(Gathered {
                    rays: all,
                    order: Some(order),
                    positions: None,
                    total: components.len(),
                }),
                None => rays,
            })
        }
        Rays::Gathered(mut gathered) => {
            gathered.order = coherent_order(&gathered.rays);
            Ok(Rays::Gathered(gathered))
        }
    }
}

/// The offsets in a band of `rows` rows, `width` wide, tile by tile in packet order.
fn band_order(width: usize, rows: usize) -> Vec<u32> {
    reducem::render::tiles(width as u32, rows as u32).concat()
}

/// The row width of `components` when they are a pinhole camera's rays in row-major order:
/// one origin (sampled), and rows either the array's last leading axis or, in a flat batch,
/// found where the step between consecutive directions jumps.
fn camera_width(components: Components<'_>, shape: &[usize]) -> Option<usize> {
    let count = components.len();
    // Too few rays for bands to pay; the row search below needs a few steps.
    if count < 2 * BAND_ROWS {
        return None;
    }
    let origin = |i: usize| -> [f32; 3] { std::array::from_fn(|k| components.ray(i)[k]) };
    let first = origin(0);
    let step = (count / ORIGIN_SAMPLES).max(1);
    if (0..count).step_by(step).any(|i| origin(i) != first) {
        return None;
    }
    let width = match shape {
        [.., rows, width] if *rows > 1 => *width,
        _ => row_width(components)?,
    };
    (width > 1 && count.is_multiple_of(width) && count / width > 1).then_some(width)
}

/// The length of the first row of a flat batch of camera rays: where the step between
/// consecutive directions stops being about the previous one; confirmed on sampled rows.
fn row_width(components: Components<'_>) -> Option<usize> {
    let count = components.len();
    let direction = |i: usize| -> [f32; 3] { std::array::from_fn(|k| components.ray(i)[3 + k]) };
    let step = |i: usize| difference(direction(i + 1), direction(i));
    let jumps_after = |i: usize| i >= 1 && jumps(step(i - 1), step(i));
    let width = (1..count.min(LONGEST_ROW) - 1).find(|&i| jumps_after(i))? + 1;
    if !count.is_multiple_of(width) {
        return None;
    }
    let rows = count / width;
    (1..rows)
        .step_by((rows / ROW_SAMPLES).max(1))
        .all(|row| jumps_after(row * width - 1))
        .then_some(width)
}

/// Whether `next` is far from `previous` (a row's end), not a smooth change of step.
fn jumps(previous: [f32; 3], next: [f32; 3]) -> bool {
    let size = |v: [f32; 3]| v.iter().map(|x| x.abs()).sum::<f32>();
    size(difference(next, previous)) > 0.5 * size(previous)
}

fn difference(a: [f32; 3], b: [f32; 3]) -> [f32; 3] {
    std::array::from_fn(|k| a[k] - b[k])
}
