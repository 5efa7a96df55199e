//! Stage *chunk*: one streaming partition of the input into spatially compact chunks of at most
//! `[chunk] max_triangles` triangles, each written with its own welded local vertex array,
//! zstd-compressed (`reducem::chunking` has the algorithm).
//!
//! The stage is one unit: a run killed inside it redoes it from the start, since its passes
//! share one plan. Triangles are first spilled per chunk as global vertex indices (12 bytes
//! each), then each chunk gathers its positions with `positions_of` and is written on its own,
//! so memory holds one chunk at a time, plus the 2-byte cell of every vertex (and, with a
//! `[vertices] weld_tolerance`, every position while the model-wide weld is computed).

use std::fs::{self, File};
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::Path;

use anyhow::Context;
use reducem::chunking::{self, MeshSource, Partition};
use reducem::geometry::{Aabb, Point};
use reducem::input::{InputError, PlyStream, WeldStats};
use serde::{Deserialize, Serialize};

use crate::chunk_io;
use crate::fingerprint::Fingerprint;
use crate::input::ResolvedInput;
use crate::stage::{for_each_unit, fresh_output, write_json, Job, Stamped};
use crate::workdir::mesh_chunk;

pub const UNIT: &str = "chunk";
const PLAN: &str = "chunks/plan.json";

/// The stage's result as later stages need it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Chunked {
    pub digest: String,
    pub triangles_per_chunk: Vec<u64>,
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    pub weld: WeldStats,
}

impl Chunked {
    pub fn chunk_count(&self) -> usize {
        self.triangles_per_chunk.len()
    }

    /// The bounds of every input vertex: the model grid is laid over them.
    pub fn bounds(&self) -> Aabb {
        Aabb {
            min: self.bounds_min,
            max: self.bounds_max,
        }
    }
}

pub fn fingerprint(job: &Job, input: &ResolvedInput) -> Fingerprint {
    Fingerprint::new()
        .with("input", &input.content)
        .with("chunk.max_triangles", job.config.chunk.max_triangles)
        .with(
            "vertices.weld_tolerance",
            job.config.vertices.weld_tolerance,
        )
}

/// The recorded result, if the stage is fresh.
pub fn fresh_result(job: &Job, fingerprint: &Fingerprint) -> Option<Chunked> {
    fresh_output(job, UNIT, PLAN, fingerprint)
}

impl Stamped for Chunked {
    fn digest(&self) -> &str {
        &self.digest
    }
}

pub fn run(job: &Job, input: &ResolvedInput) -> anyhow::Result<Chunked> {
    let fingerprint = fingerprint(job, input);
    if let Some(chunked) = fresh_result(job, &fingerprint) {
        job.progress.event(
            UNIT,
            "skip",
            &format!("fresh, {} chunks", chunked.chunk_count()),
        );
        return Ok(chunked);
    }
    clear_chunks(job)?;
    let (source, weld) = chunking::weld_source(
        open_source(&input.path)?,
        job.config.vertices.weld_tolerance,
    )?;
    let partition = chunking::partition(&*source, job.config.chunk.max_triangles)?;
    let triangles_per_chunk = spill(job, &*source, &partition)?;
    let progress = job
        .progress
        .stage(UNIT, triangles_per_chunk.len() as u64, "chunks");
    let chunks: Vec<usize> = (0..triangles_per_chunk.len()).collect();
    for_each_unit(&chunks, |chunk| {
        write_chunk(job, &*source, chunk)?;
        progress.advance(1);
        Ok(())
    })?;
    let mut outputs: Vec<String> = chunks.iter().map(|&chunk| mesh_chunk(chunk)).collect();
    let chunked = Chunked {
        digest: fingerprint.digest(),
        triangles_per_chunk,
        bounds_min: partition.bounds.min,
        bounds_max: partition.bounds.max,
        weld,
    };
    write_json(&job.work.file(PLAN), &chunked)?;
    outputs.push(PLAN.to_string());
    job.complete(UNIT, &fingerprint, &outputs)?;
    progress.finish(&format!(", {} chunks", chunked.chunk_count()));
    Ok(chunked)
}

