"""Value types of the rvehub package: numpy arrays in and out.

Conventions (those of proto/rvehub/v1/rve_service.proto):
- Tensors are 3×3 arrays indexed [i, j] (axes x, y, z); a batch of n of them
  is (n, 3, 3). RVEs are 2-D, plane strain in x–y.
- Stress is Cauchy stress in Pa, TENSION POSITIVE. Names that say
  "pressure" or "compression" are compression positive (mean_pressure
  p = −(σxx + σyy)/2).
- SI units: m, s, kg, Pa, m/s.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Dict, Iterator, List, Optional, Sequence

import numpy as np

from ._proto import pb
from .errors import RveError, status_code

# ---------------------------------------------------------------------------
# Server, template and run descriptions.


@dataclasses.dataclass(frozen=True)
class ServerInfo:
    """A server's version, load and limits (rvehub.v1.ServerInfo)."""
    version: str
    api_version: str
    threads: int
    num_rves: int
    max_rves: int
    memory_bytes: int
    max_memory_bytes: int
    num_runs: int
    num_templates: int
    max_batch: int           #: increments per call at most
    max_message_bytes: int
    uptime_seconds: float
    auth_required: bool
    tls: bool
    max_templates: int = 0   #: templates hosted at most (0: not said)


@dataclasses.dataclass(frozen=True)
class TemplateInfo:
    """A template hosted by a server."""
    name: str
    description: str
    material_name: str
    num_particles: int
    void_ratio: float     #: e of the template, [-]
    mean_pressure: float  #: p of the template, Pa, compression +


@dataclasses.dataclass(frozen=True)
class RunInfo:
    """A run hosted by a server."""
    run_id: str
    num_rves: int
    min_step: int  #: smallest committed step among its RVEs
    max_step: int


def _from_message(cls, message):
    return cls(**{f.name: getattr(message, f.name) for f in dataclasses.fields(cls)})


# ---------------------------------------------------------------------------
# Homogenised states of a batch.

_TENSOR_FIELDS = ("stress", "fabric", "fabric_anisotropy_tensor", "deformation_gradient")
_FLOAT_FIELDS = ("fabric_anisotropy", "void_ratio", "porosity", "coordination",
                 "mechanical_coordination", "permeability", "mean_rotation", "kinetic_energy",
                 "unbalanced_force_ratio", "volume", "time_step", "mass_scale", "mean_pressure",
                 "deviator_stress")
_INT_FIELDS = ("num_contacts", "steps")
_BOOL_FIELDS = ("fabric_defined",)


