#!/usr/bin/env bash
# Installs dependencies, builds and runs the tests.
# Usage: deploy/test.sh [--quick]   (--quick skips tests labelled "slow")
set -euo pipefail
cd "$(dirname "$0")/.."

ctest_args=(--output-on-failure -j2)
for arg in "$@"; do
  case "${arg}" in
    --quick) ctest_args+=(-LE slow) ;;
    *) echo "usage: $0 [--quick]" >&2; exit 2 ;;
  esac
done

bash deploy/install_deps.sh
bash deploy/build.sh
ctest --test-dir "${BUILD_DIR:-build}" "${ctest_args[@]}"
