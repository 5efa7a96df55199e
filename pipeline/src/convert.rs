//! `pipeline convert`: a conversion without a configuration file. It writes the equivalent
//! configuration into the work directory and runs it like `pipeline run`, so the job resumes,
//! reports its status and is cleaned like any other (`pipeline run WORK/convert.toml`). The
//! command removes the work directory once the output is written, unless told to keep it
//! ([`RunOptions::clean_after`]); an unfinished job keeps it, to resume.

use std::path::{Path, PathBuf};

use anyhow::Context;

use crate::config::{Config, VertexEncodingName};
use crate::error::UsageError;
use crate::preflight::{self, Naming};
use crate::progress::Progress;
use crate::run::{self, RunOptions};
use crate::workdir::WorkDir;

/// The configuration's name inside the work directory.
pub const CONFIG_NAME: &str = "convert.toml";

/// What the command line asks for.
pub struct ConvertArgs {
    pub input: PathBuf,
    pub output: PathBuf,
    pub max_length: Option<usize>,
    pub encoding: Option<VertexEncodingName>,
    pub grid_bits: Option<u32>,
    pub work: Option<PathBuf>,
    /// Further configuration keys as `(key, TOML value)`, each key one of [`SETTING_SECTIONS`]
    /// (the Python package's `reducem.convert(..., leaf_windows=4)`, `pipeline convert --face-ids`).
    pub settings: Vec<(String, String)>,
}

/// The configuration keys [`ConvertArgs::settings`] may set, with their table.
pub const SETTING_SECTIONS: [(&str, &str); 10] = [
    ("up", "input"),
    ("leaf_windows", "strip"),
    ("sah_bins", "strip"),
    ("grid_nodes", "strip"),
    ("weld_tolerance", "vertices"),
    ("max_triangles", "chunk"),
    ("face_ids", "attributes"),
    ("normals", "attributes"),
    ("colors", "attributes"),
    ("keep", "work"),
];

pub fn convert(args: &ConvertArgs, options: &RunOptions) -> anyhow::Result<()> {
    convert_reporting(args, options, Progress::new(options.log_format))
}

/// [`convert`] reporting to `progress` instead of as `options.log_format` says.
pub fn convert_reporting(
    args: &ConvertArgs,
    options: &RunOptions,
    progress: Progress,
) -> anyhow::Result<()> {
    if args.grid_bits.is_some() && args.encoding != Some(VertexEncodingName::Grid) {
        anyhow::bail!(UsageError(
            "--grid-bits applies to --encoding grid only".into()
        ));
    }
    check_readable(&args.input)?;
    let text = config_text(args)?;
    let config = Config::parse(Path::new(CONFIG_NAME), &text)
        .map_err(|error| UsageError(format!("invalid options: {}", error.message)))?;
    let work = WorkDir::new(config.work_dir());
    let config_path = work.file(CONFIG_NAME);
    if let Some(message) = preflight::unsafe_paths(&config, &config_path, Naming::CommandLine) {
        anyhow::bail!(UsageError(message));
    }
    preflight::prepare_output(&config)?;
    work.create()
        .with_context(|| format!("creating {}", work.root().display()))?;
    reducem::atomic::write_atomically(&config_path, |out| {
        std::io::Write::write_all(out, text.as_bytes())
    })
    .with_context(|| format!("writing {}", config_path.display()))?;
    run::run_reporting(&config_path, options, progress)
}

/// Fails unless `input` can be opened and read, before anything is created: a mistyped input
/// leaves no work directory and no output directory behind.
fn check_readable(input: &Path) -> anyhow::Result<()> {
    let opened = std::fs::File::open(input).and_then(|file| file.metadata());
    match opened.with_context(|| format!("input {}", input.display()))? {
        metadata if metadata.is_dir() => Err(std::io::Error::new(
            std::io::ErrorKind::IsADirectory,
            format!("input {} is a directory, not a mesh", input.display()),
        )
        .into()),
        _ => Ok(()),
    }
}

/// The configuration equivalent to `args`, with absolute paths (it lives in the work directory).
fn config_text(args: &ConvertArgs) -> anyhow::Result<String> {
    let input = absolute(&args.input)?;
    let output = absolute(&args.output)?;
    let work = match &args.work {
        Some(work) => absolute(work)?,
        None => {
            let mut work = args.output.clone().into_os_string();
            work.push(".work");
            absolute(Path::new(&work))?
        }
    };
    // `[input]` comes first, so its settings go in with its path.
    let input_keys: String = args
        .settings
        .iter()
        .filter(|(key, _)| SETTING_SECTIONS.contains(&(key.as_str(), "input")))
        .map(|(key, value)| format!("{key} = {value}\n"))
        .collect();
    let mut text = format!(
        "# Written by `pipeline convert`; `pipeline run` on this file resumes the same job.\n\
         [input]\npath = {input}\n{input_keys}\n[output]\npath = {output}\n\n[work]\ndir = {work}\n"
    );
    let mut strip = Vec::new();
    if let Some(max_length) = args.max_length {
        strip.push(format!("max_length = {max_length}\n"));
    }
    let mut vertices = Vec::new();
    if let Some(encoding) = args.encoding {
        let name = format!("{encoding:?}").to_lowercase();
        vertices.push(format!("encoding = \"{name}\"\n"));
        if let Some(bits) = args.grid_bits {
            vertices.push(format!("grid_bits = {bits}\n"));
        }
    }
    let mut tables = [
        ("strip", strip),
        ("vertices", vertices),
        ("chunk", Vec::new()),
        ("attributes", Vec::new()),
    ];
    let mut work_keys = String::new();
    for (key, value) in &args.settings {
        let section = SETTING_SECTIONS
            .iter()
            .find(|(name, _)| name == key)
            .map(|(_, section)| *section)
            .ok_or_else(|| UsageError(format!("{key} is not a setting of convert")))?;
        let line = format!("{key} = {value}\n");
        if section == "input" {
            continue;
        }
        match tables.iter_mut().find(|(name, _)| *name == section) {
            Some((_, lines)) => lines.push(line),
            None => work_keys += &line,
        }
    }
    text += &work_keys;
    for (name, lines) in tables {
        if !lines.is_empty() {
            text += &format!("\n[{name}]\n{}", lines.concat());
        }
    }
    Ok(text)
}

/// `path` made absolute, as a TOML string. A JSON string is a valid TOML basic string (the same
/// escapes), so serde_json quotes it.
fn absolute(path: &Path) -> anyhow::Result<String> {
    let absolute =
        std::path::absolute(path).with_context(|| format!("resolving {}", path.display()))?;
    let text = absolute.to_str().ok_or_else(|| {
        UsageError(format!(
            "{} is not valid UTF-8, which a configuration needs",
            path.display()
        ))
    })?;
    Ok(serde_json::to_string(text)?)
}
