#!/usr/bin/env python3
"""Digests of what a build writes, to show that a change leaves every output bit-identical.

  python3 bench/output_digests.py --build=build --work=/tmp/digests-new [--jobs=2]
  python3 bench/output_digests.py --compare OLD.json NEW.json
  python3 bench/output_digests.py --rehash WORK   (digests.json again from WORK's outputs)

The first form runs, with the build's binaries:
  - every reduced MPM case (cases/*-ci.json but fem-*) and the default case, single-element-biaxial;
  - the default case stopped after 40 steps and resumed from its checkpoint;
  - the element tests of cases/element_tests.sh;
and writes WORK/digests.json: for each run, a SHA-256 of timeseries.csv, of every dataset
of results.h5 and checkpoint.h5 (values and shape, not the file's bytes: those carry
creation times; without the run ids, which carry the start time; timeseries.csv without
its wall time per step), of summary.json without its timing fields, and of each element-test CSV.
The second form compares two such files and exits 1 when anything differs.

Needs numpy and h5py (Debian: python3-numpy python3-h5py).
"""
import argparse
import concurrent.futures
import glob
import hashlib
import json
import os
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# cases/element_tests.sh's tests (name, rve_cli options).
ELEMENT_TESTS = [
    ("biaxial_spfem", ["--test=drained-biaxial", "--material=SPFEM-biaxial",
                       "--confining=100000", "--strain=0.1"]),
    ("oedometer_consolidation", ["--test=oedometer", "--material=consolidation",
                                 "--strain=0.002"]),
    ("isotropic_set_dense", ["--test=isotropic", "--material=SET-dense", "--strain=0.01"]),
    ("undrained_shear_loose", ["--test=undrained-simple-shear", "--material=cyclic-loose",
                               "--strain=0.1"]),
    ("cyclic_strain_loose", ["--test=cyclic-simple-shear", "--material=cyclic-loose",
                             "--cyclic-control=strain", "--amplitude=0.002", "--cycles=5",
                             "--strain=0.2"]),
    ("cyclic_stress_loose", ["--test=cyclic-simple-shear", "--material=cyclic-loose-stress",
                             "--cyclic-control=stress", "--amplitude=15000", "--cycles=10",
                             "--strain=0.1"]),
]

# summary.json fields that measure the machine, not the run.
TIMING_KEYS = ("wall", "seconds", "time_split", "elapsed", "host", "started", "ended")


def sha(data):
    return hashlib.sha256(data).hexdigest()


def file_digest(path):
    with open(path, "rb") as f:
        return sha(f.read())


def h5_digests(path):
    import h5py
    import numpy as np
    out = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Dataset) and name.split("/")[-1] not in RUN_ID_DATASETS:
            value = obj[()]
            arr = np.asarray(value)
            if arr.dtype.kind in "OSU":
                blob = repr(arr.tolist()).encode()
            else:
                blob = np.ascontiguousarray(arr).tobytes()
            out[name] = sha(blob + repr((arr.shape, str(arr.dtype))).encode())

    # Walked by name rather than visititems, which skips external links
    # (results.h5 links its frames, each a file of its own).
    def walk(group, prefix):
        for key in group:
            obj = group[key]
            name = prefix + key
            if isinstance(obj, h5py.Group):
                walk(obj, name + "/")
            else:
                visit(name, obj)

    with h5py.File(path, "r") as f:
        walk(f, "")
    return out


def strip_timing(value):
    if isinstance(value, dict):
        return {k: strip_timing(v) for k, v in value.items()
                if not any(t in k for t in TIMING_KEYS)}
    if isinstance(value, list):
        return [strip_timing(v) for v in value]
    return value


# What differs between two runs of the same build: the wall time per step and
# the run id (case name and start time) its RVEs are hosted under.
WALL_COLUMNS = ("wall_per_step_s",)
RUN_ID_DATASETS = ("run_id",)


def timeseries_digest(path):
    """The CSV without its wall-time columns."""
    with open(path) as f:
        rows = [line.rstrip("\n").split(",") for line in f]
    keep = [k for k, name in enumerate(rows[0]) if name not in WALL_COLUMNS] if rows else []
    return sha("\n".join(",".join(r[k] for k in keep if k < len(r)) for r in rows).encode())


def run_digests(out_dir):
    d = {}
    ts = os.path.join(out_dir, "timeseries.csv")
    if os.path.exists(ts):
        d["timeseries.csv"] = timeseries_digest(ts)
    for name in ("results.h5", "checkpoint.h5"):
        path = os.path.join(out_dir, name)
        if os.path.exists(path):
            for key, value in h5_digests(path).items():
                d[f"{name}:{key}"] = value
    summary = os.path.join(out_dir, "summary.json")
    if os.path.exists(summary):
        with open(summary) as f:
            d["summary.json"] = sha(json.dumps(strip_timing(json.load(f)),
                                               sort_keys=True).encode())
    return d


