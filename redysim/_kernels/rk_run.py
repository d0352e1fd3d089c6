"""Runge-Kutta stepping in compiled code: many steps per call, the dynamics called directly.

:func:`rk_steps` is :class:`redysim.integrate.Solver`'s stepping (``_stages``, ``_error``,
``_adaptive_step``, ``_fixed_step``, ``_accept``) written once more, operation for operation, for
the motion of a chain or a tree without a free joint: dy/dt = (qd, qdd(q, qd)) with qdd from the
forward-dynamics entry (:mod:`.entry`) on a workspace's packed arrays. The stage sums and the
error norm are the same compiled functions (:mod:`.rk`), the controller the same arithmetic in
the same order, so a run takes the same steps as the Python loop and ends in the same bits
(``tests/test_integrate.py`` compares them on the paper's cases). Python is left once per sample
interval (or every ``max_steps`` steps) instead of at every right-hand side: a 250-DOF ode45 step
then costs its seven qdd calls and nothing more.

State arrays (all the caller's; changed in place): ``ts`` = [t, t_old, h_next], ``y``, ``f``,
``y_old``, ``f_old`` (n,), ``K`` (s + 1, n), ``counts`` = [steps, rejected, nfev]. Controller
constants in ``ctl`` (floats): [rtol, atol, hmax, power, t_end, adaptive (1/0)] and the module
constants of :mod:`redysim.integrate` passed in ``consts``: [SAFETY, MAX_GROWTH,
FIRST_REJECT_MIN, LATER_REJECT, HMIN_EPS, FINISH_SLACK, SAMPLE_EPS].

Returns 0 (stopped: the step reached ``t_stop``, t_end or ``max_steps``), ERR_NONFINITE (an error
estimate not finite: the state or qdd is), ERR_HMIN (the step fell below hmin), or ERR_QDD (qdd
not finite: the caller asks the checked ``forward_dynamics`` why).
"""

from __future__ import annotations

import math

import numpy as np

from .._jit import jit_borrowed
from .batch import planar_call as _planar
from .batch import rge_a_call as _rge_a
from .rk import combine, error_norm

ERR_NONFINITE, ERR_HMIN, ERR_QDD = -1, -2, -3
RGE_A, PLANAR = 0, 1  # which entry computes qdd



@jit_borrowed
def _copy(src, dst):
    """dst[:] = src, element by element (a slice assignment would ask numba's allocator, which
    these kernels compile without)."""
    for k in range(dst.shape[0]):
        dst[k] = src[k]


@jit_borrowed
def _rhs(kind, fdata, idata, scratch, zeros, y, out):
    """out = (qd, qdd(q, qd)) for y = (q, qd); False when qdd is not finite."""
    n = y.shape[0] // 2
    for k in range(n):
        out[k] = y[n + k]
    if kind == RGE_A:
        flag = _rge_a(fdata, idata, y[:n], y[n:], zeros, scratch, out[n:])
    else:
        flag = _planar(fdata, idata, y[:n], y[n:], zeros, scratch, out[n:])
    return flag == 0.0


@jit_borrowed
def _stages(kind, fdata, idata, scratch, zeros, A, b, c, fsal, t, y, f, h, K, tmp, y_new,
            counts):
    """K[0..s-1] (and K[s] = f(t + h, y_new) when ``fsal``) and y_new, as Solver._stages; False
    when a qdd is not finite."""
    s = b.shape[0]
    _copy(f, K[0])
    for i in range(1, s):
        combine(y, h, A[i], K, i, tmp)
        counts[2] += 1
        if not _rhs(kind, fdata, idata, scratch, zeros, tmp, K[i]):
            return False
    combine(y, h, b, K, s, y_new)
    if fsal:
        counts[2] += 1
        if not _rhs(kind, fdata, idata, scratch, zeros, y_new, K[s]):
            return False
    return True


@jit_borrowed
def rk_steps(kind, fdata, idata, scratch, zeros, A, b, c, E, E3, fsal, ctl, consts,
             ts, y, f, y_old, f_old, K, counts, tmp, y_new, err, err3, t_stop, max_steps):
    """Steps until one ends at or past ``t_stop`` (module docstring)."""
    rtol, atol, hmax, power, t_end = ctl[0], ctl[1], ctl[2], ctl[3], ctl[4]
    adaptive = ctl[5] != 0.0
    SAFETY, MAX_GROWTH, FIRST_REJECT_MIN, LATER_REJECT = consts[0], consts[1], consts[2], \
        consts[3]
    HMIN_EPS, FINISH_SLACK, SAMPLE_EPS = consts[4], consts[5], consts[6]
    s = b.shape[0]
    threshold = atol / rtol
    taken = 0
    t_stop = min(t_stop, t_end)
    while taken < max_steps and ts[0] < t_end:
        t = ts[0]
        if adaptive:
            hmin = HMIN_EPS * (np.nextafter(abs(t), np.inf) - abs(t))
            absh = min(hmax, max(hmin, ts[2]))
            done = False
            if FINISH_SLACK * absh >= t_end - t:
                absh, done = t_end - t, True
            nofailed = True
            while True:
                t_new = t_end if done else t + absh
                h = t_new - t
                if not _stages(kind, fdata, idata, scratch, zeros, A, b, c, fsal, t, y, f, h,
                               K, tmp, y_new, counts):
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
                    absh = max(hmin, absh * max(FIRST_REJECT_MIN, SAFETY * (rtol / e) ** power))
                else:
                    absh = max(hmin, LATER_REJECT * absh)
                done = False
            if nofailed:
                temp = (e / rtol) ** power / SAFETY
                absh = absh / temp if temp > 1.0 / MAX_GROWTH else MAX_GROWTH * absh
            ts[2] = absh
        else:
            h, t_new = ts[2], t + ts[2]
            if t_stop - t_new <= SAMPLE_EPS * max(1.0, abs(t_stop)):  # land on the sample time
                h, t_new = t_stop - t, t_stop
            if not _stages(kind, fdata, idata, scratch, zeros, A, b, c, fsal, t, y, f, h, K,
                           tmp, y_new, counts):
                return ERR_QDD
        # accept: (t_old, y_old, f_old) <- (t, y, f); (t, y, f) <- (t_new, y_new, f_new)
        _copy(y, y_old)
        _copy(f, f_old)
        _copy(y_new, y)
        if fsal:
            _copy(K[s], f)
        else:
            counts[2] += 1
            if not _rhs(kind, fdata, idata, scratch, zeros, y, f):
                return ERR_QDD
        ts[1] = t
        ts[0] = t_new
        counts[0] += 1
        taken += 1
        if t_stop <= t_new * (1.0 + SAMPLE_EPS):
            break
    return 0
