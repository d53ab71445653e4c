#!/usr/bin/env python3
"""Points whose RVE has lost its contacts, and the cell-mates that carry their share.

  /usr/bin/python3 cases/open_points.py RUN_DIR[=LABEL] ... [--every=K] [--z=0.5]
      [--dead=0.01] [--per-cell=K] [--out=PNG --time=T --field=p --limits=LO,HI]
      [--series=PNG]

With several points per cell the internal forces see only the sum over a cell's rows of
σyy (and over its columns of σxx): with GIMP's points at h/4 and 3h/4 of an undeformed cell
(h/6, h/2, 5h/6 with three a side) every row of the cell sits where the shape functions'
gradient is that of the linear hat, so how the stress is shared between the rows is
invisible to the grid. A packing that opens (coordination below --z) beside one that is
squeezed harder is then a state the continuum cannot correct: the "volumetric
checkerboard" inside a cell. For each chosen frame this prints how many points are open,
how many cells (of the initial lattice) hold one, the median mean stress p of their loaded
cell-mates against that of the points in cells without an open point, and the open points
by their initial row and column inside the cell (a bias there is a mode of the lattice, not
of the soil). With --dead it also counts the open points among those that have not yet
moved more than dead x the region's width (the collapse's dead zone, which should keep its
geostatic stress).

With --out it draws one panel per run at the frame nearest --time: the points coloured by
--field (a frame dataset: p, excess_pore_pressure, ... in kPa when in Pa), the open ones
ringed in red. With --series it draws, for every frame of each run, the share of points
without contacts and (saturated runs) the mean excess pore pressure against time.

Reads RUN_DIR/results.h5 (frames/STEP/position, coordination, p; the first frame's
positions give the lattice). Needs numpy and h5py (Debian's python3-numpy, python3-h5py),
and matplotlib for --out.
"""
import argparse
import json
import os

import h5py
import numpy as np


def lattice(p0):
    """Per point its initial column and row index in the point lattice."""
    xs = np.unique(np.round(p0[:, 0], 9))
    ys = np.unique(np.round(p0[:, 1], 9))
    return (np.searchsorted(xs, np.round(p0[:, 0], 9)),
            np.searchsorted(ys, np.round(p0[:, 1], 9)))


