"""Runge-Kutta stepping in compiled code: many steps per call, the dynamics called directly.

:func:`rk_steps` is :class:`redysim.integrators.explicit.Solver`'s stepping (``_stages``,
``_error``, ``_adaptive_step``, ``_fixed_step``, ``_accept``) written once more, operation for
operation, for the motion of a chain or a tree, with free joints (their quaternions projected
after each accepted step, as the Python loop does) and joint damping: dy/dt = (dq/dt, qdd(q, v))
with qdd from the forward-dynamics entry (:mod:`.entry`) on a workspace's packed arrays. The
stage sums and the error norm are the same compiled functions (:mod:`.rk`), the controller the
same arithmetic in the same order, and a free joint's dq/dt and projection the same compiled
functions the Python loop calls, so a run takes the same steps as the Python loop and ends in the
same bits
(``tests/test_integrate.py`` compares them on the paper's cases). Python is left once per sample
interval (or every ``max_steps`` steps) instead of at every right-hand side: a 250-DOF ode45 step
then costs its seven qdd calls and nothing more.

The kernels take four named bundles (:class:`Motion`, :class:`Scheme`, :class:`Control`,
:class:`StepState`): what is integrated, the tableau, the controller's settings and constants,
and the solver's state arrays (all the caller's, changed in place); and :class:`Extras` (a
model's couplings, loops or tip force on a spatial chain) or None, for which numba prunes their
branches.

Returns 0 (stopped: the step reached ``t_stop``, t_end or ``max_steps``), ERR_NONFINITE (an error
estimate not finite: the state or qdd is), ERR_HMIN (the step fell below hmin), ERR_QDD (qdd
not finite, or the loops redundant: the caller asks the checked Python right-hand side why) or
ERR_PROJECT (the projection onto the loops failed: the caller asks the checked projection why).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from redysim._jit import jit_borrowed, jit_exact

from .batch import dh_call as _dh
from .batch import planar_call as _planar
from .batch import rge_a_call as _rge_a
from .constraints import Loops, loops_project, loops_qdd, solve_small
from .entry import bundles
from .kinematics import kinematics
from .planar import planar_tip_torques
from .rk import combine, error_norm

ERR_NONFINITE, ERR_HMIN, ERR_QDD, ERR_PROJECT = -1, -2, -3, -4
RGE_A, PLANAR, DH = 0, 1, 2  # which entry computes qdd


class Couplings(NamedTuple):
    """A coupled model's couplings (q_f = m q_l + offset, mimic joints), for qdd by
    Featherstone's method on its tree (:func:`couple_qdd`) and for the projection after a step
    (:func:`project_couplings`); every array empty for a model without couplings. ``fdata``,
    ``idata``, ``scratch``: the tree without gravity's packed arrays (its qdd at v = 0 and tau = x
    is M^-1 x); ``fq``, ``lq``, ``fv``, ``lv``: each coupling's follower's and leader's q and v
    slots; ``m``, ``off``: multiplier and offset; work arrays ``zeros`` and ``row`` (n_v,), ``X``
    (k, n_v) (M^-1 J^T's columns as rows), ``A`` (k, k); ``worst`` [max |q_f - (m q_l + off)|,
    max |v_f - m v_l|] met before a projection in compiled code."""

    fdata: np.ndarray
    idata: np.ndarray
    scratch: np.ndarray
    fq: np.ndarray
    lq: np.ndarray
    fv: np.ndarray
    lv: np.ndarray
    m: np.ndarray
    off: np.ndarray
    zeros: np.ndarray
    row: np.ndarray
    X: np.ndarray
    A: np.ndarray
    worst: np.ndarray


def no_couplings() -> Couplings:
    """The empty bundle (a model without couplings)."""
    f, i = np.zeros(0), np.zeros(0, dtype=np.int64)
    return Couplings(f, i, f.copy(), i, i, i, i, f, f, f, f, np.zeros((0, 0)), np.zeros((0, 0)),
                     np.zeros(2))


def couplings_of(model, free_ws) -> Couplings:
    """The bundle of a coupled ``model`` (:meth:`redysim.Model.with_couplings`); ``free_ws``: a
    Workspace of its tree without gravity (``model.free_tree``)."""
    fq, lq, fv, lv, m, off = (np.array(a) for a in model.coupling_index)  # writable copies
    k, n = fv.shape[0], model.n_v
    return Couplings(free_ws.kernel_f, free_ws.kernel_i, free_ws.scratch, fq, lq, fv, lv, m, off,
                     np.zeros(n), np.zeros(n), np.zeros((k, n)), np.zeros((k, k)), np.zeros(2))


class Motion(NamedTuple):
    """dy/dt = (dq/dt, qdd(q, v)), y = (q, v): ``kind`` the entry computing qdd (RGE_A, PLANAR or
    DH) on a workspace's packed arrays ``fdata``, ``idata``, ``scratch``; ``zeros`` (n_v,) its tau
    without damping. ``nq``: the length of q; ``damping``: a viscous torque -damping * v at every
    joint (0: none), built in ``tau`` (n_v,). A free joint (its q slot of x in ``free_q``, its v
    slot of the linear velocity in ``free_v``) moves as dq/dt = (v_world, q (x) [0; w] / 2), every
    other coordinate q[plain_q[i]] as v[plain_v[i]]; each accepted step's quaternions are divided
    by their norms before the next step (``worst`` [0]: the largest | |q| - 1 | met before), the
    last step's of a call left to the caller, who projects after the step's samples as the Python
    loop does. Without free joints nq = n_v and the plain arrays are empty: dq/dt = v. ``tip``:
    a constant world force (3,) at a chain's tip, empty for none, its torques and the damping's
    into ``tau`` by :func:`.planar.planar_tip_torques` on a planar chain, else (with
    :class:`Extras`) :func:`spatial_tip_torques` (``length``: the links' (nl,))."""

    kind: int
    fdata: np.ndarray
    idata: np.ndarray
    scratch: np.ndarray
    zeros: np.ndarray
    nq: int
    damping: float
    tau: np.ndarray
    plain_q: np.ndarray
    plain_v: np.ndarray
    free_q: np.ndarray
    free_v: np.ndarray
    worst: np.ndarray
    tip: np.ndarray
    length: np.ndarray


class Extras(NamedTuple):
    """What only some models have, given to the stepping as an argument of its own, None for the
    others: numba then prunes its branches before typing, so that a model without them compiles
    none of their kernels (a first simulation of a chain or a robot compiled its steps in 35 s
    of CPU instead of 58 s here). ``couplings``: a coupled model's (:class:`Couplings`; qdd by
    :func:`couple_qdd`, the followers projected onto their leaders after each accepted step as
    the quaternions are); ``loops``: a closed mechanism's (:class:`.constraints.Loops`; qdd by
    :func:`.constraints.loops_qdd` on its own arrays, (q, v) projected onto the loops after each
    accepted step, before the couplings and quaternions, as the Python loop does); ``base0``
    (3,) zeros, the base at rest for :func:`spatial_tip_torques`' position pass (a tip force on
    a chain that is not planar)."""

    couplings: Couplings
    loops: Loops
    base0: np.ndarray


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
def _rhs(motion, extras, y, out):
    """out = (dq/dt, qdd(q, v)) for y = (q, v); False when qdd is not finite. The same arithmetic
    in the same order as redysim.simulation's Python right-hand side (tau = -damping * v; qdd;
    then dq/dt). ``extras``: None, or the model's :class:`Extras`."""
    nq = motion.nq
    nv = y.shape[0] - nq
    tau = motion.zeros
    if motion.tip.shape[0] != 0:  # a tip force, and the damping with it
        tau = motion.tau
        if extras is not None and motion.kind != PLANAR:  # (without extras: a planar chain)
            spatial_tip_torques(motion.fdata, motion.idata, motion.scratch, motion.zeros,
                                extras.base0, motion.length, y[:nq], motion.tip,
                                -motion.damping, y[nq:], tau)
        else:
            planar_tip_torques(motion.length, y[:nq], motion.tip, -motion.damping, y[nq:], tau)
    elif motion.damping != 0.0:
        tau = motion.tau
        d = -motion.damping
        for k in range(nv):
            tau[k] = d * y[nq + k]
    if extras is not None and extras.loops.ckind.shape[0] != 0:
        flag = 0.0 if loops_qdd(extras.loops, y[:nq], y[nq:], tau, out[nq:]) == 0 else 1.0
    elif motion.kind == RGE_A:
        flag = _rge_a(motion.fdata, motion.idata, y[:nq], y[nq:], tau, motion.scratch,
                      out[nq:])
    elif motion.kind == PLANAR:
        flag = _planar(motion.fdata, motion.idata, y[:nq], y[nq:], tau, motion.scratch,
                       out[nq:])
    else:
        flag = _dh(motion.fdata, motion.idata, y[:nq], y[nq:], tau, motion.scratch, out[nq:])
    if extras is not None and extras.couplings.fv.shape[0] != 0 and flag == 0.0:
        flag = couple_qdd(extras.couplings, y[:nq], out[nq:])
    if motion.free_q.shape[0] == 0:
        for k in range(nq):
            out[k] = y[nq + k]
        return flag == 0.0
    configuration_rate(nq, motion.plain_q, motion.plain_v, motion.free_q, motion.free_v, y, out)
    return flag == 0.0


@jit_borrowed
def configuration_rate(nq, plain_q, plain_v, free_q, free_v, y, out):
    """dq/dt into out[:nq] for y = (q, v) with free joints (``free_q``: each one's q slot of x,
    ``free_v`` its v slot of the linear velocity): v_world and q (x) [0; w] / 2, every other
    coordinate q[plain_q[i]] moving as v[plain_v[i]]. The Python loop (redysim.simulation) calls
    this same function, so that both paths round alike (the compiled steps inline it; its
    multiply-adds may fuse, in both)."""
    for i in range(plain_q.shape[0]):
        out[plain_q[i]] = y[nq + plain_v[i]]
    for j in range(free_q.shape[0]):
        qs, vs = free_q[j], nq + free_v[j]
        for k in range(3):
            out[qs + k] = y[vs + k]
        qw, qx, qy, qz = y[qs + 3], y[qs + 4], y[qs + 5], y[qs + 6]
        wx, wy, wz = y[vs + 3], y[vs + 4], y[vs + 5]
        out[qs + 3] = 0.5 * (-qx * wx - qy * wy - qz * wz)
        out[qs + 4] = 0.5 * (qw * wx + qy * wz - qz * wy)
        out[qs + 5] = 0.5 * (qw * wy - qx * wz + qz * wx)
        out[qs + 6] = 0.5 * (qw * wz + qx * wy - qy * wx)


@jit_borrowed
def spatial_tip_torques(fdata, idata, scratch, zeros, base0, length, q, force, d, qd, out):
    """out = J_tip(q)^T F + d * qd (n_v,) for a chain of any joints: the joint forces of a
    constant world force ``force`` (3,) at its tip (the distal end of the last link, along its
    x; ``length``: the links' (nl,)), each DOF's moment arm from its joint's origin, as
    :func:`redysim.algorithms.loads.tip_force_torques`, from the position pass of the
    kinematics on a workspace's packed arrays (its scratch overwritten; ``zeros`` (n_v,) and
    ``base0`` (3,) zeros), with a viscous ``d * qd`` added (d = -damping; 0: none). The Python
    loop and the compiled steps both call this function, so that they round alike."""
    tree, s = bundles(fdata, idata, scratch)
    kinematics(tree, q, zeros, zeros, base0, s)  # (the energy's specialisation)
    oO, oR, oP, voff = s.oO, s.oR, s.oP, tree.joint_voff
    k = length.shape[0] - 1
    p0 = oO[k, 0] + length[k] * oR[k, 0, 0]
    p1 = oO[k, 1] + length[k] * oR[k, 1, 0]
    p2 = oO[k, 2] + length[k] * oR[k, 2, 0]
    f0, f1, f2 = force[0], force[1], force[2]
    for b in range(k + 1):
        a0, a1, a2 = p0 - oO[b, 0], p1 - oO[b, 1], p2 - oO[b, 2]
        c0, c1, c2 = a1 * f2 - a2 * f1, a2 * f0 - a0 * f2, a0 * f1 - a1 * f0  # arm x F
        for i in range(voff[b], voff[b + 1]):
            out[i] = (oP[i, 0] * c0 + oP[i, 1] * c1 + oP[i, 2] * c2) + (
                oP[i, 3] * f0 + oP[i, 4] * f1 + oP[i, 5] * f2)
            if d != 0.0:
                out[i] = out[i] + d * qd[i]


@jit_borrowed
def couple_qdd(cp, q, qdd):
    """The tree's qdd (in place) made the coupled motion's, by Featherstone's method: X = M^-1
    J^T (one forward-dynamics call of the tree without gravity at v = 0 per coupling, J's rows
    e_f - m e_l), (J X) lam = -J qdd by Gaussian elimination with partial pivoting, qdd + X lam,
    then each follower's qdd set to m times its leader's (J qdd = 0: a linear coupling has no
    Jdot v). Returns the entry's flag (0.0: finite). The Python loop's and the compiled steps'
    coupled qdd, so that both round alike."""
    k, n = cp.fv.shape[0], qdd.shape[0]
    fv, lv, m, X, A, row = cp.fv, cp.lv, cp.m, cp.X, cp.A, cp.row
    for j in range(k):
        for r in range(n):
            row[r] = 0.0
        row[fv[j]] = 1.0
        row[lv[j]] = -m[j]
        flag = _rge_a(cp.fdata, cp.idata, q, cp.zeros, row, cp.scratch, X[j])
        if flag != 0.0:
            return flag
    lam = row  # (reused: k <= n)
    for i in range(k):
        for j in range(k):
            A[i, j] = X[j, fv[i]] - m[i] * X[j, lv[i]]
        lam[i] = -(qdd[fv[i]] - m[i] * qdd[lv[i]])
    solve_small(A, lam, k)
    for j in range(k):
        x = lam[j]
        for r in range(n):
            qdd[r] = qdd[r] + X[j, r] * x
    bad = 0.0
    for i in range(k):
        qdd[fv[i]] = m[i] * qdd[lv[i]]
    for r in range(n):
        bad += qdd[r] * 0.0
    return bad


@jit_borrowed
def coupled_qdd(fdata, idata, scratch, cp, q, v, tau, qdd):
    """qdd of a coupled model: its tree's by the entry on its packed arrays, then
    :func:`couple_qdd` (the compiled steps' right-hand side does the same)."""
    flag = _rge_a(fdata, idata, q, v, tau, scratch, qdd)
    if flag == 0.0:
        flag = couple_qdd(cp, q, qdd)
    return flag


@jit_exact
def project_couplings(cp, nq, y, worst):
    """Each follower's coordinate and velocity in y = (q, v) set from its leader's (q_f = m q_l
    + offset, v_f = m v_l), in place, IEEE as written; the largest departures met before into
    worst[0] (q) and worst[1] (v). The Python loop's projection is this function too."""
    for i in range(cp.fq.shape[0]):
        want = cp.m[i] * y[cp.lq[i]] + cp.off[i]
        e = abs(y[cp.fq[i]] - want)
        if e > worst[0]:
            worst[0] = e
        y[cp.fq[i]] = want
        want = cp.m[i] * y[nq + cp.lv[i]]
        e = abs(y[nq + cp.fv[i]] - want)
        if e > worst[1]:
            worst[1] = e
        y[nq + cp.fv[i]] = want


@jit_borrowed
def project_quaternions(free_q, y, worst):
    """Each free joint's quaternion divided by its norm, in place; the largest | |q| - 1 | met
    into worst[0]. The Python loop's projection is this function too."""
    for j in range(free_q.shape[0]):
        i = free_q[j] + 3
        norm = math.sqrt(y[i] * y[i] + y[i + 1] * y[i + 1] + y[i + 2] * y[i + 2]
                         + y[i + 3] * y[i + 3])
        e = abs(norm - 1.0)
        if e > worst[0]:
            worst[0] = e
        for k in range(4):
            y[i + k] = y[i + k] / norm


@jit_borrowed
def _stages(motion, extras, scheme, y, f, h, K, tmp, y_new, counts):
    """K[0..s-1] (and K[s] = f(t + h, y_new) when ``fsal``) and y_new, as Solver._stages; False
    when a qdd is not finite."""
    A, b = scheme.A, scheme.b
    s = b.shape[0]
    _copy(f, K[0])
    for i in range(1, s):
        combine(y, h, A[i], K, i, tmp)
        counts[2] += 1
        if not _rhs(motion, extras, tmp, K[i]):
            return False
    combine(y, h, b, K, s, y_new)
    if scheme.fsal:
        counts[2] += 1
        if not _rhs(motion, extras, y_new, K[s]):
            return False
    return True


@jit_borrowed
def rk_steps(motion, extras, scheme, ctl, st, t_stop, max_steps):
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
        if taken > 0:  # the step before: its loops, couplings and quaternions (the last
            # step's are the caller's to project after its samples), in the Python loop's order
            if extras is not None:
                if extras.loops.ckind.shape[0] != 0 and loops_project(
                        extras.loops, y[:motion.nq], y[motion.nq:], extras.loops.worst) != 0:
                    return ERR_PROJECT
                project_couplings(extras.couplings, motion.nq, y, extras.couplings.worst)
            project_quaternions(motion.free_q, y, motion.worst)
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
                if not _stages(motion, extras, scheme, y, f, h, K, tmp, y_new, counts):
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
            if not _stages(motion, extras, scheme, y, f, h, K, tmp, y_new, counts):
                return ERR_QDD
        # accept: (t_old, y_old, f_old) <- (t, y, f); (t, y, f) <- (t_new, y_new, f_new)
        _copy(y, y_old)
        _copy(f, f_old)
        _copy(y_new, y)
        if scheme.fsal:
            _copy(K[s], f)
        else:
            counts[2] += 1
            if not _rhs(motion, extras, y, f):
                return ERR_QDD
        ts[1] = t
        ts[0] = t_new
        counts[0] += 1
        taken += 1
        if t_stop <= t_new * (1.0 + ctl.sample_eps):
            break
    return 0
