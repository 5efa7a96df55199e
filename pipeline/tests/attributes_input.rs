//! `[attributes]` on the input side: keys checked like the rest, inputs without the attributes
//! asked for refused before any work, and the chunk stage's chunks carrying global face ids,
//! normals and colours exactly as the whole input read gives them.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use reducem::input::{read_mesh_with, AttributeRequest};
use reducem::mesh::Mesh;

fn temp_dir(name: &str) -> PathBuf {
    let dir =
        std::env::temp_dir().join(format!("pipeline-attributes-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir
}

fn run(config: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pipeline"))
        .args(["run", config.to_str().unwrap()])
        .args(extra)
        .output()
        .expect("run pipeline")
}

fn write_config(dir: &Path, input: &str, attributes: &str) -> PathBuf {
    let path = dir.join("job.toml");
    let body = format!(
        "{input}\n[output]\npath = \"out.rdm\"\n\n[work]\ndir = \"work\"\n\n\
         [chunk]\nmax_triangles = 20\n\n[attributes]\n{attributes}"
    );
    std::fs::write(&path, body).expect("write config");
    path
}

/// Binary PLY: a strip of 12 quads, each with its own vertex copies, the normal turning from
/// quad to quad and colours by corner.
fn quads_ply(path: &Path) {
    let quads = 12u32;
    let mut bytes = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex {}\nproperty float x\n\
         property float y\nproperty float z\nproperty float nx\nproperty float ny\n\
         property float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
         element face {quads}\nproperty list uchar int vertex_indices\nend_header\n",
        4 * quads
    )
    .into_bytes();
    for q in 0..quads {
        let angle = q as f32 * 0.25;
        let normal = [angle.sin(), 0.0, angle.cos()];
        for (corner, [x, y]) in [[0, 0], [1, 0], [1, 1], [0, 1]].into_iter().enumerate() {
            let position = [(q + x) as f32, y as f32, 0.0];
            for value in position.into_iter().chain(normal) {
                bytes.extend_from_slice(&value.to_le_bytes());
            }
            bytes.extend_from_slice(&[q as u8 * 10, corner as u8 * 60, 99]);
        }
    }
    for q in 0..quads {
        bytes.push(4);
        for corner in 0..4 {
            bytes.extend_from_slice(&((4 * q + corner) as i32).to_le_bytes());
        }
    }
    std::fs::write(path, bytes).expect("write ply");
}

/// A triangle's face id and its corners' position and normal bits and colour.
type Record = (u32, Vec<([u32; 3], [u32; 3], [u8; 4])>);

/// Every triangle's record, sorted.
fn records(mesh: &Mesh) -> Vec<Record> {
    let (normals, colors) = (
        mesh.normals.as_ref().unwrap(),
        mesh.colors.as_ref().unwrap(),
    );
    let mut records: Vec<_> = (0..mesh.triangles.len())
        .map(|t| {
            let corners = mesh.triangles[t]
                .iter()
                .map(|&v| {
                    let v = v as usize;
                    let bits = |c: [f32; 3]| c.map(f32::to_bits);
                    (bits(mesh.positions[v]), bits(normals[v]), colors[v])
                })
                .collect();
            (mesh.face_id(t), corners)
        })
        .collect();
    records.sort();
    records
}

#[test]
fn chunk_stage_chunks_carry_global_face_ids_normals_and_colours() {
    let dir = temp_dir("chunks");
    quads_ply(&dir.join("quads.ply"));
    let config = write_config(
        &dir,
        "[input]\npath = \"quads.ply\"\n",
        "face_ids = true\nnormals = \"oct16\"\ncolors = true\n",
    );
    let output = run(&config, &["--stage", "chunk"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let mut chunk_paths: Vec<PathBuf> = std::fs::read_dir(dir.join("work/chunks"))
        .unwrap()
        .map(|entry| entry.unwrap().path())
        .filter(|path| path.to_string_lossy().ends_with(".mesh.zst"))
        .collect();
    chunk_paths.sort();
    assert!(chunk_paths.len() >= 2, "{chunk_paths:?}");
    let mut found = Vec::new();
    for path in &chunk_paths {
        let chunk = pipeline::chunk_io::read_mesh(path).expect("chunk");
        assert!(chunk.face_ids.is_some());
        found.extend(records(&chunk));
    }
    found.sort();
    let request = AttributeRequest {
        normals: true,
        colors: true,
    };
    let whole = read_mesh_with(&dir.join("quads.ply"), request).unwrap();
    assert_eq!(found, records(&whole));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn chunks_without_attributes_asked_for_have_none() {
    let dir = temp_dir("plain-chunks");
    quads_ply(&dir.join("quads.ply"));
    let config = write_config(&dir, "[input]\npath = \"quads.ply\"\n", "");
    assert!(run(&config, &["--stage", "chunk"]).status.success());
    let chunk = pipeline::chunk_io::read_mesh(&dir.join("work/chunks/chunk-000000.mesh.zst"));
    let chunk = chunk.expect("chunk");
    assert_eq!(
        (chunk.face_ids, chunk.normals, chunk.colors),
        (None, None, None)
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn an_input_without_the_attributes_asked_for_is_refused_before_any_work() {
    let dir = temp_dir("missing");
    let mesh = dir.join("plain.ply");
    reducem_gen::generate(reducem_gen::Kind::Sphere, 500, 1, &mesh).unwrap();
    let config = write_config(
        &dir,
        "[input]\npath = \"plain.ply\"\n",
        "normals = \"oct8\"\n",
    );
    let output = run(&config, &[]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(65), "{stderr}");
    assert!(
        stderr.contains("plain.ply")
            && stderr.contains("normals were asked for")
            && stderr.contains("nx, ny, nz"),
        "{stderr}"
    );
    assert!(!dir.join("work").exists(), "work started");

    let config = write_config(
        &dir,
        "[input.generate]\nkind = \"sphere\"\ntriangles = 500\n",
        "colors = true\n",
    );
    let output = run(&config, &[]);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(output.status.code(), Some(78), "{stderr}");
    assert!(stderr.contains("generated meshes"), "{stderr}");
    assert!(!dir.join("work").exists(), "work started");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn attribute_keys_and_values_are_checked_with_line_and_column() {
    let dir = temp_dir("keys");
    for (attributes, expected) in [
        ("normals = \"oct4\"\n", "oct4"),
        ("colours = true\n", "colours"),
        ("face_ids = \"yes\"\n", "face_ids"),
    ] {
        let config = write_config(&dir, "[input]\npath = \"x.ply\"\n", attributes);
        let output = run(&config, &[]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(78), "{stderr}");
        assert!(
            stderr.contains("job.toml") && stderr.contains("line 14") && stderr.contains(expected),
            "{stderr}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn mesh_chunks_round_trip_with_and_without_attributes_and_reject_bad_flags() {
    let dir = temp_dir("chunk-io");
    let path = dir.join("chunk.mesh.zst");
    let full = Mesh {
        positions: vec![[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]],
        triangles: vec![[0, 1, 2], [2, 1, 0]],
        face_ids: Some(vec![7, 4_000_000_000]),
        normals: Some(vec![[0.0, 0.0, 1.0], [0.6, 0.8, 0.0], [-1.0, 0.0, 0.0]]),
        colors: Some(vec![[1, 2, 3, 4], [5, 6, 7, 8], [9, 10, 11, 12]]),
    };
    let only_colors = Mesh {
        face_ids: None,
        normals: None,
        ..full.clone()
    };
    for mesh in [&full, &only_colors] {
        let mut bytes = Vec::new();
        pipeline::chunk_io::write_mesh(&mut bytes, mesh).unwrap();
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(&pipeline::chunk_io::read_mesh(&path).unwrap(), mesh);
    }
    // Raw (decompressed) chunk bytes with one change each, recompressed.
    let mut raw = Vec::new();
    let mut bytes = Vec::new();
    pipeline::chunk_io::write_mesh(&mut bytes, &full).unwrap();
    zstd::stream::copy_decode(&bytes[..], &mut raw).unwrap();
    let unknown_flag = {
        let mut raw = raw.clone();
        raw[24] |= 8;
        raw
    };
    let short = raw[..raw.len() - 4].to_vec();
    for corrupt in [unknown_flag, short] {
        std::fs::write(&path, zstd::encode_all(&corrupt[..], 1).unwrap()).unwrap();
        let error = pipeline::chunk_io::read_mesh(&path).unwrap_err();
        assert!(error.to_string().contains("not a mesh chunk"), "{error}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn attribute_keys_map_into_the_build_parameters() {
    use reducem::format::attributes::AttributeSet;
    use reducem::format::attributes::NormalEncoding;
    let parse = |attributes: &str| {
        let text = format!(
            "[input]\npath = \"x.ply\"\n[output]\npath = \"x.rdm\"\n[attributes]\n{attributes}"
        );
        pipeline::config::Config::parse(Path::new("job.toml"), &text)
            .unwrap()
            .build_params()
            .attributes
    };
    assert_eq!(parse(""), AttributeSet::default());
    assert_eq!(
        parse("face_ids = true\nnormals = \"oct8\"\n"),
        AttributeSet {
            face_ids: true,
            normals: NormalEncoding::Oct8,
            colors: false,
        }
    );
    assert_eq!(
        parse("normals = \"oct16\"\ncolors = true\n"),
        AttributeSet {
            face_ids: false,
            normals: NormalEncoding::Oct16,
            colors: true,
        }
    );
    assert_eq!(parse("normals = \"none\"\n").normals, NormalEncoding::None);
}

/// The whole job on the quads with every attribute: each stored triangle's face id names the
/// input quad whose corners it has, each corner keeps that quad vertex's colour exactly and its
/// normal within the oct16 bound.
#[test]
fn a_staged_file_keeps_each_triangles_input_face_and_its_corners_attributes() {
    let dir = temp_dir("end-to-end");
    let input = dir.join("quads.ply");
    quads_ply(&input);
    let config = write_config(
        &dir,
        "[input]\npath = \"quads.ply\"\n",
        "face_ids = true\nnormals = \"oct16\"\ncolors = true\n",
    );
    let output = run(&config, &[]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let request = AttributeRequest {
        normals: true,
        colors: true,
    };
    let whole = read_mesh_with(&input, request).unwrap();
    let (normals, colors) = (whole.normals.unwrap(), whole.colors.unwrap());
    let file = reducem::format::reader::ReducemFile::open(&dir.join("out.rdm")).expect("open");
    let mut faces_seen = Vec::new();
    for s in 0..file.strip_count() {
        let view = file.strip(s);
        let stored = file.vertex_attributes(s).expect("vertex attributes");
        let references = view.references.to_vec();
        let points: Vec<[f32; 3]> = view.vertices.iter().collect();
        for k in 0..view.window_count() {
            let Some(triangle) = reducem::strip_windows::window_triangle(&references, k) else {
                continue;
            };
            let face = file.face_id(s, k).expect("face id") as usize;
            faces_seen.push(face);
            for r in triangle {
                let r = r as usize;
                // The quad's own vertex at this corner: its four copies are 4·face..4·face+4.
                let vertex = (4 * face..4 * face + 4)
                    .find(|&v| whole.positions[v] == points[r])
                    .unwrap_or_else(|| panic!("face {face} has no corner at {:?}", points[r]));
                assert_eq!(stored.color(r), Some(colors[vertex]));
                let normal = stored.normal(r).expect("normal");
                let cos = (0..3).map(|a| normal[a] * normals[vertex][a]).sum::<f32>();
                assert!(cos.min(1.0).acos().to_degrees() < 0.01, "{normal:?}");
            }
        }
    }
    faces_seen.sort();
    let expected: Vec<usize> = (0..12).flat_map(|q| [q, q]).collect();
    assert_eq!(faces_seen, expected);
    let _ = std::fs::remove_dir_all(&dir);
}

/// `convert` settings (the Python package's keyword arguments) reach `[attributes]`.
#[test]
fn convert_settings_set_the_attributes() {
    use pipeline::convert::{convert, ConvertArgs};
    use pipeline::run::{IfLocked, RunOptions, Shard};
    let dir = temp_dir("convert");
    quads_ply(&dir.join("quads.ply"));
    let args = ConvertArgs {
        input: dir.join("quads.ply"),
        output: dir.join("quads.rdm"),
        max_length: None,
        encoding: None,
        grid_bits: None,
        work: Some(dir.join("work")),
        settings: vec![
            ("face_ids".into(), "true".into()),
            ("normals".into(), "\"oct8\"".into()),
            ("colors".into(), "true".into()),
        ],
    };
    let options = RunOptions {
        log_format: pipeline::progress::LogFormat::Plain,
        clean_after: false,
        if_locked: IfLocked::Fail,
        stage: None,
        shard: Shard::WHOLE,
    };
    convert(&args, &options).expect("convert");
    let config = std::fs::read_to_string(dir.join("work/convert.toml")).unwrap();
    assert!(
        config.contains("[attributes]\nface_ids = true\nnormals = \"oct8\"\ncolors = true\n"),
        "{config}"
    );
    let file = reducem::format::reader::ReducemFile::open(&dir.join("quads.rdm")).expect("open");
    let attributes = file.attributes();
    assert!(attributes.face_ids && attributes.colors);
    assert_eq!(
        attributes.normals,
        reducem::format::attributes::NormalEncoding::Oct8
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// With attributes, a job killed after its chunk stage resumes to the same bytes as one run
/// through, for any thread count.
#[test]
fn jobs_with_attributes_resume_to_byte_identical_files_for_any_thread_count() {
    let outputs: Vec<Vec<u8>> = [("1", true), ("2", false)]
        .into_iter()
        .map(|(threads, in_two_runs)| {
            let dir = temp_dir(&format!("identical-{threads}"));
            quads_ply(&dir.join("quads.ply"));
            let config = write_config(
                &dir,
                "[input]\npath = \"quads.ply\"\n",
                "face_ids = true\nnormals = \"oct16\"\ncolors = true\n",
            );
            let run_with = |extra: &[&str]| {
                let output = Command::new(env!("CARGO_BIN_EXE_pipeline"))
                    .args(["run", config.to_str().unwrap()])
                    .args(extra)
                    .env("RAYON_NUM_THREADS", threads)
                    .output()
                    .expect("run pipeline");
                assert!(
                    output.status.success(),
                    "{}",
                    String::from_utf8_lossy(&output.stderr)
                );
            };
            if in_two_runs {
                run_with(&["--stage", "chunk"]);
            }
            run_with(&[]);
            let bytes = std::fs::read(dir.join("out.rdm")).expect("output");
            let _ = std::fs::remove_dir_all(&dir);
            bytes
        })
        .collect();
    assert_eq!(outputs[0], outputs[1]);
}

/// `pipeline convert --face-ids --normals oct8 --colors` stores what the flags name, and
/// without them nothing.
#[test]
fn convert_flags_store_the_attributes_they_name() {
    let dir = temp_dir("convert-flags");
    let input = dir.join("quads.ply");
    quads_ply(&input);
    let convert = |output: &str, flags: &[&str]| {
        let result = Command::new(env!("CARGO_BIN_EXE_pipeline"))
            .args(["convert", input.to_str().unwrap(), "-o"])
            .arg(dir.join(output))
            .args(flags)
            .output()
            .expect("run pipeline");
        assert!(
            result.status.success(),
            "{}",
            String::from_utf8_lossy(&result.stderr)
        );
        reducem::format::reader::ReducemFile::open(&dir.join(output)).expect("open")
    };
    let with = convert("with.rdm", &["--face-ids", "--normals", "oct8", "--colors"]);
    let stored = with.attributes();
    assert!(stored.face_ids && stored.colors);
    assert_eq!(
        stored.normals,
        reducem::format::attributes::NormalEncoding::Oct8
    );
    let without = convert("without.rdm", &[]);
    assert!(!without.attributes().any());
    assert_eq!(without.header().version_major, 4);
    let _ = std::fs::remove_dir_all(&dir);
}