@dataclasses.dataclass
class States:
    """Per-point outcomes and homogenised states of a batch, in request order.

    Per-point status: ``code`` (google.rpc.Code numbers, 0 = OK; ``ok`` is
    ``code == 0``), ``message`` (why, where code ≠ 0), ``step`` (the RVE's
    committed step after the call). A failed point's state values are NaN
    (floats) or 0 (integers, booleans); ``check()`` raises for failed points.

    State arrays, n = len(ids):
      stress (n, 3, 3)               Cauchy σ, Pa, TENSION +
      mean_pressure (n,)             p = −(σxx + σyy)/2, Pa, compression +
      deviator_stress (n,)           q = sqrt(½ s:s) in-plane, Pa
      void_ratio, porosity (n,)      e (2-D areas), n = e/(1 + e), [-]
      fabric (n, 3, 3)               φ = (1/Nc) Σ n⊗n, [-]
      fabric_anisotropy_tensor (n, 3, 3)  Fa = 4(φ − I/2) in-plane, [-]
      fabric_anisotropy (n,)         sqrt(½ Fa:Fa), [-]
      fabric_defined (n,)            False: no contacts, fabric is zero
      coordination (n,)              Z = 2 Nc/N; mechanical_coordination without rattlers
      num_contacts (n,)
      permeability (n,)              k = c e³/(1 + e), m/s
      deformation_gradient (n, 3, 3) F since creation, [-]
      mean_rotation (n,)             rad, counter-clockwise +
      kinetic_energy (n,)            J
      unbalanced_force_ratio (n,)    [-]
      volume (n,)                    V = A·t, m³
      steps (n,)                     DEM steps of the call that produced the state
      time_step (n,)                 DEM Δt, s
      mass_scale (n,)                density scaling used, [-]
      tangent (n, 3, 3, 3, 3)        contact tangent D[i, j, k, l] (dσ_ij = D_ijkl dε_kl),
                                     Pa; None unless asked for
      engine_seconds (n,)            the server engine's wall time per point, s
    """
    ids: np.ndarray
    code: np.ndarray
    message: List[str]
    step: np.ndarray
    engine_seconds: np.ndarray
    stress: np.ndarray
    fabric: np.ndarray
    fabric_anisotropy_tensor: np.ndarray
    deformation_gradient: np.ndarray
    fabric_anisotropy: np.ndarray
    void_ratio: np.ndarray
    porosity: np.ndarray
    coordination: np.ndarray
    mechanical_coordination: np.ndarray
    permeability: np.ndarray
    mean_rotation: np.ndarray
    kinetic_energy: np.ndarray
    unbalanced_force_ratio: np.ndarray
    volume: np.ndarray
    time_step: np.ndarray
    mass_scale: np.ndarray
    mean_pressure: np.ndarray
    deviator_stress: np.ndarray
    num_contacts: np.ndarray
    steps: np.ndarray
    fabric_defined: np.ndarray
    tangent: Optional[np.ndarray] = None

    def __len__(self) -> int:
        return len(self.ids)

    @property
    def ok(self) -> np.ndarray:
        """Boolean (n,): the points that succeeded."""
        return self.code == 0

    @property
    def failed(self) -> int:
        """The number of points that failed."""
        return int(np.count_nonzero(self.code))

    def check(self) -> "States":
        """Returns self when every point succeeded; else raises RveError with
        the first failed point's code and message and every failed id."""
        bad = np.flatnonzero(self.code)
        if bad.size == 0:
            return self
        k = int(bad[0])
        ids = [int(i) for i in self.ids[bad]]
        more = f" ({len(ids)} points failed: ids {ids[:10]}{'...' if len(ids) > 10 else ''})"
        raise RveError(status_code(int(self.code[k])),
                       f"id {int(self.ids[k])}: {self.message[k]}{more}", ids=ids)

    @classmethod
    def from_results(cls, results: Sequence, want_tangent: bool) -> "States":
        n = len(results)
        out = {
            "ids": np.fromiter((r.id for r in results), np.int64, n),
            "code": np.fromiter((r.code for r in results), np.int32, n),
            "message": [r.message for r in results],
            "step": np.fromiter((r.step for r in results), np.int64, n),
            "engine_seconds": np.fromiter((r.engine_seconds for r in results), np.float64, n),
        }
        for name in _TENSOR_FIELDS:
            out[name] = np.full((n, 3, 3), np.nan)
        for name in _FLOAT_FIELDS:
            out[name] = np.full(n, np.nan)
        for name in _INT_FIELDS:
            out[name] = np.zeros(n, np.int64)
        for name in _BOOL_FIELDS:
            out[name] = np.zeros(n, bool)
        tangent = np.full((n, 3, 3, 3, 3), np.nan) if want_tangent else None
        for k, r in enumerate(results):
            if r.code != 0:
                continue
            s = r.state
            for name in _TENSOR_FIELDS:
                values = getattr(s, name)
                if len(values) == 9:
                    out[name][k] = np.reshape(values, (3, 3))
            for name in _FLOAT_FIELDS + _INT_FIELDS + _BOOL_FIELDS:
                out[name][k] = getattr(s, name)
            if tangent is not None and len(s.tangent) == 81:
                tangent[k] = np.reshape(s.tangent, (3, 3, 3, 3))
        return cls(tangent=tangent, **out)


# ---------------------------------------------------------------------------
# Packings and records (Export / Import, UploadTemplate): bit-exact copies of
# the messages, with arrays as numpy arrays.


@dataclasses.dataclass
class Material:
    """Particle and contact parameters (rvehub.v1.Material); see the proto
    for each field's unit. ``model`` is "linear" or "hertz-mindlin"."""
    name: str
    density: float          #: kg/m³
    young_modulus: float    #: Pa
    stiffness_ratio: float  #: kt/kn, [-]
    poisson_ratio: float    #: [-] (Hertz–Mindlin only)
    friction: float         #: μ, [-]
    rolling_beta: float     #: [-]
    rolling_eta: float      #: [-]
    bond_cohesion: float    #: Pa
    damping: float          #: [-]
    thickness: float        #: out-of-plane disc thickness, m
    model: str = "linear"


_MODELS = {"linear": pb.CONTACT_MODEL_LINEAR, "hertz-mindlin": pb.CONTACT_MODEL_HERTZ_MINDLIN}


