"""The generated gRPC stubs of proto/rvehub/v1/rve_service.proto.

They are generated at build time (``cmake --build build --target
rvehub_python``) into ``build/python/rvehub_gen`` and never committed. With
that folder on PYTHONPATH they import directly; otherwise the build folders
named by RVEHUB_BUILD_DIR and ``build/`` under the repository are tried.
"""

import os
import sys

try:
    import grpc  # noqa: F401  (imported here to fail early with a clear message)
except ImportError as e:  # pragma: no cover - depends on the machine
    raise ImportError(
        "rvehub needs grpcio (Debian: python3-grpcio); run it with /usr/bin/python3, "
        f"not a Python without Debian's packages ({sys.executable})") from e


def _candidate_dirs():
    env = os.environ.get("RVEHUB_BUILD_DIR")
    if env:
        yield os.path.join(env, "python")
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    yield os.path.join(repo, "build", "python")


def _import_stubs():
    try:
        from rvehub_gen.v1 import rve_service_pb2, rve_service_pb2_grpc
        return rve_service_pb2, rve_service_pb2_grpc
    except ImportError:
        pass
    for d in _candidate_dirs():
        if os.path.isfile(os.path.join(d, "rvehub_gen", "v1", "rve_service_pb2.py")):
            sys.path.append(d)
            from rvehub_gen.v1 import rve_service_pb2, rve_service_pb2_grpc
            return rve_service_pb2, rve_service_pb2_grpc
    raise ImportError(
        "rvehub: the generated stubs (rvehub_gen) are not built: run "
        "`cmake --build build --target rvehub_python` and "
        "`export PYTHONPATH=$PWD/python:$PWD/build/python` in the repository")


pb, pb_grpc = _import_stubs()
