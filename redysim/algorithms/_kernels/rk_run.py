"""Explicit Runge-Kutta stepping and ode45's step-size control, written once for every stepper.

:func:`rk_steps` takes accepted steps of any explicit tableau until one reaches ``t_stop`` (or
``max_steps`` were taken), calling only a system's contract (:mod:`.system`): ``derivative(sd,
extras, t, y, out)`` at every stage and ``project_step(sd, extras, y)`` between steps. It runs
two ways, from one source:

- compiled, for a system whose physics is compiled (:class:`redysim.algorithms.system.System`):
  many steps per call without leaving machine code, the contract's compiled functions inlined;
- as Python (:func:`python_stepping`: the same function's source with the contract's names bound
  to a system's Python methods), for a system whose accelerations or forces come from Python (a
  reference engine, a user's force function, SciPy's solvers' right-hand sides) or when asked
  for the independent path (``compiled=False``): one accepted step per call, the stage sums and
  the error norm still the compiled ones (:mod:`.rk`).

Both take the same steps in the same bits when the system's derivative is compiled: the
controller, the stage sums and the derivative are the same functions.

The kernels take named bundles: the system's (:class:`.system.SystemData`, and
:class:`.system.Extras` or None), the tableau (:class:`Scheme`), the controller's settings and
constants (:class:`Control`) and the solver's state arrays (:class:`StepState`, changed in
place).

Returns 0 (stopped: the step reached ``t_stop``, t_end or ``max_steps``), ERR_NONFINITE (an error
estimate not finite: the state or the derivative is), ERR_HMIN (the step fell below hmin),
ERR_QDD (the derivative refused: the caller asks the system's checked path why) or ERR_PROJECT
(the projection failed: likewise).

References: MATLAB's ode45 (Shampine and Reichelt, "The MATLAB ODE suite", 1997) for the
controller; docs/design.md, "Integrators".
"""

from __future__ import annotations

import math
import types
from typing import NamedTuple

import numpy as np

from redysim._jit import jit_borrowed

from .rk import combine, error_norm
from .system import derivative, project_step

ERR_NONFINITE, ERR_HMIN, ERR_QDD, ERR_PROJECT = -1, -2, -3, -4


class Scheme(NamedTuple):
    """A Runge-Kutta tableau (:class:`redysim.integrators.explicit.Tableau`): A (s, s), b, c (s,),
    the error weights E (and DOP853's E3; empty when unused), whether the last stage is the
    next step's first (FSAL), and the norm of an estimate without E3 (:mod:`.rk`'s NORM_MAX,
    ode45's, or NORM_RMS, rk45's)."""

    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    E: np.ndarray
    E3: np.ndarray
    fsal: bool
    norm: int


class Control(NamedTuple):
    """The step control's settings (rtol and atol 1 for a fixed step; ``power`` the error
    exponent), :mod:`redysim.integrators.protocol`'s constants, and ``checked``: how many of the
    state's leading components the error norm measures (all of them, but for a quadrature that
    rides along after them: a system's work W, stepped by the same stages, measured by none of
    the controller's decisions, so that recording it leaves the motion's steps and bits as
    they were; docs/design.md, "Integrators")."""

    rtol: float
    atol: float
    hmax: float
    power: float
    t_end: float
    adaptive: bool
    safety: float
    max_growth: float
    first_reject_min: float
    later_reject: float
    hmin_eps: float
    finish_slack: float
    sample_eps: float
    checked: int


class StepState(NamedTuple):
    """The solver's state: ``ts`` = [t, t_old, h_next], ``y``, ``f``, ``y_old``, ``f_old``
    (n,), the stages ``K`` (s + 1, n), ``counts`` = [steps, rejected, nfev], and work arrays
    ``tmp``, ``y_new``, ``err``, ``err3`` (n,)."""

    ts: np.ndarray
    y: np.ndarray
    f: np.ndarray
    y_old: np.ndarray
    f_old: np.ndarray
    K: np.ndarray
    counts: np.ndarray
    tmp: np.ndarray
    y_new: np.ndarray
    err: np.ndarray
    err3: np.ndarray


@jit_borrowed
def copy(src, dst):
    """dst[:] = src, element by element (a slice assignment would ask numba's allocator, which
    these kernels compile without)."""
    for k in range(dst.shape[0]):
        dst[k] = src[k]


@jit_borrowed
def hmin_at(ctl, t):
    """The smallest step at time t: ``hmin_eps`` units in the last place of t."""
    return ctl.hmin_eps * (np.nextafter(abs(t), np.inf) - abs(t))


@jit_borrowed
def grown(ctl, absh, e):
    """The next step after an accepted one that needed no retry: absh (rtol / e)^power times
    ``safety``, at most ``max_growth`` times absh."""
    temp = (e / ctl.rtol) ** ctl.power / ctl.safety
    return absh / temp if temp > 1.0 / ctl.max_growth else ctl.max_growth * absh


@jit_borrowed
def shrunk(ctl, absh, hmin, e, first):
    """The retry after a rejected step: the first rejection of a step shrinks it by
    ``safety`` (rtol / e)^power, by no more than ``first_reject_min``; later ones by
    ``later_reject``; never below hmin."""
    if first:
        return max(hmin, absh * max(ctl.first_reject_min, ctl.safety * (ctl.rtol / e)
                                    ** ctl.power))
    return max(hmin, ctl.later_reject * absh)


