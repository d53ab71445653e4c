#!/usr/bin/env bash
# Builds RVEHub and runs the default case: a drained biaxial element test on
# the SET-dense material. Writes a CSV and a PNG plot to out/.
set -euo pipefail
cd "$(dirname "$0")/.."

bash deploy/install_deps.sh
bash deploy/build.sh

mkdir -p out
"${BUILD_DIR:-build}"/rve_server/cli/rve_cli element-test \
  --test=drained-biaxial --material=SET-dense --seed=1 \
  --confining=100000 --strain=0.10 \
  --out=out/biaxial_set_dense.csv --plot=out/biaxial_set_dense.png

echo "Results: $(pwd)/out/biaxial_set_dense.csv"
echo "Plot:    $(pwd)/out/biaxial_set_dense.png"
