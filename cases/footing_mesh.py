#!/usr/bin/env python3
"""Mesh study of the strip footing: N_q against the cell size, the points per cell and where the
footing's edge falls.

  /usr/bin/python3 cases/footing_mesh.py cases --out=DIR [--base=cases/footing-coarse.json]
      [--cells-per-m=4,5,6,8,9,10,12] [--points-per-cell-side=1] [--depth=0.125]
      [--seeds=1-9 --phi-deg=31.67,31.11,...] [--particles=1600]
  /usr/bin/python3 cases/footing_mesh.py plot RUN_DIR [RUN_DIR ...] --out=footing-mesh.png

`cases` writes the base case on square cells of 1/n m for each n (the grid keeps 1.2 m of empty
rows above the surface), pushed to --depth, and prints the mpm_client commands that run them.
`plot` reads finished runs (run.json, summary.json, timeseries.csv) and draws q/q_s against the
settlement and N_q (the case's ultimate-load rule) against h/(B/2), with Prandtl's value, and
prints a table. With --seeds, `cases` writes each mesh once per packing seed, and --phi-deg
gives each seed's phi' (friction_angle.py --seed=...) to its summary; `plot` then adds N_q
against each run's phi' beside Prandtl's curve. --particles prepares the templates with that
many discs (a larger sample of the material; give its phi' with --phi-deg). Runs whose packings
were compacted at other pressures (`--set=templates.0.pressure=P` on the printed commands) are
labelled by it, and likewise runs whose packings have another rolling-resistance eta
(`--set=templates.0.rolling_eta=H`), with one colour family per preparation (up to three). For
each set of runs that differ in h only (edge on a node line) `plot` fits N_q = N_0 + a h and
prints N_0, the value for h -> 0; runs with a nonlocal strain (solver.nonlocal_radius l and
nonlocal_fraction m, `--set` on the printed commands) are marked "l/m". A run is marked by
where the footing's edge falls: on a node line; inside a cell, between two points' boxes (more
than 1 point per cell); or through a column of points. Inside a cell the contact pushes that
cell's soil with the footing, so the load acts on a wider strip (mpm_client notes such a
corner at set-up; docs/footing-bearing-capacity.md).

With the edge on a node line N_q falls with h at first order, as if the footing were one cell
wider on each side (docs/footing-bearing-capacity.md). Needs numpy and matplotlib
(Debian's python3-numpy, python3-matplotlib).
"""
import argparse
import csv
import json
import math
import os

import matplotlib
import numpy as np

from friction_angle import parse_seeds, prandtl_nq

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def variant(base, n, ppc, depth, seed=None, phi_deg=None, particles=None):
    """The base case on square cells of 1/n m with ppc x ppc points, pushed to `depth` (m);
    with `seed`, its template packed from that seed, with `particles`, of that many discs, and
    `phi_deg` (deg) for its summary."""
    c = json.loads(json.dumps(base))
    soil = c["regions"][0]
    width, height = soil["upper"][0], soil["upper"][1]
    c["name"] = (f"{base['name']}-mesh-{n}" + (f"-ppc{ppc}" if ppc != 1 else "")
                 + (f"-seed{seed}" if seed is not None else "")
                 + (f"-{particles}discs" if particles else ""))
    c["description"] = (f"{base['name']} on cells of 1/{n} m, {ppc} x {ppc} points per cell "
                        f"(cases/footing_mesh.py), pushed to d = {depth} m")
    if seed is not None:
        for t in c["templates"]:
            t["seed"] = seed
        c["description"] += f", packings of seed {seed}"
    if particles:
        for t in c["templates"]:
            t["particles"] = particles
        c["description"] += f", {particles}-disc RVEs"
    if phi_deg is not None:
        c["output"]["phi_deg"] = phi_deg
    c["grid"]["cell_size"] = 1.0 / n
    c["grid"]["cells"] = [round(width * n), math.ceil((height + 1.2) * n)]
    soil["points_per_cell_side"] = ppc
    # The footing moves at v after a ramp of t_r: d = v (t - t_r / 2).
    ramp, v = c["bodies"][0]["velocity"][1][0], -c["bodies"][0]["velocity"][1][2]
    c["solver"]["end_time"] = round(depth / v + ramp / 2, 6)
    c["expected_runtime_s"] = 0
    c["output"].update(frame_every=1000000, checkpoint_every=0, progress_every=1000)
    return c


