"""Shared fixtures: the `reducem` and `pipeline` binaries, small generated meshes converted to
lossless and grid files, and ray sets (camera, random, aimed at vertices and edges)."""

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import reducem

REPO = Path(__file__).resolve().parents[2]


def _binary(name):
    """The binary `name` of this checkout: $REDUCEM_BIN / $PIPELINE_BIN, target/release,
    target/debug, or built with `cargo build --release`."""
    override = os.environ.get(f"{name.upper()}_BIN")
    if override:
        return Path(override)
    for profile in ("release", "debug"):
        path = REPO / "target" / profile / name
        if path.is_file():
            return path
    if shutil.which("cargo") is None:
        pytest.skip(f"no {name} binary and no cargo to build it")
    subprocess.run(
        ["cargo", "build", "--release", "-p", "reducem", "-p", "pipeline", "--bins"],
        cwd=REPO,
        check=True,
    )
    return REPO / "target" / "release" / name


@pytest.fixture(scope="session")
def reducem_bin():
    return _binary("reducem")


@pytest.fixture(scope="session")
def pipeline_bin():
    return _binary("pipeline")


@pytest.fixture(scope="session")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("reducem")


def generate(pipeline_bin, work, kind, triangles):
    ply = work / f"{kind}{triangles}.ply"
    if not ply.exists():
        subprocess.run(
            [pipeline_bin, "gen", kind, "--triangles", str(triangles), "-o", ply],
            check=True,
            capture_output=True,
        )
    return ply


@pytest.fixture(scope="session")
def sphere_ply(pipeline_bin, work):
    """A closed mesh (watertightness: rays at its vertices and edges must all hit)."""
    return generate(pipeline_bin, work, "sphere", 1280)


@pytest.fixture(scope="session")
def scan_ply(pipeline_bin, work):
    """A closed noisy torus with long strips and swap windows."""
    return generate(pipeline_bin, work, "scan", 6000)


def convert(ply, **options):
    suffix = "_".join(f"{k}{v}" for k, v in sorted(options.items())) or "lossless"
    out = ply.with_name(f"{ply.stem}_{suffix}.rdm")
    reducem.convert(ply, out, **options)
    return out


FILES = {
    "sphere-lossless": ("sphere_ply", {}),
    "scan-lossless": ("scan_ply", {}),
    "scan-grid": ("scan_ply", {"encoding": "grid", "grid_bits": 16}),
    "scan-leaf2": ("scan_ply", {"leaf_windows": 2, "max_length": 60}),
}


@pytest.fixture(scope="session", params=sorted(FILES))
def model(request):
    """A converted file: (name, path, opened scene)."""
    ply_fixture, options = FILES[request.param]
    path = convert(request.getfixturevalue(ply_fixture), **options)
    return request.param, path, reducem.open(path)


def camera_rays(scene, width=48, height=40):
    """A pinhole camera outside the bounds looking at their centre, rays shaped (h, w, 6)."""
    low, high = (b.astype(np.float64) for b in scene.bounds)
    centre = (low + high) / 2
    eye = centre + 0.8 * (high - low) * np.array([1.0, 0.7, 0.9])
    forward = centre - eye
    forward /= np.linalg.norm(forward)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    ys, xs = np.meshgrid(
        np.linspace(-0.5, 0.5, height), np.linspace(-0.5, 0.5, width), indexing="ij"
    )
    directions = forward + xs[..., None] * right + ys[..., None] * up
    origins = np.broadcast_to(eye, directions.shape)
    return np.concatenate([origins, directions], axis=-1).astype(np.float32)


def random_rays(scene, count=3000, seed=7):
    """Origins around and inside the bounds, directions of random length."""
    rng = np.random.default_rng(seed)
    low, high = (b.astype(np.float64) for b in scene.bounds)
    extent = high - low
    origins = low - 0.5 * extent + 2 * extent * rng.random((count, 3))
    targets = low + extent * rng.random((count, 3))
    directions = (targets - origins) * rng.uniform(0.2, 3.0, (count, 1))
    return np.concatenate([origins, directions], axis=1).astype(np.float32)


def aimed_rays(scene, seed=11):
    """Rays from outside the bounds aimed exactly at stored vertices, edge midpoints and
    points along edges: where a non-watertight test lets rays slip through."""
    rng = np.random.default_rng(seed)
    triangles = scene.triangles().astype(np.float64)
    pick = triangles[rng.choice(len(triangles), size=min(len(triangles), 600), replace=False)]
    vertices = pick[:, 0]
    midpoints = (pick[:, 0] + pick[:, 1]) / 2
    along = pick[:, 1] + rng.random((len(pick), 1)) * (pick[:, 2] - pick[:, 1])
    targets = np.concatenate([vertices, midpoints, along])
    low, high = (b.astype(np.float64) for b in scene.bounds)
    centre = (low + high) / 2
    radius = np.linalg.norm(high - low)
    away = rng.normal(size=targets.shape)
    away /= np.linalg.norm(away, axis=1, keepdims=True)
    origins = centre + 1.5 * radius * away
    return np.concatenate([origins, targets - origins], axis=1).astype(np.float32)


def query(reducem_bin, path, rays, tmin=0.0, tmax=np.inf, occluded=False, work=None):
    """`reducem query` on `rays` (n, 6): (t, normals) or the occlusion flags."""
    records = np.empty((len(rays), 8), dtype="<f4")
    records[:, :6] = rays
    records[:, 6] = tmin
    records[:, 7] = tmax
    rays_file = work / "rays.bin"
    out = work / "answers.bin"
    records.tofile(rays_file)
    command = [reducem_bin, "query", path, "--rays", rays_file, "-o", out]
    if occluded:
        command.append("--occluded")
    subprocess.run(command, check=True, capture_output=True)
    if occluded:
        return np.fromfile(out, dtype=np.uint8).astype(bool)
    answers = np.fromfile(out, dtype="<f4").reshape(-1, 4)
    return answers[:, 0], answers[:, 1:]
