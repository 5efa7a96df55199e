//! Bytes a grid file would take if groups of consecutive strips shared one vertex pool, computed
//! from today's file (issue 33: a 20-bit grid file at 7 bytes per triangle or less).
//!
//! `cargo run --release --example grid_pool_bytes -- g.rdm`
//!
//! Format 4.1 builds this layout (`vertex_encoding` 5); the estimate reads a `vertex_encoding` 3
//! file (grid files with leaves below 8 windows, or written before 4.1).
//!
//! Reads a `vertex_encoding` 3 file through the reader, re-counts its strip blocks part by part
//! (the first row must equal the file's strip data), then lays the same strips out with a pool
//! per group: the pool stores each distinct grid point of its strips once (a count byte, the
//! three axis words and fixed-width offsets over the pool's extent, as a block does today) and
//! the strips keep their references, split axes and block boxes, with the references as pool
//! indices. Groups are formed per top-level leaf, or greedily over consecutive strips (file
//! order) up to a pool size, or over whole consecutive leaves up to a pool size (then the top
//! level is estimated with that many fewer leaves).
//!
//! Variants of the strip part: the kd-tree's bound vertices kept as pool indices or dropped (a
//! strip with block boxes is walked box by box, never by its kd-tree), and references stored
//! against a per-strip base at the width of the strip's index range (a byte each, so that the
//! references start on a byte as today's do).

use std::collections::HashMap;
use std::path::Path;

use reducem_core::format::block_boxes;
use reducem_core::format::reader::{ReducemFile, TopNodes};
use reducem_core::format::vertices::StripVertices;
use reducem_core::format::{align_up, TopSlot, VertexEncoding, SECTION_ALIGN};

/// Strip records and strip bytes of one strip as today's file holds them.
struct Strip {
    /// Grid point of each reference.
    references: Vec<[u32; 3]>,
    /// Grid points of the kd-tree's bound vertices (two per internal node).
    bounds: Vec<[u32; 3]>,
    /// Stored vertices of today's block.
    stored: Vec<[u32; 3]>,
    windows: usize,
    nodes: usize,
    triangles: usize,
}

/// Bytes by part, summed over strips or groups.
#[derive(Default, Clone, Copy)]
struct Parts {
    axis_words: f64,
    offsets: f64,
    split_axes: f64,
    references: f64,
    boxes: f64,
    padding: f64,
    /// Stored grid points (not bytes).
    points: f64,
}

impl Parts {
    fn total(&self) -> f64 {
        self.axis_words
            + self.offsets
            + self.split_axes
            + self.references
            + self.boxes
            + self.padding
    }
}

/// How the strip part of a pooled layout is stored.
#[derive(Clone, Copy)]
struct StripPart {
    /// The kd-tree's split axes and bound vertices (as pool indices) stay.
    kd_tree: bool,
    /// References as a base byte, a width byte and offsets from the base.
    windowed: bool,
}

/// Bits of an axis word: `grid_bits` anchor bits and 5 width bits.
fn axis_word_bits(grid_bits: u32) -> usize {
    grid_bits as usize + 5
}

/// Bits needed for values `0..=extent`.
fn width(extent: u32) -> usize {
    (u32::BITS - extent.leading_zeros()) as usize
}

/// Per-axis offset widths over `points`' extent, summed.
fn stride(points: &[[u32; 3]]) -> usize {
    (0..3)
        .map(|a| {
            let lo = points.iter().map(|p| p[a]).min().unwrap_or(0);
            let hi = points.iter().map(|p| p[a]).max().unwrap_or(0);
            width(hi - lo)
        })
        .sum()
}

/// Bits per reference of today's packed references.
fn reference_width(vertices: usize) -> usize {
    width(vertices.max(2) as u32 - 1).max(1)
}

/// Today's packed reference bytes.
fn reference_bytes(count: usize, vertices: usize) -> usize {
    (count * reference_width(vertices)).div_ceil(8).max(3)
}

fn box_bytes(windows: usize) -> usize {
    block_boxes::area_bytes(windows)
}

fn read_strips(file: &ReducemFile) -> Vec<Strip> {
    let leaf = file.leaf_windows();
    (0..file.strip_count())
        .map(|index| {
            let view = file.strip(index);
            let StripVertices::Grid(vertices) = view.vertices else {
                panic!("not a grid file");
            };
            let stored: Vec<[u32; 3]> = (0..vertices.len())
                .map(|i| vertices.grid_point(i))
                .collect();
            let windows = view.window_count();
            let nodes = windows.div_ceil(leaf).saturating_sub(1);
            Strip {
                references: view
                    .references
                    .to_vec()
                    .iter()
                    .map(|&r| stored[r as usize])
                    .collect(),
                bounds: stored[..2 * nodes].to_vec(),
                stored,
                windows,
                nodes,
                triangles: view.triangles().len(),
            }
        })
        .collect()
}

