#!/usr/bin/env bash
# The Python package against `reducem query`, Open3D's RaycastingScene and trimesh with embreex:
# the same mesh, the same camera and ambient-occlusion rays, every engine in a fresh process
# per run. Prints medians over RUNS runs of trace throughput (Mrays/s), set-up time (reading
# and building) and memory (peak RSS of the process by /usr/bin/time, and the RSS the scene
# adds once set up).
#
#   scripts/bench_python.sh                 # 1M-triangle scan, 1024² camera rays, 5 runs
#   TRIANGLES=8000000 SIZE=2048 RUNS=3 scripts/bench_python.sh
#   CALLGRIND=1 scripts/bench_python.sh     # also the binding's overhead in instructions
#
# Wall-clock figures move with the machine's load; CALLGRIND=1 adds the overhead of
# `cast_rays` and `test_occlusions` over `reducem query` counted in instructions (valgrind,
# one thread) on a 100k-ray block of the camera rays: each tool's run minus its run on one ray,
# so that opening the file (and the binding's triangle index, built on the first query) and
# starting the interpreter are left out.
#
# PYTHON is an interpreter with the package installed (`pip install ./python`) and numpy;
# Open3D (`pip install open3d-cpu`, which needs Debian's libusb-1.0-0) and trimesh with embreex
# (`pip install trimesh embreex`) are measured when they import. Work files go to WORK.
set -euo pipefail
cd "$(dirname "$0")/.."
TRIANGLES=${TRIANGLES:-1000000}
SIZE=${SIZE:-1024}
RUNS=${RUNS:-5}
PYTHON=${PYTHON:-python3}
WORK=${WORK:-target/bench-python}
mkdir -p "$WORK"

cargo build --release -p reducem -p pipeline --bins --quiet
mesh=$WORK/scan$TRIANGLES.ply
model=$WORK/scan$TRIANGLES.rdm
[[ -f $mesh ]] || target/release/pipeline gen scan --triangles "$TRIANGLES" -o "$mesh"
[[ -f $model ]] || target/release/pipeline convert "$mesh" -o "$model" --log-format plain 2>/dev/null

engine=$WORK/engine.py
cat >"$engine" <<'EOF'
"""One engine, one run: prints `key=value` figures. argv: engine mesh model rays_dir."""
import json
import sys
import time

import numpy as np


def rss_bytes():
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * 4096


name, mesh, model, rays_dir = sys.argv[1:5]
camera = np.load(f"{rays_dir}/camera.npy")
ao = np.load(f"{rays_dir}/ao.npy")
ao_tfar = float(np.load(f"{rays_dir}/ao_tfar.npy"))
before = rss_bytes()
figures = {}
started = time.perf_counter()
if name == "reducem":
    import reducem
    scene = reducem.open(model)
    figures["read_s"] = time.perf_counter() - started
    started = time.perf_counter()
    # The triangle index of primitive_ids is built on the first hit query; built here so that
    # it counts as set-up, as Open3D's and Embree's builds do.
    scene.cast_rays(camera[:1])
    figures["build_s"] = time.perf_counter() - started
    cast = lambda rays: scene.cast_rays(rays)
    occlude = lambda rays: scene.test_occlusions(rays, tfar=ao_tfar)
elif name == "open3d":
    import open3d as o3d
    triangle_mesh = o3d.t.io.read_triangle_mesh(mesh)
    figures["read_s"] = time.perf_counter() - started
    started = time.perf_counter()
    scene = o3d.t.geometry.RaycastingScene()
    scene.add_triangles(triangle_mesh)
    scene.cast_rays(o3d.core.Tensor(camera[:1]))  # the BVH is built on the first query
    figures["build_s"] = time.perf_counter() - started
    cast = lambda rays: scene.cast_rays(o3d.core.Tensor(rays))
    occlude = lambda rays: scene.test_occlusions(o3d.core.Tensor(rays), tfar=ao_tfar)
elif name == "trimesh":
    import trimesh
    from trimesh.ray.ray_pyembree import RayMeshIntersector
    mesh_object = trimesh.load(mesh, process=False)
    figures["read_s"] = time.perf_counter() - started
    started = time.perf_counter()
    intersector = RayMeshIntersector(mesh_object)
    intersector.intersects_first(camera[:1, :3], camera[:1, 3:])
    figures["build_s"] = time.perf_counter() - started
    cast = lambda rays: intersector.intersects_first(rays[:, :3], rays[:, 3:])
    # trimesh has no ray interval: occlusion within tfar from the first hit's distance.
    def occlude(rays):
        points, index_ray, _ = intersector.intersects_location(
            rays[:, :3], rays[:, 3:], multiple_hits=False)
        distance = np.linalg.norm(points - rays[index_ray, :3], axis=1)
        distance /= np.linalg.norm(rays[index_ray, 3:], axis=1)
        occluded = np.zeros(len(rays), dtype=bool)
        occluded[index_ray[distance <= ao_tfar]] = True
        return occluded
