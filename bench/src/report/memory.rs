//! Section 1, like the paper's Table 3: memory by part of each representation, per mesh kind,
//! with the speed of the ones that trace.
//!
//! ReduceM's parts come from the file's sections ([`reducem::inspect::file_stats`]): vertices are
//! the stored vertices that are not hierarchy copies; strips + strip hierarchies are the rest of
//! the strip data (hierarchy copies, split axes, references: 1 byte each, packed in grid files) plus the strip records; the
//! top level is the node section (4-wide nodes of 128 bytes); header and inter-section padding
//! make up the rest, so the parts sum to the file size. The baseline's parts are its vertex
//! array, its triangle index array and its nodes. The paper's 40-byte row keeps the baseline's
//! tree and replaces indexed triangles and vertices by the precomputed 40-byte intersection
//! format the paper measured against (a computed figure: nothing traces that format here).

use std::collections::BTreeSet;
use std::path::Path;

use super::markdown::{figure, mib, number, Section, Table};
use super::memory_parts::MemoryParts;
use super::plot::{self, Axis, Plot, Series};
use super::speed::{self, Speed};
use super::{Sizes, MEMORY_KINDS};
use crate::baseline::TriangleBvh;
use crate::workload::engines::{Baseline, ReduceM};
use crate::workload::{convert_timed, load_mesh, median_timed, RaySet};
use reducem::conversion::BuildParams;
use reducem::format::reader::ReducemFile;
use reducem::inspect::FileStats;
use reducem::mesh::Mesh;
use reducem::trace::{TraceOptions, Tracer};

/// Bytes per triangle of the paper's precomputed intersection format (Wald 2004).
pub const PAPER_TRIANGLE_BYTES: u64 = 40;
/// Bytes of one f32 position.
const VERTEX_BYTES: u64 = 12;
/// Bytes of one indexed triangle (three u32).
const INDEXED_TRIANGLE_BYTES: u64 = 12;

#[derive(Clone, Debug, PartialEq)]
pub struct MemoryRow {
    pub kind: String,
    pub representation: String,
    /// Input triangles of the mesh: the denominator of bytes/triangle for every row.
    pub triangles: u64,
    pub parts: MemoryParts,
    /// The file size for ReduceM; for the others the sum of the parts.
    pub total_bytes: u64,
    pub build_seconds: Option<f64>,
    pub speed: Option<Speed>,
}

impl MemoryRow {
    pub fn bytes_per_triangle(&self) -> f64 {
        self.total_bytes as f64 / self.triangles.max(1) as f64
    }
}

pub const REDUCEM: &str = "ReduceM";
pub const BASELINE: &str = "baseline BVH, indexed triangles";
pub const PAPER_FORMAT: &str = "BVH + paper's 40-byte triangles";

/// Measures every representation on every kind of [`MEMORY_KINDS`].
pub fn collect(work: &Path, sizes: &Sizes) -> anyhow::Result<Vec<MemoryRow>> {
    let mut rows = Vec::new();
    for kind in MEMORY_KINDS {
        let name = kind.name();
        let mesh = load_mesh(kind, sizes.triangles, work)?;
        let converted = convert_timed(&mesh, &BuildParams::default(), work, name, sizes.runs)?;
        let file = ReducemFile::open(&converted.path)?;
        let rays = RaySet::new(&file, sizes.image, sizes.ao_rays_per_hit);
        let row = |representation: &str, parts: MemoryParts| MemoryRow {
            kind: name.to_string(),
            representation: representation.to_string(),
            triangles: mesh.triangles.len() as u64,
            parts,
            total_bytes: parts.total(),
            build_seconds: None,
            speed: None,
        };
        let reducem = ReduceM(Tracer::new(&file, TraceOptions::default()));
        rows.push(MemoryRow {
            total_bytes: converted.stats.file_bytes,
            build_seconds: Some(converted.build_seconds),
            speed: Some(speed::measure(
                &reducem,
                &rays,
                sizes.runs,
                sizes.min_trace_seconds,
            )),
            ..row(REDUCEM, reducem_parts(&converted.stats))
        });
        let (build_seconds, bvh) = median_timed(sizes.runs, || TriangleBvh::build(&mesh));
        let tree = bvh.memory_bytes()
            - VERTEX_BYTES * mesh.positions.len() as u64
            - INDEXED_TRIANGLE_BYTES * mesh.triangles.len() as u64;
        rows.push(MemoryRow {
            build_seconds: Some(build_seconds),
            speed: Some(speed::measure(
                &Baseline(&bvh),
                &rays,
                sizes.runs,
                sizes.min_trace_seconds,
            )),
            ..row(BASELINE, baseline_parts(&mesh, tree))
        });
        rows.push(row(PAPER_FORMAT, paper_parts(&mesh, tree)));
        drop(bvh);
        rows.extend(embree_rows(&mesh, &rays, sizes, &row));
    }
    Ok(rows)
}

