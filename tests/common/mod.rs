//! Shared test support: meshes, files with long strips, rays, the brute-force reference and
//! canonical triangle multisets for exact round-trip comparisons.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

use reducem::conversion::write_file;
use reducem::conversion::ChunkStats;
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::conversion::{strip_bounds, EncodedChunk};
use reducem::decode;
use reducem::format::grid::Grid;
use reducem::format::reader::ReducemFile;
use reducem::format::writer::FileInfo;
use reducem::geometry::{is_degenerate, Aabb, Point};
use reducem::input::read_mesh;
use reducem::mesh::Mesh;
use reducem::quantize::quantize_mesh;
pub use reducem::splitmix::SplitMix64;
use reducem::strip_encoding::{encode_strip, split_strip, EncodedStrip, Positions};
use reducem::strip_windows;
use reducem::toplevel::{self, TopLevel, TopLevelParams};
use reducem::trace::watertight::{intersect_triangle, RaySpace};
use reducem::trace::{Hit, Kernel, Ray, TraceOptions, Tracer};
use reducem_gen::{generate, Kind};

/// A fresh path in the system temp dir, unique per test and process.
pub fn temp_path(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reducem-tests-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create temp dir");
    dir.join(name)
}

/// A committed file of an older format, written by that version's writer: `tests/fixtures/`
/// (tori) or the fuzz corpus's `fuzz/corpus/reducem/` (spheres), as `dir/name`.
pub fn fixture_path(dir: &str, name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(dir).join(name)
}

/// The bytes of [`fixture_path`].
pub fn fixture_bytes(dir: &str, name: &str) -> Vec<u8> {
    let path = fixture_path(dir, name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A generated mesh, through a PLY file of the calling test's own (tests run in parallel in one
/// process, and two writers of one path would share its temporary).
pub fn generated(kind: Kind, triangles: u64) -> Mesh {
    let test = std::thread::current()
        .name()
        .unwrap_or("main")
        .replace("::", "-");
    let ply = temp_path(&format!("{test}-{}-{triangles}.ply", kind.name()));
    generate(kind, triangles, 5, &ply).expect("generate");
    read_mesh(&ply).expect("read")
}

/// `mesh` converted with `params` to the temporary file `name`, and opened.
pub fn converted(mesh: &Mesh, params: &BuildParams, name: &str) -> (PathBuf, ReducemFile) {
    let path = temp_path(name);
    convert_mesh(mesh, params, &path).expect("convert");
    let file = ReducemFile::open(&path).expect("open");
    (path, file)
}

/// A `w` × `h` quad grid with bumps, two triangles per quad, consistent winding.
pub fn grid(w: u32, h: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for y in 0..=h {
        for x in 0..=w {
            let z = ((x * 7 + y * 13) % 5) as f32 * 0.1;
            mesh.positions.push([x as f32, y as f32, z]);
        }
    }
    let id = |x: u32, y: u32| y * (w + 1) + x;
    for y in 0..h {
        for x in 0..w {
            mesh.triangles
                .push([id(x, y), id(x + 1, y), id(x + 1, y + 1)]);
            mesh.triangles
                .push([id(x, y), id(x + 1, y + 1), id(x, y + 1)]);
        }
    }
    mesh
}

/// A closed torus with `n` × `m` quads.
pub fn torus(n: u32, m: u32) -> Mesh {
    let mut mesh = Mesh::default();
    for i in 0..n {
        for j in 0..m {
            let (u, v) = (
                i as f32 / n as f32 * std::f32::consts::TAU,
                j as f32 / m as f32 * std::f32::consts::TAU,
            );
            let r = 3.0 + v.cos();
            mesh.positions.push([r * u.cos(), r * u.sin(), v.sin()]);
        }
    }
    let id = |i: u32, j: u32| (i % n) * m + (j % m);
    for i in 0..n {
        for j in 0..m {
            mesh.triangles
                .push([id(i, j), id(i + 1, j), id(i + 1, j + 1)]);
            mesh.triangles
                .push([id(i, j), id(i + 1, j + 1), id(i, j + 1)]);
        }
    }
    mesh
}

/// A closed icosphere of unit radius: an icosahedron with each face split `levels` times,
/// midpoints shared between neighbouring faces so the surface stays closed.
pub fn icosphere(levels: u32) -> Mesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<[f32; 3]> = vec![
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ];
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut midpoints = std::collections::HashMap::new();
        let mut midpoint = |a: u32, b: u32, positions: &mut Vec<[f32; 3]>| {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let (p, q) = (positions[a as usize], positions[b as usize]);
                positions.push([0, 1, 2].map(|i| (p[i] + q[i]) / 2.0));
                positions.len() as u32 - 1
            })
        };
        let mut finer = Vec::with_capacity(triangles.len() * 4);
        for [a, b, c] in triangles {
            let ab = midpoint(a, b, &mut positions);
            let bc = midpoint(b, c, &mut positions);
            let ca = midpoint(c, a, &mut positions);
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = finer;
    }
    for p in &mut positions {
        let length = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        *p = p.map(|x| x / length);
    }
    Mesh {
        positions,
        triangles,
        face_ids: None,
        normals: None,
        colors: None,
    }
}

