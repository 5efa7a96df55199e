//! Grid (quantized) vertices: a grid file decodes to exactly the quantized input, every vertex
//! lies within the grid's error bound of its input, chunks encoded on one model grid stay
//! closed across their boundaries, and the tolerance weld reconnects perturbed meshes.

mod common;

use common::*;
use reducem::chunking::local_mesh;
use reducem::conversion::{convert_mesh, encode_chunk, encode_chunk_on, BuildParams};
use reducem::decode;
use reducem::format::grid::Grid;
use reducem::format::reader::{ReducemFile, VertexLayout};
use reducem::geometry::{distance, Point};
use reducem::input::{weld_within_tolerance, Vertices};
use reducem::inspect::file_stats;
use reducem::mesh::Mesh;
use reducem::strip_encoding::{self, EncodedStrip};
use reducem::trace::{Ray, TraceOptions, Tracer};

fn grid_params(bits: u32, leaf_windows: usize) -> BuildParams {
    BuildParams {
        leaf_windows,
        grid_bits: Some(bits),
        ..BuildParams::default()
    }
}

fn convert_on_grid(mesh: &Mesh, params: &BuildParams, name: &str) -> ReducemFile {
    let path = temp_path(name);
    convert_mesh(mesh, params, &path).expect("convert");
    let file = ReducemFile::open(&path).expect("open");
    file.verify_checksums().expect("checksums");
    file
}

fn assert_grid_round_trip(name: &str, mesh: &Mesh, bits: u32, leaf_windows: usize) {
    let params = grid_params(bits, leaf_windows);
    let chunk = encode_chunk(mesh, &params);
    let layout = chunk.grid.into();
    for (i, strip) in chunk.strips.iter().enumerate() {
        strip_encoding::validate(strip, leaf_windows, &layout)
            .unwrap_or_else(|e| panic!("{name} at {bits} bits: strip {i}: {e}"));
    }
    let file = convert_on_grid(mesh, &params, &format!("{name}-{bits}-{leaf_windows}.rdm"));
    let (quantized, grid) = quantized_input(mesh, bits);
    // Leaves of a block box's windows or more pool the grid vertices (format 4.1).
    let layout = match leaf_windows {
        8.. => VertexLayout::Pooled { grid },
        _ => VertexLayout::Grid {
            grid,
            packed: true,
            boxes: true,
        },
    };
    assert_eq!(file.vertex_layout(), &layout);
    let expected = expected_triangles(&quantized);
    assert_eq!(
        canonical_sorted(decode::triangles(&file)),
        expected,
        "{name} at {bits} bits, leaf {leaf_windows}: decoded triangles differ"
    );
    let header = file.header();
    assert_eq!(header.triangle_count, expected.len() as u64);
    assert_eq!(
        header.dropped_triangle_count,
        (mesh.triangles.len() - expected.len()) as u64
    );
}

/// A generated mesh, through a PLY file of its own (tests run in parallel).
fn generated(kind: reducem_gen::Kind, triangles: u64) -> Mesh {
    static NEXT: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let path = temp_path(&format!("quantized-{kind:?}-{n}.ply"));
    reducem_gen::generate(kind, triangles, 2, &path).expect("generate");
    reducem::input::read_mesh(&path).expect("read")
}

#[test]
fn grid_files_decode_to_the_quantized_input_exactly() {
    let meshes = [
        ("grid", grid(40, 30)),
        ("torus", torus(48, 20)),
        ("soup", soup(400, 3)),
        ("slivers", slivers(60)),
        ("offset-sphere", transformed(&icosphere(3), |x| x + 1e5)),
    ];
    for (name, mesh) in &meshes {
        for bits in [4, 10, 16, 20, 24] {
            assert_grid_round_trip(name, mesh, bits, 2);
            assert_grid_round_trip(name, mesh, bits, 8);
        }
    }
    for leaf_windows in [1, 4, 8] {
        assert_grid_round_trip("torus-leaf", &torus(30, 12), 16, leaf_windows);
    }
}

#[test]
fn generated_scan_round_trips_on_the_grid() {
    let mesh = generated(reducem_gen::Kind::Scan, 20_000);
    for bits in [12, 20] {
        assert_grid_round_trip("scan", &mesh, bits, 2);
    }
}

/// Half a unit in the last place of `x`: the most the decode's one rounding adds.
fn half_ulp(x: f32) -> f32 {
    let x = x.abs();
    (f32::from_bits(x.to_bits() + 1) - x) / 2.0
}

