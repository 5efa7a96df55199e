"""`cast_rays` writes its answers into arrays numpy makes without zeroing them: every element
of every ray must be written, a miss's zeros too, whatever memory the arrays reuse."""

import numpy as np
import pytest

import reducem
from conftest import camera_rays

MISS_ID = 0xFFFFFFFF


def dirty_memory(rays, widths=(1, 1, 1, 2, 3, 3, 4)):
    """Frees arrays of the answers' sizes full of NaN, so that the next ones likely reuse them."""
    junk = [np.full(rays * width, np.nan, np.float32) for width in widths]
    del junk


def assert_misses(hits, miss):
    assert np.all(np.isinf(hits["t_hit"][miss]))
    assert np.all(hits["primitive_ids"][miss] == MISS_ID)
    assert np.all(hits["geometry_ids"][miss] == MISS_ID)
    for key in ("primitive_uvs", "primitive_normals", "shading_normals", "colors"):
        if key in hits:
            values = np.ascontiguousarray(hits[key][miss])
            assert not values.view(np.uint8).any(), f"{key} of a miss is not +0"


@pytest.mark.parametrize("shape", [(64, 64), (64 * 64,)])
def test_every_element_of_a_miss_is_written(model, shape):
    _, _, scene = model
    camera = camera_rays(scene, 64, 64).reshape(*shape, 6)
    hits = scene.cast_rays(camera)
    assert np.all(hits["geometry_ids"][np.isfinite(hits["t_hit"])] == 0)
    assert 0 < np.isfinite(hits["t_hit"]).sum() < hits["t_hit"].size
    del hits
    away = camera.copy()
    away[..., 3:] *= -1
    dirty_memory(camera[..., 0].size)
    assert_misses(scene.cast_rays(away), np.ones(shape, bool))
    dirty_memory(camera[..., 0].size)
    hits = scene.cast_rays(camera)
    assert_misses(hits, ~np.isfinite(hits["t_hit"]))


def write_grid_ply(path, side=8):
    """A flat square of `side`² quads in z = 0, with per-vertex normals (tilted) and colours."""
    ys, xs = np.mgrid[0 : side + 1, 0 : side + 1]
    count = (side + 1) ** 2
    lines = [
        "ply",
        "format ascii 1.0",
        f"element vertex {count}",
        *[f"property float {name}" for name in ("x", "y", "z", "nx", "ny", "nz")],
        *[f"property uchar {name}" for name in ("red", "green", "blue")],
        f"element face {2 * side * side}",
        "property list uchar int vertex_indices",
        "end_header",
    ]
    for x, y in zip(xs.ravel(), ys.ravel()):
        lines.append(f"{x} {y} 0 {0.1 * x} 0 1 {20 * x} {20 * y} 7")
    for y in range(side):
        for x in range(side):
            a = y * (side + 1) + x
            b, c, d = a + 1, a + side + 1, a + side + 2
            lines += [f"3 {a} {b} {d}", f"3 {a} {d} {c}"]
    path.write_text("\n".join(lines) + "\n")


def test_every_element_of_a_miss_is_written_with_attributes(tmp_path):
    ply = tmp_path / "grid.ply"
    write_grid_ply(ply)
    model = tmp_path / "grid.rdm"
    reducem.convert(ply, model, normals="oct16", colors=True)
    scene = reducem.open(model)
    rng = np.random.default_rng(2)
    count = 5000
    # Straight down from above the square and around it: about half of the rays miss.
    origins = np.column_stack([rng.uniform(-4, 12, (count, 2)), np.full(count, 3.0)])
    rays = np.hstack([origins, np.tile([0.0, 0.0, -1.0], (count, 1))]).astype(np.float32)
    dirty_memory(count)
    hits = scene.cast_rays(rays)
    hit = np.isfinite(hits["t_hit"])
    assert 0.2 * count < hit.sum() < 0.8 * count
    assert_misses(hits, ~hit)
    assert np.all(hits["colors"][hit][:, 3] == 255) and np.all(hits["colors"][hit][:, 2] == 7)
    np.testing.assert_allclose(np.linalg.norm(hits["shading_normals"][hit], axis=1), 1, atol=1e-6)
    one_by_one = [scene.cast_rays(ray[None]) for ray in rays[:200]]
    for key in hits:
        expected = np.concatenate([answer[key] for answer in one_by_one])
        np.testing.assert_array_equal(hits[key][:200], expected, err_msg=key)
