"""Queries beyond the closest hit, with Open3D's names: closest points, distances, crossing
counts and lists, occupancy and signed distance against float64 numpy brute forces (and the
winding number), `geometry_ids` of `cast_rays`, and `from_arrays`."""

import subprocess
import warnings

import numpy as np
import pytest

import reducem
from conftest import camera_rays, convert, random_rays

NO_ID = np.iinfo(np.uint32).max


@pytest.fixture(scope="module")
def scan(scan_ply):
    return reducem.open(convert(scan_ply))


def closest_on_triangles(point, triangles):
    """Squared distance from `point` to each triangle and the closest points, in float64, by
    the Voronoi regions of Ericson's "Real-Time Collision Detection" 5.1.5."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    ab, ac, ap = b - a, c - a, point - a
    dot = lambda x, y: np.einsum("ij,ij->i", x, y)  # noqa: E731
    d1, d2 = dot(ab, ap), dot(ac, ap)
    bp, cp = point - b, point - c
    d3, d4, d5, d6 = dot(ab, bp), dot(ac, bp), dot(ab, cp), dot(ac, cp)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    with np.errstate(divide="ignore", invalid="ignore"):
        denominator = va + vb + vc
        u, v = vb / denominator, vc / denominator
        on_ab = d1 / (d1 - d3)
        on_ac = d2 / (d2 - d6)
        on_bc = (d4 - d3) / ((d4 - d3) + (d5 - d6))
    regions = [
        (d1 <= 0) & (d2 <= 0),
        (d3 >= 0) & (d4 <= d3),
        (d6 >= 0) & (d5 <= d6),
        (vc <= 0) & (d1 >= 0) & (d3 <= 0),
        (vb <= 0) & (d2 >= 0) & (d6 <= 0),
        (va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0),
    ]
    points = [a, b, c, a + on_ab[:, None] * ab, a + on_ac[:, None] * ac, b + on_bc[:, None] * (c - b)]
    closest = a + u[:, None] * ab + v[:, None] * ac
    for region, at in zip(reversed(regions), reversed(points)):
        closest = np.where(region[:, None], at, closest)
    offset = point - closest
    return dot(offset, offset), closest


def brute_force_distances(triangles, points):
    return np.array([np.sqrt(closest_on_triangles(p, triangles)[0].min()) for p in points])


def points_near(scene, count=300, seed=3):
    """Points on random triangles moved off the surface by up to 5% of the diagonal, and a few
    far away."""
    rng = np.random.default_rng(seed)
    triangles = scene.triangles().astype(np.float64)
    corners = triangles[rng.integers(0, len(triangles), count)]
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    on = corners[:, 0] + u[:, None] * (corners[:, 1] - corners[:, 0])
    on += v[:, None] * (corners[:, 2] - corners[:, 0])
    low, high = (b.astype(np.float64) for b in scene.bounds)
    diagonal = np.linalg.norm(high - low)
    offsets = rng.normal(size=(count, 3)) * 0.03 * diagonal
    far = low + (high - low) * rng.uniform(-2, 3, (20, 3))
    return np.concatenate([on + offsets, far]).astype(np.float32)


def test_closest_points_are_the_brute_force_distance_on_the_named_face(model):
    _, _, scene = model
    triangles = scene.triangles().astype(np.float64)
    points = points_near(scene)
    found = scene.compute_closest_points(points)
    distances = scene.compute_distance(points)
    expected = brute_force_distances(triangles, points.astype(np.float64))
    diagonal = np.linalg.norm(scene.bounds[1].astype(np.float64) - scene.bounds[0])
    tolerance = 4 * np.finfo(np.float32).eps * diagonal
    np.testing.assert_allclose(distances, expected, rtol=0, atol=tolerance)
    ids = found["primitive_ids"]
    assert ids.dtype == np.uint32 and np.all(ids < len(triangles))
    corners = triangles[ids]
    u, v = found["primitive_uvs"].astype(np.float64).T
    assert np.all((u >= 0) & (v >= 0) & (u + v <= 1 + 1e-6))
    on_face = corners[:, 0] + u[:, None] * (corners[:, 1] - corners[:, 0])
    on_face += v[:, None] * (corners[:, 2] - corners[:, 0])
    np.testing.assert_allclose(found["points"], on_face, rtol=0, atol=tolerance)
    reached = np.linalg.norm(found["points"].astype(np.float64) - points, axis=1)
    np.testing.assert_allclose(reached, expected, rtol=0, atol=tolerance)
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    np.testing.assert_allclose(found["primitive_normals"], normals, atol=1e-5)


def test_closest_points_keep_the_leading_shape_and_take_float64(scan):
    points = points_near(scan, count=40)[:60].reshape(3, 20, 3)
    found = scan.compute_closest_points(points)
    assert found["points"].shape == (3, 20, 3) and found["points"].dtype == np.float32
    assert found["primitive_ids"].shape == (3, 20)
    assert found["primitive_uvs"].shape == (3, 20, 2)
    assert found["primitive_normals"].shape == (3, 20, 3)
    assert scan.compute_distance(points).shape == (3, 20)
    assert scan.compute_distance(points[0, 0]).shape == ()
    wide = scan.compute_closest_points(points.astype(np.float64), nthreads=1)
    for key, values in found.items():
        np.testing.assert_array_equal(wide[key], values)
    assert scan.compute_distance(np.zeros((0, 3))).shape == (0,)


def test_bad_query_points_are_refused(scan):
    with pytest.raises(ValueError, match=r"query_points must have shape \(\.\.\., 3\)"):
        scan.compute_distance(np.zeros((4, 2), np.float32))
    with pytest.raises(ValueError, match="query point 1 is not finite"):
        scan.compute_closest_points(np.array([[0, 0, 0], [np.nan, 0, 0]], np.float32))
    with pytest.raises(TypeError, match="float32 or float64"):
        scan.compute_distance(np.zeros((4, 3), np.int32))


def test_geometry_ids_are_zero_on_a_hit_and_max_on_a_miss(model):
    _, _, scene = model
    hits = scene.cast_rays(camera_rays(scene))
    hit = np.isfinite(hits["t_hit"])
    assert hits["geometry_ids"].dtype == np.uint32 and hits["geometry_ids"].shape == hit.shape
    assert hit.any() and (~hit).any()
    np.testing.assert_array_equal(hits["geometry_ids"], np.where(hit, 0, NO_ID))


def cube():
    """A closed unit cube, outward winding: 8 vertices, 12 triangles."""
    vertices = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], np.float64)
    quads = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    triangles = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return vertices, np.array(triangles, np.int64)


def as_set(triangles):
    """Triangles as a set of corner tuples, each rotated to start at its smallest corner (the
    winding kept)."""
    found = set()
    for triangle in np.asarray(triangles, np.float64).tolist():
        corners = [tuple(corner) for corner in triangle]
        first = corners.index(min(corners))
        found.add(tuple(corners[first:] + corners[:first]))
    return found


def test_from_arrays_converts_the_mesh_and_removes_its_temporary(tmp_path):
    import gc

    vertices, triangles = cube()
    scene = reducem.from_arrays(vertices, triangles, max_length=4)
    assert as_set(scene.triangles()) == as_set(vertices[triangles])
    work = scene.path.parent
    assert work.is_dir()
    distance = scene.compute_distance(np.array([0.5, 0.5, 3.0]))
    assert distance == np.float32(2.0)
    del scene
    gc.collect()
    assert not work.exists()
    kept = tmp_path / "cube.rdm"
    scene = reducem.from_arrays(vertices.astype(np.float32), triangles.astype(np.int32), kept)
    assert scene.path == kept and kept.is_file()
    assert as_set(reducem.open(kept).triangles()) == as_set(vertices[triangles])


def test_from_arrays_errors_name_the_array_and_index():
    vertices, triangles = cube()
    bad = triangles.copy()
    bad[5, 2] = 8
    with pytest.raises(ValueError, match=r"triangles\[5, 2\] = 8 is not a vertex index"):
        reducem.from_arrays(vertices, bad)
    bad[5, 2] = -1
    with pytest.raises(ValueError, match=r"triangles\[5, 2\] = -1"):
        reducem.from_arrays(vertices, bad)
    nan = vertices.copy()
    nan[3, 1] = np.nan
    with pytest.raises(ValueError, match=r"vertices\[3\] is not finite"):
        reducem.from_arrays(nan, triangles)
    with pytest.raises(ValueError, match=r"vertices must have shape \(n, 3\)"):
        reducem.from_arrays(vertices[:, :2], triangles)
    with pytest.raises(TypeError, match="triangles must be integers"):
        reducem.from_arrays(vertices, triangles.astype(np.float32))
    with pytest.raises(TypeError, match="vertices must be float32 or float64"):
        reducem.from_arrays(vertices.astype(np.int64), triangles)


def crossings_brute_force(triangles, rays, tnear=0.0, tfar=np.inf):
    """Every crossing of each ray in float64 (Moller-Trumbore, no tie rule): a list per ray of
    (t, triangle) and, per ray, the smallest distance of a crossing from its triangle's edges
    in barycentric weight (rays crossing near an edge are left out of exact comparisons)."""
    a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
    e1, e2 = b - a, c - a
    found, margins = [], []
    for ray in rays.astype(np.float64):
        origin, direction = ray[:3], ray[3:]
        p = np.cross(direction, e2)
        det = np.einsum("ij,ij->i", e1, p)
        with np.errstate(divide="ignore", invalid="ignore"):
            inverse = 1.0 / det
            s = origin - a
            u = np.einsum("ij,ij->i", s, p) * inverse
            q = np.cross(s, e1)
            v = (q @ direction) * inverse
            t = np.einsum("ij,ij->i", e2, q) * inverse
        weights = np.stack([1 - u - v, u, v])
        crossed = (det != 0) & np.all(weights >= 0, axis=0) & (t >= tnear) & (t <= tfar)
        near = np.abs(weights).min(axis=0)
        hits = sorted(zip(t[crossed].tolist(), np.flatnonzero(crossed).tolist()))
        found.append(hits)
        margin = near[crossed].min() if crossed.any() else np.inf
        # A triangle just missed counts as near too.
        missed = (det != 0) & (t >= tnear) & (t <= tfar) & ~crossed
        if missed.any():
            margin = min(margin, np.abs(np.minimum(weights[:, missed], 0)).sum(axis=0).min())
        margins.append(margin)
    return found, np.array(margins)


def winding_numbers(triangles, points):
    """The generalized winding number of each point in float64 (van Oosterom and Strackee's
    solid angle of each triangle)."""
    numbers = []
    for point in points.astype(np.float64):
        a, b, c = (triangles[:, k] - point for k in range(3))
        la, lb, lc = (np.linalg.norm(x, axis=1) for x in (a, b, c))
        dot = lambda x, y: np.einsum("ij,ij->i", x, y)  # noqa: E731
        numerator = dot(a, np.cross(b, c))
        denominator = la * lb * lc + dot(a, b) * lc + dot(b, c) * la + dot(c, a) * lb
        numbers.append(2 * np.arctan2(numerator, denominator).sum() / (4 * np.pi))
    return np.array(numbers)


def test_counts_and_lists_equal_the_brute_force_away_from_edges(model):
    _, _, scene = model
    triangles = scene.triangles().astype(np.float64)
    rays = random_rays(scene, count=400)
    counts = scene.count_intersections(rays)
    listed = scene.list_intersections(rays)
    expected, margins = crossings_brute_force(triangles, rays)
    clear = margins > 1e-4
    assert clear.sum() > 300
    assert counts.dtype == np.int32 and counts.shape == (400,)
    np.testing.assert_array_equal(counts[clear], [len(hits) for hits, ok in zip(expected, clear) if ok])
    splits = listed["ray_splits"]
    assert splits.dtype == np.uint32 and splits.shape == (401,) and splits[0] == 0
    np.testing.assert_array_equal(np.diff(splits), counts)
    np.testing.assert_array_equal(listed["ray_ids"], np.repeat(np.arange(400), counts))
    assert listed["primitive_uvs"].shape == (splits[-1], 2)
    for i in np.flatnonzero(clear):
        span = slice(splits[i], splits[i + 1])
        t = listed["t_hit"][span]
        assert np.all(np.diff(t) >= 0)
        np.testing.assert_allclose(t, [hit[0] for hit in expected[i]], rtol=1e-4)
        assert sorted(listed["primitive_ids"][span].tolist()) == sorted(h[1] for h in expected[i])


def test_interval_and_leading_shape_of_counts(scan):
    rays = camera_rays(scan, width=8, height=5)
    counts = scan.count_intersections(rays, tnear=0.5, tfar=2.0, nthreads=1)
    assert counts.shape == (5, 8)
    listed = scan.list_intersections(rays.astype(np.float64), tnear=0.5, tfar=2.0)
    np.testing.assert_array_equal(np.diff(listed["ray_splits"]), counts.reshape(-1))
    assert np.all((listed["t_hit"] >= 0.5) & (listed["t_hit"] <= 2.0))
    with pytest.raises(ValueError, match=r"ray 3 \(rays\[0, 3\]\) is invalid"):
        bad = rays.copy()
        bad[0, 3, 3:] = 0
        scan.count_intersections(bad)


def test_rays_from_inside_a_closed_mesh_at_vertices_and_edges_cross_once(sphere_ply):
    """The hard case of counting: rays from the centre of a closed mesh aimed exactly at its
    vertices, edge midpoints and centroids cross it once; rays from outside through the same
    points, an even number of times."""
    scene = reducem.open(convert(sphere_ply))
    triangles = scene.triangles().astype(np.float64)
    targets = np.concatenate(
        [triangles[:, 0], (triangles[:, 0] + triangles[:, 1]) / 2, triangles.mean(axis=1)]
    )
    centre = np.zeros(3)
    inside = np.concatenate([np.broadcast_to(centre, targets.shape), targets - centre], axis=1)
    assert np.all(scene.count_intersections(inside.astype(np.float32)) == 1)
    origins = 3 * targets
    outside = np.concatenate([origins, targets - origins], axis=1).astype(np.float32)
    assert np.all(scene.count_intersections(outside) % 2 == 0)


def test_occupancy_and_signed_distance_follow_the_winding_number(sphere_ply):
    scene = reducem.open(convert(sphere_ply))
    triangles = scene.triangles().astype(np.float64)
    rng = np.random.default_rng(5)
    pick = triangles[rng.integers(0, len(triangles), 150)]
    on = pick.mean(axis=1)
    normals = np.cross(pick[:, 1] - pick[:, 0], pick[:, 2] - pick[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    step = 1e-4 * np.linalg.norm(scene.bounds[1] - scene.bounds[0])
    points = np.concatenate([on + step * normals, on - step * normals]).astype(np.float32)
    inside = winding_numbers(triangles, points) > 0.5
    assert inside.sum() == 150
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        occupancy = scene.compute_occupancy(points, nsamples=3)
        signed = scene.compute_signed_distance(points, nsamples=3)
    assert occupancy.dtype == np.float32
    np.testing.assert_array_equal(occupancy, inside.astype(np.float32))
    distances = scene.compute_distance(points)
    np.testing.assert_array_equal(signed, np.where(inside, -distances, distances))


def test_an_open_mesh_warns_once_that_inside_is_not_exact():
    vertices = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    scene = reducem.from_arrays(vertices, np.array([[0, 1, 2]]))
    assert not scene.closed and scene.info["closed"] is False
    with pytest.warns(RuntimeWarning, match="not known to be closed"):
        scene.compute_occupancy(np.zeros((2, 3)))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        np.testing.assert_array_equal(scene.compute_signed_distance([[0.25, 0.25, 1]]), [1.0])


def run_tool(reducem_bin, *arguments):
    subprocess.run([reducem_bin, *map(str, arguments)], check=True, capture_output=True)


def ray_file(rays, path):
    records = np.zeros((len(rays), 8), "<f4")
    records[:, :6] = rays
    records[:, 7] = np.inf
    records.tofile(path)
    return path


def test_counts_and_lists_are_those_of_reducem_query(model, reducem_bin, tmp_path):
    _, path, scene = model
    rays = np.concatenate([random_rays(scene, count=500), camera_rays(scene).reshape(-1, 6)])
    rays_file = ray_file(rays, tmp_path / "rays.bin")
    run_tool(reducem_bin, "query", path, "--rays", rays_file, "-o", tmp_path / "counts", "--count")
    counts = np.fromfile(tmp_path / "counts", "<u4")
    np.testing.assert_array_equal(scene.count_intersections(rays), counts)
    run_tool(reducem_bin, "query", path, "--rays", rays_file, "-o", tmp_path / "all", "--all")
    data, at = np.fromfile(tmp_path / "all", np.uint8), 0
    listed = scene.list_intersections(rays)
    record = np.dtype([("t", "<f4"), ("id", "<u4"), ("u", "<f4"), ("v", "<f4")])
    for i in range(len(rays)):
        n = int(data[at : at + 4].view("<u4")[0])
        hits = data[at + 4 : at + 4 + 16 * n].view(record)
        at += 4 + 16 * n
        span = slice(listed["ray_splits"][i], listed["ray_splits"][i + 1])
        np.testing.assert_array_equal(listed["t_hit"][span], hits["t"])
        np.testing.assert_array_equal(listed["primitive_ids"][span], hits["id"])
        np.testing.assert_array_equal(listed["primitive_uvs"][span], np.stack([hits["u"], hits["v"]], 1))
    assert at == len(data)


def test_closest_signed_and_inside_are_those_of_the_tools(model, reducem_bin, tmp_path):
    _, path, scene = model
    points = points_near(scene)
    points_file = tmp_path / "points.bin"
    points.astype("<f4").tofile(points_file)
    run_tool(reducem_bin, "closest", path, "--points", points_file, "-o", tmp_path / "c", "--signed", "--samples", 3)
    answers = np.fromfile(tmp_path / "c", np.uint8).reshape(-1, 32)
    distance = answers[:, :4].copy().view("<f4")[:, 0]
    closest = answers[:, 4:16].copy().view("<f4")
    ids = answers[:, 16:20].copy().view("<u4")[:, 0]
    uvs = answers[:, 20:28].copy().view("<f4")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        np.testing.assert_array_equal(scene.compute_signed_distance(points, nsamples=3), distance)
        occupancy = scene.compute_occupancy(points, nsamples=3)
    found = scene.compute_closest_points(points)
    np.testing.assert_array_equal(found["points"], closest)
    np.testing.assert_array_equal(found["primitive_ids"], ids)
    np.testing.assert_array_equal(found["primitive_uvs"], uvs)
    run_tool(reducem_bin, "inside", path, "--points", points_file, "-o", tmp_path / "i", "--samples", 3)
    np.testing.assert_array_equal(occupancy, np.fromfile(tmp_path / "i", np.uint8))


def open3d_style_queries(scene, rays, points):
    """Code written for Open3D's RaycastingScene (tensors aside): only its names and keys."""
    hits = scene.cast_rays(rays, nthreads=2)
    return {
        "t_hit": hits["t_hit"],
        "geometry_ids": hits["geometry_ids"],
        "counts": scene.count_intersections(rays),
        "listed": scene.list_intersections(rays)["t_hit"],
        "closest": scene.compute_closest_points(points)["points"],
        "distance": scene.compute_distance(points),
        "signed": scene.compute_signed_distance(points),
        "occupancy": scene.compute_occupancy(points),
    }


