"""Explicit Runge-Kutta integrators as one family: each scheme is its tableau and error estimator.

One stepping kernel (:meth:`Solver._stages`) advances any explicit tableau; an adaptive scheme adds
an embedded error estimate and a step-size controller; a fixed-step scheme has neither. Schemes:

``ode45``   Dormand-Prince 5(4) with MATLAB ode45's step control (the paper's integrator): error
            ``h * || K^T E ./ max(|y|, |y_new|, atol/rtol) ||_inf`` accepted when ``<= rtol``;
            first step ``min(hmax, span)`` cut to ``1/rh`` with
            ``rh = || f0 ./ max(|y0|, atol/rtol) ||_inf / (0.8 rtol^(1/5))`` (no extra RHS call);
            ``hmax = 0.1 span``; growth ``0.8 (rtol/err)^(1/5)`` capped at 5x, only after a step
            that needed no retry; a first rejection shrinks by ``max(0.1, 0.8 (rtol/err)^(1/5))``,
            later ones of the same step halve it; outputs by its quartic interpolant (ntrp45).
``rk45``    the same Dormand-Prince 5(4) pair under SciPy's RK45 error norm, over the whole
            vector: ``sc = atol + rtol max(|y|, |y_new|)``, ``err = |h| rms(K^T E ./ sc)``,
            accepted when ``<= 1``; Hairer's first step and safety 0.9, otherwise ode45's
            controller and interpolant. On the same RHS it takes at most 1.2x SciPy's RK45 steps,
            where ode45 (MATLAB's max norm) takes 1.3-2x (docs/notes/2026-12-07-norm.md).
``dop853``  Dormand-Prince 8(5,3) (Hairer's DOP853 tableau, error estimator and 7th-order dense
            output) with Hairer's error norm over the whole vector, as dop853.f and SciPy's
            DOP853: ``sc = atol + rtol max(|y|, |y_new|)``, ``s5 = sum (K^T E5 ./ sc)^2``,
            ``s3`` likewise with E3, ``err = |h| s5 / sqrt((s5 + 0.01 s3) n)``, accepted when
            ``<= 1`` (:func:`redysim.algorithms._kernels.rk.error_norm`); Hairer's first step
            (HINIT: one extra RHS call) and his safety factor 0.9; otherwise ode45's controller
            (exponent 1/8, growth capped at 5x, ode45's rejections, ``hmax = 0.1 span``). Its
            rtol and atol mean what they mean for SciPy's DOP853: on the same RHS it takes at
            most 1.2x SciPy's steps (docs/notes/2026-12-07-norm.md). A max norm, as ode45's,
            would answer the rounding noise of components that start at zero.
``rk4``     classical Runge-Kutta at a fixed step ``h``; steps are shortened to land on the sample
            times; outputs are the step values.
``midpoint`` (alias ``implicit``) and ``midpoint-fixed``: the implicit midpoint rule for
            second-order systems y = (q, v), dq/dt = v, each step O(n) (Newton-Krylov with a chain's
            tension preconditioner, :mod:`redysim.integrators.implicit`), with error control by rtol
            and atol, or at a fixed step h: for chains whose explicit steps are bound by waves they
            need not resolve.
``scipy-RK45``, ``scipy-DOP853``, ``scipy-LSODA``, ``scipy-Radau``: SciPy's ``solve_ivp`` solvers
            (RMS error norm, their own controllers; docs/design.md, "Integrators", explains why
            equal tolerances do not mean equal accuracy), stepped one step at a time so that
            steps and samples are counted the same way.

Every solver counts accepted steps, rejected steps and right-hand-side evaluations (``nfev``), can
be stopped after any step by a callback, and its state (t, y, step size, counters) can be saved and
restored, so a long run resumes from a checkpoint.

References:
    J. R. Dormand, P. J. Prince, "A family of embedded Runge-Kutta formulae", J. Comp. Appl. Math.
    6 (1980). L. F. Shampine, M. W. Reichelt, "The MATLAB ODE suite", SIAM J. Sci. Comput. 18
    (1997) (ode45's control, ntrp45). E. Hairer, S. P. Norsett, G. Wanner, "Solving Ordinary
    Differential Equations I", 2nd ed., section II.10 (DOP853). docs/design.md, "Integrators".
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import NoReturn

import numpy as np

from redysim.errors import FieldError, SettingsError, StateError
from redysim.integrators.protocol import (  # noqa: F401 -- the shared stepping pieces, importable from here too
    DOP853_SAFETY,
    FINISH_SLACK,
    FIRST_REJECT_MIN,
    HMAX_FRACTION,
    HMIN_EPS,
    LATER_REJECT,
    MAX_GROWTH,
    SAFETY,
    SAMPLE_EPS,
    Counters,
    IntegrationError,
    OdeSolver,
    SolverState,
    as_dynamics,
    as_function,
)
from redysim.integrators.protocol import hermite as _hermite
from redysim.model import door

# --------------------------------------------------------------------------- settings' ranges
RTOL_MIN = 100 * float(np.finfo(float).eps)  # ode45 raises a smaller rtol to this (MATLAB)
MAX_T_END = 1e6        # s: a horizon of 11.6 days of simulated time is a unit slip, not a plan
MAX_SAMPLES = 10_000_000  # t_end / sample interval: ~1 GB of samples; more is a unit slip
MAX_FIXED_STEPS = 100_000_000  # t_end / h of a fixed-step run: a step too small for its span


# --------------------------------------------------------------------------- tableaux
@dataclass(frozen=True, eq=False)
class Tableau:
    """An explicit Runge-Kutta scheme as data.

    ``A`` (s, s) strictly lower triangular, ``b`` (s,) weights, ``c`` (s,) nodes; ``order`` of the
    propagated solution. An embedded scheme adds ``E`` (s + 1,): the error estimate is
    ``h K^T E`` over the s stages and f(t + h, y_new) (FSAL); ``E3`` (optional) is DOP853's
    3rd-order estimate; ``error_order`` the order q of the estimate (the controller's exponent is
    1 / (q + 1)). ``fsal``: the last stage is f(t + h, y_new), reused as the next step's first.
    ``norm``: how the estimate is measured and the step controlled: "max" (MATLAB's ode45: max
    norm, its first step and safety 0.8), "rms" (SciPy's RK45: the RMS over the whole vector,
    Hairer's first step, safety 0.9), "hairer" (DOP853's, with E3).
    """

    name: str
    order: int
    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    E: np.ndarray | None = None
    E3: np.ndarray | None = None
    error_order: int = 0
    fsal: bool = False
    norm: str = "max"

    @property
    def hairer_control(self) -> bool:
        """Hairer's first step (HINIT) and safety factor 0.9 (dop853, rk45), else ode45's."""
        return self.norm in ("rms", "hairer")

    @property
    def stages(self) -> int:
        return self.b.size

    @property
    def adaptive(self) -> bool:
        return self.E is not None


def _dp45() -> Tableau:
    A = np.zeros((6, 6))
    A[1, :1] = [1 / 5]
    A[2, :2] = [3 / 40, 9 / 40]
    A[3, :3] = [44 / 45, -56 / 15, 32 / 9]
    A[4, :4] = [19372 / 6561, -25360 / 2187, 64448 / 6561, -212 / 729]
    A[5, :5] = [9017 / 3168, -355 / 33, 46732 / 5247, 49 / 176, -5103 / 18656]
    b = np.array([35 / 384, 0, 500 / 1113, 125 / 192, -2187 / 6784, 11 / 84])
    c = np.array([0, 1 / 5, 3 / 10, 4 / 5, 8 / 9, 1])
    # MATLAB ode45's E = b5 - b4 over the 6 stages and f(t + h, y_new) (FSAL).
    E = np.array([71 / 57600, 0, -71 / 16695, 71 / 1920, -17253 / 339200, 22 / 525, -1 / 40])
    return Tableau("ode45", 5, A, b, c, E=E, error_order=4, fsal=True)


# ode45's interpolant (MATLAB ntrp45): y(t + s h) = y + h K^T (BI @ [s, s^2, s^3, s^4]).
NTRP45_BI = np.array([
    [1, -183 / 64, 37 / 12, -145 / 128],
    [0, 0, 0, 0],
    [0, 1500 / 371, -1000 / 159, 1000 / 371],
    [0, -125 / 32, 125 / 12, -375 / 64],
    [0, 9477 / 3392, -729 / 106, 25515 / 6784],
    [0, -11 / 7, 11 / 3, -55 / 28],
    [0, 3 / 2, -4, 5 / 2],
])


@functools.cache
def _dop853() -> tuple[Tableau, dict]:
    """DOP853's tableau and dense-output data, built on first use: the coefficients are
    Hairer's as SciPy ships them (a data module; the pinned SciPy is tested), and importing them
    imports scipy.integrate, a quarter of a second nothing else here needs."""
    from scipy.integrate._ivp import dop853_coefficients as d

    s = d.N_STAGES  # 12 stages; E3/E5 span 13 entries (the 13th is f(t + h, y_new))
    tab = Tableau("dop853", 8, d.A[:s, :s].copy(), d.B.copy(), d.C[:s].copy(), E=d.E5.copy(),
                  E3=d.E3.copy(), error_order=7, fsal=True, norm="hairer")
    dense = {"A_extra": d.A[s + 1:].copy(), "C_extra": d.C[s + 1:].copy(), "D": d.D.copy()}
    return tab, dense


def _rk4() -> Tableau:
    A = np.zeros((4, 4))
    A[1, 0] = 0.5
    A[2, 1] = 0.5
    A[3, 2] = 1.0
    return Tableau("rk4", 4, A, np.array([1 / 6, 1 / 3, 1 / 3, 1 / 6]),
                   np.array([0, 0.5, 0.5, 1.0]))


DP45 = _dp45()
# The same Dormand-Prince pair under SciPy's RK45 norm (RMS over the whole vector) and Hairer's
# first step: ode45 stays MATLAB's (the paper's step counts), rk45 is for users' runs
RK45 = Tableau("rk45", 5, DP45.A, DP45.b, DP45.c, E=DP45.E, error_order=4, fsal=True,
               norm="rms")
RK4 = _rk4()
TABLEAU_NAMES = ("ode45", "rk45", "dop853", "rk4")  # our schemes; tableau(name) gives each


def tableau(name: str) -> Tableau:
    """The tableau of one of our schemes (:data:`TABLEAU_NAMES`)."""
    if name == "dop853":
        return _dop853()[0]
    return {"ode45": DP45, "rk45": RK45, "rk4": RK4}[name]


def __getattr__(name: str):
    """DOP853 and TABLEAUS, built on first use (see :func:`_dop853`)."""
    if name == "DOP853":
        return _dop853()[0]
    if name == "TABLEAUS":
        return {n: tableau(n) for n in TABLEAU_NAMES}
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def _rk():
    """The compiled stage sums (:mod:`._kernels.rk`), imported on first use: numba's import
    is a sixth of a second that a command's ``--help`` does not need."""
    from redysim.algorithms._kernels import rk
    return rk


