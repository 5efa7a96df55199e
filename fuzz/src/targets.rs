//! The fuzz targets: what one input exercises and which invariants must hold on the way.
//!
//! A target either accepts its input or rejects it with an error; both are fine. A panic is a
//! finding, whether it comes from the code under test or from an invariant asserted here:
//! * `ply`: the whole-file reader and the windowed stream agree on what they both accept, and
//!   an accepted mesh converts to a file that opens, decodes to its triangle count and traces.
//! * `obj`: an accepted mesh converts, opens, decodes and traces the same way.
//! * `stl`: binary, ASCII and gzip/zstd-compressed STL through the table of formats; an
//!   accepted mesh converts, opens, decodes and traces the same way.
//! * `gltf`: GLB and `.gltf` JSON (data-URI buffers) through the table of formats, with
//!   normals and colours asked for and not; an accepted mesh converts, opens, decodes and traces.
//! * `reducem`: an opened file decodes to its header's triangle count and traces single rays
//!   and packets to the same hits (corrupt bounds may lose hits, never cause a panic).
//! * `rays`: a ray file `query` accepts traces on a fixed closed model with packets equal to
//!   single rays, `t` inside `[tmin, tmax]` and hit or miss as the brute-force reference says.

use std::path::{Path, PathBuf};

use reducem::conversion::{convert_mesh, BuildParams};
use reducem::decode;
use reducem::format::reader::ReducemFile;
use reducem::input::{
    read_mesh, read_mesh_with, read_obj, read_obj_with, weld_identical_positions, AttributeRequest,
    PlyFile, PlyStream,
};
use reducem::mesh::Mesh;
use reducem::trace::ray_file::parse_rays;
use reducem::trace::watertight::{intersect_triangle, RaySpace};
use reducem::trace::{Hit, Ray, TraceOptions, Tracer};

use crate::mutate::{Structure, GLTF_DICTIONARY, OBJ_DICTIONARY, PLY_DICTIONARY, STL_DICTIONARY};

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Target {
    Ply,
    Obj,
    Stl,
    Gltf,
    Reducem,
    Rays,
}

/// Whether the code under test took the input.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Outcome {
    Accepted,
    Rejected,
}

/// Converting fuzzed meshes is the slow part of a case; bigger accepted meshes are only read.
const MAX_CONVERTED_TRIANGLES: usize = 20_000;

/// Stream windows far below any real setting, so faces and vertices straddle many windows.
const STREAM_WINDOW_BYTES: usize = 64;

impl Target {
    pub const ALL: [Target; 6] = [
        Target::Ply,
        Target::Obj,
        Target::Stl,
        Target::Gltf,
        Target::Reducem,
        Target::Rays,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Target::Ply => "ply",
            Target::Obj => "obj",
            Target::Stl => "stl",
            Target::Gltf => "gltf",
            Target::Reducem => "reducem",
            Target::Rays => "rays",
        }
    }

    pub fn from_name(name: &str) -> Option<Target> {
        Target::ALL.into_iter().find(|t| t.name() == name)
    }

    /// File extension of the target's inputs (the PLY reader dispatches on it).
    pub fn extension(self) -> &'static str {
        match self {
            Target::Ply => "ply",
            Target::Obj => "obj",
            Target::Stl => "stl",
            // GLB is recognised by its magic, JSON by this extension.
            Target::Gltf => "gltf",
            Target::Reducem => "rdm",
            Target::Rays => "rays",
        }
    }

    pub fn structure(self) -> Structure {
        match self {
            Target::Ply => Structure::Text(PLY_DICTIONARY),
            Target::Obj => Structure::Text(OBJ_DICTIONARY),
            Target::Stl => Structure::Text(STL_DICTIONARY),
            Target::Gltf => Structure::Text(GLTF_DICTIONARY),
            Target::Reducem => Structure::Reducem,
            Target::Rays => Structure::Rays,
        }
    }
}

