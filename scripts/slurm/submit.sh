#!/usr/bin/env bash
# Submits a whole `pipeline` conversion to Slurm as three dependent jobs, so the strip stage (the
# expensive one) runs as a job array spread over the cluster:
#   chunk   one job:                      pipeline run CONFIG --stage chunk
#   strip   array of SHARDS tasks:        pipeline run CONFIG --stage strip --shard I/SHARDS
#           after the chunk job succeeded
#   finish  one job, merge → hierarchy → write, after every strip task succeeded (cancelled
#           instead if one failed)
# Every job runs scripts/slurm/stages.sbatch, which forwards Slurm's warning signal to the
# pipeline so a job near its time limit stops cleanly (exit 75); running this script again
# resumes where the jobs stopped, skipping finished work. The work directory (see CONFIG) must
# be on a filesystem shared by all nodes, with working flock (README.md, "Cluster use").
#
# Usage: submit.sh CONFIG [SHARDS]      (SHARDS defaults to 4)
# Environment:
#   PIPELINE           pipeline binary, as seen from the nodes (default: `pipeline` on PATH,
#                      else target/release/pipeline of this checkout)
#   PARTITION          sbatch --partition (default: the cluster's default partition)
#   TIME_LIMIT         sbatch --time of each job, e.g. 4:00:00 (default: the partition's)
#   SIGNAL_LEAD        seconds before the time limit to send SIGUSR1 (default 120)
#   LOG_DIR            where the jobs' output files go (default: the current directory)
#   JOB_NAME           prefix of the job names (default reducem)
#   EXTRA_SBATCH_OPTS  more sbatch options for every job, split on spaces, e.g. "--cpus-per-task=8"
# Prints one line per job: `chunk ID`, `strip ID`, `finish ID`.
set -euo pipefail

here=$(cd "$(dirname "$0")" && pwd)

usage() {
    sed -n 's/^# \{0,1\}//; /^Usage:/,/^Prints/p' "$0" >&2
    exit 64
}

default_pipeline() {
    if command -v pipeline >/dev/null; then
        command -v pipeline
    else
        echo "$here/../../target/release/pipeline"
    fi
}

# sbatch options shared by every job.
common_options() {
    local options=(--parsable --signal="B:USR1@${SIGNAL_LEAD:-120}")
    [[ -n ${PARTITION-} ]] && options+=(--partition="$PARTITION")
    [[ -n ${TIME_LIMIT-} ]] && options+=(--time="$TIME_LIMIT")
    # shellcheck disable=SC2206 # split on purpose: a list of options
    [[ -n ${EXTRA_SBATCH_OPTS-} ]] && options+=($EXTRA_SBATCH_OPTS)
    printf '%s\n' "${options[@]}"
}

# submit NAME [SBATCH_OPTION...] -- [STAGES_SBATCH_ARGUMENT...]: prints the job id.
submit() {
    local name=$1
    shift
    local sbatch_options=()
    while [[ $1 != -- ]]; do
        sbatch_options+=("$1")
        shift
    done
    shift
    local job_id
    job_id=$(sbatch "${common[@]}" --job-name="$job_name-$name" "${sbatch_options[@]}" \
        "$here/stages.sbatch" "$@")
    echo "${job_id%%;*}" # --parsable prints "ID" or "ID;CLUSTER"
}

(($# >= 1 && $# <= 2)) || usage
[[ -f $1 ]] || { echo "submit.sh: no config file $1" >&2; exit 66; }
config=$(realpath "$1")
shards=${2:-4}
[[ $shards =~ ^[1-9][0-9]*$ ]] || { echo "submit.sh: SHARDS must be a positive integer, not $shards" >&2; exit 64; }
pipeline=$(realpath -m "${PIPELINE:-$(default_pipeline)}")
[[ -x $pipeline ]] || { echo "submit.sh: pipeline binary $pipeline is not executable" >&2; exit 66; }
mkdir -p "${LOG_DIR:-.}"
log_dir=$(realpath "${LOG_DIR:-.}")
job_name=${JOB_NAME:-reducem}
mapfile -t common < <(common_options)

chunk=$(submit chunk --output="$log_dir/$job_name-chunk-%j.out" \
    -- "$pipeline" "$config" chunk)
echo "chunk $chunk"
strip=$(submit strip --output="$log_dir/$job_name-strip-%A_%a.out" \
    --array="0-$((shards - 1))" --dependency="afterok:$chunk" \
    -- --shards "$shards" "$pipeline" "$config" strip)
echo "strip $strip"
finish=$(submit finish --output="$log_dir/$job_name-finish-%j.out" \
    --dependency="afterok:$strip" --kill-on-invalid-dep=yes \
    -- "$pipeline" "$config" merge hierarchy write)
echo "finish $finish"