SCIPY_METHODS = ("RK45", "DOP853", "LSODA", "Radau")
# the implicit midpoint rule (redysim.integrators.implicit), with error control and at a fixed step
IMPLICIT = ("midpoint", "midpoint-fixed")
INTEGRATORS = (*TABLEAU_NAMES, *IMPLICIT, *(f"scipy-{m}" for m in SCIPY_METHODS))
ALIASES = {"implicit": "midpoint"}  # other names a user may give; canonical() maps them
FIXED_STEP = ("rk4", "midpoint-fixed")
DEFAULT_METHOD, DEFAULT_RTOL, DEFAULT_ATOL = "ode45", 1e-4, 1e-6  # the paper's ode45 settings
ADAPTIVE = tuple(m for m in INTEGRATORS if m not in FIXED_STEP)


def canonical(method: str) -> str:
    """The integrator's own name for ``method`` (an alias of :data:`ALIASES`, or itself)."""
    return ALIASES.get(method, method)


def check_settings(source: str = "integrate", names: dict[str, str] | None = None, *,
                   method: str | None = None, rtol: float | None = None,
                   atol: float | None = None, h: float | None = None,
                   t_end: float | None = None, sample: float | None = None,
                   extra_methods: tuple[str, ...] = (),
                   error: type[FieldError] = SettingsError) -> None:
    """Raise ``error`` (:class:`~redysim.errors.SettingsError` unless a caller names another
    :class:`~redysim.errors.FieldError`) unless the given run settings make sense.

    The one place that says what an integrator, a tolerance, a step, a horizon and a sample
    interval may be; case files, run specs, sweep files and the command line all call it.
    ``names`` renames fields in the message (``{"rtol": "--rtol"}``); ``None`` skips a setting.

    - ``method``: one of :data:`INTEGRATORS` or :data:`ALIASES` (or ``extra_methods``).
    - ``rtol``: ``RTOL_MIN <= rtol < 1`` (MATLAB's ode45 floor is 100 eps; a relative tolerance
      of 100 % controls nothing). ``atol``: finite and > 0.
    - ``h``: finite and > 0; a step belongs to a fixed-step method only (an adaptive method
      chooses its own), and ``t_end / h <= MAX_FIXED_STEPS``.
    - ``t_end``: ``0 < t_end <= MAX_T_END``; ``sample``: > 0, ``t_end / sample <= MAX_SAMPLES``.
    """
    names = names or {}

    def fail(field, value, problem):
        raise error(source, names.get(field, field), value, problem)

    def number(field, value):
        if isinstance(value, bool) or not isinstance(value, int | float | np.floating
                                                    | np.integer):
            fail(field, value, "must be a number")
        if not math.isfinite(value):
            fail(field, value, "must be finite")
        return float(value)

    known = INTEGRATORS + tuple(ALIASES) + extra_methods
    if method is not None and method not in known:
        fail("integrator", method, f"unknown integrator; known: {', '.join(known)}")
    method = None if method is None else canonical(method)
    if rtol is not None:
        rtol = number("rtol", rtol)
        if not rtol < 1.0:
            fail("rtol", rtol, "must be < 1 (a relative tolerance of 100 % controls nothing)")
        if not rtol >= RTOL_MIN:
            fail("rtol", rtol, f"must be at least {RTOL_MIN:.3g} (100 eps, ode45's floor: "
                               "below it the error test measures only rounding)")
    if atol is not None and not number("atol", atol) > 0:
        fail("atol", atol, "must be > 0")
    if t_end is not None:
        t_end = number("t_end", t_end)
        if not 0 < t_end <= MAX_T_END:
            fail("t_end", t_end, f"must be > 0 and at most {MAX_T_END:g} s (11.6 days of "
                                 "simulated time; more is a unit slip, not a plan)")
    if sample is not None:
        sample = number("sample", sample)
        if not sample > 0:
            fail("sample", sample, "must be > 0")
        if t_end is not None and t_end / sample > MAX_SAMPLES:
            fail("sample", sample, f"gives {t_end / sample:.3g} samples over t_end = {t_end:g} "
                                   f"s; at most {MAX_SAMPLES:,}")
    if h is not None:
        h = number("h", h)
        if not h > 0:
            fail("h", h, "must be > 0")
        if method is not None and method in ADAPTIVE:
            fail("h", h, f"is the step of a fixed-step integrator ({', '.join(FIXED_STEP)}); "
                         f"{method} chooses its own steps from rtol and atol")
        if t_end is not None and t_end / h > MAX_FIXED_STEPS:
            fail("h", h, f"gives {t_end / h:.3g} steps over t_end = {t_end:g} s; at most "
                         f"{MAX_FIXED_STEPS:,}")