/// Scratch files of one fuzzing thread, and the model the `rays` target traces.
pub struct Workspace {
    dir: PathBuf,
    model: ReducemFile,
}

impl Workspace {
    /// Creates the scratch directory `dir` and writes the closed model into it.
    pub fn new(dir: &Path) -> std::io::Result<Workspace> {
        std::fs::create_dir_all(dir)?;
        let model_path = dir.join("model.rdm");
        convert_mesh(&octahedron_sphere(4), &BuildParams::default(), &model_path)
            .map_err(std::io::Error::other)?;
        let model = ReducemFile::open(&model_path).map_err(std::io::Error::other)?;
        Ok(Workspace {
            dir: dir.to_path_buf(),
            model,
        })
    }

    /// Runs `target` on `bytes`. Panics on a finding.
    pub fn run(&self, target: Target, bytes: &[u8]) -> Outcome {
        let path = self.dir.join(format!("case.{}", target.extension()));
        std::fs::write(&path, bytes).expect("write the case to the scratch directory");
        let accepted = match target {
            Target::Ply => self.run_ply(&path),
            Target::Obj => {
                // Reading attributes must fail cleanly or succeed, whatever the file says.
                let _ = read_obj_with(&path, ALL_ATTRIBUTES);
                read_obj(&path)
                    .map(|mesh| self.convert_and_trace(&weld_identical_positions(mesh)))
                    .is_ok()
            }
            Target::Stl | Target::Gltf => {
                let _ = read_mesh_with(&path, ALL_ATTRIBUTES);
                read_mesh(&path)
                    .map(|mesh| self.convert_and_trace(&mesh))
                    .is_ok()
            }
            Target::Reducem => ReducemFile::open(&path)
                .map(|file| exercise_file(&file))
                .is_ok(),
            Target::Rays => parse_rays(&path, bytes)
                .map(|rays| check_rays(&self.model, &rays))
                .is_ok(),
        };
        if accepted {
            Outcome::Accepted
        } else {
            Outcome::Rejected
        }
    }

    fn run_ply(&self, path: &Path) -> bool {
        let whole = PlyFile::open(path).and_then(|ply| ply.read_mesh());
        if let Some(streamed) = read_streamed(path) {
            if let Ok(whole) = &whole {
                assert_eq!(
                    (
                        &streamed.positions,
                        &streamed.triangles,
                        face_ids(&streamed)
                    ),
                    (&whole.positions, &whole.triangles, face_ids(whole)),
                    "the stream and the whole-file reader differ"
                );
            }
        }
        check_ply_attributes(path);
        whole
            .map(|mesh| self.convert_and_trace(&weld_identical_positions(mesh)))
            .is_ok()
    }

    fn convert_and_trace(&self, mesh: &Mesh) {
        if mesh.triangles.len() > MAX_CONVERTED_TRIANGLES {
            return;
        }
        let path = self.dir.join("converted.rdm");
        let stats = convert_mesh(mesh, &BuildParams::default(), &path).expect("convert");
        let file = ReducemFile::open(&path).expect("a converted file opens");
        assert_eq!(
            stats.triangles + stats.dropped_triangles,
            mesh.triangles.len() as u64,
            "every input triangle is stored or counted as dropped"
        );
        exercise_file(&file);
    }
}

/// Normals and colours, for the readers that take a request.
const ALL_ATTRIBUTES: AttributeRequest = AttributeRequest {
    normals: true,
    colors: true,
};

