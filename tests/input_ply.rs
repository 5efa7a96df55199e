//! PLY input tests. Fixtures are generated here, byte by byte, so every byte offset asserted
//! in an error message can be derived from the fixture itself.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use proptest::prelude::*;
use reducem::input::{
    check_attributes, read_mesh, read_mesh_with, weld_identical_positions, AttributeRequest,
    InputError, InputErrorKind, Location, PlyFile, PlyStream,
};
use reducem::mesh::Mesh;

// ---------------------------------------------------------------------------------------------
// Fixture helpers

/// A file in the temp dir, removed when dropped.
struct TempFile(PathBuf);

impl TempFile {
    fn path(&self) -> &Path {
        &self.0
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn temp_file(name: &str, bytes: &[u8]) -> TempFile {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let unique = COUNTER.fetch_add(1, Ordering::Relaxed);
    let path = std::env::temp_dir().join(format!(
        "reducem-input-ply-{}-{unique}-{name}",
        std::process::id()
    ));
    std::fs::write(&path, bytes).expect("write fixture");
    TempFile(path)
}

#[derive(Clone, Copy, Debug)]
enum Format {
    Ascii,
    Little,
    Big,
}

impl Format {
    const ALL: [Format; 3] = [Format::Ascii, Format::Little, Format::Big];

    fn header_name(self) -> &'static str {
        match self {
            Format::Ascii => "ascii",
            Format::Little => "binary_little_endian",
            Format::Big => "binary_big_endian",
        }
    }
}

/// Writes body values in any format; ASCII values are space separated, elements end lines.
struct Body {
    format: Format,
    bytes: Vec<u8>,
}

impl Body {
    fn new(format: Format) -> Body {
        Body {
            format,
            bytes: Vec::new(),
        }
    }

    fn value(&mut self, ply_type: &str, value: f64) -> &mut Body {
        match self.format {
            Format::Ascii => {
                let text = match ply_type {
                    "float" => format!("{} ", value as f32),
                    "double" => format!("{value} "),
                    _ => format!("{} ", value as i64),
                };
                self.bytes.extend_from_slice(text.as_bytes());
            }
            Format::Little | Format::Big => {
                let mut raw = binary_value(ply_type, value);
                if let Format::Big = self.format {
                    raw.reverse();
                }
                self.bytes.extend_from_slice(&raw);
            }
        }
        self
    }

    fn end_element(&mut self) -> &mut Body {
        if let Format::Ascii = self.format {
            self.bytes.push(b'\n');
        }
        self
    }
}

fn binary_value(ply_type: &str, value: f64) -> Vec<u8> {
    match ply_type {
        "char" => (value as i8).to_le_bytes().to_vec(),
        "uchar" => (value as u8).to_le_bytes().to_vec(),
        "short" => (value as i16).to_le_bytes().to_vec(),
        "ushort" => (value as u16).to_le_bytes().to_vec(),
        "int" => (value as i32).to_le_bytes().to_vec(),
        "uint" => (value as u32).to_le_bytes().to_vec(),
        "float" => (value as f32).to_le_bytes().to_vec(),
        "double" => value.to_le_bytes().to_vec(),
        other => panic!("unknown PLY type {other}"),
    }
}

/// The types used to write a plain vertex + face file.
#[derive(Clone, Copy)]
struct Types {
    coordinate: &'static str,
    length: &'static str,
    index: &'static str,
}

const FLOAT_UCHAR_INT: Types = Types {
    coordinate: "float",
    length: "uchar",
    index: "int",
};

fn plain_header(format: Format, types: Types, vertex_count: usize, face_count: usize) -> String {
    format!(
        "ply\nformat {} 1.0\nelement vertex {vertex_count}\nproperty {c} x\nproperty {c} y\n\
         property {c} z\nelement face {face_count}\nproperty list {} {} vertex_indices\nend_header\n",
        format.header_name(),
        types.length,
        types.index,
        c = types.coordinate,
    )
}

fn write_vertices(body: &mut Body, coordinate: &str, positions: &[[f64; 3]]) {
    for position in positions {
        for &coordinate_value in position {
            body.value(coordinate, coordinate_value);
        }
        body.end_element();
    }
}

fn write_faces(body: &mut Body, types: Types, faces: &[Vec<i64>]) {
    for face in faces {
        body.value(types.length, face.len() as f64);
        for &index in face {
            body.value(types.index, index as f64);
        }
        body.end_element();
    }
}

fn plain_body(format: Format, types: Types, positions: &[[f64; 3]], faces: &[Vec<i64>]) -> Vec<u8> {
    let mut body = Body::new(format);
    write_vertices(&mut body, types.coordinate, positions);
    write_faces(&mut body, types, faces);
    body.bytes
}

fn plain_ply(format: Format, types: Types, positions: &[[f64; 3]], faces: &[Vec<i64>]) -> Vec<u8> {
    let mut bytes = plain_header(format, types, positions.len(), faces.len()).into_bytes();
    bytes.extend_from_slice(&plain_body(format, types, positions, faces));
    bytes
}

/// Five distinct points, a quad and two triangles.
fn sample_positions() -> Vec<[f64; 3]> {
    vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.5, 0.5, 1.25],
    ]
}

fn sample_faces() -> Vec<Vec<i64>> {
    vec![vec![0, 1, 2, 3], vec![0, 1, 4], vec![3, 2, 4]]
}

fn sample_mesh() -> Mesh {
    Mesh {
        positions: sample_positions()
            .iter()
            .map(|p| p.map(|c| c as f32))
            .collect(),
        triangles: vec![[0, 1, 2], [0, 2, 3], [0, 1, 4], [3, 2, 4]],
        face_ids: Some(vec![0, 0, 1, 2]),
        normals: None,
        colors: None,
    }
}

fn read(name: &str, bytes: &[u8]) -> Result<Mesh, InputError> {
    let file = temp_file(name, bytes);
    read_mesh(file.path())
}

/// Reads a fixture that must fail; returns the error and the path it was read from.
fn read_error(bytes: &[u8]) -> (InputError, String) {
    let file = temp_file("broken.ply", bytes);
    let error = read_mesh(file.path()).expect_err("fixture must be rejected");
    (error, file.path().display().to_string())
}

fn element_location(element: &str, index: u64, byte_offset: usize, line: Option<u64>) -> Location {
    Location::Element {
        element: element.to_string(),
        index,
        byte_offset: byte_offset as u64,
        line,
    }
}

// ---------------------------------------------------------------------------------------------
// Encodings and types

#[test]
fn ascii_little_and_big_endian_give_the_same_mesh() {
    for format in Format::ALL {
        let bytes = plain_ply(
            format,
            FLOAT_UCHAR_INT,
            &sample_positions(),
            &sample_faces(),
        );
        let mesh = read("sample.ply", &bytes).unwrap();
        assert_eq!(mesh, sample_mesh(), "{format:?}");
    }
}