# --------------------------------------------------------------------------- the solver
DENSE_DOUBLES = 1 << 20  # advance interpolates at most this many values (8 MiB) at a time
CHUNK_S = 0.25  # s of wall time a compiled step() call aims at (it adapts max_steps)
MAX_CHUNK_STEPS = 100_000


class Solver(OdeSolver):
    """One of our Runge-Kutta schemes (:data:`TABLEAU_NAMES`) stepping a system.

    ``system``: a function ``fun(t, y) -> dy/dt``, or a system that keeps the contract of
    :class:`redysim.integrators.protocol.Dynamics` (``derivative(t, y, out)``, and ``kernel``:
    its compiled contract or None). The steps are :func:`redysim.algorithms._kernels.rk_run
    .rk_steps` (one source for both ways): in compiled code, many steps a call (up to the first
    that reaches ``t_stop``, at most ``max_steps``, which adapts so that a call takes about
    CHUNK_S of wall time and the caller keeps its clock and progress), when the system's
    ``kernel`` is given and ``compiled`` is not False; else the same function run as Python,
    one accepted step a call. Both take the same steps in the same bits. In compiled code every
    step but a call's last is projected onto the system's constraints (the caller projects the
    last after its samples).

    ``h``: a fixed scheme's step (given to an adaptive scheme, it steps that scheme at a fixed
    step); an adaptive scheme chooses its own, at most ``hmax`` (default 0.1 x span, as ode45).
    After :meth:`step`, ``t_old``/``y_old`` and ``t``/``y`` bracket the last step and
    :meth:`dense` interpolates inside it.
    """

    y: np.ndarray
    f: np.ndarray
    h_next: float

    def __init__(self, system, t0: float, y0, t_end: float, method: str = "ode45", *,
                 rtol: float = 1e-4, atol: float = 1e-6, h: float | None = None,
                 hmax: float | None = None, state: SolverState | None = None,
                 compiled: bool | None = None, max_steps: int = 1000):
        from redysim._jit import Pinned  # (numba: imported on first use, as _rk's)
        from redysim.algorithms._kernels import rk_run

        if method not in TABLEAU_NAMES:
            raise ValueError(f"method = {method!r}: unknown; choose one of "
                             f"{', '.join(TABLEAU_NAMES)} (or scipy-*)")
        self.system = as_dynamics(system)
        self.tab = tab = tableau(method)
        self.t_end = float(t_end)
        if self.t_end <= t0:
            raise ValueError(f"t_end = {t_end!r} must be greater than t0 = {t0!r}")
        self.adaptive = tab.adaptive and h is None
        if self.adaptive:
            if not (rtol > 0 and atol > 0):
                raise ValueError(f"need rtol > 0 and atol > 0, got rtol={rtol!r}, atol={atol!r}")
            self.rtol, self.atol = float(rtol), float(atol)
            self.hmax = float(hmax) if hmax else HMAX_FRACTION * abs(self.t_end - t0)
            power = 1.0 / (tab.error_order + 1)
        else:
            if not (h is not None and h > 0):
                raise ValueError(f"fixed-step method {method!r} needs h > 0, got h={h!r}")
            self.rtol = self.atol = math.nan
            self.hmax, power = float(h), 0.0
        self._run = rk_run
        kernel = self.system.kernel
        self.compiled = kernel is not None and compiled is not False
        self._kernel = kernel if self.compiled else (self.system, None)
        self._steps = rk_run.rk_steps if self.compiled else _python_steps()
        # the compiled steps past numba's dispatch: their arguments' types are fixed by
        # construction (the system's bundles, the scheme, the control, the step state; a float
        # t_stop and an int max_steps), and a step state replaced from outside picks again
        self._pinned = Pinned(rk_run.rk_steps) if self.compiled else None
        self.max_steps = int(max_steps) if self.compiled else 1
        self._scheme = rk_run.Scheme(tab.A, tab.b, tab.c,
                                     tab.E if tab.E is not None else _NO_WEIGHTS,
                                     tab.E3 if tab.E3 is not None else _NO_WEIGHTS, tab.fsal,
                                     _rk().NORM_RMS if tab.norm == "rms" else _rk().NORM_MAX)
        n = np.size(y0)
        self.n = n
        # the components the error norm measures: a system's motion (q, v), not the work W
        # that may ride after it (redysim.algorithms._kernels.rk_run.Control)
        self.checked = min(n, int(getattr(self.system, "motion_size", n)))
        self._ctl = rk_run.Control(
            self.rtol if self.adaptive else 1.0, self.atol if self.adaptive else 1.0,
            self.hmax, power, self.t_end, bool(self.adaptive),
            DOP853_SAFETY if tab.hairer_control else SAFETY, MAX_GROWTH,
            FIRST_REJECT_MIN, LATER_REJECT, HMIN_EPS, FINISH_SLACK, SAMPLE_EPS, self.checked)
        self.K = np.empty((tab.stages + (1 if tab.fsal else 0), n))
        self._dense_K = None  # DOP853's extra stages, computed on demand per step
        if state is not None:
            state.resume(self)
            self.y, self.f = np.array(self.y, dtype=float), np.array(self.f, dtype=float)
        else:
            self.counters = Counters()
            self.t, self.y = float(t0), np.array(y0, dtype=float)
            self.f = self._call(self.t, self.y)
            self.h_next = self._initial_step() if self.adaptive else self.hmax  # (= h)
        self.t_old, self.y_old, self.f_old = self.t, self.y.copy(), self.f.copy()
        self._state = rk_run.StepState(
            np.array([self.t, self.t_old, self.h_next]), self.y, self.f, self.y_old,
            self.f_old, self.K, np.zeros(3, dtype=np.int64), np.empty(n), np.empty(n),
            np.empty(n), np.empty(n))

    # ----------------------------------------------------------------------- helpers
    def _call(self, t, y) -> np.ndarray:
        self.counters.nfev += 1
        out = np.empty(self.n)
        self.system.derivative(t, y, out)
        return out

    def _initial_step(self) -> float:
        """ode45's rule: min(hmax, span), cut to 1/rh (no extra RHS call); dop853's and rk45's
        is Hairer's (:meth:`_initial_step_hairer`)."""
        absh = min(self.hmax, self.t_end - self.t)
        m = self.checked  # (the motion's components, as the error norm's)
        if self.tab.hairer_control:
            absh = self._initial_step_hairer(absh, m)
            return max(absh, float(self._run.hmin_at(self._ctl, self.t)))
        scale = np.maximum(np.abs(self.y[:m]), self.atol / self.rtol)
        rh = np.max(np.abs(self.f[:m]) / scale) / (SAFETY * self.rtol ** self._ctl.power)
        if absh * rh > 1:
            absh = 1.0 / rh
        return max(absh, float(self._run.hmin_at(self._ctl, self.t)))

    def _initial_step_hairer(self, absh: float, m: int) -> float:
        """DOP853's first step (Hairer's HINIT in dop853.f, as SciPy's select_initial_step),
        at most ``absh``: with the RMS norm ||x|| over the m measured components scaled by
        sc = atol + rtol |y0|, d0 = ||y0||, d1 = ||f0||, h0 = 0.01 d0 / d1 (1e-6 when either is
        below 1e-5), d2 = ||f(t + h0, y0 + h0 f0) - f0|| / h0 (one RHS call), and
        h = min(100 h0, (0.01 / max(d1, d2))^(1/(q+1))) (q the estimate's order: 7 for dop853,
        4 for rk45). The sums are math.fsum's (correctly
        rounded: the same on every CPU)."""
        y, f = self.y[:m], self.f[:m]
        sc = self.atol + self.rtol * np.abs(y)

        def rms(x):
            return math.sqrt(math.fsum((x * x).tolist()) / max(m, 1))

        d0, d1 = rms(y / sc), rms(f / sc)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        h0 = min(h0, absh)
        f1 = self._call(self.t + h0, self.y + h0 * self.f)
        d2 = rms((f1[:m] - f) / sc) / h0
        if d1 <= 1e-15 and d2 <= 1e-15:
            h1 = max(1e-6, h0 * 1e-3)
        else:
            h1 = (0.01 / max(d1, d2)) ** self._ctl.power
        return min(100 * h0, h1, absh)

    def state(self) -> SolverState:
        """A copy of the resumable state (to save in a checkpoint)."""
        return SolverState(self.t, self.y.copy(), self.f.copy(), self.h_next,
                           Counters(**vars(self.counters)))

    # ----------------------------------------------------------------------- stepping
    def step(self, t_stop: float | None = None) -> None:
        """Compiled: every step up to the first that reaches ``t_stop`` (t_end when None), at
        most ``max_steps``; as Python: one accepted step, no later than ``t_stop``."""
        c, st = self.counters, self._state
        if st.y is not self.y or st.f is not self.f or st.y_old is not self.y_old \
                or st.f_old is not self.f_old:  # reassigned from outside: step those
            st = self._state = st._replace(y=self.y, f=self.f, y_old=self.y_old, f_old=self.f_old)
        st.ts[:] = self.t, self.t_old, self.h_next
        st.counts[:] = c.steps, c.rejected, c.nfev
        steps0, wall0 = c.steps, time.perf_counter()
        sd, extras = self._kernel
        until = self.t_end if t_stop is None else float(t_stop)
        try:
            if self._pinned is not None:
                scheme, ctl = self._scheme, self._ctl
                status = self._pinned.call((sd, extras, scheme, ctl, st), sd, extras, scheme,
                                           ctl, st, until, self.max_steps)
            else:
                status = self._steps(sd, extras, self._scheme, self._ctl, st, until,
                                     self.max_steps)
        finally:
            self.t, self.t_old, self.h_next = (float(x) for x in st.ts)
            c.steps, c.rejected, c.nfev = (int(x) for x in st.counts)
            self._dense_K = None
        taken, wall = c.steps - steps0, time.perf_counter() - wall0
        if taken and self.compiled:
            self.max_steps = max(1, min(MAX_CHUNK_STEPS, int(CHUNK_S * taken / max(wall,
                                                                                  1e-9))))
        if status == self._run.ERR_NONFINITE:
            raise IntegrationError(f"non-finite error estimate at t = {self.t:.6g}: the state "
                                   "or qdd is not finite")
        if status == self._run.ERR_HMIN:
            hmin = float(self._run.hmin_at(self._ctl, self.t))
            raise IntegrationError(f"step size fell below hmin = {hmin:.3g} at t = "
                                   f"{self.t:.6g}: tolerances cannot be met")
        if status == self._run.ERR_QDD:  # the system's checked path says why (StateError)
            self.system.derivative(self.t, self.y, np.empty(self.n))
            raise IntegrationError(f"qdd not finite in a stage of the step from t = "
                                   f"{self.t:.6g}")
        if status == self._run.ERR_PROJECT:  # likewise
            self.system.project(self.y)
            raise IntegrationError(f"the projection onto the loops failed after the step to t "
                                   f"= {self.t:.6g}")

    # ----------------------------------------------------------------------- dense output
    def dense(self, ts) -> np.ndarray:
        """y at times ``ts`` (m,) inside the last step [t_old, t] -> (m, n)."""
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        h = self.t - self.t_old
        s = (ts - self.t_old) / h
        combine = _rk().combine
        if self.tab.A is DP45.A:  # ode45, rk45: y_old + h sum_j (BI_j . [s, .., s^4]) K_j
            out = np.empty((s.size, self.n))
            for i, si in enumerate(s.tolist()):
                w = [((b[0] * si + b[1] * si ** 2) + b[2] * si ** 3) + b[3] * si ** 4
                     for b in _NTRP45_ROWS]
                combine(self.y_old, h, np.array(w), self.K, len(w), out[i])
            return out
        if self.tab.name == "dop853":
            return self._dense_dop853(h, s)
        # rk4: its steps land on the sample times; in between, cubic Hermite
        return _hermite(self.y_old, self.f_old, self.y, self.f, h, s)

    def _dense_dop853(self, h, s):
        if self._dense_K is None:
            combine = _rk().combine
            d = _dop853()[1]
            Kx = np.empty((d["C_extra"].size + self.K.shape[0], self.n))
            Kx[:self.K.shape[0]] = self.K
            for i, (a, c) in enumerate(zip(d["A_extra"], d["C_extra"], strict=True)):
                j = self.K.shape[0] + i
                Kx[j] = self._call(self.t_old + c * h,
                                   combine(self.y_old, h, a, Kx, j, np.empty(self.n)))
            dy = self.y - self.y_old
            F = np.empty((7, self.n))
            F[0] = dy
            F[1] = h * Kx[0] - dy
            F[2] = 2 * dy - h * (self.f + Kx[0])
            for r, weights in enumerate(d["D"]):
                combine(_NO_WEIGHTS, h, weights, Kx, Kx.shape[0], F[3 + r])
            self._dense_K = F
        F = self._dense_K
        x = s[:, None]
        y = np.zeros((s.size, self.n))
        for i, fi in enumerate(F[::-1]):
            y += fi
            y *= x if i % 2 == 0 else (1 - x)
        return y + self.y_old