/// When the file has normals and colours, reading them whole and through `PlyStream` gives
/// the same values (or both fail).
fn check_ply_attributes(path: &Path) {
    let Ok(ply) = PlyFile::open(path) else {
        return;
    };
    if ply.check_attributes(ALL_ATTRIBUTES).is_err() {
        return;
    }
    let whole = ply.read_mesh_with(ALL_ATTRIBUTES);
    let Some(stream) = PlyStream::open(path).ok().filter(|s| s.is_streamable()) else {
        return;
    };
    let ids: Vec<u32> = (0..stream.vertex_count().min(1 << 16) as u32).collect();
    let streamed = stream.attributes_of(&ids, STREAM_WINDOW_BYTES, ALL_ATTRIBUTES);
    if let (Ok(whole), Ok(streamed)) = (whole, streamed) {
        assert_eq!(
            (
                first(whole.normals, ids.len()),
                first(whole.colors, ids.len())
            ),
            (streamed.normals, streamed.colors),
            "streamed attributes differ from the whole-file read"
        );
    }
}

/// The first `count` of `values`.
fn first<T>(values: Option<Vec<T>>, count: usize) -> Option<Vec<T>> {
    values.map(|mut values| {
        values.truncate(count);
        values
    })
}

/// The mesh through `PlyStream`, when the file is streamable and every window reads.
fn read_streamed(path: &Path) -> Option<Mesh> {
    let stream = PlyStream::open(path).ok()?;
    if !stream.is_streamable() {
        return None;
    }
    let mut mesh = Mesh::default();
    stream
        .for_each_position_window(STREAM_WINDOW_BYTES, |_, positions| {
            mesh.positions.extend_from_slice(positions)
        })
        .ok()?;
    let mut face_ids = Vec::new();
    stream
        .for_each_triangle(STREAM_WINDOW_BYTES, |face, triangle| {
            mesh.triangles.push(triangle);
            face_ids.push(face as u32);
        })
        .ok()?;
    mesh.face_ids = Some(face_ids);
    Some(mesh)
}

/// Every triangle's face, however the mesh records them.
fn face_ids(mesh: &Mesh) -> Vec<u32> {
    (0..mesh.triangles.len()).map(|t| mesh.face_id(t)).collect()
}

/// Decodes, inspects and traces an opened file.
fn exercise_file(file: &ReducemFile) {
    assert_eq!(
        decode::triangles(file).count() as u64,
        file.header().triangle_count,
        "decoded triangles disagree with the validated header"
    );
    reducem::inspect::file_stats(file);
    // Checksums fail on most corrupt files that open; computing them must not.
    let _ = file.verify_checksums();
    let rays = probe_rays(file);
    let single = Tracer::new(
        file,
        TraceOptions {
            packets: false,
            ..TraceOptions::default()
        },
    );
    let packets = Tracer::new(file, TraceOptions::default());
    let expected = single.intersect_chunk(&rays);
    assert_eq!(
        hit_bits(&packets.intersect_chunk(&rays)),
        hit_bits(&expected)
    );
    assert_eq!(packets.occluded_chunk(&rays), single.occluded_chunk(&rays));
    for hit in expected.iter().flatten() {
        reducem::trace::hit_attributes(file, hit);
    }
}

/// Axis-parallel rays through the centre and corners of the header's bounds, plus diagonal
/// rays from outside them.
fn probe_rays(file: &ReducemFile) -> Vec<Ray> {
    let header = file.header();
    let finite = |x: f32| if x.is_finite() { x } else { 0.0 };
    let min = header.bounds_min.map(finite);
    let max = header.bounds_max.map(finite);
    let centre: [f32; 3] = std::array::from_fn(|i| min[i] * 0.5 + max[i] * 0.5);
    let mut rays = Vec::new();
    for target in [centre, min, max] {
        for axis in 0..3 {
            for sign in [1.0f32, -1.0] {
                let mut direction = [0.0f32; 3];
                direction[axis] = sign;
                let mut origin = target;
                origin[axis] -= sign * (max[axis] - min[axis]).abs().max(1.0) * 2.0;
                rays.push(Ray {
                    origin,
                    direction,
                    tmin: 0.0,
                    tmax: f32::INFINITY,
                });
            }
        }
        let origin = [0, 1, 2].map(|i| min[i] - (max[i] - min[i]).abs() - 1.0);
        rays.push(Ray {
            origin,
            direction: [0, 1, 2].map(|i| target[i] - origin[i]),
            tmin: 0.0,
            tmax: f32::INFINITY,
        });
    }
    // Bounds near the f32 limits overflow the arithmetic above; `query` only passes finite
    // rays with a non-zero direction, so that is the tracer's domain.
    rays.retain(|ray| {
        ray.origin
            .iter()
            .chain(&ray.direction)
            .all(|x| x.is_finite())
            && ray.direction != [0.0; 3]
    });
    rays
}

