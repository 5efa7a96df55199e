//! Decoding a ReduceM file back to triangles: the proof that the representation is lossless,
//! or, for grid vertices, that it stores exactly the quantized input (positions decoded by
//! [`crate::format::grid::Grid::decode_axis`], as the tracer sees them).

use std::io::{self, Write};
use std::path::Path;

use crate::atomic::write_atomically;
use crate::format::reader::ReducemFile;
use crate::geometry::Point;

/// Every stored triangle in file order, corners in input winding.
pub fn triangles(file: &ReducemFile) -> impl Iterator<Item = [Point; 3]> + '_ {
    (0..file.strip_count()).flat_map(move |s| {
        let view = file.strip(s);
        (0..view.window_count()).filter_map(move |k| view.window_points(k))
    })
}

/// Writes every triangle as binary little-endian PLY (`float x,y,z`; `list uchar int
/// vertex_indices`), each strip's stored vertices once, atomically replacing `out`.
pub fn write_ply(file: &ReducemFile, out: &Path) -> io::Result<()> {
    write_atomically(out, |out| write_ply_body(file, out))
}

fn write_ply_body(file: &ReducemFile, out: &mut impl Write) -> io::Result<()> {
    let header = file.header();
    write!(
        out,
        "ply\nformat binary_little_endian 1.0\ncomment decoded by reducem from {}\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
         element face {}\nproperty list uchar int vertex_indices\nend_header\n",
        file.path().display(),
        header.stored_vertex_count,
        header.triangle_count
    )?;
    for s in 0..file.strip_count() {
        for vertex in file.strip(s).vertices.iter() {
            out.write_all(bytemuck::cast_slice(&vertex))?;
        }
    }
    let mut first_vertex = 0u64;
    for s in 0..file.strip_count() {
        let view = file.strip(s);
        for triangle in view.triangles() {
            out.write_all(&[3])?;
            for r in triangle {
                let index = i32::try_from(first_vertex + r as u64)
                    .map_err(|_| io::Error::other("too many vertices for PLY int indices"))?;
                out.write_all(&index.to_le_bytes())?;
            }
        }
        first_vertex += view.vertices.len() as u64;
    }
    Ok(())
}
