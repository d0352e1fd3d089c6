"""RGE-A: forward dynamics in O(n) by Reverse Gaussian Elimination done analytically.

Solves I(q) qdd = phi for qdd without forming the GIM I, through its analytic U D U^T
factorisation (Table A.1):

    articulated masses (backward, k = nl..1; Mhat_nl = M_nl):
        Psi_k = Mhat_k P_k,  Ihat_k = P_k^T Psi_k,  Psihat_k = Psi_k Ihat_k^-1,
        Mbar_k = Mhat_k - Psihat_k Psi_k^T,  Mhat_{k-1} = M_{k-1} + A_{k,k-1}^T Mbar_k A_{k,k-1}
    backward, k = nl..1 (eta_{nl+1} = 0):
        eta_{k,k+1} = A_{k+1,k}^T eta_{k+1},  phihat_k = phi_k - P_k^T eta_{k,k+1},
        phitil_k = Ihat_k^-1 phihat_k,        eta_k = Psi_k phitil_k + eta_{k,k+1}
    forward, k = 1..nl (mu_0 = 0):
        mu_{k,k-1} = A_{k,k-1} mu_{k-1},  qdd_k = phitil_k - Psihat_k^T mu_{k,k-1},
        mu_k = P_k qdd_k + mu_{k,k-1}

As run here (notes below) phi_k - P_k^T eta_{k,k+1} becomes tau_k - P_k^T p_{k,k+1}, with the
bias p (eta plus the velocity-product wrenches) in place of eta, and the forward pass starts from
mu_0 = [0; -g] with mu_{k,k-1} = A_{k,k-1} mu_{k-1} + c_k.

Implementation notes:

- One source. Each step is a helper of :mod:`.articulated` on tuples of scalars (the body's
  mass, the elimination of an axis or of a U joint's block, the bias, the shift), which the
  SIMD tiles (:mod:`.tiles`) and the DH kernels' general step call too; the pivot of every
  elimination is the axis's joint-space inertia, armature included (:func:`.joints.
  joint_inertia`).
- Axis by axis. A joint with z_k > 1 axes (U, S) is eliminated one axis at a time, last axis
  first, with no shift between its axes (they meet at O_k). This is Table A.1 with the z_k x z_k
  block Ihat_k factored in passing as a unit upper triangle times a diagonal: identical in exact
  arithmetic, every step a symmetric rank-1 update, and D of I = U D U^T truly diagonal.
- Two rotational axes (a U joint, the ropes' joint) are eliminated from one 2 x 2 block. With
  a the last axis and b the first, H = [[ia, cab], [cab, ib]] = P^T Mhat P and Psi_a, Psi_b are
  all taken from Mhat before either elimination; axis b's quantities after axis a's are then
  Psi_b' = Psi_b - Psi_a cab / ia and Ihat_b = det H / ia, so 1 / ia and ia / det H are two
  independent divisions. The factors are the axis-by-axis ones (the same formulas, rearranged),
  and the update is still two symmetric rank-1 updates of the upper triangles. Axis by axis,
  the pass waits for a column product, a dot product, a division and a rank-1 update per axis;
  the block shortens that chain, and the pass's time with it (docs/notes/2026-11-kernels-speed.md).
- Exact symmetry. The articulated mass is carried as its blocks [[X, Y], [Y^T, Z]] with X and Z
  symmetric (6 + 9 + 6 numbers); only those numbers are ever computed, so Mhat_k is exactly
  symmetric by construction. A literal 6 x 6 transcription lets rounding make Mhat_k slightly
  asymmetric, the recursion amplifies it, and on long U chains all accuracy is gone
  (docs/notes/2026-11-algorithm-errors.md; stock Pinocchio ABA fails the same way on such chains).
- Gravity and the velocity terms never enter phi. Table A.1 as printed solves I qdd = phi with
  phi = tau - (C qd + gravity terms) (Eq. 12); on a long chain phi_k holds the gravity and
  centripetal moments of every link outboard of joint k (~(n - k)^2 m g l) while phihat_k is of
  order m g l, so phihat_k = phi_k - P_k^T eta cancels ~2 log10(n) digits and the true error grows
  ~n^2 eps (docs/notes/2026-11-algorithm-errors.md gives the measured errors against a 50-digit
  reference). Here, as in the articulated-body algorithm, gravity is the base's twist-rate [0; -g]
  that the forward pass carries up the chain, and the velocity terms enter as each link's local
  twist-rate c_k (kinematics with ``local_rates``) and its velocity-product wrench, accumulated in
  the articulated body's bias p_k = eta_k + (biases): phihat_k = tau_k - P_k^T p_{k,k+1} is then
  formed without the cancellation (``python -m redysim.harness.error_study --table`` measures it).
  Same factors, same operation count to within a 6 x 6 product per link; with t = c = 0 and tau =
  phi the passes are Table A.1 as printed (``redysim.algorithms.precision`` runs them so for the
  paper's tables).
- The running quantities stay in scalars rather than being read back from arrays
  (docs/design.md, "Performance notes").
- On a tree, body k's articulated body goes to its parent p: Mhat_p gathers A_{k,p}^T Mbar_k
  A_{k,p} (and the bias A^T p_k) from every child, and the forward pass starts each body from its
  parent's mu_p. A child that directly follows its parent (k = p + 1: every body of a chain) hands
  both on in the registers; any other child leaves them in its parent's row of the scratch's
  gather arrays (``bundles.Tree.gather``).

References:
    Agarwal et al., Appendix A.1, Eq. (A.1)-(A.8) and Table A.1; Eq. (9)-(12) for phi.
    Saha, "Analytical expression for the inverted inertia matrix of serial robots", Int. J.
    Robotics Research 18 (1999).
    Featherstone, Rigid Body Dynamics Algorithms (2008), section 7.3 (ABA: a_0 = -g, bias
    forces p^A and velocity-product accelerations c).
"""

