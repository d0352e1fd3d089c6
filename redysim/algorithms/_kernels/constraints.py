"""Closed loops in compiled code: the cut joints' equations, the loop-closed accelerations and
the projection onto the loops (:class:`redysim.algorithms.loops.ClosedLoops`'s method, written
for numba), and the small dense solves they and the couplings need.

One :class:`Loops` bundle holds a mechanism: its tree's packed arrays (with gravity: the tree's
qdd) and its tree's without gravity (the kinematics at qdd = 0 the cuts are read from, and
M^-1 x = its qdd at v = 0, tau = x), the cuts (kind, the two bodies, points and frames, the paths
from each body to the base) and the work arrays. :func:`loops_qdd` is Featherstone's method:

    qdd0 = the tree's qdd;  X = M^-1 J^T (a row a constraint equation);
    (J X^T) lam = -(J qdd0 + Jdot v);  qdd = qdd0 + X^T lam,

refusing (a status) when J M^-1 J^T's smallest and largest eigenvalues are more than SINGULAR
apart (redundant cuts or a change point: the Python side then names them), and keeping the least
ratio met. :func:`loops_project` moves (q, v) back onto the loops along the mass-weighted normal.
Both the Python loop (through ClosedLoops) and the compiled steps
(:mod:`.rk_run`) call these functions, so that the two paths round alike.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from redysim._jit import jit_borrowed

from .batch import dh_call as _dh
from .batch import planar_call as _planar
from .batch import rge_a_call as _rge_a
from .entry import bundles
from .kinematics import kinematics

POINT, PLANAR_CUT, REVOLUTE, WELD = 0, 1, 2, 3  # a cut's kind (its equations: 3, 2, 5, 6)
CUT_KINDS = {"point": POINT, "planar": PLANAR_CUT, "revolute": REVOLUTE, "weld": WELD}
RGE_A, PLANAR, DH = 0, 1, 2  # which entry computes the tree's qdd (as .rk_run's)
OK, SINGULAR_LOOPS, NOT_FINITE = 0, 1, 2  # statuses
JACOBI_SWEEPS = 60


class Loops(NamedTuple):
    """A closed mechanism (module docstring); every array empty for a model without loops.

    ``kind``: the tree's entry (RGE_A, PLANAR, DH); ``tf``, ``ti``, ``ts``: the tree's packed
    arrays; ``ff``, ``fi``, ``fs``: the tree without gravity's. Cuts (nc): ``ckind`` (POINT,
    PLANAR_CUT, REVOLUTE, WELD), ``body`` (nc, 2) (-1: the world), ``point`` (nc, 2, 3) and
    ``rot`` (nc, 2, 3, 3) in the bodies' frames, ``row0`` (nc + 1) each cut's first equation;
    the path of (cut c, side s) to the base: axes ``paxes`` and their bodies ``powner`` in
    [pstart[2c + s], pstart[2c + s + 1]). Work: ``zeros`` (n), ``base0`` (3), ``phi``,
    ``Jv``, ``Jdv``, ``lam`` (m), ``J``, ``X`` (m, n), ``A``, ``W`` (m, m), ``work`` (WORK).
    ``params``: [the projection's tolerance on |phi| (m), the least eigenvalue ratio that is
    regular, the projection's iterations]; ``nearest`` [0]: the least ratio met; ``worst``: the
    compiled steps' largest residuals (max |phi|, max |J v|) met before their projections."""

    kind: int
    tf: np.ndarray
    ti: np.ndarray
    ts: np.ndarray
    ff: np.ndarray
    fi: np.ndarray
    fs: np.ndarray
    ckind: np.ndarray
    body: np.ndarray
    point: np.ndarray
    rot: np.ndarray
    row0: np.ndarray
    pstart: np.ndarray
    paxes: np.ndarray
    powner: np.ndarray
    zeros: np.ndarray
    base0: np.ndarray
    phi: np.ndarray
    Jv: np.ndarray
    Jdv: np.ndarray
    lam: np.ndarray
    J: np.ndarray
    X: np.ndarray
    A: np.ndarray
    W: np.ndarray
    params: np.ndarray
    nearest: np.ndarray
    work: np.ndarray
    worst: np.ndarray


WORK = 51  # the work array's length: two points (9 each), two frames (15 each), a direction


def no_loops() -> Loops:
    """The empty bundle (a model without loops)."""
    f, i = np.zeros(0), np.zeros(0, dtype=np.int64)
    return Loops(RGE_A, f, i, f, f, i, f, i, np.zeros((0, 2), dtype=np.int64),
                 np.zeros((0, 2, 3)), np.zeros((0, 2, 3, 3)), np.zeros(1, dtype=np.int64),
                 np.zeros(1, dtype=np.int64), i, i, f, np.zeros(3), f, f, f, f,
                 np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0)), np.zeros((0, 0)),
                 np.zeros(3), np.full(1, np.inf), np.zeros(WORK), np.zeros(2))


