#!/usr/bin/env bash
# Builds deploy/Dockerfile with podman (daemonless) where no image registry is
# reachable and runs the default job in the image: the base image is made
# with debootstrap from the machine's Debian mirror and imported; the job's
# timeseries.csv is compared with the host build's (byte for byte but for the
# wall-clock column) when that build has mpm_client.
#
#   deploy/container_test.sh          (as root; 23-27 min on 2 cores, mostly the image's build)
#
# Everything podman writes (images, containers, layers) lives in a private
# storage directory under a new temporary directory, removed at the end,
# also on failure. The build uses the host's network (--network=host: apt in
# the build stage; no bridge, no firewall rules), the job none.
# Exit 0 ran (and equal), 1 failed, 77 when podman or debootstrap cannot be
# had (not root, no mirror).
#
# Environment: RVEHUB_BUILD (host build to compare with, default build),
# CONTAINER_BASE_TAR (a debootstrap root file system as a tar, made and kept
# there when missing; default RVEHUB_BUILD/container/base.tar),
# CONTAINER_KEEP=1 keeps the temporary directory.
set -euo pipefail
cd "$(dirname "$0")/.."
repo=$(pwd)
build=${RVEHUB_BUILD:-build}
base_tar=${CONTAINER_BASE_TAR:-$build/container/base.tar}

skip() {
  echo "container_test: $*: skipped" >&2
  exit 77
}
[[ $(id -u) -eq 0 ]] || skip "needs root (debootstrap, podman's storage)"
# runc: Debian's podman runs crun, which refuses a host with cgroups v1 and
# v2 mounted side by side ("cgroups in hybrid mode not supported").
if ! command -v podman >/dev/null || ! command -v debootstrap >/dev/null ||
   ! command -v runc >/dev/null; then
  echo "container_test: installing podman runc debootstrap" >&2
  { apt-get update -qq &&
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq podman runc debootstrap; } \
    >/tmp/container_test-apt.log 2>&1 || skip "cannot install podman, runc and debootstrap"
fi

