#[path = "../tests/common/mod.rs"]
mod common;
fn main() {
    let n: u32 = std::env::args().nth(1).unwrap().parse().unwrap();
    let mesh = common::torus(n, n / 2);
    let t = std::time::Instant::now();
    let stats = reducem::build::convert_mesh(&mesh, &Default::default(), std::path::Path::new("/tmp/torus.rdm")).unwrap();
    eprintln!("{} tris in {:.2}s {:?}", mesh.triangles.len(), t.elapsed().as_secs_f64(), stats);
}
