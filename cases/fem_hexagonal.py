#!/usr/bin/python3
"""FEMxDEM biaxial compression with the regular hexagonal RVE (Guo & Zhao
2014, §4.1.4, Figs. 13-14): the specimen's nominal axial stress against the
DEM element test on the same packing, and the accumulated deviatoric strain
over the Gauss points at the peak and a few load steps after it.

Usage:
  /usr/bin/python3 cases/fem_hexagonal.py DIR \
      [--reference cases/reference/hexagonal-drained-biaxial-100kPa.csv] \
      [--disordered-peak-pa 277.7e3] [--figure cases/figures/fem-biaxial-hexagonal.png]

DIR is a run of cases/fem-biaxial-hexagonal.json with a frame at every load
step (`--set=output.frame_every=1`): its timeseries.csv and results.h5 are
read. It prints the peak against the element test's, the ratio of the peak
to the disordered packing's (fem-biaxial-coarse's, given), the ε_q range over
the Gauss points at the peak frame and after it, and the load step in which
the stress drops. A run that stopped before the end (a step that did not
converge) is read as far as it got.
"""
import argparse
import csv
import os
import sys


def read_csv(path):
    with open(path, newline="") as f:
        rows = [r for r in csv.reader(f) if r]
    return {h: [float(r[i]) for r in rows[1:]] for i, h in enumerate(rows[0])}


def read_frames(directory):
    import h5py
    import numpy as np
    frames = {}
    with h5py.File(os.path.join(directory, "results.h5"), "r") as f:
        for name in f["frames"]:
            g = f["frames"][name]
            frames[int(name)] = {
                "x": np.array(g["position"])[:, 0], "y": np.array(g["position"])[:, 1],
                "eps_q": np.array(g["eps_q"]), "void_ratio": np.array(g["void_ratio"]),
                "u": np.array(g["displacement"])[:, :2],
            }
    return frames


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    ap.add_argument("--reference", default="cases/reference/hexagonal-drained-biaxial-100kPa.csv")
    ap.add_argument("--disordered-peak-pa", type=float, default=277.7e3,
                    help="fem-biaxial-coarse's peak nominal axial stress (SET-dense RVE)")
    ap.add_argument("--after", type=int, default=3, help="load steps after the peak to show")
    ap.add_argument("--figure", default="cases/figures/fem-biaxial-hexagonal.png")
    args = ap.parse_args()

    import numpy as np
    ts = read_csv(os.path.join(args.run, "timeseries.csv"))
    dem = read_csv(args.reference)
    frames = read_frames(args.run)
    strain = np.array(ts["axial_strain"])
    stress = np.array(ts["platen_force_per_width_Pa"])
    steps = np.array(ts["step"], dtype=int)

    k = int(np.argmax(stress))
    dem_syy = np.array(dem["syy"])
    kd = int(np.argmax(dem_syy))
    print(f"FEMxDEM peak: {stress[k] / 1e3:.1f} kPa at {strain[k] * 100:.2f} % (step {steps[k]}); "
          f"the run reached {strain[-1] * 100:.2f} % (step {steps[-1]})")
    print(f"DEM element test peak: {dem_syy[kd] / 1e3:.1f} kPa at "
          f"{dem['axial_strain'][kd] * 100:.2f} %")
    print(f"peak / disordered peak ({args.disordered_peak_pa / 1e3:.1f} kPa): "
          f"{stress[k] / args.disordered_peak_pa:.2f}")
    drops = stress[1:] / stress[:-1] - 1.0
    if len(drops):
        j = int(np.argmin(drops))
        print(f"largest one-step change: {drops[j]:+.1%} from step {steps[j]} to {steps[j + 1]} "
              f"({strain[j] * 100:.2f} % to {strain[j + 1] * 100:.2f} %)")

    def eps_q_range(step):
        f = frames[step]
        e = f["eps_q"]
        return e.min(), e.max(), (e.max() - e.min()) / e.mean()

    shown = [s for s in range(steps[k], steps[k] + args.after + 1) if s in frames]
    for s in shown:
        lo, hi, spread = eps_q_range(s)
        print(f"step {s} ({strain[list(steps).index(s)] * 100:.2f} %): ε_q {lo:.5f}-{hi:.5f} "
              f"(spread {spread:.2%} of the mean), void ratio "
              f"{frames[s]['void_ratio'].min():.4f}-{frames[s]['void_ratio'].max():.4f}")

    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fields = [shown[0]] + ([shown[-1]] if len(shown) > 1 else [])
    fig = plt.figure(figsize=(9, 4.2))
    grid = fig.add_gridspec(1, 1 + len(fields), width_ratios=[2.2] + [1] * len(fields))
    ax = fig.add_subplot(grid[0])
    ax.plot(np.array(dem["axial_strain"]) * 100, dem_syy / 1e6, "o", ms=2.5, mfc="none",
            color="0.4", label="DEM element test (hexagonal RVE)")
    ax.plot(strain * 100, stress / 1e6, "-", color="C3", lw=1.5, label="FEMxDEM, 6 x 10 Q4")
    ax.plot(strain[k] * 100, stress[k] / 1e6, "s", color="C3", ms=5)
    ax.axhline(args.disordered_peak_pa / 1e6, color="C0", ls=":", lw=1,
               label="peak with the disordered RVE")
    ax.set_xlabel("axial strain ε_a (%)")
    ax.set_ylabel("σ_yy (MPa)")
    ax.set_xlim(0, 10)
    ax.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3)
    for i, s in enumerate(fields):
        a = fig.add_subplot(grid[1 + i])
        f = frames[s]
        sc = a.scatter(f["x"] * 1e3, f["y"] * 1e3, c=f["eps_q"], s=30, marker="s", cmap="jet")
        a.set_aspect("equal")
        a.set_xticks([])
        a.set_yticks([])
        a.set_title(f"ε_q at {strain[list(steps).index(s)] * 100:.1f} %"
                    + (" (peak)" if s == steps[k] else ""), fontsize=8)
        cb = fig.colorbar(sc, ax=a, fraction=0.1)
        cb.ax.tick_params(labelsize=6)
        cb.formatter.set_useOffset(False)
        cb.update_ticks()
    fig.tight_layout()
    os.makedirs(os.path.dirname(os.path.abspath(args.figure)), exist_ok=True)
    fig.savefig(args.figure, dpi=100)
    print(f"{args.figure}: {os.path.getsize(args.figure)} bytes")
    return 0


if __name__ == "__main__":
    sys.exit(main())