@jit_borrowed
def solve_small(A, b, k):
    """A x = b for the leading k x k of A by Gaussian elimination with partial pivoting, in
    place (A is destroyed, b becomes x)."""
    for c in range(k):
        p = c
        for r in range(c + 1, k):
            if abs(A[r, c]) > abs(A[p, c]):
                p = r
        if p != c:
            for j in range(k):
                A[c, j], A[p, j] = A[p, j], A[c, j]
            b[c], b[p] = b[p], b[c]
        for r in range(c + 1, k):
            f = A[r, c] / A[c, c]
            for j in range(c + 1, k):
                A[r, j] = A[r, j] - f * A[c, j]
            b[r] = b[r] - f * b[c]
    for c in range(k - 1, -1, -1):
        x = b[c]
        for j in range(c + 1, k):
            x = x - A[c, j] * b[j]
        b[c] = x / A[c, c]


@jit_borrowed
def eigen_ratio(A, W, k):
    """The smallest over the largest |eigenvalue| of the symmetric k x k A (0 when A is zero;
    NaN when not finite), by cyclic Jacobi rotations on a copy in W: for J M^-1 J^T, its
    singular values' ratio."""
    for i in range(k):
        for j in range(k):
            W[i, j] = A[i, j]
    for _ in range(JACOBI_SWEEPS):
        off = 0.0
        diag = 0.0
        for i in range(k):
            diag += W[i, i] * W[i, i]
            for j in range(i + 1, k):
                off += W[i, j] * W[i, j]
        if not (off > 1e-32 * diag):  # (NaN: stop)
            break
        for p in range(k - 1):
            for r in range(p + 1, k):
                apr = W[p, r]
                if apr == 0.0:
                    continue
                theta = (W[r, r] - W[p, p]) / (2.0 * apr)
                t = math.copysign(1.0, theta) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for j in range(k):  # columns p, r
                    wp, wr = W[j, p], W[j, r]
                    W[j, p] = c * wp - s * wr
                    W[j, r] = s * wp + c * wr
                for j in range(k):  # rows p, r
                    wp, wr = W[p, j], W[r, j]
                    W[p, j] = c * wp - s * wr
                    W[r, j] = s * wp + c * wr
    lo, hi = math.inf, 0.0
    for i in range(k):
        e = abs(W[i, i])
        if not math.isfinite(e):
            return math.nan
        lo = min(lo, e)
        hi = max(hi, e)
    return lo / hi if hi > 0.0 else 0.0


@jit_borrowed
def _tree_qdd(lp, q, v, tau, out):
    """The tree's qdd by its entry (with gravity); 0.0 when finite."""
    if lp.kind == RGE_A:
        return _rge_a(lp.tf, lp.ti, q, v, tau, lp.ts, out)
    if lp.kind == PLANAR:
        return _planar(lp.tf, lp.ti, q, v, tau, lp.ts, out)
    return _dh(lp.tf, lp.ti, q, v, tau, lp.ts, out)


@jit_borrowed
def _unit_response(lp, q, tau, out):
    """M^-1 tau: the tree without gravity's qdd at v = 0; 0.0 when finite."""
    if lp.kind == RGE_A:
        return _rge_a(lp.ff, lp.fi, q, lp.zeros, tau, lp.fs, out)
    if lp.kind == PLANAR:
        return _planar(lp.ff, lp.fi, q, lp.zeros, tau, lp.fs, out)
    return _dh(lp.ff, lp.fi, q, lp.zeros, tau, lp.fs, out)


