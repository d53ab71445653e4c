"""Hub (one rve_server), Run (a run's RVEs on it) and local servers."""

from __future__ import annotations

import math
import os
import re
import select
import signal
import subprocess
import tempfile
import time
import weakref
from typing import Callable, Dict, Iterable, List, Optional, Sequence, Union

import grpc
import numpy as np

from . import _binaries
from ._proto import pb, pb_grpc
from .errors import RveError
from .types import (Controls, ElementTestResult, Packing, Record, RunInfo, ServerInfo, States,
                    TemplateInfo, _from_message)

ArrayLike = Union[np.ndarray, Sequence]

_NAME = re.compile(r"^[A-Za-z0-9._-]{1,128}$")

# Headroom below the message limit for framing in an Import chunk, bytes (as
# the C++ client keeps), and the bytes of a record's tag and length prefix.
_CHUNK_OVERHEAD = 64 << 10
_FRAMING = 16

_TESTS = {
    "drained-biaxial": pb.ELEMENT_TEST_DRAINED_BIAXIAL,
    "isotropic": pb.ELEMENT_TEST_ISOTROPIC,
    "oedometer": pb.ELEMENT_TEST_OEDOMETER,
    "undrained-simple-shear": pb.ELEMENT_TEST_UNDRAINED_SIMPLE_SHEAR,
    "cyclic-simple-shear": pb.ELEMENT_TEST_CYCLIC_SIMPLE_SHEAR,
}
_AXES = {"x": pb.LOADING_AXIS_X, "y": pb.LOADING_AXIS_Y, "z": pb.LOADING_AXIS_Z}


def check_name(what: str, name: str) -> str:
    """A run id or template name: [A-Za-z0-9._-]{1,128} (ValueError else)."""
    if not isinstance(name, str) or not _NAME.match(name):
        raise ValueError(f"{what} must match [A-Za-z0-9._-]{{1,128}}, got {name!r}")
    return name


def _ids_array(ids: ArrayLike, what: str = "ids") -> np.ndarray:
    a = np.asarray(ids)
    if a.ndim == 0:
        a = a.reshape(1)
    if a.ndim != 1:
        raise ValueError(f"{what} must be a 1-D sequence of integers, got shape {a.shape}")
    if a.size and not (np.issubdtype(a.dtype, np.integer) or
                       (np.issubdtype(a.dtype, np.floating) and np.all(a == np.round(a)))):
        raise ValueError(f"{what} must be integers, got dtype {a.dtype}")
    a = a.astype(np.int64)
    uniq, counts = np.unique(a, return_counts=True)
    if np.any(counts > 1):
        raise ValueError(f"{what} must be distinct; repeated: {uniq[counts > 1][:10].tolist()}")
    return a


