#!/usr/bin/env python3
"""Soil-pipe interaction (liang-zhao-mpm-dem §3.4): the pipe's forces against its displacement
in the paper's two stages, with the figures the paper gives for its Fig. 21.

  /usr/bin/python3 cases/pipe_compare.py RUN_DIR [--body=pipe] [--out=pipe.png]

Reads RUN_DIR/timeseries.csv (time, BODY_fx, BODY_fy: what the soil exerts on the pipe, N per m
of pipe; BODY_dx, BODY_dy: the pipe's displacement, m). Works on a run still going or stopped
early: it reports the stages it reached. The penetration stage is where the pipe has not yet
moved sideways, the lateral stage the rest. Its figures are summary.json's (cases/FORMAT.md):
the penetration peak of the force's mean over one grid cell of penetration (cell size from
RUN_DIR/run.json), the lateral forces' medians over the second half of the sideways travel.

The paper's figures (text of §3.4, Fig. 21): the vertical force grows to a peak of 250 kN
towards the end of the 0.8 m penetration, with moderate fluctuations, then drops suddenly;
in the lateral stage the vertical force falls to a steady 25 kN while the horizontal force
rises quickly to 50 kN and keeps growing slightly (the berm ahead of the pipe). kN per m of
pipe (plane strain).

For scale, the penetration panel also draws the drained bearing capacity of a strip as wide as
the pipe's chord at the original surface, B = 2 sqrt(d (2R - d)) (2R once d >= R), embedded to
the pipe's penetration d: F = B (gamma d N_q + gamma B N_gamma / 2), with Prandtl's N_q and
Meyerhof's N_gamma = (N_q - 1) tan(1.4 phi) (close to Martin's exact values for a rough strip),
the way pipeline design estimates vertical penetration in drained sand. It is drawn for the
RVE's peak friction angle and for its critical-state angle (cases/friction_angle.py:
footing-dense 30.19 and 19.9 deg, means over nine seeds), gamma from the geostatic stresses of the run's first frame
(results.h5). It ignores the heave and the pipe's curvature: a scale, not a solution.
Needs numpy and matplotlib (Debian's python3-numpy, python3-matplotlib), h5py for gamma.
"""
import argparse
import csv
import json
import math
import os

import matplotlib
import numpy as np

from friction_angle import prandtl_nq

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

PAPER_PEAK_VERTICAL_KN = 250.0
PAPER_LATERAL_VERTICAL_KN = 25.0
PAPER_LATERAL_HORIZONTAL_KN = 50.0
SIDEWAYS_M = 1e-4  # the lateral stage starts when the pipe has moved this far sideways (summary.cc)


def strip_bearing_force(d, radius, gamma, phi_deg):
    """Drained bearing capacity of the pipe's chord as a strip, N per m (see the docstring).

    d: penetration, m (array); radius: m; gamma: unit weight, N/m^3; phi_deg: degrees."""
    phi = math.radians(phi_deg)
    nq = prandtl_nq(phi)
    ngamma = (nq - 1) * math.tan(1.4 * phi)
    width = 2 * np.sqrt(np.clip(d, 0, radius) * (2 * radius - np.clip(d, 0, radius)))
    return width * (gamma * d * nq + 0.5 * gamma * width * ngamma)


def unit_weight(run, surface_y):
    """gamma, N/m^3: slope of the first frame's mean stress against depth below surface_y
    (the geostatic stresses the run started from; points within 0.3 m of the surface, where
    the pressure floor acts, are left out). None without results.h5."""
    path = os.path.join(run, "results.h5")
    if not os.path.exists(path):
        return None
    import h5py
    with h5py.File(path, "r") as f:
        frames = f["frames"]
        first = frames[min(frames.keys(), key=int)]
        depth = surface_y - first["position"][:, 1]
        p = first["p"][:]
    deep = depth > 0.3
    return float(np.polyfit(depth[deep], p[deep], 1)[0])


def load_run(run, body):
    """time, fx, fy (kN/m), down, left (m) and the grid's cell size (m) of a run directory."""
    with open(os.path.join(run, "timeseries.csv")) as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    with open(os.path.join(run, "run.json")) as f:
        cell = json.load(f)["case"]["grid"]["cell_size"]
    return (col["time"], col[body + "_fx"] / 1e3, col[body + "_fy"] / 1e3, -col[body + "_dy"],
            -col[body + "_dx"], cell)