@jit_borrowed
def _point(s, body, p, out):
    """A body point's world position, velocity and acceleration (qdd = 0, no gravity) into
    out[0:3], out[3:6], out[6:9]: as ClosedLoops._point."""
    if body < 0:
        for i in range(3):
            out[i] = p[i]
            out[3 + i] = 0.0
            out[6 + i] = 0.0
        return
    R, t, td, O = s.oR[body], s.t[body], s.td[body], s.oO[body]
    r0 = R[0, 0] * p[0] + R[0, 1] * p[1] + R[0, 2] * p[2]
    r1 = R[1, 0] * p[0] + R[1, 1] * p[1] + R[1, 2] * p[2]
    r2 = R[2, 0] * p[0] + R[2, 1] * p[1] + R[2, 2] * p[2]
    w0, w1, w2 = t[0], t[1], t[2]
    # w x r, then w x (w x r)
    x0, x1, x2 = w1 * r2 - w2 * r1, w2 * r0 - w0 * r2, w0 * r1 - w1 * r0
    out[0], out[1], out[2] = O[0] + r0, O[1] + r1, O[2] + r2
    out[3], out[4], out[5] = t[3] + x0, t[4] + x1, t[5] + x2
    a0, a1, a2 = td[0], td[1], td[2]
    out[6] = td[3] + (a1 * r2 - a2 * r1) + (w1 * x2 - w2 * x1)
    out[7] = td[4] + (a2 * r0 - a0 * r2) + (w2 * x0 - w0 * x2)
    out[8] = td[5] + (a0 * r1 - a1 * r0) + (w0 * x1 - w1 * x0)


@jit_borrowed
def _frame(s, body, rot, out):
    """A frame fixed to a body: its world rotation (out[0:9], row major), angular velocity and
    acceleration (out[9:12], out[12:15]); the world's is fixed."""
    if body < 0:
        for i in range(3):
            for j in range(3):
                out[3 * i + j] = rot[i, j]
        for i in range(9, 15):
            out[i] = 0.0
        return
    R = s.oR[body]
    for i in range(3):
        for j in range(3):
            out[3 * i + j] = R[i, 0] * rot[0, j] + R[i, 1] * rot[1, j] + R[i, 2] * rot[2, j]
    for i in range(3):
        out[9 + i] = s.t[body, i]
        out[12 + i] = s.td[body, i]


@jit_borrowed
def _jacobian_rows(lp, s, c, side, sign, x, r0, nrows):
    """Add sign x the velocity of world point x fixed to (cut c, side)'s body, along each axis of
    its path, to J's rows r0.. r0 + nrows (nrows <= 3: x, y, z)."""
    J, oP, oO = lp.J, s.oP, s.oO
    for e in range(lp.pstart[2 * c + side], lp.pstart[2 * c + side + 1]):
        ax, ow = lp.paxes[e], lp.powner[e]
        d0, d1, d2 = x[0] - oO[ow, 0], x[1] - oO[ow, 1], x[2] - oO[ow, 2]
        p0, p1, p2 = oP[ax, 0], oP[ax, 1], oP[ax, 2]
        col0 = oP[ax, 3] + (p1 * d2 - p2 * d1)
        col1 = oP[ax, 4] + (p2 * d0 - p0 * d2)
        col2 = oP[ax, 5] + (p0 * d1 - p1 * d0)
        J[r0, ax] += sign * col0
        if nrows > 1:
            J[r0 + 1, ax] += sign * col1
        if nrows > 2:
            J[r0 + 2, ax] += sign * col2


@jit_borrowed
def _angular_rows(lp, s, c, side, sign, u, r0):
    """Add sign x (u . the angular velocity of (cut c, side)'s body along each axis of its path)
    to J's row r0 (u: a world direction)."""
    J, oP = lp.J, s.oP
    for e in range(lp.pstart[2 * c + side], lp.pstart[2 * c + side + 1]):
        ax = lp.paxes[e]
        J[r0, ax] += sign * (u[0] * oP[ax, 0] + u[1] * oP[ax, 1] + u[2] * oP[ax, 2])