#[test]
fn double_coordinates_are_rounded_to_f32() {
    let types = Types {
        coordinate: "double",
        ..FLOAT_UCHAR_INT
    };
    let positions = vec![
        [0.1, -2.5e-7, 1.0e10],
        [1.0 / 3.0, 7.0, -0.3],
        [2.0, 2.0, 2.0],
    ];
    let faces = vec![vec![0, 1, 2]];
    for format in Format::ALL {
        let mesh = read("double.ply", &plain_ply(format, types, &positions, &faces)).unwrap();
        let expected: Vec<[f32; 3]> = positions.iter().map(|p| p.map(|c| c as f32)).collect();
        assert_eq!(mesh.positions, expected, "{format:?}");
        assert_eq!(mesh.triangles, vec![[0, 1, 2]]);
    }
}

#[test]
fn every_integer_type_works_for_list_lengths_and_indices() {
    let integer_types = ["uchar", "char", "ushort", "short", "uint", "int"];
    for length in integer_types {
        for index in integer_types {
            for format in Format::ALL {
                let types = Types {
                    coordinate: "float",
                    length,
                    index,
                };
                let bytes = plain_ply(format, types, &sample_positions(), &sample_faces());
                let mesh = read("types.ply", &bytes).unwrap();
                assert_eq!(mesh, sample_mesh(), "{length} {index} {format:?}");
            }
        }
    }
}

#[test]
fn vertex_index_property_name_is_accepted() {
    for format in Format::ALL {
        let header =
            plain_header(format, FLOAT_UCHAR_INT, 5, 3).replace("vertex_indices", "vertex_index");
        let mut bytes = header.into_bytes();
        bytes.extend_from_slice(&plain_body(
            format,
            FLOAT_UCHAR_INT,
            &sample_positions(),
            &sample_faces(),
        ));
        let mesh = read("index.ply", &bytes).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(mesh, sample_mesh(), "{format:?}");
    }
}

/// Extra vertex properties (a list among them), an extra face property, and extra elements
/// with lists before, between and after the mesh elements.
fn decorated_ply(format: Format) -> Vec<u8> {
    let header = format!(
        "ply\nformat {} 1.0\n\
         element camera 2\nproperty list uchar float params\nproperty short id\n\
         element vertex 5\nproperty uchar red\nproperty float x\nproperty list ushort double tags\n\
         property double confidence\nproperty float y\nproperty float z\nproperty int label\n\
         element material 1\nproperty list int uchar name\n\
         element face 3\nproperty uchar flags\nproperty list uchar uint vertex_indices\n\
         property list uchar float texcoord\nproperty float quality\n\
         element edge 2\nproperty int vertex1\nproperty int vertex2\nproperty list uchar int more\n\
         end_header\n",
        format.header_name()
    );
    let mut body = Body::new(format);
    for camera in 0..2 {
        body.value("uchar", 3.0)
            .value("float", 1.5)
            .value("float", 2.5)
            .value("float", -1.0);
        body.value("short", camera as f64).end_element();
    }
    for (index, position) in sample_positions().iter().enumerate() {
        body.value("uchar", 200.0).value("float", position[0]);
        body.value("ushort", index as f64);
        for tag in 0..index {
            body.value("double", tag as f64 * 0.25);
        }
        body.value("double", 0.75)
            .value("float", position[1])
            .value("float", position[2]);
        body.value("int", -7.0).end_element();
    }
    body.value("int", 4.0);
    for letter in b"wood" {
        body.value("uchar", f64::from(*letter));
    }
    body.end_element();
    for face in sample_faces() {
        body.value("uchar", 1.0).value("uchar", face.len() as f64);
        for &index in &face {
            body.value("uint", index as f64);
        }
        body.value("uchar", 2.0)
            .value("float", 0.5)
            .value("float", 0.25);
        body.value("float", 9.0).end_element();
    }
    for edge in 0..2 {
        body.value("int", edge as f64)
            .value("int", 1.0)
            .value("uchar", 1.0);
        body.value("int", 5.0).end_element();
    }
    let mut bytes = header.into_bytes();
    bytes.extend_from_slice(&body.bytes);
    bytes
}

#[test]
fn extra_properties_and_elements_are_skipped() {
    for format in Format::ALL {
        let mesh = read("decorated.ply", &decorated_ply(format)).unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(mesh, sample_mesh(), "{format:?}");
    }
}

#[test]
fn face_element_before_vertex_element_is_found() {
    for format in Format::ALL {
        let header = format!(
            "ply\nformat {} 1.0\nelement face 1\nproperty list uchar int vertex_indices\n\
             element vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n",
            format.header_name()
        );
        let mut body = Body::new(format);
        write_faces(&mut body, FLOAT_UCHAR_INT, &[vec![2, 1, 0]]);
        write_vertices(
            &mut body,
            "float",
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        );
        let mut bytes = header.into_bytes();
        bytes.extend_from_slice(&body.bytes);
        let mesh = read("face-first.ply", &bytes).unwrap();
        assert_eq!(mesh.triangles, vec![[2, 1, 0]], "{format:?}");
        assert_eq!(mesh.positions[1], [1.0, 0.0, 0.0]);
    }
}

// ---------------------------------------------------------------------------------------------
// Triangulation

#[test]
fn polygons_are_fanned_with_winding_kept() {
    let positions: Vec<[f64; 3]> = (0..255)
        .map(|i| {
            let angle = i as f64 * std::f64::consts::TAU / 255.0;
            [angle.cos(), angle.sin(), 0.0]
        })
        .collect();
    let polygon: Vec<i64> = (0..255).collect();
    let quad_reversed = vec![3, 2, 1, 0];
    let expected_fan: Vec<[u32; 3]> = (1..254).map(|i| [0, i, i + 1]).collect();
    for format in Format::ALL {
        let faces = vec![polygon.clone(), quad_reversed.clone()];
        let mesh = read(
            "fan.ply",
            &plain_ply(format, FLOAT_UCHAR_INT, &positions, &faces),
        )
        .unwrap();
        assert_eq!(mesh.triangles.len(), 253 + 2);
        assert_eq!(
            &mesh.triangles[..253],
            expected_fan.as_slice(),
            "{format:?}"
        );
        assert_eq!(&mesh.triangles[253..], &[[3, 2, 1], [3, 1, 0]]);
        let face_ids: Vec<u32> = (0..255).map(|t| mesh.face_id(t)).collect();
        assert_eq!(face_ids, [vec![0; 253], vec![1; 2]].concat(), "{format:?}");
    }
}

#[test]
fn for_each_triangle_reports_the_face_of_each_triangle() {
    let bytes = plain_ply(
        Format::Little,
        FLOAT_UCHAR_INT,
        &sample_positions(),
        &sample_faces(),
    );
    let file = temp_file("visit.ply", &bytes);
    let ply = PlyFile::open(file.path()).unwrap();
    assert_eq!((ply.vertex_count(), ply.face_count()), (5, 3));
    let mut visited = Vec::new();
    ply.for_each_triangle(|face, triangle| visited.push((face, triangle)))
        .unwrap();
    let expected = vec![
        (0, [0, 1, 2]),
        (0, [0, 2, 3]),
        (1, [0, 1, 4]),
        (2, [3, 2, 4]),
    ];
    assert_eq!(visited, expected);
    assert_eq!(ply.read_positions().unwrap(), sample_mesh().positions);
}

