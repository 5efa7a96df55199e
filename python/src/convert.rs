//! `reducem.convert(input, output, **options)`: the staged, resumable conversion of `pipeline
//! convert`, run in process. Options are named like the configuration keys (README,
//! "Configuration"); the job's configuration is written to `WORK/convert.toml`, so
//! `pipeline run WORK/convert.toml` resumes or inspects it like any other.

use std::path::PathBuf;

use pipeline::config::VertexEncodingName;
use pipeline::convert::{ConvertArgs, SETTING_SECTIONS};
use pipeline::progress::LogFormat;
use pipeline::run::{self, IfLocked, RunOptions};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};

use crate::errors::{io_error, reducem_error};

/// Options that are not configuration keys: how the job runs.
const JOB_OPTIONS: [&str; 4] = ["work", "log_format", "clean_after", "if_locked"];

/// Configuration keys with a field of their own in [`ConvertArgs`].
const ARGUMENT_KEYS: [&str; 3] = ["max_length", "encoding", "grid_bits"];

/// Converts the mesh `input` (PLY or OBJ) to the ReduceM file `output`, resuming an interrupted
/// conversion from its work directory (default `OUTPUT.work`).
#[pyfunction]
#[pyo3(signature = (input, output, **options))]
pub fn convert(
    py: Python<'_>,
    input: PathBuf,
    output: PathBuf,
    options: Option<&Bound<'_, PyDict>>,
) -> PyResult<()> {
    if !input.exists() {
        let message = format!("{}: no such file", input.display());
        return Err(io_error(std::io::ErrorKind::NotFound, message));
    }
    let mut args = ConvertArgs {
        input,
        output,
        max_length: None,
        encoding: None,
        grid_bits: None,
        work: None,
        settings: Vec::new(),
    };
    let mut job = RunOptions {
        log_format: LogFormat::Plain,
        clean_after: false,
        if_locked: IfLocked::Fail,
        stage: None,
        shard: run::Shard::WHOLE,
    };
    for (key, value) in options.into_iter().flatten() {
        let key: String = key.extract()?;
        set_option(&mut args, &mut job, &key, &value)?;
    }
    py.detach(|| pipeline::convert::convert(&args, &job))
        .map_err(reducem_error)
}

fn set_option(
    args: &mut ConvertArgs,
    job: &mut RunOptions,
    key: &str,
    value: &Bound<'_, PyAny>,
) -> PyResult<()> {
    let invalid =
        |expected: &str| PyValueError::new_err(format!("{key}={value}: expected {expected}"));
    match key {
        "max_length" => args.max_length = Some(value.extract()?),
        "grid_bits" => args.grid_bits = Some(value.extract()?),
        "encoding" => {
            args.encoding = Some(match value.extract::<String>()?.as_str() {
                "f32" => VertexEncodingName::F32,
                "grid" => VertexEncodingName::Grid,
                _ => return Err(invalid("\"f32\" or \"grid\"")),
            })
        }
        "work" => args.work = Some(value.extract()?),
        "clean_after" => job.clean_after = value.extract()?,
        "log_format" => {
            job.log_format = match value.extract::<String>()?.as_str() {
                "plain" => LogFormat::Plain,
                "json" => LogFormat::Json,
                "auto" => LogFormat::Auto,
                _ => return Err(invalid("\"plain\", \"json\" or \"auto\"")),
            }
        }
        "if_locked" => {
            job.if_locked = match value.extract::<String>()?.as_str() {
                "fail" => IfLocked::Fail,
                "skip" => IfLocked::Skip,
                _ => return Err(invalid("\"fail\" or \"skip\"")),
            }
        }
        _ if SETTING_SECTIONS.iter().any(|(name, _)| *name == key) => {
            args.settings
                .push((key.to_string(), toml_value(key, value)?));
        }
        _ => {
            let known: Vec<&str> = ARGUMENT_KEYS
                .iter()
                .chain(SETTING_SECTIONS.iter().map(|(name, _)| name))
                .chain(&JOB_OPTIONS)
                .copied()
                .collect();
            return Err(PyTypeError::new_err(format!(
                "convert() got an unexpected option {key:?} (options: {})",
                known.join(", ")
            )));
        }
    }
    Ok(())
}

/// A Python bool, int, float or str as a TOML value; the configuration's own parser checks it.
fn toml_value(key: &str, value: &Bound<'_, PyAny>) -> PyResult<String> {
    if value.is_instance_of::<PyBool>() {
        return Ok(value.extract::<bool>()?.to_string());
    }
    if value.is_instance_of::<PyInt>() {
        return Ok(value.extract::<i64>()?.to_string());
    }
    if value.is_instance_of::<PyFloat>() {
        let x: f64 = value.extract()?;
        if !x.is_finite() {
            return Err(PyValueError::new_err(format!("{key}={x}: must be finite")));
        }
        // Debug keeps a decimal point or exponent, so TOML reads a float.
        return Ok(format!("{x:?}"));
    }
    if value.is_instance_of::<PyString>() {
        let text: String = value.extract()?;
        return serde_json::to_string(&text).map_err(reducem_error);
    }
    Err(PyTypeError::new_err(format!(
        "{key}: expected a bool, int, float or str, got {}",
        value.get_type().name()?
    )))
}
