#!/usr/bin/env bash
# Start / stop a throw-away single-node Slurm cluster (slurmctld + slurmd +
# munged on this host) for integration tests and CI.
#
#   slurm-single-node.sh install            apt-get the Debian packages
#   slurm-single-node.sh start STATE_DIR    start everything, wait until idle
#   slurm-single-node.sh stop  STATE_DIR    stop what `start` started
#
# Written for Debian 12 (Slurm 22.05, munge 0.5.15) running as root WITHOUT
# systemd (containers, CI VMs): the daemons are started by hand, all Slurm
# state/logs/pid files live under STATE_DIR, and nothing is written to
# /etc/slurm.  Callers use the cluster with
#
#   source STATE_DIR/env      # export SLURM_CONF=STATE_DIR/slurm.conf
#   sbatch --wrap '...'
#
# Final job states without slurmdbd: `scontrol show job ID` and
# `squeue --states=all` (jobs are kept MinJobAge=3600 s after they end) and
# STATE_DIR/jobcomp.log (jobcomp/filetxt, one line per finished job, survives
# restarts).  `sacct` does NOT work (no accounting storage).
#
# Environment knobs (optional):
#   SLURM_SN_CTLD_PORT / SLURM_SN_SLURMD_PORT  ports (default 6817 / 6818)
#   SLURM_SN_TIMEOUT                           seconds to wait for idle (60)
#   SLURM_SN_CLUSTER                           ClusterName (activefoam)
#   SLURM_SN_CRED_EXPIRE                       requeue delay / cred life (10 s)

set -euo pipefail

