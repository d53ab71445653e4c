#!/usr/bin/env python3
"""The footing packings' peak friction angle against their void ratio, and the footing's N_q
against Prandtl's, over packings compacted at several pressures.

  /usr/bin/python3 cases/strength_void_ratio.py FA_DIR [FA_DIR ...] [--footing RUN_DIR ...]
      [--curve CSV:LABEL ...] --out=strength-void-ratio.png

Each FA_DIR holds one `friction_angle.py --out` run (any --material, --seed and
--compaction-pressure): its biaxial CSVs are fitted again per packing seed (friction_angle.fit)
and drawn as phi' against the void ratio at the tests' start, each directory's mean and spread
beside the paper's (liang-zhao-mpm-dem Table 2 and §3.3.1: e0 0.1874 and 0.2314, phi' 28.1 and
20.8 deg). footing-dense and footing-medium differ only in e0, so both lie on one curve.
--footing RUN_DIR ... adds two panels: each footing run's N_q (summary.json) against the phi'
it was compared with, beside Prandtl's N_q and the paper's footing (14.4 at 28.1 deg), and its
q/q_s against the settlement (timeseries.csv), coloured by the packing's preparation (its
compaction pressure and rolling-resistance eta) where the runs' differ, with --curve's other
curves (CSV rows "settlement m, q/q_s", as tests/mpm_client/run/prandtl_test.cc's
DISABLED_MeasureWithMohrCoulomb writes them for a Mohr-Coulomb soil). Prints a table of both.
Needs numpy and matplotlib (Debian's python3-numpy, python3-matplotlib).
"""
import argparse
import csv
import glob
import math
import os
import re
import statistics

import matplotlib
import numpy as np

from footing_mesh import load_run, preparation, preparations
from friction_angle import fit, prandtl_nq

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

# friction_angle.py's file names: MATERIAL-seedN-PkPa[-x].csv
CSV_NAME = re.compile(r"^(?P<material>.+)-seed(?P<seed>\d+)-(?P<kpa>[0-9.e+-]+)kPa(?P<x>-x)?\.csv$")
PAPER = {"footing-dense": (0.1874, 28.1), "footing-medium": (0.2314, 20.8)}
PAPER_FOOTING = (28.1, 14.4)  # phi' (deg), N_q


def spread(values):
    """Sample standard deviation, 0 for a single value."""
    return statistics.stdev(values) if len(values) > 1 else 0.0


def read_curve(path):
    """The rows (settlement m, q/q_s) of a --curve CSV; a missing or empty file, or a row
    that is not two numbers, ends the script naming it."""
    try:
        with open(path) as f:
            rows = [r for r in csv.reader(f) if r]
    except OSError as e:
        raise SystemExit(f"--curve {path}: {e.strerror}") from None
    curve = []
    for k, row in enumerate(rows, 1):
        try:
            d, q = (float(x) for x in row)
        except ValueError:
            raise SystemExit(f"--curve {path}: row {k} is not 'settlement m, q/q_s': "
                             f"{','.join(row)}") from None
        curve.append((d, q))
    if not curve:
        raise SystemExit(f"--curve {path}: no rows")
    return curve


