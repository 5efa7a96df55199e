//! glTF through `pipeline`: a generated GLB converts to the same bytes as the PLY of the same
//! mesh, and broken, truncated or Draco-compressed GLB files exit 65 naming the file and where.

mod common;

use std::path::Path;

use common::{assert_broken_inputs_exit_65, convert, pipeline, temp_dir};

fn run(args: &[&str]) -> (Option<i32>, String) {
    let result = pipeline(args);
    (
        result.status.code(),
        String::from_utf8_lossy(&result.stderr).into_owned(),
    )
}

#[test]
fn a_generated_glb_converts_to_the_bytes_of_the_same_ply() {
    let dir = temp_dir("gltf", "same");
    let gen = |name: &str, extra: &[&str]| {
        let path = dir.join(name);
        let mut args = vec![
            "gen",
            "scan",
            "--triangles",
            "3000",
            "-o",
            path.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        let (code, stderr) = run(&args);
        assert_eq!(code, Some(0), "{stderr}");
        path
    };
    let ply = gen("mesh.ply", &[]);
    let glb = gen("mesh.glb", &[]);
    let quantized = gen("quantized.glb", &["--quantized"]);
    for input in [&ply, &glb, &quantized] {
        let output = input.with_extension("rdm");
        let (code, stderr) = convert(input, &output);
        assert_eq!(code, Some(0), "{}: {stderr}", input.display());
    }
    let bytes = |path: &Path| std::fs::read(path.with_extension("rdm")).unwrap();
    assert!(
        bytes(&glb) == bytes(&ply),
        "the float GLB converts as the PLY"
    );
    let (code, stderr) = run(&[
        "gen",
        "scan",
        "--triangles",
        "30",
        "-o",
        "x.ply",
        "--quantized",
    ]);
    assert_eq!(code, Some(64), "{stderr}");
    assert!(
        stderr.contains("--quantized needs a .glb output"),
        "{stderr}"
    );
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn broken_glb_files_exit_65_naming_file_and_place() {
    let dir = temp_dir("gltf", "broken");
    let glb = dir.join("mesh.glb");
    let (code, stderr) = run(&[
        "gen",
        "sphere",
        "--triangles",
        "80",
        "-o",
        glb.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    let bytes = std::fs::read(&glb).unwrap();
    let json_end = 20 + u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let draco = String::from_utf8_lossy(&bytes[20..json_end]).replacen(
        "\"asset\"",
        "\"extensionsRequired\":[\"KHR_draco_mesh_compression\"],\"asset\"",
        1,
    );
    let mut draco_glb = bytes[..12].to_vec();
    let padded = format!("{draco:<width$}", width = draco.len().next_multiple_of(4));
    draco_glb.extend((padded.len() as u32).to_le_bytes());
    draco_glb.extend(b"JSON");
    draco_glb.extend(padded.as_bytes());
    draco_glb.extend(&bytes[json_end..]);
    let total = draco_glb.len() as u32;
    draco_glb[8..12].copy_from_slice(&total.to_le_bytes());
    let cases: [(&str, Vec<u8>, &str); 3] = [
        (
            "cut.glb",
            bytes[..bytes.len() - 7].to_vec(),
            "cut.glb: element 'GLB header' #0 at byte 8: glTF: the header declares",
        ),
        (
            "bad-json.glb",
            [&bytes[..20], b"[", &bytes[21..]].concat(),
            "bad-json.glb: element 'JSON' #0 at byte 27 (line 1): glTF: invalid type",
        ),
        (
            "draco.glb",
            draco_glb,
            "not supported, decompress with gltf-transform or gltfpack",
        ),
    ];
    assert_broken_inputs_exit_65(&dir, cases.into());
    std::fs::remove_dir_all(&dir).unwrap();
}
