#!/usr/bin/env bash
# Tracing benchmark (not a test): ReduceM vs the in-project SAH BVH baseline and, when Debian's
# libembree-dev (Embree 3) is installed, Embree through the `embree` cargo feature, on the same
# rays. Meshes, converted files and ray files are cached in /tmp/reducem-bench.
#
# Per model size it prints:
#   * trace only: Mrays/s for primary rays (1024x1024 pixels, 2x2 camera rays each: issue 33's
#     workload; ANTIALIASING=1 for one per pixel) and 16 AO rays per hit on 1 and 2 threads
#     (median of 3 runs), ReduceM once per tracer kernel this CPU runs (sse2, avx2), the
#     baseline and Embree, and memory; the default conversion settings (the pipeline's);
#   * the same for ReduceM alone on the speed setting (`[strip] max_length = FAST_LENGTH`,
#     default 16: shorter strips, more bytes);
#   * whole process: `reducem query` on the same rays as ray files (open, read, trace, write),
#     median wall time of WHOLE_RUNS (default 5) alternating runs per thread count, as Mrays/s,
#     with the median CPU time and the load average: compare with Embree's trace-only figure
#     above, which is what a batch job would pay on top of reading and building. Each run writes
#     a new output (the previous run's is removed first, untimed): replacing an existing file
#     adds the file system's freeing of its blocks, which is not the query's work;
#   * paired (with Embree): `reducem query` and Embree's batch job (`bench/examples/embree_job.rs`,
#     its trace phase: a batch job's counterpart of Embree's trace-only figure above) run back to
#     back on the same ray file, PAIRED_RUNS (default 5) pairs per ray kind on 2 threads; the
#     median of each and the median of the pairs' ratios, which a shared machine's drift between
#     the sections above does not skew (both runs of a pair see the same load);
#   * with CALLGRIND=1: instructions per AO ray (callgrind, the first 100k AO rays, 1 thread,
#     per kernel; the tracer's inclusive count divided by the rays).
#
#   scripts/bench_trace.sh                      # scan at 1M and 10M triangles
#   TRIANGLES=1000000 scripts/bench_trace.sh    # one size
#   scripts/bench_trace.sh --runs 5 --size 512  # extra arguments go to the trace-only benchmark
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
cargo build --release -p reducem-bench --example bench_trace "${features[@]}"
cargo build --release --bin reducem
if [ ${#features[@]} -gt 0 ]; then
    cargo build --release -p reducem-bench --example embree_job "${features[@]}"
fi
bench=target/release/examples/bench_trace
reducem=target/release/reducem
dir=/tmp/reducem-bench
mkdir -p "$dir"

# One run of the command: "WALL CPU" seconds (CPU = user + system, which the other jobs of a
# shared machine disturb less than the wall time).
timed_run() {
    local TIMEFORMAT='%R %U %S' times
    times=$({ time "$@" > /dev/null 2>&1; } 2>&1)
    awk '{ print $1, $2 + $3 }' <<< "$times"
}

# The median of the numbers on stdin.
median() {
    sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'
}

# `reducem query` on the ray files of `rays_dir` against `model`, per thread count: WHOLE_RUNS
# (default 5) runs of each ray kind, primary and AO alternating, median wall and CPU seconds,
# and the load average before and after (the machine may be shared).
whole_process() {
    local model=$1 rays_dir=$2 runs=${WHOLE_RUNS:-5}
    local primary_rays ao_rays
    primary_rays=$(($(stat -c %s "$rays_dir/primary.rays") / 32))
    ao_rays=$(($(stat -c %s "$rays_dir/ao.rays") / 32))
    for threads in 1 2; do
        local load_before primary=() ao=()
        load_before=$(cut -d' ' -f1 /proc/loadavg)
        for _ in $(seq "$runs"); do
            rm -f "$rays_dir/primary.hits" "$rays_dir/ao.occluded"
            primary+=("$(RAYON_NUM_THREADS=$threads timed_run "$reducem" query "$model" \
                --rays "$rays_dir/primary.rays" -o "$rays_dir/primary.hits")")
            ao+=("$(RAYON_NUM_THREADS=$threads timed_run "$reducem" query "$model" \
                --rays "$rays_dir/ao.rays" -o "$rays_dir/ao.occluded" --occluded)")
        done
        local p pc a ac
        p=$(printf '%s\n' "${primary[@]}" | cut -d' ' -f1 | median)
        pc=$(printf '%s\n' "${primary[@]}" | cut -d' ' -f2 | median)
        a=$(printf '%s\n' "${ao[@]}" | cut -d' ' -f1 | median)
        ac=$(printf '%s\n' "${ao[@]}" | cut -d' ' -f2 | median)
        awk -v t="$threads" -v pr="$primary_rays" -v p="$p" -v pc="$pc" -v ar="$ao_rays" \
            -v a="$a" -v ac="$ac" -v runs="$runs" -v l0="$load_before" \
            -v l1="$(cut -d' ' -f1 /proc/loadavg)" \
            'BEGIN { printf "  reducem query (whole process) %s thread(s): primary %7.2f Mrays/s (%.3f s, CPU %.3f s), AO %7.2f Mrays/s (%.3f s, CPU %.3f s); median of %s, load %s -> %s\n", t, pr / p / 1e6, p, pc, ar / a / 1e6, a, ac, runs, l0, l1 }'
    done
}

# `reducem query` on `model` and Embree's job on `mesh`, back to back, PAIRED_RUNS (default 5)
# pairs per ray kind on 2 threads: median whole-process seconds, median Embree trace seconds
# (its job's `trace=` phase) and the median of the pairs' ratios, Embree's trace time over the
# whole process's (the whole process's throughput as a fraction of Embree's).
paired() {
    local model=$1 mesh=$2 rays_dir=$3 runs=${PAIRED_RUNS:-5}
    local embree=target/release/examples/embree_job out="$rays_dir/paired.out"
    for kind in primary ao; do
        local rays="$rays_dir/$kind.rays" flags=() whole=() traced=() ratios=()
        [[ $kind == ao ]] && flags=(--occluded)
        for _ in $(seq "$runs"); do
            rm -f "$out"
            local seconds embree_seconds
            seconds=$(RAYON_NUM_THREADS=2 timed_run "$reducem" query "$model" --rays "$rays" \
                -o "$out" "${flags[@]}" | cut -d' ' -f1)
            rm -f "$out"
            embree_seconds=$(RAYON_NUM_THREADS=2 "$embree" "$mesh" --rays "$rays" -o "$out" \
                "${flags[@]}" 2>&1 | sed -n 's/.* trace=\([0-9.]*\) .*/\1/p')
            whole+=("$seconds")
            traced+=("$embree_seconds")
            ratios+=("$(awk -v w="$seconds" -v e="$embree_seconds" 'BEGIN { printf "%.2f", e / w }')")
        done
        rm -f "$out"
        awk -v kind="$kind" -v runs="$runs" -v w="$(printf '%s\n' "${whole[@]}" | median)" \
            -v e="$(printf '%s\n' "${traced[@]}" | median)" \
            -v r="$(printf '%s\n' "${ratios[@]}" | median)" -v all="${ratios[*]}" \
            'BEGIN { printf "  paired, 2 threads, %s: reducem query (whole process) %.3f s, Embree 3 trace %.3f s, whole / Embree %.2fx (median of %s pairs: %s)\n", kind, w, e, r, runs, all }'
    done
}

# Instructions per AO ray under callgrind, per kernel.
instructions_per_ao_ray() {
    local model=$1 rays_dir=$2
    head -c 3200000 "$rays_dir/ao.rays" > "$rays_dir/ao-100k.rays"
    for kernel in sse2 avx2; do
        local out="$rays_dir/callgrind.$kernel"
        if ! REDUCEM_KERNEL=$kernel RAYON_NUM_THREADS=1 valgrind --tool=callgrind \
            --callgrind-out-file="$out" "$reducem" query "$model" --rays "$rays_dir/ao-100k.rays" \
            -o "$rays_dir/ao-100k.occluded" --occluded > /dev/null 2>&1; then
            echo "  $kernel: not run (unsupported here, or valgrind missing)"
            continue
        fi
        local traced
        traced=$(callgrind_annotate --inclusive=yes "$out" | grep 'Tracer::occluded_chunk \[' |
            awk '{gsub(",", "", $1); print $1}')
        echo "  instructions per AO ray ($kernel, callgrind, 100k rays): $((traced / 100000))"
    done
}

# Camera rays per pixel, ANTIALIASING² (default 2: issue 33's 1024² x 4 camera rays).
antialiasing=${ANTIALIASING:-2}
for triangles in ${TRIANGLES:-1000000 10000000}; do
    rays_dir="$dir/rays-scan-$triangles-aa$antialiasing"
    log="$dir/bench-scan-$triangles-aa$antialiasing.log"
    "$bench" --kind scan --triangles "$triangles" --antialiasing "$antialiasing" \
        --write-rays "$rays_dir" "$@" | tee "$log"
    "$bench" --kind scan --triangles "$triangles" --antialiasing "$antialiasing" --reducem-only \
        --max-strip-length "${FAST_LENGTH:-16}" "$@"
    model=$(sed -n 's/^  model: //p' "$log")
    whole_process "$model" "$rays_dir"
    if [ ${#features[@]} -gt 0 ]; then
        paired "$model" "$dir/scan-$triangles.ply" "$rays_dir"
    fi
    if [[ ${CALLGRIND-} == 1 ]]; then
        instructions_per_ao_ray "$model" "$rays_dir"
    fi
done
