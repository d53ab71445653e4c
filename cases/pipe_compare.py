#!/usr/bin/env python3
"""Soil-pipe interaction (liang-zhao-mpm-dem §3.4): the pipe's forces against its displacement
in the paper's two stages, with the figures the paper gives for its Fig. 21.

  /usr/bin/python3 cases/pipe_compare.py RUN_DIR [--body=pipe] [--out=pipe.png]

Reads RUN_DIR/timeseries.csv (time, BODY_fx, BODY_fy: what the soil exerts on the pipe, N per m
of pipe; BODY_dx, BODY_dy: the pipe's displacement, m). Works on a run still going or stopped
early: it reports the stages it reached. The penetration stage is where the pipe has not yet
moved sideways, the lateral stage the rest.

The paper's figures (text of §3.4, Fig. 21): the vertical force grows to a peak of 250 kN
towards the end of the 0.8 m penetration, with moderate fluctuations, then drops suddenly;
in the lateral stage the vertical force falls to a steady 25 kN while the horizontal force
rises quickly to 50 kN and keeps growing slightly (the berm ahead of the pipe). kN per m of
pipe (plane strain). Needs numpy and matplotlib (Debian's python3-numpy, python3-matplotlib).
"""
import argparse
import csv
import os

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

PAPER_PEAK_VERTICAL_KN = 250.0
PAPER_LATERAL_VERTICAL_KN = 25.0
PAPER_LATERAL_HORIZONTAL_KN = 50.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run")
    ap.add_argument("--body", default="pipe")
    ap.add_argument("--out", default="pipe.png")
    a = ap.parse_args()
    with open(os.path.join(a.run, "timeseries.csv")) as f:
        rows = list(csv.DictReader(f))
    col = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    t = col["time"]
    fx, fy = col[a.body + "_fx"] / 1e3, col[a.body + "_fy"] / 1e3  # kN/m
    down, left = -col[a.body + "_dy"], -col[a.body + "_dx"]  # m
    lateral = left > 1e-4
    pen = ~lateral
    name = os.path.basename(a.run.rstrip("/"))
    print(f"{name}: {len(t)} rows to t = {t[-1]:.3f} s, pipe {down[-1]:.3f} m down, "
          f"{left[-1]:.3f} m to the left")
    i = int(np.argmax(np.where(pen, fy, -np.inf)))
    print(f"  penetration: peak vertical force {fy[i]:.1f} kN/m at {down[i]:.3f} m down "
          f"(t = {t[i]:.2f} s; paper {PAPER_PEAK_VERTICAL_KN:.0f} kN towards 0.8 m); "
          f"horizontal force within +-{np.max(np.abs(fx[pen])):.1f} kN/m")
    # The force fluctuates from row to row (the paper: stress waves); its
    # mean over +-0.01 m of displacement gives a peak that is not one spike.
    grid = np.arange(0.01, down[pen].max() - 0.01 + 1e-9, 0.005)
    if grid.size:
        smooth = np.array([np.mean(fy[pen][np.abs(down[pen] - d) <= 0.01]) for d in grid])
        j = int(np.argmax(smooth))
        print(f"  penetration, mean over +-0.01 m: peak {smooth[j]:.1f} kN/m at {grid[j]:.3f} m down")
    for d in (0.2, 0.4, 0.6, 0.8):
        near = pen & (np.abs(down - d) < 0.01)
        if near.any():
            print(f"    at {d:.1f} m down: vertical {np.mean(fy[near]):.1f} kN/m "
                  f"(mean over +-0.01 m)")
    if lateral.any():
        late = lateral & (left > 0.1)
        if late.any():
            print(f"  lateral (from 0.1 m on): vertical force median {np.median(fy[late]):.1f} kN/m "
                  f"(paper {PAPER_LATERAL_VERTICAL_KN:.0f}), horizontal median "
                  f"{np.median(-fx[late]):.1f} kN/m (paper {PAPER_LATERAL_HORIZONTAL_KN:.0f}), "
                  f"to {left[late][-1]:.3f} m")
    else:
        print("  lateral stage not reached")

    fig, (ax_t, ax_d, ax_l) = plt.subplots(1, 3, figsize=(17, 4.8))
    ax_t.plot(t, fy, lw=0.7, label="vertical F_y")
    ax_t.plot(t, -fx, lw=0.7, label="horizontal -F_x (resisting the pull to the left)")
    ax_t.axhline(PAPER_PEAK_VERTICAL_KN, color="k", ls=":", lw=0.8, label="paper: peak vertical")
    ax_t.set_xlabel("time (s)")
    ax_t.set_ylabel("force of the soil on the pipe (kN/m)")
    ax_t.set_title(f"{name}: forces against time")
    ax_t.legend(fontsize=8)
    ax_d.plot(down[pen], fy[pen], lw=0.7)
    ax_d.plot([0.8], [PAPER_PEAK_VERTICAL_KN], "k*", ms=10, label="paper: 250 kN near 0.8 m")
    ax_d.set_xlabel("pipe displacement down (m)")
    ax_d.set_ylabel("vertical force (kN/m)")
    ax_d.set_title(f"{name}: penetration")
    ax_d.legend(fontsize=8)
    if lateral.any():
        ax_l.plot(left[lateral], fy[lateral], lw=0.7, label="vertical")
        ax_l.plot(left[lateral], -fx[lateral], lw=0.7, label="horizontal")
        ax_l.axhline(PAPER_LATERAL_VERTICAL_KN, color="C0", ls=":", lw=0.8, label="paper: vertical")
        ax_l.axhline(PAPER_LATERAL_HORIZONTAL_KN, color="C1", ls=":", lw=0.8,
                     label="paper: horizontal")
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
