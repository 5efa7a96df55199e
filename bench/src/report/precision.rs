//! Section 7: what vertex precision costs. The sweep mesh lossless and with vertices on grids of
//! 12 to 24 bits (the pipeline's default leaves of [`PIPELINE_LEAF_WINDOWS`] windows): the
//! position error against bytes per triangle and speed. Then the tolerance weld on a copy of the
//! mesh whose shared vertices were perturbed ([`reducem_gen::perturbed_copies`], the paper's
//! Boeing 777 case): strip length, bytes and speed without and with it.

use std::path::Path;

use super::markdown::{figure, Section, Table};
use super::plot::{self, Axis, Plot, Series};
use super::speed::Speed;
use super::sweeps::Subject;
use super::Sizes;
use reducem::conversion::{BuildParams, PIPELINE_LEAF_WINDOWS};
use reducem::geometry::distance;
use reducem::input::{weld_within_tolerance, WeldStats};
use reducem::inspect::FileStats;
use reducem::trace::TraceOptions;

pub const GRID_BITS: [u32; 4] = [12, 16, 20, 24];
/// How far the weld rows' copies of a vertex are moved, as a fraction of the bounds' diagonal.
pub const PERTURBATION: f32 = 1e-6;

#[derive(Clone, Debug, PartialEq)]
pub struct PrecisionRow {
    /// `None`: lossless f32 vertices.
    pub grid_bits: Option<u32>,
    pub stats: FileStats,
    pub speed: Speed,
}

#[derive(Clone, Debug, PartialEq)]
pub struct WeldRow {
    pub weld: WeldStats,
    pub stats: FileStats,
    pub speed: Speed,
}

/// Converts and traces the lossless file and one grid file per [`GRID_BITS`].
pub fn precision(
    subject: &Subject,
    work: &Path,
    sizes: &Sizes,
) -> anyhow::Result<Vec<PrecisionRow>> {
    let params = |grid_bits| BuildParams {
        grid_bits,
        leaf_windows: PIPELINE_LEAF_WINDOWS,
        ..BuildParams::default()
    };
    std::iter::once(None)
        .chain(GRID_BITS.iter().map(|&bits| Some(bits)))
        .map(|grid_bits| (grid_bits, params(grid_bits)))
        .map(|(grid_bits, params)| {
            let (converted, speed) =
                subject.measure(&params, TraceOptions::default(), work, sizes)?;
            Ok(PrecisionRow {
                grid_bits,
                stats: converted.stats,
                speed,
            })
        })
        .collect()
}

/// Converts and traces the perturbed copy of the mesh as it is and welded.
pub fn weld(subject: &Subject, work: &Path, sizes: &Sizes) -> anyhow::Result<Vec<WeldRow>> {
    let bounds = subject.mesh.bounds();
    let amount = PERTURBATION * distance(&bounds.min, &bounds.max) as f32;
    let perturbed = reducem_gen::perturbed_copies(&subject.mesh, amount, 5);
    // Copies of one vertex are at most 2√3 × amount apart.
    [0.0, 4.0 * amount]
        .into_iter()
        .map(|tolerance| {
            let (mesh, weld) = weld_within_tolerance(perturbed.clone(), tolerance);
            let params = BuildParams::default();
            let (converted, speed) =
                subject.measure_mesh(&mesh, &params, TraceOptions::default(), work, sizes)?;
            Ok(WeldRow {
                weld,
                stats: converted.stats,
                speed,
            })
        })
        .collect()
}

fn label(row: &PrecisionRow) -> String {
    row.grid_bits
        .map_or("f32".to_string(), |bits| format!("{bits} bits"))
}