def write_cases(a):
    with open(a.base) as f:
        base = json.load(f)
    seeds = a.seeds or [None]
    phis = [float(x) for x in a.phi_deg.split(",")] if a.phi_deg else [None] * len(seeds)
    if len(phis) != len(seeds):
        raise SystemExit(f"--phi-deg gives {len(phis)} angles for {len(seeds)} seeds")
    os.makedirs(a.out, exist_ok=True)
    for n in (int(s) for s in a.cells_per_m.split(",")):
        for seed, phi in zip(seeds, phis):
            c = variant(base, n, a.points_per_cell_side, a.depth, seed, phi, a.particles)
            path = os.path.join(a.out, c["name"] + ".json")
            with open(path, "w") as f:
                json.dump(c, f, indent=1)
            print(f"{a.mpm_client} run {path} --out={os.path.join(a.out, c['name'])} "
                  f"--template-cache={os.path.join(a.out, 'templates')} --quiet")


def edge_position(case, body):
    """Where the body's edge (+x side) falls: 'node line', 'between points' or
    'through points', with h (m) and the points per cell side."""
    h = case["grid"]["cell_size"]
    ppc = case["regions"][0].get("points_per_cell_side", 1)
    edge = (body["center"][0] + body["half_size"][0] - case["grid"]["origin"][0]) / h
    # Point boxes are h/ppc wide and tile each cell from its node line.
    k = edge * ppc
    if abs(k - round(k)) > 1e-6:
        return "through points", h, ppc
    return ("node line" if abs(edge - round(edge)) < 1e-6 else "between points"), h, ppc


def load_run(run_dir):
    for name in ("run.json", "summary.json", "timeseries.csv"):
        if not os.path.isfile(os.path.join(run_dir, name)):
            raise SystemExit(f"{run_dir}: no {name} (not a finished mpm_client run)")
    with open(os.path.join(run_dir, "run.json")) as f:
        case = json.load(f)["case"]
    with open(os.path.join(run_dir, "summary.json")) as f:
        summary = json.load(f)
    if "N_q" not in summary:
        raise SystemExit(f"{run_dir}: summary.json has no N_q (not a footing run?)")
    if "N_q_prandtl" not in summary:
        raise SystemExit(f"{run_dir}: summary.json has no N_q_prandtl (the case gives no phi_deg)")
    out = case["output"]
    body = out.get("plot_body") or case["bodies"][0]["name"]
    spec = next(b for b in case["bodies"] if b["name"] == body)
    width = out["plot_width"] * case["solver"].get("thickness", 1.0)
    with open(os.path.join(run_dir, "timeseries.csv")) as f:
        rows = list(csv.DictReader(f))
    d = np.array([-float(r[body + "_dy"]) for r in rows])
    q = np.array([float(r[body + "_fy"]) for r in rows]) / width / summary["surcharge_Pa"]
    soil = case["regions"][0]
    where, h, ppc = edge_position(case, spec)
    return dict(dir=run_dir, name=case["name"], summary=summary, d=d, q=q, h=h, ppc=ppc,
                seed=case["templates"][0].get("seed", 1), cfl=case["solver"]["cfl"],
                discs=case["templates"][0].get("particles", 0),
                # Pa the packing was compacted to e0 at (`--set=templates.0.pressure=P`); 0: the
                # parameter set's p0.
                pressure=case["templates"][0].get("pressure", 0.0),
                # The rolling-resistance eta replacing the set's
                # (`--set=templates.0.rolling_eta=H`); None: the set's.
                eta=case["templates"][0].get("rolling_eta"),
                edge=where, domain=f"{soil['upper'][0]:g} x {soil['upper'][1]:g} m",
                half_width=spec["half_size"][0] * 2,
                averaging=nonlocal_label(case["solver"]))


def preparation(run):
    """A load_run run's preparation: (compaction pressure Pa, rolling eta or None)."""
    return run["pressure"], run["eta"]


def preparations(runs):
    """The distinct preparations of `runs`, by pressure, then eta (the set's first)."""
    return sorted({preparation(r) for r in runs},
                  key=lambda k: (k[0], -1 if k[1] is None else k[1]))


def nonlocal_label(solver):
    """'l/m' of a run with a nonlocal strain (solver.nonlocal_radius, m; nonlocal_fraction), or
    '' without. run.json has the fraction since it exists; the runs before it averaged fully."""
    radius = solver.get("nonlocal_radius", 0.0)
    return f"{radius:g}/{solver.get('nonlocal_fraction', 1.0):g}" if radius else ""


def extrapolations(runs):
    """N_q = N_0 + a h fitted over the meshes of each set of runs that differ in h only (edge on
    a node line, 1 point per cell, h at most a quarter of the modelled half-width B/2, at least 3
    meshes): [(runs, N_0, a)]. The slope
    set against N_0 / (B/2) says how far the load spreads beyond the footing's edge."""
    groups = {}
    for r in runs:
        if r["edge"] == "node line" and r["ppc"] == 1 and r["h"] <= r["half_width"] / 4 + 1e-9:
            key = (r["domain"], r["half_width"], r["seed"], r["discs"], r["cfl"],
                   r["averaging"])
            groups.setdefault(key, []).append(r)
    fits = []
    for group in groups.values():
        if len({r["h"] for r in group}) >= 3:
            a, n0 = np.polyfit([r["h"] for r in group], [r["summary"]["N_q"] for r in group], 1)
            fits.append((group, n0, a))
    return fits


