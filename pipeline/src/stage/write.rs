//! Stage *write*: streams the final ReduceM file from the strip chunks in hierarchy order (nodes,
//! then records, then strip data, each chunk's part in turn) to a temporary file, verifies that
//! in full (as `reducem inspect --verify`), and only then renames it over the output and records
//! the stage: an earlier output survives any failure, a failed check included.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use anyhow::Context;
use reducem::conversion::layout::{rebase_records, DataWords};
use reducem::conversion::Pooling;
use reducem::format::attribute_sections::AttributeVisit;
use reducem::format::reader::{ReducemFile, Validation};
use reducem::format::writer::{write_nodes, write_streaming, FileInfo, SectionSource};
use reducem::format::{SectionKind, GRID_LINK_INDEX};
use reducem::toplevel::relocate;

use crate::checksum::{checksum_file, Checksum};
use crate::chunk_io::StripChunk;
use crate::fingerprint::Fingerprint;
use crate::manifest::Freshness;
use crate::stage::hierarchy::{node, Hierarchy, Step};
use crate::stage::merge::Merged;
use crate::stage::Job;
use crate::workdir::strip_chunk;

pub const UNIT: &str = "write";

pub fn output_path(job: &Job) -> PathBuf {
    std::path::absolute(&job.config.output.path).unwrap_or_else(|_| job.config.output.path.clone())
}

pub fn fingerprint(job: &Job, hierarchy: &Hierarchy) -> Fingerprint {
    Fingerprint::new()
        .with("hierarchy_stage", &hierarchy.digest)
        .with("input.up", job.config.input.up_axis().name())
        .with("output.path", output_path(job).display())
}

pub fn run(job: &Job, merged: &Merged, hierarchy: &Hierarchy) -> anyhow::Result<()> {
    let fingerprint = fingerprint(job, hierarchy);
    let output = output_path(job);
    let freshness = job.freshness(UNIT, &fingerprint);
    if freshness == Freshness::Fresh {
        job.progress
            .event(UNIT, "skip", &format!("fresh: {}", output.display()));
        return Ok(());
    }
    job.note_rebuild(UNIT, &freshness, "it");
    let progress = job.progress.stage(UNIT, 3, "sections");
    if let Some(parent) = output.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    let params = job.config.build_params();
    let pooled = Pooling::of(&params, merged.grid.as_ref()).is_some();
    let info = FileInfo {
        stats: merged.stats(),
        leaf_windows: job.config.build_params().leaf_windows,
        max_strip_length: job.config.strip.max_length,
        bounds: merged.bounds(),
        grid: merged.grid,
        weld: merged.weld,
        attributes: job.config.build_params().attributes,
        closedness: Some(merged.edges.into()),
        up: Some(job.config.input.up_axis()),
        pooled,
    };
    let mut source = Spliced::new(job, merged, hierarchy)?;
    let temporary = reducem::atomic::temporary_path(&output);
    if let Err(error) = write_streaming(&temporary, &info, &mut source) {
        crate::interrupt::check()?;
        // The error's message ends with its source: as one I/O error (exit code 74) the OS
        // error is said once, not again as its cause.
        return Err(io::Error::new(error.source.kind(), error.to_string()).into());
    }
    progress.advance(3);
    let checksum = match verify(&temporary) {
        Ok(checksum) => checksum,
        Err(error) => {
            let _ = std::fs::remove_file(&temporary);
            return Err(VerificationFailed { output, error }.into());
        }
    };
    reducem::atomic::replace(&temporary, &output)
        .with_context(|| format!("renaming {} to {}", temporary.display(), output.display()))?;
    let written = job.written(&output.display().to_string(), checksum);
    job.complete(UNIT, &fingerprint, &[written])?;
    progress.finish(&format!(
        ": {} ({} triangles, {:.2} bytes/triangle)",
        output.display(),
        info.stats.triangles,
        checksum.bytes as f64 / info.stats.triangles.max(1) as f64
    ));
    Ok(())
}

/// The new file failed its final check: it was removed, and the earlier output is unchanged.
#[derive(Debug, thiserror::Error)]
#[error(
    "{}: the new file failed verification and was removed; the earlier file is unchanged and \
     the write stage is not recorded as done ({error:#}); the work directory may be damaged: \
     run `pipeline clean` on the configuration, then run the job again",
    output.display()
)]
pub struct VerificationFailed {
    pub output: PathBuf,
    /// Shown in the message with its causes, so not also a source.
    pub error: anyhow::Error,
}

/// Checks `path` as `reducem inspect --verify` does (every record, every section checksum);
/// the file's checksum for the manifest.
fn verify(path: &Path) -> anyhow::Result<Checksum> {
    let file = ReducemFile::open_with(path, Validation::Full)?;
    file.verify_checksums()?;
    drop(file);
    checksum_file(path).with_context(|| format!("reading {}", path.display()))
}

