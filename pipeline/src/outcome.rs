//! How a command ends: its exit code (the table in `reducem::exit_code`) and, with
//! `--log-format json`, the error or the final summary as one JSON object with the same fields
//! (`kind`, `file`, `element`, `index`, `offset`, `line`, `stage`, `chunk`, `counts`,
//! `seconds`; null where they do not apply), so that log processors never parse a message.

use std::path::Path;

use reducem::exit_code as exit;
use reducem::input::{InputError, Location};
use serde_json::{json, Value};

use crate::config::ConfigError;
use crate::interrupt::Interrupted;
use crate::lock::LockedError;
use crate::run::{UpstreamPending, UsageError};
use crate::stage::chunk::NoTriangles;

/// The stage a failed run stopped in (context on its error).
#[derive(Debug, thiserror::Error)]
#[error("stage {0}")]
pub struct InStage(pub String);

/// The chunk a failed unit worked on (context on its error).
#[derive(Debug, thiserror::Error)]
#[error("chunk {0}")]
pub struct InChunk(pub usize);

/// The exit code and the JSON `kind` of an error, by the typed errors in its chain.
pub fn classify(error: &anyhow::Error) -> (u8, &'static str) {
    for cause in error.chain() {
        if cause.is::<UsageError>() || cause.is::<exit::UsageError>() {
            return (exit::USAGE, "usage");
        }
        if cause.is::<LockedError>() {
            return (exit::TEMPORARY, "locked");
        }
        if let Some(interrupted) = cause.downcast_ref::<Interrupted>() {
            return (interrupted.exit_code(), "interrupted");
        }
        if cause.is::<UpstreamPending>() {
            return (exit::TEMPORARY, "stage_pending");
        }
        if cause.is::<ConfigError>() {
            return (exit::CONFIG, "config");
        }
        if cause.is::<InputError>() || cause.is::<NoTriangles>() {
            return (exit::BAD_INPUT, "bad_input");
        }
        if cause.is::<std::io::Error>() || cause.is::<reducem::format::writer::WriteError>() {
            return (exit::IO, "io");
        }
    }
    (exit::INTERNAL, "internal")
}

/// The error as one JSON object.
pub fn error_json(error: &anyhow::Error, seconds: f64) -> Value {
    let (code, kind) = classify(error);
    let mut object = fields("error", seconds);
    object["kind"] = kind.into();
    object["exit_code"] = code.into();
    object["message"] = format!("{error:#}").into();
    // Contexts are found by downcasting the error itself, not the causes of its chain.
    if let Some(InStage(stage)) = error.downcast_ref() {
        object["stage"] = stage.as_str().into();
    }
    if let Some(InChunk(chunk)) = error.downcast_ref() {
        object["chunk"] = (*chunk).into();
    }
    for cause in error.chain() {
        if let Some(input) = cause.downcast_ref::<InputError>() {
            locate_input(&mut object, input);
        } else if let Some(NoTriangles(path)) = cause.downcast_ref() {
            object["file"] = path_value(path);
        } else if let Some(config) = cause.downcast_ref::<ConfigError>() {
            object["file"] = path_value(&config.path);
        } else if let Some(locked) = cause.downcast_ref::<LockedError>() {
            object["file"] = path_value(&locked.dir);
        }
    }
    object
}

/// The final summary of a successful run as one JSON object.
pub fn summary_json(seconds: f64, counts: Value) -> Value {
    let mut object = fields("done", seconds);
    object["kind"] = "success".into();
    object["exit_code"] = exit::SUCCESS.into();
    object["stage"] = "run".into();
    object["counts"] = counts;
    object
}

/// Every field of the contract, null until known.
fn fields(event: &str, seconds: f64) -> Value {
    json!({
        "time": crate::progress::unix_time(),
        "event": event,
        "kind": null, "file": null, "element": null, "index": null, "offset": null,
        "line": null, "stage": null, "chunk": null, "counts": null, "seconds": seconds,
    })
}

fn locate_input(object: &mut Value, error: &InputError) {
    object["file"] = path_value(&error.path);
    match &error.location {
        Location::File => {}
        Location::Header { line } => object["line"] = (*line).into(),
        Location::Element {
            element,
            index,
            byte_offset,
            line,
        } => {
            object["element"] = element.as_str().into();
            object["index"] = (*index).into();
            object["offset"] = (*byte_offset).into();
            object["line"] = (*line).into();
        }
    }
}

fn path_value(path: &Path) -> Value {
    path.display().to_string().into()
}