def test_open3d_code_runs_on_a_closed_cube_exactly():
    vertices, triangles = cube()
    scene = reducem.from_arrays(vertices, triangles)
    assert scene.closed and scene.info["boundary_edges"] == 0
    rays = np.array([[0.5, 0.5, -1, 0, 0, 1], [0.25, 0.75, 0.5, 1, 0, 0], [2, 2, 2, 1, 0, 0]])
    points = np.array([[0.5, 0.5, 0.25], [0.5, 0.5, 2.0], [-1.0, 0.5, 0.5]])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        answers = open3d_style_queries(scene, rays, points)
    np.testing.assert_array_equal(answers["t_hit"], [1.0, 0.75, np.inf])
    np.testing.assert_array_equal(answers["geometry_ids"], [0, 0, NO_ID])
    np.testing.assert_array_equal(answers["counts"], [2, 1, 0])
    np.testing.assert_array_equal(answers["listed"], [1.0, 2.0, 0.75])
    np.testing.assert_array_equal(answers["closest"], [[0.5, 0.5, 0.0], [0.5, 0.5, 1.0], [0, 0.5, 0.5]])
    np.testing.assert_array_equal(answers["distance"], [0.25, 1.0, 1.0])
    np.testing.assert_array_equal(answers["signed"], [-0.25, 1.0, 1.0])
    np.testing.assert_array_equal(answers["occupancy"], [1.0, 0.0, 0.0])
