//! Attributes (format 2.5): face ids, normals and colours survive conversion exactly (normals
//! within the encoding's bound), hits report them, files without them are unchanged, and
//! crafted attribute sections are rejected naming the byte.

mod common;

use common::{canonical, icosphere, ray_towards, temp_path, torus};
use reducem::conversion::{convert_mesh, BuildParams};
use reducem::format::attributes::{
    angle_degrees, AttributeSection, AttributeSet, NormalEncoding, ATTRIBUTE_RECORD_OFFSET,
};
use reducem::format::reader::{ReducemFile, Validation};
use reducem::geometry::{is_degenerate, Point};
use reducem::mesh::Mesh;
use reducem::trace::ray_file::{trace_hits_as, HitFormat, FULL_HIT_BYTES, NO_FACE_ID};
use reducem::trace::{hit_attributes, Ray, TraceOptions, Tracer};
use reducem_gen::{generate, Kind};

fn every_attribute(normals: NormalEncoding) -> AttributeSet {
    AttributeSet {
        face_ids: true,
        normals,
        colors: true,
    }
}

fn params(attributes: AttributeSet, grid_bits: Option<u32>) -> BuildParams {
    let mut params = BuildParams {
        leaf_windows: 8,
        grid_bits,
        attributes,
        ..BuildParams::default()
    };
    params.stripify.max_length = 20;
    params
}

fn convert(mesh: &Mesh, params: &BuildParams, name: &str) -> ReducemFile {
    converted(mesh, params, name).1
}

/// The converted file's path and the file, validated in full.
fn converted(mesh: &Mesh, params: &BuildParams, name: &str) -> (std::path::PathBuf, ReducemFile) {
    let path = temp_path(name);
    convert_mesh(mesh, params, &path).expect("convert");
    let file = ReducemFile::open_with(&path, Validation::Full).expect("open");
    (path, file)
}

/// Every stored triangle with its face id: `(strip, window, corners, face id)`.
fn stored_faces(file: &ReducemFile) -> Vec<(usize, usize, [Point; 3], u32)> {
    let mut faces = Vec::new();
    for s in 0..file.strip_count() {
        let view = file.strip(s);
        for k in 0..view.window_count() {
            if let Some(corners) = view.window_points(k) {
                let id = file.face_id(s, k).expect("a face id for every triangle");
                faces.push((s, k, corners, id));
            }
        }
    }
    faces
}

/// Each stored triangle is the input face its id names (corners and winding), and every
/// non-degenerate input face is stored exactly once.
fn assert_face_ids(mesh: &Mesh, file: &ReducemFile, what: &str) {
    let mut seen = vec![0u32; mesh.triangles.len()];
    let mut by_face: std::collections::HashMap<u32, Vec<[[u32; 3]; 3]>> = Default::default();
    for (t, triangle) in mesh.triangles.iter().enumerate() {
        by_face
            .entry(mesh.face_id(t))
            .or_default()
            .push(canonical(mesh.triangle_points(triangle)));
    }
    for (s, k, corners, id) in stored_faces(file) {
        let candidates = by_face
            .get(&id)
            .unwrap_or_else(|| panic!("{what}: strip {s} window {k}: unknown face id {id}"));
        assert!(
            candidates.contains(&canonical(corners)),
            "{what}: strip {s} window {k} is not a triangle of face {id}"
        );
        seen[id as usize] += 1;
    }
    let kept = |t: &[u32; 3]| {
        let [a, b, c] = mesh.triangle_points(t);
        t[0] != t[1] && t[1] != t[2] && t[0] != t[2] && !is_degenerate(&a, &b, &c)
    };
    let mut expected = vec![0u32; mesh.triangles.len()];
    for (t, triangle) in mesh.triangles.iter().enumerate() {
        expected[mesh.face_id(t) as usize] += u32::from(kept(triangle));
    }
    assert_eq!(
        seen, expected,
        "{what}: each kept face stored once per triangle"
    );
}

