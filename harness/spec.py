"""What a run is: (case, engine and algorithm, integrator, tolerances or step, horizon, sampling).

A :class:`RunSpec` is plain data (it pickles, it goes to a Dask worker, it is one row of a sweep's
cross product). Its :attr:`RunSpec.run_id` is a stable hash of its fields, so a resumed sweep can
tell which runs are already done.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import asdict, dataclass, fields

CORE = "redysim"  # the engine name of our own core
CORE_METHODS = ("rge-a", "ge-n", "rge-n")
NATIVE = "native"  # integrator name: the engine's own time stepping
ADDED_FIELDS = ("perturb",)  # left out of run_id at their default (see RunSpec.run_id)


@dataclass(frozen=True)
class RunSpec:
    """One run.

    case:        a case name from ``cases/`` or the path of a case file.
    engine:      ``"redysim"`` (the core) or a reference engine's name (``references.ENGINES``).
    method:      for the core, ``"rge-a"`` (default), ``"ge-n"`` or ``"rge-n"``; ignored (``""``)
                 for an engine.
    integrator:  a name from ``redysim.integrate.INTEGRATORS`` (``"ode45"``, ``"dop853"``,
                 ``"rk4"``, ``"scipy-RK45"``, ...) or ``"native"`` (the engine's own stepper; needs
                 ``h``).
    rtol, atol:  tolerances of an adaptive integrator.
    h:           the step of a fixed-step integrator (``rk4``, ``native``); 0 for adaptive ones.
    t_end:       horizon [s]; 0 means the case's own ``t_end``.
    sample:      sample interval [s]; 0 means the case's (``sample_interval``, else t_end / 20).
    energy_bound: a run whose |delta_M| exceeds this [J/kg] is stopped and recorded as failed.
    max_wall_s:  a run still going after this many seconds is stopped and recorded as failed
                 (its finished samples are kept); 0 means no limit.
    perturb:     a rounding-level change of the initial state: every component y0_i of (q0, qd0)
                 becomes y0_i + perturb * max(|y0_i|, 1), and E(0) is that state's energy. 0 (the
                 default) runs the case's own state. Ensembles of runs with perturb ~ 1e-13 show
                 how much a result depends on round-off (``sweeps/drift-ensemble.toml``).
    """

    case: str
    engine: str = CORE
    method: str = "rge-a"
    integrator: str = "ode45"
    rtol: float = 1e-4
    atol: float = 1e-6
    h: float = 0.0
    t_end: float = 0.0
    sample: float = 0.0
    energy_bound: float = 1e3
    max_wall_s: float = 0.0
    perturb: float = 0.0

    def __post_init__(self):
        if self.engine != CORE and self.method in CORE_METHODS:
            object.__setattr__(self, "method", "")

    @property
    def run_id(self) -> str:
        """A stable 16-hex-digit id from every field and the code that runs it
        (:func:`harness.provenance.code_digest`): same spec and code, same id, on any machine;
        a run finished by other code is not reused."""
        from .provenance import code_digest
        fields_ = asdict(self)
        for name in ADDED_FIELDS:  # a field added later keeps the ids of runs that do not use it
            if fields_[name] == getattr(RunSpec, name):
                del fields_[name]
        blob = json.dumps({**fields_, "code": code_digest()}, sort_keys=True, default=repr)
        return hashlib.sha256(blob.encode()).hexdigest()[:16]

    @property
    def label(self) -> str:
        """A short human label: ``RE-U125-L1 redysim/rge-a ode45 rtol=1e-06``."""
        algo = f"{self.engine}/{self.method}" if self.method else self.engine
        step = f"h={self.h:g}" if self.h else f"rtol={self.rtol:g}"
        extra = f" perturb={self.perturb:g}" if self.perturb else ""
        return f"{self.case} {algo} {self.integrator} {step}{extra}"

    def to_dict(self) -> dict:
        return asdict(self)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in fields(cls))
