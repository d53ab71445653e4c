#!/usr/bin/env bash
# A drained biaxial test run by an rve_server: starts a server on a free
# loopback port, prepares SPFEM-biaxial (seed 1) into a template file, uploads
# it, runs the test on the server and writes out/server/biaxial.{csv,png}.
# The server is stopped with SIGTERM on exit. Assumes a build in
# ${BUILD_DIR:-build} (bash deploy/build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
build="${BUILD_DIR:-build}"
cli="${build}/rve_server/cli/rve_cli"
out=out/server
mkdir -p "${out}"

# Port 0: the server picks a free port and prints "listening on HOST:PORT".
# The file is emptied here: the redirection below happens in the child, maybe
# after the loop has read a previous run's address (or found no file).
: >"${out}/server.stdout"
"${build}/rve_server/server/rve_server" --listen=127.0.0.1:0 \
  >"${out}/server.stdout" 2>"${out}/server.log" &
server_pid=$!
# Running and not yet reaped (as deploy/local_cluster.sh's running).
running() {
  local state=
  { read -r _ _ state _ </proc/"$1"/stat; } 2>/dev/null || return 1
  [[ $state != Z ]]
}
# Stopped with SIGTERM, killed if still running after 10 s (bounded exit).
stop_server() {
  kill -TERM "${server_pid}" 2>/dev/null || return 0
  for _ in $(seq 100); do
    running "${server_pid}" || break
    sleep 0.1
  done
  kill -KILL "${server_pid}" 2>/dev/null || true
  wait "${server_pid}" 2>/dev/null || true
}
trap stop_server EXIT
address=""
for _ in $(seq 100); do
  address=$(sed -n 's/^listening on //p' "${out}/server.stdout")
  [[ -n "${address}" ]] && break
  kill -0 "${server_pid}" 2>/dev/null || { cat "${out}/server.log" >&2; exit 1; }
  sleep 0.1
done
[[ -n "${address}" ]] || { echo "rve_server did not report its address" >&2; exit 1; }
echo "== rve_server on ${address} (log: ${out}/server.log)"

"${cli}" prepare --material=SPFEM-biaxial --seed=1 --out="${out}/template.h5"
"${cli}" upload-template --server="${address}" --file="${out}/template.h5"
# guo-et-al-spfem-dem §3.2: peak ≈ 280 kPa at ≈ 1.8 % axial strain, then softening.
"${cli}" element-test --server="${address}" --template=SPFEM-biaxial-seed1 \
  --test=drained-biaxial --confining=100000 --strain=0.1 \
  --out="${out}/biaxial.csv" --plot="${out}/biaxial.png"
"${cli}" info --server="${address}"
echo "results in ${out}/"
