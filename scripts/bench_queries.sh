#!/usr/bin/env bash
# Closest points per second: `reducem closest` against Open3D's RaycastingScene
# (`compute_closest_points`) and fcpw (`find_closest_points`), on the same triangles (the
# model's own, decoded), the same points (on the surface offset by up to 1% of the bounding
# box's diagonal) and the same thread count, each engine in a fresh process per run. Prints
# medians over RUNS runs of the query throughput (Mpoints/s, the queries alone) and of the
# set-up (reducem: open and answer-file write excluded from the query time; peers: reading the
# mesh arrays and building their hierarchy), and the largest distance disagreement with Open3D.
#
#   scripts/bench_queries.sh                          # 1M-triangle scan, 1M points, 5 runs
#   TRIANGLES=10000000 POINTS=1000000 RUNS=3 scripts/bench_queries.sh
#
# Then, when PYTHON imports the package (`pip install ./python`), the Python rows: see
# `python_rows` at the end.
#
# PYTHON is an interpreter with numpy; Open3D (`pip install open3d-cpu`, which needs Debian's
# libusb-1.0-0) and fcpw (`pip install fcpw`) are measured when they import. fcpw's Python
# binding takes no thread count: it runs on every core, so THREADS should be the core count
# for a fair comparison. Work files go to WORK.
set -euo pipefail
cd "$(dirname "$0")/.."
TRIANGLES=${TRIANGLES:-1000000}
POINTS=${POINTS:-1000000}
THREADS=${THREADS:-$(nproc)}
RUNS=${RUNS:-5}
PYTHON=${PYTHON:-python3}
WORK=${WORK:-target/bench-queries}
mkdir -p "$WORK"

cargo build --release -p reducem -p pipeline --bins --quiet
mesh=$WORK/scan$TRIANGLES.ply
model=$WORK/scan$TRIANGLES.rdm
decoded=$WORK/scan$TRIANGLES.decoded.ply
[[ -f $mesh ]] || target/release/pipeline gen scan --triangles "$TRIANGLES" -o "$mesh"
[[ -f $model ]] || target/release/pipeline convert "$mesh" -o "$model" --log-format plain 2>/dev/null
[[ -f $decoded ]] || target/release/reducem decode "$model" -o "$decoded"

# The decoded PLY (`reducem decode`: float x, y, z; list uchar int) as numpy arrays.
cat >"$WORK/mesh.py" <<'EOF'
import numpy as np


def read_decoded(path):
    with open(path, "rb") as f:
        counts = {}
        while (line := f.readline().strip()) != b"end_header":
            words = line.split()
            if words[:1] == [b"element"]:
                counts[words[1].decode()] = int(words[2])
        vertices = np.fromfile(f, "<f4", counts["vertex"] * 3).reshape(-1, 3)
        faces = np.fromfile(f, [("n", "u1"), ("i", "<i4", 3)], counts["face"])
    return vertices, np.ascontiguousarray(faces["i"])
EOF

cat >"$WORK/points.py" <<'EOF'
"""Writes POINTS points, each on a random triangle offset by up to 1% of the diagonal."""
import sys

import numpy as np

from mesh import read_decoded

decoded, count, out = sys.argv[1], int(sys.argv[2]), sys.argv[3]
vertices, faces = read_decoded(decoded)
rng = np.random.default_rng(1)
corners = vertices[faces[rng.integers(0, len(faces), count)]].astype(np.float64)
u, v = rng.random(count), rng.random(count)
flip = u + v > 1
u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
on = corners[:, 0] + u[:, None] * (corners[:, 1] - corners[:, 0]) + v[:, None] * (corners[:, 2] - corners[:, 0])
diagonal = np.linalg.norm(vertices.max(0).astype(np.float64) - vertices.min(0))
direction = rng.normal(size=(count, 3))
direction /= np.linalg.norm(direction, axis=1)[:, None]
points = on + direction * (0.01 * diagonal * rng.random(count))[:, None]
points.astype("<f4").tofile(out)
EOF

cat >"$WORK/peer.py" <<'EOF'
"""One peer, one run: prints `setup_s query_s`, and saves the distances. argv: engine decoded
points threads distances_out."""
import sys
import time

import numpy as np

from mesh import read_decoded

