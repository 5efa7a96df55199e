//! `isosurface`: the zero level set of a 3D fractal noise field in a cube,
//! extracted with marching cubes (`marching_cubes` derives the case table so
//! that neighbouring cubes always agree, making the surface watertight).
//!
//! Closedness: samples on the domain boundary are forced outside, so every
//! surface component closes inside the box. The sample nearest the centre is
//! forced inside so that even the smallest grid has a surface.
//!
//! Degeneracy: a sample exactly at the iso level counts as outside, and the
//! crossing parameter on a lattice edge is clamped to
//! `[EDGE_MARGIN, 1 - EDGE_MARGIN]`, so crossing points never coincide with
//! lattice points or with each other, and fan triangles (whose apex is off
//! the plane of the opposite side, see `marching_cubes`) cannot collapse.
//!
//! Streaming: vertices are the crossings on lattice edges, grouped by sample
//! plane `z`: the plane's x-edges, then its y-edges, then the z-edges up to
//! plane `z + 1`. A counting pass records each
//! group's size, which fixes every group's first id, so the vertex and face
//! passes can regenerate any slab of layers independently from the field;
//! memory is a few planes of samples and ids per slab, never the volume.
//!
//! Noise features have a fixed size in cells, so the surface fills the
//! volume and triangles grow like `R^3` for `R` cells per side. Triangle
//! count: the resolution starts from a calibrated density and is corrected
//! from up to two more counting passes; the count of the best of them is
//! typically within a few percent of N (coarser at tiny N, never 0).

use std::ops::Range;

use rayon::prelude::*;

use super::marching_cubes::{case_table, Case, EDGE_CORNERS};
use super::noise::{fade, lattice_value, Rng};
use super::{Chunking, GenSummary, Generator, TRIANGLES_PER_CHUNK};

/// Measured triangles per cube of the field at large resolutions.
const TRIANGLES_PER_CELL: f64 = 0.33;
const MIN_CELLS: usize = 4;
/// Relative triangle-count error accepted without another counting pass.
const COUNT_TOLERANCE: f64 = 0.02;
const RESOLUTION_TRIES: usize = 3;
/// Coarsest noise lattice spacing in cells; finer octaves halve it.
const MAX_SPACING: usize = 16;
const MIN_SPACING: usize = 4;
const EDGE_MARGIN: f32 = 1.0 / 64.0;
/// Slabs are at least this many layers thick, to amortise recomputing the
/// sample plane each slab shares with the next.
const MIN_LAYERS_PER_SLAB: u64 = 4;

struct Octave {
    spacing: usize,
    amplitude: f32,
    seed: u64,
    /// Lattice offset in cells, so octaves' lattice planes do not align.
    shift: [usize; 3],
}

struct Volume {
    /// Cells per side; samples per side are `cells + 1`.
    cells: usize,
    octaves: Vec<Octave>,
    cases: Vec<Case>,
}

fn inside(value: f32) -> bool {
    value > 0.0
}

/// Sizes of one vertex group (sample plane `z`) and its cube layer.
#[derive(Clone, Copy, Default)]
struct GroupCount {
    plane_crossings: u64,
    vertical_crossings: u64,
    triangles: u64,
}

impl GroupCount {
    fn vertices(&self) -> u64 {
        self.plane_crossings + self.vertical_crossings
    }
}

impl Volume {
    fn new(cells: usize, seed: u64) -> Self {
        let mut rng = Rng::new(seed, 0);
        let mut octaves = Vec::new();
        let mut spacing = (cells / 4).clamp(MIN_SPACING / 2, MAX_SPACING);
        let mut amplitude = 1.0;
        while octaves.is_empty() || spacing >= MIN_SPACING {
            let shift = [0; 3].map(|_| (rng.next_u64() % spacing as u64) as usize);
            octaves.push(Octave {
                spacing,
                amplitude,
                seed: rng.next_u64(),
                shift,
            });
            spacing /= 2;
            amplitude *= 0.5;
        }
        Volume {
            cells,
            octaves,
            cases: case_table(),
        }
    }

    fn samples_per_side(&self) -> usize {
        self.cells + 1
    }

