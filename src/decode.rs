//! Decoding a ReduceM file back to triangles: the proof that the representation is lossless,
//! or, for grid vertices, that it stores exactly the quantized input (positions decoded by
//! [`crate::format::grid::Grid::decode_axis`], as the tracer sees them).

use std::io::{self, Write};
use std::path::Path;

use crate::atomic::write_atomically;
use crate::format::attributes::NormalEncoding;
use crate::format::reader::{ReducemFile, StripView};
use crate::format::vertices::StripVertices;
use crate::format::VertexEncoding;
use crate::geometry::Point;

/// Every stored triangle in file order, corners in input winding.
pub fn triangles(file: &ReducemFile) -> impl Iterator<Item = [Point; 3]> + '_ {
    (0..file.strip_count()).flat_map(move |s| {
        let view = file.strip(s);
        (0..view.window_count()).filter_map(move |k| view.window_points(k))
    })
}

/// Writes every triangle as binary little-endian PLY (`float x,y,z`; `list uchar int
/// vertex_indices`), each strip's stored vertices once (in pooled grid files, each pool's points
/// once), atomically replacing `out`. A file with attributes adds them: `float nx,ny,nz` (the
/// decoded normal) and `uchar red,green,blue,alpha` on vertices, `uint face_id` on faces after
/// `vertex_indices`.
pub fn write_ply(file: &ReducemFile, out: &Path) -> io::Result<()> {
    write_atomically(out, |out| write_ply_to(file, out))
}

/// [`write_ply`] into `out`, a stream or a file.
pub fn write_ply_to<W: Write + ?Sized>(file: &ReducemFile, out: &mut W) -> io::Result<()> {
    write_ply_header(file, decoded_vertex_count(file), out)?;
    let attributes = file.attributes();
    let mut record = Vec::with_capacity(28);
    for (s, placed) in placements(file) {
        let Some(vertices) = placed.new_vertices else {
            continue;
        };
        let stored = file.vertex_attributes(s);
        for (index, vertex) in vertices.iter().enumerate() {
            record.clear();
            record.extend(bytemuck::cast_slice(&vertex));
            if attributes.normals != NormalEncoding::None {
                let normal = stored.and_then(|a| a.normal(index)).unwrap_or_default();
                record.extend(bytemuck::cast_slice(&normal));
            }
            if attributes.colors {
                record.extend(stored.and_then(|a| a.color(index)).unwrap_or_default());
            }
            out.write_all(&record)?;
        }
    }
    for (s, placed) in placements(file) {
        let windows = placed.view.references.to_vec();
        for k in 0..placed.view.window_count() {
            let Some(triangle) = crate::strip_windows::window_triangle(&windows, k) else {
                continue;
            };
            out.write_all(&[3])?;
            for r in triangle {
                let index = i32::try_from(placed.first_vertex + r as u64)
                    .map_err(|_| io::Error::other("too many vertices for PLY int indices"))?;
                out.write_all(&index.to_le_bytes())?;
            }
            if attributes.face_ids {
                out.write_all(&file.face_id(s, k).unwrap_or(u32::MAX).to_le_bytes())?;
            }
        }
    }
    match file.defect() {
        Some(defect) => Err(io::Error::new(
            io::ErrorKind::InvalidData,
            defect.to_string(),
        )),
        None => Ok(()),
    }
}

/// A strip as decoding places it among the written vertices.
struct Placed<'a> {
    view: StripView<'a>,
    /// The vertices written for this strip: its own, its pool's points when it is the first
    /// strip of its pool, or none.
    new_vertices: Option<StripVertices<'a>>,
    /// The written vertex that is the strip's vertex 0.
    first_vertex: u64,
}

/// Every strip in file order, placed: a strip's stored vertices follow those of the strips
/// before it, except in pooled grid files, whose strips of one pool share its points.
fn placements(file: &ReducemFile) -> impl Iterator<Item = (usize, Placed<'_>)> + '_ {
    let mut written = 0u64;
    let mut pool: Option<(usize, u64)> = None;
    (0..file.strip_count()).map(move |s| {
        let view = file.strip(s);
        let placed = match file.pool(s) {
            Some(place) => {
                let new_pool = pool.is_none_or(|(offset, _)| offset != place.offset);
                if new_pool {
                    pool = Some((place.offset, written));
                    written += place.points.len() as u64;
                }
                let pool_first = pool.map_or(0, |(_, first)| first);
                Placed {
                    view,
                    new_vertices: new_pool.then_some(place.points),
                    first_vertex: pool_first + place.base as u64,
                }
            }
            None => {
                let first_vertex = written;
                written += view.vertices.len() as u64;
                Placed {
                    view,
                    new_vertices: Some(view.vertices),
                    first_vertex,
                }
            }
        };
        (s, placed)
    })
}

/// The vertices [`write_ply_to`] writes: the header's stored count, or in pooled grid files the
/// points of their pools.
fn decoded_vertex_count(file: &ReducemFile) -> u64 {
    match file.header().vertex_encoding == VertexEncoding::GridPooled as u32 {
        true => placements(file)
            .filter_map(|(_, placed)| placed.new_vertices)
            .map(|vertices| vertices.len() as u64)
            .sum(),
        false => file.header().stored_vertex_count,
    }
}

fn write_ply_header<W: Write + ?Sized>(
    file: &ReducemFile,
    vertex_count: u64,
    out: &mut W,
) -> io::Result<()> {
    let header = file.header();
    let attributes = file.attributes();
    let mut text = format!(
        "ply\nformat binary_little_endian 1.0\ncomment decoded by reducem from {}\n\
         element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
        file.path().display(),
        vertex_count,
    );
    if attributes.normals != NormalEncoding::None {
        text += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    if attributes.colors {
        text +=
            "property uchar red\nproperty uchar green\nproperty uchar blue\nproperty uchar alpha\n";
    }
    text += &format!(
        "element face {}\nproperty list uchar int vertex_indices\n",
        header.triangle_count
    );
    if attributes.face_ids {
        text += "property uint face_id\n";
    }
    text += "end_header\n";
    out.write_all(text.as_bytes())
}
