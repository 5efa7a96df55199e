//! `reducem.convert(input, output, *, progress=None, **options)`: the staged, resumable
//! conversion of `pipeline convert`, run in process. Options are named like the configuration
//! keys (README, "Configuration"); the job's configuration is written to `WORK/convert.toml`, so
//! `pipeline run WORK/convert.toml` resumes or inspects it like any other. The run reports to
//! the `reducem` logger and to the optional `progress(stage, done, total, unit)` callback.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use pipeline::config::VertexEncodingName;
use pipeline::convert::{ConvertArgs, SETTING_SECTIONS};
use pipeline::progress::{LogFormat, Progress, ProgressSink, Report};
use pipeline::run::{self, IfLocked, RunOptions};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyFloat, PyInt, PyString};

use crate::errors::{io_error, reducem_error};

/// Options that are not configuration keys: how the job runs.
const JOB_OPTIONS: [&str; 3] = ["work", "clean_after", "if_locked"];

/// `logging` levels: a stage's per-unit progress is detail, the rest is news.
const DEBUG: u8 = 10;
const INFO: u8 = 20;

/// Configuration keys with a field of their own in [`ConvertArgs`].
const ARGUMENT_KEYS: [&str; 3] = ["max_length", "encoding", "grid_bits"];

/// Converts the mesh `input` (PLY, OBJ, STL or glTF/GLB, also .gz or .zst) to the ReduceM file `output`, resuming an interrupted
/// conversion from its work directory (default `OUTPUT.work`). Reports go to the `reducem`
/// logger (INFO: stages starting and done, DEBUG: each unit of work) and, when given, to
/// `progress(stage, done, total, unit)` at a stage's start and after each unit.
#[pyfunction]
#[pyo3(signature = (input, output, *, progress = None, **options))]
pub fn convert(
    py: Python<'_>,
    input: PathBuf,
    output: PathBuf,
    progress: Option<Py<PyAny>>,
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
        // Unused: the run reports to `PythonReports` instead.
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
    let reports = Arc::new(PythonReports {
        logger: py
            .import("logging")?
            .call_method1("getLogger", ("reducem",))?
            .unbind(),
        callback: progress,
        raised: Mutex::new(None),
    });
    let progress = Progress::to_sink(reports.clone());
    let result = py.detach(|| pipeline::convert::convert_reporting(&args, &job, progress));
    // The callback's exception first: it is the one the caller's code raised.
    let raised = reports
        .raised
        .lock()
        .ok()
        .and_then(|mut raised| raised.take());
    if let Some(raised) = raised {
        return Err(raised);
    }
    result.map_err(reducem_error)
}

/// The run's reports as `logging` records and progress calls. An exception in either is kept
/// (later reports are dropped) and raised when the run ends.
struct PythonReports {
    logger: Py<PyAny>,
    callback: Option<Py<PyAny>>,
    raised: Mutex<Option<PyErr>>,
}

impl PythonReports {
    fn deliver(&self, py: Python<'_>, report: &Report<'_>) -> PyResult<()> {
        let level = if report.event == "progress" {
            DEBUG
        } else {
            INFO
        };
        let extra = PyDict::new(py);
        extra.set_item("stage", report.stage)?;
        extra.set_item("event", report.event)?;
        let keywords = PyDict::new(py);
        keywords.set_item("extra", extra)?;
        let arguments = (level, "%s: %s", report.stage, report.message);
        self.logger
            .bind(py)
            .call_method("log", arguments, Some(&keywords))?;
        // A stage's `done` repeats its last count: the callback hears each count once.
        if let (Some(callback), "start" | "progress", Some(units)) =
            (&self.callback, report.event, report.units)
        {
            callback.call1(py, (report.stage, units.done, units.total, units.name))?;
        }
        Ok(())
    }
}

impl ProgressSink for PythonReports {
    fn report(&self, report: &Report<'_>) {
        // The lock is never held while Python runs: Python may hand the GIL to a thread that
        // then waits for the lock.
        if self.raised.lock().map_or(true, |raised| raised.is_some()) {
            return;
        }
        Python::attach(|py| {
            if let Err(error) = self.deliver(py, report) {
                if let Ok(mut raised) = self.raised.lock() {
                    raised.get_or_insert(error);
                }
            }
        });
    }
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
