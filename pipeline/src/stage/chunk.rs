//! Stage *chunk*: one streaming partition of the input into spatially compact chunks of at most
//! `[chunk] max_triangles` triangles, each written with its own welded local vertex array,
//! zstd-compressed (`reducem::chunking` has the algorithm).
//!
//! The stage is one unit: a run killed inside it redoes it from the start, since its passes
//! share one plan. Triangles are first spilled per chunk as global vertex indices (12 bytes
//! each), then each chunk gathers its positions with `positions_of` and is written on its own,
//! so memory holds one chunk at a time per thread, plus, while partitioning, the 2-byte cell of
//! every vertex (and, with a `[vertices] weld_tolerance`, every position while the model-wide
//! weld is computed).
//!
//! A generated input (`[input.generate]`) is read the same way from the generator itself, which
//! runs once per pass (twice over the positions, twice over the triangles) and computes each
//! chunk's vertices on demand: no input file is written.
//!
//! Each chunk also counts the edges it holds every use of and writes the others, its border
//! edges, for the merge stage to add up (`crate::border_edges`): spilling marks the vertices
//! of chunks other than their cell's (1 bit a vertex), and one more pass over the positions
//! turns the marks into a set of shared positions (2 to 4 bits a vertex).
//!
//! With `[attributes] face_ids`, each spilled triangle carries its global input face id (16
//! bytes instead of 12) and the chunk mesh keeps them; with normals or colours, each chunk
//! reads them for its own vertices beside their positions.

use std::fs::{self, File};
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::Path;

use anyhow::Context;
use reducem::chunking::{self, MeshSource, Partition};
use reducem::closedness::{count_chunk_edges, PositionKey, SharedPositions};
use reducem::format::grid::Grid;
use reducem::geometry::Aabb;
use reducem::input::{InputError, InputErrorKind, Location, WeldStats};
use reducem::quantize::quantize_mesh;
use serde::{Deserialize, Serialize};

use crate::border_edges::{self, EdgeCounts, VertexMarks};
use crate::checksum::Checksum;
use crate::chunk_io;
use crate::fingerprint::Fingerprint;
use crate::input::ResolvedInput;
use crate::stage::{for_each_unit, fresh_output, write_json, Job, Stamped};
use crate::workdir::{border_edges as border_file, mesh_chunk};

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
    /// Edge counts over the edges whose every use lies in one chunk.
    pub inner_edges: EdgeCounts,
    /// Border edges written over all chunks, each chunk's uses of an edge once.
    pub border_edges: u64,
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
    let attributes = job.config.build_params().attributes;
    Fingerprint::new()
        .with("input", &input.content)
        .with("chunk.max_triangles", job.config.chunk.max_triangles)
        .with(
            "vertices.weld_tolerance",
            job.config.vertices.weld_tolerance,
        )
        .with("attributes.face_ids", attributes.face_ids)
        .with("attributes.normals", attributes.normals.name())
        .with("attributes.colors", attributes.colors)
        .with("chunk.border_edges", BORDER_EDGES_VERSION)
}

/// Version of the chunk stage's edge outputs (the border-edge files and the plan's counts).
const BORDER_EDGES_VERSION: u32 = 1;

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
    job.note_rebuild(UNIT, &job.freshness(UNIT, &fingerprint), "every chunk");
    if let Some(chunked) = fresh_result(job, &fingerprint) {
        job.progress.event(
            UNIT,
            "skip",
            &format!("fresh, {} chunks", chunked.chunk_count()),
        );
        return Ok(chunked);
    }
    clear_chunks(job)?;
    let started = std::time::Instant::now();
    job.progress
        .event(UNIT, "partition", &format!("reading {}", input.describe()));
    let request = job.config.attribute_request();
    let (source, weld) = chunking::weld_source(
        input.open(request, WINDOW_BYTES)?,
        job.config.vertices.weld_tolerance,
        request,
    )?;
    let partition = chunking::partition(&*source, job.config.chunk.max_triangles)?;
    let face_ids = job.config.attributes.face_ids;
    let mut marks = VertexMarks::new(source.vertex_count());
    let triangles_per_chunk = spill(
        job,
        &*source,
        &partition,
        &mut marks,
        face_ids,
        input.name(),
    )?;
    let bounds = partition.bounds;
    let grid = job.config.build_params().grid(&bounds);
    // A tolerance weld with attributes moves vertices onto others' positions, which the
    // position pass does not see; every position is then taken as shared.
    let shared = match job.config.vertices.weld_tolerance > 0.0 && request.any() {
        true => SharedPositions::everything(),
        false => border_edges::shared_positions(&*source, &partition, &marks, grid.as_ref())?,
    };
    // Every vertex's cell (2 bytes a vertex, 1 GB for a billion triangles) is no longer needed.
    drop((partition, marks));
    let triangles: u64 = triangles_per_chunk.iter().sum();
    if triangles == 0 {
        return Err(NoTriangles(input.name().to_path_buf()).into());
    }
    job.progress.event(
        UNIT,
        "partition",
        &format!(
            "{triangles} triangles partitioned and spilled in {:.1} s",
            started.elapsed().as_secs_f64()
        ),
    );
    let progress = job
        .progress
        .stage(UNIT, triangles_per_chunk.len() as u64, "chunks");
    let chunks: Vec<usize> = (0..triangles_per_chunk.len()).collect();
    let written = std::sync::Mutex::new(ChunkOutputs::default());
    for_each_unit(&chunks, |chunk| {
        let edges = EdgeContext {
            shared: &shared,
            grid: grid.as_ref(),
        };
        let output = write_chunk(job, &*source, chunk, face_ids, &edges)?;
        written
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .add(output);
        progress.advance(1);
        Ok(())
    })?;
    let written = written.into_inner().unwrap_or_else(|p| p.into_inner());
    let mut outputs = written.files;
    let chunked = Chunked {
        digest: fingerprint.digest(),
        triangles_per_chunk,
        bounds_min: bounds.min,
        bounds_max: bounds.max,
        weld,
        inner_edges: written.inner_edges,
        border_edges: written.border_edges,
    };
    outputs.push(write_json(job, PLAN, &chunked)?);
    job.complete(UNIT, &fingerprint, &outputs)?;
    progress.finish(&format!(", {} chunks", chunked.chunk_count()));
    Ok(chunked)
}