def plot(a):
    runs = [load_run(r) for r in a.runs]
    phis = sorted({r["summary"]["phi_deg"] for r in runs})
    cfls = {r["cfl"] for r in runs}
    discs = {r["discs"] for r in runs}
    pressures = {r["pressure"] for r in runs}
    etas = {r["eta"] for r in runs}
    preps = preparations(runs)
    print(f"{'run':<34} {'domain':>10} {'B/2 (m)':>8} {'h (m)':>7} {'ppc':>4} {'seed':>4} "
          f"{'discs':>5} {'p0 (kPa)':>8} {'eta':>5} {'l/m':>8} {'edge':>15} {'N_q':>6} "
          f"{'d_ult (m)':>9} {'phi':>6} {'/Prandtl':>9}")
    for r in runs:
        s = r["summary"]
        print(f"{r['name']:<34} {r['domain']:>10} {r['half_width']:8.3f} {r['h']:7.4f} "
              f"{r['ppc']:4d} {r['seed']:4d} {r['discs'] or '-':>5} "
              f"{r['pressure'] / 1e3 if r['pressure'] else '-':>8} "
              f"{'-' if r['eta'] is None else format(r['eta'], 'g'):>5} "
              f"{r['averaging'] or '-':>8} {r['edge']:>15} "
              f"{s['N_q']:6.2f} "
              f"{s['settlement_at_ultimate_m']:9.4f} {s['phi_deg']:6.2f} "
              f"{s['N_q'] / s['N_q_prandtl']:9.3f}")
    fits = extrapolations(runs)
    for group, n0, slope in fits:
        r = group[0]
        print(f"N_q = N_0 + a h over h = {min(g['h'] for g in group):.4g}-"
              f"{max(g['h'] for g in group):.4g} m ({len(group)} meshes; {r['domain']}, "
              f"B/2 {r['half_width']:g} m, nonlocal l/m {r['averaging'] or '-'}): N_0 = {n0:.2f} "
              f"({n0 / r['summary']['N_q_prandtl']:.3f} of Prandtl), "
              f"a/N_0 = {slope / n0:.2f} per m "
              f"(a footing one cell wider on each side: 1/(B/2) = {1 / r['half_width']:.2f})")
    # Runs on packings of other seeds carry their own phi' (footing_mesh.py cases --phi-deg):
    # a third panel sets their N_q against Prandtl's curve.
    fig, axes = plt.subplots(1, 2 if len(phis) == 1 else 3,
                             figsize=(13, 5.2) if len(phis) == 1 else (19, 5.2))
    ax1, ax2 = axes[0], axes[1]
    colours = [plt.cm.tab20(i % 20 / 19) for i in range(len(runs))]
    if 1 < len(preps) <= 3:
        # One colour family per preparation, so its seeds read as a group.
        families = dict(zip(preps, (plt.cm.Blues, plt.cm.Oranges, plt.cm.Greens)))
        for prep in preps:
            group = [i for i, r in enumerate(runs) if preparation(r) == prep]
            for k, i in enumerate(group):
                colours[i] = families[prep](0.45 + 0.5 * k / len(group))
    style = {"node line": "o", "between points": "s", "through points": "x"}
    for i, r in enumerate(runs):
        s = r["summary"]
        label = (f"{r['domain']}, B/2 {r['half_width']:.3g}, h {r['h']:.3g}, "
                 f"ppc {r['ppc']}: edge {r['edge']}"
                 + (f", seed {r['seed']} (phi' {s['phi_deg']:g})" if len(phis) > 1 else "")
                 + (f", CFL {r['cfl']:g}" if len(cfls) > 1 else "")
                 + (f", {r['discs'] or 'default'} discs" if len(discs) > 1 else "")
                 + ((f", compacted at {r['pressure'] / 1e3:g} kPa" if r["pressure"]
                     else ", compacted at the set's p0") if len(pressures) > 1 else "")
                 + ((f", rolling eta {r['eta']:g}" if r["eta"] is not None
                     else ", the set's rolling eta") if len(etas) > 1 else "")
                 + (f", nonlocal l/m {r['averaging']}" if r["averaging"] else ""))
        line, = ax1.plot(r["d"], r["q"], lw=0.8, ls="--" if r["edge"] == "through points" else "-",
                         color=colours[i], label=label)
        ax1.plot(s["settlement_at_ultimate_m"], s["N_q"], "o", color=line.get_color())
        ax2.plot(r["h"] / r["half_width"], s["N_q"], style[r["edge"]], color=line.get_color(), ms=8,
                 mfc="none" if r["ppc"] > 1 else line.get_color())
        if len(phis) > 1:
            axes[2].plot(s["phi_deg"], s["N_q"], style[r["edge"]], color=line.get_color(), ms=8,
                         mfc="none" if r["ppc"] > 1 else line.get_color())
    for group, n0, slope in fits:
        x = np.linspace(0, max(g["h"] for g in group) / group[0]["half_width"], 20)
        ax2.plot(x, n0 + slope * x * group[0]["half_width"], "--", lw=0.8, color="0.4")
        ax2.plot(0, n0, "*", color="0.4", ms=10)
    if fits:
        ax2.plot([], [], "--*", lw=0.8, color="0.4", label="N_0 + a h fitted (star: h -> 0)")
    prandtl = runs[0]["summary"]["N_q_prandtl"]
    if len(phis) == 1:
        ax1.axhline(prandtl, color="k", ls=":", lw=1, label=f"Prandtl, phi' = {phis[0]} deg")
        ax2.axhline(prandtl, color="k", ls=":", lw=1, label="Prandtl")
        ax2.axhspan(0.9 * prandtl, 1.1 * prandtl, color="0.92", label="Prandtl +/- 10 %")
    else:
        ax3 = axes[2]
        phi = np.linspace(phis[0] - 1.5, phis[-1] + 1.0, 100)
        nq = np.array([prandtl_nq(math.radians(x)) for x in phi])
        ax3.plot(phi, nq, "k:", lw=1, label="Prandtl")
        ax3.fill_between(phi, 0.9 * nq, 1.1 * nq, color="0.92", label="Prandtl +/- 10 %")
        ax3.set_xlabel("the packing's peak phi' (deg, biaxial 10-30 kPa: friction_angle.py)")
        ax3.set_ylabel("N_q")
        ax3.set_xlim(phi[0], phi[-1])
        ax3.set_ylim(0, 1.15 * max(nq.max(), max(r["summary"]["N_q"] for r in runs)))
        ax3.legend(fontsize=7, loc="lower right")
        ax3.set_title("N_q against each run's phi' (colours as on the left)")
    ax1.set_xlabel("settlement d (m)")
    ax1.set_ylabel("q / q_s")
    ax1.set_xlim(0, max(r["d"].max() for r in runs))
    ax1.legend(fontsize=6.5, loc="lower right")
    ax1.set_title("footing: load-settlement (dots: ultimate load)")
    for where, marker in style.items():
        ax2.plot([], [], marker, color="0.3", label=f"edge {where}")
    ax2.plot([], [], "o", color="0.3", mfc="none", label="2 x 2 points per cell")
    ax2.set_xlabel("cell size / modelled footing width, h / (B/2)")
    ax2.set_ylabel("N_q (ultimate load / surcharge)")
    ax2.set_xlim(0, 1.1 * max(r["h"] / r["half_width"] for r in runs))
    ax2.set_ylim(0, 1.15 * max(prandtl, max(r["summary"]["N_q"] for r in runs)))
    ax2.legend(fontsize=7, loc="lower right")
    ax2.set_title("N_q against the relative cell size (colours as on the left)")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print("wrote", a.out)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    sub = ap.add_subparsers(dest="command", required=True)
    c = sub.add_parser("cases", help="write the case files")
    c.add_argument("--out", required=True, help="directory")
    c.add_argument("--base", default=os.path.join(HERE, "footing-coarse.json"))
    c.add_argument("--cells-per-m", default="4,5,6,8,9,10,12")
    c.add_argument("--points-per-cell-side", type=int, default=1)
    c.add_argument("--depth", type=float, default=0.125, help="m")
    c.add_argument("--seeds", type=parse_seeds,
                   help="packing seeds, e.g. 1-9 (default: the base case's)")
    c.add_argument("--phi-deg", help="each seed's phi', deg, comma-separated (friction_angle.py)")
    c.add_argument("--particles", type=int,
                   help="discs per RVE template (default: the parameter set's)")
    c.add_argument("--mpm-client", default="build/mpm_client/mpm_client")
    p = sub.add_parser("plot", help="draw finished runs")
    p.add_argument("runs", nargs="+", metavar="RUN_DIR")
    p.add_argument("--out", default="footing-mesh.png")
    a = ap.parse_args()
    if a.command == "cases":
        write_cases(a)
    else:
        plot(a)


if __name__ == "__main__":
    main()
