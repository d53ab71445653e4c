#!/usr/bin/env python3
"""The §4.3 columns on finer cells: saturated against dry, with and without F-bar.

  /usr/bin/python3 cases/saturated_refinement.py DIR [--out=refinement.png]

DIR holds one file or run per column, named KIND_PHASE_FBAR_hCELL, e.g. mc_sat_nodal_h0.05.csv
or rve_dry_none_h0.1/:
- KIND `mc`: a Mohr–Coulomb continuum, the CSV that tests/mpm_client/run/prandtl_test.cc's
  DISABLED_MeasureWithMohrCoulomb writes with RVEHUB_PRANDTL_ENERGY_CSV (time, kinetic,
  front99); `rve`, `rve-dense`, `rve-loose`: an mpm_client run directory (its
  timeseries.csv: time, kinetic_energy, mass_front_99_x) of the medium, dense or loose
  packing. Every saturated RVE column is compared with the dry medium one, `rve_dry_*`, as
  in the paper;
- PHASE `sat` or `dry`, FBAR `nodal` or `none` (solver.f_bar), CELL the cell size in m.

For each kind, F-bar and cell size with both columns it prints the kinetic-energy peaks (J,
up to --until s, before any late blow-up), their ratio saturated/dry (the paper's Fig. 13:
"much smaller" in the saturated columns) and where 99 % of the points lie behind at 0.5 s
(its Fig. 11: the saturated fronts lag). It draws the ratio against the cell size, the
continuum's kinetic energies on its coarsest and finest cells and the RVE columns' on their
finest. --peaks=CSV adds the ratios of runs no longer at hand (columns kind, fbar, h_m,
sat_peak_J, dry_peak_J as printed here; a run in DIR takes precedence), e.g. the measured
peaks kept in cases/figures/collapse-saturated-refinement-peaks.csv. --histories=CSV adds
the curves of RVE runs no longer at hand (columns kind, phase, fbar, h_m, time_s,
kinetic_energy_J, front99_m; a run in DIR takes precedence), as
--write-histories=CSV writes them from the RVE runs in DIR, e.g.
cases/figures/collapse-saturated-refinement-histories.csv. Needs numpy and matplotlib.
"""
import argparse
import csv
import os
import re

import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

PACKINGS = {"rve": "medium", "rve-dense": "dense", "rve-loose": "loose"}  # RVE kinds
KINDS, FBARS = ("mc", *PACKINGS), ("nodal", "none")
NAME = re.compile(rf"^({'|'.join(KINDS)})_(sat|dry)_({'|'.join(FBARS)})_h([0-9.]+?)(\.csv)?$")


def label(kind):
    return "Mohr–Coulomb" if kind == "mc" else f"RVEs, {PACKINGS[kind]}"


def colour(kind):
    """One colour per RVE packing, the same in every panel."""
    return f"C{list(PACKINGS).index(kind)}"


def dry_of(kind):
    """The kind whose dry column a saturated one is compared with: the paper's dry column is
    the medium packing's."""
    return "mc" if kind == "mc" else "rve"


def read(path):
    """time (s), kinetic energy (J), 99 % front (m) of a run or an energy CSV."""
    if os.path.isdir(path):
        path, t, k, f = os.path.join(path, "timeseries.csv"), "time", "kinetic_energy", \
            "mass_front_99_x"
    else:
        t, k, f = "time", "kinetic", "front99"
    with open(path) as fh:
        rows = [r for r in csv.DictReader(fh) if r.get(f) not in (None, "")]
    col = lambda key: np.array([float(r[key]) for r in rows])  # noqa: E731
    return col(t), col(k), col(f)


def csv_rows(path, columns, numbers):
    """(line, row) of a CSV with the named columns, those in `numbers` as floats. A missing
    column, a short row or a field that is not a number ends the script with file and line."""
    with open(path) as fh:
        reader = csv.DictReader(fh)
        if not set(columns) <= set(reader.fieldnames or ()):
            raise SystemExit(f"{path}: needs the columns {', '.join(columns)}")
        for r in reader:
            if any(r[c] is None for c in columns):
                raise SystemExit(f"{path}:{reader.line_num}: fewer fields than the header")
            try:
                yield reader.line_num, {c: float(r[c]) if c in numbers else r[c] for c in columns}
            except ValueError as e:
                raise SystemExit(f"{path}:{reader.line_num}: not a number ({e})")