fn reducem_parts(stats: &FileStats) -> MemoryParts {
    let section = |name: &str| stats.bytes_by_section.get(name).copied().unwrap_or(0);
    let vertices = VERTEX_BYTES * (stats.stored_vertices - stats.hierarchy_vertices);
    MemoryParts {
        vertices,
        triangles: section("strip_data") - vertices + section("strip_records"),
        hierarchy: section("top_nodes"),
        other: section("header") + section("padding"),
    }
}

fn baseline_parts(mesh: &Mesh, tree: u64) -> MemoryParts {
    MemoryParts {
        vertices: VERTEX_BYTES * mesh.positions.len() as u64,
        triangles: INDEXED_TRIANGLE_BYTES * mesh.triangles.len() as u64,
        hierarchy: tree,
        other: 0,
    }
}

fn paper_parts(mesh: &Mesh, tree: u64) -> MemoryParts {
    MemoryParts {
        vertices: 0,
        triangles: PAPER_TRIANGLE_BYTES * mesh.triangles.len() as u64,
        hierarchy: tree,
        other: 0,
    }
}

#[cfg(feature = "embree")]
fn embree_rows(
    mesh: &Mesh,
    rays: &RaySet,
    sizes: &Sizes,
    row: &dyn Fn(&str, MemoryParts) -> MemoryRow,
) -> Vec<MemoryRow> {
    [false, true]
        .into_iter()
        .map(|compact| {
            let measured = super::embree_peer::measure(mesh, rays, sizes, compact);
            MemoryRow {
                build_seconds: Some(measured.build_seconds),
                speed: Some(measured.speed),
                ..row(measured.name, measured.parts)
            }
        })
        .collect()
}

#[cfg(not(feature = "embree"))]
fn embree_rows(
    _mesh: &Mesh,
    _rays: &RaySet,
    _sizes: &Sizes,
    _row: &dyn Fn(&str, MemoryParts) -> MemoryRow,
) -> Vec<MemoryRow> {
    Vec::new()
}

