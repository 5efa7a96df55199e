"""Ray queries on ReduceM files from numpy.

``reducem.open(path)`` maps and validates a ReduceM file (a large one part by part, as queries
reach it) and returns a ``Scene``, whose
``cast_rays`` and ``test_occlusions`` follow Open3D's ``RaycastingScene`` conventions: rays shaped
``(..., 6)`` as ``[ox, oy, oz, dx, dy, dz]``, answers shaped like the rays' leading axes.
Tracing runs in the native tracer, without the GIL, on all cores (or ``nthreads``), and gives
bit-identical answers to ``reducem query`` on the same rays.

``reducem.convert(input, output, *, progress=None, **options)`` converts a PLY, OBJ, STL or glTF mesh with
the staged, resumable conversion of ``pipeline convert``; options are named like the
configuration keys. It reports to the ``reducem`` logger (stages at INFO, each unit of work at
DEBUG) and, if given, calls ``progress(stage, done, total, unit)`` as each stage starts and
after each unit of work.

``reducem.from_arrays(vertices, triangles, path=None, **options)`` converts a mesh held in numpy
arrays the same way (in a temporary file unless ``path`` is given) and opens it, for meshes that
Open3D's ``add_triangles`` would take.
"""

from ._arrays import from_arrays
from ._native import ReducemError, Scene, convert, open

__all__ = ["ReducemError", "Scene", "convert", "from_arrays", "open"]
