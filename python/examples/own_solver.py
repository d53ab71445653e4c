#!/usr/bin/env python3
"""A user's implicit single-element solver on the RVE service.

One plane-strain element under mixed control, a drained biaxial test: the
vertical strain is prescribed (ΔF_yy), the lateral stress σxx = −p0 and the
shear stress σxy = 0 are held (tension +, Pa). Each load step solves for the
free components u = (ΔF_xx, ΔF_xy) by Newton: TRIAL increments (the RVE does
not change) with the returned contact tangent D as the Jacobian, then a
COMMIT of the converged increment. The contact tangent is stiffer than the
packing once contacts slide, so the iterations converge linearly there.

    export PYTHONPATH=$PWD/python:$PWD/build/python
    /usr/bin/python3 python/examples/own_solver.py [--steps 20]
"""

import argparse

import numpy as np

import rvehub


def delta_f(u, dyy):
    f = np.eye(3)
    f[0, 0], f[0, 1], f[1, 1] = 1 + u[0], u[1], 1 + dyy
    return f


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=20)
    ap.add_argument("--dyy", type=float, default=-5e-4, help="ΔF_yy − 1 per step (− compresses)")
    ap.add_argument("--p0", type=float, default=100e3, help="lateral stress, Pa, compression +")
    ap.add_argument("--tol", type=float, default=2e-3, help="residual / p0 to converge at")
    ap.add_argument("--out-dir", help="unused; accepted for the CTest runner")
    args = ap.parse_args()
    target = np.array([-args.p0, 0.0])  # σxx, σxy, tension +

    with rvehub.local(threads=1) as hub:
        t = hub.prepare_template("SET-dense", seed=1)
        run = hub.create_run("own-solver", t.name, ids=[0], pressure=args.p0)
        print("step  iters  eps_yy   sigma_xx_kPa  sigma_yy_kPa  q_kPa   e")
        u = np.zeros(2)  # each step starts from the last one's solution
        for step in range(1, args.steps + 1):
            for it in range(1, 21):
                s = run.apply(delta_f(u, args.dyy)[None], mode="trial", tangent=True).check()
                sig, d = s.stress[0], s.tangent[0]
                r = np.array([sig[0, 0], sig[0, 1]]) - target
                if np.max(np.abs(r)) < args.tol * args.p0:
                    break
                # dσ_ij ≈ D_ijkl dε_kl with dε = sym(dΔF): the Jacobian of
                # (σxx, σxy) with respect to (ΔF_xx, ΔF_xy).
                jac = np.array([[d[0, 0, 0, 0], 0.5 * (d[0, 0, 0, 1] + d[0, 0, 1, 0])],
                                [d[0, 1, 0, 0], 0.5 * (d[0, 1, 0, 1] + d[0, 1, 1, 0])]])
                u -= np.linalg.solve(jac, r)
            else:
                raise SystemExit(f"step {step}: Newton did not converge (residual {r} Pa)")
            c = run.apply(delta_f(u, args.dyy)[None], mode="commit").check()
            assert np.array_equal(c.stress, s.stress)  # the commit is the converged trial
            f = c.deformation_gradient[0]
            print(f"{step:4d}  {it:5d}  {1 - f[1, 1]:.5f}  {-c.stress[0, 0, 0] / 1e3:12.2f}  "
                  f"{-c.stress[0, 1, 1] / 1e3:12.2f}  {c.deviator_stress[0] / 1e3:6.2f}  "
                  f"{c.void_ratio[0]:.4f}")
        assert run.steps[0] == args.steps


if __name__ == "__main__":
    main()
