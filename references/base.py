"""The one shape of every reference-engine adapter (docs/design.md, "Reference engines").

Each engine has ONE adapter class (a subclass of :class:`Engine`), built from a
:class:`redysim.Model`, the one input: a kinematic tree, fixed or floating base; a serial chain
is a Model (a :class:`redysim.Chain` is one). A :class:`redysim.Case`
(its chain) or a :class:`redysim.Chain` handed to an adapter, ``cls(x)`` or ``cls.limits(x)``,
is converted at the door by :func:`as_model`, the one place that does it.

The adapter builds the Model's own tree from its arrays (``parent``, ``placement_R``,
``placement_p``, the per-DOF tables ``dof_kind``/``dof_u``, ``mass``, ``com``, ``inertia_com``,
``gravity``), never from the file the Model was read from, so every engine runs the system the
core runs, and it answers in the core's names, units and coordinates:

=========================  ==================================================================
``qdd(q, v, tau=None)``    vdot (n_v,) from I(q) vdot = phi(q, v, tau)
``mass_matrix(q)``         the GIM I(q), (n_v, n_v), symmetric
``bias(q, v)``             phi with tau = 0: -(C(q, v) v + gravity terms), as ``redysim.phi``
``energy(q, v)``           (T, V) in J; V = -sum m_k g . r_Ck (zero with every COM at the origin)
``position(q, frame)``     world position (3,) [m] of a frame of ``model.frames``
``tip(q)``                 ``position(q, "tip")``: a chain's distal end (its frame ``tip``)
``simulate(q0, v0, ...)``  the engine's own integrator -> :class:`Trajectory`; ``sim_reset``,
                           ``step_once``/``sim_advance``, ``sim_state``: the same, step by step;
                           ``integrators``: its integrators by name (:class:`NativeIntegrator`,
                           none for Pinocchio), ``sim_counts``, ``manifest``
``version``, ``name``      the engine package's version string; the adapter's registered name
``limits(model)``          :class:`Limits`: can the engine take the model, and if not, why
=========================  ==================================================================

q has length ``model.n_q`` and v ``model.n_v``, in the core's order (bodies in the Model's
order, each joint's axes in order). A free joint (a floating base) is the core's: q = (x, y, z,
qw, qx, qy, qz), the body origin's world position and a unit quaternion (w first; normalised
here, as the core reads only its direction), v = (v_world, w_body): the origin's velocity in
the WORLD frame and the angular velocity in the BODY frame (MuJoCo's convention). Every engine
with other coordinates is converted both ways in its adapter by one rule (:class:`FreeBlock`):
with y the engine's velocity coordinates of the joint in the core's slot order, v = B y with B
orthogonal (a rotation of the linear or the angular part), so

    y = B^T v,  tau_engine = B^T tau,  I = B I_engine B^T,  vdot = B ydot + c,
    phi = B phi_engine + I c,          c = (dB/dt) y,

which follows from I_engine ydot = tau_engine + phi_engine and v = B y (T, V are invariant).
Each engine's module docstring says what its B and c are. A model without free joints whose
coordinates the engine numbers as the core does (every chain, in every engine) is handed over
as it is, with no conversion at all.

Joints: :func:`joint_axes` is the one place that turns a model into what the adapters build:
per body, its joint's type, its parent body, its placement (R, p) in the parent's frame and its
elementary 1-DOF axes in order, read from the Model's own per-DOF tables (``dof_kind``,
``dof_u``, ``joint_voff``, the arrays the kernels run on). An :class:`Axis` is "R" (revolute
about ``u``) or "P" (prismatic along ``u``), ``u`` a unit vector in the frame left by the axes
before it (the joint's placed frame for the first axis). The frame after a revolute axis is
R Rot(u, q); a prismatic axis moves the joint's origin by R u q (the body frame then starts
there). So an R joint about -z gives the axis (0, 0, -1), never +z; U = R about y, then R about
the rotated z; S = the U axes, then R about the body's own x; a free joint has no axes (each
engine has its own free joint). Every engine builds the axes one after the other, each axis's
frame at the previous one's (see each module's docstring for how); a chain's link k hangs from
link k - 1 at l_{k-1} along its x axis, the placement a Chain gives it.

``limits`` decides before anything is built, from the model's size and the measured limits of
``references/limits.toml`` (how each was measured is written there; DOF = n_v, links = bodies,
or the depth of the body tree for an engine whose limit is a depth, ``depth_limited``), then
from its joints and bodies: a joint or a body the engine has no construction for
(:meth:`Engine.unsupported`, in the engine's own words). A missing engine package raises
:class:`EngineUnavailable` naming the package, never a bare ImportError.
"""

from __future__ import annotations

import importlib
import math
import tomllib
from dataclasses import dataclass
from pathlib import Path
from typing import Any, ClassVar, NamedTuple

import numpy as np

from redysim import Case, Chain, Model
from redysim.errors import SettingsError
from redysim.integrators.explicit import check_settings, sample_times
from redysim.integrators.protocol import Counters, IntegrationError, OdeSolver
from redysim.model.parts import KIND_CODES
from redysim.model.tree import BALL_JOINT, FREE, quaternion_matrix

LIMITS_FILE = Path(__file__).with_name("limits.toml")
KIND_NAMES = {code: kind for kind, code in KIND_CODES.items()}  # the core's dof_kind codes


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
    """The engine was asked to build a model that its :meth:`Engine.limits` refuses."""


@dataclass(frozen=True)
class Limits:
    """Whether an engine can take a model: ``ok`` and, when not, ``reason`` (empty when ok)."""

    ok: bool
    reason: str = ""

    def __bool__(self) -> bool:
        return self.ok


class Trajectory(NamedTuple):
    """Samples of a native simulation: times t (m,), q (m, n_q), v (m, n_v) the velocities v;
    the integrator's name (a key of the engine's ``integrators``)."""

    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    integrator: str


class NativeIntegrator(NamedTuple):
    """One of an engine's own time integrators, as runs, sweeps and manifests name it.

    ``name``: the short name (``"rk4"``, ``"implicitfast"``, ``"dopri5"``, ...), the key in the
    adapter's ``integrators`` and what ``integrator="native:NAME"`` selects; ``adaptive``: it
    controls its own error and takes tolerances (``rtol``, ``atol``), else it takes a fixed step
    ``h``; ``what``: the engine's own name and setting of it, for the manifest (e.g.
    ``"mjINT_IMPLICITFAST"``); ``note``: anything a fair comparison must know (what the
    integrator leaves out, how its tolerance is read)."""

    name: str
    adaptive: bool
    what: str
    note: str = ""


