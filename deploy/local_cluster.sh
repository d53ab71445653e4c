#!/usr/bin/env bash
# N rve_servers on this machine, on loopback addresses only, a case run across
# them with mpm_client, then the servers stopped (SIGTERM) whatever happened.
#
#   deploy/local_cluster.sh N CASE.json OUT_DIR [mpm_client options...]
#
# Each server listens on 127.0.0.1:<free port> with SERVER_THREADS workers
# (default 1); their logs, addresses and process ids go to OUT_DIR/servers/
# (addresses: one HOST:PORT per line; pids: one per line, in the same order),
# so a test or a person can stop one (kill -9, kill -STOP) while the run
# goes on. mpm_client's exit status is the script's.
#
# Environment: RVEHUB_BUILD (build directory, default build), SERVER_THREADS.
set -euo pipefail

if [[ $# -lt 3 || ! "$1" =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: $0 N CASE.json OUT_DIR [mpm_client options...]" >&2
  exit 2
fi
n=$1 case_file=$2 out=$3
shift 3
build=${RVEHUB_BUILD:-build}
server=$build/rve_server/server/rve_server
client=$build/mpm_client/mpm_client
threads=${SERVER_THREADS:-1}
for b in "$server" "$client"; do
  [[ -x $b ]] || { echo "$0: $b is not built (bash deploy/build.sh)" >&2; exit 1; }
done

dir=$out/servers
mkdir -p "$dir"
: >"$dir/addresses"
: >"$dir/pids"
pids=()
# Running and not yet reaped (an exited child stays a zombie until waited for).
running() {
  local state=
  { read -r _ _ state _ </proc/"$1"/stat; } 2>/dev/null || return 1
  [[ $state != Z ]]
}
stop_servers() {
  for p in "${pids[@]}"; do
    kill -TERM "$p" 2>/dev/null || true
    kill -CONT "$p" 2>/dev/null || true  # a stopped server must see its SIGTERM
  done
  # Bounded: a server can miss its SIGTERM (one sent while the server was
  # still starting left it running, and the wait hung a test for 600 s);
  # after the drain grace it is killed.
  for ((t = 0; t < 100; t++)); do
    local left=0
    for p in "${pids[@]}"; do running "$p" && left=1; done
    ((left)) || break
    sleep 0.1
  done
  for p in "${pids[@]}"; do
    kill -KILL "$p" 2>/dev/null || true
    wait "$p" 2>/dev/null || true
  done
}
trap stop_servers EXIT

addresses=()
for ((i = 0; i < n; i++)); do
  # Emptied here, not by the redirection below: that happens in the child,
  # after this loop may already have read a previous run's address.
  : >"$dir/server-$i.out"
  "$server" --listen=127.0.0.1:0 --threads="$threads" --drain-seconds=5 \
    >"$dir/server-$i.out" 2>"$dir/server-$i.log" &
  pids+=($!)
  # The server's first stdout line: "listening on HOST:PORT" (bounded wait).
  address=
  for ((t = 0; t < 100; t++)); do
    address=$(sed -n 's/^listening on //p' "$dir/server-$i.out" 2>/dev/null | head -n 1)
    [[ -n $address ]] && break
    kill -0 "${pids[$i]}" 2>/dev/null || break
    sleep 0.1
  done
  if [[ -z $address ]]; then
    echo "$0: server $i did not start; its log:" >&2
    cat "$dir/server-$i.log" >&2
    exit 1
  fi
  addresses+=("$address")
  echo "$address" >>"$dir/addresses"
  echo "${pids[$i]}" >>"$dir/pids"
  echo "server $i: $address (pid ${pids[$i]})" >&2
done

list=$(IFS=,; echo "${addresses[*]}")
status=0
"$client" run "$case_file" --out="$out" --servers="$list" "$@" || status=$?
exit "$status"
