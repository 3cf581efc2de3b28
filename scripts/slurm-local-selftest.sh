#!/usr/bin/env bash
# Smoke test of scripts/slurm-local.sh against a real single-node SLURM cluster:
#   bash scripts/slurm-local-selftest.sh [DIR]
# 1. start (installs SLURM with apt-get when missing), 2. an 8-task job array, 3. cancelling
# array tasks and finding the tasks that did not finish from the result files, 4. common sbatch
# options, 5. stop leaves no daemons, 6. start/stop idempotence and recovery from killed
# daemons. Prints "N passed, M failed" and exits 1 if anything failed. When SLURM cannot be
# run here (not root, or missing and no apt-get) it prints the reason and exits 0.
# DIR defaults to a new directory under /tmp, which is removed at the end when everything passed.
set -uo pipefail
here=$(cd "$(dirname "$0")" && pwd)
sl=$here/slurm-local.sh
made_dir=0
if [ $# -ge 1 ]; then dir=$1; else dir=$(mktemp -d /tmp/slurm-selftest.XXXXXX) && made_dir=1; fi
mkdir -p "$dir"
dir=$(cd "$dir" && pwd)
passed=0
failed=0

ok() { passed=$((passed + 1)); echo "ok   - $*"; }
fail() { failed=$((failed + 1)); echo "FAIL - $*"; }
check() { # check DESCRIPTION COMMAND...
    local d=$1
    shift
    if "$@"; then ok "$d"; else fail "$d"; fi
}
now() { date +%s.%N; }
since() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }

# Polls squeue until job $1 has no pending/running/completing task left (at most $2 seconds).
# squeue -j shows only active states by default; once the record is purged (MinJobAge) it
# prints nothing on stdout and "Invalid job id" on stderr, which also means "done".
wait_job() {
    local j=$1 limit=$2 t0
    t0=$(date +%s)
    while [ -n "$(squeue -h -j "$j" -o %i 2>/dev/null)" ]; do
        [ $(($(date +%s) - t0)) -ge "$limit" ] && return 1
        sleep 0.5
    done
}

# The driver's way to learn which tasks did not finish: the result file of each task index
# it submitted. Prints the missing indices.
missing_tasks() { # missing_tasks PREFIX FIRST LAST
    local i
    for i in $(seq "$2" "$3"); do [ -s "$1$i" ] || printf '%s ' "$i"; done
}

no_daemons() {
    local d
    for d in slurmctld slurmd slurmstepd; do
        if pgrep -x "$d" >/dev/null; then return 1; fi
    done
    # munged is only required gone if none was running before we started.
    if [ -z "$munge_before" ] && pgrep -x munged >/dev/null; then return 1; fi
    return 0
}

munge_before=$(pgrep -x munged || true)
cleanup() { bash "$sl" stop "$dir" >/dev/null 2>&1 || true; }
trap cleanup EXIT

# ---- 1. start from scratch
t0=$(now)
bash "$sl" start "$dir"
rc=$?
if [ "$rc" = 77 ]; then
    echo "slurm-local-selftest: skipped (see the SKIP line above)"
    trap - EXIT
    [ "$made_dir" = 1 ] && rm -rf "$dir"
    exit 0
fi
t_start=$(since "$t0")
check "start exits 0 (took ${t_start} s)" [ "$rc" = 0 ]
if [ "$rc" != 0 ]; then
    echo "$passed passed, $((failed + 1)) failed"
    exit 1
fi
# shellcheck disable=SC1091
source "$dir/env.sh"
check "env.sh sets SLURM_CONF" [ "$SLURM_CONF" = "$dir/slurm.conf" ]
check "sinfo shows the node idle" [ "$(sinfo -h -o %T | head -n 1)" = idle ]
check "pid files name live daemons" kill -0 "$(cat "$dir/slurmctld.pid")" "$(cat "$dir/slurmd.pid")"

work=$dir/work
mkdir -p "$work"
cd "$work" || exit 1

# ---- 2. an 8-task array
t0=$(now)
j=$(sbatch --parsable --array=0-7 --output="$work/out_%A_%a.txt" \
    --wrap "sleep 2; echo \$SLURM_ARRAY_TASK_ID > $work/done_\$SLURM_ARRAY_TASK_ID")
check "sbatch --array=0-7 returns a job id ($j)" [ -n "$j" ]
check "array drains from squeue within 120 s" wait_job "$j" 120
t_array=$(since "$t0")
check "all 8 tasks wrote their result (took ${t_array} s)" [ -z "$(missing_tasks "$work/done_" 0 7)" ]
check "task 5 wrote its index" [ "$(cat "$work/done_5" 2>/dev/null)" = 5 ]
check "jobcomp.txt lists 8 COMPLETED tasks of the array" \
    [ "$(grep -c "ArrayJobId=$j .*ExitCode=0:0" "$dir/jobcomp.txt")" = 8 ]

