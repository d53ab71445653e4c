#!/usr/bin/env bash
# deploy/slurm/rvehub.sbatch under a real Slurm, on this machine alone: a
# private munged, slurmctld and one slurmd per node (n1..nN, each on its own
# loopback address 127.0.0.2.., its own port), the case submitted with sbatch
# across N servers, and its timeseries.csv compared byte for byte with an
# embedded run's (mpm_client run CASE without --servers).
#
#   deploy/slurm/local_slurm_test.sh [CASE.json]   (default cases/footing-dense-ci.json)
#
# Everything it starts (daemons, the job, its servers) is stopped and its
# temporary directory removed on exit, also on failure or interruption.
# Exit 0 equal, 1 different or failed, 77 when Slurm or munge cannot be had
# or started (not root, no package mirror): CTest reports that as skipped.
#
# Environment: RVEHUB_BUILD (build directory, default build), SLURM_TEST_NODES
# (default 3), SLURM_TEST_KEEP=1 keeps the temporary directory (daemons are
# stopped all the same).
set -euo pipefail
cd "$(dirname "$0")/../.."
repo=$(pwd)

case_file=${1:-cases/footing-dense-ci.json}
build=$(cd "${RVEHUB_BUILD:-build}" && pwd)
nodes=${SLURM_TEST_NODES:-3}
client=$build/mpm_client/mpm_client
for b in "$client" "$build/rve_server/server/rve_server" "$build/rve_server/cli/rve_cli"; do
  [[ -x $b ]] || { echo "local_slurm_test: $b is not built" >&2; exit 1; }
done
[[ $nodes =~ ^[1-9]$ ]] || { echo "local_slurm_test: SLURM_TEST_NODES must be 1..9" >&2; exit 2; }

skip() {
  echo "local_slurm_test: $*: skipped" >&2
  exit 77
}

# --- Slurm and munge: Debian's packages, installed when missing (as root).
if ! command -v slurmctld >/dev/null || ! command -v slurmd >/dev/null ||
   ! command -v sbatch >/dev/null || ! command -v munged >/dev/null; then
  [[ $(id -u) -eq 0 ]] || skip "slurmctld, slurmd, sbatch or munged missing and not root"
  command -v apt-get >/dev/null || skip "slurmctld, slurmd, sbatch or munged missing and no apt-get"
  echo "local_slurm_test: installing slurmctld slurmd slurm-client munge" >&2
  if ! { apt-get update -qq &&
         DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
           slurmctld slurmd slurm-client munge; } >/tmp/local_slurm_test-apt.log 2>&1; then
    tail -n 5 /tmp/local_slurm_test-apt.log >&2
    skip "cannot install Slurm and munge with apt-get"
  fi
fi
# The daemons below run as root (SlurmUser=root), as the jobs' user must be
# the submitter's and slurmd starts them.
[[ $(id -u) -eq 0 ]] || skip "slurmd must run as root to start jobs"

tmp=$(mktemp -d /tmp/rvehub-slurm.XXXXXX)
chmod 700 "$tmp"
pids=()     # daemons we started, stopped in reverse order
job=