#[test]
fn every_vertex_lies_within_half_a_cell_of_its_input() {
    let meshes = [
        ("scan", generated(reducem_gen::Kind::Scan, 6_000)),
        ("soup", soup(500, 9)),
        (
            "offset-sphere",
            transformed(&icosphere(3), |x| x * 3.0 + 1e5),
        ),
    ];
    for (name, mesh) in &meshes {
        for bits in [8, 16, 20, 24] {
            let file = convert_on_grid(mesh, &grid_params(bits, 2), &format!("bound-{name}.rdm"));
            let grid = file.precision().grid();
            assert_eq!(grid, Grid::over(&mesh.bounds(), bits));
            let (quantized, _) = quantized_input(mesh, bits);
            let mut largest = 0.0f64;
            let mut squares = 0.0f64;
            for (input, stored) in mesh.positions.iter().zip(&quantized.positions) {
                for axis in 0..3 {
                    let bound = grid.cell / 2.0 + half_ulp(stored[axis]);
                    assert!(
                        (stored[axis] - input[axis]).abs() <= bound,
                        "{name} at {bits} bits: {input:?} stored at {stored:?}"
                    );
                }
                let d = distance(input, stored);
                largest = largest.max(d);
                squares += d * d;
            }
            let stats = file_stats(&file);
            assert_eq!(stats.position_error_max, largest, "{name} at {bits} bits");
            let rms = (squares / mesh.positions.len() as f64).sqrt();
            assert!((stats.position_error_rms - rms).abs() <= 1e-12 * rms.max(1.0));
            assert!(stats.position_error_max <= grid.cell as f64 * 3f64.sqrt() / 2.0 * 1.0001);
            let relative = stats.position_error_max / stats.bounds_diagonal;
            assert_eq!(stats.position_error_max_relative, relative);
        }
    }
}

/// The triangles of `mesh` whose first vertex lies in each of the four quadrants around the
/// z axis, each as a chunk with its own vertex array, as the pipeline's chunk stage makes them.
fn quadrant_chunks(mesh: &Mesh) -> Vec<Mesh> {
    let mut quadrants = vec![Vec::new(); 4];
    for triangle in &mesh.triangles {
        let p = mesh.positions[triangle[0] as usize];
        quadrants[(p[0] >= 0.0) as usize + 2 * (p[1] >= 0.0) as usize].push(*triangle);
    }
    quadrants
        .iter()
        .map(|triangles| {
            local_mesh(triangles, None, |ids| {
                let positions = ids.iter().map(|&v| mesh.positions[v as usize]).collect();
                Ok::<_, ()>(Vertices {
                    positions,
                    ..Vertices::default()
                })
            })
            .expect("positions")
        })
        .collect()
}

#[test]
fn chunks_on_one_model_grid_stay_closed_across_their_boundaries() {
    let mesh = icosphere(4);
    let inside: Vec<Point> = vec![[0.0; 3], [0.3, -0.2, 0.1], [-0.5, 0.4, -0.3]];
    for bits in [10, 16, 24] {
        let params = grid_params(bits, 2);
        let grid = params.grid(&mesh.bounds());
        let mut strips: Vec<EncodedStrip> = Vec::new();
        let mut triangles = 0;
        for chunk in quadrant_chunks(&mesh) {
            let encoded = encode_chunk_on(&chunk, &params, grid.as_ref());
            assert_eq!(encoded.stats.dropped_triangles, 0);
            triangles += encoded.stats.triangles;
            strips.extend(encoded.strips);
        }
        let path = temp_path(&format!("quadrants-{bits}.rdm"));
        write_encoded_strips(&strips, grid, triangles, 2, &path);
        let file = ReducemFile::open(&path).expect("open");
        let (quantized, _) = quantized_input(&mesh, bits);
        assert_eq!(
            canonical_sorted(decode::triangles(&file)),
            expected_triangles(&quantized)
        );
        assert_closed(
            &file,
            &quantized,
            &inside,
            &format!("quadrants at {bits} bits"),
        );
    }
}

#[test]
fn coarse_grids_drop_collapsed_triangles_and_keep_the_rest() {
    let mesh = icosphere(4);
    let file = convert_on_grid(&mesh, &grid_params(5, 2), "coarse.rdm");
    let (quantized, _) = quantized_input(&mesh, 5);
    let expected = expected_triangles(&quantized);
    assert!(expected.len() < mesh.triangles.len(), "nothing collapsed");
    assert_eq!(canonical_sorted(decode::triangles(&file)), expected);
    // Fewer distinct grid points than input vertices: coincident ones were merged.
    assert!(file.header().input_vertex_count < mesh.positions.len() as u64);
}