pub fn section(rows: &[MemoryRow], plots_dir: &Path) -> anyhow::Result<Section> {
    let mut table = Table::new(vec![
        "mesh",
        "representation",
        "total MiB",
        "B/tri",
        "vertices MiB",
        "triangles or strips + strip hierarchies MiB",
        "top level or tree MiB",
        "header, padding, other MiB",
        "build s",
        "primary Mrays/s",
        "AO Mrays/s",
        "primary hits",
        "AO occluded",
    ]);
    for r in rows {
        let speed = r.speed.as_ref();
        table.push(vec![
            r.kind.clone(),
            r.representation.clone(),
            mib(r.total_bytes),
            format!("{:.2}", r.bytes_per_triangle()),
            mib(r.parts.vertices),
            mib(r.parts.triangles),
            mib(r.parts.hierarchy),
            mib(r.parts.other),
            number(r.build_seconds, 3),
            number(speed.map(|s| s.primary_mrays), 2),
            number(speed.map(|s| s.ao_mrays), 2),
            speed.map_or("–".into(), |s| s.primary_hits.to_string()),
            speed.map_or("–".into(), |s| s.ao_occluded.to_string()),
        ]);
    }
    let plot_path = plot::draw(&speed_plot(rows), plots_dir)?;
    let embree_note = if cfg!(feature = "embree") {
        "Embree 3 rows: memory is what Embree allocated through its device memory monitor \
         (vertex and index buffers under vertices and triangles, BVH and the rest under tree); \
         scene flags default or `RTC_SCENE_FLAG_COMPACT`, single-ray `rtcIntersect1` / \
         `rtcOccluded1`, not robust mode."
    } else {
        "Embree default and compact: not measured (built without the `embree` feature; \
         `scripts/report.sh` turns it on when libembree-dev is installed)."
    };
    let markdown = format!(
        "## 1. Memory (paper Table 3)\n\n\
         Bytes by part per mesh kind, the build time and the speed on the same rays. \
         B/tri divides by the mesh's input triangles for every row. ReduceM's parts sum to the \
         file size. The `{PAPER_FORMAT}` row is computed, not traced: the baseline's tree plus \
         {PAPER_TRIANGLE_BYTES} bytes per triangle, the format the paper compared against. \
         The last two columns say what each engine answered on the same rays, and they should \
         be equal: ReduceM and the baseline accept a hit at `t` in `[tmin, tmax]`, Embree in \
         `(tnear, tfar]`, so only a ray starting exactly on a surface could tell them apart, \
         and AO rays start off the surface they leave (the hit point interpolated on its \
         triangle, pushed along the normal by a few ULPs). {}\n\
         {embree_note}\n\n{}{}",
        agreement(rows),
        table.to_markdown(),
        figure(
            &plot_path,
            "Memory against speed: bytes per triangle (x) and primary-ray Mrays/s (y), one point per mesh kind and representation.",
            "Left is smaller and up is faster: each representation's cloud of points shows what its bytes buy in speed across the mesh kinds.",
        )
    );
    Ok(Section {
        markdown,
        plots: vec![plot_path],
    })
}

/// Whether every traced representation of a kind counted the same hits and occluded rays, and
/// where not, the counts.
fn agreement(rows: &[MemoryRow]) -> String {
    let mut differing = Vec::new();
    for kind in rows.iter().map(|r| &r.kind).collect::<BTreeSet<_>>() {
        let traced: Vec<(&str, Speed)> = rows
            .iter()
            .filter(|r| &r.kind == kind)
            .filter_map(|r| Some((r.representation.as_str(), r.speed?)))
            .collect();
        let alike = |count: fn(&Speed) -> usize| {
            traced
                .windows(2)
                .all(|pair| count(&pair[0].1) == count(&pair[1].1))
        };
        if !alike(|s| s.primary_hits) || !alike(|s| s.ao_occluded) {
            let counts: Vec<String> = traced
                .iter()
                .map(|(name, s)| format!("{name} {}/{}", s.primary_hits, s.ao_occluded))
                .collect();
            differing.push(format!("{kind} ({})", counts.join(", ")));
        }
    }
    if differing.is_empty() {
        return "In this run every engine answered alike on every mesh kind.".into();
    }
    format!(
        "In this run they differ on {} (primary hits/AO occluded), so an engine or the ray \
         setup is wrong there: `bench/examples/bench_trace.rs --check-ao` checks the rays the \
         engines disagree on against the brute force.",
        differing.join("; ")
    )
}

fn speed_plot(rows: &[MemoryRow]) -> Plot {
    let mut series: Vec<Series> = Vec::new();
    for r in rows {
        let Some(speed) = r.speed else { continue };
        let point = (r.bytes_per_triangle(), speed.primary_mrays);
        match series.iter_mut().find(|s| s.label == r.representation) {
            Some(s) => s.points.push(point),
            None => series.push(Series::points(&r.representation, vec![point])),
        }
    }
    Plot {
        file_stem: "memory_vs_speed",
        title: "Memory against primary-ray speed (all mesh kinds)".into(),
        x: Axis::linear("memory (bytes per triangle)"),
        y: Axis::linear("primary rays (Mrays/s)"),
        series,
    }
}
