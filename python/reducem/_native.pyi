"""Types of the native module; the runtime signatures are in ``python/src/``."""

import math
import pathlib
from os import PathLike
from typing import Any, Callable, Literal, Mapping, Optional, Sequence, TypedDict, Union

import numpy as np
from numpy.typing import ArrayLike, NDArray

_Path = Union[str, PathLike[str]]
_Invalid = Literal["raise", "miss"]

class _Hits(TypedDict):
    t_hit: NDArray[np.float32]
    geometry_ids: NDArray[np.uint32]
    primitive_ids: NDArray[np.uint32]
    primitive_uvs: NDArray[np.float32]
    primitive_normals: NDArray[np.float32]

class _HitsWithAttributes(_Hits, total=False):
    # Present only when the file stores normals or colours.
    shading_normals: NDArray[np.float32]
    colors: NDArray[np.uint8]

class _ClosestPoints(TypedDict):
    points: NDArray[np.float32]
    primitive_ids: NDArray[np.uint32]
    primitive_uvs: NDArray[np.float32]
    primitive_normals: NDArray[np.float32]

class _Intersections(TypedDict):
    ray_splits: NDArray[np.uint32]
    ray_ids: NDArray[np.uint32]
    t_hit: NDArray[np.float32]
    primitive_ids: NDArray[np.uint32]
    primitive_uvs: NDArray[np.float32]

class ReducemError(Exception):
    """A file, ray set, scene or conversion that reducem rejects; the message names the file,
    the section or element and the byte offset."""

class Scene:
    """A mapped ReduceM file, from ``reducem.open``."""

    @property
    def bounds(self) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """``(min, max)`` of the stored vertices, float32 ``(3,)`` each."""
    @property
    def info(self) -> dict[str, Any]:
        """The statistics ``reducem inspect --json`` prints, with the same keys."""
    @property
    def path(self) -> pathlib.Path:
        """The file's path."""
    @property
    def closed(self) -> bool:
        """Whether the conversion found the mesh closed; false when the file does not say."""
    def cast_rays(
        self,
        rays: ArrayLike,
        tnear: float = 0.0,
        tfar: float = math.inf,
        nthreads: int = 0,
        invalid: _Invalid = "raise",
    ) -> _HitsWithAttributes:
        """Closest hits of ``rays`` (``(..., 6)``: origin, direction)."""
    def test_occlusions(
        self,
        rays: ArrayLike,
        tnear: float = 0.0,
        tfar: float = math.inf,
        nthreads: int = 0,
        invalid: _Invalid = "raise",
    ) -> NDArray[np.bool_]:
        """Whether each ray hits anything on ``[tnear, tfar]``."""
    def count_intersections(
        self, rays: ArrayLike, tnear: float = 0.0, tfar: float = math.inf, nthreads: int = 0
    ) -> NDArray[np.int32]:
        """How many times each ray crosses the surface on ``[tnear, tfar]``, ``(...)``."""
    def list_intersections(
        self, rays: ArrayLike, tnear: float = 0.0, tfar: float = math.inf, nthreads: int = 0
    ) -> _Intersections:
        """Every crossing of each ray on ``[tnear, tfar]``, a ray's contiguous, t ascending."""
    def compute_signed_distance(
        self, query_points: ArrayLike, nthreads: int = 0, nsamples: int = 1
    ) -> NDArray[np.float32]:
        """The distance from each point to the surface, negative inside, ``(...)``."""
    def compute_occupancy(
        self, query_points: ArrayLike, nthreads: int = 0, nsamples: int = 1
    ) -> NDArray[np.float32]:
        """1.0 for each point inside the surface, 0.0 outside, ``(...)``."""
    def compute_closest_points(
        self, query_points: ArrayLike, nthreads: int = 0
    ) -> _ClosestPoints:
        """The closest point of the surface to each of ``query_points`` (``(..., 3)``)."""
    def compute_distance(self, query_points: ArrayLike, nthreads: int = 0) -> NDArray[np.float32]:
        """The distance from each of ``query_points`` to the surface, ``(...)``."""
    def triangles(self) -> NDArray[np.float32]:
        """Every stored triangle, float32 ``(n, 3, 3)``, in file order and input winding."""
    def render(
        self,
        scene: Union[_Path, Mapping[str, Any]],
        *,
        up: Literal["y", "z"] = ...,
        width: int = ...,
        height: int = ...,
        antialiasing: int = ...,
        camera_position: Sequence[float] = ...,
        look_at: Sequence[float] = ...,
        camera_up: Sequence[float] = ...,
        fov: float = ...,
        ao_samples: int = ...,
        ao_distance: float = ...,
        exposure: float = ...,
    ) -> NDArray[np.uint8]:
        """Renders as ``reducem render``: the 8-bit sRGB image, ``(height, width, 3)``.
        Overrides left out keep the scene's value."""

def open(path: _Path) -> Scene:
    """Maps the ReduceM file at ``path`` and validates it."""

def convert(
    input: _Path,
    output: _Path,
    *,
    progress: Optional[Callable[[str, int, int, str], object]] = None,
    up: Literal["y", "z"] = ...,
    max_length: int = ...,
    leaf_windows: int = ...,
    sah_bins: int = ...,
    grid_nodes: bool = ...,
    encoding: Literal["f32", "grid"] = ...,
    grid_bits: int = ...,
    weld_tolerance: float = ...,
    max_triangles: int = ...,
    face_ids: bool = ...,
    normals: Literal["none", "oct8", "oct16"] = ...,
    colors: bool = ...,
    keep: bool = ...,
    work: _Path = ...,
    clean_after: bool = ...,
    if_locked: Literal["fail", "skip"] = ...,
) -> None:
    """Converts the mesh ``input`` (PLY, OBJ or STL, also .gz or .zst) to the ReduceM file ``output`` as ``pipeline
    convert`` does, resuming from its work directory. Options left out take the configuration's
    defaults; reports go to the ``reducem`` logger and to ``progress(stage, done, total, unit)``."""
