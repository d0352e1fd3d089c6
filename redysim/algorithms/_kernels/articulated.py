"""The articulated-body algebra, once: a body's mass in the world frame, the elimination of an
axis, the articulated body's bias and its shift to the parent.

Every backward pass of RGE-A is made of these steps: the single-state kernels (:mod:`.rge_a`, and
through them the lean entries of :mod:`.lean`), the SIMD tiles (:mod:`.tiles`, which call them
once per state inside their loops over states) and the DH kernels' general step (:mod:`.dh`). A
change to the joint-space inertia (armature: :func:`.joints.joint_inertia`) or to an articulated
mass's algebra is an edit here.

An articulated mass Mhat = [[X, Y], [Y^T, Z]] is carried as the 21 numbers of its blocks, X and Z
symmetric: ``M`` = (x00, x01, x02, x11, x12, x22, y00, y01, y02, y10, y11, y12, y20, y21, y22, z00,
z01, z02, z11, z12, z22) (the order of :data:`.bundles.GATHER_MASS`'s rows), only the upper
triangles of X and Z, so it is exactly symmetric by construction (docs/design.md, "The
algorithm"). A bias wrench ``nf`` = (n0, n1, n2, f0, f1, f2): moment about the body's origin, and
force. Both are tuples of scalars: numba keeps them in registers when the helpers are inlined
(``redysim._jit.inline``), and a helper passed scalars costs nothing, where an array passed in a
hot loop cost a reference count per call in a kernel compiled with them.

The operations are those the kernels did before they were gathered here, in the same order and
grouping: the results are the same bits (IEEE order of operations is part of the contract:
``redysim._jit``).

References:
    Agarwal et al., Appendix A.1, Table A.1; Featherstone, Rigid Body Dynamics Algorithms (2008),
    section 7.3 (the articulated-body algorithm: U = I^A S, D = S^T I^A S + armature,
    I^a = I^A - U D^-1 U^T, the bias p^a = p^A + I^a c + U D^-1 u).
"""

from __future__ import annotations

from redysim._jit import inline

from .joints import PRISMATIC, REVOLUTE, joint_inertia

ZERO21 = (0.0,) * 21  # an articulated mass of nothing
ZERO6 = (0.0,) * 6


@inline
def world_inertia(principal, j00, j01, j02, j11, j12, j22, R):
    """X = R J R^T, a body's inertia J about its origin (upper triangle: j00..j22) turned into
    the world frame by its frame R (9-tuple): X's upper triangle, 6 numbers. ``principal``: J
    is diagonal (principal axes along the body frame's: rods, cylinders), X = sum_i J_ii r_i
    r_i^T over R's columns."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    if principal:
        return (j00 * (r00 * r00) + j11 * (r01 * r01) + j22 * (r02 * r02),
                j00 * (r00 * r10) + j11 * (r01 * r11) + j22 * (r02 * r12),
                j00 * (r00 * r20) + j11 * (r01 * r21) + j22 * (r02 * r22),
                j00 * (r10 * r10) + j11 * (r11 * r11) + j22 * (r12 * r12),
                j00 * (r10 * r20) + j11 * (r11 * r21) + j22 * (r12 * r22),
                j00 * (r20 * r20) + j11 * (r21 * r21) + j22 * (r22 * r22))
    # B = R J (J exactly symmetric), X = B R^T
    c00 = r00 * j00 + r01 * j01 + r02 * j02
    c01 = r00 * j01 + r01 * j11 + r02 * j12
    c02 = r00 * j02 + r01 * j12 + r02 * j22
    c10 = r10 * j00 + r11 * j01 + r12 * j02
    c11 = r10 * j01 + r11 * j11 + r12 * j12
    c12 = r10 * j02 + r11 * j12 + r12 * j22
    c20 = r20 * j00 + r21 * j01 + r22 * j02
    c21 = r20 * j01 + r21 * j11 + r22 * j12
    c22 = r20 * j02 + r21 * j12 + r22 * j22
    return (c00 * r00 + c01 * r01 + c02 * r02, c00 * r10 + c01 * r11 + c02 * r12,
            c00 * r20 + c01 * r21 + c02 * r22, c10 * r10 + c11 * r11 + c12 * r12,
            c10 * r20 + c11 * r21 + c12 * r22, c20 * r20 + c21 * r21 + c22 * r22)


@inline
def world_moment(mc0, mc1, mc2, R):
    """m d = R (m c): a body's first moment about its origin in the world frame."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    return (r00 * mc0 + r01 * mc1 + r02 * mc2, r10 * mc0 + r11 * mc1 + r12 * mc2,
            r20 * mc0 + r21 * mc1 + r22 * mc2)


