//! The `reducem` Python package's native module: a mapped ReduceM file as a `Scene` that casts
//! numpy rays with the same tracer and the same ray validation as `reducem query`, the file's
//! statistics, triangles and renders, and the staged conversion of `pipeline convert`.
//!
//! Conventions follow Open3D's `RaycastingScene.cast_rays` (rays shaped `(..., 6)`, a dict of
//! `t_hit`, `primitive_ids`, `primitive_uvs`, `primitive_normals`), so that code written for it
//! runs on a mapped file. Every failure is a Python exception: `FileNotFoundError` for a missing
//! file, `ValueError`/`TypeError` for bad arguments, `reducem.ReducemError` with the Rust message
//! (file, section, byte offset) for anything the file or the conversion rejects.

#![deny(unsafe_code)]

mod answers;
mod convert;
mod crossings;
mod errors;
mod order;
mod points;
mod primitive_ids;
mod rays;
mod render;
mod scene;

use pyo3::prelude::*;

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("ReducemError", m.py().get_type::<errors::ReducemError>())?;
    m.add_class::<scene::Scene>()?;
    m.add_function(wrap_pyfunction!(scene::open, m)?)?;
    m.add_function(wrap_pyfunction!(convert::convert, m)?)?;
    Ok(())
}