/// `count` random triangles in the unit cube, sizes from tiny to large.
pub fn soup(count: usize, seed: u64) -> Mesh {
    let mut rng = SplitMix64::new(seed);
    let mut mesh = Mesh::default();
    for i in 0..count {
        let center = [rng.unit(), rng.unit(), rng.unit()];
        let size = 0.3 * rng.unit().powi(2);
        for _ in 0..3 {
            mesh.positions
                .push(center.map(|c| c + size * rng.range(-1.0, 1.0)));
        }
        let base = 3 * i as u32;
        mesh.triangles.push([base, base + 1, base + 2]);
    }
    mesh
}

/// A fan of needle triangles around a hub plus a row of near-degenerate caps.
pub fn slivers(count: u32) -> Mesh {
    let mut mesh = Mesh::default();
    mesh.positions.push([0.0, 0.0, 0.0]);
    for i in 0..=count {
        let angle = i as f32 / count as f32 * 0.01;
        mesh.positions
            .push([10.0 * angle.cos(), 10.0 * angle.sin(), 0.0]);
    }
    for i in 1..=count {
        mesh.triangles.push([0, i, i + 1]);
    }
    let base = mesh.positions.len() as u32;
    for i in 0..=count {
        let x = i as f32 * 0.1;
        mesh.positions.push([x, -1.0, 0.5]);
        mesh.positions.push([x + 0.05, -1.0 + 1e-5, 0.5 + 1e-6]);
    }
    for i in 0..count {
        let (a, b) = (base + 2 * i, base + 2 * i + 1);
        mesh.triangles.push([a, b, a + 2]);
        mesh.triangles.push([b, b + 2, a + 2]);
    }
    mesh
}

/// The mesh with every position mapped by `f`.
pub fn transformed(mesh: &Mesh, f: impl Fn(f32) -> f32) -> Mesh {
    Mesh {
        positions: mesh.positions.iter().map(|p| p.map(&f)).collect(),
        triangles: mesh.triangles.clone(),
        face_ids: None,
        normals: None,
        colors: None,
    }
}

/// Long strips over the mesh's triangles in mesh order: a triangle that continues the strip's
/// last edge with the right parity extends it, any other is joined through swap windows. Strips
/// end after `max_windows` windows. Exercises deep strip kd-trees and swaps whatever the real
/// stripifier does.
pub fn long_strips(mesh: &Mesh, max_windows: usize) -> Vec<Vec<u32>> {
    let mut strips = Vec::new();
    let mut current: Vec<u32> = Vec::new();
    for &[a, b, c] in &mesh.triangles {
        if current.len() >= max_windows + 2 {
            strips.push(std::mem::take(&mut current));
        }
        if current.is_empty() {
            current.extend([a, b, c]);
        } else if let Some(next) = continuation(&current, [a, b, c]) {
            current.push(next);
        } else {
            join(&mut current, [a, b, c]);
        }
    }
    if !current.is_empty() {
        strips.push(current);
    }
    strips
}

