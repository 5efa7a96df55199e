//! Section 2, like the paper's Table 2: Strip-RT against a rasterization stripifier under the
//! same encoding.
//!
//! The peer is meshoptimizer's stripifier (the `meshopt` crate), run the way a rasterizer would:
//! vertex-cache optimization first, then `stripify` with restart indices. Its strips are turned
//! into this project's convention ([`reducem::strip_windows`]) and then encoded, given a top level and
//! written exactly as Strip-RT's ([`reducem::conversion::encode_stripification`],
//! [`reducem::conversion::write_chunk`]). The conventions agree within a restart-delimited strip:
//! meshoptimizer's window `k` is `(s[k], s[k+1], s[k+2])`, odd windows flipped, windows with a
//! repeated index skipped (its swaps), so only the restarts and the length limit need work:
//! strips are cut at restarts, then into pieces of at most `max_length` triangles. A piece that
//! would start at an odd window gets its first reference repeated in front (one swap window), so
//! every window keeps its parity and every triangle its input winding.

use std::path::Path;
use std::time::Instant;

use super::markdown::{figure, number, Section, Table};
use super::plot::{self, Axis, Plot, Series};
use super::speed::{self, Speed};
use super::{Sizes, MEMORY_KINDS};
use crate::workload::engines::ReduceM;
use crate::workload::{convert_timed, load_mesh, RaySet};
use reducem::conversion::{encode_stripification, write_chunk, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::inspect::{file_stats, FileStats};
use reducem::mesh::Mesh;
use reducem::strip_windows::{window_count, window_triangle};
use reducem::stripify::adjacency::is_dropped;
use reducem::stripify::Stripification;
use reducem::trace::{TraceOptions, Tracer};

/// meshoptimizer's restart index for 32-bit indices.
const RESTART: u32 = u32::MAX;

pub const STRIP_RT: &str = "Strip-RT";
pub const MESHOPT: &str = "meshoptimizer stripify";

#[derive(Clone, Debug, PartialEq)]
pub struct StripifierRow {
    pub kind: String,
    pub stripifier: &'static str,
    pub stats: FileStats,
    pub build_seconds: f64,
    pub speed: Speed,
}

/// Strips of `mesh` from meshoptimizer, in this project's convention, at most `max_length`
/// triangles each; degenerate triangles are dropped first, as Strip-RT drops them.
pub fn meshopt_stripification(mesh: &Mesh, max_length: usize) -> Stripification {
    let kept: Vec<&[u32; 3]> = mesh
        .triangles
        .iter()
        .filter(|t| !is_dropped(mesh, t))
        .collect();
    let indices: Vec<u32> = kept.iter().flat_map(|t| t.iter().copied()).collect();
    let vertex_count = mesh.positions.len();
    let cache_ordered = meshopt::optimize_vertex_cache(&indices, vertex_count);
    let stripped = meshopt::stripify(&cache_ordered, vertex_count, RESTART)
        .expect("meshopt_stripifyBound bounds the output");
    let strips: Vec<Vec<u32>> = stripped
        .split(|&i| i == RESTART)
        .flat_map(|strip| limit_length(strip, max_length.max(1)))
        .collect();
    Stripification {
        triangles: reducem::stripify::match_triangles(mesh, &strips),
        strips,
        dropped_triangles: (mesh.triangles.len() - kept.len()) as u64,
    }
}

/// Cuts a strip into pieces of at most `max_length` real triangles, every window keeping its
/// parity; pieces start and end at real triangles.
pub fn limit_length(strip: &[u32], max_length: usize) -> Vec<Vec<u32>> {
    let real: Vec<usize> = (0..window_count(strip.len()))
        .filter(|&k| window_triangle(strip, k).is_some())
        .collect();
    real.chunks(max_length)
        .map(|windows| {
            let (first, last) = (windows[0], windows[windows.len() - 1]);
            let mut piece = Vec::with_capacity(last - first + 4);
            if first % 2 == 1 {
                piece.push(strip[first]);
            }
            piece.extend_from_slice(&strip[first..last + 3]);
            piece
        })
        .collect()
}

/// Converts `mesh` through meshoptimizer's strips; the median build time over `runs`.
fn convert_meshopt(
    mesh: &Mesh,
    params: &BuildParams,
    out: &Path,
    runs: usize,
) -> anyhow::Result<(FileStats, f64)> {
    let mut times = Vec::new();
    for _ in 0..runs.max(1) {
        let started = Instant::now();
        let stripification = meshopt_stripification(mesh, params.stripify.max_length);
        let chunk = encode_stripification(mesh, &stripification, params.leaf_windows);
        write_chunk(&chunk, params, out)?;
        times.push(started.elapsed().as_secs_f64());
    }
    times.sort_by(f64::total_cmp);
    let stats = file_stats(&ReducemFile::open(out)?);
    Ok((stats, times[times.len() / 2]))
}

/// Both stripifiers on every kind of [`MEMORY_KINDS`], paper parameters (60, leaf 2).
pub fn collect(work: &Path, sizes: &Sizes) -> anyhow::Result<Vec<StripifierRow>> {
    let params = BuildParams::default();
    let mut rows = Vec::new();
    for kind in MEMORY_KINDS {
        let name = kind.name();
        let mesh = load_mesh(kind, sizes.triangles, work)?;
        let strip_rt = convert_timed(&mesh, &params, work, name, sizes.runs)?;
        let meshopt_path = work.join(format!("{name}-meshopt.rdm"));
        let (meshopt_stats, meshopt_seconds) =
            convert_meshopt(&mesh, &params, &meshopt_path, sizes.runs)?;
        let strip_rt_file = ReducemFile::open(&strip_rt.path)?;
        let rays = RaySet::new(&strip_rt_file, sizes.image, sizes.ao_rays_per_hit);
        let meshopt_file = ReducemFile::open(&meshopt_path)?;
        for (stripifier, file, stats, build_seconds) in [
            (
                STRIP_RT,
                &strip_rt_file,
                strip_rt.stats,
                strip_rt.build_seconds,
            ),
            (MESHOPT, &meshopt_file, meshopt_stats, meshopt_seconds),
        ] {
            let engine = ReduceM(Tracer::new(file, TraceOptions::default()));
            rows.push(StripifierRow {
                kind: name.to_string(),
                stripifier,
                stats,
                build_seconds,
                speed: speed::measure(&engine, &rays, sizes.runs, sizes.min_trace_seconds),
            });
        }
    }
    Ok(rows)
}

pub fn section(rows: &[StripifierRow], plots_dir: &Path) -> anyhow::Result<Section> {
    let mut table = Table::new(vec![
        "mesh",
        "stripifier",
        "avg strip length",
        "strips",
        "B/tri",
        "hierarchy overhead %",
        "build s",
        "primary Mrays/s",
        "AO Mrays/s",
        "primary hits",
    ]);
    for r in rows {
        table.push(vec![
            r.kind.clone(),
            r.stripifier.to_string(),
            format!("{:.2}", r.stats.avg_strip_length),
            r.stats.strips.to_string(),
            format!("{:.2}", r.stats.bytes_per_triangle),
            format!("{:.2}", r.stats.hierarchy_overhead_pct),
            number(Some(r.build_seconds), 3),
            format!("{:.2}", r.speed.primary_mrays),
            format!("{:.2}", r.speed.ao_mrays),
            r.speed.primary_hits.to_string(),
        ]);
    }
    let plot_path = plot::draw(&plot(rows), plots_dir)?;
    let markdown = format!(
        "## 2. Stripifier (paper Table 2)\n\n\
         Strip-RT against meshoptimizer's rasterization stripifier (vertex-cache order, then \
         `meshopt::stripify`; its strips cut at restarts and at 60 triangles), both encoded, \
         given a top level and written by the same code with the paper's parameters (at most \
         60 triangles per strip, leaf 2). B/tri is the file size over stored triangles; \
         hierarchy overhead is the stored copies that exist only for the strip hierarchies, as \
         % of input vertices (the paper's Table 1 metric). Build time covers stripification, \
         encoding, top level and writing (median of the runs). The primary hit counts agree \
         because both files hold the same triangles.\n\n{}{}",
        table.to_markdown(),
        figure(
            &plot_path,
            "Stripifiers: bytes per triangle (x) against primary-ray Mrays/s (y), one point per mesh kind and stripifier.",
            "Up is faster and left is smaller; both files hold the same triangles in the same encoding, so any gap comes from how the triangles were grouped into strips.",
        )
    );
    Ok(Section {
        markdown,
        plots: vec![plot_path],
    })
}

fn plot(rows: &[StripifierRow]) -> Plot {
    let series = [STRIP_RT, MESHOPT]
        .map(|stripifier| {
            let points = rows
                .iter()
                .filter(|r| r.stripifier == stripifier)
                .map(|r| (r.stats.bytes_per_triangle, r.speed.primary_mrays))
                .collect();
            Series::points(stripifier, points)
        })
        .to_vec();
    Plot {
        file_stem: "stripifier",
        title: "Strip-RT against meshoptimizer's stripifier (all mesh kinds)".into(),
        x: Axis::linear("memory (bytes per triangle)"),
        y: Axis::linear("primary rays (Mrays/s)"),
        series,
    }
}
