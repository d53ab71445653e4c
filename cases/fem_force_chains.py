#!/usr/bin/env python3
"""Force chains in the RVEs of chosen Gauss points of a FEMxDEM run (Guo & Zhao
2014 §4.1.3, Fig. 16): each packing's discs and contact forces, at chosen load
steps, a point inside the shear band against points at its edge and away from it.

Usage:
  /usr/bin/python3 cases/fem_force_chains.py RUN_DIR --points inside=39 edge=317 away=477 \
      --steps 13 100 [--rve-cli build/rve_server/cli/rve_cli] \
      [--figure cases/figures/fem-biaxial-force-chains.png]

RUN_DIR is a `fem_client run` whose output.packings holds the points
(e.g. `--set=output.packings=[39,317,477]`), with frames at the steps: its
packings-STEP.h5 are read through `rve_cli contacts`, which gives each contact's
forces as the engine's force law does. A line joins the centres of two discs in
contact, its width proportional to the normal force (the same scale in every
panel).
"""
import argparse
import csv
import os
import subprocess
import sys
import tempfile


def read_csv(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def packing(rve_cli, run_dir, step, point, scratch):
    prefix = os.path.join(scratch, f"{step}-{point}")
    subprocess.run([rve_cli, "contacts", f"--file={os.path.join(run_dir, f'packings-{step}.h5')}",
                    f"--id={point}", f"--out={prefix}"], check=True, stdout=subprocess.DEVNULL)
    discs = read_csv(prefix + "-discs.csv")
    contacts = read_csv(prefix + "-contacts.csv")
    return ([(float(d["x_m"]), float(d["y_m"]), float(d["radius_m"])) for d in discs],
            [(int(c["i"]), float(c["branch_x_m"]), float(c["branch_y_m"]),
              float(c["normal_force_N"])) for c in contacts])


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("run_dir")
    ap.add_argument("--points", nargs="+", required=True, metavar="LABEL=ID")
    ap.add_argument("--steps", nargs="+", type=int, required=True)
    ap.add_argument("--rve-cli", default="build/rve_server/cli/rve_cli")
    ap.add_argument("--figure", default=os.path.join(os.path.dirname(__file__), "figures",
                                                     "fem-biaxial-force-chains.png"))
    a = ap.parse_args()
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.collections import LineCollection
    points = [(p.partition("=")[0], int(p.partition("=")[2])) for p in a.points]
    with open(os.path.join(a.run_dir, "timeseries.csv"), newline="") as f:
        strain = {int(r["step"]): float(r["axial_strain"]) for r in csv.DictReader(f)}
    with tempfile.TemporaryDirectory() as scratch:
        data = {(s, p): packing(a.rve_cli, a.run_dir, s, p, scratch)
                for s in a.steps for _, p in points}
    fmax = max(c[3] for _, contacts in data.values() for c in contacts)
    fig, axes = plt.subplots(len(points), len(a.steps),
                             figsize=(3.2 * len(a.steps), 3.2 * len(points)), squeeze=False)
    for row, (label, point) in enumerate(points):
        for col, step in enumerate(a.steps):
            discs, contacts = data[(step, point)]
            ax = axes[row][col]
            for x, y, r in discs:
                ax.add_patch(plt.Circle((x, y), r, fill=False, lw=0.2, color="0.7"))
            segments = [[(discs[i][0], discs[i][1]), (discs[i][0] + bx, discs[i][1] + by)]
                        for i, bx, by, _ in contacts]
            widths = [4.0 * fn / fmax for *_, fn in contacts]
            ax.add_collection(LineCollection(segments, linewidths=widths, colors="k"))
            ax.set_aspect("equal")
            ax.autoscale_view()
            ax.set_xticks([])
            ax.set_yticks([])
            fn = [c[3] for c in contacts]
            ax.set_title(f"{label} (Gauss point {point}), {strain.get(step, 0) * 100:.1f} %\n"
                         f"{len(contacts)} contacts, max fn {max(fn, default=0):.0f} N",
                         fontsize=8)
    fig.suptitle("Force chains in the RVEs (line width ∝ normal force; G&Z Fig. 16)", fontsize=9)
    fig.tight_layout()
    fig.savefig(a.figure, dpi=75)
    print(f"wrote {a.figure}")
    for (step, point), (discs, contacts) in sorted(data.items()):
        fn = [c[3] for c in contacts]
        mean = sum(fn) / len(fn) if fn else 0.0
        print(f"step {step}, Gauss point {point}: {len(discs)} discs, {len(contacts)} contacts, "
              f"coordination {2 * len(contacts) / len(discs):.2f}, mean fn {mean:.1f} N, "
              f"max {max(fn, default=0):.1f} N")
    return 0


if __name__ == "__main__":
    sys.exit(main())
