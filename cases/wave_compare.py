#!/usr/bin/env python3
"""Wave-propagation runs side by side (liang-zhao-wu-soga-2023 §4.4, Figs. 16-20): the
vertical displacement and excess pore pressure of Point B against time (Fig. 19), the orbit
of the surface Point A (Fig. 17), the surface u_y in space and time (Fig. 20), and the speed
of the surface wave against Rayleigh's for the RVE's measured moduli.

  /usr/bin/python3 cases/wave_compare.py RUN_DIR[=LABEL] ... --case=CASE.json
      [--out=wave.png] [--fields=fields.png] [--modulus=M --shear=G]

Reads each RUN_DIR's timeseries.csv (monitor columns <name>_ux, _uy, _p) and results.h5
(frames: position, excess_pore_pressure). The monitors R3, R5, R7 of the case lie on the
surface 3, 5 and 7 m from the load's centre; the delay of their u_y traces (the lag that
maximises their cross-correlation before the first reflection) gives the surface wave's
speed. Rayleigh's speed comes from the skeleton's constrained modulus M and shear modulus
G (Pa, measured on the RVE: rve_cli element-test --test=oedometer / undrained-simple-shear)
and the saturated density: drained (the skeleton's own Poisson ratio) and undrained
(incompressible grains and water, c_R = 0.9553 c_s). Needs numpy, h5py, matplotlib.
"""
import argparse
import csv
import json
import os

import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def rayleigh_ratio(kappa2):
    """c_R/c_s for (c_p/c_s)^2 = kappa2 (inf: incompressible), the root in (0, 1) of
    eta^6 - 8 eta^4 + (24 - 16/kappa2) eta^2 - 16 (1 - 1/kappa2) = 0."""
    inv = 0.0 if np.isinf(kappa2) else 1.0 / kappa2
    roots = np.roots([1, 0, -8, 0, 24 - 16 * inv, 0, -16 * (1 - inv)])
    real = [r.real for r in roots if abs(r.imag) < 1e-9 and 0 < r.real < 1]
    return min(real)


def read_run(path):
    with open(os.path.join(path, "timeseries.csv")) as f:
        rows = list(csv.DictReader(f))
    cols = {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}
    frames = []
    with h5py.File(os.path.join(path, "results.h5"), "r") as h5:
        keys = sorted(h5["frames"], key=int)
        first = h5["frames"][keys[0]]
        x0 = first["position"][:, :2]
        # Saturated density: solids rho_s/(1 + e) plus water n rho_f.
        rho = (2650 / (1 + float(np.mean(first["void_ratio"][:])))
               + 1000 * float(np.mean(first["porosity"][:])))
        for k in keys:
            g = h5["frames"][k]
            frames.append((float(g.attrs["time"]), g["position"][:, :2] - x0,
                           g["excess_pore_pressure"][:]))
    return cols, x0, frames, rho


def nearest(x0, position):
    """The point that starts nearest (the first of equals), as the monitors pick it."""
    d = ((x0 - np.asarray(position)) ** 2).sum(axis=1)
    return int(np.argmin(d))


