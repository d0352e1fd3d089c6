"""Simulate a chain or a model from a state: the motion, the energy balance, the centre of mass.

:func:`simulate` integrates dy/dt = (dq/dt, vdot) with y = (q, v), vdot from
:func:`redysim.forward_dynamics` (RGE-A on the tree, or GE-N / RGE-N) and dq/dt = v, except for a
free joint, whose quaternion moves as dq/dt = q (x) [0; w_body] / 2 (docs/design.md, "Kinematic
trees"). Any of :data:`redysim.integrators.explicit.INTEGRATORS` steps it; ours (ode45, dop853, rk4)
in compiled code (:class:`redysim.integrators.explicit.CompiledSolver`; free joints, damping,
couplings, loops and a chain's tip force included, not other forces), and the implicit
midpoint
(:mod:`redysim.integrators.implicit`) with a chain's tension
preconditioner. A quaternion integrated so drifts off the unit sphere by the integrator's error;
after every accepted step it is projected back (divided by its norm; so are the samples interpolated
between steps), the largest norm error seen before a projection is reported, and the kernels read
any quaternion's direction only (so a stage's slightly-off quaternion is harmless).

The energy E = T + V is sampled with the motion; with no joint torques it is conserved, and its
change per unit mass delta_M = (E - E0) / M (the paper's Eq. 11) measures the integration error.
The centre of mass is sampled too: in a free fall (a floating base, no contact) it follows
c(t) = c0 + cdot0 t + g t^2 / 2 exactly, a check that needs no reference solution.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple, cast

import numpy as np

from redysim.algorithms._kernels.planar import planar_tip_torques
from redysim.algorithms._kernels.rk_run import (
    configuration_rate,
    coupled_qdd,
    couplings_of,
    no_couplings,
    project_couplings,
    project_quaternions,
    spatial_tip_torques,
)
from redysim.algorithms.dynamics import check_coupled, check_state, energy, forward_dynamics
from redysim.algorithms.loads import check_force, tip_force_potential, tip_force_torques
from redysim.algorithms.loops import NEAR_CHANGE_POINT
from redysim.algorithms.workspace import Workspace
from redysim.errors import SettingsError, StateError
from redysim.integrators.explicit import (
    ALIASES,
    DEFAULT_ATOL,
    DEFAULT_METHOD,
    DEFAULT_RTOL,
    FIXED_STEP,
    IMPLICIT,
    INTEGRATORS,
    TABLEAU_NAMES,
    CompiledSolver,
    advance,
    canonical,
    check_settings,
    compile_kernels,
    make_solver,
    sample_times,
)
from redysim.integrators.implicit import TensionPreconditioner
from redysim.integrators.implicit import compile_kernels as implicit_kernels
from redysim.integrators.protocol import Counters, IntegrationError, OdeSolver, SolverState
from redysim.model.tree import FREE, Model

DEFAULT_SAMPLES = 10  # samples over the horizon when no interval is given
NATIVE = "native"  # the integrator of a reference engine's own stepper (Simulator, engine=)
QUATERNION_TOL = 1e-6  # | |q0's quaternion| - 1 | allowed (then normalised); more is refused
NUMBERS = (int, float, np.integer, np.floating)  # a setting's number types (not bool)
BATCH_SETTINGS = ("integrator", "rtol", "atol", "h", "sample", "damping", "max_cpu_s")


def is_native(integrator) -> bool:
    """Whether ``integrator`` names a reference engine's own integrator: ``"native"`` (the
    engine's default) or ``"native:NAME"`` (one of the engine's ``integrators``)."""
    return isinstance(integrator, str) and (integrator == NATIVE or
                                            integrator.startswith(NATIVE + ":"))


def native_name(integrator: str) -> str | None:
    """The engine's integrator named by ``"native:NAME"`` (NAME), or None for ``"native"``."""
    return integrator.split(":", 1)[1] if ":" in integrator else None


def _check_simulate_settings(source: str, t_end, *, integrator, rtol, atol, h, sample,
                             damping, progress=None, max_cpu_s=None,
                             adaptive_native: bool = False) -> tuple[str, bool]:
    """Check simulate's settings, naming the bad one (SettingsError); return the canonical
    integrator name and whether it is fixed-step (an engine's own stepper, NATIVE, is unless
    ``adaptive_native``: an engine's error-controlled integrator, which takes tolerances)."""
    if not isinstance(integrator, str):
        raise SettingsError(source, "integrator", integrator, "must be an integrator's name; "
                            f"known: {', '.join((*INTEGRATORS, *ALIASES, NATIVE))}")
    if t_end is None:
        raise SettingsError(source, "t_end", None, "missing: the horizon [s]")
    native = is_native(integrator)
    integrator = integrator if native else canonical(integrator)
    fixed = integrator in FIXED_STEP or (native and not adaptive_native)
    if fixed and h is None:
        raise SettingsError(source, "h", h, f"{integrator} is a fixed-step integrator: give "
                            "its step h [s]")
    if native and adaptive_native:
        check_settings(source, method=None, rtol=rtol, atol=atol, h=None, t_end=t_end,
                       sample=sample)
        if h is not None:  # the largest step it may take
            check_settings(source, method=None, h=h, t_end=t_end)
    else:
        check_settings(source, method=None if native else integrator,
                       rtol=None if fixed else rtol, atol=None if fixed else atol, h=h,
                       t_end=t_end, sample=sample)
    if isinstance(damping, bool) or not isinstance(damping, NUMBERS) or \
            not (math.isfinite(damping) and damping >= 0):
        shown = float(damping) if isinstance(damping, NUMBERS[2:]) else damping
        raise SettingsError(source, "damping", shown, "must be a finite number >= 0: the "
                            "viscous torque -damping * v at every joint [N m s] (0: none)")
    _check_run_settings(source, progress=progress, max_cpu_s=max_cpu_s)
    return integrator, fixed


