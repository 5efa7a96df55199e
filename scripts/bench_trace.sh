#!/usr/bin/env bash
# Tracing benchmark (not a test): ReduceM vs the in-project SAH BVH baseline and, when Debian's
# libembree-dev (Embree 3) is installed, Embree through the `embree` cargo feature, on the same
# rays. Prints Mrays/s for primary rays and 16-sample AO at 1024x1024 on 1 and 2 threads (median
# of 3 runs) and memory, then ReduceM alone on the speed setting (`[strip] max_length =
# FAST_LENGTH`, default 16: shorter strips, more bytes). Meshes and converted files are cached in
# /tmp/reducem-bench.
#
#   scripts/bench_trace.sh                      # scan at 1M and 10M triangles
#   TRIANGLES=1000000 scripts/bench_trace.sh    # one size
#   scripts/bench_trace.sh --runs 5 --size 512  # extra arguments go to the benchmark
set -euo pipefail
cd "$(dirname "$0")/.."
features=()
# (Not `ldconfig -p | grep -q`: grep exits at the first match, ldconfig dies of SIGPIPE, and
# pipefail turns that into "not found".)
if [ -f /usr/include/embree3/rtcore.h ]; then
    features=(--features embree)
else
    echo "libembree-dev not found (apt-get install -y libembree-dev): benchmarking without Embree"
fi
cargo build --release --example bench_trace "${features[@]}"
for triangles in ${TRIANGLES:-1000000 10000000}; do
    cargo run --quiet --release --example bench_trace "${features[@]}" -- \
        --kind scan --triangles "$triangles" "$@"
    cargo run --quiet --release --example bench_trace "${features[@]}" -- \
        --kind scan --triangles "$triangles" --reducem-only \
        --max-strip-length "${FAST_LENGTH:-16}" "$@"
done
