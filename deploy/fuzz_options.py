#!/usr/bin/env python3
"""Release check: the binaries' options set to absurd values.

Each option of mpm_client (run and resume), rve_server and rve_cli's
element-test is given numbers out of range, non-numbers, empty and very long
values, and paths that are directories, devices or too long. Every call must
end by itself with exit 0, 1 or 2, a message on stderr when not 0; a server
that starts must stop on SIGTERM the same way. A signal, a sanitizer report,
a call past --timeout or a failure without a message is a finding; the
script prints each and exits 1 if there was any.

  python3 deploy/fuzz_options.py
  python3 deploy/fuzz_options.py --build=build-sanitize   # ASan/UBSan

Servers listen and clients dial on 127.0.0.1 only. Everything is written
under --work (default build/fuzz-options), which is also the working
directory, so values taken for relative paths land there. Its first sweeps
found mpm_client and rve_server aborting on a directory given as a token or
certificate file and on a --template-cache or --checkpoint-dir name too long
for the system, reading /dev/zero until the memory was gone, rve_server
aborting on --threads=100000, and ports past 65535 read modulo 65536; each
is now refused with its reason.
"""
import argparse
import os
import shutil
import signal
import subprocess
import sys

from fuzz_common import ROOT, failure, sanitizer_env

LONG = "x" * 5000
NUMBERS = ["", "0", "-1", "1", "2.5", "-0", "1e308", "-1e308", "1e-308", "nan", "inf", "-inf",
           "99999999999999999999", "2147483648", "0x10", " 5", "abc", "1,2", "=", LONG]
# A directory (made under --work), devices, a path that cannot exist, one too long, one
# missing; relative paths land in --work.
PATHS = ["a-directory", "/dev/zero", "/dev/null", "/proc/nonexistent/x", LONG, "missing"]


