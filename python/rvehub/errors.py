"""Errors of the rvehub package."""

from typing import Optional, Sequence

import grpc


def status_code(number: int) -> grpc.StatusCode:
    """The grpc.StatusCode of a google.rpc.Code number (per-RVE ``code``)."""
    for c in grpc.StatusCode:
        if c.value[0] == number:
            return c
    return grpc.StatusCode.UNKNOWN


class RveError(Exception):
    """A call the server refused or that failed on the way.

    ``code`` is the grpc.StatusCode (``code.name`` is e.g. "NOT_FOUND"),
    ``message`` the server's message, ``rpc`` the call (e.g. "Apply") and
    ``target`` the server's address. For a batch whose RVEs failed one by one
    (``States.check()``), ``ids`` are the failed material points and ``code``
    and ``message`` those of the first of them.
    """

    def __init__(self, code: grpc.StatusCode, message: str, rpc: str = "", target: str = "",
                 ids: Optional[Sequence[int]] = None):
        self.code = code
        self.message = message
        self.rpc = rpc
        self.target = target
        self.ids = list(ids) if ids is not None else []
        where = ""
        if rpc and target:
            where = f" ({rpc} on {target})"
        elif rpc or target:
            where = f" ({rpc or target})"
        super().__init__(f"{code.name}: {message}{where}")

    @classmethod
    def from_rpc(cls, error: grpc.RpcError, rpc: str, target: str) -> "RveError":
        code = error.code() if hasattr(error, "code") else grpc.StatusCode.UNKNOWN
        details = error.details() if hasattr(error, "details") else str(error)
        return cls(code or grpc.StatusCode.UNKNOWN, details or "", rpc, target)
