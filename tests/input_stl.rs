//! STL input: binary and ASCII against a mesh written by the test itself, welded as an
//! independent first-occurrence weld of the facet corners says, and each classic trap.

use std::collections::HashMap;
use std::io::Write;
use std::path::{Path, PathBuf};

use reducem::input::{
    detect, read_mesh, read_mesh_with, AttributeRequest, InputErrorKind, Location, UpAxis,
};
use reducem::mesh::Mesh;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("reducem-input-stl-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Facets as corner positions.
type Facet = [[f32; 3]; 3];

fn binary_stl(header: &[u8; 80], facets: &[Facet]) -> Vec<u8> {
    let mut bytes = header.to_vec();
    bytes.extend_from_slice(&(facets.len() as u32).to_le_bytes());
    for facet in facets {
        // A wrong normal on purpose: it must not matter.
        bytes.extend([9f32, 9.0, 9.0].iter().flat_map(|v| v.to_le_bytes()));
        for corner in facet {
            bytes.extend(corner.iter().flat_map(|v| v.to_le_bytes()));
        }
        bytes.extend_from_slice(&[0, 0]);
    }
    bytes
}

fn ascii_stl(facets: &[Facet]) -> Vec<u8> {
    let mut text = String::from("solid test\n");
    for facet in facets {
        text.push_str("  facet normal 0 0 1\n    outer loop\n");
        for corner in facet {
            // `{:?}` prints the shortest decimal that reads back as the same f32.
            text.push_str(&format!(
                "      vertex {:?} {:?} {:?}\n",
                corner[0], corner[1], corner[2]
            ));
        }
        text.push_str("    endloop\n  endfacet\n");
    }
    text.push_str("endsolid test\n");
    text.into_bytes()
}

/// The expected mesh: corners welded by their bits, in order of first occurrence.
fn expected_mesh(facets: &[Facet]) -> Mesh {
    let mut index: HashMap<[u32; 3], u32> = HashMap::new();
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    for facet in facets {
        triangles.push(facet.map(|corner| {
            *index.entry(corner.map(f32::to_bits)).or_insert_with(|| {
                positions.push(corner);
                positions.len() as u32 - 1
            })
        }));
    }
    Mesh {
        positions,
        triangles,
        face_ids: None,
        normals: None,
        colors: None,
    }
}

fn facets_of(mesh: &Mesh) -> Vec<Facet> {
    mesh.triangles
        .iter()
        .map(|t| t.map(|v| mesh.positions[v as usize]))
        .collect()
}

fn generated_facets(kind: reducem_gen::Kind) -> Vec<Facet> {
    let dir = temp_dir(&format!("gen-{kind}"));
    let path = dir.join("mesh.ply");
    reducem_gen::generate(kind, 3000, 5, &path).unwrap();
    let facets = facets_of(
        &reducem::input::PlyFile::open(&path)
            .unwrap()
            .read_mesh()
            .unwrap(),
    );
    std::fs::remove_dir_all(&dir).unwrap();
    facets
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let path = dir.join(name);
    std::fs::File::create(&path)
        .and_then(|mut file| file.write_all(bytes))
        .unwrap();
    path
}

#[test]
fn binary_and_ascii_read_every_generated_kind_welded_bit_exactly() {
    let dir = temp_dir("kinds");
    for kind in reducem_gen::Kind::ALL {
        let facets = generated_facets(kind);
        let expected = expected_mesh(&facets);
        let binary = write(&dir, "mesh.stl", &binary_stl(&[b' '; 80], &facets));
        assert_eq!(read_mesh(&binary).unwrap(), expected, "{kind} binary");
        let ascii = write(&dir, "mesh-ascii.stl", &ascii_stl(&facets));
        assert_eq!(read_mesh(&ascii).unwrap(), expected, "{kind} ASCII");
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn negative_zero_stays_apart_and_face_ids_are_facet_indices() {
    let dir = temp_dir("zero");
    let facets = [
        [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        [[-0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]],
    ];
    let path = write(&dir, "zero.stl", &binary_stl(&[0; 80], &facets));
    let mesh = read_mesh(&path).unwrap();
    assert_eq!(mesh.positions.len(), 4);
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [3, 2, 1]]);
    assert_eq!((mesh.face_id(0), mesh.face_id(1)), (0, 1));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_binary_header_beginning_with_solid_is_read_as_binary() {
    let dir = temp_dir("solid-header");
    let mut header = [b' '; 80];
    header[..23].copy_from_slice(b"solid exported by a CAD");
    let facets = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]];
    let path = write(&dir, "part.stl", &binary_stl(&header, &facets));
    assert_eq!(read_mesh(&path).unwrap(), expected_mesh(&facets));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn a_facet_count_that_disagrees_with_the_size_names_both() {
    let dir = temp_dir("count");
    let facets = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]; 2];
    let mut bytes = binary_stl(&[0; 80], &facets);
    bytes[80..84].copy_from_slice(&5u32.to_le_bytes());
    let path = write(&dir, "count.stl", &bytes);
    let error = read_mesh(&path).unwrap_err();
    assert_eq!(
        error.kind,
        InputErrorKind::StlFacetCount {
            declared: 5,
            expected_bytes: 334,
            bytes: 184,
            whole_facets: 2
        }
    );
    assert!(error
        .to_string()
        .starts_with(&format!("{}: ", path.display())));

    // Truncated in the middle of a facet: the same error, by the size.
    let path = write(&dir, "cut.stl", &binary_stl(&[0; 80], &facets)[..150]);
    let error = read_mesh(&path).unwrap_err();
    assert!(matches!(
        error.kind,
        InputErrorKind::StlFacetCount {
            declared: 2,
            bytes: 150,
            whole_facets: 1,
            ..
        }
    ));
    let path = write(&dir, "short.stl", &[0; 40]);
    let error = read_mesh(&path).unwrap_err();
    assert_eq!(error.kind, InputErrorKind::Truncated { needed: 44 });
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ascii_decimals_round_once_to_the_nearest_float() {
    let dir = temp_dir("rounding");
    // Just above the midpoint of 1 and the next f32: correctly rounded it is the next f32;
    // through f64 it becomes the midpoint exactly and then rounds to even, 1.0.
    let text =
        "solid r\nfacet normal 0 0 0\nouter loop\nvertex 1.0000000596046447753906250001 0 0\n\
                vertex 0 1 0\nvertex 0 0 1e-45\nendloop\nendfacet\nendsolid r\n";
    let path = write(&dir, "rounding.stl", text.as_bytes());
    let mesh = read_mesh(&path).unwrap();
    assert_eq!(mesh.positions[0][0], f32::from_bits(1.0f32.to_bits() + 1));
    assert_eq!(mesh.positions[2][2], f32::from_bits(1));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn ascii_errors_name_the_file_facet_line_and_byte() {
    let dir = temp_dir("ascii-errors");
    let good = "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\n";
    let cases: [(&str, &str, u64, usize, InputErrorKind); 4] = [
        (
            "token",
            "facet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 x 0\n",
            1,
            9,
            InputErrorKind::MalformedToken {
                token: "x".into(),
                expected: "float",
            },
        ),
        (
            "keyword",
            "facet normal 0 0 1\nouter lop\n",
            1,
            6,
            InputErrorKind::StlSyntax {
                expected: "loop",
                found: "lop".into(),
            },
        ),
        (
            "nan",
            "facet normal 0 0 1\nouter loop\nvertex 0 0 nan\n",
            1,
            11,
            InputErrorKind::NonFiniteCoordinate {
                axis: 'z',
                value: f64::NAN,
            },
        ),
        (
            "end",
            "facet normal 0 0 1\nouter loop\nvertex 0 0 0\n",
            1,
            0,
            InputErrorKind::UnexpectedEndOfText,
        ),
    ];
    for (name, tail, facet, column, kind) in cases {
        let text = format!("{good}{tail}");
        let path = write(&dir, &format!("{name}.stl"), text.as_bytes());
        let error = read_mesh(&path).unwrap_err();
        let Location::Element {
            element,
            index,
            byte_offset,
            line,
        } = error.location.clone()
        else {
            panic!("{name}: {error}");
        };
        let line = line.expect("a line");
        let lines: Vec<&str> = text.split_inclusive('\n').collect();
        let line_start: usize = lines[..line as usize - 1].iter().map(|l| l.len()).sum();
        let expected_line = if name == "end" {
            lines.len() as u64
        } else {
            (good.lines().count() + tail.lines().count()) as u64
        };
        assert_eq!(
            (element.as_str(), index, line),
            ("facet", facet, expected_line),
            "{name}"
        );
        let column = if name == "end" {
            lines[line as usize - 1].len()
        } else {
            column
        };
        assert_eq!(byte_offset, (line_start + column) as u64, "{name}: {error}");
        if name == "nan" {
            assert!(matches!(
                error.kind,
                InputErrorKind::NonFiniteCoordinate { axis: 'z', .. }
            ));
        } else {
            assert_eq!(error.kind, kind, "{name}");
        }
        assert!(error
            .to_string()
            .contains(&format!("{name}.stl: element 'facet' #1 at byte")));
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn binary_errors_name_the_facet_and_byte_of_the_value() {
    let dir = temp_dir("binary-errors");
    let mut facets = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]; 3];
    facets[2][1][1] = f32::INFINITY;
    let path = write(&dir, "inf.stl", &binary_stl(&[0; 80], &facets));
    let error = read_mesh(&path).unwrap_err();
    assert_eq!(
        error.location,
        Location::Element {
            element: "facet".into(),
            index: 2,
            byte_offset: 84 + 2 * 50 + 12 + 12 + 4,
            line: None
        }
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn stl_gives_no_vertex_attributes_and_says_why() {
    let dir = temp_dir("attributes");
    let facets = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]];
    let path = write(&dir, "a.stl", &binary_stl(&[0; 80], &facets));
    let request = AttributeRequest {
        normals: true,
        colors: false,
    };
    let error = read_mesh_with(&path, request).unwrap_err();
    assert!(
        matches!(
            error.kind,
            InputErrorKind::MissingAttribute {
                attribute: "normals",
                ..
            }
        ),
        "{error}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn content_decides_the_format_before_the_extension() {
    let dir = temp_dir("detect");
    let facets = [[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]];
    let misnamed = write(&dir, "really-stl.ply", &binary_stl(&[0; 80], &facets));
    let detected = detect(&misnamed).unwrap();
    assert_eq!(detected.format.name(), "STL");
    assert_eq!(detected.format.default_up(), UpAxis::Z);
    assert_eq!(read_mesh(&misnamed).unwrap(), expected_mesh(&facets));
    let obj = write(&dir, "tri.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_eq!(detect(&obj).unwrap().format.default_up(), UpAxis::Y);
    std::fs::remove_dir_all(&dir).unwrap();
}
