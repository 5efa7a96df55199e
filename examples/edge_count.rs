//! The edge counts of one mesh as a chunk of the pipeline counts them, for instruction counts of
//! the counting alone:
//!
//! `RAYON_NUM_THREADS=1 valgrind --tool=callgrind --toggle-collect='reducem::closedness::count_edges'
//!  target/release/examples/edge_count MESH.ply`
//!
//! The mesh is welded by position first, as the chunk stage welds each chunk.

use reducem::closedness::count_edges;

fn main() {
    let path = std::env::args().nth(1).expect("usage: edge_count MESH");
    let mesh = reducem::input::read_mesh(std::path::Path::new(&path)).expect("read mesh");
    let mesh = reducem::input::weld_identical_positions(mesh);
    let counts = count_edges(&mesh);
    println!(
        "{} triangles, {} vertices: {} boundary edges, {} non-manifold edges",
        mesh.triangles.len(),
        mesh.positions.len(),
        counts.boundary_edges,
        counts.nonmanifold_edges
    );
}
