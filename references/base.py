"""The common shape of every reference-engine adapter (STYLE.md habit 9).

An adapter builds the SAME chain as the core (DESIGN.md section 2: gravity -Y, link frame at the
proximal joint, x along the link, U = Ry(q1) then Rz(q2), R about z, inertia about the COM in the
link frame, joint k at length[k-1] along the parent's x axis, base fixed at the origin) and answers
in the core's names and units:

=========================  ==================================================================
``qdd(q, qd, tau=None)``   joint accelerations from I(q) qdd = phi(q, qd, tau)
``mass_matrix(q)``         the GIM I(q), (n, n), symmetric
``bias(q, qd)``            phi with tau = 0: -(C(q, qd) qd + gravity terms), as ``redysim.phi``
``energy(q, qd)``          (T, V) in J; V = sum m_k g y_Ck (zero with every COM at y = 0)
``tip(q, qd)``             world position of the distal end of the last link
``simulate(q0, qd0, ...)`` the engine's own fixed-step integrator -> :class:`Trajectory`
``version``                the engine package's version string
``limits(case_or_chain)``  :class:`Limits`: can the engine take this case, and if not, why
=========================  ==================================================================

A missing engine package raises :class:`EngineUnavailable` naming the package, never a bare
ImportError. ``limits`` reads the measured limits in ``references/limits.toml`` (how each was
measured is written there) and refuses a case BEFORE anything is built.
"""

from __future__ import annotations

import importlib
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, NamedTuple

import numpy as np

from redysim import Case, Chain

LIMITS_FILE = Path(__file__).with_name("limits.toml")
SUPPORTED_JOINTS = ("R", "U")  # R about z, U = Ry Rz (DESIGN.md section 2)


class EngineUnavailable(RuntimeError):
    """The engine's Python package is not installed (or fails to import)."""

    def __init__(self, engine: str, package: str, detail: str = ""):
        self.engine = engine
        self.package = package
        msg = (f"engine {engine!r} needs the Python package {package!r}, which is not installed"
               f" or does not import ({detail}); install it with the 'engines' extra"
               f" (pip install 'redysim[engines]')")
        super().__init__(msg)


class EngineLimitExceeded(RuntimeError):
    """The engine was asked to build a chain that its :meth:`Engine.limits` refuses."""


@dataclass(frozen=True)
class Limits:
    """Whether an engine can take a case: ``ok`` and, when not, ``reason`` (empty when ok)."""

    ok: bool
    reason: str = ""

    def __bool__(self) -> bool:
        return self.ok


class Trajectory(NamedTuple):
    """Samples of a native simulation: times (m,), q (m, n), qd (m, n); the integrator's name."""

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    integrator: str


def import_engine(engine: str, package: str, module: str | None = None):
    """Import the engine's module or raise :class:`EngineUnavailable` naming the package."""
    try:
        return importlib.import_module(module or package)
    except Exception as exc:  # ImportError, or a broken binary wheel (OSError)
        raise EngineUnavailable(engine, package, f"{type(exc).__name__}: {exc}") from None


def as_chain(case_or_chain: Case | Chain) -> Chain:
    """The Chain of a Case, or the Chain itself."""
    if isinstance(case_or_chain, Case):
        return case_or_chain.chain
    if isinstance(case_or_chain, Chain):
        return case_or_chain
    raise TypeError(f"expected a redysim Case or Chain, got {type(case_or_chain).__name__}")


def joint_kinds(chain: Chain) -> list[str]:
    """The chain's joint types as "R" (about z) or "U"; anything else raises ValueError."""
    out = []
    for k, j in enumerate(chain.joints):
        axes = j.axes()
        if j.type == "R" and np.array_equal(axes[0][1], [0.0, 0.0, 1.0]):
            out.append("R")
        elif j.type == "U":
            out.append("U")
        else:
            raise ValueError(f"joint {k}: type {j.type!r} with axes {[a[1] for a in axes]} is not "
                             f"modelled by the reference adapters (only R about z and U = Ry Rz)")
    return out


def load_limits() -> dict[str, Any]:
    """The measured limits table ``references/limits.toml``."""
    with open(LIMITS_FILE, "rb") as fh:
        return tomllib.load(fh)


def check_vec(chain: Chain, name: str, x, optional: bool = False) -> np.ndarray | None:
    """x as a float vector of length n (raises ValueError naming it)."""
    if x is None:
        if optional:
            return None
        raise ValueError(f"{name} is required")
    a = np.asarray(x, dtype=float)
    if a.shape != (chain.n_dof,):
        raise ValueError(f"{name} has shape {a.shape}; the chain has {chain.n_dof} DOF")
    return a


