#!/usr/bin/env bash
# Kill-and-resume campaign (issue 4): converts a generated mesh once for reference, then for each
# trial starts from a clean work directory, SIGKILLs `pipeline run` at random moments (several
# times per trial, so kills land in every stage), lets the same command finish, and compares the
# output with the reference byte for byte. The test suite runs a small version of this
# (pipeline/tests/resume.rs); this script runs as many trials as you like on a bigger mesh.
#
# Usage: scripts/kill_resume.sh [TRIALS] [TRIANGLES] [KILLS_PER_TRIAL]   (default 50 2000000 3)
set -euo pipefail
cd "$(dirname "$0")/.."
trials=${1:-50}
triangles=${2:-2000000}
kills=${3:-3}
work=${KILL_DIR:-/tmp/reducem-kill}
mkdir -p "$work"
cargo build --release -p pipeline -q
pipeline=target/release/pipeline
[ -f "$work/input.ply" ] || "$pipeline" gen scan --triangles "$triangles" -o "$work/input.ply" 2>/dev/null

write_config() {
  printf '[input]\npath = "%s"\n[output]\npath = "%s"\n[work]\ndir = "%s"\n[chunk]\nmax_triangles = %d\n' \
    "$work/input.ply" "$work/$1.rdm" "$work/$1.work" $(( triangles / 10 + 1 )) > "$work/$1.toml"
}

write_config reference
rm -rf "$work/reference.work"
start=$(date +%s%N)
"$pipeline" run "$work/reference.toml" --log-format plain 2>/dev/null
full_ms=$(( ($(date +%s%N) - start) / 1000000 ))
echo "reference run: ${full_ms} ms"

write_config trial
failures=0
for trial in $(seq "$trials"); do
  rm -rf "$work/trial.work" "$work/trial.rdm"
  for _ in $(seq "$kills"); do
    "$pipeline" run "$work/trial.toml" --log-format plain 2>/dev/null &
    pid=$!
    sleep "$(awk -v ms="$full_ms" -v r="$RANDOM" 'BEGIN { printf "%.3f", ms * (r / 32768) / 1000 }')"
    kill -KILL "$pid" 2>/dev/null || true
    wait "$pid" 2>/dev/null || true
  done
  "$pipeline" run "$work/trial.toml" --log-format plain 2>/dev/null
  if cmp -s "$work/reference.rdm" "$work/trial.rdm"; then
    echo "trial $trial: identical"
  else
    echo "trial $trial: DIFFERENT"
    failures=$(( failures + 1 ))
  fi
done
echo "kill/resume: $trials trials x $kills kills, $failures different"
[ "$failures" -eq 0 ]
