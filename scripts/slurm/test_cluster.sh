#!/usr/bin/env bash
# End-to-end test of scripts/slurm/submit.sh on a real, throwaway Slurm cluster: one node on
# localhost, with munged, slurmctld and slurmd run as root from a temporary directory (their own
# key, socket, config, state and logs; nothing under /etc is changed). It converts a small
# generated mesh with 4 strip shards and checks that the file is byte-identical to a
# single-machine `pipeline run` of the same configuration, then prints both wall times. Then it
# stops a strip task with SIGUSR1 (as Slurm does before a time limit), resubmits, and checks
# that the resubmission did only the rest and wrote the same file.
# It stops exactly the daemons it started (and cancels its jobs), also when it fails.
#
# Usage (as root, on Debian or Ubuntu; installs slurmctld slurmd munge slurm-client with apt):
#   scripts/slurm/test_cluster.sh
# Environment: SLURM_TEST_TIMEOUT  seconds to wait for the jobs (default 900)
# Exit status 0 only if everything passed; the last line says PASSED or FAILED.
set -euo pipefail

repo=$(cd "$(dirname "$0")/../.." && pwd)
shards=4
triangles=200000
chunk_triangles=2000 # about 100 chunks of the 200k-triangle mesh
# The stop-and-resume test needs a strip task that is still working when the signal comes (it is
# sent once the task logs its plan, polled every 0.5 s): a single-CPU release build strips the
# 200k mesh in about 0.4 s, so that test converts a mesh ten times larger, about 4 s of work.
resume_triangles=2000000
resume_chunk_triangles=20000
min_chunks=8
controller_port=16817 # not Slurm's default ports, so a real cluster on this host is untouched
node_port=16818
timeout=${SLURM_TEST_TIMEOUT:-900}

tmp=
daemon_pids=()
job_ids=()   # every job submitted, for cleanup
submitted=() # chunk, strip and finish job of the latest submission
chunks=
passed=

say() { echo "slurm test: $*"; }
fail() {
    say "$*" >&2
    exit 1
}