def _check_run_settings(source: str, *, progress=None, max_cpu_s=None) -> None:
    """Check a run's hooks and limit (Simulator.run's), naming the bad one (SettingsError)."""
    if max_cpu_s is not None and (isinstance(max_cpu_s, bool) or not isinstance(
            max_cpu_s, NUMBERS) or not (math.isfinite(max_cpu_s) and max_cpu_s > 0)):
        shown = float(max_cpu_s) if isinstance(max_cpu_s, NUMBERS[2:]) else max_cpu_s
        raise SettingsError(source, "max_cpu_s", shown, "must be None or a finite number of "
                            "seconds > 0")
    if progress is not None and not callable(progress):
        raise SettingsError(source, "progress", progress, "must be None or a callable "
                            "progress(t, t_end, steps, wall_s)")


@dataclass
class Simulation:
    """Samples at ``t`` (m,): ``q`` (m, n_q), ``v`` (m, n_v), ``energy`` (m,) [J], ``delta_M``
    (m,) [J/kg], ``com`` (m, 3) [m]; the run's counts and times; ``status`` 0 done, 1 stopped, -1
    failed (``message`` says why); ``quaternion_error``: the largest | |q| - 1 | of a free joint's
    quaternion before its projection after a step (0 without one). With loops: ``forces`` (m, rows)
    the loop forces at the samples [N], ``residual_q`` [m] and ``residual_v`` [m/s] the largest loop
    residuals met after a step, before its projection; ``near_change_point``: the time [s] of the
    step at which the motion came nearest a change point (J M^-1 J^T's singular values within
    :data:`redysim.algorithms.loops.NEAR_CHANGE_POINT` of each other: a configuration where the
    mechanism can switch branches), None when it came nowhere near one; a run that then failed or
    stopped says so in its ``message``. ``observed``: name -> (m, k) rows of each observer
    (:class:`Simulator`); ``y_final``: (q, v) at the last sample; ``E0``: the energy at t = 0 (the
    reference of ``delta_M``; with a resumed run's skipped samples, not the first sample's). ``q``
    and ``v`` have no rows when the run kept no
    states (``keep_states=False``)."""

    name: str
    t: np.ndarray
    q: np.ndarray
    v: np.ndarray
    energy: np.ndarray
    delta_M: np.ndarray
    com: np.ndarray
    steps: int
    rejected: int
    nfev: int
    status: int
    message: str
    cpu_s: float
    wall_s: float
    jit_s: float
    quaternion_error: float
    forces: np.ndarray | None = None
    residual_q: float = 0.0
    residual_v: float = 0.0
    near_change_point: float | None = None
    observed: dict = field(default_factory=dict)
    y_final: np.ndarray | None = None
    E0: float = math.nan


