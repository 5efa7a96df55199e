//! A generated mesh read by the out-of-core chunker as a [`MeshSource`], without a file: the
//! chunker's passes over positions and triangles run the generator again (chunks produced in
//! parallel batches, visited in order), and a chunk's vertices are computed on demand.
//!
//! This removes the input file from a job on a generated mesh: a billion-triangle scan's PLY is
//! 19 GB, more than the chunk stage's own spill and chunk files. Time is about even: the chunk
//! stage of a 100M scan takes 16.3 s generated, against 3.2 s to write the PLY and 15.6 s to
//! hash and chunk it (partition runs the generator twice over the positions and twice over the
//! triangles).
//!
//! Kinds with random access to their vertices ([`Generator::positions_of`]: scan, soup,
//! terrain) give a chunk's positions directly; for the others, the vertex chunks holding the
//! wanted ids are generated again, which the first position pass makes possible by recording
//! where each vertex chunk starts. Either way the positions are bit-identical to the PLY that
//! [`super::generate`] writes, so the converted file is byte-identical too.

use std::sync::OnceLock;

use rayon::prelude::*;

use super::{GenSummary, Generator, Kind};
use reducem::chunking::MeshSource;
use reducem::geometry::Point;
use reducem::input::{InputError, VertexAttributes};

/// The mesh of `kind` with about `triangles` triangles from seed `seed`, as a chunker source.
pub struct GeneratedSource {
    generator: Box<dyn Generator>,
    summary: GenSummary,
    /// The first vertex id of every vertex chunk, and the vertex count last.
    vertex_chunk_starts: OnceLock<Vec<u64>>,
}

/// Chunks produced in parallel per batch, per thread.
const CHUNKS_PER_THREAD: usize = 4;

impl GeneratedSource {
    pub fn new(kind: Kind, triangles: u64, seed: u64) -> GeneratedSource {
        let generator = super::generator(kind, triangles, seed);
        GeneratedSource {
            summary: generator.summary(),
            generator,
            vertex_chunk_starts: OnceLock::new(),
        }
    }

    pub fn summary(&self) -> GenSummary {
        self.summary
    }

    fn vertex_chunk_starts(&self) -> &[u64] {
        self.vertex_chunk_starts.get_or_init(|| {
            let mut starts = vec![0];
            in_order(
                self.generator.vertex_chunks(),
                |chunk, out| self.generator.vertex_chunk(chunk, out),
                |positions| starts.push(starts[starts.len() - 1] + positions.len() as u64),
            );
            starts
        })
    }

    /// Positions of `sorted_ids` from the vertex chunks holding them, generated again.
    fn positions_from_chunks(&self, sorted_ids: &[u32]) -> Vec<Point> {
        let starts = self.vertex_chunk_starts();
        let chunk_of = |id: u32| starts.partition_point(|&start| start <= id as u64) - 1;
        let runs: Vec<&[u32]> = sorted_ids
            .chunk_by(|&a, &b| chunk_of(a) == chunk_of(b))
            .collect();
        let picked: Vec<Vec<Point>> = runs
            .par_iter()
            .map(|ids| {
                let chunk = chunk_of(ids[0]);
                let mut positions = Vec::new();
                self.generator.vertex_chunk(chunk, &mut positions);
                let start = starts[chunk];
                ids.iter()
                    .map(|&id| positions[(id as u64 - start) as usize])
                    .collect()
            })
            .collect();
        picked.concat()
    }
}

impl MeshSource for GeneratedSource {
    fn vertex_count(&self) -> u64 {
        self.summary.vertices
    }

    fn for_each_position_window(
        &self,
        visit: &mut dyn FnMut(u64, &[Point]),
    ) -> Result<(), InputError> {
        let mut starts = vec![0u64];
        in_order(
            self.generator.vertex_chunks(),
            |chunk, out| self.generator.vertex_chunk(chunk, out),
            |positions| {
                let first = starts[starts.len() - 1];
                visit(first, &positions);
                starts.push(first + positions.len() as u64);
            },
        );
        let _ = self.vertex_chunk_starts.set(starts);
        Ok(())
    }

