"""What the benchmarks that run reducem against its peers (scripts/bench_queries.sh,
bench_python.py) hand both: `reducem decode`'s PLY as numpy arrays, the rays, and ray files
for `reducem query`."""
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


def camera_rays(low, high, side):
    """A 60° pinhole camera framing the bounds, `(side, side, 6)` float32, row by row (as
    Open3D's create_rays_pinhole orders its rays)."""
    centre, size = (low + high) / 2, float(np.linalg.norm(high - low))
    eye = centre + np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0]) * size
    forward = (centre - eye) / np.linalg.norm(centre - eye)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = np.tan(np.radians(30.0))
    ys, xs = np.meshgrid(np.linspace(half, -half, side), np.linspace(-half, half, side),
                         indexing="ij")
    directions = forward + xs[..., None] * right + ys[..., None] * up
    origins = np.broadcast_to(eye, directions.shape)
    return np.concatenate([origins, directions], -1).astype(np.float32)


def incoherent_rays(low, high, count):
    """Uniform origins in the bounds, directions uniform on the sphere, `(count, 6)` float32."""
    rng = np.random.default_rng(1)
    origins = low + rng.random((count, 3)) * (high - low)
    return np.concatenate([origins, rng.normal(size=(count, 3))], -1).astype(np.float32)


def write_ray_file(rays, path):
    records = np.zeros((rays.size // 6, 8), "<f4")
    records[:, :6] = rays.reshape(-1, 6)
    records[:, 7] = np.inf
    records.tofile(path)