def lag_speed(t, near, far, distance, t_max):
    """Surface-wave speed from the lag maximising the cross-correlation of two u_y
    traces before t_max, refined by a parabola through the peak, m/s."""
    keep = t <= t_max
    a, b = near[keep], far[keep]
    dt = t[1] - t[0]
    corr = [np.dot(a[: len(a) - s], b[s:]) for s in range(len(a) // 2)]
    s = int(np.argmax(corr))
    if 0 < s < len(corr) - 1:
        c0, c1, c2 = corr[s - 1], corr[s], corr[s + 1]
        s = s + 0.5 * (c0 - c2) / (c0 - 2 * c1 + c2)
    return distance / (s * dt) if s > 0 else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", nargs="+", help="RUN_DIR[=LABEL]")
    ap.add_argument("--case", required=True, help="the case file (monitor positions)")
    ap.add_argument("--out", default="wave.png")
    ap.add_argument("--fields", default="", help="field snapshots of the first run (PNG)")
    ap.add_argument("--modulus", type=float, default=56e6, help="constrained modulus M, Pa")
    ap.add_argument("--shear", type=float, default=25e6, help="shear modulus G, Pa")
    ap.add_argument("--density", type=float, default=0.0,
                    help="saturated density, kg/m3 (default: from the first run's frame 0)")
    args = ap.parse_args()
    case = json.load(open(args.case))
    monitors = {m["name"]: m["position"] for m in case["phases"]["monitors"]}
    width = case["regions"][0]["upper"][0]

    runs = []
    for spec in args.runs:
        path, _, label = spec.partition("=")
        runs.append((label or os.path.basename(path.rstrip("/")), *read_run(path)))

    rho = args.density if args.density > 0 else runs[0][4]
    cs = np.sqrt(args.shear / rho)
    c_drained = rayleigh_ratio(args.modulus / args.shear) * cs
    c_undrained = rayleigh_ratio(np.inf) * cs
    print(f"rho_sat = {rho:.0f} kg/m3, c_s = {cs:.1f} m/s, c_p (drained) = "
          f"{np.sqrt(args.modulus / rho):.1f} m/s; Rayleigh c_R drained {c_drained:.1f}, "
          f"undrained {c_undrained:.1f} m/s")

    fig, axes = plt.subplots(2, 2, figsize=(11, 8.5))
    (ax_uy, ax_p), (ax_orbit, ax_map) = axes
    for label, cols, x0, frames, _ in runs:
        t = cols["time"]
        ax_uy.plot(t, 1e3 * cols["B_uy"], label=label, lw=0.9)
        ax_p.plot(t, 1e-3 * cols["B_p"], label=label, lw=0.9)
        ax_orbit.plot(1e3 * cols["A_ux"], 1e3 * cols["A_uy"], label=label, lw=0.8)
        # Before the first reflection reaches R7 (the side wall is as far again).
        d = {m: abs(x0[nearest(x0, monitors[m])][0] - monitors["B"][0]) for m in ("R3", "R7")}
        t_max = (width - monitors["B"][0] + (width - monitors["B"][0] - d["R7"])) / c_undrained
        speed = lag_speed(t, cols["R3_uy"], cols["R7_uy"], d["R7"] - d["R3"], t_max)
        peak_uy = 1e3 * cols["B_uy"].min()
        peak_p = 1e-3 * cols["B_p"].max()
        print(f"{label}: B peak u_y {peak_uy:.3f} mm at {t[cols['B_uy'].argmin()]:.4f} s, "
              f"peak excess p {peak_p:.2f} kPa at {t[cols['B_p'].argmax()]:.4f} s; "
              f"A |u| max {1e3 * np.hypot(cols['A_ux'], cols['A_uy']).max():.3f} mm; "
              f"surface wave R3->R7 {speed:.1f} m/s "
              f"({speed / c_drained:.3f} x drained c_R, {speed / c_undrained:.3f} x undrained)")
    ax_uy.set(title="Point B: vertical displacement (Fig. 19a)", xlabel="time (s)",
              ylabel="u_y (mm, up +)")
    ax_p.set(title="Point B: excess pore pressure (Fig. 19b)", xlabel="time (s)",
             ylabel="Δp (kPa)")
    ax_orbit.set(title="Point A: orbit (Fig. 17)", xlabel="u_x (mm)", ylabel="u_y (mm)")
    ax_orbit.set_aspect("equal", adjustable="datalim")
    for ax in (ax_uy, ax_p, ax_orbit):
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)

    # Surface u_y of the first run in space and time, with Rayleigh's fronts.
    label, cols, x0, frames, _ = runs[0]
    top = np.isclose(x0[:, 1], x0[:, 1].max())
    order = np.argsort(x0[top, 0])
    xs = x0[top, 0][order]
    ts = np.array([f[0] for f in frames])
    uy = np.array([f[1][top, 1][order] for f in frames]) * 1e3
    lim = np.abs(uy).max() * 0.3
    ax_map.pcolormesh(xs, ts, uy, cmap="RdBu_r", vmin=-lim, vmax=lim, shading="nearest")
    xc = monitors["B"][0]
    for c, style in ((c_drained, "--"), (c_undrained, ":")):
        for side in (-1, 1):
            edge = xc + side * 0.5
            ax_map.plot([edge, edge + side * c * ts[-1]], [0, ts[-1]], "k" + style, lw=0.8)
    ax_map.set(title=f"{label}: surface u_y (Fig. 20; lines: c_R drained --, undrained :)",
               xlabel="x (m)", ylabel="time (s)", xlim=(xs[0], xs[-1]), ylim=(0, ts[-1]))
    fig.suptitle(f"{case['name']}: {', '.join(r[0] for r in runs)}")
    fig.tight_layout()
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")

    if args.fields:
        # Displacement magnitude and excess pore pressure at the paper's instants.
        want = [0.04, 0.07, 0.09, 0.12]
        fig, axes = plt.subplots(len(want), 2, figsize=(12, 2.6 * len(want)))
        for row, tw in zip(axes, want):
            k = int(np.argmin([abs(f[0] - tw) for f in frames]))
            tk, u, dp = frames[k]
            mag = 1e3 * np.hypot(u[:, 0], u[:, 1])
            sc = row[0].scatter(x0[:, 0], x0[:, 1], c=mag, s=2, cmap="viridis", vmin=0,
                                vmax=max(mag.max(), 1e-12))
            fig.colorbar(sc, ax=row[0], label="|u| (mm)")
            lim = max(np.abs(dp).max(), 1.0) * 1e-3
            sc = row[1].scatter(x0[:, 0], x0[:, 1], c=1e-3 * dp, s=2, cmap="RdBu_r",
                                vmin=-lim, vmax=lim)
            fig.colorbar(sc, ax=row[1], label="Δp (kPa)")
            for ax, what in zip(row, ("displacement (Fig. 16)", "excess pore pressure (Fig. 18)")):
                ax.set(title=f"{label}: {what}, t = {tk:.3f} s", aspect="equal")
        fig.tight_layout()
        fig.savefig(args.fields, dpi=80)
        print(f"wrote {args.fields}")


if __name__ == "__main__":
    main()