    /// Face ids are face indices: every generated face is a triangle.
    fn for_each_triangle(&self, visit: &mut dyn FnMut(u64, [u32; 3])) -> Result<(), InputError> {
        let mut face = 0u64;
        in_order(
            self.generator.face_chunks(),
            |chunk, out| self.generator.face_chunk(chunk, out),
            |triangles| {
                for triangle in triangles {
                    visit(face, triangle);
                    face += 1;
                }
            },
        );
        Ok(())
    }

    fn positions_of(&self, sorted_ids: &[u32]) -> Result<Vec<Point>, InputError> {
        Ok(self
            .generator
            .positions_of(sorted_ids)
            .unwrap_or_else(|| self.positions_from_chunks(sorted_ids)))
    }

    /// Generated meshes have no normals or colours (the pipeline refuses jobs asking for them).
    fn attributes_of(&self, _sorted_ids: &[u32]) -> Result<VertexAttributes, InputError> {
        Ok(VertexAttributes::default())
    }
}

/// Produces `chunks` chunks in parallel batches and hands them to `visit` in chunk order; a
/// batch holds a few chunks per thread, so memory stays a few chunks whatever the mesh size.
fn in_order<T: Send>(
    chunks: usize,
    produce: impl Fn(usize, &mut Vec<T>) + Sync,
    mut visit: impl FnMut(Vec<T>),
) {
    let batch = CHUNKS_PER_THREAD * rayon::current_num_threads();
    for start in (0..chunks).step_by(batch) {
        let produced: Vec<Vec<T>> = (start..(start + batch).min(chunks))
            .into_par_iter()
            .map(|chunk| {
                let mut out = Vec::new();
                produce(chunk, &mut out);
                out
            })
            .collect();
        produced.into_iter().for_each(&mut visit);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The source's positions, triangles and random-access positions against the PLY that
    /// `generate` writes, for every kind.
    #[test]
    fn every_kind_streams_the_mesh_it_writes() {
        for kind in Kind::ALL {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("mesh.ply");
            super::super::generate(kind, 3000, 4, &path).unwrap();
            let ply = reducem::input::PlyFile::open(&path)
                .unwrap()
                .read_mesh_with(Default::default())
                .unwrap();
            let source = GeneratedSource::new(kind, 3000, 4);
            let mut positions = Vec::new();
            source
                .for_each_position_window(&mut |first, window| {
                    assert_eq!(first, positions.len() as u64);
                    positions.extend_from_slice(window);
                })
                .unwrap();
            let bits = |points: &[Point]| -> Vec<[u32; 3]> {
                points.iter().map(|p| p.map(f32::to_bits)).collect()
            };
            assert_eq!(bits(&positions), bits(&ply.positions), "{kind:?} positions");
            let mut triangles = Vec::new();
            source
                .for_each_triangle(&mut |face, triangle| {
                    assert_eq!(face, triangles.len() as u64);
                    triangles.push(triangle);
                })
                .unwrap();
            assert_eq!(triangles, ply.triangles, "{kind:?} triangles");
            let every_third: Vec<u32> = (0..positions.len() as u32).step_by(3).collect();
            let picked = source.positions_of(&every_third).unwrap();
            let expected: Vec<Point> = every_third.iter().map(|&v| positions[v as usize]).collect();
            assert_eq!(bits(&picked), bits(&expected), "{kind:?} positions_of");
            let fresh = GeneratedSource::new(kind, 3000, 4);
            let picked = fresh.positions_of(&every_third).unwrap();
            assert_eq!(
                bits(&picked),
                bits(&expected),
                "{kind:?} positions_of first"
            );
        }
    }
}
