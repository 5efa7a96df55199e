"""The package's contract: shapes, dtypes, input forms, errors, and the file-level calls
(bounds, info, triangles, render, convert) against the command-line tools."""

import json
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import reducem
from conftest import camera_rays, convert, generate, random_rays


@pytest.fixture(scope="module")
def scan(scan_ply):
    path = convert(scan_ply)
    return path, reducem.open(path)


def test_answers_have_the_rays_leading_shape_and_dtypes(scan):
    _, scene = scan
    rays = camera_rays(scene, width=10, height=6).reshape(2, 3, 10, 6)
    hits = scene.cast_rays(rays)
    assert hits["t_hit"].shape == (2, 3, 10) and hits["t_hit"].dtype == np.float32
    assert hits["primitive_ids"].shape == (2, 3, 10) and hits["primitive_ids"].dtype == np.uint32
    assert hits["primitive_uvs"].shape == (2, 3, 10, 2)
    assert hits["primitive_uvs"].dtype == np.float32
    assert hits["primitive_normals"].shape == (2, 3, 10, 3)
    assert hits["primitive_normals"].dtype == np.float32
    occluded = scene.test_occlusions(rays)
    assert occluded.shape == (2, 3, 10) and occluded.dtype == np.bool_
    flat = scene.cast_rays(rays.reshape(-1, 6))
    for key, value in hits.items():
        np.testing.assert_array_equal(value.reshape(flat[key].shape), flat[key])
    np.testing.assert_array_equal(occluded.ravel(), np.isfinite(flat["t_hit"]))
    single = scene.cast_rays(rays[0, 0, 0])
    assert single["t_hit"].shape == () and single["primitive_uvs"].shape == (2,)


def test_float64_rays_are_traced_as_their_float32_values(scan):
    _, scene = scan
    rays = random_rays(scene).astype(np.float64) + 1e-9
    wide = scene.cast_rays(rays)
    narrow = scene.cast_rays(rays.astype(np.float32))
    for key in wide:
        np.testing.assert_array_equal(wide[key], narrow[key])
    np.testing.assert_array_equal(
        scene.test_occlusions(rays), scene.test_occlusions(rays.astype(np.float32))
    )


def test_empty_rays(scan):
    _, scene = scan
    for shape in [(0, 6), (3, 0, 6)]:
        hits = scene.cast_rays(np.zeros(shape, dtype=np.float32))
        assert hits["t_hit"].shape == shape[:-1]
        assert hits["primitive_normals"].shape == shape[:-1] + (3,)
        assert scene.test_occlusions(np.zeros(shape)).shape == shape[:-1]


def test_non_contiguous_rays(scan):
    _, scene = scan
    rays = random_rays(scene)
    expected = scene.cast_rays(rays[::3])
    strided = scene.cast_rays(rays[::3])
    fortran = scene.cast_rays(np.asfortranarray(rays[::3]))
    transposed = scene.cast_rays(np.ascontiguousarray(rays[::3].T).T)
    lists = scene.cast_rays(rays[::3].tolist())
    for other in (strided, fortran, transposed):
        for key in expected:
            np.testing.assert_array_equal(other[key], expected[key])
    # A list is converted as float64, then traced in float32: the same rays.
    np.testing.assert_array_equal(lists["t_hit"], expected["t_hit"])
    interleaved = np.zeros((len(rays), 12), dtype=np.float32)
    interleaved[:, ::2] = rays
    np.testing.assert_array_equal(
        scene.cast_rays(interleaved[:, ::2])["t_hit"], scene.cast_rays(rays)["t_hit"]
    )


@pytest.mark.parametrize("shape", [(6,), (5,), (3, 5), (4, 7), (2, 3, 1), ()])
def test_wrong_shapes_name_the_shape(scan, shape):
    _, scene = scan
    rays = np.ones(shape, dtype=np.float32)
    if shape == (6,):
        scene.cast_rays(rays)
        return
    shown = str(shape)
    with pytest.raises(ValueError, match=__import__("re").escape(shown)):
        scene.cast_rays(rays)
    with pytest.raises(ValueError, match=__import__("re").escape(shown)):
        scene.test_occlusions(rays)


