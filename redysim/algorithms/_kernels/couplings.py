"""Coupled joints in RGE-A's recursion: the coupled motion from the tree's factors, in O(n).

A coupling (a mimic joint) holds q_f = m q_l + offset, so J qdd = 0 with J's row e_f - m e_l
(linear: no Jdot v). The coupled motion is qdd = M^-1 (tau - h + J^T lam) with lam such that
J qdd = 0. RGE-A factors M = U D U^T on its way (its backward pass leaves D in ``Ihat`` and U's
columns in ``Psihat``; :mod:`.rge_a`), and the backward pass applied to a right-hand side b alone
(no velocity, no gravity) is U^-1 b: phihat_j = b_j - P_j^T eta, eta <- eta + Psihat_j phihat_j,
eta moved to the parent's origin between bodies. For b = e_f - m e_l that wrench is zero off the
paths from the follower's and the leader's bodies to the root, so each column y_c = U^-1 J_c^T
is found on those paths only (the bodies of which, ancestors first, are the coupling's static
``path``). Then, after the tree's own qdd0 (the three passes):

    A = J M^-1 J^T = Y^T D^-1 Y      (k x k, summed over each column's path)
    A lam = -J qdd0                  (Gaussian elimination with partial pivoting, k x k)
    qdd = qdd0 + U^-T D^-1 (Y lam)   (RGE-A's own forward pass, from zero base acceleration and
                                      zero twist-rates, on phitil = D^-1 Y lam)

and each follower's qdd set to m times its leader's (the solve leaves rounding). One forward
pass and the short path sweeps more than the tree's call, where the method this replaces ran
one whole call of the tree per coupling (docs/design.md, "Coupled joints").

:func:`couple_step` is the one implementation, inlined where the tree's passes were just run on
the same bundles: :func:`coupled_qdd` (which the public entry :func:`coupled_entry`, batches
:func:`coupled_rows` and a run's compiled derivative :func:`.system.derivative` call) and the
evaluator's lean entries (:mod:`.lean`).

Layout. A coupled model's workspace (:class:`redysim.algorithms.workspace.Workspace`, a model
with couplings that is not planar) appends to its packed arrays, after the tree's (whose header
does not see them, so every other kernel reads the arrays as before):

- ints: ``k``, the floats' offset, the scratch's offset, the path bodies' count, the path DOFs'
  count, then ``fq``, ``lq``, ``fv``, ``lv`` (k each: each coupling's follower's and leader's q
  and v slots), ``boff`` (k + 1) and ``bodies`` (each coupling's path bodies, children before
  parents), ``doff`` (k + 1) and ``dofs`` (their DOFs, in the order the sweep meets them); the
  very last int is where this segment starts.
- floats: ``m`` (k), ``offset`` (k), the tolerance of a state's check (relative, as
  :data:`redysim.algorithms.dynamics.COUPLING_TOL`), 3 zeros (a base at rest).
- scratch: ``Y`` (k, n_v), ``Z`` = D^-1 Y (k, n_v) on the paths, ``A`` (k, k), ``lam`` (k),
  ``E`` (n_b, 6) the wrenches handed to the parents, ``delta`` (n_v); flat, row by row.
"""

from __future__ import annotations

import numpy as np
from numba import types

from redysim._jit import EntryPoint, inline, jit_borrowed

from .bundles import H_NB, H_NQ, H_NV
from .entry import F_BASE_ACCEL, F_ZEROS, SIZE_MISMATCH, bundles
from .kinematics import kinematics
from .rge_a import rge_a_backward, rge_a_forward

COUPLING_TOL = 1e-9  # |q_f - (m q_l + offset)| allowed, relative to 1 + |q_f| (and for v, qdd)
OFF_COUPLINGS = -2.0  # an entry's flag: q or v off the couplings (the checked path says which)
HEAD = 5  # ints before the arrays: k, float offset, scratch offset, path bodies, path DOFs


