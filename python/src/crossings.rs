//! Every crossing of numpy rays, counted or listed, by the core's crossing walk
//! ([`reducem_core::query::crossings`]: a crossing through an edge or a vertex of a closed mesh
//! counts once), chunk by chunk on rayon's threads as `cast_rays` traces.

use rayon::prelude::*;
use reducem_core::format::reader::ReducemFile;
use reducem_core::query::crossings::for_each_crossing;
use reducem_core::trace::Ray;

use crate::primitive_ids::PrimitiveIds;
use crate::rays::Rays;

/// Rays walked by one task.
const CHUNK: usize = 1024;

/// The crossings of every ray, as `list_intersections` returns them: ray `i`'s are
/// `splits[i]..splits[i + 1]`, `t` ascending, ties by primitive id.
pub struct Crossings {
    pub splits: Vec<u32>,
    pub ray_ids: Vec<u32>,
    pub t: Vec<f32>,
    pub ids: Vec<u32>,
    pub uvs: Vec<f32>,
}

/// One crossing: `t`, primitive id, `u`, `v`.
type Crossing = (f32, u32, f32, f32);

/// One chunk's crossing counts per ray and its crossings, or its first invalid ray.
type ChunkCrossings = Result<(Vec<u32>, Vec<Crossing>), usize>;

/// The number of crossings of each ray in its interval (rays validated by
/// [`Rays::chunk_into`]: `Err` with the first invalid one's index).
pub fn count(file: &ReducemFile, rays: &Rays) -> Result<Vec<i32>, usize> {
    let mut counts = vec![0i32; rays.traced()];
    let first_invalid = counts
        .par_chunks_mut(CHUNK)
        .enumerate()
        .map_init(Vec::new, |traced, (chunk, out)| {
            let first = chunk * CHUNK;
            read(rays, first, out.len(), traced)?;
            for (count, ray) in out.iter_mut().zip(traced.iter()) {
                for_each_crossing(file, ray, |_, _, _| *count += 1);
            }
            Ok(())
        })
        .filter_map(Result::err)
        .min();
    first_invalid.map_or(Ok(counts), Err)
}

/// Every crossing of each ray in its interval, `t` ascending, ties by primitive id.
pub fn list(file: &ReducemFile, ids: &PrimitiveIds, rays: &Rays) -> Result<Crossings, usize> {
    let chunks: Vec<ChunkCrossings> = (0..rays.traced().div_ceil(CHUNK))
        .into_par_iter()
        .map_init(Vec::new, |traced, chunk| {
            let first = chunk * CHUNK;
            read(rays, first, CHUNK.min(rays.traced() - first), traced)?;
            let mut counts = Vec::with_capacity(traced.len());
            let mut found = Vec::new();
            for ray in traced.iter() {
                let start = found.len();
                for_each_crossing(file, ray, |strip, window, hit| {
                    let id = ids.id(file, strip, window);
                    found.push((hit.t, id, hit.weights[1], hit.weights[2]));
                });
                found[start..].sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                counts.push((found.len() - start) as u32);
            }
            Ok((counts, found))
        })
        .collect();
    // The first invalid ray of all, not of whichever chunk failed first.
    let first_invalid = chunks.iter().filter_map(|chunk| chunk.as_ref().err()).min();
    if let Some(&invalid) = first_invalid {
        return Err(invalid);
    }
    Ok(flatten(chunks.into_iter().flatten().collect()))
}

/// Rays `first .. first + len` into `traced`; `Err` with the first invalid one's index.
fn read(rays: &Rays, first: usize, len: usize, traced: &mut Vec<Ray>) -> Result<(), usize> {
    match rays.chunk_into(first..first + len, traced) {
        Some(invalid) => Err(invalid),
        None => Ok(()),
    }
}

/// The chunks' crossings as one list with the rays' splits.
fn flatten(chunks: Vec<(Vec<u32>, Vec<Crossing>)>) -> Crossings {
    let total: usize = chunks.iter().map(|(_, found)| found.len()).sum();
    let mut crossings = Crossings {
        splits: vec![0],
        ray_ids: Vec::with_capacity(total),
        t: Vec::with_capacity(total),
        ids: Vec::with_capacity(total),
        uvs: Vec::with_capacity(2 * total),
    };
    let mut ray = 0u32;
    for (counts, found) in chunks {
        for count in counts {
            crossings
                .ray_ids
                .extend(std::iter::repeat_n(ray, count as usize));
            let last = crossings.splits[crossings.splits.len() - 1];
            crossings.splits.push(last + count);
            ray += 1;
        }
        for (t, id, u, v) in found {
            crossings.t.push(t);
            crossings.ids.push(id);
            crossings.uvs.extend([u, v]);
        }
    }
    crossings
}