from __future__ import annotations

from redysim._jit import inline, jit_borrowed

from .articulated import (
    ZERO6,
    ZERO21,
    add6,
    add21,
    add_body,
    articulated_bias,
    eliminate_axis,
    eliminate_pair,
    shift_bias,
    shift_to_parent,
    velocity_wrench,
    world_inertia,
    world_moment,
)
from .joints import PRISMATIC
from .kinematics import kinematics


@jit_borrowed
def rge_a_backward(tree, s, tau):
    """Backward pass: articulated masses, the bias of every articulated body, phitil (Table A.1).

    Reads the kinematics pass run with ``local_rates`` (s.oR, s.oO, s.oP, s.t, and s.td: each
    body's local velocity-product twist-rate c_k) and tau. Writes s.Ihat (n,) (the diagonal D of
    I = U D U^T, each axis's armature included), s.Psihat (n, 6), s.phitil (n,) and s.phihat (n,).
    With t = c = 0 and tau = phi it is Table A.1 as printed (the bias carry-over p is then eta);
    with t = c = 0 and tau = 0 it gives the factors alone.

    Compiled twice from one source (:func:`_rge_a_backward`), for a serial chain and for any
    tree, as :func:`~.kinematics.kinematics` is.
    """
    if tree.serial != 0:
        _rge_a_backward(tree, s, tau, True)
    else:
        _rge_a_backward(tree, s, tau, False)


