fn main() {
    let path = std::env::args().nth(1).unwrap();
    let f = reducem::format::reader::ReducemFile::open(std::path::Path::new(&path)).unwrap();
    let (mut w, mut t, mut v, mut nodes) = (0usize, 0usize, 0usize, 0usize);
    for s in 0..f.strip_count() {
        let view = f.strip(s);
        w += view.window_count();
        t += reducem::strip::triangles(view.references).count();
        let mut d: Vec<u8> = view.references.to_vec(); d.sort(); d.dedup(); v += d.len();
        nodes += reducem::format::implicit_tree::internal_nodes(view.window_count(), f.leaf_windows());
    }
    println!("windows {w} tris {t} swaps {} distinct-per-strip {v} slots {}", w - t, 2 * nodes);
}
