//! numpy rays `(..., 6)` to tracer rays, validated as `reducem query` validates a ray file
//! ([`reducem_core::trace::ray_file::parse_rays`]): NaN or infinite components and zero
//! directions are refused (the message of the first comes from the ray-file parser itself),
//! and a ray traced here is bit for bit the ray `reducem query` traces from a file of the same
//! values. Rays are read from the caller's array as they are traced, chunk by chunk, with no
//! ray-file records or array of tracer rays in between.

use std::ops::Range;
use std::path::Path;
use std::sync::atomic::{AtomicUsize, Ordering};

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
    /// Rays read out of the caller's array (the valid ones, for `invalid="miss"`, or all of
    /// them to be traced in another order).
    Gathered(Gathered),
}

/// Rays read out of the caller's array, traced in `order` (indices into `rays`) when it is
/// given, else in theirs; ray `j` of `rays` is ray `positions[j]` (or `j`) among `total`.
/// Tracing reads them through `order`, chunk by chunk, as `reducem query` reads its records,
/// rather than copying them all into that order first.
pub struct Gathered {
    pub rays: Vec<Ray>,
    pub order: Option<Vec<u32>>,
    pub positions: Option<Vec<usize>>,
    pub total: usize,
}

impl Gathered {
    /// The index in `rays` of the `k`th ray traced.
    fn traced_index(&self, k: usize) -> usize {
        self.order.as_ref().map_or(k, |order| order[k] as usize)
    }

    /// The position among the caller's rays of the `k`th ray traced.
    pub fn position(&self, k: usize) -> usize {
        let j = self.traced_index(k);
        self.positions.as_ref().map_or(j, |positions| positions[j])
    }
}

impl Rays<'_> {
    /// Rays to trace.
    pub fn traced(&self) -> usize {
        match self {
            Rays::All { components, .. } => components.len(),
            Rays::Gathered(gathered) => gathered.rays.len(),
        }
    }

    /// The traced rays `range` (of `0..traced()`), in `into` (cleared first; reused by a
    /// thread from chunk to chunk). Checks the rays as it reads them, so that valid rays take
    /// no pass of their own: the first invalid ray's index, and then `into` is incomplete.
    pub fn chunk_into(&self, range: Range<usize>, into: &mut Vec<Ray>) -> Option<usize> {
        into.clear();
        match self {
            Rays::Gathered(Gathered {
                rays, order: None, ..
            }) => {
                into.extend_from_slice(&rays[range]);
                None
            }
            Rays::Gathered(Gathered {
                rays,
                order: Some(order),
                ..
            }) => {
                into.extend(order[range].iter().map(|&j| rays[j as usize]));
                None
            }
            Rays::All {
                components: Components::F32(values),
                tnear,
                tfar,
            } => read_rays(values, range, into, |x| x, (*tnear, *tfar)),
            Rays::All {
                components: Components::F64(values),
                tnear,
                tfar,
            } => read_rays(values, range, into, |x| x as f32, (*tnear, *tfar)),
        }
    }
}

impl Rays<'_> {
    /// The traced rays `start + offset` of each of `offsets`, in that order, in `into`
    /// (cleared first), read straight from the caller's array; the smallest index of an
    /// invalid one among them, and then `into` is incomplete.
    pub fn gather_into(&self, start: usize, offsets: &[u32], into: &mut Vec<Ray>) -> Option<usize> {
        into.clear();
        match self {
            Rays::Gathered(gathered) => {
                let ray =
                    |offset: u32| gathered.rays[gathered.traced_index(start + offset as usize)];
                into.extend(offsets.iter().map(|&offset| ray(offset)));
                None
            }
            Rays::All {
                components: Components::F32(values),
                tnear,
                tfar,
            } => gather_rays(values, (start, offsets), into, |x| x, (*tnear, *tfar)),
            Rays::All {
                components: Components::F64(values),
                tnear,
                tfar,
            } => gather_rays(
                values,
                (start, offsets),
                into,
                |x| x as f32,
                (*tnear, *tfar),
            ),
        }
    }
}

/// Rays `start + offset` of `values` (six components each, converted by `to_f32`) appended
/// to `into`; the smallest index of an invalid one.
fn gather_rays<T: Copy>(
    values: &[T],
    (start, offsets): (usize, &[u32]),
    into: &mut Vec<Ray>,
    to_f32: impl Fn(T) -> f32,
    (tnear, tfar): (f32, f32),
) -> Option<usize> {
    let mut first_invalid: Option<usize> = None;
    for &offset in offsets {
        let i = start + offset as usize;
        let components = &values[6 * i..6 * i + 6];
        let ray: [f32; 6] = std::array::from_fn(|k| to_f32(components[k]));
        if is_valid(&ray) {
            into.push(to_ray(ray, tnear, tfar));
        } else {
            first_invalid = Some(first_invalid.map_or(i, |first| first.min(i)));
        }
    }
    first_invalid
}

/// Rays `range` of `values` (six components each, converted by `to_f32`) appended to `into`
/// until an invalid one, whose index it returns.
fn read_rays<T: Copy>(
    values: &[T],
    range: Range<usize>,
    into: &mut Vec<Ray>,
    to_f32: impl Fn(T) -> f32,
    (tnear, tfar): (f32, f32),
) -> Option<usize> {
    let components = values[6 * range.start..6 * range.end].chunks_exact(6);
    for (i, ray) in range.zip(components) {
        let ray: [f32; 6] = std::array::from_fn(|k| to_f32(ray[k]));
        if !is_valid(&ray) {
            return Some(i);
        }
        into.push(to_ray(ray, tnear, tfar));
    }
    None
}

