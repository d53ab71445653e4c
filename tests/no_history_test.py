#!/usr/bin/env python3
"""Fails if a tracked text file narrates the project's making.

Files are for users and maintainers: no issue numbers ("issue 11", "#12"), no
session numbers ("session 31") and no commit hashes used as history ("since
dcaa055"). This scans every file git tracks (or, outside a git checkout, every
file under the source tree but build*/ and out/), skipping binaries, and prints
each match as PATH:LINE: TEXT.

  /usr/bin/python3 tests/no_history_test.py [SOURCE_DIR] [--extra=FILE ...]
  /usr/bin/python3 tests/no_history_test.py --self-test

--extra scans more files as if they were tracked. --self-test plants history
lines in a scratch file and checks that each is caught and that the allowed
lines are not. Exit status 0: clean (or the self-test passed); 1: matches found.

Legitimate matches are allowed by the short, explicit list below; keep it short.
"""
import argparse
import fnmatch
import os
import re
import subprocess
import sys

# What history looks like.
PATTERNS = [
    ("issue number", re.compile(r"(?i)\bissues? ?#?[0-9]+\b")),
    ("session number", re.compile(r"(?i)\bsessions? ?#?[0-9]+\b")),
    # "#12" as a reference; not "&#12;" (an HTML entity) nor a quoted colour
    # ("'#336699'", "color: #336699").
    ("#number", re.compile(r"(?<![&\w'\"])(?<!color: )#[0-9]+\b(?![0-9a-fA-F])")),
    # A commit hash: 7-40 hex digits with at least one letter and one digit,
    # a word of its own; not part of a decimal number ("2.604362925e-05"),
    # nor a hex literal ("0x1f2e3d4c").
    ("commit hash", re.compile(
        r"(?<![\w.])(?=[0-9a-f]*[a-f])(?=[0-9a-f]*[0-9])[0-9a-f]{7,40}(?![\w.]|[-+][0-9])")),
]

# Files not scanned, each with its reason.
SKIP_FILES = [
    "tests/no_history_test.py",   # this file: its patterns and examples
    "cases/reference/*.csv",      # published curves: columns of numbers
]

# Lines allowed to match, each a regular expression with its reason.
ALLOW_LINES = [
    # A run record names the commit it ran (the version it was built from).
    re.compile(r'^\s*"(version|commit|git_describe)":\s*"[0-9a-f]{7,40}(-dirty)?",?\s*$'),
    # VALIDATION.md's table rows name the version each recorded run was built from.
    re.compile(r'^\|.*\| version [0-9a-f]{7,40}(-dirty)?[ ,]'),
]


def tracked_files(root):
    try:
        out = subprocess.run(["git", "-C", root, "ls-files", "-z"], check=True,
                             capture_output=True).stdout
        return [p for p in out.decode("utf-8", "replace").split("\0") if p]
    except (OSError, subprocess.CalledProcessError):
        files = []
        for dirpath, dirnames, filenames in os.walk(root):
            rel = os.path.relpath(dirpath, root)
            dirnames[:] = [d for d in dirnames
                           if not (rel == "." and (d.startswith("build") or d == "out"))
                           and d != ".git"]
            files += [os.path.normpath(os.path.join(rel, f)) for f in filenames]
        return files


def skipped(path):
    return any(fnmatch.fnmatch(path, pattern) for pattern in SKIP_FILES)


def text_lines(path):
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError:
        return None
    if b"\0" in data[:8192]:
        return None  # binary (figures, HDF5 files)
    return data.decode("utf-8", "replace").splitlines()


def scan(root, paths):
    found = []
    for rel in paths:
        if skipped(rel):
            continue
        lines = text_lines(os.path.join(root, rel))
        if lines is None:
            continue
        for number, line in enumerate(lines, 1):
            if any(allow.search(line) for allow in ALLOW_LINES):
                continue
            for what, pattern in PATTERNS:
                m = pattern.search(line)
                if m:
                    found.append((rel, number, what, m.group(0), line.strip()))
                    break
    return found


# --self-test: lines that must fail, and lines that must pass.
PLANTED = [
    "The footing reached N_q 14.9 (issue 11).",
    "Measured in session 31 on one worker.",
    "See #12 for the discussion.",
    "Since dcaa055 the reach is the material's.",
    "before Issue #9 the step took 20 DEM steps",
    "commit 303cc6d0a1b2c3d4e5f60718293a4b5c6d7e8f90",
]
CLEAN = [
    "#include <vector>",
    "colour = '#336699'  # and &#160; in HTML; color: #336699",
    "2.604362925e-05,0.008797296265,100275.4897",
    "must lie in 0..9007199254740992 (2^53); mask 0x1f2e3d4c",
    '  "version": "1d8f4d0",',
    "the footing's N_q falls with the mesh (docs/footing-bearing-capacity.md)",
]


def self_test():
    import tempfile
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        for name, lines, want in (("planted.md", PLANTED, len(PLANTED)), ("clean.md", CLEAN, 0)):
            with open(os.path.join(tmp, name), "w", encoding="utf-8") as fh:
                fh.write("\n".join(lines) + "\n")
            found = scan(tmp, [name])
            for rel, number, what, match, line in found:
                print(f"{rel}:{number}: {what} '{match}'")
            if len(found) != want:
                print(f"{name}: {len(found)} match(es), expected {want}", file=sys.stderr)
                ok = False
    print("self-test " + ("passed" if ok else "FAILED"))
    return 0 if ok else 1


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?",
                    default=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    ap.add_argument("--extra", action="append", default=[],
                    help="a further file to scan (absolute, or relative to ROOT)")
    ap.add_argument("--self-test", action="store_true")
    a = ap.parse_args()
    if a.self_test:
        return self_test()
    paths = tracked_files(a.root) + a.extra
    found = scan(a.root, paths)
    for rel, number, what, match, line in found:
        print(f"{rel}:{number}: {what} '{match}': {line[:160]}")
    if found:
        print(f"{len(found)} place(s) narrate the project's history: say what the product "
              "does instead (allow-list: tests/no_history_test.py)", file=sys.stderr)
        return 1
    print(f"no history in {len(paths)} files")
    return 0


if __name__ == "__main__":
    sys.exit(main())