class _Motion:
    """The right-hand side (dq/dt, vdot) of a system, with its workspace: vdot from the core's
    forward dynamics (``method``) or the ``qdd(q, v, tau)`` provider, with the generalized
    forces ``tau(t, q, v)`` and a viscous ``damping`` torque -damping * v at every joint; with
    ``loops`` the loops closed (:class:`redysim.algorithms.loops.ClosedLoops`)."""

    def __init__(self, system: Model, loops=None, damping: float = 0.0, *, qdd=None,
                 method: str = "rge-a", tau=None, tip_force=None):
        self.system = system
        self.loops, self.damping = loops, float(damping)
        self.qdd, self.method, self.tau = qdd, method, tau
        self.tip_force = tip_force  # (3,) or None: a constant world force at a chain's tip
        self.length = (None if tip_force is None
                       else np.ascontiguousarray(system.length, dtype=float))
        self.residual_q = self.residual_v = 0.0  # the largest met after a step
        self.ws = Workspace(system)  # the RHS's, and between steps the samples' and observers'
        self.nq, self.nv = system.n_q, system.n_v
        # a free joint's (q index of x, v index of its linear velocity); every other coordinate
        # moves as its velocity
        free = [(int(system.joint_qoff[k]), int(system.joint_voff[k]))
                for k, t in enumerate(system.joint_types) if t == FREE]
        self.free = free
        plain_q: list[int] = []
        plain_v: list[int] = []
        qoff = system.joint_qoff
        voff = system.joint_voff
        for k in range(qoff.shape[0] - 1):
            if (int(qoff[k]), int(voff[k])) in free:
                continue
            plain_q.extend(range(qoff[k], qoff[k + 1]))
            plain_v.extend(range(voff[k], voff[k + 1]))
        self.plain_q = np.array(plain_q, dtype=np.int64)
        self.plain_v = np.array(plain_v, dtype=np.int64)
        self.free_q = np.array([qs for qs, _ in free], dtype=np.int64)
        self.free_v = np.array([vs for _, vs in free], dtype=np.int64)
        self.mass = system.total_mass
        # a coupled model's couplings (the compiled steps' bundle): qdd and the projection by
        # the compiled steps' own functions, so that both paths round alike
        self.couplings = (couplings_of(system, Workspace(system.free_tree)) if system.couplings
                          else no_couplings())

    def forces(self, t, q, v):
        """The generalized forces at (t, q, v): the tip force's, tau's and the damping's (None:
        none). A chain's tip force and damping come from the compiled steps' own functions
        (:func:`redysim.algorithms._kernels.planar.planar_tip_torques` on a planar chain, else
        :func:`redysim.algorithms._kernels.rk_run.spatial_tip_torques`): both paths round
        alike."""
        if self.tip_force is not None:
            tip = np.empty(self.nv)
            if self.system.is_planar:
                planar_tip_torques(self.length, q, self.tip_force, -self.damping, v, tip)
            else:
                ws = self.ws
                spatial_tip_torques(ws.kernel_f, ws.kernel_i, ws.scratch, ws.zeros, np.zeros(3),
                                    self.length, np.ascontiguousarray(q, dtype=float),
                                    self.tip_force, -self.damping,
                                    np.ascontiguousarray(v, dtype=float), tip)
                if not np.isfinite(tip).all():  # the loads module says why
                    tip_force_torques(self.system, q, self.tip_force, ws=self.ws)
            return tip if self.tau is None else tip + np.asarray(self.tau(t, q, v), dtype=float)
        tau = None if self.tau is None else np.asarray(self.tau(t, q, v), dtype=float)
        if self.damping:
            tau = -self.damping * v if tau is None else tau - self.damping * v
        return tau

    def qdd_of(self, t, q, v, out=None):
        """vdot at (t, q, v): the provider's (with loops: an engine's constrained
        accelerations, its loop adapter's), the loops' or the core's."""
        tau = self.forces(t, q, v)
        if self.loops is not None and self.qdd is None:
            a = self.loops.forward_dynamics(q, v, tau)
        elif self.qdd is not None:
            a = np.asarray(self.qdd(q, v, tau), dtype=float)
            if a.shape != (self.nv,):
                raise ValueError(f"the accelerations' provider (qdd) returned shape {a.shape}; "
                                 f"{self.system.name!r} has {self.nv} DOF, so it must return "
                                 f"shape ({self.nv},)")
        elif self.system.couplings and self.method == "rge-a" and not self.system.is_planar:
            a = np.empty(self.nv) if out is None else out
            q, v = check_state(self.system, "q", q), check_state(self.system, "v", v)
            ws = self.ws
            if coupled_qdd(ws.kernel_f, ws.kernel_i, ws.scratch, self.couplings, q, v,
                           ws.zeros if tau is None else tau, a) != 0.0:
                # not finite: the checked path says why (or, finite there, is the answer)
                a[:] = forward_dynamics(self.system, q, v, tau, self.method)
            return a
        else:
            return forward_dynamics(self.system, q, v, tau, self.method, ws=self.ws, out=out)
        if out is None:
            return a
        out[:] = a
        return out

    def rhs(self, t, y):
        nq = self.nq
        out = np.empty(nq + self.nv)
        q, v = y[:nq], y[nq:]
        self.qdd_of(t, q, v, out=out[nq:])
        if not self.free:
            out[:nq] = v
            return out
        # v_world and q (x) [0; w_body] / 2 for a free joint: the compiled steps' own function
        configuration_rate(nq, self.plain_q, self.plain_v, self.free_q, self.free_v, y, out)
        return out

    def project(self, y, record: bool = True) -> float:
        """Divide each quaternion of ``y`` by its norm, in place; the largest | |q| - 1 |. With
        loops, move (q, v) back onto them (in place), keeping the largest residuals met (when
        ``record``: a step's, not an interpolated sample's); with couplings, each follower back
        on its leader (a Runge-Kutta step keeps a linear coupling to rounding)."""
        if self.loops is not None:
            nq = self.nq
            y[:nq], y[nq:], rq, rv = self.loops.project(y[:nq], y[nq:])
            if record:
                self.residual_q, self.residual_v = max(self.residual_q, rq), \
                    max(self.residual_v, rv)
        if self.system.couplings:  # followers back on their leaders (linear: exact)
            met = np.zeros(2)  # the compiled steps' own projection
            project_couplings(self.couplings, self.nq, y, met)
            if record:
                self.residual_q = max(self.residual_q, float(met[0]))
                self.residual_v = max(self.residual_v, float(met[1]))
        if not self.free:
            return 0.0
        worst = np.zeros(1)  # the compiled steps' own projection
        project_quaternions(self.free_q, y, worst)
        return float(worst[0])

    def energy_and_com(self, q, v) -> tuple[float, np.ndarray]:
        """E = T + V, and the centre of mass from the same kinematics pass."""
        ws = self.ws
        T, V = energy(self.system, q, v, ws=ws)
        tree = ws.tree
        md = np.einsum("kij,kj->ki", ws.oR, tree.mass_com)  # m_k R_k c_k
        com = (tree.mass @ ws.oO + md.sum(axis=0)) / self.mass
        return T + V, com


class _Stop(Exception):
    """Raised inside a run (a limit, from an RHS call) to end it with a status and message."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status, self.message = status, message


class EngineStepper(OdeSolver):
    """A reference engine's own integrator behind the solver protocol: ``engine`` has
    ``sim_reset(q0, v0, h, integrator=, rtol=, atol=)``, ``step_once()``, ``sim_advance(t)``,
    ``sim_state()`` and ``sim_counts()`` (``redysim.references``; duck-typed: the core imports no
    engine). A fixed-step integrator takes one step a call of :meth:`step`, and its state is
    known at whole steps only, so the sample times must be whole multiples of ``h`` (checked by
    :class:`Simulator`); an adaptive one (``adaptive``) lands on each sample time ``t_stop`` by
    its own error control, one call of :meth:`step` per sample, and its steps, rejections and
    qdd calls are the engine's own count (-1 where it gives none)."""

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
            assert self.h is not None  # a fixed-step native integrator's h (Simulator checks)
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

    def state(self) -> SolverState:
        raise NotImplementedError("an engine's own stepper cannot be checkpointed")