#[test]
fn face_ids_round_trip_on_every_generator_kind() {
    for kind in Kind::ALL {
        let ply = temp_path(&format!("faces-{kind:?}.ply"));
        generate(kind, 6_000, 5, &ply).expect("generate");
        let mesh = reducem::input::read_mesh(&ply).expect("read");
        for (bits, label) in [(None, "lossless"), (Some(16), "grid")] {
            let attributes = AttributeSet {
                face_ids: true,
                ..AttributeSet::default()
            };
            let name = format!("faces-{kind:?}-{label}.rdm");
            let file = convert(&mesh, &params(attributes, bits), &name);
            let what = format!("{kind:?} {label}");
            match bits {
                None => assert_face_ids(&mesh, &file, &what),
                Some(bits) => {
                    // Grid files store the snapped triangles: each is its face's, snapped.
                    let (mut snapped, _) = common::quantized_input(&mesh, bits);
                    snapped.face_ids = mesh.face_ids.clone();
                    assert_face_ids(&snapped, &file, &what);
                }
            }
        }
    }
}

/// A mesh whose faces are polygons: every second face is a quad fanned into two triangles,
/// so face ids are not triangle indices; its triangles are also shuffled out of face order.
fn polygon_mesh() -> Mesh {
    let mut mesh = torus(40, 24);
    let count = mesh.triangles.len();
    let mut face = 0u32;
    let mut ids = Vec::with_capacity(count);
    for t in 0..count {
        ids.push(face);
        if t % 4 != 0 {
            face += 1;
        }
    }
    let mut order: Vec<usize> = (0..count).collect();
    order.sort_by_key(|&t| (t * 7919) % count);
    mesh.triangles = order.iter().map(|&t| mesh.triangles[t]).collect();
    mesh.face_ids = Some(order.iter().map(|&t| ids[t]).collect());
    mesh
}

#[test]
fn polygon_face_ids_name_their_polygon() {
    let mesh = polygon_mesh();
    let attributes = AttributeSet {
        face_ids: true,
        ..AttributeSet::default()
    };
    let file = convert(&mesh, &params(attributes, None), "polygons.rdm");
    assert_face_ids(&mesh, &file, "polygons");
}

/// A sphere with its analytic normals and a colour per vertex from its position.
fn coloured_sphere() -> Mesh {
    let mut mesh = icosphere(4);
    mesh.normals = Some(
        mesh.positions
            .iter()
            .map(|p| {
                let length = p.iter().map(|c| c * c).sum::<f32>().sqrt();
                p.map(|c| c / length)
            })
            .collect(),
    );
    mesh.colors = Some(
        mesh.positions
            .iter()
            .enumerate()
            .map(|(v, p)| {
                let channel = |c: f32| ((c + 1.0) * 127.0) as u8;
                [channel(p[0]), channel(p[1]), channel(p[2]), (v % 256) as u8]
            })
            .collect(),
    );
    mesh
}

#[test]
fn normals_and_colours_round_trip_per_stored_vertex() {
    let mesh = coloured_sphere();
    let input_vertex: std::collections::HashMap<[u32; 3], usize> = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(v, p)| (p.map(f32::to_bits), v))
        .collect();
    for (encoding, bound) in [(NormalEncoding::Oct16, 0.01), (NormalEncoding::Oct8, 1.0)] {
        let name = format!("sphere-{}.rdm", encoding.name());
        let file = convert(&mesh, &params(every_attribute(encoding), None), &name);
        let mut worst: f64 = 0.0;
        for s in 0..file.strip_count() {
            let stored = file.vertex_attributes(s).expect("per-vertex attributes");
            for (i, position) in file.strip(s).vertices.iter().enumerate() {
                let v = input_vertex[&position.map(f32::to_bits)];
                assert_eq!(stored.color(i), Some(mesh.colors.as_ref().unwrap()[v]));
                let normal = stored.normal(i).expect("a normal");
                worst = worst.max(angle_degrees(normal, mesh.normals.as_ref().unwrap()[v]));
            }
        }
        assert!(worst <= bound, "{}: {worst} degrees", encoding.name());
        let recorded = file.attribute_record().normal_error_max_degrees;
        assert!(
            (recorded - worst).abs() < 1e-3,
            "recorded {recorded}, measured {worst}"
        );
        assert_face_ids(&mesh, &file, encoding.name());
    }
}