figures["scene_mb"] = (rss_bytes() - before) / 1e6
for label, rays, run in (("camera", camera, cast), ("ao", ao, occlude)):
    started = time.perf_counter()
    answers = run(rays)
    seconds = time.perf_counter() - started
    figures[f"{label}_mrays"] = len(rays) / seconds / 1e6
    if name == "reducem" and label == "camera":
        figures["camera_hits"] = int(np.isfinite(answers["t_hit"]).sum())
print(json.dumps(figures))
EOF

# The rays: a camera framing the model, and per primary hit one cosine-weighted AO ray of 5%
# of the diagonal, lifted off the surface; written as .npy and as `reducem query` ray files.
"$PYTHON" - "$model" "$WORK" "$SIZE" <<'EOF'
import sys
import numpy as np
import reducem

model, work, size = sys.argv[1], sys.argv[2], int(sys.argv[3])
scene = reducem.open(model)
low, high = (b.astype(np.float64) for b in scene.bounds)
centre, diagonal = (low + high) / 2, np.linalg.norm(high - low)
eye = centre + diagonal * np.array([0.55, 0.45, 0.6])
forward = (centre - eye) / np.linalg.norm(centre - eye)
right = np.cross(forward, [0, 0, 1.0]); right /= np.linalg.norm(right)
up = np.cross(right, forward)
ys, xs = np.meshgrid(np.linspace(0.45, -0.45, size), np.linspace(-0.45, 0.45, size), indexing="ij")
directions = forward + xs[..., None] * right + ys[..., None] * up
camera = np.concatenate([np.broadcast_to(eye, directions.shape), directions], -1)
camera = camera.reshape(-1, 6).astype(np.float32)
hits = scene.cast_rays(camera)
hit = np.isfinite(hits["t_hit"])
normal = hits["primitive_normals"][hit].astype(np.float64)
normal *= -np.sign(np.sum(normal * camera[hit, 3:], axis=1, keepdims=True))
point = camera[hit, :3] + hits["t_hit"][hit, None] * camera[hit, 3:] + 1e-5 * diagonal * normal
rng = np.random.default_rng(1)
tangent = np.cross(normal, rng.normal(size=normal.shape))
tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
bitangent = np.cross(normal, tangent)
r, phi = np.sqrt(rng.random(len(normal)))[:, None], 2 * np.pi * rng.random(len(normal))[:, None]
direction = r * np.cos(phi) * tangent + r * np.sin(phi) * bitangent + np.sqrt(1 - r**2) * normal
ao = np.concatenate([point, direction], 1).astype(np.float32)
ao_tfar = np.float32(0.05 * diagonal)
np.save(f"{work}/camera.npy", camera)
np.save(f"{work}/ao.npy", ao)
np.save(f"{work}/ao_tfar.npy", ao_tfar)
for name, rays, tmax in (("camera", camera, np.inf), ("ao", ao, ao_tfar)):
    records = np.empty((len(rays), 8), "<f4")
    records[:, :6], records[:, 6], records[:, 7] = rays, 0, tmax
    records.tofile(f"{work}/{name}.rays")
print(f"{len(camera)} camera rays ({hit.sum()} hits), {len(ao)} AO rays of {ao_tfar:.4g}")
EOF

engines=(reducem)
"$PYTHON" -c 'import open3d' 2>/dev/null && engines+=(open3d) || echo "open3d: not importable, skipped"
"$PYTHON" -c 'import trimesh, embreex' 2>/dev/null && engines+=(trimesh) || echo "trimesh/embreex: not importable, skipped"

results=$WORK/results.jsonl
: >"$results"
for run in $(seq "$RUNS"); do
  for kind in camera ao; do
    flag=(); [[ $kind == ao ]] && flag=(--occluded)
    /usr/bin/time -f '%e %M' -o "$WORK/time" target/release/reducem query "$model" \
      --rays "$WORK/$kind.rays" -o "$WORK/$kind.answers" "${flag[@]}" 2>"$WORK/summary"
    read -r wall peak_kb <"$WORK/time"
    mrays=$(grep -o 'mrays_per_s=[0-9.]*' "$WORK/summary" | cut -d= -f2)
    echo "{\"engine\": \"query\", \"kind\": \"$kind\", \"mrays\": $mrays, \"wall_s\": $wall, \"peak_mb\": $((peak_kb / 1000))}" >>"$results"
  done
  for name in "${engines[@]}"; do
    /usr/bin/time -f '%M' -o "$WORK/time" "$PYTHON" "$engine" "$name" "$mesh" "$model" "$WORK" >"$WORK/figures"
    peak_kb=$(cat "$WORK/time")
    "$PYTHON" -c 'import json,sys; f=json.load(open(sys.argv[1])); f.update(engine=sys.argv[2], peak_mb=int(sys.argv[3])//1000); print(json.dumps(f))' \
      "$WORK/figures" "$name" "$peak_kb" >>"$results"
  done
done

