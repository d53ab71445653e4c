#!/usr/bin/env bash
# Checks what deploy/ ships: the Kubernetes manifests against the API's
# schemas (npm's kubernetes-models, installed on first use into
# ${RVEHUB_BUILD:-build}/k8s-validate; node from Debian's nodejs) and the
# shell scripts with shellcheck (Debian's shellcheck).
# Exit 0 valid, 1 invalid, 77 when a tool cannot be had (no node/npm, no
# package registry): CTest reports that as skipped, not passed.
set -euo pipefail
cd "$(dirname "$0")/.."

tools=${RVEHUB_BUILD:-build}/k8s-validate
if ! command -v node >/dev/null || ! command -v npm >/dev/null; then
  echo "validate_manifests: node and npm are needed (apt-get install nodejs npm): skipped" >&2
  exit 77
fi
if [[ ! -d $tools/node_modules/kubernetes-models ]]; then
  mkdir -p "$tools"
  if ! npm install --prefix "$tools" --no-audit --no-fund --loglevel=error \
       kubernetes-models@5.1.0 js-yaml@4.1.0 >"$tools/npm.log" 2>&1; then
    echo "validate_manifests: cannot install kubernetes-models from npm: skipped" >&2
    tail -n 5 "$tools/npm.log" >&2
    exit 77
  fi
fi
status=0
# ESM resolves packages from the script's directory up: run a copy beside them.
cp deploy/kubernetes/validate.mjs "$tools/validate.mjs"
node "$tools/validate.mjs" deploy/kubernetes/*.yaml || status=1
# The validator must refuse a broken manifest (a port that is no integer),
# or its "valid" above means nothing.
sed 's/port: 50051/port: "fifty"/' deploy/kubernetes/rve-server.yaml >"$tools/broken.yaml"
if node "$tools/validate.mjs" "$tools/broken.yaml" >/dev/null; then
  echo "validate_manifests: a broken manifest passed: the validator checks nothing" >&2
  status=1
fi

if command -v shellcheck >/dev/null; then
  # Warnings and errors; its notes (a trap's handler looks unreachable to it)
  # are not.
  shellcheck --severity=warning deploy/*.sh deploy/slurm/*.sh deploy/slurm/*.sbatch &&
    echo "shellcheck: deploy scripts clean" ||
    status=1
else
  echo "validate_manifests: shellcheck not installed: scripts not checked" >&2
fi
exit "$status"
