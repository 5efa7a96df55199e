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
    };
    assert_eq!(mesh, expected);
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

#[test]
fn malformed_obj_names_the_file() {
    let file = temp_file("broken.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    let error = read_mesh(&file.0).unwrap_err();
    assert_eq!(error.location, Location::File);
    assert!(matches!(error.kind, InputErrorKind::Obj(_)), "{error}");
    assert!(
        error
            .to_string()
            .starts_with(&format!("{}: OBJ: ", file.0.display())),
        "{error}"
    );
}

#[test]
fn non_finite_obj_coordinates_are_rejected() {
    let file = temp_file("nan.obj", "v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n");
    let error = read_mesh(&file.0).unwrap_err();
    assert!(
        matches!(
            error.kind,
            InputErrorKind::NonFiniteCoordinate { axis: 'y', .. }
        ),
        "{error}"
    );
}