class NativeStepper:
    """An engine's own integrator as a run's stepper: ``Simulator(system, t_end,
    integrator=engine.stepper("rk4", h=1e-3))`` (:class:`redysim.simulation.Simulator` asks it
    what it asks :class:`redysim.simulation.Integrator`: :meth:`checked`, :meth:`warm_up`,
    :meth:`solver`). A fixed-step integrator takes its step ``h``; an adaptive one ``rtol`` and
    ``atol`` (and ``h`` as the largest step it may take). The engine steps its own model:
    a system that adds anything to its model (forces, damping, loops) is refused by name."""

    def __init__(self, engine: Engine, name: str | None = None, *, h: float | None = None,
                 rtol: float | None = None, atol: float | None = None):
        self.engine, self.h, self.rtol, self.atol = engine, h, rtol, atol
        self.info = engine.native_integrator(name)  # (ValueError naming its integrators)
        self.name = f"native:{self.info.name}"

    @property
    def fixed(self) -> bool:
        return not self.info.adaptive

    def checked(self, source: str, t_end: float, sample: float) -> NativeStepper:
        """Its settings checked for a run to t_end sampled every ``sample`` s: a fixed-step
        integrator's state is known at whole steps only, so the sample times must be whole
        multiples of h (SettingsError naming the bad setting)."""
        if t_end is None:
            raise SettingsError(source, "t_end", None, "missing: the horizon [s]")
        if self.fixed:
            if self.h is None:
                raise SettingsError(source, "h", None, f"{self.name} is a fixed-step "
                                    "integrator: give its step h [s]")
            check_settings(source, h=self.h, t_end=t_end, sample=sample)
            ts = sample_times(0.0, t_end, sample)
            if np.abs(ts / self.h - np.round(ts / self.h)).max() > 1e-6:
                raise SettingsError(source, "sample", sample, f"an engine's own stepper knows "
                                    f"its state at whole steps only: the sample times must be "
                                    f"whole multiples of h = {self.h:g}")
        else:
            check_settings(source, rtol=self.rtol, atol=self.atol, t_end=t_end, sample=sample)
            if self.h is not None:  # the largest step it may take
                check_settings(source, h=self.h, t_end=t_end)
        return self

    def warm_up(self) -> None:
        return None

    def solver(self, system, t0: float, y0, t_end: float, state=None) -> EngineStepper:
        why = self.engine.no_native_passive()
        if why:
            raise SettingsError(getattr(system, "source", "simulate"), "integrator", self.name,
                                why + ": run it through redysim's integrators (ode45, dop853, "
                                "rk4, ...), which apply them around the engine's qdd")
        why = self.engine.no_native_armature()
        if why:
            raise SettingsError(getattr(system, "source", "simulate"), "integrator", self.name,
                                why + ": run it through redysim's integrators (ode45, dop853, "
                                "rk4, ...), with the engine's qdd")
        added = getattr(system, "additions", [])
        if added:  # the engine steps its own model: nothing of ours reaches it
            raise SettingsError(getattr(system, "source", "simulate"), "integrator", self.name,
                                f"steps the engine's own model, which has none of "
                                f"{', '.join(added)}: run it through redysim's integrators "
                                "(ode45, dop853, rk4, ...)")
        if state is not None:
            raise SettingsError(getattr(system, "source", "simulate"), "state", "checkpoint",
                                "an engine's own stepper cannot be resumed from a checkpoint")
        return EngineStepper(self.engine, t0, y0, t_end, self.h, system.n_q,
                             integrator=self.info.name, rtol=self.rtol, atol=self.atol,
                             adaptive=self.info.adaptive)


class EngineStepper(OdeSolver):
    """A reference engine's own integrator behind the solver protocol
    (:class:`redysim.integrators.protocol.OdeSolver`). A fixed-step integrator takes one step a
    call of :meth:`step`, and its state is known at whole steps only (the sample times are whole
    multiples of ``h``: :meth:`NativeStepper.checked`); an adaptive one (``adaptive``) lands on
    each sample time ``t_stop`` by its own error control, one call of :meth:`step` per sample,
    and its steps, rejections and qdd calls are the engine's own count (-1 where it gives none)."""

    def __init__(self, engine, t0: float, y0, t_end: float, h: float | None, nq: int, *,
                 integrator: str | None = None, rtol: float | None = None,
                 atol: float | None = None, adaptive: bool = False):
        self.engine, self.nq, self.adaptive = engine, nq, adaptive
        self.h = float(h) if h else None
        self.t_end = float(t_end)
        self.counters = Counters(nfev=-1)  # the engine does not report its qdd calls
        self.t, self.y = float(t0), np.array(y0, dtype=float)
        self.t_old, self.y_old = self.t, self.y
        self._start = float(t0)
        if adaptive:
            engine.sim_reset(self.y[:nq], self.y[nq:], self.h, integrator=integrator,
                             rtol=rtol, atol=atol)
        else:
            engine.sim_reset(self.y[:nq], self.y[nq:], self.h, integrator=integrator)

    def step(self, t_stop: float | None = None) -> None:
        if self.adaptive:
            t_new = self.t_end if t_stop is None else min(float(t_stop), self.t_end)
            self.engine.sim_advance(t_new - self._start)
            steps, rejected, nfev = self.engine.sim_counts()
            self.counters.steps = max(steps, self.counters.steps + 1)
            self.counters.rejected, self.counters.nfev = rejected, nfev
        else:
            assert self.h is not None  # a fixed-step native integrator's h (checked)
            self.engine.step_once()
            self.counters.steps += 1
            t_new = self._start + self.counters.steps * self.h
        q, v = self.engine.sim_state()
        y = np.concatenate((q, v))
        if not np.isfinite(y).all():
            raise IntegrationError(f"non-finite state at t = {t_new:.6g}")
        self.t_old, self.y_old = self.t, self.y
        self.t, self.y = t_new, y

    def dense(self, ts) -> np.ndarray:
        ts = np.atleast_1d(ts)
        if np.abs(ts - self.t).max() > 1e-9 * max(1.0, self.t):
            raise IntegrationError("an engine's own stepper knows its state at whole steps "
                                   "only: sample at whole multiples of h")
        return np.tile(self.y, (ts.size, 1))

    def set_deadline(self, clock, deadline: float) -> None:
        """The CPU-time limit inside the engine's own adaptive advance, where it can stop
        between its own steps (:meth:`Engine.set_sim_deadline`)."""
        if self.adaptive:
            self.engine.set_sim_deadline(clock, deadline)


