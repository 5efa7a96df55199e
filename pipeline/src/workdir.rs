//! The work directory: where each stage's outputs live, and the atomic write every one of them
//! goes through.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};

/// The file that marks a directory as a work directory made by pipeline: `pipeline clean`
/// removes no directory without it (or, from older versions, without a manifest).
pub const MARKER: &str = "pipeline-work-dir";

/// Paths inside a job's work directory.
#[derive(Clone, Debug)]
pub struct WorkDir {
    root: PathBuf,
}

impl WorkDir {
    pub fn new(root: PathBuf) -> WorkDir {
        WorkDir { root }
    }

    pub fn root(&self) -> &Path {
        &self.root
    }

    pub fn manifest(&self) -> PathBuf {
        self.root.join("manifest.json")
    }

    /// A path relative to the root, as recorded in the manifest.
    pub fn file(&self, relative: &str) -> PathBuf {
        self.root.join(relative)
    }

    /// Creates the directory, marks it as made by pipeline, then creates its subdirectories. The
    /// marker comes first and is written in place (its content does not matter, only that it
    /// exists), so a run killed at any moment leaves an empty directory or a marked one, never
    /// a non-empty unmarked one that the next run would refuse as foreign.
    pub fn create(&self) -> io::Result<()> {
        fs::create_dir_all(&self.root)?;
        let marker = self.root.join(MARKER);
        if !marker.exists() {
            fs::write(
                &marker,
                b"A work directory of pipeline: `pipeline clean` removes it whole.\n",
            )?;
        }
        fs::create_dir_all(self.root.join("chunks"))?;
        fs::create_dir_all(self.root.join("strips"))?;
        fs::create_dir_all(self.root.join("locks"))
    }

    pub fn made_by_pipeline(&self) -> bool {
        self.root.join(MARKER).is_file() || self.manifest().is_file()
    }
}

/// Relative path of mesh chunk `index`.
pub fn mesh_chunk(index: usize) -> String {
    format!("chunks/chunk-{index:06}.mesh.zst")
}

/// Relative path of the strip-stage output of chunk `index`.
pub fn strip_chunk(index: usize) -> String {
    format!("strips/chunk-{index:06}.strips")
}

/// Relative path of the border edges of chunk `index` (`crate::border_edges`).
pub fn border_edges(index: usize) -> String {
    format!("chunks/border-{index:06}.edges")
}
