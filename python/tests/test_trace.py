"""`Scene.cast_rays` and `Scene.test_occlusions`: bit for bit against `reducem query`, against a
numpy brute-force watertight intersection, and what `primitive_ids` and `primitive_uvs` mean."""

import numpy as np
import pytest

import reducem
from conftest import aimed_rays, camera_rays, convert, query, random_rays

RAY_SETS = {"camera": camera_rays, "random": random_rays, "aimed": aimed_rays}


def bits(values):
    return np.ascontiguousarray(values, dtype=np.float32).view(np.uint32)


@pytest.mark.parametrize("rays_name", sorted(RAY_SETS))
def test_hits_are_bit_identical_to_reducem_query(model, rays_name, reducem_bin, tmp_path):
    _, path, scene = model
    rays = RAY_SETS[rays_name](scene).reshape(-1, 6)
    hits = scene.cast_rays(rays)
    t, normals = query(reducem_bin, path, rays, work=tmp_path)
    assert np.isfinite(hits["t_hit"]).sum() > len(rays) // 10, "too few hits to compare"
    np.testing.assert_array_equal(bits(hits["t_hit"]), bits(t))
    np.testing.assert_array_equal(bits(hits["primitive_normals"]), bits(normals))


@pytest.mark.parametrize("rays_name", sorted(RAY_SETS))
def test_occlusions_are_identical_to_reducem_query(model, rays_name, reducem_bin, tmp_path):
    _, path, scene = model
    rays = RAY_SETS[rays_name](scene).reshape(-1, 6)
    for tfar in (np.inf, np.float32(0.3)):
        occluded = scene.test_occlusions(rays, tfar=tfar)
        expected = query(reducem_bin, path, rays, tmax=tfar, occluded=True, work=tmp_path)
        np.testing.assert_array_equal(occluded, expected)


def test_interval_matches_reducem_query(model, reducem_bin, tmp_path):
    _, path, scene = model
    rays = random_rays(scene)
    hits = scene.cast_rays(rays, tnear=0.25, tfar=0.75)
    t, normals = query(reducem_bin, path, rays, tmin=0.25, tmax=0.75, work=tmp_path)
    np.testing.assert_array_equal(bits(hits["t_hit"]), bits(t))
    np.testing.assert_array_equal(bits(hits["primitive_normals"]), bits(normals))
    finite = np.isfinite(hits["t_hit"])
    assert np.all((hits["t_hit"][finite] >= 0.25) & (hits["t_hit"][finite] <= 0.75))


def test_rays_at_vertices_and_edges_of_a_convex_mesh_stop_there(sphere_ply):
    """Watertight: a ray from outside a convex closed mesh, aimed straight at one of its
    vertices or at a point of one of its edges, hits there (t = 1) rather than slipping
    through to the far side (t near 2)."""
    for options in ({}, {"encoding": "grid", "grid_bits": 12}):
        scene = reducem.open(convert(sphere_ply, **options))
        triangles = scene.triangles().astype(np.float64)
        low, high = (b.astype(np.float64) for b in scene.bounds)
        centre = (low + high) / 2
        rng = np.random.default_rng(3)
        along = rng.random((len(triangles), 1))
        targets = np.concatenate(
            [
                triangles[:, 0],
                (triangles[:, 0] + triangles[:, 1]) / 2,
                triangles[:, 1] + along * (triangles[:, 2] - triangles[:, 1]),
            ]
        )
        origins = centre + 3 * (targets - centre)
        rays = np.concatenate([origins, targets - origins], axis=1).astype(np.float32)
        hits = scene.cast_rays(rays)
        # The grid moves vertices by up to half a cell, which may dent the surface a little.
        tolerance = 1e-5 if not options else 1e-2
        np.testing.assert_allclose(hits["t_hit"], 1.0, atol=tolerance)


