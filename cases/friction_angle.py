#!/usr/bin/env python3
"""Peak friction angle of an RVE from drained biaxial tests, and Prandtl's N_q.

As liang-zhao-mpm-dem §3.3.1 does for the footing: biaxial tests on the same
RVE at 10, 15, 20, 25 and 30 kPa; the Mohr circles of the peak states give
phi' (best fit of sin phi' = (s1 - s3)/(s1 + s3) through the origin, i.e. a
cohesionless envelope), and N_q = tan^2(pi/4 + phi'/2) exp(pi tan phi').
The tests run on to 30 % axial strain; the mean stress ratio from 15 % on
gives the critical-state (large-strain) angle phi_cs, which a deep
penetration mobilises in a strain-softening soil (cases/pipe_compare.py).

  python3 cases/friction_angle.py [--material=footing-dense] [--seed=1]
      [--rve-cli=build/rve_server/cli/rve_cli] [--out=out/friction_angle]
"""
import argparse
import csv
import math
import os
import subprocess


def peak_state(path):
    """(sigma_1, sigma_3) at the peak deviator of a biaxial CSV, Pa, compression +."""
    best = None
    with open(path) as f:
        for row in csv.DictReader(f):
            s1, s3 = float(row["syy"]), float(row["sxx"])
            if best is None or s1 - s3 > best[0] - best[1]:
                best = (s1, s3)
    return best


def prandtl_nq(phi):
    """Prandtl's bearing-capacity factor N_q for a friction angle phi in radians."""
    return math.tan(math.pi / 4 + phi / 2) ** 2 * math.exp(math.pi * math.tan(phi))


def large_strain_ratio(path, from_strain):
    """Mean (s1 - s3)/(s1 + s3) over the rows at axial strain >= from_strain."""
    ratios = []
    with open(path) as f:
        for row in csv.DictReader(f):
            if float(row["axial_strain"]) >= from_strain:
                s1, s3 = float(row["syy"]), float(row["sxx"])
                ratios.append((s1 - s3) / (s1 + s3))
    return sum(ratios) / len(ratios)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--material", default="footing-dense")
    ap.add_argument("--seed", default="1")
    ap.add_argument("--rve-cli", default="build/rve_server/cli/rve_cli")
    ap.add_argument("--out", default="out/friction_angle")
    ap.add_argument("--pressures", default="10e3,15e3,20e3,25e3,30e3", help="Pa, comma-separated")
    ap.add_argument("--strain", type=float, default=0.30, help="axial strain at the end")
    ap.add_argument("--cs-from", type=float, default=0.15,
                    help="axial strain from which the stress ratio counts as critical state")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    num = den = 0.0
    cs = []
    for p in (float(x) for x in a.pressures.split(",")):
        path = os.path.join(a.out, f"{a.material}-{p / 1e3:g}kPa.csv")
        subprocess.run([a.rve_cli, "element-test", "--test=drained-biaxial",
                        f"--material={a.material}", f"--seed={a.seed}", f"--confining={p}",
                        f"--strain={a.strain}",
                        # Rows every 0.02 % of strain, as the 8 % tests had: the peak is
                        # read off the rows.
                        f"--rows={round(a.strain / 0.0002)}", f"--out={path}"], check=True,
                       stderr=subprocess.DEVNULL)
        s1, s3 = peak_state(path)
        radius, centre = (s1 - s3) / 2, (s1 + s3) / 2
        num += radius * centre
        den += centre * centre
        cs.append(large_strain_ratio(path, a.cs_from))
        print(f"sigma3 = {p / 1e3:5.1f} kPa: peak sigma1 = {s1 / 1e3:7.2f} kPa, "
              f"phi = {math.degrees(math.asin(radius / centre)):5.2f} deg, from "
              f"{a.cs_from:.0%} strain on {math.degrees(math.asin(cs[-1])):5.2f} deg")
    phi = math.asin(num / den)
    nq = prandtl_nq(phi)
    print(f"{a.material}: phi' = {math.degrees(phi):.2f} deg (least squares over the Mohr "
          f"circles), Prandtl N_q = {nq:.2f}; phi_cs = "
          f"{math.degrees(math.asin(sum(cs) / len(cs))):.2f} deg (mean stress ratio from "
          f"{a.cs_from:.0%} axial strain on)")


if __name__ == "__main__":
    main()
