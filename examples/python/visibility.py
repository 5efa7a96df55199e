"""Which of N points on a model see each other: one shadow ray per pair, traced with
`Scene.test_occlusions`, the symmetric N x N visibility matrix saved as .npy.

    python examples/python/visibility.py MODEL.rdm --points 200 -o visible.npy

The points are where random rays from outside the bounds first hit the model (found with
`Scene.cast_rays`), lifted off the surface along the normal facing the ray so that a point
does not hide itself. A pair sees each other when nothing lies strictly between them.
"""

import argparse
import time
from pathlib import Path

import numpy as np

import reducem


def surface_points(scene, count, seed):
    """`count` points on the model, each lifted by 1e-4 of the diagonal off its surface."""
    rng = np.random.default_rng(seed)
    low, high = (bound.astype(np.float64) for bound in scene.bounds)
    centre, diagonal = (low + high) / 2, np.linalg.norm(high - low)
    points = []
    while sum(len(p) for p in points) < count:
        away = rng.normal(size=(4 * count, 3))
        away /= np.linalg.norm(away, axis=1, keepdims=True)
        origins = centre + diagonal * away
        targets = low + (high - low) * rng.random((4 * count, 3))
        rays = np.concatenate([origins, targets - origins], axis=1)
        hits = scene.cast_rays(rays)
        hit = np.isfinite(hits["t_hit"])
        normals = hits["primitive_normals"][hit].astype(np.float64)
        facing = -np.sign(np.sum(normals * rays[hit, 3:], axis=1, keepdims=True))
        on_surface = rays[hit, :3] + hits["t_hit"][hit, None] * rays[hit, 3:]
        points.append(on_surface + 1e-4 * diagonal * facing * normals)
    return np.concatenate(points)[:count]


def visibility(scene, points):
    """`visible[i, j]`: the segment between points i and j is free."""
    count = len(points)
    first, second = np.triu_indices(count, k=1)
    rays = np.concatenate([points[first], points[second] - points[first]], axis=1)
    # t is in units of the direction (the whole segment), so [0, 1] is the segment itself;
    # the ends are left out by a hair so that the target's own surface does not count.
    blocked = scene.test_occlusions(rays, tnear=1e-6, tfar=1 - 1e-6)
    visible = np.eye(count, dtype=bool)
    visible[first, second] = visible[second, first] = ~blocked
    return visible


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", type=Path, help="a ReduceM file")
    parser.add_argument("--points", type=int, default=200)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("-o", "--output", type=Path, help="where to save the matrix (.npy)")
    args = parser.parse_args()

    scene = reducem.open(args.model)
    points = surface_points(scene, args.points, args.seed)
    started = time.perf_counter()
    visible = visibility(scene, points)
    seconds = time.perf_counter() - started
    pairs = args.points * (args.points - 1) // 2
    mutual = (visible.sum() - args.points) // 2
    print(
        f"{args.points} points, {pairs} pairs: {mutual} see each other "
        f"({100 * mutual / max(pairs, 1):.1f}%), traced in {seconds * 1e3:.1f} ms"
    )
    if args.output:
        np.save(args.output, visible)
        print(f"wrote {args.output}")


if __name__ == "__main__":
    main()
