//! Where `cast_rays` writes its answers: numpy arrays made uninitialised by `numpy.empty` (no
//! zero-fill before tracing, and numpy's allocator, which reuses freed memory and asks for huge
//! pages), written in place by the tracing threads. Every element of every ray is written, a
//! miss's too, so nothing of the memory's earlier contents shows.

use numpy::{PyArrayDyn, PyArrayMethods, PyReadwriteArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use reducem_core::format::attributes::{AttributeSet, NormalEncoding};
use reducem_core::trace::{Hit, HitAttributes};

use crate::order::CHUNK;
use crate::primitive_ids::NO_PRIMITIVE;
use crate::rays::Gathered;

/// The arrays `cast_rays` returns, shaped as the rays' leading shape (and a last axis for the
/// vector answers).
pub struct AnswerArrays<'py> {
    t: Bound<'py, PyArrayDyn<f32>>,
    ids: Bound<'py, PyArrayDyn<u32>>,
    geometry_ids: Bound<'py, PyArrayDyn<u32>>,
    uvs: Bound<'py, PyArrayDyn<f32>>,
    normals: Bound<'py, PyArrayDyn<f32>>,
    shading_normals: Option<Bound<'py, PyArrayDyn<f32>>>,
    colors: Option<Bound<'py, PyArrayDyn<u8>>>,
}

impl<'py> AnswerArrays<'py> {
    /// Uninitialised arrays for rays of leading shape `shape` in a file with `attributes`.
    pub fn empty(
        py: Python<'py>,
        shape: &[usize],
        attributes: AttributeSet,
    ) -> PyResult<AnswerArrays<'py>> {
        let shaped = |extra: &[usize]| [shape, extra].concat();
        let has_normals = attributes.normals != NormalEncoding::None;
        Ok(AnswerArrays {
            t: empty(py, &shaped(&[]), "float32")?,
            ids: empty(py, &shaped(&[]), "uint32")?,
            geometry_ids: empty(py, &shaped(&[]), "uint32")?,
            uvs: empty(py, &shaped(&[2]), "float32")?,
            normals: empty(py, &shaped(&[3]), "float32")?,
            shading_normals: has_normals
                .then(|| empty(py, &shaped(&[3]), "float32"))
                .transpose()?,
            colors: attributes
                .colors
                .then(|| empty(py, &shaped(&[4]), "uint8"))
                .transpose()?,
        })
    }

    /// The arrays borrowed for writing (numpy's borrow checking: no other Rust code reads or
    /// writes them meanwhile).
    pub fn borrow(&self) -> BorrowedAnswers<'py> {
        BorrowedAnswers {
            t: self.t.readwrite(),
            ids: self.ids.readwrite(),
            geometry_ids: self.geometry_ids.readwrite(),
            uvs: self.uvs.readwrite(),
            normals: self.normals.readwrite(),
            shading_normals: self.shading_normals.as_ref().map(|a| a.readwrite()),
            colors: self.colors.as_ref().map(|a| a.readwrite()),
        }
    }

    /// The dict `cast_rays` returns, with Open3D's keys (and the attribute keys the file has).
    pub fn into_dict(self, py: Python<'py>) -> PyResult<Bound<'py, PyDict>> {
        let result = PyDict::new(py);
        result.set_item("t_hit", self.t)?;
        result.set_item("primitive_ids", self.ids)?;
        result.set_item("geometry_ids", self.geometry_ids)?;
        result.set_item("primitive_uvs", self.uvs)?;
        result.set_item("primitive_normals", self.normals)?;
        if let Some(normals) = self.shading_normals {
            result.set_item("shading_normals", normals)?;
        }
        if let Some(colors) = self.colors {
            result.set_item("colors", colors)?;
        }
        Ok(result)
    }
}

/// `numpy.empty(shape, dtype)` as the array type of `T`.
fn empty<'py, T: numpy::Element>(
    py: Python<'py>,
    shape: &[usize],
    dtype: &str,
) -> PyResult<Bound<'py, PyArrayDyn<T>>> {
    let array = py
        .import("numpy")?
        .call_method1("empty", (shape.to_vec(), dtype))?;
    Ok(array.cast_into::<PyArrayDyn<T>>()?)
}

