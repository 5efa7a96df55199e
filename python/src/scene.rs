//! `reducem.open(path) -> Scene`: a mapped, validated file and its ray queries.
//!
//! Tracing runs without the GIL on rayon's threads (a pool of `nthreads` when given), chunk by
//! chunk through [`Tracer::intersect_each`] and [`Tracer::occluded_chunk`], the calls
//! `reducem query` makes, in the order [`order`] picks: the same rays give bit-identical `t`
//! and normals.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, PoisonError};

use numpy::ndarray::{Array, IxDyn};
use numpy::{PyArray, PyArray1};
use pyo3::exceptions::{PyRuntimeWarning, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use rayon::prelude::*;
use rayon::ThreadPool;
use reducem_core::format::reader::ReducemFile;
use reducem_core::query::occupancy::inside_rays;
use reducem_core::trace::{surface_attributes, Hit, Kernel, TraceOptions, Tracer};

use crate::answers::{AnswerArrays, AnswerBuffers, Answers};
use crate::crossings;
use crate::errors::{format_error, reducem_error};
use crate::order::{self, Chunk, ChunkOrder};
use crate::points::{self, ClosestAnswers};
use crate::primitive_ids::{PrimitiveIds, NO_PRIMITIVE};
use crate::rays::{self, Components, InvalidRays, Rays};

/// A mapped ReduceM file.
#[pyclass(frozen, weakref, module = "reducem")]
pub struct Scene {
    file: ReducemFile,
    /// How answers name triangles, made on the first query that names them (without face ids
    /// it reads every strip's references, which opening does not).
    primitive_ids: OnceLock<PrimitiveIds>,
    /// The not-exact warning was given.
    warned_not_exact: AtomicBool,
}

/// Maps the ReduceM file at `path` and validates it: a file up to 1 MiB in full, a larger one
/// its header and section table at once and each strip and node when first reached, so that
/// opening costs the same for any model; a query that reaches a corrupt part raises
/// `ReducemError` naming the file and byte.
#[pyfunction]
pub fn open(py: Python<'_>, path: PathBuf) -> PyResult<Scene> {
    let file = py
        .detach(|| ReducemFile::open(&path))
        .map_err(format_error)?;
    Ok(Scene {
        file,
        primitive_ids: OnceLock::new(),
        warned_not_exact: AtomicBool::new(false),
    })
}

#[pymethods]
impl Scene {
    /// Closest hits of `rays` (`(..., 6)`: origin, direction; float32 or float64, traced in
    /// float32) on `[tnear, tfar]`, in units of each direction's length. Returns a dict:
    /// `t_hit` float32 `(...)` (inf on a miss), `primitive_ids` uint32 `(...)` (the input
    /// face id when the file stores face ids, else the stored triangle's row in `triangles()`;
    /// 4294967295 on a miss), `geometry_ids` uint32 `(...)` (0 on a hit, 4294967295 on a
    /// miss, as Open3D's for a scene of one geometry), `primitive_uvs` float32
    /// `(..., 2)` (barycentric weights of the triangle's second and third corners),
    /// `primitive_normals` float32 `(..., 3)` (unit geometric normal in input winding, zero on
    /// a miss). When the file stores normals, `shading_normals` float32 `(..., 3)` (the stored
    /// normals interpolated at the hit, zero on a miss); when it stores colours, `colors` uint8
    /// `(..., 4)` (RGBA interpolated, zero on a miss). `nthreads` > 0 traces on that many
    /// threads; `invalid="miss"` answers invalid rays (NaN, infinite, zero direction) as misses
    /// instead of raising `ValueError`.
    #[pyo3(signature = (rays, tnear = 0.0, tfar = f32::INFINITY, nthreads = 0, invalid = "raise"))]
    fn cast_rays<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        tnear: f32,
        tfar: f32,
        nthreads: usize,
        invalid: &str,
    ) -> PyResult<Bound<'py, PyDict>> {
        check_ids_fit(&self.file)?;
        let query = RayQuery::new(tnear, tfar, nthreads, invalid)?;
        let attributes = self.file.attributes();
        let arrays = rays::with_components(rays, |shape, components| {
            let arrays = AnswerArrays::empty(py, &shape, attributes)?;
            let mut borrowed = arrays.borrow();
            let mut out = borrowed.slices()?;
            // A retry with the valid rays alone (`invalid="miss"`) writes every answer again.
            let cast = |scene: &Scene, rays: Rays, shape: &[usize], kernel| {
                scene.cast(rays, shape, kernel, &mut out)
            };
            py.detach(|| self.answer_rays(components, &shape, query, cast))
                .map_err(PyValueError::new_err)?;
            drop(borrowed);
            Ok(arrays)
        })?;
        self.complete()?;
        arrays.into_dict(py)
    }

    /// Whether each ray of `rays` (as for `cast_rays`) hits anything on `[tnear, tfar]`:
    /// bool `(...)`; an invalid ray with `invalid="miss"` is not occluded.
    #[pyo3(signature = (rays, tnear = 0.0, tfar = f32::INFINITY, nthreads = 0, invalid = "raise"))]
    fn test_occlusions<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        tnear: f32,
        tfar: f32,
        nthreads: usize,
        invalid: &str,
    ) -> PyResult<Bound<'py, PyAny>> {
        let query = RayQuery::new(tnear, tfar, nthreads, invalid)?;
        let (shape, occluded) = self.trace(py, rays, query, Scene::occlusions)?;
        ndarray(py, occluded, &shape)
    }

    /// The closest point of the surface to each of `query_points` (`(..., 3)`, float32 or
    /// float64, computed in float32), exact point-triangle distance. Returns a dict: `points`
    /// float32 `(..., 3)`, `primitive_ids` uint32 `(...)` (named as by `cast_rays`),
    /// `primitive_uvs` float32 `(..., 2)` (the point's barycentric weights of the triangle's
    /// second and third corners), `primitive_normals` float32 `(..., 3)` (the triangle's unit
    /// geometric normal in input winding).
    #[pyo3(signature = (query_points, nthreads = 0))]
    fn compute_closest_points<'py>(
        &self,
        py: Python<'py>,
        query_points: &Bound<'py, PyAny>,
        nthreads: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        check_ids_fit(&self.file)?;
        let (shape, answers) = self.closest(py, query_points, nthreads)?;
        let result = PyDict::new(py);
        let with = |extra: &[usize]| [&shape[..], extra].concat();
        result.set_item("points", ndarray(py, answers.points, &with(&[3]))?)?;
        result.set_item("primitive_ids", ndarray(py, answers.ids, &shape)?)?;
        result.set_item("primitive_uvs", ndarray(py, answers.uvs, &with(&[2]))?)?;
        result.set_item(
            "primitive_normals",
            ndarray(py, answers.normals, &with(&[3]))?,
        )?;
        Ok(result)
    }

    /// The distance from each of `query_points` (as for `compute_closest_points`) to the
    /// surface: float32 `(...)`.
    #[pyo3(signature = (query_points, nthreads = 0))]
    fn compute_distance<'py>(
        &self,
        py: Python<'py>,
        query_points: &Bound<'py, PyAny>,
        nthreads: usize,
    ) -> PyResult<Bound<'py, PyAny>> {
        let (shape, answers) = self.closest(py, query_points, nthreads)?;
        ndarray(py, answers.distances, &shape)
    }

    /// How many times each ray of `rays` (as for `cast_rays`) crosses the surface on
    /// `[tnear, tfar]`: int32 `(...)`. A crossing through an edge or a vertex of a closed,
    /// consistently oriented mesh counts once; a ray in a triangle's plane crosses nothing there.
    #[pyo3(signature = (rays, tnear = 0.0, tfar = f32::INFINITY, nthreads = 0))]
    fn count_intersections<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        tnear: f32,
        tfar: f32,
        nthreads: usize,
    ) -> PyResult<Bound<'py, PyAny>> {
        let query = RayQuery::new(tnear, tfar, nthreads, "raise")?;
        let (shape, counts) = self.trace(py, rays, query, |scene, rays, _, _| {
            crossings::count(&scene.file, &rays)
        })?;
        ndarray(py, counts, &shape)
    }

    /// Every crossing of each ray of `rays` (as for `count_intersections`) on `[tnear, tfar]`:
    /// a dict of `ray_splits` uint32 `(N + 1,)` (ray `i`'s crossings are
    /// `ray_splits[i]:ray_splits[i + 1]`, `N` the number of rays, flattened), `ray_ids` uint32,
    /// `t_hit` float32, `primitive_ids` uint32 `(H,)` and `primitive_uvs` float32 `(H, 2)`, a
    /// ray's crossings contiguous, `t` ascending, ties by primitive id.
    #[pyo3(signature = (rays, tnear = 0.0, tfar = f32::INFINITY, nthreads = 0))]
    fn list_intersections<'py>(
        &self,
        py: Python<'py>,
        rays: &Bound<'py, PyAny>,
        tnear: f32,
        tfar: f32,
        nthreads: usize,
    ) -> PyResult<Bound<'py, PyDict>> {
        check_ids_fit(&self.file)?;
        let query = RayQuery::new(tnear, tfar, nthreads, "raise")?;
        let (_, found) = self.trace(py, rays, query, |scene, rays, _, _| {
            crossings::list(&scene.file, scene.primitive_ids(), &rays)
        })?;
        let hits = found.t.len();
        let result = PyDict::new(py);
        let splits = found.splits.len();
        result.set_item("ray_splits", ndarray(py, found.splits, &[splits])?)?;
        result.set_item("ray_ids", ndarray(py, found.ray_ids, &[hits])?)?;
        result.set_item("t_hit", ndarray(py, found.t, &[hits])?)?;
        result.set_item("primitive_ids", ndarray(py, found.ids, &[hits])?)?;
        result.set_item("primitive_uvs", ndarray(py, found.uvs, &[hits, 2])?)?;
        Ok(result)
    }

    /// The distance from each of `query_points` (as for `compute_closest_points`) to the
    /// surface, negative inside: float32 `(...)`. Inside is the parity of one ray's crossings
    /// on a closed mesh (exact), else the majority of `nsamples` rays in fixed directions (not
    /// exact: a `RuntimeWarning` says so, once per scene).
    #[pyo3(signature = (query_points, nthreads = 0, nsamples = 1))]
    fn compute_signed_distance<'py>(
        &self,
        py: Python<'py>,
        query_points: &Bound<'py, PyAny>,
        nthreads: usize,
        nsamples: u32,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.inside_query(
            py,
            query_points,
            nthreads,
            nsamples,
            points::signed_distances,
        )
    }

    /// 1.0 for each of `query_points` inside the surface, 0.0 outside: float32 `(...)`,
    /// decided as for `compute_signed_distance`.
    #[pyo3(signature = (query_points, nthreads = 0, nsamples = 1))]
    fn compute_occupancy<'py>(
        &self,
        py: Python<'py>,
        query_points: &Bound<'py, PyAny>,
        nthreads: usize,
        nsamples: u32,
    ) -> PyResult<Bound<'py, PyAny>> {
        self.inside_query(py, query_points, nthreads, nsamples, points::occupancy)
    }

    /// Whether the conversion found the mesh closed (every edge shared by exactly two
    /// triangles running it in opposite directions); false when the file does not say (files
    /// converted before closedness was stored).
    #[getter]
    fn closed(&self) -> bool {
        self.file.closed()
    }

    /// `(min, max)` of the stored vertices, float32 `(3,)` each.
    #[getter]
    fn bounds<'py>(
        &self,
        py: Python<'py>,
    ) -> (Bound<'py, PyArray1<f32>>, Bound<'py, PyArray1<f32>>) {
        let header = self.file.header();
        (
            PyArray1::from_slice(py, &header.bounds_min),
            PyArray1::from_slice(py, &header.bounds_max),
        )
    }

    /// The statistics `reducem inspect --json` prints, as a dict with the same keys, and
    /// `closed`, `boundary_edges`, `nonmanifold_edges` (None when the file does not say).
    #[getter]
    fn info<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        // The statistics read every strip: all of them are validated first.
        py.detach(|| self.file.validate_all())
            .map_err(format_error)?;
        let stats = py.detach(|| reducem::inspect::file_stats(&self.file));
        let text = serde_json::to_string(&stats).map_err(reducem_error)?;
        let info = py.import("json")?.call_method1("loads", (text,))?;
        // The closedness keys, unless the statistics carry them already.
        let closedness = self.file.closedness();
        let keys = [
            (
                "closed",
                self.file.closed().into_pyobject(py)?.to_owned().into_any(),
            ),
            (
                "boundary_edges",
                closedness.map(|c| c.boundary_edges).into_pyobject(py)?,
            ),
            (
                "nonmanifold_edges",
                closedness.map(|c| c.nonmanifold_edges).into_pyobject(py)?,
            ),
        ];
        for (key, value) in keys {
            if !info.contains(key)? {
                info.set_item(key, value)?;
            }
        }
        Ok(info)
    }

    /// Every stored triangle, float32 `(n, 3, 3)` (triangle, corner, axis), in file order and
    /// input winding: the triangles `reducem decode` writes, in its order.
    fn triangles<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        py.detach(|| self.file.validate_all())
            .map_err(format_error)?;
        let corners: Vec<f32> = py.detach(|| {
            reducem::decode::triangles(&self.file)
                .flat_map(|triangle| triangle.into_iter().flatten())
                .collect()
        });
        let count = corners.len() / 9;
        ndarray(py, corners, &[count, 3, 3])
    }

    /// Renders the file as `reducem render` does: `scene` is a scene TOML path or a dict with
    /// the same tables and keys (docs/SCENES.md); keyword overrides are named like the
    /// command's flags (`width`, `height`, `antialiasing`, `camera_position` with `look_at`,
    /// `camera_up`, `fov`, `ao_samples`, `ao_distance`, `exposure`, `up="y"`). Returns the
    /// 8-bit sRGB image, uint8 `(height, width, 3)`.
    #[pyo3(signature = (scene, **overrides))]
    fn render<'py>(
        &self,
        py: Python<'py>,
        scene: &Bound<'py, PyAny>,
        overrides: Option<&Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let scene = crate::render::load(scene, overrides)?;
        let options = TraceOptions {
            kernel: kernel()?,
            ..TraceOptions::default()
        };
        let (width, height, pixels) = py.detach(|| {
            let tracer = Tracer::new(&self.file, options);
            let (frame, _) = reducem::render::render(&tracer, &scene);
            let pixels = reducem::render::image::srgb_bytes(&frame);
            (frame.width as usize, frame.height as usize, pixels)
        });
        self.complete()?;
        ndarray(py, pixels, &[height, width, 3])
    }

    /// The file's path.
    #[getter]
    fn path(&self) -> PathBuf {
        self.file.path().to_path_buf()
    }

    fn __repr__(&self) -> String {
        format!(
            "reducem.Scene({:?}, triangles={})",
            self.file.path().display().to_string(),
            self.file.header().triangle_count
        )
    }
}