@inline
def velocity_wrench(X, d0, d1, d2, w0, w1, w2):
    """A body's velocity-product wrench about its origin, Newton-Euler at zero twist-rate:
    n = w x (X w), f = w x (w x m d) (X its inertia in the world frame, 6 numbers; m d = (d0,
    d1, d2); w its angular velocity). Returns (n0, n1, n2, f0, f1, f2)."""
    X00, X01, X02, X11, X12, X22 = X
    h0 = X00 * w0 + X01 * w1 + X02 * w2
    h1 = X01 * w0 + X11 * w1 + X12 * w2
    h2 = X02 * w0 + X12 * w1 + X22 * w2
    g0 = w1 * d2 - w2 * d1
    g1 = w2 * d0 - w0 * d2
    g2 = w0 * d1 - w1 * d0
    return (w1 * h2 - w2 * h1, w2 * h0 - w0 * h2, w0 * h1 - w1 * h0,
            w1 * g2 - w2 * g1, w2 * g0 - w0 * g2, w0 * g1 - w1 * g0)


@inline
def add_body(M, nf, X, d0, d1, d2, m, wrench):
    """Mhat + M_k and p + w_k: a body's extended mass [[X, C(m d)], [-C(m d), m 1]] (X its
    inertia about its origin and m d its first moment, world frame) and its velocity-product
    wrench added to an articulated body."""
    (x00, x01, x02, x11, x12, x22, y00, y01, y02, y10, y11, y12, y20, y21, y22,
     z00, z01, z02, z11, z12, z22) = M
    n0, n1, n2, f0, f1, f2 = nf
    X00, X01, X02, X11, X12, X22 = X
    ln0, ln1, ln2, lf0, lf1, lf2 = wrench
    return ((x00 + X00, x01 + X01, x02 + X02, x11 + X11, x12 + X12, x22 + X22,
             y00, y01 - d2, y02 + d1, y10 + d2, y11, y12 - d0, y20 - d1, y21 + d0, y22,
             z00 + m, z01, z02, z11 + m, z12, z22 + m),
            (n0 + ln0, n1 + ln1, n2 + ln2, f0 + lf0, f1 + lf1, f2 + lf2))


@inline
def add21(M, G):
    """The sum of two articulated masses (21 numbers each)."""
    return (M[0] + G[0], M[1] + G[1], M[2] + G[2], M[3] + G[3], M[4] + G[4], M[5] + G[5],
            M[6] + G[6], M[7] + G[7], M[8] + G[8], M[9] + G[9], M[10] + G[10], M[11] + G[11],
            M[12] + G[12], M[13] + G[13], M[14] + G[14], M[15] + G[15], M[16] + G[16],
            M[17] + G[17], M[18] + G[18], M[19] + G[19], M[20] + G[20])


@inline
def add6(a, b):
    """The sum of two 6-vectors."""
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2], a[3] + b[3], a[4] + b[4], a[5] + b[5])


@inline
def column_mass(kind, e0, e1, e2, M):
    """Psi = Mhat p and P^T Mhat P for the column p of one axis, Mhat = [[X, Y], [Y^T, Z]].

    p = [e; 0] (revolute, ball) : Psi = [X e; Y^T e], p^T Psi = e . X e;
    p = [0; e] (prismatic): Psi = [Y e; Z e], p^T Psi = e . Z e.
    Only the non-zero half of p is multiplied: half the work of a 6 x 6 product, and a shorter
    serial chain in RGE-A's backward pass. Returns (Psi_0..Psi_5, p^T Psi).
    """
    (x00, x01, x02, x11, x12, x22, y00, y01, y02, y10, y11, y12, y20, y21, y22,
     z00, z01, z02, z11, z12, z22) = M
    if kind == PRISMATIC:  # (a ball's columns are rotational: the revolute branch)
        u0 = y00 * e0 + y01 * e1 + y02 * e2
        u1 = y10 * e0 + y11 * e1 + y12 * e2
        u2 = y20 * e0 + y21 * e1 + y22 * e2
        u3 = z00 * e0 + z01 * e1 + z02 * e2
        u4 = z01 * e0 + z11 * e1 + z12 * e2
        u5 = z02 * e0 + z12 * e1 + z22 * e2
        return u0, u1, u2, u3, u4, u5, e0 * u3 + e1 * u4 + e2 * u5
    u0 = x00 * e0 + x01 * e1 + x02 * e2
    u1 = x01 * e0 + x11 * e1 + x12 * e2
    u2 = x02 * e0 + x12 * e1 + x22 * e2
    u3 = y00 * e0 + y10 * e1 + y20 * e2
    u4 = y01 * e0 + y11 * e1 + y21 * e2
    u5 = y02 * e0 + y12 * e1 + y22 * e2
    return u0, u1, u2, u3, u4, u5, e0 * u0 + e1 * u1 + e2 * u2


