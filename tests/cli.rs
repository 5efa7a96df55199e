//! The `reducem` command-line contract: `inspect --json` keys and consistency (the precision
//! keys included), `decode` output for lossless and grid files.

mod common;

use std::process::Command;

use common::{canonical_sorted, expected_triangles, quantized_input, temp_path, torus};
use reducem::build::{convert_mesh, BuildParams};
use reducem::geometry::distance;
use reducem::input::read_mesh;

fn reducem(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_reducem"))
        .args(args)
        .output()
        .expect("run reducem")
}

#[test]
fn inspect_json_has_the_contract_keys_and_adds_up() {
    let mesh = torus(40, 20);
    let path = temp_path("cli-inspect.rdm");
    convert_mesh(&mesh, &BuildParams::default(), &path).expect("convert");
    let output = reducem(&["inspect", path.to_str().unwrap(), "--json", "--verify"]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let stats: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    for key in [
        "triangles",
        "dropped_triangles",
        "strips",
        "input_vertices",
        "stored_vertices",
        "file_bytes",
        "bytes_per_triangle",
        "bytes_by_section",
        "hierarchy_overhead_pct",
        "avg_strip_length",
        "max_strip_length",
    ] {
        assert!(stats.get(key).is_some(), "missing key {key}");
    }
    assert_eq!(stats["triangles"], 1600);
    assert_eq!(stats["input_vertices"], 800);
    let file_bytes = std::fs::metadata(&path).unwrap().len();
    assert_eq!(stats["file_bytes"], file_bytes);
    let section_sum: u64 = stats["bytes_by_section"]
        .as_object()
        .unwrap()
        .values()
        .map(|v| v.as_u64().unwrap())
        .sum();
    assert_eq!(section_sum, file_bytes);
    assert!(stats["max_strip_length"].as_u64().unwrap() <= 60);
}

#[test]
fn decode_writes_the_input_triangles_as_ply() {
    let mesh = torus(30, 12);
    let path = temp_path("cli-decode.rdm");
    let ply = temp_path("cli-decode.ply");
    convert_mesh(&mesh, &BuildParams::default(), &path).expect("convert");
    let output = reducem(&[
        "decode",
        path.to_str().unwrap(),
        "-o",
        ply.to_str().unwrap(),
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let decoded = read_mesh(&ply).expect("decoded PLY reads back");
    let decoded_triangles = decoded.triangles.iter().map(|t| decoded.triangle_points(t));
    assert_eq!(
        canonical_sorted(decoded_triangles),
        expected_triangles(&mesh)
    );
}

#[test]
fn a_corrupt_file_is_an_error_naming_it() {
    let path = temp_path("cli-corrupt.rdm");
    std::fs::write(&path, b"not a reducem file").unwrap();
    let output = reducem(&["inspect", path.to_str().unwrap()]);
    assert!(!output.status.success());
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(
        stderr.contains("cli-corrupt.rdm") && stderr.contains("header"),
        "{stderr}"
    );
}

#[test]
fn inspect_json_reports_the_grid_and_the_position_error() {
    let mesh = torus(40, 20);
    let path = temp_path("cli-inspect-grid.rdm");
    let params = BuildParams {
        grid_bits: Some(16),
        ..BuildParams::default()
    };
    convert_mesh(&mesh, &params, &path).expect("convert");
    let output = reducem(&["inspect", path.to_str().unwrap(), "--json", "--verify"]);
    assert!(output.status.success());
    let stats: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    let (quantized, grid) = quantized_input(&mesh, 16);
    let largest = mesh
        .positions
        .iter()
        .zip(&quantized.positions)
        .map(|(p, q)| distance(p, q))
        .fold(0.0, f64::max);
    assert_eq!(stats["format_version"], "2.3");
    assert_eq!(stats["vertex_encoding"], "grid");
    assert_eq!(stats["top_node_bytes"], 64);
    assert_eq!(stats["grid_bits"], 16);
    assert_eq!(
        stats["grid_cell"].as_f64().map(|c| c as f32),
        Some(grid.cell)
    );
    assert_eq!(stats["position_error_max"].as_f64(), Some(largest));
    let diagonal = stats["bounds_diagonal"].as_f64().unwrap();
    assert_eq!(
        stats["position_error_max_relative"].as_f64(),
        Some(largest / diagonal)
    );
    assert!(stats["position_error_rms"].as_f64().unwrap() <= largest);
    assert_eq!(stats["weld_tolerance"], 0.0);
    assert_eq!(stats["welded_vertices"], 0);

    let lossless = temp_path("cli-inspect-f32.rdm");
    convert_mesh(&mesh, &BuildParams::default(), &lossless).expect("convert");
    let output = reducem(&["inspect", lossless.to_str().unwrap(), "--json"]);
    let stats: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    assert_eq!(stats["vertex_encoding"], "f32");
    assert_eq!(stats["format_version"], "2.1");
    assert_eq!(stats["top_node_bytes"], 128);
    assert_eq!(stats["grid_bits"], 0);
    assert_eq!(stats["position_error_max"], 0.0);

    let grid_nodes = temp_path("cli-inspect-f32-grid-nodes.rdm");
    let params = BuildParams {
        grid_nodes: true,
        ..BuildParams::default()
    };
    convert_mesh(&mesh, &params, &grid_nodes).expect("convert");
    let output = reducem(&["inspect", grid_nodes.to_str().unwrap(), "--json"]);
    let stats: serde_json::Value = serde_json::from_slice(&output.stdout).expect("one JSON object");
    assert_eq!(stats["vertex_encoding"], "f32");
    assert_eq!(stats["format_version"], "2.4");
    assert_eq!(stats["top_node_bytes"], 64);
}

#[test]
fn decode_writes_the_quantized_triangles_of_a_grid_file() {
    let mesh = torus(30, 12);
    let path = temp_path("cli-decode-grid.rdm");
    let ply = temp_path("cli-decode-grid.ply");
    let params = BuildParams {
        grid_bits: Some(12),
        ..BuildParams::default()
    };
    convert_mesh(&mesh, &params, &path).expect("convert");
    let output = reducem(&[
        "decode",
        path.to_str().unwrap(),
        "-o",
        ply.to_str().unwrap(),
    ]);
    assert!(output.status.success());
    let decoded = read_mesh(&ply).expect("decoded PLY reads back");
    let decoded_triangles = decoded.triangles.iter().map(|t| decoded.triangle_points(t));
    let (quantized, _) = quantized_input(&mesh, 12);
    assert_eq!(
        canonical_sorted(decoded_triangles),
        expected_triangles(&quantized)
    );
}
