//! Rust errors as Python exceptions.

use std::io;

use pyo3::exceptions::{PyException, PyFileNotFoundError, PyOSError, PyPermissionError};
use pyo3::prelude::*;
use reducem_core::format::reader::FormatError;

pyo3::create_exception!(
    reducem,
    ReducemError,
    PyException,
    "A file, ray set, scene or conversion that reducem rejects; the message names the file, \
     the section or element and the byte offset."
);

/// An I/O error as the matching `OSError` subclass, with `message` (which names the file).
pub fn io_error(kind: io::ErrorKind, message: String) -> PyErr {
    match kind {
        io::ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
        io::ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
        _ => PyOSError::new_err(message),
    }
}

/// A file that could not be opened: `OSError` (`FileNotFoundError`, ...) when it could not be
/// read, [`ReducemError`] when its contents are invalid.
pub fn format_error(error: FormatError) -> PyErr {
    match &error {
        FormatError::Io { source, .. } => io_error(source.kind(), error.to_string()),
        FormatError::Invalid { .. } => ReducemError::new_err(error.to_string()),
    }
}

/// Any other failure of the Rust side, with its chain of causes.
pub fn reducem_error(error: impl std::fmt::Display) -> PyErr {
    ReducemError::new_err(format!("{error:#}"))
}