/// How `cast_rays` and `test_occlusions` were asked to trace.
#[derive(Clone, Copy)]
struct RayQuery {
    tnear: f32,
    tfar: f32,
    nthreads: usize,
    invalid: InvalidRays,
    kernel: Kernel,
}

impl RayQuery {
    fn new(tnear: f32, tfar: f32, nthreads: usize, invalid: &str) -> PyResult<RayQuery> {
        let invalid = InvalidRays::parse(invalid)?;
        rays::check_interval(tnear, tfar)?;
        Ok(RayQuery {
            tnear,
            tfar,
            nthreads,
            invalid,
            kernel: kernel()?,
        })
    }
}

impl Scene {
    /// Reads and validates `rays`, answers them with `answer` without the GIL on the query's
    /// threads, and fails when they met a corrupt part of the file; the rays' leading shape
    /// and the answers.
    fn trace<T: Send>(
        &self,
        py: Python<'_>,
        rays: &Bound<'_, PyAny>,
        query: RayQuery,
        answer: impl FnMut(&Scene, Rays, &[usize], Kernel) -> Result<T, usize> + Send,
    ) -> PyResult<(Vec<usize>, T)> {
        let traced = rays::with_components(rays, |shape, components| {
            let answers = py.detach(|| self.answer_rays(components, &shape, query, answer));
            Ok((shape, answers.map_err(PyValueError::new_err)?))
        })?;
        self.complete()?;
        Ok(traced)
    }

