#!/bin/bash
# A single-node Slurm cluster on this machine, for trying the job scripts and for the Slurm
# test (tests/slurm.rs): munged, slurmctld and slurmd on localhost, every file under one
# folder, a minimal configuration (no cgroups, no accounting), ports picked free.
#
#     local-cluster.sh start DIR   # starts the daemons, waits until the node is idle, prints
#                                  # the SLURM_CONF to export for sbatch, squeue, scontrol ...
#     local-cluster.sh stop DIR    # stops the daemons start wrote into DIR/pids, by their ids
#
# Needs Debian's slurm-wlm and munge packages (slurmctld, slurmd, munged, mungekey). Runs as
# root (CI) or as any user (jobs then run as that user). The daemons run in the foreground of
# background shells, so that their process ids are the ones written to DIR/pids.
set -euo pipefail

usage() {
    echo "usage: $0 start|stop DIR" >&2
    exit 2
}
(($# == 2)) || usage
cmd=$1
mkdir -p "$2"
dir=$(cd "$2" && pwd)

stop() {
    [ -f "$dir/pids" ] || return 0
    # Jobs first, while the controller can still cancel them.
    if [ -f "$dir/slurm.conf" ]; then
        jobs=$(SLURM_CONF="$dir/slurm.conf" timeout 10 squeue -h -o %A 2>/dev/null || true)
        [ -z "$jobs" ] || SLURM_CONF="$dir/slurm.conf" timeout 10 scancel $jobs 2>/dev/null || true
    fi
    # In reverse order of starting: slurmd, slurmctld, munged.
    tac "$dir/pids" | while read -r name pid; do
        kill -TERM "$pid" 2>/dev/null || continue
        for _ in $(seq 100); do
            kill -0 "$pid" 2>/dev/null || break
            sleep 0.1
        done
        if kill -0 "$pid" 2>/dev/null; then
            echo "local-cluster: $name ($pid) did not stop in 10 s: killing it" >&2
            kill -KILL "$pid" 2>/dev/null || true
        fi
    done
    rm -f "$dir/pids"
}

# Waits up to $1 seconds for the command that follows to succeed.
wait_for() {
    local limit=$1
    shift
    for _ in $(seq $((limit * 5))); do
        if "$@" >/dev/null 2>&1; then return 0; fi
        sleep 0.2
    done
    return 1
}

fail() {
    echo "local-cluster: $1; logs in $dir:" >&2
    for log in "$dir"/*.log; do
        echo "--- $log" >&2
        tail -n 20 "$log" >&2 || true
    done
    stop
    exit 1
}

# A port nothing listens on (bash alone: CI machines need not have python).
free_port() {
    local port
    while true; do
        port=$((20000 + RANDOM % 40000))
        (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null || break
    done
    echo "$port"
}

start() {
    for p in munged mungekey slurmctld slurmd sinfo; do
        command -v "$p" >/dev/null 2>&1 || [ -x "/usr/sbin/$p" ] || {
            echo "local-cluster: $p is not installed (apt-get install slurm-wlm munge)" >&2
            exit 1
        }
    done
    export PATH="$PATH:/usr/sbin"
    if [ -f "$dir/pids" ]; then
        echo "local-cluster: $dir/pids exists: a cluster may run there (stop it first)" >&2
        exit 1
    fi
    local user host cpus
    user=$(id -un)
    host=$(hostname -s)
    cpus=$(nproc)
    mkdir -p "$dir/munge" "$dir/state" "$dir/spool"
    chmod 700 "$dir/munge"
    rm -f "$dir/munge/munge.key"
    mungekey --create --keyfile="$dir/munge/munge.key"
    chmod 400 "$dir/munge/munge.key"
    cat >"$dir/slurm.conf" <<EOF
# A single-node cluster for noisefree's Slurm test (scripts/slurm/local-cluster.sh).
ClusterName=noisefree
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$(free_port)
SlurmdPort=$(free_port)
SlurmUser=$user
SlurmdUser=$user
AuthType=auth/munge
AuthInfo=socket=$dir/munge/munge.socket
CredType=cred/munge
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=2
# Finished jobs stay visible to scontrol for an hour (the test reads their states).
MinJobAge=3600
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
    export SLURM_CONF="$dir/slurm.conf"
    : >"$dir/pids"
    munged -F --force --key-file="$dir/munge/munge.key" --socket="$dir/munge/munge.socket" \
        --pid-file="$dir/munge/munged.pid" --log-file="$dir/munged.log" \
        --seed-file="$dir/munge/munged.seed" >>"$dir/munged.log" 2>&1 &
    echo "munged $!" >>"$dir/pids"
    wait_for 30 munge -n --socket="$dir/munge/munge.socket" || fail "munged did not start"
    slurmctld -D -f "$dir/slurm.conf" >>"$dir/slurmctld.out.log" 2>&1 &
    echo "slurmctld $!" >>"$dir/pids"
    wait_for 60 scontrol ping || fail "slurmctld did not answer"
    slurmd -D -f "$dir/slurm.conf" -N "$host" >>"$dir/slurmd.out.log" 2>&1 &
    echo "slurmd $!" >>"$dir/pids"
    idle() { sinfo -h -N -o %T | grep -q '^idle'; }
    wait_for 60 idle || fail "the node did not become idle"
    echo "$SLURM_CONF"
}

case $cmd in
start) start ;;
stop) stop ;;
*) usage ;;
esac
