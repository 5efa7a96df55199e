//! The job's input: a user file, identified by its content hash (cached in the manifest while
//! path, size and modification time are unchanged, so a rerun does not reread 5 GB), or a
//! synthetic mesh, identified by its parameters and the generator's version and streamed from
//! the generator into the chunk stage without an input file.

use std::path::Path;
use std::time::UNIX_EPOCH;

use anyhow::Context;
use reducem::input::AttributeRequest;
use reducem::input::MeshSource;
use reducem_gen::{self as gen, GeneratedSource};

use crate::config::Input;
use crate::fingerprint::hash_file;
use crate::job::Job;
use crate::manifest::{InputIdentity, GENERATED, UNHASHED};

/// The mesh and what identifies its content.
pub struct ResolvedInput {
    pub mesh: Input,
    pub content: String,
}

impl ResolvedInput {
    /// The mesh as the chunk stage reads it: a file through windows of `window_bytes`, or the
    /// generator itself.
    pub fn open(
        &self,
        request: AttributeRequest,
        window_bytes: usize,
    ) -> anyhow::Result<Box<dyn MeshSource>> {
        Ok(match &self.mesh {
            Input::File(path) => reducem::input::open_source(path, request, window_bytes)?,
            &Input::Generate {
                kind,
                triangles,
                seed,
            } => Box::new(GeneratedSource::new(kind, triangles, seed)),
        })
    }

    /// The input in words, for logs.
    pub fn describe(&self) -> String {
        match &self.mesh {
            Input::File(path) => path.display().to_string(),
            Input::Generate { .. } => format!(
                "the {} (streamed from the generator, no input file)",
                self.content.trim_start_matches(GENERATED)
            ),
        }
    }

    /// What names the input in errors: its path, or the configuration table of a generated mesh.
    pub fn name(&self) -> &Path {
        match &self.mesh {
            Input::File(path) => path,
            Input::Generate { .. } => Path::new("[input.generate]"),
        }
    }
}

/// Resolves the input, hashing a file whose identity is not cached.
pub fn resolve(job: &Job) -> anyhow::Result<ResolvedInput> {
    match job.config.input().map_err(anyhow::Error::msg)? {
        Input::File(path) => Ok(ResolvedInput {
            content: content_hash(job, &path)?,
            mesh: Input::File(path),
        }),
        generated => {
            remove_former_generated_files(job)?;
            Ok(ResolvedInput {
                content: generated_content(&generated),
                mesh: generated,
            })
        }
    }
}

/// The input as far as it is known without doing any work (for `status`).
pub fn peek(job: &Job) -> Result<ResolvedInput, String> {
    match job.config.input()? {
        Input::File(path) => {
            let identity = identity(&path).map_err(|e| format!("input {}: {e}", path.display()))?;
            let cached = job
                .manifest()
                .input
                .clone()
                .filter(|c| same_identity(c, &identity));
            let content = cached.map_or_else(|| unhashed_content(&identity), |c| c.hash);
            Ok(ResolvedInput {
                mesh: Input::File(path),
                content,
            })
        }
        generated => Ok(ResolvedInput {
            content: generated_content(&generated),
            mesh: generated,
        }),
    }
}

/// A generated mesh is fixed by its parameters and the generator's version; the words are what
/// `status` shows when they change.
fn generated_content(input: &Input) -> String {
    match input {
        Input::Generate {
            kind,
            triangles,
            seed,
        } => format!(
            "{GENERATED}{kind} mesh of about {triangles} triangles, seed {seed}, generator version {}",
            gen::GENERATOR_VERSION
        ),
        Input::File(path) => format!("file {}", path.display()),
    }
}

/// Earlier versions generated the input into the work directory as a PLY file (19 GB for a
/// billion-triangle scan); it is no longer read, so a work directory holding one loses it.
fn remove_former_generated_files(job: &Job) -> anyhow::Result<()> {
    let Ok(entries) = std::fs::read_dir(job.work.root()) else {
        return Ok(());
    };
    for entry in entries.flatten() {
        let name = entry.file_name().to_string_lossy().into_owned();
        if name.starts_with("generated-") && name.ends_with(".ply") {
            let path = entry.path();
            std::fs::remove_file(&path).with_context(|| format!("removing {}", path.display()))?;
            job.progress.event(
                "input",
                "clean",
                &format!(
                    "removed {}, a generated input no longer used",
                    path.display()
                ),
            );
        }
    }
    Ok(())
}

/// What status knows of a changed input: its size and modification time.
fn unhashed_content(identity: &InputIdentity) -> String {
    let modified = UNIX_EPOCH + std::time::Duration::from_nanos(identity.modified_ns as u64);
    format!(
        "{UNHASHED}now {} bytes, modified {}",
        identity.bytes,
        crate::time::iso8601(modified)
    )
}

fn content_hash(job: &Job, path: &Path) -> anyhow::Result<String> {
    let identity = identity(path).with_context(|| format!("reading {}", path.display()))?;
    if let Some(cached) = job
        .manifest()
        .input
        .clone()
        .filter(|c| same_identity(c, &identity))
    {
        return Ok(cached.hash);
    }
    job.progress
        .event("input", "start", &format!("hashing {}", path.display()));
    let hash = hash_file(path).with_context(|| format!("reading {}", path.display()))?;
    job.update_manifest(|manifest| {
        manifest.input = Some(InputIdentity {
            hash: hash.clone(),
            ..identity
        })
    })?;
    Ok(hash)
}

fn identity(path: &Path) -> std::io::Result<InputIdentity> {
    let meta = std::fs::metadata(path)?;
    let modified_ns = meta
        .modified()?
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos());
    Ok(InputIdentity {
        path: std::fs::canonicalize(path)?.display().to_string(),
        bytes: meta.len(),
        modified_ns,
        hash: String::new(),
    })
}

fn same_identity(cached: &InputIdentity, current: &InputIdentity) -> bool {
    cached.path == current.path
        && cached.bytes == current.bytes
        && cached.modified_ns == current.modified_ns
}
