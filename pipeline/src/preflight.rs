//! Checks made before any work, so that a mistake in a job costs seconds, never its input: the
//! output must not be an input of the job (the mesh or the configuration), the work directory
//! must not hold the mesh or the output (`pipeline clean` removes it whole) and must be one the
//! pipeline made (or a new or empty one), the output's directory must take a new file, and the
//! input must have the vertex attributes `[attributes]` asks for.

use std::path::{Component, Path, PathBuf};

use anyhow::Context;

use crate::config::{Config, ConfigError, Input};
use crate::workdir::WorkDir;

/// How a message names the output and the work directory: as the configuration keys, or as
/// the command-line options of `pipeline convert`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Naming {
    Config,
    CommandLine,
}

impl Naming {
    fn output(self) -> &'static str {
        match self {
            Naming::Config => "[output] path",
            Naming::CommandLine => "output",
        }
    }

    fn work(self) -> &'static str {
        match self {
            Naming::Config => "[work] dir",
            Naming::CommandLine => "work directory",
        }
    }
}

/// Why the job's paths are unsafe, as a message naming both paths; `None` when they are safe.
pub fn unsafe_paths(config: &Config, config_path: &Path, naming: Naming) -> Option<String> {
    let output = &config.output.path;
    let mesh = match config.input() {
        Ok(Input::File(path)) => Some(path),
        _ => None,
    };
    let inputs = mesh.iter().map(PathBuf::as_path).chain([config_path]);
    for input in inputs {
        if reducem::atomic::same_file(output, input) {
            return Some(format!(
                "{} {} is the input {} (the same file); writing it would destroy the input, \
                 so choose another output path",
                naming.output(),
                output.display(),
                input.display()
            ));
        }
    }
    let work = config.work_dir();
    let inside_work = mesh.iter().chain([output]).find(|path| inside(&work, path));
    if let Some(path) = inside_work {
        return Some(format!(
            "{} {} contains {}; `pipeline clean` removes the whole work directory, so give \
             the job a directory of its own",
            naming.work(),
            work.display(),
            path.display()
        ));
    }
    foreign_work_dir(&work, naming)
}

/// Fails, naming the input file and the properties it lacks, when `[attributes]` asks for
/// normals or colours that the input does not have (PLY: from the header alone; OBJ: one pass
/// over its lines). Generated meshes have neither.
pub fn check_input_attributes(config: &Config) -> anyhow::Result<()> {
    let request = config.attribute_request();
    if !request.any() {
        return Ok(());
    }
    match config.input() {
        Ok(Input::File(path)) => Ok(reducem::input::check_attributes(&path, request)?),
        Ok(Input::Generate { .. }) => Err(ConfigError::new(
            &config.source,
            "[attributes] asks for normals or colours, but generated meshes ([input.generate]) \
             have neither; give an [input] path to a mesh with them"
                .into(),
        )
        .into()),
        // `Config::parse` has already rejected an invalid `[input]`.
        Err(message) => Err(ConfigError::new(&config.source, message).into()),
    }
}

/// Why `pipeline clean` must not remove the work directory, if it must not.
pub fn unsafe_to_clean(config: &Config, config_path: &Path) -> Option<String> {
    let work = WorkDir::new(config.work_dir());
    if !work.made_by_pipeline() {
        return Some(format!(
            "{} was not made by pipeline (it holds neither {} nor manifest.json); not removing \
             it",
            work.root().display(),
            crate::workdir::MARKER
        ));
    }
    unsafe_paths(config, config_path, Naming::Config)
}

/// An existing work directory is refused unless it is empty or was made by pipeline: it may be
/// a directory of the user's that `pipeline clean` would otherwise remove.
fn foreign_work_dir(work: &Path, naming: Naming) -> Option<String> {
    let entries = match std::fs::read_dir(work) {
        Ok(entries) => entries,
        Err(_) if !work.exists() => return None,
        Err(error) => return Some(format!("{} {}: {error}", naming.work(), work.display())),
    };
    let empty = entries.count() == 0;
    (!empty && !WorkDir::new(work.to_path_buf()).made_by_pipeline()).then(|| {
        format!(
            "{} {} already exists, is not empty and was not made by pipeline (no {} or \
             manifest.json in it); choose a new or empty directory",
            naming.work(),
            work.display(),
            crate::workdir::MARKER
        )
    })
}

/// Creates the output's directory and checks that it takes a new file, before the first stage.
pub fn prepare_output(config: &Config) -> anyhow::Result<()> {
    let output = &config.output.path;
    if let Some(parent) = output.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating the output directory {}", parent.display()))?;
    }
    reducem::atomic::check_writable(output).with_context(|| format!("output {}", output.display()))
}

/// Whether `path` is `dir` or inside it, symlinks resolved.
fn inside(dir: &Path, path: &Path) -> bool {
    resolved(path).starts_with(resolved(dir))
}

/// `path` absolute with its longest existing ancestor canonicalised (symlinks resolved) and the
/// rest appended as written: also defined for paths that do not exist yet.
fn resolved(path: &Path) -> PathBuf {
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf());
    let mut existing = absolute.as_path();
    let mut rest = Vec::new();
    loop {
        if let Ok(canonical) = existing.canonicalize() {
            return rest.iter().rev().fold(canonical, |p, c| p.join(c));
        }
        match (existing.parent(), existing.components().next_back()) {
            (Some(parent), Some(Component::Normal(name))) => {
                rest.push(name.to_os_string());
                existing = parent;
            }
            _ => return absolute,
        }
    }
}
