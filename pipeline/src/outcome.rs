//! How a command fails: its exit code (the table and mapping in `reducem::exit_code`, with the
//! pipeline's own error types) and, with `--log-format json`, the error as one JSON object with
//! the fields of [`crate::outcome_json`] (`kind`, `file`, `element`, `index`, `offset`, `line`,
//! `stage`, `chunk`; null where they do not apply), so that log processors never parse a message.

use std::path::Path;

use reducem::exit_code::{self as exit, Exit};
use reducem::input::{InputError, Location};
use serde_json::Value;

use crate::config::ConfigError;
pub use crate::error::{InChunk, InStage};
use crate::interrupt::Interrupted;
use crate::lock::LockedError;
use crate::outcome_json::fields;
use crate::stage::chunk::NoTriangles;
use crate::stage::UpstreamPending;

/// The exit code and the JSON `kind` of an error, by the typed errors in its chain.
pub fn classify(error: &anyhow::Error) -> Exit {
    exit::classify(error, pipeline_exit)
}

/// The exit of the pipeline's own error types.
fn pipeline_exit(cause: &(dyn std::error::Error + 'static)) -> Option<Exit> {
    if cause.is::<LockedError>() {
        return Some((exit::TEMPORARY, "locked"));
    }
    if let Some(interrupted) = cause.downcast_ref::<Interrupted>() {
        return Some((interrupted.exit_code(), "interrupted"));
    }
    if cause.is::<UpstreamPending>() {
        return Some((exit::TEMPORARY, "stage_pending"));
    }
    if cause.is::<ConfigError>() {
        return Some((exit::CONFIG, "config"));
    }
    if cause.is::<NoTriangles>() {
        return Some((exit::BAD_INPUT, "bad_input"));
    }
    None
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
