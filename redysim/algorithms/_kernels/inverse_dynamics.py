"""Recursive inverse dynamics (Newton-Euler with the DeNOC matrices) and phi.

Backward pass k = nb..1 (children first) over the kinematics pass's twists and twist-rates:
    body wrench about O_k:  w_k = M_k td_k + W_k M_k t_k  (Newton-Euler),
        f = m vd + wd x (m d) + w x (w x m d),   n = I_O wd + w x (I_O w) + (m d) x vd,
    resultant:             W_k = w_k + sum over the children c of A_{c,k}^T W_c,
    joint torques:         tau_j = P_j^T W_k + armature_j qdd_j (the joint's own inertia).
With qdd = 0 and the base's twist-rate [0; -g] the same pass gives C qd + gravity terms, so
phi = tau - (C qd + gravity terms) (Eq. 12).

References:
    Agarwal et al., Eq. (9)-(12); Appendix A.1 (gravity as a base acceleration).
    Saha, J. Appl. Mech. 66 (1999), the DeNOC inverse dynamics.
"""

from __future__ import annotations

from redysim._jit import jit_borrowed

from .joints import joint_force


@jit_borrowed
def rnea_backward(tree, s, qdd, tau):
    """tau = P^T W + armature qdd from the kinematics pass run with ``qdd`` (the armature's
    part: :func:`.joints.joint_force`); s.W (nb, 6) receives the resultant wrenches about O_k.
    A child that does not follow its parent (k + 1) adds its wrench, moved to the parent's O,
    to the parent's row of s.gather_wrench."""
    mass, inertia_O, mass_com, joint_voff, armature = (tree.mass, tree.inertia_O, tree.mass_com,
                                                       tree.joint_voff, tree.armature)
    serial, parent, gather = tree.serial, tree.parent, tree.gather
    oR, oO, oP, t, td, W, gw = s.oR, s.oO, s.oP, s.t, s.td, s.W, s.gather_wrench
    for g in range(gw.shape[0]):
        gw[g, :] = 0.0
    nl = mass.shape[0]
    # backward: k = nb..1, children first
    for k in range(nl - 1, -1, -1):
        R = oR[k]
        IO = inertia_O[k]
        mc = mass_com[k]
        m = mass[k]
        # m d and I_O in the world frame
        md0 = R[0, 0] * mc[0] + R[0, 1] * mc[1] + R[0, 2] * mc[2]
        md1 = R[1, 0] * mc[0] + R[1, 1] * mc[1] + R[1, 2] * mc[2]
        md2 = R[2, 0] * mc[0] + R[2, 1] * mc[1] + R[2, 2] * mc[2]
        w0, w1, w2 = t[k, 0], t[k, 1], t[k, 2]
        a0, a1, a2 = td[k, 0], td[k, 1], td[k, 2]
        b0, b1, b2 = td[k, 3], td[k, 4], td[k, 5]
        # I_O applied in the link frame: x_local = R^T x, y = R (I_O x_local)
        wl0 = R[0, 0] * w0 + R[1, 0] * w1 + R[2, 0] * w2
        wl1 = R[0, 1] * w0 + R[1, 1] * w1 + R[2, 1] * w2
        wl2 = R[0, 2] * w0 + R[1, 2] * w1 + R[2, 2] * w2
        al0 = R[0, 0] * a0 + R[1, 0] * a1 + R[2, 0] * a2
        al1 = R[0, 1] * a0 + R[1, 1] * a1 + R[2, 1] * a2
        al2 = R[0, 2] * a0 + R[1, 2] * a1 + R[2, 2] * a2
        hl0 = IO[0, 0] * wl0 + IO[0, 1] * wl1 + IO[0, 2] * wl2
        hl1 = IO[1, 0] * wl0 + IO[1, 1] * wl1 + IO[1, 2] * wl2
        hl2 = IO[2, 0] * wl0 + IO[2, 1] * wl1 + IO[2, 2] * wl2
        gl0 = IO[0, 0] * al0 + IO[0, 1] * al1 + IO[0, 2] * al2
        gl1 = IO[1, 0] * al0 + IO[1, 1] * al1 + IO[1, 2] * al2
        gl2 = IO[2, 0] * al0 + IO[2, 1] * al1 + IO[2, 2] * al2
        h0 = R[0, 0] * hl0 + R[0, 1] * hl1 + R[0, 2] * hl2
        h1 = R[1, 0] * hl0 + R[1, 1] * hl1 + R[1, 2] * hl2
        h2 = R[2, 0] * hl0 + R[2, 1] * hl1 + R[2, 2] * hl2
        g0 = R[0, 0] * gl0 + R[0, 1] * gl1 + R[0, 2] * gl2
        g1 = R[1, 0] * gl0 + R[1, 1] * gl1 + R[1, 2] * gl2
        g2 = R[2, 0] * gl0 + R[2, 1] * gl1 + R[2, 2] * gl2
        # w x (m d) and w x (w x m d)
        c0 = w1 * md2 - w2 * md1
        c1 = w2 * md0 - w0 * md2
        c2 = w0 * md1 - w1 * md0
        f0 = m * b0 + (a1 * md2 - a2 * md1) + (w1 * c2 - w2 * c1)
        f1 = m * b1 + (a2 * md0 - a0 * md2) + (w2 * c0 - w0 * c2)
        f2 = m * b2 + (a0 * md1 - a1 * md0) + (w0 * c1 - w1 * c0)
        n0 = g0 + (w1 * h2 - w2 * h1) + (md1 * b2 - md2 * b1)
        n1 = g1 + (w2 * h0 - w0 * h2) + (md2 * b0 - md0 * b2)
        n2 = g2 + (w0 * h1 - w1 * h0) + (md0 * b1 - md1 * b0)
        if serial == 0 and gather[k] >= 0:  # the children that do not follow
            g = gather[k]
            n0 += gw[g, 0]
            n1 += gw[g, 1]
            n2 += gw[g, 2]
            f0 += gw[g, 3]
            f1 += gw[g, 4]
            f2 += gw[g, 5]
        # W_k = w_k + A_{k+1,k}^T W_{k+1}: move W_{k+1}'s moment from O_{k+1} to O_k
        if k < nl - 1 and (serial != 0 or parent[k + 1] == k):
            r0 = oO[k + 1, 0] - oO[k, 0]
            r1 = oO[k + 1, 1] - oO[k, 1]
            r2 = oO[k + 1, 2] - oO[k, 2]
            F0, F1, F2 = W[k + 1, 3], W[k + 1, 4], W[k + 1, 5]
            n0 += W[k + 1, 0] + (r1 * F2 - r2 * F1)
            n1 += W[k + 1, 1] + (r2 * F0 - r0 * F2)
            n2 += W[k + 1, 2] + (r0 * F1 - r1 * F0)
            f0 += F0
            f1 += F1
            f2 += F2
        W[k, 0] = n0
        W[k, 1] = n1
        W[k, 2] = n2
        W[k, 3] = f0
        W[k, 4] = f1
        W[k, 5] = f2
        p = k - 1 if serial != 0 else parent[k]
        if p >= 0 and serial == 0 and parent[k] != k - 1:  # into the parent's gather row, at O_p
            g = gather[p]
            r0 = oO[k, 0] - oO[p, 0]
            r1 = oO[k, 1] - oO[p, 1]
            r2 = oO[k, 2] - oO[p, 2]
            gw[g, 0] += n0 + (r1 * f2 - r2 * f1)
            gw[g, 1] += n1 + (r2 * f0 - r0 * f2)
            gw[g, 2] += n2 + (r0 * f1 - r1 * f0)
            gw[g, 3] += f0
            gw[g, 4] += f1
            gw[g, 5] += f2
        # tau_j = P_j^T W_k
        for j in range(joint_voff[k], joint_voff[k + 1]):
            p = oP[j]
            tau[j] = (p[0] * n0 + p[1] * n1 + p[2] * n2 + p[3] * f0 + p[4] * f1 + p[5] * f2)
    if armature.shape[0] != 0:  # + armature_j qdd_j (a pass of its own: none without armature)
        for j in range(tau.shape[0]):
            tau[j] = joint_force(tau[j], armature, j, qdd[j])
