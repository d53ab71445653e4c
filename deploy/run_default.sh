#!/usr/bin/env bash
# Builds RVEHub and runs the default job: the single element biaxial case
# (liang-zhao-mpm-dem §3.1) with the MPM client on an embedded RVE server —
# four material points, each with its own SET-dense DEM packing, confined at
# 100 kPa and compressed to 15 % axial strain. Writes out/single-element-biaxial/
# (results.h5 + results.xdmf for ParaView, timeseries.csv, plot.png, checkpoint.h5).
set -euo pipefail
cd "$(dirname "$0")/.."

bash deploy/install_deps.sh
# Only the client and what it links: the first result comes before the tests are
# compiled (deploy/test.sh builds the rest).
bash deploy/build.sh mpm_client

out=out/single-element-biaxial
"${BUILD_DIR:-build}"/mpm_client/mpm_client run cases/single-element-biaxial.json \
  --out="${out}" --template-cache=out/templates

echo "Results: $(pwd)/${out}/timeseries.csv, $(pwd)/${out}/results.xdmf (ParaView)"
echo "Plot:    $(pwd)/${out}/plot.png"
