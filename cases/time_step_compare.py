#!/usr/bin/env python3
"""Runs of one case at different time steps, side by side: one timeseries.csv column against
another, and the kinetic energy (log scale) against the same x, for each run.

  /usr/bin/python3 cases/time_step_compare.py RUN_DIR=LABEL [RUN_DIR=LABEL ...] \\
      --x=COLUMN[*SCALE] --y=COLUMN[*SCALE] [--xlabel=...] [--ylabel=...] \\
      [--xmin=X] [--xmax=X] [--title=...] [--out=time-step.png]

A column may carry a scale factor: --x=pipe_dy*-1 --y=pipe_fy*0.001 draws the pipe's
penetration (m) against the soil's upward force on it (kN per m). Typical uses: a run resumed from a
checkpoint with `mpm_client resume --cfl=...` beside the run it came from (its timeseries.csv
then starts at the checkpoint), or two full runs at CFL 0.5 and 0.25. Prints, for each run, the
largest kinetic energy and the row where it occurs within the x range.
For the differences of two runs' headline curves (the same answers?), use bench/compare_runs.py;
this script is for seeing where and how a run goes unstable.
Needs numpy and matplotlib (Debian's python3-numpy, python3-matplotlib).
"""
import argparse
import csv
import os

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def column(rows, spec):
    """The values of 'NAME' or 'NAME*SCALE' over the rows."""
    name, _, scale = spec.partition("*")
    factor = float(scale) if scale else 1.0
    return factor * np.array([float(r[name]) for r in rows])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", metavar="RUN_DIR=LABEL")
    ap.add_argument("--x", required=True)
    ap.add_argument("--y", required=True)
    ap.add_argument("--xlabel")
    ap.add_argument("--ylabel")
    ap.add_argument("--xmin", type=float)
    ap.add_argument("--xmax", type=float)
    ap.add_argument("--title", default="")
    ap.add_argument("--out", default="time-step.png")
    a = ap.parse_args()

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 7), sharex=True)
    for spec in a.runs:
        run, _, label = spec.partition("=")
        with open(os.path.join(run, "timeseries.csv")) as f:
            rows = list(csv.DictReader(f))
        x, y = column(rows, a.x), column(rows, a.y)
        ke = column(rows, "kinetic_energy")
        keep = np.ones_like(x, dtype=bool)
        if a.xmin is not None:
            keep &= x >= a.xmin
        if a.xmax is not None:
            keep &= x <= a.xmax
        if not keep.any():
            print(f"{label or run}: no rows in the x range")
            continue
        top.plot(x[keep], y[keep], lw=1, label=label or run)
        bottom.semilogy(x[keep], np.maximum(ke[keep], 1e-12), lw=1, label=label or run)
        i = np.flatnonzero(keep)[np.argmax(ke[keep])]
        print(f"{label or run}: rows {keep.sum()}, x {x[keep][0]:.6g} to {x[keep][-1]:.6g}; "
              f"largest kinetic energy {ke[i]:.4g} J at x = {x[i]:.6g} "
              f"(time {float(rows[i]['time']):.6g} s, step {rows[i]['step']})")
    top.set_ylabel(a.ylabel or a.y)
    top.grid(alpha=0.3)
    top.legend()
    bottom.set_ylabel("kinetic energy (J)")
    bottom.set_xlabel(a.xlabel or a.x)
    bottom.grid(alpha=0.3)
    top.set_title(a.title)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
