//! OBJ input tests: fixtures are written to the temp dir by each test.

use std::path::PathBuf;

use reducem::input::{
    check_attributes, read_mesh, read_mesh_with, read_obj, read_obj_with, AttributeRequest,
    InputErrorKind, Location,
};
use reducem::mesh::Mesh;

/// A file in the temp dir, removed when dropped.
struct TempFile(PathBuf);

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

fn temp_file(name: &str, text: &str) -> TempFile {
    let path =
        std::env::temp_dir().join(format!("reducem-input-obj-{}-{name}", std::process::id()));
    std::fs::write(&path, text).expect("write fixture");
    TempFile(path)
}

const TWO_OBJECTS: &str = "\
# a quad and a triangle sharing two of its corners
o first
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
f 1 2 3 4
o second
v 1 0 0
v 2 0 0
v 1 1 0
f 5 6 7
";

#[test]
fn objects_are_merged_fanned_and_welded() {
    let file = temp_file("two-objects.obj", TWO_OBJECTS);
    let mesh = read_mesh(&file.0).unwrap();
    let expected = Mesh {
        positions: vec![
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
            [2.0, 0.0, 0.0],
        ],
        triangles: vec![[0, 1, 2], [0, 2, 3], [1, 4, 2]],
        face_ids: Some(vec![0, 0, 1]),
        normals: None,
        colors: None,
    };
    assert_eq!(mesh, expected);
}

#[test]
fn face_ids_follow_f_statements_across_groups_and_polygons() {
    // A pentagon, a triangle in another group, then the first group again with a quad.
    let text = "v 0 0 0
v 1 0 0
v 2 1 0
v 1 2 0
v 0 1 0
g a
f 1 2 3 4 5
g b
f 1 2 4
g a
f 2 3 4 5
";
    let file = temp_file("groups.obj", text);
    // Welded: `tobj` gives each group its own copies of the vertices.
    let mesh = read_mesh(&file.0).unwrap();
    assert_eq!(
        mesh.triangles,
        vec![
            [0, 1, 2],
            [0, 2, 3],
            [0, 3, 4],
            [0, 1, 3],
            [1, 2, 3],
            [1, 3, 4]
        ]
    );
    assert_eq!(mesh.face_ids, Some(vec![0, 0, 0, 1, 2, 2]));
}

#[test]
fn unwelded_objects_keep_their_own_vertices_with_offsets() {
    let file = temp_file("two-objects-raw.obj", TWO_OBJECTS);
    let mesh = read_obj(&file.0).unwrap();
    assert_eq!(mesh.positions.len(), 7);
    assert_eq!(
        mesh.positions[4..],
        [[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [1.0, 1.0, 0.0]]
    );
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]]);
}

#[test]
fn upper_case_extension_and_negative_indices_work() {
    let file = temp_file(
        "relative.OBJ",
        "v 0 0 0\nv 0 0 1\nv 0 1 0\nv 1 0 0\nf -4 -3 -2 -1\n",
    );
    let mesh = read_mesh(&file.0).unwrap();
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(mesh.positions[3], [1.0, 0.0, 0.0]);
}

/// The message of reading `text` as an OBJ file, which must fail at `location`.
fn error_at(name: &str, text: &str, location: Location) -> String {
    let file = temp_file(name, text);
    let error = read_mesh(&file.0).unwrap_err();
    assert_eq!(error.location, location, "{error}");
    assert!(error.to_string().starts_with(&file.0.display().to_string()));
    error.to_string()
}

fn element(element: &str, index: u64, byte_offset: u64, line: u64) -> Location {
    Location::Element {
        element: element.into(),
        index,
        byte_offset,
        line: Some(line),
    }
}