_NO_WEIGHTS = np.empty(0)
_NTRP45_ROWS = NTRP45_BI.tolist()


def _python_derivative(system, _extras, t, y, out) -> bool:
    system.derivative(t, y, out)  # (raises, saying why, where it cannot)
    return True


def _python_project(system, _extras, y) -> int:
    system.project(y)
    return 0


@functools.cache
def _python_steps():
    """The stepping's Python form (:func:`redysim.algorithms._kernels.rk_run.python_stepping`)
    on a system's Python methods."""
    return _rk_run().python_stepping(_python_derivative, _python_project)


def _rk_run():
    from redysim.algorithms._kernels import rk_run
    return rk_run


# --------------------------------------------------------------------------- SciPy solvers
class ScipySolver(OdeSolver):
    """A SciPy ``solve_ivp`` solver with the same interface as :class:`Solver`.

    Rejected steps: SciPy does not report them; for the explicit Runge-Kutta pairs they follow
    from the RHS count (each attempt costs a fixed number of calls); for LSODA and Radau they
    are -1 (not known).
    """

    def __init__(self, rhs, t0, y0, t_end, method, *, rtol=1e-4, atol=1e-6, hmax=None):
        from scipy.integrate import DOP853 as SDOP853
        from scipy.integrate import LSODA, RK45, Radau

        classes = {"RK45": RK45, "DOP853": SDOP853, "LSODA": LSODA, "Radau": Radau}
        if method not in classes:
            raise ValueError(f"method = scipy-{method!r}: unknown; choose one of "
                             f"{', '.join('scipy-' + m for m in classes)}")
        self.method = method
        self.counters = Counters()
        self.t_end = float(t_end)
        self.rtol, self.atol = rtol, atol
        self._rhs = rhs

        def f(t, y):
            self.counters.nfev += 1
            return np.asarray(rhs(t, y), dtype=float)

        kw = {"max_step": hmax} if hmax else {}
        self._s = classes[method](f, t0, np.array(y0, dtype=float), t_end, rtol=rtol,
                                  atol=atol, **kw)
        self._nfev0 = self.counters.nfev  # RHS calls before the first step (f0, first-step guess)
        self.t, self.y = self._s.t, self._s.y
        self.t_old, self._dense = self.t, None

    @property
    def done(self) -> bool:
        return self._s.status != "running"

    def step(self, t_stop=None):
        msg = self._s.step()
        if self._s.status == "failed":
            raise IntegrationError(f"scipy-{self.method} failed at t = {self._s.t:.6g}: {msg}")
        if not np.isfinite(self._s.y).all():
            raise IntegrationError(f"scipy-{self.method}: non-finite state at t = {self._s.t:.6g}")
        self.counters.steps += 1
        self.t_old, self.t, self.y = self._s.t_old, self._s.t, self._s.y
        self._dense = None
        if self.method in ("RK45", "DOP853"):
            per_attempt = self._s.n_stages
            attempts = (self.counters.nfev - self._nfev0) // per_attempt
            self.counters.rejected = attempts - self.counters.steps
        else:
            self.counters.rejected = -1  # not reported by SciPy

    def dense(self, ts):
        if self._dense is None:
            n0 = self.counters.nfev
            self._dense = self._s.dense_output()
            self._dense_calls = self.counters.nfev - n0
            self._nfev0 += self._dense_calls  # dense-output calls are not step attempts
        return np.atleast_2d(self._dense(np.atleast_1d(ts)).T)


