#!/bin/bash
# A real SLURM on this one machine: installs Debian's slurm-wlm and munge if they are missing, writes a minimal
# slurm.conf for this host (its hostname, CPUs and memory as `slurmd -C` finds them; no cgroups: proctrack/linuxproc,
# task/affinity), starts munged, slurmctld and slurmd, waits until `sinfo` shows the node idle, then submits the
# docs' recipe (experiments/slurm_evolve.sbatch, docs/scaling.md "A SLURM cluster") scaled to this machine with
# `sbatch`: 2 tasks of 1 CPU on this node, a tiny search. The job's two processes join through jax.distributed from
# SLURM's environment. The same command then runs as one process, and the script compares the two runs' history,
# top-k and every checkpoint bit for bit. On exit, whatever happens (an error, INT or TERM), the job is cancelled and
# the daemons are stopped.
#
#   bash experiments/slurm_local.sh [--result FILE]        # as root (or with passwordless sudo), from anywhere
#
# Environment: PYTHON (default .venv/bin/python, else python3: the jaxarm the job runs is the one beside it),
# WORK (default runs/slurm-local: logs and both runs, those of a previous run removed first), SLURM_LOCAL_ARGS (the
# scaled search's options), SLURM_LOCAL_TIME (the job's --time, default 00:20:00).
# Writes WORK/slurm_local.json (or --result FILE): command, date, machine, commit, the job's log, the comparison.
#
# Exit status: 0 the SLURM job gave the same bits as one process; 1 the bits differ; 2 the job or the one-process
# run failed; 77 SLURM cannot start here (not root and no passwordless sudo, no apt-get, the packages cannot be
# installed, a daemon does not start, the node never becomes idle): one line "slurm_local: cannot start SLURM: ...".
set -uo pipefail
invocation="bash experiments/slurm_local.sh${*:+ $*}"
cd "$(dirname "$0")/.."
repo=$(pwd)
result=""
while [ $# -gt 0 ]; do
  case "$1" in
    --result) result=$2; shift 2 ;;
    -h|--help) sed -n '2,/^set -uo/p' "$0" | sed '$d'; exit 0 ;;
    *) echo "slurm_local: unknown argument $1 (--result FILE)" >&2; exit 2 ;;
  esac
done

# --- root ----------------------------------------------------------------------------------------------------------
cannot() { echo "slurm_local: cannot start SLURM: $*"; exit 77; }
say() { echo "slurm_local: $*"; }
if [ "$(id -u)" = 0 ]; then sudo=""; as_munge=(runuser -u munge --)
elif command -v sudo >/dev/null && sudo -n true 2>/dev/null; then sudo="sudo -n"; as_munge=(sudo -n -u munge)
else cannot "not root and no passwordless sudo (the daemons run as root)"; fi
py=${PYTHON:-.venv/bin/python}
[ -x "$py" ] || py=$(command -v python3)
py=$(cd "$(dirname "$py")" && pwd)/$(basename "$py")
bin=$(dirname "$py")
[ -x "$bin/jaxarm" ] || { echo "slurm_local: no jaxarm beside $py (PYTHON=... names the environment's python)"
                         exit 2; }
work=${WORK:-runs/slurm-local}
mkdir -p "$work" || { echo "slurm_local: cannot create $work (WORK=... names another folder)"; exit 2; }
work=$(cd "$work" && pwd)
[ -n "$result" ] || result=$work/slurm_local.json
scaled=${SLURM_LOCAL_ARGS:---population 8 --seeds-per-candidate 2 --generations 2 --chunk 1 --train-s 0.5 --top-k 4}
job_time=${SLURM_LOCAL_TIME:-00:20:00}

# --- packages ------------------------------------------------------------------------------------------------------
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null || ! command -v sbatch >/dev/null \
    || ! command -v munged >/dev/null; then
  command -v apt-get >/dev/null || cannot "slurmctld/slurmd/munged are not installed and there is no apt-get"
  say "installing slurm-wlm and munge with apt-get (log: $work/apt.log)"
  export DEBIAN_FRONTEND=noninteractive
  if ! $sudo apt-get install -y --no-install-recommends slurm-wlm munge >"$work/apt.log" 2>&1; then
    $sudo apt-get update >>"$work/apt.log" 2>&1
    $sudo apt-get install -y --no-install-recommends slurm-wlm munge >>"$work/apt.log" 2>&1 \
      || cannot "apt-get install slurm-wlm munge failed: $(grep -E '^E:' "$work/apt.log" | head -1)" \
                "(log: $work/apt.log)"
  fi
  hash -r
fi
for tool in slurmctld slurmd sbatch sinfo scontrol munged munge unmunge; do
  command -v $tool >/dev/null || PATH=$PATH:/usr/sbin:/sbin
  command -v $tool >/dev/null || cannot "$tool not found after installing slurm-wlm and munge"
done
[ -r /etc/munge/munge.key ] || $sudo test -r /etc/munge/munge.key || cannot "no munge key /etc/munge/munge.key"