/// Today's blocks, part by part.
fn today(strips: &[Strip], grid_bits: u32) -> Parts {
    let mut parts = Parts::default();
    for strip in strips {
        let v = strip.stored.len();
        let offset_bits = v * stride(&strip.stored);
        let vertex_bytes = (3 * axis_word_bits(grid_bits) + offset_bits).div_ceil(8);
        let axes = strip.nodes.div_ceil(4);
        let references = reference_bytes(strip.references.len(), v);
        let boxes = box_bytes(strip.windows);
        let block = vertex_bytes + axes + references + boxes;
        parts.axis_words += (3 * axis_word_bits(grid_bits)) as f64 / 8.0;
        parts.offsets += offset_bits as f64 / 8.0;
        parts.points += v as f64;
        parts.split_axes += axes as f64;
        parts.references += references as f64;
        parts.boxes += boxes as f64;
        parts.padding += (align_up(block as u64, 4) as usize - block) as f64
            + (vertex_bytes as f64 - (3 * axis_word_bits(grid_bits) + offset_bits) as f64 / 8.0);
    }
    parts
}

/// The pool of a group: its distinct grid points in order of first use.
fn pool(strips: &[Strip], part: StripPart) -> HashMap<[u32; 3], usize> {
    let mut pool = HashMap::new();
    for strip in strips {
        let bounds = if part.kd_tree { &strip.bounds[..] } else { &[] };
        for point in strip.references.iter().chain(bounds) {
            let next = pool.len();
            pool.entry(*point).or_insert(next);
        }
    }
    pool
}

fn pool_size(strips: &[Strip], part: StripPart) -> usize {
    pool(strips, part).len()
}

/// Bytes of one group laid out with a shared pool, added to `parts`.
fn add_group(strips: &[Strip], grid_bits: u32, part: StripPart, parts: &mut Parts) {
    let pool = pool(strips, part);
    let mut points = vec![[0u32; 3]; pool.len()];
    for (point, &index) in &pool {
        points[index] = *point;
    }
    let r = reference_width(pool.len());
    // A count byte, the axis words and the offsets, rounded to a byte.
    let header_bits = 8 + 3 * axis_word_bits(grid_bits);
    let offset_bits = points.len() * stride(&points);
    let pool_bytes = (header_bits + offset_bits).div_ceil(8);
    parts.axis_words += header_bits as f64 / 8.0;
    parts.offsets += offset_bits as f64 / 8.0;
    parts.points += points.len() as f64;
    parts.padding += pool_bytes as f64 - (header_bits + offset_bits) as f64 / 8.0;
    let mut group_bytes = pool_bytes;
    for strip in strips {
        let indices: Vec<usize> = strip.references.iter().map(|p| pool[p]).collect();
        let reference_bits = if part.windowed {
            let lo = *indices.iter().min().unwrap_or(&0);
            let hi = *indices.iter().max().unwrap_or(&0);
            16 + indices.len() * width((hi - lo) as u32)
        } else {
            indices.len() * r
        };
        let references = reference_bits.div_ceil(8).max(3);
        let axes = if part.kd_tree {
            strip.nodes.div_ceil(4) + (2 * strip.nodes * r).div_ceil(8)
        } else {
            0
        };
        let boxes = box_bytes(strip.windows);
        parts.references += references as f64;
        parts.split_axes += axes as f64;
        parts.boxes += boxes as f64;
        group_bytes += references + axes + boxes;
    }
    parts.padding += (align_up(group_bytes as u64, 4) as usize - group_bytes) as f64;
}

/// Strip ranges of the top level's leaves, in file order.
fn leaves(file: &ReducemFile) -> Vec<(usize, usize)> {
    let TopNodes::Wide(nodes) = file.top_nodes() else {
        panic!("not a format 4 file");
    };
    let mut leaves: Vec<(usize, usize)> = nodes
        .iter()
        .flat_map(|node| (0..8).map(move |slot| node.slot(slot)))
        .filter_map(|slot| match slot {
            TopSlot::Leaf { first, count } => Some((first as usize, (first + count) as usize)),
            _ => None,
        })
        .collect();
    leaves.sort_unstable();
    leaves
}

/// Greedy runs of consecutive units (strip ranges) whose pool holds at most `cap` points; a
/// unit whose own pool exceeds `cap` is taken strip by strip.
fn greedy(
    strips: &[Strip],
    units: &[(usize, usize)],
    cap: usize,
    part: StripPart,
) -> Vec<(usize, usize)> {
    let fitting = units.iter().flat_map(|&(first, end)| {
        let whole = pool_size(&strips[first..end], part) <= cap;
        let pieces: Vec<(usize, usize)> = match whole {
            true => vec![(first, end)],
            false => (first..end).map(|s| (s, s + 1)).collect(),
        };
        pieces
    });
    let mut groups = Vec::new();
    let mut open: Option<(usize, usize)> = None;
    for (first, end) in fitting {
        open = match open {
            Some((s, _)) if pool_size(&strips[s..end], part) <= cap => Some((s, end)),
            Some(full) => {
                groups.push(full);
                Some((first, end))
            }
            None => Some((first, end)),
        };
    }
    groups.extend(open);
    for &(first, end) in &groups {
        let size = pool_size(&strips[first..end], part);
        assert!(
            size <= cap,
            "strips {first}..{end}: a pool of {size} points"
        );
    }
    groups
}

