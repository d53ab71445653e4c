#!/usr/bin/env bash
# Configures and builds RVEHub (Release, Ninja) into ${BUILD_DIR:-build}.
# Usage: deploy/build.sh [TARGET ...]   (no target: everything, tests included;
#        deploy/build.sh mpm_client builds the client and what it links, nothing else)
set -euo pipefail
cd "$(dirname "$0")/.."

BUILD_DIR="${BUILD_DIR:-build}"
cmake -S . -B "${BUILD_DIR}" -G Ninja -DCMAKE_BUILD_TYPE=Release
targets=()
for t in "$@"; do targets+=(--target "${t}"); done
cmake --build "${BUILD_DIR}" -j"$(nproc)" "${targets[@]}"