#[test]
fn malformed_obj_names_the_line_and_byte_of_the_defect() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n";
    let message = error_at("broken.obj", text, element("face", 0, 30, 4));
    assert!(
        message.ends_with(
            "element 'face' #0 at byte 30 (line 4): OBJ: face vertex index 9 out of range \
             (3 vertices)"
        ),
        "{message}"
    );
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf -4 1 2\n";
    let message = error_at("relative.obj", text, element("face", 1, 34, 5));
    assert!(message.contains("index -4 out of range"), "{message}");
    let text = "v 0 0 0\nv 1 x 0\n";
    let message = error_at("token.obj", text, element("vertex", 1, 12, 2));
    assert!(message.contains("malformed number token 'x'"), "{message}");
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2/a 3\n";
    let message = error_at("corner.obj", text, element("face", 0, 28, 4));
    assert!(message.contains("malformed face corner '2/a'"), "{message}");
}

#[test]
fn absurd_texture_and_normal_indices_are_defects_not_overflows() {
    let corners = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/9223372036854775807 2/1 3/1\n";
    let message = error_at("texture.obj", corners, element("face", 0, 33, 5));
    assert!(
        message.contains("face texture coordinate index 9223372036854775807 out of range"),
        "{message}"
    );
    let corners = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//-9223372036854775807 2//1 3//1\n";
    let message = error_at("normal.obj", corners, element("face", 0, 35, 5));
    assert!(
        message
            .contains("face normal index -9223372036854775807 out of range (1 normals before it)"),
        "{message}"
    );
}

#[test]
fn unknown_statements_do_not_fail_the_read() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\ncurv 0 1 1 2\nf 1 2 3\nfoo\ncurv 0 1 2 3\n";
    let file = temp_file("unknown.obj", text);
    let mesh = read_mesh(&file.0).unwrap();
    assert_eq!(mesh.triangles.len(), 1);
}

#[test]
fn non_finite_obj_coordinates_are_rejected() {
    let file = temp_file("nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n");
    let error = read_mesh(&file.0).unwrap_err();
    assert_eq!(error.location, element("vertex", 1, 12, 2), "{error}");
    assert!(
        matches!(
            error.kind,
            InputErrorKind::NonFiniteCoordinate { axis: 'y', .. }
        ),
        "{error}"
    );
}

// ---------------------------------------------------------------------------------------------
// Normals and colours

const NORMALS: AttributeRequest = AttributeRequest {
    normals: true,
    colors: false,
};
const COLORS: AttributeRequest = AttributeRequest {
    normals: false,
    colors: true,
};

/// A crease: a quad in z = 0 with normal +z, and a triangle in y = 0 with normal -y sharing the
/// quad's edge (1, 2), in a second group, the triangle's corners through negative indices and
/// with texture coordinates.
const CREASE: &str = "\
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0.5 0 -1
vn 0 0 1
vn 0 -1 0
vt 0 0
f 1//1 2//1 3//1 4//1
g side
f -5/1/-1 -1/1/-1 -4/1/-1
";

/// Every triangle's corners as (position, normal), in order.
fn corners_with_normals(mesh: &Mesh) -> Vec<[([f32; 3], [f32; 3]); 3]> {
    let normals = mesh.normals.as_ref().expect("normals");
    mesh.triangles
        .iter()
        .map(|t| t.map(|v| (mesh.positions[v as usize], normals[v as usize])))
        .collect()
}

#[test]
fn corners_with_different_normals_become_distinct_vertices() {
    let file = temp_file("crease.obj", CREASE);
    let mesh = read_mesh_with(&file.0, NORMALS).unwrap();
    let (up, side) = ([0.0, 0.0, 1.0], [0.0, -1.0, 0.0]);
    let expected = vec![
        [
            ([0.0, 0.0, 0.0], up),
            ([1.0, 0.0, 0.0], up),
            ([1.0, 1.0, 0.0], up),
        ],
        [
            ([0.0, 0.0, 0.0], up),
            ([1.0, 1.0, 0.0], up),
            ([0.0, 1.0, 0.0], up),
        ],
        [
            ([0.0, 0.0, 0.0], side),
            ([0.5, 0.0, -1.0], side),
            ([1.0, 0.0, 0.0], side),
        ],
    ];
    assert_eq!(corners_with_normals(&mesh), expected);
    assert_eq!(mesh.face_ids, Some(vec![0, 0, 1]));
    // The shared edge's two positions carry two normals each: 4 + 3 vertices, welded or not.
    assert_eq!(mesh.positions.len(), 7);
    assert_eq!(read_obj_with(&file.0, NORMALS).unwrap().positions.len(), 7);
    // Without normals, the positions weld into 5 vertices.
    let plain = read_mesh(&file.0).unwrap();
    assert_eq!(plain.positions.len(), 5);
    assert_eq!(plain.normals, None);
}

