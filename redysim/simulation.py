"""Simulate a model from a state: the motion, the energy balance, the centre of mass.

A run is three things, assembled by :class:`Simulator`: a system
(:class:`redysim.algorithms.system.System`: the model and the forces and constraints on it, whose
state derivative every stepper calls), a stepper (:class:`Integrator`: one of the core's
integrators and its settings, or an object with the same three methods, such as a reference
engine's own stepper) and observers (what is kept at each sample). :func:`simulate` runs one
from plain keywords, :func:`simulator` assembles one from them.

The energy E = T + V is sampled with the motion (the potentials of the system's forces counted);
with no work done by them it is conserved, and its change per unit mass delta_M = (E - E0) / M
(the paper's Eq. 11) measures the integration error. The forces without a potential (a damping,
a caller's ``tau`` without ``potential``: :attr:`System.work_forces`) do work W(t), stepped with
the motion by the core's Runge-Kutta integrators as one more component of the state; then E -
W is conserved, and delta_M = (E - W - E0) / M is the balance that measures the error
(``Simulation.work``; docs/design.md, "Passive elements"). The centre of mass is sampled too:
in a free fall (a floating base, no contact) it follows c(t) = c0 + cdot0 t + g t^2 / 2
exactly, a check that needs no reference solution.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import NamedTuple, Protocol, cast

import numpy as np

from redysim.algorithms.loops import NEAR_CHANGE_POINT
from redysim.algorithms.system import System
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
    advance,
    canonical,
    check_settings,
    compile_kernels,
    make_solver,
    sample_times,
)
from redysim.integrators.implicit import TensionPreconditioner
from redysim.integrators.implicit import compile_kernels as implicit_kernels
from redysim.integrators.protocol import OdeSolver, SolverState
from redysim.model import door
from redysim.model.tree import Model

DEFAULT_SAMPLES = 10  # samples over the horizon when no interval is given
NUMBERS = (int, float, np.integer, np.floating)  # a setting's number types (not bool)
BATCH_SETTINGS = ("integrator", "rtol", "atol", "h", "sample", "damping", "max_cpu_s")
# simulator()'s keywords, by what takes them
SYSTEM_SETTINGS = ("damping", "stiffness", "spring_ref", "tip_force", "body_forces", "gravcomp",
                   "tau", "potential", "loops", "qdd", "method")
INTEGRATOR_SETTINGS = ("rtol", "atol", "h", "compiled")


class Stepper(Protocol):
    """What :class:`Simulator` asks of a stepper (:class:`Integrator`, or an engine's own)."""

    @property
    def name(self) -> str: ...

    def checked(self, source: str, t_end: float, sample: float) -> Stepper: ...

    def warm_up(self) -> None: ...

    def solver(self, system, t0: float, y0, t_end: float,
               state: SolverState | None = None) -> OdeSolver: ...


@dataclass(frozen=True)
class Integrator:
    """One of the core's integrators (:data:`redysim.integrators.explicit.INTEGRATORS`) and its
    settings: ``rtol`` and ``atol`` (an adaptive one's), ``h`` (a fixed-step one's), and
    ``compiled`` (False: the Python stepping even where the compiled one could run, the same
    steps in the same bits, an independent path for checks; None: compiled where it can).

    :class:`Simulator` asks a stepper three things, which a reference engine's own stepper
    answers too (:mod:`redysim.references`): :meth:`checked` (its settings, for a run's horizon
    and samples), :meth:`warm_up` (compile what its steps call) and :meth:`solver` (an
    :class:`~redysim.integrators.protocol.OdeSolver` stepping a system).
    """

    name: str = DEFAULT_METHOD
    rtol: float = DEFAULT_RTOL
    atol: float = DEFAULT_ATOL
    h: float | None = None
    compiled: bool | None = None

    @property
    def fixed(self) -> bool:
        """Whether it steps at a fixed h (else by its error control)."""
        return self.name in FIXED_STEP

    def checked(self, source: str, t_end: float, sample: float) -> Integrator:
        """This integrator by its own name (an alias mapped), its settings checked for a run to
        ``t_end`` sampled every ``sample`` s (SettingsError naming the bad one)."""
        if not isinstance(self.name, str):
            raise SettingsError(source, "integrator", self.name, "must be an integrator's "
                                f"name; known: {', '.join((*INTEGRATORS, *ALIASES))}")
        if t_end is None:
            raise SettingsError(source, "t_end", None, "missing: the horizon [s]")
        check_settings(source, method=self.name, t_end=t_end, sample=sample)
        me = replace(self, name=canonical(self.name))
        if me.fixed and me.h is None:
            raise SettingsError(source, "h", None, f"{me.name} is a fixed-step integrator: give "
                                "its step h [s]")
        check_settings(source, method=me.name, rtol=None if me.fixed else me.rtol,
                       atol=None if me.fixed else me.atol, h=me.h, t_end=t_end)
        return me

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the kernels its steps call."""
        (implicit_kernels if self.name in IMPLICIT else compile_kernels)()

    def solver(self, system, t0: float, y0, t_end: float,
               state: SolverState | None = None) -> OdeSolver:
        """The solver stepping ``system`` from (t0, y0) (or from a checkpoint's ``state``)."""
        # a chain's tension preconditioner (redysim.integrators.implicit); a tree steps without
        pre = TensionPreconditioner(system.model) if self.name in IMPLICIT and \
            system.model.chain_layout is None else None
        return make_solver(system, t0, y0, t_end, self.name, rtol=self.rtol, atol=self.atol,
                           h=self.h, state=state, preconditioner=pre, compiled=self.compiled)


def _check_observers(source: str, observe) -> None:
    """``observe``: None or a dict of name -> callable (SettingsError naming the bad one)."""
    if observe is None:
        return
    if not isinstance(observe, dict):
        raise SettingsError(source, "observe", type(observe).__name__, "must be None or a dict "
                            "of name -> f(sample) (frame_observer(model) gives one)")
    for name, f in observe.items():
        if not isinstance(name, str) or not callable(f):
            raise SettingsError(source, f"observe[{name!r}]", f, "must be a name (a str) -> a "
                                "callable f(sample)")


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
    stopped says so in its ``message``. ``work``: the work W [J] of the forces without a
    potential (:attr:`~redysim.algorithms.system.System.work_forces`: the damping's, a ``tau``'s
    given without ``potential``) from t = 0 to each sample, stepped with the motion, and then
    ``delta_M`` = (E - W - E0) / M, the energy balance; zeros for a system without such forces
    (delta_M = (E - E0) / M, as before); None when the stepper does not carry it (the implicit
    midpoint, SciPy's, an engine's own: ``work_note`` says so, and delta_M is then E's change
    alone). ``observed``: name -> (m, k) rows of each observer
    (:class:`Simulator`); ``y_final``: (q, v) at the last sample; ``E0``: the energy at t = 0 (the
    reference of ``delta_M``; with a resumed run's skipped samples, not the first sample's). ``q``
    and ``v`` have no rows when the run kept no
    states (``keep_states=False``). ``sample_cpu_s``: the part of ``cpu_s`` spent taking the
    samples (their projection, energy and observers: the caller's measurement, not the
    integration's work), on the run's CPU clock; NaN unless the run was asked to time them
    (``Simulator.run(time_samples=True)``, as the harness's runs are)."""

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
    work: np.ndarray | None = None
    work_note: str = ""
    sample_cpu_s: float = math.nan  # of cpu_s: the sampling's (NaN: not timed)


class _Stop(Exception):
    """Raised inside a run (a limit, from an RHS call) to end it with a status and message."""

    def __init__(self, status: int, message: str):
        super().__init__(message)
        self.status, self.message = status, message


class Sample(NamedTuple):
    """What an observer of :class:`Simulator` is handed at each sample: the time ``t`` [s], the
    state ``q``, ``v`` (on the constraints: quaternions unit, loops closed), the energy ``E``
    [J] (forces' potential included) and centre of mass ``com`` [m], ``accel()``, the run's
    own qdd there (computed once, on first call), and ``ws``, the system's workspace, free for an
    observer's own kinematics (nothing else uses it between two steps); ``W``: the work of the
    forces without a potential since t = 0 [J] (:attr:`Simulation.work`; 0.0 without such
    forces, None when the stepper does not carry it), so that E - W is the conserved one."""

    t: float
    q: np.ndarray
    v: np.ndarray
    E: float
    com: np.ndarray
    accel: Callable[[], np.ndarray]
    ws: Workspace
    W: float | None = 0.0


def frame_observer(model: Model, frame: str = "tip", *, acceleration: bool = False):
    """An observer for :class:`Simulator`: a frame's world position and velocity at each sample
    (and, with ``acceleration``, its acceleration from the run's own qdd), as one row
    [px, py, pz, vx, vy, vz(, ax, ay, az)]. ``frame``: as :func:`redysim.frame_motion`."""
    from redysim.algorithms.dynamics import frame_motion

    def observe(s: Sample):
        m = frame_motion(model, s.q, s.v, s.accel() if acceleration else None, frame=frame,
                         ws=s.ws)
        return np.concatenate((m.position, m.velocity, *(() if m.acceleration is None
                                                         else (m.acceleration,))))

    return observe


def momentum_observer(model: Model):
    """An observer for :class:`Simulator`: the momentum (:func:`redysim.momentum`) at each
    sample as one row [p (3), h_G (3)]: linear, and angular about the centre of mass."""
    from redysim.algorithms.dynamics import momentum

    def observe(s: Sample):
        mom = momentum(model, s.q, s.v, ws=s.ws)
        return np.concatenate((mom.linear, mom.angular))

    return observe


class Simulator:
    """One run of a system, assembled in one place: every simulation of redysim
    (:func:`simulate`, the harness's runs, sweeps, reference solutions, long runs and refinement
    studies) is one.

    ``system``: a :class:`~redysim.algorithms.system.System` (the model and the forces and
    constraints on it), or a :class:`~redysim.Model`, simulated as it is. ``q0``, ``v0``: the
    initial state (default: the model's own configuration, at rest). ``integrator``: an
    :class:`Integrator`, or its name (its default settings); or an engine's own stepper
    (:mod:`redysim.references`), which answers the same three questions. ``sample``: the
    interval between samples [s] (default t_end / 10). ``observe``: name -> ``f(sample)``
    called at each sample with a :class:`Sample`; what it returns (an array, or None: nothing
    kept) is stacked into ``Simulation.observed[name]`` (:func:`frame_observer` gives a frame's
    path). The energy, delta_M and the centre of mass are always sampled; ``keep_states`` keeps q
    and v at every sample too (off for long runs of huge systems: ``y_final`` is kept anyway).
    ``state``: resume from a checkpoint (:class:`~redysim.integrators.protocol.SolverState`; its
    ``sampled_until`` samples are not taken again).

    The first derivative and energy calls and the stepper's kernels (JIT compile or disk-cache
    load) are made in the constructor and timed apart (``jit_s``). Bad settings raise
    SettingsError and a bad q0 or v0 StateError, naming them, before anything runs.
    """

    def __init__(self, system: System | Model, t_end: float, *, q0=None, v0=None,
                 integrator: Stepper | str = DEFAULT_METHOD, sample: float | None = None,
                 observe: dict | None = None, keep_states: bool = True,
                 state: SolverState | None = None):
        system = system if isinstance(system, System) else System(system)
        source = system.source
        if not isinstance(integrator, str) and not all(
                callable(getattr(integrator, m, None)) for m in ("checked", "warm_up", "solver")):
            raise SettingsError(source, "integrator", integrator, "must be an integrator's name "
                                f"({', '.join(INTEGRATORS)}), an Integrator or an engine's "
                                "stepper")
        stepper: Stepper = integrator if not isinstance(integrator, str) else \
            Integrator(integrator)
        for key, x in (("t_end", t_end), ("sample", sample)):
            if x is not None and (isinstance(x, bool) or not isinstance(x, NUMBERS)):
                raise SettingsError(source, key, x, "must be a number of seconds (a "
                                    f"{type(x).__name__} was given)")
        if state is not None and not isinstance(state, SolverState):
            raise SettingsError(source, "state", type(state).__name__, "must be None or a "
                                "SolverState (a solver's state(), as a checkpoint saves it)")
        _check_observers(source, observe)
        self.sample = sample if sample is not None or t_end is None else t_end / DEFAULT_SAMPLES
        self.integrator = stepper.checked(source, t_end, self.sample)
        self.system, self.t_end = system, float(t_end)
        self.ts = sample_times(0.0, self.t_end, self.sample)
        self.observe, self.keep_states = dict(observe or {}), bool(keep_states)
        self.skip_until = None if state is None else state.sampled_until
        system.reset()
        # the work W rides in the state of the core's Runge-Kutta steps (their error norm
        # leaves it out: the motion's steps and bits are those of a run without it); the
        # implicit midpoint's y is (q, v), SciPy's norm would count it, an engine steps its own
        carries = isinstance(self.integrator, Integrator) and \
            self.integrator.name in TABLEAU_NAMES
        self.work_note = "" if carries or not system.work_forces else (
            f"the work of {' and '.join(system.work_forces)} is not recorded by "
            f"{self.integrator.name} (only the core's {', '.join(TABLEAU_NAMES)} step it): "
            "delta_M is the energy's change, not the balance E - W - E0")
        self.y0 = system.initial_state(q0, v0, second_order=self.integrator.name in IMPLICIT,
                                       work=carries)
        self.work_slot = system.motion_size if self.y0.size > system.motion_size else None
        if state is not None and np.size(state.y) != self.y0.size:
            raise SettingsError(source, "state", f"y of {np.size(state.y)} components",
                                f"this run steps {self.y0.size} (q, v"
                                + (", and the work W" if self.work_slot else "")
                                + "): a checkpoint of another system or code")
        t_jit = time.perf_counter()
        system.rhs(0.0, self.y0)  # the first calls: JIT compile or disk-cache load, timed apart
        nq, end = system.n_q, system.motion_size  # q = y0[:nq], v = y0[nq:end]
        system.energy_and_com(self.y0[:nq], self.y0[nq:end])
        self.integrator.warm_up()
        self.jit_s = time.perf_counter() - t_jit
        self.E0 = system.run_energy_and_com(self.y0)[0]
        self._limits = _Limits(system)  # the stepper's view: the limits checked at every call
        self.solver = self.integrator.solver(self._limits, 0.0, self.y0, self.t_end, state)

    @property
    def compiled(self) -> bool:
        """Whether the steps run in compiled code (the same steps, bit for bit, as the Python
        stepping)."""
        return bool(getattr(self.solver, "compiled", False))

    def run(self, *, progress: Callable[[float, float, int, float], str | None] | None = None,
            on_step: Callable[[object], str | None] | None = None,
            max_cpu_s: float | None = None, max_wall_s: float | None = None,
            clock: str = "thread", energy_bound: float | None = None,
            time_samples: bool = False) -> Simulation:
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
        limit ..."), never failed. Both are checked after every step and every derivative call
        (one implicit step can take long). ``energy_bound``: a run whose |delta_M| (the balance
        E - W - E0 per unit mass where the work W is recorded) passes it fails ("energy
        blow-up"). ``time_samples``: time the sampling apart (``sample_cpu_s``; two clock
        reads a sample, a system call each: the harness's runs ask, for their cost; else
        ``sample_cpu_s`` is NaN, not measured). An unexpected error of a provider (an engine's
        qdd, say) is
        raised as it is, the run's samples up to it attached as its ``partial``
        :class:`Simulation`."""
        if getattr(self, "_ran", False):
            raise RuntimeError("a Simulator runs once (its solver is at the end of the run); "
                               "make another to run again")
        self._ran = True
        source = self.system.source
        _check_run_settings(source, progress=progress, max_cpu_s=max_cpu_s)
        if max_wall_s is not None and not (isinstance(max_wall_s, NUMBERS) and max_wall_s > 0):
            raise SettingsError(source, "max_wall_s", max_wall_s, "must be None or a number of "
                                "seconds > 0")
        if energy_bound is not None and (isinstance(energy_bound, bool) or not isinstance(
                energy_bound, NUMBERS) or not energy_bound > 0):
            raise SettingsError(source, "energy_bound", energy_bound, "must be None or a "
                                "number > 0 (a bound on |delta_M| [J/kg])")
        run = _Run(self, progress, on_step, energy_bound)
        run.time_samples = bool(time_samples)
        run.limit(time.thread_time if clock == "thread" else time.process_time, max_cpu_s,
                  max_wall_s)
        return run.go()


class _Limits:
    """A system as a stepper sees it, with a run's limits checked at every derivative call (one
    implicit step can take long); its compiled contract passes through (the compiled steps
    return to Python at every chunk, where the run checks them)."""

    def __init__(self, system: System):
        self.system, self.kernel = system, system.kernel
        self.check: Callable[[float], None] | None = None  # raising _Stop past a limit

    def derivative(self, t, y, out) -> None:
        if self.check is not None:
            self.check(t)
        self.system.derivative(t, y, out)

    def project(self, y) -> None:
        self.system.project(y)

    def __getattr__(self, name: str):  # the rest is the system's
        return getattr(self.system, name)


class _Run:
    """One run of a :class:`Simulator`: the samples it keeps, the limits it checks, the hooks it
    calls."""

    def __init__(self, sim: Simulator, progress, on_step, energy_bound):
        self.sim, self.system = sim, sim.system
        self.progress, self.on_step, self.energy_bound = progress, on_step, energy_bound
        self.ts: list[float] = []
        self.ys: list[np.ndarray] = []
        self.energies: list[float] = []
        self.works: list[float] = []
        self.coms: list[np.ndarray] = []
        self.forces: list[np.ndarray] = []
        self.observed: dict[str, list] = {name: [] for name in sim.observe}
        self.last_y: np.ndarray | None = None
        self.sample_cpu = 0.0  # CPU time spent in on_sample (when time_samples)
        self.time_samples = False

    def limit(self, cpu, max_cpu_s, max_wall_s) -> None:
        """Start the clocks: past max_cpu_s of ``cpu`` the run fails, past max_wall_s of wall
        time it stops."""
        self.cpu, self.max_cpu_s, self.max_wall_s = cpu, max_cpu_s, max_wall_s
        self.cpu0, self.wall0 = cpu(), time.perf_counter()
        self.cpu_end = self.cpu0 + max_cpu_s if max_cpu_s else math.inf
        self.wall_end = self.wall0 + max_wall_s if max_wall_s else math.inf
        self.sim._limits.check = self.check_limits if (max_cpu_s or max_wall_s) else None

    def check_limits(self, t: float) -> None:
        """Raise _Stop past a limit; without one, no clock is read (a thread's CPU clock is a
        system call, which on a loaded VM was measured to take most of a small robot's run)."""
        if self.cpu_end < math.inf and self.cpu() > self.cpu_end:
            raise _Stop(-1, f"time limit: max_cpu_s = {self.max_cpu_s:g} s of CPU reached at "
                            f"t = {t:.6g}")
        if self.wall_end < math.inf and time.perf_counter() > self.wall_end:
            raise _Stop(1, f"stopped by the wall-clock limit, max_wall_s = {self.max_wall_s:g} "
                           f"s (the caller's patience, not a result), at t = {t:.6g}; the "
                           "samples so far are kept")

    # ----------------------------------------------------------------------- the hooks
    def on_sample(self, t: float, y: np.ndarray) -> None:
        """Keep the sample at t (the state y, projected onto the constraints: interpolated
        between steps); observers' rows; the energy checks."""
        sim = self.sim
        if sim.skip_until is not None and t <= sim.skip_until:
            return None  # taken before the checkpoint this run resumed from
        if not self.time_samples:
            return self._sample(t, y)
        t0 = self.cpu()
        try:
            return self._sample(t, y)
        finally:
            self.sample_cpu += self.cpu() - t0

    def _sample(self, t: float, y: np.ndarray) -> None:
        sim, system = self.sim, self.system
        y = y.copy()
        system.project(y, record=False)
        slot = sim.work_slot
        W = (float(y[slot]) if slot is not None else None if sim.work_note else 0.0)
        y = y[:system.motion_size]  # (q, v)
        q, v = y[:system.n_q], y[system.n_q:]
        a: list[np.ndarray] = []

        def accel():
            if not a:
                a.append(system.qdd(t, q, v))
            return a[0]

        try:
            if system.loops is not None:
                tau = system.forces(t, q, v)
                self.forces.append(system.loops.forward_dynamics_and_forces(q, v, tau)[1])
            E, com = system.run_energy_and_com(y)  # (y: this sample's own float64 copy)
            sample = Sample(t, q, v, E, com, accel, system.ws, W)
            rows = {name: f(sample) for name, f in sim.observe.items()}
        except StateError as exc:  # the state overflowed (or went NaN) between samples
            raise _Stop(-1, f"at t = {t:.6g}: {type(exc).__name__}: {exc}") from None
        self.ts.append(t)
        if sim.keep_states:
            self.ys.append(y)
        self.last_y = y
        self.energies.append(E)
        self.works.append(math.nan if W is None else W)
        self.coms.append(com)
        for name, row in rows.items():
            if row is not None:
                self.observed[name].append(np.asarray(row))
        if not math.isfinite(E):
            raise _Stop(-1, f"non-finite energy at t = {t:.6g}")
        # the balance E - W - E0 (W = 0 without forces that lack a potential: E - E0's bits)
        dM = ((E - W if slot is not None and W is not None else E) - sim.E0) \
            / system.model.total_mass
        if self.energy_bound and abs(dM) > self.energy_bound:
            raise _Stop(-1, f"energy blow-up: |delta_M| = {abs(dM):.3g} J/kg > bound "
                            f"{self.energy_bound:g} at t = {t:.6g}")
        return None

    def step_done(self, solver) -> str | None:
        """After each step (each chunk of compiled steps) and its samples: the step projected
        onto the constraints, the limits, the caller's hooks (a message stops the run)."""
        self.system.project(solver.y)
        self.system.after_step(solver.t)
        self.check_limits(solver.t)
        h, t_end = getattr(solver, "h_next", None), self.sim.t_end
        if isinstance(h, float) and solver.t < t_end and h < np.spacing(t_end):
            # the step is below the resolution of time at t_end: the run would crawl for ever
            raise _Stop(-1, f"step size underflow: h = {h:.3g} s at t = {solver.t:.6g} is "
                            f"below the spacing of t_end = {t_end:g} s ({np.spacing(t_end):.3g}):"
                            " the forces or accelerations are too large to follow (a unit "
                            "slip?)")
        if self.progress and (stop := self.progress(solver.t, self.sim.t_end,
                                                    solver.counters.steps,
                                                    time.perf_counter() - self.wall0)):
            return str(stop)
        if self.on_step and (stop := self.on_step(solver)):
            return str(stop)
        return None

    # ----------------------------------------------------------------------- the run
    def go(self) -> Simulation:
        """Step to the end, then the result (module docstring of :meth:`Simulator.run`)."""
        solver = self.sim.solver
        unexpected = None
        solver.set_deadline(self.cpu, self.cpu_end)  # an engine's own adaptive advance
        try:
            status, message = advance(solver, self.sim.ts, on_sample=self.on_sample,
                                      on_step=self.step_done)
        except _Stop as stop:
            status, message = stop.status, stop.message
        except TimeoutError as exc:  # an engine's advance stopped at the limit
            status, message = -1, (f"time limit: max_cpu_s = {self.max_cpu_s:g} s of CPU "
                                   f"reached after t = {solver.t:.6g} ({exc})")
        except StateError as exc:  # qdd not defined or overflowed at a stage
            status, message = -1, f"at t = {solver.t:.6g}: {exc}"
        except Exception as exc:  # a provider's own error (an engine's): raised, with the
            unexpected = exc      # samples finished before it attached (below)
            status, message = -1, f"at t = {solver.t:.6g}: {type(exc).__name__}: {exc}"
        finally:
            self.sim._limits.check = None
            solver.set_deadline(None, math.inf)
        near, message = self._change_point(status, message, solver.t)
        result = self.result(status, message, near)
        if unexpected is not None:
            # never lose finished work: the caller keeps it (an attribute on any exception)
            unexpected.partial = result  # type: ignore[attr-defined]
            raise unexpected
        return result

    def _change_point(self, status: int, message: str, t: float) -> tuple[float | None, str]:
        """The time of the step nearest a loop's change point (None: none came near), and the
        message, saying so when the run failed or stopped."""
        system = self.system
        if system.loops is None:
            return None, message
        system.after_step(t)  # the failing step's own, if any
        ratio, when = system.nearest_change_point
        if ratio > NEAR_CHANGE_POINT:
            return None, message
        if status != 0 and "change point" not in message:
            message += (f" (the motion passed near a change point at t = {when:.6g}: "
                        f"J M^-1 J^T's singular values {ratio:.1e} apart, a configuration "
                        "where the mechanism can switch branches)")
        return float(when), message

    def result(self, status: int, message: str, near: float | None) -> Simulation:
        sim, system = self.sim, self.system
        c, nq, mass = sim.solver.counters, system.n_q, system.model.total_mass
        Y = np.array(self.ys) if self.ys else np.empty((0, system.motion_size))
        E = np.array(self.energies)
        W = np.array(self.works)
        worst = system.worst
        return Simulation(
            name=system.model.name, t=np.array(self.ts), q=Y[:, :nq], v=Y[:, nq:], energy=E,
            delta_M=((E - W if sim.work_slot is not None else E) - sim.E0) / mass
            if E.size else E,
            com=np.array(self.coms).reshape(-1, 3), steps=c.steps, rejected=c.rejected,
            nfev=c.nfev, status=status, message=message, cpu_s=self.cpu() - self.cpu0,
            wall_s=time.perf_counter() - self.wall0, jit_s=sim.jit_s,
            quaternion_error=float(worst[0]),
            forces=np.array(self.forces) if system.loops is not None else None,
            residual_q=float(worst[1]), residual_v=float(worst[2]), near_change_point=near,
            observed={k: np.array(v) for k, v in self.observed.items()}, y_final=self.last_y,
            E0=sim.E0, work=None if sim.work_note else W, work_note=sim.work_note,
            sample_cpu_s=self.sample_cpu if self.time_samples else math.nan)


def simulator(model: Model, t_end: float, *, q0=None, v0=None,
              integrator: Stepper | str = DEFAULT_METHOD, sample: float | None = None,
              observe: dict | None = None, keep_states: bool = True,
              state: SolverState | None = None, source: str = "simulate",
              **settings) -> Simulator:
    """A :class:`Simulator` from plain keywords, as case and scenario files and the harness give
    them: :class:`~redysim.algorithms.system.System`'s (``damping``, ``stiffness``,
    ``spring_ref``, ``tip_force``, ``body_forces``, ``gravcomp``, ``tau``, ``potential``,
    ``loops``, ``qdd``, ``method``), :class:`Integrator`'s (``rtol``, ``atol``, ``h``,
    ``compiled``, with ``integrator`` its name) and the Simulator's own. An integrator given as an
    object takes none of rtol, atol, h and compiled. Unknown keywords raise TypeError naming
    them."""
    unknown = [k for k in settings if k not in SYSTEM_SETTINGS + INTEGRATOR_SETTINGS]
    if unknown:
        raise TypeError(f"simulator() got unexpected keyword arguments {unknown}; it takes "
                        f"{', '.join(SYSTEM_SETTINGS + INTEGRATOR_SETTINGS)} and Simulator's")
    steps = {k: settings[k] for k in INTEGRATOR_SETTINGS if settings.get(k) is not None}
    stepper = integrator
    if isinstance(integrator, str) or not hasattr(integrator, "solver"):  # a name
        stepper = Integrator(cast(str, integrator), **steps)
    elif steps:
        raise SettingsError(source, next(iter(steps)), next(iter(steps.values())), "is a "
                            "setting of redysim's integrators; the stepper given takes its own")
    system = System(model, source=source,
                    **{k: settings[k] for k in SYSTEM_SETTINGS if k in settings})
    return Simulator(system, t_end, q0=q0, v0=v0, integrator=stepper, sample=sample,
                     observe=observe, keep_states=keep_states, state=state)


def simulate(model: Model, t_end: float, *, q0=None, v0=None,
             integrator: str = DEFAULT_METHOD, rtol: float = DEFAULT_RTOL,
             atol: float = DEFAULT_ATOL, h: float | None = None, sample: float | None = None,
             progress: Callable[[float, float, int, float], str | None] | None = None,
             loops=None, damping: float = 0.0,
             max_cpu_s: float | None = None) -> Simulation:
    """The passive motion of ``model`` from (q0, v0) over [0, t_end] (no joint torques): a
    :class:`Simulator` run.

    loops: a :class:`redysim.algorithms.loops.ClosedLoops` of ``model``: the motion with its loops
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
    door.require_model(model, "simulate")
    return simulator(model, t_end, q0=q0, v0=v0, integrator=integrator, rtol=rtol, atol=atol,
                     h=h, sample=sample, loops=loops, damping=damping
                     ).run(progress=progress, max_cpu_s=max_cpu_s)


def simulate_batch(model: Model, t_end: float, *, q0, v0=None,
                   threads: int | None = None, **settings) -> list[Simulation]:
    """Independent motions of one system from the rows of q0 (B, n_q) and v0 (B, n_v) (default
    zeros): :func:`simulate` of each row, each with its own step sizes, the rows handed out one at a
    time to the calling thread and up to ``threads`` - 1 helper threads (default
    :func:`redysim.algorithms.dynamics.default_threads`: every core this process may use, or
    ``REDYSIM_THREADS``); the caller waits at the end for the rows helpers have started. The steps
    run in compiled code without the GIL (:class:`redysim.integrators.explicit.Solver`), so
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
    door.require_model(model, "simulate_batch")
    given = {"integrator": DEFAULT_METHOD, "rtol": DEFAULT_RTOL, "atol": DEFAULT_ATOL,
             "h": None, "sample": None, "damping": 0.0, "max_cpu_s": None, **settings}
    Integrator(given["integrator"], rtol=given["rtol"], atol=given["atol"], h=given["h"]).checked(
        "simulate_batch", t_end, given["sample"] or (t_end and t_end / DEFAULT_SAMPLES))
    System(model, damping=given["damping"], source="simulate_batch")  # (checks it)
    _check_run_settings("simulate_batch", max_cpu_s=given["max_cpu_s"])
    for name, value, n in (("q0", q0, model.n_q), ("v0", v0, model.n_v)):
        try:
            shape = None if isinstance(value, str) else np.shape(value)
        except ValueError:  # ragged rows: check_batch names them
            shape = (None, None)
        if value is not None and (shape is None or len(shape) != 2):
            raise StateError(f"simulate_batch: {name} has shape {shape}: a batch needs "
                             f"(B, {n}), one initial state a row (for one motion, "
                             f"simulate(model, t_end, {name}=...))")
    Q0 = check_batch(model, "q", q0, None, label="simulate_batch: q0")
    V0 = np.zeros((Q0.shape[0], model.n_v)) if v0 is None else \
        check_batch(model, "v", v0, Q0.shape[0], label="simulate_batch: v0")
    out: list[Simulation | None] = [None] * Q0.shape[0]

    def rows(first, last, _own):
        for i in range(first, last):
            try:
                out[i] = simulate(model, t_end, q0=Q0[i], v0=V0[i], **settings)
            except StateError as exc:
                raise StateError(f"row {i} of q0 and v0: {exc}") from None

    run_blocks(Q0.shape[0], threads, rows)
    return cast(list[Simulation], out)  # every row filled: run_blocks ran them all, or raised