def test_integer_rays_are_a_type_error(scan):
    _, scene = scan
    with pytest.raises(TypeError, match="int64"):
        scene.cast_rays(np.ones((2, 6), dtype=np.int64))


def test_invalid_rays_raise_naming_the_first_or_answer_misses(scan):
    _, scene = scan
    rays = camera_rays(scene, width=4, height=3)
    rays[1, 2, 4] = np.nan
    rays[2, 0, 3:] = 0
    with pytest.raises(ValueError, match=r"ray 6 \(rays\[1, 2\]\).*dy is NaN"):
        scene.cast_rays(rays)
    with pytest.raises(ValueError, match=r"rays\[1, 2\]"):
        scene.test_occlusions(rays)
    hits = scene.cast_rays(rays, invalid="miss")
    occluded = scene.test_occlusions(rays, invalid="miss")
    valid = camera_rays(scene, width=4, height=3)
    expected = scene.cast_rays(valid)
    bad = np.zeros((3, 4), dtype=bool)
    bad[1, 2] = bad[2, 0] = True
    assert np.all(np.isinf(hits["t_hit"][bad])) and not occluded[bad].any()
    assert np.all(hits["primitive_ids"][bad] == 2**32 - 1)
    for key in expected:
        np.testing.assert_array_equal(hits[key][~bad], expected[key][~bad])
    zero = np.array([[0, 0, 0, 0, 0, 0]], dtype=np.float32)
    with pytest.raises(ValueError, match="direction is zero"):
        scene.cast_rays(zero)
    with pytest.raises(ValueError, match="raise"):
        scene.cast_rays(valid, invalid="ignore")


def test_bad_intervals(scan):
    _, scene = scan
    rays = random_rays(scene, count=4)
    for tnear, tfar in [(-1.0, 1.0), (2.0, 1.0), (np.nan, 1.0)]:
        with pytest.raises(ValueError, match="tnear"):
            scene.cast_rays(rays, tnear=tnear, tfar=tfar)


def test_thread_counts_give_the_same_answers(scan):
    _, scene = scan
    rays = random_rays(scene, count=20000)
    expected = scene.cast_rays(rays)
    for nthreads in (1, 3):
        hits = scene.cast_rays(rays, nthreads=nthreads)
        for key in expected:
            np.testing.assert_array_equal(hits[key], expected[key])
        np.testing.assert_array_equal(
            scene.test_occlusions(rays, nthreads=nthreads), np.isfinite(expected["t_hit"])
        )


def test_missing_file_is_file_not_found(tmp_path):
    with pytest.raises(FileNotFoundError, match="absent.rdm"):
        reducem.open(tmp_path / "absent.rdm")