// ---------------------------------------------------------------------------------------------
// Header variants

#[test]
fn crlf_comments_and_obj_info_are_accepted() {
    for format in Format::ALL {
        let header = plain_header(format, FLOAT_UCHAR_INT, 5, 3)
            .replace(
                "format",
                "comment written by a test\nobj_info scanner 42\nformat",
            )
            .replace("element face", "comment between elements\nelement face")
            .replace('\n', "\r\n");
        let mut body_bytes = plain_body(
            format,
            FLOAT_UCHAR_INT,
            &sample_positions(),
            &sample_faces(),
        );
        if let Format::Ascii = format {
            body_bytes = String::from_utf8(body_bytes)
                .unwrap()
                .replace('\n', "\r\n")
                .into_bytes();
        }
        let mut bytes = header.into_bytes();
        bytes.extend_from_slice(&body_bytes);
        let mesh = read("crlf.ply", &bytes).unwrap_or_else(|e| panic!("{format:?}: {e}"));
        assert_eq!(mesh, sample_mesh(), "{format:?}");
    }
}

#[test]
fn extension_is_case_insensitive() {
    let bytes = plain_ply(
        Format::Little,
        FLOAT_UCHAR_INT,
        &sample_positions(),
        &sample_faces(),
    );
    let mesh = read("upper.PLY", &bytes).unwrap();
    assert_eq!(mesh, sample_mesh());
}

// ---------------------------------------------------------------------------------------------
// Welding

#[test]
fn triangle_soup_is_welded_in_first_occurrence_order() {
    let soup = vec![
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [-1.0, 0.0, 0.0],
    ];
    let faces = vec![vec![0, 1, 2], vec![3, 4, 5], vec![6, 7, 8]];
    let mesh = read(
        "soup.ply",
        &plain_ply(Format::Big, FLOAT_UCHAR_INT, &soup, &faces),
    )
    .unwrap();
    let expected = Mesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 1.0, 0.0],
            [-1.0, 0.0, 0.0],
        ],
        triangles: vec![[0, 1, 2], [1, 3, 2], [0, 2, 4]],
        face_ids: None,
        normals: None,
        colors: None,
    };
    assert_eq!(mesh, expected);
}

#[test]
fn welding_compares_bits_and_keeps_unreferenced_vertices() {
    let mesh = Mesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [-0.0, 0.0, 0.0],
            [5.0, 5.0, 5.0],
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
        ],
        triangles: vec![[3, 1, 4]],
        face_ids: None,
        normals: None,
        colors: None,
    };
    let welded = weld_identical_positions(mesh);
    assert_eq!(
        welded.positions,
        vec![
            [0.0, 0.0, 0.0],
            [-0.0, 0.0, 0.0],
            [5.0, 5.0, 5.0],
            [1.0, 0.0, 0.0]
        ]
    );
    assert_eq!(welded.positions[1][0].to_bits(), (-0.0f32).to_bits());
    assert_eq!(welded.triangles, vec![[0, 1, 3]]);
}

#[test]
fn welding_without_duplicates_changes_nothing() {
    assert_eq!(weld_identical_positions(sample_mesh()), sample_mesh());
    assert_eq!(weld_identical_positions(Mesh::default()), Mesh::default());
}

// ---------------------------------------------------------------------------------------------
// Errors

const VERTEX_BYTES: usize = 12;

fn sample_binary_with_header() -> (Vec<u8>, usize) {
    let bytes = plain_ply(
        Format::Little,
        FLOAT_UCHAR_INT,
        &sample_positions(),
        &sample_faces(),
    );
    let header_length = plain_header(Format::Little, FLOAT_UCHAR_INT, 5, 3).len();
    (bytes, header_length)
}

#[test]
fn truncated_fixed_size_vertices_fail_the_count_check() {
    let (bytes, header_length) = sample_binary_with_header();
    let cut = header_length + 3 * VERTEX_BYTES + 6;
    let (error, path) = read_error(&bytes[..cut]);
    assert_eq!(
        error.location,
        element_location("vertex", 0, header_length, None)
    );
    assert!(
        matches!(
            error.kind,
            InputErrorKind::CountExceedsFile {
                count: 5,
                min_bytes_each: 12,
                remaining: 42
            }
        ),
        "{error}"
    );
    assert_eq!(
        error.to_string(),
        format!(
            "{path}: element 'vertex' #0 at byte {header_length}: the header declares 5 elements \
             of at least 12 bytes each, but only 42 bytes remain in the file"
        )
    );
}

#[test]
fn truncated_face_names_element_index_and_offset() {
    let faces = vec![vec![0, 1, 2, 3], vec![3, 2, 4, 0], vec![3, 2, 4]];
    let bytes = plain_ply(Format::Little, FLOAT_UCHAR_INT, &sample_positions(), &faces);
    let header_length = plain_header(Format::Little, FLOAT_UCHAR_INT, 5, 3).len();
    // Faces: two quads (17 bytes each) and a triangle; cut inside the triangle's indices.
    let third_face = header_length + 5 * VERTEX_BYTES + 17 + 17;
    let cut = third_face + 1 + 4 + 2;
    let (error, path) = read_error(&bytes[..cut]);
    let value_offset = third_face + 1 + 4;
    assert_eq!(
        error.location,
        element_location("face", 2, value_offset, None)
    );
    assert_eq!(error.kind, InputErrorKind::Truncated { needed: 2 });
    assert_eq!(
        error.to_string(),
        format!(
            "{path}: element 'face' #2 at byte {value_offset}: file ends in the middle of the \
             element (2 more bytes needed)"
        )
    );
}

#[test]
fn truncated_vertex_with_list_property_names_element_index_and_offset() {
    let header = "ply\nformat binary_big_endian 1.0\nelement vertex 5\nproperty float x\n\
                  property float y\nproperty float z\nproperty list uchar float extra\n\
                  element face 0\nproperty list uchar int vertex_indices\nend_header\n";
    let mut body = Body::new(Format::Big);
    for position in sample_positions() {
        for coordinate in position {
            body.value("float", coordinate);
        }
        body.value("uchar", 2.0)
            .value("float", 0.5)
            .value("float", 0.25);
    }
    let mut bytes = header.as_bytes().to_vec();
    bytes.extend_from_slice(&body.bytes);
    let list_start = header.len() + 4 * 21 + VERTEX_BYTES;
    let (error, _) = read_error(&bytes[..list_start + 1 + 2]);
    // The skipped list of two floats needs 8 bytes; 2 are present.
    assert_eq!(
        error.location,
        element_location("vertex", 4, list_start + 1, None)
    );
    assert_eq!(error.kind, InputErrorKind::Truncated { needed: 6 });

    let mesh = read("vertex-list.ply", &bytes).unwrap();
    assert_eq!(mesh.positions, sample_mesh().positions);
}