@jit_borrowed
def loops_evaluate(lp, q, v):
    """phi, J, J v and Jdot v of the cuts at (q, v) into lp's arrays (as ClosedLoops.evaluate):
    the kinematics at qdd = 0 without gravity, on the tree without gravity's scratch."""
    tree, s = bundles(lp.ff, lp.fi, lp.fs)
    kinematics(tree, q, v, lp.zeros, lp.base0, s)  # (the energy's specialisation)
    J = lp.J
    n = J.shape[1]
    for r in range(J.shape[0]):
        for j in range(n):
            J[r, j] = 0.0
    w = lp.work
    pa, pb, fa, fb, u = w[0:9], w[9:18], w[18:33], w[33:48], w[48:51]
    for c in range(lp.ckind.shape[0]):
        kind, r0 = lp.ckind[c], lp.row0[c]
        ba, bb = lp.body[c, 0], lp.body[c, 1]
        _point(s, ba, lp.point[c, 0], pa)
        _point(s, bb, lp.point[c, 1], pb)
        k = 2 if kind == PLANAR_CUT else 3
        for i in range(k):
            lp.phi[r0 + i] = pa[i] - pb[i]
            lp.Jv[r0 + i] = pa[3 + i] - pb[3 + i]
            lp.Jdv[r0 + i] = pa[6 + i] - pb[6 + i]
        _jacobian_rows(lp, s, c, 0, 1.0, pa, r0, k)
        if bb >= 0:
            _jacobian_rows(lp, s, c, 1, -1.0, pb, r0, k)
        if kind != REVOLUTE and kind != WELD:
            continue
        _frame(s, ba, lp.rot[c, 0], fa)
        _frame(s, bb, lp.rot[c, 1], fb)
        w0, w1, w2 = fa[9] - fb[9], fa[10] - fb[10], fa[11] - fb[11]
        al0, al1, al2 = fa[12] - fb[12], fa[13] - fb[13], fa[14] - fb[14]
        r = r0 + 3
        if kind == WELD:  # w_a - w_b = 0 along the world axes; phi = 1/2 sum_k b_k x a_k
            ph0 = ph1 = ph2 = 0.0
            for col in range(3):
                a0, a1, a2 = fa[col], fa[3 + col], fa[6 + col]
                b0, b1, b2 = fb[col], fb[3 + col], fb[6 + col]
                ph0 += b1 * a2 - b2 * a1
                ph1 += b2 * a0 - b0 * a2
                ph2 += b0 * a1 - b1 * a0
            lp.phi[r], lp.phi[r + 1], lp.phi[r + 2] = 0.5 * ph0, 0.5 * ph1, 0.5 * ph2
            lp.Jv[r], lp.Jv[r + 1], lp.Jv[r + 2] = w0, w1, w2
            lp.Jdv[r], lp.Jdv[r + 1], lp.Jdv[r + 2] = al0, al1, al2
            for i in range(3):
                u[0] = u[1] = u[2] = 0.0
                u[i] = 1.0
                _angular_rows(lp, s, c, 0, 1.0, u, r + i)
                if bb >= 0:
                    _angular_rows(lp, s, c, 1, -1.0, u, r + i)
            continue
        # revolute: along y_B and x_B (fixed on body b); phi = (z_A . x_B, -(z_A . y_B))
        zA0, zA1, zA2 = fa[2], fa[5], fa[8]
        wb0, wb1, wb2 = fb[9], fb[10], fb[11]
        lp.phi[r] = zA0 * fb[0] + zA1 * fb[3] + zA2 * fb[6]
        lp.phi[r + 1] = -(zA0 * fb[1] + zA1 * fb[4] + zA2 * fb[7])
        for i in range(2):
            col = 1 - i  # y_B, then x_B
            u[0], u[1], u[2] = fb[col], fb[3 + col], fb[6 + col]
            x0 = wb1 * u[2] - wb2 * u[1]
            x1 = wb2 * u[0] - wb0 * u[2]
            x2 = wb0 * u[1] - wb1 * u[0]
            lp.Jv[r + i] = u[0] * w0 + u[1] * w1 + u[2] * w2
            lp.Jdv[r + i] = (u[0] * al0 + u[1] * al1 + u[2] * al2) + (w0 * x0 + w1 * x1
                                                                         + w2 * x2)
            _angular_rows(lp, s, c, 0, 1.0, u, r + i)
            if bb >= 0:
                _angular_rows(lp, s, c, 1, -1.0, u, r + i)


