//! Stage *merge*: gathers every chunk's strip summary (strip, node and data sizes, bounds and
//! statistics) into one table, and fixes where each chunk's strip blocks will sit in the final
//! strip-data section. Reads only the chunk headers, and the chunks' border edges, which it
//! pairs over the whole model for the edge counts (`crate::border_edges`). It also carries what
//! the chunk stage measured (the weld) and the model grid to the write stage.

use anyhow::Context;
use reducem::conversion::ChunkStats;
use reducem::format::grid::Grid;
use reducem::geometry::Aabb;
use reducem::input::WeldStats;
use serde::{Deserialize, Serialize};

use crate::border_edges::{self, EdgeCounts};
use crate::chunk_io::StripChunk;
use crate::fingerprint::Fingerprint;
use crate::stage::chunk::Chunked;
use crate::stage::{fresh_output, write_json, Job, Stamped};
use crate::workdir::strip_chunk;

pub const UNIT: &str = "merge";
const TABLE: &str = "merge.json";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ChunkSummary {
    pub strips: u32,
    pub nodes: u32,
    pub data_bytes: u64,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    /// The chunk's counts, by name (before, a positional array of six and the quantization
    /// beside it).
    pub stats: ChunkStats,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Merged {
    pub digest: String,
    pub chunks: Vec<ChunkSummary>,
    /// The grid every chunk's vertices were snapped to, if any.
    pub grid: Option<Grid>,
    pub weld: WeldStats,
    /// The whole model's edge counts.
    pub edges: EdgeCounts,
}

impl Merged {
    pub fn stats(&self) -> ChunkStats {
        let mut total = ChunkStats::default();
        for chunk in &self.chunks {
            total.add(&chunk.stats);
        }
        total
    }

    pub fn bounds(&self) -> Aabb {
        self.chunks
            .iter()
            .filter(|c| c.strips > 0)
            .fold(Aabb::EMPTY, |b, c| {
                b.union(&Aabb {
                    min: c.bounds_min,
                    max: c.bounds_max,
                })
            })
    }
}

/// Version of the merge table's JSON: 2 names the counts of each chunk, 3 adds the model's
/// edge counts. A table of an older
/// version does not parse, so its fingerprint differs and the stage reruns (it reads only the
/// chunk headers).
const TABLE_VERSION: u32 = 3;

pub fn fingerprint(strip_digest: &str) -> Fingerprint {
    Fingerprint::new()
        .with("strip_stage", strip_digest)
        .with("merge.table_version", TABLE_VERSION)
}

pub fn fresh_result(job: &Job, fingerprint: &Fingerprint) -> Option<Merged> {
    fresh_output(job, UNIT, TABLE, fingerprint)
}

impl Stamped for Merged {
    fn digest(&self) -> &str {
        &self.digest
    }
}

pub fn run(job: &Job, chunked: &Chunked, strip_digest: &str) -> anyhow::Result<Merged> {
    let chunk_count = chunked.chunk_count();
    let fingerprint = fingerprint(strip_digest);
    job.note_rebuild(UNIT, &job.freshness(UNIT, &fingerprint), "it");
    if let Some(merged) = fresh_result(job, &fingerprint) {
        job.progress.event(UNIT, "skip", "fresh");
        return Ok(merged);
    }
    let progress = job.progress.stage(UNIT, chunk_count as u64, "chunks");
    let mut chunks = Vec::with_capacity(chunk_count);
    for chunk in 0..chunk_count {
        crate::interrupt::check()?;
        let path = job.work.file(&strip_chunk(chunk));
        let header = StripChunk::open(&path)
            .with_context(|| format!("reading {}", path.display()))?
            .header;
        chunks.push(ChunkSummary {
            strips: header.strip_count as u32,
            nodes: header.node_count as u32,
            data_bytes: header.data_bytes,
            bounds_min: header.bounds_min,
            bounds_max: header.bounds_max,
            stats: header.chunk_stats(),
        });
        progress.advance(1);
    }
    let mut edges = chunked.inner_edges;
    edges.add(border_edges::count_all(
        &job.work,
        chunk_count,
        chunked.border_edges,
    )?);
    let merged = Merged {
        digest: fingerprint.digest(),
        chunks,
        grid: job.config.build_params().grid(&chunked.bounds()),
        weld: chunked.weld,
        edges,
    };
    let written = write_json(job, TABLE, &merged)?;
    job.complete(UNIT, &fingerprint, &[written])?;
    progress.finish(&format!(
        ", {} strips",
        merged.chunks.iter().map(|c| c.strips as u64).sum::<u64>()
    ));
    Ok(merged)
}