/// Traces `query`-accepted rays on the model and checks them against the reference.
fn check_rays(model: &ReducemFile, rays: &[Ray]) {
    let single = Tracer::new(
        model,
        TraceOptions {
            packets: false,
            ..TraceOptions::default()
        },
    );
    let packets = Tracer::new(model, TraceOptions::default());
    let hits = single.intersect_chunk(rays);
    assert_eq!(hit_bits(&packets.intersect_chunk(rays)), hit_bits(&hits));
    let occluded = packets.occluded_chunk(rays);
    for ((ray, hit), occluded) in rays.iter().zip(&hits).zip(occluded) {
        let reference = brute_force(model, ray);
        assert_eq!(
            hit.is_some(),
            reference.is_some(),
            "{ray:?}: tracer {hit:?}, reference t {reference:?}"
        );
        assert_eq!(occluded, hit.is_some(), "{ray:?}: occlusion disagrees");
        if let Some(hit) = hit {
            assert!(
                ray.tmin <= hit.t && hit.t <= ray.tmax,
                "{ray:?}: t {} outside the ray's interval",
                hit.t
            );
        }
    }
}

/// The closest `t` over every decoded triangle.
fn brute_force(file: &ReducemFile, ray: &Ray) -> Option<f32> {
    let space = RaySpace::new(ray.origin, ray.direction);
    decode::triangles(file)
        .filter_map(|triangle| intersect_triangle(&space, &triangle, ray.tmin, ray.tmax))
        .map(|hit| hit.t)
        .reduce(f32::min)
}

fn hit_bits(hits: &[Option<Hit>]) -> Vec<Option<[u32; 4]>> {
    hits.iter()
        .map(|hit| hit.map(|h| [h.t.to_bits(), h.u.to_bits(), h.v.to_bits(), h.strip]))
        .collect()
}

/// A closed sphere: an octahedron with each face split `levels` times, projected outwards.
/// Shared edge midpoints keep it watertight.
pub fn octahedron_sphere(levels: u32) -> Mesh {
    let mut mesh = Mesh {
        positions: vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ],
        triangles: vec![
            [0, 2, 4],
            [2, 1, 4],
            [1, 3, 4],
            [3, 0, 4],
            [2, 0, 5],
            [1, 2, 5],
            [3, 1, 5],
            [0, 3, 5],
        ],
        face_ids: None,
        normals: None,
        colors: None,
    };
    for _ in 0..levels {
        let mut midpoints = std::collections::HashMap::new();
        let mut finer = Vec::with_capacity(mesh.triangles.len() * 4);
        for [a, b, c] in std::mem::take(&mut mesh.triangles) {
            let mut midpoint = |p: u32, q: u32| {
                *midpoints.entry((p.min(q), p.max(q))).or_insert_with(|| {
                    let (x, y) = (mesh.positions[p as usize], mesh.positions[q as usize]);
                    mesh.positions.push([0, 1, 2].map(|i| (x[i] + y[i]) / 2.0));
                    mesh.positions.len() as u32 - 1
                })
            };
            let (ab, bc, ca) = (midpoint(a, b), midpoint(b, c), midpoint(c, a));
            finer.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        mesh.triangles = finer;
    }
    for p in &mut mesh.positions {
        let length = (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt();
        *p = p.map(|x| x / length);
    }
    mesh
}