    /// `answer` of the rays `components` (leading shape `shape`) on the query's threads; for
    /// `invalid="miss"`, once more on the valid ones alone when it met an invalid ray.
    fn answer_rays<T: Send>(
        &self,
        components: Components<'_>,
        shape: &[usize],
        query: RayQuery,
        mut answer: impl FnMut(&Scene, Rays, &[usize], Kernel) -> Result<T, usize> + Send,
    ) -> Result<T, String> {
        let RayQuery {
            tnear,
            tfar,
            nthreads,
            invalid,
            kernel,
        } = query;
        in_pool(nthreads, || {
            let all = Rays::All {
                components,
                tnear,
                tfar,
            };
            let first_invalid = match answer(self, all, shape, kernel) {
                Ok(answers) => return Ok(answers),
                Err(index) => index,
            };
            if invalid == InvalidRays::Raise {
                let interval = (tnear, tfar);
                return Err(rays::describe_invalid(
                    first_invalid,
                    components,
                    interval,
                    shape,
                ));
            }
            let valid = rays::valid_only(components, tnear, tfar);
            answer(self, valid, shape, kernel)
                .map_err(|index| format!("ray {index} is invalid after filtering"))
        })
    }

    /// Closest points of `query_points` without the GIL on `nthreads` threads, and their
    /// leading shape; fails when the search met a corrupt part of the file.
    fn closest(
        &self,
        py: Python<'_>,
        query_points: &Bound<'_, PyAny>,
        nthreads: usize,
    ) -> PyResult<(Vec<usize>, ClosestAnswers)> {
        self.per_point(py, query_points, nthreads, |file, components| {
            points::closest_points(file, self.primitive_ids(), components)
        })
    }