# ---- 3. cancel array tasks while the array runs
mkdir -p "$work/c"
j=$(sbatch --parsable --array=0-7 --output="$work/c/out_%A_%a.txt" \
    --wrap "sleep 3; echo \$SLURM_ARRAY_TASK_ID > $work/c/done_\$SLURM_ARRAY_TASK_ID")
for _ in $(seq 1 60); do
    [ "$(squeue -h -j "${j}_0" -o %t 2>/dev/null)" = R ] && break
    sleep 0.25
done
check "task 0 is running" [ "$(squeue -h -j "${j}_0" -o %t 2>/dev/null)" = R ]
scancel "${j}_3" # pending at this point (2 CPUs: tasks 0 and 1 run)
scancel "${j}_0" # running
sleep 1
# -r: one line per array task, also for pending ones. A pending task that is cancelled
# disappears at once (no CA line); a running one shows CA (-t all) until MinJobAge.
check "squeue -r no longer lists task 3" bash -c "! squeue -h -r -t all -j $j -o %i | grep -qx ${j}_3"
check "squeue -t all shows task 0 cancelled (CA)" [ "$(squeue -h -t all -j "${j}_0" -o %t 2>/dev/null)" = CA ]
check "the other tasks complete within 120 s" wait_job "$j" 120
check "result files show exactly tasks 0 and 3 missing" [ "$(missing_tasks "$work/c/done_" 0 7)" = "0 3 " ]
# Finished tasks stay in slurmctld's memory for MinJobAge (30 s) or a little longer.
# -o: one line per array task.
sc=$(scontrol -o show job "$j" 2>&1)
if grep 'ArrayTaskId=0 ' <<<"$sc" | grep -q ' JobState=CANCELLED '; then
    ok "scontrol show job lists task 0 CANCELLED"
else
    fail "scontrol show job lists task 0 CANCELLED"
    grep -oE '^JobId=[0-9]+ ArrayJobId=[0-9]+ ArrayTaskId=[^ ]+|JobState=[A-Z_]+' <<<"$sc"
fi
check "jobcomp.txt records task 0 as CANCELLED" grep -q "JobState=CANCELLED .*ArrayJobId=$j ArrayTaskId=0 " "$dir/jobcomp.txt"
check "sacct does not work (no accounting storage)" bash -c '! sacct -n -j '"$j"' >/dev/null 2>&1'

# ---- 4. sbatch options a driver uses
mkdir -p "$work/cd"
j=$(sbatch --parsable --cpus-per-task=1 --time=00:10:00 --partition=debug --chdir="$work/cd" \
    --output="$work/cd/out.txt" --wrap 'pwd > pwd.txt')
check "sbatch --cpus-per-task --time --partition --chdir accepted ($j)" [ -n "$j" ]
check "that job ends within 60 s" wait_job "$j" 60
check "--chdir is the job's working directory" [ "$(cat "$work/cd/pwd.txt" 2>/dev/null)" = "$work/cd" ]
check "--time is the job's limit" bash -c "scontrol show job $j | grep -q TimeLimit=00:10:00"

# ---- 5. stop
cd "$dir" || exit 1
t0=$(now)
bash "$sl" stop "$dir"
rc=$?
t_stop=$(since "$t0")
check "stop exits 0 (took ${t_stop} s)" [ "$rc" = 0 ]
check "no slurmctld/slurmd/slurmstepd (nor munged we started) left" no_daemons
pgrep -a slurm
pgrep -a munge

# ---- 6. idempotence, leftovers
check "stop again is a no-op" bash "$sl" stop "$dir"
t0=$(now)
check "second start exits 0" bash "$sl" start "$dir"
t_restart=$(since "$t0")
check "start when already up exits 0" bash "$sl" start "$dir"
check "status exits 0" bash -c "bash '$sl' status '$dir' >/dev/null"
kill -KILL "$(cat "$dir/slurmctld.pid")" "$(cat "$dir/slurmd.pid")" 2>/dev/null
sleep 1
check "start after the daemons were killed (-9) exits 0" bash "$sl" start "$dir"
check "node idle after that" [ "$(sinfo -h -o %T | head -n 1)" = idle ]
check "second stop exits 0" bash "$sl" stop "$dir"
check "no daemons left after the second cycle" no_daemons

echo "times: start ${t_start} s (restart ${t_restart} s), 8-task array ${t_array} s, stop ${t_stop} s"
if [ "$failed" = 0 ]; then
    [ "$made_dir" = 1 ] && rm -rf "$dir"
else
    echo "kept $dir for inspection"
fi
echo "$passed passed, $failed failed"
[ "$failed" = 0 ]
