//! Welding: vertices at bit-identical positions become one vertex.
//!
//! Exact bit equality (not a distance tolerance) is what the rest of the pipeline wants: it
//! recovers the connectivity of triangle soups and of meshes split into per-part vertex lists
//! without ever moving a point. Consequently `-0.0` and `0.0` stay distinct.
//!
//! Sort-based rather than hash-based: each vertex becomes one `u128` key (96 position bits
//! above its 32-bit index), and a parallel unstable sort groups equal positions with the
//! lowest index first. That is deterministic regardless of thread count, needs no hasher
//! tuning, and sorts 10M keys in well under a second on two cores. Survivors keep their
//! first-occurrence order, so a mesh without duplicates comes back unchanged.
//!
//! Vertices carry their normals and colours: two vertices at one position with different
//! attributes stay apart (their positions are still bit-identical, so triangles around them
//! meet exactly and tracing stays watertight). The alternative, letting the first vertex's
//! attributes win, joins strips across creases and colour seams but shades them wrongly: a
//! hard edge of a CAD part would be smoothed over. Measured on the `cad` generator's mesh
//! (200,000 triangles, 102,950 vertices) written as OBJ with normals, average strip length
//! with the paper's `max_length` 60 and the pipeline's 20
//! (`cargo run --release --example attribute_weld -- 200000 cad`):
//!
//! | normals                                  | stay apart: vertices, strips 60 / 20 | first wins: vertices, strips 60 / 20 |
//! |------------------------------------------|--------------------------------------|--------------------------------------|
//! | smoothed within 30° (hard edges split)   | 115,017, 15.30 / 11.47               | 102,950, 18.95 / 12.91               |
//! | one `vn` per face (every edge a crease)  | 389,321, 1.57 / 1.55                 | 102,950, 18.95 / 12.91               |
//!
//! So keeping them apart costs 19% of the strip length (11% at the pipeline's length) where
//! normals follow the surface, and is right: those are the vertices whose shading differs.
//! Per-face normals make every triangle its own strip, but they carry nothing the geometric
//! normal does not, so such inputs are better converted without `[attributes] normals`.
//!
//! Keys with attributes are wider than a u128, so such meshes sort vertex indices by a
//! (position, normal, colour) tuple instead; meshes without attributes keep the u128 path.

use rayon::prelude::*;

use crate::mesh::Mesh;

/// Merges vertices with bit-identical positions (and, where the mesh has them, identical
/// normals and colours); the first occurrence wins and triangles are remapped. Unreferenced vertices are kept. Triangles must refer to existing vertices, as the
/// readers guarantee.
pub fn weld_identical_positions(mesh: Mesh) -> Mesh {
    weld_identical_positions_kept(mesh).0
}

/// [`weld_identical_positions`], and for each vertex of the result its index in `mesh` (so that
/// data kept beside the positions can follow).
pub(crate) fn weld_identical_positions_kept(mesh: Mesh) -> (Mesh, Vec<u32>) {
    let representative = if mesh.normals.is_none() && mesh.colors.is_none() {
        first_occurrences(&mesh)
    } else {
        first_occurrences_with_attributes(&mesh)
    };
    let mut new_index = vec![0u32; mesh.positions.len()];
    let mut kept = Vec::with_capacity(mesh.positions.len());
    for index in 0..mesh.positions.len() {
        let first = representative[index] as usize;
        new_index[index] = if first == index {
            kept.push(index as u32);
            // Fewer survivors than input vertices, whose indices fit in u32.
            (kept.len() - 1) as u32
        } else {
            new_index[first]
        };
    }
    let triangles = mesh
        .triangles
        .into_par_iter()
        .map(|triangle| triangle.map(|vertex| new_index[vertex as usize]))
        .collect();
    let welded = Mesh {
        positions: gather(&mesh.positions, &kept),
        triangles,
        face_ids: mesh.face_ids,
        normals: mesh.normals.map(|normals| gather(&normals, &kept)),
        colors: mesh.colors.map(|colors| gather(&colors, &kept)),
    };
    (welded, kept)
}

/// `values[v]` for every `v` of `kept`.
fn gather<T: Copy>(values: &[T], kept: &[u32]) -> Vec<T> {
    kept.iter().map(|&v| values[v as usize]).collect()
}

/// For every vertex, the index of the first vertex with the same position and attributes.
fn first_occurrences_with_attributes(mesh: &Mesh) -> Vec<u32> {
    let bits = |values: [f32; 3]| values.map(f32::to_bits);
    let key = |vertex: u32| {
        let v = vertex as usize;
        let normal = mesh.normals.as_ref().map_or([0; 3], |n| bits(n[v]));
        let color = mesh.colors.as_ref().map_or(0, |c| u32::from_le_bytes(c[v]));
        (bits(mesh.positions[v]), normal, color, vertex)
    };
    let mut order: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    order.par_sort_unstable_by_key(|&vertex| key(vertex));
    let mut representative = vec![0u32; mesh.positions.len()];
    let same_vertex = |a: &u32, b: &u32| {
        let (ka, kb) = (key(*a), key(*b));
        (ka.0, ka.1, ka.2) == (kb.0, kb.1, kb.2)
    };
    for group in order.chunk_by(same_vertex) {
        for &vertex in group {
            representative[vertex as usize] = group[0];
        }
    }
    representative
}

/// For every vertex, the index of the first vertex at the same position.
fn first_occurrences(mesh: &Mesh) -> Vec<u32> {
    let mut keys: Vec<u128> = mesh
        .positions
        .par_iter()
        .enumerate()
        .map(|(index, point)| {
            let [x, y, z] = point.map(|c| u128::from(c.to_bits()));
            (x << 96) | (y << 64) | (z << 32) | index as u128
        })
        .collect();
    keys.par_sort_unstable();
    let mut representative = vec![0u32; mesh.positions.len()];
    for group in keys.chunk_by(|a, b| a >> 32 == b >> 32) {
        let first = group[0] as u32;
        for key in group {
            representative[*key as u32 as usize] = first;
        }
    }
    representative
}
