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

# The decoded PLY as numpy arrays, for the Python parts below.
cp scripts/bench_inputs.py "$WORK/bench_inputs.py"

cat >"$WORK/points.py" <<'EOF'
"""Writes POINTS points, each on a random triangle offset by up to 1% of the diagonal."""
import sys

import numpy as np

from bench_inputs import read_decoded

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

from bench_inputs import read_decoded

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

# Named by mesh too: the points of one scan are not on the surface of another.
points=$WORK/points$TRIANGLES-$POINTS.bin
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

# Every crossing: `reducem query --count` and `--all` against Open3D's count_intersections and
# list_intersections on RAYS incoherent rays across the bounds; `reducem inside` against
# Open3D's compute_occupancy (nsamples=1) and trimesh's contains (with embreex when installed)
# on the same points. Medians of RUNS runs of the queries alone, in Mqueries/s.
RAYS=${RAYS:-$POINTS}
cat >"$WORK/crossings.py" <<'EOF'
"""argv: decoded rays_out points_in count. Writes incoherent rays between random points of the
bounds grown by 10%, as a reducem ray file (f32 x 8: origin, direction, tmin, tmax)."""
import sys

import numpy as np

from bench_inputs import read_decoded

decoded, out, count = sys.argv[1], sys.argv[2], int(sys.argv[3])
vertices, _ = read_decoded(decoded)
low, high = vertices.min(0).astype(np.float64), vertices.max(0).astype(np.float64)
grow = 0.1 * (high - low)
rng = np.random.default_rng(2)
a = rng.uniform(low - grow, high + grow, (count, 3))
b = rng.uniform(low - grow, high + grow, (count, 3))
rays = np.zeros((count, 8), "<f4")
rays[:, :3], rays[:, 3:6], rays[:, 7] = a, b - a, np.inf
rays.tofile(out)
EOF
cat >"$WORK/crossing_peer.py" <<'EOF'
"""One peer, one query kind, one run: prints `query_s`, saves the answers. argv: engine kind
decoded input threads answers_out (kind: count, all, inside)."""
import sys
import time

import numpy as np

from bench_inputs import read_decoded

name, kind, decoded, source, threads, out = sys.argv[1:7]
threads = int(threads)
vertices, faces = read_decoded(decoded)
if kind == "inside":
    queries = np.fromfile(source, "<f4").reshape(-1, 3)
else:
    queries = np.fromfile(source, "<f4").reshape(-1, 8)[:, :6].copy()
if name == "open3d":
    import open3d as o3d

    scene = o3d.t.geometry.RaycastingScene(nthreads=threads)
    scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces.astype(np.uint32)))
    scene.count_intersections(o3d.core.Tensor(queries[:1, :6] if kind != "inside" else
                                              np.array([[0, 0, 0, 1, 0, 0]], np.float32)))
    tensor = o3d.core.Tensor(queries)
    started = time.perf_counter()
    if kind == "count":
        answers = scene.count_intersections(tensor, nthreads=threads).numpy()
    elif kind == "all":
        answers = scene.list_intersections(tensor, nthreads=threads)["ray_splits"].numpy()
    else:
        answers = scene.compute_occupancy(tensor, nthreads=threads).numpy()
    query = time.perf_counter() - started
else:
    import trimesh

    mesh = trimesh.Trimesh(vertices, faces, process=False)
    mesh.contains(queries[:1])
    started = time.perf_counter()
    answers = mesh.contains(queries)
    query = time.perf_counter() - started
np.save(out, np.asarray(answers))
print(query)
EOF
rays=$WORK/rays$RAYS.bin
[[ -f $rays ]] || (cd "$WORK" && "$PYTHON" crossings.py "$(basename "$decoded")" "$(basename "$rays")" "$RAYS")
"$PYTHON" -c "import trimesh" 2>/dev/null && has_trimesh=1 || { has_trimesh=0; echo "trimesh: not importable, skipped"; }
crossing_results=$WORK/crossing-results.txt
: >"$crossing_results"
seconds_of() { grep -o 'seconds=[0-9.]*' "$1" | cut -d= -f2; }
for run in $(seq "$RUNS"); do
  for kind in count all; do
    RAYON_NUM_THREADS=$THREADS target/release/reducem query "$model" --rays "$rays" --$kind \
      -o "$WORK/reducem.$kind" 2>"$WORK/summary"
    echo "$kind reducem $(seconds_of "$WORK/summary")" >>"$crossing_results"
  done
  target/release/reducem inside "$model" --points "$points" -o "$WORK/reducem.inside" \
    --threads "$THREADS" 2>"$WORK/summary"
  echo "inside reducem $(seconds_of "$WORK/summary")" >>"$crossing_results"
  for kind in count all inside; do
    if [[ " ${engines[*]} " == *" open3d "* ]]; then
      input=$([[ $kind == inside ]] && basename "$points" || basename "$rays")
      echo "$kind open3d $(cd "$WORK" && "$PYTHON" crossing_peer.py open3d $kind \
        "$(basename "$decoded")" "$input" "$THREADS" "open3d.$kind.npy")" >>"$crossing_results"
    fi
  done
  if ((has_trimesh)); then
    echo "inside trimesh $(cd "$WORK" && "$PYTHON" crossing_peer.py trimesh inside \
      "$(basename "$decoded")" "$(basename "$points")" "$THREADS" trimesh.inside.npy)" >>"$crossing_results"
  fi
done

"$PYTHON" - "$crossing_results" "$WORK" "$RAYS" "$POINTS" "$THREADS" <<'EOF'
import os
import statistics
import sys

import numpy as np

results, work, rays, points, threads = sys.argv[1:6]
rows = {}
for line in open(results):
    kind, name, query = line.split()
    rows.setdefault((kind, name), []).append(float(query))