class Sample(NamedTuple):
    """What an observer of :class:`Simulator` is handed at each sample: the time ``t`` [s], the
    state ``q``, ``v`` (on the constraints: quaternions unit, loops closed), the energy ``E``
    [J] (forces' potential included) and centre of mass ``com`` [m], ``accel()``, the run's
    own qdd there (computed once, on first call), and ``ws``, the system's workspace, free for an
    observer's own kinematics (nothing else uses it between two steps)."""

    t: float
    q: np.ndarray
    v: np.ndarray
    E: float
    com: np.ndarray
    accel: Callable[[], np.ndarray]
    ws: Workspace


def frame_observer(system: Model, frame: str = "tip", *, acceleration: bool = False):
    """An observer for :class:`Simulator`: a frame's world position and velocity at each sample
    (and, with ``acceleration``, its acceleration from the run's own qdd), as one row
    [px, py, pz, vx, vy, vz(, ax, ay, az)]. ``frame``: as :func:`redysim.frame_motion`."""
    from redysim.algorithms.dynamics import frame_motion

    def observe(s: Sample):
        m = frame_motion(system, s.q, s.v, s.accel() if acceleration else None, frame=frame,
                         ws=s.ws)
        return np.concatenate((m.position, m.velocity, *(() if m.acceleration is None
                                                         else (m.acceleration,))))

    return observe


def momentum_observer(system: Model):
    """An observer for :class:`Simulator`: the momentum (:func:`redysim.momentum`) at each
    sample as one row [p (3), h_G (3)]: linear, and angular about the centre of mass."""
    from redysim.algorithms.dynamics import momentum

    def observe(s: Sample):
        mom = momentum(system, s.q, s.v, ws=s.ws)
        return np.concatenate((mom.linear, mom.angular))

    return observe


