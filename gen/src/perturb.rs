//! Perturbed shared vertices: a mesh whose every triangle has its own copies of its corners,
//! each copy moved a little. The input the tolerance weld is for: parts exported separately
//! (the paper's Boeing 777), whose shared vertices no longer coincide bit for bit, so that
//! bit-exact welding finds no shared edge. Used by the tests and the report; not a `pipeline gen`
//! kind, since it transforms a mesh rather than generating one.

use reducem::mesh::Mesh;
use reducem::splitmix::SplitMix64;

/// `mesh` with three fresh vertices per triangle, every coordinate moved by a uniform amount in
/// `[-amount, amount)` (deterministic for a seed); each copy keeps its vertex's attributes and
/// each triangle its face.
pub fn perturbed_copies(mesh: &Mesh, amount: f32, seed: u64) -> Mesh {
    let mut rng = SplitMix64::new(seed);
    let mut out = Mesh {
        positions: Vec::with_capacity(3 * mesh.triangles.len()),
        triangles: Vec::with_capacity(mesh.triangles.len()),
        face_ids: mesh.face_ids.clone(),
        normals: mesh.normals.as_ref().map(|_| Vec::new()),
        colors: mesh.colors.as_ref().map(|_| Vec::new()),
    };
    for triangle in &mesh.triangles {
        let base = out.positions.len() as u32;
        for &v in triangle {
            let p = mesh.positions[v as usize];
            out.positions
                .push(p.map(|c| c + rng.range(-amount, amount)));
            if let (Some(copies), Some(normals)) = (&mut out.normals, &mesh.normals) {
                copies.push(normals[v as usize]);
            }
            if let (Some(copies), Some(colors)) = (&mut out.colors, &mesh.colors) {
                copies.push(colors[v as usize]);
            }
        }
        out.triangles.push([base, base + 1, base + 2]);
    }
    out
}
