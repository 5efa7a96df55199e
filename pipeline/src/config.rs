//! The job configuration: a TOML file whose every key is known (unknown keys are errors with
//! line and column), relative paths resolved against the file's directory.

use std::path::{Path, PathBuf};

use serde::Deserialize;

use reducem::format::attributes::AttributeSet;
use reducem::format::attributes::NormalEncoding;
use reducem_gen::Kind;

use crate::workdir::WorkDir;

/// A configuration problem, naming the file and, for syntax and unknown keys, line and column.
#[derive(Debug, thiserror::Error)]
#[error("{}: {message}", path.display())]
pub struct ConfigError {
    pub path: PathBuf,
    pub message: String,
}

impl ConfigError {
    pub fn new(path: &Path, message: String) -> ConfigError {
        ConfigError {
            path: path.to_path_buf(),
            message,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Config {
    pub input: InputConfig,
    pub output: OutputConfig,
    #[serde(default)]
    pub chunk: ChunkConfig,
    #[serde(default)]
    pub strip: StripConfig,
    #[serde(default)]
    pub vertices: VerticesConfig,
    #[serde(default)]
    pub work: WorkConfig,
    #[serde(default)]
    pub attributes: AttributesConfig,
    /// The configuration file itself (where the default work directory goes).
    #[serde(skip)]
    pub source: PathBuf,
}

/// Exactly one of `path` (a PLY, OBJ, STL or glTF/GLB file, also gzip- or zstd-compressed) and `generate` (a synthetic mesh).
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InputConfig {
    pub path: Option<PathBuf>,
    pub generate: Option<GenerateConfig>,
    /// The model's up axis, `"y"` or `"z"`, stored as a hint for viewers; by default z for STL
    /// and y otherwise ([`reducem::closedness::default_up`]).
    #[serde(default)]
    pub up: Option<UpName>,
}

/// `[input] up`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpName {
    Y,
    Z,
}

impl InputConfig {
    /// The up axis to store: the configured one, else the default of the input's format.
    pub fn up_axis(&self) -> reducem::format::model::UpAxis {
        use reducem::format::model::UpAxis;
        match (self.up, &self.path) {
            (Some(UpName::Y), _) => UpAxis::Y,
            (Some(UpName::Z), _) => UpAxis::Z,
            (None, Some(path)) => reducem::closedness::default_up(path),
            (None, None) => UpAxis::Y,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GenerateConfig {
    pub kind: String,
    pub triangles: u64,
    #[serde(default = "default_seed")]
    pub seed: u64,
}

#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputConfig {
    pub path: PathBuf,
}

/// Out-of-core partition parameters.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ChunkConfig {
    /// Most triangles per chunk. The default keeps one chunk's Strip-RT and encoding within
    /// about 1 GiB (roughly 250 bytes per triangle at peak).
    pub max_triangles: u64,
}

impl Default for ChunkConfig {
    fn default() -> Self {
        ChunkConfig {
            max_triangles: 4_000_000,
        }
    }
}

/// Strip-RT and strip-encoding parameters; defaults are the paper's.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct StripConfig {
    /// Default [`reducem::conversion::PIPELINE_MAX_STRIP_LENGTH`] (20; the paper's is 60).
    pub max_length: usize,
    /// Strip kd-tree leaf size in windows, as the file header and the library name it. Default
    /// [`reducem::conversion::PIPELINE_LEAF_WINDOWS`] (8; the paper's is 2). Configs written before
    /// the rename say `leaf_triangles`, which is still accepted.
    #[serde(alias = "leaf_triangles")]
    pub leaf_windows: Option<usize>,
    pub sah_bins: usize,
    /// No effect since format 4, whose compressed 8-wide nodes serve every vertex encoding
    /// (it asked format 2.4 to 3 writers for 64-byte grid nodes in lossless files); still
    /// accepted so that older configurations run.
    pub grid_nodes: bool,
}

impl Default for StripConfig {
    fn default() -> Self {
        StripConfig {
            max_length: reducem::conversion::PIPELINE_MAX_STRIP_LENGTH,
            leaf_windows: None,
            sah_bins: 16,
            grid_nodes: false,
        }
    }
}

/// How vertex positions are stored, and which input vertices are merged first.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VerticesConfig {
    pub encoding: VertexEncodingName,
    /// Bits per axis of the model grid, for `encoding = "grid"`.
    pub grid_bits: u32,
    /// Input vertices closer than this (model units) are merged before anything else; 0 merges
    /// bit-identical positions only.
    pub weld_tolerance: f32,
}

impl Default for VerticesConfig {
    fn default() -> Self {
        VerticesConfig {
            encoding: VertexEncodingName::F32,
            grid_bits: 20,
            weld_tolerance: 0.0,
        }
    }
}

/// `[vertices] encoding`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize, clap::ValueEnum)]
#[serde(rename_all = "lowercase")]
pub enum VertexEncodingName {
    /// Lossless f32 copies of the input positions.
    #[value(name = "f32")]
    F32,
    /// Points of one global grid over the model, `grid_bits` bits per axis.
    Grid,
}

/// What the file stores besides positions; all off by default, and each costs nothing when
/// off (the input's normals and colours are not even read).
#[derive(Clone, Debug, Default, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct AttributesConfig {
    /// The input face index of every stored triangle.
    pub face_ids: bool,
    /// Per-vertex normals (PLY `nx ny nz`, OBJ `vn`) and their encoding.
    pub normals: NormalEncodingName,
    /// Per-vertex RGBA8 colours (PLY `red green blue [alpha]`, OBJ `v x y z r g b`).
    pub colors: bool,
}

