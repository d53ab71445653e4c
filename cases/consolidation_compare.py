#!/usr/bin/env python3
"""1-D consolidation runs against Terzaghi: pore-pressure isochrones at the frames of the run
and the degree of consolidation from the surface settlement, with the worst error per Tv.

  /usr/bin/python3 cases/consolidation_compare.py RUN_DIR[=LABEL[=K]] ... [--out=consolidation.png]
      [--modulus=25.08e6] [--permeability=1e-3] [--surcharge=110e3] [--height=1]
      [--solid-density=2650]

Each isochrone is also compared with the same problem solved with the mixture's inertia
(`inertial_p`, the solver's equations in 1-D; dotted on the figure): Terzaghi leaves the
inertia out, and at Tv = 0.010 (3.9 ms) the exact isochrone still ends at a wave front.

Terzaghi's p0 is the load the water carries at first: the surcharge less the RVEs' initial
effective σyy (the first row of timeseries.csv; the RVEs are consolidated to 100 kPa within
1 %, so p0 is ~10.6 kPa rather than the nominal 10). c_v = k·M/(ρ_f·g) (k from --permeability, or K after a run's label: a permeability
sweep on one figure) with M = K + 4G/3 of the
RVE (25.08 MPa measured by `rve_cli element-test oedometer` on the consolidation set; the
paper's 25.06), ρ_f = 1000 kg/m³, g = 9.81 m/s². Reads RUN_DIR/results.h5 (frames: position,
pore_pressure) and RUN_DIR/timeseries.csv (time, mean_syy, surface_settlement). Needs numpy,
h5py and matplotlib (Debian's python3-numpy, python3-h5py, python3-matplotlib).
"""
import argparse
import csv
import os

import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

RHO_F, G = 1000.0, 9.81


def terzaghi_p(p0, z_over_h, tv):
    """Excess pore pressure of a layer drained at z = 0, impermeable at z = H."""
    total = np.zeros_like(z_over_h, dtype=float)
    for m in range(2000):
        a = (2 * m + 1) * np.pi / 2
        total += 2 / a * np.sin(a * z_over_h) * np.exp(-a * a * tv)
        if np.all(2 / a * np.exp(-a * a * np.asarray(tv)) < 1e-12):
            break
    return p0 * total


def mixture_inertia(n, rho_s, rho_f=RHO_F):
    """Mass per volume that the skeleton's motion carries in 1-D, kg/m3 (see inertial_p)."""
    return (1 - n) * (rho_s - rho_f + rho_f / n)


def inertial_p(p0, modulus, k, n, rho_s, rho_f, height, times, cells=1000):
    """Terzaghi's problem with the mixture's inertia, the solver's own equations in 1-D.

    Incompressible grains and fluid, impermeable fixed base: continuity gives
    n (v_f - v_s) = -v_s, and the two momentum balances become the damped wave equation
    m u_tt + (gamma_w/k) u_t = M u_zz for the downward solid displacement u(z, t), with
    m = (1 - n)(rho_s - rho_f + rho_f/n), -M u_z = p0 at the drained top and u = 0 at the
    base; then p_z = (gamma_w/k) v_s + rho_f (1 - n)/n a_s. Terzaghi's solution is its limit
    m -> 0; the wave front sqrt(M/m) t bounds the early isochrones. Finite differences
    (`cells` cells, damping by Crank-Nicolson). Returns {t: (z, p)} with z the depth, m.
    Returns None when the inertial time m k/gamma_w is negligible (< 1e-4 of the first
    time), i.e. the answer is Terzaghi's."""
    gamma_w = RHO_F * G
    m = mixture_inertia(n, rho_s, rho_f)
    c = gamma_w / k
    targets = sorted(t for t in times if t > 0)
    if not targets or m / c < 1e-4 * targets[0]:
        return None
    dz = height / cells
    dt = 0.4 * dz / np.sqrt(modulus / m)
    mass = np.full(cells + 1, m * dz)
    damp = np.full(cells + 1, c * dz)
    mass[0], damp[0] = 0.5 * m * dz, 0.5 * c * dz
    u, v = np.zeros(cells + 1), np.zeros(cells + 1)
    z = np.arange(cells + 1) * dz
    out, t = {}, 0.0
    for target in targets:
        while t < target * (1 - 1e-12):
            h = min(dt, target - t)
            sig = modulus * (u[:-1] - u[1:]) / dz  # effective stress, compression +
            f = np.zeros(cells + 1)
            f[0] = p0 - sig[0]
            f[1:-1] = sig[:-1] - sig[1:]
            new = ((mass / h - damp / 2) * v + f) / (mass / h + damp / 2)
            new[-1] = 0.0
            a, v = (new - v) / h, new
            u += h * v
            t += h
        integrand = c * v + rho_f * (1 - n) / n * a
        p = np.concatenate([[0.0], np.cumsum(0.5 * (integrand[1:] + integrand[:-1]) * dz)])
        out[target] = (z, p)
    return out