# --- the cluster's files -------------------------------------------------------------------------------------------
rm -rf "$work/slurm" "$work/one" "$work"/slurm-*.log "$work"/*.log.txt "$work"/sbatch.*
state=$(mktemp -d /tmp/jaxarm-slurm.XXXXXX) || cannot "mktemp -d failed"
pids=()      # the daemons', the job's sbatch and the one-process run's: stopped on exit
cleanup() {
  trap - EXIT INT TERM
  [ -z "${jobid:-}" ] && [ -s "$work/sbatch.out" ] && jobid=$(cut -d';' -f1 "$work/sbatch.out")
  if [ -n "${jobid:-}" ]; then     # the job's processes end before the daemons that watch them
    SLURM_CONF=$state/slurm.conf scancel "$jobid" 2>/dev/null
    for _ in $(seq 60); do
      st=$(SLURM_CONF=$state/slurm.conf squeue -h -j "$jobid" -o %T 2>/dev/null)
      case "$st" in *RUNNING*|*COMPLETING*|*PENDING*|*CONFIGURING*|*SUSPENDED*) sleep 0.5 ;; *) break ;; esac
    done
    # what SLURM did not end (its daemons gone first): the job's processes, found by its own output folder
    for p in $(pgrep -f -- "--out $work/slurm" 2>/dev/null); do $sudo kill -9 "$p" 2>/dev/null; done
  fi
  for f in "$state/slurmd.pid" "$state/slurmctld.pid" "$state/munge/munged.pid"; do
    [ -s "$f" ] && pids+=("$(cat "$f")")
  done
  for p in "${pids[@]}"; do $sudo kill "$p" 2>/dev/null; done
  for _ in 1 2 3 4 5 6 7 8 9 10; do
    alive=""; for p in "${pids[@]}"; do kill -0 "$p" 2>/dev/null && alive=1; done
    [ -z "$alive" ] && break; sleep 0.5
  done
  for p in "${pids[@]}"; do $sudo kill -9 "$p" 2>/dev/null; done
  $sudo cp "$state/slurm.conf" "$state/munge/munged.log" "$work/daemons/" 2>/dev/null
  $sudo rm -rf "$state"
}
trap cleanup EXIT
trap 'exit 130' INT TERM
chmod 755 "$state"
mkdir -p "$state/munge" "$state/ctld" "$state/spool" "$work/daemons"
$sudo chown munge:munge "$state/munge" 2>/dev/null || $sudo chown munge "$state/munge" || cannot "no munge user"
chmod 755 "$work/daemons" 2>/dev/null

free_port() { "$py" -c 'import socket; s = socket.socket(); s.bind(("", 0)); print(s.getsockname()[1])'; }
host=$(hostname -s)
getent hosts "$host" >/dev/null || cannot "this host's name $host does not resolve (add it to /etc/hosts)"
node=$(slurmd -C 2>/dev/null | head -1)
case "$node" in NodeName=*" CPUs="*) ;; *) cannot "slurmd -C does not describe this machine: $node" ;; esac
cpus=$(sed -E 's/.* CPUs=([0-9]+).*/\1/' <<<"$node")
[ "$cpus" -ge 2 ] || cannot "this machine has $cpus CPU; the recipe scaled to it runs 2 tasks of 1 CPU"
ctld_port=$(free_port); slurmd_port=$(free_port)
while [ "$slurmd_port" = "$ctld_port" ]; do slurmd_port=$(free_port); done
cat >"$state/slurm.conf" <<EOF
# one-machine SLURM written by experiments/slurm_local.sh
ClusterName=jaxarm-local
SlurmctldHost=$host
SlurmctldPort=$ctld_port
SlurmdPort=$slurmd_port
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$state/munge/munge.socket
StateSaveLocation=$state/ctld
SlurmdSpoolDir=$state/spool
SlurmctldPidFile=$state/slurmctld.pid
SlurmdPidFile=$state/slurmd.pid
SlurmctldLogFile=$work/daemons/slurmctld.log
SlurmdLogFile=$work/daemons/slurmd.log
# no cgroups (a container may not have them): processes tracked through /proc, tasks pinned to their CPUs
ProctrackType=proctrack/linuxproc
TaskPlugin=task/affinity
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
SchedulerType=sched/backfill
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
MpiDefault=none
MailProg=/bin/true
ReturnToService=2
SlurmctldTimeout=60
SlurmdTimeout=60
InactiveLimit=0
KillWait=5
MinJobAge=600
$node
PartitionName=local Nodes=$host Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF=$state/slurm.conf

# --- the daemons ---------------------------------------------------------------------------------------------------
say "starting munged, slurmctld and slurmd (state: $state; logs: $work/daemons)"
"${as_munge[@]}" munged --force --socket="$state/munge/munge.socket" --pid-file="$state/munge/munged.pid" \
  --log-file="$state/munge/munged.log" --seed-file="$state/munge/munged.seed" >"$work/daemons/munged.out" 2>&1 \
  || cannot "munged does not start: $(tail -1 "$work/daemons/munged.out")"