#[test]
fn a_tolerance_weld_reconnects_a_perturbed_mesh_into_long_strips() {
    let mesh = grid(50, 40);
    let perturbed = reducem_gen::perturbed_copies(&mesh, 1e-5, 4);
    let apart = convert_on_grid(&perturbed, &BuildParams::default(), "perturbed.rdm");
    assert_eq!(file_stats(&apart).avg_strip_length, 1.0);

    let tolerance = 1e-4;
    let (welded, stats) = weld_within_tolerance(perturbed.clone(), tolerance);
    assert_eq!(welded.positions.len(), mesh.positions.len());
    assert_eq!(
        stats.displacement.count as usize,
        perturbed.positions.len() - mesh.positions.len()
    );
    assert!(stats.displacement.max <= tolerance as f64);
    for (triangle, original) in welded.triangles.iter().zip(&perturbed.triangles) {
        for (v, o) in triangle.iter().zip(original) {
            let moved = distance(
                &welded.positions[*v as usize],
                &perturbed.positions[*o as usize],
            );
            assert!(moved <= tolerance as f64);
        }
    }
    let joined = convert_on_grid(&welded, &BuildParams::default(), "welded.rdm");
    assert_eq!(
        canonical_sorted(decode::triangles(&joined)),
        expected_triangles(&welded)
    );
    let length = file_stats(&joined).avg_strip_length;
    assert!(length > 10.0, "average strip length {length}");
}

/// Every box of a format 4 file's 96-byte nodes, decoded, holds every vertex of the strips
/// below it, in lossless files and grid files at 8 and 24 bits: the outward rounding to 8-bit
/// planes is conservative.
#[test]
fn wide_node_boxes_hold_their_strips() {
    use reducem::format::reader::TopNodes;
    let mesh = generated(reducem_gen::Kind::Scan, 20_000);
    let lossless = BuildParams {
        leaf_windows: 4,
        ..BuildParams::default()
    };
    for (name, params) in [
        ("f32", lossless),
        ("8", grid_params(8, 4)),
        ("24", grid_params(24, 4)),
    ] {
        let file = convert_on_grid(&mesh, &params, &format!("wide-nodes-{name}.rdm"));
        let TopNodes::Wide(nodes) = file.top_nodes() else {
            panic!("{name}: a format 4 file has wide nodes");
        };
        assert!(nodes.len() > 1, "{name}");
        assert_boxes_hold_strips(&file, nodes, |node, slot| node.slot_box(slot));
    }
}

/// Every box of a 3.1 grid file's 64-byte nodes, decoded on the node grid, holds every vertex
/// of the strips below it.
#[test]
fn grid_node_boxes_of_format_3_hold_their_strips() {
    use reducem::format::reader::TopNodes;
    let path = fixture_path("tests/fixtures", "torus-grid-format-3.1.rdm");
    let file = ReducemFile::open(&path).expect("open the 3.1 fixture");
    let TopNodes::Grid(nodes, grid) = file.top_nodes() else {
        panic!("a 3.1 grid file has grid nodes");
    };
    assert!(nodes.len() > 1);
    assert_boxes_hold_strips(&file, nodes, |node, slot| {
        let min = [0, 1, 2].map(|a| grid.decode_axis(node.min[a][slot], a));
        let max = [0, 1, 2].map(|a| grid.decode_axis(node.max[a][slot], a));
        (min, max)
    });
}

/// Every occupied slot's box, `decode`d, holds every vertex of every strip below it (a child's
/// box need not lie inside its parent's: each is rounded outward in its own node's frame), and
/// the leaves hold every strip once.
fn assert_boxes_hold_strips<N: reducem::format::NodeRecord>(
    file: &ReducemFile,
    nodes: &[N],
    decode: impl Fn(&N, usize) -> (Point, Point),
) {
    let inside =
        |p: &Point, (min, max): &(Point, Point)| (0..3).all(|a| min[a] <= p[a] && p[a] <= max[a]);
    for (index, node) in nodes.iter().enumerate() {
        for slot in 0..node.occupied() {
            let bounds = decode(node, slot);
            for strip in strips_below(nodes, node.slot(slot)) {
                let view = file.strip(strip);
                for v in 0..view.vertices.len() {
                    let point = view.vertices.point(v);
                    assert!(
                        inside(&point, &bounds),
                        "node {index} slot {slot} {bounds:?}: strip {strip} {point:?}"
                    );
                }
            }
        }
    }
    let mut all = strips_below(nodes, reducem::format::TopSlot::Internal(0));
    all.sort_unstable();
    assert_eq!(all, (0..file.strip_count()).collect::<Vec<_>>());
}

/// The strips of the leaves below `slot`.
fn strips_below<N: reducem::format::NodeRecord>(
    nodes: &[N],
    slot: reducem::format::TopSlot,
) -> Vec<usize> {
    use reducem::format::TopSlot;
    match slot {
        TopSlot::Internal(child) => {
            let node = &nodes[child as usize];
            (0..node.occupied())
                .flat_map(|s| strips_below(nodes, node.slot(s)))
                .collect()
        }
        TopSlot::Leaf { first, count } => (first as usize..(first + count) as usize).collect(),
        other => panic!("{other:?}"),
    }
}

