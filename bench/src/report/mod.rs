//! The measured trade-offs report behind `reducem-bench report` (feature `report`): the paper's
//! Tables 2 and 3 and Fig. 5 reproduced against real peers, and what accuracy costs in time.
//!
//! Every number in `REPORT.md` comes from a run of the current code on generated meshes; nothing
//! is typed in by hand. [`run`] generates (or reuses) the meshes in the work directory, runs each
//! section's measurements, then writes `REPORT.md` with its tables and one SVG per plot (SVG so
//! that no font rasterizer is needed). The sections:
//!
//! 1. [`memory`]: bytes by part of ReduceM, the in-project baseline BVH, the paper's 40-byte
//!    triangle format and Embree (with the `embree` feature), per mesh kind, with trace speed.
//! 2. [`stripifier`]: Strip-RT against meshoptimizer's rasterization stripifier, same encoding.
//! 3. to 5. [`sweeps`]: maximum strip length, leaf size × subtree intersection, SAH bins.
//! 6. [`accuracy`]: ambient-occlusion samples against image error and render time.
//! 7. [`precision`]: lossless against grid vertices of 12 to 24 bits (error, bytes, speed), and
//!    the tolerance weld on a perturbed copy of the mesh.
//! 8. [`attributes`]: bytes per triangle of face ids, normals and colours, and tracing speed
//!    with and without them.
//!
//! [`Scale`] sets mesh and image sizes: `tiny` runs in seconds (the tests), `medium` in minutes,
//! `full` in about half an hour on 2 cores.

pub mod accuracy;
pub mod attributes;
#[cfg(feature = "embree")]
#[allow(unsafe_code)]
mod embree_peer;
pub mod machine;
pub mod markdown;
pub mod memory;
pub mod memory_parts;
pub mod plot;
pub mod precision;
pub mod speed;
pub mod stripifier;
pub mod sweeps;

use std::path::{Path, PathBuf};

use anyhow::Context;

use machine::MachineFacts;
use markdown::Section;
use reducem_gen::Kind;

/// How large the measured meshes and images are.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Scale {
    /// Seconds: for the tests.
    Tiny,
    /// Minutes: for development.
    Medium,
    /// About 30 minutes on 2 cores: the report's headline figures.
    Full,
}

/// Sizes of one scale.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sizes {
    /// Triangles of every generated mesh (the generators round to what their shape allows).
    pub triangles: u64,
    /// Edge in pixels of the square image whose primary rays are traced.
    pub image: u32,
    /// AO rays traced per primary hit in the speed measurements.
    pub ao_rays_per_hit: u32,
    /// Edge in pixels of the AO accuracy images.
    pub accuracy_image: u32,
    /// Runs per timing; the median is reported.
    pub runs: usize,
    /// Shortest trace run: a ray set is traced repeatedly until this many seconds have passed.
    pub min_trace_seconds: f64,
}

impl Scale {
    pub fn sizes(self) -> Sizes {
        match self {
            Scale::Tiny => Sizes {
                triangles: 3_000,
                image: 32,
                ao_rays_per_hit: 4,
                accuracy_image: 24,
                runs: 3,
                min_trace_seconds: 0.0,
            },
            Scale::Medium => Sizes {
                triangles: 300_000,
                image: 256,
                ao_rays_per_hit: 8,
                accuracy_image: 128,
                runs: 5,
                min_trace_seconds: 0.2,
            },
            Scale::Full => Sizes {
                triangles: 4_000_000,
                image: 512,
                ao_rays_per_hit: 8,
                accuracy_image: 256,
                runs: 5,
                min_trace_seconds: 0.3,
            },
        }
    }
}

/// Where the report reads and writes.
#[derive(Clone, Debug)]
pub struct ReportConfig {
    pub scale: Scale,
    /// `REPORT.md`, the plots and the sample images go here.
    pub out_dir: PathBuf,
    /// Generated meshes (kept between runs) and converted files.
    pub work_dir: PathBuf,
}

/// The mesh kinds of the memory table, as in the issue: one of each family the paper measured.
pub const MEMORY_KINDS: [Kind; 4] = [Kind::Scan, Kind::Terrain, Kind::Isosurface, Kind::Cad];
/// The mesh of the single-mesh sections: a closed scanned-looking surface, like the paper's Lucy.
pub const SWEEP_KIND: Kind = Kind::Scan;