#[test]
fn truncated_ascii_body_names_line() {
    let bytes = plain_ply(
        Format::Ascii,
        FLOAT_UCHAR_INT,
        &sample_positions(),
        &sample_faces(),
    );
    let text = String::from_utf8(bytes).unwrap();
    let cut = text.trim_end().rfind(' ').unwrap();
    let (error, _) = read_error(&text.as_bytes()[..cut]);
    // Header has 9 lines, 5 vertex lines, then faces on lines 15..=17.
    assert_eq!(error.location, element_location("face", 2, cut, Some(17)));
    assert_eq!(error.kind, InputErrorKind::UnexpectedEndOfText);
}

#[test]
fn huge_face_count_fails_before_reading_or_allocating() {
    let header = plain_header(Format::Little, FLOAT_UCHAR_INT, 5, 1 << 40);
    let mut bytes = header.clone().into_bytes();
    bytes.extend_from_slice(&plain_body(
        Format::Little,
        FLOAT_UCHAR_INT,
        &sample_positions(),
        &sample_faces(),
    ));
    let (error, path) = read_error(&bytes);
    let face_start = header.len() + 5 * VERTEX_BYTES;
    assert_eq!(
        error.location,
        element_location("face", 0, face_start, None)
    );
    assert_eq!(
        error.kind,
        InputErrorKind::CountExceedsFile {
            count: 1 << 40,
            min_bytes_each: 13,
            remaining: 43
        }
    );
    assert!(error
        .to_string()
        .starts_with(&format!("{path}: element 'face' #0 at byte {face_start}: ")));
}

#[test]
fn huge_count_overflowing_u64_product_is_rejected() {
    let header = plain_header(Format::Little, FLOAT_UCHAR_INT, 5, 0)
        .replace("element vertex 5", "element vertex 18446744073709551615");
    let (error, _) = read_error(header.as_bytes());
    assert!(
        matches!(error.kind, InputErrorKind::TooManyVertices { .. }),
        "{error}"
    );

    let element = "element vertex 5\nproperty float x\nproperty float y\nproperty float z\n";
    let header = plain_header(Format::Little, FLOAT_UCHAR_INT, 5, 0).replace(
        element,
        &format!("element junk 9223372036854775807\nproperty double a\n{element}"),
    );
    let (error, _) = read_error(header.as_bytes());
    assert!(
        matches!(error.kind, InputErrorKind::CountExceedsFile { .. }),
        "{error}"
    );
    assert!(matches!(&error.location, Location::Element { element, .. } if element == "junk"));
}

#[test]
fn out_of_range_index_is_reported_exactly() {
    let mut faces = sample_faces();
    faces[1][2] = 99;
    for format in [Format::Little, Format::Big] {
        let bytes = plain_ply(format, FLOAT_UCHAR_INT, &sample_positions(), &faces);
        let (error, path) = read_error(&bytes);
        let header_length = plain_header(format, FLOAT_UCHAR_INT, 5, 3).len();
        let offset = header_length + 5 * VERTEX_BYTES + 17 + 1 + 2 * 4;
        assert_eq!(
            error.to_string(),
            format!("{path}: element 'face' #1 at byte {offset}: vertex index 99 out of range (5 vertices)")
        );
        assert_eq!(
            error.kind,
            InputErrorKind::IndexOutOfRange {
                index: 99,
                vertex_count: 5
            }
        );
    }
}

#[test]
fn negative_index_is_out_of_range_in_ascii() {
    let mut faces = sample_faces();
    faces[2][0] = -1;
    let bytes = plain_ply(Format::Ascii, FLOAT_UCHAR_INT, &sample_positions(), &faces);
    let text = String::from_utf8(bytes.clone()).unwrap();
    let offset = text.find("3 -1").unwrap() + 2;
    let (error, path) = read_error(&bytes);
    assert_eq!(
        error.to_string(),
        format!(
            "{path}: element 'face' #2 at byte {offset} (line 17): vertex index -1 out of range \
             (5 vertices)"
        )
    );
}

#[test]
fn non_finite_coordinates_are_rejected() {
    let header_length = plain_header(Format::Little, FLOAT_UCHAR_INT, 5, 3).len();
    let mut positions = sample_positions();
    positions[2][1] = f64::NAN;
    let bytes = plain_ply(Format::Little, FLOAT_UCHAR_INT, &positions, &sample_faces());
    let (error, _) = read_error(&bytes);
    let offset = header_length + 2 * VERTEX_BYTES + 4;
    assert_eq!(error.location, element_location("vertex", 2, offset, None));
    assert!(matches!(
        error.kind,
        InputErrorKind::NonFiniteCoordinate { axis: 'y', .. }
    ));

    let mut positions = sample_positions();
    positions[4][2] = f64::INFINITY;
    let bytes = plain_ply(Format::Ascii, FLOAT_UCHAR_INT, &positions, &sample_faces());
    let offset = String::from_utf8_lossy(&bytes).find("inf").unwrap();
    let (error, path) = read_error(&bytes);
    assert_eq!(
        error.to_string(),
        format!("{path}: element 'vertex' #4 at byte {offset} (line 14): coordinate z is inf, not a finite number")
    );
}

#[test]
fn float_beyond_the_supported_range_is_rejected() {
    let mut positions = sample_positions();
    positions[2][1] = -274_877_906_944.0; // -2^38, exact in f32
    let bytes = plain_ply(Format::Little, FLOAT_UCHAR_INT, &positions, &sample_faces());
    let header_length = plain_header(Format::Little, FLOAT_UCHAR_INT, 5, 3).len();
    let (error, path) = read_error(&bytes);
    let offset = header_length + 2 * 12 + 4;
    assert_eq!(
        error.to_string(),
        format!("{path}: element 'vertex' #2 at byte {offset}: coordinate y = -2.74877906944e11 is outside the supported range ±1e11")
    );
}

#[test]
fn double_beyond_f32_range_is_rejected() {
    let types = Types {
        coordinate: "double",
        ..FLOAT_UCHAR_INT
    };
    let mut positions = sample_positions();
    positions[1][0] = 1.0e300;
    let bytes = plain_ply(Format::Big, types, &positions, &sample_faces());
    let header_length = plain_header(Format::Big, types, 5, 3).len();
    let (error, path) = read_error(&bytes);
    let offset = header_length + 24;
    assert_eq!(
        error.to_string(),
        format!("{path}: element 'vertex' #1 at byte {offset}: coordinate x = 1e300 is outside the supported range ±1e11")
    );
}

#[test]
fn face_with_two_vertices_is_rejected() {
    let mut faces = sample_faces();
    faces[2] = vec![0, 1];
    let (bytes, header_length) = {
        let bytes = plain_ply(Format::Little, FLOAT_UCHAR_INT, &sample_positions(), &faces);
        (
            bytes,
            plain_header(Format::Little, FLOAT_UCHAR_INT, 5, 3).len(),
        )
    };
    let (error, path) = read_error(&bytes);
    let offset = header_length + 5 * VERTEX_BYTES + 17 + 13;
    assert_eq!(
        error.to_string(),
        format!("{path}: element 'face' #2 at byte {offset}: face has 2 vertices; at least 3 are needed")
    );
}

