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
  this cut its time by 15-16 % at 2,000-100,000 DOF (docs/design.md, "Performance notes").
- Exact symmetry. The articulated mass is carried as its blocks [[X, Y], [Y^T, Z]] with X and Z
  symmetric (6 + 9 + 6 numbers); only those numbers are ever computed, so Mhat_k is exactly
  symmetric by construction. A literal 6 x 6 transcription lets rounding make Mhat_k slightly
  asymmetric, the recursion amplifies it, and all accuracy is gone by ~100 U-links
  (docs/design.md, "The algorithm"; stock Pinocchio ABA fails the same way on such chains).
- Gravity and the velocity terms never enter phi. Table A.1 as printed solves I qdd = phi with
  phi = tau - (C qd + gravity terms) (Eq. 12); on a long chain phi_k holds the gravity and
  centripetal moments of every link outboard of joint k (~(n - k)^2 m g l) while phihat_k is of
  order m g l, so phihat_k = phi_k - P_k^T eta cancels ~2 log10(n) digits and the true error grows
  ~n^2 eps (docs/design.md, "The algorithm", gives the measured errors against a 50-digit
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

from .joints import PRISMATIC, column_mass
from .kinematics import kinematics


@inline
def articulated_bias(ca0, ca1, ca2, cb0, cb1, cb2, x00, x01, x02, x11, x12, x22,
                     y00, y01, y02, y10, y11, y12, y20, y21, y22, z00, z01, z02, z11, z12, z22):
    """Mbar c, the increment of an articulated body's bias p = [n; f], with c = [ca; cb] the
    body's local twist-rate and Mbar = [[X, Y], [Y^T, Z]] (upper triangles of X and Z): 6
    scalars. The single-state pass and the SIMD tiles (:mod:`.tiles`) share it (and
    :func:`shift_to_parent`). (Fewer than 31 arguments: Python passes more as a tuple, which
    numba cannot inline.)"""
    return ((x00 * ca0 + x01 * ca1 + x02 * ca2) + (y00 * cb0 + y01 * cb1 + y02 * cb2),
            (x01 * ca0 + x11 * ca1 + x12 * ca2) + (y10 * cb0 + y11 * cb1 + y12 * cb2),
            (x02 * ca0 + x12 * ca1 + x22 * ca2) + (y20 * cb0 + y21 * cb1 + y22 * cb2),
            (y00 * ca0 + y10 * ca1 + y20 * ca2) + (z00 * cb0 + z01 * cb1 + z02 * cb2),
            (y01 * ca0 + y11 * ca1 + y21 * ca2) + (z01 * cb0 + z11 * cb1 + z12 * cb2),
            (y02 * ca0 + y12 * ca1 + y22 * ca2) + (z02 * cb0 + z12 * cb1 + z22 * cb2))


@inline
def shift_to_parent(s0, s1, s2, x00, x01, x02, x11, x12, x22,
                    y00, y01, y02, y10, y11, y12, y20, y21, y22, z00, z01, z02, z11, z12, z22):
    """An articulated mass handed on to its parent's origin, a = (s0, s1, s2) = O_p - O_k
    (A_{k,p}): Mbar <- A^T Mbar A, which leaves Z as it is. Returns X's upper triangle and Y:
    15 scalars. (The bias's part, n <- n - a x f, is the caller's.)"""
    # S = Y C(a): column j of C(a) is a x e_j
    S00 = y01 * s2 - y02 * s1
    S01 = y02 * s0 - y00 * s2
    S02 = y00 * s1 - y01 * s0
    S10 = y11 * s2 - y12 * s1
    S11 = y12 * s0 - y10 * s2
    S12 = y10 * s1 - y11 * s0
    S20 = y21 * s2 - y22 * s1
    S21 = y22 * s0 - y20 * s2
    S22 = y20 * s1 - y21 * s0
    # CZ = C(a) Z
    q00 = s1 * z02 - s2 * z01
    q01 = s1 * z12 - s2 * z11
    q02 = s1 * z22 - s2 * z12
    q10 = s2 * z00 - s0 * z02
    q11 = s2 * z01 - s0 * z12
    q12 = s2 * z02 - s0 * z22
    q20 = s0 * z01 - s1 * z00
    q21 = s0 * z11 - s1 * z01
    q22 = s0 * z12 - s1 * z02
    # X <- X + S + S^T - CZ C(a) (upper triangle);  Y <- Y - CZ
    return (x00 + (2.0 * S00 - (q01 * s2 - q02 * s1)), x01 + (S01 + S10 - (q02 * s0 - q00 * s2)),
            x02 + (S02 + S20 - (q00 * s1 - q01 * s0)), x11 + (2.0 * S11 - (q12 * s0 - q10 * s2)),
            x12 + (S12 + S21 - (q10 * s1 - q11 * s0)), x22 + (2.0 * S22 - (q20 * s1 - q21 * s0)),
            y00 - q00, y01 - q01, y02 - q02, y10 - q10, y11 - q11, y12 - q12,
            y20 - q20, y21 - q21, y22 - q22)


@jit_borrowed
def rge_a_backward(tree, s, tau):
    """Backward pass: articulated masses, the bias of every articulated body, phitil (Table A.1).

    Reads the kinematics pass run with ``local_rates`` (s.oR, s.oO, s.oP, s.t, and s.td: each
    body's local velocity-product twist-rate c_k) and tau. Writes s.Ihat (n,) (the diagonal D of
    I = U D U^T), s.Psihat (n, 6), s.phitil (n,) and s.phihat (n,).
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
    """:func:`rge_a_backward`, ``serial`` a constant."""
    mass, inertia_O, mass_com, dof_kind, joint_voff = (tree.mass, tree.inertia_O, tree.mass_com,
                                                       tree.dof_kind, tree.joint_voff)
    parent, gather = tree.parent, tree.gather
    oR, oO, oP, t, c = s.oR, s.oO, s.oP, s.t, s.td
    Ihat, Psihat, phitil, phihat = s.Ihat, s.Psihat, s.phitil, s.phihat
    gm, gw = s.gather_mass, s.gather_wrench
    for g in range(gm.shape[0]):
        gm[g, :] = 0.0
        gw[g, :] = 0.0
    nb = mass.shape[0]
    # Mbar_{k+1} (blocks X, Y, Z) and p_{k+1} moved to O_k: zero beyond the tip
    x00 = x01 = x02 = x11 = x12 = x22 = 0.0
    y00 = y01 = y02 = y10 = y11 = y12 = y20 = y21 = y22 = 0.0
    z00 = z01 = z02 = z11 = z12 = z22 = 0.0
    n0 = n1 = n2 = f0 = f1 = f2 = 0.0
    # backward: k = nb..1, children first
    for k in range(nb - 1, -1, -1):
        # ---- M_k in the world frame: X = R I_O R^T, m d = R (m c), Z = m 1
        R = oR[k]
        J = inertia_O[k]
        mc = mass_com[k]
        m = mass[k]
        r00, r01, r02 = R[0, 0], R[0, 1], R[0, 2]
        r10, r11, r12 = R[1, 0], R[1, 1], R[1, 2]
        r20, r21, r22 = R[2, 0], R[2, 1], R[2, 2]
        j00, j01, j02, j11, j12, j22 = J[0, 0], J[0, 1], J[0, 2], J[1, 1], J[1, 2], J[2, 2]
        if j01 == 0.0 and j02 == 0.0 and j12 == 0.0:
            # principal axes along the link frame's (rod, cylinder): X = sum_i J_ii r_i r_i^T
            # over the columns r_i of R
            X00 = j00 * (r00 * r00) + j11 * (r01 * r01) + j22 * (r02 * r02)
            X01 = j00 * (r00 * r10) + j11 * (r01 * r11) + j22 * (r02 * r12)
            X02 = j00 * (r00 * r20) + j11 * (r01 * r21) + j22 * (r02 * r22)
            X11 = j00 * (r10 * r10) + j11 * (r11 * r11) + j22 * (r12 * r12)
            X12 = j00 * (r10 * r20) + j11 * (r11 * r21) + j22 * (r12 * r22)
            X22 = j00 * (r20 * r20) + j11 * (r21 * r21) + j22 * (r22 * r22)
        else:  # B = R I_O (inertia_O is exactly symmetric), X = B R^T
            c00 = r00 * j00 + r01 * j01 + r02 * j02
            c01 = r00 * j01 + r01 * j11 + r02 * j12
            c02 = r00 * j02 + r01 * j12 + r02 * j22
            c10 = r10 * j00 + r11 * j01 + r12 * j02
            c11 = r10 * j01 + r11 * j11 + r12 * j12
            c12 = r10 * j02 + r11 * j12 + r12 * j22
            c20 = r20 * j00 + r21 * j01 + r22 * j02
            c21 = r20 * j01 + r21 * j11 + r22 * j12
            c22 = r20 * j02 + r21 * j12 + r22 * j22
            X00 = c00 * r00 + c01 * r01 + c02 * r02
            X01 = c00 * r10 + c01 * r11 + c02 * r12
            X02 = c00 * r20 + c01 * r21 + c02 * r22
            X11 = c10 * r10 + c11 * r11 + c12 * r12
            X12 = c10 * r20 + c11 * r21 + c12 * r22
            X22 = c20 * r20 + c21 * r21 + c22 * r22
        d0 = r00 * mc[0] + r01 * mc[1] + r02 * mc[2]
        d1 = r10 * mc[0] + r11 * mc[1] + r12 * mc[2]
        d2 = r20 * mc[0] + r21 * mc[1] + r22 * mc[2]
        # ---- the link's velocity-product wrench about O_k (Newton-Euler at zero twist-rate):
        #      f = w x (w x md),  n = w x (X w)
        w0, w1, w2 = t[k, 0], t[k, 1], t[k, 2]
        h0 = X00 * w0 + X01 * w1 + X02 * w2
        h1 = X01 * w0 + X11 * w1 + X12 * w2
        h2 = X02 * w0 + X12 * w1 + X22 * w2
        g0 = w1 * d2 - w2 * d1
        g1 = w2 * d0 - w0 * d2
        g2 = w0 * d1 - w1 * d0
        lf0 = w1 * g2 - w2 * g1
        lf1 = w2 * g0 - w0 * g2
        lf2 = w0 * g1 - w1 * g0
        ln0 = w1 * h2 - w2 * h1
        ln1 = w2 * h0 - w0 * h2
        ln2 = w0 * h1 - w1 * h0
        if not serial and gather[k] >= 0:
            # ---- the children that do not follow body k left theirs in its gather row
            g = gather[k]
            x00 += gm[g, 0]
            x01 += gm[g, 1]
            x02 += gm[g, 2]
            x11 += gm[g, 3]
            x12 += gm[g, 4]
            x22 += gm[g, 5]
            y00 += gm[g, 6]
            y01 += gm[g, 7]
            y02 += gm[g, 8]
            y10 += gm[g, 9]
            y11 += gm[g, 10]
            y12 += gm[g, 11]
            y20 += gm[g, 12]
            y21 += gm[g, 13]
            y22 += gm[g, 14]
            z00 += gm[g, 15]
            z01 += gm[g, 16]
            z02 += gm[g, 17]
            z11 += gm[g, 18]
            z12 += gm[g, 19]
            z22 += gm[g, 20]
            n0 += gw[g, 0]
            n1 += gw[g, 1]
            n2 += gw[g, 2]
            f0 += gw[g, 3]
            f1 += gw[g, 4]
            f2 += gw[g, 5]
        # ---- Mhat_k = M_k + A^T Mbar_{k+1} A;  p_k = (link's wrench) + A^T p_{k+1}
        x00 += X00
        x01 += X01
        x02 += X02
        x11 += X11
        x12 += X12
        x22 += X22
        y01 -= d2  # Y_k = C(m d)
        y02 += d1
        y10 += d2
        y12 -= d0
        y20 -= d1
        y21 += d0
        z00 += m
        z11 += m
        z22 += m
        n0 += ln0
        n1 += ln1
        n2 += ln2
        f0 += lf0
        f1 += lf1
        f2 += lf2
        jb = joint_voff[k]
        jl = joint_voff[k + 1] - 1  # the last axis
        block = jl == jb + 1 and dof_kind[jb] != PRISMATIC and dof_kind[jl] != PRISMATIC
        if block:
            # ---- two rotational axes (a U joint), a the last, b the first: the same two
            # eliminations as the loop below, each axis's Ihat, Psihat and phitil as Table A.1's,
            # but both started from Mhat's 2 x 2 block, so that the two divisions run side by
            # side instead of one waiting for the other's rank-1 update (module docstring)
            ja = jl
            a0, a1, a2 = oP[ja, 0], oP[ja, 1], oP[ja, 2]
            b0, b1, b2 = oP[jb, 0], oP[jb, 1], oP[jb, 2]
            # Psi_a = Mhat P_a, Psi_b = Mhat P_b (P = [e; 0]), both from the same Mhat
            u0 = x00 * a0 + x01 * a1 + x02 * a2
            u1 = x01 * a0 + x11 * a1 + x12 * a2
            u2 = x02 * a0 + x12 * a1 + x22 * a2
            u3 = y00 * a0 + y10 * a1 + y20 * a2
            u4 = y01 * a0 + y11 * a1 + y21 * a2
            u5 = y02 * a0 + y12 * a1 + y22 * a2
            w0 = x00 * b0 + x01 * b1 + x02 * b2
            w1 = x01 * b0 + x11 * b1 + x12 * b2
            w2 = x02 * b0 + x12 * b1 + x22 * b2
            w3 = y00 * b0 + y10 * b1 + y20 * b2
            w4 = y01 * b0 + y11 * b1 + y21 * b2
            w5 = y02 * b0 + y12 * b1 + y22 * b2
            # the block P^T Mhat P = [[ia, cab], [cab, ib]] and its determinant
            ia = (a0 * u0 + a1 * u1) + a2 * u2
            ib = (b0 * w0 + b1 * w1) + b2 * w2
            cab = (b0 * u0 + b1 * u1) + b2 * u2
            det = ia * ib - cab * cab
            inva = 1.0 / ia
            invb = ia / det  # 1 / Ihat_b (below), in parallel with 1 / ia
            # axis a as Table A.1: Ihat_a = ia, Psihat_a = Psi_a / ia
            pa = tau[ja] - (a0 * n0 + a1 * n1 + a2 * n2)
            ptil = pa * inva
            phihat[ja] = pa
            Ihat[ja] = ia
            phitil[ja] = ptil
            sa0, sa1, sa2 = u0 * inva, u1 * inva, u2 * inva
            sa3, sa4, sa5 = u3 * inva, u4 * inva, u5 * inva
            Psihat[ja, 0] = sa0
            Psihat[ja, 1] = sa1
            Psihat[ja, 2] = sa2
            Psihat[ja, 3] = sa3
            Psihat[ja, 4] = sa4
            Psihat[ja, 5] = sa5
            # axis b on Mhat - Psi_a Psi_a^T / ia: Psi_b' = Psi_b - Psi_a cab / ia, whose
            # Ihat_b = ib - cab^2 / ia = det / ia (its inverse ia / det)
            r = cab * inva
            ib1 = det * inva
            v0, v1, v2 = w0 - u0 * r, w1 - u1 * r, w2 - u2 * r
            v3, v4, v5 = w3 - u3 * r, w4 - u4 * r, w5 - u5 * r
            pb = tau[jb] - ((b0 * n0 + b1 * n1 + b2 * n2) + cab * ptil)
            ptilb = pb * invb
            phihat[jb] = pb
            Ihat[jb] = ib1
            phitil[jb] = ptilb
            sb0, sb1, sb2 = v0 * invb, v1 * invb, v2 * invb
            sb3, sb4, sb5 = v3 * invb, v4 * invb, v5 * invb
            Psihat[jb, 0] = sb0
            Psihat[jb, 1] = sb1
            Psihat[jb, 2] = sb2
            Psihat[jb, 3] = sb3
            Psihat[jb, 4] = sb4
            Psihat[jb, 5] = sb5
            # p <- p + Psi_a phitil_a + Psi_b' phitil_b
            n0 += u0 * ptil + v0 * ptilb
            n1 += u1 * ptil + v1 * ptilb
            n2 += u2 * ptil + v2 * ptilb
            f0 += u3 * ptil + v3 * ptilb
            f1 += u4 * ptil + v4 * ptilb
            f2 += u5 * ptil + v5 * ptilb
            # Mhat <- (Mhat - Psihat_a Psi_a^T) - Psihat_b Psi_b'^T (upper triangles only)
            x00 = (x00 - sa0 * u0) - sb0 * v0
            x01 = (x01 - sa0 * u1) - sb0 * v1
            x02 = (x02 - sa0 * u2) - sb0 * v2
            x11 = (x11 - sa1 * u1) - sb1 * v1
            x12 = (x12 - sa1 * u2) - sb1 * v2
            x22 = (x22 - sa2 * u2) - sb2 * v2
            y00 = (y00 - sa0 * u3) - sb0 * v3
            y01 = (y01 - sa0 * u4) - sb0 * v4
            y02 = (y02 - sa0 * u5) - sb0 * v5
            y10 = (y10 - sa1 * u3) - sb1 * v3
            y11 = (y11 - sa1 * u4) - sb1 * v4
            y12 = (y12 - sa1 * u5) - sb1 * v5
            y20 = (y20 - sa2 * u3) - sb2 * v3
            y21 = (y21 - sa2 * u4) - sb2 * v4
            y22 = (y22 - sa2 * u5) - sb2 * v5
            z00 = (z00 - sa3 * u3) - sb3 * v3
            z01 = (z01 - sa3 * u4) - sb3 * v4
            z02 = (z02 - sa3 * u5) - sb3 * v5
            z11 = (z11 - sa4 * u4) - sb4 * v4
            z12 = (z12 - sa4 * u5) - sb4 * v5
            z22 = (z22 - sa5 * u5) - sb5 * v5
        # ---- eliminate joint k's axes, last first (Table A.1, axis by axis)
        for j in range(jl, jl if block else jb - 1, -1):
            p0, p1, p2, p3, p4, p5 = oP[j, 0], oP[j, 1], oP[j, 2], oP[j, 3], oP[j, 4], oP[j, 5]
            # phihat_j = tau_j - P^T p (Table A.1's phi_j - P^T eta, without forming phi_j)
            ph = tau[j] - (p0 * n0 + p1 * n1 + p2 * n2 + p3 * f0 + p4 * f1 + p5 * f2)
            phihat[j] = ph
            # Psi = Mhat p, Ihat = P^T Psi (the column's kind is dispatched in joints.py)
            kind = dof_kind[j]
            u0, u1, u2, u3, u4, u5, ih = column_mass(
                kind, p0 + p3, p1 + p4, p2 + p5, x00, x01, x02, x11, x12, x22,
                y00, y01, y02, y10, y11, y12, y20, y21, y22, z00, z01, z02, z11, z12, z22)
            inv = 1.0 / ih
            v0, v1, v2, v3, v4, v5 = u0 * inv, u1 * inv, u2 * inv, u3 * inv, u4 * inv, u5 * inv
            ptil = ph * inv
            Ihat[j] = ih
            phitil[j] = ptil
            Psihat[j, 0] = v0
            Psihat[j, 1] = v1
            Psihat[j, 2] = v2
            Psihat[j, 3] = v3
            Psihat[j, 4] = v4
            Psihat[j, 5] = v5
            # p <- p + Psi phitil  (Table A.1's eta)
            n0 += u0 * ptil
            n1 += u1 * ptil
            n2 += u2 * ptil
            f0 += u3 * ptil
            f1 += u4 * ptil
            f2 += u5 * ptil
            # Mhat <- Mhat - Psihat Psi^T (symmetric blocks: upper triangles only)
            x00 -= v0 * u0
            x01 -= v0 * u1
            x02 -= v0 * u2
            x11 -= v1 * u1
            x12 -= v1 * u2
            x22 -= v2 * u2
            y00 -= v0 * u3
            y01 -= v0 * u4
            y02 -= v0 * u5
            y10 -= v1 * u3
            y11 -= v1 * u4
            y12 -= v1 * u5
            y20 -= v2 * u3
            y21 -= v2 * u4
            y22 -= v2 * u5
            z00 -= v3 * u3
            z01 -= v3 * u4
            z02 -= v3 * u5
            z11 -= v4 * u4
            z12 -= v4 * u5
            z22 -= v5 * u5
        # ---- the articulated body's bias: p <- p + Mbar_k c_k (c_k = 0 with qd = 0)
        d0, d1, d2, d3, d4, d5 = articulated_bias(
            c[k, 0], c[k, 1], c[k, 2], c[k, 3], c[k, 4], c[k, 5],
            x00, x01, x02, x11, x12, x22, y00, y01, y02, y10, y11, y12, y20, y21, y22,
            z00, z01, z02, z11, z12, z22)
        n0 += d0
        n1 += d1
        n2 += d2
        f0 += d3
        f1 += d4
        f2 += d5
        p = k - 1 if serial else parent[k]
        if p >= 0:
            # ---- hand on to the parent p: shift to O_p with a = O_p - O_k (A_{k,p}):
            #      p <- A^T p (n <- n - a x f);  Mbar <- A^T Mbar A
            s0 = oO[p, 0] - oO[k, 0]
            s1 = oO[p, 1] - oO[k, 1]
            s2 = oO[p, 2] - oO[k, 2]
            n0 -= s1 * f2 - s2 * f1
            n1 -= s2 * f0 - s0 * f2
            n2 -= s0 * f1 - s1 * f0
            (x00, x01, x02, x11, x12, x22,
             y00, y01, y02, y10, y11, y12, y20, y21, y22) = shift_to_parent(
                s0, s1, s2, x00, x01, x02, x11, x12, x22,
                y00, y01, y02, y10, y11, y12, y20, y21, y22, z00, z01, z02, z11, z12, z22)
        if not serial and parent[k] != k - 1:
            if p >= 0:  # into the parent's gather row, and start the next body from zero
                g = gather[p]
                gm[g, 0] += x00
                gm[g, 1] += x01
                gm[g, 2] += x02
                gm[g, 3] += x11
                gm[g, 4] += x12
                gm[g, 5] += x22
                gm[g, 6] += y00
                gm[g, 7] += y01
                gm[g, 8] += y02
                gm[g, 9] += y10
                gm[g, 10] += y11
                gm[g, 11] += y12
                gm[g, 12] += y20
                gm[g, 13] += y21
                gm[g, 14] += y22
                gm[g, 15] += z00
                gm[g, 16] += z01
                gm[g, 17] += z02
                gm[g, 18] += z11
                gm[g, 19] += z12
                gm[g, 20] += z22
                gw[g, 0] += n0
                gw[g, 1] += n1
                gw[g, 2] += n2
                gw[g, 3] += f0
                gw[g, 4] += f1
                gw[g, 5] += f2
            x00 = x01 = x02 = x11 = x12 = x22 = 0.0
            y00 = y01 = y02 = y10 = y11 = y12 = y20 = y21 = y22 = 0.0
            z00 = z01 = z02 = z11 = z12 = z22 = 0.0
            n0 = n1 = n2 = f0 = f1 = f2 = 0.0


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