pub fn section(
    rows: &[PrecisionRow],
    weld_rows: &[WeldRow],
    plots_dir: &Path,
) -> anyhow::Result<Section> {
    let mut table = Table::new(vec![
        "vertices",
        "grid cell",
        "max error / diagonal",
        "RMS error / diagonal",
        "B/tri",
        "primary Mrays/s",
        "AO Mrays/s",
    ]);
    for r in rows {
        table.push(vec![
            label(r),
            match r.grid_bits {
                Some(_) => format!("{:.3e}", r.stats.grid_cell),
                None => "—".to_string(),
            },
            format!("{:.2e}", r.stats.position_error_max_relative),
            format!("{:.2e}", r.stats.position_error_rms_relative),
            format!("{:.2}", r.stats.bytes_per_triangle),
            format!("{:.2}", r.speed.primary_mrays),
            format!("{:.2}", r.speed.ao_mrays),
        ]);
    }
    let grids: Vec<&PrecisionRow> = rows.iter().filter(|r| r.grid_bits.is_some()).collect();
    let error = Plot {
        file_stem: "precision_error_bytes",
        title: "Vertex precision: error against memory".into(),
        x: Axis::linear("bytes per triangle (B)"),
        y: Axis::log10("largest position error / bounds diagonal (log scale)"),
        series: vec![Series::line(
            "grid vertices",
            grids
                .iter()
                .map(|r| {
                    let s = &r.stats;
                    (s.bytes_per_triangle, s.position_error_max_relative)
                })
                .collect(),
        )
        .with_point_labels(grids.iter().map(|r| label(r)).collect())],
    };
    let speed = Plot {
        file_stem: "precision_speed_bytes",
        title: "Vertex precision: speed against memory".into(),
        x: Axis::linear("bytes per triangle (B)"),
        y: Axis::linear("rays per second (Mrays/s)"),
        series: [("primary", true), ("ambient occlusion", false)]
            .into_iter()
            .map(|(name, primary)| {
                let points = rows
                    .iter()
                    .map(|r| {
                        let mrays = match primary {
                            true => r.speed.primary_mrays,
                            false => r.speed.ao_mrays,
                        };
                        (r.stats.bytes_per_triangle, mrays)
                    })
                    .collect();
                Series::points(name, points).with_point_labels(rows.iter().map(label).collect())
            })
            .collect(),
    };
    let error_path = plot::draw(&error, plots_dir)?;
    let speed_path = plot::draw(&speed, plots_dir)?;
    let markdown = format!(
        "## 7. Vertex precision\n\n\
         The sweep mesh with lossless f32 vertices and with vertices on one grid over the model \
         (`[vertices] encoding = \"grid\"`), both with the pipeline's leaves of \
         {PIPELINE_LEAF_WINDOWS} windows, traced with \
         the same rays. The error is the distance from each input \
         vertex to where the file stores it, over the bounds' diagonal (`reducem inspect`); a \
         grid cell is the step on every axis, so the error is at most √3/2 cells.\n\n{}{}{}{}",
        table.to_markdown(),
        figure(
            &error_path,
            "Largest position error over the bounds' diagonal (y, log scale) against file bytes per triangle (x), one point per grid size (lossless f32 has no error and is not drawn).",
            "Each grid bit halves the error and costs about 3 bits per stored vertex (one per axis), about 0.4 bytes per triangle: the slope is the price of precision in memory.",
        ),
        figure(
            &speed_path,
            "Primary and AO Mrays/s (y) against file bytes per triangle (x), one point per vertex encoding (labelled).",
            "Grid vertices are decoded in place at every visit; the gap to lossless is what decoding costs in time, against what the smaller file saves in memory.",
        ),
        weld_section(weld_rows),
    );
    Ok(Section {
        markdown,
        plots: vec![error_path, speed_path],
    })
}

fn weld_section(rows: &[WeldRow]) -> String {
    let mut table = Table::new(vec![
        "weld tolerance",
        "welded vertices",
        "largest move",
        "avg strip length",
        "B/tri",
        "primary Mrays/s",
        "AO Mrays/s",
    ]);
    for r in rows {
        table.push(vec![
            format!("{:.2e}", r.weld.tolerance),
            r.weld.displacement.count.to_string(),
            format!("{:.2e}", r.weld.displacement.max),
            format!("{:.2}", r.stats.avg_strip_length),
            format!("{:.2}", r.stats.bytes_per_triangle),
            format!("{:.2}", r.speed.primary_mrays),
            format!("{:.2}", r.speed.ao_mrays),
        ]);
    }
    format!(
        "### Weld tolerance\n\n\
         A copy of the sweep mesh in which every triangle has its own copies of its corners, \
         each moved by up to {PERTURBATION:e} of the diagonal per axis (shared vertices \
         perturbed, as in the paper's Boeing 777), converted lossless as it is and after \
         `[vertices] weld_tolerance` merged the copies again. Without the weld no two triangles \
         share a vertex, so every strip is one triangle.\n\n{}",
        table.to_markdown()
    )
}