name, decoded, points_path, threads, out = sys.argv[1:6]
threads = int(threads)
points = np.fromfile(points_path, "<f4").reshape(-1, 3)
started = time.perf_counter()
vertices, faces = read_decoded(decoded)
if name == "open3d":
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene(nthreads=threads)
    scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces.astype(np.uint32)))
    # The hierarchy is built on the first query: one point, counted as set-up.
    scene.compute_closest_points(o3d.core.Tensor(points[:1]), nthreads=threads)
    setup = time.perf_counter() - started
    started = time.perf_counter()
    found = scene.compute_closest_points(o3d.core.Tensor(points), nthreads=threads)
    query = time.perf_counter() - started
    distances = np.linalg.norm(found["points"].numpy() - points, axis=1)
elif name == "fcpw":
    import fcpw

    scene = fcpw.scene_3D()
    scene.set_object_count(1)
    scene.set_object_vertices(np.asfortranarray(vertices), 0)
    scene.set_object_triangles(np.asfortranarray(faces), 0)
    scene.build(fcpw.aggregate_type.bvh_surface_area, True)
    setup = time.perf_counter() - started
    queries = np.asfortranarray(points)
    radii = np.full(len(points), np.inf, np.float32)
    interactions = fcpw.interaction_3D_list()
    started = time.perf_counter()
    scene.find_closest_points(queries, radii, interactions)
    query = time.perf_counter() - started
    distances = np.array([i.d for i in interactions], np.float32)
np.save(out, distances.astype(np.float32))
print(setup, query)
EOF

points=$WORK/points$POINTS.bin
[[ -f $points ]] || (cd "$WORK" && "$PYTHON" points.py "$(basename "$decoded")" "$POINTS" "$(basename "$points")")

engines=()
for peer in open3d fcpw; do
  "$PYTHON" -c "import $peer" 2>/dev/null && engines+=("$peer") || echo "$peer: not importable, skipped"
done

results=$WORK/results.txt
: >"$results"
for run in $(seq "$RUNS"); do
  started=$(date +%s.%N)
  target/release/reducem closest "$model" --points "$points" -o "$WORK/reducem.answers" \
    --threads "$THREADS" 2>"$WORK/summary"
  wall=$(echo "$(date +%s.%N) - $started" | bc)
  query=$(grep -o 'seconds=[0-9.]*' "$WORK/summary" | cut -d= -f2)
  echo "reducem $(echo "$wall - $query" | bc) $query" >>"$results"
  for peer in "${engines[@]}"; do
    (cd "$WORK" && "$PYTHON" peer.py "$peer" "$(basename "$decoded")" "$(basename "$points")" \
      "$THREADS" "$peer.distances.npy") | sed "s/^/$peer /" >>"$results"
  done
done

"$PYTHON" - "$results" "$WORK" "$POINTS" "$THREADS" "$TRIANGLES" <<'EOF'
import os
import statistics
import sys

import numpy as np

results, work, points, threads, triangles = sys.argv[1:6]
rows = {}
for line in open(results):
    name, setup, query = line.split()
    rows.setdefault(name, []).append((float(setup), float(query)))
print(f"scan {int(triangles):,} triangles, {int(points):,} points within 1% of the diagonal, "
      f"{threads} threads, medians of {len(rows['reducem'])} runs")
print(f"{'engine':<10} {'Mpoints/s':>10} {'query s':>9} {'set-up s':>9}")
for name, runs in rows.items():
    query = statistics.median(q for _, q in runs)
    setup = statistics.median(s for s, _ in runs)
    print(f"{name:<10} {int(points) / query / 1e6:>10.3f} {query:>9.3f} {setup:>9.3f}")
answers = np.fromfile(f"{work}/reducem.answers", "<f4").reshape(-1, 8)
for name in rows:
    path = f"{work}/{name}.distances.npy"
    if name != "reducem" and os.path.exists(path):
        gap = np.abs(np.load(path).astype(np.float64) - answers[:, 0]).max()
        print(f"largest |distance - {name}'s|: {gap:.3g}")
EOF

