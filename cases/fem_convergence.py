#!/usr/bin/env python3
"""Newton convergence of the single-element FEMxDEM test per tangent operator
(Guo & Zhao 2014, Fig. 7): E_d and E_f per iteration at two loading stages.

Usage:
  cases/fem_convergence.py --run contact=DIR --run perturbation=DIR \
      [--run initial-elastic=DIR] [--strains 0.005 0.05] \
      [--figure cases/figures/fem-single-element-convergence.png] \
      [--records cases/results/fem-single-element-operators.json]

Each DIR is a finished `fem_client run cases/fem-single-element.json
--set=solver.tangent=...` (its iterations.csv, timeseries.csv, summary.json and
run.json are read). The figure shows E_d (solid) and E_f (dashed) against the
iteration at the load steps nearest to the given axial strains; the records
file keeps each run's summary, run record and those steps' iterations, so the
figure can be drawn again without the runs. Prints a table of iterations and
TRIALs per stage.
"""
import argparse
import csv
import json
import os
import sys


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    return [dict(zip(header, map(float, r))) for r in rows[1:] if r]


def stage_step(timeseries, strain):
    """The load step whose axial strain is nearest to `strain`."""
    best = min(timeseries[1:], key=lambda r: abs(r["axial_strain"] - strain))
    return int(best["step"]), best["axial_strain"]


def load_run(directory, strains):
    timeseries = read_csv(os.path.join(directory, "timeseries.csv"))
    iterations = read_csv(os.path.join(directory, "iterations.csv"))
    with open(os.path.join(directory, "summary.json")) as f:
        summary = json.load(f)
    with open(os.path.join(directory, "run.json")) as f:
        run = json.load(f)
    run.pop("case", None)  # the case file says it
    stages = []
    for strain in strains:
        step, at = stage_step(timeseries, strain)
        its = [r for r in iterations if int(r["step"]) == step]
        row = next(r for r in timeseries if int(r["step"]) == step)
        stages.append({
            "axial_strain": at,
            "step": step,
            "trials": int(row["trials"]),
            "error_d": [r["error_d"] for r in its],
            "error_f": [r["error_f"] for r in its],
            "substeps": int(max(r["substep"] for r in its)) if its else 0,
        })
    return {"run": run, "summary": summary, "stages": stages}


def plot(records, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(records)
    n = len(next(iter(records.values()))["stages"])
    fig, axes = plt.subplots(1, n, figsize=(5.2 * n, 4.0), sharey=True)
    if n == 1:
        axes = [axes]
    colours = {"contact": "tab:blue", "perturbation": "tab:red", "initial-elastic": "tab:green"}
    for k, ax in enumerate(axes):
        for name in names:
            s = records[name]["stages"][k]
            its = range(1, len(s["error_d"]) + 1)
            c = colours.get(name, None)
            ax.semilogy(its, s["error_d"], "o-", color=c, ms=4,
                        label=f"{name}: E_d ({len(s['error_d'])} it., {s['trials']} TRIALs)")
            ax.semilogy(its, [max(e, 1e-12) for e in s["error_f"]], "s--", color=c, ms=3,
                        alpha=0.6, label=f"{name}: E_f")
        ax.axhline(0.01, color="k", lw=0.8, ls=":")
        ax.text(1, 0.011, "tolerance E_d < 0.01", fontsize=8)
        strain = records[names[0]]["stages"][k]["axial_strain"]
        ax.set_title(f"single element, axial strain {100 * strain:.1f} %")
        ax.set_xlabel("Newton iteration")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("error (eq. 21)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--run", action="append", default=[], metavar="OPERATOR=DIR")
    p.add_argument("--strains", type=float, nargs="+", default=[0.005, 0.05])
    p.add_argument("--figure")
    p.add_argument("--records")
    p.add_argument("--from-records", help="draw the figure from a records file instead of runs")
    a = p.parse_args()
    if a.from_records:
        with open(a.from_records) as f:
            records = json.load(f)
    else:
        if not a.run:
            p.error("give --run OPERATOR=DIR at least once, or --from-records")
        records = {}
        for item in a.run:
            name, _, directory = item.partition("=")
            if not directory:
                p.error(f"--run {item}: expected OPERATOR=DIR")
            records[name] = load_run(directory, a.strains)
    print("| operator | axial strain | iterations | TRIALs | last E_d |")
    print("|---|---|---|---|---|")
    for name, r in records.items():
        for s in r["stages"]:
            print(f"| {name} | {100 * s['axial_strain']:.1f} % | {len(s['error_d'])} | "
                  f"{s['trials']} | {s['error_d'][-1]:.2e} |")
    if a.records:
        with open(a.records, "w") as f:
            json.dump(records, f, indent=1, sort_keys=True)
            f.write("\n")
        print(f"wrote {a.records}")
    if a.figure:
        plot(records, a.figure)
    return 0


if __name__ == "__main__":
    sys.exit(main())
