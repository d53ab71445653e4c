"""rvehub: a Python client of RVEHub's RVE service (rvehub.v1.RveService).

    import numpy as np, rvehub
    with rvehub.local(threads=1) as hub:              # an rve_server on 127.0.0.1
        t = hub.prepare_template("SET-dense", seed=1)  # rve_cli prepare + upload
        run = hub.create_run("demo", t.name, ids=[0, 1], pressure=100e3)
        dF = np.tile(np.eye(3), (2, 1, 1)); dF[:, 1, 1] -= 1e-4  # compress y
        s = run.apply(dF, mode="trial", tangent=True)  # nothing changes
        s = run.apply(dF, mode="commit")               # step 1
        print(s.stress[:, 1, 1])                       # Pa, tension +

Conventions are the proto's: Cauchy stress in Pa, TENSION POSITIVE;
"pressure"/"compression" values compression positive; tensors (n, 3, 3) in
x, y, z; 2-D RVEs in plane strain; SI units. Element-test columns are
compression positive, as rve_cli writes them.
"""

from typing import Optional

from .errors import RveError, status_code
from .hub import (Hub, LocalHub, Run, check_delta_f, prepare_template_file, template_name)
from .types import (ELEMENT_TEST_COLUMNS, Controls, ElementTestResult, Material, Packing, Record,
                    RunInfo, ServerInfo, States, TemplateInfo, read_element_test_csv)
from ._binaries import find_binary

__all__ = [
    "connect", "local", "Hub", "LocalHub", "Run", "RveError", "States", "Record", "Packing",
    "Material", "Controls", "ServerInfo", "TemplateInfo", "RunInfo", "ElementTestResult",
    "ELEMENT_TEST_COLUMNS", "read_element_test_csv", "prepare_template_file", "template_name",
    "find_binary", "check_delta_f", "status_code",
]


def connect(target: str, *, token: Optional[str] = None,
            root_certificates: Optional[bytes] = None, timeout: Optional[float] = 600.0,
            build_dir: Optional[str] = None) -> Hub:
    """A Hub on the rve_server at ``target`` ("HOST:PORT"). ``token``: the
    bearer token of a server started with --auth_token_file;
    ``root_certificates``: PEM CA bytes for a TLS server (else plaintext);
    ``timeout``: each call's deadline, s (None: none); ``build_dir``: where
    rve_cli is found for prepare_template (else RVEHUB_BUILD_DIR, build/)."""
    return Hub(target, token=token, root_certificates=root_certificates, timeout=timeout,
               build_dir=build_dir)


def local(*, server: Optional[str] = None, build_dir: Optional[str] = None, threads: int = 0,
          token: Optional[str] = None, extra_args=(), timeout: Optional[float] = 600.0,
          start_timeout: float = 60.0) -> LocalHub:
    """Starts an rve_server on 127.0.0.1 with a free port and returns a Hub on
    it, which stops it on close(), at the end of a ``with`` block or at exit.
    The binary: ``server``, else found in ``build_dir``, RVEHUB_BUILD_DIR or
    build/ under the repository. ``threads``: its worker threads (0: all
    cores); ``extra_args``: more rve_server flags (e.g. "--max_batch=10")."""
    return LocalHub(server=server, build_dir=build_dir, threads=threads, token=token,
                    extra_args=extra_args, timeout=timeout, start_timeout=start_timeout)
