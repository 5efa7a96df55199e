//! Mesh input: PLY (binary little/big endian and ASCII) and OBJ, triangulated and welded.
//!
//! [`read_mesh`] is the one-call entry point. [`PlyFile`] is exposed separately so callers
//! can read positions and triangles without building a [`Mesh`], and [`PlyStream`] reads
//! binary PLY window by window so the out-of-core chunker's memory stays bounded by the window
//! rather than the file size.
//! Every reader triangulates polygons as fans `(v0, vi, vi+1)`, keeping winding; welding is a
//! separate pass so that both formats share it and streaming callers can skip it.

mod error;
mod obj;
mod obj_survey;
mod ply;
pub mod stream;
mod tolerance_weld;
mod weld;

use std::path::Path;

pub use crate::format::counts::WeldStats;
pub use error::{InputError, InputErrorKind, Location};
pub use obj::read_obj;
pub use ply::PlyFile;
pub use stream::PlyStream;
pub use tolerance_weld::{tolerance_representatives, weld_within_tolerance};
pub use weld::{weld_identical_positions, weld_identical_positions_kept};

use crate::mesh::Mesh;

/// Reads a mesh by file extension (`.ply` or `.obj`, any case), triangulates polygons and
/// welds bit-identical positions.
pub fn read_mesh(path: &Path) -> Result<Mesh, InputError> {
    let extension = path
        .extension()
        .and_then(|extension| extension.to_str())
        .map(str::to_ascii_lowercase);
    let mesh = match extension.as_deref() {
        Some("ply") => PlyFile::open(path)?.read_mesh()?,
        Some("obj") => read_obj(path)?,
        _ => {
            let kind = InputErrorKind::UnsupportedExtension;
            return Err(InputError::new(path, Location::File, kind));
        }
    };
    Ok(weld_identical_positions(mesh))
}