def import_engine(engine: str, package: str, module: str | None = None):
    """Import the engine's module or raise :class:`EngineUnavailable` naming the package."""
    try:
        return importlib.import_module(module or package)
    except Exception as exc:  # ImportError, or a broken binary wheel (OSError)
        raise EngineUnavailable(engine, package, f"{type(exc).__name__}: {exc}") from None


# --------------------------------------------------------------------------- the door
def as_model(model: Model | Case | Chain) -> Model:
    """The Model an adapter builds: ``model`` itself (a :class:`redysim.Model`, a Chain
    included), or a Case's chain. Raises TypeError for anything else."""
    if isinstance(model, Case):
        model = model.chain
    if isinstance(model, Model):  # a Chain is one
        return model
    raise TypeError(f"expected a redysim Model (a Chain is one), or a Case, got "
                    f"{type(model).__name__}")


# --------------------------------------------------------------------------- joints
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


def axis(kind: str, u) -> Axis:
    """The :class:`Axis` of kind "R" or "P" along the unit vector ``u``."""
    u = tuple(float(x) for x in u)
    # exactly +x, +y or +z (the rule of the core's coordinate-axis codes)
    plus = [j for j in range(3) if u[j] == 1.0 and u[j - 1] == u[j - 2] == 0.0]
    return Axis(kind, u, plus[0] if plus else None)


class JointAxes(NamedTuple):
    """Body k's joint: its type (R, P, U, S, ball or free), its elementary axes in order (none for
    a free or ball joint), the parent body (-1: the world), the placement (R (3, 3), p (3,)) of the
    joint's frame in the parent's frame, and the joint's and the body's names."""

    type: str
    axes: tuple[Axis, ...]
    parent: int = -1
    R: np.ndarray | None = None
    p: np.ndarray | None = None
    name: str = ""
    body: str = ""

    def describe(self) -> str:
        """E.g. "U = R about +y then R about +z", "free"."""
        if self.type in (FREE, BALL_JOINT):
            return self.type
        return f"{self.type} = " + " then ".join(a.describe() for a in self.axes)

    def where(self) -> str:
        """E.g. "body 'link2', joint 'joint2' (U = R about +y then R about +z)"."""
        return f"body {self.body!r}, joint {self.name!r} ({self.describe()})"


def joint_axes(model: Model | Case | Chain) -> list[JointAxes]:
    """Per body, its joint (:class:`JointAxes`, module docstring) from the model's own per-DOF
    tables (a Case or Chain is converted by :func:`as_model`). Raises ValueError on a DOF kind
    the adapters do not model (outside a free joint)."""
    model = as_model(model)
    out = []
    for k, jtype in enumerate(model.joint_types):
        axes = []
        if jtype not in (FREE, BALL_JOINT):
            for i in range(int(model.joint_voff[k]), int(model.joint_voff[k + 1])):
                kind = KIND_NAMES.get(int(model.dof_kind[i]))  # R or P; a BALL is not one
                if kind is None:
                    raise ValueError(f"body {model.body_names[k]!r}: DOF kind "
                                     f"{int(model.dof_kind[i])} outside a free joint")
                axes.append(axis(kind, model.dof_u[i]))
        out.append(JointAxes(jtype, tuple(axes), int(model.parent[k]),
                             np.array(model.placement_R[k], dtype=float),
                             np.array(model.placement_p[k], dtype=float),
                             model.joint_names[k], model.body_names[k]))
    return out


def tree_depth(model: Model) -> int:
    """The number of bodies on the longest path from the world to a leaf."""
    depth = np.zeros(model.n_bodies, dtype=np.int64)
    for k, p in enumerate(model.parent):
        depth[k] = 1 if p < 0 else depth[p] + 1
    return int(depth.max())


def depth_first(model: Model) -> list[int]:
    """The bodies in depth-first pre-order (each body's subtree follows it contiguously;
    children in the Model's order). The Model's own order only puts parents first."""
    children: list[list[int]] = [[] for _ in range(model.n_bodies)]
    roots = []
    for k, p in enumerate(model.parent):
        (roots if p < 0 else children[p]).append(k)
    order, stack = [], roots[::-1]
    while stack:
        k = stack.pop()
        order.append(k)
        stack.extend(children[k][::-1])
    return order


def build_warnings(engine) -> str:
    """What an engine wrote to stderr while its adapter built the model, as its adapter kept it
    (``build_warnings``: message -> how many bodies; a loop adapter's, of the tree engine it
    holds), as one line; ``""`` when it said nothing. DART's Inertia warns for a principal
    moment that is not > 0 (a thin rod about its axis), and uses it as given."""
    said = getattr(engine, "build_warnings", None) or \
        getattr(getattr(engine, "tree", None), "build_warnings", None) or {}
    return "; ".join(f"{w} ({n} bod{'ies' if n > 1 else 'y'})" for w, n in said.items())


def free_rotation(q, qs: int) -> np.ndarray:
    """The rotation of the free joint whose configuration starts at ``q[qs]`` (its quaternion,
    w first, normalised)."""
    quat = np.asarray(q[qs + 3:qs + 7], dtype=float)
    return quaternion_matrix(*(quat / np.linalg.norm(quat)))


def rotation_quaternion(R) -> np.ndarray:
    """The unit quaternion (w, x, y, z), w >= 0, of the rotation matrix R (Shepperd's method:
    the largest of 1 + trace, 1 + 2 R_ii - trace under the square root)."""
    R = np.asarray(R, dtype=float)
    t = np.trace(R)
    d = np.diag(R)
    i = int(np.argmax([t, *d]))
    if i == 0:
        s = 2.0 * math.sqrt(1.0 + t)
        quat = np.array([s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s,
                         (R[1, 0] - R[0, 1]) / s])
    else:
        a = i - 1
        b, c = (a + 1) % 3, (a + 2) % 3
        s = 2.0 * math.sqrt(1.0 + 2.0 * d[a] - t)
        quat = np.empty(4)
        quat[0] = (R[c, b] - R[b, c]) / s
        quat[1 + a] = s / 4
        quat[1 + b] = (R[b, a] + R[a, b]) / s
        quat[1 + c] = (R[c, a] + R[a, c]) / s
    quat /= np.linalg.norm(quat)
    return quat if quat[0] >= 0 else -quat