PEAK_COLUMNS = ("kind", "fbar", "h_m", "sat_peak_J", "dry_peak_J")
HISTORY_COLUMNS = ("kind", "phase", "fbar", "h_m", "time_s", "kinetic_energy_J", "front99_m")


def read_histories(path):
    """{(kind, phase, fbar, h): (time, kinetic energy, front)} from a --histories CSV."""
    curves = {}
    for line, r in csv_rows(path, HISTORY_COLUMNS, HISTORY_COLUMNS[3:]):
        if r["kind"] not in PACKINGS or r["phase"] not in ("sat", "dry") or \
                r["fbar"] not in FBARS:
            raise SystemExit(f"{path}:{line}: kind must be one of {', '.join(PACKINGS)}, "
                             f"phase sat or dry, fbar one of {', '.join(FBARS)}")
        if not r["h_m"] > 0:
            raise SystemExit(f"{path}:{line}: h_m must be > 0")
        curves.setdefault((r["kind"], r["phase"], r["fbar"], r["h_m"]), []).append(
            [r[c] for c in HISTORY_COLUMNS[4:]])
    return {key: tuple(np.array(rows).T) for key, rows in curves.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("dir")
    ap.add_argument("--out", default="saturated-refinement.png")
    ap.add_argument("--until", type=float, default=0.6, help="s: the peak is sought before")
    ap.add_argument("--peaks", help="CSV of recorded peaks of runs not in DIR")
    ap.add_argument("--histories", help="CSV of recorded curves of RVE runs not in DIR")
    ap.add_argument("--write-histories", help="write the RVE runs' curves in DIR to this CSV")
    a = ap.parse_args()
    runs = {}
    for name in sorted(os.listdir(a.dir)):
        m = NAME.match(name)
        if m and os.path.exists(os.path.join(a.dir, name)):
            kind, phase, fbar, h = m.group(1), m.group(2), m.group(3), float(m.group(4))
            runs[(kind, phase, fbar, h)] = read(os.path.join(a.dir, name))
    if a.write_histories:
        with open(a.write_histories, "w", newline="") as fh:
            out = csv.writer(fh)
            out.writerow(HISTORY_COLUMNS)
            for (kind, phase, fbar, h), curve in sorted(runs.items()):
                if kind != "mc":
                    for t, k, f in zip(*curve):
                        out.writerow([kind, phase, fbar, h, f"{t:.4f}", f"{k:.2f}", f"{f:.4f}"])
        print(f"wrote {a.write_histories}")
    if a.histories:
        for key, curve in read_histories(a.histories).items():
            runs.setdefault(key, curve)
    if not runs:
        raise SystemExit(f"{a.dir}: no file or run named like mc_sat_nodal_h0.1.csv")

    mc_cells = sorted({h for (kind, _, _, h) in runs if kind == "mc"})
    rve_cells = sorted({h for (kind, _, _, h) in runs if kind != "mc"})
    # The continuum's coarsest and finest cells, then the RVE columns' finest (every packing).
    panels = [("mc", h) for h in dict.fromkeys(mc_cells[-1:] + mc_cells[:1])]
    panels += [("rve", h) for h in rve_cells[:1]]
    fig, axes = plt.subplots(1, 1 + len(panels), figsize=(5 * (1 + len(panels)), 4.5),
                             squeeze=False)
    axes = axes[0]
    ratios = {}
    recorded_dry = {}  # (fbar, h): a dry RVE peak (J) from --peaks

    def add(kind, fbar, h, ps, pd, fronts):
        """One saturated/dry pair: its ratio for the plot and its row in the table."""
        ratios.setdefault((kind, fbar), []).append((h, ps / pd))
        print(f"{kind:10s}{fbar:6s}{h:6.3f}  {ps:10.0f} {pd:10.0f} {ps / pd:6.2f}  {fronts:>24s}")

    print(f"{'kind':10s}{'F-bar':6s}{'h m':>6s}  {'sat peak J':>10s} {'dry peak J':>10s} "
          f"{'ratio':>6s}  {'front 0.5 s sat / dry m':>24s}")
    for (kind, phase, fbar, h), (t, k, f) in sorted(runs.items()):
        if phase != "sat" or (dry_of(kind), "dry", fbar, h) not in runs:
            continue
        td, kd, fd = runs[(dry_of(kind), "dry", fbar, h)]
        ps, pd = k[t <= a.until].max(), kd[td <= a.until].max()
        add(kind, fbar, h, ps, pd, f"{np.interp(0.5, t, f):.2f} / {np.interp(0.5, td, fd):.2f}")
    if a.peaks:
        for line, r in csv_rows(a.peaks, PEAK_COLUMNS, PEAK_COLUMNS[2:]):
            kind, fbar, h, ps, pd = (r[c] for c in PEAK_COLUMNS)
            if not (h > 0 and ps > 0 and pd > 0):
                raise SystemExit(f"{a.peaks}:{line}: h_m and the peaks must be > 0")
            if kind not in KINDS or fbar not in FBARS:
                raise SystemExit(f"{a.peaks}:{line}: kind must be one of {', '.join(KINDS)} "
                                 f"and fbar one of {', '.join(FBARS)}")
            if kind != "mc":
                recorded_dry[(fbar, h)] = pd
            if (kind, "sat", fbar, h) in runs and (dry_of(kind), "dry", fbar, h) in runs:
                continue
            add(kind, fbar, h, ps, pd, "(recorded)")
    # One colour per kind (the RVE panel's), F-bar filled and solid, without it open and dashed.
    marker = {"mc": "o", "rve": "s", "rve-dense": "^", "rve-loose": "v"}
    for (kind, fbar), pts in sorted(ratios.items()):
        h, r = np.array(sorted(pts)).T
        color = "k" if kind == "mc" else colour(kind)
        axes[0].plot(h, r, marker[kind] + ("-" if fbar == "nodal" else "--"), color=color,
                     mfc=color if fbar == "nodal" else "none",
                     label=f"{label(kind)}, F-bar {fbar}")
    axes[0].set_xlabel("cell size h (m), 5 × 5 points per cell")
    axes[0].set_ylabel("kinetic-energy peak, saturated / dry")
    axes[0].set_xlim(0, 0.11)
    axes[0].set_ylim(0.3, 1.1)
    axes[0].axvline(0.1, color="grey", lw=0.5)
    axes[0].axhline(1.0, color="grey", lw=0.5)
    axes[0].legend(fontsize=7, ncol=2, loc="lower center")
    axes[0].set_title("saturated/dry peak against cell size")
    style = {("sat", "nodal"): "-", ("sat", "none"): "--", ("dry", "nodal"): ":",
             ("dry", "none"): "-."}
    for ax, (panel_kind, h) in zip(axes[1:], panels):
        drawn = set()
        for (kind, phase, fbar, hh), (t, k, _) in sorted(runs.items()):
            if (kind == "mc") == (panel_kind == "mc") and hh == h:
                color = colour(kind) if kind != "mc" else ("C0" if fbar == "nodal" else "C1")
                who = "" if kind == "mc" else f"{PACKINGS[kind]}, "
                ax.plot(t, k, style[(phase, fbar)], color=color,
                        label=f"{who}{phase}, F-bar {fbar}")
                drawn.add((phase, fbar))
        if panel_kind != "mc":
            # A dry column whose run is no longer at hand: its recorded peak.
            for fbar in FBARS:
                if ("sat", fbar) in drawn and ("dry", fbar) not in drawn and \
                        (fbar, h) in recorded_dry:
                    ax.axhline(recorded_dry[(fbar, h)], color="grey", ls=style[("dry", fbar)],
                               label=f"dry medium peak, F-bar {fbar} (recorded)")
        ax.set_xlim(0, 1.0)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("kinetic energy of the solids (J)")
        what = "Mohr–Coulomb column" if panel_kind == "mc" else "RVE columns"
        ax.set_title(f"{what}, h = {h} m")
        ax.legend(fontsize=8)
    fig.suptitle("liang-zhao-wu-soga-2023 §4.3 columns (collapse-saturated-dense, -medium, "
                 "-loose, collapse-dry-medium) on finer cells")
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