/// Bytes of input mapped at a time by the streaming passes.
const WINDOW_BYTES: usize = 64 << 20;

/// The input as a [`MeshSource`]: binary PLY streams through bounded windows; inputs that
/// cannot be streamed (ASCII PLY, OBJ: small in practice) are read whole.
fn open_source(path: &Path) -> anyhow::Result<Box<dyn MeshSource>> {
    let is_ply = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("ply"));
    if is_ply {
        let stream = PlyStream::open(path)?;
        if stream.is_streamable() {
            return Ok(Box::new(WindowedPly(stream)));
        }
    }
    Ok(Box::new(reducem::input::read_mesh(path)?))
}

/// A binary PLY read through windows of [`WINDOW_BYTES`].
struct WindowedPly(PlyStream);

impl MeshSource for WindowedPly {
    fn vertex_count(&self) -> u64 {
        self.0.vertex_count()
    }

    fn for_each_position_window(
        &self,
        visit: &mut dyn FnMut(u64, &[Point]),
    ) -> Result<(), InputError> {
        self.0.for_each_position_window(WINDOW_BYTES, visit)
    }

    fn for_each_triangle(&self, visit: &mut dyn FnMut(u64, [u32; 3])) -> Result<(), InputError> {
        self.0.for_each_triangle(WINDOW_BYTES, visit)
    }

    fn positions_of(&self, sorted_ids: &[u32]) -> Result<Vec<Point>, InputError> {
        self.0.positions_of(sorted_ids, WINDOW_BYTES)
    }
}

fn clear_chunks(job: &Job) -> anyhow::Result<()> {
    let dir = job.work.file("chunks");
    if dir.exists() {
        fs::remove_dir_all(&dir).with_context(|| format!("clearing {}", dir.display()))?;
    }
    fs::create_dir_all(&dir).with_context(|| format!("creating {}", dir.display()))
}

fn spill_path(job: &Job, chunk: usize) -> std::path::PathBuf {
    job.work.file(&format!("chunks/spill-{chunk:06}.ids"))
}

/// Writes every triangle's global vertex indices to its chunk's spill file.
fn spill(job: &Job, source: &dyn MeshSource, partition: &Partition) -> anyhow::Result<Vec<u64>> {
    let chunk_count = partition.plan.chunk_count();
    let mut writers = (0..chunk_count)
        .map(|chunk| {
            let path = spill_path(job, chunk);
            File::create(&path)
                .map(|f| BufWriter::with_capacity(1 << 16, f))
                .with_context(|| format!("creating {}", path.display()))
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let mut counts = vec![0u64; chunk_count];
    let mut first_error = None;
    chunking::distribute(source, partition, &mut |chunk, triangle| {
        counts[chunk as usize] += 1;
        if first_error.is_none() {
            first_error = writers[chunk as usize]
                .write_all(bytemuck::cast_slice(&triangle))
                .err();
        }
    })?;
    if let Some(error) = first_error {
        return Err(error).context("writing spill files");
    }
    for writer in &mut writers {
        writer.flush().context("writing spill files")?;
    }
    Ok(counts)
}

/// Turns one spill file into a mesh chunk and removes the spill.
fn write_chunk(job: &Job, source: &dyn MeshSource, chunk: usize) -> anyhow::Result<()> {
    let spill = spill_path(job, chunk);
    let mut bytes = Vec::new();
    BufReader::new(File::open(&spill)?).read_to_end(&mut bytes)?;
    let triangles: Vec<[u32; 3]> = bytemuck::pod_collect_to_vec(&bytes);
    drop(bytes);
    let mesh = chunking::local_mesh(&triangles, |distinct| source.positions_of(distinct))?;
    let mesh = reducem::input::weld_identical_positions(mesh);
    let relative = mesh_chunk(chunk);
    let path = job.work.file(&relative);
    reducem::atomic::write_atomically(&path, |out| chunk_io::write_mesh(out, &mesh))
        .with_context(|| format!("writing {}", path.display()))?;
    fs::remove_file(&spill).with_context(|| format!("removing {}", spill.display()))
}
