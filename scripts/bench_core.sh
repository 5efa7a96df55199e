#!/usr/bin/env bash
# Core conversion benchmark (issue 2): for each mesh kind and size, generate the mesh once, then
# convert it RUNS times with `pipeline run`, and print bytes/triangle with the section breakdown,
# hierarchy overhead, average strip length, the median conversion time, throughput per core and
# the peak RSS of the median run.
#
# Usage: scripts/bench_core.sh [RUNS] [KIND:TRIANGLES ...]
#   default: 3 runs of scan:1000000 scan:10000000 cad:1000000 cad:10000000
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3}
shift || true
cases=("$@")
[ ${#cases[@]} -gt 0 ] || cases=(scan:1000000 scan:10000000 cad:1000000 cad:10000000)
work=${BENCH_DIR:-/tmp/reducem-bench}
mkdir -p "$work"
cargo build --release --workspace --bins -q
cores=$(nproc)

printf '%-6s %10s %7s %10s %8s %7s %9s %7s %7s %11s %10s\n' kind triangles B/tri strip_data records nodes overhead% avglen conv_s ktri/s/core peakRSS_MB
for case in "${cases[@]}"; do
  kind=${case%%:*}; n=${case##*:}
  ply="$work/$kind-$n.ply"
  [ -f "$ply" ] || ./target/release/pipeline gen "$kind" --triangles "$n" -o "$ply" 2>/dev/null
  cat > "$work/$kind-$n.toml" <<TOML
[input]
path = "$ply"
[output]
path = "$work/$kind-$n.rdm"
[work]
dir = "$work/$kind-$n.work"
TOML
  times=()
  for _ in $(seq "$runs"); do
    rm -rf "$work/$kind-$n.work"
    /usr/bin/time -f '%e %M' -o "$work/time.txt" ./target/release/pipeline run "$work/$kind-$n.toml" 2>/dev/null
    times+=("$(cat "$work/time.txt")")
  done
  median=$(printf '%s\n' "${times[@]}" | sort -n | sed -n "$(( (runs + 1) / 2 ))p")
  seconds=${median% *}; rss_kb=${median#* }
  ./target/release/reducem inspect "$work/$kind-$n.rdm" --json | python3 -c '
import json, sys
s = json.load(sys.stdin); t = s["triangles"]; b = s["bytes_by_section"]
sec, rss, cores, kind = float(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
print("%-6s %10d %7.2f %10.2f %8.2f %7.2f %9.2f %7.2f %7.2f %11.0f %10.0f" % (
    kind, t, s["bytes_per_triangle"], b["strip_data"] / t, b["strip_records"] / t, b["top_nodes"] / t,
    s["hierarchy_overhead_pct"], s["avg_strip_length"], sec, t / sec / cores / 1e3, rss / 1024))
' "$seconds" "$rss_kb" "$cores" "$kind"
done
echo "(strip_data = local vertices, split axes and 1-byte references; strip_data, records, nodes in bytes/triangle; median of $runs runs; conversion = read + Strip-RT + encode + top level + write + verify)"
