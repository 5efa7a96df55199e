//! Streaming binary little-endian PLY writer shared by all generators.
//!
//! The header needs the element counts, so callers declare them up front and
//! the writer checks at `finish` that exactly that many records were written.
//! Records are produced by a [`Generator`] in parallel chunks, encoded as
//! records in the same parallel tasks (`VertexBuf` / `FaceBuf`) and written
//! strictly in chunk order while the next batch is being computed, which
//! keeps the output deterministic and the memory bounded by a few chunks.
//!
//! The file is written to a hidden temporary next to the target and moved over
//! it only after a complete, synced write ([`reducem::atomic::replace`], which
//! also syncs the directory), so an earlier good output is never replaced by a
//! partial one; the temporary is removed on any failure.

use std::fs::{self, File};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{ensure, Context, Result};
use rayon::prelude::*;

use super::{GenSummary, Generator};
use reducem::atomic;

/// Writes `generator`'s mesh to `target`.
pub fn write(generator: &dyn Generator, target: &Target) -> Result<GenSummary> {
    let mut writer = PlyWriter::create(target, generator.summary())?;
    writer.write_vertices(generator.vertex_chunks(), |chunk, out| {
        let mut positions = Vec::new();
        generator.vertex_chunk(chunk, &mut positions);
        positions.into_iter().for_each(|p| out.push(p));
    })?;
    writer.write_faces(generator.face_chunks(), |chunk, out| {
        let mut triangles = Vec::new();
        generator.face_chunk(chunk, &mut triangles);
        triangles.into_iter().for_each(|t| out.push(t));
    })?;
    writer.finish()
}

/// Where a generator writes and the `comment` line naming what it wrote.
pub struct Target<'a> {
    pub path: &'a Path,
    pub comment: &'a str,
}

/// Bytes of one vertex record: three `float`s.
const VERTEX_BYTES: usize = 12;
/// Bytes of one face record: a `uchar` count of 3 and three `int`s.
const FACE_BYTES: usize = 13;

/// A chunk of vertex records in file order.
#[derive(Default)]
pub struct VertexBuf {
    bytes: Vec<u8>,
}

impl VertexBuf {
    pub fn push(&mut self, position: [f32; 3]) {
        let mut record = [0u8; VERTEX_BYTES];
        for (slot, coordinate) in record.chunks_exact_mut(4).zip(position) {
            slot.copy_from_slice(&coordinate.to_le_bytes());
        }
        self.bytes.extend_from_slice(&record);
    }
}

/// A chunk of triangle records in file order.
#[derive(Default)]
pub struct FaceBuf {
    bytes: Vec<u8>,
}

impl FaceBuf {
    /// Indices are below 2^31 (checked when the writer is created), so their
    /// `u32` bytes equal the `int` bytes PLY declares.
    pub fn push(&mut self, triangle: [u32; 3]) {
        let mut record = [3u8; FACE_BYTES];
        for (slot, index) in record[1..].chunks_exact_mut(4).zip(triangle) {
            slot.copy_from_slice(&index.to_le_bytes());
        }
        self.bytes.extend_from_slice(&record);
    }
}

/// Removes the temporary file unless the write completed and was renamed.
struct TemporaryFile {
    path: PathBuf,
    keep: bool,
}

impl Drop for TemporaryFile {
    fn drop(&mut self) {
        if !self.keep {
            let _ = fs::remove_file(&self.path);
        }
    }
}

pub struct PlyWriter {
    file: BufWriter<File>,
    temporary: TemporaryFile,
    target: PathBuf,
    declared: GenSummary,
    written: GenSummary,
}

impl PlyWriter {
    pub fn create(target: &Target, declared: GenSummary) -> Result<Self> {
        ensure!(
            declared.vertices <= i32::MAX as u64,
            "{} vertices exceed the PLY int index range",
            declared.vertices
        );
        let temporary = TemporaryFile {
            path: atomic::temporary_path(target.path),
            keep: false,
        };
        let file = File::create(&temporary.path)
            .with_context(|| format!("cannot create {}", temporary.path.display()))?;
        let mut writer = PlyWriter {
            file: BufWriter::with_capacity(1 << 20, file),
            temporary,
            target: target.path.to_path_buf(),
            declared,
            written: GenSummary::default(),
        };
        writer.write_header(target.comment)?;
        Ok(writer)
    }

