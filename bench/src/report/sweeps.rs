//! Sections 3 to 5: build parameters and traversal options against bytes, build time and speed,
//! on one mesh ([`super::SWEEP_KIND`]) and one ray set.
//!
//! 3. Maximum strip length, like the paper's Fig. 5 (which went from 4 to 64 on Lucy).
//! 4. Strip kd-tree leaf size (a build parameter) × subtree intersection size (a traversal
//!    option: intervals of at most that many windows are intersected at once).
//! 5. SAH bins of Strip-RT's partition (timed as the whole conversion, which it dominates) and of
//!    the top level (timed as the top-level build alone, which is all it changes). Neither
//!    builder has a full-sweep SAH option, so only binned SAH is measured.

use std::path::Path;

use super::markdown::{figure, Section, Table};
use super::plot::{self, Axis, Plot, Series};
use super::speed::{self, Speed};
use super::Sizes;
use crate::workload::engines::ReduceM;
use crate::workload::{convert_timed, median_timed, Converted, RaySet};
use reducem::conversion::{encode_chunk, strip_bounds, write_chunk, BuildParams};
use reducem::format::reader::ReducemFile;
use reducem::inspect::{file_stats, FileStats};
use reducem::mesh::Mesh;
use reducem::toplevel;
use reducem::trace::{TraceOptions, Tracer};

pub const STRIP_LENGTHS: [usize; 7] = [4, 8, 16, 32, 60, 64, 128];
pub const LEAF_SIZES: [usize; 5] = [1, 2, 4, 8, 16];
pub const SUBTREE_SIZES: [usize; 6] = [1, 2, 4, 8, 16, 32];
pub const SAH_BINS: [usize; 6] = [2, 4, 8, 16, 32, 64];

pub const PARTITION_BINS: &str = "Strip-RT partition bins (whole conversion timed)";
pub const TOP_LEVEL_BINS: &str = "top-level bins (top-level build timed)";

/// The mesh of the sweeps and the rays every variant of it is traced with.
pub struct Subject {
    pub mesh: Mesh,
    pub rays: RaySet,
}

impl Subject {
    /// Converts `mesh` with the paper's parameters once, to make the rays.
    pub fn new(mesh: Mesh, work: &Path, sizes: &Sizes) -> anyhow::Result<Subject> {
        let converted = convert_timed(&mesh, &BuildParams::default(), work, "sweep-default", 1)?;
        let file = ReducemFile::open(&converted.path)?;
        let rays = RaySet::new(&file, sizes.image, sizes.ao_rays_per_hit);
        Ok(Subject { mesh, rays })
    }

    /// Converts with `params` and measures the file with `options`.
    pub(super) fn measure(
        &self,
        params: &BuildParams,
        options: TraceOptions,
        work: &Path,
        sizes: &Sizes,
    ) -> anyhow::Result<(Converted, Speed)> {
        self.measure_mesh(&self.mesh, params, options, work, sizes)
    }

    /// [`Subject::measure`] for a variant of the mesh, traced with the same rays.
    pub(super) fn measure_mesh(
        &self,
        mesh: &Mesh,
        params: &BuildParams,
        options: TraceOptions,
        work: &Path,
        sizes: &Sizes,
    ) -> anyhow::Result<(Converted, Speed)> {
        let converted = convert_timed(mesh, params, work, "sweep", sizes.runs)?;
        let speed = self.speed(&converted.path, options, sizes)?;
        Ok((converted, speed))
    }

