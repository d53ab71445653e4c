#!/usr/bin/env python3
"""Field snapshots of an mpm_client run: deviatoric strain, void ratio and rotation of the
material points at chosen frames, with the case's rigid bodies drawn where they were.

  /usr/bin/python3 cases/plot_fields.py CASE.json RUN_DIR [--frames=last|STEP,STEP,...]
      [--fields=eps_q,void_ratio,rotation] [--xlim=0,4 --ylim=4,8]
      [--limits=eps_q=0:1.5,void_ratio=0.15:0.4] [--out=RUN_DIR/fields.png]

Reads RUN_DIR/results.h5 (frames/STEP/...) and RUN_DIR/timeseries.csv (each body's
<name>_dx, <name>_dy at the nearest recorded step). --limits fixes a field's colour range
(values beyond it take the end colours), so that a few points strained far beyond the rest
do not wash out the shear bands. Needs numpy, h5py and matplotlib
(Debian's python3-numpy, python3-h5py, python3-matplotlib).
"""
import argparse
import csv
import json
import os

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.patches import Circle, Rectangle  # noqa: E402

LABELS = {
    "eps_q": "deviatoric strain eps_q (-)",
    "eps_v": "volumetric strain eps_v (-, compression +)",
    "void_ratio": "void ratio e (-)",
    "rotation": "mean particle rotation (rad)",
    "p": "mean stress p (Pa)",
    "q": "deviator q (Pa)",
    "fabric_anisotropy": "fabric anisotropy Fa (-)",
    "coordination": "coordination number (-)",
}


def body_offsets(csv_path, names, step):
    """Each body's displacement (m) at the recorded step nearest to `step`."""
    best, row_at = None, None
    with open(csv_path) as f:
        for row in csv.DictReader(f):
            d = abs(int(float(row["step"])) - step)
            if best is None or d < best:
                best, row_at = d, row
    if row_at is None:
        return {n: (0.0, 0.0) for n in names}
    return {n: (float(row_at.get(n + "_dx", 0.0)), float(row_at.get(n + "_dy", 0.0)))
            for n in names}


def draw_body(ax, body, offset):
    cx, cy = body["center"][0] + offset[0], body["center"][1] + offset[1]
    style = dict(facecolor="0.6", edgecolor="k", linewidth=0.8, zorder=3)
    if body["shape"] == "circle":
        ax.add_patch(Circle((cx, cy), body["radius"], **style))
    else:
        hx, hy = body["half_size"]
        ax.add_patch(Rectangle((cx - hx, cy - hy), 2 * hx, 2 * hy, **style))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("case")
    ap.add_argument("run_dir")
    ap.add_argument("--frames", default="last")
    ap.add_argument("--fields", default="eps_q,void_ratio,rotation")
    ap.add_argument("--xlim", default=None, help="x0,x1 in m")
    ap.add_argument("--ylim", default=None, help="y0,y1 in m")
    ap.add_argument("--limits", default="", help="FIELD=LOW:HIGH,... colour ranges")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    limits = {}
    for item in filter(None, a.limits.split(",")):
        try:
            name, span = item.split("=")
            low, high = map(float, span.split(":"))
        except ValueError:
            ap.error(f"--limits: expected FIELD=LOW:HIGH, got {item!r}")
        limits[name] = (low, high)
    with open(a.case) as f:
        case = json.load(f)
    bodies = case.get("bodies", [])
    fields = a.fields.split(",")
    with h5py.File(os.path.join(a.run_dir, "results.h5"), "r") as h5:
        steps = sorted(int(k) for k in h5["frames"].keys())
        frames = [steps[-1]] if a.frames == "last" else [int(s) for s in a.frames.split(",")]
        fig, axes = plt.subplots(len(frames), len(fields), squeeze=False,
                                 figsize=(5.2 * len(fields), 4.2 * len(frames)))
        # Square markers about one initial point spacing wide on a ~4 in axis.
        grid = case["grid"]
        spacing = grid["cell_size"] / min(r.get("points_per_cell_side", 2)
                                          for r in case["regions"])
        if a.xlim:
            x0, x1 = map(float, a.xlim.split(","))
            span = x1 - x0
        else:
            span = grid["cell_size"] * grid["cells"][0]
        size = (72.0 * 3.6 / span * spacing) ** 2
        for i, step in enumerate(frames):
            g = h5["frames"][str(step)]
            x, y = g["position"][:, 0], g["position"][:, 1]
            offsets = body_offsets(os.path.join(a.run_dir, "timeseries.csv"),
                                   [b["name"] for b in bodies], step)
            for j, name in enumerate(fields):
                ax = axes[i][j]
                low, high = limits.get(name, (None, None))
                sc = ax.scatter(x, y, c=g[name][:], s=size, marker="s", cmap="viridis",
                                linewidths=0, vmin=low, vmax=high)
                fig.colorbar(sc, ax=ax, label=LABELS.get(name, name),
                             extend="both" if name in limits else "neither")
                for b in bodies:
                    draw_body(ax, b, offsets[b["name"]])
                ax.set_aspect("equal")
                if a.xlim:
                    ax.set_xlim(*map(float, a.xlim.split(",")))
                if a.ylim:
                    ax.set_ylim(*map(float, a.ylim.split(",")))
                ax.set_title(f"{case['name']}: {name}, t = {g.attrs['time']:.3g} s (step {step})",
                             fontsize=9)
                ax.set_xlabel("x (m)")
                ax.set_ylabel("y (m)")
        fig.tight_layout()
        out = a.out or os.path.join(a.run_dir, "fields.png")
        fig.savefig(out, dpi=110)
        print(out)


if __name__ == "__main__":
    main()
