//! Closedness of a model converted in several chunks. The chunk stage finds the positions that
//! triangles of more than one chunk may use ([`shared_positions`]); each chunk counts the edges
//! it holds every use of and writes the rest, its border edges, to a work file of its own; the
//! merge stage adds those up over all chunks ([`count_all`]), in passes over hash partitions of
//! the edges so that memory stays bounded whatever the model's size.
//!
//! A border-edge file is `RDMEDGE1`, the edge count (u64), the edges ([`BorderEdge`], 32 bytes
//! each, in key order), then the XXH3 of the edges: a file damaged where the manifest's
//! checksum cannot see it (after it was hashed) fails the run instead of changing a count.

use std::io::{self, Write};
use std::path::{Path, PathBuf};

use reducem::chunking::{MeshSource, Partition};
use reducem::closedness::{stored_key, BorderEdge, SharedPositions};
use reducem::format::grid::Grid;
use reducem::format::model::Closedness;
use reducem::input::InputError;
use serde::{Deserialize, Serialize};

use crate::workdir::border_edges;

const MAGIC: [u8; 8] = *b"RDMEDGE1";
const HEADER_BYTES: usize = 16;
const TRAILER_BYTES: usize = 8;
const EDGE_BYTES: usize = std::mem::size_of::<BorderEdge>();
/// Border edges held in memory at once by [`count_all`]: 256 MiB of them.
const PASS_EDGES: u64 = (256 << 20) / EDGE_BYTES as u64;

/// Edge counts as the work files' JSON records them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct EdgeCounts {
    pub boundary_edges: u64,
    pub nonmanifold_edges: u64,
}

impl EdgeCounts {
    pub fn add(&mut self, other: Closedness) {
        self.boundary_edges += other.boundary_edges;
        self.nonmanifold_edges += other.nonmanifold_edges;
    }
}

impl From<EdgeCounts> for Closedness {
    fn from(counts: EdgeCounts) -> Closedness {
        Closedness {
            boundary_edges: counts.boundary_edges,
            nonmanifold_edges: counts.nonmanifold_edges,
        }
    }
}

/// One bit per input vertex, set when a triangle of a chunk other than its cell's uses it.
pub struct VertexMarks(Vec<u64>);

impl VertexMarks {
    pub fn new(vertex_count: u64) -> VertexMarks {
        VertexMarks(vec![0; vertex_count.div_ceil(64) as usize])
    }

    /// Notes the vertices of `triangle`, which went to `chunk`, that its cell's chunk does not
    /// hold alone: every vertex of a cell dealt out over several chunks, and every vertex of
    /// another chunk's cell.
    pub fn note(&mut self, partition: &Partition, chunk: u32, triangle: [u32; 3]) {
        for vertex in triangle {
            let cell = partition.vertex_cells[vertex as usize];
            if partition.plan.home_chunk(cell) != Some(chunk) {
                self.0[vertex as usize / 64] |= 1 << (vertex % 64);
            }
        }
    }

    fn contains(&self, vertex: usize) -> bool {
        self.0[vertex / 64] & (1 << (vertex % 64)) != 0
    }
}

/// The stored positions (on `grid` when quantized) that triangles of more than one chunk may
/// use: those of marked vertices, and those a grid moved into another cell, where vertices of
/// another cell may land too. Any other position has all its triangles in its cell's chunk.
pub fn shared_positions(
    source: &dyn MeshSource,
    partition: &Partition,
    marks: &VertexMarks,
    grid: Option<&Grid>,
) -> Result<SharedPositions, InputError> {
    let mut shared = SharedPositions::new(source.vertex_count());
    source.for_each_position_window(&mut |start, positions| {
        for (offset, position) in positions.iter().enumerate() {
            let vertex = start as usize + offset;
            let key = stored_key(position, grid);
            let moved = grid.is_some()
                && partition.cell_of(&key.map(f32::from_bits)) != partition.vertex_cells[vertex];
            if moved || marks.contains(vertex) {
                shared.insert(&key);
            }
        }
    })?;
    Ok(shared)
}

/// Writes `edges` (in key order) as a border-edge file.
pub fn write(out: &mut dyn Write, edges: &[BorderEdge]) -> io::Result<()> {
    let bytes: &[u8] = bytemuck::cast_slice(edges);
    out.write_all(&MAGIC)?;
    out.write_all(&(edges.len() as u64).to_le_bytes())?;
    out.write_all(bytes)?;
    out.write_all(&xxhash_rust::xxh3::xxh3_64(bytes).to_le_bytes())
}

/// A border-edge file that does not hold what was written.
#[derive(Debug, thiserror::Error)]
#[error(
    "{}: border edges damaged ({reason}); the work directory may be damaged: run `pipeline \
     clean` on the configuration, then run the job again",
    path.display()
)]
pub struct DamagedEdges {
    pub path: PathBuf,
    pub reason: String,
}

/// Reads and checks a border-edge file.
pub fn read(path: &Path) -> anyhow::Result<Vec<BorderEdge>> {
    let bytes = std::fs::read(path)?;
    let damaged = |reason: String| DamagedEdges {
        path: path.to_path_buf(),
        reason,
    };
    if bytes.len() < HEADER_BYTES + TRAILER_BYTES || bytes[..8] != MAGIC {
        return Err(damaged("no border-edge header at byte 0".into()).into());
    }
    let word = |at: usize| u64::from_le_bytes(bytes[at..at + 8].try_into().unwrap_or_default());
    let count = word(8);
    let end = HEADER_BYTES as u64 + count.saturating_mul(EDGE_BYTES as u64);
    if end + TRAILER_BYTES as u64 != bytes.len() as u64 {
        let detail = format!(
            "{count} edges at byte 8, but the file has {} bytes",
            bytes.len()
        );
        return Err(damaged(detail).into());
    }
    let edges = &bytes[HEADER_BYTES..end as usize];
    if xxhash_rust::xxh3::xxh3_64(edges) != word(end as usize) {
        let detail = format!("the edges' checksum at byte {end} does not match them");
        return Err(damaged(detail).into());
    }
    Ok(bytemuck::pod_collect_to_vec(edges))
}

/// The counts of every chunk's border edges, reading `chunk_count` files in passes over hash
/// partitions of at most [`PASS_EDGES`] edges each; `border_count` is their total.
pub fn count_all(
    work: &crate::workdir::WorkDir,
    chunk_count: usize,
    border_count: u64,
) -> anyhow::Result<Closedness> {
    let passes = border_count.div_ceil(PASS_EDGES).max(1);
    let mut counts = Closedness::default();
    for pass in 0..passes {
        let mut edges = Vec::new();
        for chunk in 0..chunk_count {
            crate::interrupt::check()?;
            let all = read(&work.file(&border_edges(chunk)))?;
            edges.extend(all.into_iter().filter(|e| partition_of(e, passes) == pass));
        }
        edges.sort_unstable();
        let found = reducem::closedness::count_border_edges(&edges);
        counts.boundary_edges += found.boundary_edges;
        counts.nonmanifold_edges += found.nonmanifold_edges;
    }
    Ok(counts)
}

/// The pass that counts `edge`: every chunk's uses of one edge fall in the same pass.
fn partition_of(edge: &BorderEdge, passes: u64) -> u64 {
    let [a, b, c] = edge.first;
    let [d, e, f] = edge.second;
    reducem::splitmix::hash_words(&[a, b, c, d, e, f]) % passes
}
