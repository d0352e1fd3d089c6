"""Runge-Kutta stepping in compiled code: many steps per call, the dynamics called directly.

:func:`rk_steps` is :class:`redysim.integrators.explicit.Solver`'s stepping (``_stages``,
``_error``, ``_adaptive_step``, ``_fixed_step``, ``_accept``) written once more, operation for
operation, for the motion of a chain or a tree without a free joint: dy/dt = (qd, qdd(q, qd)) with
qdd from the forward-dynamics entry (:mod:`.entry`) on a workspace's packed arrays. The stage sums
and the error norm are the same compiled functions (:mod:`.rk`), the controller the same arithmetic
in the same order, so a run takes the same steps as the Python loop and ends in the same bits
(``tests/test_integrate.py`` compares them on the paper's cases). Python is left once per sample
interval (or every ``max_steps`` steps) instead of at every right-hand side: a 250-DOF ode45 step
then costs its seven qdd calls and nothing more.

The kernels take four named bundles (:class:`Motion`, :class:`Scheme`, :class:`Control`,
:class:`StepState`): what is integrated, the tableau, the controller's settings and constants,
and the solver's state arrays (all the caller's, changed in place).

Returns 0 (stopped: the step reached ``t_stop``, t_end or ``max_steps``), ERR_NONFINITE (an error
estimate not finite: the state or qdd is), ERR_HMIN (the step fell below hmin), or ERR_QDD (qdd
not finite: the caller asks the checked ``forward_dynamics`` why).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from redysim._jit import jit_borrowed

from .batch import planar_call as _planar
from .batch import rge_a_call as _rge_a
from .rk import combine, error_norm

ERR_NONFINITE, ERR_HMIN, ERR_QDD = -1, -2, -3
RGE_A, PLANAR = 0, 1  # which entry computes qdd


class Motion(NamedTuple):
    """dy/dt = (qd, qdd(q, qd)): ``kind`` the entry computing qdd (RGE_A or PLANAR) on a
    workspace's packed arrays ``fdata``, ``idata``, ``scratch``; ``zeros`` (n_v,) its tau."""

    kind: int
    fdata: np.ndarray
    idata: np.ndarray
    scratch: np.ndarray
    zeros: np.ndarray


class Scheme(NamedTuple):
    """A Runge-Kutta tableau (:class:`redysim.integrators.explicit.Tableau`): A (s, s), b, c (s,),
    the error weights E (and DOP853's E3; empty when unused), and whether the last stage is the next
    step's first (FSAL)."""

    A: np.ndarray
    b: np.ndarray
    c: np.ndarray
    E: np.ndarray
    E3: np.ndarray
    fsal: bool


class Control(NamedTuple):
    """The step control's settings (rtol and atol 1 for a fixed step; ``power`` the error
    exponent) and :mod:`redysim.integrators.explicit`'s constants."""

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
def _copy(src, dst):
    """dst[:] = src, element by element (a slice assignment would ask numba's allocator, which
    these kernels compile without)."""
    for k in range(dst.shape[0]):
        dst[k] = src[k]


@jit_borrowed
def _rhs(motion, y, out):
    """out = (qd, qdd(q, qd)) for y = (q, qd); False when qdd is not finite."""
    n = y.shape[0] // 2
    for k in range(n):
        out[k] = y[n + k]
    if motion.kind == RGE_A:
        flag = _rge_a(motion.fdata, motion.idata, y[:n], y[n:], motion.zeros, motion.scratch,
                      out[n:])
    else:
        flag = _planar(motion.fdata, motion.idata, y[:n], y[n:], motion.zeros, motion.scratch,
                       out[n:])
    return flag == 0.0


@jit_borrowed
def _stages(motion, scheme, y, f, h, K, tmp, y_new, counts):
    """K[0..s-1] (and K[s] = f(t + h, y_new) when ``fsal``) and y_new, as Solver._stages; False
    when a qdd is not finite."""
    A, b = scheme.A, scheme.b
    s = b.shape[0]
    _copy(f, K[0])
    for i in range(1, s):
        combine(y, h, A[i], K, i, tmp)
        counts[2] += 1
        if not _rhs(motion, tmp, K[i]):
            return False
    combine(y, h, b, K, s, y_new)
    if scheme.fsal:
        counts[2] += 1
        if not _rhs(motion, y_new, K[s]):
            return False
    return True


@jit_borrowed
def rk_steps(motion, scheme, ctl, st, t_stop, max_steps):
    """Steps until one ends at or past ``t_stop`` (module docstring)."""
    rtol, atol, hmax, power, t_end, adaptive = ctl.rtol, ctl.atol, ctl.hmax, ctl.power, \
        ctl.t_end, ctl.adaptive
    ts, y, f, y_old, f_old, K, counts = st.ts, st.y, st.f, st.y_old, st.f_old, st.K, st.counts
    tmp, y_new, err, err3 = st.tmp, st.y_new, st.err, st.err3
    E, E3 = scheme.E, scheme.E3
    s = scheme.b.shape[0]
    threshold = atol / rtol
    taken = 0
    t_stop = min(t_stop, t_end)
    while taken < max_steps and ts[0] < t_end:
        t = ts[0]
        if adaptive:
            hmin = ctl.hmin_eps * (np.nextafter(abs(t), np.inf) - abs(t))
            absh = min(hmax, max(hmin, ts[2]))
            done = False
            if ctl.finish_slack * absh >= t_end - t:
                absh, done = t_end - t, True
            nofailed = True
            while True:
                t_new = t_end if done else t + absh
                h = t_new - t
                if not _stages(motion, scheme, y, f, h, K, tmp, y_new, counts):
                    return ERR_QDD
                e = error_norm(h, E, E3, K, E.shape[0], y, y_new, threshold, err, err3)
                if not math.isfinite(e):
                    return ERR_NONFINITE
                if e <= rtol:
                    break
                counts[1] += 1
                if absh <= hmin:
                    return ERR_HMIN
                if nofailed:
                    nofailed = False
                    absh = max(hmin, absh * max(ctl.first_reject_min,
                                                ctl.safety * (rtol / e) ** power))
                else:
                    absh = max(hmin, ctl.later_reject * absh)
                done = False
            if nofailed:
                temp = (e / rtol) ** power / ctl.safety
                absh = absh / temp if temp > 1.0 / ctl.max_growth else ctl.max_growth * absh
            ts[2] = absh
        else:
            h, t_new = ts[2], t + ts[2]
            if t_stop - t_new <= ctl.sample_eps * max(1.0, abs(t_stop)):  # land on the sample
                h, t_new = t_stop - t, t_stop
            if not _stages(motion, scheme, y, f, h, K, tmp, y_new, counts):
                return ERR_QDD
        # accept: (t_old, y_old, f_old) <- (t, y, f); (t, y, f) <- (t_new, y_new, f_new)
        _copy(y, y_old)
        _copy(f, f_old)
        _copy(y_new, y)
        if scheme.fsal:
            _copy(K[s], f)
        else:
            counts[2] += 1
            if not _rhs(motion, y, f):
                return ERR_QDD
        ts[1] = t
        ts[0] = t_new
        counts[0] += 1
        taken += 1
        if t_stop <= t_new * (1.0 + ctl.sample_eps):
            break
    return 0
