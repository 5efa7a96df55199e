#!/usr/bin/env bash
# Batch-job benchmark (not a test): the whole wall time of answering a ray file from a cold
# start, `reducem query` on a converted model (open + trace + write) against Embree 3 on the
# mesh (read the PLY + build + trace + write, `bench/examples/embree_job.rs`), for jobs of 1, 1k,
# 1M and 10M rays, and the ray count where the two take the same time. Needs libembree-dev and
# root (to drop the page cache before each cold run: `echo 3 > /proc/sys/vm/drop_caches`).
#
#   scripts/bench_jobs.sh MODEL.ply MODEL.rdm RAYS        # RAYS: a ray file of at least 1M rays
#   RUNS=3 THREADS=2 scripts/bench_jobs.sh ...            # runs per figure (median), threads
#
# The rays of a job are the first N rays from the middle of RAYS (the 10M job repeats the 1M
# rays ten times). Prints per job and engine: median wall seconds (cold), peak RSS, and for
# the largest job the trace rate that sets the break-even point.
set -euo pipefail
cd "$(dirname "$0")/.."
if [ $# -ne 3 ]; then
    echo "usage: scripts/bench_jobs.sh MODEL.ply MODEL.rdm RAYS" >&2
    exit 64
fi
mesh=$1 model=$2 rays=$3
runs=${RUNS:-3}
export RAYON_NUM_THREADS=${THREADS:-2}
cargo build --release --bin reducem
cargo build --release -p reducem-bench --features embree --example embree_job
reducem=target/release/reducem
embree=target/release/examples/embree_job
work=$(mktemp -d /tmp/reducem-jobs.XXXXXX)
trap 'rm -rf "$work"' EXIT

# Job ray files: N rays from the middle of the 1M rays.
middle=$(($(stat -c %s "$rays") / 32 / 2))
dd if="$rays" of="$work/1.rays" bs=32 skip="$middle" count=1 status=none
dd if="$rays" of="$work/1k.rays" bs=32 skip="$middle" count=1000 status=none
head -c $((1048576 * 32)) "$rays" > "$work/1M.rays"
for _ in 1 2 3 4 5 6 7 8 9 10; do cat "$work/1M.rays"; done > "$work/10M.rays"

cold() {
    sync
    echo 3 > /proc/sys/vm/drop_caches
}

# Median wall seconds and peak RSS (KiB) of `runs` cold runs of the command.
measure() {
    local results=()
    for _ in $(seq "$runs"); do
        cold
        results+=("$(/usr/bin/time -f '%e %M' "$@" 2>&1 >/dev/null | tail -1)")
    done
    printf '%s\n' "${results[@]}" | sort -g | sed -n "$(((runs + 1) / 2))p"
}

echo "mesh $mesh ($(du -h "$mesh" | cut -f1)), model $model ($(du -h "$model" | cut -f1)), $RAYON_NUM_THREADS thread(s), median of $runs cold runs"
printf '%-6s %-8s %10s %12s\n' job engine seconds peak_MiB
declare -A seconds
for job in 1 1k 1M 10M; do
    read -r r_s r_kb < <(measure "$reducem" query "$model" --rays "$work/$job.rays" -o "$work/out.hits")
    read -r e_s e_kb < <(measure "$embree" "$mesh" --rays "$work/$job.rays" -o "$work/out.hits")
    seconds[$job,reducem]=$r_s
    seconds[$job,embree]=$e_s
    printf '%-6s %-8s %10.2f %12.0f\n' "$job" reducem "$r_s" "$((r_kb / 1024))"
    printf '%-6s %-8s %10.2f %12.0f\n' "$job" embree "$e_s" "$((e_kb / 1024))"
done
# Each engine's job time as setup + rays / rate, from the 1-ray and 10M-ray jobs.
awk -v r1="${seconds[1,reducem]}" -v r10="${seconds[10M,reducem]}" \
    -v e1="${seconds[1,embree]}" -v e10="${seconds[10M,embree]}" 'BEGIN {
    n = 10485760
    rr = (r10 - r1) / n; er = (e10 - e1) / n
    # Cold runs of a big model vary by seconds: a setup slower than the whole 10M job says the
    # rays cost less than that noise, and they are taken as free.
    if (er < 0) er = 0
    printf "per ray: reducem %.3f us, embree %.3f us; setup: reducem %.2f s, embree %.2f s\n", rr * 1e6, er * 1e6, r1, e1
    if (rr > er) printf "break-even: %.0f rays (Embree is faster beyond)\n", (e1 - r1) / (rr - er)
    else print "break-even: none (ReduceM is faster at every job size)"
}'
