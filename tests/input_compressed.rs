//! gzip- and zstd-compressed inputs read exactly as their plain content, recognised by their
//! magic bytes whatever the name says.

use std::io::Write;
use std::path::{Path, PathBuf};

use reducem::input::{detect, open_source, read_mesh, Compression, InputErrorKind, Location};

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "reducem-input-compressed-{name}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

fn zstd(bytes: &[u8]) -> Vec<u8> {
    zstd::encode_all(bytes, 3).unwrap()
}

/// A small generated mesh as binary PLY, OBJ and binary STL.
fn plain_files(dir: &Path) -> Vec<PathBuf> {
    let ply = dir.join("mesh.ply");
    reducem_gen::generate(reducem_gen::Kind::Scan, 2000, 3, &ply).unwrap();
    let mesh = reducem::input::PlyFile::open(&ply)
        .unwrap()
        .read_mesh()
        .unwrap();
    let mut obj = String::new();
    for p in &mesh.positions {
        obj.push_str(&format!("v {:?} {:?} {:?}\n", p[0], p[1], p[2]));
    }
    for t in &mesh.triangles {
        obj.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    let mut stl = vec![0u8; 80];
    stl.extend_from_slice(&(mesh.triangles.len() as u32).to_le_bytes());
    for t in &mesh.triangles {
        stl.extend_from_slice(&[0; 12]);
        for &v in t {
            stl.extend(
                mesh.positions[v as usize]
                    .iter()
                    .flat_map(|c| c.to_le_bytes()),
            );
        }
        stl.extend_from_slice(&[0, 0]);
    }
    std::fs::write(dir.join("mesh.obj"), obj).unwrap();
    std::fs::write(dir.join("mesh.stl"), stl).unwrap();
    vec![ply, dir.join("mesh.obj"), dir.join("mesh.stl")]
}

#[test]
fn compressed_inputs_read_as_their_plain_content() {
    let dir = temp_dir("same");
    for plain in plain_files(&dir) {
        let bytes = std::fs::read(&plain).unwrap();
        let expected = read_mesh(&plain).unwrap();
        let name = plain.file_name().unwrap().to_str().unwrap();
        for (suffix, compressed, compression) in [
            ("gz", gzip(&bytes), Compression::Gzip),
            ("zst", zstd(&bytes), Compression::Zstd),
        ] {
            let path = dir.join(format!("{name}.{suffix}"));
            std::fs::write(&path, compressed).unwrap();
            assert_eq!(detect(&path).unwrap().compression, Some(compression));
            assert_eq!(read_mesh(&path).unwrap(), expected, "{}", path.display());

            let source = open_source(&path, Default::default(), 4096).unwrap();
            let mut triangles = Vec::new();
            source
                .for_each_triangle(&mut |_, t| triangles.push(t))
                .unwrap();
            let ids: Vec<u32> = (0..source.vertex_count() as u32).collect();
            let positions = source.positions_of(&ids).unwrap();
            let streamed: Vec<_> = triangles
                .iter()
                .map(|t| t.map(|v| positions[v as usize]))
                .collect();
            let whole: Vec<_> = expected
                .triangles
                .iter()
                .map(|t| t.map(|v| expected.positions[v as usize]))
                .collect();
            assert_eq!(streamed, whole, "{}", path.display());
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn the_magic_bytes_decide_not_the_name() {
    let dir = temp_dir("magic");
    let plain = &plain_files(&dir)[0];
    let path = dir.join("named-plain.ply");
    std::fs::write(&path, zstd(&std::fs::read(plain).unwrap())).unwrap();
    assert_eq!(read_mesh(&path).unwrap(), read_mesh(plain).unwrap());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn corrupt_and_truncated_streams_name_the_compressed_file() {
    let dir = temp_dir("corrupt");
    let plain = &plain_files(&dir)[0];
    let bytes = std::fs::read(plain).unwrap();
    let gz = gzip(&bytes);
    let cut = dir.join("cut.ply.gz");
    std::fs::write(&cut, &gz[..gz.len() / 2]).unwrap();
    let error = read_mesh(&cut).unwrap_err();
    assert_eq!(error.path, cut);
    assert!(
        matches!(
            error.kind,
            InputErrorKind::Decompression {
                compression: "gzip",
                ..
            }
        ),
        "{error}"
    );

    // A defect inside the content is located in the decompressed bytes, under the .zst name.
    let mut broken = bytes.clone();
    let header_end = broken
        .windows(11)
        .position(|w| w == b"end_header\n")
        .unwrap()
        + 11;
    let header = String::from_utf8_lossy(&broken[..header_end]).into_owned();
    let vertex_count: usize = header
        .lines()
        .find_map(|line| line.strip_prefix("element vertex "))
        .unwrap()
        .parse()
        .unwrap();
    let first_face = header_end + 12 * vertex_count;
    broken[first_face + 1..first_face + 5].copy_from_slice(&u32::MAX.to_le_bytes());
    let zst = dir.join("broken.ply.zst");
    std::fs::write(&zst, zstd(&broken)).unwrap();
    let plain_broken = dir.join("broken.ply");
    std::fs::write(&plain_broken, &broken).unwrap();
    let (compressed_error, plain_error) = match (read_mesh(&zst), read_mesh(&plain_broken)) {
        (Err(c), Err(p)) => (c, p),
        other => panic!("expected two errors, got {other:?}"),
    };
    assert_eq!(compressed_error.path, zst);
    assert_eq!(compressed_error.kind, plain_error.kind);
    assert_eq!(compressed_error.location, plain_error.location);
    assert!(matches!(
        compressed_error.location,
        Location::Element { .. }
    ));
    std::fs::remove_dir_all(&dir).unwrap();
}