    /// Fills `out` with the field on sample plane `z`, row-major in (y, x).
    fn fill_plane(&self, z: usize, out: &mut Vec<f32>) {
        let n = self.samples_per_side();
        out.clear();
        out.resize(n * n, 0.0);
        for octave in &self.octaves {
            add_octave(octave, n, z, out);
        }
        let boundary = |i: usize| i == 0 || i == self.cells;
        let centre = self.cells / 2;
        for y in 0..n {
            for x in 0..n {
                let value = &mut out[y * n + x];
                if boundary(x) || boundary(y) || boundary(z) {
                    *value = -1.0;
                } else if (x, y, z) == (centre, centre, centre) {
                    *value = value.max(0.5);
                }
            }
        }
    }

    /// Runs `visit(z, plane z, plane z + 1)` for each plane in `planes`,
    /// computing every plane once; the last plane has no upper neighbour.
    fn for_each_plane(
        &self,
        planes: Range<usize>,
        mut visit: impl FnMut(usize, &[f32], Option<&[f32]>),
    ) {
        let (mut lower, mut upper) = (Vec::new(), Vec::new());
        self.fill_plane(planes.start, &mut lower);
        for z in planes {
            if z < self.cells {
                self.fill_plane(z + 1, &mut upper);
                visit(z, &lower, Some(&upper));
                std::mem::swap(&mut lower, &mut upper);
            } else {
                visit(z, &lower, None);
            }
        }
    }

    /// Calls `visit(axis, x, y)` for each sign-changing x-edge, then y-edge,
    /// of a plane, in id order.
    fn for_each_plane_crossing(&self, plane: &[f32], mut visit: impl FnMut(usize, usize, usize)) {
        let n = self.samples_per_side();
        for (axis, step) in [(0, 1), (1, n)] {
            for y in 0..n - axis {
                for x in 0..n - 1 + axis {
                    let at = y * n + x;
                    if inside(plane[at]) != inside(plane[at + step]) {
                        visit(axis, x, y);
                    }
                }
            }
        }
    }

    /// Calls `visit(x, y)` for each sign-changing z-edge between two planes.
    fn for_each_vertical_crossing(
        &self,
        lower: &[f32],
        upper: &[f32],
        mut visit: impl FnMut(usize, usize),
    ) {
        let n = self.samples_per_side();
        for (at, (&below, &above)) in lower.iter().zip(upper).enumerate() {
            if inside(below) != inside(above) {
                visit(at % n, at / n);
            }
        }
    }

    /// Calls `visit(x, y, case)` for each cube between two planes that the
    /// surface passes through, in (y, x) order.
    fn for_each_surface_cube(
        &self,
        lower: &[f32],
        upper: &[f32],
        mut visit: impl FnMut(usize, usize, &Case),
    ) {
        let n = self.samples_per_side();
        for y in 0..self.cells {
            for x in 0..self.cells {
                let pattern = (0..8).fold(0usize, |pattern, corner| {
                    let plane = if corner & 4 == 0 { lower } else { upper };
                    let at = (y + (corner >> 1 & 1)) * n + x + (corner & 1);
                    pattern | (inside(plane[at]) as usize) << corner
                });
                let case = &self.cases[pattern];
                if !case.is_empty() {
                    visit(x, y, case);
                }
            }
        }
    }

    fn count_group(&self, lower: &[f32], upper: Option<&[f32]>) -> GroupCount {
        let mut count = GroupCount::default();
        self.for_each_plane_crossing(lower, |_, _, _| count.plane_crossings += 1);
        if let Some(upper) = upper {
            self.for_each_vertical_crossing(lower, upper, |_, _| count.vertical_crossings += 1);
            self.for_each_surface_cube(lower, upper, |_, _, case| {
                count.triangles += case.len() as u64;
            });
        }
        count
    }

    fn slabs(&self, triangles_per_layer: u64) -> Chunking {
        let layers = (TRIANGLES_PER_CHUNK / triangles_per_layer.max(1)).max(MIN_LAYERS_PER_SLAB);
        Chunking::by_work(self.samples_per_side() as u64, 1, layers)
    }

    fn count_groups(&self) -> Vec<GroupCount> {
        let estimated_per_layer = (TRIANGLES_PER_CELL * (self.cells * self.cells) as f64) as u64;
        let slabs = self.slabs(estimated_per_layer);
        let per_slab: Vec<Vec<GroupCount>> = (0..slabs.count())
            .into_par_iter()
            .map(|slab| {
                let mut counts = Vec::new();
                let planes = slabs.range(slab);
                self.for_each_plane(
                    planes.start as usize..planes.end as usize,
                    |_, lower, upper| {
                        counts.push(self.count_group(lower, upper));
                    },
                );
                counts
            })
            .collect();
        per_slab.concat()
    }

