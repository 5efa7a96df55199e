#!/usr/bin/env python3
"""Issue 31 item 3 in one process: reducem's `cast_rays` on a row-major pinhole camera built
with numpy (as Open3D's `create_rays_pinhole` orders it) and `test_occlusions` on incoherent
rays, against Open3D's `RaycastingScene` on the same triangles, rays and thread count, and
`reducem query` on the same rays (written as ray files, its own figure of the tracing).
Prints medians of --runs calls in Mrays/s (every engine once per run, in turn) and the ratios
the issue's targets are stated in.

    python3 scripts/bench_python.py --triangles 1000000 --threads 2 --runs 3

Needs numpy and the package (`pip install ./python`); Open3D when it imports. Builds the
release binaries, and generates, converts and decodes the scan into --work when missing
(the decoded PLY gives Open3D exactly the model's triangles); --clean removes them afterwards.
"""
import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

# numpy's BLAS threads spin after building the rays and take cores from the calls timed (as
# scripts/bench_queries.sh runs its Python rows).
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_inputs import camera_rays, incoherent_rays, read_decoded, write_ray_file  # noqa: E402

import reducem  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent


def arguments():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--triangles", type=int, default=1_000_000)
    parser.add_argument("--side", type=int, default=1024, help="camera width and height")
    parser.add_argument("--threads", type=int, default=os.cpu_count())
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--work", type=Path, default=ROOT / "target" / "bench-python")
    parser.add_argument("--clean", action="store_true", help="delete the work files at the end")
    return parser.parse_args()


def run(*command, **options):
    return subprocess.run(command, check=True, capture_output=True, text=True, **options)


def prepare(triangles, work):
    """The converted model and its decoded PLY, made once per triangle count."""
    work.mkdir(parents=True, exist_ok=True)
    run("cargo", "build", "--release", "--quiet", "-p", "reducem", "-p", "pipeline", "--bins",
        cwd=ROOT)
    release = ROOT / "target" / "release"
    mesh, model = work / f"scan{triangles}.ply", work / f"scan{triangles}.rdm"
    decoded = work / f"scan{triangles}.decoded.ply"
    if not model.exists():
        run(release / "pipeline", "gen", "scan", "--triangles", str(triangles), "-o", mesh)
        run(release / "pipeline", "convert", mesh, "-o", model, "--log-format", "plain")
        mesh.unlink()
    if not decoded.exists():
        run(release / "reducem", "decode", model, "-o", decoded)
    return release / "reducem", model, decoded


def seconds(call):
    started = time.perf_counter()
    call()
    return time.perf_counter() - started


def query_seconds(binary, model, rays_path, threads, occluded):
    """`reducem query`'s own seconds of tracing (without reading rays or writing answers)."""
    command = [binary, "query", model, "--rays", rays_path, "-o", rays_path.with_suffix(".out")]
    command += ["--occluded"] if occluded else []
    summary = run(*command, env=dict(os.environ, RAYON_NUM_THREADS=str(threads))).stderr
    return float(re.search(r"seconds=([0-9.]+)", summary).group(1))


def main():
    args = arguments()
    binary, model, decoded = prepare(args.triangles, args.work)
    scene = reducem.open(model)
    low, high = (np.asarray(b, np.float64) for b in scene.bounds)
    camera = camera_rays(low, high, args.side)
    incoherent = incoherent_rays(low, high, args.side * args.side)
    count, threads, runs = args.side * args.side, args.threads, args.runs
    calls = {
        ("reducem", "camera"): lambda: scene.cast_rays(camera, nthreads=threads),
        ("reducem", "camera flat"): lambda: scene.cast_rays(camera.reshape(-1, 6),
                                                            nthreads=threads),
        ("reducem", "incoherent"): lambda: scene.test_occlusions(incoherent, nthreads=threads),
    }
    for name, rays, occluded in (("camera", camera, False), ("incoherent", incoherent, True)):
        path = args.work / f"{name}.rays"
        write_ray_file(rays, path)
        calls["query", name] = lambda path=path, occluded=occluded: query_seconds(
            binary, model, path, threads, occluded)
    try:
        import open3d as o3d
    except ImportError:
        print("open3d: not importable, skipped")
        o3d = None
    if o3d is not None:
        vertices, faces = read_decoded(decoded)
        faces = faces.astype(np.uint32)
        peer = o3d.t.geometry.RaycastingScene(nthreads=threads)
        peer.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces))
        peer.cast_rays(o3d.core.Tensor(camera[:1, :1]), nthreads=threads)  # builds the BVH
        peer_camera, peer_incoherent = o3d.core.Tensor(camera), o3d.core.Tensor(incoherent)
        calls["open3d", "camera"] = lambda: peer.cast_rays(peer_camera, nthreads=threads)
        calls["open3d", "incoherent"] = lambda: peer.test_occlusions(peer_incoherent,
                                                                     nthreads=threads)
    # One untimed round first: reducem validates a large file's strips as rays first reach
    # them, and Open3D's hierarchy is built already. Then every engine once per run, in turn,
    # so that a change of the machine's load between runs reaches all of them alike.
    for call in calls.values():
        call()
    times = {key: [] for key in calls}
    for _ in range(runs):
        for key, call in calls.items():
            times[key].append(call() if key[0] == "query" else seconds(call))
    figures = {key: count / statistics.median(values) / 1e6 for key, values in times.items()}
    for name in ("camera", "incoherent"):
        (args.work / f"{name}.rays").unlink()
        (args.work / f"{name}.out").unlink()
    print(f"{args.triangles} triangles, {count} rays, {threads} threads, medians of {runs}; "
          f"load {os.getloadavg()[0]:.1f}")
    print(f"{'rays':<14}{'reducem':>9}{'query':>9}{'Open3D':>9}{'÷ query':>9}{'÷ Open3D':>10}")
    for rays, peer_rays in (("camera", "camera"), ("camera flat", "camera"),
                            ("incoherent", "incoherent")):
        ours, cli = figures["reducem", rays], figures["query", peer_rays]
        peer = figures.get(("open3d", peer_rays), float("nan"))
        print(f"{rays:<14}{ours:>9.2f}{cli:>9.2f}{peer:>9.2f}{ours / cli:>9.2f}"
              f"{ours / peer:>10.2f}")
    if args.clean:
        shutil.rmtree(args.work)


if __name__ == "__main__":
    sys.exit(main())