# The Python package's rows (when `import reducem` works in PYTHON): cast_rays on a row-major
# pinhole camera, test_occlusions on incoherent rays and compute_closest_points on the points
# above, against Open3D in the same process, and `reducem query` on the same rays (its own
# timing of the tracing, RAYON_NUM_THREADS=THREADS); medians of RUNS calls each.
python_rows() {
  "$PYTHON" -c "import reducem" 2>/dev/null || {
    echo "reducem (Python): not importable, Python rows skipped"
    return
  }
  cat >"$WORK/python_rays.py" <<'EOF'
"""Python ray queries, one process: reducem's cast_rays on a row-major 1024x1024 pinhole camera
and test_occlusions on incoherent rays, and compute_closest_points on the benchmark's points,
against Open3D's RaycastingScene on the same triangles, rays, points and thread count. Writes
both ray sets as ray files for `reducem query`. Prints `name Mqueries/s` (medians).
argv: model decoded points threads runs work"""
import statistics
import sys
import time

import numpy as np

import reducem
from mesh import read_decoded

model, decoded, points_path, threads, runs, work = sys.argv[1:7]
threads, runs = int(threads), int(runs)
scene = reducem.open(model)
low, high = (np.asarray(b, np.float64) for b in scene.bounds)
centre, size = (low + high) / 2, float(np.linalg.norm(high - low))

# A pinhole camera as Open3D's create_rays_pinhole orders its rays: (height, width, 6), row by row.
side = 1024
eye = centre + np.array([0.3, 0.5, 1.0]) / np.linalg.norm([0.3, 0.5, 1.0]) * size
forward = (centre - eye) / np.linalg.norm(centre - eye)
right = np.cross(forward, [0.0, 1.0, 0.0])
right /= np.linalg.norm(right)
up = np.cross(right, forward)
half = np.tan(np.radians(30.0))
ys, xs = np.meshgrid(np.linspace(half, -half, side), np.linspace(-half, half, side), indexing="ij")
directions = forward + xs[..., None] * right + ys[..., None] * up
camera = np.concatenate([np.broadcast_to(eye, directions.shape), directions], -1).astype(np.float32)

rng = np.random.default_rng(1)
count = side * side
origins = low + rng.random((count, 3)) * (high - low)
spread = rng.normal(size=(count, 3))
incoherent = np.concatenate([origins, spread], -1).astype(np.float32)


def ray_file(rays, path):
    flat = rays.reshape(-1, 6)
    records = np.zeros((len(flat), 8), "<f4")
    records[:, :6] = flat
    records[:, 7] = np.inf
    records.tofile(path)


ray_file(camera, f"{work}/camera.rays")
ray_file(incoherent, f"{work}/incoherent.rays")


def rate(call, queries=count):
    times = []
    for _ in range(runs):
        started = time.perf_counter()
        call()
        times.append(time.perf_counter() - started)
    return queries / statistics.median(times) / 1e6


points = np.fromfile(points_path, "<f4").reshape(-1, 3)


figures = {
    "reducem cast_rays camera": rate(lambda: scene.cast_rays(camera, nthreads=threads)),
    "reducem test_occlusions incoherent": rate(
        lambda: scene.test_occlusions(incoherent, nthreads=threads)
    ),
    "reducem compute_closest_points": rate(
        lambda: scene.compute_closest_points(points, nthreads=threads), len(points)
    ),
}
try:
    import open3d as o3d
except ImportError:
    o3d = None
if o3d is not None:
    vertices, faces = read_decoded(decoded)
    peer = o3d.t.geometry.RaycastingScene(nthreads=threads)
    peer.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces.astype(np.uint32)))
    peer.cast_rays(o3d.core.Tensor(camera[:1, :1]), nthreads=threads)
    o3d_camera, o3d_incoherent = o3d.core.Tensor(camera), o3d.core.Tensor(incoherent)
    figures["open3d cast_rays camera"] = rate(lambda: peer.cast_rays(o3d_camera, nthreads=threads))
    figures["open3d test_occlusions incoherent"] = rate(
        lambda: peer.test_occlusions(o3d_incoherent, nthreads=threads)
    )
    o3d_points = o3d.core.Tensor(points)
    figures["open3d compute_closest_points"] = rate(
        lambda: peer.compute_closest_points(o3d_points, nthreads=threads), len(points)
    )
for name, mrays in figures.items():
    print(f"{name} {mrays:.2f}")
EOF
  echo "Python rows: Mqueries/s, $THREADS threads, medians of $RUNS calls"
  (cd "$WORK" && OPENBLAS_NUM_THREADS=1 "$PYTHON" python_rays.py "$(basename "$model")" \
    "$(basename "$decoded")" "$(basename "$points")" "$THREADS" "$RUNS" .)
  for rays in camera incoherent; do
    local occluded=()
    [[ $rays == incoherent ]] && occluded=(--occluded)
    for run in $(seq "$RUNS"); do
      RAYON_NUM_THREADS=$THREADS target/release/reducem query "$model" --rays "$WORK/$rays.rays" \
        -o "$WORK/query.answers" "${occluded[@]}" 2>&1 | grep -o 'mrays_per_s=[0-9.]*' | cut -d= -f2
    done | sort -n | awk -v name="reducem query $rays" '{ v[NR] = $1 } END { print name, v[int((NR + 1) / 2)] }'
  done
}
python_rows