# Running and not yet reaped.
running() {
  local state=
  { read -r _ _ state _ </proc/"$1"/stat; } 2>/dev/null || return 1
  [[ $state != Z ]]
}
# Processes that hold something under $tmp open, or run from it, or name it
# on their command line: what a killed slurmd can leave behind (slurmstepd,
# the job's servers). Only ours can: the directory is new and private.
leftovers() {
  local p
  for p in /proc/[0-9]*; do
    p=${p#/proc/}
    [[ $p == "$$" || $p == "$BASHPID" ]] && continue
    if tr '\0' ' ' 2>/dev/null <"/proc/$p/cmdline" | grep -qF "$tmp" ||
       [[ $(readlink "/proc/$p/cwd" 2>/dev/null) == "$tmp"* ]] ||
       find "/proc/$p/fd" -maxdepth 1 -lname "$tmp/*" 2>/dev/null | grep -q .; then
      echo "$p"
    fi
  done
}
cleanup() {
  local status=$? p t
  set +e
  trap - EXIT INT TERM
  if [[ -n $job ]]; then
    scancel "$job" 2>/dev/null
    for ((t = 0; t < 100; t++)); do  # bounded: 10 s for the job's steps to end
      squeue -h -j "$job" 2>/dev/null | grep -q . || break
      sleep 0.1
    done
  fi
  for ((i = ${#pids[@]} - 1; i >= 0; i--)); do kill -TERM "${pids[$i]}" 2>/dev/null; done
  for ((t = 0; t < 50; t++)); do
    local left=0
    for p in "${pids[@]}"; do running "$p" && left=1; done
    ((left)) || break
    sleep 0.1
  done
  for p in "${pids[@]}"; do
    kill -KILL "$p" 2>/dev/null
    wait "$p" 2>/dev/null
  done
  for ((t = 0; t < 5; t++)); do  # bounded: a killed process may take a moment to go
    local left=
    left=$(leftovers)
    [[ -z $left ]] && break
    for p in $left; do
      echo "local_slurm_test: killing leftover process $p: $(tr '\0' ' ' 2>/dev/null <"/proc/$p/cmdline")" >&2
      kill -KILL "$p" 2>/dev/null
    done
    sleep 1
  done
  if ((status != 0 && status != 77)); then
    for f in "$tmp"/log/*.log "$tmp"/job.out "$tmp"/slurm/servers/*.log; do
      [[ -f $f ]] || continue
      echo "--- $f (last lines)" >&2
      tail -n 15 "$f" >&2
    done
  fi
  if [[ ${SLURM_TEST_KEEP:-0} == 1 ]]; then
    echo "local_slurm_test: kept $tmp" >&2
  else
    rm -rf "$tmp"
  fi
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

# Free TCP ports (slurmd binds all addresses, so each slurmd needs its own).
mapfile -t ports < <(/usr/bin/python3 - "$((nodes + 1))" <<'EOF'
import socket, sys
socks = []
for _ in range(int(sys.argv[1])):
    s = socket.socket()
    s.bind(("", 0))
    socks.append(s)
for s in socks:
    print(s.getsockname()[1])
EOF
)

# --- munge: a private key and socket.
mkdir -m 700 "$tmp/munge" "$tmp/log" "$tmp/state" "$tmp/spool"
head -c 1024 /dev/urandom >"$tmp/munge/munge.key"
chmod 400 "$tmp/munge/munge.key"
socket=$tmp/munge/munge.socket
munged --foreground --force --socket="$socket" --key-file="$tmp/munge/munge.key" \
  --pid-file="$tmp/munge/munged.pid" --log-file="$tmp/log/munged.log" \
  --seed-file="$tmp/munge/munge.seed" >"$tmp/log/munged.out" 2>&1 &
pids+=($!)
for ((t = 0; t < 50; t++)); do [[ -S $socket ]] && break; sleep 0.1; done
[[ -S $socket ]] || { cat "$tmp/log/munged.out" >&2; skip "munged did not start"; }

# --- slurm.conf: nodes n1..nN at 127.0.0.2.., one port each; no cgroups, no
# accounting, everything under $tmp.
conf=$tmp/slurm.conf
{
  cat <<EOF
ClusterName=rvehubtest
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=${ports[0]}
AuthType=auth/munge
CredType=cred/munge
AuthInfo=socket=$socket
SlurmUser=root
SlurmdUser=root
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool/%n
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd-%n.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd-%n.log
SlurmctldDebug=info
SlurmdDebug=info
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
SwitchType=switch/none
SchedulerType=sched/builtin
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
SlurmdParameters=config_overrides
ReturnToService=2
MailProg=/bin/true
PlugStackConfig=$tmp/plugstack.conf
EOF
  for ((i = 1; i <= nodes; i++)); do
    echo "NodeName=n$i NodeAddr=127.0.0.$((i + 1)) Port=${ports[$i]} CPUs=2 RealMemory=1000 State=UNKNOWN"
  done
  echo "PartitionName=test Nodes=n[1-$nodes] Default=YES MaxTime=30 State=UP"
} >"$conf"
: >"$tmp/plugstack.conf"
export SLURM_CONF=$conf

slurmctld -D -i -f "$conf" >"$tmp/log/slurmctld.out" 2>&1 &
pids+=($!)
for ((i = 1; i <= nodes; i++)); do
  slurmd -D -N "n$i" -f "$conf" >"$tmp/log/slurmd-n$i.out" 2>&1 &
  pids+=($!)
done
# Bounded: every node idle within 30 s.
up=0
for ((t = 0; t < 150; t++)); do
  states=$(sinfo -h -N -o '%T' 2>/dev/null | sort | uniq -c | tr -s ' ' || true)
  if [[ $(sinfo -h -N -t idle -o '%N' 2>/dev/null | wc -l) -eq $nodes ]]; then up=1; break; fi
  sleep 0.2
done
if ((!up)); then
  echo "local_slurm_test: node states: ${states:-none}" >&2
  for f in "$tmp"/log/*; do echo "--- $f" >&2; tail -n 10 "$f" >&2; done
  skip "Slurm did not come up on this machine"
fi
echo "local_slurm_test: Slurm up: $nodes nodes ($(sinfo -h -N -o '%N@%o' | tr '\n' ' '))" >&2

# --- the job, and the embedded run while it is queued/running would share
# the 2 cores: run the embedded one first.
start=$SECONDS
"$client" run "$case_file" --out="$tmp/embedded" >"$tmp/embedded.log" 2>&1 ||
  { tail -n 20 "$tmp/embedded.log" >&2; echo "local_slurm_test: the embedded run failed" >&2; exit 1; }
echo "local_slurm_test: embedded run: $((SECONDS - start)) s" >&2

start=$SECONDS
job=$(RVEHUB_BUILD=$build RVEHUB_PORT=0 sbatch --parsable --nodes="$nodes" --cpus-per-task=1 \
        --time=5 --chdir="$repo" --output="$tmp/job.out" \
        deploy/slurm/rvehub.sbatch "$case_file" "$tmp/slurm")
job=${job%%;*}
echo "local_slurm_test: submitted job $job" >&2
state=
for ((t = 0; t < 750; t++)); do  # bounded: 150 s
  state=$(scontrol show job "$job" 2>/dev/null | sed -n 's/.*JobState=\([A-Z_]*\).*/\1/p')
  case $state in
    COMPLETED | FAILED | CANCELLED | TIMEOUT | NODE_FAIL | OUT_OF_MEMORY | PREEMPTED | BOOT_FAIL | DEADLINE) break ;;
  esac
  sleep 0.2
done
echo "local_slurm_test: job $job: ${state:-unknown} after $((SECONDS - start)) s" >&2
if [[ $state != COMPLETED ]]; then
  echo "--- job output" >&2
  cat "$tmp/job.out" >&2 2>/dev/null
  exit 1
fi
job=
grep -h 'servers ' "$tmp/job.out" >&2 || true

# The servers: one per node, each on its node's own address.
servers=$(sed -n 's/^rvehub.sbatch: servers //p' "$tmp/job.out")
bad=$(tr ',' '\n' <<<"$servers" | grep -cv '^127\.' || true)
count=$(tr ',' '\n' <<<"$servers" | grep -c . || true)
if [[ $count -ne $nodes || $bad -ne 0 ]]; then
  echo "local_slurm_test: expected $nodes servers on loopback addresses, got: $servers" >&2
  exit 1
fi
# The servers were stopped with SIGTERM (drained, checkpoint written), not
# killed.
for ((i = 1; i <= nodes; i++)); do
  if ! grep -q 'msg=stopped' "$tmp/slurm/servers/n$i.log"; then
    echo "local_slurm_test: the server on n$i was not stopped by SIGTERM (no drain)" >&2
    exit 1
  fi
done

# timeseries.csv byte for byte, less its one column that measures the
# machine (wall_per_step_s, mpm_client/README.md).
strip_wall() {
  awk -F, -v OFS=, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "wall_per_step_s") w = i }
                    { if (w) { for (i = w; i < NF; i++) $i = $(i + 1); NF-- } print }' "$1"
}
strip_wall "$tmp/embedded/timeseries.csv" >"$tmp/embedded.csv"
strip_wall "$tmp/slurm/timeseries.csv" >"$tmp/slurm.csv"
if [[ $(head -n 1 "$tmp/embedded.csv") == "$(head -n 1 "$tmp/embedded/timeseries.csv")" ]]; then
  echo "local_slurm_test: no wall_per_step_s column in timeseries.csv" >&2
  exit 1
fi
if ! cmp "$tmp/embedded.csv" "$tmp/slurm.csv"; then
  echo "local_slurm_test: timeseries.csv differs from the embedded run's" >&2
  exit 1
fi
echo "local_slurm_test: timeseries.csv equal to the embedded run's but for wall_per_step_s" \
     "($(wc -l <"$tmp/slurm.csv") lines, sha256 $(sha256sum <"$tmp/slurm.csv" | cut -c1-16))" \
     "with $nodes servers: $servers" >&2
