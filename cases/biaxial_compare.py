#!/usr/bin/env python3
"""The biaxial specimen on several meshes (liang-zhao-mpm-dem §3.2, Figs. 6-7): each run's
nominal curve (platen force over the specimen's width against platen travel over its height,
compression +) on one panel, with the DEM element test on the same RVE, and the peak and the
stress at the end listed.

  /usr/bin/python3 cases/biaxial_compare.py RUN_DIR[=LABEL] [RUN_DIR[=LABEL] ...] [--reference=CSV]
      [--out=biaxial-meshes.png] [--title=TEXT]

Each RUN_DIR holds run.json (its case: the first region and the plot_body, else the first
body) and timeseries.csv (<body>_fy, <body>_dy). The reference is an `rve_cli element-test`
CSV (syy against axial_strain); by default the one the first run's case names in
output.reference_curve. Needs numpy and matplotlib (Debian's python3-numpy,
python3-matplotlib).
"""
import argparse
import json
import os

import numpy as np
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def nominal_curve(run_dir):
    """(case name, strain [-], stress [Pa], lost points at the end or None) of a run."""
    with open(os.path.join(run_dir, "run.json")) as f:
        case = json.load(f)["case"]
    region = case["regions"][0]
    width = region["upper"][0] - region["lower"][0]
    height = region["upper"][1] - region["lower"][1]
    thickness = case["solver"].get("thickness", 1.0)
    body = case.get("output", {}).get("plot_body") or case["bodies"][0]["name"]
    data = np.genfromtxt(os.path.join(run_dir, "timeseries.csv"), delimiter=",", names=True)
    strain = -data[body + "_dy"] / height
    stress = data[body + "_fy"] / (width * thickness)
    lost = data["lost_points"][-1] if "lost_points" in data.dtype.names else None
    return case, strain, stress, lost


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("runs", nargs="+", help="RUN_DIR or RUN_DIR=LABEL")
    parser.add_argument("--reference", default=None)
    parser.add_argument("--out", default="biaxial-meshes.png")
    parser.add_argument("--title", default="biaxial specimen on the paper's meshes (liang-zhao-mpm-dem §3.2)",
                        help="the figure's title (say what the runs share, e.g. their time step)")
    args = parser.parse_args()

    fig, ax = plt.subplots(figsize=(7.5, 5))
    reference = args.reference
    for arg in args.runs:
        run, _, given_label = arg.partition("=")
        case, strain, stress, lost = nominal_curve(run)
        reference = reference or case.get("output", {}).get("reference_curve")
        k = int(np.argmax(stress))
        extra = f", {int(lost)} points parked" if lost else ""
        label = given_label or case["name"].replace("biaxial-specimen-", "").replace(
            "medium", "m4 (medium)")
        print(f"{label}: peak {stress[k] / 1e3:.1f} kPa at {100 * strain[k]:.2f} %, "
              f"{stress[-1] / 1e3:.1f} kPa at {100 * strain[-1]:.2f} %{extra}")
        ax.plot(100 * strain, stress / 1e3, lw=1.0, label=label)
    if reference:
        ref = np.genfromtxt(reference, delimiter=",", names=True)
        ax.plot(100 * ref["axial_strain"], ref["syy"] / 1e3, "k--", lw=1.2, label="DEM element test")
    ax.set_xlabel("nominal axial strain: platen travel / height (%)")
    ax.set_ylabel("nominal axial stress: platen force / width (kPa)")
    ax.set_title(args.title)
    ax.set_xlim(0, 15)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
