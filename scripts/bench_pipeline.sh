#!/usr/bin/env bash
# Out-of-core pipeline benchmark (issue 4): generate `scan` meshes of the given sizes, convert
# each with `pipeline run` from a clean work directory, and print wall time per stage, total
# throughput, peak RSS and output bytes/triangle.
#
# Usage: scripts/bench_pipeline.sh [TRIANGLES ...]   (default: 1000000 10000000 100000000 300000000)
#        scripts/bench_pipeline.sh --formats [TRIANGLES [RUNS]]   (default: 10000000 3)
# Needs about 60 bytes of free disk per triangle under $BENCH_DIR (default /tmp/reducem-pipeline).
#
# --formats converts the same `scan` mesh as binary PLY, binary STL, float GLB, quantized GLB
# (KHR_mesh_quantization) and zstd-compressed PLY RUNS times each and prints the medians of the total time and of the chunk stage (the one that
# reads the input), the chunk stage against PLY's, and the largest peak RSS.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ "${1:-}" = "--formats" ]; then
  n=${2:-10000000}
  runs=${3:-3}
  work=${BENCH_DIR:-/tmp/reducem-pipeline}
  mkdir -p "$work"
  cargo build --release -p pipeline --bin pipeline -q
  ./target/release/pipeline gen scan --triangles "$n" -o "$work/formats-$n.ply" 2>/dev/null
  ./target/release/pipeline gen scan --triangles "$n" -o "$work/formats-$n.stl" 2>/dev/null
  ./target/release/pipeline gen scan --triangles "$n" -o "$work/formats-$n.glb" 2>/dev/null
  ./target/release/pipeline gen scan --triangles "$n" -o "$work/formats-$n-quantized.glb" \
    --quantized 2>/dev/null
  zstd -q -f -3 "$work/formats-$n.ply" -o "$work/formats-$n.ply.zst"
  for input in "$work/formats-$n.ply" "$work/formats-$n.stl" "$work/formats-$n.glb" \
    "$work/formats-$n-quantized.glb" "$work/formats-$n.ply.zst"; do
    for run in $(seq "$runs"); do
      rm -rf "$work/formats.work" "$work/formats.rdm"
      printf '[input]\npath = "%s"\n[output]\npath = "%s"\n[work]\ndir = "%s"\n' \
        "$input" "$work/formats.rdm" "$work/formats.work" > "$work/formats.toml"
      /usr/bin/time -f '%e %M' -o "$work/time.txt" \
        ./target/release/pipeline run "$work/formats.toml" --log-format json 2> "$work/formats.jsonl"
      read -r total rss_kb < "$work/time.txt"
      chunk=$(python3 -c 'import json,sys
for line in open(sys.argv[1]):
    try: e = json.loads(line)
    except ValueError: continue
    if e.get("event") == "done" and e.get("stage") == "chunk": print(e["elapsed_s"])' "$work/formats.jsonl")
      echo "$(basename "$input") $total $chunk $rss_kb $(stat -c %s "$input")"
    done
  done > "$work/formats-$n.txt"
  rm -rf "$work/formats.work" "$work/formats.rdm" "$work/formats-$n".ply* "$work/formats-$n.stl" \
    "$work/formats-$n"*.glb
  python3 - "$n" "$work/formats-$n.txt" <<'PY'
import statistics, sys
n, results = sys.argv[1:]
rows = {}
for line in open(results):
    name, total, chunk, rss_kb, size = line.split()
    rows.setdefault(name, []).append((float(total), float(chunk), int(rss_kb), int(size)))
ply_chunk = statistics.median(c for _, c, _, _ in rows[f"formats-{n}.ply"])
print("%-24s %10s %9s %9s %13s %11s %5s" % ("input", "input_MB", "total_s", "chunk_s", "chunk_vs_PLY", "peakRSS_MB", "runs"))
for name, values in rows.items():
    chunk = statistics.median(v[1] for v in values)
    print("%-24s %10.0f %9.1f %9.1f %13.2f %11.0f %5d" % (
        name, values[0][3] / 1e6, statistics.median(v[0] for v in values), chunk,
        chunk / ply_chunk, max(v[2] for v in values) / 1024, len(values)))
PY
  exit 0
fi
sizes=("$@")
[ ${#sizes[@]} -gt 0 ] || sizes=(1000000 10000000 100000000 300000000)
work=${BENCH_DIR:-/tmp/reducem-pipeline}
mkdir -p "$work"
cargo build --release --workspace --bins -q

printf '%11s %8s %8s %8s %8s %8s %8s %9s %10s %9s %7s\n' triangles gen_s chunk_s strip_s merge_s hier_s write_s total_s Mtri/s peakRSS_MB B/tri
for n in "${sizes[@]}"; do
  ply="$work/scan-$n.ply"
  gen_s=cached
  if [ ! -f "$ply" ]; then
    start=$(date +%s.%N)
    ./target/release/pipeline gen scan --triangles "$n" -o "$ply" 2>/dev/null
    gen_s=$(echo "$(date +%s.%N) - $start" | bc)
  fi
  rm -rf "$work/scan-$n.work" "$work/scan-$n.rdm"
  printf '[input]\npath = "%s"\n[output]\npath = "%s"\n[work]\ndir = "%s"\n' \
    "$ply" "$work/scan-$n.rdm" "$work/scan-$n.work" > "$work/scan-$n.toml"
  /usr/bin/time -f '%e %M' -o "$work/time.txt" \
    ./target/release/pipeline run "$work/scan-$n.toml" --log-format json 2> "$work/log-$n.jsonl"
  read -r total rss_kb < "$work/time.txt"
  ./target/release/reducem inspect "$work/scan-$n.rdm" --json > "$work/inspect-$n.json"
  python3 - "$n" "$gen_s" "$total" "$rss_kb" "$work/log-$n.jsonl" "$work/inspect-$n.json" <<'PY'
import json, sys
n, gen_s, total, rss_kb, log, inspect = sys.argv[1:]
stage = {}
for line in open(log):
    try:
        event = json.loads(line)
    except ValueError:
        continue
    if event.get("event") == "done" and "elapsed_s" in event:
        stage[event["stage"]] = event["elapsed_s"]
s = json.load(open(inspect))
g = gen_s if gen_s == "cached" else "%.1f" % float(gen_s)
print("%11d %8s %8.1f %8.1f %8.1f %8.1f %8.1f %9.1f %10.2f %9.0f %7.2f" % (
    int(n), g, stage.get("chunk", 0), stage.get("strip", 0), stage.get("merge", 0),
    stage.get("hierarchy", 0), stage.get("write", 0), float(total), s["triangles"] / float(total) / 1e6,
    int(rss_kb) / 1024, s["bytes_per_triangle"]))
PY
done
