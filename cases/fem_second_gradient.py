#!/usr/bin/env python3
"""The shear band's width with and without Desrues et al.'s local second
gradient (§4.5, Fig. 12): FEMxDEM biaxial compression on several meshes.

Usage:
  /usr/bin/python3 cases/fem_second_gradient.py \
      --run "coarse Q8R, D = 30 N=DIR" --run ... [--at 0.10] \
      [--figures cases/figures] [--records cases/results/fem-biaxial-second-gradient.json]
  /usr/bin/python3 cases/fem_second_gradient.py --from-records [--figures ...]

Each DIR is a finished `fem_client run` of a biaxial case with frames (its
timeseries.csv, summary.json, run.json and results.h5 are read); the label
before "=" names it in the figure. A label containing "D = " is a run with
the second gradient, any other one without it.

The band is measured at the frame nearest to the axial strain --at from the
Gauss points' deviatoric strain eps_q in the middle half of the specimen's
height (away from the platens). Outside the band eps_q is at its level b,
the 5th percentile there. The band's centre line is the principal axis of
the points' positions weighted by (eps_q - b)^2; eps_q is averaged in bins
of 2.5 mm of distance across it, up to 25 mm either side: the profile. Its
peak and its width at half the peak's excess over b (crossings interpolated
between bins) describe the band on any mesh.
"""
import argparse
import json
import math
import os
import sys

from fem_biaxial import read_csv, rounded  # the same runs' files, read alike

HEIGHT_M = 0.1    # the specimen's initial height
BIN_M = 2.5e-3    # the profile's bins across the band
HALF_WINDOW_M = 0.025


def band_profile(x, y, eps_q, height):
    """The band across its centre line in the middle half of the specimen's
    height `height` (m): see the module's text. Returns a dict of the
    profile (bin centres m, mean eps_q or None), the outside level b, the
    peak, the width at half the peak's excess (m) and the band's angle from
    horizontal (deg)."""
    import numpy as np
    middle = (y > 0.25 * height) & (y < 0.75 * height)
    px, py, e = x[middle], y[middle], eps_q[middle]
    base = float(np.percentile(e, 5))
    w = np.clip(e - base, 0.0, None) ** 2
    c = np.array([np.sum(w * px), np.sum(w * py)]) / np.sum(w)
    d = np.stack([px - c[0], py - c[1]])
    vals, vecs = np.linalg.eigh((w * d) @ d.T / np.sum(w))
    t, n = vecs[:, 1], vecs[:, 0]  # along and across the band
    s = n @ d
    edges = np.arange(-HALF_WINDOW_M, HALF_WINDOW_M + BIN_M / 2, BIN_M)
    centres = 0.5 * (edges[1:] + edges[:-1])
    prof = []
    for lo, hi in zip(edges[:-1], edges[1:]):
        inside = (s >= lo) & (s < hi)
        prof.append(float(e[inside].mean()) if inside.any() else float("nan"))
    prof = np.array(prof)
    k = int(np.nanargmax(prof))
    peak = float(prof[k])
    half = base + 0.5 * (peak - base)

    def crossing(step):
        # The first bin from the peak outwards below half, interpolated.
        j = k
        while 0 <= j + step < len(prof) and not (prof[j + step] < half):
            j += step
        if not 0 <= j + step < len(prof):
            return float(centres[j])
        a, b = prof[j], prof[j + step]
        return float(centres[j] + step * BIN_M * (a - half) / (a - b))

    width = crossing(1) - crossing(-1)
    return {"distance_m": rounded(centres), "eps_q": [None if np.isnan(v) else round(v, 5)
                                                      for v in prof],
            "outside": base, "peak": peak, "width_m": width,
            "angle_deg": math.degrees(math.atan2(abs(t[1]), abs(t[0])))}


def load_run(label, directory, at):
    import h5py
    import numpy as np
    ts = read_csv(os.path.join(directory, "timeseries.csv"))
    with open(os.path.join(directory, "summary.json")) as f:
        summary = json.load(f)
    with open(os.path.join(directory, "run.json")) as f:
        run = json.load(f)
    strain_per_step = ts["axial_strain"][-1] / ts["step"][-1]
    with h5py.File(os.path.join(directory, "results.h5"), "r") as f:
        names = sorted(f["frames"], key=int)
        name = min(names, key=lambda k: abs(int(k) * strain_per_step - at))
        g = f["frames"][name]
        pos = np.array(g["position"])
        x, y, eps_q = pos[:, 0], pos[:, 1], np.array(g["eps_q"])
    strain = int(name) * strain_per_step
    band = band_profile(x, y, eps_q, HEIGHT_M * (1.0 - strain))
    return {
        "run": {k: run.get(k) for k in ("version", "host", "start", "end", "outcome",
                                         "command_line")},
        "summary": summary,
        "points": int(len(x)),
        "axial_strain": strain,
        "band": band,
        "eps_q_max": float(eps_q.max()),
        "curve": {"axial_strain": rounded(ts["axial_strain"]),
                  "stress_Pa": rounded(ts["platen_force_per_width_Pa"]),
                  "iterations": ts["iterations"]},
        "map": {"x": rounded(x), "y": rounded(y), "eps_q": rounded(eps_q)},
    }


