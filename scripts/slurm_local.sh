#!/usr/bin/env bash
# A real single-node Slurm on localhost, for the tests and for trying
# `cradle slurm` without a cluster. Needs root and Debian's packages:
#     apt-get install slurm-wlm munge
#
#     scripts/slurm_local.sh start    # munged, slurmctld, slurmd; waits until the node is idle
#     scripts/slurm_local.sh stop     # cancels jobs, stops the Slurm daemons
#     eval "$(scripts/slurm_local.sh env)"   # SLURM_CONF for sbatch/squeue in this shell
#                                            # (/etc/slurm/slurm.conf is linked to it when free)
#
# Everything Slurm writes lives in $CRADLE_SLURM_DIR (default /tmp/cradle-slurm):
# slurm.conf (one node with this machine's CPUs and memory, one partition,
# no cgroups: proctrack/linuxproc, task/none), state, spool, logs.
set -euo pipefail
S=${CRADLE_SLURM_DIR:-/tmp/cradle-slurm}
CONF=$S/slurm.conf
export SLURM_CONF=$CONF

start_munge() {
    if munge -n </dev/null >/dev/null 2>&1 && unmunge </dev/null >/dev/null 2>&1 <<<"$(munge -n)"; then
        return
    fi
    if [ ! -s /etc/munge/munge.key ]; then
        mungekey --create --force 2>/dev/null ||
            dd if=/dev/urandom of=/etc/munge/munge.key bs=1 count=1024 status=none
    fi
    chown munge:munge /etc/munge/munge.key
    chmod 400 /etc/munge/munge.key
    mkdir -p /run/munge
    chown munge:munge /run/munge
    chmod 755 /run/munge
    runuser -u munge -- /usr/sbin/munged
    for _ in $(seq 50); do
        munge -n >/dev/null 2>&1 && return
        sleep 0.1
    done
    echo "slurm_local: munged did not start" >&2
    exit 1
}

write_conf() {
    mkdir -p "$S/state" "$S/spool" "$S/log"
    local host cpus mem
    host=$(hostname -s)
    cpus=$(nproc)
    mem=$(awk '/MemTotal/ {printf "%d", $2 / 1024 * 0.8}' /proc/meminfo)
    cat >"$CONF" <<CONF
ClusterName=cradle
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
StateSaveLocation=$S/state
SlurmdSpoolDir=$S/spool
SlurmctldPidFile=$S/slurmctld.pid
SlurmdPidFile=$S/slurmd.pid
SlurmctldLogFile=$S/log/slurmctld.log
SlurmdLogFile=$S/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
# Schedule jobs as they come and free CPUs at once (the default waits up
# to 3 s between rounds: most of the tests' Slurm time).
SchedulerParameters=batch_sched_delay=0
ReturnToService=2
MpiDefault=none
SlurmctldTimeout=30
SlurmdTimeout=30
NodeName=$host CPUs=$cpus RealMemory=$mem State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
CONF
}

case "${1:-}" in
start)
    start_munge
    if ! scontrol ping 2>/dev/null | grep -q "is UP"; then
        write_conf
        # sbatch, squeue, … read /etc/slurm/slurm.conf unless SLURM_CONF says
        # otherwise: point it here when it is ours to take.
        if [ ! -e /etc/slurm/slurm.conf ] || [ -L /etc/slurm/slurm.conf ]; then
            mkdir -p /etc/slurm
            ln -sfn "$CONF" /etc/slurm/slurm.conf
        fi
        slurmctld -f "$CONF"
        slurmd -f "$CONF"
    fi
    for _ in $(seq 120); do
        state=$(sinfo -h -o %T 2>/dev/null | head -1 || true)
        case "$state" in
        idle* | mixed* | allocated*) echo "slurm_local: node $state ($CONF)"; exit 0 ;;
        esac
        sleep 0.5
    done
    echo "slurm_local: the node did not come up; see $S/log/" >&2
    tail -20 "$S/log/slurmctld.log" "$S/log/slurmd.log" >&2 || true
    exit 1
    ;;
stop)
    scancel --user="$(id -un)" 2>/dev/null || true
    for d in slurmd slurmctld; do
        [ -f "$S/$d.pid" ] && kill "$(cat "$S/$d.pid")" 2>/dev/null || true
    done
    echo "slurm_local: stopped"
    ;;
env)
    echo "export SLURM_CONF=$CONF"
    ;;
*)
    echo "usage: $0 start|stop|env" >&2
    exit 2
    ;;
esac