def test_ids_uvs_and_normals_describe_the_triangle_hit(model):
    """The hit point is (1 - u - v) v0 + u v1 + v v2 of row `primitive_ids` of triangles(),
    and the normal is that triangle's unit normal in its winding."""
    _, _, scene = model
    triangles = scene.triangles().astype(np.float64)
    rays = np.concatenate([random_rays(scene), aimed_rays(scene)]).astype(np.float64)
    hits = scene.cast_rays(rays)
    hit = np.isfinite(hits["t_hit"])
    ids = hits["primitive_ids"]
    assert np.all(ids[~hit] == np.iinfo(np.uint32).max)
    assert np.all(ids[hit] < len(triangles))
    assert np.all(hits["primitive_normals"][~hit] == 0)
    corners = triangles[ids[hit]]
    u, v = hits["primitive_uvs"][hit].astype(np.float64).T
    assert np.all((u >= 0) & (v >= 0) & (u + v <= 1 + 1e-6))
    on_triangle = (1 - u - v)[:, None] * corners[:, 0] + u[:, None] * corners[:, 1]
    on_triangle += v[:, None] * corners[:, 2]
    along_ray = rays[hit, :3] + hits["t_hit"][hit, None] * rays[hit, 3:]
    scale = np.linalg.norm(scene.bounds[1] - scene.bounds[0])
    np.testing.assert_allclose(on_triangle, along_ray, atol=2e-5 * scale)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    np.testing.assert_allclose(hits["primitive_normals"][hit], normals, atol=1e-5)


def watertight_closest(triangles, rays):
    """Brute force: the closest hit of every ray on every triangle, by the watertight test of
    Woop, Benthin and Wald (JCGT 2013) in float64. Returns t (inf on a miss), the triangle and
    the smallest barycentric weight (how far inside the triangle the hit is)."""
    t_best = np.full(len(rays), np.inf)
    id_best = np.full(len(rays), -1)
    margin_best = np.zeros(len(rays))
    second = np.full(len(rays), np.inf)
    for r, ray in enumerate(rays.astype(np.float64)):
        origin, direction = ray[:3], ray[3:]
        kz = int(np.argmax(np.abs(direction)))
        kx, ky = (kz + 1) % 3, (kz + 2) % 3
        if direction[kz] < 0:
            kx, ky = ky, kx
        sx, sy, sz = direction[kx] / direction[kz], direction[ky] / direction[kz], 1 / direction[kz]
        local = triangles - origin
        ax, ay = local[:, 0, kx] - sx * local[:, 0, kz], local[:, 0, ky] - sy * local[:, 0, kz]
        bx, by = local[:, 1, kx] - sx * local[:, 1, kz], local[:, 1, ky] - sy * local[:, 1, kz]
        cx, cy = local[:, 2, kx] - sx * local[:, 2, kz], local[:, 2, ky] - sy * local[:, 2, kz]
        u = cx * by - cy * bx
        v = ax * cy - ay * cx
        w = bx * ay - by * ax
        det = u + v + w
        inside = ((u >= 0) & (v >= 0) & (w >= 0)) | ((u <= 0) & (v <= 0) & (w <= 0))
        inside &= det != 0
        with np.errstate(divide="ignore", invalid="ignore"):
            t = (u * local[:, 0, kz] + v * local[:, 1, kz] + w * local[:, 2, kz]) * sz / det
            weights = np.stack([u, v, w]) / det
        t = np.where(inside & (t >= 0), t, np.inf)
        order = np.argsort(t)
        t_best[r], id_best[r] = t[order[0]], order[0]
        second[r] = t[order[1]] if len(order) > 1 else np.inf
        margin_best[r] = weights[:, order[0]].min()
    return t_best, id_best, margin_best, second


def test_against_brute_force_watertight(model):
    _, _, scene = model
    triangles = scene.triangles().astype(np.float64)
    rays = np.concatenate([random_rays(scene, count=400), camera_rays(scene, 16, 12).reshape(-1, 6)])
    hits = scene.cast_rays(rays)
    t, ids, margin, second = watertight_closest(triangles, rays)
    # Hits well inside a triangle, well separated from the next: the answer is unambiguous
    # under rounding, so hit or miss, the triangle and t must agree.
    extent = np.linalg.norm(scene.bounds[1] - scene.bounds[0])
    scale = extent / np.linalg.norm(rays[:, 3:], axis=1)
    with np.errstate(invalid="ignore"):  # inf - inf for rays that hit nothing
        clear = (margin > 1e-4) & (second - t > 1e-4 * scale)
    missed = ~np.isfinite(t)
    assert clear.sum() > 50 and missed.sum() > 20
    assert np.all(~np.isfinite(hits["t_hit"][missed]))
    np.testing.assert_array_equal(hits["primitive_ids"][clear], ids[clear])
    error = np.abs(hits["t_hit"][clear] - t[clear]) / scale[clear]
    assert error.max() < 1e-6, f"t differs by {error.max():.3g} of the diagonal"