/// What the chunks wrote: their files, and their edge counts summed.
#[derive(Default)]
struct ChunkOutputs {
    files: Vec<(String, Checksum)>,
    inner_edges: EdgeCounts,
    border_edges: u64,
}

impl ChunkOutputs {
    fn add(&mut self, chunk: WrittenChunk) {
        self.files.extend(chunk.files);
        self.inner_edges.add(chunk.inner_edges);
        self.border_edges += chunk.border_edges;
    }
}

/// What one chunk wrote.
struct WrittenChunk {
    files: [(String, Checksum); 2],
    inner_edges: reducem::format::model::Closedness,
    border_edges: u64,
}

/// What a chunk needs to tell its border edges: the shared positions, and the model grid its
/// vertices will be stored on.
struct EdgeContext<'a> {
    shared: &'a SharedPositions,
    grid: Option<&'a Grid>,
}

/// The input holds no triangle: there is nothing to convert (bad input, not an empty file).
#[derive(Debug, thiserror::Error)]
#[error("{}: the mesh has no triangles, so there is nothing to convert", .0.display())]
pub struct NoTriangles(pub std::path::PathBuf);

/// Bytes of input mapped at a time by the streaming passes.
const WINDOW_BYTES: usize = 64 << 20;

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

/// Writes every triangle's global vertex indices, and with `face_ids` its input face, to its
/// chunk's spill file (`input` names the file in errors).
fn spill(
    job: &Job,
    source: &dyn MeshSource,
    partition: &Partition,
    marks: &mut VertexMarks,
    face_ids: bool,
    input: &Path,
) -> anyhow::Result<Vec<u64>> {
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
    let mut face_beyond_u32 = None;
    chunking::distribute(source, partition, &mut |chunk, face, triangle| {
        counts[chunk as usize] += 1;
        marks.note(partition, chunk, triangle);
        if first_error.is_some() {
            return;
        }
        let writer = &mut writers[chunk as usize];
        let written = writer.write_all(bytemuck::cast_slice(&triangle));
        first_error = match (written, u32::try_from(face)) {
            (Err(error), _) => Some(error),
            (Ok(()), _) if !face_ids => None,
            (Ok(()), Ok(face)) => writer.write_all(&face.to_le_bytes()).err(),
            (Ok(()), Err(_)) => {
                face_beyond_u32.get_or_insert(face);
                None
            }
        }
        .map(|error| (chunk as usize, error));
    })?;
    if let Some(face) = face_beyond_u32 {
        let kind = InputErrorKind::TooManyFaces {
            face_count: face + 1,
        };
        return Err(InputError::new(input, Location::File, kind).into());
    }
    if let Some((chunk, error)) = first_error {
        let path = spill_path(job, chunk);
        return Err(error).with_context(|| format!("writing {}", path.display()));
    }
    for (chunk, writer) in writers.iter_mut().enumerate() {
        let path = spill_path(job, chunk);
        writer
            .flush()
            .with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(counts)
}

/// Turns one spill file into a mesh chunk and its border edges, and removes the spill.
fn write_chunk(
    job: &Job,
    source: &dyn MeshSource,
    chunk: usize,
    face_ids: bool,
    edges: &EdgeContext,
) -> anyhow::Result<WrittenChunk> {
    let spill = spill_path(job, chunk);
    let mut bytes = Vec::new();
    File::open(&spill)
        .and_then(|file| BufReader::new(file).read_to_end(&mut bytes))
        .with_context(|| format!("reading {}", spill.display()))?;
    let (triangles, face_ids) = if face_ids {
        let records: Vec<[u32; 4]> = bytemuck::pod_collect_to_vec(&bytes);
        let triangles: Vec<[u32; 3]> = records.iter().map(|r| [r[0], r[1], r[2]]).collect();
        (triangles, Some(records.iter().map(|r| r[3]).collect()))
    } else {
        (bytemuck::pod_collect_to_vec(&bytes), None)
    };
    drop(bytes);
    let mesh = chunking::local_mesh(&triangles, face_ids, |distinct| {
        chunking::vertices_of(source, distinct)
    })?;
    let mesh = reducem::input::weld_identical_positions(mesh);
    let mesh_file = job.write_output(&mesh_chunk(chunk), |mut out| {
        chunk_io::write_mesh(&mut out, &mesh)
    })?;
    let shared = |key: &PositionKey| edges.shared.contains(key);
    // Counted as stored: on the grid, snapping can join or part edges.
    let (inner_edges, border) = match edges.grid {
        Some(grid) => count_chunk_edges(&quantize_mesh(&mesh, grid).mesh, shared),
        None => count_chunk_edges(&mesh, shared),
    };
    let edge_file =
        job.write_output(&border_file(chunk), |out| border_edges::write(out, &border))?;
    fs::remove_file(&spill).with_context(|| format!("removing {}", spill.display()))?;
    Ok(WrittenChunk {
        files: [mesh_file, edge_file],
        inner_edges,
        border_edges: border.len() as u64,
    })
}
