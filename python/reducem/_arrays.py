"""``reducem.from_arrays``: a Scene from numpy vertex and triangle arrays, through the same
conversion as a mesh file (the arrays are written as a binary PLY next to the output)."""

import os
import shutil
import tempfile
import weakref
from pathlib import Path
from typing import Any, Optional, Union

import numpy as np

from ._native import Scene, convert, open

_INDEX_LIMIT = np.iinfo(np.int32).max


def from_arrays(
    vertices: Any,
    triangles: Any,
    path: Optional[Union[str, "os.PathLike[str]"]] = None,
    **options: Any,
) -> Scene:
    """Converts the mesh of ``vertices`` (float32 or float64 ``(n, 3)``, stored as float32) and
    ``triangles`` (integer ``(m, 3)``, indices into ``vertices``) with ``reducem.convert``'s
    ``options`` and opens the result: at ``path`` when given (kept), else in a temporary
    directory removed when the returned Scene is garbage-collected or at exit."""
    vertices = _vertices(vertices)
    triangles = _triangles(triangles, len(vertices))
    work = Path(tempfile.mkdtemp(prefix="reducem-"))
    try:
        ply = work / "mesh.ply"
        _write_ply(ply, vertices, triangles)
        output = Path(path) if path is not None else work / "mesh.rdm"
        convert(ply, output, work=work / "convert.work", clean_after=True, **options)
        ply.unlink()
        scene = open(output)
    except BaseException:
        shutil.rmtree(work, ignore_errors=True)
        raise
    if path is not None:
        shutil.rmtree(work, ignore_errors=True)
    else:
        weakref.finalize(scene, shutil.rmtree, str(work), True)
    return scene


def _vertices(values: Any) -> "np.ndarray[Any, np.dtype[np.float32]]":
    array = np.asarray(values)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"vertices must have shape (n, 3), got shape {array.shape}")
    if array.dtype not in (np.float32, np.float64):
        raise TypeError(f"vertices must be float32 or float64, got dtype {array.dtype}")
    bad = np.flatnonzero(~np.isfinite(array).all(axis=1))
    if len(bad):
        raise ValueError(f"vertices[{bad[0]}] is not finite: {array[bad[0]].tolist()}")
    return np.ascontiguousarray(array, dtype="<f4")


def _triangles(values: Any, vertex_count: int) -> "np.ndarray[Any, np.dtype[np.int32]]":
    array = np.asarray(values)
    if array.ndim != 2 or array.shape[1] != 3:
        raise ValueError(f"triangles must have shape (m, 3), got shape {array.shape}")
    if not np.issubdtype(array.dtype, np.integer):
        raise TypeError(f"triangles must be integers, got dtype {array.dtype}")
    if vertex_count > _INDEX_LIMIT:
        raise ValueError(f"vertices: {vertex_count} vertices, at most {_INDEX_LIMIT} supported")
    bad = np.argwhere((array < 0) | (array >= vertex_count))
    if len(bad):
        row, corner = bad[0]
        raise ValueError(
            f"triangles[{row}, {corner}] = {array[row, corner]} is not a vertex index "
            f"(0 to {vertex_count - 1})"
        )
    return np.ascontiguousarray(array, dtype="<i4")


def _write_ply(path: Path, vertices: Any, triangles: Any) -> None:
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(vertices)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        f"element face {len(triangles)}\n"
        "property list uchar int vertex_indices\nend_header\n"
    )
    faces = np.empty(len(triangles), dtype=[("n", "u1"), ("i", "<i4", 3)])
    faces["n"] = 3
    faces["i"] = triangles
    with path.open("wb") as out:
        out.write(header.encode("ascii"))
        vertices.tofile(out)
        faces.tofile(out)
