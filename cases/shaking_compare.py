#!/usr/bin/env python3
"""Cyclic-shaking runs side by side (liang-zhao-wu-soga-2023 §4.2, Figs. 8-9b): the excess
pore pressure ratio dp/sigma'_yy0 at each monitor against time, the surface settlement, and
the shear stress against the horizontal displacement at one monitor (the loops).

  /usr/bin/python3 cases/shaking_compare.py RUN_DIR[=LABEL] ... [--out=shaking.png]
      [--loop=B]

Reads each RUN_DIR's timeseries.csv (columns <monitor>_excess_ratio, <monitor>_sxy,
<monitor>_ux and surface_settlement, written by saturated cases with monitors). Needs
matplotlib (Debian's python3-matplotlib).
"""
import argparse
import csv
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+", help="RUN_DIR[=LABEL]")
    ap.add_argument("--out", default="shaking.png")
    ap.add_argument("--loop", default="B", help="monitor whose sxy-ux loop is drawn")
    args = ap.parse_args()
    runs = []
    for spec in args.runs:
        path, _, label = spec.partition("=")
        with open(os.path.join(path, "timeseries.csv")) as f:
            rows = list(csv.DictReader(f))
        monitors = [k[: -len("_excess_ratio")] for k in rows[0] if k.endswith("_excess_ratio")]
        runs.append((label or os.path.basename(path.rstrip("/")), rows, monitors))
    monitors = runs[0][2]
    loop = args.loop if args.loop + "_sxy" in runs[0][1][0] else None
    panels = len(monitors) + 1 + (loop is not None)
    fig, axes = plt.subplots(1, panels, figsize=(4.2 * panels, 3.4))
    settle_ax = axes[len(monitors)]
    for label, rows, _ in runs:
        t = [float(r["time"]) for r in rows]
        for ax, m in zip(axes, monitors):
            ax.plot(t, [float(r[m + "_excess_ratio"]) for r in rows], label=label, lw=0.8)
            ax.set_title(f"point {m}")
            ax.set_xlabel("time (s)")
            ax.set_ylabel("excess pore pressure ratio (-)")
        settle_ax.plot(t, [1e3 * float(r["surface_settlement"]) for r in rows], label=label)
        if loop is not None:
            # Shear stress as soil mechanics signs it: the tension-positive
            # sigma_xy of the file, in kPa, against u_x in mm.
            axes[-1].plot([1e3 * float(r[loop + "_ux"]) for r in rows],
                          [1e-3 * float(r[loop + "_sxy"]) for r in rows], label=label, lw=0.6)
        settle = 1e3 * float(rows[-1]["surface_settlement"])
        final = ", ".join(f"{m} {float(rows[-1][m + '_excess_ratio']):.3f}" for m in monitors)
        print(f"{label}: at t = {t[-1]:.2f} s excess ratio {final}; settlement {settle:.2f} mm")
    settle_ax.set_title("surface settlement")
    settle_ax.set_xlabel("time (s)")
    settle_ax.set_ylabel("settlement (mm)")
    if loop is not None:
        axes[-1].set_title(f"point {loop}: shear stress against displacement")
        axes[-1].set_xlabel("u_x (mm)")
        axes[-1].set_ylabel("sigma_xy (kPa)")
    for ax in axes:
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