@jit_borrowed
def _stages(sd, extras, scheme, t, y, f, h, K, tmp, y_new, counts):
    """K[0..s-1] (and K[s] = f(t + h, y_new) when ``fsal``) and y_new; False when the derivative
    refused. The stage sums y + h sum_j a_ij K_j are taken in a fixed order without BLAS
    (:mod:`.rk`): a step is the same on every CPU."""
    A, b, c = scheme.A, scheme.b, scheme.c
    s = b.shape[0]
    copy(f, K[0])
    for i in range(1, s):
        combine(y, h, A[i], K, i, tmp)
        counts[2] += 1
        if not derivative(sd, extras, t + c[i] * h, tmp, K[i]):
            return False
    combine(y, h, b, K, s, y_new)
    if scheme.fsal:
        counts[2] += 1
        if not derivative(sd, extras, t + h, y_new, K[s]):
            return False
    return True


@jit_borrowed
def _attempt(sd, extras, scheme, ctl, st, t):
    """One adaptive step from t: stages and error estimate, retried with shrinking steps until
    the error is within rtol. Returns (status, t_new, e, nofailed) (status 0: accepted)."""
    y, f, K, counts = st.y, st.f, st.K, st.counts
    E, E3, t_end = scheme.E, scheme.E3, ctl.t_end
    hmin = hmin_at(ctl, t)
    absh = min(ctl.hmax, max(hmin, st.ts[2]))
    done = False
    if ctl.finish_slack * absh >= t_end - t:
        absh, done = t_end - t, True
    nofailed = True
    while True:
        t_new = t_end if done else t + absh
        h = t_new - t
        if not _stages(sd, extras, scheme, t, y, f, h, K, st.tmp, st.y_new, counts):
            return ERR_QDD, t_new, 0.0, nofailed
        m = ctl.checked  # (the state's leading components: not a quadrature after them)
        e = error_norm(h, E, E3, K, E.shape[0], y[:m], st.y_new[:m], ctl.rtol, ctl.atol,
                       st.err[:m], st.err3[:m], scheme.norm)
        if not math.isfinite(e):
            return ERR_NONFINITE, t_new, e, nofailed
        if e <= ctl.rtol:
            break
        counts[1] += 1
        if absh <= hmin:
            return ERR_HMIN, t_new, e, nofailed
        absh = shrunk(ctl, absh, hmin, e, nofailed)
        nofailed = False
        done = False
    st.ts[2] = grown(ctl, absh, e) if nofailed else absh
    return 0, t_new, e, nofailed


@jit_borrowed
def rk_steps(sd, extras, scheme, ctl, st, t_stop, max_steps):
    """Steps until one ends at or past ``t_stop`` (module docstring). Every step but the last
    of a call is projected (the last is the caller's, after its samples)."""
    ts, y, f, K, counts = st.ts, st.y, st.f, st.K, st.counts
    s = scheme.b.shape[0]
    taken = 0
    t_stop = min(t_stop, ctl.t_end)
    while taken < max_steps and ts[0] < ctl.t_end:
        if taken > 0 and project_step(sd, extras, y) != 0:
            return ERR_PROJECT
        t = ts[0]
        if ctl.adaptive:
            status, t_new, _, _ = _attempt(sd, extras, scheme, ctl, st, t)
            if status != 0:
                return status
        else:
            h, t_new = ts[2], t + ts[2]
            if t_stop - t_new <= ctl.sample_eps * max(1.0, abs(t_stop)):  # land on the sample
                h, t_new = t_stop - t, t_stop
            if not _stages(sd, extras, scheme, t, y, f, h, K, st.tmp, st.y_new, counts):
                return ERR_QDD
        # accept: (t_old, y_old, f_old) <- (t, y, f); (t, y, f) <- (t_new, y_new, f_new)
        copy(y, st.y_old)
        copy(f, st.f_old)
        copy(st.y_new, y)
        if scheme.fsal:
            copy(K[s], f)
        else:
            counts[2] += 1
            if not derivative(sd, extras, t_new, y, f):
                return ERR_QDD
        ts[1] = t
        ts[0] = t_new
        counts[0] += 1
        taken += 1
        if t_stop <= t_new * (1.0 + ctl.sample_eps):
            break
    return 0


def _numpy_copy(src, dst):
    dst[:] = src


def _py(dispatcher):
    """A kernel's Python source (itself under NUMBA_DISABLE_JIT)."""
    return getattr(dispatcher, "py_func", dispatcher)


def python_stepping(system_derivative, system_project):
    """:func:`rk_steps` as Python, its own source, with the system's contract bound to
    ``system_derivative(sd, extras, t, y, out) -> bool`` and ``system_project(sd, extras, y)
    -> int`` (Python callables: ``sd`` is then whatever the caller passes, a Python
    system); the stage sums and the error norm are the compiled ones (:mod:`.rk`), the
    controller's scalar formulas their own Python source (the same IEEE operations: a call of
    compiled code from Python costs more than they do), the copies numpy's. Returns the
    Python ``rk_steps``."""
    names = dict(globals(), derivative=system_derivative, project_step=system_project,
                 copy=_numpy_copy, hmin_at=_py(hmin_at), grown=_py(grown), shrunk=_py(shrunk))

    def rebind(dispatcher):
        fn = _py(dispatcher)
        return types.FunctionType(fn.__code__, names, fn.__name__, fn.__defaults__,
                                  fn.__closure__)

    for name in ("_stages", "_attempt", "rk_steps"):
        names[name] = rebind(globals()[name])
    return names["rk_steps"]