/// Every ray of `components` on `[tnear, tfar]` in their order, read on every core; or the
/// first invalid one's index. Each ray is checked as it is converted (no second pass over
/// them), and collected by index into one vector: no per-ray lookup by index, and no list of
/// pieces copied again as a short-circuiting collect of `Option`s makes.
pub fn read_all(components: Components<'_>, interval: (f32, f32)) -> Result<Vec<Ray>, usize> {
    let first_invalid = AtomicUsize::new(usize::MAX);
    let rays = match components {
        Components::F32(values) => read_all_of(values, |x| x, interval, &first_invalid),
        Components::F64(values) => read_all_of(values, |x| x as f32, interval, &first_invalid),
    };
    match first_invalid.into_inner() {
        usize::MAX => Ok(rays),
        index => Err(index),
    }
}

fn read_all_of<T: Copy + Sync>(
    values: &[T],
    to_f32: impl Fn(T) -> f32 + Sync,
    (tnear, tfar): (f32, f32),
    first_invalid: &AtomicUsize,
) -> Vec<Ray> {
    values
        .par_chunks_exact(6)
        .enumerate()
        .map(|(i, ray)| {
            let ray: [f32; 6] = std::array::from_fn(|k| to_f32(ray[k]));
            if !is_valid(&ray) {
                first_invalid.fetch_min(i, Ordering::Relaxed);
            }
            to_ray(ray, tnear, tfar)
        })
        .collect()
}

/// The components of rays, C-contiguous, as the caller's array holds them.
#[derive(Clone, Copy)]
pub enum Components<'a> {
    F32(&'a [f32]),
    F64(&'a [f64]),
}

impl Components<'_> {
    /// Points in components that are points `(..., 3)`.
    pub fn points(&self) -> usize {
        match self {
            Components::F32(values) => values.len() / 3,
            Components::F64(values) => values.len() / 3,
        }
    }

    /// Rays in components that are rays `(..., 6)`.
    pub fn len(&self) -> usize {
        match self {
            Components::F32(values) => values.len() / 6,
            Components::F64(values) => values.len() / 6,
        }
    }

    /// Point `i` of components that are points `(..., 3)`, in f32 as [`Components::ray`].
    pub fn point(&self, i: usize) -> [f32; 3] {
        match self {
            Components::F32(values) => std::array::from_fn(|k| values[3 * i + k]),
            Components::F64(values) => std::array::from_fn(|k| values[3 * i + k] as f32),
        }
    }

    /// Ray `i` in f32; float64 components are computed in f32 as Open3D does (the nearest f32
    /// of each).
    pub fn ray(&self, i: usize) -> [f32; 6] {
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
    let layout = "(..., 6) [ox, oy, oz, dx, dy, dz]";
    with_floats(rays, "rays", (6, layout), read)
}

/// [`with_components`] for an array named `name` whose last axis holds `width` components
/// (described as `layout` in errors).
pub fn with_floats<T>(
    values: &Bound<'_, PyAny>,
    name: &str,
    (width, layout): (usize, &str),
    read: impl FnOnce(Vec<usize>, Components<'_>) -> PyResult<T>,
) -> PyResult<T> {
    let numpy = values.py().import("numpy")?;
    let array = numpy.call_method1("asarray", (values,))?;
    // The shape before `ascontiguousarray`, which makes a 0-d array 1-d.
    let shape = array.getattr("shape")?.extract::<Vec<usize>>()?;
    let shape = leading_shape(&shape, name, width, layout)?;
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
        "{name} must be float32 or float64, got dtype {dtype}"
    )))
}

fn contiguous<T>(slice: Result<&[T], numpy::AsSliceError>) -> PyResult<&[T]> {
    slice.map_err(|error| PyValueError::new_err(error.to_string()))
}

/// `shape[:-1]`, after checking that the last axis holds `width` components.
fn leading_shape(shape: &[usize], name: &str, width: usize, layout: &str) -> PyResult<Vec<usize>> {
    match shape.split_last() {
        Some((&last, leading)) if last == width => Ok(leading.to_vec()),
        _ => Err(PyValueError::new_err(format!(
            "{name} must have shape {layout}, got shape {}",
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

/// The valid rays of `components` on `[tnear, tfar]` and their positions, for `invalid="miss"`
/// once a call met an invalid ray. Runs without the GIL, on every core.
pub fn valid_only<'a>(components: Components<'a>, tnear: f32, tfar: f32) -> Rays<'a> {
    let (positions, rays): (Vec<usize>, Vec<Ray>) = (0..components.len())
        .into_par_iter()
        .map(|i| (i, components.ray(i)))
        .filter(|(_, ray)| is_valid(ray))
        .map(|(i, ray)| (i, to_ray(ray, tnear, tfar)))
        .unzip();
    Rays::Gathered(Gathered {
        rays,
        order: None,
        positions: Some(positions),
        total: components.len(),
    })
}

/// Why ray `index` of `components` (an invalid one, leading shape `shape`) is invalid.
pub fn describe_invalid(
    index: usize,
    components: Components<'_>,
    (tnear, tfar): (f32, f32),
    shape: &[usize],
) -> String {
    describe(index, components.ray(index), tnear, tfar, shape)
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