print(f"\n{int(rays):,} incoherent rays, {int(points):,} points, {threads} threads, medians")
print(f"{'query':<8} {'engine':<10} {'Mqueries/s':>10} {'query s':>9}")
for (kind, name), runs in rows.items():
    count = int(points) if kind == "inside" else int(rays)
    query = statistics.median(runs)
    print(f"{kind:<8} {name:<10} {count / query / 1e6:>10.3f} {query:>9.3f}")
counts = np.fromfile(f"{work}/reducem.count", "<u4")
if os.path.exists(f"{work}/open3d.count.npy"):
    other = np.load(f"{work}/open3d.count.npy")
    print(f"rays whose count differs from Open3D's: {(counts != other).sum():,} of {len(counts):,}")
EOF

# The hard cases: rays from the centre of a closed generated sphere (HARD_TRIANGLES) at every
# vertex, edge midpoint and centroid cross the surface exactly once; wrong counts per engine.
HARD_TRIANGLES=${HARD_TRIANGLES:-20000}
hard=$WORK/sphere$HARD_TRIANGLES
[[ -f $hard.rdm ]] || {
  target/release/pipeline gen sphere --triangles "$HARD_TRIANGLES" -o "$hard.ply"
  target/release/pipeline convert "$hard.ply" -o "$hard.rdm" --log-format plain 2>/dev/null
  target/release/reducem decode "$hard.rdm" -o "$hard.decoded.ply"
}
cat >"$WORK/hard.py" <<'EOF'
"""argv: decoded rays_out. Rays from the vertex centroid at every vertex, edge midpoint and
triangle centroid, computed in f64 and rounded once."""
import sys

import numpy as np

from bench_inputs import read_decoded

vertices, faces = read_decoded(sys.argv[1])
wide = vertices.astype(np.float64)
corners = wide[faces]
targets = np.concatenate([
    wide,
    (corners[:, 0] + corners[:, 1]) / 2, (corners[:, 1] + corners[:, 2]) / 2,
    (corners[:, 2] + corners[:, 0]) / 2, corners.mean(1),
]).astype(np.float32)
centre = wide.mean(0).astype(np.float32)
rays = np.zeros((len(targets), 8), "<f4")
rays[:, :3], rays[:, 3:6], rays[:, 7] = centre, targets - centre, np.inf
rays.tofile(sys.argv[2])
EOF
(cd "$WORK" && "$PYTHON" hard.py "$(basename "$hard").decoded.ply" hard.rays)
target/release/reducem inspect --json "$hard.rdm" | "$PYTHON" -c 'import json, sys
s = json.load(sys.stdin)
print("\nhard cases: sphere of {:,} triangles, closed: {}".format(s["triangles"], s["closed"]))'
target/release/reducem query "$hard.rdm" --rays "$WORK/hard.rays" --count -o "$WORK/hard.reducem" 2>/dev/null
"$PYTHON" - "$WORK" "$(basename "$hard").decoded.ply" <<'EOF'
import sys

import numpy as np

sys.path.insert(0, sys.argv[1])
from bench_inputs import read_decoded

work = sys.argv[1]
counts = {"reducem": np.fromfile(f"{work}/hard.reducem", "<u4")}
try:
    import open3d as o3d

    vertices, faces = read_decoded(f"{work}/{sys.argv[2]}")
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(o3d.core.Tensor(vertices), o3d.core.Tensor(faces.astype(np.uint32)))
    rays = np.fromfile(f"{work}/hard.rays", "<f4").reshape(-1, 8)[:, :6].copy()
    counts["open3d"] = scene.count_intersections(o3d.core.Tensor(rays)).numpy()
except ImportError:
    pass
print(f"{'engine':<10} {'rays':>9} {'wrong counts':>13} {'%':>7}")
for name, c in counts.items():
    wrong = int((c != 1).sum())
    print(f"{name:<10} {len(c):>9,} {wrong:>13,} {100 * wrong / len(c):>7.2f}")
EOF

# The Python package's rows (when `import reducem` works in PYTHON): cast_rays on a row-major
# pinhole camera (shaped (H, W, 6) and flat), test_occlusions on incoherent rays and
# compute_closest_points on the points above, against Open3D in the same process, and `reducem
# query` on the same rays (its own timing of the tracing, RAYON_NUM_THREADS=THREADS); medians of
# RUNS calls each, after one untimed call.
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
from bench_inputs import camera_rays, incoherent_rays, read_decoded, write_ray_file

model, decoded, points_path, threads, runs, work = sys.argv[1:7]
threads, runs = int(threads), int(runs)
scene = reducem.open(model)
low, high = (np.asarray(b, np.float64) for b in scene.bounds)
side = 1024
camera = camera_rays(low, high, side)
count = side * side
incoherent = incoherent_rays(low, high, count)
write_ray_file(camera, f"{work}/camera.rays")
write_ray_file(incoherent, f"{work}/incoherent.rays")


def rate(call, queries=count):
    # One untimed call first, for either engine: the medians are of calls on a warm scene
    # (reducem's first query builds its primitive ids and validates strips as rays reach them).
    call()
    times = []
    for _ in range(runs):
        started = time.perf_counter()
        call()
        times.append(time.perf_counter() - started)
    return queries / statistics.median(times) / 1e6


points = np.fromfile(points_path, "<f4").reshape(-1, 3)


figures = {
    "reducem cast_rays camera": rate(lambda: scene.cast_rays(camera, nthreads=threads)),
    "reducem cast_rays camera (H*W, 6)": rate(
        lambda: scene.cast_rays(camera.reshape(-1, 6), nthreads=threads)
    ),
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