    fn write_header(&mut self, comment: &str) -> Result<()> {
        let header = format!(
            "ply\nformat binary_little_endian 1.0\ncomment {comment}\n\
             element vertex {}\nproperty float x\nproperty float y\nproperty float z\n\
             element face {}\nproperty list uchar int vertex_indices\nend_header\n",
            self.declared.vertices, self.declared.triangles
        );
        self.file.write_all(header.as_bytes())?;
        Ok(())
    }

    /// Writes `chunks` chunks of vertices, chunk `i` filled by `produce(i, ..)`.
    pub fn write_vertices(
        &mut self,
        chunks: usize,
        produce: impl Fn(usize, &mut VertexBuf) + Sync,
    ) -> Result<()> {
        ensure!(self.written.triangles == 0, "vertices written after faces");
        let file = &mut self.file;
        let written = &mut self.written.vertices;
        write_ordered(chunks, produce, |chunk: VertexBuf| {
            *written += (chunk.bytes.len() / VERTEX_BYTES) as u64;
            file.write_all(&chunk.bytes)
        })?;
        Ok(())
    }

    /// Writes `chunks` chunks of faces, chunk `i` filled by `produce(i, ..)`.
    pub fn write_faces(
        &mut self,
        chunks: usize,
        produce: impl Fn(usize, &mut FaceBuf) + Sync,
    ) -> Result<()> {
        ensure!(
            self.written.vertices == self.declared.vertices,
            "faces written before all vertices"
        );
        let file = &mut self.file;
        let written = &mut self.written.triangles;
        write_ordered(chunks, produce, |chunk: FaceBuf| {
            *written += (chunk.bytes.len() / FACE_BYTES) as u64;
            file.write_all(&chunk.bytes)
        })?;
        Ok(())
    }

    /// Checks the declared counts were met, syncs, and renames into place.
    pub fn finish(mut self) -> Result<GenSummary> {
        ensure!(
            self.written == self.declared,
            "generator bug: header declares {:?} but {:?} were written",
            self.declared,
            self.written
        );
        self.file.flush()?;
        self.file.get_ref().sync_all()?;
        atomic::replace(&self.temporary.path, &self.target)
            .with_context(|| format!("cannot move output into {}", self.target.display()))?;
        self.temporary.keep = true;
        Ok(self.written)
    }
}

/// Produces chunks in parallel batches and hands them to `consume` in chunk
/// order; consuming one batch overlaps with producing the next, so the disk
/// write and the generation share the cores.
fn write_ordered<B: Default + Send>(
    chunks: usize,
    produce: impl Fn(usize, &mut B) + Sync,
    mut consume: impl FnMut(B) -> io::Result<()> + Send,
) -> io::Result<()> {
    let batch = 2 * rayon::current_num_threads();
    let produce_batch = |start: usize| -> Vec<B> {
        (start..(start + batch).min(chunks))
            .into_par_iter()
            .map(|chunk| {
                let mut buffer = B::default();
                produce(chunk, &mut buffer);
                buffer
            })
            .collect()
    };
    let mut ready: Vec<B> = Vec::new();
    for start in (0..chunks).step_by(batch) {
        let ready_batch = std::mem::take(&mut ready);
        let (consumed, next) = rayon::join(
            || ready_batch.into_iter().try_for_each(&mut consume),
            || produce_batch(start),
        );
        consumed?;
        ready = next;
    }
    ready.into_iter().try_for_each(&mut consume)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn abandoned_write_keeps_previous_output_and_cleans_up() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("mesh.ply");
        fs::write(&out, b"previous good output").unwrap();
        let target = Target {
            path: &out,
            comment: "test",
        };
        let declared = GenSummary {
            vertices: 3,
            triangles: 1,
        };
        let mut writer = PlyWriter::create(&target, declared).unwrap();
        writer
            .write_vertices(1, |_, buf| buf.push([0.0; 3]))
            .unwrap();
        assert!(
            writer.finish().is_err(),
            "short vertex count must be refused"
        );
        assert_eq!(fs::read(&out).unwrap(), b"previous good output");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn chunks_are_written_in_order() {
        let mut seen = Vec::new();
        write_ordered(
            37,
            |chunk, out: &mut Vec<usize>| out.push(chunk),
            |chunk| {
                seen.extend(chunk);
                Ok(())
            },
        )
        .unwrap();
        assert_eq!(seen, (0..37).collect::<Vec<_>>());
    }
}