/// More nodes or strips than a top-level link addresses: checked before anything is written,
/// so relocating a chunk's links cannot fail midway (2^28 strips are some five billion
/// triangles). Not a known error kind, so exit code 70.
#[derive(Debug, thiserror::Error)]
#[error("more than 2^28 top-level nodes or strips: too many for a format 4 link")]
pub struct TooManyLinks;

/// A node the write could not encode or relocate (prevented by [`TooManyLinks`]).
fn invalid(detail: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidData, detail)
}

/// What a write stopped between two chunks says; the stage reports the stop itself.
const INTERRUPTED: &str = "stopped on request";

/// The final file's sections, read chunk by chunk from the strip stage's outputs.
struct Spliced<'a> {
    job: &'a Job<'a>,
    steps: &'a [Step],
    strip_count: u64,
    /// Where each chunk's strip blocks start in the strip-data section, in 4-byte words.
    data_word_base: Vec<u32>,
}

impl<'a> Spliced<'a> {
    fn new(
        job: &'a Job<'a>,
        merged: &'a Merged,
        hierarchy: &'a Hierarchy,
    ) -> anyhow::Result<Spliced<'a>> {
        let mut data_word_base = vec![0u32; merged.chunks.len()];
        let mut words = DataWords::default();
        for step in &hierarchy.steps {
            if let Step::Chunk { index, .. } = *step {
                data_word_base[index] = words.place(merged.chunks[index].data_bytes)?;
            }
        }
        let strip_count = merged.chunks.iter().map(|c| c.strips as u64).sum();
        let node_count = hierarchy.steps.iter().map(|step| match *step {
            Step::Node { .. } => 1,
            Step::Chunk { index, .. } => merged.chunks[index].nodes as u64,
        });
        let links = u64::from(GRID_LINK_INDEX) + 1;
        if strip_count > links || node_count.sum::<u64>() > links {
            return Err(TooManyLinks.into());
        }
        Ok(Spliced {
            job,
            steps: &hierarchy.steps,
            strip_count,
            data_word_base,
        })
    }

    fn chunk(&self, index: usize) -> io::Result<StripChunk> {
        let path = self.job.work.file(&strip_chunk(index));
        StripChunk::open(&path)
            .map_err(|e| io::Error::new(e.kind(), format!("{}: {e}", path.display())))
    }

    /// The chunks in file order; a stop request ends the walk between two chunks.
    fn chunks(&self) -> impl Iterator<Item = io::Result<(usize, u32, u32)>> + '_ {
        self.steps.iter().filter_map(|step| match *step {
            _ if crate::interrupt::check().is_err() => Some(Err(io::Error::other(INTERRUPTED))),
            Step::Chunk {
                index,
                node_base,
                strip_base,
            } => Some(Ok((index, node_base, strip_base))),
            Step::Node { .. } => None,
        })
    }
}

impl SectionSource for Spliced<'_> {
    fn strip_count(&self) -> u64 {
        self.strip_count
    }

    fn write_section(&mut self, kind: SectionKind, out: &mut dyn Write) -> io::Result<()> {
        match kind {
            SectionKind::TopNodes => self.steps.iter().try_for_each(|step| match *step {
                _ if crate::interrupt::check().is_err() => Err(io::Error::other(INTERRUPTED)),
                Step::Node { ref slots } => write_nodes(out, &[node(slots).map_err(invalid)?]),
                Step::Chunk {
                    index,
                    node_base,
                    strip_base,
                } => {
                    let nodes = self.chunk(index)?.nodes()?;
                    let moved = nodes
                        .iter()
                        .map(|n| relocate(n, node_base, strip_base))
                        .collect::<Result<Vec<_>, _>>()
                        .map_err(|e| invalid(format!("chunk {index}: {e}")))?;
                    write_nodes(out, &moved)
                }
            }),
            SectionKind::StripRecords => self.chunks().try_for_each(|chunk| {
                let (index, _, _) = chunk?;
                let mut records = self.chunk(index)?.records()?;
                rebase_records(&mut records, self.data_word_base[index])?;
                out.write_all(bytemuck::cast_slice(&records))
            }),
            SectionKind::StripData => self
                .chunks()
                .try_for_each(|chunk| self.chunk(chunk?.0)?.copy_data(out)),
        }
    }

    fn visit_attributes(&mut self, visit: &mut AttributeVisit) -> io::Result<()> {
        self.chunks()
            .try_for_each(|chunk| self.chunk(chunk?.0)?.visit_attributes(visit))
    }
}
