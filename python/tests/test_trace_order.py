"""The order batches are traced in leaves the answers alone: camera rays (traced in bands of
tiles) and large incoherent batches (traced sorted by octant and origin cell, as `reducem
query` sorts them) answer bit for bit as the same rays one call per ray and as `reducem query`."""

import numpy as np
import pytest

from conftest import camera_rays, query, random_rays

# Large enough for `reducem query`'s reordering of incoherent batches (2**16 rays and up).
SORTED_RAYS = 70_000

KEYS = ("t_hit", "primitive_ids", "geometry_ids", "primitive_uvs", "primitive_normals")


def bits(values):
    values = np.ascontiguousarray(values)
    return values.view(np.uint32) if values.dtype == np.float32 else values


def assert_same_hits(hits, expected):
    for key in KEYS:
        np.testing.assert_array_equal(bits(hits[key]), bits(expected[key]), err_msg=key)


def one_call_per_ray(scene, rays):
    """`cast_rays` of each ray alone, stacked in the rays' order (flat)."""
    answers = [scene.cast_rays(ray[None]) for ray in rays.reshape(-1, 6)]
    return {key: np.concatenate([a[key] for a in answers]) for key in KEYS}


def flat(hits):
    """`hits` of any leading shape as a flat batch's."""
    count = hits["t_hit"].size
    return {key: hits[key].reshape(count, *hits[key].shape[hits["t_hit"].ndim:]) for key in KEYS}


CAMERAS = {
    "image (h, w, 6)": lambda scene: camera_rays(scene, 48, 40),
    "flat (h*w, 6)": lambda scene: camera_rays(scene, 48, 40).reshape(-1, 6),
    "tiles cut by the edges (h, w, 6)": lambda scene: camera_rays(scene, 29, 37),
    "tiles cut by the edges, flat": lambda scene: camera_rays(scene, 29, 37).reshape(-1, 6),
    "two images (2, h, w, 6)": lambda scene: np.stack([camera_rays(scene, 21, 18)] * 2),
    "float64 (h, w, 6)": lambda scene: camera_rays(scene, 48, 40).astype(np.float64),
    "float64 flat": lambda scene: camera_rays(scene, 48, 40).reshape(-1, 6).astype(np.float64),
    "every other column, not contiguous": lambda scene: camera_rays(scene, 96, 40)[:, ::2],
    "float64 every other row": lambda scene: camera_rays(scene, 48, 80).astype(np.float64)[::2],
}


@pytest.mark.parametrize("camera", sorted(CAMERAS))
def test_camera_rays_answer_as_one_call_per_ray_and_reducem_query(
    model, camera, reducem_bin, tmp_path
):
    _, path, scene = model
    rays = CAMERAS[camera](scene)
    assert "contiguous" not in camera or not rays.flags.c_contiguous
    hits = scene.cast_rays(rays)
    assert hits["t_hit"].shape == rays.shape[:-1]
    assert np.isfinite(hits["t_hit"]).sum() > hits["t_hit"].size // 10, "too few hits"
    assert_same_hits(flat(hits), one_call_per_ray(scene, rays))
    traced = rays.reshape(-1, 6).astype(np.float32)
    t, normals = query(reducem_bin, path, traced, work=tmp_path)
    np.testing.assert_array_equal(bits(hits["t_hit"].reshape(-1)), bits(t))
    np.testing.assert_array_equal(bits(hits["primitive_normals"].reshape(-1, 3)), bits(normals))
    occluded = scene.test_occlusions(rays)
    assert occluded.shape == rays.shape[:-1]
    expected = query(reducem_bin, path, traced, occluded=True, work=tmp_path)
    np.testing.assert_array_equal(occluded.reshape(-1), expected)


def test_large_incoherent_batch_answers_as_small_batches_and_reducem_query(
    model, reducem_bin, tmp_path
):
    _, path, scene = model
    rays = random_rays(scene, count=SORTED_RAYS, seed=3)
    # Halves are below the size that is reordered: traced in their own order.
    half = SORTED_RAYS // 2
    parts = [scene.cast_rays(rays[:half]), scene.cast_rays(rays[half:])]
    in_order = {key: np.concatenate([p[key] for p in parts]) for key in KEYS}
    hits = scene.cast_rays(rays)
    assert np.isfinite(hits["t_hit"]).sum() > SORTED_RAYS // 10, "too few hits"
    assert_same_hits(hits, in_order)
    t, normals = query(reducem_bin, path, rays, work=tmp_path)
    np.testing.assert_array_equal(bits(hits["t_hit"]), bits(t))
    np.testing.assert_array_equal(bits(hits["primitive_normals"]), bits(normals))
    occluded = scene.test_occlusions(rays)
    halves = np.concatenate([scene.test_occlusions(rays[:half]), scene.test_occlusions(rays[half:])])
    np.testing.assert_array_equal(occluded, halves)
    np.testing.assert_array_equal(occluded, query(reducem_bin, path, rays, occluded=True, work=tmp_path))


