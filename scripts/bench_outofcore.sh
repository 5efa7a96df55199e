#!/usr/bin/env bash
# Tracing a model larger than the memory left for the page cache.
#
# A balloon process locks (mlock) all of the available memory but BUDGET GiB, so that the model's
# pages compete for BUDGET GiB (with the process's own memory, the rays, and whatever else runs
# on the machine). For each budget, and unconstrained, it traces the primary and the AO rays of
# frames at each size with `reducem query`, cold (the model's pages dropped from the page cache
# with posix_fadvise(DONTNEED), nothing else is touched) and then warm (RUNS runs, median), and
# prints Mrays/s (tracing alone, as `reducem query` reports it), wall time, major page faults and
# maximum resident set (/usr/bin/time -v), and bytes read from storage (the reaped child's
# /proc/self/io read_bytes).
#
# The balloon never leaves less than 3 GiB unlocked (smaller budgets are refused), stops locking
# early if the machine's available memory shrinks while it locks, dies with this script
# (PR_SET_PDEATHSIG) and is killed by a trap on every exit path.
#
#   scripts/bench_outofcore.sh
#   MODEL=/work/big/scan300m.rdm BUDGETS="4 3" SIZES="512 1024" AO_SAMPLES=4 RUNS=3 scripts/bench_outofcore.sh
#   REDUCEM=/path/to/another/reducem ... compares another build (e.g. one without a paging hint)
set -euo pipefail
cd "$(dirname "$0")/.."

MODEL=${MODEL:-/work/big/scan300m.rdm}
BUDGETS=${BUDGETS:-"4 3"}
SIZES=${SIZES:-"512 1024"}
AO_SAMPLES=${AO_SAMPLES:-4}
RUNS=${RUNS:-3}
RAYS_DIR=${RAYS_DIR:-$(dirname "$MODEL")/rays-$(basename "$MODEL" .rdm)-ao$AO_SAMPLES}
MIN_UNLOCKED_GIB=3

cargo build --release --quiet --bin reducem
cargo build --release --quiet -p reducem-bench --example bench_trace
REDUCEM=${REDUCEM:-target/release/reducem}
WORK=$(mktemp -d)
BALLOON_PID=""

release_balloon() {
    if [ -n "$BALLOON_PID" ]; then
        kill "$BALLOON_PID" 2>/dev/null || true
        wait "$BALLOON_PID" 2>/dev/null || true
        BALLOON_PID=""
    fi
}
trap 'release_balloon; rm -rf "$WORK"' EXIT
trap 'exit 130' INT TERM HUP

# The balloon: locks anonymous memory 256 MiB at a time until only BUDGET GiB stay available,
# reports how much it holds, then keeps the budget while the benchmark runs: it locks more when
# other processes free memory and unlocks when they need it, so the machine's available memory
# stays within a chunk of BUDGET (never below the 3 GiB floor checked before it starts).
cat > "$WORK/balloon.py" <<'EOF'
import ctypes, mmap, signal, sys, time
libc = ctypes.CDLL("libc.so.6", use_errno=True)
libc.prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG: die with the script, whatever kills it
budget = int(float(sys.argv[1]) * 2**30)
chunk = 256 * 2**20
def available():
    for line in open("/proc/meminfo"):
        if line.startswith("MemAvailable:"):
            return int(line.split()[1]) * 1024
held = []
def adjust():
    while available() - chunk > budget:
        block = mmap.mmap(-1, chunk, flags=mmap.MAP_PRIVATE | mmap.MAP_ANONYMOUS)
        view = ctypes.c_char.from_buffer(block)
        address = ctypes.addressof(view)
        del view  # release the export, so that the block can be closed (unmapped) later
        if libc.mlock(ctypes.c_void_p(address), ctypes.c_size_t(chunk)) != 0:
            sys.exit("mlock failed: errno %d (ulimit -l, or run as root)" % ctypes.get_errno())
        held.append(block)
    while held and available() < budget - chunk:
        held.pop().close()
adjust()
print("locked %.1f GiB, %.1f GiB available" % (len(held) * chunk / 2**30, available() / 2**30), flush=True)
while True:
    time.sleep(0.2)
    adjust()
EOF

# One measured run: prints "mrays wall majflt read_bytes maxrss_kib".
cat > "$WORK/measure.py" <<'EOF'
import re, subprocess, sys
def read_bytes():
    for line in open("/proc/self/io"):
        if line.startswith("read_bytes:"):
            return int(line.split()[1])