def cell_mean(down, force, cell):
    """The force's mean over one cell of penetration around each row (summary.json's rule)."""
    return np.array([np.mean(force[np.abs(down - d) <= 0.5 * cell]) for d in down])


def penetration(down, left, fy, cell):
    """The penetration rows (the pipe not yet moved sideways), their cell-mean vertical force
    (cell_mean) and the row of its peak."""
    pen = left <= SIDEWAYS_M
    smooth = cell_mean(down[pen], fy[pen], cell)
    return pen, smooth, int(np.argmax(smooth))


def lateral_medians(fx, fy, left, lateral):
    """The vertical and horizontal forces' medians over the second half of the sideways travel
    (summary.json's rule), kN/m."""
    late = lateral & (left >= 0.5 * left.max())
    return float(np.median(fy[late])), float(np.median(np.abs(fx[late])))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    ap.add_argument("--body", default="pipe")
    ap.add_argument("--out", default="pipe.png")
    ap.add_argument("--radius", type=float, default=0.5, help="pipe radius, m")
    ap.add_argument("--surface", type=float, default=2.5, help="initial soil surface y, m")
    ap.add_argument("--phi", type=float, default=30.19, help="peak friction angle, deg")
    ap.add_argument("--phi-cs", type=float, default=19.9, help="critical-state angle, deg")
    ap.add_argument("--gamma", type=float, help="unit weight, N/m^3 (default: from results.h5)")
    ap.add_argument("--also", action="append", default=[], metavar="RUN_DIR",
                    help="another run of the case to draw beside it (e.g. another mesh)")
    a = ap.parse_args()
    gamma = a.gamma if a.gamma else unit_weight(a.run, a.surface)
    t, fx, fy, down, left, cell = load_run(a.run, a.body)
    pen, smooth, j = penetration(down, left, fy, cell)
    lateral = ~pen
    name = os.path.basename(a.run.rstrip("/"))
    print(f"{name}: {len(t)} rows to t = {t[-1]:.3f} s, pipe {down[-1]:.3f} m down, "
          f"{left[-1]:.3f} m to the left")
    if gamma:
        print(f"  unit weight {gamma / 1e3:.2f} kN/m^3 (first frame's geostatic stresses)")
    i = int(np.argmax(np.where(pen, fy, -np.inf)))
    print(f"  penetration: peak vertical force {fy[i]:.1f} kN/m at {down[i]:.3f} m down "
          f"(t = {t[i]:.2f} s; paper {PAPER_PEAK_VERTICAL_KN:.0f} kN towards 0.8 m); "
          f"horizontal force within +-{np.max(np.abs(fx[pen])):.1f} kN/m")
    # The force fluctuates from row to row (the paper: stress waves); as
    # summary.json does, the peak is that of its mean over one grid cell of
    # penetration (the cell size from the run record, run.json).
    print(f"  penetration, mean over one cell ({cell:g} m): peak {smooth[j]:.1f} kN/m at "
          f"{down[pen][j]:.3f} m down")
    for d in (0.2, 0.4, 0.6, 0.8):
        near = pen & (np.abs(down - d) <= 0.5 * cell)
        if near.any():
            scale = ""
            if gamma:
                scale = ", strip bearing capacity {:.0f} (phi {:g}) / {:.0f} (phi_cs {:g})".format(
                    strip_bearing_force(d, a.radius, gamma, a.phi) / 1e3, a.phi,
                    strip_bearing_force(d, a.radius, gamma, a.phi_cs) / 1e3, a.phi_cs)
            print(f"    at {d:.1f} m down: vertical {np.mean(fy[near]):.1f} kN/m "
                  f"(mean over one cell){scale}")
    if lateral.any():
        vertical, horizontal = lateral_medians(fx, fy, left, lateral)
        print(f"  lateral (from {0.5 * left.max():.3f} m on): vertical force median "
              f"{vertical:.1f} kN/m (paper {PAPER_LATERAL_VERTICAL_KN:.0f}), horizontal "
              f"median {horizontal:.1f} kN/m (paper {PAPER_LATERAL_HORIZONTAL_KN:.0f}), "
              f"to {left.max():.3f} m")
    else:
        print("  lateral stage not reached")

    fig, (ax_t, ax_d, ax_l) = plt.subplots(1, 3, figsize=(17, 4.8))
    ax_t.plot(t, fy, lw=0.7, label="vertical F_y")
    ax_t.plot(t, fx, lw=0.7, label="horizontal F_x (+: resisting the pull to the left)")
    ax_t.axhline(PAPER_PEAK_VERTICAL_KN, color="k", ls=":", lw=0.8, label="paper: peak vertical")
    ax_t.set_xlabel("time (s)")
    ax_t.set_ylabel("force of the soil on the pipe (kN/m)")
    ax_t.set_title(f"{name}: forces against time")
    ax_t.legend(fontsize=8)
    ax_d.plot(down[pen], fy[pen], lw=0.7, label=f"{name} (cells of {cell:g} m)")
    for k, other in enumerate(a.also):
        _, ofx, ofy, odown, oleft, ocell = load_run(other, a.body)
        oname = os.path.basename(other.rstrip("/"))
        opn, osm, oj = penetration(odown, oleft, ofy, ocell)
        olat = ~opn
        print(f"  {oname}: penetration peak {osm[oj]:.1f} kN/m (mean over one cell of "
              f"{ocell:g} m) at {odown[opn][oj]:.3f} m down, to {odown.max():.3f} m")
        ax_d.plot(odown[opn], ofy[opn], lw=0.7, color=f"C{k + 2}",
                  label=f"{oname} (cells of {ocell:g} m)")
        if olat.any():
            vertical, horizontal = lateral_medians(ofx, ofy, oleft, olat)
            print(f"  {oname}: lateral medians vertical {vertical:.1f}, horizontal "
                  f"{horizontal:.1f} kN/m, to {oleft.max():.3f} m")
            ls = ("--", ":", "-.")[k % 3]
            ax_l.plot(oleft[olat], ofy[olat], lw=0.6, ls=ls, color="C0", label=f"vertical, {oname}")
            ax_l.plot(oleft[olat], ofx[olat], lw=0.6, ls=ls, color="C1",
                      label=f"horizontal F_x, {oname}")
    ax_d.plot([0.8], [PAPER_PEAK_VERTICAL_KN], "k*", ms=10, label="paper: 250 kN near 0.8 m")
    if gamma:
        dd = np.linspace(0, max(down[pen].max(), 1.6 * a.radius), 81)
        for phi, ls in ((a.phi, "--"), (a.phi_cs, "-.")):
            ax_d.plot(dd, strip_bearing_force(dd, a.radius, gamma, phi) / 1e3, "k", ls=ls, lw=0.8,
                      label=f"strip bearing capacity, phi = {phi:g} deg")
        ax_d.set_ylim(0, 1.15 * max(PAPER_PEAK_VERTICAL_KN, fy[pen].max()))
    ax_d.set_xlabel("pipe displacement down (m)")
    ax_d.set_ylabel("vertical force (kN/m)")
    ax_d.set_title(f"{name}: penetration")
    ax_d.legend(fontsize=8)
    if lateral.any():
        ax_l.plot(left[lateral], fy[lateral], lw=0.7, label="vertical")
        ax_l.plot(left[lateral], fx[lateral], lw=0.7, label="horizontal F_x")
        ax_l.axhline(PAPER_LATERAL_VERTICAL_KN, color="C0", ls=":", lw=0.8, label="paper: vertical")
        ax_l.axhline(PAPER_LATERAL_HORIZONTAL_KN, color="C1", ls=":", lw=0.8,
                     label="paper: horizontal")
        ax_l.legend(fontsize=8)
    elif ax_l.lines:
        ax_l.legend(fontsize=8)
    else:
        ax_l.text(0.5, 0.5, "lateral stage not reached", ha="center", transform=ax_l.transAxes)
    ax_l.set_xlabel("pipe displacement to the left (m)")
    ax_l.set_ylabel("force (kN/m)")
    ax_l.set_title(f"{name}: lateral movement")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
