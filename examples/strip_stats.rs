//! Strip-RT quality and cost report: swaps per triangle, average strip length, stripify time and
//! peak memory for one mesh.
//!
//! `cargo run --release --example strip_stats -- <scan|terrain|grid|torus> <triangles> [threads]`
//!
//! `scan` and `terrain` are written once by `reducem_gen` to the temp dir and read back; `grid`
//! and `torus` are built in memory by the integration tests' builders. Peak memory is the
//! process's high-water mark (`VmHWM`), printed before and after stripification so the part
//! that stripification adds beyond the mesh can be read off (run it under `/usr/bin/time -v`
//! for an outside view).

#[path = "../tests/common/mod.rs"]
mod common;

use std::time::Instant;

use reducem::mesh::Mesh;
use reducem::stripify::{stripify, StripifyParams};
use reducem_gen::Kind;

fn generated(kind: Kind, triangles: u64) -> Mesh {
    let name = format!("{kind:?}").to_lowercase();
    let path = std::env::temp_dir().join(format!("strip_stats_{name}_{triangles}.ply"));
    if !path.exists() {
        reducem_gen::generate(kind, triangles, 1, &path).expect("generate mesh");
    }
    reducem::input::read_mesh(&path).expect("read generated mesh")
}

fn mesh(kind: &str, triangles: u64) -> Mesh {
    let quads_per_side = ((triangles / 2) as f64).sqrt().round().max(1.0) as u32;
    match kind {
        "scan" => generated(Kind::Scan, triangles),
        "terrain" => generated(Kind::Terrain, triangles),
        "grid" => common::grid(quads_per_side, quads_per_side),
        "torus" => common::torus(2 * quads_per_side, quads_per_side / 2),
        other => panic!("unknown mesh kind {other}"),
    }
}

/// Peak resident set size of this process in MiB, from `/proc/self/status` (Linux).
fn peak_rss_mib() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|line| line.strip_prefix("VmHWM:"))
        .and_then(|rest| {
            rest.trim()
                .trim_end_matches("kB")
                .trim()
                .parse::<f64>()
                .ok()
        })
        .map_or(f64::NAN, |kib| kib / 1024.0)
}

fn main() {
    let mut args = std::env::args().skip(1);
    let kind = args.next().unwrap_or_else(|| "scan".into());
    let triangles: u64 = args
        .next()
        .map_or(200_000, |n| n.parse().expect("triangle count"));
    let threads: usize = args.next().map_or(0, |n| n.parse().expect("thread count"));
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .expect("thread pool");
    let mesh = mesh(&kind, triangles);
    let peak_before = peak_rss_mib();
    let start = Instant::now();
    let result = stripify(&mesh, &StripifyParams::default());
    let seconds = start.elapsed().as_secs_f64();
    let peak_after = peak_rss_mib();
    let real = result.triangle_count();
    let windows: usize = result
        .strips
        .iter()
        .map(|s| reducem::strip_windows::window_count(s.len()))
        .sum();
    println!(
        "{kind} {real} triangles: {} strips, average length {:.2}, windows/triangle {:.4}, \
         swaps/triangle {:.4}, stripify {seconds:.2} s, peak RSS {peak_before:.0} → {peak_after:.0} MiB \
         ({:.1} B/triangle beyond the earlier peak)",
        result.strips.len(),
        result.average_strip_length(),
        windows as f64 / real as f64,
        (windows - real) as f64 / real as f64,
        (peak_after - peak_before) * 1024.0 * 1024.0 / real as f64,
    );
}
