#!/usr/bin/env python3
"""A drained biaxial test on a local rve_server, plotted with matplotlib.

The curve is checked against `rve_cli element-test` of the same parameter
set and seed: its CSV holds the same values to its printed precision.

    export PYTHONPATH=$PWD/python:$PWD/build/python
    /usr/bin/python3 python/examples/element_test.py [--out-dir DIR] [--strain 0.03]
"""

import argparse
import os
import subprocess
import tempfile

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import rvehub  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out-dir", help="where the PNG and CSVs go (default: a temporary folder)")
    ap.add_argument("--material", default="SET-dense")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--confining", type=float, default=100e3, help="Pa, compression +")
    ap.add_argument("--strain", type=float, default=0.03, help="axial strain to stop at")
    ap.add_argument("--rows", type=int, default=60)
    args = ap.parse_args()
    out_dir = args.out_dir or tempfile.mkdtemp(prefix="rvehub-biaxial-")
    os.makedirs(out_dir, exist_ok=True)
    options = dict(confining=args.confining, strain=args.strain, rows=args.rows)

    with rvehub.local(threads=1) as hub:
        res = hub.element_test("drained-biaxial", material=args.material, seed=args.seed,
                               **options)

    # Columns as rve_cli's CSV, compression positive, strains in [-], stresses in Pa.
    ea, ev = 100 * res["axial_strain"], 100 * res["vol_strain"]
    fig, ax = plt.subplots(1, 3, figsize=(13, 4))
    ax[0].plot(ea, res["syy"] / 1e3, label="σyy")
    ax[0].plot(ea, res["sxx"] / 1e3, label="σxx")
    ax[0].plot(ea, res["q"] / 1e3, label="q")
    ax[0].set(xlabel="axial strain (%)", ylabel="stress (kPa, compression +)",
              title=f"drained biaxial, {res.template}")
    ax[0].legend()
    ax[1].plot(ea, ev)
    ax[1].set(xlabel="axial strain (%)", ylabel="volumetric strain (%, compression +)")
    ax[2].plot(ea, res["void_ratio"])
    ax[2].set(xlabel="axial strain (%)", ylabel="void ratio e")
    fig.tight_layout()
    png = os.path.join(out_dir, "biaxial.png")
    fig.savefig(png, dpi=80)
    plt.close(fig)

    # The same test in rve_cli, in its own process without a server.
    csv = os.path.join(out_dir, "rve_cli.csv")
    subprocess.run([rvehub.find_binary("rve_cli"), "element-test", "--test=drained-biaxial",
                    f"--material={args.material}", f"--seed={args.seed}",
                    f"--confining={args.confining!r}", f"--strain={args.strain!r}",
                    f"--rows={args.rows}", f"--out={csv}"],
                   check=True, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                   stderr=subprocess.DEVNULL)
    ref = rvehub.read_element_test_csv(csv)
    for c in rvehub.ELEMENT_TEST_COLUMNS:
        printed = np.array(["%.10g" % v for v in res[c]], dtype=np.float64)  # rve_cli's %.10g
        np.testing.assert_array_equal(printed, ref[c], err_msg=f"column {c}")
    with open(csv) as f:
        assert f.read() == res.csv_text()

    k = int(np.argmax(res["q"]))
    print(f"{res.rows} rows; peak q = {res['q'][k] / 1e3:.1f} kPa at {ea[k]:.2f} % axial strain, "
          f"p = {res['p'][k] / 1e3:.1f} kPa")
    print(f"equal to rve_cli's CSV ({csv}); plot {png}")


if __name__ == "__main__":
    main()
