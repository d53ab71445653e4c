#!/usr/bin/env python3
"""Runs one pytest file or example for CTest (python/CMakeLists.txt).

    run_ctest.py --pytest FILE
    run_ctest.py --example FILE [--needs MODULE ...] [ARGS...]

Exits 77 (CTest's SKIP_RETURN_CODE here), saying why, when a Python
dependency is missing or the stubs could not be generated; otherwise the
test's own exit status.
"""

import importlib
import os
import runpy
import sys

DEBIAN = {"numpy": "python3-numpy", "grpc": "python3-grpcio", "pytest": "python3-pytest",
          "matplotlib": "python3-matplotlib", "grpc_tools": "python3-grpc-tools"}


def skip(reason: str) -> None:
    print(f"SKIPPED: {reason}", flush=True)
    sys.exit(77)


def main() -> int:
    argv = sys.argv[1:]
    if len(argv) < 2 or argv[0] not in ("--pytest", "--example"):
        print(__doc__, file=sys.stderr)
        return 2
    kind, path, rest = argv[0], argv[1], argv[2:]
    needs = ["numpy", "grpc"] + (["pytest"] if kind == "--pytest" else [])
    while len(rest) >= 2 and rest[0] == "--needs":
        needs.append(rest[1])
        rest = rest[2:]
    if os.environ.get("RVEHUB_SKIP_REASON"):
        skip(os.environ["RVEHUB_SKIP_REASON"])
    for module in needs:
        try:
            importlib.import_module(module)
        except ImportError:
            skip(f"{sys.executable} has no module {module} (Debian: {DEBIAN.get(module, module)}; "
                 "deploy/install_deps.sh installs it)")
    try:
        importlib.import_module("rvehub_gen.v1.rve_service_pb2")
    except ImportError as e:
        skip(f"the generated stubs do not import ({e}): build the rvehub_python target")
    if kind == "--pytest":
        import pytest
        return int(pytest.main(["-q", "-p", "no:cacheprovider", "-rs", path, *rest]))
    sys.argv = [path, *rest]
    runpy.run_path(path, run_name="__main__")
    return 0


if __name__ == "__main__":
    sys.exit(main())
