//! `cad`: many disconnected parts (slabs, boxes, cylinders, spheres,
//! tessellated plates) placed pseudo-randomly, as in a CAD assembly export:
//! huge two-triangle box faces sit next to finely tessellated small parts,
//! so triangle areas span many orders of magnitude. Parts share no vertices.
//!
//! Part 0 is always a large base slab; the others draw a shape, a size
//! (log-uniform, so small and large parts are equally common per decade) and
//! a triangle budget (log-uniform up to about `8 sqrt(N)`), and sit on a
//! jittered sunflower spiral around the origin, turned about the vertical.
//! Part sizes and tessellation limits keep every triangle's edges far above
//! `f32` resolution at the spiral's extent, so no triangle collapses.
//!
//! The part list (O(parts) ~ O(sqrt N log N) small records) is the only
//! state kept: each part's mesh is rebuilt from its record when its chunk is
//! written, once for vertices and once for faces.
//!
//! Triangle count: parts are added while they fit in the budget; the rest is
//! filled with plates of `2ab` triangles, so the count is N rounded down to
//! even (at least 2). Closed parts are wound outward, plates face up.

use std::f64::consts::{PI, TAU};
use std::ops::Range;

use super::noise::Rng;
use super::{GenSummary, Generator, TRIANGLES_PER_CHUNK};

type Vec3 = [f64; 3];

const SLAB_SIZE: Vec3 = [60.0, 60.0, 0.5];
const MIN_PART_SIZE: f64 = 0.1;
const MAX_PART_SIZE: f64 = 4.0;
/// Distance scale of the placement spiral.
const SPIRAL_STEP: f64 = 2.5;
/// The largest part budget: enough for fine parts, small enough that
/// tessellation stays far above `f32` resolution.
const MAX_PART_TRIANGLES: u64 = 100_000;

#[derive(Clone, Copy, Debug)]
enum Shape {
    Box {
        size: Vec3,
    },
    /// A surface of revolution: `segments` around, `rings` interior profile
    /// points between the two poles (cylinder with capped ends, or sphere).
    Revolved {
        radius: f64,
        height: f64,
        segments: u32,
        rings: u32,
        round: bool,
    },
    Plate {
        size: [f64; 2],
        cells: [u32; 2],
    },
}

impl Shape {
    fn triangles(&self) -> u64 {
        match *self {
            Shape::Box { .. } => 12,
            Shape::Revolved {
                segments, rings, ..
            } => 2 * segments as u64 * rings as u64,
            Shape::Plate { cells, .. } => 2 * cells[0] as u64 * cells[1] as u64,
        }
    }

    fn vertices(&self) -> u64 {
        match *self {
            Shape::Box { .. } => 8,
            Shape::Revolved {
                segments, rings, ..
            } => segments as u64 * rings as u64 + 2,
            Shape::Plate { cells, .. } => (cells[0] as u64 + 1) * (cells[1] as u64 + 1),
        }
    }
}

#[derive(Clone, Copy, Debug)]
struct Part {
    shape: Shape,
    origin: Vec3,
    /// Rotation about the vertical axis.
    yaw: f64,
    first_vertex: u64,
}

/// A part's mesh in its local frame.
#[derive(Default)]
struct LocalMesh {
    positions: Vec<Vec3>,
    triangles: Vec<[u32; 3]>,
}

impl LocalMesh {
    fn quad(&mut self, [a, b, c, d]: [u32; 4]) {
        self.triangles.push([a, b, c]);
        self.triangles.push([a, c, d]);
    }
}

fn box_mesh(size: Vec3) -> LocalMesh {
    let positions = (0..8)
        .map(|corner| {
            [0, 1, 2].map(|axis| {
                if corner >> axis & 1 == 1 {
                    size[axis]
                } else {
                    0.0
                }
            })
        })
        .collect();
    let mut mesh = LocalMesh {
        positions,
        triangles: Vec::new(),
    };
    for axis in 0..3 {
        let (first, second) = (1 << ((axis + 1) % 3), 1 << ((axis + 2) % 3));
        for side in [0, 1 << axis] {
            // Counter-clockwise seen from outside: the (first, second) square
            // is right-handed about +axis, so the low side runs it backwards.
            let square = [side, side | first, side | first | second, side | second];
            let [a, b, c, d] = square;
            mesh.quad(if side == 0 { [a, d, c, b] } else { square });
        }
    }
    mesh
}

/// Profile points from the bottom pole to the top pole (exclusive), as
/// (radius, height); rings are evenly spaced along the profile.
fn profile(radius: f64, height: f64, rings: u32, round: bool) -> Vec<[f64; 2]> {
    (1..=rings)
        .map(|k| {
            if round {
                let polar = PI * k as f64 / (rings + 1) as f64;
                [radius * polar.sin(), radius * (1.0 - polar.cos())]
            } else {
                [radius, height * (k - 1) as f64 / (rings - 1) as f64]
            }
        })
        .collect()
}

