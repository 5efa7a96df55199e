//! numpy rays `(..., 6)` to tracer rays, validated as `reducem query` validates a ray file
//! ([`reducem_core::trace::ray_file::parse_rays`]): NaN or infinite components and zero
//! directions are refused (the message of the first comes from the ray-file parser itself),
//! and a ray traced here is bit for bit the ray `reducem query` traces from a file of the same
//! values. Rays are read from the caller's array as they are traced, chunk by chunk, with no
//! ray-file records or array of tracer rays in between.

use std::ops::Range;
use std::path::Path;

use numpy::{PyArrayDyn, PyArrayMethods};
use pyo3::exceptions::{PyTypeError, PyValueError};
use pyo3::prelude::*;
use rayon::prelude::*;
use reducem_core::trace::ray_file::{self, RayFileError};
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

/// The validated rays of one call.
pub enum Rays<'a> {
    /// Every ray is valid: read from the caller's array chunk by chunk as they are traced, so
    /// that no array of tracer rays is allocated.
    All {
        components: Components<'a>,
        tnear: f32,
        tfar: f32,
    },
    /// Invalid rays answered as misses: the valid ones and their positions among `total`.
    Valid {
        rays: Vec<Ray>,
        positions: Vec<usize>,
        total: usize,
    },
}

impl Rays<'_> {
    /// Rays to trace.
    pub fn traced(&self) -> usize {
        match self {
            Rays::All { components, .. } => components.len(),
            Rays::Valid { rays, .. } => rays.len(),
        }
    }

    /// The traced rays `range` (of `0..traced()`).
    pub fn chunk(&self, range: Range<usize>) -> Vec<Ray> {
        match self {
            Rays::All {
                components,
                tnear,
                tfar,
            } => range
                .map(|i| to_ray(components.ray(i), *tnear, *tfar))
                .collect(),
            Rays::Valid { rays, .. } => rays[range].to_vec(),
        }
    }
}

/// The components of rays, C-contiguous, as the caller's array holds them.
#[derive(Clone, Copy)]
pub enum Components<'a> {
    F32(&'a [f32]),
    F64(&'a [f64]),
}

impl Components<'_> {
    pub fn len(&self) -> usize {
        match self {
            Components::F32(values) => values.len() / 6,
            Components::F64(values) => values.len() / 6,
        }
    }

    /// Ray `i` in f32; float64 components are computed in f32 as Open3D does (the nearest f32
    /// of each).
    fn ray(&self, i: usize) -> [f32; 6] {
        match self {
            Components::F32(values) => std::array::from_fn(|k| values[6 * i + k]),
            Components::F64(values) => std::array::from_fn(|k| values[6 * i + k] as f32),
        }
    }
}

/// Calls `read` with the leading shape and the components of `rays` (any array-like shaped
/// `(..., 6)`; a C-contiguous float32 or float64 array is read in place, anything else is
/// first made one by numpy).
pub fn with_components<T>(
    rays: &Bound<'_, PyAny>,
    read: impl FnOnce(Vec<usize>, Components<'_>) -> PyResult<T>,
) -> PyResult<T> {
    let numpy = rays.py().import("numpy")?;
    let array = numpy.call_method1("asarray", (rays,))?;
    // The shape before `ascontiguousarray`, which makes a 0-d array 1-d.
    let shape = leading_shape(&array.getattr("shape")?.extract::<Vec<usize>>()?)?;
    let array = numpy.call_method1("ascontiguousarray", (array,))?;
    if let Ok(array) = array.cast::<PyArrayDyn<f32>>() {
        let readonly = array.readonly();
        return read(shape, Components::F32(contiguous(readonly.as_slice())?));
    }
    if let Ok(array) = array.cast::<PyArrayDyn<f64>>() {
        let readonly = array.readonly();
        return read(shape, Components::F64(contiguous(readonly.as_slice())?));
    }
    let dtype = array.getattr("dtype")?.str()?.to_string();
    Err(PyTypeError::new_err(format!(
        "rays must be float32 or float64, got dtype {dtype}"
    )))
}

fn contiguous<T>(slice: Result<&[T], numpy::AsSliceError>) -> PyResult<&[T]> {
    slice.map_err(|error| PyValueError::new_err(format!("rays: {error}")))
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

/// The rays of `components` on `[tnear, tfar]` (checked by [`check_interval`]), validated;
/// `shape` names an invalid one. Runs without the GIL, on every core.
pub fn validate<'a>(
    shape: &[usize],
    components: Components<'a>,
    tnear: f32,
    tfar: f32,
    invalid: InvalidRays,
) -> Result<Rays<'a>, String> {
    let all = 0..components.len();
    let first_invalid = all
        .clone()
        .into_par_iter()
        .position_first(|i| !is_valid(&components.ray(i)));
    let Some(first_invalid) = first_invalid else {
        return Ok(Rays::All {
            components,
            tnear,
            tfar,
        });
    };
    if invalid == InvalidRays::Raise {
        let ray = components.ray(first_invalid);
        return Err(describe(first_invalid, ray, tnear, tfar, shape));
    }
    let (positions, rays): (Vec<usize>, Vec<Ray>) = all
        .into_par_iter()
        .map(|i| (i, components.ray(i)))
        .filter(|(_, ray)| is_valid(ray))
        .map(|(i, ray)| (i, to_ray(ray, tnear, tfar)))
        .unzip();
    Ok(Rays::Valid {
        rays,
        positions,
        total: components.len(),
    })
}

/// What [`ray_file::parse_rays`] accepts of a ray, given an interval that
/// [`check_interval`] accepted: finite components and a non-zero direction.
fn is_valid(ray: &[f32; 6]) -> bool {
    ray.iter().all(|x| x.is_finite()) && ray[3..] != [0.0; 3]
}

fn to_ray([ox, oy, oz, dx, dy, dz]: [f32; 6], tmin: f32, tmax: f32) -> Ray {
    Ray {
        origin: [ox, oy, oz],
        direction: [dx, dy, dz],
        tmin,
        tmax,
    }
}

/// Why ray `index` is invalid, in the ray parser's words (the ray is encoded as a ray-file
/// record and parsed), named by its index in the caller's array.
fn describe(index: usize, ray: [f32; 6], tnear: f32, tfar: f32, shape: &[usize]) -> String {
    let record = ray_file::encode_rays(&[to_ray(ray, tnear, tfar)]);
    let detail = match ray_file::parse_rays(Path::new("rays"), &record) {
        Err(RayFileError::Invalid { detail, .. }) => detail,
        _ => "rejected".to_string(),
    };
    format!(
        "ray {index} (rays[{}]) is invalid: {detail}",
        multi_index(index, shape)
    )
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