# The Debian mirror apt uses (deb822 URIs: or a one-line deb entry).
mirror=$(sed -n 's/^URIs: *//p; s/^deb \(\[[^]]*\] \)\{0,1\}\([^ ]*\) .*/\2/p' \
           /etc/apt/sources.list.d/*.sources /etc/apt/sources.list 2>/dev/null |
         tr ' ' '\n' | grep -E '^https?://[^ ]*/debian/?$' | head -n 1) || true
mirror=${mirror:-http://deb.debian.org/debian}

tmp=$(mktemp -d /tmp/rvehub-container.XXXXXX)
podman_=(podman --root="$tmp/storage" --runroot="$tmp/run" --runtime=runc)
# The sandbox refuses to raise RLIMIT_NOFILE and RLIMIT_NPROC to podman's
# defaults (1048576, and even to their current hard values for NPROC):
# the container gets the host's open-file limit and a lower process limit.
ulimits=(--ulimit="nofile=$(ulimit -Hn):$(ulimit -Hn)" --ulimit=nproc=32768:32768)
cleanup() {
  local status=$?
  set +e
  trap - EXIT INT TERM
  "${podman_[@]}" rm -a -f >/dev/null 2>&1
  "${podman_[@]}" rmi -a -f >/dev/null 2>&1
  # Any overlay mount left under the private storage, deepest first.
  awk -v d="$tmp/" 'index($2, d) == 1 { print $2 }' /proc/mounts | sort -r |
    while read -r m; do umount -l "$m"; done
  if [[ ${CONTAINER_KEEP:-0} == 1 ]]; then
    echo "container_test: kept $tmp" >&2
  else
    rm -rf "$tmp"
  fi
  exit "$status"
}
trap cleanup EXIT
trap 'exit 130' INT
trap 'exit 143' TERM

start=$SECONDS
if [[ ! -s $base_tar ]]; then
  echo "container_test: debootstrap --variant=minbase bookworm from $mirror" >&2
  mkdir -p "$(dirname "$base_tar")"
  debootstrap --variant=minbase bookworm "$tmp/rootfs" "$mirror" >"$tmp/debootstrap.log" 2>&1 ||
    { tail -n 5 "$tmp/debootstrap.log" >&2; skip "debootstrap failed"; }
  tar -C "$tmp/rootfs" -cf "$base_tar.tmp" . && mv "$base_tar.tmp" "$base_tar"
  rm -rf "$tmp/rootfs"
fi
"${podman_[@]}" import --quiet "$base_tar" localhost/rvehub-base:bookworm >/dev/null
echo "container_test: base image localhost/rvehub-base:bookworm ($((SECONDS - start)) s)" >&2

start=$SECONDS
if ! "${podman_[@]}" build --network=host "${ulimits[@]}" \
       --build-arg=BASE=localhost/rvehub-base:bookworm \
       --build-arg=RUNTIME_BASE=localhost/rvehub-base:bookworm \
       -f deploy/Dockerfile -t localhost/rvehub:test "$repo" >"$tmp/build.log" 2>&1; then
  tail -n 30 "$tmp/build.log" >&2
  echo "container_test: podman build failed" >&2
  exit 1
fi
echo "container_test: image built ($((SECONDS - start)) s): $("${podman_[@]}" images --format '{{.Repository}}:{{.Tag}} {{.Size}}' localhost/rvehub:test)" >&2

# The image's own command: rve_server on 0.0.0.0:50051 (the Kubernetes
# StatefulSet's), asked by rve_cli inside the container, stopped by podman's
# SIGTERM (it must drain and log "stopped", not wait for the SIGKILL).
"${podman_[@]}" run -d --name=rvehub-server --network=none "${ulimits[@]}" \
  localhost/rvehub:test >/dev/null
ok=0
for ((t = 0; t < 30; t++)); do  # bounded: 30 s to answer
  if "${podman_[@]}" exec rvehub-server rve_cli info --server=127.0.0.1:50051 --timeout=2 \
       >"$tmp/info.log" 2>&1; then
    ok=1
    break
  fi
  sleep 1
done
"${podman_[@]}" stop --time=40 rvehub-server >/dev/null
"${podman_[@]}" logs rvehub-server >"$tmp/server.log" 2>&1
if ((!ok)) || ! grep -q 'msg=stopped' "$tmp/server.log"; then
  cat "$tmp/info.log" "$tmp/server.log" >&2
  echo "container_test: the image's rve_server did not answer or did not stop on SIGTERM" >&2
  exit 1
fi
echo "container_test: rve_server in the container answered ($(tr '\n' ' ' <"$tmp/info.log" | cut -c1-120)) and stopped on SIGTERM" >&2

# The default job (deploy/run_default.sh) as the image's user 65532.
start=$SECONDS
mkdir -p "$tmp/out"
chown 65532:65532 "$tmp/out"
if ! "${podman_[@]}" run --rm --network=none "${ulimits[@]}" -v "$tmp/out:/out" \
       --entrypoint=mpm_client localhost/rvehub:test \
       run /opt/rvehub/cases/single-element-biaxial.json --out=/out/single-element-biaxial \
       --template-cache=/out/templates >"$tmp/run.log" 2>&1; then
  tail -n 30 "$tmp/run.log" >&2
  echo "container_test: the default job failed in the container" >&2
  exit 1
fi
echo "container_test: default job in the container: $((SECONDS - start)) s" >&2
tail -n 3 "$tmp/run.log" >&2
ls "$tmp/out/single-element-biaxial" >&2

client=$build/mpm_client/mpm_client
if [[ -x $client ]]; then
  "$client" run cases/single-element-biaxial.json --out="$tmp/host" \
    --template-cache="$tmp/host-templates" >"$tmp/host.log" 2>&1 ||
    { tail -n 20 "$tmp/host.log" >&2; echo "container_test: the host run failed" >&2; exit 1; }
  strip_wall() {
    awk -F, -v OFS=, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "wall_per_step_s") w = i }
                      { if (w) { for (i = w; i < NF; i++) $i = $(i + 1); NF-- } print }' "$1"
  }
  strip_wall "$tmp/out/single-element-biaxial/timeseries.csv" >"$tmp/container.csv"
  strip_wall "$tmp/host/timeseries.csv" >"$tmp/host.csv"
  if ! cmp "$tmp/container.csv" "$tmp/host.csv"; then
    echo "container_test: timeseries.csv differs from the host build's" >&2
    exit 1
  fi
  echo "container_test: timeseries.csv equal to the host build's but for wall_per_step_s" \
       "($(wc -l <"$tmp/host.csv") lines)" >&2
fi