    fn world(&self, index: usize) -> f32 {
        (2.0 * index as f64 / self.cells as f64 - 1.0) as f32
    }

    /// The crossing on the lattice edge from sample `from` (value
    /// `from_value`) one step along `axis`.
    fn crossing(&self, from: [usize; 3], axis: usize, from_value: f32, to_value: f32) -> [f32; 3] {
        let t = (from_value / (from_value - to_value)).clamp(EDGE_MARGIN, 1.0 - EDGE_MARGIN);
        let mut position = from.map(|i| self.world(i));
        position[axis] += t * (self.world(from[axis] + 1) - position[axis]);
        position
    }

    fn write_group_vertices(
        &self,
        z: usize,
        lower: &[f32],
        upper: Option<&[f32]>,
        out: &mut Vec<[f32; 3]>,
    ) {
        let n = self.samples_per_side();
        self.for_each_plane_crossing(lower, |axis, x, y| {
            let step = if axis == 0 { 1 } else { n };
            out.push(self.crossing([x, y, z], axis, lower[y * n + x], lower[y * n + x + step]));
        });
        if let Some(upper) = upper {
            self.for_each_vertical_crossing(lower, upper, |x, y| {
                out.push(self.crossing([x, y, z], 2, lower[y * n + x], upper[y * n + x]));
            });
        }
    }

    /// Ids of a plane's crossing x-edges and y-edges, indexed `y * n + x`.
    fn plane_ids(&self, plane: &[f32], first_id: u64) -> [Vec<u32>; 2] {
        let n = self.samples_per_side();
        let mut ids = [vec![u32::MAX; n * n], vec![u32::MAX; n * n]];
        let mut next = first_id as u32;
        self.for_each_plane_crossing(plane, |axis, x, y| {
            ids[axis][y * n + x] = next;
            next += 1;
        });
        ids
    }

    fn write_layer_faces(
        &self,
        z: usize,
        lower: &[f32],
        upper: &[f32],
        groups: &[GroupStart],
        out: &mut Vec<[u32; 3]>,
    ) {
        let n = self.samples_per_side();
        let (here, above) = (groups[z], groups[z + 1]);
        let lower_ids = self.plane_ids(lower, here.first_id);
        let upper_ids = self.plane_ids(upper, above.first_id);
        let mut vertical_ids = vec![u32::MAX; n * n];
        let mut next = (here.first_id + here.count.plane_crossings) as u32;
        self.for_each_vertical_crossing(lower, upper, |x, y| {
            vertical_ids[y * n + x] = next;
            next += 1;
        });
        self.for_each_surface_cube(lower, upper, |x, y, case| {
            let edge_id = |edge: u8| {
                let (corner, axis) = (EDGE_CORNERS[edge as usize].0 as usize, edge as usize / 4);
                let at = (y + (corner >> 1 & 1)) * n + x + (corner & 1);
                match axis {
                    2 => vertical_ids[at],
                    _ if corner & 4 == 0 => lower_ids[axis][at],
                    _ => upper_ids[axis][at],
                }
            };
            case.iter()
                .for_each(|triangle| out.push(triangle.map(edge_id)));
        });
    }
}

/// Adds one octave of trilinearly faded value noise to a sample plane.
/// Lattice values are hashed once per lattice node of the two lattice planes
/// bracketing `z`, not per sample.
fn add_octave(octave: &Octave, n: usize, z: usize, out: &mut [f32]) {
    let spacing = octave.spacing;
    let weights: Vec<f32> = (0..spacing)
        .map(|k| fade(k as f64 / spacing as f64) as f32)
        .collect();
    let [sx, sy, sz] = octave.shift;
    let lattice_z = ((z + sz) / spacing) as i64;
    let weight_z = weights[(z + sz) % spacing];
    let nodes_x = (n - 1 + sx) / spacing + 2;
    let nodes_y = (n - 1 + sy) / spacing + 2;
    let lattice: Vec<f32> = (0..nodes_y * nodes_x)
        .map(|at| {
            let node = [(at % nodes_x) as i64, (at / nodes_x) as i64];
            let below = lattice_value(octave.seed, &[node[0], node[1], lattice_z]);
            let above = lattice_value(octave.seed, &[node[0], node[1], lattice_z + 1]);
            below + (above - below) * weight_z
        })
        .collect();
    let mut row = vec![0.0f32; nodes_x];
    for y in 0..n {
        let (node_y, weight_y) = ((y + sy) / spacing, weights[(y + sy) % spacing]);
        let (near, far) = (
            &lattice[node_y * nodes_x..],
            &lattice[(node_y + 1) * nodes_x..],
        );
        for (node, value) in row.iter_mut().enumerate() {
            *value = near[node] + (far[node] - near[node]) * weight_y;
        }
        for (x, sample) in out[y * n..(y + 1) * n].iter_mut().enumerate() {
            let (node_x, weight_x) = ((x + sx) / spacing, weights[(x + sx) % spacing]);
            let blended = row[node_x] + (row[node_x + 1] - row[node_x]) * weight_x;
            *sample += octave.amplitude * blended;
        }
    }
}