def terzaghi_u(tv):
    total = np.zeros_like(tv, dtype=float)
    for m in range(2000):
        a = (2 * m + 1) * np.pi / 2
        total += 2 / (a * a) * np.exp(-a * a * tv)
    return 1 - total


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("runs", nargs="+", help="RUN_DIR, RUN_DIR=LABEL or RUN_DIR=LABEL=K (m/s)")
    ap.add_argument("--out", default="consolidation.png")
    ap.add_argument("--modulus", type=float, default=25.08e6, help="M = K + 4G/3, Pa")
    ap.add_argument("--permeability", type=float, default=1e-3, help="k, m/s")
    ap.add_argument("--surcharge", type=float, default=110e3, help="total load on the top, Pa")
    ap.add_argument("--height", type=float, default=1.0, help="H, m")
    ap.add_argument("--solid-density", type=float, default=2650.0,
                    help="grain density of the RVEs, kg/m3 (for the reference with inertia)")
    a = ap.parse_args()
    fig, (ax_p, ax_u, ax_b) = plt.subplots(1, 3, figsize=(18, 5))
    z = np.linspace(0, 1, 201)
    for index, run in enumerate(a.runs):
        parts = run.split("=")
        path = parts[0]
        label = parts[1] if len(parts) > 1 else os.path.basename(path.rstrip("/"))
        k = float(parts[2]) if len(parts) > 2 else a.permeability
        cv = k * a.modulus / (RHO_F * G)
        with open(os.path.join(path, "timeseries.csv")) as f:
            rows = list(csv.DictReader(f))
        p0 = a.surcharge - float(rows[0]["mean_syy"])
        t = np.array([float(r["time"]) for r in rows])
        settlement = np.array([float(r["surface_settlement"]) for r in rows])
        tv_rows = cv * t / a.height**2
        u = settlement / (p0 * a.height / a.modulus)
        mask = tv_rows > 0
        ax_u.semilogx(tv_rows[mask], u[mask], "o" if index == 0 else "s", ms=2, label=label)
        late = tv_rows[mask] > 0.01
        worst_u = np.max(np.abs(u[mask] - terzaghi_u(tv_rows[mask]))[late]) if late.any() else 0
        print(f"{label}: k = {k:g} m/s, p0 = {p0:.1f} Pa, c_v = {cv:.4f} m2/s, worst "
              f"|U - Terzaghi| = {worst_u:.4f} for Tv > 0.01")
        if "base_p" in rows[0]:
            base = np.array([float(r["base_p"]) for r in rows]) / p0
            line = ax_b.semilogx(t[mask], base[mask], lw=1, label=f"{label} (k = {k:g} m/s)")
            ax_b.semilogx(t[mask], terzaghi_p(1.0, np.ones(mask.sum()) * 0.9975, tv_rows[mask]),
                          "--", color=line[0].get_color(), lw=0.8)
        e0 = float(rows[0]["mean_void_ratio"])
        porosity = e0 / (1 + e0)
        with h5py.File(os.path.join(path, "results.h5"), "r") as h5:
            times = [h5["frames"][s].attrs["time"] for s in h5["frames"].keys()]
            inertial = inertial_p(p0, a.modulus, k, porosity, a.solid_density, RHO_F, a.height,
                                  times)
            for step in sorted(h5["frames"].keys(), key=int):
                frame = h5["frames"][step]
                tv = cv * frame.attrs["time"] / a.height**2
                if tv <= 0:
                    continue
                y = frame["position"][:, 1]
                p = frame["pore_pressure"][:]
                exact = terzaghi_p(p0, (a.height - y) / a.height, tv)
                worst = np.max(np.abs(p - exact)) / p0
                line = f"  Tv = {tv:.4f}: worst |p - Terzaghi| = {100 * worst:.2f} % of p0"
                if inertial is not None:
                    zi, pi = inertial[frame.attrs["time"]]
                    with_inertia = np.interp(a.height - y, zi, pi)
                    gap = np.max(np.abs(with_inertia - exact)) / p0
                    worst_i = np.max(np.abs(p - with_inertia)) / p0
                    rms_i = np.sqrt(np.mean((p - with_inertia) ** 2)) / p0
                    # The reference's step across its wave front (depth sqrt(M/m) t),
                    # over one cell (two point spacings): a grid smears a step, so
                    # there the worst error is about half of it, however fine the grid.
                    rows_y = np.unique(np.round(y, 4))
                    width = 2 * (rows_y[-1] - rows_y[0]) / (len(rows_y) - 1)
                    front = np.sqrt(a.modulus / mixture_inertia(porosity, a.solid_density)) \
                        * frame.attrs["time"]
                    step_at_front = abs(np.interp(front - width / 2, zi, pi)
                                        - np.interp(front + width / 2, zi, pi)) / p0
                    worst_at = a.height - y[np.argmax(np.abs(p - with_inertia))]
                    line += (f"; with the mixture's inertia: {100 * worst_i:.2f} % at "
                             f"{worst_at:.3f} m deep (rms {100 * rms_i:.2f} %; that reference "
                             f"differs from Terzaghi by {100 * gap:.2f} %")
                    if front < a.height:
                        line += (f" and steps by {100 * step_at_front:.2f} % of p0 over one cell "
                                 f"at its wave front, {front:.3f} m deep")
                    line += ")"
                    if index == 0:
                        ax_p.plot(pi / p0, zi / a.height, "k:", lw=0.8)
                print(line)
                order = np.argsort(y)
                ax_p.plot(p[order] / p0, (a.height - y[order]) / a.height,
                          "o" if index == 0 else "s", ms=3, mfc="none",
                          label=label if step == sorted(h5["frames"].keys(), key=int)[1] else None)
                if index == 0:
                    ax_p.plot(terzaghi_p(1.0, z, tv), z, "k-", lw=0.8)
                    ax_p.annotate(f"{tv:.3g}", (terzaghi_p(1.0, np.array([0.6]), tv)[0], 0.6),
                                  fontsize=7)
    tv_line = np.logspace(-3, 0.5, 200)
    ax_u.semilogx(tv_line, terzaghi_u(tv_line), "k-", lw=0.8, label="Terzaghi")
    ax_p.set_xlabel("excess pore pressure p / p0 (-)")
    ax_p.set_ylabel("depth z / H (-)")
    ax_p.invert_yaxis()
    ax_p.set_title("consolidation-1d: isochrones (lines: Terzaghi, dotted: with inertia; labels: Tv)")
    ax_p.legend(loc="lower left")
    ax_u.set_xlabel("time factor Tv = c_v t / H^2 (-)")
    ax_u.set_ylabel("degree of consolidation U = s / s_final (-)")
    ax_u.set_title("consolidation-1d: degree of consolidation")
    ax_u.legend()
    ax_b.set_xlabel("time t (s)")
    ax_b.set_ylabel("excess pore pressure at the base p / p0 (-)")
    ax_b.set_title("base point (dashed: Terzaghi)")
    ax_b.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(a.out, dpi=110)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    main()