before = read_bytes()
run = subprocess.run(["/usr/bin/time", "-v"] + sys.argv[1:], capture_output=True, text=True)
read = read_bytes() - before
if run.returncode != 0:
    sys.exit(run.stderr)
def field(name):
    return re.search(re.escape(name) + r": (\S+)", run.stderr).group(1)
wall = field("Elapsed (wall clock) time (h:mm:ss or m:ss)").split(":")
seconds = sum(float(part) * 60 ** i for i, part in enumerate(reversed(wall)))
mrays = re.search(r"mrays_per_s=(\S+)", run.stderr).group(1)
print(mrays, "%.2f" % seconds, field("Major (requiring I/O) page faults"), read,
      field("Maximum resident set size (kbytes)"))
EOF

drop_model_pages() {
    python3 -c "import os,sys; fd=os.open(sys.argv[1], os.O_RDONLY); os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED); os.close(fd)" "$MODEL"
}

# Ray files, written by the tracing benchmark from the model's own primary hits.
for size in $SIZES; do
    if [ ! -f "$RAYS_DIR/$size/ao.rays" ]; then
        target/release/examples/bench_trace --model "$MODEL" --size "$size" \
            --ao-samples "$AO_SAMPLES" --runs 1 --threads 2 --reducem-only \
            --write-rays "$RAYS_DIR/$size" > /dev/null
    fi
done

median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

model_gib=$(awk -v b="$(stat -c %s "$MODEL")" 'BEGIN { printf "%.2f", b / 2^30 }')
echo "model $MODEL ($model_gib GiB), AO $AO_SAMPLES samples per pixel, warm figures the median of $RUNS runs"
printf "%-14s %-11s %9s | %8s %7s %8s %9s | %8s %7s %8s %9s | %9s\n" budget frame rays \
    "cold Mr/s" "wall s" "majflt" "read MiB" "warm Mr/s" "wall s" "majflt" "read MiB" "maxRSS MiB"
for budget in unconstrained $BUDGETS; do
    if [ "$budget" != unconstrained ]; then
        if awk -v b="$budget" -v m="$MIN_UNLOCKED_GIB" 'BEGIN { exit !(b < m) }'; then
            echo "budget $budget GiB refused: at least $MIN_UNLOCKED_GIB GiB stay unlocked" >&2
            continue
        fi
        rm -f "$WORK/balloon.out"
        python3 "$WORK/balloon.py" "$budget" > "$WORK/balloon.out" &
        BALLOON_PID=$!
        until [ -s "$WORK/balloon.out" ] || ! kill -0 "$BALLOON_PID" 2>/dev/null; do sleep 0.5; done
        kill -0 "$BALLOON_PID" 2>/dev/null || { echo "the balloon failed" >&2; exit 1; }
        echo "# budget $budget GiB: balloon $(cat "$WORK/balloon.out")"
    fi
    for size in $SIZES; do
        for kind in primary ao; do
            flag=()
            [ "$kind" = ao ] && flag=(--occluded)
            rays="$RAYS_DIR/$size/$kind.rays"
            count=$(( $(stat -c %s "$rays") / 32 ))
            query=("$REDUCEM" query "$MODEL" --rays "$rays" -o "$WORK/answers" "${flag[@]}")
            drop_model_pages
            read -r c_mrays c_wall c_faults c_read c_rss < <(python3 "$WORK/measure.py" "${query[@]}")
            : > "$WORK/warm"
            for _ in $(seq "$RUNS"); do
                python3 "$WORK/measure.py" "${query[@]}" >> "$WORK/warm"
            done
            w_mrays=$(cut -d' ' -f1 "$WORK/warm" | median)
            w_wall=$(cut -d' ' -f2 "$WORK/warm" | median)
            w_faults=$(cut -d' ' -f3 "$WORK/warm" | median)
            w_read=$(cut -d' ' -f4 "$WORK/warm" | median)
            w_rss=$(cut -d' ' -f5 "$WORK/warm" | median)
            rss=$(( (c_rss > w_rss ? c_rss : w_rss) / 1024 ))
            printf "%-14s %-11s %9d | %8s %7s %8s %9d | %8s %7s %8s %9d | %9d\n" \
                "$budget" "${size}² $kind" "$count" \
                "$c_mrays" "$c_wall" "$c_faults" $(( c_read >> 20 )) \
                "$w_mrays" "$w_wall" "$w_faults" $(( w_read >> 20 )) "$rss"
        done
    done
    release_balloon
done