fn revolved_mesh(radius: f64, height: f64, segments: u32, rings: u32, round: bool) -> LocalMesh {
    let top = if round { 2.0 * radius } else { height };
    let mut mesh = LocalMesh::default();
    mesh.positions.push([0.0, 0.0, 0.0]);
    for [r, z] in profile(radius, height, rings, round) {
        for s in 0..segments {
            let (sin, cos) = (TAU * s as f64 / segments as f64).sin_cos();
            mesh.positions.push([r * cos, r * sin, z]);
        }
    }
    mesh.positions.push([0.0, 0.0, top]);
    let ring = |k: u32, s: u32| 1 + k * segments + s % segments;
    let top_pole = 1 + rings * segments;
    for s in 0..segments {
        mesh.triangles.push([0, ring(0, s + 1), ring(0, s)]);
        for k in 0..rings - 1 {
            mesh.quad([
                ring(k, s),
                ring(k, s + 1),
                ring(k + 1, s + 1),
                ring(k + 1, s),
            ]);
        }
        mesh.triangles
            .push([top_pole, ring(rings - 1, s), ring(rings - 1, s + 1)]);
    }
    mesh
}

fn plate_mesh(size: [f64; 2], cells: [u32; 2]) -> LocalMesh {
    let mut mesh = LocalMesh::default();
    for j in 0..=cells[1] {
        for i in 0..=cells[0] {
            let (x, y) = (i as f64 / cells[0] as f64, j as f64 / cells[1] as f64);
            mesh.positions.push([size[0] * x, size[1] * y, 0.0]);
        }
    }
    let id = |i: u32, j: u32| j * (cells[0] + 1) + i;
    for j in 0..cells[1] {
        for i in 0..cells[0] {
            mesh.quad([id(i, j), id(i + 1, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    mesh
}

impl Part {
    fn local_mesh(&self) -> LocalMesh {
        match self.shape {
            Shape::Box { size } => box_mesh(size),
            Shape::Revolved {
                radius,
                height,
                segments,
                rings,
                round,
            } => revolved_mesh(radius, height, segments, rings, round),
            Shape::Plate { size, cells } => plate_mesh(size, cells),
        }
    }

    fn world(&self, p: Vec3) -> [f32; 3] {
        let (sin, cos) = self.yaw.sin_cos();
        let turned = [cos * p[0] - sin * p[1], sin * p[0] + cos * p[1], p[2]];
        [0, 1, 2].map(|axis| (turned[axis] + self.origin[axis]) as f32)
    }
}

/// Draws a part shape with roughly `budget` triangles and size `size`.
fn random_shape(rng: &mut Rng, budget: u64, size: f64) -> Shape {
    let side = |budget: f64| (budget.sqrt().round() as u32).max(1);
    match rng.next_u64() % 4 {
        0 => Shape::Box {
            size: [
                size * rng.range(0.3, 1.0),
                size * rng.range(0.3, 1.0),
                size * rng.range(0.3, 1.0),
            ],
        },
        1 | 2 => {
            let segments = side(budget as f64 / 2.0).max(3);
            let rings = (budget / (2 * segments as u64)).max(2) as u32;
            let round = rng.unit() < 0.5;
            Shape::Revolved {
                radius: size / 2.0,
                height: size * rng.range(0.5, 3.0),
                segments,
                rings,
                round,
            }
        }
        _ => {
            let cells = side(budget as f64 / 2.0);
            Shape::Plate {
                size: [size, size * rng.range(0.2, 1.0)],
                cells: [cells, cells],
            }
        }
    }
}

/// Plates of `2ab` triangles with `a ~ b` that together use up `remaining`
/// (rounded down to even).
fn filler_plates(mut remaining: u64) -> Vec<Shape> {
    let mut plates = Vec::new();
    while remaining >= 2 {
        let cells = remaining / 2;
        let a = (cells as f64).sqrt() as u64;
        let b = cells / a;
        plates.push(Shape::Plate {
            size: [1.0, 1.0],
            cells: [a as u32, b as u32],
        });
        remaining -= 2 * a * b;
    }
    plates
}

fn plan_parts(triangles: u64, seed: u64) -> Vec<Part> {
    let budget = triangles.max(2);
    let max_part = ((8.0 * (budget as f64).sqrt()) as u64).clamp(64, MAX_PART_TRIANGLES);
    let mut rng = Rng::new(seed, 0);
    let slab = Shape::Box { size: SLAB_SIZE };
    let mut shapes = Vec::new();
    let mut used = 0;
    if budget >= slab.triangles() {
        shapes.push(slab);
        used = slab.triangles();
    }
    loop {
        let size = rng.log_range(MIN_PART_SIZE, MAX_PART_SIZE);
        let part_budget = rng.log_range(12.0, max_part as f64) as u64;
        let shape = random_shape(&mut rng, part_budget, size);
        if used + shape.triangles() > budget {
            break;
        }
        used += shape.triangles();
        shapes.push(shape);
    }
    shapes.extend(filler_plates(budget - used));
    place(shapes, &mut rng)
}

/// Puts part `k > 0` on a jittered sunflower spiral, so parts spread evenly
/// and the layout grows with the part count.
fn place(shapes: Vec<Shape>, rng: &mut Rng) -> Vec<Part> {
    let golden_angle = PI * (3.0 - 5f64.sqrt());
    let mut first_vertex = 0;
    shapes
        .into_iter()
        .enumerate()
        .map(|(k, shape)| {
            let origin = if k == 0 {
                [-SLAB_SIZE[0] / 2.0, -SLAB_SIZE[1] / 2.0, -SLAB_SIZE[2]]
            } else {
                let radius = SPIRAL_STEP * (k as f64).sqrt() + rng.range(-0.5, 0.5);
                let angle = golden_angle * k as f64 + rng.range(-0.2, 0.2);
                [
                    radius * angle.cos(),
                    radius * angle.sin(),
                    rng.range(0.0, 2.0),
                ]
            };
            let part = Part {
                shape,
                origin,
                yaw: rng.range(0.0, TAU),
                first_vertex,
            };
            first_vertex += shape.vertices();
            part
        })
        .collect()
}

/// Consecutive parts grouped into chunks of about `TRIANGLES_PER_CHUNK`.
fn part_chunks(parts: &[Part]) -> Vec<Range<usize>> {
    let mut chunks = Vec::new();
    let (mut start, mut triangles) = (0, 0);
    for (index, part) in parts.iter().enumerate() {
        triangles += part.shape.triangles();
        if triangles >= TRIANGLES_PER_CHUNK || index + 1 == parts.len() {
            chunks.push(start..index + 1);
            (start, triangles) = (index + 1, 0);
        }
    }
    chunks
}

/// The placed parts, grouped into chunks.
pub struct Assembly {
    parts: Vec<Part>,
    chunks: Vec<Range<usize>>,
}

impl Assembly {
    pub fn for_triangles(triangles: u64, seed: u64) -> Self {
        let parts = plan_parts(triangles, seed);
        let chunks = part_chunks(&parts);
        Assembly { parts, chunks }
    }
}

impl Generator for Assembly {
    fn summary(&self) -> GenSummary {
        GenSummary {
            vertices: self.parts.iter().map(|p| p.shape.vertices()).sum(),
            triangles: self.parts.iter().map(|p| p.shape.triangles()).sum(),
        }
    }

    fn vertex_chunks(&self) -> usize {
        self.chunks.len()
    }

    fn vertex_chunk(&self, chunk: usize, out: &mut Vec<[f32; 3]>) {
        for part in &self.parts[self.chunks[chunk].clone()] {
            let local = part.local_mesh();
            out.extend(local.positions.iter().map(|&p| part.world(p)));
        }
    }

    fn face_chunks(&self) -> usize {
        self.chunks.len()
    }

    fn face_chunk(&self, chunk: usize, out: &mut Vec<[u32; 3]>) {
        for part in &self.parts[self.chunks[chunk].clone()] {
            let offset = part.first_vertex as u32;
            let local = part.local_mesh();
            out.extend(local.triangles.iter().map(|t| t.map(|i| i + offset)));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::test_mesh::{generated, Mesh};
    use super::super::Kind;

    #[test]
    fn cad_has_many_parts_with_wildly_varying_triangle_sizes() {
        for (requested, seed) in [(5_000u64, 1), (20_001, 2)] {
            let (summary, mesh) = generated(Kind::Cad, requested, seed);
            assert_eq!(summary.triangles, requested / 2 * 2);
            assert!(mesh.components() >= 2);
            mesh.assert_consistent_manifold_with_boundary();
            let areas: Vec<f64> = mesh.faces.iter().map(|&f| mesh.area(f)).collect();
            let largest = areas.iter().cloned().fold(0.0, f64::max);
            let smallest = areas.iter().cloned().fold(f64::MAX, f64::min);
            assert!(
                largest / smallest >= 1e3,
                "areas span only {smallest}..{largest}"
            );
        }
    }

    #[test]
    fn closed_parts_are_watertight_and_face_outward() {
        for shape in [
            super::box_mesh([1.0, 2.0, 3.0]),
            super::revolved_mesh(0.5, 2.0, 7, 3, false),
            super::revolved_mesh(0.5, 0.0, 9, 5, true),
        ] {
            let mesh = Mesh {
                comment: String::new(),
                positions: shape
                    .positions
                    .iter()
                    .map(|p| p.map(|c| c as f32))
                    .collect(),
                faces: shape.triangles,
            };
            mesh.assert_closed_consistent_manifold();
            mesh.assert_no_degenerate_triangles();
            assert!(mesh.signed_volume() > 0.0);
        }
    }
}