    /// `answer` for `query_points` without the GIL on `nthreads` threads, and their leading
    /// shape; fails when it met a corrupt part of the file.
    fn per_point<T: Send>(
        &self,
        py: Python<'_>,
        query_points: &Bound<'_, PyAny>,
        nthreads: usize,
        answer: impl Fn(&ReducemFile, Components<'_>) -> T + Sync,
    ) -> PyResult<(Vec<usize>, T)> {
        let found = points::with_points(py, query_points, |shape, components| {
            let answers = py.detach(|| in_pool(nthreads, || Ok(answer(&self.file, components))));
            Ok((shape, answers.map_err(PyValueError::new_err)?))
        })?;
        self.complete()?;
        Ok(found)
    }

    /// `answer` of `query_points` and the rays that decide inside from `nsamples` (one on a
    /// closed mesh), as an array of their leading shape; warns when that is not exact.
    fn inside_query<'py>(
        &self,
        py: Python<'py>,
        query_points: &Bound<'py, PyAny>,
        nthreads: usize,
        nsamples: u32,
        answer: fn(&ReducemFile, Components<'_>, u32) -> Vec<f32>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let rays = inside_rays(&self.file, nsamples);
        let (shape, answers) = self.per_point(py, query_points, nthreads, |file, points| {
            answer(file, points, rays)
        })?;
        self.warn_unless_exact(py)?;
        ndarray(py, answers, &shape)
    }

    /// A `RuntimeWarning`, the first time on this scene, that inside/outside answers are a
    /// vote of rays rather than exact because the mesh is not known to be closed.
    fn warn_unless_exact(&self, py: Python<'_>) -> PyResult<()> {
        if self.file.closed() || self.warned_not_exact.swap(true, Ordering::Relaxed) {
            return Ok(());
        }
        let message = format!(
            "{}: the mesh is not known to be closed; inside/outside is the majority of \
             nsamples rays, not exact",
            self.file.path().display()
        );
        let warning = py.get_type::<PyRuntimeWarning>();
        PyErr::warn(py, &warning, &std::ffi::CString::new(message)?, 1)
    }

    /// Fails when rays met a corrupt strip or node (the file is validated lazily, part by part
    /// as rays reach it, when larger than 1 MiB): the answers are then incomplete, and the error
    /// names the file and the byte, as `reducem query` does.
    fn complete(&self) -> PyResult<()> {
        self.file
            .defect()
            .map_or(Ok(()), |defect| Err(format_error(defect)))
    }

    /// Writes the closest hits of `rays` (leading shape `shape`) into `out`, or gives the index
    /// of the first invalid ray among them. Rays in their own order or in bands are answered
    /// straight into `out`; rays gathered in another order into buffers, then placed.
    fn cast(
        &self,
        rays: Rays,
        shape: &[usize],
        kernel: Kernel,
        out: &mut Answers,
    ) -> Result<(), usize> {
        let (rays, order) = trace_order(rays, shape)?;
        let Rays::Gathered(gathered) = &rays else {
            return self.cast_into(&rays, &order, kernel, out);
        };
        let mut traced = AnswerBuffers::new(rays.traced(), self.file.attributes());
        self.cast_into(&rays, &order, kernel, &mut traced.answers())?;
        out.place(&traced, gathered);
        Ok(())
    }

    /// Writes the closest hits of `rays`, cut into chunks by `order`, into `out` (one answer
    /// per traced ray).
    fn cast_into(
        &self,
        rays: &Rays,
        order: &ChunkOrder,
        kernel: Kernel,
        out: &mut Answers,
    ) -> Result<(), usize> {
        let tracer = Tracer::new(&self.file, trace_options(kernel));
        let ids = self.primitive_ids();
        let chunk_rays = order.chunk_rays();
        let first_invalid = AtomicUsize::new(usize::MAX);
        out.chunks(chunk_rays)
            .into_par_iter()
            .enumerate()
            .for_each_init(Chunk::default, |traced, (chunk, mut out)| {
                let range = chunk * chunk_rays..chunk * chunk_rays + out.len();
                if let Some(invalid) = order.read(rays, range, traced) {
                    first_invalid.fetch_min(invalid, Ordering::Relaxed);
                    return;
                }
                out.fill_misses();
                let answer = |k: usize, hit: Option<Hit>| {
                    if let Some(hit) = hit {
                        self.write_hit(&mut out, traced.places[k] as usize, &hit, ids);
                    }
                };
                match order {
                    ChunkOrder::Image { .. } => {
                        tracer.intersect_each_in_order(&traced.rays, answer)
                    }
                    ChunkOrder::Input => tracer.intersect_each(&traced.rays, answer),
                }
            });
        check_valid(first_invalid)
    }

    /// Writes `hit`, named and with its attributes read, as ray `place`'s answer in `out` (whose
    /// rays are misses until then). Out of line, so that the per-ray closure that calls it
    /// stays small enough to be inlined into the tracing loop.
    #[inline(never)]
    fn write_hit(&self, out: &mut Answers, place: usize, hit: &Hit, ids: &PrimitiveIds) {
        let id = ids.id(&self.file, hit.strip, hit.window);
        let read = self
            .file
            .attributes()
            .per_vertex()
            .then(|| surface_attributes(&self.file, hit));
        out.write_hit(place, hit, id, read);
    }

    /// Whether each of `rays` (leading shape `shape`) is occluded, or the index of the first
    /// invalid ray among them.
    fn occlusions(&self, rays: Rays, shape: &[usize], kernel: Kernel) -> Result<Vec<bool>, usize> {
        let (rays, order) = trace_order(rays, shape)?;
        let tracer = Tracer::new(&self.file, trace_options(kernel));
        let mut occluded = vec![false; rays.traced()];
        let chunk_rays = order.chunk_rays();
        let first_invalid = AtomicUsize::new(usize::MAX);
        occluded
            .par_chunks_mut(chunk_rays)
            .enumerate()
            .for_each_init(Chunk::default, |traced, (chunk, out)| {
                let range = chunk * chunk_rays..chunk * chunk_rays + out.len();
                if let Some(invalid) = order.read(&rays, range, traced) {
                    first_invalid.fetch_min(invalid, Ordering::Relaxed);
                    return;
                }
                let occluded = tracer.occluded_chunk(&traced.rays);
                for (&place, answer) in traced.places.iter().zip(occluded) {
                    out[place as usize] = answer;
                }
            });
        check_valid(first_invalid)?;
        let Rays::Gathered(gathered) = rays else {
            return Ok(occluded);
        };
        let mut all = vec![false; gathered.total];
        for (k, answer) in occluded.into_iter().enumerate() {
            all[gathered.position(k)] = answer;
        }
        Ok(all)
    }

    /// The scene's [`PrimitiveIds`], made on the first query that names triangles.
    fn primitive_ids(&self) -> &PrimitiveIds {
        self.primitive_ids
            .get_or_init(|| PrimitiveIds::of(&self.file))
    }
}

/// The rays to trace (gathered out of `rays` in another order, or `rays` as they are) and how
/// to cut them into chunks: camera rays in bands of tiles, an incoherent batch sorted as
/// `reducem query` sorts it, anything else as it comes ([`order`]).
fn trace_order<'a>(rays: Rays<'a>, shape: &[usize]) -> Result<(Rays<'a>, ChunkOrder), usize> {
    match ChunkOrder::of(&rays, shape) {
        ChunkOrder::Input => Ok((order::sorted(rays)?, ChunkOrder::Input)),
        bands => Ok((rays, bands)),
    }
}

