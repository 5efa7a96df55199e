"""`reducem decode`'s PLY (float x, y, z; list uchar int) as numpy arrays, for the benchmarks
that hand a model's own triangles to the peers (scripts/bench_queries.sh, bench_python.py)."""
import numpy as np


def read_decoded(path):
    """Vertices as float32 (n, 3) and faces as int32 (m, 3)."""
    with open(path, "rb") as f:
        counts = {}
        while (line := f.readline().strip()) != b"end_header":
            words = line.split()
            if words[:1] == [b"element"]:
                counts[words[1].decode()] = int(words[2])
        vertices = np.fromfile(f, "<f4", counts["vertex"] * 3).reshape(-1, 3)
        faces = np.fromfile(f, [("n", "u1"), ("i", "<i4", 3)], counts["face"])
    return vertices, np.ascontiguousarray(faces["i"])