/// [`AnswerArrays`] borrowed for writing.
pub struct BorrowedAnswers<'py> {
    t: PyReadwriteArrayDyn<'py, f32>,
    ids: PyReadwriteArrayDyn<'py, u32>,
    geometry_ids: PyReadwriteArrayDyn<'py, u32>,
    uvs: PyReadwriteArrayDyn<'py, f32>,
    normals: PyReadwriteArrayDyn<'py, f32>,
    shading_normals: Option<PyReadwriteArrayDyn<'py, f32>>,
    colors: Option<PyReadwriteArrayDyn<'py, u8>>,
}

impl BorrowedAnswers<'_> {
    /// The arrays' elements, flat in ray order, to hand to the tracing threads.
    pub fn slices(&mut self) -> PyResult<Answers<'_>> {
        Ok(Answers {
            t: flat(&mut self.t)?,
            ids: flat(&mut self.ids)?,
            geometry_ids: flat(&mut self.geometry_ids)?,
            uvs: flat(&mut self.uvs)?,
            normals: flat(&mut self.normals)?,
            shading_normals: match self.shading_normals.as_mut() {
                Some(array) => flat(array)?,
                None => &mut [],
            },
            colors: match self.colors.as_mut() {
                Some(array) => flat(array)?,
                None => &mut [],
            },
        })
    }
}

fn flat<'a, T: numpy::Element>(array: &'a mut PyReadwriteArrayDyn<'_, T>) -> PyResult<&'a mut [T]> {
    array
        .as_slice_mut()
        .map_err(|error| PyValueError::new_err(error.to_string()))
}

/// Answers of rays (a batch or a chunk of it), flat, in ray order; `shading_normals` and `colors` are empty when the file
/// has none.
pub struct Answers<'a> {
    t: &'a mut [f32],
    ids: &'a mut [u32],
    geometry_ids: &'a mut [u32],
    uvs: &'a mut [f32],
    normals: &'a mut [f32],
    shading_normals: &'a mut [f32],
    colors: &'a mut [u8],
}

impl Answers<'_> {
    /// Rays answered.
    pub fn len(&self) -> usize {
        self.t.len()
    }

    /// The answers cut into chunks of `rays` consecutive rays.
    pub fn chunks(&mut self, rays: usize) -> Vec<Answers<'_>> {
        let mut shading_normals = self.shading_normals.chunks_mut(3 * rays);
        let mut colors = self.colors.chunks_mut(4 * rays);
        self.t
            .chunks_mut(rays)
            .zip(self.ids.chunks_mut(rays))
            .zip(self.geometry_ids.chunks_mut(rays))
            .zip(self.uvs.chunks_mut(2 * rays))
            .zip(self.normals.chunks_mut(3 * rays))
            .map(|((((t, ids), geometry_ids), uvs), normals)| Answers {
                t,
                ids,
                geometry_ids,
                uvs,
                normals,
                shading_normals: shading_normals.next().unwrap_or_default(),
                colors: colors.next().unwrap_or_default(),
            })
            .collect()
    }

    /// `traced`, the answers of the rays of `gathered` in the order they were traced, put at
    /// their rays' positions among these; misses elsewhere (rays left out as invalid). On
    /// every core.
    pub fn place(&mut self, traced: &AnswerBuffers, gathered: &Gathered) {
        let mut source = vec![usize::MAX; self.len()];
        for k in 0..gathered.rays.len() {
            source[gathered.position(k)] = k;
        }
        self.chunks(CHUNK)
            .into_par_iter()
            .zip(source.par_chunks(CHUNK))
            .for_each(|(mut out, sources)| {
                for (k, &from) in sources.iter().enumerate() {
                    match from {
                        usize::MAX => out.write_miss(k),
                        from => out.copy(k, traced, from),
                    }
                }
            });
    }
}

/// Answers owned by the binding: of rays traced out of their order, before they are placed.
pub struct AnswerBuffers {
    t: Vec<f32>,
    ids: Vec<u32>,
    geometry_ids: Vec<u32>,
    uvs: Vec<f32>,
    normals: Vec<f32>,
    shading_normals: Vec<f32>,
    colors: Vec<u8>,
}

