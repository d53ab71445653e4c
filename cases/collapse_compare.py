#!/usr/bin/env python3
"""Column-collapse runs side by side: front and kinetic energy against time, the final
deposit coloured by deviatoric strain, and per run the normalised run-out d* and the
angle of the dead zone (the wedge of points that never moved).

  /usr/bin/python3 cases/collapse_compare.py RUN_DIR[=LABEL] ... [--out=collapse.png]
      [--dead=0.01]
  /usr/bin/python3 cases/collapse_compare.py --points CSV ... [--dead=0.01]

Beside d* from the farthest point it prints the front of the main deposit: the paper
measures d_f "after removing the scatter points" not in contact with the main deposit. Two
points are taken as in contact when they lie within --link initial point spacings (2: a gap
of at most one missing point); the main deposit is the largest set of points so linked, and
the others (drawn grey) are scatter. It also prints where the main deposit is at least 2
and 3 points thick, since a sheet one or two points thick along the base is where such
readings part, and where 98 and 99 % of the points lie behind (the points carry equal
shares of the column's mass): a reading that no single link decides (summary.json's
runout_normalised_mass98 and _mass99).

The energy panel is the paper's Fig. 27: kinetic, potential and dissipated energy over the
initial potential energy, E_d = E_p0 - E_p - E_k (paper: E_k peaks at 0.1 E_p0 near 0.4 s,
E_d ends at 0.55 E_p0); it needs the timeseries' potential_energy column and the base at y = 0, where the collapse cases put it.

Reads each RUN_DIR's timeseries.csv (time, front_x, kinetic_energy; deposit_front_x where
the run wrote it, else the main deposit's front comes from every frame) and results.h5
(frames/STEP/position, eps_q). d0 is the column's initial width: the largest initial x of
the points plus their half spacing, as summary.json's run-out (cases/FORMAT.md). A point is
in the dead zone when its displacement from its initial position never exceeded
`--dead`·d0 in any frame; the dead zone's angle to the base is that of a straight line
fitted to its upper edge (per row of points, the rightmost dead point). Needs numpy, h5py
and matplotlib (Debian's python3-numpy, python3-h5py, python3-matplotlib).

--points reads instead the points CSVs of a continuum on the same case
(tests/mpm_client/run/prandtl_test.cc's DISABLED_MeasureWithMohrCoulomb with RVEHUB_PRANDTL_POINTS_CSV: the
points' starts x0, y0, their ends x and the largest distance each has been from its start,
over every step) and prints the same dead zone and where 98 and 99 % of the points lie.
"""
import argparse
import csv
import os

import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read_series(run):
    with open(os.path.join(run, "timeseries.csv")) as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time"]) for r in rows])
    front = np.array([float(r["front_x"]) for r in rows])
    deposit = (np.array([float(r["deposit_front_x"]) for r in rows])
               if "deposit_front_x" in rows[0] else None)
    ke = np.array([float(r["kinetic_energy"]) for r in rows])
    pe = (np.array([float(r["potential_energy"]) for r in rows])
          if "potential_energy" in rows[0] else None)
    return t, front, deposit, ke, pe


def read_frames(run):
    """Times (s) and positions (m) of every frame in step order, and the last frame's eps_q."""
    with h5py.File(os.path.join(run, "results.h5"), "r") as f:
        steps = sorted(f["frames"].keys(), key=int)
        times = np.array([f["frames"][s].attrs["time"] for s in steps])
        pos = np.stack([f["frames"][s]["position"][:, :2] for s in steps])
        eps_q = f["frames"][steps[-1]]["eps_q"][:]
    return times, pos, eps_q


def column_width(x0):
    """The initial point spacing and the column's width d0 (m) from the points' initial x."""
    spacing = np.diff(np.unique(np.round(x0, 9))).min()
    return spacing, x0.max() + spacing / 2


def share_fronts(x_end, spacing):
    """(percent, x) for 98 and 99 %: where that share of the points lies behind, m, half a
    spacing added to the point's centre (the points carry equal shares of the mass)."""
    xs = np.sort(x_end)
    return [(q, xs[int(np.ceil(q / 100 * len(xs))) - 1] + spacing / 2) for q in (98, 99)]


