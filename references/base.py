"""The common shape of every reference-engine adapter (docs/design.md, "Reference engines").

An adapter builds the SAME chain as the core (``redysim/chain.py``: link frame at the proximal
joint, x along the link, joint k at length[k-1] along the parent's x axis, base fixed at the
origin, inertia about the COM in the link frame, the chain's gravity vector) and answers in the
core's names and units:

=========================  ==================================================================
``qdd(q, qd, tau=None)``   joint accelerations from I(q) qdd = phi(q, qd, tau)
``mass_matrix(q)``         the GIM I(q), (n, n), symmetric
``bias(q, qd)``            phi with tau = 0: -(C(q, qd) qd + gravity terms), as ``redysim.phi``
``energy(q, qd)``          (T, V) in J; V = -sum m_k g . r_Ck (zero with every COM at the origin)
``tip(q, qd)``             world position of the distal end of the last link
``simulate(q0, qd0, ...)`` the engine's own fixed-step integrator -> :class:`Trajectory`
``version``                the engine package's version string
``limits(case_or_chain)``  :class:`Limits`: can the engine take this case, and if not, why
=========================  ==================================================================

Joints: :func:`joint_axes` is the one place that turns a chain into what the adapters build. It
reads the core's own per-DOF tables (``Chain.dof_kind``, ``dof_u``, ``joint_qoff``, the
arrays the kernels run on) and gives, per joint, its elementary 1-DOF axes in
order: an :class:`Axis` is "R" (revolute about ``u``) or "P" (prismatic along ``u``), ``u`` a unit
vector in the frame left by the axes before it (the parent link's frame for the first axis). The
frame after a revolute axis is R Rot(u, q); a prismatic axis moves the joint's origin by R u q
(the link frame then starts there: O_{k+1} = O_k + l_k x_k from the moved O_k). So an R joint
about -z gives the axis (0, 0, -1), never +z; U = R about y, then R about the rotated z; S = the
U axes, then R about the link's own x. Every engine builds the axes one after the other, each
axis's frame at the previous one's (see each module's docstring for how); an engine refuses, in
:meth:`Engine.limits`, only a joint it has no construction for (:meth:`Engine.unsupported`).

A :class:`redysim.Model` (a kinematic tree) handed to an adapter class, ``cls(model)`` or
``cls.limits(model)``, goes to the same engine's tree adapter (``references/trees.py``).

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

from redysim import Case, Chain, Model
from redysim.chain import KIND_CODES

LIMITS_FILE = Path(__file__).with_name("limits.toml")
KIND_NAMES = {code: kind for kind, code in KIND_CODES.items()}  # the core's dof_kind codes


# engine name -> its tree adapter (a ``references.trees.TreeEngine`` subclass, registered when
# it is defined, next to the engine's chain adapter in the same module)
TREE_ADAPTERS: dict[str, type] = {}


def tree_adapter(name: str) -> type:
    """The tree adapter registered under ``name`` (the chain adapters' names)."""
    try:
        return TREE_ADAPTERS[name]
    except KeyError:
        raise KeyError(f"no tree engine {name!r}; known: {', '.join(TREE_ADAPTERS)}") from None


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


class Axis(NamedTuple):
    """One elementary 1-DOF axis of a joint, as the core's kernels read it.

    ``kind`` "R" (revolute about ``u``) or "P" (prismatic along ``u``); ``u`` the unit axis in
    the frame left by the axes before it; ``coordinate`` 0, 1 or 2 when ``u`` is exactly +x, +y
    or +z (the core's axis code), None for any other direction, -x, -y and -z included.
    """

    kind: str
    u: tuple[float, float, float]
    coordinate: int | None

    @property
    def vector(self) -> np.ndarray:
        """``u`` as a new float array."""
        return np.array(self.u, dtype=float)

    @property
    def signed_coordinate(self) -> tuple[int, float] | None:
        """(i, +1.0 or -1.0) when ``u`` is exactly +e_i or -e_i, else None."""
        for i in range(3):
            if all(self.u[j] == 0.0 for j in range(3) if j != i) and abs(self.u[i]) == 1.0:
                return i, float(self.u[i])
        return None

    def describe(self) -> str:
        """E.g. "R about -z", "P along (0.267, -0.535, 0.802)"."""
        sc = self.signed_coordinate
        if sc:
            where = ("+" if sc[1] > 0 else "-") + "xyz"[sc[0]]
        else:
            where = "(" + ", ".join(f"{x:.6g}" for x in self.u) + ")"
        return f"{self.kind} {'about' if self.kind == 'R' else 'along'} {where}"


class JointAxes(NamedTuple):
    """A joint of the chain: its type name (a key of ``redysim.chain.JOINT_TYPES``) and its
    elementary axes in order."""

    type: str
    axes: tuple[Axis, ...]

    def describe(self) -> str:
        """E.g. "U = R about +y then R about +z"."""
        return f"{self.type} = " + " then ".join(a.describe() for a in self.axes)


def joint_axes(chain: Chain) -> list[JointAxes]:
    """Per joint, its elementary axes (see the module docstring), from the chain's own per-DOF
    tables; one :class:`JointAxes` per link. Joints shared by several links (a uniform chain
    repeats one Joint object) are read once. Raises ValueError on a DOF kind it does not know."""
    kinds, units, qoff = chain.dof_kind, chain.dof_u, chain.joint_qoff
    seen: dict = {}
    out = []
    for k, joint in enumerate(chain.joints):
        try:
            hash(joint)
            key = joint  # equal Joints have equal rows in the tables
        except TypeError:  # an axis given as a list or an array
            key = id(joint)
        ja = seen.get(key)
        if ja is None:
            axes = []
            for i in range(int(qoff[k]), int(qoff[k + 1])):
                kind = KIND_NAMES.get(int(kinds[i]))
                if kind is None:
                    raise ValueError(f"joint {k} ({joint.type}): DOF kind {int(kinds[i])} is not "
                                     f"modelled by the reference adapters (only R and P axes)")
                u = tuple(float(x) for x in units[i])
                # exactly +x, +y or +z (the rule of the core's coordinate-axis codes)
                plus = [j for j in range(3) if u[j] == 1.0 and u[j - 1] == u[j - 2] == 0.0]
                axes.append(Axis(kind, u, plus[0] if plus else None))
            ja = seen[key] = JointAxes(joint.type, tuple(axes))
        out.append(ja)
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


class EnginePackage:
    """An adapter's package: whether it imports, and its version (shared by the chain adapters
    and the tree adapters, :mod:`.trees`). Subclasses set ``name``, ``package``, ``module``."""

    name: ClassVar[str] = ""
    package: ClassVar[str] = ""  # the pip package that provides the engine
    module: ClassVar[str] = ""

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


class Engine(EnginePackage):
    """Base class of the adapters. Subclasses set the class attributes and the ``_build`` and
    ``_qdd`` ... hooks; the public methods here check sizes at the door and call them."""

    name: ClassVar[str] = ""
    package: ClassVar[str] = ""  # the pip package that provides the engine
    module: ClassVar[str] = ""  # the module to import
    integrator: ClassVar[str] = ""  # what simulate() uses

    def __new__(cls, case_or_chain=None, *args, **kwargs):
        # a kinematic tree goes to the engine's tree adapter (references/trees.py), which is
        # not a subclass of this one, so its own __init__ runs and this class's does not
        if isinstance(case_or_chain, Model) and cls.name:
            return tree_adapter(cls.name)(case_or_chain, *args, **kwargs)
        return super().__new__(cls)

    def __init__(self, case_or_chain: Case | Chain, *, check_limits: bool = True):
        self.lib = import_engine(self.name, self.package, self.module)
        self.chain = as_chain(case_or_chain)
        if check_limits:
            lim = self.limits(self.chain)
            if not lim.ok:
                raise EngineLimitExceeded(f"{self.name}: {lim.reason}")
        self.joints = joint_axes(self.chain)
        self._build()

    # ----------------------------------------------------------------------- limits
    @classmethod
    def limits(cls, case_or_chain: Case | Chain) -> Limits:
        """Can this engine take the case? Decided from the chain's size and joints and the
        measured limits in ``references/limits.toml``, before anything is built. A
        :class:`redysim.Model` is judged by the engine's tree adapter (references/trees.py)."""
        if isinstance(case_or_chain, Model):
            return tree_adapter(cls.name).limits(case_or_chain)
        chain = as_chain(case_or_chain)
        try:
            joints = joint_axes(chain)
        except ValueError as exc:
            return Limits(False, f"{cls.name}: {exc}")
        for k, ja in enumerate(joints):
            why = cls.unsupported(ja)
            if why:
                return Limits(False, f"{cls.name}: joint {k} ({ja.describe()}) cannot be built: "
                                     f"{why}")
        entry = load_limits()["engine"][cls.name]
        n, nl = chain.n_dof, chain.n_links
        max_dof, max_links = int(entry["max_dof"]), int(entry.get("max_links", 10**9))
        if n > max_dof or nl > max_links:
            what = f"{n:,} DOF" if n > max_dof else f"{nl:,} links"
            return Limits(False, f"{cls.name}: {what} exceeds its limit on this machine "
                                 f"(max {max_dof:,} DOF, {max_links:,} links): {entry['stops']}")
        return Limits(True, "")

    @classmethod
    def unsupported(cls, joint: JointAxes) -> str:
        """Why this engine cannot build ``joint`` ("" when it can). Every adapter here builds
        any sequence of R and P axes unless it overrides this."""
        return ""

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
