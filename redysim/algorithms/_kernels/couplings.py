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

The columns are swept side by side, body by body over the union of their paths (each column's
own steps in its own order: their chains of dependent steps overlap), and A over the DOFs two
paths share.

Local groups. Couplings whose follower and leader meet in a subtree whose root has a parent (a
gripper's) are closed at that root inside the backward pass (:func:`local_passes`): after the
root's joint is eliminated, the group's columns are swept on the subtree alone (W, k_g x 6: each
column's wrench out of the root), A_g = Y^T D^-1 Y there, and s = J qdd of the subtree from a zero
twist-rate at the root's joint (:func:`_local_forward`). A force J^T lam in the subtree adds W lam
to the wrench the root hands on and J qdd = s - W^T mu + A_g lam (mu: the twist-rate at the
root's joint), so the coupled subtree's articulated body is Mbar + W A_g^-1 W^T with bias
nf - W A_g^-1 s, handed to the parent as any other (:func:`_close_group`). RGE-A's forward pass
then gives the trunk's coupled qdd and the subtree's uncoupled one; A_g lam = -J qdd and a local
forward pass on D^-1 Y lam from zero correct the subtree (:func:`_finish_local`). The trunk is
eliminated once; a coupling whose paths meet at the first body (across branches) makes the
whole model take the general path above.

:func:`couple_step` (the general path) and :func:`local_passes` are the implementation, run
where the tree's kinematics (for the first, its passes too) were just run on the same bundles:
:func:`coupled_qdd` (which the public entry :func:`coupled_entry`, batches :func:`coupled_rows`
and a run's compiled derivative :func:`.system.derivative` call) and the evaluator's lean
entries (:mod:`.lean`).

Layout. A coupled model's workspace (:class:`redysim.algorithms.workspace.Workspace`, a model
with couplings that is not planar) appends to its packed arrays, after the tree's (whose header
does not see them, so every other kernel reads the arrays as before):

- ints: ``k``, the floats' offset, the scratch's offset, the union's bodies' count, their
  columns' count, where the local groups' ints start (0: the general path), then ``fq``,
  ``lq``, ``fv``, ``lv`` (k each: each coupling's follower's and leader's q and v slots),
  ``union`` (the paths' bodies, children before parents), ``coff`` and ``cols`` (on each, the
  couplings whose path holds it); the local groups' (:func:`local_segment`: each group's root,
  columns, subtree and paths in it; ``hook``, nb: the group closed at each body, or -1); the
  very last int is where this segment starts.
- floats: ``m`` (k), ``offset`` (k), the tolerance of a state's check (relative, as
  :data:`redysim.algorithms.dynamics.COUPLING_TOL`), 3 zeros (a base at rest).
- scratch: ``Y`` (k, n_v), ``Z`` = D^-1 Y (k, n_v) on the paths, ``A`` (k, k), ``lam`` (k),
  ``E`` (k, n_b, 6) the wrenches handed to the parents, ``delta`` (n_v); with local groups also
  ``A2`` (k, k), ``W`` (k, 6), ``X`` (k, 7), ``MU`` (n_b, 6), ``phz`` (n_v); flat, row by row.
"""

from __future__ import annotations

import numpy as np
from numba import types

from redysim._jit import EntryPoint, inline, jit_borrowed

from .articulated import (
    ZERO6,
    ZERO21,
    add6,
    add_body,
    articulated_bias,
    shift_bias,
    shift_to_parent,
)
from .bundles import H_NB, H_NQ, H_NV
from .entry import F_BASE_ACCEL, F_ZEROS, SIZE_MISMATCH, bundles
from .kinematics import kinematics
from .rge_a import _body, _eliminate_joint, _gathered, _leave, rge_a_backward, rge_a_forward

COUPLING_TOL = 1e-9  # |q_f - (m q_l + offset)| allowed, relative to 1 + |q_f| (and for v, qdd)
OFF_COUPLINGS = -2.0  # an entry's flag: q or v off the couplings (the checked path says which)
HEAD = 6  # ints before the arrays: k, float offset, scratch offset, union bodies, their
# columns, the local groups' offset (0: the general path)


def coupling_tail(model, parent, joint_voff, serial: bool, tol: float, f_at: int, i_at: int,
                  s_at: int) -> tuple[np.ndarray, np.ndarray, int]:
    """The ints, floats and scratch size a coupled ``model``'s workspace appends to its packed
    arrays (module docstring), the tree's being ``f_at`` floats, ``i_at`` ints and ``s_at``
    scratch long; ``parent``, ``joint_voff``: the tree's tables (``serial``: parent k - 1)."""
    fq, lq, fv, lv, m, off = (np.asarray(a) for a in model.coupling_index)
    k, n, nb = fv.shape[0], model.n_v, joint_voff.shape[0] - 1
    body_of = np.searchsorted(joint_voff, np.arange(n), side="right") - 1

    def up(b: int) -> set[int]:
        out = set()
        while b >= 0:
            out.add(b)
            b = b - 1 if serial else int(parent[b])
        return out

    paths = [up(int(body_of[fv[c]])) | up(int(body_of[lv[c]])) for c in range(k)]
    # the union of the paths, children before parents (a parent's index is below its
    # children's), and on each of its bodies the columns whose path holds it, in order
    union = sorted(set().union(*paths), reverse=True)
    coff: list[int] = [0]
    cols: list[int] = []
    for b in union:
        cols.extend(c for c in range(k) if b in paths[c])
        coff.append(len(cols))
    head = np.array([k, f_at, s_at, len(union), len(cols), 0])
    ints = np.concatenate((head, fq, lq, fv, lv, np.array(union), np.array(coff),
                           np.array(cols))).astype(np.int64)
    items = 2 * k * n + k * k + k + 6 * k * nb + n
    groups = local_groups(model, parent, joint_voff, serial)
    if groups is not None:
        seg, more = local_segment(model, parent, joint_voff, serial, groups)
        ints[5] = i_at + ints.shape[0]
        ints = np.concatenate((ints, seg))
        items += more
    ints = np.concatenate((ints, [i_at])).astype(np.int64)
    floats = np.concatenate((m, off, [tol, 0.0, 0.0, 0.0])).astype(np.float64)
    return ints, floats, items


@inline
def _tail(fdata, idata, scratch):
    """The couplings' segments of a workspace's packed arrays, as flat views (module docstring;
    no reshape, whose strides numba gets from a C helper at a cost per call)."""
    c0 = idata[idata.shape[0] - 1]
    k, fo, so, nub, ncol = idata[c0], idata[c0 + 1], idata[c0 + 2], idata[c0 + 3], idata[c0 + 4]
    nv, nb = idata[H_NV], idata[H_NB]
    i = c0 + HEAD
    fq, lq, fv, lv = (idata[i:i + k], idata[i + k:i + 2 * k], idata[i + 2 * k:i + 3 * k],
                      idata[i + 3 * k:i + 4 * k])
    i += 4 * k
    union = idata[i:i + nub]
    coff = idata[i + nub:i + 2 * nub + 1]
    cols = idata[i + 2 * nub + 1:i + 2 * nub + 1 + ncol]
    m, off, tol, base0 = (fdata[fo:fo + k], fdata[fo + k:fo + 2 * k], fdata[fo + 2 * k],
                          fdata[fo + 2 * k + 1:fo + 2 * k + 4])
    Y = scratch[so:so + k * nv]  # (k, nv) row by row, as Z
    Z = scratch[so + k * nv:so + 2 * k * nv]
    so += 2 * k * nv
    A = scratch[so:so + k * k]  # (k, k)
    lam = scratch[so + k * k:so + k * k + k]
    so += k * k + k
    E = scratch[so:so + 6 * k * nb]  # (k, nb, 6)
    delta = scratch[so + 6 * k * nb:so + 6 * k * nb + nv]
    return (k, fq, lq, fv, lv, union, coff, cols, m, off, tol, base0, Y, Z, A, lam, E, delta)


@inline
def on_couplings(fdata, idata, scratch, q, v):
    """True when every follower's q is m q_l + offset and its v m v_l, to the workspace's
    relative tolerance (NaN passes: the passes then say it is not finite)."""
    (k, fq, lq, fv, lv, _, _, _, m, off, tol, _, _, _, _, _, _, _) = _tail(fdata, idata,
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
    (k, fq, lq, fv, lv, union, coff, cols, m, off, tol, base0, Y, Z, A, lam, E,
     delta) = _tail(fdata, idata, scratch)
    serial = tree.serial != 0
    parent, voff, oO, oP, Ihat, Psihat = tree.parent, tree.joint_voff, s.oO, s.oP, s.Ihat, s.Psihat
    nv = qdd.shape[0]
    nb6 = 6 * (voff.shape[0] - 1)
    nub = union.shape[0]
    # each column y_c = U^-1 (e_f - m e_l) on its path: the columns swept side by side, body
    # by body over the paths' union, children before parents (each column's own steps, in
    # its own order, as alone; the columns' chains of dependent steps overlap)
    for i in range(nub):
        b = union[i]
        for t in range(coff[i], coff[i + 1]):
            o = cols[t] * nb6 + 6 * b
            for r in range(6):
                E[o + r] = 0.0
    for i in range(nub):
        b = union[i]
        p = b - 1 if serial else parent[b]
        if p >= 0:  # a = O_p - O_b, the shift to the parent's origin: n <- n - a x f
            a0, a1, a2 = oO[p, 0] - oO[b, 0], oO[p, 1] - oO[b, 1], oO[p, 2] - oO[b, 2]
        else:
            a0, a1, a2 = 0.0, 0.0, 0.0
        for t in range(coff[i], coff[i + 1]):
            c = cols[t]
            f, ld, mc, row, o = fv[c], lv[c], m[c], c * nv, c * nb6
            e0, e1, e2 = E[o + 6 * b], E[o + 6 * b + 1], E[o + 6 * b + 2]
            e3, e4, e5 = E[o + 6 * b + 3], E[o + 6 * b + 4], E[o + 6 * b + 5]
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
            if p >= 0:
                o += 6 * p
                E[o] += e0 - (a1 * e5 - a2 * e4)
                E[o + 1] += e1 - (a2 * e3 - a0 * e5)
                E[o + 2] += e2 - (a0 * e4 - a1 * e3)
                E[o + 3] += e3
                E[o + 4] += e4
                E[o + 5] += e5
    # A = Y^T D^-1 Y, A_cd summed over the DOFs the paths of c and d share (y_d is zero off
    # its path), DOF by DOF over the union; A lam = -J qdd0
    for j in range(k * k):
        A[j] = 0.0
    for i in range(nub):
        b = union[i]
        for j in range(voff[b + 1] - 1, voff[b] - 1, -1):
            for t in range(coff[i], coff[i + 1]):
                c = cols[t]
                z = Z[c * nv + j]
                for u in range(t, coff[i + 1]):
                    d = cols[u]
                    A[c * k + d] += z * Y[d * nv + j]
    for c in range(k):
        for d in range(c + 1, k):
            A[d * k + c] = A[c * k + d]
        lam[c] = -(qdd[fv[c]] - m[c] * qdd[lv[c]])
    _solve(A, lam, k)
    # qdd += U^-T (D^-1 Y lam): RGE-A's forward pass on phitil = Z lam, zero base acceleration
    # and zero twist-rates (the passes' own c_k, no longer needed, are cleared)
    phitil, td = s.phitil, s.td
    for j in range(nv):
        phitil[j] = 0.0
    for i in range(nub):
        b = union[i]
        for j in range(voff[b + 1] - 1, voff[b] - 1, -1):
            x = 0.0
            for t in range(coff[i], coff[i + 1]):
                c = cols[t]
                x += Z[c * nv + j] * lam[c]
            phitil[j] = x
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


# ---------------------------------------------------------------------------- local groups
def local_groups(model, parent, joint_voff, serial: bool):
    """The couplings grouped by the subtree that holds them (module docstring, "Local
    groups"): each coupling's root is the lowest common ancestor of its follower's and its
    leader's bodies; groups whose subtrees meet are merged into the higher root. Returns
    [(root, [columns])], or None when some group's root is the tree's first body (no parent
    to hand its articulated body to: the general path)."""
    fq, lq, fv, lv, m, off = (np.asarray(a) for a in model.coupling_index)
    k, n = fv.shape[0], model.n_v
    body_of = np.searchsorted(joint_voff, np.arange(n), side="right") - 1

    def par(b: int) -> int:
        return b - 1 if serial else int(parent[b])

    def up(b: int) -> list[int]:
        out = []
        while b >= 0:
            out.append(b)
            b = par(b)
        return out

    roots = []
    for c in range(k):
        a, b = up(int(body_of[fv[c]])), set(up(int(body_of[lv[c]])))
        roots.append(next(x for x in a if x in b))
    changed = True
    while changed:
        changed = False
        for c in range(k):
            for d in range(k):
                if roots[d] != roots[c] and roots[c] in up(roots[d]):
                    roots[d] = roots[c]
                    changed = True
    if any(par(r) < 0 for r in roots):
        return None
    groups: dict[int, list[int]] = {}
    for c in range(k):
        groups.setdefault(roots[c], []).append(c)
    return sorted(groups.items())


def local_segment(model, parent, joint_voff, serial: bool, groups) -> tuple[np.ndarray, int]:
    """The local groups' ints (module docstring, "Layout") and their scratch's size."""
    fq, lq, fv, lv, m, off = (np.asarray(a) for a in model.coupling_index)
    k, n, nb = fv.shape[0], model.n_v, joint_voff.shape[0] - 1
    body_of = np.searchsorted(joint_voff, np.arange(n), side="right") - 1

    def par(b: int) -> int:
        return b - 1 if serial else int(parent[b])

    def under(b: int, root: int) -> bool:
        while b >= 0 and b != root:
            b = par(b)
        return b == root

    def up_to(b: int, root: int) -> set[int]:
        out = set()
        while True:
            out.add(b)
            if b == root:
                return out
            b = par(b)

    roots: list[int] = []
    gcols: list[int] = []
    lub: list[int] = []
    lcols: list[int] = []
    sub: list[int] = []
    goff, aoff, lbo, lcoff, sbo, loc = [0], [0], [0], [0], [0], [0] * k
    hook = [-1] * nb
    for g, (root, cols) in enumerate(groups):
        roots.append(root)
        hook[root] = g
        for i, c in enumerate(cols):
            loc[c] = i
        gcols.extend(cols)
        goff.append(len(gcols))
        aoff.append(aoff[-1] + len(cols) ** 2)
        paths = {c: up_to(int(body_of[fv[c]]), root) | up_to(int(body_of[lv[c]]), root)
                 for c in cols}
        for b in sorted(set().union(*paths.values()), reverse=True):
            lub.append(b)
            lcols.extend(c for c in cols if b in paths[c])
            lcoff.append(len(lcols))
        lbo.append(len(lub))
        sub.extend(b for b in range(nb) if under(b, root))
        sbo.append(len(sub))
    ints = [len(groups), len(lub), len(lcols), len(sub), *roots, *goff, *gcols, *loc, *aoff,
            *lbo, *lub, *lcoff, *lcols, *sbo, *sub, *hook]
    return np.asarray(ints, dtype=np.int64), k * k + 13 * k + 6 * nb + n


@inline
def _local_tail(idata, scratch, k, nv, nb, lo, so):
    """The local groups' segments (module docstring, "Layout"): ints at ``lo``, scratch at
    ``so``."""
    G, nlub, nlcol, nsub = idata[lo], idata[lo + 1], idata[lo + 2], idata[lo + 3]
    i = lo + 4
    roots = idata[i:i + G]
    i += G
    goff = idata[i:i + G + 1]
    i += G + 1
    gcols = idata[i:i + k]
    loc = idata[i + k:i + 2 * k]
    i += 2 * k
    aoff = idata[i:i + G + 1]
    i += G + 1
    lbo = idata[i:i + G + 1]
    i += G + 1
    lub = idata[i:i + nlub]
    i += nlub
    lcoff = idata[i:i + nlub + 1]
    i += nlub + 1
    lcols = idata[i:i + nlcol]
    i += nlcol
    sbo = idata[i:i + G + 1]
    i += G + 1
    sub = idata[i:i + nsub]
    i += nsub
    hook = idata[i:i + nb]
    A2 = scratch[so:so + k * k]
    so += k * k
    W = scratch[so:so + 6 * k]  # (k, 6): each column's wrench out of its group's root
    X = scratch[so + 6 * k:so + 13 * k]  # (k, 7): A^-1 [W^T | s], row by row within a group
    so += 13 * k
    MU = scratch[so:so + 6 * nb]  # (nb, 6): the local passes' twist-rates
    phz = scratch[so + 6 * nb:so + 6 * nb + nv]
    return (roots, goff, gcols, loc, aoff, lbo, lub, lcoff, lcols, sbo, sub, hook, A2, W, X, MU,
            phz)


@inline
def _solve_multi(A, B, k, nr):
    """A X = B for a k x k A and a k x nr B (flat, row by row) in place by Gaussian elimination
    with partial pivoting (as :func:`_solve`, nr right-hand sides)."""
    for c in range(k):
        p = c
        for r in range(c + 1, k):
            if abs(A[r * k + c]) > abs(A[p * k + c]):
                p = r
        if p != c:
            for j in range(k):
                A[c * k + j], A[p * k + j] = A[p * k + j], A[c * k + j]
            for j in range(nr):
                B[c * nr + j], B[p * nr + j] = B[p * nr + j], B[c * nr + j]
        for r in range(c + 1, k):
            f = A[r * k + c] / A[c * k + c]
            for j in range(c + 1, k):
                A[r * k + j] = A[r * k + j] - f * A[c * k + j]
            for j in range(nr):
                B[r * nr + j] = B[r * nr + j] - f * B[c * nr + j]
    for c in range(k - 1, -1, -1):
        for j in range(nr):
            x = B[c * nr + j]
            for i in range(c + 1, k):
                x = x - A[c * k + i] * B[i * nr + j]
            B[c * nr + j] = x / A[c * k + c]


@inline
def _local_forward(serial, parent, voff, oO, oP, Psihat, phit, c, use_c, sub, s0, s1, root, MU,
                   out):
    """RGE-A's forward pass on the subtree of ``root`` (its bodies sub[s0:s1], parents first)
    from a zero twist-rate at the root's joint: out_j = phit_j - Psihat_j^T mu, with each
    non-root body's local twist-rate c_k when ``use_c``."""
    for i in range(s0, s1):
        b = sub[i]
        if b == root:
            m0, m1, m2, m3, m4, m5 = 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
        else:
            p = b - 1 if serial else parent[b]
            a0, a1, a2 = oO[p, 0] - oO[b, 0], oO[p, 1] - oO[b, 1], oO[p, 2] - oO[b, 2]
            u0, u1, u2 = MU[6 * p], MU[6 * p + 1], MU[6 * p + 2]
            m0, m1, m2 = u0, u1, u2
            m3 = MU[6 * p + 3] + (a1 * u2 - a2 * u1)
            m4 = MU[6 * p + 4] + (a2 * u0 - a0 * u2)
            m5 = MU[6 * p + 5] + (a0 * u1 - a1 * u0)
            if use_c:
                m0, m1, m2 = m0 + c[b, 0], m1 + c[b, 1], m2 + c[b, 2]
                m3, m4, m5 = m3 + c[b, 3], m4 + c[b, 4], m5 + c[b, 5]
        for j in range(voff[b], voff[b + 1]):
            x = ((phit[j] - (Psihat[j, 0] * m0 + Psihat[j, 1] * m1))
                 - ((Psihat[j, 2] * m2 + Psihat[j, 3] * m3)
                    + (Psihat[j, 4] * m4 + Psihat[j, 5] * m5)))
            out[j] = x
            m0 += oP[j, 0] * x
            m1 += oP[j, 1] * x
            m2 += oP[j, 2] * x
            m3 += oP[j, 3] * x
            m4 += oP[j, 4] * x
            m5 += oP[j, 5] * x
        MU[6 * b], MU[6 * b + 1], MU[6 * b + 2] = m0, m1, m2
        MU[6 * b + 3], MU[6 * b + 4], MU[6 * b + 5] = m3, m4, m5


@inline
def _close_group(tree, s, fdata, idata, scratch, g, M, nf, serial):
    """Group g's couplings closed at its root, just eliminated in the backward pass (module
    docstring, "Local groups"): its columns swept on the subtree, A = Y^T D^-1 Y, s = J qdd of
    the subtree from a zero twist-rate at the root, then Mbar + W A^-1 W^T and nf - W A^-1 s.
    Returns the new (M, nf)."""
    (k, fq, lq, fv, lv, union, coff, cols, m, off, tol, base0, Y, Z, A, lam, E,
     delta) = _tail(fdata, idata, scratch)
    c0 = idata[idata.shape[0] - 1]
    nv, nb = idata[H_NV], idata[H_NB]
    (roots, goff, gcols, loc, aoff, lbo, lub, lcoff, lcols, sbo, sub, hook, A2, W, X, MU,
     phz) = _local_tail(idata, scratch, k, nv, nb, idata[c0 + 5],
                              idata[c0 + 2] + _general_size(k, nv, nb))
    parent, voff, oO, oP, Ihat, Psihat = tree.parent, tree.joint_voff, s.oO, s.oP, s.Ihat, s.Psihat
    root = roots[g]
    nb6 = 6 * nb
    kg = goff[g + 1] - goff[g]
    for i in range(lbo[g], lbo[g + 1]):
        b = lub[i]
        for t in range(lcoff[i], lcoff[i + 1]):
            o = lcols[t] * nb6 + 6 * b
            for r in range(6):
                E[o + r] = 0.0
    for i in range(lbo[g], lbo[g + 1]):
        b = lub[i]
        p = b - 1 if serial else parent[b]
        a0, a1, a2 = oO[p, 0] - oO[b, 0], oO[p, 1] - oO[b, 1], oO[p, 2] - oO[b, 2]
        for t in range(lcoff[i], lcoff[i + 1]):
            c = lcols[t]
            f, ld, mc, row, o = fv[c], lv[c], m[c], c * nv, c * nb6
            e0, e1, e2 = E[o + 6 * b], E[o + 6 * b + 1], E[o + 6 * b + 2]
            e3, e4, e5 = E[o + 6 * b + 3], E[o + 6 * b + 4], E[o + 6 * b + 5]
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
            if b != root:
                o += 6 * p
                E[o] += e0 - (a1 * e5 - a2 * e4)
                E[o + 1] += e1 - (a2 * e3 - a0 * e5)
                E[o + 2] += e2 - (a0 * e4 - a1 * e3)
                E[o + 3] += e3
                E[o + 4] += e4
                E[o + 5] += e5
            else:
                W[6 * c], W[6 * c + 1], W[6 * c + 2] = e0, e1, e2
                W[6 * c + 3], W[6 * c + 4], W[6 * c + 5] = e3, e4, e5
    ao = aoff[g]
    for j in range(kg * kg):
        A[ao + j] = 0.0
    for i in range(lbo[g], lbo[g + 1]):
        b = lub[i]
        for j in range(voff[b + 1] - 1, voff[b] - 1, -1):
            for t in range(lcoff[i], lcoff[i + 1]):
                c = lcols[t]
                ca = loc[c]
                z = Z[c * nv + j]
                for u in range(t, lcoff[i + 1]):
                    d = lcols[u]
                    A[ao + ca * kg + loc[d]] += z * Y[d * nv + j]
    for a in range(kg):
        for d in range(a + 1, kg):
            A[ao + d * kg + a] = A[ao + a * kg + d]
    for j in range(kg * kg):
        A2[j] = A[ao + j]
    # s = J qdd of the subtree from a zero twist-rate at the root (its own phitil and c_k)
    _local_forward(serial, parent, voff, oO, oP, Psihat, s.phitil, s.td, True, sub, sbo[g],
                   sbo[g + 1], root, MU, delta)
    g0 = goff[g]
    for a in range(kg):
        c = gcols[g0 + a]
        for r in range(6):
            X[7 * (g0 + a) + r] = W[6 * c + r]
        X[7 * (g0 + a) + 6] = delta[fv[c]] - m[c] * delta[lv[c]]
    Xg = X[7 * g0:7 * (g0 + kg)]
    _solve_multi(A2, Xg, kg, 7)
    # D = W A^-1 W^T (6 x 6), n = W A^-1 s
    d00 = d01 = d02 = d03 = d04 = d05 = 0.0
    d11 = d12 = d13 = d14 = d15 = 0.0
    d22 = d23 = d24 = d25 = 0.0
    d33 = d34 = d35 = d44 = d45 = d55 = 0.0
    n0 = n1 = n2 = n3 = n4 = n5 = 0.0
    for a in range(kg):
        c = gcols[g0 + a]
        w0, w1, w2 = W[6 * c], W[6 * c + 1], W[6 * c + 2]
        w3, w4, w5 = W[6 * c + 3], W[6 * c + 4], W[6 * c + 5]
        xr = 7 * a
        x0, x1, x2, x3, x4, x5, x6 = (Xg[xr], Xg[xr + 1], Xg[xr + 2], Xg[xr + 3], Xg[xr + 4],
                                      Xg[xr + 5], Xg[xr + 6])
        d00 += w0 * x0
        d01 += w0 * x1
        d02 += w0 * x2
        d03 += w0 * x3
        d04 += w0 * x4
        d05 += w0 * x5
        d11 += w1 * x1
        d12 += w1 * x2
        d13 += w1 * x3
        d14 += w1 * x4
        d15 += w1 * x5
        d22 += w2 * x2
        d23 += w2 * x3
        d24 += w2 * x4
        d25 += w2 * x5
        d33 += w3 * x3
        d34 += w3 * x4
        d35 += w3 * x5
        d44 += w4 * x4
        d45 += w4 * x5
        d55 += w5 * x5
        n0 += w0 * x6
        n1 += w1 * x6
        n2 += w2 * x6
        n3 += w3 * x6
        n4 += w4 * x6
        n5 += w5 * x6
    (x00, x01, x02, x11, x12, x22, y00, y01, y02, y10, y11, y12, y20, y21, y22,
     z00, z01, z02, z11, z12, z22) = M
    M = (x00 + d00, x01 + d01, x02 + d02, x11 + d11, x12 + d12, x22 + d22,
         y00 + d03, y01 + d04, y02 + d05, y10 + d13, y11 + d14, y12 + d15,
         y20 + d23, y21 + d24, y22 + d25, z00 + d33, z01 + d34, z02 + d35, z11 + d44,
         z12 + d45, z22 + d55)
    nf = (nf[0] - n0, nf[1] - n1, nf[2] - n2, nf[3] - n3, nf[4] - n4, nf[5] - n5)
    return M, nf


@inline
def _general_size(k, nv, nb):
    """The general path's scratch (before the local groups')."""
    return 2 * k * nv + k * k + k + 6 * k * nb + nv


@inline
def _coupled_backward(tree, s, tau, fdata, idata, scratch, serial):
    """RGE-A's backward pass (:func:`.rge_a._rge_a_backward`, the same steps) with each local
    group closed at its root (:func:`_close_group`) before the root's articulated body is
    handed to its parent."""
    hook = idata[idata.shape[0] - 1 - idata[H_NB]:idata.shape[0] - 1]
    parent, gather, joint_voff = tree.parent, tree.gather, tree.joint_voff
    oO, c = s.oO, s.td
    Ihat, phihat, phitil, Psihat = s.Ihat, s.phihat, s.phitil, s.Psihat
    gm, gw = s.gather_mass, s.gather_wrench
    for g in range(gm.shape[0]):
        gm[g, :] = 0.0
        gw[g, :] = 0.0
    M, nf = ZERO21, ZERO6
    for k in range(tree.mass.shape[0] - 1, -1, -1):
        X, d0, d1, d2, wrench = _body(tree, s, k)
        if not serial and gather[k] >= 0:
            M, nf = _gathered(gm, gw, gather[k], M, nf)
        M, nf = add_body(M, nf, X, d0, d1, d2, tree.mass[k], wrench)
        M, nf = _eliminate_joint(tree, s.oP, tau, Ihat, phihat, phitil, Psihat, joint_voff[k],
                                 joint_voff[k + 1] - 1, M, nf)
        if hook[k] >= 0:
            M, nf = _close_group(tree, s, fdata, idata, scratch, hook[k], M, nf, serial)
        nf = add6(nf, articulated_bias((c[k, 0], c[k, 1], c[k, 2], c[k, 3], c[k, 4], c[k, 5]),
                                       M))
        p = k - 1 if serial else parent[k]
        if p >= 0:
            s0, s1, s2 = oO[p, 0] - oO[k, 0], oO[p, 1] - oO[k, 1], oO[p, 2] - oO[k, 2]
            nf = shift_bias(s0, s1, s2, nf)
            M = shift_to_parent(s0, s1, s2, M)
        if not serial and parent[k] != k - 1:
            if p >= 0:
                _leave(gm, gw, gather[p], M, nf)
            M, nf = ZERO21, ZERO6


@inline
def _finish_local(tree, s, fdata, idata, scratch, qdd, serial):
    """After the forward pass on the closed groups' factors: each group's lam from A lam =
    -J qdd (its subtree's qdd, free of the couplings, given its root's twist-rate) and its
    subtree's qdd += U^-T D^-1 Y lam, a local forward pass from zero."""
    (k, fq, lq, fv, lv, union, coff, cols, m, off, tol, base0, Y, Z, A, lam, E,
     delta) = _tail(fdata, idata, scratch)
    c0 = idata[idata.shape[0] - 1]
    nv, nb = idata[H_NV], idata[H_NB]
    (roots, goff, gcols, loc, aoff, lbo, lub, lcoff, lcols, sbo, sub, hook, A2, W, X, MU,
     phz) = _local_tail(idata, scratch, k, nv, nb, idata[c0 + 5],
                        idata[c0 + 2] + _general_size(k, nv, nb))
    parent, voff, oO, oP, Psihat = tree.parent, tree.joint_voff, s.oO, s.oP, s.Psihat
    for g in range(roots.shape[0]):
        g0, kg, ao = goff[g], goff[g + 1] - goff[g], aoff[g]
        for j in range(kg * kg):
            A2[j] = A[ao + j]
        for a in range(kg):
            c = gcols[g0 + a]
            lam[a] = -(qdd[fv[c]] - m[c] * qdd[lv[c]])
        _solve(A2, lam, kg)
        for i in range(sbo[g], sbo[g + 1]):
            b = sub[i]
            for j in range(voff[b], voff[b + 1]):
                phz[j] = 0.0
        for i in range(lbo[g], lbo[g + 1]):
            b = lub[i]
            for j in range(voff[b + 1] - 1, voff[b] - 1, -1):
                x = 0.0
                for t in range(lcoff[i], lcoff[i + 1]):
                    c = lcols[t]
                    x += Z[c * nv + j] * lam[loc[c]]
                phz[j] = x
        _local_forward(serial, parent, voff, oO, oP, Psihat, phz, s.td, False, sub, sbo[g],
                       sbo[g + 1], roots[g], MU, delta)
        for i in range(sbo[g], sbo[g + 1]):
            b = sub[i]
            for j in range(voff[b], voff[b + 1]):
                qdd[j] = qdd[j] + delta[j]
    bad = 0.0
    for c in range(k):
        qdd[fv[c]] = m[c] * qdd[lv[c]]
    for j in range(nv):
        bad += qdd[j] * 0.0
    return bad


@jit_borrowed
def local_passes(tree, s, fdata, idata, scratch, tau, base_accel, qdd):
    """A coupled model whose couplings all close in subtrees (local groups), after the
    kinematics pass: the backward pass closing each group at its root, RGE-A's forward pass,
    then each group's subtree corrected (:func:`_finish_local`). Returns 0.0, or NaN when some
    qdd is not finite."""
    if tree.serial != 0:
        _coupled_backward(tree, s, tau, fdata, idata, scratch, True)
        bad = rge_a_forward(tree, s, base_accel, qdd)
        if bad != 0.0:
            return bad
        return _finish_local(tree, s, fdata, idata, scratch, qdd, True)
    _coupled_backward(tree, s, tau, fdata, idata, scratch, False)
    bad = rge_a_forward(tree, s, base_accel, qdd)
    if bad != 0.0:
        return bad
    return _finish_local(tree, s, fdata, idata, scratch, qdd, False)


@inline
def is_local(idata):
    """True when the workspace's couplings close in local groups (:func:`local_passes`)."""
    return idata[idata[idata.shape[0] - 1] + 5] != 0


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
    if is_local(idata):
        return local_passes(tree, s, fdata, idata, scratch, tau, base_accel, qdd)
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