    fn speed(&self, file: &Path, options: TraceOptions, sizes: &Sizes) -> anyhow::Result<Speed> {
        let file = ReducemFile::open(file)?;
        let engine = ReduceM(Tracer::new(&file, options));
        Ok(speed::measure(
            &engine,
            &self.rays,
            sizes.runs,
            sizes.min_trace_seconds,
        ))
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct StripLengthRow {
    pub max_length: usize,
    pub stats: FileStats,
    pub build_seconds: f64,
    pub speed: Speed,
}

pub fn strip_lengths(
    subject: &Subject,
    work: &Path,
    sizes: &Sizes,
) -> anyhow::Result<Vec<StripLengthRow>> {
    STRIP_LENGTHS
        .iter()
        .map(|&max_length| {
            let mut params = BuildParams::default();
            params.stripify.max_length = max_length;
            let (converted, speed) =
                subject.measure(&params, TraceOptions::default(), work, sizes)?;
            Ok(StripLengthRow {
                max_length,
                stats: converted.stats,
                build_seconds: converted.build_seconds,
                speed,
            })
        })
        .collect()
}

#[derive(Clone, Debug, PartialEq)]
pub struct LeafSubtreeRow {
    pub leaf_windows: usize,
    pub subtree_windows: usize,
    pub bytes_per_triangle: f64,
    pub speed: Speed,
}

pub fn leaf_subtree(
    subject: &Subject,
    work: &Path,
    sizes: &Sizes,
) -> anyhow::Result<Vec<LeafSubtreeRow>> {
    let mut rows = Vec::new();
    for leaf_windows in LEAF_SIZES {
        let params = BuildParams {
            leaf_windows,
            ..BuildParams::default()
        };
        let converted = convert_timed(&subject.mesh, &params, work, "sweep", 1)?;
        for subtree_windows in SUBTREE_SIZES {
            let options = TraceOptions {
                subtree_windows,
                ..TraceOptions::default()
            };
            rows.push(LeafSubtreeRow {
                leaf_windows,
                subtree_windows,
                bytes_per_triangle: converted.stats.bytes_per_triangle,
                speed: subject.speed(&converted.path, options, sizes)?,
            });
        }
    }
    Ok(rows)
}

#[derive(Clone, Debug, PartialEq)]
pub struct SahRow {
    pub hierarchy: &'static str,
    pub bins: usize,
    pub build_seconds: f64,
    pub bytes_per_triangle: f64,
    pub speed: Speed,
}

pub fn sah_bins(subject: &Subject, work: &Path, sizes: &Sizes) -> anyhow::Result<Vec<SahRow>> {
    let mut rows = Vec::new();
    for bins in SAH_BINS {
        let mut params = BuildParams::default();
        params.stripify.sah_bins = bins;
        let (converted, speed) = subject.measure(&params, TraceOptions::default(), work, sizes)?;
        rows.push(SahRow {
            hierarchy: PARTITION_BINS,
            bins,
            build_seconds: converted.build_seconds,
            bytes_per_triangle: converted.stats.bytes_per_triangle,
            speed,
        });
    }
    let chunk = encode_chunk(&subject.mesh, &BuildParams::default());
    let bounds = strip_bounds(&chunk.strips);
    let path = work.join("sweep-top.rdm");
    for bins in SAH_BINS {
        let mut params = BuildParams::default();
        params.top_level.bins = bins;
        let (build_seconds, _) =
            median_timed(sizes.runs, || toplevel::build(&bounds, &params.top_level));
        write_chunk(&chunk, &params, &path)?;
        rows.push(SahRow {
            hierarchy: TOP_LEVEL_BINS,
            bins,
            build_seconds,
            bytes_per_triangle: file_stats(&ReducemFile::open(&path)?).bytes_per_triangle,
            speed: subject.speed(&path, TraceOptions::default(), sizes)?,
        });
    }
    Ok(rows)
}

pub fn strip_length_section(rows: &[StripLengthRow], plots_dir: &Path) -> anyhow::Result<Section> {
    let mut table = Table::new(vec![
        "max strip length",
        "avg strip length",
        "B/tri",
        "hierarchy overhead %",
        "build s",
        "primary Mrays/s",
        "AO Mrays/s",
    ]);
    for r in rows {
        table.push(vec![
            r.max_length.to_string(),
            format!("{:.2}", r.stats.avg_strip_length),
            format!("{:.2}", r.stats.bytes_per_triangle),
            format!("{:.2}", r.stats.hierarchy_overhead_pct),
            format!("{:.3}", r.build_seconds),
            format!("{:.2}", r.speed.primary_mrays),
            format!("{:.2}", r.speed.ao_mrays),
        ]);
    }
    let x = || Axis::log2("maximum strip length (triangles, log scale)");
    let bytes = Plot {
        file_stem: "strip_length_bytes",
        title: "Maximum strip length against memory and build time".into(),
        x: x(),
        y: Axis::linear("bytes per triangle (B)"),
        series: vec![Series::line(
            "file bytes per triangle",
            rows.iter()
                .map(|r| (r.max_length as f64, r.stats.bytes_per_triangle))
                .collect(),
        )],
    };
    let speed = Plot {
        file_stem: "strip_length_speed",
        title: "Maximum strip length against speed".into(),
        x: x(),
        y: Axis::linear("rays per second (Mrays/s)"),
        series: speed_series(rows.iter().map(|r| (r.max_length as f64, r.speed))),
    };
    let bytes_path = plot::draw(&bytes, plots_dir)?;
    let speed_path = plot::draw(&speed, plots_dir)?;
    let markdown = format!(
        "## 3. Strip length (paper Fig. 5)\n\n\
         The sweep mesh converted with each maximum strip length (leaf 2, 16 bins); build time \
         is the whole conversion (median of the runs).\n\n{}{}{}",
        table.to_markdown(),
        figure(
            &bytes_path,
            "Memory against the maximum strip length: file bytes per triangle (y) for limits 4 to 128 triangles (x, log scale).",
            "Longer strips share more vertices and need fewer strip records and top-level nodes, until few strips reach the limit (compare the average length in the table).",
        ),
        figure(
            &speed_path,
            "Speed against the maximum strip length: primary and AO Mrays/s (y) for limits 4 to 128 triangles (x, log scale).",
            "The paper found speed rising with the limit and then dropping slightly; where the curve bends here is the limit worth using on this mesh.",
        )
    );
    Ok(Section {
        markdown,
        plots: vec![bytes_path, speed_path],
    })
}

fn speed_series(points: impl Iterator<Item = (f64, Speed)> + Clone) -> Vec<Series> {
    vec![
        Series::line(
            "primary",
            points.clone().map(|(x, s)| (x, s.primary_mrays)).collect(),
        ),
        Series::line(
            "ambient occlusion",
            points.map(|(x, s)| (x, s.ao_mrays)).collect(),
        ),
    ]
}

pub fn leaf_subtree_section(rows: &[LeafSubtreeRow], plots_dir: &Path) -> anyhow::Result<Section> {
    let mut table = Table::new(vec![
        "leaf windows",
        "subtree windows",
        "B/tri",
        "primary Mrays/s",
        "AO Mrays/s",
    ]);
    for r in rows {
        table.push(vec![
            r.leaf_windows.to_string(),
            r.subtree_windows.to_string(),
            format!("{:.2}", r.bytes_per_triangle),
            format!("{:.2}", r.speed.primary_mrays),
            format!("{:.2}", r.speed.ao_mrays),
        ]);
    }
    let series_of = |metric: fn(&Speed) -> f64| -> Vec<Series> {
        LEAF_SIZES
            .iter()
            .map(|&leaf| {
                let points = rows
                    .iter()
                    .filter(|r| r.leaf_windows == leaf)
                    .map(|r| (r.subtree_windows as f64, metric(&r.speed)))
                    .collect();
                Series::line(&format!("leaf {leaf}"), points)
            })
            .collect()
    };
    let x = || Axis::log2("subtree intersection size (windows, log scale)");
    let primary = Plot {
        file_stem: "leaf_subtree_primary",
        title: "Leaf size and subtree intersection: primary rays".into(),
        x: x(),
        y: Axis::linear("primary rays (Mrays/s)"),
        series: series_of(|s| s.primary_mrays),
    };
    let ao = Plot {
        file_stem: "leaf_subtree_ao",
        title: "Leaf size and subtree intersection: AO rays".into(),
        x: x(),
        y: Axis::linear("AO rays (Mrays/s)"),
        series: series_of(|s| s.ao_mrays),
    };
    let primary_path = plot::draw(&primary, plots_dir)?;
    let ao_path = plot::draw(&ao, plots_dir)?;
    let markdown = format!(
        "## 4. Leaf size and subtree intersection\n\n\
         Strip kd-tree leaf size (build parameter, windows) × `TraceOptions::subtree_windows` \
         (intervals of at most that many windows are intersected without descending further; \
         a subtree size below the leaf size acts as the leaf size). Leaf size changes the file \
         only through the strip hierarchies' size.\n\n{}{}{}",
        table.to_markdown(),
        figure(
            &primary_path,
            "Primary-ray Mrays/s (y) against the subtree intersection size (x, log scale), one line per strip kd-tree leaf size.",
            "Small subtrees descend further and test fewer windows; large ones test whole intervals at once: the peak is the better balance on this machine.",
        ),
        figure(
            &ao_path,
            "AO-ray Mrays/s (y) against the subtree intersection size (x, log scale), one line per strip kd-tree leaf size.",
            "AO rays are short and stop at the first hit, so they may prefer a different balance than primary rays.",
        )
    );
    Ok(Section {
        markdown,
        plots: vec![primary_path, ao_path],
    })
}

pub fn sah_section(rows: &[SahRow], plots_dir: &Path) -> anyhow::Result<Section> {
    let mut table = Table::new(vec![
        "bins of",
        "bins",
        "build s",
        "B/tri",
        "primary Mrays/s",
        "AO Mrays/s",
    ]);
    for r in rows {
        table.push(vec![
            r.hierarchy.to_string(),
            r.bins.to_string(),
            format!("{:.4}", r.build_seconds),
            format!("{:.2}", r.bytes_per_triangle),
            format!("{:.2}", r.speed.primary_mrays),
            format!("{:.2}", r.speed.ao_mrays),
        ]);
    }
    let series = [PARTITION_BINS, TOP_LEVEL_BINS]
        .map(|hierarchy| {
            let rows: Vec<&SahRow> = rows.iter().filter(|r| r.hierarchy == hierarchy).collect();
            let points = rows
                .iter()
                .map(|r| (r.build_seconds, r.speed.primary_mrays))
                .collect();
            let labels = rows.iter().map(|r| format!("{} bins", r.bins)).collect();
            Series::line(hierarchy, points).with_point_labels(labels)
        })
        .to_vec();
    let plot = Plot {
        file_stem: "sah_bins",
        title: "SAH bins: build time against primary-ray speed".into(),
        x: Axis::log10("build time (s, log scale)"),
        y: Axis::linear("primary rays (Mrays/s)"),
        series,
    };
    let plot_path = plot::draw(&plot, plots_dir)?;
    let markdown = format!(
        "## 5. SAH quality\n\n\
         Binned SAH with 2 to 64 bins, in Strip-RT's partition (other parameters at the paper's \
         values) and in the top level (partition at 16 bins). No full-sweep SAH exists in \
         either builder, so none is measured.\n\n{}{}",
        table.to_markdown(),
        figure(
            &plot_path,
            "SAH bins: build time (x, log scale) against primary-ray Mrays/s (y); each point is labelled with its bin count.",
            "A point up and to the left is a better trade; lines join the bin counts in order, so where a line stops rising, more bins only cost build time.",
        )
    );
    Ok(Section {
        markdown,
        plots: vec![plot_path],
    })
}