/// Everything measured, as typed rows; the markdown and the plots are made from this.
#[derive(Clone, Debug)]
pub struct ReportData {
    pub machine: MachineFacts,
    pub sizes: Sizes,
    pub memory: Vec<memory::MemoryRow>,
    pub stripifiers: Vec<stripifier::StripifierRow>,
    pub strip_lengths: Vec<sweeps::StripLengthRow>,
    pub leaf_subtree: Vec<sweeps::LeafSubtreeRow>,
    pub sah_bins: Vec<sweeps::SahRow>,
    pub ambient_occlusion: Vec<accuracy::AoRow>,
    pub precision: Vec<precision::PrecisionRow>,
    pub weld: Vec<precision::WeldRow>,
    pub attributes: Vec<attributes::AttributeRow>,
}

/// What [`run`] wrote.
#[derive(Clone, Debug)]
pub struct Written {
    pub report: PathBuf,
    pub plots: Vec<PathBuf>,
    pub images: Vec<PathBuf>,
}

/// Measures every section and writes the report; returns the data and the files written.
pub fn run(config: &ReportConfig) -> anyhow::Result<(ReportData, Written)> {
    let sizes = config.scale.sizes();
    std::fs::create_dir_all(&config.work_dir)
        .with_context(|| format!("creating {}", config.work_dir.display()))?;
    let plots_dir = config.out_dir.join("plots");
    std::fs::create_dir_all(&plots_dir)
        .with_context(|| format!("creating {}", plots_dir.display()))?;
    let machine = MachineFacts::read(config.scale);
    let work = &config.work_dir;
    let memory = memory::collect(work, &sizes)?;
    let stripifiers = stripifier::collect(work, &sizes)?;
    let subject = sweeps::Subject::new(
        crate::workload::load_mesh(SWEEP_KIND, sizes.triangles, work)?,
        work,
        &sizes,
    )?;
    let strip_lengths = sweeps::strip_lengths(&subject, work, &sizes)?;
    let leaf_subtree = sweeps::leaf_subtree(&subject, work, &sizes)?;
    let sah_bins = sweeps::sah_bins(&subject, work, &sizes)?;
    let (ambient_occlusion, images) = accuracy::collect(work, &config.out_dir, &sizes)?;
    let precision = precision::precision(&subject, work, &sizes)?;
    let weld = precision::weld(&subject, work, &sizes)?;
    let attributes = attributes::collect(&subject, work, &sizes)?;
    let data = ReportData {
        machine,
        sizes,
        memory,
        stripifiers,
        strip_lengths,
        leaf_subtree,
        sah_bins,
        ambient_occlusion,
        precision,
        weld,
        attributes,
    };
    let written = write(&data, &config.out_dir, &plots_dir, images)?;
    Ok((data, written))
}

/// Renders every section and writes `REPORT.md` beside the plots.
fn write(
    data: &ReportData,
    out_dir: &Path,
    plots_dir: &Path,
    images: Vec<PathBuf>,
) -> anyhow::Result<Written> {
    let sections: Vec<Section> = vec![
        memory::section(&data.memory, plots_dir)?,
        stripifier::section(&data.stripifiers, plots_dir)?,
        sweeps::strip_length_section(&data.strip_lengths, plots_dir)?,
        sweeps::leaf_subtree_section(&data.leaf_subtree, plots_dir)?,
        sweeps::sah_section(&data.sah_bins, plots_dir)?,
        accuracy::section(
            &data.ambient_occlusion,
            data.sizes.accuracy_image,
            &images,
            out_dir,
            plots_dir,
        )?,
        precision::section(&data.precision, &data.weld, plots_dir)?,
        attributes::section(&data.attributes)?,
    ];
    let mut text = markdown::preamble(&data.machine, &data.sizes);
    let mut plots = Vec::new();
    for section in sections {
        text.push_str(&section.markdown);
        plots.extend(section.plots);
    }
    let report = out_dir.join("REPORT.md");
    std::fs::write(&report, text).with_context(|| format!("writing {}", report.display()))?;
    Ok(Written {
        report,
        plots,
        images,
    })
}
