//! OBJ input tests: fixtures are written to the temp dir by each test.

use std::path::PathBuf;

use reducem::input::{read_mesh, read_obj, InputErrorKind, Location};
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
