"""A spinning lidar inside a ReduceM file: one revolution of a 64-channel scanner (64 x 2048
rays, elevations -25 to +15 degrees), traced with `Scene.cast_rays`, the returns written as a
binary PLY point cloud (x, y, z, range, normal).

    python examples/python/lidar.py MODEL.rdm -o cloud.ply [--position X Y Z]

The scanner sits at `--position`, by default the centre of the model's bounds, with its spin
axis along z. Ranges beyond `--max-range` (default: the bounds' diagonal) are no return.
"""

import argparse
import time
from pathlib import Path

import numpy as np

import reducem


def scanner_rays(position, channels=64, steps=2048, lowest=-25.0, highest=15.0):
    """Unit rays of one revolution, shaped (channels, steps, 6)."""
    elevation = np.radians(np.linspace(lowest, highest, channels))[:, None]
    azimuth = np.linspace(0.0, 2 * np.pi, steps, endpoint=False)[None, :]
    directions = np.stack(
        np.broadcast_arrays(
            np.cos(elevation) * np.cos(azimuth),
            np.cos(elevation) * np.sin(azimuth),
            np.sin(elevation),
        ),
        axis=-1,
    )
    origins = np.broadcast_to(np.asarray(position, dtype=np.float64), directions.shape)
    return np.concatenate([origins, directions], axis=-1).astype(np.float32)


def write_ply(path, points, ranges, normals):
    """Binary little-endian PLY: float x y z range nx ny nz per point."""
    record = np.dtype(
        [(name, "<f4") for name in ("x", "y", "z", "range", "nx", "ny", "nz")]
    )
    cloud = np.empty(len(points), dtype=record)
    for axis, name in enumerate("xyz"):
        cloud[name] = points[:, axis]
        cloud["n" + name] = normals[:, axis]
    cloud["range"] = ranges
    properties = "".join(f"property float {name}\n" for name in record.names)
    header = (
        "ply\nformat binary_little_endian 1.0\ncomment lidar returns traced by reducem\n"
        f"element vertex {len(points)}\n{properties}end_header\n"
    )
    with open(path, "wb") as out:
        out.write(header.encode())
        out.write(cloud.tobytes())


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", type=Path, help="a ReduceM file")
    parser.add_argument("-o", "--output", type=Path, required=True, help="the PLY to write")
    parser.add_argument("--position", type=float, nargs=3, help="scanner position X Y Z")
    parser.add_argument("--max-range", type=float, help="farthest return (model units)")
    parser.add_argument("--channels", type=int, default=64)
    parser.add_argument("--steps", type=int, default=2048, help="azimuth steps per revolution")
    args = parser.parse_args()

    scene = reducem.open(args.model)
    low, high = scene.bounds
    position = args.position if args.position else (low + high) / 2
    max_range = args.max_range or float(np.linalg.norm(high - low))
    rays = scanner_rays(position, args.channels, args.steps)

    started = time.perf_counter()
    hits = scene.cast_rays(rays, tfar=max_range)
    seconds = time.perf_counter() - started

    returned = np.isfinite(hits["t_hit"])
    ranges = hits["t_hit"][returned]
    points = rays[returned][:, :3] + ranges[:, None] * rays[returned][:, 3:]
    write_ply(args.output, points, ranges, hits["primitive_normals"][returned])
    print(
        f"{rays.shape[0]} x {rays.shape[1]} rays from {np.round(position, 4).tolist()}: "
        f"{returned.sum()} returns in {seconds * 1e3:.1f} ms "
        f"({rays[..., 0].size / seconds / 1e6:.2f} Mrays/s); wrote {args.output}"
    )


if __name__ == "__main__":
    main()
