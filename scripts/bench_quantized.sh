#!/usr/bin/env bash
# Vertex precision benchmark (issue 8; not a test): converts one `scan` mesh lossless and on
# grids of 16, 20 and 24 bits with `pipeline run`, then prints per encoding the file's bytes per
# triangle, the position error (`reducem inspect --json`: max and RMS, absolute and relative to
# the bounding-box diagonal) and ReduceM's tracing speed on 1 thread (examples/bench_trace:
# 1024x1024 primary rays and 16 AO rays per hit, median of 3 runs, packets). On a shared
# machine one measurement can be off by a quarter, so the encodings are traced in PASSES
# interleaved passes (default 3) and the table shows each one's best pass.
#
#   scripts/bench_quantized.sh                         # scan at 10M triangles
#   TRIANGLES=1000000 scripts/bench_quantized.sh       # another size
#   BITS="12 16 20 24" PASSES=1 scripts/bench_quantized.sh
#   EXTRA_TOML=$'[strip]\nleaf_windows = 2' ...      # appended to every job's config
#
# The input PLY is shared with the other benchmarks in $BENCH_DIR (default /tmp/reducem-bench);
# converted files and work directories go to $BENCH_DIR/quantized.
set -euo pipefail
cd "$(dirname "$0")/.."
triangles=${TRIANGLES:-10000000}
bits_list=${BITS:-16 20 24}
passes=${PASSES:-3}
dir=${BENCH_DIR:-/tmp/reducem-bench}
work="$dir/quantized"
mkdir -p "$work"
cargo build --release --workspace --bins -q
cargo build --release -p reducem-bench --example bench_trace -q
ply="$dir/scan-$triangles.ply"
[ -f "$ply" ] || ./target/release/pipeline gen scan --triangles "$triangles" -o "$ply" 2>/dev/null

# One work directory for every encoding: the chunk stage runs once, the others rerun. It starts
# clean, so that no file of an earlier build is taken as fresh.
rm -rf "$work/scan-$triangles.work"
convert() {
  local name=$1 vertices=$2
  cat > "$work/$name.toml" <<TOML
[input]
path = "$ply"
[output]
path = "$work/scan-$triangles-$name.rdm"
[work]
dir = "$work/scan-$triangles.work"
[vertices]
$vertices
${EXTRA_TOML:-}
TOML
  ./target/release/pipeline run "$work/$name.toml" --log-format plain 2>/dev/null
}

names=(lossless)
convert lossless 'encoding = "f32"'
for bits in $bits_list; do
  names+=("grid$bits")
  convert "grid$bits" "encoding = \"grid\"
grid_bits = $bits"
done

speeds="$work/speeds.txt"
: > "$speeds"
for _ in $(seq "$passes"); do
  for name in "${names[@]}"; do
    line=$(./target/release/examples/bench_trace --model "$work/scan-$triangles-$name.rdm" \
      --kind scan --triangles "$triangles" --dir "$dir" --threads 1 --runs 3 | grep 'reducem (packets)')
    echo "$name $line" >> "$speeds"
  done
done

python3 - "$work" "$triangles" "$speeds" "${names[@]}" <<'PY'
import json, re, subprocess, sys
work, triangles, speeds, names = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
best = {}
for line in open(speeds):
    name, rest = line.split(" ", 1)
    primary, ao = map(float, re.findall(r"(?:primary|AO)\s+([0-9.]+) Mrays/s", rest))
    p, a = best.get(name, (0.0, 0.0))
    best[name] = (max(p, primary), max(a, ao))
print("%-8s %5s %7s %10s %10s %10s %10s %9s %8s" % (
    "encoding", "bits", "B/tri", "max_err", "rms_err", "max_rel", "rms_rel", "primary", "AO"))
for name in names:
    path = "%s/scan-%s-%s.rdm" % (work, triangles, name)
    s = json.loads(subprocess.check_output(["./target/release/reducem", "inspect", path, "--json"]))
    bits = str(s["grid_bits"]) if s["grid_bits"] else "-"
    primary, ao = best[name]
    print("%-8s %5s %7.2f %10.3e %10.3e %10.3e %10.3e %9.2f %8.2f" % (
        s["vertex_encoding"], bits, s["bytes_per_triangle"], s["position_error_max"],
        s["position_error_rms"], s["position_error_max_relative"],
        s["position_error_rms_relative"], primary, ao))
PY
echo "(scan, $triangles triangles; errors in model units and relative to the bounds' diagonal; primary and AO in Mrays/s on 1 thread, 1024x1024 primary rays, 16 AO rays per hit, median of 3 runs, best of $passes passes)"
