#!/usr/bin/env python3
"""Compares two mpm_client runs of one case: the same answers?

  python3 bench/compare_runs.py CASE.json BASE_DIR NEW_DIR [--out=PNG]
      [--base-label=...] [--new-label=...]

Reads each run's timeseries.csv and, from the case, what its headline curve is:
  load-settlement (a body pushed into the soil): q = <body>_fy / plot_width
      (Pa per metre of thickness) against the settlement d = -<body>_dy (m);
  stress-strain (a platen on a specimen): sigma_yy = mean_syy (Pa, compression +)
      against the nominal axial strain -platen_dy / H (H from the soil region);
  none (a flow, e.g. the column collapse): the front x and the kinetic energy
      against time.
Prints the differences the time-to-solution goals are judged by and writes both
curves on one plot (numpy and matplotlib; Debian: python3-numpy python3-matplotlib).

Differences of a curve y(x): NEW is interpolated onto BASE's x; the difference at
a point is |y_new - y_base| / max(|y_base|, 0.1 * peak), so the first, nearly
unloaded points do not dominate. Reported separately up to BASE's peak and after
it, and after the peak also the mean |difference| as a share of the peak (a
softening branch is noisy: its worst point says little). For a flow: the final front and the run-out d* = (d_f - d_0)/d_0, and the
peak kinetic energy with its time.
"""
import argparse
import csv
import json
import sys


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    return {k: [float(r[k]) for r in rows] for k in rows[0]}


def curve(case, ts):
    out = case.get("output", {})
    plot = out.get("plot", "none")
    if plot == "load-settlement":
        body = out["plot_body"]
        width = out.get("plot_width", 1.0) * case["solver"].get("thickness", 1.0)
        x = [-d for d in ts[body + "_dy"]]
        y = [f / width for f in ts[body + "_fy"]]
        return "settlement d (m)", "q (Pa)", x, y
    if plot == "stress-strain":
        region = case["regions"][0]
        height = region["upper"][1] - region["lower"][1]
        body = next((b["name"] for b in case.get("bodies", [])), None)
        if body is not None:
            x = [-d / height for d in ts[body + "_dy"]]
        else:
            x = ts["mean_eyy"]
        return "nominal axial strain", "mean sigma_yy (Pa)", x, ts["mean_syy"]
    return None


def interp(x0, xs, ys):
    """Linear interpolation of (xs, ys) (xs ascending) at x0; None outside."""
    if x0 < xs[0] or x0 > xs[-1]:
        return None
    lo, hi = 0, len(xs) - 1
    while hi - lo > 1:
        mid = (lo + hi) // 2
        if xs[mid] <= x0:
            lo = mid
        else:
            hi = mid
    if xs[hi] == xs[lo]:
        return ys[lo]
    t = (x0 - xs[lo]) / (xs[hi] - xs[lo])
    return ys[lo] + t * (ys[hi] - ys[lo])


def monotone(x, y):
    """Points with strictly increasing x (a curve may pause while x holds)."""
    xs, ys = [], []
    for a, b in zip(x, y):
        if not xs or a > xs[-1]:
            xs.append(a)
            ys.append(b)
    return xs, ys


def compare_curve(xb, yb, xn, yn):
    xb, yb = monotone(xb, yb)
    xn, yn = monotone(xn, yn)
    k_peak = max(range(len(yb)), key=lambda k: yb[k])
    peak = yb[k_peak]
    pre, post, pre_x, post_x = 0.0, 0.0, None, None
    post_sum, post_n = 0.0, 0
    for k, (x0, y0) in enumerate(zip(xb, yb)):
        y1 = interp(x0, xn, yn)
        if y1 is None:
            continue
        d = abs(y1 - y0) / max(abs(y0), 0.1 * abs(peak))
        if k <= k_peak:
            if d > pre:
                pre, pre_x = d, x0
        else:
            if d > post:
                post, post_x = d, x0
            post_sum += abs(y1 - y0) / abs(peak)
            post_n += 1
    kn = max(range(len(yn)), key=lambda k: yn[k])
    return {"base_peak": peak, "base_peak_x": xb[k_peak], "new_peak": yn[kn],
            "new_peak_x": xn[kn], "peak_rel_diff": (yn[kn] - peak) / peak,
            "max_rel_diff_to_peak": pre, "at_x": pre_x,
            "max_rel_diff_after_peak": post, "after_peak_at_x": post_x,
            # A softening branch is noisy (shear bands, cell crossings): its
            # mean difference, as a share of the peak, says more than its worst point.
            "mean_abs_diff_after_peak_over_peak": post_sum / max(post_n, 1)}