/// `bytes` (a format 3.x grid file, opened as `file`) rewritten as format 2.2 wrote it: u32
/// axis words, one byte per reference, no block boxes, `vertex_encoding` 2, the blocks, records
/// and checksums laid out anew.
fn with_byte_references(bytes: &[u8], file: &ReducemFile) -> Vec<u8> {
    use reducem::format::quantized::{pack, AxisWordLayout};
    use reducem::format::vertices::StripVertices;
    use reducem::format::{SectionKind, StripRecord};
    let section = |kind: SectionKind| {
        let entry = 104 + (kind as usize - 1) * 32;
        let field = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap());
        (entry, field(entry + 8) as usize, field(entry + 16) as usize)
    };
    let mut records = Vec::new();
    let mut data = Vec::new();
    for s in 0..file.strip_count() {
        let view = file.strip(s);
        let StripVertices::Grid(vertices) = view.vertices else {
            panic!("not a grid file")
        };
        let points: Vec<[u32; 3]> = (0..vertices.len())
            .map(|i| vertices.grid_point(i))
            .collect();
        records.push(StripRecord {
            data_word: (data.len() / 4) as u32,
            vertex_count: vertices.len() as u16,
            reference_count: view.references.len() as u16,
        });
        data.extend(pack(&points, vertices.grid().bits, AxisWordLayout::Words));
        data.extend_from_slice(view.axes);
        data.extend(view.references.to_vec());
        data.resize(data.len().next_multiple_of(4), 0);
    }
    let (records_entry, records_at, records_len) = section(SectionKind::StripRecords);
    let (data_entry, data_at, _) = section(SectionKind::StripData);
    let mut out = bytes[..data_at].to_vec();
    out[records_at..records_at + records_len].copy_from_slice(bytemuck::cast_slice(&records));
    out.extend_from_slice(&data);
    let seal = |out: &mut Vec<u8>, entry: usize, at: usize, len: usize| {
        out[entry + 16..entry + 24].copy_from_slice(&(len as u64).to_le_bytes());
        let checksum = xxhash_rust::xxh3::xxh3_64(&out[at..at + len]);
        out[entry + 24..entry + 32].copy_from_slice(&checksum.to_le_bytes());
    };
    seal(&mut out, records_entry, records_at, records_len);
    seal(&mut out, data_entry, data_at, data.len());
    out[8..10].copy_from_slice(&2u16.to_le_bytes());
    out[10..12].copy_from_slice(&2u16.to_le_bytes());
    out[20..24].copy_from_slice(&2u32.to_le_bytes());
    let checksum = xxhash_rust::xxh3::xxh3_64(&out[..200]);
    out[200..208].copy_from_slice(&checksum.to_le_bytes());
    out
}

/// Older formats stay readable: a 2.2 grid file (u32 axis words, 1-byte references, no block
/// boxes) decodes and traces exactly as the 3.1 file (packed, with boxes, the same grid nodes)
/// it was rewritten from.
#[test]
fn format_2_2_grid_files_with_byte_references_read_the_same() {
    let path = fixture_path("tests/fixtures", "torus-grid-format-3.1.rdm");
    let packed = std::fs::read(&path).expect("read the 3.1 fixture");
    let new = ReducemFile::open(&path).expect("open 3.1");
    let bytes = with_byte_references(&packed, &new);
    let old_path = temp_path("byte-references.rdm");
    std::fs::write(&old_path, &bytes).expect("write");
    let old = ReducemFile::open(&old_path).expect("open 2.2");
    old.verify_checksums().expect("2.2 checksums");
    assert_eq!(
        (old.header().version_major, old.header().version_minor),
        (2, 2)
    );
    assert_eq!(
        old.vertex_layout(),
        &VertexLayout::Grid {
            grid: old.precision().grid(),
            packed: false,
            boxes: false,
        }
    );
    assert_eq!(
        canonical_sorted(decode::triangles(&old)),
        canonical_sorted(decode::triangles(&new))
    );
    let targets = vertex_and_edge_targets(&torus(24, 12));
    let origin = [0.5, 0.5, 5.0];
    let rays: Vec<Ray> = targets.iter().map(|&t| ray_towards(origin, t)).collect();
    let trace = |file: &ReducemFile| {
        let hits = Tracer::new(file, TraceOptions::default()).intersect_batch(&rays);
        hits.iter().map(hit_bits).collect::<Vec<_>>()
    };
    let hits = trace(&new);
    assert!(hits.iter().filter(|h| h.is_some()).count() > rays.len() / 2);
    assert_eq!(trace(&old), hits);
}
