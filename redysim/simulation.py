"""Simulate a chain or a model from a state: the motion, the energy balance, the centre of mass.

:func:`simulate` integrates dy/dt = (dq/dt, vdot) with y = (q, v), vdot from
:func:`redysim.forward_dynamics` (RGE-A on the tree, or GE-N / RGE-N) and dq/dt = v, except for a
free joint, whose quaternion moves as dq/dt = q (x) [0; w_body] / 2 (docs/design.md, "Kinematic
trees"). Any of :data:`redysim.integrate.INTEGRATORS` steps it; ours (ode45, dop853, rk4) in
compiled code (:class:`redysim.integrate.CompiledSolver`) when there is no free joint, and the
implicit midpoint (:mod:`redysim.implicit`) with a chain's tension preconditioner. A
quaternion integrated so drifts
off the unit sphere by the integrator's error; after every accepted step it is projected back
(divided by its norm; so are the samples interpolated between steps), the largest norm error
seen before a projection is reported, and the kernels read any quaternion's direction only (so
a stage's slightly-off quaternion is harmless).

The energy E = T + V is sampled with the motion; with no joint torques it is conserved, and its
change per unit mass delta_M = (E - E0) / M (the paper's Eq. 11) measures the integration error.
The centre of mass is sampled too: in a free fall (a floating base, no contact) it follows
c(t) = c0 + cdot0 t + g t^2 / 2 exactly, a check that needs no reference solution.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .chain import Chain
from .dynamics import check_state, energy, forward_dynamics
from .errors import SettingsError, StateError
from .implicit import TensionPreconditioner
from .implicit import compile_kernels as implicit_kernels
from .integrate import (
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
from .loops import NEAR_CHANGE_POINT
from .model import FREE, Model
from .workspace import Workspace

DEFAULT_SAMPLES = 10  # samples over the horizon when no interval is given
QUATERNION_TOL = 1e-6  # | |q0's quaternion| - 1 | allowed (then normalised); more is refused
NUMBERS = (int, float, np.integer, np.floating)  # a setting's number types (not bool)
BATCH_SETTINGS = ("integrator", "rtol", "atol", "h", "sample", "damping", "max_cpu_s")


def _check_simulate_settings(source: str, t_end, *, integrator, rtol, atol, h, sample,
                             damping, progress=None, max_cpu_s=None) -> tuple[str, bool]:
    """Check simulate's settings, naming the bad one (SettingsError); return the canonical
    integrator name and whether it is fixed-step."""
    if not isinstance(integrator, str):
        raise SettingsError(source, "integrator", integrator, "must be an integrator's name; "
                            f"known: {', '.join((*INTEGRATORS, *ALIASES))}")
    if t_end is None:
        raise SettingsError(source, "t_end", None, "missing: the horizon [s]")
    integrator = canonical(integrator)
    fixed = integrator in FIXED_STEP
    if fixed and h is None:
        raise SettingsError(source, "h", h, f"{integrator} is a fixed-step integrator: give "
                            "its step h [s]")
    check_settings(source, method=integrator, rtol=None if fixed else rtol,
                   atol=None if fixed else atol, h=h, t_end=t_end, sample=sample)
    if isinstance(damping, bool) or not isinstance(damping, NUMBERS) or \
            not (math.isfinite(damping) and damping >= 0):
        shown = float(damping) if isinstance(damping, NUMBERS[2:]) else damping
        raise SettingsError(source, "damping", shown, "must be a finite number >= 0: the "
                            "viscous torque -damping * v at every joint [N m s] (0: none)")
    if max_cpu_s is not None and (isinstance(max_cpu_s, bool) or not isinstance(
            max_cpu_s, NUMBERS) or not (math.isfinite(max_cpu_s) and max_cpu_s > 0)):
        shown = float(max_cpu_s) if isinstance(max_cpu_s, NUMBERS[2:]) else max_cpu_s
        raise SettingsError(source, "max_cpu_s", shown, "must be None or a finite number of "
                            "seconds > 0")
    if progress is not None and not callable(progress):
        raise SettingsError(source, "progress", progress, "must be None or a callable "
                            "progress(t, t_end, steps, wall_s)")
    return integrator, fixed


@dataclass
class Simulation:
    """Samples at ``t`` (m,): ``q`` (m, n_q), ``v`` (m, n_v), ``energy`` (m,) [J], ``delta_M``
    (m,) [J/kg], ``com`` (m, 3) [m]; the run's counts and times; ``status`` 0 done, 1 stopped, -1
    failed (``message`` says why); ``quaternion_error``: the largest | |q| - 1 | of a free
    joint's quaternion before its projection after a step (0 without one). With loops:
    ``forces`` (m, rows) the loop forces at the samples [N], ``residual_q`` [m] and
    ``residual_v`` [m/s] the largest loop residuals met after a step, before its projection;
    ``near_change_point``: the time [s] of the step at which the motion came nearest a change
    point (J M^-1 J^T's singular values within :data:`redysim.loops.NEAR_CHANGE_POINT` of each
    other: a configuration where the mechanism can switch branches), None when it came nowhere
    near one; a run that then failed or stopped says so in its ``message``."""

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

    @property
    def E0(self) -> float:
        return float(self.energy[0]) if self.energy.size else math.nan


class _Motion:
    """The right-hand side (dq/dt, vdot) of a system, with its workspace; with ``loops`` the
    loops closed (:class:`redysim.loops.ClosedLoops`), with ``damping`` a viscous torque
    -damping * v at every joint."""

    def __init__(self, system: Chain | Model, loops=None, damping: float = 0.0):
        self.system = system
        self.loops, self.damping = loops, float(damping)
        self.residual_q = self.residual_v = 0.0  # the largest met after a step
        self.ws = Workspace(system)
        self.nq, self.nv = system.n_q, system.n_v
        # a free joint's (q index of x, v index of its linear velocity); every other coordinate
        # moves as its velocity
        free = [] if isinstance(system, Chain) else \
            [(int(system.joint_qoff[k]), int(system.joint_voff[k]))
             for k, t in enumerate(system.joint_types) if t == FREE]
        self.free = free
        self.quaternions = np.array([qs + 3 for qs, _ in free], dtype=np.int64)
        plain_q, plain_v = [], []
        qoff = system.joint_qoff
        voff = system.joint_qoff if isinstance(system, Chain) else system.joint_voff
        for k in range(qoff.shape[0] - 1):
            if (int(qoff[k]), int(voff[k])) in free:
                continue
            plain_q.extend(range(qoff[k], qoff[k + 1]))
            plain_v.extend(range(voff[k], voff[k + 1]))
        self.plain_q = np.array(plain_q, dtype=np.int64)
        self.plain_v = np.array(plain_v, dtype=np.int64)
        self.mass = system.total_mass

    def rhs(self, _t, y):
        nq = self.nq
        out = np.empty(nq + self.nv)
        q, v = y[:nq], y[nq:]
        tau = -self.damping * v if self.damping else None
        if self.loops is not None:
            out[nq:] = self.loops.forward_dynamics(q, v, tau)[0]
        else:
            forward_dynamics(self.system, q, v, tau, ws=self.ws, out=out[nq:])
        if not self.free:
            out[:nq] = v
            return out
        out[self.plain_q] = v[self.plain_v]
        for qs, vs in self.free:
            out[qs:qs + 3] = v[vs:vs + 3]
            qw, qx, qy, qz = y[qs + 3:qs + 7]
            wx, wy, wz = v[vs + 3:vs + 6]
            out[qs + 3] = 0.5 * (-qx * wx - qy * wy - qz * wz)
            out[qs + 4] = 0.5 * (qw * wx + qy * wz - qz * wy)
            out[qs + 5] = 0.5 * (qw * wy - qx * wz + qz * wx)
            out[qs + 6] = 0.5 * (qw * wz + qx * wy - qy * wx)
        return out

    def project(self, y, record: bool = True) -> float:
        """Divide each quaternion of ``y`` by its norm, in place; the largest | |q| - 1 |. With
        loops, move (q, v) back onto them (in place), keeping the largest residuals met (when
        ``record``: a step's, not an interpolated sample's)."""
        if self.loops is not None:
            nq = self.nq
            y[:nq], y[nq:], rq, rv = self.loops.project(y[:nq], y[nq:])
            if record:
                self.residual_q, self.residual_v = max(self.residual_q, rq), \
                    max(self.residual_v, rv)
        worst = 0.0
        for i in self.quaternions:
            norm = math.sqrt(float(y[i:i + 4] @ y[i:i + 4]))
            worst = max(worst, abs(norm - 1.0))
            y[i:i + 4] /= norm
        return worst

    def energy_and_com(self, q, v) -> tuple[float, np.ndarray]:
        """E = T + V, and the centre of mass from the same kinematics pass."""
        T, V = energy(self.system, q, v, ws=self.ws)
        tree, ws = self.ws.tree, self.ws
        md = np.einsum("kij,kj->ki", ws.oR, tree.mass_com)  # m_k R_k c_k
        com = (tree.mass @ ws.oO + md.sum(axis=0)) / self.mass
        return T + V, com


def simulate(system: Chain | Model, t_end: float, *, q0=None, v0=None,
             integrator: str = DEFAULT_METHOD, rtol: float = DEFAULT_RTOL,
             atol: float = DEFAULT_ATOL, h: float | None = None, sample: float | None = None,
             progress: Callable[[float, float, int, float], str | None] | None = None,
             loops=None, damping: float = 0.0,
             max_cpu_s: float | None = None) -> Simulation:
    """The passive motion of ``system`` from (q0, v0) over [0, t_end] (no joint torques).

    loops: a :class:`redysim.loops.ClosedLoops` of ``system``: the motion with its loops closed,
    (q, v) projected back onto them after every step; the samples then carry the loop forces
    and the run the largest residuals it met. damping: a viscous torque -damping * v at every
    joint [N m s] (0: none; the energy then falls).

    q0: default the model's own configuration (:meth:`Model.initial`: the file's, else every
    joint at zero, quaternions the identity), zeros for a chain; v0: default zeros.
    integrator, rtol, atol, h: as :func:`redysim.integrate.integrate` (h for the fixed-step
    rk4 and midpoint-fixed only); ``implicit`` is ``midpoint``.
    sample: the sample interval (default t_end / 10). progress: None, or a callable called as
    ``progress(t, t_end, steps, wall_s)`` after each step (each chunk of steps in compiled
    code); a message (a str) it returns stops the run there: ``status`` 1 and that message,
    the samples so far kept (a wall-clock limit of the caller's, say). max_cpu_s: a limit on
    the run's CPU time [s] (its thread's, JIT compile excluded; None: none): a run past it
    stops with ``status`` -1, "time limit: max_cpu_s = ...", its samples kept (a limit that,
    unlike a wall-clock one, does not depend on what else the machine is doing). Raises
    SettingsError for a setting out of range (naming it: ``damping``, ``progress``,
    ``max_cpu_s``, ...) and StateError for a bad q0 or v0.
    """
    if not isinstance(system, Chain | Model):
        raise TypeError(f"simulate takes a redysim.Chain or redysim.Model, not "
                        f"{type(system).__name__}")
    integrator, fixed = _check_simulate_settings("simulate", t_end, integrator=integrator,
                                                 rtol=rtol, atol=atol, h=h, sample=sample,
                                                 damping=damping, progress=progress,
                                                 max_cpu_s=max_cpu_s)
    damping = float(damping)
    sample = sample if sample is not None else t_end / DEFAULT_SAMPLES
    if q0 is None:
        q0 = system.initial() if isinstance(system, Model) else np.zeros(system.n_q)
    q0 = check_state(system, "q", q0)
    v0 = check_state(system, "qd", np.zeros(system.n_v) if v0 is None else v0)
    motion = _Motion(system, loops, damping)
    y0 = np.concatenate((q0, v0))
    if loops is not None:
        if getattr(loops, "model", None) is not system:
            raise SettingsError("simulate", "loops", type(loops).__name__, "must be the "
                                "ClosedLoops of the model simulated (ClosedLoops(model, cuts))")
        loops.check_start(q0)
    for k, t in enumerate(getattr(system, "joint_types", ())):
        if t == FREE:  # its quaternion, before any projection: the norm as given
            i = int(system.joint_qoff[k]) + 3
            norm = math.sqrt(float(y0[i:i + 4] @ y0[i:i + 4]))
            if not abs(norm - 1.0) <= QUATERNION_TOL:
                raise StateError(f"q0[{i}:{i + 4}], the quaternion (w, x, y, z) of joint "
                                 f"{system.joint_names[k]!r}, has norm {norm:.9g}: give a unit "
                                 "quaternion")
    motion.project(y0, record=False)
    t_jit = time.perf_counter()
    motion.rhs(0.0, y0)  # the first calls: JIT compile or on-disk cache load, timed apart
    motion.energy_and_com(q0, v0)
    # the steppers' own kernels; the implicit step calls none of the Runge-Kutta ones
    (implicit_kernels if integrator in IMPLICIT else compile_kernels)()
    jit_s = time.perf_counter() - t_jit
    ts, ys, energies, coms, forces = [], [], [], [], []
    worst = [0.0]

    def on_sample(t, y):
        y = y.copy()
        motion.project(y, record=False)  # interpolated between steps: back on the constraints
        if loops is not None:
            tau = -damping * y[motion.nq:] if damping else None
            forces.append(loops.forward_dynamics(y[:motion.nq], y[motion.nq:], tau)[1])
        E, com = motion.energy_and_com(y[:motion.nq], y[motion.nq:])
        ts.append(t)
        ys.append(y)
        energies.append(E)
        coms.append(com)
        return None if math.isfinite(E) else f"non-finite energy at t = {t:.6g}"

    # CPU time of this thread: the compiled steps run on it, and a batch's other threads'
    # runs are not this run's (simulate_batch)
    cpu0, wall0 = time.thread_time(), time.perf_counter()

    nearest = [math.inf, None]  # the least s_min / s_max of the loops' J X, and its step's t
    if loops is not None:
        loops.nearest_change_point()  # from here on

    over_cpu = [False]

    def on_step(s):
        worst[0] = max(worst[0], motion.project(s.y))
        if max_cpu_s is not None and time.thread_time() - cpu0 > max_cpu_s:
            over_cpu[0] = True
            return f"time limit: max_cpu_s = {max_cpu_s:g} s of CPU reached at t = {s.t:.6g}"
        if loops is not None:
            ratio = loops.nearest_change_point()
            if ratio < nearest[0]:
                nearest[:] = ratio, s.t
        if progress is not None:
            stop = progress(s.t, t_end, s.counters.steps, time.perf_counter() - wall0)
            if stop is not None:
                return str(stop)
        return None

    if loops is None and not damping and not motion.free and integrator in TABLEAU_NAMES:
        # dq/dt = v and the tree's own qdd: steps in compiled code
        planar = isinstance(system, Chain) and system.is_planar
        solver = CompiledSolver(motion.rhs, 0.0, y0, t_end, integrator, ws=motion.ws,
                                planar=planar, rtol=rtol, atol=atol, h=h)
    elif integrator in IMPLICIT:
        if motion.free:
            raise SettingsError("simulate", "integrator", integrator, "steps systems whose "
                                "dq/dt is v; a free joint's quaternion moves otherwise: use "
                                "ode45 or dop853")
        # a chain's tension preconditioner (redysim.implicit); a tree steps without one
        pre = TensionPreconditioner(system) if isinstance(system, Chain) else None
        solver = make_solver(motion.rhs, 0.0, y0, t_end, integrator, rtol=rtol, atol=atol, h=h,
                             preconditioner=pre)
    else:
        solver = make_solver(motion.rhs, 0.0, y0, t_end, integrator, rtol=rtol, atol=atol, h=h)
    try:
        status, message = advance(solver, sample_times(0.0, t_end, sample), on_sample=on_sample,
                                  on_step=on_step)
    except StateError as exc:  # qdd not defined or overflowed at a stage
        status, message = -1, f"at t = {solver.t:.6g}: {exc}"
    if over_cpu[0]:
        status = -1  # a limit that decides the result: failed, not stopped
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
    Y = np.array(ys) if ys else np.empty((0, y0.size))
    E = np.array(energies)
    return Simulation(
        name=system.name, t=np.array(ts), q=Y[:, :motion.nq], v=Y[:, motion.nq:], energy=E,
        delta_M=(E - E[0]) / motion.mass if E.size else E, com=np.array(coms).reshape(-1, 3),
        steps=c.steps, rejected=c.rejected, nfev=c.nfev, status=status, message=message,
        cpu_s=time.thread_time() - cpu0, wall_s=time.perf_counter() - wall0, jit_s=jit_s,
        quaternion_error=worst[0], forces=np.array(forces) if loops is not None else None,
        residual_q=motion.residual_q, residual_v=motion.residual_v, near_change_point=near)


def simulate_batch(system: Chain | Model, t_end: float, *, q0, v0=None,
                   threads: int | None = None, **settings) -> list[Simulation]:
    """Independent motions of one system from the rows of q0 (B, n_q) and v0 (B, n_v) (default
    zeros): :func:`simulate` of each row, each with its own step sizes, the rows split over
    ``threads`` threads (default: every core this process may use). The steps run in compiled
    code without the GIL (:class:`redysim.integrate.CompiledSolver`), so the threads run at once;
    each result's ``cpu_s`` is its own thread's. ``settings``: :func:`simulate`'s keywords
    (integrator, rtol, atol, h, sample, damping); not ``progress`` or ``loops``. Everything is
    checked before any thread starts: a bad or unknown setting raises SettingsError naming it,
    a q0 or v0 that is not a 2-D array of rows StateError saying what a batch needs. A row that
    fails raises its StateError, naming the row.
    """
    from .dynamics import check_batch, run_blocks

    for key in ("progress", "loops"):
        if key in settings:
            raise SettingsError("simulate_batch", key, settings[key], "is not taken by a batch; "
                                "simulate the rows one by one")
    for key, value in settings.items():
        if key not in BATCH_SETTINGS:
            raise SettingsError("simulate_batch", key, value, f"unknown setting; a batch takes "
                                f"{', '.join(BATCH_SETTINGS)} (simulate's keywords)")
    if not isinstance(system, Chain | Model):
        raise TypeError(f"simulate_batch takes a redysim.Chain or redysim.Model, not "
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
        check_batch(system, "qd", v0, Q0.shape[0])
    out: list[Simulation | None] = [None] * Q0.shape[0]

    def rows(_block, first, last):
        for i in range(first, last):
            try:
                out[i] = simulate(system, t_end, q0=Q0[i], v0=V0[i], **settings)
            except StateError as exc:
                raise StateError(f"row {i} of q0 and v0: {exc}") from None

    run_blocks(Q0.shape[0], threads, rows)
    return out
