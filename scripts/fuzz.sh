#!/usr/bin/env bash
# Fuzz campaign (not a test): every target of the stable mutation fuzzer (reducem-fuzz) for
# SECONDS each, one after the other, at the lowest CPU priority and on one thread, then the
# ReduceM corruption campaign (bit flips, truncations, section swaps) for SECONDS more. Prints
# executions per target; findings go to fuzz/crashes/ and the exit status is non-zero.
#
#   scripts/fuzz.sh            # 1800 s (30 minutes) per target: 2.5 hours in all
#   scripts/fuzz.sh 60         # a one-minute smoke run per target
#   SEED=7 scripts/fuzz.sh     # another mutation sequence
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-1800}
cargo build --release -p reducem-fuzz
status=0
nice -n 19 target/release/reducem-fuzz run all --seconds "$seconds" --seed "${SEED:-1}" || status=$?
nice -n 19 target/release/reducem-fuzz run reducem --corruptions --seconds "$seconds" \
    --seed "${SEED:-1}" || status=$?
exit "$status"