@inline
def downdate(M, v, u):
    """Mhat - v u^T for the symmetric rank-1 term Psihat Psi^T (v = Psi / D, u = Psi): the
    upper triangles only, so the result is exactly symmetric."""
    (x00, x01, x02, x11, x12, x22, y00, y01, y02, y10, y11, y12, y20, y21, y22,
     z00, z01, z02, z11, z12, z22) = M
    v0, v1, v2, v3, v4, v5 = v
    u0, u1, u2, u3, u4, u5 = u
    return (x00 - v0 * u0, x01 - v0 * u1, x02 - v0 * u2, x11 - v1 * u1, x12 - v1 * u2,
            x22 - v2 * u2,
            y00 - v0 * u3, y01 - v0 * u4, y02 - v0 * u5, y10 - v1 * u3, y11 - v1 * u4,
            y12 - v1 * u5, y20 - v2 * u3, y21 - v2 * u4, y22 - v2 * u5,
            z00 - v3 * u3, z01 - v3 * u4, z02 - v3 * u5, z11 - v4 * u4, z12 - v4 * u5,
            z22 - v5 * u5)


@inline
def eliminate_axis(kind, p0, p1, p2, p3, p4, p5, tau_j, armature, j, M, nf):
    """Axis j of Table A.1 on the articulated body (M, nf) with its column P = (p0..p5):

        phihat = tau_j - P^T p,  Psi = Mhat P,  D = P^T Psi + armature[j],
        Psihat = Psi / D,  phitil = phihat / D,  p <- p + Psi phitil,  Mhat <- Mhat - Psihat Psi^T.

    Returns (M, nf, D, phihat, phitil, Psihat (6-tuple))."""
    n0, n1, n2, f0, f1, f2 = nf
    # phihat_j = tau_j - P^T p (Table A.1's phi_j - P^T eta, without forming phi_j)
    ph = tau_j - (p0 * n0 + p1 * n1 + p2 * n2 + p3 * f0 + p4 * f1 + p5 * f2)
    # Psi = Mhat P, D = P^T Psi + armature (the column's kind dispatched in column_mass)
    u0, u1, u2, u3, u4, u5, ih = column_mass(kind, p0 + p3, p1 + p4, p2 + p5, M)
    ih = joint_inertia(ih, armature, j)
    inv = 1.0 / ih
    v0, v1, v2, v3, v4, v5 = u0 * inv, u1 * inv, u2 * inv, u3 * inv, u4 * inv, u5 * inv
    ptil = ph * inv
    # p <- p + Psi phitil (Table A.1's eta); Mhat <- Mhat - Psihat Psi^T
    nf = (n0 + u0 * ptil, n1 + u1 * ptil, n2 + u2 * ptil, f0 + u3 * ptil, f1 + u4 * ptil,
          f2 + u5 * ptil)
    return (downdate(M, (v0, v1, v2, v3, v4, v5), (u0, u1, u2, u3, u4, u5)), nf, ih, ph, ptil,
            (v0, v1, v2, v3, v4, v5))