class FreeBlock(NamedTuple):
    """One free joint's conversion at a state (module docstring): the core's velocity slots
    ``vs:vs + 6`` are ``B y`` and its acceleration ``B ydot + c``, y the engine's velocity
    coordinates of the joint gathered into the core's slot order."""

    vs: int
    B: np.ndarray
    c: np.ndarray


def load_limits() -> dict[str, Any]:
    """The measured limits table ``references/limits.toml``."""
    with open(LIMITS_FILE, "rb") as fh:
        return tomllib.load(fh)


# --------------------------------------------------------------------------- the adapters
class EnginePackage:
    """An adapter's package: whether it imports, and its version (shared by the adapters,
    :class:`Engine`, and the loop adapters, ``redysim.references.loops``). Subclasses set ``name``,
    ``package``, ``module``."""

    name: ClassVar[str] = ""
    package: ClassVar[str] = ""  # the pip package that provides the engine
    module: ClassVar[str] = ""  # the module to import

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
    """Base class of the adapters (module docstring): one subclass per engine, built from a
    :class:`redysim.Model` (a Case or Chain is converted at the door, :func:`as_model`).

    ``cls(model, check_limits=True)`` imports the engine (:class:`EngineUnavailable` naming the
    package when it does not), refuses a model its :meth:`limits` refuse
    (:class:`EngineLimitExceeded` with the reason) and builds it (``_build``).

    A subclass sets ``name``, ``package``, ``module``, ``integrator`` and implements ``_build``
    and the hooks, which take and return the ENGINE's coordinates; the public methods check the
    sizes at the door (ValueError naming the argument) and convert:

    - ``_engine_state(q, v)`` -> (state, blocks): whatever the hooks need to set the
      configuration and one :class:`FreeBlock` per free joint (called only when the engine's
      coordinates are not the core's, ``identity`` False; default: q itself);
    - on that state, ``_qdd(state, y, tau_e)``, ``_mass_matrix(state)``, ``_bias(state, y)``,
      ``_energy(state, y)`` and ``_position(state, body, point)``, y and tau_e engine-ordered
      vectors of length n_v (tau_e None: no applied force);
    - the native stepper, in the core's coordinates: ``_sim_reset(q0, v0, h)``,
      ``_sim_step()``, ``_sim_state()`` -> (q, v); the integrator chosen and its settings are
      ``self.sim_integrator`` (a :class:`NativeIntegrator` of ``integrators``) and
      ``self.sim_settings`` (``h``, ``rtol``, ``atol``), set before ``_sim_reset`` is called.
      An adaptive integrator implements ``_sim_advance(t)`` (land on time t by its own error
      control) instead of ``_sim_step``; ``_sim_counts()`` -> (steps, rejected, nfev) where the
      engine reports them (-1 each where it does not); ``_settings()`` -> dict: the engine's
      flags and solver settings for the manifest (:meth:`manifest`).

    Attributes: ``model`` (the Model built), ``joints`` (:func:`joint_axes` of it), ``free``
    ((body, first q slot, first v slot) of each free joint), ``eidx`` (n_v,): the engine's index
    of each of the core's velocity slots (set by ``_build``, and ``qidx`` (n_q,) of the
    configuration slots by an engine whose configuration vector has the core's length; the
    identity unless the engine numbers them otherwise), ``identity``: True when there is no free
    joint and these maps are the identity, so that nothing is converted.
    """

    integrator: ClassVar[str] = ""  # the default native integrator: a key of ``integrators``
    # the engine's own time integrators, by name (NativeIntegrator); empty: the engine has none
    integrators: ClassVar[dict[str, NativeIntegrator]] = {}
    no_integrator: ClassVar[str] = ""  # why ``integrators`` is empty, in the engine's words
    depth_limited: ClassVar[bool] = False  # limits.toml's max_links is a body-tree depth
    # how the engine holds a model's couplings (Model.couplings: mimic joints) in its qdd, its
    # own construction; "" when it has none: ``no_couplings`` says why (in the engine's terms),
    # and then, with ``projects_couplings``, qdd is the engine's own M and bias restricted to
    # the coupled motion by the adapter (:meth:`_coupled_qdd`), else limits refuses the model
    couples: ClassVar[str] = ""
    no_couplings: ClassVar[str] = "no joint coupling built in this adapter"
    projects_couplings: ClassVar[bool] = True
    # how the engine's own integrators hold the couplings; "" when they do not (a coupled
    # model's native run is then refused, naming ``no_couplings``)
    couples_native: ClassVar[str] = ""
    # how the engine holds a model's armature (Model.armature: each joint's own inertia on the
    # diagonal of M); "" when it cannot (limits then refuses a model with armature, naming this
    # reason: never dropped silently)
    holds_armature: ClassVar[str] = ""
    no_armature: ClassVar[str] = "no joint armature built in this adapter"
    # False: the engine has no armature field, and the adapter holds it in the engine's qdd
    # from the engine's own M and bias, (M + diag(armature)) qdd = tau + phi (``holds_armature``
    # says so): the engine's own integrators step its model without it, so a native run of a
    # model with armature is refused by name (:meth:`no_native_armature`), and armature on a
    # free or ball joint (whose engine coordinates are not the core's) is refused by ``limits``
    armature_native: ClassVar[bool] = True
    # how the engine's own integrators hold a model's passive elements (Model.damping,
    # stiffness with spring_ref, gravcomp: forces of the model, not additions of a run); "" when
    # they cannot (its native stepping then refuses such a model, naming them: never dropped).
    # Its qdd stays the rigid body's map tau -> qdd, as the core's forward_dynamics; a run
    # through redysim's integrators applies them around it (System)
    holds_passive: ClassVar[str] = ""
    # how the engine builds a ball joint (q a unit quaternion (w, x, y, z), v the body's
    # angular velocity in its own frame); "" when it cannot (limits then refuses a model with
    # one, naming the joint and this reason)
    holds_ball: ClassVar[str] = ""
    no_ball: ClassVar[str] = "no ball joint built in this adapter"

    def __init__(self, model: Model | Case | Chain, *, check_limits: bool = True):
        self.lib = import_engine(self.name, self.package, self.module)
        self.model = as_model(model)
        if check_limits:
            lim = self.limits(self.model)
            if not lim.ok:
                raise EngineLimitExceeded(f"{self.name}: {lim.reason}")
        m = self.model
        self.joints = joint_axes(m)
        self.free = [(k, int(m.joint_qoff[k]), int(m.joint_voff[k]))
                     for k, j in enumerate(self.joints) if j.type == FREE]
        self.balls = [(k, int(m.joint_qoff[k]), int(m.joint_voff[k]))
                      for k, j in enumerate(self.joints) if j.type == BALL_JOINT]
        # the coordinates of the joints that are neither free nor ball: the same numbers in q
        # and in v
        jointed = [k for k, j in enumerate(self.joints) if j.type not in (FREE, BALL_JOINT)]
        self._qslots = np.array([i for k in jointed
                                 for i in range(m.joint_qoff[k], m.joint_qoff[k + 1])], dtype=int)
        self._vslots = np.array([i for k in jointed
                                 for i in range(m.joint_voff[k], m.joint_voff[k + 1])], dtype=int)
        self.eidx = np.arange(m.n_v)
        self.identity = False
        self._build()
        # the engine's coordinates are the core's: nothing to convert (every chain, every engine)
        qidx = getattr(self, "qidx", None)
        self.identity = (not self.free and not self.balls
                         and bool(np.array_equal(self.eidx, np.arange(m.n_v)))
                         and (qidx is None or bool(np.array_equal(qidx, np.arange(m.n_q)))))

    # ----------------------------------------------------------------------- limits
    @classmethod
    def limits(cls, model: Model | Case | Chain) -> Limits:
        """Can this engine take the model (a Case or Chain: its Model)? Decided before anything
        is built: its size against the measured limits in ``references/limits.toml``, then its
        joints and bodies (:meth:`unsupported`). Raises TypeError for a ``model`` that is not a
        Model, Case or Chain."""
        model = as_model(model)
        entry = load_limits()["engine"][cls.name]
        n = model.n_v
        links = tree_depth(model) if cls.depth_limited else model.n_bodies
        max_dof, max_links = int(entry["max_dof"]), int(entry.get("max_links", 10**9))
        if n > max_dof or links > max_links:
            what = (f"{n:,} DOF" if n > max_dof else
                    f"a body tree {links:,} deep" if cls.depth_limited else f"{links:,} bodies")
            return Limits(False, f"{cls.name}: {what} exceeds its limit on this machine "
                                 f"(max {max_dof:,} DOF, {max_links:,} links): {entry['stops']}")
        try:
            joints = joint_axes(model)
        except ValueError as exc:
            return Limits(False, f"{cls.name}: {exc}")
        balls = [j for j in joints if j.type == BALL_JOINT]
        if balls and not cls.holds_ball:
            return Limits(False, f"{cls.name}: {balls[0].where()}: a ball joint, which this "
                                 f"engine does not build: {cls.no_ball}")
        why = cls.unsupported(model, joints)
        if why:
            return Limits(False, f"{cls.name}: {why}")
        if np.any(model.armature) and cls.holds_armature and not cls.armature_native:
            for k, j in enumerate(joints):
                a = model.armature[model.joint_voff[k]:model.joint_voff[k + 1]]
                if j.type in (FREE, BALL_JOINT) and np.any(a):
                    return Limits(False, f"{cls.name}: the {j.type} joint of body {j.body!r} "
                                         f"has armature ({', '.join(f'{x:g}' for x in a)}): "
                                         f"{cls.no_armature}, and the adapter adds armature "
                                         f"on 1-DOF axes only (engine and core coordinates "
                                         f"differ on a {j.type} joint)")
        if np.any(model.armature) and not cls.holds_armature:
            j = int(np.flatnonzero(model.armature)[0])
            return Limits(False, f"{cls.name}: the model has armature (a joint's own inertia, "
                                 f"armature[{j}] = {float(model.armature[j]):g}), which this "
                                 f"engine does not build: {cls.no_armature}")
        if model.couplings and not cls.couples and not cls.projects_couplings:
            return Limits(False, f"{cls.name}: the model couples joints "
                                 f"({', '.join(c.follower for c in model.couplings)} follow "
                                 f"others: mimic joints), which this engine does not build: "
                                 f"{cls.no_couplings}")
        return Limits(True, "")

    @classmethod
    def unsupported(cls, model: Model, joints: list[JointAxes]) -> str:
        """Why this engine cannot build the model ("" when it can), naming the body and joint.
        Every adapter builds any sequence of R and P axes and a free joint unless it overrides
        this."""
        return ""

    # ----------------------------------------------------------------------- the door
    def _vec(self, name: str, x, size: str, optional: bool = False) -> np.ndarray | None:
        """x as a float vector of the model's length ``size`` ("n_q" or "n_v"); raises
        ValueError naming it."""
        if x is None:
            if optional:
                return None
            raise ValueError(f"{name} is required")
        a = np.asarray(x, dtype=float)
        n = getattr(self.model, size)
        if a.shape != (n,):
            raise ValueError(f"{name} has shape {a.shape}; the model has {size} = {n}")
        return a

    def _to_engine(self, x, blocks) -> np.ndarray:
        """A velocity or force in the core's coordinates as the engine's (B^T per free joint,
        then scattered to the engine's order)."""
        if self.identity:
            return x
        g = np.array(x, dtype=float)
        for b in blocks:
            g[b.vs:b.vs + 6] = b.B.T @ g[b.vs:b.vs + 6]
        y = np.zeros(self.model.n_v)
        y[self.eidx] = g
        return y

    def _from_engine(self, y, blocks) -> np.ndarray:
        """An engine-ordered velocity-like vector in the core's coordinates (B per free
        joint), a new array (never a view of the engine's memory). Raises ValueError when the
        engine's vector is not one value per velocity coordinate."""
        if self.identity:
            return np.array(y, dtype=float)
        n = self.model.n_v
        g = np.asarray(y, dtype=float)
        if g.shape != (n,):
            raise ValueError(f"{self.name}: the engine answered a vector of shape {g.shape}; "
                             f"the model has n_v = {n}")
        g = g[self.eidx]
        for b in blocks:
            g[b.vs:b.vs + 6] = b.B @ g[b.vs:b.vs + 6]
        return g

    def _gim_from_engine(self, M, blocks) -> np.ndarray:
        """An engine-ordered mass matrix in the core's coordinates (B I B^T per free joint), a
        new array."""
        if self.identity:
            return np.array(M, dtype=float)
        n = self.model.n_v
        M = np.asarray(M, dtype=float)
        if M.shape != (n, n):
            raise ValueError(f"{self.name}: the engine answered a mass matrix of shape "
                             f"{M.shape}; the model has n_v = {n}")
        M = M[np.ix_(self.eidx, self.eidx)]
        if blocks:
            T = np.eye(n)
            for b in blocks:
                T[b.vs:b.vs + 6, b.vs:b.vs + 6] = b.B
            M = T @ M @ T.T
        return M

    def _c(self, blocks) -> np.ndarray:
        c = np.zeros(self.model.n_v)
        for b in blocks:
            c[b.vs:b.vs + 6] = b.c
        return c

    def _scatter(self, q) -> np.ndarray:
        """An engine position vector (n_v,) holding the coordinates of every joint that is not
        free at its engine slot (a free joint's slots left zero, for the engine to fill)."""
        qe = np.zeros(self.model.n_v)
        qe[self.eidx[self._vslots]] = q[self._qslots]
        return qe

    def _gather(self, qe) -> np.ndarray:
        """The core's q (n_q,) with the coordinates of every joint that is not free taken from
        the engine position vector ``qe`` (a free joint's slots left zero)."""
        q = np.zeros(self.model.n_q)
        q[self._qslots] = np.asarray(qe, dtype=float)[self.eidx[self._vslots]]
        return q

    def _state(self, q, v):
        """(state, blocks) at (q, v): q itself and no blocks when the engine's coordinates are
        the core's (``identity``), else the engine's ``_engine_state``."""
        return (q, []) if self.identity else self._engine_state(q, v)

    # ----------------------------------------------------------------------- public API
    def qdd(self, q, v, tau=None) -> np.ndarray:
        """vdot (n_v,) from I(q) vdot = phi(q, v, tau); tau None: no joint force."""
        q, v = self._vec("q", q, "n_q"), self._vec("v", v, "n_v")
        tau = self._vec("tau", tau, "n_v", optional=True)
        if self.model.couplings and not self.couples:
            return self._coupled_qdd(q, v, tau)
        state, blocks = self._state(q, v)
        tau_e = None if tau is None else self._to_engine(tau, blocks)
        out = self._from_engine(self._qdd(state, self._to_engine(v, blocks), tau_e), blocks)
        return out + self._c(blocks) if blocks else out

    @classmethod
    def holds_couplings_in(cls, info: NativeIntegrator) -> bool:
        """Whether the engine's own integrator ``info`` holds a model's couplings (default: all
        of them when ``couples_native`` says how, none otherwise)."""
        return bool(cls.couples_native)

    @classmethod
    def coupling(cls) -> str:
        """How this engine's qdd holds a model's couplings: its own construction (``couples``),
        or the adapter's projection of the engine's M and bias and why (``no_couplings``)."""
        if cls.couples:
            return cls.couples
        return (f"the engine's own M and bias restricted to the coupled motion by the adapter, "
                f"qdd = G (G^T M G)^-1 G^T phi (v = G v_independent), as it has none: "
                f"{cls.no_couplings}")

    def _coupled_qdd(self, q, v, tau) -> np.ndarray:
        """qdd of a coupled model from the engine's own mass matrix and bias (its CRBA and
        RNEA, whatever it calls them), for an engine with no coupling of its own: the motions
        that keep the couplings are v = G u (u the velocities of the joints that follow none,
        a follower's row m times its leader's), the couplings' forces do no work on them, so
        G^T M G u' = G^T phi and qdd = G u' (the couplings are linear: no velocity term). The
        state is taken as given (as the core's right-hand side takes it): a follower's rows are
        exactly m times its leader's."""
        m = self.model
        _, _, fv, lv, mult, _ = m.coupling_index
        free = np.setdiff1d(np.arange(m.n_v), fv)
        G = np.zeros((m.n_v, free.size))
        G[free, np.arange(free.size)] = 1.0
        for f, ld, mu in zip(fv, lv, mult, strict=True):
            G[f] = mu * G[ld]
        M = self.mass_matrix(q)
        phi = self.bias(q, v) if tau is None else self.bias(q, v) + tau
        return G @ np.linalg.solve(G.T @ M @ G, G.T @ phi)

    def mass_matrix(self, q) -> np.ndarray:
        """The GIM I(q), (n_v, n_v), symmetric."""
        q = self._vec("q", q, "n_q")
        state, blocks = self._state(q, np.zeros(self.model.n_v))
        return self._gim_from_engine(self._mass_matrix(state), blocks)

    def bias(self, q, v) -> np.ndarray:
        """phi (n_v,) with tau = 0, as ``redysim.phi``."""
        q, v = self._vec("q", q, "n_q"), self._vec("v", v, "n_v")
        state, blocks = self._state(q, v)
        phi = self._from_engine(self._bias(state, self._to_engine(v, blocks)), blocks)
        if blocks:
            phi = phi + self._gim_from_engine(self._mass_matrix(state), blocks) @ self._c(blocks)
        return phi

    def energy(self, q, v) -> tuple[float, float]:
        """(T, V) [J]."""
        q, v = self._vec("q", q, "n_q"), self._vec("v", v, "n_v")
        state, blocks = self._state(q, v)
        T, V = self._energy(state, self._to_engine(v, blocks))
        return float(T), float(V)

    def position(self, q, frame: str = "tip") -> np.ndarray:
        """World position (3,) [m] of the model's frame ``frame`` (``model.frames``: a body and
        a point in its frame) at q. Raises ValueError for a frame the model does not have."""
        m = self.model
        if frame not in m.frames:
            raise ValueError(f"{self.name}: the model {m.name!r} has no frame {frame!r}; its "
                             f"frames: {', '.join(map(repr, m.frames)) or 'none'}")
        body, point = m.frames[frame]
        q = self._vec("q", q, "n_q")
        state, _ = self._state(q, np.zeros(m.n_v))
        return np.array(self._position(state, int(body), np.array(point, dtype=float)),
                        dtype=float)

    def tip(self, q) -> np.ndarray:
        """World position (3,) of the frame "tip" (a chain's distal end)."""
        return self.position(q, "tip")

    def no_native_passive(self) -> str:
        """Why the engine's own integrators cannot step this model ("" when they can): it has
        passive elements (:attr:`Model.damping`, ...) the engine's native model does not hold
        (:attr:`holds_passive`)."""
        m = self.model
        if m.gravcomp_loads.shape[0]:  # (no engine's body holds two fractions of its weight)
            return (f"{self.name}'s own integrators step its model, whose bodies hold one "
                    "gravity compensation fraction each, not the model's gravcomp_loads (a "
                    "fused body's parts of other fractions, each at its own centre of mass)")
        if not m.has_passive:
            return ""
        if self.holds_passive:
            why = self.passive_unheld()
            return (f"{self.name}'s own integrators step its model, which holds the model's "
                    f"passive elements ({self.holds_passive}) but not {why}") if why else ""
        held = [key for key in ("damping", "stiffness", "gravcomp") if np.any(getattr(m, key))]
        return (f"{self.name}'s own integrators step its model, which does not hold the "
                f"model's {', '.join(held)} (its qdd is the rigid body's, tau -> qdd)")

    def passive_unheld(self) -> str:
        """Which of the model's passive elements the engine's native model does not hold and
        why, naming the joint or body ("" when it holds them all), for an engine that holds
        them (:attr:`holds_passive`) element by element; by default it holds them all."""
        return ""

    def passive_on_free(self) -> str:
        """The first free or ball joint with damping (or a spring), named ("" when none):
        the engines whose native passive elements act on 1-DOF joints only."""
        m = self.model
        for k, jt in enumerate(m.joint_types):
            if jt in (FREE, BALL_JOINT):
                sl = slice(int(m.joint_voff[k]), int(m.joint_voff[k + 1]))
                if np.any(m.damping[sl]) or np.any(m.stiffness[sl]):
                    return (f"the damping of the {jt} joint {m.joint_names[k]!r} (body "
                            f"{m.body_names[k]!r}): this adapter puts damping on 1-DOF joints "
                            f"only (the engine's coordinates of a {jt} joint are not the core's)")
        return ""

    def no_native_armature(self) -> str:
        """Why the engine's own integrators cannot step this model for its armature ("" when
        they can): the engine has no armature field (:attr:`armature_native` False), so the
        adapter holds it in the qdd only."""
        m = self.model
        if self.armature_native or not np.any(m.armature):
            return ""
        j = int(np.flatnonzero(m.armature)[0])
        return (f"{self.name}'s own integrators step its model, which has no armature "
                f"(armature[{j}] = {float(m.armature[j]):g}: {self.no_armature}); its qdd holds "
                f"it ({self.holds_armature})")

    @property
    def armature_e(self) -> np.ndarray:
        """The model's armature in the engine's velocity order (n_v,), zero on a free or ball
        joint (which ``limits`` refuses with armature when the engine holds it in its qdd
        only)."""
        a = np.zeros(self.model.n_v)
        a[self.eidx[self._vslots]] = self.model.armature[self._vslots]
        return a

    def stepper(self, name: str | None = None, *, h: float | None = None,
                rtol: float | None = None, atol: float | None = None) -> NativeStepper:
        """The engine's own integrator ``name`` (None: its default) as a run's stepper
        (:class:`NativeStepper`): ``Simulator(model, t_end, integrator=eng.stepper("rk4",
        h=1e-3))``. Raises ValueError naming the engine's integrators when it has no such one."""
        return NativeStepper(self, name, h=h, rtol=rtol, atol=atol)

    def native_integrator(self, name: str | None = None) -> NativeIntegrator:
        """The engine's own integrator ``name`` (None or "": its default, ``integrator``).
        Raises ValueError naming the engine's integrators when it has no such one (or none)."""
        if not self.integrators:
            why = f" ({self.no_integrator})" if self.no_integrator else ""
            raise ValueError(
                f"engine {self.name!r} has no time integrator of its own{why}: run it through "
                f"redysim's integrators, its qdd in ours, e.g. `redysim simulate CASE --engine "
                f"{self.name} --integrator ode45` (Python: simulator(model, t_end, "
                f"qdd=eng.qdd, integrator='ode45'))")
        name = name or self.integrator
        if name not in self.integrators:
            raise ValueError(f"engine {self.name!r} has no integrator {name!r}; its own: "
                             f"{', '.join(self.integrators)}")
        return self.integrators[name]

    def simulate(self, q0, v0, t_end: float, h: float, *, every: int = 1,
                 integrator: str | None = None, rtol: float | None = None,
                 atol: float | None = None) -> Trajectory:
        """The passive motion (no joint force) from (q0, v0) to t_end with the engine's own
        integrator ``integrator`` (default: ``self.integrator``). A fixed-step one takes the
        step h; an adaptive one (``rtol``, ``atol``) lands on the grid of h by its own control.
        Every ``every``-th grid point is kept (and the start and the last). Raises ValueError
        for h <= 0, t_end < 0 (or either not finite), every < 1 or an unknown integrator."""
        q0, v0 = self._vec("q0", q0, "n_q"), self._vec("v0", v0, "n_v")
        steps = self._steps(t_end, h, every)
        ts, qs, vs = [0.0], [q0.copy()], [v0.copy()]
        self.sim_reset(q0, v0, h, integrator=integrator, rtol=rtol, atol=atol)
        adaptive = self.sim_integrator.adaptive
        for i in range(1, steps + 1):
            if adaptive:
                if i % every and i != steps:
                    continue
                self.sim_advance(i * h)
            else:
                self._sim_step()
            if i % every == 0 or i == steps:
                q, v = self._sim_state()
                ts.append(i * h)
                qs.append(q)
                vs.append(v)
        return Trajectory(np.array(ts), np.array(qs), np.array(vs), self.sim_integrator.name)

    @staticmethod
    def _steps(t_end, h, every) -> int:
        if not (math.isfinite(h) and math.isfinite(t_end) and h > 0 and t_end >= 0):
            raise ValueError(f"need finite h > 0 and t_end >= 0, got h={h}, t_end={t_end}")
        if isinstance(every, bool) or not isinstance(every, int | np.integer) or every < 1:
            raise ValueError(f"every must be a whole number >= 1, got {every!r}")
        return int(round(t_end / h))

    def sim_reset(self, q0, v0, h: float | None = None, *, integrator: str | None = None,
                  rtol: float | None = None, atol: float | None = None) -> None:
        """Set the native stepper's state (q0, v0) at t = 0 and its integrator (default
        ``self.integrator``): a fixed-step one takes the step h (required), an adaptive one
        ``rtol`` (required) and ``atol`` (default ``rtol``), and h, when given, as its largest
        step. Raises ValueError naming the bad setting."""
        info = self.native_integrator(integrator)
        if self.model.couplings and not self.holds_couplings_in(info):
            raise ValueError(
                f"engine {self.name!r}'s own integrator {info.name!r} does not hold the "
                f"model's couplings ({', '.join(c.follower for c in self.model.couplings)} "
                f"follow others): {self.no_couplings}; run its qdd, which does, in redysim's "
                f"integrators (--integrator ode45)")
        why = self.no_native_passive()
        if why:
            raise ValueError(why)
        why = self.no_native_armature()
        if why:
            raise ValueError(why + ": run its qdd in redysim's integrators (--integrator ode45)")
        if info.adaptive:
            if rtol is None or not (math.isfinite(rtol) and rtol > 0):
                raise ValueError(f"{self.name} integrator {info.name!r} is adaptive: give "
                                 f"rtol > 0, got {rtol!r}")
            atol = rtol if atol is None else atol
            if not (math.isfinite(atol) and atol > 0):
                raise ValueError(f"{self.name} integrator {info.name!r}: atol must be > 0, got "
                                 f"{atol!r}")
            if h is not None:
                self._steps(0.0, h, 1)
        else:
            if rtol is not None or atol is not None:
                raise ValueError(f"{self.name} integrator {info.name!r} is fixed-step: it takes "
                                 "a step h, not tolerances")
            if h is None:
                raise ValueError(f"{self.name} integrator {info.name!r} is fixed-step: give its "
                                 "step h")
            self._steps(0.0, h, 1)
        self.sim_integrator = info
        self.sim_settings = {"h": h, "rtol": rtol, "atol": atol}
        self.sim_t = 0.0
        self._sim_steps = 0
        self._sim_reset(self._vec("q0", q0, "n_q"), self._vec("v0", v0, "n_v"), h)

    def step_once(self) -> None:
        """One step of a fixed-step native integrator from the stepper's state (set by
        :meth:`sim_reset`)."""
        if self.sim_integrator.adaptive:
            raise ValueError(f"{self.name} integrator {self.sim_integrator.name!r} is adaptive: "
                             "advance it to a time (sim_advance), not by a step")
        self._sim_step()
        self._sim_steps += 1
        self.sim_t = self._sim_steps * self.sim_settings["h"]

    # (clock, deadline): the CPU-time limit inside the native stepper's own advance
    _deadline: tuple = (None, math.inf)

    def set_sim_deadline(self, clock, deadline: float) -> None:
        """A CPU-time limit inside the native stepper's own advance: an adaptive integrator
        lands on a sample time by its own steps, which one call from Python cannot check. Once
        ``clock()`` passes ``deadline``, an engine that can stop between its own steps (Drake: a
        monitor; Exudyn: a pre-step function) stops there and :meth:`sim_advance` raises
        TimeoutError; ``math.inf``: no limit (the default).
        :class:`redysim.simulation.Simulator` sets it from a run's ``max_cpu_s`` and clears it
        after the run."""
        self._deadline = (clock, float(deadline))

    def _past_deadline(self) -> bool:
        clock, deadline = self._deadline
        return clock is not None and math.isfinite(deadline) and clock() > deadline

    def sim_advance(self, t: float) -> None:
        """Advance the native state to time t: an adaptive integrator lands on t by its own
        control; a fixed-step one takes whole steps to it (ValueError when t is not a whole
        number of steps from the start, or lies behind the state)."""
        if not t >= self.sim_t:
            raise ValueError(f"{self.name}: cannot advance to t = {t!r}, behind the state's "
                             f"t = {self.sim_t!r}")
        if self.sim_integrator.adaptive:
            if t > self.sim_t:
                self._sim_advance(float(t))
                self.sim_t = float(t)
            return
        h = self.sim_settings["h"]
        k = t / h
        if abs(k - round(k)) > 1e-6:
            raise ValueError(f"{self.name} integrator {self.sim_integrator.name!r} is "
                             f"fixed-step: t = {t!r} is not a whole number of steps h = {h:g}")
        while self._sim_steps < round(k):
            self.step_once()

    def sim_state(self) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) of the native stepper now, in the core's coordinates (new arrays)."""
        return self._sim_state()

    def sim_counts(self) -> tuple[int, int, int]:
        """(steps, rejected steps, qdd evaluations) of the native integrator since
        :meth:`sim_reset`, as the engine reports them; -1 for what it does not report (a
        fixed-step integrator's steps are always known)."""
        steps, rejected, nfev = self._sim_counts()
        if not self.sim_integrator.adaptive and steps < 0:
            steps = self._sim_steps
        return int(steps), int(rejected), int(nfev)

    def manifest(self) -> dict[str, Any]:
        """Everything a fair comparison must know about how this engine ran: its name and
        package version, the native integrator and its settings (after :meth:`sim_reset`),
        and the adapter's flags and solver settings (``_settings``: stages disabled, solver
        iterations, tolerances); for a coupled model, how its qdd holds the couplings."""
        info = getattr(self, "sim_integrator", None)
        out: dict[str, Any] = {"engine": self.name, "package": self.package,
                               "version": self.version}
        if info is not None:
            out.update(integrator=info.name, integrator_what=info.what,
                       adaptive=info.adaptive, integrator_note=info.note,
                       **{k: v for k, v in self.sim_settings.items() if v is not None})
        out.update(self._settings())
        if self.model.couplings:  # how its qdd holds them: its own, or the adapter's projection
            out["couplings"] = self.coupling()
        return out

    def __repr__(self) -> str:
        m = self.model
        return f"{type(self).__name__}({m.name!r}, {m.n_bodies} bodies, n_v = {m.n_v})"

    # ----------------------------------------------------------------------- hooks
    def _build(self) -> None:
        raise NotImplementedError

    def _engine_state(self, q, v):
        return q, []

    def _qdd(self, state, y, tau_e):
        raise NotImplementedError

    def _mass_matrix(self, state):
        raise NotImplementedError

    def _bias(self, state, y):
        raise NotImplementedError

    def _energy(self, state, y):
        raise NotImplementedError

    def _position(self, state, body: int, point: np.ndarray):
        raise NotImplementedError

    def _sim_reset(self, q0, v0, h):
        raise NotImplementedError

    def _sim_step(self):
        raise NotImplementedError

    def _sim_state(self):
        raise NotImplementedError

    def _sim_advance(self, t: float) -> None:
        raise NotImplementedError(f"{self.name} has no adaptive integrator")

    def _sim_counts(self) -> tuple[int, int, int]:
        return -1, -1, -1

    def _settings(self) -> dict[str, Any]:
        return {}
