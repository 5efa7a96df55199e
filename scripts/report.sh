#!/usr/bin/env bash
# The measured trade-offs report (issue 5) in one command: builds `reducem-bench` with the `report`
# feature (and `embree` when libembree-dev is installed, so that Embree is measured), then writes
# report/REPORT.md with its tables, plots (report/plots/*.svg) and AO images.
#
# Usage: scripts/report.sh [tiny|medium|full]   (default full: about 30 minutes on 2 cores)
# Generated meshes are kept in $REPORT_WORK (default target/report-work) between runs.
set -euo pipefail
cd "$(dirname "$0")/.."
scale=${1:-full}
features=report
if [ -f /usr/include/embree3/rtcore.h ]; then
  features=report,embree
else
  echo "report: libembree-dev not installed; Embree rows will say 'not measured'" >&2
fi
cargo build --release -p reducem-bench --features "$features" -q
nice -n "${REPORT_NICE:-0}" ./target/release/reducem-bench report --scale "$scale" --out report \
  --work "${REPORT_WORK:-target/report-work}"