@inline
def _rge_a_backward(tree, s, tau, serial):
    """:func:`rge_a_backward`, ``serial`` a constant. Each body's steps are
    :mod:`.articulated`'s, shared with the SIMD tiles."""
    parent, gather, joint_voff = tree.parent, tree.gather, tree.joint_voff
    oO, c = s.oO, s.td
    # The arrays written are read out of the bundle here, before the loop, and handed to the
    # helpers one by one. Where the bundle is made in the caller (the lean entries, .lean),
    # numba's dead-code elimination keeps a write only to an array it sees alive after it
    # (here: used again by the next body) or drawn from an argument; it lost the writes made
    # through a field read in a helper, or through a tuple of the arrays.
    Ihat, phihat, phitil, Psihat = s.Ihat, s.phihat, s.phitil, s.Psihat
    gm, gw = s.gather_mass, s.gather_wrench
    for g in range(gm.shape[0]):
        gm[g, :] = 0.0
        gw[g, :] = 0.0
    # Mbar_{k+1} (21 numbers: blocks X, Y, Z) and p_{k+1} moved to O_k: zero beyond the tip
    M, nf = ZERO21, ZERO6
    # backward: k = nb..1, children first
    for k in range(tree.mass.shape[0] - 1, -1, -1):
        # ---- M_k in the world frame and the body's velocity-product wrench
        X, d0, d1, d2, wrench = _body(tree, s, k)
        if not serial and gather[k] >= 0:
            # ---- the children that do not follow body k left theirs in its gather row
            M, nf = _gathered(gm, gw, gather[k], M, nf)
        # ---- Mhat_k = M_k + A^T Mbar_{k+1} A;  p_k = (body's wrench) + A^T p_{k+1}
        M, nf = add_body(M, nf, X, d0, d1, d2, tree.mass[k], wrench)
        # ---- eliminate joint k's axes, last first (Table A.1, axis by axis)
        M, nf = _eliminate_joint(tree, s.oP, tau, Ihat, phihat, phitil, Psihat, joint_voff[k],
                                 joint_voff[k + 1] - 1, M, nf)
        # ---- the articulated body's bias: p <- p + Mbar_k c_k (c_k = 0 with qd = 0)
        nf = add6(nf, articulated_bias((c[k, 0], c[k, 1], c[k, 2], c[k, 3], c[k, 4], c[k, 5]),
                                       M))
        p = k - 1 if serial else parent[k]
        if p >= 0:
            # ---- hand on to the parent p: shift to O_p with a = O_p - O_k (A_{k,p}):
            #      p <- A^T p (n <- n - a x f);  Mbar <- A^T Mbar A
            s0, s1, s2 = oO[p, 0] - oO[k, 0], oO[p, 1] - oO[k, 1], oO[p, 2] - oO[k, 2]
            nf = shift_bias(s0, s1, s2, nf)
            M = shift_to_parent(s0, s1, s2, M)
        if not serial and parent[k] != k - 1:
            if p >= 0:  # into the parent's gather row, and start the next body from zero
                _leave(gm, gw, gather[p], M, nf)
            M, nf = ZERO21, ZERO6


@inline
def _body(tree, s, k):
    """Body k's inertia about its origin in the world frame (X, 6 numbers), its first moment m
    d (3) and its velocity-product wrench (6)."""
    R = s.oR[k]
    J = tree.inertia_O[k]
    mc = tree.mass_com[k]
    frame = (R[0, 0], R[0, 1], R[0, 2], R[1, 0], R[1, 1], R[1, 2], R[2, 0], R[2, 1], R[2, 2])
    j00, j01, j02, j11, j12, j22 = J[0, 0], J[0, 1], J[0, 2], J[1, 1], J[1, 2], J[2, 2]
    X = world_inertia(j01 == 0.0 and j02 == 0.0 and j12 == 0.0,
                      j00, j01, j02, j11, j12, j22, frame)
    d0, d1, d2 = world_moment(mc[0], mc[1], mc[2], frame)
    return X, d0, d1, d2, velocity_wrench(X, d0, d1, d2, s.t[k, 0], s.t[k, 1], s.t[k, 2])


@inline
def _eliminate_joint(tree, oP, tau, Ihat, phihat, phitil, Psihat, jb, jl, M, nf):
    """Joint k's axes jb..jl eliminated from (M, nf), last first, their factors written to the
    scratch's Ihat, phihat, phitil, Psihat (module docstring: two rotational axes as one
    block)."""
    dof_kind, armature = tree.dof_kind, tree.armature
    block = jl == jb + 1 and dof_kind[jb] != PRISMATIC and dof_kind[jl] != PRISMATIC
    if block:
        # two rotational axes (a U joint), a the last, b the first: the same two eliminations
        # as the loop below, both started from Mhat's 2 x 2 block, so that the two divisions
        # run side by side instead of one waiting for the other's rank-1 update
        M, nf, fa, fb = eliminate_pair(oP[jl, 0], oP[jl, 1], oP[jl, 2],
                                       oP[jb, 0], oP[jb, 1], oP[jb, 2], tau[jl], tau[jb],
                                       armature, jl, jb, M, nf)
        _factors(Ihat, phihat, phitil, Psihat, jl, fa[0], fa[1], fa[2], fa[3])
        _factors(Ihat, phihat, phitil, Psihat, jb, fb[0], fb[1], fb[2], fb[3])
        return M, nf
    for j in range(jl, jb - 1, -1):
        M, nf, ih, ph, ptil, v = eliminate_axis(
            dof_kind[j], oP[j, 0], oP[j, 1], oP[j, 2], oP[j, 3], oP[j, 4], oP[j, 5], tau[j],
            armature, j, M, nf)
        _factors(Ihat, phihat, phitil, Psihat, j, ih, ph, ptil, v)
    return M, nf


