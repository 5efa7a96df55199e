//! Mesh input: PLY (binary little/big endian and ASCII) and OBJ.

use std::path::Path;

use crate::mesh::Mesh;

/// Errors reading a mesh, each naming the file and where in it the defect is.
#[derive(Debug, thiserror::Error)]
pub enum InputError {
    #[error("{path}: {message}")]
    Invalid { path: String, message: String },
}

/// Reads a mesh by file extension (`.ply` or `.obj`), triangulates polygons and welds
/// bit-identical positions.
pub fn read_mesh(path: &Path) -> Result<Mesh, InputError> {
    Err(InputError::Invalid {
        path: path.display().to_string(),
        message: "mesh input is not implemented yet".into(),
    })
}
