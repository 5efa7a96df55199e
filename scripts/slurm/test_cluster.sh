#!/usr/bin/env bash
# End-to-end test of scripts/slurm/submit.sh on a real, throwaway Slurm cluster: one node on
# localhost, with munged, slurmctld and slurmd run as root from a temporary directory (their own
# key, socket, config, state and logs; nothing under /etc is changed). It converts a small
# generated mesh with 4 strip shards and checks that the file is byte-identical to a
# single-machine `pipeline run` of the same configuration, then prints both wall times.
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
chunk_triangles=20000 # about 10 chunks of the 200k-triangle mesh
min_chunks=8
controller_port=16817 # not Slurm's default ports, so a real cluster on this host is untouched
node_port=16818
timeout=${SLURM_TEST_TIMEOUT:-900}

tmp=
daemon_pids=()
job_ids=()
passed=

say() { echo "slurm test: $*"; }
fail() {
    say "$*" >&2
    exit 1
}

install_packages() {
    local packages=(slurmctld slurmd munge slurm-client)
    if dpkg-query -W -f='${Status}\n' "${packages[@]}" 2>/dev/null | grep -vq 'install ok installed' ||
        (($(dpkg-query -W "${packages[@]}" 2>/dev/null | wc -l) < ${#packages[@]})); then
        say "installing ${packages[*]}"
        apt-get update -q
        DEBIAN_FRONTEND=noninteractive apt-get install -y -q "${packages[@]}"
    fi
}

# start NAME COMMAND...: runs a daemon in the foreground of a background job, output to its log.
start() {
    local name=$1
    shift
    "$@" >"$tmp/log/$name.out" 2>&1 &
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
    wait_until 30 bash -c "munge -n -S '$tmp/munge-socket/socket' | unmunge -S '$tmp/munge-socket/socket'" ||
        fail "munged does not answer"
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
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
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
    wait_until 60 bash -c '[[ $(sinfo -h -N -o %t) == idle ]]' ||
        fail "the node is not idle after 60 s: $(sinfo -h -N -o '%N %t %E' 2>&1)"
    say "cluster up: $(sinfo -h -N -o '%N %c CPUs %m MB %t')"
}

build() {
    say "building"
    (cd "$repo" && nice cargo build --release -q -p pipeline -p reducem)
    pipeline=${CARGO_TARGET_DIR:-$repo/target}/release/pipeline
}

# write_config NAME: a configuration converting the test mesh into NAME/ (output and work).
write_config() {
    cat >"$tmp/data/$1.toml" <<CONF
[input]
path = "mesh.ply"

[output]
path = "$1/out.rdm"

[chunk]
max_triangles = $chunk_triangles

[work]
dir = "$1/work"
CONF
}

# Job states of every job (and array task) in job_ids, one per line.
job_states() {
    local id
    for id in "${job_ids[@]}"; do
        scontrol -o show job "$id" | grep -o 'JobState=[A-Z_]*' | cut -d= -f2 || return 1
    done
}

jobs_finished() {
    local states
    states=$(job_states) || return 1
    ! grep -qvE '^(COMPLETED|FAILED|CANCELLED|TIMEOUT|NODE_FAIL|OUT_OF_MEMORY|PREEMPTED|BOOT_FAIL|DEADLINE)$' <<<"$states"
}

show_jobs() {
    local id
    for id in "${job_ids[@]}"; do
        scontrol -o show job "$id" | awk '{
            line = ""
            for (i = 1; i <= NF; i++)
                if ($i ~ /^(JobId|ArrayTaskId|JobName|JobState|Reason|ExitCode|RunTime)=/) line = line " " $i
            print "  " line
        }'
    done
}

run_on_cluster() {
    local started output
    started=$EPOCHREALTIME
    output=$(PIPELINE=$pipeline LOG_DIR=$tmp/log/jobs TIME_LIMIT=30:00 \
        "$repo/scripts/slurm/submit.sh" "$tmp/data/cluster.toml" "$shards")
    echo "$output"
    mapfile -t job_ids < <(awk '{ print $2 }' <<<"$output")
    ((${#job_ids[@]} == 3)) || fail "submit.sh printed no 3 job ids"
    wait_until "$timeout" jobs_finished || fail "the jobs did not finish within $timeout s"
    cluster_seconds=$(elapsed_since "$started")
    show_jobs
    job_states | grep -qv '^COMPLETED$' && fail "a job did not complete (logs in $tmp/log/jobs)"
    return 0
}

run_single_machine() {
    local started
    started=$EPOCHREALTIME
    nice "$pipeline" run "$tmp/data/single.toml" --log-format plain >"$tmp/log/single.out" 2>&1 ||
        fail "single-machine run failed: $(tail -n 5 "$tmp/log/single.out")"
    single_seconds=$(elapsed_since "$started")
}

elapsed_since() {
    awk -v start="$1" -v end="$EPOCHREALTIME" 'BEGIN { printf "%.1f", end - start }'
}

check_results() {
    local chunks
    chunks=$("$pipeline" status "$tmp/data/cluster.toml" | grep -c '^strip/chunk-.* done$' || true)
    ((chunks >= min_chunks)) || fail "only $chunks chunks; the test needs at least $min_chunks"
    cmp "$tmp/data/cluster/out.rdm" "$tmp/data/single/out.rdm" ||
        fail "the cluster's file differs from the single-machine file"
    say "$chunks chunks over $shards shards; files identical ($(stat -c %s "$tmp/data/single/out.rdm") bytes)"
}

# On exit: cancel our jobs, stop our daemons (newest first), show logs if something failed.
cleanup() {
    local status=$?
    set +e
    if ((${#job_ids[@]})) && ! jobs_finished; then
        scancel "${job_ids[@]}"
        wait_until 30 jobs_finished
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
        for log in "$tmp"/log/*.log "$tmp"/log/*.out "$tmp"/log/jobs/*.out; do
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
    run_on_cluster
    run_single_machine
    check_results
    passed=1
}

main "$@"
