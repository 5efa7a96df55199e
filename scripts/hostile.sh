#!/usr/bin/env bash
# Hostile-input campaigns beyond the default test suite (not a test run for CI):
#  1. the escape campaign: REDUCEM_ESCAPE_RAYS (default 10 million) rays from inside closed
#     spheres at scales 1e-6..1e6 and offsets up to 1e6, aimed at every vertex and edge midpoint;
#  2. the corruption campaign under valgrind memcheck: CORRUPTIONS (default 3000) bit flips,
#     truncations and section swaps of the ReduceM seeds, opened and traced, with any invalid
#     read or write reported as an error.
#
#   scripts/hostile.sh
#   REDUCEM_ESCAPE_RAYS=1000000 CORRUPTIONS=300 scripts/hostile.sh
set -euo pipefail
cd "$(dirname "$0")/.."
REDUCEM_ESCAPE_RAYS=${REDUCEM_ESCAPE_RAYS:-10000000} nice -n 19 \
    cargo test --test trace_extreme -- --ignored escape_campaign --nocapture
cargo build --release -p reducem-fuzz
nice -n 19 valgrind --error-exitcode=99 --quiet \
    target/release/reducem-fuzz run reducem --corruptions --cases "${CORRUPTIONS:-3000}" \
    --case-timeout-seconds 600