#[test]
fn negative_list_length_is_rejected() {
    let types = Types {
        length: "char",
        ..FLOAT_UCHAR_INT
    };
    let header_length = plain_header(Format::Little, types, 5, 3).len();
    let mut bytes = plain_ply(Format::Little, types, &sample_positions(), &sample_faces());
    let second_face = header_length + 5 * VERTEX_BYTES + 17;
    bytes[second_face] = 0xff;
    let (error, _) = read_error(&bytes);
    assert_eq!(
        error.location,
        element_location("face", 1, second_face, None)
    );
    assert_eq!(error.kind, InputErrorKind::NegativeListLength(-1));
}

#[test]
fn malformed_ascii_token_names_line_and_offset() {
    let bytes = plain_ply(
        Format::Ascii,
        FLOAT_UCHAR_INT,
        &sample_positions(),
        &sample_faces(),
    );
    let text = String::from_utf8(bytes)
        .unwrap()
        .replacen("0.5", "0.5abc", 1);
    let offset = text.find("0.5abc").unwrap();
    let (error, path) = read_error(text.as_bytes());
    assert_eq!(
        error.to_string(),
        format!("{path}: element 'vertex' #4 at byte {offset} (line 14): malformed float token '0.5abc'")
    );
}

fn header_only(body_declarations: &str) -> Vec<u8> {
    format!("ply\nformat binary_little_endian 1.0\n{body_declarations}end_header\n").into_bytes()
}

#[test]
fn unsupported_properties_are_rejected_with_their_element_line() {
    let face = "element face 0\nproperty list uchar int vertex_indices\n";
    let cases = [
        (
            format!("element vertex 0\nproperty list uchar float x\nproperty float y\nproperty float z\n{face}"),
            "vertex coordinate 'x' is",
            3,
        ),
        (
            format!("element vertex 0\nproperty float x\nproperty float y\n{face}"),
            "element 'vertex' has no property 'z'",
            3,
        ),
        (
            format!("element vertex 0\nproperty int x\nproperty float y\nproperty float z\n{face}"),
            "only float or double are supported",
            3,
        ),
        (
            "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n\
             element face 0\nproperty int vertex_indices\n"
                .to_string(),
            "face property 'vertex_indices' is",
            7,
        ),
        (
            "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n\
             element face 0\nproperty list uchar float vertex_indices\n"
                .to_string(),
            "a list of integers is required",
            7,
        ),
        (
            "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n\
             element face 0\nproperty list uchar int corners\n"
                .to_string(),
            "no list property 'vertex_indices' or 'vertex_index'",
            7,
        ),
        (
            format!("element vertex 0\nproperty float x\nproperty float y\nproperty float z\n{face}\
                     element extra 1\nproperty list float int weird\n"),
            "element 'extra' has a list whose length type is not an integer",
            9,
        ),
    ];
    for (declarations, message, line) in cases {
        let (error, path) = read_error(&header_only(&declarations));
        assert_eq!(error.location, Location::Header { line }, "{error}");
        assert!(
            matches!(error.kind, InputErrorKind::UnsupportedProperty(_)),
            "{error}"
        );
        assert!(error.to_string().contains(message), "{error}");
        assert!(
            error
                .to_string()
                .starts_with(&format!("{path}: header line {line}: ")),
            "{error}"
        );
    }
}

#[test]
fn missing_mesh_elements_are_rejected() {
    let (error, path) = read_error(&header_only(
        "element face 0\nproperty list uchar int vertex_indices\n",
    ));
    assert_eq!(error.kind, InputErrorKind::MissingElement("vertex"));
    assert_eq!(
        error.to_string(),
        format!("{path}: the header declares no 'vertex' element")
    );
    let vertices = "element vertex 0\nproperty float x\nproperty float y\nproperty float z\n";
    let (error, _) = read_error(&header_only(vertices));
    assert_eq!(error.kind, InputErrorKind::MissingElement("face"));
}

#[test]
fn non_ply_files_are_rejected() {
    for bytes in [
        &b""[..],
        b"plx\nformat ascii 1.0\n",
        b"OFF\n3 1 0\n",
        b"ply",
    ] {
        let (error, path) = read_error(bytes);
        assert_eq!(error.kind, InputErrorKind::NotPly);
        assert_eq!(
            error.to_string(),
            format!("{path}: not a PLY file (it does not start with the line 'ply')")
        );
    }
}

#[test]
fn header_syntax_errors_come_from_ply_rs_with_their_line() {
    let (error, path) =
        read_error(b"ply\nformat ascii 1.0\nelement vertex 3\nproperty flaot x\nend_header\n");
    assert_eq!(error.location, Location::Header { line: 4 });
    assert!(matches!(error.kind, InputErrorKind::Header(_)));
    assert!(
        error
            .to_string()
            .starts_with(&format!("{path}: header line 4: invalid PLY header: ")),
        "{error}"
    );

    let (error, _) = read_error(b"ply\nformat ascii 1.0\nelement vertex 3\n");
    assert!(
        matches!(error.kind, InputErrorKind::Header(ref m) if m.contains("end_header")),
        "{error}"
    );
}

#[test]
fn unknown_extension_and_missing_file_are_rejected() {
    let file = temp_file("mesh.xyz", b"1 2 3");
    let error = read_mesh(file.path()).unwrap_err();
    assert!(matches!(error.kind, InputErrorKind::UnsupportedFormat(_)));
    assert_eq!(error.location, Location::File);

    let missing = std::env::temp_dir().join("reducem-input-ply-does-not-exist.ply");
    let error = read_mesh(&missing).unwrap_err();
    assert!(matches!(error.kind, InputErrorKind::Io(_)));
    assert!(error
        .to_string()
        .starts_with(&missing.display().to_string()));
}

// ---------------------------------------------------------------------------------------------
// Large files: the parallel block decoders and their fallbacks

/// A grid of `side × side` vertices, two triangles per cell.
fn grid(side: usize) -> (Vec<[f64; 3]>, Vec<Vec<i64>>) {
    let positions = (0..side * side)
        .map(|i| {
            [
                (i % side) as f64,
                (i / side) as f64,
                ((i * 7) % 13) as f64 * 0.125,
            ]
        })
        .collect();
    let mut faces = Vec::new();
    for row in 0..side - 1 {
        for column in 0..side - 1 {
            let corner = (row * side + column) as i64;
            let side = side as i64;
            faces.push(vec![corner, corner + 1, corner + side + 1]);
            faces.push(vec![corner, corner + side + 1, corner + side]);
        }
    }
    (positions, faces)
}

/// The face each fan triangle of `faces` comes from.
fn fan_face_ids(faces: &[Vec<i64>]) -> Vec<u32> {
    faces
        .iter()
        .enumerate()
        .flat_map(|(face, corners)| std::iter::repeat_n(face as u32, corners.len() - 2))
        .collect()
}

fn fan_triangles(faces: &[Vec<i64>]) -> Vec<[u32; 3]> {
    faces
        .iter()
        .flat_map(|face| {
            (1..face.len() - 1).map(move |i| [face[0], face[i], face[i + 1]].map(|v| v as u32))
        })
        .collect()
}