def test_corrupted_files_raise_reducem_error(scan, tmp_path):
    path, _ = scan
    data = bytearray(path.read_bytes())
    truncated = tmp_path / "truncated.rdm"
    truncated.write_bytes(data[: len(data) // 2])
    with pytest.raises(reducem.ReducemError, match="truncated.rdm"):
        reducem.open(truncated)
    garbage = tmp_path / "garbage.rdm"
    garbage.write_bytes(b"not a reducem file" * 300)
    with pytest.raises(reducem.ReducemError, match="garbage.rdm"):
        reducem.open(garbage)
    # Strip records pointing past the data: the reader names the section and byte.
    bent = tmp_path / "bent.rdm"
    for position in range(4096, len(data), max(1, len(data) // 64)):
        corrupted = bytearray(data)
        corrupted[position : position + 8] = b"\xff" * 8
        bent.write_bytes(corrupted)
        try:
            scene = reducem.open(bent)
        except reducem.ReducemError as error:
            assert "bent.rdm" in str(error) and "byte" in str(error)
            continue
        # Geometry bytes the reader cannot tell from valid ones: tracing must still answer.
        scene.cast_rays(random_rays(scene, count=200))
        scene.test_occlusions(random_rays(scene, count=200))


def test_a_corrupt_part_of_a_large_file_raises_when_reached(pipeline_bin, work, tmp_path):
    # Above 1 MiB a file is validated part by part as rays reach it: opening succeeds, and the
    # calls that meet the corrupt strips raise, naming the file and the byte.
    path = convert(generate(pipeline_bin, work, "scan", 100_000))
    data = bytearray(path.read_bytes())
    assert len(data) > 1 << 20
    # Section table at byte 104, entries of 32 bytes; the third is the strip data.
    entry = 104 + 2 * 32
    offset = int.from_bytes(data[entry + 8 : entry + 16], "little")
    length = int.from_bytes(data[entry + 16 : entry + 24], "little")
    data[offset + length // 4 : offset + 3 * length // 4] = b"\xff" * (length // 2)
    corrupt = tmp_path / "corrupt-strips.rdm"
    corrupt.write_bytes(bytes(data))
    scene = reducem.open(corrupt)
    rays = camera_rays(scene, width=64, height=64)
    for call in (scene.cast_rays, scene.test_occlusions):
        with pytest.raises(reducem.ReducemError, match=r"corrupt-strips\.rdm.*byte"):
            call(rays)
    for read in (lambda: scene.info, scene.triangles):
        with pytest.raises(reducem.ReducemError, match=r"corrupt-strips\.rdm.*byte"):
            read()


def test_bounds_info_and_triangles_match_the_tools(scan, reducem_bin, tmp_path):
    path, scene = scan
    stats = json.loads(
        subprocess.run(
            [reducem_bin, "inspect", "--json", path], check=True, capture_output=True
        ).stdout
    )
    info = scene.info
    assert {key: info[key] for key in stats} == stats
    assert info["closed"] is scene.closed
    assert {"boundary_edges", "nonmanifold_edges"} <= set(info)
    low, high = scene.bounds
    assert low.dtype == np.float32 and low.shape == (3,)
    np.testing.assert_array_equal(low, np.float32(stats["bounds_min"]))
    np.testing.assert_array_equal(high, np.float32(stats["bounds_max"]))
    ply = tmp_path / "decoded.ply"
    subprocess.run([reducem_bin, "decode", path, "-o", ply], check=True, capture_output=True)
    vertices, faces = read_binary_ply(ply)
    triangles = scene.triangles()
    assert triangles.dtype == np.float32 and triangles.shape == (stats["triangles"], 3, 3)
    np.testing.assert_array_equal(triangles, vertices[faces])


def read_binary_ply(path):
    """Vertices (float x, y, z) and triangles (uchar 3, int indices) as `decode` writes them."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().splitlines()
    counts = {line.split()[1]: int(line.split()[2]) for line in header if line.startswith("element")}
    vertices = np.frombuffer(data, dtype="<f4", count=3 * counts["vertex"], offset=end)
    faces = np.frombuffer(
        data, dtype=np.dtype([("n", "u1"), ("v", "<i4", 3)]), offset=end + vertices.nbytes
    )
    assert np.all(faces["n"] == 3)
    return vertices.reshape(-1, 3), faces["v"]


def test_render_from_a_path_or_a_dict(scan, tmp_path):
    _, scene = scan
    toml = tmp_path / "scene.toml"
    toml.write_text(
        "[image]\nwidth = 40\nheight = 30\n\n[camera]\nfov_degrees = 50.0\n\n"
        "[[directional_light]]\ndirection = [-1.0, -0.5, -1.0]\ncast_shadows = true\n"
    )
    from_file = scene.render(toml)
    from_dict = scene.render(
        {
            "image": {"width": 40, "height": 30},
            "camera": {"fov_degrees": 50.0},
            "directional_light": [{"direction": [-1.0, -0.5, -1.0], "cast_shadows": True}],
        }
    )
    assert from_file.shape == (30, 40, 3) and from_file.dtype == np.uint8
    np.testing.assert_array_equal(from_file, from_dict)
    assert len(np.unique(from_file.reshape(-1, 3), axis=0)) > 10
    smaller = scene.render(toml, width=20, height=10, ao_samples=4)
    assert smaller.shape == (10, 20, 3)
    with pytest.raises(TypeError, match="widht"):
        scene.render(toml, widht=3)
    with pytest.raises(ValueError, match="colour"):
        scene.render({"image": {"colour": 1}})
    with pytest.raises(FileNotFoundError):
        scene.render(tmp_path / "absent.toml")


def test_convert_writes_what_pipeline_convert_writes(scan_ply, pipeline_bin, tmp_path):
    for options, flags in [
        ({}, []),
        ({"encoding": "grid", "grid_bits": 14, "max_length": 30}, ["--encoding", "grid", "--grid-bits", "14", "--max-length", "30"]),
    ]:
        ours = tmp_path / "ours.rdm"
        theirs = tmp_path / "theirs.rdm"
        reducem.convert(scan_ply, ours, **options)
        subprocess.run(
            [pipeline_bin, "convert", scan_ply, "-o", theirs, *flags],
            check=True,
            capture_output=True,
        )
        assert ours.read_bytes() == theirs.read_bytes()
        # Resumable: a second run finds every stage done and leaves the file as it is.
        reducem.convert(scan_ply, ours, **options)
        assert ours.read_bytes() == theirs.read_bytes()
        shutil.rmtree(tmp_path / "ours.rdm.work")
        ours.unlink()


def test_convert_settings_reach_the_file(scan_ply, tmp_path):
    out = tmp_path / "leaf.rdm"
    reducem.convert(scan_ply, out, leaf_windows=4, weld_tolerance=0.0, max_triangles=2000, keep=False)
    info = reducem.open(out).info
    assert info["leaf_triangles"] == 4
    assert not (tmp_path / "leaf.rdm.work").exists()
    for up in ("z", "y"):
        reducem.convert(scan_ply, tmp_path / f"{up}.rdm", up=up)
        assert reducem.open(tmp_path / f"{up}.rdm").info["up"] == up


def test_convert_errors(scan_ply, tmp_path):
    with pytest.raises(TypeError, match="max_lenght"):
        reducem.convert(scan_ply, tmp_path / "x.rdm", max_lenght=3)
    with pytest.raises(ValueError, match="encoding"):
        reducem.convert(scan_ply, tmp_path / "x.rdm", encoding="f16")
    with pytest.raises(FileNotFoundError, match="absent.ply"):
        reducem.convert(tmp_path / "absent.ply", tmp_path / "x.rdm")
    with pytest.raises(reducem.ReducemError, match="grid"):
        reducem.convert(scan_ply, tmp_path / "x.rdm", grid_bits=12)
    bad = tmp_path / "bad.ply"
    bad.write_bytes(b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nend_header\n")
    with pytest.raises(reducem.ReducemError, match="bad.ply"):
        reducem.convert(bad, tmp_path / "bad.rdm")


def _ply_triangles(path):
    """Positions (n, 3, 3) of the triangles of a binary little-endian PLY of `pipeline gen`
    (float x, y, z vertices; faces of three int corners)."""
    data = Path(path).read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode()
    count = lambda element: int(header.split(f"element {element} ")[1].split()[0])
    vertices, faces = count("vertex"), count("face")
    positions = np.frombuffer(data, dtype="<f4", count=3 * vertices, offset=end).reshape(-1, 3)
    record = np.dtype([("n", "u1"), ("corners", "<i4", 3)])
    corners = np.frombuffer(data, dtype=record, count=faces, offset=end + 12 * vertices)["corners"]
    return positions[corners]


def test_face_ids_are_the_primitive_ids(scan_ply, tmp_path):
    out = tmp_path / "faces.rdm"
    reducem.convert(scan_ply, out, face_ids=True)
    scene = reducem.open(out)
    assert scene.info["face_ids"] and scene.info["normals"] == "none"
    triangles = _ply_triangles(scan_ply).astype(np.float64)
    centroids = triangles.mean(axis=1)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    # From just outside each triangle's centroid straight at it: only that face is in reach.
    rays = np.hstack([centroids + 1e-4 * normals, -normals])
    hits = scene.cast_rays(rays, tfar=2e-4)
    assert "shading_normals" not in hits and "colors" not in hits
    assert np.array_equal(hits["primitive_ids"], np.arange(len(triangles), dtype=np.uint32))
