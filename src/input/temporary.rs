//! Files the readers write under the system's temporary directory while reading an input (a
//! decompressed copy, a welded STL), deleted when dropped; errors found in them name the input.

use std::fs::{File, OpenOptions};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use super::ply::io_error;
use super::{InputError, MeshSource, VertexAttributes};
use crate::geometry::Point;

/// A temporary file standing for the input `original`, deleted when dropped.
pub(crate) struct TemporaryFile {
    original: PathBuf,
    temporary: PathBuf,
}

impl TemporaryFile {
    /// Creates a new empty file for `original`, named after the process, a counter and `name`.
    pub(crate) fn create(original: &Path, name: &str) -> Result<(TemporaryFile, File), InputError> {
        static NEXT: AtomicU64 = AtomicU64::new(0);
        let temporary = std::env::temp_dir().join(format!(
            "reducem-{}-{}-{name}",
            std::process::id(),
            NEXT.fetch_add(1, Ordering::Relaxed)
        ));
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .open(&temporary)
            .map_err(|error| io_error(&temporary, &error))?;
        let created = TemporaryFile {
            original: original.to_path_buf(),
            temporary,
        };
        Ok((created, file))
    }

    pub(crate) fn path(&self) -> &Path {
        &self.temporary
    }

    /// `error` as found in the temporary file, naming the input instead.
    pub(crate) fn rename(&self, mut error: InputError) -> InputError {
        error.path.clone_from(&self.original);
        error
    }
}

impl Drop for TemporaryFile {
    fn drop(&mut self) {
        // The file is ours alone; a failure leaves a file in the temporary directory.
        let _ = std::fs::remove_file(&self.temporary);
    }
}

/// A source read from a temporary file, which it keeps until dropped; its errors name the
/// input.
pub(crate) struct TemporarySource {
    source: Box<dyn MeshSource>,
    file: TemporaryFile,
}

impl TemporarySource {
    pub(crate) fn new(source: Box<dyn MeshSource>, file: TemporaryFile) -> TemporarySource {
        TemporarySource { source, file }
    }
}

impl MeshSource for TemporarySource {
    fn vertex_count(&self) -> u64 {
        self.source.vertex_count()
    }

    fn for_each_position_window(
        &self,
        visit: &mut dyn FnMut(u64, &[Point]),
    ) -> Result<(), InputError> {
        let result = self.source.for_each_position_window(visit);
        result.map_err(|error| self.file.rename(error))
    }

    fn for_each_triangle(&self, visit: &mut dyn FnMut(u64, [u32; 3])) -> Result<(), InputError> {
        let result = self.source.for_each_triangle(visit);
        result.map_err(|error| self.file.rename(error))
    }

    fn positions_of(&self, sorted_ids: &[u32]) -> Result<Vec<Point>, InputError> {
        let result = self.source.positions_of(sorted_ids);
        result.map_err(|error| self.file.rename(error))
    }

    fn attributes_of(&self, sorted_ids: &[u32]) -> Result<VertexAttributes, InputError> {
        let result = self.source.attributes_of(sorted_ids);
        result.map_err(|error| self.file.rename(error))
    }
}