#[test]
fn large_binary_files_decode_across_blocks() {
    let (positions, mut faces) = grid(300);
    let expected_positions: Vec<[f32; 3]> = positions.iter().map(|p| p.map(|c| c as f32)).collect();
    for format in [Format::Little, Format::Big] {
        let bytes = plain_ply(format, FLOAT_UCHAR_INT, &positions, &faces);
        let file = temp_file("grid.ply", &bytes);
        let ply = PlyFile::open(file.path()).unwrap();
        assert_eq!(ply.read_positions().unwrap(), expected_positions);
        assert_eq!(ply.read_triangles().unwrap(), fan_triangles(&faces));
    }
    // A quad late in the file defeats the all-triangles guess; the sequential path takes over.
    faces[170_000] = vec![5, 6, 7, 8];
    let bytes = plain_ply(Format::Little, FLOAT_UCHAR_INT, &positions, &faces);
    let file = temp_file("grid-quad.ply", &bytes);
    let triangles = PlyFile::open(file.path())
        .unwrap()
        .read_triangles()
        .unwrap();
    assert_eq!(triangles, fan_triangles(&faces));
    assert_eq!(triangles[170_000..170_002], [[5, 6, 7], [5, 7, 8]]);
}

#[test]
fn large_binary_files_report_the_first_defect() {
    let (positions, mut faces) = grid(300);
    faces[150_000][1] = 90_000;
    faces[70_000][2] = 90_001;
    let bytes = plain_ply(Format::Little, FLOAT_UCHAR_INT, &positions, &faces);
    let header_length = plain_header(
        Format::Little,
        FLOAT_UCHAR_INT,
        positions.len(),
        faces.len(),
    )
    .len();
    let (error, _) = read_error(&bytes);
    let offset = header_length + positions.len() * VERTEX_BYTES + 70_000 * 13 + 1 + 2 * 4;
    assert_eq!(
        error.location,
        element_location("face", 70_000, offset, None)
    );
    assert_eq!(
        error.kind,
        InputErrorKind::IndexOutOfRange {
            index: 90_001,
            vertex_count: 90_000
        }
    );

    let mut positions = positions;
    positions[80_000][0] = f64::NAN;
    positions[30_000][2] = f64::NAN;
    let bytes = plain_ply(Format::Little, FLOAT_UCHAR_INT, &positions, &faces);
    let (error, _) = read_error(&bytes);
    let offset = header_length + 30_000 * VERTEX_BYTES + 8;
    assert_eq!(
        error.location,
        element_location("vertex", 30_000, offset, None)
    );
}

// ---------------------------------------------------------------------------------------------
// Round trip

fn polygon_mesh() -> impl Strategy<Value = (Vec<[f32; 3]>, Vec<Vec<i64>>)> {
    let coordinate = prop_oneof![
        -1.0e6f32..1.0e6f32,
        any::<f32>().prop_filter("in range", |c| c.abs() <= reducem::geometry::MAX_COORDINATE),
    ];
    prop::collection::vec([coordinate.clone(), coordinate.clone(), coordinate], 1..40)
        .prop_flat_map(|positions| {
            let count = positions.len() as i64;
            let face = prop::collection::vec(0..count, 3..8);
            (Just(positions), prop::collection::vec(face, 0..30))
        })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(64))]

    #[test]
    fn written_meshes_read_back_exactly((positions, faces) in polygon_mesh(), big in any::<bool>()) {
        let format = if big { Format::Big } else { Format::Little };
        let wide: Vec<[f64; 3]> = positions.iter().map(|p| p.map(f64::from)).collect();
        let bytes = plain_ply(format, FLOAT_UCHAR_INT, &wide, &faces);
        let file = temp_file("roundtrip.ply", &bytes);
        let mesh = PlyFile::open(file.path()).unwrap().read_mesh().unwrap();
        let bits = |points: &[[f32; 3]]| points.iter().map(|p| p.map(f32::to_bits)).collect::<Vec<_>>();
        prop_assert_eq!(bits(&mesh.positions), bits(&positions));
        let face_ids: Vec<u32> = (0..mesh.triangles.len()).map(|t| mesh.face_id(t)).collect();
        prop_assert_eq!(face_ids, fan_face_ids(&faces));
        prop_assert_eq!(mesh.triangles, fan_triangles(&faces));
    }
}

// ---------------------------------------------------------------------------------------------
// Throughput (ignored: run with `cargo test --test input_ply -- --ignored --nocapture`)

/// Writes a binary little-endian grid of `side × side` vertices and two triangles per cell
/// straight to bytes (the `Body` helper is too slow for 10M faces).
fn write_grid_ply(path: &Path, side: u32) -> (usize, usize) {
    let face_count = 2 * (side - 1) as usize * (side - 1) as usize;
    let vertex_count = (side * side) as usize;
    let mut bytes =
        plain_header(Format::Little, FLOAT_UCHAR_INT, vertex_count, face_count).into_bytes();
    bytes.reserve(vertex_count * 12 + face_count * 13);
    for i in 0..side * side {
        for coordinate in [(i % side) as f32, (i / side) as f32, (i % 97) as f32 * 0.01] {
            bytes.extend_from_slice(&coordinate.to_le_bytes());
        }
    }
    for row in 0..side - 1 {
        for column in 0..side - 1 {
            let corner = row * side + column;
            for triangle in [
                [corner, corner + 1, corner + side + 1],
                [corner, corner + side + 1, corner + side],
            ] {
                bytes.push(3);
                for index in triangle {
                    bytes.extend_from_slice(&(index as i32).to_le_bytes());
                }
            }
        }
    }
    std::fs::write(path, &bytes).expect("write benchmark file");
    (bytes.len(), face_count)
}

fn report(label: &str, bytes: usize, triangles: usize, seconds: f64) {
    println!(
        "{label}: {seconds:.3} s, {:.0} MB/s, {:.1} M triangles/s",
        bytes as f64 / seconds / 1e6,
        triangles as f64 / seconds / 1e6
    );
}

#[test]
#[ignore = "writes a ~190 MB file and measures read speed"]
fn measure_binary_read_throughput() {
    use std::time::Instant;

    let path = std::env::temp_dir().join(format!("reducem-input-bench-{}.ply", std::process::id()));
    let (bytes, triangles) = write_grid_ply(&path, 2237);
    println!("{} MB, {triangles} triangles", bytes / 1_000_000);

    let start = Instant::now();
    let ply = PlyFile::open(&path).unwrap();
    let positions = ply.read_positions().unwrap();
    let parallel = ply.read_triangles().unwrap();
    report(
        "open + positions + triangles (parallel)",
        bytes,
        triangles,
        start.elapsed().as_secs_f64(),
    );

    let start = Instant::now();
    let mut streamed = 0usize;
    ply.for_each_triangle(|_, _| streamed += 1).unwrap();
    report(
        "for_each_triangle (sequential)",
        bytes,
        triangles,
        start.elapsed().as_secs_f64(),
    );
    assert_eq!(streamed, parallel.len());

    let start = Instant::now();
    let mesh = weld_identical_positions(Mesh {
        positions,
        triangles: parallel,
        face_ids: None,
        normals: None,
        colors: None,
    });
    report("weld", bytes, triangles, start.elapsed().as_secs_f64());
    assert_eq!(mesh.positions.len(), 2237 * 2237);

    let start = Instant::now();
    let mesh = read_mesh(&path).unwrap();
    report(
        "read_mesh (with weld)",
        bytes,
        triangles,
        start.elapsed().as_secs_f64(),
    );
    assert_eq!(mesh.triangles.len(), triangles);
    let _ = std::fs::remove_file(&path);
}