# Installs the Debian packages that are missing (none: no network needed).
install_packages() {
    local package missing=()
    for package in slurmctld slurmd munge slurm-client; do
        dpkg-query -W -f='${Status}' "$package" 2>/dev/null | grep -q 'install ok installed' ||
            missing+=("$package")
    done
    if ((${#missing[@]})); then
        say "installing ${missing[*]}"
        apt-get update -q
        DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${missing[@]}"
    fi
}

# start NAME COMMAND...: runs a daemon in the foreground of a background job, logging to
# log/NAME.log.
start() {
    local name=$1
    shift
    "$@" >"$tmp/log/$name.log" 2>&1 &
    daemon_pids+=($!)
    say "started $name (pid $!)"
}

# wait_until SECONDS COMMAND...: polls COMMAND until it succeeds; fails after SECONDS.
wait_until() {
    local deadline=$((SECONDS + $1))
    shift
    until "$@" >/dev/null 2>&1; do
        ((SECONDS < deadline)) || return 1
        sleep 0.5
    done
}

# munged insists on a private key (owned by its user, mode 0400, in a directory others cannot
# write) and on a socket directory everyone may enter.
start_munge() {
    mkdir -m 0700 "$tmp/munge"
    mkdir -m 0755 "$tmp/munge-socket"
    mungekey --create --keyfile="$tmp/munge/munge.key"
    chmod 0400 "$tmp/munge/munge.key"
    start munged munged --foreground --socket="$tmp/munge-socket/socket" \
        --key-file="$tmp/munge/munge.key" --pid-file="$tmp/munge/munged.pid" \
        --seed-file="$tmp/munge/seed"
    wait_until 30 munge_answers || fail "munged does not answer"
}

munge_answers() {
    munge -n -S "$tmp/munge-socket/socket" | unmunge -S "$tmp/munge-socket/socket"
}

write_slurm_conf() {
    local host cpus memory
    host=$(hostname -s)
    cpus=$(nproc)
    memory=$(($(awk '/^MemTotal:/ { print $2 }' /proc/meminfo) / 1024))
    cat >"$tmp/slurm.conf" <<CONF
ClusterName=reducemtest
SlurmctldHost=$host
SlurmctldPort=$controller_port
SlurmdPort=$node_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$tmp/munge-socket/socket
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/run/slurmctld.pid
SlurmdPidFile=$tmp/run/slurmd.pid
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
AccountingStorageType=accounting_storage/none
JobAcctGatherType=jobacct_gather/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
MinJobAge=3600
NodeName=$host CPUs=$cpus RealMemory=$memory State=UNKNOWN
PartitionName=test Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
    export SLURM_CONF=$tmp/slurm.conf
}

start_slurm() {
    mkdir -p "$tmp/state" "$tmp/spool" "$tmp/run"
    write_slurm_conf
    start slurmctld slurmctld -D -f "$SLURM_CONF"
    start slurmd slurmd -D -f "$SLURM_CONF"
    wait_until 60 node_idle ||
        fail "the node is not idle after 60 s: $(sinfo -h -N -o '%N %t %E' 2>&1)"
    say "cluster up: $(sinfo -h -N -o '%N %c CPUs %m MB %t')"
}

node_idle() {
    [[ $(sinfo -h -N -o %t) == idle ]]
}

build() {
    say "building"
    (cd "$repo" && nice cargo build --release -q -p pipeline -p reducem)
    pipeline=${CARGO_TARGET_DIR:-$repo/target}/release/pipeline
}

# write_config NAME [MESH CHUNK_TRIANGLES]: a configuration converting MESH (default the test
# mesh) into NAME/ (output and work).
write_config() {
    cat >"$tmp/data/$1.toml" <<CONF
[input]
path = "${2:-mesh.ply}"

[output]
path = "$1/out.rdm"

[chunk]
max_triangles = ${3:-$chunk_triangles}

[work]
dir = "$1/work"
CONF
}

# submit CONFIG SHARDS [EXTRA_SBATCH_OPTS]: submits with submit.sh; sets `submitted` to the
# chunk, strip and finish job ids (and adds them to job_ids, which cleanup cancels).
submit() {
    local output
    output=$(PIPELINE=$pipeline LOG_DIR=$tmp/log/jobs TIME_LIMIT=30:00 EXTRA_SBATCH_OPTS=${3-} \
        "$repo/scripts/slurm/submit.sh" "$tmp/data/$1.toml" "$2")
    echo "$output"
    mapfile -t submitted < <(awk '{ print $2 }' <<<"$output")
    ((${#submitted[@]} == 3)) || fail "submit.sh did not print 3 job ids"
    job_ids+=("${submitted[@]}")
}

# job_field FIELD JOB...: FIELD (JobState, ExitCode, ...) of each job and array task, one a line.
job_field() {
    local field=$1 id
    shift
    for id in "$@"; do
        scontrol -o show job "$id" | grep -o "\b$field=[^ ]*" | cut -d= -f2 || return 1
    done
}

# jobs_finished JOB...: whether every job (and array task) has ended.
jobs_finished() {
    local states
    states=$(job_field JobState "$@") || return 1
    ! grep -qvE '^(COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|PREEMPTED|BOOT_FAIL|DEADLINE)$' <<<"$states"
}

wait_for_jobs() {
    wait_until "$timeout" jobs_finished "$@" || fail "the jobs did not finish within $timeout s"
    local id
    for id in "$@"; do
        scontrol -o show job "$id" | awk '{
            line = ""
            for (i = 1; i <= NF; i++)
                if ($i ~ /^(JobId|ArrayTaskId|JobName|JobState|Reason|ExitCode|StartTime|EndTime)=/) line = line " " $i
            print " " line
        }'
    done
}

expect_completed() {
    job_field JobState "$@" | grep -qv '^COMPLETED$' && fail "a job did not complete (logs in $tmp/log/jobs)"
    return 0
}

# converted_by ARRAY: chunks the strip tasks of job array ARRAY converted, from their logs.
converted_by() {
    cat "$tmp/log/jobs/reducem-strip-$1"_*.out |
        sed -n 's/.* \([0-9][0-9]*\) chunks converted.*/\1/p' | awk '{ n += $1 } END { print n + 0 }'
}

done_chunks() {
    "$pipeline" status "$tmp/data/$1.toml" | grep -c '^strip/chunk-.* done$' || true
}

elapsed_since() {
    awk -v start="$1" -v end="$EPOCHREALTIME" 'BEGIN { printf "%.1f", end - start }'
}

run_on_cluster() {
    local started
    started=$EPOCHREALTIME
    submit cluster "$shards"
    wait_for_jobs "${submitted[@]}"
    cluster_seconds=$(elapsed_since "$started")
    expect_completed "${submitted[@]}"
    chunks=$(done_chunks cluster)
    ((chunks >= min_chunks)) || fail "only $chunks chunks; the test needs at least $min_chunks"
    (($(converted_by "${submitted[1]}") == chunks)) ||
        fail "the strip tasks converted $(converted_by "${submitted[1]}") chunks, not $chunks"
}

run_single_machine() {
    local started
    started=$EPOCHREALTIME
    nice "$pipeline" run "$tmp/data/single.toml" --log-format plain >"$tmp/log/single.out" 2>&1 ||
        fail "single-machine run failed: $(tail -n 5 "$tmp/log/single.out")"
    single_seconds=$(elapsed_since "$started")
}

# expect_identical NAME [REFERENCE]: NAME's file is byte-identical to REFERENCE's (default single).
expect_identical() {
    cmp "$tmp/data/$1/out.rdm" "$tmp/data/${2:-single}/out.rdm" ||
        fail "the file of $1 differs from the single-machine file of ${2:-single}"
}

# Stops one single-threaded strip task with SIGUSR1 to its batch shell (what Slurm sends before
# a time limit) while it works, expects exit 75 and the finishing job cancelled, then resubmits
# and expects the rest done and the same file. The signal is sent once the task logs its plan;
# if it lands before the first chunk is recorded or after the last one, it tries again.
stop_and_resume() {
    local attempt strip state stopped_after=0
    for attempt in 1 2 3; do
        "$pipeline" clean "$tmp/data/resume.toml" 2>/dev/null
        submit resume 1 --cpus-per-task=1
        strip=${submitted[1]}
        wait_until 120 grep -q 'strip: .* chunks to do' "$tmp/log/jobs/reducem-strip-${strip}_0.out" ||
            fail "the strip task did not start within 120 s"
        # (The task may have ended already: then scancel fails and the state below says so.)
        scancel --batch --signal=USR1 "${strip}_0" || true
        wait_for_jobs "${submitted[@]}"
        state=$(job_field JobState "${strip}_0")/$(job_field ExitCode "${strip}_0")
        stopped_after=$(done_chunks resume)
        if [[ $state == FAILED/75:0 ]] && ((stopped_after > 0)); then
            break
        fi
        [[ $state == COMPLETED/0:0 || $state == FAILED/75:0 ]] ||
            fail "the stopped strip task ended $state, not FAILED/75:0"
        say "attempt $attempt: the signal came with $stopped_after chunks done (or after the last); again"
        stopped_after=0
    done
    ((stopped_after > 0)) || fail "could not stop the strip task while it worked in 3 attempts"
    [[ $(job_field JobState "${submitted[2]}") == CANCELLED ]] ||
        fail "the finishing job was not cancelled after the strip task failed"
    submit resume 1 --cpus-per-task=1
    wait_for_jobs "${submitted[@]}"
    expect_completed "${submitted[@]}"
    local resumed resume_chunks
    resumed=$(converted_by "${submitted[1]}")
    resume_chunks=$(done_chunks resume)
    ((stopped_after + resumed == resume_chunks)) ||
        fail "stopped after $stopped_after chunks, resumed with $resumed; expected $resume_chunks in all"
    nice "$pipeline" run "$tmp/data/resume_single.toml" --log-format plain >"$tmp/log/resume_single.out" 2>&1 ||
        fail "single-machine run of the resume mesh failed: $(tail -n 5 "$tmp/log/resume_single.out")"
    expect_identical resume resume_single
    say "stopped by SIGUSR1 after $stopped_after of $resume_chunks chunks (exit 75, finishing job cancelled); the resubmission converted the other $resumed"
}

# On exit: cancel our jobs, stop our daemons (newest first), show logs if something failed.
cleanup() {
    local status=$?
    set +e
    if ((${#job_ids[@]})) && ! jobs_finished "${job_ids[@]}"; then
        scancel "${job_ids[@]}"
        wait_until 30 jobs_finished "${job_ids[@]}"
    fi
    local i
    for ((i = ${#daemon_pids[@]} - 1; i >= 0; i--)); do
        kill "${daemon_pids[i]}" 2>/dev/null
        wait "${daemon_pids[i]}" 2>/dev/null
    done
    if [[ -n $passed ]]; then
        rm -rf "$tmp"
        say "PASSED (cluster $cluster_seconds s, single machine $single_seconds s)"
        exit 0
    fi
    if [[ -n $tmp ]]; then
        local log
        for log in "$tmp"/log/*.log "$tmp"/log/single.out "$tmp"/log/jobs/*.out; do
            [[ -f $log ]] && { echo "--- $log (last lines)"; tail -n 15 "$log"; }
        done
        echo "(kept $tmp)"
    fi
    say "FAILED (exit status $status)"
    exit "$((status == 0 ? 1 : status))"
}

main() {
    [[ $EUID -eq 0 ]] || fail "run as root (it installs packages and runs the Slurm daemons)"
    trap cleanup EXIT
    trap 'exit 130' INT
    trap 'exit 143' TERM
    install_packages
    tmp=$(mktemp -d /tmp/reducem-slurm-test.XXXXXX)
    chmod 0755 "$tmp"
    mkdir -p "$tmp/log/jobs" "$tmp/data"
    start_munge
    start_slurm
    build
    nice "$pipeline" gen scan --triangles "$triangles" -o "$tmp/data/mesh.ply"
    write_config cluster
    write_config single
    nice "$pipeline" gen scan --triangles "$resume_triangles" -o "$tmp/data/mesh-resume.ply"
    write_config resume mesh-resume.ply "$resume_chunk_triangles"
    write_config resume_single mesh-resume.ply "$resume_chunk_triangles"
    run_on_cluster
    run_single_machine
    expect_identical cluster
    say "$chunks chunks over $shards shards; files identical ($(stat -c %s "$tmp/data/single/out.rdm") bytes)"
    stop_and_resume
    passed=1
}

main "$@"
