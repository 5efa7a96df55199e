//! The formats of the input table through `pipeline convert`: a compressed input converts to
//! the same bytes as its plain content, and broken files of every format exit 65 naming the
//! file and where.

mod common;

use std::io::Write;
use std::path::Path;

use common::{assert_broken_inputs_exit_65, convert, temp_dir};

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    encoder.write_all(bytes).unwrap();
    encoder.finish().unwrap()
}

/// The generated PLY's triangles as a binary STL.
fn stl_of(ply: &Path) -> Vec<u8> {
    let mesh = reducem::input::read_mesh(ply).unwrap();
    let mut stl = vec![b' '; 80];
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
    stl
}

#[test]
fn compressed_inputs_convert_to_the_bytes_of_their_plain_content() {
    let dir = temp_dir("formats", "compressed");
    let ply = dir.join("mesh.ply");
    reducem_gen::generate(reducem_gen::Kind::Scan, 3000, 2, &ply).unwrap();
    let stl = dir.join("mesh.stl");
    std::fs::write(&stl, stl_of(&ply)).unwrap();
    for plain in [ply, stl] {
        let bytes = std::fs::read(&plain).unwrap();
        let (code, stderr) = convert(&plain, &dir.join("plain.rdm"));
        assert_eq!(code, Some(0), "{stderr}");
        let expected = std::fs::read(dir.join("plain.rdm")).unwrap();
        let name = plain.file_name().unwrap().to_str().unwrap();
        for (suffix, compressed) in [
            ("gz", gzip(&bytes)),
            ("zst", zstd::encode_all(&bytes[..], 3).unwrap()),
        ] {
            let input = dir.join(format!("{name}.{suffix}"));
            std::fs::write(&input, compressed).unwrap();
            let output = dir.join(format!("{name}.{suffix}.rdm"));
            let (code, stderr) = convert(&input, &output);
            assert_eq!(code, Some(0), "{stderr}");
            assert!(
                std::fs::read(&output).unwrap() == expected,
                "{}",
                input.display()
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn broken_stl_and_compressed_files_exit_65_naming_file_and_place() {
    let dir = temp_dir("formats", "broken");
    let ply = dir.join("mesh.ply");
    reducem_gen::generate(reducem_gen::Kind::Sphere, 500, 1, &ply).unwrap();
    let stl = stl_of(&ply);
    let ascii =
        "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 q\n";
    let cases: [(&str, Vec<u8>, &str); 4] = [
        (
            "cut.stl",
            stl[..stl.len() - 7].to_vec(),
            "cut.stl: the binary STL header declares",
        ),
        (
            "bad.stl",
            ascii.as_bytes().to_vec(),
            "bad.stl: element 'facet' #0 at byte 75 (line 6): malformed float token 'q'",
        ),
        (
            "cut.stl.gz",
            gzip(&stl)[..200].to_vec(),
            "cut.stl.gz: the gzip stream is corrupt after",
        ),
        (
            "bad.stl.zst",
            zstd::encode_all(ascii.as_bytes(), 3).unwrap(),
            "bad.stl.zst: element 'facet' #0 at byte 75 (line 6)",
        ),
    ];
    assert_broken_inputs_exit_65(&dir, cases.into());
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn convert_help_names_every_format_of_the_table() {
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["convert", "--help"])
        .output()
        .unwrap();
    let help = String::from_utf8_lossy(&output.stdout);
    for format in reducem::input::FORMATS {
        assert!(help.contains(format.name()), "{} in {help}", format.name());
    }
    assert!(help.contains("glTF 2.0 / GLB"), "{help}");
}