#[test]
#[ignore = "compares against ply-rs-bw's own decoding on a ~19 MB file"]
fn measure_speedup_over_ply_rs() {
    use ply_rs_bw::parser::Parser;
    use ply_rs_bw::ply::DefaultElement;
    use std::time::Instant;

    let path = std::env::temp_dir().join(format!(
        "reducem-input-bench-small-{}.ply",
        std::process::id()
    ));
    let (bytes, triangles) = write_grid_ply(&path, 708);

    let start = Instant::now();
    let mesh = PlyFile::open(&path).unwrap().read_mesh().unwrap();
    let ours = start.elapsed().as_secs_f64();
    report("ours", bytes, triangles, ours);

    let start = Instant::now();
    let mut file = std::fs::File::open(&path).unwrap();
    let ply = Parser::<DefaultElement>::new().read_ply(&mut file).unwrap();
    let theirs = start.elapsed().as_secs_f64();
    report("ply-rs-bw", bytes, triangles, theirs);
    println!("speedup {:.1}x", theirs / ours);
    assert_eq!(ply.payload["face"].len(), mesh.triangles.len());
    let _ = std::fs::remove_file(&path);
}

// ---------------------------------------------------------------------------------------------
// Normals and colours

/// How the attribute fixture stores its normals and colours.
#[derive(Clone, Copy, Debug)]
struct AttributeTypes {
    normal: &'static str,
    color: &'static str,
    alpha: bool,
}

const SAMPLE_NORMALS: [[f64; 3]; 5] = [
    [0.0, 0.0, 1.0],
    [0.6, 0.8, 0.0],
    [-1.0, 0.0, 0.0],
    [0.0, -0.28, 0.96],
    [0.1, 0.2, 0.3],
];

/// Colour channels as stored: uchar values, or the same over 255 as floats (0.5 → 128).
const SAMPLE_COLORS: [[f64; 4]; 5] = [
    [255.0, 0.0, 0.0, 255.0],
    [0.0, 255.0, 0.0, 128.0],
    [0.0, 0.0, 255.0, 0.0],
    [51.0, 102.0, 153.0, 204.0],
    [1.0, 254.0, 128.0, 17.0],
];

fn stored_channel(types: AttributeTypes, value: f64) -> f64 {
    // 128 is written as 0.5, which rounds back to 128.
    match types.color {
        "uchar" => value,
        _ if value == 128.0 => 0.5,
        _ => value / 255.0,
    }
}

/// The sample mesh with a `quality` property between positions and normals, then normals and
/// colours; returns the file and the header length.
fn attribute_ply(format: Format, types: AttributeTypes) -> (Vec<u8>, usize) {
    let alpha = if types.alpha {
        format!("property {} alpha\n", types.color)
    } else {
        String::new()
    };
    let header = format!(
        "ply\nformat {} 1.0\nelement vertex 5\nproperty float x\nproperty float y\n\
         property float z\nproperty float quality\nproperty {n} nx\nproperty {n} ny\n\
         property {n} nz\nproperty {c} red\nproperty {c} green\nproperty {c} blue\n{alpha}\
         element face 3\nproperty list uchar int vertex_indices\nend_header\n",
        format.header_name(),
        n = types.normal,
        c = types.color,
    );
    let mut body = Body::new(format);
    for (vertex, position) in sample_positions().iter().enumerate() {
        for &c in position {
            body.value("float", c);
        }
        body.value("float", 7.5);
        for &n in &SAMPLE_NORMALS[vertex] {
            body.value(types.normal, n);
        }
        let channels = if types.alpha { 4 } else { 3 };
        for &channel in &SAMPLE_COLORS[vertex][..channels] {
            body.value(types.color, stored_channel(types, channel));
        }
        body.end_element();
    }
    write_faces(&mut body, FLOAT_UCHAR_INT, &sample_faces());
    let mut bytes = header.clone().into_bytes();
    bytes.extend_from_slice(&body.bytes);
    (bytes, header.len())
}

const ALL_ATTRIBUTES: AttributeRequest = AttributeRequest {
    normals: true,
    colors: true,
};

fn expected_normals() -> Vec<[f32; 3]> {
    SAMPLE_NORMALS.iter().map(|n| n.map(|c| c as f32)).collect()
}

fn expected_colors(alpha: bool) -> Vec<[u8; 4]> {
    SAMPLE_COLORS
        .iter()
        .map(|c| {
            let [r, g, b, a] = c.map(|channel| channel as u8);
            [r, g, b, if alpha { a } else { 255 }]
        })
        .collect()
}

fn attribute_type_variants() -> Vec<AttributeTypes> {
    let mut variants = Vec::new();
    for normal in ["float", "double"] {
        for color in ["uchar", "float", "double"] {
            for alpha in [false, true] {
                variants.push(AttributeTypes {
                    normal,
                    color,
                    alpha,
                });
            }
        }
    }
    variants
}

#[test]
fn normals_and_colours_are_read_exactly_in_every_encoding_and_type() {
    for format in Format::ALL {
        for types in attribute_type_variants() {
            let (bytes, _) = attribute_ply(format, types);
            let file = temp_file("attributes.ply", &bytes);
            let mesh = read_mesh_with(file.path(), ALL_ATTRIBUTES)
                .unwrap_or_else(|e| panic!("{format:?} {types:?}: {e}"));
            let label = format!("{format:?} {types:?}");
            assert_eq!(mesh.positions, sample_mesh().positions, "{label}");
            assert_eq!(mesh.normals, Some(expected_normals()), "{label}");
            assert_eq!(mesh.colors, Some(expected_colors(types.alpha)), "{label}");
            assert_eq!(mesh.triangles, sample_mesh().triangles, "{label}");
            assert_eq!(mesh.face_ids, Some(vec![0, 0, 1, 2]), "{label}");
        }
    }
}

#[test]
fn attributes_not_asked_for_are_not_read() {
    let types = AttributeTypes {
        normal: "double",
        color: "float",
        alpha: true,
    };
    for format in Format::ALL {
        let (bytes, _) = attribute_ply(format, types);
        let file = temp_file("attributes.ply", &bytes);
        let mesh = read_mesh(file.path()).expect("read");
        assert_eq!(mesh, sample_mesh(), "{format:?}");
        let only_colors = AttributeRequest {
            normals: false,
            colors: true,
        };
        let mesh = read_mesh_with(file.path(), only_colors).expect("read");
        assert_eq!(mesh.normals, None);
        assert_eq!(mesh.colors, Some(expected_colors(true)));
    }
}

