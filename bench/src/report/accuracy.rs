//! Section 6: what accuracy costs in time. Ambient occlusion with 1 to 256 samples per pixel
//! against a 1024-sample reference, through the renderer ([`reducem::render::render`]).
//!
//! The error is the RMSE of the linear RGB image against the reference, over all pixels and
//! channels. The renderer's samples are stateless hashes of (seed, pixel, sample index), so an
//! image with `n` samples uses the first `n` of the reference's 1024: the curve shows how the
//! estimate converges, not the luck of independent draws. AO is the renderer's only sampled
//! effect: shadows are one ray per light (hard shadows) and have no sample count to trade.

use std::path::{Path, PathBuf};

use super::markdown::{figure, Section, Table};
use super::plot::{self, Axis, Plot, Series};
use super::Sizes;
use crate::workload::{ao_scene, convert_timed, load_mesh, median_timed};
use reducem::conversion::BuildParams;
use reducem::format::reader::ReducemFile;
use reducem::render::image::write_png;
use reducem::render::{render, Frame};
use reducem::trace::{TraceOptions, Tracer};
use reducem_gen::Kind;

/// A heightfield: valleys and ridges give ambient occlusion something to estimate.
pub const ACCURACY_KIND: Kind = Kind::Terrain;
pub const SAMPLE_COUNTS: [u32; 9] = [1, 2, 4, 8, 16, 32, 64, 128, 256];
pub const REFERENCE_SAMPLES: u32 = 1024;
/// Sample counts whose images are written beside the report.
const SHOWN_SAMPLES: [u32; 2] = [1, 16];

#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AoRow {
    pub samples: u32,
    pub ao_rays: u64,
    /// Median render time of all passes (primary and AO).
    pub render_seconds: f64,
    pub rmse: f64,
}

/// Renders the reference and every sample count of the [`ACCURACY_KIND`] mesh; writes a few
/// images into `out_dir`.
pub fn collect(
    work: &Path,
    out_dir: &Path,
    sizes: &Sizes,
) -> anyhow::Result<(Vec<AoRow>, Vec<PathBuf>)> {
    let mesh = load_mesh(ACCURACY_KIND, sizes.triangles, work)?;
    let converted = convert_timed(&mesh, &BuildParams::default(), work, "accuracy", 1)?;
    let file = ReducemFile::open(&converted.path)?;
    let tracer = Tracer::new(&file, TraceOptions::default());
    let size = sizes.accuracy_image;
    let (reference, _) = render(&tracer, &ao_scene(size, REFERENCE_SAMPLES));
    let mut images = Vec::new();
    let mut rows = Vec::new();
    for samples in SAMPLE_COUNTS {
        let scene = ao_scene(size, samples);
        let (render_seconds, (frame, report)) =
            median_timed(sizes.runs, || render(&tracer, &scene));
        if SHOWN_SAMPLES.contains(&samples) {
            images.push(write_image(&frame, out_dir, samples)?);
        }
        rows.push(AoRow {
            samples,
            ao_rays: report.rays_of("ambient_occlusion"),
            render_seconds,
            rmse: rmse(&frame, &reference),
        });
    }
    images.push(write_image(&reference, out_dir, REFERENCE_SAMPLES)?);
    Ok((rows, images))
}

fn write_image(frame: &Frame, out_dir: &Path, samples: u32) -> anyhow::Result<PathBuf> {
    let path = out_dir.join(format!("ao-{samples}spp.png"));
    write_png(frame, &path)?;
    Ok(path)
}

/// Root mean square difference over every pixel and channel.
pub fn rmse(frame: &Frame, reference: &Frame) -> f64 {
    let values = frame
        .pixels
        .iter()
        .flatten()
        .zip(reference.pixels.iter().flatten());
    let (sum, count) = values.fold((0.0, 0usize), |(sum, count), (a, b)| {
        let d = f64::from(a - b);
        (sum + d * d, count + 1)
    });
    (sum / count.max(1) as f64).sqrt()
}

pub fn section(
    rows: &[AoRow],
    size: u32,
    images: &[PathBuf],
    out_dir: &Path,
    plots_dir: &Path,
) -> anyhow::Result<Section> {
    let mut table = Table::new(vec![
        "AO samples",
        "AO rays",
        "render s",
        "RMSE",
        "RMSE × √samples",
    ]);
    for r in rows {
        table.push(vec![
            r.samples.to_string(),
            r.ao_rays.to_string(),
            format!("{:.4}", r.render_seconds),
            format!("{:.5}", r.rmse),
            format!("{:.4}", r.rmse * f64::from(r.samples).sqrt()),
        ]);
    }
    let cost = Plot {
        file_stem: "ao_accuracy_time",
        title: "Ambient occlusion: error against render time".into(),
        x: Axis::log10("render time (s, log scale)"),
        y: Axis::log10("RMSE against 1024 samples (linear RGB, log scale)"),
        series: vec![Series::line(
            "1, 2, 4, …, 256 samples per pixel",
            rows.iter().map(|r| (r.render_seconds, r.rmse)).collect(),
        )
        .with_point_labels(rows.iter().map(|r| format!("{} spp", r.samples)).collect())],
    };
    let cost_path = plot::draw(&cost, plots_dir)?;
    let image_links: String = images
        .iter()
        .filter_map(|p| p.strip_prefix(out_dir).ok())
        .map(|p| format!("![{0}]({0}) ", p.display()))
        .collect();
    let markdown = format!(
        "## 6. Accuracy against time: ambient occlusion samples\n\n\
         The scene of `configs/scenes/ao16.toml` at {size}×{size} pixels on the terrain mesh, \
         rendered with 1 to 256 AO samples per pixel and compared with a {REFERENCE_SAMPLES}-sample \
         render. Render time is all passes (primary and AO; median of the runs). Shadows are \
         the renderer's other effect but are not sampled (one ray per light), so AO is the only \
         accuracy/time curve there is. Monte Carlo error falls as 1/√samples: a constant last \
         column means the estimate converges as it should (the reference's own error makes the \
         last rows fall slightly faster).\n\n{}{}\
         Images (1 sample, 16 samples, reference): {image_links}\n\n",
        table.to_markdown(),
        figure(
            &cost_path,
            "Ambient occlusion: image RMSE against the 1024-sample reference (y, log scale) against render time (x, log scale), one point per sample count (labelled in samples per pixel).",
            "Each doubling of samples doubles the AO rays and so roughly the time, and divides the error by about √2: the slope is the price of accuracy.",
        ),
    );
    Ok(Section {
        markdown,
        plots: vec![cost_path],
    })
}
