//! Pooled grid files (format 4.1, `vertex_encoding` 5) against format 4.0 grid files
//! (`vertex_encoding` 3) of the same strips, the pooled file's top level collapsed for its
//! bytes: `reducem query` (closest hits in full records, occlusion, crossing counts) and
//! `reducem closest` answer byte for byte alike, and both decode to the same triangles.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

use common::{canonical_sorted, generated, temp_path, SplitMix64};
use reducem::conversion::{convert_mesh, encode_chunk, BuildParams, ChunkLayout};
use reducem::decode;
use reducem::format::reader::ReducemFile;
use reducem::format::writer::FileInfo;
use reducem::format::{VertexEncoding, POOLED_MINOR};
use reducem::mesh::Mesh;
use reducem_gen::Kind;

fn grid_params() -> BuildParams {
    BuildParams {
        grid_bits: Some(20),
        leaf_windows: 8,
        ..BuildParams::default()
    }
}

/// `mesh` converted as the writer does (pooled) and as format 4.0 wrote the same strips.
fn both_files(mesh: &Mesh, name: &str) -> (PathBuf, PathBuf) {
    let params = grid_params();
    let pooled = temp_path(&format!("{name}-pooled.rdm"));
    convert_mesh(mesh, &params, &pooled).expect("convert pooled");
    let chunk = encode_chunk(mesh, &params);
    let layout = ChunkLayout::new(&chunk.strips, &params.top_level).expect("layout");
    let info = FileInfo {
        stats: chunk.stats,
        leaf_windows: params.leaf_windows,
        max_strip_length: params.stripify.max_length,
        bounds: layout.bounds,
        grid: chunk.grid,
        weld: Default::default(),
        attributes: params.attributes,
        closedness: None,
        up: None,
        pooled: false,
    };
    let unpooled = temp_path(&format!("{name}-4.0.rdm"));
    reducem::conversion::write_file(&unpooled, &info, &layout.top, &chunk.strips)
        .expect("write 4.0");
    (pooled, unpooled)
}

/// Rays from random vertices in random directions (AO-like, short) and from outside the model
/// through random vertices (camera-like), as `reducem query` reads them.
fn ray_file(mesh: &Mesh, path: &Path) {
    let mut rng = SplitMix64::new(17);
    let bounds = mesh.bounds();
    let diagonal = (0..3).map(|a| bounds.extent(a).powi(2)).sum::<f32>().sqrt();
    let mut bytes = Vec::new();
    for k in 0..4000 {
        let vertex = mesh.positions[rng.next_u64() as usize % mesh.positions.len()];
        let direction: [f32; 3] = std::array::from_fn(|_| rng.range(-1.0, 1.0));
        let ray: [f32; 8] = match k % 2 {
            0 => {
                let [x, y, z] = vertex;
                let [dx, dy, dz] = direction;
                [x, y, z, dx, dy, dz, 1e-4 * diagonal, 0.1 * diagonal]
            }
            _ => {
                let origin: [f32; 3] = std::array::from_fn(|a| vertex[a] - direction[a] * diagonal);
                let [x, y, z] = origin;
                let [dx, dy, dz] = direction;
                [x, y, z, dx, dy, dz, 0.0, f32::INFINITY]
            }
        };
        bytes.extend(ray.iter().flat_map(|c| c.to_le_bytes()));
    }
    std::fs::write(path, bytes).expect("write rays");
}

fn point_file(mesh: &Mesh, path: &Path) {
    let mut rng = SplitMix64::new(29);
    let bounds = mesh.bounds();
    let bytes: Vec<u8> = (0..2000)
        .flat_map(|_| {
            let p: [f32; 3] =
                std::array::from_fn(|a| bounds.min[a] + rng.range(-0.2, 1.2) * bounds.extent(a));
            p.into_iter().flat_map(f32::to_le_bytes)
        })
        .collect();
    std::fs::write(path, bytes).expect("write points");
}

/// The answer file of `reducem ARGS... -o OUT` on `model`.
fn answers(model: &Path, args: &[&str], out: &Path) -> Vec<u8> {
    let status = Command::new(env!("CARGO_BIN_EXE_reducem"))
        .args(args)
        .arg(model)
        .arg("-o")
        .arg(out)
        .status()
        .expect("run reducem");
    assert!(status.success(), "reducem {args:?} on {}", model.display());
    std::fs::read(out).expect("read answers")
}

fn assert_same_answers(kind: Kind, triangles: u64) {
    let mesh = generated(kind, triangles);
    let name = format!("grid-pool-{}", kind.name());
    let (pooled, unpooled) = both_files(&mesh, &name);
    let pooled_file = ReducemFile::open(&pooled).expect("open pooled");
    let unpooled_file = ReducemFile::open(&unpooled).expect("open 4.0");
    pooled_file.validate_all().expect("pooled file valid");
    let header = pooled_file.header();
    assert_eq!(header.vertex_encoding, VertexEncoding::GridPooled as u32);
    assert_eq!(
        (header.version_major, header.version_minor),
        (4, POOLED_MINOR)
    );
    let header = unpooled_file.header();
    assert_eq!(
        header.vertex_encoding,
        VertexEncoding::GridPackedReferences as u32
    );
    assert_eq!((header.version_major, header.version_minor), (4, 0));
    assert!(pooled_file.file_bytes() < unpooled_file.file_bytes());
    assert_eq!(
        canonical_sorted(decode::triangles(&pooled_file)),
        canonical_sorted(decode::triangles(&unpooled_file)),
        "{name}: decoded triangles differ"
    );
    assert_decoded_ply_writes_each_pool_once(&pooled_file, &unpooled_file, &name);
    let rays = temp_path(&format!("{name}.rays"));
    ray_file(&mesh, &rays);
    let points = temp_path(&format!("{name}.points"));
    point_file(&mesh, &points);
    let rays = rays.to_str().unwrap();
    let points = points.to_str().unwrap();
    let queries: [&[&str]; 4] = [
        &["query", "--rays", rays, "--format", "full"],
        &["query", "--rays", rays, "--occluded"],
        &["query", "--rays", rays, "--count"],
        &["closest", "--points", points],
    ];
    for (q, args) in queries.iter().enumerate() {
        let out = |which: &str| temp_path(&format!("{name}-{q}-{which}.out"));
        let expected = answers(&unpooled, args, &out("4.0"));
        let actual = answers(&pooled, args, &out("pooled"));
        assert_eq!(actual, expected, "{name}: reducem {args:?} answers differ");
        if q == 0 {
            let hits = expected
                .chunks(48)
                .filter(|record| f32::from_le_bytes(record[..4].try_into().unwrap()).is_finite())
                .count();
            assert!(hits > 100, "{name}: only {hits} rays hit");
        }
    }
}

