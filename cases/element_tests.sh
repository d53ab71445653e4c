#!/usr/bin/env bash
# Runs every element test once on its reference material, writing CSVs and
# plots to out/cases/. Assumes a build in build/ (bash deploy/build.sh).
set -euo pipefail
cd "$(dirname "$0")/.."
cli="${BUILD_DIR:-build}/rve_server/cli/rve_cli"
out=out/cases
mkdir -p "${out}"

run() {
  local name=$1
  shift
  echo "== ${name}"
  "${cli}" element-test "$@" --out="${out}/${name}.csv" --plot="${out}/${name}.png"
}

# guo-et-al-spfem-dem §3.2: peak ≈ 280 kPa at ≈ 1.8 % axial strain, then softening.
run biaxial_spfem --test=drained-biaxial --material=SPFEM-biaxial --confining=100000 --strain=0.1
# liang-zhao-wu-soga §4.1: K + 4G/3 = 25.06 MPa.
run oedometer_consolidation --test=oedometer --material=consolidation --strain=0.002
run isotropic_set_dense --test=isotropic --material=SET-dense --strain=0.01
run undrained_shear_loose --test=undrained-simple-shear --material=cyclic-loose --strain=0.1
# guo-zhao-2014 §5: loose RVEs under cyclic simple shear, strain and stress control.
run cyclic_strain_loose --test=cyclic-simple-shear --material=cyclic-loose \
  --cyclic-control=strain --amplitude=0.002 --cycles=5 --strain=0.2
run cyclic_stress_loose --test=cyclic-simple-shear --material=cyclic-loose-stress \
  --cyclic-control=stress --amplitude=15000 --cycles=10 --strain=0.1
echo "results in ${out}/"