for _ in $(seq 20); do [ -S "$state/munge/munge.socket" ] && break; sleep 0.25; done
munge -n --socket="$state/munge/munge.socket" | unmunge --socket="$state/munge/munge.socket" >/dev/null 2>&1 \
  || cannot "munge does not answer on $state/munge/munge.socket"
$sudo slurmctld -D -f "$state/slurm.conf" >"$work/daemons/slurmctld.out" 2>&1 &
pids+=($!)
$sudo slurmd -D -f "$state/slurm.conf" >"$work/daemons/slurmd.out" 2>&1 &
pids+=($!)
idle=""
for _ in $(seq 60); do
  states=$(sinfo -h -N -o '%T' 2>/dev/null | sort -u | tr '\n' ' ')
  case "$states" in idle*) idle=1; break ;; esac
  for p in "${pids[@]}"; do kill -0 "$p" 2>/dev/null || break 2; done
  sleep 1
done
if [ -z "$idle" ]; then
  why=$(cat "$work/daemons/slurmctld.out" "$work/daemons/slurmd.out" "$work/daemons/slurmctld.log" \
        "$work/daemons/slurmd.log" 2>/dev/null | grep -iE 'error|fatal' | tail -1)
  cannot "the node is not idle after 60 s (sinfo: ${states:-no answer}; ${why:-no error logged})"
fi
say "sinfo: $(sinfo -h -o '%P %a %D %T %c CPUs %N' | head -1)"

# --- the recipe under sbatch, then the same command as one process -------------------------------------------------
export PATH=$bin:$PATH
# what the jaxarm command imports (from /, as its entry script does not see the working folder)
jaxarm_from=$(cd / && "$py" -c 'import os, jaxarm; print(os.path.dirname(jaxarm.__file__))' 2>/dev/null)
say "jaxarm: $bin/jaxarm, importing $jaxarm_from"
# shellcheck disable=SC2206
extra=($scaled)
submit=(sbatch --parsable --wait --nodes=1 --ntasks-per-node=2 --cpus-per-task=1 --time="$job_time"
        --output="$work/slurm-%j.log" experiments/slurm_evolve.sbatch "${extra[@]}" --out "$work/slurm")
say "${submit[*]}"
started=$(date +%s)
"${submit[@]}" >"$work/sbatch.out" 2>"$work/sbatch.err" &     # waited for, so that a signal stops it at once
pids+=($!)
wait $!
job_rc=$?
jobid=$(cut -d';' -f1 "$work/sbatch.out" 2>/dev/null)
job_s=$(( $(date +%s) - started ))
if [ -z "$jobid" ]; then
  say "sbatch did not submit the job (status $job_rc): $(head -3 "$work/sbatch.err")"
  exit 2
fi
job_log=$work/slurm-$jobid.log
say "job $jobid ended with status $job_rc after $job_s s; its log ($job_log):"
sed 's/^/    /' "$job_log" 2>/dev/null
[ -s "$work/sbatch.err" ] && sed 's/^/    sbatch: /' "$work/sbatch.err"
sacct_line=$(scontrol show job "$jobid" 2>/dev/null | grep -oE 'JobState=[A-Z_]+|ExitCode=[0-9:]+|NumTasks=[0-9]+' \
             | tr '\n' ' ')
say "scontrol: ${sacct_line:-(job record gone)}"
[ "$job_rc" = 0 ] || { say "the job failed (its log above); not comparing"; exit 2; }
# the recipe's command without srun and "$@" (its two lines joined)
recipe=$(grep -E '^srun ' -A1 experiments/slurm_evolve.sbatch | sed -E 's/^srun //; s/ *\\$//; s/"\$@"//' \
         | tr -s ' \n' '  ')
# shellcheck disable=SC2206
one_cmd=($recipe "${extra[@]}" --out "$work/one")
say "one process: ${one_cmd[*]}"
started=$(date +%s)
env -u SLURM_CONF "${one_cmd[@]}" >"$work/one.log.txt" 2>&1 &
pids+=($!)
wait $!
one_rc=$?
one_s=$(( $(date +%s) - started ))
say "one process ended with status $one_rc after $one_s s"
[ "$one_rc" = 0 ] || tail -20 "$work/one.log.txt" | sed 's/^/    /'

"$py" experiments/slurm_local_compare.py --slurm "$work/slurm" --one "$work/one" --job-log "$job_log" \
  --one-log "$work/one.log.txt" --result "$result" --job-id "$jobid" --job-rc "$job_rc" --one-rc "$one_rc" \
  --job-s "$job_s" --one-s "$one_s" --submit "${submit[*]}" --one-command "${one_cmd[*]}" \
  --sinfo "$(sinfo -h -o '%P %a %D %T %c CPUs %N' | head -1)" --scontrol "$sacct_line" --slurm-version "$(sinfo -V)" \
  --jaxarm "$jaxarm_from" --command "$invocation"
exit $?