class Simulator:
    """One run of a system, assembled in one place: every simulation of redysim (``simulate``,
    the harness's runs, sweeps, reference solutions, long runs and refinement studies) is one.

    The state is y = (q, v); dq/dt = v but a free joint's quaternion, which moves as
    q (x) [0; w_body] / 2 and is projected back onto the unit sphere after every step (module
    docstring). Hooks (each optional):

    - ``qdd(q, v, tau) -> (n_v,)``: the accelerations' provider, instead of the core's forward
      dynamics by ``method`` ("rge-a", "ge-n", "rge-n"): a reference engine's, or the core in
      emulated float32; with loops, the constrained accelerations (an engine's loop adapter,
      :mod:`redysim.references.loops`), the loops still projected after every step. ``engine``
      with ``integrator="native"`` or ``"native:NAME"``: the engine steps itself
      (:class:`EngineStepper`).
    - ``tau(t, q, v) -> (n_v,)``: generalized forces (loads), and ``damping``: a viscous torque
      -damping * v at every joint [N m s]; ``potential(q)``: the potential energy [J] of the
      forces ``tau`` gives, when they have one (counted in E, so that delta_M stays an energy
      balance). ``tip_force``: a constant world force [N] (3,) at a chain's tip (a case's
      ``[load] tip_force``): its joint torques J^T F (added to ``tau``'s), and its potential
      -F . p_tip counted in E (added to ``potential``'s; :mod:`redysim.algorithms.loads`); on a
      planar chain its steps run in compiled code.
    - ``loops``: a :class:`redysim.algorithms.loops.ClosedLoops` of the system (by default, a model
          with
      cut joints, :meth:`Model.with_cuts`, gets its own): its loops closed, (q, v) projected
      back onto them after every step; the samples carry the loop forces.
    - ``observe``: name -> ``f(sample)`` called at each sample with a :class:`Sample` (t, q, v,
      E, com, and ``accel()``: the run's qdd there, computed once on demand); what it returns
      (an array, or None: nothing kept) is stacked into ``Simulation.observed[name]``.
      :func:`frame_observer` gives a frame's path. The energy, delta_M and the centre of mass
      are always sampled;
      ``keep_states`` keeps q and v at every sample too (off for long runs of huge systems:
      ``y_final`` is kept anyway).
    - ``energy_bound``: a run whose |delta_M| passes it fails ("energy blow-up").
    - ``state`` (a :class:`redysim.integrators.explicit.SolverState`): resume from a checkpoint;
          samples
      at or before ``skip_until`` are not taken again.
    - ``compiled``: False steps in the Python loop even where compiled steps could run (the
      same steps, bit for bit: an independent path for checks); None chooses.

    The solver is chosen here: ours in compiled code
    (:class:`~redysim.integrators.explicit.CompiledSolver`) when qdd is the core's RGE-A with no
    forces but a chain's tip force (free joints, damping, couplings and the core's loops
    included); the implicit midpoint with a
    chain's tension preconditioner;
    SciPy's; the Python loop otherwise. Every solver follows one protocol
    (:class:`redysim.integrators.protocol.OdeSolver`). The first RHS and energy calls and the
    steppers' kernels (JIT compile or disk-cache load) are made in the constructor and timed apart
    (``jit_s``). Bad settings raise SettingsError and a bad q0 or v0 StateError, naming them, before
    anything runs.
    """

    def __init__(self, system: Model, t_end: float, *, q0=None, v0=None,
                 integrator: str = DEFAULT_METHOD, rtol: float = DEFAULT_RTOL,
                 atol: float = DEFAULT_ATOL, h: float | None = None,
                 sample: float | None = None, method: str = "rge-a", qdd=None, tau=None,
                 potential=None, damping: float = 0.0, loops=None, engine=None,
                 observe=None, keep_states: bool = True, energy_bound: float | None = None,
                 state: SolverState | None = None, skip_until: float | None = None,
                 compiled: bool | None = None, source: str = "simulate", tip_force=None):
        if not isinstance(system, Model):
            raise TypeError(f"{source} takes a redysim.Model (a Chain is one), not "
                            f"{type(system).__name__}")
        native = is_native(integrator)
        native_info = None
        if native:
            if engine is None:
                raise SettingsError(source, "integrator", integrator, "needs a reference "
                                    "engine (the core has no native stepper: use rk4 with a "
                                    "step h)")
            try:
                native_info = engine.native_integrator(native_name(integrator))
            except ValueError as exc:
                raise SettingsError(source, "integrator", integrator, str(exc)) from None
            extra = [name for name, given in (("tau", tau is not None), ("damping", damping),
                                              ("tip_force", tip_force is not None),
                                              ("loops", loops is not None or system.cuts))
                     if given]
            if extra:  # the engine steps its own model: nothing of ours reaches it
                raise SettingsError(source, "integrator", integrator, f"steps the engine's own "
                                    f"model, which has none of {', '.join(extra)}: run it "
                                    "through redysim's integrators (ode45, dop853, rk4, ...)")
        adaptive_native = bool(native_info is not None and native_info.adaptive)
        integrator, fixed = _check_simulate_settings(
            source, t_end, integrator=integrator, rtol=rtol, atol=atol, h=h, sample=sample,
            damping=damping, adaptive_native=adaptive_native)
        self.system, self.source = system, source
        self.t_end, self.integrator = float(t_end), integrator
        self.rtol, self.atol, self.h = rtol, atol, h
        self.sample = sample if sample is not None else t_end / DEFAULT_SAMPLES
        self.ts = sample_times(0.0, self.t_end, self.sample)
        if fixed and native and np.abs(self.ts / h - np.round(self.ts / h)).max() > 1e-6:
            raise SettingsError(source, "sample", self.sample, f"an engine's own stepper knows "
                                f"its state at whole steps only: the sample times must be whole "
                                f"multiples of h = {h:g}")
        self.keep_states, self.energy_bound = bool(keep_states), energy_bound
        self._compiled = compiled
        self.observe = dict(observe or {})
        self.skip_until = skip_until
        if q0 is None:
            q0 = system.initial()
        q0 = check_state(system, "q", q0)
        v0 = check_state(system, "v", np.zeros(system.n_v) if v0 is None else v0)
        self.damping = float(damping)
        if loops is None and system.cuts:  # a closed mechanism: its loops closed
            from redysim.algorithms.loops import ClosedLoops

            loops = ClosedLoops(system, source=source)
        if tip_force is not None:
            if system.chain_layout is not None:
                raise SettingsError(source, "tip_force", tip_force, f"acts at a chain's tip; "
                                    f"{system.name!r} is a tree (no single tip)")
            try:
                tip_force = check_force(tip_force)
            except StateError as exc:
                raise SettingsError(source, "tip_force", tip_force, str(exc)) from None
        self.motion = _Motion(system, loops, self.damping, qdd=qdd, method=method, tau=tau,
                              tip_force=tip_force)
        if tip_force is not None:  # its potential, on the samples' workspace
            force, ws, given = tip_force, self.motion.ws, potential

            def potential(q):  # the force's, and the caller's for its tau (if any)
                own = tip_force_potential(system, q, force, ws=ws)
                return own if given is None else own + given(q)
        self.potential = potential
        self.loops = loops
        y0 = np.concatenate((q0, v0))
        if loops is not None:
            if getattr(loops, "model", None) is not system:
                raise SettingsError(source, "loops", type(loops).__name__, "must be the "
                                    "ClosedLoops of the model simulated (ClosedLoops(model, "
                                    "cuts))")
            loops.check_start(q0)
        if system.couplings:  # (the steps' right-hand side takes its state as given)
            check_coupled(system, "q", q0)
            check_coupled(system, "v", v0)
        for k, t in enumerate(getattr(system, "joint_types", ())):
            if t == FREE:  # its quaternion, before any projection: the norm as given
                i = int(system.joint_qoff[k]) + 3
                norm = math.sqrt(float(y0[i:i + 4] @ y0[i:i + 4]))
                if not abs(norm - 1.0) <= QUATERNION_TOL:
                    raise StateError(f"q0[{i}:{i + 4}], the quaternion (w, x, y, z) of joint "
                                     f"{system.joint_names[k]!r}, has norm {norm:.9g}: give a "
                                     "unit quaternion")
        if integrator in IMPLICIT and self.motion.free:
            raise SettingsError(source, "integrator", integrator, "steps systems whose dq/dt "
                                "is v; a free joint's quaternion moves otherwise: use ode45 or "
                                "dop853")
        self.motion.project(y0, record=False)
        self.y0 = y0
        t_jit = time.perf_counter()
        self.motion.rhs(0.0, y0)  # the first calls: JIT compile or disk-cache load, timed apart
        self._energy_and_com(y0[:self.motion.nq], y0[self.motion.nq:])
        if not native:  # the steppers' own kernels; the implicit step calls no Runge-Kutta ones
            (implicit_kernels if integrator in IMPLICIT else compile_kernels)()
        self.jit_s = time.perf_counter() - t_jit
        self.E0 = self._energy_and_com(y0[:self.motion.nq], y0[self.motion.nq:])[0]
        self._rhs = self.motion.rhs  # the solver's; wrapped by run() to check the limits
        if native:
            assert native_info is not None
            self.solver = EngineStepper(engine, 0.0, y0, self.t_end, h, self.motion.nq,
                                        integrator=native_info.name, rtol=rtol, atol=atol,
                                        adaptive=adaptive_native)
        elif state is None:
            self.solver = self._make_solver(None)
        else:
            self.solver = self._make_solver(state)

    # ----------------------------------------------------------------------- assembly
    @property
    def compiled(self) -> bool:
        """Whether the steps run in compiled code: ours, on the core's RGE-A, free joints,
        damping, couplings (on a spatial tree) and loops (the core's ClosedLoops, not on a
        coupled tree) included, a chain's tip force, no other forces (the same steps
        as the Python loop, bit for bit)."""
        m, system = self.motion, self.system
        can = (m.qdd is None and m.method == "rge-a" and m.tau is None
               and (m.loops is None or getattr(m.loops, "bundle", None) is not None)
               and not (system.couplings and system.is_planar)
               and self.integrator in TABLEAU_NAMES)
        return can and self._compiled is not False

    def _make_solver(self, state):
        kw = dict(rtol=self.rtol, atol=self.atol, h=self.h)
        rhs = self._call_rhs
        if self.compiled:
            planar = self.system.is_planar
            return CompiledSolver(rhs, 0.0, self.y0, self.t_end, self.integrator,
                                  ws=self.motion.ws, planar=planar, state=state,
                                  damping=self.motion.damping,
                                  free=(self.motion.free_q, self.motion.free_v,
                                        self.motion.plain_q, self.motion.plain_v),
                                  tip_force=self.motion.tip_force,
                                  couplings=(self.motion.couplings if self.system.couplings
                                             else None),
                                  loops=self.motion.loops, **kw)
        if self.integrator in IMPLICIT:
            # a chain's tension preconditioner (redysim.integrators.implicit); a tree steps without
            # one
            pre = (TensionPreconditioner(self.system) if self.system.chain_layout is None
                   else None)
            return make_solver(rhs, 0.0, self.y0, self.t_end, self.integrator, state=state,
                               preconditioner=pre, **kw)
        return make_solver(rhs, 0.0, self.y0, self.t_end, self.integrator, state=state, **kw)

    def _call_rhs(self, t, y):
        return self._rhs(t, y)

    def _energy_and_com(self, q, v) -> tuple[float, np.ndarray]:
        E, com = self.motion.energy_and_com(q, v)
        if self.potential is not None:
            E += self.potential(q)
        return E, com

    # ----------------------------------------------------------------------- the run
    def run(self, *, progress: Callable[[float, float, int, float], str | None] | None = None,
            on_step: Callable[[object], str | None] | None = None,
            max_cpu_s: float | None = None, max_wall_s: float | None = None,
            clock: str = "thread") -> Simulation:
        """Integrate to t_end (or until stopped) and return the samples and counts (once: a
        second call raises RuntimeError).

        ``progress(t, t_end, steps, wall_s)``: after each step (each chunk of steps in compiled
        code); ``on_step(solver)``: likewise, after the step's samples (a checkpoint saved here
        holds every sample up to the solver's t). A message (a str) either returns stops the
        run there: ``status`` 1 and that message, the samples so far kept.
        ``max_cpu_s``: a limit on the run's CPU time [s] (``clock``: "thread", this thread's,
        or "process", the process's; JIT excluded): past it the run fails (``status`` -1,
        "time limit: max_cpu_s = ..."), whatever else the machine does. ``max_wall_s``: the
        caller's patience: past it the run is stopped (``status`` 1, "stopped by the wall-clock
        limit ..."), never failed. Both are checked after every step and every RHS call (one
        implicit step can take long). An unexpected error of a provider (an engine's qdd, say)
        is raised as it is, the run's samples up to it attached as its ``partial``
        :class:`Simulation`."""
        if getattr(self, "_ran", False):
            raise RuntimeError("a Simulator runs once (its solver is at the end of the run); "
                               "make another to run again")
        self._ran = True
        _check_run_settings(self.source, progress=progress, max_cpu_s=max_cpu_s)
        if max_wall_s is not None and not (isinstance(max_wall_s, NUMBERS) and max_wall_s > 0):
            raise SettingsError(self.source, "max_wall_s", max_wall_s, "must be None or a "
                                "number of seconds > 0")
        cpu = time.thread_time if clock == "thread" else time.process_time
        motion, loops, system = self.motion, self.loops, self.system
        nq, mass = motion.nq, motion.mass
        ts, ys, energies, coms, forces = [], [], [], [], []
        observed: dict[str, list] = {name: [] for name in self.observe}
        last = {"y": None}
        worst = [0.0]
        cpu0, wall0 = cpu(), time.perf_counter()
        cpu_end = cpu0 + max_cpu_s if max_cpu_s else math.inf
        wall_end = wall0 + max_wall_s if max_wall_s else math.inf

        def check_limits(t):
            if cpu() > cpu_end:
                raise _Stop(-1, f"time limit: max_cpu_s = {max_cpu_s:g} s of CPU reached at "
                                f"t = {t:.6g}")
            if time.perf_counter() > wall_end:
                raise _Stop(1, f"stopped by the wall-clock limit, max_wall_s = {max_wall_s:g} "
                               f"s (the caller's patience, not a result), at t = {t:.6g}; the "
                               "samples so far are kept")

        if max_cpu_s or max_wall_s:
            def limited(t, y):
                check_limits(t)
                return motion.rhs(t, y)
            self._rhs = limited
        else:
            self._rhs = motion.rhs

        def on_sample(t, y):
            if self.skip_until is not None and t <= self.skip_until:
                return None  # taken before the checkpoint this run resumed from
            y = y.copy()
            motion.project(y, record=False)  # interpolated between steps: back on constraints
            q, v = y[:nq], y[nq:]
            a = []

            def accel():
                if not a:
                    a.append(motion.qdd_of(t, q, v))
                return a[0]

            try:
                if loops is not None:
                    tau = motion.forces(t, q, v)
                    forces.append(loops.forward_dynamics_and_forces(q, v, tau)[1])
                E, com = self._energy_and_com(q, v)
                sample = Sample(t, q, v, E, com, accel, motion.ws)
                rows = {name: f(sample) for name, f in self.observe.items()}
            except StateError as exc:  # the state overflowed (or went NaN) between samples
                raise _Stop(-1, f"at t = {t:.6g}: {type(exc).__name__}: {exc}") from None
            ts.append(t)
            if self.keep_states:
                ys.append(y)
            last["y"] = y
            energies.append(E)
            coms.append(com)
            for name, row in rows.items():
                if row is not None:
                    observed[name].append(np.asarray(row))
            if not math.isfinite(E):
                raise _Stop(-1, f"non-finite energy at t = {t:.6g}")
            dM = (E - self.E0) / mass
            if self.energy_bound and abs(dM) > self.energy_bound:
                raise _Stop(-1, f"energy blow-up: |delta_M| = {abs(dM):.3g} J/kg > bound "
                                f"{self.energy_bound:g} at t = {t:.6g}")
            return None

        # the least s_min / s_max of the loops' J X, and its t (NaN until one is met)
        nearest = [math.inf, math.nan]
        if loops is not None:
            loops.nearest_change_point()  # from here on

        compiled = isinstance(self.solver, CompiledSolver)
        compiled_free = compiled and bool(motion.free)
        compiled_coupled = compiled and bool(system.couplings)
        compiled_loops = compiled and loops is not None
        if compiled_loops:  # (a ClosedLoops may serve several runs)
            loops.bundle.worst[:] = 0.0

        def step_done(s):
            # every step of a compiled call but its last projected in compiled code
            if compiled_free:
                worst[0] = max(worst[0], float(s.quaternion_worst[0]))
            for on, met in ((compiled_loops, loops.bundle.worst if compiled_loops else None),
                            (compiled_coupled, motion.couplings.worst)):
                if on:
                    motion.residual_q = max(motion.residual_q, float(met[0]))
                    motion.residual_v = max(motion.residual_v, float(met[1]))
            worst[0] = max(worst[0], motion.project(s.y))
            check_limits(s.t)
            if loops is not None:
                ratio = loops.nearest_change_point()
                if ratio < nearest[0]:
                    nearest[:] = ratio, s.t
            for hook in (lambda: progress and progress(s.t, self.t_end, s.counters.steps,
                                                       time.perf_counter() - wall0),
                         lambda: on_step and on_step(s)):
                stop = hook()
                if stop:
                    return str(stop)
            return None

        solver = self.solver
        unexpected = None
        # an engine's own adaptive advance checks the CPU limit between its own steps
        engine_limit = isinstance(solver, EngineStepper) and math.isfinite(cpu_end) and hasattr(
            solver.engine, "set_sim_deadline")
        if engine_limit:
            solver.engine.set_sim_deadline(cpu, cpu_end)
        try:
            status, message = advance(solver, self.ts, on_sample=on_sample, on_step=step_done)
        except _Stop as stop:
            status, message = stop.status, stop.message
        except TimeoutError as exc:  # that engine's advance stopped at the limit
            status, message = -1, (f"time limit: max_cpu_s = {max_cpu_s:g} s of CPU reached "
                                   f"after t = {solver.t:.6g} ({exc})")
        except StateError as exc:  # qdd not defined or overflowed at a stage
            status, message = -1, f"at t = {solver.t:.6g}: {exc}"
        except Exception as exc:  # a provider's own error (an engine's): raised, with the
            unexpected = exc      # samples finished before it attached (below)
            status, message = -1, f"at t = {solver.t:.6g}: {type(exc).__name__}: {exc}"
        finally:
            self._rhs = motion.rhs
            if engine_limit:
                solver.engine.set_sim_deadline(None, math.inf)
        near = None
        if loops is not None:
            ratio = loops.nearest_change_point()  # the failing step's own, if any
            if ratio < nearest[0]:
                nearest[:] = ratio, solver.t
            if nearest[0] <= NEAR_CHANGE_POINT:
                near = float(nearest[1])
                if status != 0 and "change point" not in message:
                    message += (f" (the motion passed near a change point at t = {near:.6g}: "
                                f"J M^-1 J^T's singular values {nearest[0]:.1e} apart, a "
                                "configuration where the mechanism can switch branches)")
        c = solver.counters
        n_y = self.y0.size
        Y = np.array(ys) if ys else np.empty((0, n_y))
        E = np.array(energies)
        result = Simulation(
            name=system.name, t=np.array(ts), q=Y[:, :nq], v=Y[:, nq:], energy=E,
            delta_M=(E - self.E0) / mass if E.size else E,
            com=np.array(coms).reshape(-1, 3), steps=c.steps, rejected=c.rejected,
            nfev=c.nfev, status=status, message=message, cpu_s=cpu() - cpu0,
            wall_s=time.perf_counter() - wall0, jit_s=self.jit_s, quaternion_error=worst[0],
            forces=np.array(forces) if loops is not None else None,
            residual_q=motion.residual_q, residual_v=motion.residual_v, near_change_point=near,
            observed={k: np.array(v) for k, v in observed.items()}, y_final=last["y"],
            E0=self.E0)
        if unexpected is not None:
            # never lose finished work: the caller keeps it (an attribute on any exception)
            unexpected.partial = result  # type: ignore[attr-defined]
            raise unexpected
        return result


