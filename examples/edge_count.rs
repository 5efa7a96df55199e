//! The edge counts of one mesh as a chunk of the pipeline counts them, for instruction counts of
//! the counting alone:
//!
//! `RAYON_NUM_THREADS=1 valgrind --tool=callgrind --toggle-collect='edge_count::count'
//!  target/release/examples/edge_count MESH.ply`
//!
//! The mesh is welded by position first, as the chunk stage welds each chunk, and its shared
//! positions are an empty set sized for its vertices, so every position is asked about as there.

use reducem::closedness::{count_chunk_edges, SharedPositions};
use reducem::format::model::Closedness;
use reducem::mesh::Mesh;

#[inline(never)]
fn count(mesh: &Mesh, shared: &SharedPositions) -> (Closedness, usize) {
    let (counts, border) = count_chunk_edges(mesh, |key| shared.contains(key));
    (counts, border.len())
}

fn main() {
    let path = std::env::args().nth(1).expect("usage: edge_count MESH");
    let mesh = reducem::input::read_mesh(std::path::Path::new(&path)).expect("read mesh");
    let mesh = reducem::input::weld_identical_positions(mesh);
    let shared = SharedPositions::new(mesh.positions.len() as u64);
    let (counts, border) = count(&mesh, &shared);
    println!(
        "{} triangles, {} vertices: {} boundary edges, {} non-manifold edges, {border} border edges",
        mesh.triangles.len(),
        mesh.positions.len(),
        counts.boundary_edges,
        counts.nonmanifold_edges
    );
}