def points_summary(path, dead):
    """The dead zone and the 98 and 99 % fronts of a continuum's points CSV (--points), read
    as a run's: d0 and the fronts with half the initial spacing added."""
    with open(path) as f:
        rows = list(csv.DictReader(f))
    missing = {"x", "x0", "y0", "max_displacement"} - set(rows[0] if rows else ())
    if missing:
        raise SystemExit(f"{path}: no points or no column {', '.join(sorted(missing))} (a points "
                         "CSV from the measuring tool)")
    col = lambda key: np.array([float(r[key]) for r in rows])  # noqa: E731
    start = np.column_stack([col("x0"), col("y0")])
    spacing, d0 = column_width(start[:, 0])
    # dead_zone takes the largest distance from the start over the frames: two "frames",
    # the start and the start moved by that distance.
    moved = start + np.column_stack([col("max_displacement"), np.zeros(len(rows))])
    mask, angle = dead_zone(np.stack([start, moved]), d0, dead)
    fronts = ", ".join(f"{q:g} % lie behind d* {(x - d0) / d0:.2f}"
                       for q, x in share_fronts(col("x"), spacing))
    angle_text = "n/a" if angle is None else f"{angle:.1f} deg"
    print(f"{path}: dead zone {mask.sum()} points, angle {angle_text}; of the points {fronts}")


def stop_time(t, front, tolerance):
    """The first time from which the front stays within tolerance of its last value
    (summary.json's front_stop_time_s)."""
    k = len(front) - 1
    while k > 0 and abs(front[k - 1] - front[-1]) <= tolerance:
        k -= 1
    return t[k]


def thick_front(final, spacing, layers):
    """The farthest x (m) at which the deposit is at least `layers` points thick: its top
    (the highest point within one spacing of x, plus half a spacing) stands that high."""
    x, y = final[:, 0], final[:, 1]
    order = np.argsort(-x)
    for i in order:
        near = np.abs(x - x[i]) <= spacing / 2
        if y[near].max() + spacing / 2 >= layers * spacing - 1e-9:
            return x[i] + spacing / 2
    return 0.0


def main_deposit(final, spacing, link):
    """Mask of the points in the largest set linked by distances <= link·spacing."""
    reach = link * spacing
    n = len(final)
    parent = np.arange(n)

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    bins = {}
    for i, key in enumerate(map(tuple, np.floor(final / reach).astype(int))):
        bins.setdefault(key, []).append(i)
    for (bx, by), members in bins.items():
        near = [j for dx in (-1, 0, 1) for dy in (-1, 0, 1) for j in bins.get((bx + dx, by + dy), [])]
        near = np.array(near)
        for i in members:
            close = near[np.linalg.norm(final[near] - final[i], axis=1) <= reach]
            for j in close:
                ri, rj = root(i), root(j)
                if ri != rj:
                    parent[ri] = rj
    roots = np.array([root(i) for i in range(n)])
    return roots == np.bincount(roots).argmax()