def _finite_scalar(what: str, v) -> float:
    try:
        x = float(v)
    except (TypeError, ValueError):
        raise TypeError(f"{what} must be a number, got {v!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"{what} must be finite, got {x}")
    return x


def _per_point(what: str, v, n: int) -> np.ndarray:
    a = np.asarray(v, dtype=np.float64)
    if a.ndim == 0:
        a = np.full(n, float(a))
    if a.shape != (n,):
        raise ValueError(f"{what} must be a number or have shape ({n},), got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ValueError(f"{what} must be finite (index {int(np.flatnonzero(~np.isfinite(a))[0])})")
    return a


def check_delta_f(delta_f: ArrayLike, ids: np.ndarray) -> np.ndarray:
    """ΔF as an (n, 3, 3) float64 array, checked as the server does: finite,
    plane strain (z row and column those of the identity, within 1e-12) and
    det > 0. A (3, 3) ΔF applies to every point."""
    n = len(ids)
    try:
        f = np.asarray(delta_f, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise TypeError(f"delta_f must be an array of numbers: {e}") from None
    if f.shape == (3, 3):
        f = np.broadcast_to(f, (n, 3, 3))
    if f.shape != (n, 3, 3):
        raise ValueError(f"delta_f must have shape ({n}, 3, 3) (one 3×3 ΔF per id) or (3, 3), "
                         f"got {f.shape}")
    bad = ~np.all(np.isfinite(f), axis=(1, 2))
    if np.any(bad):
        k = int(np.flatnonzero(bad)[0])
        raise ValueError(f"delta_f[{k}] (id {int(ids[k])}) is not finite: {f[k].tolist()}")
    tol = 1e-12
    plane = ((np.abs(f[:, 2, 2] - 1) <= tol) & (np.abs(f[:, 0, 2]) <= tol) &
             (np.abs(f[:, 1, 2]) <= tol) & (np.abs(f[:, 2, 0]) <= tol) & (np.abs(f[:, 2, 1]) <= tol))
    if not np.all(plane):
        k = int(np.flatnonzero(~plane)[0])
        raise ValueError(f"delta_f[{k}] (id {int(ids[k])}) is not plane strain: ΔF_zz must be 1 "
                         "and ΔF_xz, ΔF_yz, ΔF_zx, ΔF_zy 0 (2-D RVEs)")
    det = f[:, 0, 0] * f[:, 1, 1] - f[:, 0, 1] * f[:, 1, 0]
    if not np.all(det > 0):
        k = int(np.flatnonzero(~(det > 0))[0])
        raise ValueError(f"delta_f[{k}] (id {int(ids[k])}): det ΔF = {det[k]} must be > 0")
    return f


def template_name(material: str = "SET-dense", seed: int = 1, *, pressure: Optional[float] = None,
                  void_ratio: Optional[float] = None, particles: Optional[int] = None,
                  rolling_eta: Optional[float] = None) -> str:
    """The template name ``rve_cli prepare`` gives these options by default:
    MATERIAL-seedN with -pPPa, -eE, -Mdiscs and -etaH added."""
    name = f"{material}-seed{int(seed)}"
    if pressure is not None and pressure > 0:
        name += "-p%.6gPa" % pressure
    if void_ratio is not None and void_ratio > 0:
        name += "-e%.6g" % void_ratio
    if particles is not None and particles > 0:
        name += f"-{int(particles)}discs"
    if rolling_eta is not None:
        name += "-eta%.6g" % rolling_eta
    return name.replace("+", "")


def _variant_args(pressure, void_ratio, particles, rolling_eta) -> List[str]:
    args = []
    if pressure is not None:
        args.append("--pressure=%r" % _finite_scalar("pressure", pressure))
    if void_ratio is not None:
        args.append("--void-ratio=%r" % _finite_scalar("void_ratio", void_ratio))
    if particles is not None:
        args.append(f"--particles={int(particles)}")
    if rolling_eta is not None:
        args.append("--rolling-eta=%r" % _finite_scalar("rolling_eta", rolling_eta))
    return args


def prepare_template_file(path: str, material: str = "SET-dense", seed: int = 1, *,
                          pressure: Optional[float] = None, void_ratio: Optional[float] = None,
                          particles: Optional[int] = None, rolling_eta: Optional[float] = None,
                          name: Optional[str] = None, cli: Optional[str] = None,
                          build_dir: Optional[str] = None, timeout: Optional[float] = 3600) -> str:
    """Prepares a packing of parameter set ``material`` with ``seed`` (as
    ``rve_cli prepare``) into the template file ``path`` (HDF5); returns the
    template's name (``name``, or rve_cli's default, see template_name).
    ``pressure`` Pa (compression +), ``void_ratio``, ``particles`` and
    ``rolling_eta`` are rve_cli's variant options. The packing is prepared in
    this process's rve_cli, not on a server."""
    cli = _binaries.find_binary("rve_cli", cli, build_dir)
    args = ["prepare", f"--material={material}", f"--seed={int(seed)}", f"--out={path}"]
    args += _variant_args(pressure, void_ratio, particles, rolling_eta)
    if name is not None:
        args.append(f"--name={check_name('name', name)}")
    out = _binaries.run_cli(cli, args, timeout)
    for line in out.splitlines():
        if line.startswith("template "):
            return line[len("template "):].strip()
    raise RuntimeError(f"rve_cli prepare printed no template name:\n{out}")


class Hub:
    """A connection to one rve_server (``rvehub.connect``, ``rvehub.local``).

    Every call has a deadline of ``timeout`` seconds (None: none). A call the
    server refuses raises RveError (``.code``, the server's ``.message``);
    such a call changes nothing on the server. Per-point failures of a batch
    are reported per point (``States.code``), not raised.
    """

    def __init__(self, target: str, *, token: Optional[str] = None,
                 root_certificates: Optional[bytes] = None, timeout: Optional[float] = 600.0,
                 build_dir: Optional[str] = None, cli: Optional[str] = None):
        if not isinstance(target, str) or not target:
            raise ValueError(f"target must be 'HOST:PORT', got {target!r}")
        self.target = target
        self.timeout = timeout
        self._token = token
        self._root_certificates = root_certificates
        self._build_dir = build_dir
        self._cli = cli
        self._metadata = (("authorization", f"Bearer {token}"),) if token else ()
        options = [("grpc.max_receive_message_length", -1), ("grpc.max_send_message_length", -1)]
        if root_certificates is not None:
            creds = grpc.ssl_channel_credentials(root_certificates=root_certificates)
            self._channel = grpc.secure_channel(target, creds, options)
        else:
            self._channel = grpc.insecure_channel(target, options)
        self._stub = pb_grpc.RveServiceStub(self._channel)
        self._max_message_bytes: Optional[int] = None
        self._closed = False

    # -- plumbing -------------------------------------------------------------

    def _check_open(self) -> None:
        if self._closed:
            raise RuntimeError(f"{self!r} is closed")

    def _call(self, rpc: str, request, timeout: Optional[float] = None):
        self._check_open()
        method = getattr(self._stub, rpc)
        try:
            return method(request, timeout=timeout if timeout is not None else self.timeout,
                          metadata=self._metadata)
        except grpc.RpcError as e:
            raise RveError.from_rpc(e, rpc, self.target) from None

    def _stream(self, rpc: str, request, timeout: Optional[float] = None):
        self._check_open()
        method = getattr(self._stub, rpc)
        call = method(request, timeout=timeout if timeout is not None else self.timeout,
                      metadata=self._metadata)
        try:
            yield from call
        except grpc.RpcError as e:
            raise RveError.from_rpc(e, rpc, self.target) from None
        finally:
            call.cancel()

    def close(self) -> None:
        """Closes the connection (a local server is also stopped); later calls
        raise RuntimeError."""
        self._closed = True
        self._channel.close()

    def __enter__(self) -> "Hub":
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({getattr(self, 'target', '')!r})"

    # -- server ---------------------------------------------------------------

    def info(self) -> ServerInfo:
        """The server's version, load and limits."""
        info = _from_message(ServerInfo, self._call("GetServerInfo", pb.ServerInfoRequest()))
        self._max_message_bytes = info.max_message_bytes
        return info

    def templates(self) -> List[TemplateInfo]:
        """The templates the server hosts, by name (every page of its listing)."""
        return [_from_message(TemplateInfo, t)
                for t in self._pages("ListTemplates", pb.ListTemplatesRequest, "templates")]

    def runs(self) -> List[RunInfo]:
        """The runs the server hosts, by run id (every page of its listing)."""
        return [_from_message(RunInfo, x)
                for x in self._pages("ListRuns", pb.ListRunsRequest, "runs")]

    def _pages(self, method: str, request_type, field: str) -> list:
        """Every entry of a paged listing: a reply holds as many as fit in a
        message and a next_page_token while more follow."""
        entries, token = [], ""
        while True:
            r = self._call(method, request_type(page_token=token))
            entries.extend(getattr(r, field))
            if not r.next_page_token:
                return entries
            if r.next_page_token <= token:  # pages are in key order: it would never end
                raise RveError(grpc.StatusCode.INTERNAL,
                               f"the server's next page token {r.next_page_token!r} does not "
                               f"follow {token!r}", method, self.target)
            token = r.next_page_token

    # -- templates ------------------------------------------------------------

    def upload_template(self, name: str, packing: Union[Packing, Record], description: str = "",
                        *, replace: bool = False) -> TemplateInfo:
        """Uploads ``packing`` (a Packing, or an exported Record's) as template
        ``name``. replace=False: an existing name is ALREADY_EXISTS."""
        check_name("template name", name)
        if isinstance(packing, Record):
            packing = packing.packing
        if not isinstance(packing, Packing):
            raise TypeError(f"packing must be a rvehub.Packing or Record, got {type(packing)}")
        entry = pb.Template(name=name, description=description, packing=packing.to_proto())
        r = self._call("UploadTemplate", pb.UploadTemplateRequest(entry=entry, replace=replace))
        return _from_message(TemplateInfo, r)

    def upload_template_file(self, path: str, *, replace: bool = False) -> List[TemplateInfo]:
        """Uploads every template of a template file (``rve_cli prepare --out``
        or a server checkpoint's templates.h5) through ``rve_cli
        upload-template``; returns what the server then lists of them."""
        # rve_cli is the project's one reader of template files (store/): the
        # HDF5 layout and its checks stay in one place, and this package needs
        # no HDF5 binding. The connection's token and CA travel as files.
        if not os.path.isfile(path):
            raise FileNotFoundError(f"template file '{path}' does not exist")
        cli = _binaries.find_binary("rve_cli", self._cli, self._build_dir)
        with tempfile.TemporaryDirectory(prefix="rvehub-") as tmp:
            args = ["upload-template", f"--server={self.target}", f"--file={path}",
                    f"--timeout={self.timeout or 0}"]
            if replace:
                args.append("--replace")
            if self._token:
                token_file = os.path.join(tmp, "token")
                fd = os.open(token_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
                with os.fdopen(fd, "w") as f:
                    f.write(self._token)
                args.append(f"--token-file={token_file}")
            if self._root_certificates is not None:
                ca = os.path.join(tmp, "ca.pem")
                with open(ca, "wb") as f:
                    f.write(self._root_certificates)
                args.append(f"--tls-ca={ca}")
            out = _binaries.run_cli(cli, args)
        names = [m.group(1) for m in re.finditer(r"^uploaded (\S+): ", out, re.M)]
        hosted = {t.name: t for t in self.templates()}
        return [hosted[n] for n in names if n in hosted]

    def prepare_template(self, material: str = "SET-dense", seed: int = 1, *,
                         pressure: Optional[float] = None, void_ratio: Optional[float] = None,
                         particles: Optional[int] = None, rolling_eta: Optional[float] = None,
                         name: Optional[str] = None, replace: bool = False,
                         reuse: bool = True) -> TemplateInfo:
        """Prepares parameter set ``material`` with ``seed`` (``rve_cli
        prepare``, in this process's machine) and uploads it as template
        ``name`` (default: rve_cli's name, e.g. SET-dense-seed1). reuse=True:
        a template of that name already on the server is taken as it is
        (preparation is deterministic, so the same options give the same
        packing). Options as rve_cli's: ``pressure`` Pa (compression +),
        ``void_ratio``, ``particles``, ``rolling_eta``."""
        if name is None:
            name = template_name(material, seed, pressure=pressure, void_ratio=void_ratio,
                                 particles=particles, rolling_eta=rolling_eta)
        check_name("template name", name)
        if reuse and not replace:
            for t in self.templates():
                if t.name == name:
                    return t
        with tempfile.TemporaryDirectory(prefix="rvehub-") as tmp:
            path = os.path.join(tmp, "template.h5")
            prepare_template_file(path, material, seed, pressure=pressure, void_ratio=void_ratio,
                                  particles=particles, rolling_eta=rolling_eta, name=name,
                                  cli=self._cli, build_dir=self._build_dir)
            infos = self.upload_template_file(path, replace=replace)
        if len(infos) != 1:
            raise RuntimeError(f"template {name} was uploaded but the server does not list it")
        return infos[0]

    # -- runs -----------------------------------------------------------------

    def create_run(self, run_id: str, template: str, ids: ArrayLike, *,
                   pressure: Optional[ArrayLike] = None,
                   vertical_compression: Optional[ArrayLike] = None,
                   k0: Optional[ArrayLike] = None,
                   controls: Optional[Controls] = None) -> "Run":
        """Creates RVEs ``ids`` of run ``run_id`` from ``template`` (all or
        nothing) and returns the Run. Initial state: ``pressure`` (Pa,
        compression +: σxx = σyy = −p), or a K0 state with y vertical
        (``vertical_compression`` σv Pa, compression +, and ``k0`` = σh/σv),
        each a number or one per id; neither: the template's. The states after
        consolidation are in ``run.created``."""
        run = Run(self, run_id)
        run.create(ids, template, pressure=pressure, vertical_compression=vertical_compression,
                   k0=k0, controls=controls)
        return run

    def run(self, run_id: str) -> "Run":
        """A handle on an existing run (its ids and committed steps are read
        from the server; RveError NOT_FOUND for an unknown run)."""
        run = Run(self, run_id)
        run.refresh()
        return run

    def drop(self, run_id: str, ids: Optional[ArrayLike] = None) -> int:
        """Frees RVEs ``ids`` of a run (None: the whole run); returns how many."""
        check_name("run id", run_id)
        req = pb.DropRequest(run_id=run_id)
        if ids is not None:
            req.ids.extend(_ids_array(ids).tolist())
        return int(self._call("Drop", req).dropped)

    def export(self, run_id: str, ids: Optional[ArrayLike] = None) -> List[Record]:
        """Full states of RVEs ``ids`` of a run (None: all), for import_."""
        check_name("run id", run_id)
        req = pb.ExportRequest(run_id=run_id)
        if ids is not None:
            req.ids.extend(_ids_array(ids).tolist())
        records = []
        declared = None
        for chunk in self._stream("Export", req):
            if declared is None:
                declared = chunk.total_records
            records.extend(Record.from_proto(r) for r in chunk.records)
        if declared and declared != len(records):
            raise RveError(grpc.StatusCode.DATA_LOSS,
                           f"export declared {declared} records but carried {len(records)}",
                           "Export", self.target)
        return records

    def import_(self, records: Iterable[Record], *, run_id: Optional[str] = None) -> int:
        """Imports exported records (all or nothing: ALREADY_EXISTS if any
        (run, id) exists); ``run_id`` puts them into that run instead of
        their own. Returns how many were imported."""
        records = list(records)
        if not records:
            raise ValueError("import_ needs at least one record")
        for r in records:
            if not isinstance(r, Record):
                raise TypeError(f"import_ takes rvehub.Record objects, got {type(r)}")
        if run_id is not None:
            check_name("run id", run_id)
        protos = []
        for r in records:
            m = r.to_proto()
            if run_id is not None:
                m.run_id = run_id
            protos.append(m)
        if self._max_message_bytes is None:
            self.info()
        limit = min(self._max_message_bytes or (2**31 - 1), 2**31 - 1)
        budget = max(limit - _CHUNK_OVERHEAD, limit // 2)

        def chunks():
            chunk = pb.RveChunk(total_records=len(protos))
            size = _FRAMING
            for m in protos:
                s = m.ByteSize() + _FRAMING
                if s > budget:
                    raise RveError(grpc.StatusCode.RESOURCE_EXHAUSTED,
                                   f"RVE ({m.run_id!r}, {m.id}) takes {s} bytes, over the "
                                   f"budget of {budget} bytes per Import message", "Import",
                                   self.target)
                if chunk.records and size + s > budget:
                    yield chunk
                    chunk = pb.RveChunk()
                    size = _FRAMING
                chunk.records.append(m)
                size += s
            if chunk.records:
                yield chunk

        # Sizes are checked before anything is sent: the server imports all
        # or nothing, but a stream cut by the client should not reach it.
        all_chunks = list(chunks())
        return int(self._call("Import", iter(all_chunks)).imported)

    # -- element tests --------------------------------------------------------

    def element_test(self, test: str = "drained-biaxial", *, template: Optional[str] = None,
                     material: Optional[str] = None, seed: Optional[int] = None,
                     pressure: Optional[float] = None, void_ratio: Optional[float] = None,
                     particles: Optional[int] = None, rolling_eta: Optional[float] = None,
                     confining: Optional[float] = None, strain: Optional[float] = None,
                     rows: Optional[int] = None, inertial_number: Optional[float] = None,
                     cyclic_control: Optional[str] = None, amplitude: Optional[float] = None,
                     cycles: Optional[int] = None, axis: Optional[str] = None,
                     progress: Optional[Callable[[float], None]] = None) -> ElementTestResult:
        """Runs an element test on the server (RunElementTest) on a fresh RVE
        of ``template``, or of the packing of ``material``/``seed`` (and the
        variant options pressure, void_ratio, particles, rolling_eta), which is
        prepared and uploaded first unless the server has it (prepare_template).
        The options are rve_cli element-test's, with its defaults when None:
        test (drained-biaxial | isotropic | oedometer | undrained-simple-shear
        | cyclic-simple-shear), confining (Pa, compression +, 100e3), strain
        (0.1), rows (400), inertial_number (1e-3), axis ("y"; "x" for
        drained-biaxial and oedometer), and for cyclic-simple-shear only
        cyclic_control ("strain" | "stress"), amplitude (0.005, or Pa) and
        cycles (5). ``progress(fraction)`` is called as the server reports.

        Returns the rows as numpy columns named as rve_cli's CSV, compression
        positive, the same values as ``rve_cli element-test`` of the same set
        and seed (see ElementTestResult)."""
        if test not in _TESTS:
            raise ValueError(f"test must be one of {', '.join(_TESTS)}; got {test!r}")
        local_options = {"material": material, "seed": seed, "pressure": pressure,
                         "void_ratio": void_ratio, "particles": particles,
                         "rolling_eta": rolling_eta}
        if template is not None:
            check_name("template", template)
            given = [k for k, v in local_options.items() if v is not None]
            if given:
                raise ValueError(f"{given[0]} does not apply with template= (the template fixes "
                                 "the packing)")
        if test != "cyclic-simple-shear":
            for k, v in (("cyclic_control", cyclic_control), ("amplitude", amplitude),
                         ("cycles", cycles)):
                if v is not None:
                    raise ValueError(f"{k} applies to cyclic-simple-shear only")
        req = pb.ElementTestRequest(test=_TESTS[test])
        # Zero means the server's default in the request: an explicit 0 here
        # would silently become the default, so it is refused instead.
        for field, v, what in (("confining_pressure", confining, "confining"),
                               ("max_strain", strain, "strain"),
                               ("inertial_number", inertial_number, "inertial_number"),
                               ("amplitude", amplitude, "amplitude")):
            if v is not None:
                x = _finite_scalar(what, v)
                if not x > 0:
                    raise ValueError(f"{what} must be > 0, got {x}")
                setattr(req, field, x)
        for field, v in (("rows", rows), ("cycles", cycles)):
            if v is not None:
                if int(v) != v or v < 1:
                    raise ValueError(f"{field} must be a positive integer, got {v!r}")
                if v > 2**31 - 1:
                    raise ValueError(f"{field} = {v} is too large")
                setattr(req, field, int(v))
        if cyclic_control is not None:
            if cyclic_control not in ("strain", "stress"):
                raise ValueError(f"cyclic_control must be 'strain' or 'stress', got "
                                 f"{cyclic_control!r}")
            req.cyclic_stress_control = cyclic_control == "stress"
        if axis is not None:
            if axis not in _AXES:
                raise ValueError(f"axis must be 'x', 'y' or 'z' (z needs a 3-D RVE), got {axis!r}")
            if axis != "y" and test not in ("drained-biaxial", "oedometer"):
                raise ValueError("axis applies to drained-biaxial and oedometer only")
            req.axis = _AXES[axis]
        if template is None:
            template = self.prepare_template(
                material if material is not None else "SET-dense",
                seed if seed is not None else 1, pressure=pressure, void_ratio=void_ratio,
                particles=particles, rolling_eta=rolling_eta).name
        req.template_name = template
        rows_out = []
        for update in self._stream("RunElementTest", req):
            if progress is not None:
                progress(update.progress)
            rows_out.extend(update.rows)
        return ElementTestResult.from_rows(rows_out, template=template, test=test)


class Run:
    """The RVEs of one run on a hub, keyed by material-point id.

    The handle keeps each RVE's committed step (from the server's replies),
    so ``apply`` numbers its steps itself: a COMMIT completes step s + 1 of
    RVEs at step s; a TRIAL computes the same and changes nothing.
    """

    def __init__(self, hub: Hub, run_id: str):
        self.hub = hub
        self.run_id = check_name("run id", run_id)
        self._steps: Dict[int, int] = {}
        self.created: Optional[States] = None

    def __repr__(self) -> str:
        return f"Run({self.run_id!r}, {len(self._steps)} RVEs on {self.hub.target})"

    @property
    def ids(self) -> np.ndarray:
        """The material-point ids this handle knows, in creation order."""
        return np.fromiter(self._steps.keys(), np.int64, len(self._steps))

    @property
    def steps(self) -> np.ndarray:
        """The committed step of each of ``ids``."""
        return np.fromiter(self._steps.values(), np.int64, len(self._steps))

    def _note_steps(self, states: States) -> None:
        for i, s, c in zip(states.ids.tolist(), states.step.tolist(), states.code.tolist()):
            if c != grpc.StatusCode.NOT_FOUND.value[0]:
                self._steps[i] = s

    def refresh(self) -> States:
        """Reads every RVE of the run (GetStates) and its committed step."""
        states = self.states()
        self._steps = {}
        self._note_steps(states)
        return states

    def create(self, ids: ArrayLike, template: str, *, pressure: Optional[ArrayLike] = None,
               vertical_compression: Optional[ArrayLike] = None, k0: Optional[ArrayLike] = None,
               controls: Optional[Controls] = None) -> States:
        """Creates RVEs ``ids`` in this run (see Hub.create_run); returns
        their states after consolidation (step 0)."""
        check_name("template", template)
        a = _ids_array(ids)
        if a.size == 0:
            raise ValueError("ids must not be empty")
        req = pb.CreateRvesRequest(run_id=self.run_id, template_name=template, ids=a.tolist(),
                                   want_state=True)
        n = len(a)
        if pressure is not None and (vertical_compression is not None or k0 is not None):
            raise ValueError("give pressure or vertical_compression and k0, not both")
        if (vertical_compression is None) != (k0 is None):
            raise ValueError("a K0 state needs both vertical_compression and k0")
        if pressure is not None:
            p = _per_point("pressure", pressure, n)
            if np.ndim(pressure) == 0:
                req.initial_stress.pressure = float(p[0])
            else:
                for x in p:
                    req.initial_stresses.add(pressure=float(x))
        elif k0 is not None:
            sv = _per_point("vertical_compression", vertical_compression, n)
            kk = _per_point("k0", k0, n)
            if np.ndim(vertical_compression) == 0 and np.ndim(k0) == 0:
                req.initial_stress.k0.vertical_compression = float(sv[0])
                req.initial_stress.k0.k0 = float(kk[0])
            else:
                for v, k in zip(sv, kk):
                    s = req.initial_stresses.add()
                    s.k0.vertical_compression = float(v)
                    s.k0.k0 = float(k)
        if controls is not None:
            if not isinstance(controls, Controls):
                raise TypeError(f"controls must be rvehub.Controls, got {type(controls)}")
            req.controls.CopyFrom(controls.to_proto())
        r = self.hub._call("CreateRves", req)
        states = States.from_results(r.results, want_tangent=False)
        self._note_steps(states)
        self.created = states
        return states

    def _resolve_ids(self, ids: Optional[ArrayLike]) -> np.ndarray:
        if ids is None:
            a = self.ids
            if a.size == 0:
                raise ValueError(f"run {self.run_id!r}: this handle knows no RVEs; pass ids or "
                                 "use hub.run(run_id)")
            return a
        a = _ids_array(ids)
        if a.size == 0:
            raise ValueError("ids must not be empty")
        return a

    def apply(self, delta_f: ArrayLike, *, ids: Optional[ArrayLike] = None, mode: str = "commit",
              tangent: bool = False, step: Optional[int] = None,
              max_inertial_number: float = 0.0, relax: bool = False, relax_tolerance: float = 0.0,
              relax_max_steps: int = 0, duration: float = 0.0,
              stress_only: bool = False) -> States:
        """Applies deformation-gradient increments to RVEs ``ids`` (None:
        every RVE of this handle, in ``self.ids`` order).

        delta_f: (n, 3, 3) ΔF, one per id (or one (3, 3) for all), mapping
          each RVE's committed configuration to the new one (F_new = ΔF·F_old),
          dimensionless; plane strain in x–y, det > 0.
        mode: "commit" advances each RVE from step − 1 to step (repeating the
          current step's COMMIT with the same ΔF returns the stored result);
          "trial" computes step from the committed step − 1 and changes
          nothing (Newton iterations).
        step: the step this increment completes; None: committed step + 1
          (the ids must then be at one committed step).
        tangent: also return the contact tangent D (n, 3, 3, 3, 3), Pa.
        The other options are ApplyOptions' (0: the server's default).

        Returns States: per-point code/message/step and the new states
        (stress Pa, tension +). A malformed request raises ValueError before
        sending, or RveError (INVALID_ARGUMENT, NOT_FOUND for an unknown run
        or id) from the server; either way no RVE is changed."""
        if mode not in ("commit", "trial"):
            raise ValueError(f"mode must be 'commit' or 'trial', got {mode!r}")
        a = self._resolve_ids(ids)
        f = check_delta_f(delta_f, a)
        if step is None:
            known = [self._steps[i] for i in a.tolist() if i in self._steps]
            if len(set(known)) > 1:
                raise ValueError(
                    f"the ids are at different committed steps ({min(known)}..{max(known)}): "
                    "pass step= or apply to each group")
            # Ids this handle does not know get the server's verdict (NOT_FOUND
            # for ids not in the run).
            step = (known[0] if known else 0) + 1
        if int(step) != step or step < 1:
            raise ValueError(f"step must be an integer ≥ 1, got {step!r}")
        for what, v in (("max_inertial_number", max_inertial_number),
                        ("relax_tolerance", relax_tolerance), ("duration", duration)):
            _finite_scalar(what, v)
        opts = pb.ApplyOptions(want_tangent=bool(tangent),
                               max_inertial_number=float(max_inertial_number), relax=bool(relax),
                               relax_tolerance=float(relax_tolerance),
                               relax_max_steps=int(relax_max_steps), duration=float(duration),
                               stress_only=bool(stress_only))
        req = pb.ApplyRequest(
            run_id=self.run_id, step=int(step),
            mode=pb.APPLY_MODE_COMMIT if mode == "commit" else pb.APPLY_MODE_TRIAL, options=opts)
        flat = f.reshape(len(a), 9).tolist()
        for i, values in zip(a.tolist(), flat):
            req.increments.add(id=i, delta_f=values)
        r = self.hub._call("Apply", req)
        states = States.from_results(r.results, want_tangent=bool(tangent))
        self._note_steps(states)
        return states

    def states(self, ids: Optional[ArrayLike] = None, *, tangent: bool = False) -> States:
        """The committed states of RVEs ``ids`` (None: every RVE of the run);
        an unknown id is reported per point (code NOT_FOUND)."""
        req = pb.GetStatesRequest(run_id=self.run_id, want_tangent=bool(tangent))
        if ids is not None:
            req.ids.extend(_ids_array(ids).tolist())
        r = self.hub._call("GetStates", req)
        return States.from_results(r.results, want_tangent=bool(tangent))

    def export(self, ids: Optional[ArrayLike] = None) -> List[Record]:
        """Full states of RVEs ``ids`` (None: every RVE of the run)."""
        return self.hub.export(self.run_id, ids)

    def drop(self, ids: Optional[ArrayLike] = None) -> int:
        """Frees RVEs ``ids`` (None: the whole run); returns how many."""
        n = self.hub.drop(self.run_id, ids)
        if ids is None:
            self._steps = {}
        else:
            for i in _ids_array(ids).tolist():
                self._steps.pop(i, None)
        return n


# ---------------------------------------------------------------------------
# Local servers.


def _stop_process(proc: subprocess.Popen, grace: float) -> Optional[int]:
    if proc.poll() is None:
        try:
            proc.send_signal(signal.SIGTERM)
            proc.send_signal(signal.SIGCONT)
        except ProcessLookupError:
            pass
        try:
            proc.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()
    if proc.stdout is not None:
        proc.stdout.close()
    return proc.returncode


class LocalHub(Hub):
    """A Hub on an rve_server this process started on 127.0.0.1 (port 0);
    ``close()``, the end of a ``with`` block, or the interpreter's exit
    stops it (SIGTERM, then SIGKILL after ``drain_seconds`` + 10 s)."""

    def __init__(self, *, server: Optional[str] = None, build_dir: Optional[str] = None,
                 threads: int = 0, token: Optional[str] = None, extra_args: Sequence[str] = (),
                 timeout: Optional[float] = 600.0, start_timeout: float = 60.0,
                 drain_seconds: int = 5, log_path: Optional[str] = None):
        binary = _binaries.find_binary("rve_server", server, build_dir)
        self._tmp = tempfile.TemporaryDirectory(prefix="rvehub-server-")
        self.log_path = log_path or os.path.join(self._tmp.name, "rve_server.log")
        args = [binary, "--listen=127.0.0.1:0", f"--threads={int(threads)}",
                f"--drain_seconds={int(drain_seconds)}"]
        if token:
            token_file = os.path.join(self._tmp.name, "token")
            fd = os.open(token_file, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
            with os.fdopen(fd, "w") as f:
                f.write(token)
            args.append(f"--auth_token_file={token_file}")
        args.extend(extra_args)
        with open(self.log_path, "wb") as log:
            self.process = subprocess.Popen(args, stdin=subprocess.DEVNULL,
                                            stdout=subprocess.PIPE, stderr=log)
        self._finalizer = weakref.finalize(self, _stop_process, self.process, drain_seconds + 10)
        address = self._read_address(start_timeout)
        super().__init__(address, token=token, timeout=timeout, build_dir=build_dir)

    def _read_address(self, start_timeout: float) -> str:
        # The server's first stdout line: "listening on 127.0.0.1:PORT".
        deadline = time.monotonic() + start_timeout
        line = b""
        fd = self.process.stdout.fileno()
        while not line.endswith(b"\n"):
            left = deadline - time.monotonic()
            if left <= 0:
                break
            ready, _, _ = select.select([fd], [], [], min(left, 0.5))
            if ready:
                chunk = os.read(fd, 256)
                if not chunk:
                    break
                line += chunk
            elif self.process.poll() is not None:
                break
        text = line.decode(errors="replace").strip()
        if not text.startswith("listening on "):
            self._finalizer()
            log = ""
            try:
                with open(self.log_path, errors="replace") as f:
                    log = f.read()[-4000:]
            except OSError:
                pass
            raise RuntimeError(f"rve_server did not start (exit status {self.process.returncode}, "
                               f"stdout {text!r}); its log:\n{log}")
        return text[len("listening on "):]

    def stop(self) -> Optional[int]:
        """Stops the server (SIGTERM, it drains calls in flight); returns its
        exit status (0 after a clean stop)."""
        Hub.close(self)
        self._finalizer()
        return self.process.returncode

    def close(self) -> None:
        self.stop()