#[derive(Clone, Copy)]
struct GroupStart {
    first_id: u64,
    count: GroupCount,
}

/// Picks the resolution whose triangle count is nearest `triangles`.
fn choose_volume(triangles: u64, seed: u64) -> (Volume, Vec<GroupCount>) {
    let target = triangles.max(1) as f64;
    let mut cells = ((target / TRIANGLES_PER_CELL).cbrt().round() as usize).max(MIN_CELLS);
    let mut best: Option<(f64, Volume, Vec<GroupCount>)> = None;
    for _ in 0..RESOLUTION_TRIES {
        let volume = Volume::new(cells, seed);
        let counts = volume.count_groups();
        let total = counts.iter().map(|c| c.triangles).sum::<u64>() as f64;
        let error = (total - target).abs() / target;
        let next_cells =
            ((cells as f64 * (target / total.max(1.0)).cbrt()).round() as usize).max(MIN_CELLS);
        if best
            .as_ref()
            .is_none_or(|(best_error, ..)| error < *best_error)
        {
            best = Some((error, volume, counts));
        }
        if error <= COUNT_TOLERANCE || next_cells == cells {
            break;
        }
        cells = next_cells;
    }
    let (_, volume, counts) = best.expect("at least one resolution tried");
    (volume, counts)
}

/// The surface at the resolution chosen for a triangle count, with each layer's first vertex.
pub struct Isosurface {
    volume: Volume,
    groups: Vec<GroupStart>,
    summary: GenSummary,
    slabs: Chunking,
}

impl Isosurface {
    pub fn for_triangles(triangles: u64, seed: u64) -> Self {
        let (volume, counts) = choose_volume(triangles, seed);
        let mut first_id = 0;
        let groups: Vec<GroupStart> = counts
            .iter()
            .map(|&count| {
                let start = GroupStart { first_id, count };
                first_id += count.vertices();
                start
            })
            .collect();
        let summary = GenSummary {
            vertices: first_id,
            triangles: counts.iter().map(|c| c.triangles).sum(),
        };
        let slabs = volume.slabs(summary.triangles / volume.cells as u64);
        Isosurface {
            volume,
            groups,
            summary,
            slabs,
        }
    }

    fn planes(&self, slab: usize) -> Range<usize> {
        let range = self.slabs.range(slab);
        range.start as usize..range.end as usize
    }
}

impl Generator for Isosurface {
    fn summary(&self) -> GenSummary {
        self.summary
    }

    fn vertex_chunks(&self) -> usize {
        self.slabs.count()
    }

    fn vertex_chunk(&self, slab: usize, out: &mut Vec<[f32; 3]>) {
        let volume = &self.volume;
        volume.for_each_plane(self.planes(slab), |z, lower, upper| {
            volume.write_group_vertices(z, lower, upper, out)
        });
    }

    fn face_chunks(&self) -> usize {
        self.slabs.count()
    }

    fn face_chunk(&self, slab: usize, out: &mut Vec<[u32; 3]>) {
        let volume = &self.volume;
        volume.for_each_plane(self.planes(slab), |z, lower, upper| {
            if let Some(upper) = upper {
                volume.write_layer_faces(z, lower, upper, &self.groups, out);
            }
        });
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_mesh::generated;
    use super::super::Kind;

    #[test]
    fn isosurface_is_closed_and_consistently_wound() {
        for (requested, seed) in [(20_000, 1), (5_000, 2), (1_000, 3)] {
            let (summary, mesh) = generated(Kind::Isosurface, requested, seed);
            let error = summary.triangles.abs_diff(requested) as f64 / requested as f64;
            assert!(error < 0.25, "asked {requested}, got {summary:?}");
            mesh.assert_closed_consistent_manifold();
            assert!(
                mesh.signed_volume() > 0.0,
                "normals must face out of the solid"
            );
        }
    }
}
