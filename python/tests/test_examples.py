"""The examples in examples/python run on a small generated mesh and write what they say."""

import subprocess
import sys

import numpy as np

import reducem
from conftest import REPO, convert

EXAMPLES = REPO / "examples" / "python"


def test_lidar_writes_the_returns_as_ply(scan_ply, tmp_path):
    model = convert(scan_ply)
    cloud = tmp_path / "cloud.ply"
    run = subprocess.run(
        [sys.executable, EXAMPLES / "lidar.py", model, "-o", cloud, "--steps", "512"],
        check=True,
        capture_output=True,
        text=True,
    )
    assert "returns" in run.stdout
    data = cloud.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    count = int(next(line for line in data[:end].decode().splitlines() if "vertex" in line).split()[2])
    records = np.frombuffer(data, dtype="<f4", offset=end).reshape(-1, 7)
    assert len(records) == count > 0
    # Every return lies at its range from the scanner (the bounds' centre).
    low, high = reducem.open(model).bounds
    centre = ((low + high) / 2).astype(np.float32)
    distances = np.linalg.norm(records[:, :3] - centre, axis=1)
    np.testing.assert_allclose(distances, records[:, 3], rtol=1e-4)


def test_visibility_writes_a_symmetric_matrix(scan_ply, tmp_path):
    model = convert(scan_ply)
    out = tmp_path / "visible.npy"
    subprocess.run(
        [sys.executable, EXAMPLES / "visibility.py", model, "--points", "60", "-o", out],
        check=True,
        capture_output=True,
    )
    visible = np.load(out)
    assert visible.shape == (60, 60) and visible.dtype == bool
    assert np.array_equal(visible, visible.T) and visible.diagonal().all()
    # A torus: some pairs see each other, some are hidden by the ring.
    assert 0 < visible.sum() - 60 < 60 * 59