class Sweep:
    def __init__(self, args):
        self.args = args
        self.findings = []
        self.calls = 0
        self.env = sanitizer_env()

    def judge(self, argv, rc, err, started=False):
        self.calls += 1
        last = (err.strip().splitlines() or [""])[-1][:200]
        shown = " ".join(a if len(a) < 60 else a[:20] + f"...({len(a)})" for a in argv[1:])
        kind = failure(rc, err) or ""
        if not kind and (rc not in (0, 1, 2) or (rc != 0 and not last)):
            kind = "NO MESSAGE" if rc in (1, 2) else f"EXIT {rc}"
        line = f"{'started, ' if started else ''}rc={rc} {os.path.basename(argv[0])} {shown} :: {last}"
        self.log.write(line + "\n")
        if kind:
            self.findings.append(f"{kind}: {line}")
            print(f"finding: {kind}: {line}", flush=True)

    def call(self, argv):
        try:
            r = subprocess.run(argv, capture_output=True, text=True, errors="replace",
                               env=self.env, timeout=self.args.timeout,
                               cwd=self.args.work)
            self.judge(argv, r.returncode, r.stderr)
        except subprocess.TimeoutExpired:
            self.judge(argv, None, "")

    def server(self, argv):
        """Starts rve_server; one still running after 3 s must stop on SIGTERM (exit 0, or 1
        with its reason, e.g. a checkpoint it could not write)."""
        p = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                             errors="replace", env=self.env, cwd=self.args.work)
        try:
            _, err = p.communicate(timeout=3)
            self.judge(argv, p.returncode, err)
            return
        except subprocess.TimeoutExpired:
            pass
        p.send_signal(signal.SIGTERM)
        try:
            _, err = p.communicate(timeout=60)
            rc = p.returncode
            self.judge(argv, rc, err, started=True)
        except subprocess.TimeoutExpired:
            p.kill()
            p.communicate()
            self.judge(argv, None, "", started=True)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--build", default=os.path.join(ROOT, "build"), help="build directory")
    ap.add_argument("--timeout", type=float, default=300, help="seconds one call may take")
    ap.add_argument("--work", default=os.path.join(ROOT, "build", "fuzz-options"),
                    help="scratch and working directory (default build/fuzz-options)")
    args = ap.parse_args()
    # The calls run in --work: relative paths given here are the caller's.
    args.build, args.work = os.path.abspath(args.build), os.path.abspath(args.work)
    client = os.path.join(args.build, "mpm_client/mpm_client")
    server = os.path.join(args.build, "rve_server/server/rve_server")
    cli = os.path.join(args.build, "rve_server/cli/rve_cli")
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(os.path.join(args.work, "a-directory"))
    case = os.path.join(ROOT, "cases", "footing-soft-ci.json")
    cache = os.path.join(args.work, "templates")
    out = os.path.join(args.work, "out")
    s = Sweep(args)
    with open(os.path.join(args.work, "log.txt"), "w") as s.log:
        # A checkpoint to resume from, and the template cache every run shares.
        base = os.path.join(args.work, "base")
        s.call([client, "run", case, f"--out={base}", f"--template-cache={cache}",
                "--stop-after=20", "--quiet"])
        run = [client, "run", case, f"--out={out}", "--quiet", "--stop-after=5"]
        for option in ["--threads", "--timeout", "--min-timeout", "--stop-after"]:
            for v in NUMBERS:
                s.call(run + [f"--template-cache={cache}", f"{option}={v}"])
        for option in ["--token-file", "--tls-ca", "--template-cache"]:
            for v in PATHS + NUMBERS[:4]:
                extra = [] if option == "--template-cache" else [f"--template-cache={cache}"]
                s.call(run + extra + [f"{option}={v}"])
        for v in ["", ":", ",", "127.0.0.1:", "127.0.0.1:0", "127.0.0.1:1", "127.0.0.1:70000",
                  "127.0.0.1:-1", "[::1]:1", "127.0.0.1:1" + ",127.0.0.1:2" * 300]:
            s.call(run + [f"--template-cache={cache}", "--timeout=5", "--min-timeout=2",
                          f"--servers={v}"])
        for v in ["", "/proc/nonexistent/x", case, "/dev/null", LONG]:
            s.call([client, "run", case, f"--out={v}", "--quiet", f"--template-cache={cache}",
                    "--stop-after=5"])
        for option in ["--end-time", "--cfl", "--f-bar", "--nonlocal-radius",
                       "--nonlocal-fraction"]:
            for v in NUMBERS + ["none", "nodal"]:
                res = os.path.join(args.work, "resumed")
                shutil.rmtree(res, ignore_errors=True)
                shutil.copytree(base, res)
                s.call([client, "resume", os.path.join(res, "checkpoint.h5"), "--quiet",
                        f"--template-cache={cache}", "--stop-after=5", f"{option}={v}"])
        for v in PATHS:
            s.call([client, "check", v])
            s.call([client, "resume", v])

        listen = "--listen=127.0.0.1:0"
        for flag in ["--threads", "--max-rves", "--max-memory-mb", "--max-batch",
                     "--max-message-mb", "--drain-seconds", "--health-without-token"]:
            for v in NUMBERS + ["9223372036854775807"]:
                s.server([server, listen, "--drain-seconds=2", f"{flag}={v}"])
        for flag in ["--auth-token-file", "--checkpoint-dir", "--tls-cert"]:
            for v in PATHS:
                extra = ["--tls-key=/tmp"] if flag == "--tls-cert" else []
                s.server([server, listen, "--drain-seconds=2", f"{flag}={v}"] + extra)
        for v in ["", ":", "127.0.0.1:", "127.0.0.1:70000", "127.0.0.1:-1", "127.0.0.1:abc",
                  "[::1]:0", "127.0.0.1:0:0", LONG]:
            s.server([server, f"--listen={v}", "--drain-seconds=2"])

        # Element tests on a small packing, cut short, each option absurd.
        test = [cli, "element-test", "--particles=50", "--strain=0.002", "--rows=20"]
        for option in ["--confining", "--strain", "--rows", "--inertial-number", "--pressure",
                       "--void-ratio", "--particles", "--seed", "--rolling-eta", "--amplitude",
                       "--cycles"]:
            for v in NUMBERS:
                kind = ["--test=cyclic-simple-shear"] if option in ("--amplitude",
                                                                    "--cycles") else []
                s.call(test + kind + [f"--out={os.path.join(args.work, 'e.csv')}",
                                      f"{option}={v}"])
        for v in PATHS:
            s.call(test + [f"--out={v}"])
            s.call(test + [f"--out={os.path.join(args.work, 'e.csv')}", f"--plot={v}"])
            s.call([cli, "prepare", "--particles=50", f"--out={v}"])
            s.call([cli, "info", "--server=127.0.0.1:1", f"--token-file={v}"])
    print(f"{s.calls} calls, {len(s.findings)} findings (log: {args.work}/log.txt)")
    return 1 if s.findings else 0


if __name__ == "__main__":
    sys.exit(main())