/// Rays at every triangle's centroid from outside: the full record names the face hit, the
/// barycentrics, both normals and the interpolated colour, checked against the input mesh.
#[test]
fn full_hit_records_match_the_input_mesh() {
    let mesh = coloured_sphere();
    let file = convert(
        &mesh,
        &params(every_attribute(NormalEncoding::Oct16), None),
        "sphere-full.rdm",
    );
    let rays: Vec<Ray> = mesh
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = mesh.triangle_points(t);
            let centroid: Point = std::array::from_fn(|i| (a[i] + b[i] + c[i]) / 3.0);
            ray_towards(centroid.map(|x| x * 3.0), centroid)
        })
        .collect();
    let tracer = Tracer::new(&file, TraceOptions::default());
    let bytes = trace_hits_as(&tracer, &rays, HitFormat::Full);
    assert_eq!(bytes.len(), rays.len() * FULL_HIT_BYTES);
    for (face, record) in bytes.chunks_exact(FULL_HIT_BYTES).enumerate() {
        let word = |i: usize| u32::from_le_bytes(record[i * 4..i * 4 + 4].try_into().unwrap());
        let float = |i: usize| f32::from_bits(word(i));
        assert_eq!(word(3), face as u32, "ray {face} hits its own face");
        let (u, v) = (float(1), float(2));
        let [a, b, c] = mesh.triangles[face].map(|v| v as usize);
        let weights = [1.0 - u - v, u, v];
        let normals = mesh.normals.as_ref().unwrap();
        let expected: Point = std::array::from_fn(|i| {
            weights[0] * normals[a][i] + weights[1] * normals[b][i] + weights[2] * normals[c][i]
        });
        let length = expected.iter().map(|x| x * x).sum::<f32>().sqrt();
        let shading = [float(7), float(8), float(9)];
        assert!(
            angle_degrees(shading, expected.map(|x| x / length)) < 0.05,
            "ray {face}"
        );
        let colors = mesh.colors.as_ref().unwrap();
        for channel in 0..4 {
            let exact: f32 = weights[0] * colors[a][channel] as f32
                + weights[1] * colors[b][channel] as f32
                + weights[2] * colors[c][channel] as f32;
            let stored = record[40 + channel] as f32;
            assert!(
                (stored - exact).abs() <= 0.5 + 1e-3,
                "ray {face} channel {channel}"
            );
        }
        assert_eq!(word(11), 0, "reserved word");
    }
    let miss = trace_hits_as(
        &tracer,
        &[ray_towards([5.0, 5.0, 5.0], [6.0, 6.0, 6.0])],
        HitFormat::Full,
    );
    assert_eq!(&miss[..4], &f32::INFINITY.to_le_bytes());
    assert_eq!(&miss[12..16], &NO_FACE_ID.to_le_bytes());
    assert!(miss[16..].iter().all(|&b| b == 0) && miss[4..12].iter().all(|&b| b == 0));
}

/// Geometry and tracing do not depend on attributes: the same hits, bit for bit, on a grid
/// file with and without them.
#[test]
fn attributes_leave_geometry_and_hits_unchanged() {
    let mesh = coloured_sphere();
    let plain = convert(
        &mesh,
        &params(AttributeSet::default(), Some(18)),
        "plain.rdm",
    );
    let with = convert(
        &mesh,
        &params(every_attribute(NormalEncoding::Oct8), Some(18)),
        "with.rdm",
    );
    // Without attributes a grid file pools its vertices (format 4.1); with them it keeps
    // per-strip vertices (4.0): the same triangles and hits either way.
    let version = |file: &ReducemFile| (file.header().version_major, file.header().version_minor);
    assert_eq!(version(&plain), (4, reducem::format::POOLED_MINOR));
    assert_eq!(version(&with), (4, 0));
    assert_eq!(
        common::canonical_sorted(reducem::decode::triangles(&plain)),
        common::canonical_sorted(reducem::decode::triangles(&with))
    );
    let rays: Vec<Ray> = common::vertex_and_edge_targets(&mesh)
        .into_iter()
        .map(|target| ray_towards([2.5, 1.5, 2.0], target))
        .collect();
    let trace = |file: &ReducemFile| {
        let tracer = Tracer::new(file, TraceOptions::default());
        tracer.intersect_chunk(&rays)
    };
    let (a, b) = (trace(&plain), trace(&with));
    assert_eq!(
        a.iter().map(common::hit_bits).collect::<Vec<_>>(),
        b.iter().map(common::hit_bits).collect::<Vec<_>>()
    );
    let hits = b.iter().flatten().count();
    assert!(hits > rays.len() / 3, "{hits} hits");
    for hit in b.iter().flatten() {
        let attributes = hit_attributes(&with, hit);
        assert!(attributes.face_id.is_some() && attributes.color.is_some());
    }
}