/// The reference that appends triangle `t` as the next window, if it shares the last edge in
/// the winding the window's parity gives.
fn continuation(strip: &[u32], t: [u32; 3]) -> Option<u32> {
    let n = strip.len();
    let k = n - 2;
    let (p, q) = (strip[n - 2], strip[n - 1]);
    let (first, second) = if k.is_multiple_of(2) { (p, q) } else { (q, p) };
    (0..3).find_map(|r| {
        let rotated = [t[r], t[(r + 1) % 3], t[(r + 2) % 3]];
        (rotated[0] == first && rotated[1] == second).then_some(rotated[2])
    })
}

/// Appends triangle `t` after swap windows, with one more repeated reference when needed so
/// that it lands on an even window and keeps its winding.
fn join(strip: &mut Vec<u32>, [a, b, c]: [u32; 3]) {
    let last = *strip.last().expect("non-empty strip");
    strip.extend([last, a, a]);
    if (strip.len() - 1) % 2 == 1 {
        strip.push(a);
    }
    strip.extend([b, c]);
}

/// Writes `strips` over `mesh` as a ReduceM file: the build side's encoder, top level and
/// writer, without the stripifier.
pub fn write_strips(mesh: &Mesh, strips: &[Vec<u32>], leaf_windows: usize, path: &Path) {
    let positions = Positions::F32(&mesh.positions);
    write_positioned_strips(positions, None, strips, leaf_windows, path);
}

/// [`write_strips`] over vertices in any encoding (`grid` when `positions` are grid points).
pub fn write_positioned_strips(
    positions: Positions,
    grid: Option<Grid>,
    strips: &[Vec<u32>],
    leaf_windows: usize,
    path: &Path,
) {
    let mut encoded: Vec<EncodedStrip> = Vec::new();
    let mut stack: Vec<&[u32]> = strips.iter().rev().map(|s| s.as_slice()).collect();
    while let Some(references) = stack.pop() {
        match encode_strip(references, positions, leaf_windows) {
            Ok(strip) => encoded.push(strip),
            Err(_) => {
                let (first, second) = split_strip(references);
                stack.push(second);
                stack.push(first);
            }
        }
    }
    let triangles = strips
        .iter()
        .map(|s| strip_windows::triangles(s).count() as u64);
    write_encoded_strips(&encoded, grid, triangles.sum(), leaf_windows, path);
}

/// Writes encoded strips (of `triangles` real triangles) with a top level over them.
pub fn write_encoded_strips(
    encoded: &[EncodedStrip],
    grid: Option<Grid>,
    triangles: u64,
    leaf_windows: usize,
    path: &Path,
) {
    let stats = ChunkStats {
        stored_vertices: encoded.iter().map(|s| s.vertex_count as u64).sum(),
        triangles,
        ..ChunkStats::default()
    };
    let bounds: Vec<Aabb> = encoded.iter().map(|s| s.bounds).collect();
    let top = toplevel::build(&bounds, &TopLevelParams::default()).expect("top level");
    let info = FileInfo {
        stats,
        leaf_windows,
        max_strip_length: 1000,
        bounds: bounds.iter().fold(Aabb::EMPTY, |a, b| a.union(b)),
        grid,
        weld: Default::default(),
        attributes: Default::default(),
        closedness: None,
        up: None,
        pooled: false,
    };
    write_file(path, &info, &top, encoded).expect("write file");
}

/// Writes an encoded chunk under a hand-built top level `top`, whose boxes may reach beyond the
/// model bounds (so no node grid covers them).
pub fn write_chunk_under(
    chunk: &EncodedChunk,
    top: &TopLevel,
    (leaf_windows, max_strip_length): (usize, usize),
    path: &Path,
) {
    let bounds = strip_bounds(&chunk.strips);
    let info = FileInfo {
        stats: chunk.stats,
        leaf_windows,
        max_strip_length,
        bounds: bounds.iter().fold(Aabb::EMPTY, |a, b| a.union(b)),
        grid: chunk.grid,
        weld: Default::default(),
        attributes: Default::default(),
        closedness: None,
        up: None,
        pooled: false,
    };
    write_file(path, &info, top, &chunk.strips).expect("write file");
}