/// `reducem decode`'s PLY of the pooled file: each pool's points once, fewer vertices than the
/// 4.0 file stores, and the 4.0 file's triangles; the pooled file's header counts those points
/// as stored.
fn assert_decoded_ply_writes_each_pool_once(
    pooled: &ReducemFile,
    unpooled: &ReducemFile,
    name: &str,
) {
    let ply = temp_path(&format!("{name}-decoded.ply"));
    decode::write_ply(pooled, &ply).expect("decode pooled");
    let mut offsets: Vec<_> = (0..pooled.strip_count())
        .map(|s| {
            pooled.strip(s);
            let place = pooled
                .pool(s)
                .expect("every strip of a pooled file is in a pool");
            (place.offset, place.points.len())
        })
        .collect();
    offsets.dedup();
    let pool_points: usize = offsets.iter().map(|&(_, points)| points).sum();
    let bytes = std::fs::read(&ply).unwrap();
    let header = String::from_utf8_lossy(&bytes[..bytes.len().min(512)]);
    let vertex_line = header
        .lines()
        .find(|line| line.starts_with("element vertex "));
    assert_eq!(
        vertex_line,
        Some(format!("element vertex {pool_points}").as_str())
    );
    assert!((pool_points as u64) < unpooled.header().stored_vertex_count);
    assert_eq!(pooled.header().stored_vertex_count, pool_points as u64);
    assert_eq!(pooled.pool_points(), Some(pool_points as u64));
    assert_eq!(unpooled.pool_points(), None);
    let mesh = reducem::input::read_mesh(&ply).expect("read the decoded PLY");
    let corners = mesh
        .triangles
        .iter()
        .map(|t| t.map(|v| mesh.positions[v as usize]));
    assert_eq!(
        canonical_sorted(corners),
        canonical_sorted(decode::triangles(unpooled)),
        "{name}: the decoded PLY's triangles differ"
    );
}

#[test]
fn pooled_scan_answers_as_its_format_4_0_file() {
    assert_same_answers(Kind::Scan, 30_000);
}

#[test]
fn pooled_terrain_answers_as_its_format_4_0_file() {
    assert_same_answers(Kind::Terrain, 20_000);
}

#[test]
fn files_with_short_leaves_or_attributes_are_not_pooled() {
    let mesh = generated(Kind::Scan, 2_000);
    let short_leaves = BuildParams {
        leaf_windows: 4,
        ..grid_params()
    };
    let (_, file) = common::converted(&mesh, &short_leaves, "grid-pool-short-leaves.rdm");
    assert_eq!(
        file.header().vertex_encoding,
        VertexEncoding::GridPackedReferences as u32
    );
    let with_normals = BuildParams {
        attributes: reducem::format::attributes::AttributeSet {
            normals: reducem::format::attributes::NormalEncoding::Oct16,
            ..Default::default()
        },
        ..grid_params()
    };
    let (_, file) = common::converted(&mesh, &with_normals, "grid-pool-normals.rdm");
    assert_eq!(
        file.header().vertex_encoding,
        VertexEncoding::GridPackedReferences as u32
    );
    let (_, file) = common::converted(&mesh, &grid_params(), "grid-pool-default.rdm");
    assert_eq!(
        file.header().vertex_encoding,
        VertexEncoding::GridPooled as u32
    );
}

/// A 4.1 file of an earlier writer, whose header counts the vertices of the strips' views (the
/// fuzz corpus's pooled file): `reducem inspect` reports the pools' points, as for a file whose
/// header counts them.
#[test]
fn inspect_counts_pool_points_in_earlier_pooled_files() {
    let seed = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz/corpus/reducem/grid-pooled.rdm");
    let file = ReducemFile::open(&seed).expect("open the pooled seed");
    let points = file.pool_points().expect("a pooled file");
    let mut spans = 0;
    let mut previous = None;
    let mut counted = 0;
    for s in 0..file.strip_count() {
        file.strip(s);
        let place = file.pool(s).expect("every strip is in a pool");
        spans += u64::from(file.strip_records()[s].vertex_count);
        if previous != Some(place.offset) {
            counted += place.points.len() as u64;
            previous = Some(place.offset);
        }
    }
    assert_eq!(points, counted);
    assert_eq!(file.header().stored_vertex_count, spans);
    assert!(points < spans, "{points} pool points, {spans} spanned");
    let stats = reducem::inspect::file_stats(&file);
    assert_eq!(stats.stored_vertices, points);
}