def packings(directory, peak_within, cs_from):
    """{(material, seed): (phi' deg, e at the start)} of one friction_angle.py output
    directory."""
    tests = {}
    for path in sorted(glob.glob(os.path.join(directory, "*.csv"))):
        m = CSV_NAME.match(os.path.basename(path))
        if not m:
            continue
        axis = "x" if m["x"] else "y"
        tests.setdefault((m["material"], int(m["seed"])), []).append(
            (path, axis, float(m["kpa"]) * 1e3))
    if not tests:
        raise SystemExit(f"{directory}: no friction_angle.py CSVs (MATERIAL-seedN-PkPa.csv)")
    out = {}
    for key, group in sorted(tests.items()):
        phi, _, _, void = fit(group, peak_within, cs_from)
        out[key] = (math.degrees(phi), void)
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dirs", nargs="+", help="friction_angle.py --out directories")
    ap.add_argument("--footing", nargs="*", default=[], help="footing run directories")
    ap.add_argument("--curve", nargs="*", default=[],
                    help="CSV:LABEL, rows of settlement (m) and q/q_s")
    ap.add_argument("--out", required=True, help="PNG")
    ap.add_argument("--peak-within", type=float, default=0.08)
    ap.add_argument("--cs-from", type=float, default=0.15)
    a = ap.parse_args()
    # Read first, so that a bad curve or run ends the script before the tests are refitted.
    curves = []
    for spec in a.curve:
        path, _, label = spec.partition(":")
        curves.append((read_curve(path), label or os.path.basename(path)))
    runs = [load_run(run) for run in a.footing]  # footing_mesh.load_run: summary, q/q_s(d)

    panels = 3 if a.footing else 1
    fig, axes = plt.subplots(1, panels, figsize=(6.2 * panels, 5), squeeze=False)
    ax = axes[0][0]
    colours = {"footing-dense": "tab:blue", "footing-medium": "tab:orange"}
    print("directory | material | seeds | e at the start (mean ± sd) | phi' deg (mean ± sd)")
    for directory in a.dirs:
        by_material = {}
        for (material, _), value in packings(directory, a.peak_within, a.cs_from).items():
            by_material.setdefault(material, []).append(value)
        for material, values in by_material.items():
            phis, voids = [v[0] for v in values], [v[1] for v in values]
            colour = colours.get(material, "tab:grey")
            ax.plot(voids, phis, ".", color=colour, alpha=0.35)
            ax.errorbar(statistics.mean(voids), statistics.mean(phis), xerr=spread(voids),
                        yerr=spread(phis), fmt="o", color=colour, capsize=3)
            ax.annotate(os.path.basename(os.path.normpath(directory)),
                        (statistics.mean(voids), statistics.mean(phis)), fontsize=7,
                        xytext=(4, 4), textcoords="offset points")
            print(f"{directory} | {material} | {len(values)} | {statistics.mean(voids):.4f} ± "
                  f"{spread(voids):.4f} | {statistics.mean(phis):.2f} ± {spread(phis):.2f}")
    for material, (e0, phi) in PAPER.items():
        ax.plot(e0, phi, "*", ms=14, color=colours[material], mec="k",
                label=f"paper, {material} (e0, phi')")
    ax.set_xlabel("void ratio at the biaxial tests' start (10-30 kPa)")
    ax.set_ylabel("peak phi' (deg), tests at 10-30 kPa")
    ax.set_title("footing packings: strength against density\n"
                 "dots: seeds; circles: mean ± sd of each preparation")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)

    if a.footing:
        # One colour per preparation of the footing's packing: where it was compacted and its
        # rolling-resistance eta (footing_mesh.preparation; None: the set's).
        preps = preparations(runs)
        colour_of = {k: plt.cm.tab10(i % 10) for i, k in enumerate(preps)}

        def legend_text(pressure, eta):
            return (f"compacted at {pressure / 1e3:g} kPa" if pressure else "the set's p0") + (
                f", eta {eta:g}" if eta is not None else ", the set's eta")

        ax = axes[0][1]
        grid = np.linspace(20, 34, 200)
        prandtl = [prandtl_nq(math.radians(x)) for x in grid]
        ax.plot(grid, prandtl, "k-", label="Prandtl N_q")
        ax.fill_between(grid, [0.9 * p for p in prandtl], [1.1 * p for p in prandtl],
                        color="k", alpha=0.08, label="Prandtl ± 10 %")
        print("footing run | phi' deg | N_q | Prandtl | N_q / Prandtl | settlement at ultimate m")
        for run in runs:
            s = run["summary"]
            ratio = s["N_q"] / s["N_q_prandtl"]
            ax.plot(s["phi_deg"], s["N_q"], "o", color=colour_of[preparation(run)])
            ax.annotate(f"{os.path.basename(os.path.normpath(run['dir']))} ({ratio:.2f})",
                        (s["phi_deg"], s["N_q"]), fontsize=7, xytext=(4, -10),
                        textcoords="offset points")
            print(f"{run['dir']} | {s['phi_deg']:.2f} | {s['N_q']:.2f} | {s['N_q_prandtl']:.2f} | "
                  f"{ratio:.3f} | {s['settlement_at_ultimate_m']:.3f}")
        if len(preps) > 1:
            for k in preps:
                ax.plot([], [], "o", color=colour_of[k], label=legend_text(*k))
        ax.plot(*PAPER_FOOTING, "*", ms=14, color="tab:red", mec="k", label="paper's footing")
        ax.set_xlabel("phi' of the footing's packing (deg)")
        ax.set_ylabel("N_q = q_ult / q_s")
        ax.set_title("footing N_q against Prandtl's (N_q / Prandtl in brackets)")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)

        ax = axes[0][2]
        for run in runs:
            ax.plot(run["d"], run["q"], lw=1.2,
                    color=colour_of[preparation(run)] if len(preps) > 1 else None,
                    label=f"RVEs: {os.path.basename(os.path.normpath(run['dir']))}")
        for rows, label in curves:
            ax.plot([r[0] for r in rows], [r[1] for r in rows], "--", lw=1.0, label=label)
        ax.set_xlabel("settlement d (m)")
        ax.set_ylabel("q / q_s")
        ax.set_title("load against settlement")
        ax.grid(alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle("footing-dense / footing-medium packings (cases/strength_void_ratio.py)",
                 fontsize=10)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
