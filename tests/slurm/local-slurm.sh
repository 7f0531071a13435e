#!/bin/bash
# A one-node Slurm on this machine, for tests/test_batch.py: munge, slurmctld and slurmd as
# root, no cgroups, no systemd. Everything (configuration, state, logs, pid files) lives in
# $DOLFRAG_SLURM_DIR (default /var/spool/dolfrag-slurm); the clients find the configuration
# through SLURM_CONF, so a system's own /etc/slurm is never touched.
#
#   tests/slurm/local-slurm.sh start    # idempotent: does nothing if both daemons answer
#   tests/slurm/local-slurm.sh stop     # ends the daemons this script started (by pid file)
#   export SLURM_CONF=/var/spool/dolfrag-slurm/slurm.conf   # then sbatch, squeue, scontrol
#
# Needs the Debian 12 packages slurm-wlm and munge (make install). Exits non-zero with the
# daemons' last log lines if the scheduler does not come up.
set -euo pipefail
DIR=${DOLFRAG_SLURM_DIR:-/var/spool/dolfrag-slurm}
export SLURM_CONF=$DIR/slurm.conf
NODE=$(hostname -s)
# the hardware as slurmd itself sees it: nproc would follow OMP_NUM_THREADS (a CI machine that
# sets it to 1 declared a 1-CPU node, and the 2-rank test jobs pended for ever)
CPUS=$(slurmd -C | sed -n 's/.* CPUs=\([0-9]*\).*/\1/p')
MEMORY_MB=$(awk '/MemTotal/ {print int($2 / 1024 * 0.9)}' /proc/meminfo)

write_conf() {
    mkdir -p "$DIR/ctld" "$DIR/d"
    # KillWait: s between the limit's SIGTERM and SIGKILL (Slurm's default, the one
    # docs/usage.md assumes). MinJobAge: a finished job stays in `scontrol show job` (its
    # Restarts count) for 10 minutes; there is no accounting database, so no sacct.
    # cred_expire: a requeued job is held that long (default 120 s, measured 121 s) before
    # it may start again; a step's credential must outlive its launch, well under a second
    # here. SchedulerParameters: a pass every 2 s (sched_interval) instead of 60 s starts the
    # eligible job at once.
    cat > "$SLURM_CONF" <<CONF
ClusterName=dolfrag-local
SlurmctldHost=$NODE
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=cred_expire=10
StateSaveLocation=$DIR/ctld
SlurmdSpoolDir=$DIR/d
SlurmctldPidFile=$DIR/slurmctld.pid
SlurmdPidFile=$DIR/slurmd.pid
SlurmctldLogFile=$DIR/slurmctld.log
SlurmdLogFile=$DIR/slurmd.log
SlurmctldPort=6817
SlurmdPort=6818
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
MpiDefault=pmix
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
ReturnToService=2
MailProg=/bin/true
KillWait=30
MinJobAge=600
SchedulerParameters=sched_interval=2
NodeName=$NODE CPUs=$CPUS RealMemory=$MEMORY_MB State=UNKNOWN
PartitionName=local Nodes=$NODE Default=YES MaxTime=INFINITE State=UP
CONF
}

up() {
    scontrol ping 2>/dev/null | grep -q "is UP" && sinfo -h -o %T 2>/dev/null | grep -qx -E "idle|allocated|mixed|completing"
}

stale() {  # daemons left up with another configuration (another CPU count, say)
    [ "$(sinfo -h -o %c 2>/dev/null)" != "$CPUS" ]
}

start_munge() {
    # the pid file first: without munged, the munge client retries for about a minute
    if pgrep -F /run/munge/munged.pid >/dev/null 2>&1; then
        return
    fi
    mkdir -p /run/munge /var/log/munge /var/lib/munge
    chown munge:munge /run/munge /var/log/munge /var/lib/munge
    runuser -u munge -- /usr/sbin/munged
}

start() {
    if up && ! stale; then
        echo "Slurm is up ($SLURM_CONF)"
        return
    fi
    stop >/dev/null
    write_conf
    start_munge
    pgrep -F "$DIR/slurmctld.pid" >/dev/null 2>&1 || slurmctld -f "$SLURM_CONF"
    pgrep -F "$DIR/slurmd.pid" >/dev/null 2>&1 || slurmd -f "$SLURM_CONF"
    for _ in $(seq 60); do
        # a node left down or drained by an earlier run (a task that would not die) is taken back
        if sinfo -h -o %T 2>/dev/null | grep -q -E "down|drain"; then
            scontrol update nodename="$NODE" state=resume
        fi
        if up; then
            echo "Slurm is up ($SLURM_CONF)"
            return
        fi
        sleep 0.5
    done
    echo "Slurm did not come up in 30 s; scontrol ping: $(scontrol ping 2>&1 | tr '\n' ' ')" >&2
    tail -n 5 "$DIR/slurmctld.log" "$DIR/slurmd.log" >&2 || true
    exit 1
}

stop() {
    for daemon in slurmd slurmctld; do
        [ -f "$DIR/$daemon.pid" ] && kill "$(cat "$DIR/$daemon.pid")" 2>/dev/null || true
    done
    for daemon in slurmd slurmctld; do  # gone, so that a start right after starts anew
        while pgrep -F "$DIR/$daemon.pid" >/dev/null 2>&1; do sleep 0.2; done
    done
    echo "Slurm stopped (munged left running: kill \$(cat /run/munge/munged.pid) ends it)"
}

case "${1:-}" in
    start) start ;;
    stop) stop ;;
    *) echo "usage: $0 start|stop" >&2; exit 2 ;;
esac