/// `[attributes] normals`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum NormalEncodingName {
    #[default]
    None,
    Oct8,
    Oct16,
}

impl NormalEncodingName {
    pub fn encoding(self) -> NormalEncoding {
        match self {
            NormalEncodingName::None => NormalEncoding::None,
            NormalEncodingName::Oct8 => NormalEncoding::Oct8,
            NormalEncodingName::Oct16 => NormalEncoding::Oct16,
        }
    }
}

/// Where intermediate files go; defaults to `<configuration name>.work` next to the
/// configuration file.
#[derive(Clone, Debug, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct WorkConfig {
    pub dir: Option<PathBuf>,
    /// `false`: remove the work directory after a successful run (it is often larger than the
    /// output); the next run then starts over.
    pub keep: bool,
}

impl Default for WorkConfig {
    fn default() -> Self {
        WorkConfig {
            dir: None,
            keep: true,
        }
    }
}

fn default_seed() -> u64 {
    1
}

/// The input after validation.
#[derive(Clone, Debug, PartialEq)]
pub enum Input {
    File(PathBuf),
    Generate {
        kind: Kind,
        triangles: u64,
        seed: u64,
    },
}

impl Config {
    /// Reads, parses and checks `path`; relative paths in it become relative to its directory.
    pub fn load(path: &Path) -> Result<Config, ConfigError> {
        let text = std::fs::read_to_string(path)
            .map_err(|error| ConfigError::new(path, error.to_string()))?;
        Config::parse(path, &text)
    }

    /// Parses and checks configuration text; `path` names it in errors and is the base of its
    /// relative paths.
    pub fn parse(path: &Path, text: &str) -> Result<Config, ConfigError> {
        let error = |message: String| ConfigError::new(path, message);
        let mut config: Config =
            toml::from_str(text).map_err(|e| error(e.to_string().trim_end().to_string()))?;
        config.resolve_paths(path.parent().unwrap_or(Path::new("")));
        config.source = path.to_path_buf();
        config.input().map_err(error)?;
        config.build_params().check().map_err(error)?;
        if config.chunk.max_triangles == 0 {
            return Err(error("[chunk] max_triangles must be at least 1".into()));
        }
        let tolerance = config.vertices.weld_tolerance;
        if !(tolerance.is_finite() && tolerance >= 0.0) {
            return Err(error(format!(
                "[vertices] weld_tolerance = {tolerance} must be a finite number >= 0"
            )));
        }
        Ok(config)
    }

    fn resolve_paths(&mut self, base: &Path) {
        let resolve = |p: &mut PathBuf| *p = base.join(&*p);
        self.input.path.as_mut().map(resolve);
        resolve(&mut self.output.path);
        self.work.dir.as_mut().map(resolve);
    }

    pub fn input(&self) -> Result<Input, String> {
        match (&self.input.path, &self.input.generate) {
            (Some(path), None) => Ok(Input::File(path.clone())),
            (None, Some(generate)) => {
                let kind = generate.kind.parse::<Kind>().map_err(|_| {
                    format!(
                        "[input.generate] kind = {:?} is not one of {}",
                        generate.kind,
                        Kind::names()
                    )
                })?;
                if let Some(message) = too_few_triangles(kind, generate.triangles) {
                    return Err(format!("[input.generate] triangles = {message}"));
                }
                Ok(Input::Generate {
                    kind,
                    triangles: generate.triangles,
                    seed: generate.seed,
                })
            }
            _ => Err("[input] needs exactly one of `path` and `[input.generate]`".into()),
        }
    }

    /// `[work] dir`; by default `<configuration name>.work` beside the configuration file, so
    /// that it does not depend on `[output] path` (changing the output reruns only *write*). A
    /// work directory at the former default, `<output>.work`, is kept while the new default
    /// does not exist, so that upgrading does not rerun a job.
    pub fn work_dir(&self) -> PathBuf {
        if let Some(dir) = &self.work.dir {
            return dir.clone();
        }
        let default = self.source.with_extension("work");
        let mut former = self.output.path.clone().into_os_string();
        former.push(".work");
        let former = PathBuf::from(former);
        if !default.exists() && WorkDir::new(former.clone()).made_by_pipeline() {
            return former;
        }
        default
    }

    pub fn build_params(&self) -> reducem::conversion::BuildParams {
        let grid = self.vertices.encoding == VertexEncodingName::Grid;
        let mut params = reducem::conversion::BuildParams {
            leaf_windows: self
                .strip
                .leaf_windows
                .unwrap_or(reducem::conversion::PIPELINE_LEAF_WINDOWS),
            grid_bits: grid.then_some(self.vertices.grid_bits),
            ..Default::default()
        };
        params.stripify.max_length = self.strip.max_length;
        params.stripify.sah_bins = self.strip.sah_bins;
        params.grid_nodes = self.strip.grid_nodes;
        params.attributes = AttributeSet {
            face_ids: self.attributes.face_ids,
            normals: self.attributes.normals.encoding(),
            colors: self.attributes.colors,
        };
        params
    }

    /// The vertex attributes the input must provide.
    pub fn attribute_request(&self) -> reducem::input::AttributeRequest {
        reducem::input::AttributeRequest::for_build(&self.build_params().attributes)
    }
}

/// Why a generated mesh of `kind` cannot have about `triangles` triangles, if it cannot.
pub fn too_few_triangles(kind: Kind, triangles: u64) -> Option<String> {
    let smallest = kind.smallest_triangles();
    let name = kind.name();
    (triangles < smallest).then(|| {
        format!("{triangles} is too few: the smallest {name} mesh has {smallest} triangles")
    })
}