def coupling_tail(model, parent, joint_voff, serial: bool, tol: float, f_at: int, i_at: int,
                  s_at: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The ints, floats and scratch size a coupled ``model``'s workspace appends to its packed
    arrays (module docstring), the tree's being ``f_at`` floats, ``i_at`` ints and ``s_at``
    scratch long; ``parent``, ``joint_voff``: the tree's tables (``serial``: parent k - 1)."""
    fq, lq, fv, lv, m, off = (np.asarray(a) for a in model.coupling_index)
    k, n, nb = fv.shape[0], model.n_v, joint_voff.shape[0] - 1
    body_of = np.searchsorted(joint_voff, np.arange(n), side="right") - 1

    def up(b: int) -> list[int]:
        out = []
        while b >= 0:
            out.append(b)
            b = b - 1 if serial else int(parent[b])
        return out

    bodies: list[int] = []
    dofs: list[int] = []
    boff, doff = [0], [0]
    for c in range(k):
        path = sorted(set(up(int(body_of[fv[c]]))) | set(up(int(body_of[lv[c]]))), reverse=True)
        bodies.extend(path)
        for b in path:
            dofs.extend(range(int(joint_voff[b + 1]) - 1, int(joint_voff[b]) - 1, -1))
        boff.append(len(bodies))
        doff.append(len(dofs))
    ints = np.concatenate(([k, f_at, s_at, len(bodies), len(dofs)], fq, lq, fv, lv, boff, bodies,
                           doff, dofs, [i_at])).astype(np.int64)
    floats = np.concatenate((m, off, [tol, 0.0, 0.0, 0.0])).astype(np.float64)
    return ints, floats, 2 * k * n + k * k + k + 6 * nb + n


@inline
def _tail(fdata, idata, scratch):
    """The couplings' segments of a workspace's packed arrays, as flat views (module docstring;
    no reshape, whose strides numba gets from a C helper at a cost per call)."""
    c0 = idata[idata.shape[0] - 1]
    k, fo, so, nbp, ndp = idata[c0], idata[c0 + 1], idata[c0 + 2], idata[c0 + 3], idata[c0 + 4]
    nv, nb = idata[H_NV], idata[H_NB]
    i = c0 + HEAD
    fq, lq, fv, lv = (idata[i:i + k], idata[i + k:i + 2 * k], idata[i + 2 * k:i + 3 * k],
                      idata[i + 3 * k:i + 4 * k])
    i += 4 * k
    boff = idata[i:i + k + 1]
    bodies = idata[i + k + 1:i + k + 1 + nbp]
    i += k + 1 + nbp
    doff = idata[i:i + k + 1]
    dofs = idata[i + k + 1:i + k + 1 + ndp]
    m, off, tol, base0 = (fdata[fo:fo + k], fdata[fo + k:fo + 2 * k], fdata[fo + 2 * k],
                          fdata[fo + 2 * k + 1:fo + 2 * k + 4])
    Y = scratch[so:so + k * nv]  # (k, nv) row by row, as Z
    Z = scratch[so + k * nv:so + 2 * k * nv]
    so += 2 * k * nv
    A = scratch[so:so + k * k]  # (k, k)
    lam = scratch[so + k * k:so + k * k + k]
    so += k * k + k
    E = scratch[so:so + 6 * nb]  # (nb, 6)
    delta = scratch[so + 6 * nb:so + 6 * nb + nv]
    return (k, fq, lq, fv, lv, boff, bodies, doff, dofs, m, off, tol, base0, Y, Z, A, lam, E,
            delta)


@inline
def on_couplings(fdata, idata, scratch, q, v):
    """True when every follower's q is m q_l + offset and its v m v_l, to the workspace's
    relative tolerance (NaN passes: the passes then say it is not finite)."""
    (k, fq, lq, fv, lv, _, _, _, _, m, off, tol, _, _, _, _, _, _, _) = _tail(fdata, idata,
                                                                             scratch)
    for c in range(k):
        x = q[fq[c]]
        if abs(x - (m[c] * q[lq[c]] + off[c])) > tol * (1.0 + abs(x)):
            return False
        x = v[fv[c]]
        if abs(x - m[c] * v[lv[c]]) > tol * (1.0 + abs(x)):
            return False
    return True


@inline
def _solve(A, b, k):
    """A x = b for a k x k A (flat, row by row) by Gaussian elimination with partial pivoting,
    in place (as :func:`.constraints.solve_small`, on a flat A)."""
    for c in range(k):
        p = c
        for r in range(c + 1, k):
            if abs(A[r * k + c]) > abs(A[p * k + c]):
                p = r
        if p != c:
            for j in range(k):
                A[c * k + j], A[p * k + j] = A[p * k + j], A[c * k + j]
            b[c], b[p] = b[p], b[c]
        for r in range(c + 1, k):
            f = A[r * k + c] / A[c * k + c]
            for j in range(c + 1, k):
                A[r * k + j] = A[r * k + j] - f * A[c * k + j]
            b[r] = b[r] - f * b[c]
    for c in range(k - 1, -1, -1):
        x = b[c]
        for j in range(c + 1, k):
            x = x - A[c * k + j] * b[j]
        b[c] = x / A[c * k + c]


@inline
def couple_step(tree, s, fdata, idata, scratch, qdd):
    """The tree's qdd (in place), just computed by RGE-A's three passes on this workspace's
    bundles ``tree``, ``s`` (of its packed arrays), made the coupled motion's (module
    docstring). Returns 0.0, or NaN when some qdd is not finite (a singular J M^-1 J^T
    included). Inlined into each caller (:func:`coupled_qdd`, the lean entries), which hand it
    the bundles they made."""
    (k, fq, lq, fv, lv, boff, bodies, doff, dofs, m, off, tol, base0, Y, Z, A, lam, E,
     delta) = _tail(fdata, idata, scratch)
    serial = tree.serial != 0
    parent, voff, oO, oP, Ihat, Psihat = tree.parent, tree.joint_voff, s.oO, s.oP, s.Ihat, s.Psihat
    nv = qdd.shape[0]
    for j in range(k * nv):
        Y[j] = 0.0
    # each column y_c = U^-1 (e_f - m e_l) on its path, children before parents
    for c in range(k):
        f, ld, mc, row = fv[c], lv[c], m[c], c * nv
        for i in range(boff[c], boff[c + 1]):
            for r in range(6):
                E[6 * bodies[i] + r] = 0.0
        for i in range(boff[c], boff[c + 1]):
            b = bodies[i]
            e0, e1, e2 = E[6 * b], E[6 * b + 1], E[6 * b + 2]
            e3, e4, e5 = E[6 * b + 3], E[6 * b + 4], E[6 * b + 5]
            for j in range(voff[b + 1] - 1, voff[b] - 1, -1):
                rhs = 1.0 if j == f else 0.0
                if j == ld:
                    rhs = rhs - mc
                ph = rhs - (oP[j, 0] * e0 + oP[j, 1] * e1 + oP[j, 2] * e2
                            + oP[j, 3] * e3 + oP[j, 4] * e4 + oP[j, 5] * e5)
                Y[row + j] = ph
                Z[row + j] = ph / Ihat[j]
                e0 += Psihat[j, 0] * ph
                e1 += Psihat[j, 1] * ph
                e2 += Psihat[j, 2] * ph
                e3 += Psihat[j, 3] * ph
                e4 += Psihat[j, 4] * ph
                e5 += Psihat[j, 5] * ph
            p = b - 1 if serial else parent[b]
            if p >= 0:  # to the parent's origin, a = O_p - O_b: n <- n - a x f
                a0, a1, a2 = oO[p, 0] - oO[b, 0], oO[p, 1] - oO[b, 1], oO[p, 2] - oO[b, 2]
                E[6 * p] += e0 - (a1 * e5 - a2 * e4)
                E[6 * p + 1] += e1 - (a2 * e3 - a0 * e5)
                E[6 * p + 2] += e2 - (a0 * e4 - a1 * e3)
                E[6 * p + 3] += e3
                E[6 * p + 4] += e4
                E[6 * p + 5] += e5
    # A = Y^T D^-1 Y (column c's path holds every DOF where z_c is not zero), A lam = -J qdd0
    for c in range(k):
        for d in range(c, k):
            acc = 0.0
            for i in range(doff[c], doff[c + 1]):
                j = dofs[i]
                acc += Z[c * nv + j] * Y[d * nv + j]
            A[c * k + d] = acc
            A[d * k + c] = acc
        lam[c] = -(qdd[fv[c]] - m[c] * qdd[lv[c]])
    _solve(A, lam, k)
    # qdd += U^-T (D^-1 Y lam): RGE-A's forward pass on phitil = Z lam, zero base acceleration
    # and zero twist-rates (the passes' own c_k, no longer needed, are cleared)
    phitil, td = s.phitil, s.td
    for j in range(nv):
        phitil[j] = 0.0
    for c in range(k):
        x = lam[c]
        for i in range(doff[c], doff[c + 1]):
            j = dofs[i]
            phitil[j] += Z[c * nv + j] * x
    for b in range(td.shape[0]):
        for r in range(6):
            td[b, r] = 0.0
    bad = rge_a_forward(tree, s, base0, delta)
    for j in range(nv):
        qdd[j] = qdd[j] + delta[j]
    for c in range(k):
        qdd[fv[c]] = m[c] * qdd[lv[c]]
    for j in range(nv):
        bad += qdd[j] * 0.0
    return bad


@jit_borrowed
def coupled_qdd(fdata, idata, scratch, q, v, tau, qdd):
    """qdd of a coupled model on its workspace's packed arrays (no check of the lengths or that
    the state keeps the couplings): RGE-A's three passes as :func:`.entry.rge_a_entry` runs
    them, then :func:`couple_step` (what a coupled system's derivative, the public entry and
    batches run). Returns 0.0, or NaN when some qdd is not finite."""
    h = idata
    tree, s = bundles(fdata, idata, scratch)
    base_accel = fdata[h[F_BASE_ACCEL]:h[F_BASE_ACCEL] + 3]
    zeros = fdata[h[F_ZEROS]:h[F_ZEROS] + h[H_NV]]
    kinematics(tree, q, v, zeros, base_accel, s, True)
    rge_a_backward(tree, s, tau)
    bad = rge_a_forward(tree, s, base_accel, qdd)
    if bad != 0.0:
        return bad
    return couple_step(tree, s, fdata, idata, scratch, qdd)


def coupled_entry(fdata, idata, q, qd, tau, scratch, qdd):
    """A coupled model's qdd on its workspace's packed arrays: :func:`.entry.rge_a_entry`'s
    checks, the state's against the couplings, then :func:`coupled_qdd`. Returns 0.0, NaN (not
    finite), SIZE_MISMATCH or OFF_COUPLINGS (q or v off the couplings), having written nothing
    in the last two."""
    h = idata
    nv = h[H_NV]
    if q.shape[0] != h[H_NQ] or qd.shape[0] != nv or tau.shape[0] != nv or qdd.shape[0] != nv:
        return SIZE_MISMATCH
    if not on_couplings(fdata, idata, scratch, q, qd):
        return OFF_COUPLINGS
    return coupled_qdd(fdata, idata, scratch, q, qd, tau, qdd)


coupled_call = jit_borrowed(coupled_entry)


@jit_borrowed
def coupled_rows(fdata, idata, Q, QD, TAU, scratch, QDD, first, last):
    """QDD[i] = the coupled qdd(Q[i], QD[i], TAU[i] or TAU[0]), for first <= i < last (as
    :func:`.batch.forward_rows`): -1, or the first row off the couplings or not finite."""
    every = TAU.shape[0] > 1
    for i in range(first, last):
        if coupled_call(fdata, idata, Q[i], QD[i], TAU[i] if every else TAU[0], scratch,
                        QDD[i]) != 0.0:
            return i
    return -1


_F1 = types.Array(types.float64, 1, "C")
_I1 = types.Array(types.int64, 1, "C")
_RO = types.Array(types.float64, 1, "C", readonly=True)
COUPLED = EntryPoint(coupled_entry, types.float64(_F1, _I1, _RO, _RO, _RO, _F1, _F1),
                     ((coupled_qdd, (_F1, _I1, _F1, _RO, _RO, _RO, _F1)),))