impl AnswerBuffers {
    pub fn new(rays: usize, attributes: AttributeSet) -> AnswerBuffers {
        let per_ray = |present: bool, count: usize| if present { count * rays } else { 0 };
        AnswerBuffers {
            t: vec![0.0; rays],
            ids: vec![0; rays],
            geometry_ids: vec![0; rays],
            uvs: vec![0.0; 2 * rays],
            normals: vec![0.0; 3 * rays],
            shading_normals: vec![0.0; per_ray(attributes.normals != NormalEncoding::None, 3)],
            colors: vec![0; per_ray(attributes.colors, 4)],
        }
    }

    pub fn answers(&mut self) -> Answers<'_> {
        Answers {
            t: &mut self.t,
            ids: &mut self.ids,
            geometry_ids: &mut self.geometry_ids,
            uvs: &mut self.uvs,
            normals: &mut self.normals,
            shading_normals: &mut self.shading_normals,
            colors: &mut self.colors,
        }
    }
}

impl Answers<'_> {
    /// Every element of every ray's answer written as a miss, before the hits are written over
    /// them: a fill of each array, cheaper than a miss written ray by ray in the tracing loop.
    pub fn fill_misses(&mut self) {
        self.t.fill(f32::INFINITY);
        self.ids.fill(NO_PRIMITIVE);
        self.geometry_ids.fill(NO_PRIMITIVE);
        self.uvs.fill(0.0);
        self.normals.fill(0.0);
        self.shading_normals.fill(0.0);
        self.colors.fill(0);
    }

    /// Writes every element of ray `k`'s answer as a miss: `t` inf, ids 4294967295, zeros.
    pub fn write_miss(&mut self, k: usize) {
        self.t[k] = f32::INFINITY;
        self.ids[k] = NO_PRIMITIVE;
        self.geometry_ids[k] = NO_PRIMITIVE;
        self.uvs[2 * k..2 * k + 2].fill(0.0);
        self.normals[3 * k..3 * k + 3].fill(0.0);
        if !self.shading_normals.is_empty() {
            self.shading_normals[3 * k..3 * k + 3].fill(0.0);
        }
        if !self.colors.is_empty() {
            self.colors[4 * k..4 * k + 4].fill(0);
        }
    }

    /// Writes every element of ray `k`'s answer: `hit` named `id`, with its attributes `read`
    /// (when the file has per-vertex ones).
    pub fn write_hit(&mut self, k: usize, hit: &Hit, id: u32, read: Option<HitAttributes>) {
        self.t[k] = hit.t;
        self.ids[k] = id;
        self.geometry_ids[k] = 0;
        self.uvs[2 * k..2 * k + 2].copy_from_slice(&[hit.u, hit.v]);
        self.normals[3 * k..3 * k + 3].copy_from_slice(&hit.normal);
        if !self.shading_normals.is_empty() {
            let normal = read.map_or(hit.normal, |read| read.shading_normal);
            self.shading_normals[3 * k..3 * k + 3].copy_from_slice(&normal);
        }
        if !self.colors.is_empty() {
            let color = read.and_then(|read| read.color).unwrap_or([0; 4]);
            self.colors[4 * k..4 * k + 4].copy_from_slice(&color);
        }
    }

    /// Ray `k`'s answer copied from ray `from` of `traced`.
    fn copy(&mut self, k: usize, traced: &AnswerBuffers, from: usize) {
        self.t[k] = traced.t[from];
        self.ids[k] = traced.ids[from];
        self.geometry_ids[k] = traced.geometry_ids[from];
        self.uvs[2 * k..2 * k + 2].copy_from_slice(&traced.uvs[2 * from..2 * from + 2]);
        self.normals[3 * k..3 * k + 3].copy_from_slice(&traced.normals[3 * from..3 * from + 3]);
        if !self.shading_normals.is_empty() {
            let normal = &traced.shading_normals[3 * from..3 * from + 3];
            self.shading_normals[3 * k..3 * k + 3].copy_from_slice(normal);
        }
        if !self.colors.is_empty() {
            self.colors[4 * k..4 * k + 4].copy_from_slice(&traced.colors[4 * from..4 * from + 4]);
        }
    }
}