def plot(records, figures):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    runs = records["runs"]
    labels = list(runs)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    fig = plt.figure(figsize=(2.0 * len(labels) + 8.5, 5.0))
    grid = fig.add_gridspec(1, len(labels) + 2, width_ratios=[1] * len(labels) + [2.2, 2.2])
    for k, label in enumerate(labels):
        r = runs[label]
        m = r["map"]
        ax = fig.add_subplot(grid[0, k])
        sc = ax.scatter(m["x"], m["y"], c=m["eps_q"], s=max(3, 1800 / len(m["x"])), marker="s",
                        cmap="jet", vmin=0)
        ax.set_aspect("equal")
        ax.set_xticks([])
        ax.set_yticks([])
        ax.set_title(f"{label}\n{r['points']} RVEs, band {r['band']['width_m'] * 1e3:.0f} mm",
                     fontsize=7, color=colours[k % len(colours)])
        fig.colorbar(sc, ax=ax, orientation="horizontal", pad=0.03, fraction=0.05,
                     label="ε_q")
    ax = fig.add_subplot(grid[0, len(labels)])
    for k, label in enumerate(labels):
        b = runs[label]["band"]
        prof = np.array([np.nan if v is None else v for v in b["eps_q"]])
        ax.plot(np.array(b["distance_m"]) * 1e3, prof, marker=".",
                ls="-" if "D = " in label else "--", color=colours[k % len(colours)],
                label=label)
    ax.set_xlabel("distance across the band (mm)")
    ax.set_ylabel("ε_q, mean over the band's length")
    ax.legend(fontsize=6)
    ax = fig.add_subplot(grid[0, len(labels) + 1])
    for k, label in enumerate(labels):
        c = runs[label]["curve"]
        ax.plot(np.array(c["axial_strain"]) * 100, np.array(c["stress_Pa"]) / 1e3,
                ls="-" if "D = " in label else "--", color=colours[k % len(colours)],
                label=label)
    ax.set_xlabel("axial strain (%)")
    ax.set_ylabel("platen stress σ_yy (kPa)")
    ax.set_xlim(0, 10)
    strain = next(iter(runs.values()))["axial_strain"] * 100
    fig.suptitle(f"Biaxial compression: ε_q at {strain:.0f} % axial strain on Q8R meshes "
                 "without (dashed) and with (solid) the local second gradient "
                 "(Desrues et al. §4.5)", fontsize=9)
    fig.tight_layout()
    path = os.path.join(figures, "fem-biaxial-second-gradient-bands.png")
    fig.savefig(path, dpi=90)
    plt.close(fig)
    print(f"wrote {path}")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--run", action="append", default=[], help="LABEL=DIR")
    p.add_argument("--at", type=float, default=0.10, help="axial strain of the band's frame")
    p.add_argument("--figures", default=os.path.join(os.path.dirname(__file__), "figures"))
    p.add_argument("--records", default=os.path.join(os.path.dirname(__file__), "results",
                                                     "fem-biaxial-second-gradient.json"))
    p.add_argument("--from-records", action="store_true")
    a = p.parse_args()
    if a.from_records:
        with open(a.records) as f:
            records = json.load(f)
    else:
        if not a.run:
            p.error("give --run LABEL=DIR at least once, or --from-records")
        records = {"at_axial_strain": a.at, "runs": {}}
        for spec in a.run:
            label, _, directory = spec.rpartition("=")
            if not label:
                p.error(f"--run {spec}: expected LABEL=DIR")
            records["runs"][label] = load_run(label, directory, a.at)
        with open(a.records, "w") as f:
            json.dump(records, f, indent=1)
            f.write("\n")
        print(f"wrote {a.records}")
    for label, r in records["runs"].items():
        band = r["band"]
        print(f"{label}: {r['points']} RVEs, at {r['axial_strain'] * 100:.1f} %: band width "
              f"{band['width_m'] * 1e3:.1f} mm at {band['angle_deg']:.1f} deg, profile peak "
              f"{band['peak']:.3f} over {band['outside']:.3f} outside, largest eps_q "
              f"{r['eps_q_max']:.3f}; peak stress {r['summary']['peak_stress_Pa'] / 1e3:.1f} kPa, "
              f"wall {r['summary']['wall_s']:.0f} s")
    plot(records, a.figures)
    return 0


if __name__ == "__main__":
    sys.exit(main())
