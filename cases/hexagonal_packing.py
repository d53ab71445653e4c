#!/usr/bin/python3
"""The regular hexagonal RVE of guo-zhao-2014 §4.1.4 (Figs. 13-14) as a template file.

400 equal discs on a triangular lattice (20 rows of 20, each row offset by a
radius from the one below) fill a rectangular periodic cell whose height, 20
row spacings of sqrt(3)·r, closes the lattice exactly. The discs carry
SET-dense's contact model and parameters and its mean radius (r = 5 mm, the
middle of its 3-7 mm range), so the packing differs from the disordered
SET-dense RVE in its structure only. The packing is uploaded to a local
rve_server at zero stress (the discs just touch), consolidated isotropically
to SET-dense's preparation pressure (100 kPa) by creating an RVE of it at that
pressure, and the consolidated state is hosted as the template; the server
then stops with a checkpoint directory, whose templates.h5 is the template
file a case names (templates[].file, template_name).

Usage (from the repository root, after building rve_server and rvehub_python):
  PYTHONPATH=python:build/python /usr/bin/python3 cases/hexagonal_packing.py \
      [--out=cases/reference/hexagonal-400.h5] [--csv=cases/reference/hexagonal-drained-biaxial-100kPa.csv]

With --csv it also runs the drained biaxial element test at 100 kPa to 10 %
axial strain on the template (rve_server's RunElementTest, as
`rve_cli element-test --server --template`) and writes rve_cli's CSV.
"""

import argparse
import dataclasses
import os
import shutil
import sys
import tempfile

import numpy as np

import rvehub

NAME = "hexagonal-400"
MATERIAL = "SET-dense"
ROWS = 20          # rows of the lattice
PER_ROW = 20       # discs per row
RADIUS = 5e-3      # SET-dense's mean radius: radii uniform in 3-7 mm
PRESSURE = 100e3   # SET-dense's preparation pressure, Pa
TOLERANCE = 0.005  # relative, on the consolidated mean pressure


def lattice(template: rvehub.Packing) -> rvehub.Packing:
    """The stress-free hexagonal packing with ``template``'s material and controls."""
    width = PER_ROW * 2.0 * RADIUS
    row = np.sqrt(3.0) * RADIUS
    height = ROWS * row  # an even number of rows: row 0 and row ROWS match across the cell
    j, i = np.meshgrid(np.arange(ROWS), np.arange(PER_ROW), indexing="ij")
    x = (i + 0.5 + 0.5 * (j % 2)) * 2.0 * RADIUS
    y = (j + 0.5) * row
    n = ROWS * PER_ROW
    zero = np.zeros(n)
    cell = np.array([[width, 0.0], [0.0, height]])
    return dataclasses.replace(
        template, cell=cell, reference_cell=cell.copy(), frame=np.eye(2),
        radius=np.full(n, RADIUS), sx=(x / width).ravel(), sy=(y / height).ravel(),
        vx=zero, vy=zero, omega=zero, theta=zero,
        contact_i=np.zeros(0, np.uint32), contact_j=np.zeros(0, np.uint32),
        contact_tangential_force=np.zeros(0), contact_rolling_moment=np.zeros(0),
        contact_bond_strength=np.zeros(0),
        initial_void_ratio=width * height / (n * np.pi * RADIUS ** 2) - 1.0, total_steps=0)


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", default="cases/reference/hexagonal-400.h5")
    ap.add_argument("--csv", default="", help="also write the drained biaxial test's CSV here")
    ap.add_argument("--strain", type=float, default=0.1, help="the element test's axial strain")
    args = ap.parse_args()

    work = tempfile.mkdtemp(prefix="hexagonal-")
    try:
        # The material and controls (time step factor, I bound, skin, ...)
        # are SET-dense's exactly: taken from a prepared SET-dense RVE. This
        # throwaway server also consolidates the lattice, so that the
        # checkpointed server below hosts the consolidated template only.
        with rvehub.local(threads=1) as hub:
            dense = hub.prepare_template(MATERIAL, seed=1)
            template = hub.create_run("probe", dense.name, ids=[0]).export()[0].packing
            hub.upload_template(f"{NAME}-raw", lattice(template), "hexagonal lattice, discs touching")
            run = hub.create_run("consolidate", f"{NAME}-raw", ids=[0], pressure=PRESSURE)
            s = run.created
            packing = run.export()[0].packing
        p = float(s.mean_pressure[0])
        e0 = float(s.void_ratio[0])
        if abs(p / PRESSURE - 1.0) > TOLERANCE:
            print(f"consolidated to p = {p:.1f} Pa, not {PRESSURE:.0f} Pa ± {TOLERANCE:.1%}",
                  file=sys.stderr)
            return 1
        packing = dataclasses.replace(packing, initial_void_ratio=e0, total_steps=0)
        desc = (f"regular hexagonal packing (guo-zhao-2014 §4.1.4): {ROWS} rows of {PER_ROW} "
                f"discs, r = {RADIUS * 1e3:g} mm, material {MATERIAL}, e0 = {e0:.4f}, "
                f"p0 = {p:.1f} Pa")

        ckpt = os.path.join(work, "checkpoint")
        with rvehub.local(threads=1, extra_args=[f"--checkpoint-dir={ckpt}"]) as hub:
            info = hub.upload_template(NAME, packing, desc)
            print(f"template {info.name}: e0 = {info.void_ratio:.4f}, p0 = {info.mean_pressure:.1f} "
                  f"Pa, q0 = {float(s.deviator_stress[0]):.3g} Pa, coordination "
                  f"{float(s.coordination[0]):.2f}")
            if args.csv:
                curve = hub.element_test("drained-biaxial", template=NAME, confining=PRESSURE,
                                         strain=args.strain)
                curve.to_csv(args.csv)
                q = curve["q"]
                k = int(np.argmax(q))
                print(f"drained biaxial: peak q = {q[k]:.1f} Pa at axial strain "
                      f"{curve['axial_strain'][k]:.4f}; {args.csv}")
        files = os.listdir(ckpt)
        src = os.path.join(ckpt, "templates.h5")
        if not os.path.isfile(src):
            print(f"the server wrote no templates.h5 to {ckpt} ({files})", file=sys.stderr)
            return 1
        os.makedirs(os.path.dirname(os.path.abspath(args.out)), exist_ok=True)
        shutil.copyfile(src, args.out)
        print(f"{args.out}: {os.path.getsize(args.out)} bytes")
        return 0
    finally:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == "__main__":
    sys.exit(main())