/// Leaves left after merging consecutive leaves while they hold at most `most` strips together.
fn merged_leaves(leaves: &[(usize, usize)], most: usize) -> usize {
    let mut count = 0;
    let mut open = most;
    for &(first, end) in leaves {
        if open + (end - first) > most {
            count += 1;
            open = 0;
        }
        open += end - first;
    }
    count
}

/// One way of grouping strips: strip ranges in file order, each sharing a pool.
struct Scheme {
    name: String,
    groups: Vec<(usize, usize)>,
    /// Groups are runs of whole leaves, which would become the top level's leaves.
    whole_leaves: bool,
}

struct Row {
    name: String,
    parts: Parts,
    groups: usize,
    top_nodes: f64,
}

fn main() {
    let path = std::env::args()
        .nth(1)
        .expect("usage: grid_pool_bytes FILE.rdm");
    let file = ReducemFile::open(Path::new(&path)).expect("open");
    assert_eq!(
        file.header().vertex_encoding,
        VertexEncoding::GridPackedReferences as u32,
        "{path}: the estimate re-counts per-strip grid blocks (vertex_encoding 3)"
    );
    let grid_bits = file.precision().grid_bits;
    let strips = read_strips(&file);
    let triangles: usize = strips.iter().map(|s| s.triangles).sum();
    let per_tri = |bytes: f64| bytes / triangles as f64;
    let records = per_tri(8.0 * strips.len() as f64);
    let nodes = file.top_nodes().len() as f64;
    let leaves = leaves(&file);
    let strip_units: Vec<(usize, usize)> = (0..strips.len()).map(|s| (s, s + 1)).collect();
    let stored: usize = strips.iter().map(|s| s.stored.len()).sum();
    println!(
        "{path}: {triangles} triangles, {} strips, {} leaves, {} top nodes, {stored} stored vertices ({:.3} per triangle)",
        strips.len(),
        leaves.len(),
        nodes,
        stored as f64 / triangles as f64
    );

    let mut rows = vec![Row {
        name: "today (encoding 3)".into(),
        parts: today(&strips, grid_bits),
        groups: strips.len(),
        top_nodes: nodes,
    }];
    let variants = [
        (
            "kd kept",
            StripPart {
                kd_tree: true,
                windowed: false,
            },
        ),
        (
            "no kd",
            StripPart {
                kd_tree: false,
                windowed: false,
            },
        ),
        (
            "no kd, windowed refs",
            StripPart {
                kd_tree: false,
                windowed: true,
            },
        ),
    ];
    for (label, part) in variants {
        let mut schemes = vec![Scheme {
            name: "per leaf".into(),
            groups: leaves.clone(),
            whole_leaves: false,
        }];
        for cap in [64, 128, 256] {
            schemes.push(Scheme {
                name: format!("strips <= {cap}"),
                groups: greedy(&strips, &strip_units, cap, part),
                whole_leaves: false,
            });
            schemes.push(Scheme {
                name: format!("leaves <= {cap}"),
                groups: greedy(&strips, &leaves, cap, part),
                whole_leaves: true,
            });
        }
        for scheme in schemes {
            let groups = scheme.groups;
            let mut parts = Parts::default();
            for &(first, end) in &groups {
                add_group(&strips[first..end], grid_bits, part, &mut parts);
            }
            // Groups of whole leaves become the leaves: the tree shrinks with their number.
            let top_nodes = match scheme.whole_leaves {
                true => (nodes * (groups.len() - 1) as f64 / (leaves.len() - 1) as f64).ceil(),
                false => nodes,
            };
            rows.push(Row {
                name: format!("{}, {label}", scheme.name),
                parts,
                groups: groups.len(),
                top_nodes,
            });
        }
    }

    for most in [2, 4, 8] {
        let merged = merged_leaves(&leaves, most);
        let estimate = (nodes * (merged - 1) as f64 / (leaves.len() - 1) as f64).ceil();
        println!(
            "leaves of up to {most} consecutive strips: {merged} leaves, about {estimate} top nodes, {:.2} B/tri",
            per_tri(96.0 * estimate)
        );
    }
    println!(
        "| layout | groups | pool pts/tri | axis words | offsets | split axes+kd | references | boxes | padding | strip data | records | top nodes | file |"
    );
    println!("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for row in &rows {
        let p = row.parts;
        let top = per_tri(96.0 * row.top_nodes);
        let data = per_tri(p.total());
        // Header page and section alignment as the file has them.
        let sections = [96.0 * row.top_nodes, 8.0 * strips.len() as f64, p.total()];
        let file_bytes: f64 = SECTION_ALIGN as f64
            + sections
                .iter()
                .map(|&b| align_up(b.ceil() as u64, SECTION_ALIGN) as f64)
                .sum::<f64>();
        println!(
            "| {} | {} | {:.3} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} |",
            row.name,
            row.groups,
            per_tri(p.points),
            per_tri(p.axis_words),
            per_tri(p.offsets),
            per_tri(p.split_axes),
            per_tri(p.references),
            per_tri(p.boxes),
            per_tri(p.padding),
            data,
            records,
            top,
            per_tri(file_bytes),
        );
    }
}