def simulate(system: Model, t_end: float, *, q0=None, v0=None,
             integrator: str = DEFAULT_METHOD, rtol: float = DEFAULT_RTOL,
             atol: float = DEFAULT_ATOL, h: float | None = None, sample: float | None = None,
             progress: Callable[[float, float, int, float], str | None] | None = None,
             loops=None, damping: float = 0.0,
             max_cpu_s: float | None = None) -> Simulation:
    """The passive motion of ``system`` from (q0, v0) over [0, t_end] (no joint torques): a
    :class:`Simulator` run.

    loops: a :class:`redysim.algorithms.loops.ClosedLoops` of ``system``: the motion with its loops
    closed, (q, v) projected back onto them after every step; the samples then carry the loop forces
    and the run the largest residuals it met. damping: a viscous torque -damping * v at every joint
    [N m s] (0: none; the energy then falls).

    q0: default the model's own configuration (:meth:`Model.initial`: the file's, else every joint
    at zero, quaternions the identity), zeros for a chain; v0: default zeros. integrator, rtol,
    atol, h: as :func:`redysim.integrators.explicit.integrate` (h for the fixed-step rk4 and
    midpoint-fixed only); ``implicit`` is ``midpoint``. sample: the sample interval (default t_end /
    10). progress: None, or a callable called as ``progress(t, t_end, steps, wall_s)`` after each
    step (each chunk of steps in compiled code); a message (a str) it returns stops the run there:
    ``status`` 1 and that message, the samples so far kept (a wall-clock limit of the caller's,
    say). max_cpu_s: a limit on the run's CPU time [s] (its thread's, JIT compile excluded; None:
    none): a run past it stops with ``status`` -1, "time limit: max_cpu_s = ...", its samples kept
    (a limit that, unlike a wall-clock one, does not depend on what else the machine is doing).
    Raises SettingsError for a setting out of range (naming it: ``damping``, ``progress``,
    ``max_cpu_s``, ...) and StateError for a bad q0 or v0.
    """
    _check_run_settings("simulate", progress=progress, max_cpu_s=max_cpu_s)  # before warm-up
    return Simulator(system, t_end, q0=q0, v0=v0, integrator=integrator, rtol=rtol, atol=atol,
                     h=h, sample=sample, loops=loops, damping=damping
                     ).run(progress=progress, max_cpu_s=max_cpu_s)


