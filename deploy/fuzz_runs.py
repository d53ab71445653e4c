#!/usr/bin/env python3
"""Release check: mutated reduced cases that `mpm_client check` accepts are run.

case_fuzz_test's CaseFuzz reads mutated cases and runs the accepted ones 20 steps
with an elastic stand-in for their RVEs; this runs each accepted one for a few
steps with its RVEs on the embedded server (no network), the way a user's typo
would run. Every run must end by
itself: done, or refused with a message. A signal, a sanitizer report or a run
past --timeout is a finding; the script prints each with its mutation and
exits 1 if there was any.

  python3 deploy/fuzz_runs.py --seed=7 --iterations=2000
  python3 deploy/fuzz_runs.py --binary=build-sanitize/mpm_client/mpm_client  # ASan/UBSan

Seeded: the same seed, cases and binary give the same mutations. Each run's
last stderr line goes to WORK/log.txt (refused runs: the reason; a run past
--timeout: the last it printed, a progress line at least once a minute, so a
slow run tells itself from a hung one); findings keep their case file and
stderr in WORK. Its first runs (about 2700 mutated
cases on the release build, several hundred under the sanitizers) found no
crash or hang, but tiny positive fields whose quotients went non-finite, a
water table above the soil and packings squeezed to e < 0: each is now
refused when the case or the RVE is read.
"""
import argparse
import glob
import json
import os
import random
import shutil
import subprocess
import sys
import time

from fuzz_common import ROOT, failure, sanitizer_env

ABSURD = [0, -1, 1, 2147483648.0, 9.3e18, 1e308, -1e308, 1e-308, -0.0, 1e-30, 1e30, 1e6,
          1e-6, "", None, [], {}, [1e308, -1e308], [0, 0, 0], True]
FACTORS = [-1.0, 0.5, 2.0, 10.0, 1e3, 1e-3, 1e6, 1e-6]


def leaves(doc, at=""):
    """JSON pointers of the scalar leaves (descriptions left alone)."""
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from leaves(v, f"{at}/{k}")
    elif isinstance(doc, list):
        for i, v in enumerate(doc):
            yield from leaves(v, f"{at}/{i}")
    elif not at.endswith("description"):
        yield at


def locate(doc, pointer):
    *path, last = pointer.split("/")[1:]
    for p in path:
        doc = doc[int(p)] if isinstance(doc, list) else doc[p]
    return doc, int(last) if isinstance(doc, list) else last


def mutate(doc, rng):
    what = []
    for _ in range(rng.randint(1, 2)):
        pointer = rng.choice(list(leaves(doc)))
        parent, key = locate(doc, pointer)
        x = parent[key]
        if isinstance(x, (int, float)) and not isinstance(x, bool) and rng.random() < 0.5:
            parent[key] = x * rng.choice(FACTORS)
        else:
            parent[key] = rng.choice(ABSURD)
        what.append(f"{pointer}={json.dumps(parent[key])}")
    return what


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--binary", default=os.path.join(ROOT, "build/mpm_client/mpm_client"))
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--iterations", type=int, default=500)
    ap.add_argument("--steps", type=int, default=200, help="steps each accepted case runs")
    ap.add_argument("--timeout", type=float, default=600, help="seconds one run may take")
    ap.add_argument("--work", default=os.path.join(ROOT, "build", "fuzz-runs"),
                    help="scratch directory (default build/fuzz-runs)")
    args = ap.parse_args()

    # fem-*.json are fem_client's cases, not mpm_client's.
    cases = sorted(c for c in glob.glob(os.path.join(ROOT, "cases", "*-ci.json"))
                   if not os.path.basename(c).startswith("fem-"))
    os.makedirs(args.work, exist_ok=True)
    # Cases name reference curves relative to themselves.
    ref = os.path.join(args.work, "reference")
    if not os.path.exists(ref):
        os.symlink(os.path.join(ROOT, "cases", "reference"), ref)
    env = sanitizer_env()
    rng = random.Random(args.seed)
    counts, findings = {}, 0
    with open(os.path.join(args.work, "log.txt"), "w") as log:
        for it in range(args.iterations):
            name = rng.choice(cases)
            with open(name) as f:
                doc = json.load(f)
            what = mutate(doc, rng)
            path = os.path.join(args.work, "case.json")
            with open(path, "w") as f:
                json.dump(doc, f)
            try:
                check = subprocess.run([args.binary, "check", path], capture_output=True,
                                       text=True, env=env, timeout=args.timeout)
            except subprocess.TimeoutExpired:  # reading a case must not hang either
                check = subprocess.CompletedProcess([], None, "", "")
            if check.returncode == 0:
                out = os.path.join(args.work, "out")
                shutil.rmtree(out, ignore_errors=True)
                start = time.time()
                try:
                    r = subprocess.run(
                        [args.binary, "run", path, f"--out={out}", "--threads=1",
                         f"--template-cache={os.path.join(args.work, 'templates')}",
                         f"--stop-after={args.steps}"],
                        capture_output=True, text=True, env=env, timeout=args.timeout)
                    rc, err = r.returncode, r.stderr
                except subprocess.TimeoutExpired as e:
                    # What it printed by then: its notes and progress lines (a
                    # line a minute at least) tell a slow run from a hung one.
                    partial = e.stderr or ""
                    if isinstance(partial, bytes):
                        partial = partial.decode(errors="replace")
                    rc, err = None, partial
                seconds = time.time() - start
            else:
                rc, err, seconds = check.returncode, check.stderr, 0.0
                if rc is not None and rc > 0:  # refused when read: not run
                    counts["not read"] = counts.get("not read", 0) + 1
                    continue
            kind = failure(rc, err) or ("ran" if rc == 0 else "refused")
            counts[kind] = counts.get(kind, 0) + 1
            last = (err.strip().splitlines() or [""])[-1][:300]
            log.write(f"{it} {kind} rc={rc} {seconds:.1f}s {os.path.basename(name)} "
                      f"{what} :: {last}\n")
            log.flush()
            if kind in ("TIMEOUT", "SANITIZER", "SIGNAL"):
                findings += 1
                shutil.copy(path, os.path.join(args.work, f"finding-{it}.json"))
                with open(os.path.join(args.work, f"finding-{it}.txt"), "w") as f:
                    f.write(err)
                print(f"finding: iteration {it}, {kind}, {os.path.basename(name)} {what}")
    print(f"seed {args.seed}, {args.iterations} mutated cases: "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main())
