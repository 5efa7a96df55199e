//! Pooled grid files (format 4.1, [`crate::format::pool`]): once the top level has fixed the
//! strips' file order, consecutive strips of a chunk share one pool of grid points, and each
//! strip keeps a part of references and block boxes.

use std::collections::HashMap;

use crate::format::attributes::AttributeSet;
use crate::format::block_boxes::BOX_WINDOWS;

use crate::format::grid::Grid;
use crate::format::pool::{PartHeader, MAX_POOL_DISTANCE, MAX_POOL_POINTS};
use crate::format::quantized::{self, AxisWordLayout};
use crate::format::reader::{strip_view, VertexLayout};
use crate::format::references::pack;
use crate::format::vertices::StripVertices;
use crate::format::{align_up, StripRecord};
use crate::strip_encoding::{block_boxes, EncodedStrip};

/// Whether a file of these settings pools its grid vertices: per-vertex attributes are stored
/// per strip vertex, which a pool does not have, so files with attributes keep
/// `vertex_encoding` 3, as do files with leaves below a block box's windows (their strips'
/// kd-trees would be walked, and pools have none).
pub fn pools_vertices(grid: Option<&Grid>, attributes: AttributeSet, leaf_windows: usize) -> bool {
    grid.is_some() && !attributes.any() && leaf_windows >= BOX_WINDOWS
}

/// One strip's references as grid points, read back from its `vertex_encoding` 3 block.
struct StripPoints {
    /// The grid point of each reference, swaps included.
    references: Vec<[u32; 3]>,
}

/// Rewrites the blocks of `strips` (`vertex_encoding` 3 on `grid`), grouped in `order` (file
/// order), as pooled parts: each strip's block becomes its part, the last of a group's also
/// holds the group's pool, and its `vertex_count` the vertices its view spans in the pool.
/// Returns the pools' points, which the header counts as stored.
/// Returns the stored vertex count the strips' views then have.
pub fn pool_blocks(
    strips: &mut [EncodedStrip],
    order: &[u32],
    grid: &Grid,
    leaf_windows: usize,
) -> u64 {
    let points: Vec<StripPoints> = order
        .iter()
        .map(|&s| read_points(&strips[s as usize], grid, leaf_windows))
        .collect();
    let mut stored = 0;
    let mut first = 0;
    while first < order.len() {
        let end = group_end(&points, first);
        stored += write_group(strips, &order[first..end], &points[first..end], grid);
        first = end;
    }
    stored
}

fn read_points(strip: &EncodedStrip, grid: &Grid, leaf_windows: usize) -> StripPoints {
    let record = StripRecord {
        data_word: 0,
        vertex_count: strip.vertex_count,
        reference_count: strip.reference_count,
    };
    let view = strip_view(
        &strip.block,
        &record,
        leaf_windows,
        &VertexLayout::from(Some(*grid)),
    );
    let StripVertices::Grid(vertices) = view.vertices else {
        unreachable!("grid strips have grid vertices");
    };
    let references = view.references.to_vec();
    StripPoints {
        references: references
            .iter()
            .map(|&r| vertices.grid_point(r as usize))
            .collect(),
    }
}

/// The end of the group starting at strip `first`: strips join while the pool's distinct points
/// stay within [`MAX_POOL_POINTS`] and the first part within reach of the pool.
fn group_end(points: &[StripPoints], first: usize) -> usize {
    let mut pool: HashMap<[u32; 3], ()> = HashMap::new();
    let mut part_bytes = 0;
    let mut end = first;
    while let Some(strip) = points.get(end) {
        let fresh: Vec<[u32; 3]> = strip
            .references
            .iter()
            .filter(|p| !pool.contains_key(*p))
            .copied()
            .collect::<std::collections::HashSet<_>>()
            .into_iter()
            .collect();
        let bytes = upper_part_bytes(strip.references.len());
        let fits =
            pool.len() + fresh.len() <= MAX_POOL_POINTS && part_bytes + bytes <= MAX_POOL_DISTANCE;
        if end > first && !fits {
            break;
        }
        pool.extend(fresh.into_iter().map(|p| (p, ())));
        part_bytes += bytes;
        end += 1;
    }
    end
}

/// The most bytes a part of `references` references takes: a byte each, boxes, padding.
fn upper_part_bytes(references: usize) -> usize {
    let windows = references.saturating_sub(2);
    4 + references + crate::format::block_boxes::area_bytes(windows) + 3
}

/// Writes one group's parts and pool into its strips' blocks; returns the pool's points.
fn write_group(
    strips: &mut [EncodedStrip],
    order: &[u32],
    points: &[StripPoints],
    grid: &Grid,
) -> u64 {
    let mut pool: Vec<[u32; 3]> = Vec::new();
    let mut index: HashMap<[u32; 3], usize> = HashMap::new();
    let mut parts = Vec::with_capacity(order.len());
    for strip in points {
        let indices: Vec<usize> = strip
            .references
            .iter()
            .map(|p| {
                *index.entry(*p).or_insert_with(|| {
                    pool.push(*p);
                    pool.len() - 1
                })
            })
            .collect();
        parts.push(encode_part(&indices, &pool, grid));
    }
    let mut distance: usize = parts.iter().map(|(part, _)| part.len()).sum();
    for (&s, (mut part, span)) in order.iter().zip(parts) {
        let header = PartHeader {
            pool_distance: distance,
            base: part[2] as usize,
        };
        distance -= part.len();
        part[..3].copy_from_slice(&header.bytes());
        let strip = &mut strips[s as usize];
        strip.vertex_count = span as u16;
        strip.block = part;
    }
    let last = order[order.len() - 1] as usize;
    strips[last].block.extend(pool_block(&pool, grid));
    pool.len() as u64
}

/// A strip's part (its pool distance left zero) and the vertices its view spans.
fn encode_part(indices: &[usize], pool: &[[u32; 3]], grid: &Grid) -> (Vec<u8>, usize) {
    let base = indices.iter().copied().min().unwrap_or(0);
    let span = indices.iter().copied().max().unwrap_or(0) + 1 - base;
    let references: Vec<u8> = indices.iter().map(|&i| (i - base) as u8).collect();
    let mut part = vec![0, 0, base as u8];
    part.extend(pack(&references, span));
    let positions: Vec<_> = indices.iter().map(|&i| grid.decode(&pool[i])).collect();
    part.extend(block_boxes::encode(&positions, grid.decode(&pool[base])));
    part.resize(align_up(part.len() as u64, 4) as usize, 0);
    (part, span)
}

/// A pool's bytes: its count byte, its points as a block stores vertices, a tail, padding.
fn pool_block(pool: &[[u32; 3]], grid: &Grid) -> Vec<u8> {
    let layout = AxisWordLayout::Packed {
        grid_bits: grid.bits,
    };
    let mut bytes = vec![(pool.len() - 1) as u8];
    bytes.extend(quantized::pack(pool, grid.bits, layout));
    bytes.extend([0; crate::format::pool::POOL_TAIL_BYTES]);
    bytes.resize(align_up(bytes.len() as u64, 4) as usize, 0);
    bytes
}
