#!/usr/bin/env bash
# Starts and stops a real single-node SLURM cluster on this host, for tests.
#
#   bash scripts/slurm-local.sh start  DIR   # install if needed, start munged/slurmctld/slurmd
#   bash scripts/slurm-local.sh stop   DIR   # cancel jobs, stop the daemons started for DIR
#   bash scripts/slurm-local.sh status DIR   # sinfo + squeue
#
# After `start`, `source DIR/env.sh` sets SLURM_CONF so that sbatch/squeue/scancel/sinfo talk
# to this cluster. Everything (config, state, spool, pid and log files) lives under DIR
# (except the spool directory when DIR is too long for its Unix sockets, see spool_dir);
# the only files outside it are Debian's packages, the munge key /etc/munge/munge.key and
# munged's usual socket/pid/log files (/run/munge, /var/log/munge).
#
# Exit codes: 0 ok; 1 failure (the tail of the daemon logs is printed); 2 usage;
# 77 skipped: SLURM is missing and cannot be installed here (not root, or no apt-get), or we
# are not root. A skip prints exactly one line "slurm-local: SKIP: <reason>".
#
# The cluster: one node (this host, its real CPUs and memory from `slurmd -C`), one partition
# `debug` (default, no time limit), select/cons_tres + CR_Core so several 1-CPU tasks run at
# once, no cgroups, no accounting daemon (sacct does not work; jobs that ended are listed in
# DIR/jobcomp.txt, one line each, by jobcomp/filetxt). No systemd is needed: the daemons are
# started directly. Environment knobs:
#   SLURM_LOCAL_CTLD_PORT (default 6817), SLURM_LOCAL_SLURMD_PORT (default 6818)
#   SLURM_LOCAL_WAIT  seconds to wait for the node to become idle (default 60)
set -euo pipefail

prog=slurm-local
ctld_port=${SLURM_LOCAL_CTLD_PORT:-6817}
slurmd_port=${SLURM_LOCAL_SLURMD_PORT:-6818}
wait_s=${SLURM_LOCAL_WAIT:-60}

say() { echo "$prog: $*" >&2; }
die() { say "ERROR: $*"; exit 1; }
skip() { echo "$prog: SKIP: $*"; exit 77; }

usage() {
    echo "usage: $0 start|stop|status DIR" >&2
    exit 2
}

# ---------------------------------------------------------------------------------------------
# Process helpers. A pid file is trusted only if the process is alive AND its name is the
# expected one (a pid may have been reused after a reboot or a killed run).

# gone PID -> succeeds when the process has exited (no longer in /proc, or a zombie).
gone() { [ ! -d "/proc/$1" ] || [ "$(awk '/^State:/ {print $2}' "/proc/$1/status" 2>/dev/null)" = Z ]; }

# pid_alive PIDFILE NAME -> prints the pid and succeeds when PIDFILE names a live NAME process.
pid_alive() {
    local f=$1 name=$2 pid comm
    [ -s "$f" ] || return 1
    pid=$(head -n 1 "$f" | tr -dc '0-9')
    [ -n "$pid" ] || return 1
    comm=$(cat "/proc/$pid/comm" 2>/dev/null) || return 1
    # comm is cut at 15 characters; slurmstepd shows up as "slurmstepd".
    [ "$comm" = "$name" ] || return 1
    ! gone "$pid" || return 1
    echo "$pid"
}

# pids_with_conf NAME... -> pids of NAME processes whose environment has SLURM_CONF=$conf.
# The daemons are started with SLURM_CONF in their environment and slurmstepd inherits it
# from slurmd, so this finds what belongs to THIS cluster even when a pid file is missing
# (e.g. the starting script was killed between starting a daemon and recording it).
# Only builtins in the loop: the machine may run hundreds of processes.
pids_with_conf() {
    local p c e names=" $* "
    for p in /proc/[0-9]*; do
        { read -r c <"$p/comm"; } 2>/dev/null || continue
        [[ $names == *" $c "* ]] || continue
        while IFS= read -r -d '' e; do
            if [ "$e" = "SLURM_CONF=$conf" ]; then
                echo "${p#/proc/}"
                break
            fi
        done 2>/dev/null <"$p/environ"
    done
}