#[test]
fn obj_vertex_colours_are_read_per_vertex() {
    let text = "v 0 0 0 1 0 0\nv 1 0 0 0 0.5 1\nv 1 1 0 0.2 0.4 0.6\nv 0 1 0 0 0 0\n\
                f 1 2 3 4\nf 1 3 2\n";
    let file = temp_file("colours.obj", text);
    let mesh = read_mesh_with(&file.0, COLORS).unwrap();
    assert_eq!(
        mesh.colors,
        Some(vec![
            [255, 0, 0, 255],
            [0, 128, 255, 255],
            [51, 102, 153, 255],
            [0, 0, 0, 255],
        ])
    );
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [0, 2, 3], [0, 2, 1]]);
    assert_eq!(mesh.face_ids, Some(vec![0, 0, 1]));
    assert_eq!(read_mesh(&file.0).unwrap().colors, None);
}

#[test]
fn obj_attribute_defects_are_located_when_asked_for() {
    let read = |name: &str, text: &str, request: AttributeRequest| {
        let file = temp_file(name, text);
        let error = read_mesh_with(&file.0, request).unwrap_err();
        assert!(error.to_string().starts_with(&file.0.display().to_string()));
        error
    };
    let nan = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 nan 1\nf 1//1 2//1 3//1\n";
    let error = read("nan-normal.obj", nan, NORMALS);
    assert_eq!(error.location, element("normal", 0, 29, 4), "{error}");
    assert!(matches!(
        error.kind,
        InputErrorKind::NonFiniteNormal { axis: 'y', .. }
    ));
    let file = temp_file("nan-unasked.obj", nan);
    read_mesh(&file.0).expect("normals not asked for are not checked");

    let bright = "v 0 0 0 1 1 1\nv 1 0 0 0 1.5 0\nv 0 1 0 0 0 0\nf 1 2 3\n";
    let error = read("bright.obj", bright, COLORS);
    assert_eq!(error.location, element("vertex", 1, 24, 2), "{error}");
    assert_eq!(
        error.kind,
        InputErrorKind::ColorOutOfRange {
            channel: "green",
            value: 1.5
        }
    );

    let beyond = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n";
    let error = read("beyond.obj", beyond, NORMALS);
    assert_eq!(error.location, element("face", 0, 40, 5), "{error}");
    assert!(error
        .to_string()
        .contains("face normal index 2 out of range"));

    let partly = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1\nf 1//1 3 2//1\n";
    let error = read("partly.obj", partly, NORMALS);
    assert_eq!(error.location, element("face", 1, 57, 6), "{error}");

    let some_colours = "v 0 0 0 1 1 1\nv 1 0 0\nv 0 1 0 0 0 0\nf 1 2 3\n";
    let error = read("some-colours.obj", some_colours, COLORS);
    assert_eq!(error.location, element("vertex", 1, 14, 2), "{error}");
}

#[test]
fn asking_an_obj_for_attributes_it_lacks_names_them() {
    let file = temp_file("plain.obj", TWO_OBJECTS);
    for (request, message) in [
        (
            NORMALS,
            "normals were asked for, but the file has no 'vn' statements",
        ),
        (
            COLORS,
            "colours were asked for, but no vertex has a colour ('v x y z r g b')",
        ),
    ] {
        let error = check_attributes(&file.0, request).unwrap_err();
        assert_eq!(error.location, Location::File);
        assert_eq!(
            error.to_string(),
            format!("{}: {message}", file.0.display())
        );
        assert_eq!(
            read_mesh_with(&file.0, request).unwrap_err().to_string(),
            error.to_string()
        );
    }
}