def widened(rays, dtype):
    """`rays` as `dtype` in a view that is not contiguous (every other column of a wider array)."""
    wide = np.zeros((len(rays), 12), dtype)
    wide[:, ::2] = rays
    return wide[:, ::2]


SORTED_LAYOUTS = {
    "float64": lambda rays: rays.astype(np.float64),
    "strided float32": lambda rays: widened(rays, np.float32),
    "strided float64": lambda rays: widened(rays, np.float64),
}


@pytest.mark.parametrize("layout", sorted(SORTED_LAYOUTS))
def test_sorted_batch_answers_any_layout_as_contiguous_float32(model, layout):
    _, _, scene = model
    rays = random_rays(scene, count=SORTED_RAYS, seed=7)
    other = SORTED_LAYOUTS[layout](rays)
    assert other.dtype != np.float32 or not other.flags.c_contiguous
    assert_same_hits(scene.cast_rays(other), scene.cast_rays(rays))
    np.testing.assert_array_equal(scene.test_occlusions(other), scene.test_occlusions(rays))


def test_thread_pools_kept_between_calls_answer_alike(model):
    _, _, scene = model
    rays = random_rays(scene, count=SORTED_RAYS, seed=9)
    expected = scene.test_occlusions(rays, nthreads=1)
    assert 0 < expected.sum() < SORTED_RAYS
    for nthreads in (2, 1, 2, 3, 0):
        np.testing.assert_array_equal(scene.test_occlusions(rays, nthreads=nthreads), expected)


def test_invalid_rays_in_a_sorted_batch_are_misses_or_the_first_is_named(model):
    _, _, scene = model
    rays = random_rays(scene, count=SORTED_RAYS, seed=5)
    invalid = [41_000, 12_345, 69_999]
    rays[invalid[0], 0] = np.nan
    rays[invalid[1], 3:] = 0.0
    rays[invalid[2], 4] = np.inf
    with pytest.raises(ValueError, match=r"^ray 12345 \(rays\[12345\]\) is invalid"):
        scene.test_occlusions(rays)
    with pytest.raises(ValueError, match=r"^ray 12345 \(rays\[12345\]\) is invalid"):
        scene.cast_rays(rays)
    hits = scene.cast_rays(rays, invalid="miss")
    occluded = scene.test_occlusions(rays, invalid="miss")
    valid = np.ones(SORTED_RAYS, bool)
    valid[invalid] = False
    assert np.all(np.isinf(hits["t_hit"][~valid])) and not occluded[~valid].any()
    assert np.all(hits["primitive_ids"][~valid] == 0xFFFFFFFF)
    alone = scene.cast_rays(rays[valid])
    for key in KEYS:
        np.testing.assert_array_equal(bits(hits[key][valid]), bits(alone[key]), err_msg=key)
    np.testing.assert_array_equal(occluded[valid], scene.test_occlusions(rays[valid]))


def test_invalid_camera_ray_is_named_by_its_index(model):
    _, _, scene = model
    rays = camera_rays(scene, 48, 40)
    rays[3, 17, 4] = np.nan
    rays[30, 2, 3:] = 0.0
    with pytest.raises(ValueError, match=r"^ray 161 \(rays\[3, 17\]\) is invalid"):
        scene.cast_rays(rays)
    hits = scene.cast_rays(rays, invalid="miss")
    assert np.isinf(hits["t_hit"][3, 17]) and np.isinf(hits["t_hit"][30, 2])
    rays[3, 17] = rays[3, 16]
    rays[30, 2] = rays[30, 1]
    expected = scene.cast_rays(rays)
    keep = np.ones(rays.shape[:-1], bool)
    keep[3, 17] = keep[30, 2] = False
    for key in KEYS:
        np.testing.assert_array_equal(bits(hits[key][keep]), bits(expected[key][keep]), err_msg=key)
