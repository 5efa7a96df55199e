"""The package as type checkers and editors see it: the stub describes every public name and
argument of the native module, ships with the package, and mypy checks code against it."""

import ast
import inspect
import re
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

import reducem
from conftest import convert
from reducem import _native

PACKAGE = Path(reducem.__file__).parent


def stub():
    """The installed stub's top-level functions and classes by name."""
    tree = ast.parse((PACKAGE / "_native.pyi").read_text())
    return {
        node.name: node
        for node in tree.body
        if isinstance(node, (ast.FunctionDef, ast.ClassDef))
    }


def parameters(function):
    """A stub function's parameters as `{name: (kind, default source or None)}`."""
    args = function.args
    found = {}
    positional = args.posonlyargs + args.args
    defaults = [None] * (len(positional) - len(args.defaults)) + args.defaults
    for arg, default in zip(positional, defaults):
        found[arg.arg] = ("positional", default and ast.unparse(default))
    for arg, default in zip(args.kwonlyargs, args.kw_defaults):
        found[arg.arg] = ("keyword", default and ast.unparse(default))
    return found


def public(names):
    return {name for name in names if not name.startswith("_")}


def test_the_package_ships_its_stub_and_marker():
    assert (PACKAGE / "py.typed").is_file()
    assert (PACKAGE / "_native.pyi").is_file()


def test_every_public_name_of_the_native_module_is_in_the_stub():
    assert public(dir(_native)) <= set(stub())
    # The package's own Python modules carry their annotations (py.typed).
    written_in_python = {"from_arrays"}
    assert set(reducem.__all__) <= set(stub()) | written_in_python
    members = {
        node.name
        for node in stub()["Scene"].body
        if isinstance(node, ast.FunctionDef)
    }
    assert public(dir(_native.Scene)) <= members


def check_positional(stubbed, runtime):
    """The runtime's named parameters are the stub's, with the same defaults where the runtime
    shows one (it shows `...` for infinity)."""
    named = [
        p
        for p in runtime.parameters.values()
        if p.kind not in (p.VAR_KEYWORD, p.VAR_POSITIONAL)
    ]
    for p in named:
        assert p.name in stubbed, f"{p.name} missing from the stub"
        _, default = stubbed[p.name]
        if p.default is p.empty:
            assert default is None, f"{p.name}: the stub has a default, the runtime none"
        elif p.default is not Ellipsis:
            assert ast.literal_eval(default) == p.default, p.name
    stub_positional = [name for name, (kind, _) in stubbed.items() if kind == "positional"]
    assert stub_positional == [p.name for p in named if p.kind != p.KEYWORD_ONLY]


@pytest.mark.parametrize(
    "name",
    [
        "open",
        "convert",
        "Scene.cast_rays",
        "Scene.test_occlusions",
        "Scene.render",
        "Scene.compute_closest_points",
        "Scene.compute_distance",
        "Scene.count_intersections",
        "Scene.list_intersections",
        "Scene.compute_signed_distance",
        "Scene.compute_occupancy",
    ],
)
def test_stub_signatures_match_the_runtime(name):
    owner, _, member = name.rpartition(".")
    runtime = getattr(getattr(_native, owner), member) if owner else getattr(_native, member)
    node = stub()[owner or member]
    if owner:
        node = next(n for n in node.body if isinstance(n, ast.FunctionDef) and n.name == member)
    check_positional(parameters(node), inspect.signature(runtime))


def options_listed(error):
    return set(re.search(r"\((?:options|overrides): ([^)]*)\)", str(error)).group(1).split(", "))


def keyword_options(function):
    return {name for name, (kind, _) in parameters(function).items() if kind == "keyword"}


def test_stub_lists_every_option_convert_accepts(scan_ply, tmp_path):
    with pytest.raises(TypeError) as refused:
        reducem.convert(scan_ply, tmp_path / "x.rdm", no_such_option=1)
    assert keyword_options(stub()["convert"]) - {"progress"} == options_listed(refused.value)


def test_stub_lists_every_override_render_accepts(scan_ply):
    scene = reducem.open(convert(scan_ply))
    with pytest.raises(TypeError) as refused:
        scene.render({}, no_such_override=1)
    render = next(n for n in stub()["Scene"].body if getattr(n, "name", "") == "render")
    assert keyword_options(render) == options_listed(refused.value)


def mypy(tmp_path, source):
    pytest.importorskip("mypy")
    program = tmp_path / "example.py"
    program.write_text(textwrap.dedent(source))
    return subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--no-incremental", str(program)],
        capture_output=True,
        text=True,
        cwd=tmp_path,
    )


def test_mypy_accepts_typed_use_of_the_package(tmp_path):
    checked = mypy(
        tmp_path,
        """
        import numpy as np
        from numpy.typing import NDArray
        import reducem

        def depth(path: str, rays: NDArray[np.float32]) -> NDArray[np.float32]:
            scene: reducem.Scene = reducem.open(path)
            hits = scene.cast_rays(rays, tfar=100.0, invalid="miss")
            missed: NDArray[np.uint32] = hits["geometry_ids"]
            nearest = scene.compute_closest_points(rays[..., :3], nthreads=2)
            far: NDArray[np.float32] = scene.compute_distance(nearest["points"])
            counts: NDArray[np.int32] = scene.count_intersections(rays, tfar=5.0)
            listed: NDArray[np.uint32] = scene.list_intersections(rays)["ray_splits"]
            inside: NDArray[np.float32] = scene.compute_occupancy(rays[..., :3], nsamples=3)
            signed = scene.compute_signed_distance(rays[..., :3], nthreads=1)
            closed: bool = scene.closed
            print(missed, nearest["primitive_normals"], far, counts, listed, inside, signed, closed)
            arrays: reducem.Scene = reducem.from_arrays(
                np.zeros((3, 3)), np.array([[0, 1, 2]]), max_length=4
            )
            low, high = scene.bounds
            image: NDArray[np.uint8] = scene.render({"image": {"width": 8}}, width=16, up="y")
            print(low, high, image.shape, scene.info["triangles"], scene.path.name)
            return hits["t_hit"]

        def report(stage: str, done: int, total: int, unit: str) -> None:
            print(stage, done, total, unit)

        reducem.convert("in.ply", "out.rdm", progress=report, encoding="grid", grid_bits=16)
        """,
    )
    assert checked.returncode == 0, checked.stdout + checked.stderr


def test_mypy_rejects_what_the_package_would_refuse(tmp_path):
    checked = mypy(
        tmp_path,
        """
        import reducem

        reducem.convert("in.ply", "out.rdm", encoding="f16")
        reducem.convert("in.ply", "out.rdm", max_lenght=3)
        occluded: str = reducem.open("model.rdm").test_occlusions([[0, 0, 0, 0, 0, 1]])
        """,
    )
    errors = [line for line in checked.stdout.splitlines() if ": error:" in line]
    assert [line.split(":")[1] for line in errors] == ["4", "5", "6"], checked.stdout