/// Overwrites `bytes` at `offset` of a copy of `source`, and opens it in full.
fn open_corrupted(source: &std::path::Path, offset: u64, bytes: &[u8], name: &str) -> String {
    let mut data = std::fs::read(source).expect("read");
    data[offset as usize..offset as usize + bytes.len()].copy_from_slice(bytes);
    let path = temp_path(name);
    std::fs::write(&path, &data).expect("write");
    match ReducemFile::open_with(&path, Validation::Full) {
        Ok(_) => String::new(),
        Err(error) => error.to_string(),
    }
}

#[test]
fn crafted_attribute_sections_are_rejected_naming_the_byte() {
    let mesh = coloured_sphere();
    let params = params(every_attribute(NormalEncoding::Oct16), None);
    let (path, file) = converted(&mesh, &params, "crafted.rdm");
    let entry = |kind: AttributeSection| file.attribute_record().sections[kind.slot()];

    let record_flags = open_corrupted(&path, ATTRIBUTE_RECORD_OFFSET as u64, &[0xff], "flags.rdm");
    assert!(
        record_flags.contains("header at byte 472"),
        "{record_flags}"
    );

    let groups = entry(AttributeSection::FaceIdGroups);
    let moved = open_corrupted(&path, groups.offset + 16, &[0xff, 0xff], "groups.rdm");
    assert!(
        moved.contains(&format!("face_id_groups at byte {}", groups.offset + 16)),
        "{moved}"
    );

    let ids = entry(AttributeSection::FaceIds);
    let widths = open_corrupted(&path, ids.offset, &[0xff], "widths.rdm");
    assert!(
        widths.contains(&format!("face_ids at byte {}", ids.offset)),
        "{widths}"
    );

    let vertex_groups = entry(AttributeSection::VertexGroups);
    let counted = open_corrupted(
        &path,
        vertex_groups.offset + 8,
        &[0x01],
        "vertex-groups.rdm",
    );
    assert!(
        counted.contains(&format!(
            "vertex_groups at byte {}",
            vertex_groups.offset + 8
        )),
        "{counted}"
    );
    drop(file);
}

/// A lazily opened file finds a corrupt face id entry when a lookup reaches it: the lookup
/// answers `None` and the defect names the section and byte, as for a corrupt strip.
#[test]
fn lazy_lookups_keep_attribute_defects() {
    let mesh = coloured_sphere();
    let params = params(every_attribute(NormalEncoding::Oct16), None);
    let (path, file) = converted(&mesh, &params, "lazy-attributes.rdm");
    let groups: Vec<reducem::format::attributes::FaceIdGroup> =
        bytemuck::pod_collect_to_vec(file.attribute_bytes(AttributeSection::FaceIdGroups));
    let group = groups.len() / 2;
    let ids = file.attribute_record().sections[AttributeSection::FaceIds.slot()];
    let entry_byte = ids.offset + groups[group].bit_offset / 8;
    let strip = group * reducem::format::attributes::GROUP_STRIPS;
    let intact = file.face_id(0, 0);
    assert!(intact.is_some());
    drop(file);
    let mut data = std::fs::read(&path).expect("read");
    // Every bit set: a base width of 63, which no entry may have.
    data[entry_byte as usize] = 0xff;
    data[entry_byte as usize + 1] = 0xff;
    let corrupt = temp_path("lazy-attributes-corrupt.rdm");
    std::fs::write(&corrupt, &data).expect("write");
    let file = ReducemFile::open_with(&corrupt, Validation::Lazy)
        .expect("a lazy open reads only the header page");
    assert_eq!(file.face_id(0, 0), intact);
    assert!(file.defect().is_none());
    assert_eq!(file.face_id(strip, 0), None);
    let defect = file.defect().expect("the defect is kept").to_string();
    assert!(defect.contains("face_ids at byte"), "{defect}");
    assert!(ReducemFile::open_with(&corrupt, Validation::Full).is_err());
}