/// `Err` with the first invalid ray's index when a chunk met one.
fn check_valid(first_invalid: AtomicUsize) -> Result<(), usize> {
    match first_invalid.into_inner() {
        usize::MAX => Ok(()),
        index => Err(index),
    }
}

/// `primitive_ids` are uint32 with 4294967295 for a miss: refuses a file with more triangles.
fn check_ids_fit(file: &ReducemFile) -> PyResult<()> {
    let triangles = file.header().triangle_count;
    if triangles >= u64::from(NO_PRIMITIVE) {
        return Err(crate::errors::ReducemError::new_err(format!(
            "{}: {triangles} triangles do not fit the uint32 primitive_ids",
            file.path().display()
        )));
    }
    Ok(())
}

/// The kernel `reducem query` uses: `REDUCEM_KERNEL`, or the fastest this CPU runs.
fn kernel() -> PyResult<Kernel> {
    Kernel::from_env().map_err(|error| PyValueError::new_err(error.to_string()))
}

fn trace_options(kernel: Kernel) -> TraceOptions {
    TraceOptions {
        kernel,
        ..TraceOptions::default()
    }
}

/// Runs `work` on rayon's global pool, or on the pool of `threads` threads when that is not 0.
fn in_pool<T: Send>(
    threads: usize,
    work: impl FnOnce() -> Result<T, String> + Send,
) -> Result<T, String> {
    if threads == 0 {
        return work();
    }
    pool(threads)?.install(work)
}

/// The pool of `threads` threads, built on its first use and kept: a call with `nthreads`
/// then starts and joins no threads, and runs on threads whose stacks are already faulted in.
fn pool(threads: usize) -> Result<Arc<ThreadPool>, String> {
    static POOLS: Mutex<Vec<(usize, Arc<ThreadPool>)>> = Mutex::new(Vec::new());
    let mut pools = POOLS.lock().unwrap_or_else(PoisonError::into_inner);
    if let Some((_, pool)) = pools.iter().find(|(count, _)| *count == threads) {
        return Ok(Arc::clone(pool));
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|error| format!("nthreads = {threads}: {error}"))?;
    let pool = Arc::new(pool);
    pools.push((threads, Arc::clone(&pool)));
    Ok(pool)
}

/// `values` as a numpy array of `shape` (without a copy).
fn ndarray<'py, T: numpy::Element>(
    py: Python<'py>,
    values: Vec<T>,
    shape: &[usize],
) -> PyResult<Bound<'py, PyAny>> {
    let array = Array::from_shape_vec(IxDyn(shape), values).map_err(reducem_error)?;
    Ok(PyArray::from_owned_array(py, array).into_any())
}