@inline
def eliminate_pair(a0, a1, a2, b0, b1, b2, tau_a, tau_b, armature, ja, jb, M, nf):
    """Two rotational axes of one joint (a U joint), a = (a0, a1, a2) the last and b the first,
    eliminated from one 2 x 2 block: the same factors as two :func:`eliminate_axis` steps (a,
    then b), rearranged so that their two divisions are independent.

    H = P^T Mhat P + diag(armature[ja], armature[jb]) = [[ia, cab], [cab, ib]] and Psi_a, Psi_b are
    taken from Mhat before either elimination; axis b's after axis a's are then Psi_b' = Psi_b -
    Psi_a cab / ia and D_b = det H / ia, so 1 / ia and ia / det H run side by side.
    Returns (M, nf, (D_a, phihat_a, phitil_a, Psihat_a), (D_b, phihat_b, phitil_b, Psihat_b))."""
    n0, n1, n2, f0, f1, f2 = nf
    # Psi_a = Mhat P_a, Psi_b = Mhat P_b (P = [e; 0]), both from the same Mhat
    u0, u1, u2, u3, u4, u5, ia = column_mass(REVOLUTE, a0, a1, a2, M)
    w0, w1, w2, w3, w4, w5, ib = column_mass(REVOLUTE, b0, b1, b2, M)
    # the block H and its determinant
    ia = joint_inertia(ia, armature, ja)
    ib = joint_inertia(ib, armature, jb)
    cab = (b0 * u0 + b1 * u1) + b2 * u2
    det = ia * ib - cab * cab
    inva = 1.0 / ia
    invb = ia / det  # 1 / D_b (below), in parallel with 1 / ia
    # axis a as Table A.1: D_a = ia, Psihat_a = Psi_a / ia
    pa = tau_a - (a0 * n0 + a1 * n1 + a2 * n2)
    ptil = pa * inva
    sa = (u0 * inva, u1 * inva, u2 * inva, u3 * inva, u4 * inva, u5 * inva)
    # axis b on Mhat - Psi_a Psi_a^T / ia: Psi_b' = Psi_b - Psi_a cab / ia, whose
    # D_b = ib - cab^2 / ia = det / ia (its inverse ia / det)
    r = cab * inva
    ib1 = det * inva
    v0, v1, v2 = w0 - u0 * r, w1 - u1 * r, w2 - u2 * r
    v3, v4, v5 = w3 - u3 * r, w4 - u4 * r, w5 - u5 * r
    pb = tau_b - ((b0 * n0 + b1 * n1 + b2 * n2) + cab * ptil)
    ptilb = pb * invb
    sb = (v0 * invb, v1 * invb, v2 * invb, v3 * invb, v4 * invb, v5 * invb)
    # p <- p + Psi_a phitil_a + Psi_b' phitil_b
    nf = (n0 + (u0 * ptil + v0 * ptilb), n1 + (u1 * ptil + v1 * ptilb),
          n2 + (u2 * ptil + v2 * ptilb), f0 + (u3 * ptil + v3 * ptilb),
          f1 + (u4 * ptil + v4 * ptilb), f2 + (u5 * ptil + v5 * ptilb))
    # Mhat <- (Mhat - Psihat_a Psi_a^T) - Psihat_b Psi_b'^T (upper triangles only)
    M = downdate(downdate(M, sa, (u0, u1, u2, u3, u4, u5)), sb, (v0, v1, v2, v3, v4, v5))
    return M, nf, (ia, pa, ptil, sa), (ib1, pb, ptilb, sb)


@inline
def articulated_bias(c, M):
    """Mbar c, the increment of an articulated body's bias p = [n; f], with c = (ca; cb) the
    body's local twist-rate (6-tuple) and Mbar = [[X, Y], [Y^T, Z]] (21 numbers): 6 numbers."""
    ca0, ca1, ca2, cb0, cb1, cb2 = c
    (x00, x01, x02, x11, x12, x22, y00, y01, y02, y10, y11, y12, y20, y21, y22,
     z00, z01, z02, z11, z12, z22) = M
    return ((x00 * ca0 + x01 * ca1 + x02 * ca2) + (y00 * cb0 + y01 * cb1 + y02 * cb2),
            (x01 * ca0 + x11 * ca1 + x12 * ca2) + (y10 * cb0 + y11 * cb1 + y12 * cb2),
            (x02 * ca0 + x12 * ca1 + x22 * ca2) + (y20 * cb0 + y21 * cb1 + y22 * cb2),
            (y00 * ca0 + y10 * ca1 + y20 * ca2) + (z00 * cb0 + z01 * cb1 + z02 * cb2),
            (y01 * ca0 + y11 * ca1 + y21 * ca2) + (z01 * cb0 + z11 * cb1 + z12 * cb2),
            (y02 * ca0 + y12 * ca1 + y22 * ca2) + (z02 * cb0 + z12 * cb1 + z22 * cb2))


@inline
def shift_bias(s0, s1, s2, nf):
    """A wrench moved to the parent's origin, a = (s0, s1, s2) = O_p - O_k: n <- n - a x f."""
    n0, n1, n2, f0, f1, f2 = nf
    return (n0 - (s1 * f2 - s2 * f1), n1 - (s2 * f0 - s0 * f2), n2 - (s0 * f1 - s1 * f0),
            f0, f1, f2)


@inline
def shift_to_parent(s0, s1, s2, M):
    """An articulated mass handed on to its parent's origin, a = (s0, s1, s2) = O_p - O_k
    (A_{k,p}): Mbar <- A^T Mbar A, which leaves Z as it is. Returns the 21 numbers."""
    (x00, x01, x02, x11, x12, x22, y00, y01, y02, y10, y11, y12, y20, y21, y22,
     z00, z01, z02, z11, z12, z22) = M
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
            y20 - q20, y21 - q21, y22 - q22, z00, z01, z02, z11, z12, z22)
