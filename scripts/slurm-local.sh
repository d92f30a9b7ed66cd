#!/usr/bin/env bash
# A one-node Slurm cluster on this machine, for tests and for trying the job scripts in
# deploy/slurm/ before a real cluster: installs Debian's slurm-wlm and munge where missing,
# writes a minimal slurm.conf, starts munged, slurmctld and slurmd as background processes
# (no systemd), waits until the node is idle, and stops exactly the processes it started.
#
#   scripts/slurm-local.sh start    # prints the line to eval: export SLURM_CONF=...
#   scripts/slurm-local.sh stop
#   scripts/slurm-local.sh status
#
# State lives in $DIPS_SLURM_DIR (default /tmp/dips-slurm): the config, the daemons' logs,
# their pid files. Needs root (it installs packages and runs the daemons as root).
# Exit code 3 from `start`: the packages could not be installed (no package registry).
set -euo pipefail

dir=${DIPS_SLURM_DIR:-/tmp/dips-slurm}
conf=$dir/slurm.conf
pids=$dir/started.pids

log() { printf 'slurm-local: %s\n' "$*" >&2; }

install_packages() {
    if command -v slurmctld >/dev/null && command -v slurmd >/dev/null \
        && command -v munged >/dev/null && command -v sbatch >/dev/null; then
        return 0
    fi
    log "installing slurm-wlm and munge (Debian packages)"
    export DEBIAN_FRONTEND=noninteractive
    if ! { timeout 300 apt-get update -qq \
        && timeout 600 apt-get install -y -qq --no-install-recommends slurm-wlm munge; } >"$dir/apt.log" 2>&1
    then
        log "could not install slurm-wlm/munge (see $dir/apt.log)"
        return 3
    fi
}

write_config() {
    local host cpus mem
    host=$(hostname -s)
    cpus=$(nproc)
    mem=$(( $(awk '/MemTotal/ {print $2}' /proc/meminfo) / 1024 - 1024 ))
    mkdir -p "$dir/state" "$dir/spool" "$dir/munge" "$dir/run"
    cat >"$conf" <<CONF
# Written by scripts/slurm-local.sh: one node, every core, no accounting, no cgroups.
ClusterName=dips-local
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
MpiDefault=none
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
# Start dependent jobs within seconds (the defaults wait up to a minute on an idle node).
SchedulerParameters=sched_interval=2,bf_interval=2
SelectType=select/cons_tres
SelectTypeParameters=CR_Core_Memory
DefMemPerCPU=2048
ReturnToService=2
SlurmctldPort=${DIPS_SLURMCTLD_PORT:-6817}
SlurmdPort=${DIPS_SLURMD_PORT:-6818}
StateSaveLocation=$dir/state
SlurmdSpoolDir=$dir/spool
SlurmctldPidFile=$dir/run/slurmctld.pid
SlurmdPidFile=$dir/run/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmdTimeout=30
MinJobAge=300
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
    # Debian's slurmd reads cgroup.conf beside slurm.conf even with cgroups unused.
    printf 'CgroupPlugin=cgroup/v1\nIgnoreSystemd=yes\n' >"$dir/cgroup.conf"
}

start_munge() {
    local key=/etc/munge/munge.key
    if [ ! -s "$key" ]; then
        mkdir -p /etc/munge
        dd if=/dev/urandom bs=1 count=1024 of="$key" status=none
        chmod 400 "$key"
    fi
    chown -R root:root /etc/munge 2>/dev/null || true
    mkdir -p /run/munge /var/lib/munge /var/log/munge
    if [ -S /run/munge/munge.socket.2 ] && munge -n 2>/dev/null | unmunge >/dev/null 2>&1; then
        log "munged already running; using it"
        return 0
    fi
    munged --force --socket=/run/munge/munge.socket.2 --pid-file="$dir/run/munged.pid" \
        --log-file="$dir/munged.log" --seed-file="$dir/munge/seed"
    for _ in $(seq 50); do
        [ -s "$dir/run/munged.pid" ] && break
        sleep 0.1
    done
    cat "$dir/run/munged.pid" >>"$pids"
}

wait_idle() {
    for _ in $(seq 120); do
        state=$(sinfo -h -N -o '%t' 2>/dev/null | head -1 || true)
        case "$state" in
            idle*|mix*|alloc*) log "node $(hostname -s) is $state"; return 0 ;;
            down*|drain*|inval*)
                scontrol update nodename="$(hostname -s)" state=resume >/dev/null 2>&1 || true ;;
        esac
        sleep 0.5
    done
    log "the node did not become idle in 60 s; logs in $dir"
    tail -5 "$dir/slurmctld.log" "$dir/slurmd.log" >&2 || true
    return 1
}

start() {
    mkdir -p "$dir"
    if [ -s "$pids" ]; then
        log "already started (pids in $pids); stop it first"
        echo "export SLURM_CONF=$conf"
        return 0
    fi
    install_packages || return $?
    write_config
    : >"$pids"
    start_munge
    export SLURM_CONF=$conf
    slurmctld -f "$conf"
    for _ in $(seq 50); do [ -s "$dir/run/slurmctld.pid" ] && break; sleep 0.1; done
    cat "$dir/run/slurmctld.pid" >>"$pids"
    slurmd -f "$conf"
    for _ in $(seq 50); do [ -s "$dir/run/slurmd.pid" ] && break; sleep 0.1; done
    cat "$dir/run/slurmd.pid" >>"$pids"
    wait_idle
    echo "export SLURM_CONF=$conf"
}

stop() {
    if [ ! -s "$pids" ]; then
        log "nothing started by this script"
        return 0
    fi
    # Jobs first, so no step is left behind, then exactly the daemons this script started.
    SLURM_CONF=$conf scancel --user=root >/dev/null 2>&1 || true
    while read -r pid; do
        [ -n "$pid" ] && kill "$pid" 2>/dev/null || true
    done <"$pids"
    for _ in $(seq 50); do
        alive=0
        while read -r pid; do
            [ -n "$pid" ] && kill -0 "$pid" 2>/dev/null && alive=1
        done <"$pids"
        [ $alive = 0 ] && break
        sleep 0.1
    done
    while read -r pid; do
        [ -n "$pid" ] && kill -9 "$pid" 2>/dev/null || true
    done <"$pids"
    rm -f "$pids"
    log "stopped"
}

case "${1:-}" in
    start) start ;;
    stop) stop ;;
    status) SLURM_CONF=$conf sinfo; SLURM_CONF=$conf squeue ;;
    *) echo "usage: $0 start|stop|status" >&2; exit 2 ;;
esac