# --------------------------------------------------------------------------- the driver
@dataclass
class Solution:
    """Samples (``t`` (m,), ``y`` (m, n)) and the counts; ``status`` 0 done, 1 stopped by the
    callback, -1 failed (``message`` says why)."""

    t: np.ndarray
    y: np.ndarray
    steps: int
    rejected: int
    nfev: int
    status: int
    message: str
    cpu_s: float
    wall_s: float


def make_solver(system, t0, y0, t_end, method="ode45", *, rtol=1e-4, atol=1e-6, h=None,
                hmax=None, preconditioner=None, state: SolverState | None = None,
                compiled: bool | None = None):
    """A :class:`Solver` (ours), a :class:`redysim.integrators.implicit.MidpointSolver`
    (``"midpoint"``, ``"midpoint-fixed"``: y = (q, v) with dq/dt = v, ``preconditioner`` its
    :class:`~redysim.integrators.implicit.TensionPreconditioner` or None) or a :class:`ScipySolver`
    (``"scipy-..."``) by name, stepping ``system`` (a function ``fun(t, y)`` or a system:
    :class:`~redysim.integrators.protocol.Dynamics`); ``state``: resume ours from a checkpoint
    (SciPy's cannot); ``compiled``: as :class:`Solver`'s."""
    method = canonical(method)
    if method in IMPLICIT:
        from redysim.integrators.implicit import MidpointSolver

        if method == "midpoint-fixed" and h is None:
            raise ValueError("midpoint-fixed needs a step h > 0")
        return MidpointSolver(as_function(system), t0, y0, t_end, rtol=rtol, atol=atol, h=h,
                              hmax=hmax, preconditioner=preconditioner, state=state)
    if method.startswith("scipy-"):
        if state is not None:
            raise ValueError(f"{method}'s state cannot be resumed: SciPy's solvers keep it")
        return ScipySolver(as_function(system), t0, y0, t_end, method[len("scipy-"):],
                           rtol=rtol, atol=atol, hmax=hmax)
    return Solver(system, t0, y0, t_end, method, rtol=rtol, atol=atol, h=h, hmax=hmax,
                  state=state, compiled=compiled)