def run(cmd, log):
    with open(log, "w") as f:
        r = subprocess.run(cmd, cwd=ROOT, stdout=f, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} failed ({r.returncode}); see {log}")


def mpm_case(build, work, cache, case):
    name = os.path.splitext(os.path.basename(case))[0]
    out = os.path.join(work, name)
    run([os.path.join(build, "mpm_client", "mpm_client"), "run", case, f"--out={out}",
         f"--template-cache={cache}", "--threads=1"], out + ".log")
    return name, run_digests(out)


def resumed(build, work, cache):
    out = os.path.join(work, "single-element-biaxial-resumed")
    binary = os.path.join(build, "mpm_client", "mpm_client")
    run([binary, "run", "cases/single-element-biaxial.json", f"--out={out}",
         f"--template-cache={cache}", "--threads=1", "--stop-after=40"], out + ".1.log")
    run([binary, "resume", os.path.join(out, "checkpoint.h5"), "--threads=1"], out + ".2.log")
    return "single-element-biaxial-resumed", run_digests(out)


def element_test(build, work, name, args):
    out = os.path.join(work, "element-tests", name + ".csv")
    run([os.path.join(build, "rve_server", "cli", "rve_cli"), "element-test", *args,
         f"--out={out}"], out + ".log")
    return "element-test " + name, {"csv": file_digest(out)}


def collect(args):
    build = os.path.abspath(args.build)
    work = os.path.abspath(args.work)
    cache = os.path.join(work, "templates")
    os.makedirs(os.path.join(work, "element-tests"), exist_ok=True)
    # Templates are prepared once, before the cases that share them run in parallel.
    mpm_case(build, work, cache, "cases/single-element-biaxial.json")
    # fem-*.json are fem_client's cases, not mpm_client's.
    cases = sorted(c for c in glob.glob(os.path.join(ROOT, "cases", "*-ci.json"))
                   if not os.path.basename(c).startswith("fem-"))
    cases.append(os.path.join(ROOT, "cases", "single-element-biaxial.json"))
    jobs = []
    with concurrent.futures.ThreadPoolExecutor(max_workers=args.jobs) as pool:
        for case in cases:
            jobs.append(pool.submit(mpm_case, build, work, cache, os.path.relpath(case, ROOT)))
        jobs.append(pool.submit(resumed, build, work, cache))
        for name, opts in ELEMENT_TESTS:
            jobs.append(pool.submit(element_test, build, work, name, opts))
        digests = dict(job.result() for job in jobs)
    path = os.path.join(work, "digests.json")
    with open(path, "w") as f:
        json.dump(digests, f, indent=1, sort_keys=True)
    print(f"{sum(len(v) for v in digests.values())} digests of {len(digests)} runs: {path}")


def rehash(work):
    digests = {}
    for name in sorted(os.listdir(work)):
        path = os.path.join(work, name)
        if name == "element-tests":
            for csv in sorted(glob.glob(os.path.join(path, "*.csv"))):
                test = os.path.splitext(os.path.basename(csv))[0]
                digests["element-test " + test] = {"csv": file_digest(csv)}
        elif os.path.isdir(path) and name != "templates":
            digests[name] = run_digests(path)
    with open(os.path.join(work, "digests.json"), "w") as f:
        json.dump(digests, f, indent=1, sort_keys=True)
    print(f"{sum(len(v) for v in digests.values())} digests of {len(digests)} runs")


def compare(old_path, new_path):
    with open(old_path) as f:
        old = json.load(f)
    with open(new_path) as f:
        new = json.load(f)
    differ = 0
    for run_name in sorted(set(old) | set(new)):
        a, b = old.get(run_name), new.get(run_name)
        if a is None or b is None:
            print(f"{run_name}: only in {'new' if a is None else 'old'}")
            differ += 1
            continue
        for key in sorted(set(a) | set(b)):
            if a.get(key) != b.get(key):
                print(f"{run_name}: {key} differs")
                differ += 1
    total = sum(len(v) for v in old.values())
    print(f"{differ} of {total} digests differ" if differ else f"all {total} digests identical")
    return 1 if differ else 0


def main():
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--build", default="build")
    p.add_argument("--work")
    p.add_argument("--jobs", type=int, default=2)
    p.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"))
    p.add_argument("--rehash", metavar="WORK")
    args = p.parse_args()
    if args.compare:
        return compare(*args.compare)
    if args.rehash:
        rehash(args.rehash)
        return 0
    if not args.work:
        p.error("--work is needed to collect digests")
    collect(args)
    return 0


if __name__ == "__main__":
    sys.exit(main())