/// A mesh written with long strips and opened.
pub fn open_with_long_strips(mesh: &Mesh, name: &str, max_windows: usize) -> ReducemFile {
    let path = temp_path(name);
    write_strips(mesh, &long_strips(mesh, max_windows), 2, &path);
    ReducemFile::open(&path).expect("open")
}

/// [`open_with_long_strips`] with vertices on the `bits`-bit grid over the mesh's bounds: long
/// strips over the quantized mesh (coincident grid points welded and collapsed triangles
/// dropped, as the build does).
pub fn open_with_long_strips_on_grid(
    mesh: &Mesh,
    name: &str,
    max_windows: usize,
    bits: u32,
) -> ReducemFile {
    let grid = Grid::over(&mesh.bounds(), bits);
    let mut quantized = quantize_mesh(mesh, &grid);
    let positions = &quantized.mesh.positions;
    quantized.mesh.triangles.retain(|t| {
        let [a, b, c] = t.map(|v| positions[v as usize]);
        !is_degenerate(&a, &b, &c)
    });
    let positions = Positions::Grid {
        points: &quantized.points,
        decoded: &quantized.mesh.positions,
        bits,
    };
    let strips = long_strips(&quantized.mesh, max_windows);
    let path = temp_path(name);
    write_positioned_strips(positions, Some(grid), &strips, 2, &path);
    ReducemFile::open(&path).expect("open")
}

/// `mesh` with every vertex snapped to the `bits`-bit grid over its bounds (not welded), and
/// that grid: what a grid file of `mesh` must decode to, exactly.
pub fn quantized_input(mesh: &Mesh, bits: u32) -> (Mesh, Grid) {
    let grid = Grid::over(&mesh.bounds(), bits);
    let snapped = Mesh {
        positions: mesh
            .positions
            .iter()
            .map(|p| grid.decode(&grid.quantize(p)))
            .collect(),
        triangles: mesh.triangles.clone(),
        face_ids: None,
        normals: None,
        colors: None,
    };
    (snapped, grid)
}

/// The brute-force closest hit over every decoded triangle: `(t, triangle)`.
pub fn brute_force(file: &ReducemFile, ray: &Ray) -> Option<(f32, [Point; 3])> {
    let space = RaySpace::new(ray.origin, ray.direction);
    let mut best: Option<(f32, [Point; 3])> = None;
    for triangle in decode::triangles(file) {
        let limit = best.map_or(ray.tmax, |(t, _)| t);
        if let Some(hit) = intersect_triangle(&space, &triangle, ray.tmin, limit) {
            if best.is_none_or(|(t, _)| hit.t < t) {
                best = Some((hit.t, triangle));
            }
        }
    }
    best
}

/// The triangle a hit reports, in input winding.
pub fn hit_triangle(file: &ReducemFile, hit: &Hit) -> [Point; 3] {
    file.strip(hit.strip as usize)
        .window_points(hit.window as usize)
        .expect("a hit is never a swap window")
}

pub fn shares_vertex(a: &[Point; 3], b: &[Point; 3]) -> bool {
    a.iter()
        .any(|p| b.iter().any(|q| p.map(f32::to_bits) == q.map(f32::to_bits)))
}

/// Bit patterns of every field, so hits compare exactly.
pub fn hit_bits(hit: &Option<Hit>) -> Option<[u32; 8]> {
    hit.map(|h| {
        [
            h.t.to_bits(),
            h.u.to_bits(),
            h.v.to_bits(),
            h.normal[0].to_bits(),
            h.normal[1].to_bits(),
            h.normal[2].to_bits(),
            h.strip,
            h.window as u32,
        ]
    })
}