# stop_pids LABEL PID... : SIGTERM, wait up to 10 s, then SIGKILL and wait up to 5 s more.
stop_pids() {
    local label=$1 i p left=()
    shift
    [ $# -gt 0 ] || return 0
    kill -TERM "$@" 2>/dev/null || true
    for i in $(seq 1 150); do
        left=()
        for p in "$@"; do gone "$p" || left+=("$p"); done
        [ ${#left[@]} -eq 0 ] && break
        if [ "$i" = 100 ]; then
            say "$label did not stop on SIGTERM within 10 s, sending SIGKILL to ${left[*]}"
            kill -KILL "${left[@]}" 2>/dev/null || true
        fi
        sleep 0.1
    done
    if [ ${#left[@]} -gt 0 ]; then
        say "WARNING: $label still running: ${left[*]}"
        return 1
    fi
    # Exited processes whose parent is PID 1 stay zombies until PID 1 reaps them; some
    # container init processes do that only every few seconds. Wait (up to 10 s) so that
    # `pgrep slurm` is empty when stop returns; a zombie that stays is not an error.
    for i in $(seq 1 100); do
        left=()
        for p in "$@"; do [ -d "/proc/$p" ] && left+=("$p"); done
        [ ${#left[@]} -eq 0 ] && return 0
        sleep 0.1
    done
    return 0
}

show_logs() {
    local f
    for f in "$dir/slurmctld.log" "$dir/slurmd.log" "$dir/slurmctld.out" "$dir/slurmd.out" /var/log/munge/munged.log; do
        [ -s "$f" ] || continue
        echo "----- tail $f" >&2
        tail -n 25 "$f" >&2
    done
}

# ---------------------------------------------------------------------------------------------
# Installation (Debian packages) and munge.

have_slurm() {
    command -v sbatch >/dev/null 2>&1 && command -v slurmctld >/dev/null 2>&1 &&
        command -v slurmd >/dev/null 2>&1 && command -v munged >/dev/null 2>&1
}

install_slurm() {
    local log=$dir/apt.log policy=/usr/sbin/policy-rc.d made_policy=0 rc=0
    say "installing slurmctld slurmd slurm-client munge with apt-get (log: $log) ..."
    # Without systemd the maintainer scripts would try to start the services through the
    # SysV scripts; forbid that (exit 101 = "action not allowed") so that nothing runs that
    # this script does not know about. A pre-existing policy-rc.d (Docker images) is kept.
    if [ ! -e "$policy" ]; then
        printf '#!/bin/sh\nexit 101\n' >"$policy" && chmod 755 "$policy" && made_policy=1
    fi
    export DEBIAN_FRONTEND=noninteractive
    {
        # Refresh the package lists only when they do not know slurmctld (fresh machine).
        if ! apt-cache show slurmctld >/dev/null 2>&1; then apt-get update -q; fi
        apt-get install -y -q --no-install-recommends slurmctld slurmd slurm-client munge ||
            { apt-get update -q && apt-get install -y -q --no-install-recommends slurmctld slurmd slurm-client munge; }
    } >>"$log" 2>&1 || rc=$?
    [ "$made_policy" = 1 ] && rm -f "$policy"
    if [ "$rc" != 0 ]; then
        tail -n 15 "$log" >&2
        die "apt-get install failed (exit $rc), see $log"
    fi
    have_slurm || die "packages installed but sbatch/slurmctld/slurmd/munged still missing (see $log)"
}

munge_ok() { munge -n 2>/dev/null | unmunge >/dev/null 2>&1; }

# Creates /etc/munge/munge.key if missing (Debian's postinst normally does) and makes sure the
# owner and modes are the ones munged insists on.
ensure_munge_key() {
    local key=/etc/munge/munge.key owner=root
    id munge >/dev/null 2>&1 && owner=munge
    mkdir -p /etc/munge /var/lib/munge /var/log/munge /run/munge
    if [ ! -s "$key" ]; then
        say "creating $key"
        if command -v mungekey >/dev/null 2>&1; then
            mungekey --create --keyfile="$key" --force >/dev/null
        else
            dd if=/dev/urandom of="$key" bs=1024 count=1 status=none
        fi
    fi
    chown "$owner:$owner" /etc/munge "$key" /var/lib/munge /var/log/munge /run/munge
    chmod 0700 /etc/munge /var/lib/munge /var/log/munge
    chmod 0755 /run/munge
    chmod 0400 "$key"
}

# Starts munged unless one already answers (then it is reused and not stopped by `stop`).
start_munge() {
    local i pid
    if munge_ok; then
        say "munged already running; using it"
        return 0
    fi
    ensure_munge_key
    rm -f "$dir/munged.pid"
    # munged daemonizes and writes /run/munge/munged.pid. Run it as the munge user like the
    # Debian service does; with no munge user, as root (--force skips its ownership checks).
    if id munge >/dev/null 2>&1; then
        runuser -u munge -- munged </dev/null >>"$dir/munged.out" 2>&1 ||
            die "munged failed to start: $(tail -n 3 "$dir/munged.out" | tr '\n' ' ')"
    else
        munged --force </dev/null >>"$dir/munged.out" 2>&1 ||
            die "munged failed to start: $(tail -n 3 "$dir/munged.out" | tr '\n' ' ')"
    fi
    for i in $(seq 1 50); do
        if munge_ok && pid=$(pid_alive /run/munge/munged.pid munged); then
            echo "$pid" >"$dir/munged.pid"
            return 0
        fi
        sleep 0.1
    done
    die "munged does not answer (see $dir/munged.out, /var/log/munge/munged.log)"
}

# ---------------------------------------------------------------------------------------------
# slurm.conf for this host.

write_conf() {
    local host node_line
    host=$(hostname -s)
    # `slurmd -C` prints "NodeName=<host> CPUs=.. Boards=.. SocketsPerBoard=.. CoresPerSocket=..
    # ThreadsPerCore=.. RealMemory=.." and then an UpTime line. Keep the first line.
    node_line=$(slurmd -C 2>/dev/null | grep -m 1 '^NodeName=') || die "slurmd -C failed: $(slurmd -C 2>&1 | tail -n 2)"
    node_line="NodeName=$host ${node_line#NodeName=* }"
    cat >"$conf.tmp" <<EOF
# Written by scripts/slurm-local.sh for a single-node test cluster on $host. Do not edit:
# it is rewritten by every 'start'.
ClusterName=sinterdem-local
# The address is given explicitly so that nothing depends on how the host name resolves.
SlurmctldHost=$host(127.0.0.1)
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
MpiDefault=none
StateSaveLocation=$dir/state
SlurmdSpoolDir=$spool
SlurmctldPidFile=$dir/slurmctld.pid
SlurmdPidFile=$dir/slurmd.pid
SlurmctldLogFile=$dir/slurmctld.log
SlurmdLogFile=$dir/slurmd.log
SlurmctldDebug=info
SlurmdDebug=info
# No cgroups: plain /proc process tracking, no task affinity/containment.
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
# Start the next array tasks as soon as CPUs free up (defaults delay batch jobs by up to 3 s).
SchedulerParameters=batch_sched_delay=0,sched_min_interval=0
# No accounting daemon; finished jobs are appended to a text file (one line per job, with
# JobState=COMPLETED/FAILED/CANCELLED/TIMEOUT/NODE_FAIL).
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/filetxt
JobCompLoc=$dir/jobcomp.txt
# Short timeouts so that tests are fast; a node that was down comes back by itself.
ReturnToService=2
SlurmctldTimeout=30
SlurmdTimeout=30
MessageTimeout=10
InactiveLimit=0
KillWait=2
# Finished jobs stay visible to squeue/scontrol for MinJobAge seconds (purged by a sweep that
# runs about once a minute, so in practice 30-90 s).
MinJobAge=30
# Trust the node description below even if slurmd measures slightly different memory.
SlurmdParameters=config_overrides
$node_line NodeAddr=127.0.0.1 NodeHostname=$host State=UNKNOWN
PartitionName=debug Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
    mv "$conf.tmp" "$conf"
    node=$host
}

# Sets $spool. slurmstepd listens on a Unix socket SPOOL/<node>_<jobid>.<stepid>, and a socket
# path longer than 107 bytes makes every job fail to launch ("launch failed requeued held").
# For a long DIR the spool directory is therefore /tmp/slurm-local-<checksum of DIR>, with a
# symlink DIR/spool pointing to it.
spool_dir() {
    spool=$dir/spool
    if [ $((${#spool} + ${#node} + 23)) -gt 107 ]; then
        spool=/tmp/slurm-local-$(printf '%s' "$dir" | cksum | cut -d' ' -f1)
        rm -rf "$dir/spool"
        ln -sfn "$spool" "$dir/spool"
        say "DIR is too long for slurmstepd's sockets; spool directory is $spool"
    fi
}

write_env() {
    cat >"$dir/env.sh" <<EOF
# Written by scripts/slurm-local.sh: source this to use the local test cluster.
export SLURM_CONF=$conf
EOF
}

# ---------------------------------------------------------------------------------------------
# Subcommands.

node_state() { sinfo -h -n "$node" -o '%T' 2>/dev/null | head -n 1; }

cluster_up() {
    pid_alive "$dir/slurmctld.pid" slurmctld >/dev/null && pid_alive "$dir/slurmd.pid" slurmd >/dev/null &&
        [ -s "$conf" ] && case $(node_state) in idle* | mixed* | allocated* | completing*) true ;; *) false ;; esac
}

cmd_start() {
    local t0 i pid state
    t0=$(date +%s)
    if ! have_slurm; then
        [ "$(id -u)" = 0 ] || skip "SLURM is not installed and we are not root (cannot apt-get install slurmctld slurmd slurm-client munge)"
        command -v apt-get >/dev/null 2>&1 || skip "SLURM is not installed and there is no apt-get"
        install_slurm
    fi
    [ "$(id -u)" = 0 ] || skip "slurm-local needs root (slurmd and munged run as root/munge)"
    if [ -s "$conf" ]; then
        node=$(sed -n 's/^SlurmctldHost=\([^(]*\).*/\1/p' "$conf")
        if cluster_up; then
            write_env
            say "already running (SLURM_CONF=$conf)"
            return 0
        fi
        # A leftover from a killed or half-started run: stop whatever of it still runs.
        say "cleaning up a previous run in $dir"
        cmd_stop quiet || true
    fi
    mkdir -p "$dir"
    # Another cluster (another DIR) on the same ports would answer our sinfo and look like us.
    local port
    for port in "$ctld_port" "$slurmd_port"; do
        if (exec 3<>"/dev/tcp/127.0.0.1/$port") 2>/dev/null; then
            die "port $port is in use (another slurmctld/slurmd? stop it, or set SLURM_LOCAL_CTLD_PORT/SLURM_LOCAL_SLURMD_PORT)"
        fi
    done
    start_munge
    # Fresh state each start: no jobs are recovered from a previous run.
    spool_dir
    rm -rf "$dir/state" "$spool"
    mkdir -p "$dir/state" "$spool"
    rm -f "$dir/slurmctld.pid" "$dir/slurmd.pid"
    write_conf
    write_env
    export SLURM_CONF=$conf
    # Both daemons fork into the background and write their pid files themselves. -i: ignore
    # (there is no) saved state. Their own output goes to DIR/*.out, their logs to DIR/*.log.
    slurmctld -i -f "$conf" </dev/null >>"$dir/slurmctld.out" 2>&1 || { show_logs; cmd_stop quiet || true; die "slurmctld failed to start"; }
    slurmd -f "$conf" -N "$node" </dev/null >>"$dir/slurmd.out" 2>&1 || { show_logs; cmd_stop quiet || true; die "slurmd failed to start"; }
    for i in $(seq 1 "$((wait_s * 2))"); do
        state=$(node_state || true)
        case $state in
            idle*) break ;;
            down* | drain*)
                # ReturnToService=2 should make a registered node usable; nudge it.
                scontrol update NodeName="$node" State=RESUME >/dev/null 2>&1 || true ;;
        esac
        if [ "$i" -gt 10 ]; then
            pid_alive "$dir/slurmctld.pid" slurmctld >/dev/null || { show_logs; cmd_stop quiet || true; die "slurmctld exited"; }
            pid_alive "$dir/slurmd.pid" slurmd >/dev/null || { show_logs; cmd_stop quiet || true; die "slurmd exited"; }
        fi
        sleep 0.5
    done
    if [ "${state:-}" != idle ] || ! pid_alive "$dir/slurmctld.pid" slurmctld >/dev/null ||
        ! pid_alive "$dir/slurmd.pid" slurmd >/dev/null; then
        show_logs
        sinfo -R >&2 2>/dev/null || true
        cmd_stop quiet || true
        die "node $node not idle after ${wait_s}s (state: ${state:-unknown})"
    fi
    pid=$(pid_alive "$dir/slurmctld.pid" slurmctld)
    say "up in $(($(date +%s) - t0)) s: node $node idle, slurmctld pid $pid, slurmd pid $(pid_alive "$dir/slurmd.pid" slurmd); source $dir/env.sh"
}

# stop [quiet]: cancel this cluster's jobs, then stop slurmd, slurmctld and (if ours) munged.
cmd_stop() {
    local quiet=${1:-} pids p i
    if [ ! -d "$dir" ]; then
        say "nothing to stop: $dir does not exist"
        return 0
    fi
    export SLURM_CONF=$conf
    # Cancel running jobs first so that their slurmstepd processes end cleanly.
    if pid_alive "$dir/slurmctld.pid" slurmctld >/dev/null && [ -n "$(timeout 20 squeue -h -o %i 2>/dev/null | head -n 1)" ]; then
        local u
        for u in $(squeue -h -o %u 2>/dev/null | sort -u); do scancel --quiet --user="$u" 2>/dev/null || true; done
        for i in $(seq 1 20); do
            [ -z "$(squeue -h -t PENDING,RUNNING,COMPLETING,CONFIGURING,SUSPENDED -o %i 2>/dev/null | head -n 1)" ] && break
            sleep 0.5
        done
    fi
    local rc=0
    # The daemons by their pid files, plus any process that carries our SLURM_CONF: a daemon
    # whose pid was never recorded, slurmctld's helper slurmscriptd, slurmstepd of jobs.
    # munged only if this script started it for DIR. All are signalled at once: each one that
    # exits has to be reaped by PID 1, which takes ~2 s in some sandboxes.
    pids=()
    p=$(pid_alive "$dir/slurmd.pid" slurmd) && pids+=("$p")
    p=$(pid_alive "$dir/slurmctld.pid" slurmctld) && pids+=("$p")
    p=$(pid_alive "$dir/munged.pid" munged) && pids+=("$p")
    while read -r p; do [ -n "$p" ] && pids+=("$p"); done < <(pids_with_conf slurmd slurmstepd slurmctld slurmscriptd)
    if [ ${#pids[@]} -gt 0 ]; then
        mapfile -t pids < <(printf '%s\n' "${pids[@]}" | sort -u)
        stop_pids "slurm daemons" "${pids[@]}" || rc=1
    fi
    rm -f "$dir/slurmd.pid" "$dir/slurmctld.pid" "$dir/munged.pid"
    [ "$quiet" = quiet ] || say "stopped ($dir)"
    return "$rc"
}

cmd_status() {
    [ -s "$conf" ] || die "no cluster in $dir (no slurm.conf)"
    export SLURM_CONF=$conf
    local rc=0
    sinfo || rc=1
    squeue || rc=1
    return "$rc"
}

[ $# -eq 2 ] || usage
sub=$1
[ "$sub" = start ] && { mkdir -p "$2" || die "cannot create directory $2"; }
if [ -d "$2" ]; then dir=$(cd "$2" && pwd); else dir=$2; fi
conf=$dir/slurm.conf
node=$(hostname -s)
case $sub in
    start) cmd_start ;;
    stop) cmd_stop ;;
    status) cmd_status ;;
    *) usage ;;
esac