@dataclasses.dataclass
class Controls:
    """Numerical controls of an RVE (rvehub.v1.Controls); every field has a
    range the server checks (INVALID_ARGUMENT naming it). Take a template's
    or RVE's from an exported record and change what you need with
    ``dataclasses.replace``: a field left 0 is out of most ranges."""
    time_step_factor: float = 0.0     #: (0, 1]
    max_inertial_number: float = 0.0  #: [1e-6, 1]
    pressure_floor: float = 0.0       #: Pa, [1, 1e9]
    min_steps: int = 0                #: [0, 1e6]
    max_stretch: float = 0.0          #: (0, 10]
    max_rotation: float = 0.0         #: rad, (0, π/2]
    mass_scale: float = 0.0           #: ≥ 1
    skin: float = 0.0                 #: (0, 2]

    def to_proto(self):
        return pb.Controls(**dataclasses.asdict(self))

    @classmethod
    def from_proto(cls, m) -> "Controls":
        return _from_message(cls, m)


_CELL_FIELDS = ("cell", "reference_cell", "frame")  # 2×2 row-major
_UINT_FIELDS = ("contact_i", "contact_j")


@dataclasses.dataclass
class Packing:
    """A periodic 2-D packing (rvehub.v1.Packing): everything for a bit-exact
    continuation. ``cell``, ``reference_cell``, ``frame``: (2, 2) arrays (m;
    columns of ``cell`` are the cell vectors, x = cell·s); per particle (N,):
    ``radius`` (m), ``sx``, ``sy`` (reduced coordinates), ``vx``, ``vy``
    (m/s), ``omega`` (rad/s, ccw +), ``theta`` (rad); per contact (sorted, i <
    j): ``contact_i``, ``contact_j`` (uint32), ``contact_tangential_force``
    (N), ``contact_rolling_moment`` (N·m), ``contact_bond_strength`` (N)."""
    material: Material
    controls: Controls
    cell: np.ndarray
    reference_cell: np.ndarray
    frame: np.ndarray
    radius: np.ndarray
    sx: np.ndarray
    sy: np.ndarray
    vx: np.ndarray
    vy: np.ndarray
    omega: np.ndarray
    theta: np.ndarray
    contact_i: np.ndarray
    contact_j: np.ndarray
    contact_tangential_force: np.ndarray
    contact_rolling_moment: np.ndarray
    contact_bond_strength: np.ndarray
    initial_void_ratio: float = 0.0        #: e0, [-]
    permeability_coefficient: float = 0.0  #: c in k = c·e³/(1+e), m/s
    total_steps: int = 0                   #: DEM steps since creation

    @property
    def num_particles(self) -> int:
        return int(len(self.radius))

    @classmethod
    def from_proto(cls, m) -> "Packing":
        values = {}
        for f in dataclasses.fields(cls):
            v = getattr(m, f.name)
            if f.name == "material":
                mat = {g.name: getattr(v, g.name) for g in dataclasses.fields(Material)}
                mat["model"] = {k_: name for name, k_ in _MODELS.items()}.get(v.model, "linear")
                values[f.name] = Material(**mat)
            elif f.name == "controls":
                values[f.name] = Controls.from_proto(v)
            elif f.name in _CELL_FIELDS:
                a = np.array(v, np.float64)
                values[f.name] = a.reshape(2, 2) if a.size == 4 else a
            elif f.name in _UINT_FIELDS:
                values[f.name] = np.array(v, np.uint32)
            elif f.type is np.ndarray or f.type == "np.ndarray":
                values[f.name] = np.array(v, np.float64)
            else:
                values[f.name] = v
        return cls(**values)

    def to_proto(self):
        m = pb.Packing()
        mat = dataclasses.asdict(self.material)
        model = mat.pop("model")
        if model not in _MODELS:
            raise ValueError(f"material.model must be one of {sorted(_MODELS)}, got {model!r}")
        m.material.CopyFrom(pb.Material(model=_MODELS[model], **mat))
        m.controls.CopyFrom(self.controls.to_proto())
        for f in dataclasses.fields(self):
            if f.name in ("material", "controls"):
                continue
            v = getattr(self, f.name)
            if f.name in _UINT_FIELDS:
                getattr(m, f.name).extend(np.asarray(v, np.uint32).ravel().tolist())
            elif f.type is np.ndarray or f.type == "np.ndarray":
                a = np.asarray(v, np.float64).ravel()
                getattr(m, f.name).extend(a.tolist())
            else:
                setattr(m, f.name, v)
        return m