#[test]
fn streamed_attributes_of_chosen_vertices_match_the_whole_read() {
    let types = AttributeTypes {
        normal: "float",
        color: "uchar",
        alpha: false,
    };
    for format in [Format::Little, Format::Big] {
        let (bytes, _) = attribute_ply(format, types);
        let file = temp_file("attributes.ply", &bytes);
        let stream = PlyStream::open(file.path()).expect("open");
        stream.check_attributes(ALL_ATTRIBUTES).expect("has them");
        for window_bytes in [1, 40, 1 << 20] {
            let ids = [0, 2, 3, 4];
            let found = stream
                .attributes_of(&ids, window_bytes, ALL_ATTRIBUTES)
                .expect("attributes");
            let pick = |all: Vec<[f32; 3]>| ids.iter().map(|&v| all[v as usize]).collect();
            assert_eq!(found.normals, Some(pick(expected_normals())));
            let colors = expected_colors(false);
            let picked: Vec<[u8; 4]> = ids.iter().map(|&v| colors[v as usize]).collect();
            assert_eq!(found.colors, Some(picked));
        }
    }
}

#[test]
fn asking_for_attributes_the_file_lacks_names_the_missing_properties() {
    let bytes = plain_ply(
        Format::Little,
        FLOAT_UCHAR_INT,
        &sample_positions(),
        &sample_faces(),
    );
    let file = temp_file("plain.ply", &bytes);
    let error = read_mesh_with(file.path(), ALL_ATTRIBUTES).expect_err("no normals");
    assert_eq!(error.location, Location::File);
    assert_eq!(
        error.to_string(),
        format!(
            "{}: normals were asked for, but element 'vertex' has no float or double \
             properties nx, ny, nz",
            file.path().display()
        )
    );
    let error = check_attributes(
        file.path(),
        AttributeRequest {
            normals: false,
            colors: true,
        },
    )
    .expect_err("no colours");
    assert!(
        error.to_string().ends_with(
            "colours were asked for, but element 'vertex' has no uchar, float or double \
             properties red, green, blue"
        ),
        "{error}"
    );
    // A colour in a type we do not read counts as missing, and only that channel is named.
    let mut ushort_blue = header_only(
        "element vertex 1\nproperty float x\nproperty float y\nproperty float z\n\
         property uchar red\nproperty uchar green\nproperty ushort blue\n\
         element face 0\nproperty list uchar int vertex_indices\n",
    );
    ushort_blue.extend_from_slice(&[0; 16]);
    let file = temp_file("ushort.ply", &ushort_blue);
    let error = check_attributes(file.path(), ALL_ATTRIBUTES).expect_err("no nx");
    assert!(
        error.to_string().contains("properties nx, ny, nz"),
        "{error}"
    );
    let colors = AttributeRequest {
        normals: false,
        colors: true,
    };
    let error = check_attributes(file.path(), colors).expect_err("blue is ushort");
    assert!(error.to_string().ends_with("property blue"), "{error}");
}

#[test]
fn bad_normals_and_colours_name_element_and_byte() {
    let types = AttributeTypes {
        normal: "double",
        color: "float",
        alpha: false,
    };
    // Vertex: x y z quality (4 floats), nx ny nz (3 doubles), red green blue (3 floats).
    let stride = 16 + 24 + 12;
    for format in [Format::Little, Format::Big] {
        let (mut bytes, header) = attribute_ply(format, types);
        // Vertex 3's ny becomes NaN.
        let at = header + 3 * stride + 16 + 8;
        let mut nan = f64::NAN.to_le_bytes();
        if let Format::Big = format {
            nan.reverse();
        }
        bytes[at..at + 8].copy_from_slice(&nan);
        let file = temp_file("nan.ply", &bytes);
        let error = read_mesh_with(file.path(), ALL_ATTRIBUTES).expect_err("NaN normal");
        assert_eq!(error.location, element_location("vertex", 3, at, None));
        assert!(matches!(
            error.kind,
            InputErrorKind::NonFiniteNormal { axis: 'y', .. }
        ));
        // Not asked for, the NaN is never read.
        read_mesh(file.path()).expect("normals skipped");

        let (mut bytes, header) = attribute_ply(format, types);
        // Vertex 1's blue becomes 1.5.
        let at = header + stride + 16 + 24 + 8;
        let mut value = 1.5f32.to_le_bytes();
        if let Format::Big = format {
            value.reverse();
        }
        bytes[at..at + 4].copy_from_slice(&value);
        let file = temp_file("bright.ply", &bytes);
        let error = read_mesh_with(file.path(), ALL_ATTRIBUTES).expect_err("colour > 1");
        assert_eq!(error.location, element_location("vertex", 1, at, None));
        assert_eq!(
            error.kind,
            InputErrorKind::ColorOutOfRange {
                channel: "blue",
                value: 1.5
            }
        );
    }
}

#[test]
fn bad_ascii_colour_names_its_line() {
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
                property float z\nproperty float red\nproperty float green\nproperty float blue\n\
                element face 1\nproperty list uchar int vertex_indices\nend_header\n\
                0 0 0 1 1 1\n1 0 0 0.5 -0.25 0\n0 1 0 0 0 0\n3 0 1 2\n";
    let file = temp_file("ascii.ply", text.as_bytes());
    let colors = AttributeRequest {
        normals: false,
        colors: true,
    };
    let error = read_mesh_with(file.path(), colors).expect_err("negative colour");
    let at = text.find("-0.25").unwrap();
    assert_eq!(error.location, element_location("vertex", 1, at, Some(14)));
    assert!(matches!(
        error.kind,
        InputErrorKind::ColorOutOfRange {
            channel: "green",
            ..
        }
    ));
}

#[test]
fn welding_keeps_vertices_with_different_attributes_apart() {
    // Two triangles over one edge, each with its own copies of the edge's vertices: the copies
    // of vertex 1 have the same normal and colour, those of vertex 2 different normals.
    let mesh = Mesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ],
        triangles: vec![[0, 1, 2], [3, 4, 5]],
        face_ids: None,
        normals: Some(vec![
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.6, 0.8],
        ]),
        colors: Some(vec![[9, 9, 9, 255]; 6]),
    };
    let welded = weld_identical_positions(mesh.clone());
    assert_eq!(welded.positions.len(), 5);
    assert_eq!(welded.triangles, vec![[0, 1, 2], [1, 3, 4]]);
    assert_eq!(welded.positions[4], welded.positions[2]);
    assert_eq!(welded.normals.as_ref().unwrap()[4], [0.0, 0.6, 0.8]);
    assert_eq!(welded.normals.as_ref().unwrap()[2], [0.0, 0.0, 1.0]);
    // A colour difference alone keeps them apart too.
    let mut recoloured = mesh;
    recoloured.normals = None;
    recoloured.colors.as_mut().unwrap()[3] = [9, 9, 8, 255];
    let welded = weld_identical_positions(recoloured);
    assert_eq!(welded.positions.len(), 5);
    assert_eq!(welded.triangles, vec![[0, 1, 2], [3, 4, 2]]);
    assert_eq!(welded.colors.unwrap()[3], [9, 9, 8, 255]);
}