PROG=${0##*/}
CTLD_PORT=${SLURM_SN_CTLD_PORT:-6817}
SLURMD_PORT=${SLURM_SN_SLURMD_PORT:-6818}
TIMEOUT=${SLURM_SN_TIMEOUT:-60}
CLUSTER=${SLURM_SN_CLUSTER:-activefoam}
CRED_EXPIRE=${SLURM_SN_CRED_EXPIRE:-10}

PACKAGES=(slurmctld slurmd slurm-client munge)
MUNGE_KEY=/etc/munge/munge.key
MUNGE_RUN=/run/munge              # tmpfs: gone after every reboot/container start
MUNGE_PIDFILE=$MUNGE_RUN/munged.pid

log() { printf '%s: %s\n' "$PROG" "$*" >&2; }
die() { log "error: $*"; exit 1; }

usage() {
    cat >&2 <<EOF
usage: $PROG install
       $PROG start STATE_DIR
       $PROG stop  STATE_DIR
EOF
    exit 2
}

need_root() {
    # slurmd must be root to launch jobs (setuid to the submitting user), and
    # munged needs /run/munge + /etc/munge set up with munge ownership.
    [[ $EUID -eq 0 ]] || die "must run as root (slurmd and munged setup need it)"
}

# True if PID is alive and its command name is NAME (guards against pid reuse
# after a crash: never kill a stranger because of a stale pid file).
# A zombie counts as dead: in containers whose pid 1 reaps lazily, a killed
# daemon can linger as <defunct> with the same comm.
pid_is() {
    local pid=$1 name=$2 comm stat
    [[ $pid =~ ^[0-9]+$ ]] || return 1
    comm=$(cat "/proc/$pid/comm" 2>/dev/null) || return 1
    [[ $comm == "$name" ]] || return 1
    stat=$(cat "/proc/$pid/stat" 2>/dev/null) || return 1
    stat=${stat##*) }           # fields after "(comm) ": state is first
    [[ ${stat%% *} != Z ]]
}

read_pid() { [[ -r $1 ]] && tr -dc '0-9' <"$1"; return 0; }

# Send TERM, wait up to 15 s, then KILL.  No-op when not running.
kill_pidfile() {
    local pidfile=$1 name=$2 pid i
    pid=$(read_pid "$pidfile")
    if [[ -n $pid ]] && pid_is "$pid" "$name"; then
        kill -TERM "$pid" 2>/dev/null || true
        for ((i = 0; i < 75; i++)); do
            pid_is "$pid" "$name" || break
            sleep 0.2
        done
        if pid_is "$pid" "$name"; then
            log "$name ($pid) ignored SIGTERM, sending SIGKILL"
            kill -KILL "$pid" 2>/dev/null || true
            sleep 0.5
        fi
    fi
    rm -f "$pidfile"
}

# ---------------------------------------------------------------- install --
cmd_install() {
    local missing=() p
    for p in "${PACKAGES[@]}"; do
        dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q 'install ok installed' \
            || missing+=("$p")
    done
    if [[ ${#missing[@]} -eq 0 ]]; then
        log "already installed: ${PACKAGES[*]}"
        return 0
    fi
    local sudo=()
    if [[ $EUID -ne 0 ]]; then
        command -v sudo >/dev/null || die "not root and no sudo: cannot install ${missing[*]}"
        sudo=(sudo)
    fi
    export DEBIAN_FRONTEND=noninteractive
    local apt=("${sudo[@]}" apt-get install -y --no-install-recommends "${PACKAGES[@]}")
    # Package post-install scripts try to start services; without systemd /
    # with policy-rc.d that just prints a warning, which is harmless: `start`
    # runs the daemons itself.
    if ! "${apt[@]}"; then
        log "install failed, running apt-get update and retrying"
        "${sudo[@]}" apt-get update || log "apt-get update failed"
        "${apt[@]}" || die "could not install ${PACKAGES[*]} (no network / no Debian repo?)"
    fi
    for p in slurmctld slurmd sinfo sbatch munged munge unmunge; do
        command -v "$p" >/dev/null || [[ -x /usr/sbin/$p ]] \
            || die "installed, but $p is still missing"
    done
    log "installed: ${PACKAGES[*]}"
}

# ------------------------------------------------------------------ munge --
munge_ok() { munge -n 2>/dev/null | unmunge >/dev/null 2>&1; }

setup_munge_files() {
    local owner=munge:munge
    getent passwd munge >/dev/null || owner=root:root
    # munged insists on: key readable only by its user, and no group/other
    # write access on its key, socket, log and seed directories.
    install -d -m 0700 -o "${owner%:*}" -g "${owner#*:}" /etc/munge /var/lib/munge /var/log/munge
    install -d -m 0755 -o "${owner%:*}" -g "${owner#*:}" "$MUNGE_RUN"
    if [[ ! -s $MUNGE_KEY ]]; then
        log "generating $MUNGE_KEY"
        if command -v mungekey >/dev/null || [[ -x /usr/sbin/mungekey ]]; then
            PATH=$PATH:/usr/sbin mungekey -c -k "$MUNGE_KEY"
        else
            dd if=/dev/urandom of="$MUNGE_KEY" bs=1024 count=1 status=none
        fi
    fi
    chown "$owner" "$MUNGE_KEY"
    chmod 0400 "$MUNGE_KEY"
}

start_munge() {
    local state=$1 i mine
    if munge_ok; then
        mine=$(read_pid "$state/munged.started")
        if [[ -n $mine ]] && pid_is "$mine" munged; then
            return 0   # ours from an earlier `start` of this STATE_DIR: keep
        fi
        # A munged is already serving the default socket (distro service,
        # another test): share it and leave it alone on `stop`.
        rm -f "$state/munged.started"
        log "using already running munged"
        return 0
    fi
    rm -f "$state/munged.started"
    setup_munge_files
    # A dead munged leaves its pid file and socket behind; clear them so the
    # new one can bind (it would refuse otherwise).
    local old
    old=$(read_pid "$MUNGE_PIDFILE")
    if [[ -z $old ]] || ! pid_is "$old" munged; then
        rm -f "$MUNGE_PIDFILE" "$MUNGE_RUN"/munge.socket.2 "$MUNGE_RUN"/munge.socket.2.lock
    fi
    if getent passwd munge >/dev/null; then
        # Normal case: run as the unprivileged munge user (runuser: no PAM/tty
        # needed, unlike su).
        runuser -u munge -- /usr/sbin/munged
    else
        # No munge user (odd install): root needs --force.
        /usr/sbin/munged --force
    fi
    for ((i = 0; i < 20; i++)); do
        munge_ok && break
        sleep 0.5
    done
    munge_ok || {
        tail -n 20 /var/log/munge/munged.log >&2 2>/dev/null || true
        die "munged started but 'munge -n | unmunge' fails"
    }
    read_pid "$MUNGE_PIDFILE" >"$state/munged.started"
}

stop_munge() {
    local state=$1 pid
    [[ -f $state/munged.started ]] || return 0
    pid=$(read_pid "$state/munged.started")
    if [[ -n $pid ]] && pid_is "$pid" munged; then
        printf '%s\n' "$pid" >"$state/munged.pid.tmp"
        kill_pidfile "$state/munged.pid.tmp" munged
    fi
    rm -f "$state/munged.started"
}

# ------------------------------------------------------------------ slurm --
write_conf() {
    local state=$1 host=$2 cpus mem_kb mem_mb
    cpus=$(nproc)
    mem_kb=$(awk '/^MemTotal:/ {print $2}' /proc/meminfo)
    # Slurm drains a node whose RealMemory exceeds what slurmd measures, so
    # advertise ~90 % of MemTotal (slurmd subtracts a little itself).
    mem_mb=$((mem_kb * 9 / 10 / 1024))
    ((mem_mb > 0)) || mem_mb=1
    cat >"$state/slurm.conf" <<EOF
# Generated by $PROG on $(date -u +%FT%TZ); do not edit, rerun start.
ClusterName=$CLUSTER
# NodeAddr / ctld address are pinned to loopback so a container hostname that
# does not resolve (or resolves to an unreachable address) does not matter.
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$CTLD_PORT
SlurmdPort=$SLURMD_PORT
AuthType=auth/munge
CredType=cred/munge
# cred_expire also sets how long a requeued job waits before it may start
# again (default 120 s, far too slow for tests).
AuthInfo=cred_expire=$CRED_EXPIRE
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/spool
SlurmctldPidFile=$state/slurmctld.pid
SlurmdPidFile=$state/slurmd.pid
SlurmctldLogFile=$state/slurmctld.log
SlurmdLogFile=$state/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
MpiDefault=none
# No cgroups: works in unprivileged containers and without systemd.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
# No slurmdbd, so sacct does not work; finished jobs are appended to the
# jobcomp file instead, and kept in slurmctld memory for MinJobAge seconds.
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$state/jobcomp.log
MinJobAge=3600
# Allocate individual cores so several 1-CPU jobs/array tasks run at once.
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
# Node comes back by itself after a daemon restart / unexpected reboot.
ReturnToService=2
# Trust the config below even if slurmd measures slightly different hardware
# (containers with cpusets, memory limits): never drain for "low memory".
SlurmdParameters=config_overrides
# Quick turnaround for tests: run the main/backfill schedulers every few
# seconds (defaults 60/30 s), else e.g. a requeued job whose BeginTime has
# passed can sit PENDING for up to a minute.
SchedulerParameters=sched_interval=3,bf_interval=3
KillWait=5
SlurmdTimeout=60
InactiveLimit=0
NodeName=$host NodeAddr=127.0.0.1 CPUs=$cpus RealMemory=$mem_mb State=UNKNOWN
PartitionName=debug Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
}

dump_logs() {
    local state=$1 f
    for f in "$state/slurmctld.log" "$state/slurmd.log"; do
        [[ -f $f ]] || continue
        printf '==== tail %s ====\n' "$f" >&2
        tail -n 30 "$f" >&2
    done
    printf '==== sinfo ====\n' >&2
    timeout 10 sinfo -N -l >&2 2>&1 || true
}

cmd_start() {
    local state=$1 host t0 t_slurmd i st reg
    need_root
    PATH=$PATH:/usr/sbin:/sbin
    for i in slurmctld slurmd sinfo munged munge unmunge; do
        command -v "$i" >/dev/null || die "$i not found; run '$PROG install' first"
    done
    t0=$SECONDS
    mkdir -p "$state"
    state=$(cd "$state" && pwd -P)   # absolute: it ends up in slurm.conf
    # Restart-safe: stop anything a previous `start` left behind first.
    stop_slurm "$state"
    mkdir -p "$state/ctld" "$state/spool"
    chmod 0755 "$state" "$state/ctld" "$state/spool"

    start_munge "$state"

    # slurmd identifies its node by the short hostname, so NodeName must be
    # exactly `hostname -s` (slurmd -N needs a multiple-slurmd build).
    host=$(hostname -s)
    [[ -n $host ]] || die "empty hostname"
    write_conf "$state" "$host"
    printf 'export SLURM_CONF=%q\n' "$state/slurm.conf" >"$state/env"
    # Local to this process only: the client commands below need it.
    export SLURM_CONF=$state/slurm.conf

    # Both daemonize (no -D); state in StateSaveLocation is reused, so job
    # ids keep increasing across restarts of the same STATE_DIR.
    slurmctld -f "$SLURM_CONF" || { dump_logs "$state"; die "slurmctld failed to start"; }
    t_slurmd=$(date +%s)
    slurmd -f "$SLURM_CONF" || { dump_logs "$state"; die "slurmd failed to start"; }

    # Ready = node IDLE *and* registered by the slurmd we just started: a
    # reused STATE_DIR makes slurmctld report the recovered node as idle
    # before any slurmd has talked to it.
    for ((i = 0; i < TIMEOUT * 2; i++)); do
        st=$(timeout 10 sinfo -h -N -n "$host" -o '%T' 2>/dev/null | head -n1 || true)
        case $st in
            idle)
                reg=$(timeout 10 scontrol -o show node "$host" 2>/dev/null \
                    | grep -o 'SlurmdStartTime=[^ ]*' | cut -d= -f2 || true)
                reg=$(date -d "$reg" +%s 2>/dev/null || echo 0)
                ((reg >= t_slurmd - 2)) && break
                st="idle (slurmd not registered yet)" ;;
            # Recovered state may leave the node down/drained from the last
            # run (e.g. stop while jobs were running); bring it back.
            down* | drain* | fail*)
                if ((i % 4 == 0)); then
                    timeout 10 scontrol update NodeName="$host" State=RESUME >/dev/null 2>&1 || true
                fi ;;
        esac
        sleep 0.5
    done
    if [[ $st != idle ]]; then
        log "last node state: ${st:-none}"
        dump_logs "$state"
        die "node $host not idle after ${TIMEOUT}s (state: '${st:-none}')"
    fi
    log "cluster up in $((SECONDS - t0))s: node $host ($(nproc) CPUs), partition debug; source $state/env"
}

stop_slurm() {
    local state=$1 pid i
    pid=$(read_pid "$state/slurmctld.pid")
    # slurmd does not kill running jobs when it exits (slurmstepd lives on),
    # so cancel everything while the controller is still up and give the
    # steps a moment to die.  Only if munge works: with munged dead every
    # Slurm client call retries for ~50 s before failing.
    if [[ -n $pid ]] && pid_is "$pid" slurmctld && [[ -f $state/slurm.conf ]] && munge_ok; then
        SLURM_CONF=$state/slurm.conf timeout 20 scancel --partition=debug >/dev/null 2>&1 || true
        for ((i = 0; i < 20; i++)); do
            [[ -z $(SLURM_CONF=$state/slurm.conf timeout 10 squeue -h -t running,completing,configuring 2>/dev/null || true) ]] && break
            sleep 0.5
        done
    fi
    kill_pidfile "$state/slurmd.pid" slurmd
    kill_pidfile "$state/slurmctld.pid" slurmctld
}

cmd_stop() {
    local state=$1
    [[ -d $state ]] || return 0   # nothing was ever started: idempotent
    state=$(cd "$state" && pwd -P)
    stop_slurm "$state"
    stop_munge "$state"
    log "stopped"
}

# ------------------------------------------------------------------- main --
[[ $# -ge 1 ]] || usage
case $1 in
    install) [[ $# -eq 1 ]] || usage; cmd_install ;;
    start) [[ $# -eq 2 ]] || usage; cmd_start "$2" ;;
    stop) [[ $# -eq 2 ]] || usage; cmd_stop "$2" ;;
    *) usage ;;
esac