@inline
def _factors(Ihat, phihat, phitil, Psihat, j, ih, ph, ptil, v):
    """Axis j's factors into the scratch's arrays: D (Ihat), phihat, phitil, Psihat."""
    Ihat[j] = ih
    phihat[j] = ph
    phitil[j] = ptil
    Psihat[j, 0] = v[0]
    Psihat[j, 1] = v[1]
    Psihat[j, 2] = v[2]
    Psihat[j, 3] = v[3]
    Psihat[j, 4] = v[4]
    Psihat[j, 5] = v[5]


@inline
def _gathered(gm, gw, g, M, nf):
    """(M, nf) plus what the children left in gather row g."""
    return (add21(M, (gm[g, 0], gm[g, 1], gm[g, 2], gm[g, 3], gm[g, 4], gm[g, 5], gm[g, 6],
                      gm[g, 7], gm[g, 8], gm[g, 9], gm[g, 10], gm[g, 11], gm[g, 12], gm[g, 13],
                      gm[g, 14], gm[g, 15], gm[g, 16], gm[g, 17], gm[g, 18], gm[g, 19],
                      gm[g, 20])),
            add6(nf, (gw[g, 0], gw[g, 1], gw[g, 2], gw[g, 3], gw[g, 4], gw[g, 5])))


@inline
def _leave(gm, gw, g, M, nf):
    """(M, nf) added into gather row g."""
    for i in range(21):
        gm[g, i] += M[i]
    for i in range(6):
        gw[g, i] += nf[i]


@jit_borrowed
def rge_a_forward(tree, s, base_accel, qdd):
    """Forward pass of Table A.1: qdd_k = phitil_k - Psihat_k^T mu_{k,p}, axis by axis.

    mu starts from the base's twist-rate [0; base_accel] and takes in each body's local
    twist-rate c_k (zeros and zero for Table A.1 as printed, where both are inside phi).
    The step to a body that follows its parent (k + 1 from k) is taken with the parent joint's
    last axis (every joint has one), so that its qdd enters through a single multiply-add: the
    pass is bound by that chain of dependent operations (docs/design.md, "Performance notes").
    A body with a child that does not follow it leaves mu_k in its gather row for that child.
    Returns 0.0, or NaN when some qdd is not finite.

    Compiled twice from one source (:func:`_rge_a_forward`), for a serial chain and for any tree.
    """
    if tree.serial != 0:
        return _rge_a_forward(tree, s, base_accel, qdd, True)
    return _rge_a_forward(tree, s, base_accel, qdd, False)