@jit_borrowed
def _mobility(lp, q):
    """X's rows = M^-1 J's rows and A = J X^T (m x m); the status and the eigenvalue ratio."""
    J, X, A = lp.J, lp.X, lp.A
    m, n = J.shape[0], J.shape[1]
    for i in range(m):
        if _unit_response(lp, q, J[i], X[i]) != 0.0:
            return NOT_FINITE, math.nan
    for i in range(m):
        for j in range(m):
            x = 0.0
            for r in range(n):
                x += J[i, r] * X[j, r]
            A[i, j] = x
    ratio = eigen_ratio(A, lp.W, m)
    if ratio < lp.nearest[0]:
        lp.nearest[0] = ratio
    if not ratio > lp.params[1]:
        return SINGULAR_LOOPS, ratio
    return OK, ratio


@jit_borrowed
def loops_qdd(lp, q, v, tau, qdd):
    """qdd with the loops closed into ``qdd``, the loop forces into lp.lam (module docstring);
    returns OK, SINGULAR_LOOPS or NOT_FINITE."""
    if _tree_qdd(lp, q, v, tau, qdd) != 0.0:
        return NOT_FINITE
    loops_evaluate(lp, q, v)
    status, _ = _mobility(lp, q)
    if status != OK:
        return status
    J, X, lam = lp.J, lp.X, lp.lam
    m, n = J.shape[0], J.shape[1]
    for i in range(m):
        x = 0.0
        for r in range(n):
            x += J[i, r] * qdd[r]
        lam[i] = -(x + lp.Jdv[i])
    solve_small(lp.A, lam, m)
    bad = 0.0
    for r in range(n):
        x = qdd[r]
        for i in range(m):
            x += X[i, r] * lam[i]
        qdd[r] = x
        bad += x * 0.0
    return OK if bad == 0.0 else NOT_FINITE


@jit_borrowed
def loops_project(lp, q, v, worst):
    """(q, v) moved onto the loops in place (as ClosedLoops.project: Newton steps q <- q - X^T
    (J X^T)^-1 phi until |phi| <= the tolerance, then v <- v - X^T (J X^T)^-1 J v); the residuals
    found before (max |phi|, max |J v|) into worst[0], worst[1] where larger. Returns OK,
    SINGULAR_LOOPS or NOT_FINITE."""
    J, X, lam, phi = lp.J, lp.X, lp.lam, lp.phi
    m, n = J.shape[0], J.shape[1]
    loops_evaluate(lp, q, v)
    rq = rv = 0.0
    for i in range(m):
        rq = max(rq, abs(phi[i]))
        rv = max(rv, abs(lp.Jv[i]))
    worst[0] = max(worst[0], rq)
    worst[1] = max(worst[1], rv)
    for _ in range(int(lp.params[2])):
        big = 0.0
        for i in range(m):
            big = max(big, abs(phi[i]))
        if big <= lp.params[0]:
            break
        status, _ = _mobility(lp, q)
        if status != OK:
            return status
        for i in range(m):
            lam[i] = phi[i]
        solve_small(lp.A, lam, m)
        for r in range(n):
            x = 0.0
            for i in range(m):
                x += X[i, r] * lam[i]
            q[r] = q[r] - x
        loops_evaluate(lp, q, v)
    status, _ = _mobility(lp, q)
    if status != OK:
        return status
    for i in range(m):
        x = 0.0
        for r in range(n):
            x += J[i, r] * v[r]
        lam[i] = x
    solve_small(lp.A, lam, m)
    bad = 0.0
    for r in range(n):
        x = 0.0
        for i in range(m):
            x += X[i, r] * lam[i]
        v[r] = v[r] - x
        bad += (q[r] + v[r]) * 0.0
    return OK if bad == 0.0 else NOT_FINITE