"$PYTHON" - "$results" "$model" "$mesh" "$RUNS" <<'EOF'
import json, os, sys
import numpy as np

rows = [json.loads(line) for line in open(sys.argv[1])]
median = lambda values: float(np.median(values)) if values else float("nan")
pick = lambda engine, key, kind=None: median([r[key] for r in rows if r["engine"] == engine
                                              and (kind is None or r.get("kind") == kind) and key in r])
print(f"model {sys.argv[2]} ({os.path.getsize(sys.argv[2]) / 1e6:.0f} MB), mesh {sys.argv[3]} "
      f"({os.path.getsize(sys.argv[3]) / 1e6:.0f} MB); medians of {sys.argv[4]} runs")
print(f"{'engine':<22}{'camera Mrays/s':>15}{'AO Mrays/s':>12}{'read s':>9}{'build s':>9}"
      f"{'scene MB':>10}{'peak MB':>9}")
print(f"{'reducem query (CLI)':<22}{pick('query', 'mrays', 'camera'):>15.2f}"
      f"{pick('query', 'mrays', 'ao'):>12.2f}{'':>9}{'':>9}{'':>10}"
      f"{pick('query', 'peak_mb', 'camera'):>9.0f}")
names = {"reducem": "reducem (Python)", "open3d": "Open3D RaycastingScene", "trimesh": "trimesh + embreex"}
for engine, label in names.items():
    if any(r["engine"] == engine for r in rows):
        print(f"{label:<22}{pick(engine, 'camera_mrays'):>15.2f}{pick(engine, 'ao_mrays'):>12.2f}"
              f"{pick(engine, 'read_s'):>9.3f}{pick(engine, 'build_s'):>9.3f}"
              f"{pick(engine, 'scene_mb'):>10.0f}{pick(engine, 'peak_mb'):>9.0f}")
for kind, key in (("camera", "camera_mrays"), ("ao", "ao_mrays")):
    cli, binding = pick("query", "mrays", kind), pick("reducem", key)
    print(f"binding overhead on {kind} rays: {100 * (cli / binding - 1):+.1f}% (the whole "
          f"cast_rays/test_occlusions call against the tracing alone of reducem query, "
          f"its summary's seconds, which leave out reading and checking the rays)")
print(f"reducem query end to end (open, read rays, trace, write): camera "
      f"{pick('query', 'wall_s', 'camera'):.3f} s, AO {pick('query', 'wall_s', 'ao'):.3f} s")
EOF

if [[ ${CALLGRIND-} == 1 ]]; then
  "$PYTHON" - "$WORK" "$SIZE" <<'EOF'
import sys
import numpy as np
work, size = sys.argv[1], int(sys.argv[2])
side = min(size, 316)
first = (size - side) // 2
camera = np.load(f"{work}/camera.npy").reshape(size, size, 6)
block = np.ascontiguousarray(camera[first:first + side, first:first + side].reshape(-1, 6))
np.save(f"{work}/block.npy", block)
for name, rays in (("block", block), ("one", block[:1])):
    records = np.empty((len(rays), 8), "<f4")
    records[:, :6], records[:, 6], records[:, 7] = rays, 0, np.inf
    records.tofile(f"{work}/{name}.rays")
EOF
  cat >"$WORK/callgrind.py" <<'EOF'
import sys
import numpy as np
import reducem
scene = reducem.open(sys.argv[1])
rays = np.load(sys.argv[2])
scene.cast_rays(rays[:1])
if sys.argv[3] == "cast":
    scene.cast_rays(rays)
elif sys.argv[3] == "occluded":
    scene.test_occlusions(rays)
EOF
  instructions() {
    RAYON_NUM_THREADS=1 OPENBLAS_NUM_THREADS=1 valgrind --tool=callgrind \
      --callgrind-out-file=/dev/null "$@" 2>&1 | grep -o 'Collected : [0-9]*' | awk '{print $3}'
  }
  rays=$("$PYTHON" -c 'import numpy as np, sys; print(len(np.load(sys.argv[1])))' "$WORK/block.npy")
  query_one=$(instructions target/release/reducem query "$model" --rays "$WORK/one.rays" -o "$WORK/one.answers")
  python_none=$(instructions "$PYTHON" "$WORK/callgrind.py" "$model" "$WORK/block.npy" none)
  for kind in cast occluded; do
    flag=()
    [[ $kind == occluded ]] && flag=(--occluded)
    query=$(instructions target/release/reducem query "$model" --rays "$WORK/block.rays" \
      -o "$WORK/block.answers" "${flag[@]}")
    python=$(instructions "$PYTHON" "$WORK/callgrind.py" "$model" "$WORK/block.npy" "$kind")
    awk -v kind="$kind" -v n="$rays" -v q=$((query - query_one)) -v p=$((python - python_none)) \
      'BEGIN { printf "instructions per ray (%s, %d camera rays, one thread): reducem query %.0f, binding %.0f (%+.1f%%)\n", kind, n, q / n, p / n, 100 * (p / q - 1) }'
  done
fi
