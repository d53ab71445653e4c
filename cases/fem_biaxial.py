#!/usr/bin/env python3
"""FEMxDEM biaxial compression on several meshes (Guo & Zhao 2014, §4):
global curves against the DEM element test (Fig. 10), the displacement field
at the start of loading (Fig. 11), the deviatoric strain and void ratio fields
at the peak and at the end (Fig. 12), three Gauss points' local responses
(Fig. 15) and the proportion of failed points (Fig. 17).

Usage:
  /usr/bin/python3 cases/fem_biaxial.py \
      --run coarse=DIR --run medium=DIR --run fine=DIR --run coarse-q8=DIR \
      [--start DIR] [--local medium] [--figures cases/figures] \
      [--records cases/results/fem-biaxial.json]

Each DIR is a finished `fem_client run cases/fem-biaxial-MESH.json` with
frames every few load steps (`--set=output.frame_every=2`): its timeseries.csv,
summary.json, run.json and results.h5 are read. --start is a run of the fine
case stopped after its first load step with a frame there
(`--set=loading.end_axial_strain=0.001 --set=output.frame_every=1`). The
records file keeps each run's headline numbers and the fields the figures
show, so the figures can be drawn again without the runs (--from-records).

A Gauss point has failed (G&Z's footnote: "the total loss of strength") when
its mean stress has fallen below 1 % of the initial 100 kPa.
"""
import argparse
import csv
import json
import os
import re
import sys

FAILED_P_PA = 1e3  # a point below this mean stress has lost its strength
WIDTH_M = 0.05


