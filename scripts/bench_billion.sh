#!/usr/bin/env bash
# A billion triangles on one machine (issue 17, item 4): `pipeline run` of configs/billion.toml
# (a generated scan streamed straight into the chunk stage, no input file), then a rendered
# frame. Prints the time of every stage (from the run's JSON log), peak RSS (/usr/bin/time -v),
# the disk used by the work directory and the output (peak while running and at the end), the
# machine's load during the run, and the frame's trace time and resident memory.
#
# Usage: scripts/bench_billion.sh
#   TRIANGLES=100000000   triangles to generate (default 1000000000, the config's)
#   ENCODING=grid|f32     [vertices] encoding (default grid, the config's)
#   CHUNK_TRIANGLES=N     [chunk] max_triangles (default the pipeline's, 4000000)
#   BENCH_DIR=DIR         where the config, output, work directory and logs go
#                         (default /tmp/reducem-billion)
#   KEEP_WORK=1           keep the work directory (default: removed after the run)
#   RESUME=1              resume a stopped run in its work directory (default: start afresh);
#                         the stages done before are then timed as skipped
#   MIN_FREE_GB=15        stop the run (SIGTERM: it resumes where it stopped) if the file system
#                         of BENCH_DIR has less free space than this
#   SCENES="primary ao16" scenes of configs/scenes/ to render at 1024x1024 (empty: no frame),
#                         each cold (the model's pages dropped with posix_fadvise) then warm
#   RENDER_ONLY=1         only render the output of an earlier run
#
# The run is niced: the machine is shared. Disk at the peak (the end of the write stage): about
# 26 bytes per triangle with grid vertices (work directory 19, output 7.4), about 48 with f32
# vertices (work directory 28, output 19.6); see docs/BENCHMARKS.md, "A billion triangles".
set -euo pipefail
cd "$(dirname "$0")/.."
triangles=${TRIANGLES:-1000000000}
encoding=${ENCODING:-grid}
dir=${BENCH_DIR:-/tmp/reducem-billion}
min_free_gb=${MIN_FREE_GB:-15}
scenes=${SCENES-primary ao16}
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
CARGO_BUILD_JOBS=${CARGO_BUILD_JOBS:-2} cargo build --release -p pipeline -p reducem --bins -q

drop_pages() {
  python3 -c "import os,sys; fd=os.open(sys.argv[1], os.O_RDONLY); os.posix_fadvise(fd, 0, 0, os.POSIX_FADV_DONTNEED); os.close(fd)" "$1"
}

# Renders every scene of $scenes from the output, cold then warm.
render_frames() {
  for scene in $scenes; do
    drop_pages "$output"
    for cache in cold warm; do
      frame="$dir/$name-$scene-$cache"
      /usr/bin/time -v -o "$frame.time" \
        ./target/release/reducem render "$output" --scene "configs/scenes/$scene.toml" \
        -o "$frame.png" --json > "$frame.json"
      python3 - "$scene $cache" "$frame.json" "$frame.time" <<'PY'
import json, re, sys
scene, report, time_file = sys.argv[1:]
r = json.load(open(report))
timing = open(time_file).read()
wall = re.search(r"Elapsed \(wall clock\) time.*: (\S+)", timing).group(1)
rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", timing).group(1))
faults = int(re.search(r"Major \(requiring I/O\) page faults: (\d+)", timing).group(1))
m = r["memory"]
print(f"frame {scene} {r['width']}x{r['height']}: {r['total_rays']} rays traced in {r['trace_seconds']:.2f} s "
      f"({r['mrays_per_second']:.2f} Mrays/s), process wall {wall}, peak RSS {rss_kb / 2**20:.2f} GiB, "
      f"file resident {m['mapped_resident_bytes'] / 2**30:.2f} of {m['file_bytes'] / 2**30:.2f} GiB, "
      f"{faults} major page faults")
PY
    done
  done
}

name="scan-$triangles-$encoding${CHUNK_TRIANGLES:+-chunk$CHUNK_TRIANGLES}"
config="$dir/$name.toml"
output="$dir/$name.rdm"
work="$dir/$name.work"
log="$dir/$name.jsonl"
sed -e "s|^triangles = .*|triangles = $triangles|" \
    -e "s|^encoding = .*|encoding = \"$encoding\"|" \
    -e "s|^path = .*|path = \"$output\"|" \
    -e "s|^dir = .*|dir = \"$work\"|" configs/billion.toml > "$config"