class Engine:
    """Base class of the adapters. Subclasses set the class attributes and the ``_build`` and
    ``_qdd`` ... hooks; the public methods here check sizes at the door and call them."""

    name: ClassVar[str] = ""
    package: ClassVar[str] = ""  # the pip package that provides the engine
    module: ClassVar[str] = ""  # the module to import
    integrator: ClassVar[str] = ""  # what simulate() uses

    def __init__(self, case_or_chain: Case | Chain, *, check_limits: bool = True):
        self.lib = import_engine(self.name, self.package, self.module)
        self.chain = as_chain(case_or_chain)
        if check_limits:
            lim = self.limits(self.chain)
            if not lim.ok:
                raise EngineLimitExceeded(f"{self.name}: {lim.reason}")
        self.kinds = joint_kinds(self.chain)
        self._build()

    # ----------------------------------------------------------------------- availability
    @classmethod
    def available(cls) -> bool:
        """True when the engine's package imports."""
        try:
            import_engine(cls.name, cls.package, cls.module)
        except EngineUnavailable:
            return False
        return True

    @classmethod
    def package_version(cls) -> str:
        return import_engine(cls.name, cls.package, cls.module).__version__

    @property
    def version(self) -> str:
        """The engine package's version."""
        return self.package_version()

    # ----------------------------------------------------------------------- limits
    @classmethod
    def limits(cls, case_or_chain: Case | Chain) -> Limits:
        """Can this engine take the case? Decided from the chain's size and joints and the
        measured limits in ``references/limits.toml``, before anything is built."""
        chain = as_chain(case_or_chain)
        try:
            joint_kinds(chain)
        except ValueError as exc:
            return Limits(False, str(exc))
        entry = load_limits()["engine"][cls.name]
        n, nl = chain.n_dof, chain.n_links
        max_dof, max_links = int(entry["max_dof"]), int(entry.get("max_links", 10**9))
        if n > max_dof or nl > max_links:
            what = f"{n:,} DOF" if n > max_dof else f"{nl:,} links"
            return Limits(False, f"{cls.name}: {what} exceeds its limit on this machine "
                                 f"(max {max_dof:,} DOF, {max_links:,} links): {entry['stops']}")
        return Limits(True, "")

    # ----------------------------------------------------------------------- public API
    def qdd(self, q, qd, tau=None) -> np.ndarray:
        c = self.chain
        return self._qdd(check_vec(c, "q", q), check_vec(c, "qd", qd),
                         check_vec(c, "tau", tau, optional=True))

    def mass_matrix(self, q) -> np.ndarray:
        return self._mass_matrix(check_vec(self.chain, "q", q))

    def bias(self, q, qd) -> np.ndarray:
        return self._bias(check_vec(self.chain, "q", q), check_vec(self.chain, "qd", qd))

    def energy(self, q, qd) -> tuple[float, float]:
        T, V = self._energy(check_vec(self.chain, "q", q), check_vec(self.chain, "qd", qd))
        return float(T), float(V)

    def tip(self, q, qd) -> np.ndarray:
        return self._tip(check_vec(self.chain, "q", q), check_vec(self.chain, "qd", qd))

    def simulate(self, q0, qd0, t_end: float, h: float, *, every: int = 1) -> Trajectory:
        """Integrate from (q0, qd0) to t_end with the engine's own fixed-step integrator, step h;
        keep every ``every``-th step (and the first)."""
        c = self.chain
        q0, qd0 = check_vec(c, "q0", q0), check_vec(c, "qd0", qd0)
        if not (h > 0 and t_end >= 0):
            raise ValueError(f"need h > 0 and t_end >= 0, got h={h}, t_end={t_end}")
        steps = int(round(t_end / h))
        ts, qs, qds = [0.0], [q0.copy()], [qd0.copy()]
        self._sim_reset(q0, qd0, h)
        for i in range(1, steps + 1):
            self._sim_step()
            if i % every == 0 or i == steps:
                q, qd = self._sim_state()
                ts.append(i * h)
                qs.append(q)
                qds.append(qd)
        return Trajectory(np.array(ts), np.array(qs), np.array(qds), self.integrator)

    def step_once(self) -> None:
        """One native step from the state set by :meth:`sim_reset` (for benchmarks)."""
        self._sim_step()

    def sim_reset(self, q0, qd0, h: float) -> None:
        """Set the native stepper's state and step (before :meth:`step_once`)."""
        self._sim_reset(check_vec(self.chain, "q0", q0), check_vec(self.chain, "qd0", qd0), h)

    def sim_state(self) -> tuple[np.ndarray, np.ndarray]:
        """(q, qd) of the native stepper now."""
        return self._sim_state()

    def __repr__(self) -> str:
        return f"{type(self).__name__}({self.chain.name!r}, {self.chain.n_dof} DOF)"

    # ----------------------------------------------------------------------- hooks
    def _build(self) -> None:
        raise NotImplementedError

    def _qdd(self, q, qd, tau):
        raise NotImplementedError

    def _mass_matrix(self, q):
        raise NotImplementedError

    def _bias(self, q, qd):
        raise NotImplementedError

    def _energy(self, q, qd):
        raise NotImplementedError

    def _tip(self, q, qd):
        raise NotImplementedError

    def _sim_reset(self, q0, qd0, h):
        raise NotImplementedError

    def _sim_step(self):
        raise NotImplementedError

    def _sim_state(self):
        raise NotImplementedError