/// `reducem decode` writes the attributes as PLY properties: each vertex's normal and colour
/// after its position, each face's id after its corners, in the file's order.
#[test]
fn decode_writes_attribute_properties() {
    let mesh = coloured_sphere();
    let file = convert(
        &mesh,
        &params(every_attribute(NormalEncoding::Oct8), None),
        "decode-attributes.rdm",
    );
    let ply = temp_path("decode-attributes.ply");
    reducem::decode::write_ply(&file, &ply).expect("decode");
    let bytes = std::fs::read(&ply).expect("read");
    let end = b"end_header\n";
    let body_start = bytes
        .windows(end.len())
        .position(|w| w == end)
        .expect("header end")
        + end.len();
    let header = String::from_utf8_lossy(&bytes[..body_start]);
    for property in ["property float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\nelement face", "property list uchar int vertex_indices\nproperty uint face_id\nend_header"] {
        assert!(header.contains(property), "{header}");
    }
    let mut at = body_start;
    let float = |at: usize| f32::from_le_bytes(bytes[at..at + 4].try_into().unwrap());
    for s in 0..file.strip_count() {
        let stored = file.vertex_attributes(s).unwrap();
        for (i, position) in file.strip(s).vertices.iter().enumerate() {
            assert_eq!([float(at), float(at + 4), float(at + 8)], position);
            assert_eq!(
                [float(at + 12), float(at + 16), float(at + 20)],
                stored.normal(i).unwrap()
            );
            assert_eq!(bytes[at + 24..at + 28], stored.color(i).unwrap());
            at += 28;
        }
    }
    for (s, k, _, id) in stored_faces(&file) {
        assert_eq!(bytes[at], 3, "strip {s} window {k}");
        let written = u32::from_le_bytes(bytes[at + 13..at + 17].try_into().unwrap());
        assert_eq!(written, id, "strip {s} window {k}");
        at += 17;
    }
    assert_eq!(at, bytes.len());
}

/// A closed sphere whose vertices are split by their normals (each triangle's corners carry
/// the face normal, so snapping to the grid keeps the copies apart at bit-identical grid
/// points) stays watertight on a grid file with every attribute: rays at every vertex and edge
/// from inside hit, in every tracer variant.
#[test]
fn a_grid_file_with_split_attributes_stays_watertight() {
    let sphere = icosphere(3);
    let mut split = Mesh {
        positions: Vec::new(),
        triangles: Vec::new(),
        face_ids: None,
        normals: Some(Vec::new()),
        colors: Some(Vec::new()),
    };
    for (t, triangle) in sphere.triangles.iter().enumerate() {
        let [a, b, c] = sphere.triangle_points(triangle);
        let normal = [0, 1, 2].map(|i| (a[i] + b[i] + c[i]) / 3.0);
        let first = split.positions.len() as u32;
        split.positions.extend([a, b, c]);
        split.normals.as_mut().unwrap().extend([normal; 3]);
        split
            .colors
            .as_mut()
            .unwrap()
            .extend([[t as u8, 0, 0, 255]; 3]);
        split.triangles.push([first, first + 1, first + 2]);
    }
    let params = params(every_attribute(NormalEncoding::Oct16), Some(16));
    let file = convert(&split, &params, "split-grid.rdm");
    assert!(file.header().stored_vertex_count >= 3 * sphere.triangles.len() as u64);
    let (quantized, _) = common::quantized_input(&split, 16);
    let inside = [[0.0, 0.0, 0.0], [0.1, -0.2, 0.05]];
    common::assert_closed(&file, &quantized, &inside, "split sphere on a 16-bit grid");
}