if [ -n "${CHUNK_TRIANGLES:-}" ]; then
  printf '\n[chunk]\nmax_triangles = %s\n' "$CHUNK_TRIANGLES" >> "$config"
fi
if [ "${RENDER_ONLY:-0}" = 1 ]; then
  render_frames
  exit 0
fi
if [ "${RESUME:-0}" != 1 ]; then
  rm -rf "$work" "$output"
fi

# Samples disk use, free space and load every 10 s while the run lasts; stops the run (its own
# child only) if free space falls below the floor.
watch_disk() {
  local run_pid=$1 samples="$dir/$name.disk"
  : > "$samples"
  while kill -0 "$run_pid" 2> /dev/null; do
    local used free load
    used=$( (du -sb "$work" "$output" 2> /dev/null || true) | awk '{s += $1} END {printf "%.0f\n", s}')
    free=$(df -B1 --output=avail "$dir" | tail -1)
    load=$(cut -d' ' -f1 /proc/loadavg)
    echo "$used $free $load" >> "$samples"
    if [ "$free" -lt $((min_free_gb << 30)) ]; then
      echo "bench_billion: less than $min_free_gb GB free, stopping the run" >&2
      pkill -TERM -P "$run_pid" || true
    fi
    sleep 10
  done
}

echo "converting $triangles triangles ($encoding vertices) into $output"
nice -n 10 /usr/bin/time -v -o "$dir/$name.time" \
  ./target/release/pipeline run "$config" --log-format json 2> "$log" &
run_pid=$!
watch_disk "$run_pid" &
watch_pid=$!
status=0
wait "$run_pid" || status=$?
wait "$watch_pid" || true
if [ "$status" -ne 0 ]; then
  tail -3 "$log" >&2
  echo "bench_billion: pipeline run failed with $status; work directory kept: $work" >&2
  exit "$status"
fi
final_work=$(du -sb "$work" | cut -f1)
./target/release/reducem inspect "$output" --json > "$dir/$name.inspect.json"

python3 - "$log" "$dir/$name.time" "$dir/$name.disk" "$dir/$name.inspect.json" "$final_work" <<'PY'
import json, re, sys
log, time_file, disk_file, inspect_file, final_work = sys.argv[1:]
first, end = {}, None
for line in open(log):
    try:
        event = json.loads(line)
    except ValueError:
        continue
    stage = event.get("stage")
    if stage == "run":
        end = event["time"]
    elif stage and stage not in first:
        first[stage] = event["time"]
stages = sorted(first, key=first.get)
print("stage       seconds")
for stage, following in zip(stages, stages[1:] + [None]):
    until = first[following] if following else end
    print(f"{stage:<10} {until - first[stage]:8.1f}")
print(f"{'total':<10} {end - first[stages[0]]:8.1f}")
timing = open(time_file).read()
rss_kb = int(re.search(r"Maximum resident set size \(kbytes\): (\d+)", timing).group(1))
wall = re.search(r"Elapsed \(wall clock\) time.*: (\S+)", timing).group(1)
cpu = re.search(r"Percent of CPU this job got: (\S+)", timing).group(1)
cpu_s = sum(float(re.search(rf"{kind} time \(seconds\): (\S+)", timing).group(1)) for kind in ("User", "System"))
print(f"wall {wall}, CPU {cpu} ({cpu_s:.0f} CPU seconds), peak RSS {rss_kb / 2**20:.2f} GiB")
samples = [line.split() for line in open(disk_file) if line.strip()]
if samples:
    peak = max(float(s[0]) for s in samples)
    least_free = min(float(s[1]) for s in samples)
    load = sum(float(s[2]) for s in samples) / len(samples)
    print(f"disk: peak work directory + output {peak / 1e9:.1f} GB, least free {least_free / 1e9:.1f} GB, "
          f"mean 1-min load {load:.2f} on {len(samples)} samples")
s = json.load(open(inspect_file))
strip_data = s["bytes_by_section"]["strip_data"]
print(f"output {s['file_bytes'] / 1e9:.2f} GB, {s['triangles']} triangles, "
      f"{s['bytes_per_triangle']:.2f} bytes/triangle (strip data {strip_data / s['triangles']:.2f}, "
      f"{strip_data / 2**34:.0%} of the format's 16 GiB); work directory at the end {int(final_work) / 1e9:.1f} GB")
PY

render_frames

if [ "${KEEP_WORK:-0}" != 1 ] && [ -d "$work" ]; then
  ./target/release/pipeline clean "$config"
fi