def sample_times(t0: float, t_end: float, interval: float) -> np.ndarray:
    """t0, t0 + interval, ..., t_end (t_end always included)."""
    if not interval > 0:
        raise ValueError(f"sample interval must be > 0, got {interval!r}")
    m = int(math.floor((t_end - t0) / interval * (1 + SAMPLE_EPS)))
    ts = t0 + interval * np.arange(m + 1)
    if t_end - ts[-1] > SAMPLE_EPS * max(1.0, t_end):
        ts = np.append(ts, t_end)
    else:
        ts[-1] = t_end
    return ts


def advance(solver, t_eval, on_sample=None, on_step=None) -> tuple[int, str]:
    """Step ``solver`` to the last of ``t_eval``, calling ``on_sample(t, y)`` at each sample time
    (in order; samples at or before the current time are emitted first, with the current state)
    and ``on_step(solver)`` after each accepted step and its samples. Either callback returning a
    non-empty string stops the run with that message. Returns (status, message) as in
    :class:`Solution`."""
    i = 0
    t_eval = np.asarray(t_eval, dtype=float)
    while i < t_eval.size and t_eval[i] <= solver.t * (1 + SAMPLE_EPS):
        if on_sample and (msg := on_sample(float(t_eval[i]), solver.y.copy())):
            return 1, msg
        i += 1
    try:
        while i < t_eval.size and not solver.done:
            solver.step(t_eval[i])  # (a fixed step lands on it; OdeSolver.step)
            j = i
            while j < t_eval.size and t_eval[j] <= solver.t * (1 + SAMPLE_EPS):
                j += 1
            # the step's samples, interpolated a few at a time: a long implicit step holds
            # ~50 samples, and at 200,000 states all at once were 80 MB an array
            chunk = max(1, DENSE_DOUBLES // max(1, np.size(solver.y)))
            for k in range(i, j, chunk):
                ts = t_eval[k:min(j, k + chunk)]
                ys = solver.dense(np.minimum(ts, solver.t))
                ys[ts >= solver.t] = solver.y  # the step's end: no interpolation
                for t, y in zip(ts, ys, strict=True):
                    if on_sample and (msg := on_sample(float(t), y)):
                        return 1, msg
            i = j
            # after the step's samples: a checkpoint taken here holds every sample up to t
            if on_step and (msg := on_step(solver)):
                return 1, msg
    except IntegrationError as exc:
        return -1, str(exc)
    return 0, "ok"


@functools.cache  # once a process: after that a run would pay its set-up for nothing
def compile_kernels() -> None:
    """Compile (or load from numba's disk cache) the stage-sum kernels every scheme calls, by a
    few ode45 steps on a 2-state problem (with samples: its dense output too): so that a timed
    integration does not include it. Every scheme calls the two kernels with the same argument
    types (``tests/test_integrate.py`` checks that DOP853 and RK4 compile nothing more), and
    DOP853's tableau would import SciPy's integrate package, slow enough to show in a timed run
    (docs/notes/2026-11-costs-in-the-code.md). And the compiled stepping, by two steps of a
    one-link chain: its types are every plain chain's."""
    integrate(lambda _t, y: -y, (0.0, 2e-3), [1.0, 0.5], "ode45", t_eval=[0.0, 1e-3, 2e-3])
    from redysim.algorithms.system import System
    from redysim.model.tree import Chain

    system = System(Chain.uniform(1, "U", mass=1.0))
    solver = Solver(system, 0.0, np.full(system.size, 0.1), 1e-3, "ode45", max_steps=2)
    solver.step(1e-3)


def _check_rhs(rhs, t0: float, y0) -> None:
    """Refuse, naming it, a y0 that is not a finite numeric vector, or an ``rhs`` that is not
    callable or whose dy/dt at (t0, y0) is not of y0's shape: each would fail deep inside a
    step ("operands could not be broadcast")."""
    y = door.numeric("y0", y0)
    if y.ndim != 1:
        raise StateError(f"integrate: y0 has shape {y.shape}; it must be a vector (1-D)")
    if not y.size:
        raise StateError("integrate: y0 is empty: there is no state to integrate (give y0 as "
                         "a vector of at least one number)")
    door.require_finite("y0", y.astype(float))
    if not callable(rhs):
        raise TypeError(f"integrate: rhs = {type(rhs).__name__}: must be a function "
                        "rhs(t, y) -> dy/dt")
    dy = np.asarray(rhs(t0, y.astype(float)))
    if dy.shape != y.shape:
        raise StateError(f"integrate: rhs(t0, y0) has shape {dy.shape}; y0 has shape "
                         f"{y.shape}: rhs(t, y) must return dy/dt of y's shape")
    if dy.dtype.kind not in "biuf":  # complex would be cast to its real part, with a warning
        raise StateError(f"integrate: rhs(t0, y0) returns {dy.dtype} values; integrate takes "
                         "real dy/dt (a complex ODE: integrate its real and imaginary parts "
                         "as one real vector of twice the length)")


def integrate(rhs: Callable, t_span: tuple[float, float], y0, method: str = "ode45", *,
              rtol: float = 1e-4, atol: float = 1e-6, h: float | None = None,
              hmax: float | None = None, t_eval=None, callback=None) -> Solution:
    """Integrate ``dy/dt = rhs(t, y)`` over ``t_span`` = (t0, t_end), t_end > t0; samples at
    ``t_eval`` (default: every accepted step's end). ``callback(t, y)`` at each sample may
    return a message to stop.

    ``method``: one of :data:`INTEGRATORS` (or :data:`ALIASES`); ``midpoint`` needs y = (q, v)
    with dq/dt = v. ``h``: the step of a fixed-step method (given to an adaptive scheme it
    steps that scheme at a fixed step, for convergence studies).
    ``t_eval``: strictly increasing times within ``t_span``, as SciPy's ``solve_ivp`` requires;
    anything else is refused (unsorted times gave wrong values, a time before t0 the initial
    state, and times past t_end were dropped). ``hmax``: an adaptive step's largest (default
    0.1 x the span), a finite number > 0.
    Raises :class:`~redysim.errors.SettingsError` for a setting (method, t_span, rtol, atol, h,
    hmax, t_eval) and :class:`~redysim.errors.StateError` for a y0 (empty, not finite, odd for
    the midpoint methods) or an rhs answer (another shape, complex) it cannot take: both are
    ValueErrors.
    """
    def fail(field, value, problem) -> NoReturn:
        raise SettingsError("integrate", field, value, problem)

    if not isinstance(method, str) or canonical(method) not in INTEGRATORS:
        fail("method", method, f"unknown; choose one of {', '.join(INTEGRATORS)} (or "
             f"{', '.join(ALIASES)})")
    method = canonical(method)
    try:
        t0, t1 = map(float, t_span)
    except (TypeError, ValueError):
        fail("t_span", t_span, "must be two numbers (t0, t_end)")
    if not (math.isfinite(t0) and math.isfinite(t1) and t1 > t0):
        fail("t_span", t_span, "need finite t0 < t_end (forward in time)")
    adaptive = method not in FIXED_STEP and h is None
    check_settings("integrate", method=method, rtol=rtol if adaptive else None,
                   atol=atol if adaptive else None)
    for name, step in (("h", h), ("hmax", hmax)):  # (hmax = 0 was ignored, hmax < 0 blamed
        if step is None:                            # on the tolerances)
            continue
        if isinstance(step, bool) or not isinstance(step, int | float | np.integer
                                                    | np.floating):
            fail(name, step, "must be a number (a step in the units of t)")
        if not (math.isfinite(step) and step > 0):
            fail(name, step, "must be a finite step > 0" + (" (None: 0.1 x the span)"
                                                             if name == "hmax" else ""))
    if h is None and (method in FIXED_STEP or method == "midpoint-fixed"):
        fail("h", h, f"the fixed-step method {method!r} needs h > 0 (its step)")
    if h is not None and (t1 - t0) / h > MAX_FIXED_STEPS:  # (as simulate refuses it: a run
        # of 2e12 steps does not end; hold-out battery 6)
        fail("h", h, f"gives {(t1 - t0) / h:.3g} steps over t_span = ({t0:g}, {t1:g}); at "
             f"most {MAX_FIXED_STEPS:,}")
    if callback is not None and not callable(callback):
        fail("callback", callback, "must be a function callback(t, y), or None")
    if t_eval is not None:
        try:
            t_eval = np.asarray(t_eval, dtype=float)
        except (TypeError, ValueError):
            fail("t_eval", t_eval, "must be a vector of times")
        if t_eval.ndim != 1:
            fail("t_eval", t_eval, f"must be 1-dimensional, got shape {t_eval.shape}")
        if not np.isfinite(t_eval).all():
            fail("t_eval", t_eval, "must be finite")
        if t_eval.size and (t_eval.min() < t0 or t_eval.max() > t1):
            fail("t_eval", t_eval, f"Values in t_eval are not within t_span = ({t0:g}, "
                 f"{t1:g}): they run from {t_eval.min():g} to {t_eval.max():g}")
        if np.any(np.diff(t_eval) <= 0):
            fail("t_eval", t_eval, "Values in t_eval are not properly sorted (they must "
                 "increase strictly)")
    if not hasattr(rhs, "derivative"):  # a function: its answer's shape checked once, here
        _check_rhs(rhs, t0, y0)
    if method in IMPLICIT and np.size(y0) % 2:
        raise StateError(f"integrate: y0 has {np.size(y0)} entries; {method} steps y = (q, v), "
                         "two halves of equal length (dq/dt = v)")
    cpu0, wall0 = time.process_time(), time.perf_counter()
    solver = make_solver(rhs, t0, y0, t1, method, rtol=rtol, atol=atol, h=h, hmax=hmax)
    ts, ys = [], []

    def keep(t, y):
        ts.append(t)
        ys.append(y)
        return callback(t, y) if callback else None

    if t_eval is None:
        keep(solver.t, solver.y.copy())

        def every_step(s):
            return keep(s.t, s.y.copy())

        status, msg = advance(solver, [t1], on_step=every_step)
    else:
        status, msg = advance(solver, t_eval, on_sample=keep)
    c = solver.counters
    Y = np.array(ys) if ys else np.empty((0, np.size(y0)))
    return Solution(np.array(ts), Y, c.steps, c.rejected,
                    c.nfev, status, msg, time.process_time() - cpu0,
                    time.perf_counter() - wall0)