def read_csv(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    return {h: [float(r[i]) for r in rows[1:] if r] for i, h in enumerate(header)}


def read_frames(directory):
    import h5py
    import numpy as np
    frames = []
    with h5py.File(os.path.join(directory, "results.h5"), "r") as f:
        for name in sorted(f["frames"], key=int):
            g = f["frames"][name]
            frames.append({
                "step": int(name),
                "x": np.array(g["position"])[:, 0],
                "y": np.array(g["position"])[:, 1],
                **{k: np.array(g[k]) for k in
                   ("eps_q", "eps_v", "void_ratio", "p", "q", "coordination")},
                "u": np.array(g["displacement"])[:, :2] if "displacement" in g else None,
            })
    return frames


def nearest_frame(frames, step):
    return min(frames, key=lambda fr: abs(fr["step"] - step))


def rounded(values, digits=5):
    return [float(f"{v:.{digits}g}") for v in values]


def load_run(name, directory):
    ts = read_csv(os.path.join(directory, "timeseries.csv"))
    with open(os.path.join(directory, "summary.json")) as f:
        summary = json.load(f)
    with open(os.path.join(directory, "run.json")) as f:
        run = json.load(f)
    frames = read_frames(directory)
    steps = ts["step"]
    strain_per_step = ts["axial_strain"][-1] / steps[-1] if steps[-1] else 0.001
    peak_step = round(summary["peak_strain"] / strain_per_step)
    peak, final = nearest_frame(frames, peak_step), frames[-1]

    def field_stats(fr):
        return {"step": fr["step"], "axial_strain": fr["step"] * strain_per_step,
                "eps_q": [float(fr["eps_q"].min()), float(fr["eps_q"].max())],
                "void_ratio": [float(fr["void_ratio"].min()), float(fr["void_ratio"].max())]}

    def at_strain(target):
        k = min(range(len(steps)), key=lambda i: abs(ts["axial_strain"][i] - target))
        return ts["platen_force_per_width_Pa"][k]

    failed = [{"axial_strain": fr["step"] * strain_per_step,
               "fraction": float((fr["p"] < FAILED_P_PA).mean())} for fr in frames]
    record = {
        "run": {k: run.get(k) for k in ("version", "host", "start", "end", "outcome",
                                         "command_line")},
        "summary": summary,
        "points": int(len(final["x"])),
        "stress_at_5pct_Pa": at_strain(0.05),
        "stress_at_10pct_Pa": at_strain(0.10),
        "fields_at_peak": field_stats(peak),
        "fields_at_end": field_stats(final),
        "failed": failed,
        "curve": {"axial_strain": rounded(ts["axial_strain"]),
                  "stress_Pa": rounded(ts["platen_force_per_width_Pa"]),
                  "vol_strain": rounded(ts["vol_strain"]),
                  "iterations": ts["iterations"]},
        "maps": {lab: {"x": rounded(fr["x"]), "y": rounded(fr["y"]),
                       "eps_q": rounded(fr["eps_q"]), "void_ratio": rounded(fr["void_ratio"]),
                       "failed": [bool(v) for v in fr["p"] < FAILED_P_PA]}
                 for lab, fr in (("peak", peak), ("end", final))},
    }
    return record, frames


def local_points(frames):
    """Inside the band (largest final eps_q), away from it (smallest) and at
    its edge (the largest final void ratio among the rest; G&Z's N°422 dilates
    most)."""
    import numpy as np
    final = frames[-1]
    inside = int(np.argmax(final["eps_q"]))
    away = int(np.argmin(final["eps_q"]))
    order = np.argsort(-final["void_ratio"])
    edge = int(next(k for k in order if k not in (inside, away)))
    out = {}
    for label, k in (("away", away), ("inside", inside), ("edge", edge)):
        out[label] = {"gauss_point": k,
                      "eps_q": rounded([fr["eps_q"][k] for fr in frames]),
                      "eps_v": rounded([fr["eps_v"][k] for fr in frames]),
                      "p": rounded([fr["p"][k] for fr in frames]),
                      "q": rounded([fr["q"][k] for fr in frames])}
    return out


def start_field(directory):
    fr = [f for f in read_frames(directory) if f["step"] == 1][0]
    import numpy as np
    x, y, u = fr["x"], fr["y"], fr["u"]
    # The part of u_x that a symmetric response about the vertical centre
    # line would not have: u_x(x) + u_x(W − x) at mirrored points.
    mirror = [int(np.argmin((x - (WIDTH_M - xi)) ** 2 + (y - yi) ** 2)) for xi, yi in zip(x, y)]
    asym = np.abs(u[:, 0] + u[mirror, 0]).max() / np.abs(u[:, 0]).max()
    return {"x": rounded(x), "y": rounded(y), "ux": rounded(u[:, 0]), "uy": rounded(u[:, 1]),
            "ux_asymmetry": float(asym)}


def reference_curve(path):
    ref = read_csv(path)
    return ref["axial_strain"], ref["syy"], ref["vol_strain"]


def plot(records, reference, figures):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    runs = records["runs"]
    colours = {"coarse": "tab:blue", "medium": "tab:orange", "fine": "tab:red",
               "coarse-q8": "tab:green"}
    # Fig. 10: the global curves.
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    if reference:
        ea, syy, ev = reference
        a1.plot(np.array(ea) * 100, np.array(syy) / 1e3, color="0.5", lw=0.8, label="DEM element test")
        a2.plot(np.array(ea) * 100, np.array(ev) * 100, color="0.5", lw=0.8)
    for name, r in runs.items():
        c = r["curve"]
        label = f"{name} ({r['points']} RVEs)"
        a1.plot(np.array(c["axial_strain"]) * 100, np.array(c["stress_Pa"]) / 1e3,
                color=colours.get(name), label=label)
        a2.plot(np.array(c["axial_strain"]) * 100, np.array(c["vol_strain"]) * 100,
                color=colours.get(name))
    a1.set_xlabel("axial strain (%)")
    a1.set_ylabel("platen stress σ_yy (kPa)")
    a2.set_xlabel("axial strain (%)")
    a2.set_ylabel("volumetric strain (%, compression +)")
    a1.legend(fontsize=8)
    a1.set_xlim(0, 10)
    a2.set_xlim(0, 10)
    fig.suptitle("FEM×DEM biaxial compression, 50 mm × 100 mm, σ3 = 100 kPa (G&Z Fig. 10)")
    fig.tight_layout()
    fig.savefig(os.path.join(figures, "fem-biaxial-stress-strain-meshes.png"), dpi=110)
    plt.close(fig)

    # Fig. 12: eps_q and void ratio at the peak and at the end.
    names = list(runs)
    fig, axes = plt.subplots(len(names), 4, figsize=(9, 3.3 * len(names)), squeeze=False)
    for row, name in enumerate(names):
        for col, (when, key) in enumerate((("peak", "eps_q"), ("peak", "void_ratio"),
                                           ("end", "eps_q"), ("end", "void_ratio"))):
            m = runs[name]["maps"][when]
            ax = axes[row][col]
            sc = ax.scatter(m["x"], m["y"], c=m[key], s=max(4, 2400 / len(m["x"])),
                            marker="s", cmap="jet")
            ax.set_aspect("equal")
            ax.set_xticks([])
            ax.set_yticks([])
            strain = runs[name][f"fields_at_{when}"]["axial_strain"] * 100
            ax.set_title(f"{name}: {'ε_q' if key == 'eps_q' else 'e'} at {strain:.1f} %",
                         fontsize=8)
            fig.colorbar(sc, ax=ax, fraction=0.08)
    fig.tight_layout()
    fig.savefig(os.path.join(figures, "fem-biaxial-localisation-fields.png"), dpi=90)
    plt.close(fig)

    # Fig. 11: the displacement at the first load step, and its horizontal
    # part alone (a symmetric response would mirror it about x = W/2).
    if "start" in records:
        s = records["start"]
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(6.4, 6))
        a1.quiver(s["x"], s["y"], s["ux"], s["uy"], angles="xy", scale_units="xy",
                  scale=max(np.hypot(s["ux"], s["uy"])) / 0.004, width=0.004)
        a1.set_title("u at ε_a = 0.1 %", fontsize=9)
        sc = a2.scatter(s["x"], s["y"], c=np.array(s["ux"]) * 1e6, s=14, marker="s",
                        cmap="coolwarm")
        fig.colorbar(sc, ax=a2, fraction=0.1, label="u_x (µm)")
        a2.set_title(f"u_x: asymmetry {s['ux_asymmetry']:.2f}", fontsize=9)
        for ax in (a1, a2):
            ax.set_aspect("equal")
            ax.set_xlim(-0.005, 0.055)
            ax.set_ylim(-0.005, 0.105)
        fig.suptitle("Fine mesh after the first load step (G&Z Fig. 11)", fontsize=10)
        fig.tight_layout()
        fig.savefig(os.path.join(figures, "fem-biaxial-displacement-start.png"), dpi=110)
        plt.close(fig)

    # Fig. 15: local responses.
    if "local" in records:
        loc = records["local"]
        fig, axes = plt.subplots(1, 3, figsize=(11, 3.6))
        for label, d in loc["points"].items():
            lab = f"{label} (N° {d['gauss_point']})"
            axes[0].plot(np.array(d["eps_q"]) * 100, np.array(d["q"]) / 1e3, label=lab)
            axes[1].plot(np.array(d["p"]) / 1e3, np.array(d["q"]) / 1e3, label=lab)
            axes[2].plot(np.array(d["eps_q"]) * 100, np.array(d["eps_v"]) * 100, label=lab)
        axes[0].set_xlabel("ε_q (%)")
        axes[0].set_ylabel("q (kPa)")
        axes[1].set_xlabel("p (kPa)")
        axes[1].set_ylabel("q (kPa)")
        axes[2].set_xlabel("ε_q (%)")
        axes[2].set_ylabel("ε_v (%, compression +)")
        axes[0].legend(fontsize=8)
        fig.suptitle(f"Local responses on the {loc['mesh']} mesh (G&Z Fig. 15)")
        fig.tight_layout()
        fig.savefig(os.path.join(figures, "fem-biaxial-local-responses.png"), dpi=110)
        plt.close(fig)

        # Fig. 17: the failed points.
        r = runs[loc["mesh"]]
        fig, (a1, a2) = plt.subplots(1, 2, figsize=(8, 4), gridspec_kw={"width_ratios": [2, 1]})
        a1.plot([f["axial_strain"] * 100 for f in r["failed"]],
                [f["fraction"] * 100 for f in r["failed"]])
        a1.set_xlabel("axial strain (%)")
        a1.set_ylabel("failed Gauss points (%)")
        m = r["maps"]["end"]
        col = ["red" if f else "0.8" for f in m["failed"]]
        a2.scatter(m["x"], m["y"], c=col, s=12, marker="s")
        a2.set_aspect("equal")
        a2.set_xticks([])
        a2.set_yticks([])
        a2.set_title("failed at the end (red)", fontsize=9)
        fig.suptitle(f"Failed points (p < {FAILED_P_PA / 1e3:g} kPa), {loc['mesh']} mesh (G&Z Fig. 17)")
        fig.tight_layout()
        fig.savefig(os.path.join(figures, "fem-biaxial-failed-points.png"), dpi=110)
        plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--run", action="append", default=[], help="MESH=DIR")
    ap.add_argument("--start", help="the fine mesh stopped after its first load step")
    ap.add_argument("--local", default="medium", help="the mesh of Figs. 15 and 17")
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--reference",
                    default=os.path.join(here, "reference", "set-dense-drained-biaxial-100kPa.csv"))
    ap.add_argument("--figures", default=os.path.join(here, "figures"))
    ap.add_argument("--records", default=os.path.join(here, "results", "fem-biaxial.json"))
    ap.add_argument("--from-records", action="store_true",
                    help="draw the figures from the records file alone")
    args = ap.parse_args()

    if args.from_records:
        with open(args.records) as f:
            records = json.load(f)
    else:
        records = {"runs": {}}
        frames_of = {}
        for item in args.run:
            name, _, directory = item.partition("=")
            records["runs"][name], frames_of[name] = load_run(name, directory)
        if args.local in frames_of:
            records["local"] = {"mesh": args.local, "points": local_points(frames_of[args.local])}
        if args.start:
            records["start"] = start_field(args.start)
        os.makedirs(os.path.dirname(args.records), exist_ok=True)
        # One key per line, each list of numbers on one line: small, and
        # the run record's fields (its version) on lines of their own.
        text = json.dumps(records, indent=1)
        text = re.sub(r"\[\s*([^\[\]{}\"]*?)\s*\]",
                      lambda m: "[" + ",".join(m.group(1).split()).replace(",,", ",") + "]", text)
        with open(args.records, "w") as f:
            f.write(text + "\n")
    reference = reference_curve(args.reference) if os.path.exists(args.reference) else None
    plot(records, reference, args.figures)

    print(f"{'mesh':10s} {'RVEs':>5s} {'peak kPa':>9s} {'at %':>5s} {'5 % kPa':>8s} "
          f"{'10 % kPa':>8s} {'it/step':>7s} {'wall s':>7s} {'eq max end':>10s} {'e max end':>9s}")
    for name, r in records["runs"].items():
        s = r["summary"]
        print(f"{name:10s} {r['points']:5d} {s['peak_stress_Pa'] / 1e3:9.1f} "
              f"{s['peak_strain'] * 100:5.2f} {r['stress_at_5pct_Pa'] / 1e3:8.1f} "
              f"{r['stress_at_10pct_Pa'] / 1e3:8.1f} {s['iterations_mean']:7.2f} "
              f"{s['wall_s']:7.0f} {r['fields_at_end']['eps_q'][1]:10.3f} "
              f"{r['fields_at_end']['void_ratio'][1]:9.4f}")
    if "start" in records:
        print(f"start: u_x asymmetry {records['start']['ux_asymmetry']:.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
