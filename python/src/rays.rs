//! numpy rays `(..., 6)` to tracer rays, validated exactly as `reducem query` validates a ray
//! file: each ray is encoded as a ray-file record and parsed by
//! [`reducem_core::trace::ray_file::parse_rays`], so NaN, infinite or zero directions and bad
//! intervals are caught by the same code with the same messages, and a ray traced here is
//! bit for bit the ray `reducem query` traces from a file of the same values.

use std::path::Path;

use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rayon::prelude::*;
use reducem_core::trace::ray_file::{self, RayFileError, RAY_BYTES};
use reducem_core::trace::Ray;

/// What an invalid ray does (`invalid=` of `cast_rays` and `test_occlusions`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InvalidRays {
    /// `ValueError` naming the first invalid ray.
    Raise,
    /// Answered as a miss (not occluded).
    Miss,
}

impl InvalidRays {
    pub fn parse(name: &str) -> PyResult<InvalidRays> {
        match name {
            "raise" => Ok(InvalidRays::Raise),
            "miss" => Ok(InvalidRays::Miss),
            other => Err(PyValueError::new_err(format!(
                "invalid={other:?}: expected \"raise\" or \"miss\""
            ))),
        }
    }
}

/// The rays of one call: the valid ones, traced as one batch, and where they go.
pub struct Rays {
    /// Leading shape of the input (`rays.shape[:-1]`).
    pub shape: Vec<usize>,
    pub valid: Vec<Ray>,
    /// With invalid rays answered as misses: the position of every valid ray in the input;
    /// `None` when every ray is valid.
    pub positions: Option<Vec<usize>>,
}

impl Rays {
    pub fn total(&self) -> usize {
        self.shape.iter().product()
    }
}

/// The components of `rays` as f32, in C order, with the leading shape.
pub fn components(rays: &Bound<'_, PyAny>) -> PyResult<(Vec<usize>, Vec<f32>)> {
    let py = rays.py();
    let array = py.import("numpy")?.call_method1("asarray", (rays,))?;
    if let Ok(array) = array.cast::<PyArrayDyn<f32>>() {
        let shape = leading_shape(array.shape())?;
        let readonly = array.readonly();
        return Ok((shape, contiguous(readonly.as_array(), |x| x)));
    }
    if let Ok(array) = array.cast::<PyArrayDyn<f64>>() {
        let shape = leading_shape(array.shape())?;
        let readonly = array.readonly();
        // Computed in f32, as Open3D does: the nearest f32 of each component.
        return Ok((shape, contiguous(readonly.as_array(), |x| x as f32)));
    }
    let dtype = array.getattr("dtype")?.str()?.to_string();
    Err(PyTypeError::new_err(format!(
        "rays must be float32 or float64, got dtype {dtype}"
    )))
}

/// The elements of `view` in C order, converted; one parallel copy when it is contiguous.
fn contiguous<T: Copy + Sync>(
    view: numpy::ndarray::ArrayViewD<'_, T>,
    convert: impl Fn(T) -> f32 + Sync,
) -> Vec<f32> {
    match view.as_slice() {
        Some(slice) => slice.par_iter().map(|&x| convert(x)).collect(),
        None => view.iter().map(|&x| convert(x)).collect(),
    }
}

/// `shape[:-1]`, after checking that the last axis holds the six components.
fn leading_shape(shape: &[usize]) -> PyResult<Vec<usize>> {
    match shape.split_last() {
        Some((6, leading)) => Ok(leading.to_vec()),
        _ => Err(PyValueError::new_err(format!(
            "rays must have shape (..., 6) [ox, oy, oz, dx, dy, dz], got shape {}",
            python_shape(shape)
        ))),
    }
}

/// `(2, 3)`, `(5,)`, `()`, as Python prints a shape.
pub fn python_shape(shape: &[usize]) -> String {
    match shape {
        [one] => format!("({one},)"),
        _ => {
            let parts: Vec<String> = shape.iter().map(usize::to_string).collect();
            format!("({})", parts.join(", "))
        }
    }
}

/// Checks the interval every ray gets.
pub fn check_interval(tnear: f32, tfar: f32) -> PyResult<()> {
    if tnear.is_nan() || tfar.is_nan() || tnear < 0.0 || tnear > tfar {
        return Err(PyValueError::new_err(format!(
            "tnear = {tnear}, tfar = {tfar}: need 0 <= tnear <= tfar"
        )));
    }
    Ok(())
}

/// Validates the rays `components` (six per ray) on `[tnear, tfar]`. Runs without the GIL.
pub fn validate(
    shape: Vec<usize>,
    components: &[f32],
    tnear: f32,
    tfar: f32,
    invalid: InvalidRays,
) -> Result<Rays, String> {
    let records = encode_records(components, tnear, tfar);
    let name = Path::new("rays");
    match ray_file::parse_rays(name, &records) {
        Ok(valid) => Ok(Rays {
            shape,
            valid,
            positions: None,
        }),
        Err(error) if invalid == InvalidRays::Raise => Err(describe(&error, &shape)),
        Err(_) => {
            let parsed: Vec<Option<Ray>> = records
                .par_chunks_exact(RAY_BYTES)
                .map(|record| ray_file::parse_rays(name, record).ok().map(|rays| rays[0]))
                .collect();
            let positions = (0..parsed.len()).filter(|&i| parsed[i].is_some()).collect();
            Ok(Rays {
                shape,
                valid: parsed.into_iter().flatten().collect(),
                positions: Some(positions),
            })
        }
    }
}

/// The ray-file records of the rays, `[tnear, tfar]` each.
fn encode_records(components: &[f32], tnear: f32, tfar: f32) -> Vec<u8> {
    let mut records = vec![0u8; components.len() / 6 * RAY_BYTES];
    records
        .par_chunks_exact_mut(RAY_BYTES)
        .zip(components.par_chunks_exact(6))
        .for_each(|(record, ray)| {
            let fields = ray.iter().chain([&tnear, &tfar]);
            for (out, field) in record.chunks_exact_mut(4).zip(fields) {
                out.copy_from_slice(&field.to_le_bytes());
            }
        });
    records
}

/// The ray parser's message, with the ray named by its index in the caller's array.
fn describe(error: &RayFileError, shape: &[usize]) -> String {
    match error {
        RayFileError::Invalid { ray, detail, .. } => {
            let detail = detail.replace("tmin", "tnear").replace("tmax", "tfar");
            format!(
                "ray {ray} (rays[{}]) is invalid: {detail}",
                multi_index(*ray, shape)
            )
        }
        other => other.to_string(),
    }
}

/// The index of flat position `flat` in an array of `shape`, as `i, j, k`.
fn multi_index(mut flat: usize, shape: &[usize]) -> String {
    let mut index = vec![0; shape.len()];
    for (slot, &extent) in index.iter_mut().zip(shape).rev() {
        *slot = flat % extent.max(1);
        flat /= extent.max(1);
    }
    let parts: Vec<String> = index.iter().map(usize::to_string).collect();
    parts.join(", ")
}
