"""Finding the project's binaries (rve_server, rve_cli) and running rve_cli."""

import os
import re
import subprocess
from typing import List, Optional, Sequence

import grpc

from .errors import RveError

_RELATIVE = {
    "rve_server": os.path.join("rve_server", "server", "rve_server"),
    "rve_cli": os.path.join("rve_server", "cli", "rve_cli"),
}


def repo_root() -> str:
    return os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def find_binary(name: str, path: Optional[str] = None, build_dir: Optional[str] = None) -> str:
    """The path of ``name`` (rve_server or rve_cli).

    Looked for, in order: ``path`` itself; ``build_dir``; the build folder in
    the environment variable RVEHUB_BUILD_DIR; ``build/`` under the
    repository. In a build folder the binary is at its CMake place
    (rve_server/server/rve_server, rve_server/cli/rve_cli) or at its top.
    """
    if path is not None:
        if os.path.isfile(path) and os.access(path, os.X_OK):
            return path
        raise FileNotFoundError(f"{name}: '{path}' is not an executable file")
    dirs: List[str] = []
    if build_dir is not None:
        dirs.append(build_dir)
    if os.environ.get("RVEHUB_BUILD_DIR"):
        dirs.append(os.environ["RVEHUB_BUILD_DIR"])
    dirs.append(os.path.join(repo_root(), "build"))
    tried = []
    for d in dirs:
        for candidate in (os.path.join(d, _RELATIVE[name]), os.path.join(d, name)):
            tried.append(candidate)
            if os.path.isfile(candidate) and os.access(candidate, os.X_OK):
                return candidate
    raise FileNotFoundError(
        f"{name} not found (tried {', '.join(tried)}): build it (`cmake --build build "
        f"--target {name}`), or pass its path or build folder, or set RVEHUB_BUILD_DIR")


_ERROR_LINE = re.compile(r"^rve_cli: ([A-Z_]+): (.*)$", re.S)


def run_cli(cli: str, args: Sequence[str], timeout: Optional[float] = None) -> str:
    """Runs rve_cli and returns its stdout. Exit 1 raises RveError with the
    code rve_cli names; exit 2 (usage) raises ValueError."""
    proc = subprocess.run([cli, *args], stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, timeout=timeout, check=False)
    if proc.returncode == 0:
        return proc.stdout
    last = proc.stderr.strip().splitlines()[-1] if proc.stderr.strip() else ""
    command = f"rve_cli {args[0]}" if args else "rve_cli"
    if proc.returncode == 2:
        raise ValueError(f"{command}: {last.removeprefix('rve_cli: ')}")
    m = _ERROR_LINE.match(last)
    if m and m.group(1) in grpc.StatusCode.__members__:
        raise RveError(grpc.StatusCode[m.group(1)], m.group(2), command)
    raise RveError(grpc.StatusCode.UNKNOWN,
                   f"exit status {proc.returncode}: {proc.stderr.strip()[-2000:]}", command)