def per_cell_side(run):
    """The first region's points per cell side from RUN_DIR/run.json's case, else 2."""
    try:
        with open(os.path.join(run, "run.json")) as f:
            return int(json.load(f)["case"]["regions"][0]["points_per_cell_side"])
    except (OSError, KeyError, IndexError, ValueError):
        return 2


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="RUN_DIR or RUN_DIR=LABEL")
    ap.add_argument("--every", type=int, default=4, help="every K-th frame (and the last)")
    ap.add_argument("--z", type=float, default=0.5, help="open below this coordination")
    ap.add_argument("--per-cell", type=int, default=0,
                    help="points per cell side (default: from the case in RUN_DIR/run.json, "
                         "else 2)")
    ap.add_argument("--dead", type=float, default=0.0,
                    help="also count open points among those moved < dead x width so far")
    ap.add_argument("--out", default="", help="draw the --time frame of each run here (PNG)")
    ap.add_argument("--time", type=float, default=0.0, help="s, the frame drawn")
    ap.add_argument("--field", default="p", help="the frame dataset that colours the points")
    ap.add_argument("--limits", default="", help="LO,HI of the colour scale (kPa)")
    ap.add_argument("--series", default="",
                    help="draw the open share and mean excess pore pressure against time (PNG)")
    a = ap.parse_args()
    if a.every < 1:
        ap.error(f"--every must be >= 1, got {a.every}")
    if a.per_cell < 0:
        ap.error(f"--per-cell must be >= 1 (0: from the case), got {a.per_cell}")
    if a.out and a.limits:
        try:
            lo, hi = map(float, a.limits.split(","))
        except ValueError:
            ap.error(f"--limits must be LO,HI in kPa, got {a.limits!r}")
        if not lo < hi:
            ap.error(f"--limits needs LO < HI, got {a.limits!r}")
    panels, series = [], []
    for spec in a.runs:
        run, label = (spec.split("=", 1) + [os.path.basename(spec.rstrip("/"))])[:2]
        with h5py.File(os.path.join(run, "results.h5"), "r") as f:
            steps = sorted(f["frames"].keys(), key=int)
            p0 = f["frames"][steps[0]]["position"][:, :2]
            ix, iy = lattice(p0)
            k = a.per_cell or per_cell_side(run)
            cell = (ix // k) * 100000 + (iy // k)
            width = np.ptp(p0[:, 0]) + np.diff(np.unique(np.round(p0[:, 0], 9))).min()
            moved = np.zeros(len(p0))
            chosen = set(steps[::a.every] + [steps[-1]])
            print(f"{label}: {len(p0)} points, {len(np.unique(cell))} cells of {k} x {k}")
            history = []  # (t, open share, mean excess pore pressure kPa or nan)
            for s in steps:
                g = f["frames"][s]
                pos = g["position"][:, :2]
                moved = np.maximum(moved, np.linalg.norm(pos - p0, axis=1))
                if a.series:
                    dp = (np.mean(g["excess_pore_pressure"][:]) / 1e3
                          if "excess_pore_pressure" in g else np.nan)
                    history.append((g.attrs["time"], np.mean(g["coordination"][:] < a.z), dp))
                if s not in chosen:
                    continue
                z, p = g["coordination"][:], g["p"][:]
                open_ = z < a.z
                cells = np.unique(cell[open_])
                in_open = np.isin(cell, cells)
                mates = in_open & ~open_
                rest = ~in_open
                med = lambda m: f"{np.median(p[m]) / 1e3:.1f}" if m.any() else "-"
                rows = " ".join(f"{np.sum(open_ & (iy % k == r))}" for r in range(k))
                cols = " ".join(f"{np.sum(open_ & (ix % k == c))}" for c in range(k))
                line = (f"  t {g.attrs['time']:.3f} s: open {open_.sum()}, in {len(cells)} cells; "
                        f"p of their cell-mates {med(mates)} kPa, elsewhere {med(rest)} kPa; "
                        f"open by row in the cell (bottom first) {rows}, by column {cols}")
                if a.dead > 0:
                    dead = moved < a.dead * width
                    line += f"; unmoved {dead.sum()}, open among them {np.sum(open_ & dead)}"
                print(line)
            if a.series:
                series.append((label, np.array(history)))
            if a.out:
                s = min(steps, key=lambda step: abs(f["frames"][step].attrs["time"] - a.time))
                g = f["frames"][s]
                panels.append((label, g.attrs["time"], g["position"][:, :2],
                               g[a.field][:] / 1e3, g["coordination"][:] < a.z))
    if a.out:
        draw(panels, a)
    if a.series:
        draw_series(series, a)


def draw(panels, a):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 4.5), squeeze=False)
    lo, hi = (map(float, a.limits.split(",")) if a.limits else (None, None))
    for ax, (label, t, pos, value, open_) in zip(axes[0], panels):
        sc = ax.scatter(pos[:, 0], pos[:, 1], c=value, s=6, cmap="coolwarm" if lo is not None
                        and lo < 0 < hi else "viridis", vmin=lo, vmax=hi)
        ax.scatter(pos[open_, 0], pos[open_, 1], s=14, facecolors="none", edgecolors="red",
                   linewidths=0.6, label=f"no contacts (Z < {a.z}): {open_.sum()}")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(f"{label}, t = {t:.3f} s", fontsize=9)
        ax.legend(loc="upper right", fontsize=7)
        fig.colorbar(sc, ax=ax, label=f"{a.field} (kPa)", shrink=0.7)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


def draw_series(series, a):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    wet = any(np.isfinite(h[:, 2]).any() for _, h in series)
    fig, axes = plt.subplots(1, 2 if wet else 1, figsize=(11 if wet else 5.5, 4), squeeze=False)
    for label, h in series:
        axes[0][0].plot(h[:, 0], 100 * h[:, 1], label=label)
        if wet and np.isfinite(h[:, 2]).any():
            axes[0][1].plot(h[:, 0], h[:, 2], label=label)
    axes[0][0].set_xlabel("t (s)")
    axes[0][0].set_ylabel(f"points without contacts, Z < {a.z} (%)")
    axes[0][0].legend(fontsize=7)
    if wet:
        axes[0][1].set_xlabel("t (s)")
        axes[0][1].set_ylabel("mean excess pore pressure (kPa)")
        axes[0][1].axhline(0, color="grey", lw=0.5)
        axes[0][1].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(a.series, dpi=110)
    print(f"wrote {a.series}")


if __name__ == "__main__":
    main()
