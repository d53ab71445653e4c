#!/usr/bin/env python3
"""A batch of material points spread over several rve_servers.

Starts three servers on 127.0.0.1 (as remote ones would be reached with
rvehub.connect("host:port")), uploads one template file to each, places the
points round-robin, and applies each load step to all servers at once (one
thread per server: the gRPC calls run in parallel). The assembled stresses
are then checked against the same batch on one server: an RVE's result does
not depend on where it is hosted.

    export PYTHONPATH=$PWD/python:$PWD/build/python
    /usr/bin/python3 python/examples/remote.py [--servers 3] [--points 12]
"""

import argparse
import contextlib
import os
import tempfile
from concurrent.futures import ThreadPoolExecutor

import numpy as np

import rvehub


class Spread:
    """One run over several hubs: point k of the batch lives on hub k % n."""

    def __init__(self, hubs, run_id, template, ids, pressure):
        self.parts = []  # (run, positions in the batch)
        for h, hub in enumerate(hubs):
            pos = np.arange(h, len(ids), len(hubs))
            if pos.size:
                run = hub.create_run(run_id, template, ids[pos], pressure=pressure[pos])
                self.parts.append((run, pos))
        self.n = len(ids)
        self.pool = ThreadPoolExecutor(len(self.parts))

    def apply(self, delta_f, **options):
        """ΔF (n, 3, 3) for the whole batch; stress (n, 3, 3) Pa, tension +,
        and per-point codes, in batch order."""
        jobs = [self.pool.submit(run.apply, delta_f[pos], **options) for run, pos in self.parts]
        stress, code = np.empty((self.n, 3, 3)), np.empty(self.n, np.int32)
        for (run, pos), job in zip(self.parts, jobs):
            s = job.result()
            stress[pos], code[pos] = s.stress, s.code
        return stress, code


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--servers", type=int, default=3)
    ap.add_argument("--points", type=int, default=12)
    ap.add_argument("--steps", type=int, default=5)
    ap.add_argument("--out-dir", help="where the template file goes (default: a temporary folder)")
    args = ap.parse_args()
    ids = np.arange(100, 100 + args.points)
    pressure = np.linspace(50e3, 200e3, args.points)  # Pa, compression +
    rng = np.random.default_rng(1)
    path = np.tile(np.eye(3), (args.steps, args.points, 1, 1))
    path[:, :, 1, 1] -= 2e-4  # vertical compression
    path[:, :, 0, 1] += rng.uniform(0, 2e-4, (args.steps, args.points))  # and some shear

    with contextlib.ExitStack() as stack, tempfile.TemporaryDirectory() as tmp:
        hubs = [stack.enter_context(rvehub.local(threads=1)) for _ in range(args.servers)]
        file = os.path.join(args.out_dir or tmp, "template.h5")
        os.makedirs(os.path.dirname(file), exist_ok=True)
        name = rvehub.prepare_template_file(file, "SET-dense", seed=1)  # prepared once
        for hub in hubs:
            hub.upload_template_file(file, replace=True)
        spread = Spread(hubs, "spread", name, ids, pressure)
        for k in range(args.steps):
            stress, code = spread.apply(path[k])
            assert not code.any(), code
        print("server           points  run steps")
        for run, pos in spread.parts:
            print(f"{run.hub.target:16s} {len(pos):6d}  {run.steps.tolist()}")

        single = hubs[0].create_run("single", name, ids, pressure=pressure)
        for k in range(args.steps):
            alone = single.apply(path[k]).check()
        assert np.array_equal(alone.stress, stress), "spread and single-server results differ"
        spread.pool.shutdown()
    q = np.sqrt(0.25 * (stress[:, 0, 0] - stress[:, 1, 1]) ** 2 + stress[:, 0, 1] ** 2)
    print(f"{args.points} points on {args.servers} servers, {args.steps} steps: the same bits "
          f"as on one server; q = {q.min() / 1e3:.1f}..{q.max() / 1e3:.1f} kPa")


if __name__ == "__main__":
    main()