@inline
def _rge_a_forward(tree, s, base_accel, qdd, serial):
    """:func:`rge_a_forward`, ``serial`` a constant."""
    joint_voff = tree.joint_voff
    parent, gather = tree.parent, tree.gather
    oO, oP, Psihat, phitil, c, gt = s.oO, s.oP, s.Psihat, s.phitil, s.td, s.gather_twist
    nb = joint_voff.shape[0] - 1
    # mu_1 = A_{1,0} mu_0 + c_1 with mu_0 = [0; base_accel] (no shift at the base)
    m0, m1, m2 = c[0, 0], c[0, 1], c[0, 2]
    m3, m4, m5 = base_accel[0] + c[0, 3], base_accel[1] + c[0, 4], base_accel[2] + c[0, 5]
    nonfinite = 0.0  # stays 0 unless a qdd is NaN or +-inf (x * 0 is then NaN)
    # forward: k = 1..nb, parents first
    for k in range(nb):
        if not serial and parent[k] != k - 1:  # from the parent's mu (its gather row) or base
            p = parent[k]
            if p < 0:
                m0, m1, m2 = c[k, 0], c[k, 1], c[k, 2]
                m3, m4, m5 = (base_accel[0] + c[k, 3], base_accel[1] + c[k, 4],
                              base_accel[2] + c[k, 5])
            else:  # mu_{k,p} = A_{k,p} mu_p + c_k,  A [w; v] = [w; v + a x w],  a = O_p - O_k
                g = gather[p]
                a0 = oO[p, 0] - oO[k, 0]
                a1 = oO[p, 1] - oO[k, 1]
                a2 = oO[p, 2] - oO[k, 2]
                u0, u1, u2 = gt[g, 0], gt[g, 1], gt[g, 2]
                m3 = (gt[g, 3] + c[k, 3]) + (a1 * u2 - a2 * u1)
                m4 = (gt[g, 4] + c[k, 4]) + (a2 * u0 - a0 * u2)
                m5 = (gt[g, 5] + c[k, 5]) + (a0 * u1 - a1 * u0)
                m0, m1, m2 = u0 + c[k, 0], u1 + c[k, 1], u2 + c[k, 2]
        jl = joint_voff[k + 1] - 1  # the joint's last axis
        onward = k + 1 < nb and (serial or parent[k + 1] == k)  # body k + 1 hangs from k
        keep = not serial and gather[k] >= 0  # mu_k wanted by another child
        for j in range(joint_voff[k], jl + 1):
            # qdd_j = phitil_j - Psihat_j^T mu, summed as a tree (a shorter dependency chain)
            x = ((phitil[j] - (Psihat[j, 0] * m0 + Psihat[j, 1] * m1))
                 - ((Psihat[j, 2] * m2 + Psihat[j, 3] * m3)
                    + (Psihat[j, 4] * m4 + Psihat[j, 5] * m5)))
            qdd[j] = x
            nonfinite += x * 0.0
            p0, p1, p2, p3, p4, p5 = oP[j, 0], oP[j, 1], oP[j, 2], oP[j, 3], oP[j, 4], oP[j, 5]
            if keep and j == jl:  # mu_k = mu + P qdd, for the children that do not follow
                g = gather[k]
                gt[g, 0] = m0 + p0 * x
                gt[g, 1] = m1 + p1 * x
                gt[g, 2] = m2 + p2 * x
                gt[g, 3] = m3 + p3 * x
                gt[g, 4] = m4 + p4 * x
                gt[g, 5] = m5 + p5 * x
            if j < jl or not onward:
                # mu <- mu + P qdd
                m0 += p0 * x
                m1 += p1 * x
                m2 += p2 * x
                m3 += p3 * x
                m4 += p4 * x
                m5 += p5 * x
            else:
                # the joint's last axis, and on to body k+1 at once:
                #   mu_{k+1} = A_{k+1,k} (mu + P qdd) + c_{k+1},  A [w; v] = [w; v + a x w],
                # a = O_k - O_{k+1}, grouped as (terms known before qdd) + qdd (A P): only
                # one multiply-add waits for qdd
                a0 = oO[k, 0] - oO[k + 1, 0]
                a1 = oO[k, 1] - oO[k + 1, 1]
                a2 = oO[k, 2] - oO[k + 1, 2]
                m3, m4, m5 = (((m3 + c[k + 1, 3]) + (a1 * m2 - a2 * m1))
                              + ((a1 * p2 - a2 * p1) + p3) * x,
                              ((m4 + c[k + 1, 4]) + (a2 * m0 - a0 * m2))
                              + ((a2 * p0 - a0 * p2) + p4) * x,
                              ((m5 + c[k + 1, 5]) + (a0 * m1 - a1 * m0))
                              + ((a0 * p1 - a1 * p0) + p5) * x)
                m0 = (m0 + c[k + 1, 0]) + p0 * x
                m1 = (m1 + c[k + 1, 1]) + p1 * x
                m2 = (m2 + c[k + 1, 2]) + p2 * x
    return nonfinite


@jit_borrowed
def rge_a_forward_dynamics(tree, q, qd, tau, base_accel, zeros, s, qdd):
    """qdd = I^-1 phi in O(n): the kinematics pass (local twist-rates c_k, qdd = 0), then Table
    A.1's backward pass (with the bias of each articulated body) and its forward pass from the
    base's twist-rate [0; base_accel] = [0; -g]. One call from Python for the three passes.
    Returns 0.0, or NaN when some qdd is not finite."""
    kinematics(tree, q, qd, zeros, base_accel, s, True)
    rge_a_backward(tree, s, tau)
    return rge_a_forward(tree, s, base_accel, qdd)