def simulate_batch(system: Model, t_end: float, *, q0, v0=None,
                   threads: int | None = None, **settings) -> list[Simulation]:
    """Independent motions of one system from the rows of q0 (B, n_q) and v0 (B, n_v) (default
    zeros): :func:`simulate` of each row, each with its own step sizes, the rows handed out one at a
    time to the calling thread and up to ``threads`` - 1 helper threads (default
    :func:`redysim.algorithms.dynamics.default_threads`: every core this process may use, or
    ``REDYSIM_THREADS``); the caller waits at the end for the rows helpers have started. The steps
    run in compiled code without the GIL (:class:`redysim.integrators.explicit.CompiledSolver`), so
    the threads run at once; each result's ``cpu_s`` is its own thread's. ``settings``:
    :func:`simulate`'s keywords (integrator, rtol, atol, h, sample, damping); not ``progress`` or
    ``loops``. Everything is checked before any thread starts: a bad or unknown setting raises
    SettingsError naming it, a q0 or v0 that is not a 2-D array of rows StateError saying what a
    batch needs. A row that fails raises its StateError, naming the row.
    """
    from redysim.algorithms.dynamics import check_batch, run_blocks

    for key in ("progress", "loops"):
        if key in settings:
            raise SettingsError("simulate_batch", key, settings[key], "is not taken by a batch; "
                                "simulate the rows one by one")
    for key, value in settings.items():
        if key not in BATCH_SETTINGS:
            raise SettingsError("simulate_batch", key, value, f"unknown setting; a batch takes "
                                f"{', '.join(BATCH_SETTINGS)} (simulate's keywords)")
    if not isinstance(system, Model):
        raise TypeError(f"simulate_batch takes a redysim.Model (a Chain is one), not "
                        f"{type(system).__name__}")
    defaults = {"integrator": DEFAULT_METHOD, "rtol": DEFAULT_RTOL, "atol": DEFAULT_ATOL,
                "h": None, "sample": None, "damping": 0.0, "max_cpu_s": None}
    _check_simulate_settings("simulate_batch", t_end, **{**defaults, **settings})
    for name, value, n in (("q0", q0, system.n_q), ("v0", v0, system.n_v)):
        try:
            shape = None if isinstance(value, str) else np.shape(value)
        except ValueError:  # ragged rows: check_batch names them
            shape = (None, None)
        if value is not None and (shape is None or len(shape) != 2):
            raise StateError(f"simulate_batch: {name} has shape {shape}: a batch needs "
                             f"(B, {n}), one initial state a row (for one motion, "
                             f"simulate(system, t_end, {name}=...))")
    Q0 = check_batch(system, "q", q0, None)
    V0 = np.zeros((Q0.shape[0], system.n_v)) if v0 is None else \
        check_batch(system, "v", v0, Q0.shape[0])
    out: list[Simulation | None] = [None] * Q0.shape[0]

    def rows(first, last, _own):
        for i in range(first, last):
            try:
                out[i] = simulate(system, t_end, q0=Q0[i], v0=V0[i], **settings)
            except StateError as exc:
                raise StateError(f"row {i} of q0 and v0: {exc}") from None

    run_blocks(Q0.shape[0], threads, rows)
    return cast(list[Simulation], out)  # every row filled: run_blocks ran them all, or raised