@dataclasses.dataclass
class Record:
    """One RVE's full state (rvehub.v1.RveRecord), from ``Run.export`` and
    for ``Hub.import_``. ``last_delta_f`` (3, 3): ΔF of the last commit."""
    run_id: str
    id: int
    step: int
    last_delta_f: np.ndarray
    packing: Packing

    @classmethod
    def from_proto(cls, m) -> "Record":
        return cls(run_id=m.run_id, id=int(m.id), step=int(m.step),
                   last_delta_f=np.array(m.last_delta_f, np.float64).reshape(3, 3),
                   packing=Packing.from_proto(m.packing))

    def to_proto(self):
        return pb.RveRecord(run_id=self.run_id, id=int(self.id), step=int(self.step),
                            last_delta_f=np.asarray(self.last_delta_f, np.float64).ravel().tolist(),
                            packing=self.packing.to_proto())


# ---------------------------------------------------------------------------
# Element tests.

#: Columns of an element test, named and ordered as rve_cli's CSV.
ELEMENT_TEST_COLUMNS = (
    "step", "axial_strain", "vol_strain", "sxx", "syy", "sxy", "p", "q", "void_ratio",
    "coordination", "fabric_xx", "fabric_yy", "fabric_xy", "Fa", "permeability", "shear_strain")

# CSV column -> ElementTestRow field.
_ROW_FIELD = {c: ("fabric_anisotropy" if c == "Fa" else c) for c in ELEMENT_TEST_COLUMNS}


class ElementTestResult(Mapping):
    """The rows of an element test as numpy columns, named as rve_cli's CSV:
    step, axial_strain, vol_strain, sxx, syy, sxy, p, q, void_ratio,
    coordination, fabric_xx, fabric_yy, fabric_xy, Fa, permeability,
    shear_strain.

    Geomechanics signs, as rve_cli writes them: stresses sxx, syy, sxy and p
    in Pa, COMPRESSION POSITIVE (the negated engine stress); axial_strain =
    1 − F_aa along the test's axis and vol_strain = 1 − det F, compression
    positive; q = sqrt(½ s:s) in Pa; shear_strain γ = F_xy; permeability m/s;
    Fa the fabric anisotropy. ``step`` is int64, the rest float64.
    """

    def __init__(self, columns: Dict[str, np.ndarray], template: str = "", test: str = ""):
        self._columns = columns
        self.template = template
        self.test = test

    @classmethod
    def from_rows(cls, rows: Sequence, template: str = "", test: str = "") -> "ElementTestResult":
        n = len(rows)
        columns = {}
        for c in ELEMENT_TEST_COLUMNS:
            field = _ROW_FIELD[c]
            dtype = np.int64 if c == "step" else np.float64
            columns[c] = np.fromiter((getattr(r, field) for r in rows), dtype, n)
        return cls(columns, template, test)

    def __getitem__(self, key: str) -> np.ndarray:
        return self._columns[key]

    def __iter__(self) -> Iterator[str]:
        return iter(ELEMENT_TEST_COLUMNS)

    def __len__(self) -> int:
        return len(ELEMENT_TEST_COLUMNS)

    @property
    def rows(self) -> int:
        """The number of rows."""
        return int(len(self._columns["step"]))

    def csv_text(self) -> str:
        """The rows as rve_cli writes its CSV (%.10g, the same header)."""
        lines = [",".join(ELEMENT_TEST_COLUMNS)]
        floats = ELEMENT_TEST_COLUMNS[1:]
        for k in range(self.rows):
            lines.append(",".join([str(int(self._columns["step"][k]))] +
                                  ["%.10g" % self._columns[c][k] for c in floats]))
        return "\n".join(lines) + "\n"

    def to_csv(self, path: str) -> None:
        """Writes the rows as rve_cli's CSV."""
        with open(path, "w", encoding="ascii") as f:
            f.write(self.csv_text())

    def __repr__(self) -> str:
        return f"ElementTestResult(test={self.test!r}, template={self.template!r}, rows={self.rows})"


def read_element_test_csv(path: str) -> Dict[str, np.ndarray]:
    """Reads a CSV of ``rve_cli element-test --out`` into numpy columns."""
    with open(path, encoding="ascii") as f:
        header = f.readline().strip().split(",")
        data = [line.strip().split(",") for line in f if line.strip()]
    cols = {}
    for j, name in enumerate(header):
        dtype = np.int64 if name == "step" else np.float64
        cols[name] = np.array([row[j] for row in data], dtype=dtype)
    return cols