def dead_zone(pos, d0, dead):
    """Mask of the points that never moved more than dead·d0, and the angle (deg) of the
    line fitted to the dead zone's upper-right edge (None when too few rows)."""
    moved = np.linalg.norm(pos - pos[0], axis=2).max(axis=0)
    mask = moved < dead * d0
    x0, y0 = pos[0, :, 0], pos[0, :, 1]
    edge_x, edge_y = [], []
    for y in np.unique(np.round(y0[mask], 9)):
        row = mask & (np.abs(y0 - y) < 1e-9)
        edge_x.append(x0[row].max())
        edge_y.append(y)
    if len(edge_x) < 3:
        return mask, None
    slope = np.polyfit(edge_x, edge_y, 1)[0]  # dy/dx of the edge (negative: falls to the right)
    return mask, float(np.degrees(np.arctan(abs(slope))))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="*", help="RUN_DIR or RUN_DIR=LABEL")
    ap.add_argument("--points", nargs="+", metavar="CSV",
                    help="instead of runs: continuum points CSVs (see above)")
    ap.add_argument("--out", default="collapse.png")
    ap.add_argument("--dead", type=float, default=0.01,
                    help="dead-zone displacement threshold as a fraction of d0")
    ap.add_argument("--link", type=float, default=2.0,
                    help="points within this many initial spacings are in contact")
    a = ap.parse_args()
    if not a.link > 0:
        ap.error(f"--link must be > 0, got {a.link}")
    if a.points:
        for path in a.points:
            points_summary(path, a.dead)
        return
    if not a.runs:
        ap.error("give run directories or --points CSVs")
    runs = [(r.split("=", 1) + [os.path.basename(r.rstrip("/"))])[:2] for r in a.runs]
    panels = 3 + len(runs)
    fig, axes = plt.subplots(1, panels, figsize=(5 * panels, 4))
    for run, label in runs:
        t, front, deposit, ke, pe = read_series(run)
        frame_t, pos, eps_q = read_frames(run)
        x0 = pos[0, :, 0]
        spacing, d0 = column_width(x0)
        d_f = pos[-1, :, 0].max() + spacing / 2
        runout = (d_f - d0) / d0
        mask, angle = dead_zone(pos, d0, a.dead)
        angle_text = "n/a" if angle is None else f"{angle:.1f} deg"
        print(f"{label}: d* = {runout:.3f} at t = {t[-1]:.3f} s, front {d_f:.3f} m, "
              f"peak KE {ke.max():.4g} J at {t[ke.argmax()]:.3f} s, dead zone {mask.sum()} "
              f"points, angle {angle_text}")
        main = main_deposit(pos[-1], spacing, a.link)
        main_front = pos[-1, main, 0].max() + spacing / 2
        print(f"{label}: main deposit (linked within {a.link:g} spacings; {np.sum(~main)} "
              f"scatter points off it): front {main_front:.3f} m, d* {(main_front - d0) / d0:.3f}")
        fronts = [(k, thick_front(pos[-1][main], spacing, k)) for k in (2, 3)]
        print(f"{label}: where the main deposit is at least " + ", ".join(
            f"{k} points thick: {x:.3f} m (d* {(x - d0) / d0:.2f})" for k, x in fronts))
        print(f"{label}: of all the points, " + ", ".join(
            f"{q:g} % lie behind {x:.3f} m (d* {(x - d0) / d0:.2f})"
            for q, x in share_fronts(pos[-1, :, 0], spacing)))
        # The main deposit's front in time: the run's own column where it wrote one
        # (two spacings), else from every frame.
        if deposit is not None and a.link == 2.0:
            dep_t, dep = t, deposit
        else:
            dep_t = frame_t
            dep = np.array([p[main_deposit(p, spacing, a.link), 0].max() for p in pos])
        stop = stop_time(dep_t, dep, 0.01 * d0)
        still = "at rest" if stop <= 0.9 * dep_t[-1] else "still moving at the end"
        print(f"{label}: main deposit's front within 1 % of d0 of its last value from "
              f"{stop:.3f} s ({still})")
        line, = axes[0].plot(dep_t, dep + spacing / 2, label=label)
        axes[0].plot(t, front + spacing / 2, ":", color=line.get_color(), lw=0.8)
        axes[1].plot(t, ke, label=label)
        if pe is not None:
            ep0 = pe[0]
            dissipated = (ep0 - pe - ke) / ep0
            print(f"{label}: E_k peaks at {ke.max() / ep0:.3f} E_p0, E_d = {dissipated[-1]:.3f} "
                  f"E_p0 at t = {t[-1]:.3f} s (E_p0 = {ep0:.5g} J)")
            line, = axes[2].plot(t, ke / ep0, label=f"{label}: E_k")
            axes[2].plot(t, pe / ep0, "--", color=line.get_color(), label=f"{label}: E_p")
            axes[2].plot(t, dissipated, ":", color=line.get_color(), label=f"{label}: E_d")
        ax = axes[3 + runs.index([run, label])]
        sc = ax.scatter(pos[-1, :, 0], pos[-1, :, 1], c=eps_q, s=8, cmap="viridis", vmin=0,
                        vmax=max(1.0, np.percentile(eps_q, 95)))
        ax.scatter(pos[-1, mask, 0], pos[-1, mask, 1], s=8, facecolors="none",
                   edgecolors="red", linewidths=0.5, label=f"dead zone ({angle_text})")
        if (~main).any():
            ax.scatter(pos[-1, ~main, 0], pos[-1, ~main, 1], s=10, color="grey", marker="x",
                       linewidths=0.6, label=f"scatter ({np.sum(~main)})")
        ax.set_aspect("equal")
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        ax.set_title(f"{label}: deposit at {t[-1]:.2f} s, d* = {(main_front - d0) / d0:.2f} "
                     f"(farthest point {runout:.2f})", fontsize=9)
        ax.legend(loc="upper right", fontsize=8)
        fig.colorbar(sc, ax=ax, label="eps_q (-)", shrink=0.7)
    axes[0].set_xlabel("time (s)")
    axes[0].set_ylabel("front d_f (m)")
    axes[0].set_title("main deposit's front (dotted: farthest point)")
    axes[0].legend()
    axes[1].set_xlabel("time (s)")
    axes[1].set_ylabel("kinetic energy (J)")
    axes[1].set_title("kinetic energy")
    axes[1].legend()
    axes[2].axhline(0.1, color="grey", lw=0.5)
    axes[2].axhline(0.55, color="grey", lw=0.5)
    axes[2].set_xlabel("time (s)")
    axes[2].set_ylabel("energy / E_p0 (-)")
    axes[2].set_title("energies (grey: paper's E_k peak 0.1, final E_d 0.55)")
    axes[2].legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