def front_from_frames(run_dir):
    """(time, front x) of every results.h5 frame (runs from before front_x
    was a timeseries column); needs h5py (Debian: python3-h5py)."""
    import h5py
    out = []
    with h5py.File(run_dir + "/results.h5", "r") as f:
        for name in f["frames"]:
            g = f["frames"][name]
            out.append((float(g.attrs["time"]), float(g["position"][:, 0].max())))
    out.sort()
    return [t for t, _ in out], [x for _, x in out]


def with_front(ts, run_dir):
    if "front_x" not in ts:
        ts = dict(ts)
        ts["front_time"], ts["front_x"] = front_from_frames(run_dir)
    else:
        ts["front_time"] = ts["time"]
    return ts


def compare_flow(tb, tn):
    out = {}
    for name, ts in (("base", tb), ("new", tn)):
        d0, df = ts["front_x"][0], ts["front_x"][-1]
        ke = ts["kinetic_energy"]
        k = max(range(len(ke)), key=lambda i: ke[i])
        out[name] = {"front_final_m": df, "runout_normalised": (df - d0) / d0,
                     "kinetic_peak_J": ke[k], "kinetic_peak_time_s": ts["time"][k]}
    out["runout_rel_diff"] = abs(out["new"]["runout_normalised"] - out["base"]["runout_normalised"]) \
        / abs(out["base"]["runout_normalised"])
    out["front_final_rel_diff"] = abs(out["new"]["front_final_m"] - out["base"]["front_final_m"]) \
        / abs(out["base"]["front_final_m"])
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("case")
    ap.add_argument("base")
    ap.add_argument("new")
    ap.add_argument("--out", default="")
    ap.add_argument("--base-label", default="base")
    ap.add_argument("--new-label", default="new")
    a = ap.parse_args()
    case = json.load(open(a.case))
    tb = read_csv(a.base + "/timeseries.csv")
    tn = read_csv(a.new + "/timeseries.csv")
    c = curve(case, tb)
    if c is not None:
        xlabel, ylabel, xb, yb = c
        _, _, xn, yn = curve(case, tn)
        result = compare_curve(xb, yb, xn, yn)
        panels = [(xlabel, ylabel, (xb, yb), (xn, yn))]
    else:
        tb, tn = with_front(tb, a.base), with_front(tn, a.new)
        result = compare_flow(tb, tn)
        panels = [("time (s)", "front x (m)", (tb["front_time"], tb["front_x"]),
                   (tn["front_time"], tn["front_x"])),
                  ("time (s)", "kinetic energy (J)", (tb["time"], tb["kinetic_energy"]),
                   (tn["time"], tn["kinetic_energy"]))]
    print(json.dumps({"case": case.get("name", a.case), **result}, indent=1))
    if a.out:
        try:
            import matplotlib
            matplotlib.use("Agg")
            import matplotlib.pyplot as plt
        except ImportError:
            print("no matplotlib: apt-get install python3-matplotlib", file=sys.stderr)
            return 1
        fig, axes = plt.subplots(1, len(panels), figsize=(6 * len(panels), 4.5), squeeze=False)
        for ax, (xl, yl, b, n) in zip(axes[0], panels):
            ax.plot(b[0], b[1], "k-", lw=2, label=a.base_label)
            ax.plot(n[0], n[1], "r--", lw=1.5, label=a.new_label)
            ax.set_xlabel(xl)
            ax.set_ylabel(yl)
            ax.grid(alpha=0.3)
            ax.legend()
        fig.suptitle(case.get("name", a.case))
        fig.tight_layout()
        fig.savefig(a.out, dpi=110)
    return 0


if __name__ == "__main__":
    sys.exit(main())
