//! The job's input: a user file, identified by its content hash (cached in the manifest while
//! path, size and modification time are unchanged, so a rerun does not reread 5 GB), or a
//! synthetic mesh generated into the work directory as a unit of its own.

use std::path::PathBuf;
use std::time::UNIX_EPOCH;

use anyhow::Context;
use reducem::tools::gen;

use crate::config::Input;
use crate::fingerprint::{hash_file, Fingerprint};
use crate::manifest::{Freshness, InputIdentity};
use crate::stage::Job;

/// Where the mesh is and what identifies its content.
pub struct ResolvedInput {
    pub path: PathBuf,
    pub content: String,
}

const GENERATE_UNIT: &str = "generate";

/// Resolves the input, generating it first if the configuration asks for a synthetic mesh.
pub fn resolve(job: &Job) -> anyhow::Result<ResolvedInput> {
    match job.config.input().map_err(anyhow::Error::msg)? {
        Input::File(path) => Ok(ResolvedInput {
            content: content_hash(job, &path)?,
            path,
        }),
        Input::Generate {
            kind,
            triangles,
            seed,
        } => {
            let generated = Generated::new(kind, triangles, seed);
            if job.freshness(GENERATE_UNIT, &generated.fingerprint) != Freshness::Fresh {
                job.progress.event(
                    GENERATE_UNIT,
                    "start",
                    &format!("{kind:?} mesh, {triangles} triangles, seed {seed}"),
                );
                gen::generate(kind, triangles, seed, &job.work.file(&generated.relative))?;
                job.complete(
                    GENERATE_UNIT,
                    &generated.fingerprint,
                    std::slice::from_ref(&generated.relative),
                )?;
            }
            Ok(generated.resolved(job))
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
            Ok(ResolvedInput { path, content })
        }
        Input::Generate {
            kind,
            triangles,
            seed,
        } => {
            let generated = Generated::new(kind, triangles, seed);
            match job.freshness(GENERATE_UNIT, &generated.fingerprint) {
                Freshness::Fresh => Ok(generated.resolved(job)),
                _ => Err("the generated input is not made yet".into()),
            }
        }
    }
}

/// Marks an input content that status could not know without hashing the file.
pub const UNHASHED: &str = "unhashed: ";

/// What status knows of a changed input: its size and modification time.
fn unhashed_content(identity: &InputIdentity) -> String {
    let modified = UNIX_EPOCH + std::time::Duration::from_nanos(identity.modified_ns as u64);
    format!(
        "{UNHASHED}now {} bytes, modified {}",
        identity.bytes,
        crate::time::iso8601(modified)
    )
}

/// A synthetic input: where it goes in the work directory and what it depends on.
struct Generated {
    relative: String,
    fingerprint: Fingerprint,
}

impl Generated {
    fn new(kind: gen::Kind, triangles: u64, seed: u64) -> Generated {
        let name = kind.name();
        Generated {
            relative: format!("generated-{name}-{triangles}-{seed}.ply"),
            fingerprint: Fingerprint::new()
                .with("input.generate.kind", name)
                .with("input.generate.triangles", triangles)
                .with("input.generate.seed", seed),
        }
    }

    /// The generated file's content is fixed by its parameters and the program version.
    fn resolved(&self, job: &Job) -> ResolvedInput {
        ResolvedInput {
            path: job.work.file(&self.relative),
            content: format!("generated:{}", self.fingerprint.digest()),
        }
    }
}

fn content_hash(job: &Job, path: &std::path::Path) -> anyhow::Result<String> {
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

fn identity(path: &std::path::Path) -> std::io::Result<InputIdentity> {
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
