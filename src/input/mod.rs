//! Mesh input: PLY (binary little/big endian and ASCII), OBJ, STL (binary and ASCII) and glTF
//! 2.0 (`.gltf`, `.glb`), plain or compressed with gzip or zstd, triangulated and welded.
//!
//! [`formats`] holds the table of formats, which recognises a file and opens it as a
//! [`MeshSource`] for the chunker; [`read_mesh`] is the one-call entry point. [`PlyFile`] is exposed separately so callers
//! can read positions and triangles without building a [`Mesh`], and [`PlyStream`] reads
//! binary PLY window by window so the out-of-core chunker's memory stays bounded by the window
//! rather than the file size.
//! Every reader triangulates polygons as fans `(v0, vi, vi+1)`, keeping winding; welding is a
//! separate pass so that both formats share it and streaming callers can skip it.

mod compressed;
mod error;
pub mod formats;
mod gltf;
mod obj;
mod obj_survey;
mod ply;
mod source;
mod stl;
mod stl_stream;
mod stream;
mod temporary;
mod tolerance_weld;
mod weld;

use std::path::Path;

pub use crate::format::counts::WeldStats;
pub use compressed::Compression;
pub use error::{InputError, InputErrorKind, Location};
pub use formats::{
    check_attributes, detect, format_names, open_source, read_mesh_with, Detected, MeshFormat,
    UpAxis, FORMATS,
};
pub use obj::{read_obj, read_obj_with};
pub use ply::PlyFile;
pub(crate) use source::pick;
pub use source::MeshSource;
pub use stream::PlyStream;
pub(crate) use tolerance_weld::tolerance_representatives;
pub use tolerance_weld::weld_within_tolerance;
pub use weld::weld_identical_positions;
pub(crate) use weld::weld_identical_positions_kept;

use crate::format::attributes::{AttributeSet, NormalEncoding};
use crate::geometry::Point;
use crate::mesh::Mesh;

/// Which vertex attributes to read besides positions (face ids are always known). Attributes
/// not asked for are skipped like any other property, so asking for none costs nothing.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AttributeRequest {
    /// PLY `nx ny nz`, OBJ `vn` through each face corner's normal index.
    pub normals: bool,
    /// PLY `red green blue [alpha]`, OBJ `v x y z r g b`.
    pub colors: bool,
}

impl AttributeRequest {
    /// The vertex attributes a build with `params` stores.
    pub fn for_build(params: &AttributeSet) -> AttributeRequest {
        AttributeRequest {
            normals: params.normals != NormalEncoding::None,
            colors: params.colors,
        }
    }

    pub fn any(self) -> bool {
        self.normals || self.colors
    }
}

/// Normals and colours of chosen vertices, parallel to them; `None` where not asked for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct VertexAttributes {
    pub normals: Option<Vec<[f32; 3]>>,
    pub colors: Option<Vec<[u8; 4]>>,
}

/// Vertices as read: positions, and the attributes asked for, parallel to them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Vertices {
    pub positions: Vec<Point>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub colors: Option<Vec<[u8; 4]>>,
}

/// Reads a mesh in any format of the table ([`FORMATS`]), compressed or not, triangulates
/// polygons and welds bit-identical positions.
pub fn read_mesh(path: &Path) -> Result<Mesh, InputError> {
    read_mesh_with(path, AttributeRequest::default())
}