/// A ray from `origin` through `target`, unbounded.
pub fn ray_towards(origin: Point, target: Point) -> Ray {
    Ray {
        origin,
        direction: [0, 1, 2].map(|i| target[i] - origin[i]),
        tmin: 0.0,
        tmax: f32::INFINITY,
    }
}

/// A ray between two random points of the box `[-5, 5] × [-5, 5] × [-2, 2]`, unbounded.
pub fn random_ray_in_the_slab(rng: &mut SplitMix64) -> Ray {
    let mut point = || {
        [
            rng.range(-5.0, 5.0),
            rng.range(-5.0, 5.0),
            rng.range(-2.0, 2.0),
        ]
    };
    let origin = point();
    ray_towards(origin, point())
}

/// Every mesh vertex and every edge midpoint: the points rays are aimed at exactly.
pub fn vertex_and_edge_targets(mesh: &Mesh) -> Vec<Point> {
    let mut targets = mesh.positions.clone();
    for t in &mesh.triangles {
        for i in 0..3 {
            let (p, q) = (
                mesh.positions[t[i] as usize],
                mesh.positions[t[(i + 1) % 3] as usize],
            );
            targets.push([0, 1, 2].map(|k| p[k] * 0.5 + q[k] * 0.5));
        }
    }
    targets
}

/// Corner positions rotated so the lexicographically smallest bit pattern comes first: equal
/// for two triangles exactly when they have the same corners in the same winding.
pub fn canonical(t: [Point; 3]) -> [[u32; 3]; 3] {
    let bits = t.map(|p| p.map(f32::to_bits));
    let first = (0..3).min_by_key(|&i| bits[i]).unwrap_or(0);
    [0, 1, 2].map(|k| bits[(first + k) % 3])
}

/// The sorted canonical multiset of a mesh's non-degenerate triangles.
pub fn expected_triangles(mesh: &Mesh) -> Vec<[[u32; 3]; 3]> {
    let mut all: Vec<_> = mesh
        .triangles
        .iter()
        .map(|t| mesh.triangle_points(t))
        .filter(|[a, b, c]| !is_degenerate(a, b, c))
        .map(canonical)
        .collect();
    all.sort_unstable();
    all
}

/// The sorted canonical multiset of decoded triangles.
pub fn canonical_sorted(triangles: impl Iterator<Item = [Point; 3]>) -> Vec<[[u32; 3]; 3]> {
    let mut all: Vec<_> = triangles.map(canonical).collect();
    all.sort_unstable();
    all
}

/// Every tracer configuration whose answers must agree bit for bit: each kernel this CPU runs
/// ([`Kernel::supported`]), single rays and packets; the baseline kernel's single rays first.
pub fn tracer_variants(file: &ReducemFile) -> Vec<(String, Tracer<'_>)> {
    let mut variants = Vec::new();
    for kernel in Kernel::supported() {
        for packets in [false, true] {
            let options = TraceOptions {
                packets,
                kernel,
                ..TraceOptions::default()
            };
            let name = format!("{kernel} {}", if packets { "packets" } else { "single" });
            variants.push((name, Tracer::new(file, options)));
        }
    }
    variants
}

/// Rays from every `inside` point at every vertex and edge midpoint all hit, with every
/// [`tracer_variants`] configuration; returns the count.
pub fn assert_closed(file: &ReducemFile, mesh: &Mesh, inside: &[Point], what: &str) -> usize {
    let targets = vertex_and_edge_targets(mesh);
    let mut traced = 0;
    for (variant, tracer) in tracer_variants(file) {
        for &origin in inside {
            let rays: Vec<Ray> = targets.iter().map(|&t| ray_towards(origin, t)).collect();
            let hits = tracer.intersect_batch(&rays);
            let occluded = tracer.occluded_batch(&rays);
            for ((ray, hit), occluded) in rays.iter().zip(&hits).zip(&occluded) {
                assert!(
                    hit.is_some() && *occluded,
                    "{what} ({variant}): {ray:?} escaped"
                );
            }
            traced += 2 * rays.len();
        }
    }
    traced
}
