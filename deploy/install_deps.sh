#!/usr/bin/env bash
# Installs the Debian 12 packages RVEHub needs to build and test.
# Fast path: does nothing when every package is already installed
# (set RVEHUB_FORCE_APT=1 to run apt-get anyway).
set -euo pipefail

PACKAGES=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libabsl-dev libgtest-dev libgmock-dev libbenchmark-dev libcairo2-dev
  libgrpc++-dev libprotobuf-dev protobuf-compiler protobuf-compiler-grpc libhdf5-dev nlohmann-json3-dev
  openssl git ca-certificates
  python3 python3-grpcio python3-grpc-tools python3-numpy python3-pytest python3-matplotlib python3-h5py
)

missing=()
for pkg in "${PACKAGES[@]}"; do
  status="$(dpkg-query -W -f='${db:Status-Status}' "${pkg}" 2>/dev/null || true)"
  if [[ "${status}" != "installed" ]]; then
    missing+=("${pkg}")
  fi
done

if [[ ${#missing[@]} -eq 0 && "${RVEHUB_FORCE_APT:-0}" != "1" ]]; then
  echo "install_deps: all ${#PACKAGES[@]} packages already installed."
  exit 0
fi

if [[ ${#missing[@]} -gt 0 ]]; then
  echo "install_deps: missing packages: ${missing[*]}"
fi

if [[ "$(id -u)" -eq 0 ]]; then
  SUDO=()
elif command -v sudo >/dev/null 2>&1; then
  SUDO=(sudo)
else
  echo "install_deps: not root and sudo is not available; as root run:" >&2
  echo "  apt-get install -y --no-install-recommends ${missing[*]:-${PACKAGES[*]}}" >&2
  exit 1
fi

"${SUDO[@]}" apt-get update
"${SUDO[@]}" env DEBIAN_FRONTEND=noninteractive \
  apt-get install -y --no-install-recommends "${PACKAGES[@]}"
echo "install_deps: done."
