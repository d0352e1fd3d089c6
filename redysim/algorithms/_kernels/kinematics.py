"""Kinematics: body rotations and positions, motion subspaces, twists and twist-rates.

One forward pass (parents before children) shared by inverse dynamics, RGE-A forward dynamics,
the GIM, the energy and the frames. Twist propagation, Eq. (4), from body k's parent p:
    t_k = A_{k,p} t_p + P_k qd_k,
and its time derivative
    td_k = A_{k,p} td_p + [0; w_p x (v_k - v_p)] + P_k qdd_k + Pd_k qd_k,
with Pd's column j = w_j x p_j, w_j the angular velocity of the frame axis j is fixed in. The base's
twist-rate is ``base_accel`` ([0; -g] for dynamics, 0 for true accelerations): gravity enters as an
acceleration of the base (paper, Appendix A.1).

With ``local_rates`` the pass writes, instead of td_k, its local part
    td_k - A_{k,p} td_p = [0; w_p x (v_k - v_p)] + P_k qdd_k + Pd_k qd_k
(with qdd = 0: the velocity-product twist-rate c_k of the articulated-body algorithm), so that
neither the base's twist-rate nor anything inboard of joint k is in it; and of t_k only the
angular velocity w_k, all that RGE-A's passes read (docs/design.md, "Performance notes").

The running frame, twist and twist-rate stay in scalars and are written out once per body; a body
that does not hang from the one before it reads its parent's back from the arrays.

References:
    Agarwal et al., Eq. (4)-(8) (DeNOC: t = N_l N_d qd); Table A.1's note on gravity.
"""

from __future__ import annotations

from redysim._jit import inline, jit_borrowed

from .bundles import ALONG_X
from .joints import BALL, axis_rates, jcalc, turned


@jit_borrowed
def kinematics(tree, q, qd, qdd, base_accel, s, local_rates=False):
    """Fill s.oR (nb,3,3), s.oO (nb,3), s.oP (n,6), s.t (nb,6), s.td (nb,6) for (q, qd, qdd).

    base_accel: (3,) linear acceleration of the fixed base (pass -gravity for dynamics).
    local_rates: write each body's local twist-rate term in td (module docstring), not td_k,
        and leave t's linear part (t[:, 3:]) unset.

    Compiled twice from one source (:func:`_kinematics`): for a serial chain, whose tree tables
    it never reads, and for any tree; the chain's copy has none of the tree's branches.
    """
    if tree.serial != 0:
        _kinematics(tree, q, qd, qdd, base_accel, s, local_rates, True)
    else:
        _kinematics(tree, q, qd, qdd, base_accel, s, local_rates, False)


@inline
def _kinematics(tree, q, qd, qdd, base_accel, s, local_rates, serial):
    """:func:`kinematics`, ``serial`` a constant."""
    oR, oO, oP, t, td = s.oR, s.oO, s.oP, s.t, s.td
    joint_voff, dof_kind, dof_axis, dof_u = tree.joint_voff, tree.dof_kind, tree.dof_axis, \
        tree.dof_u
    parent, along = tree.parent, tree.along
    placement_code, placement_R, placement_p, qshift = (tree.placement_code, tree.placement_R,
                                                        tree.placement_p, tree.qshift)
    r00 = r11 = r22 = 1.0
    r01 = r02 = r10 = r12 = r20 = r21 = 0.0
    O0 = O1 = O2 = 0.0
    w0 = w1 = w2 = v0 = v1 = v2 = 0.0  # twist of the parent
    a0 = a1 = a2 = 0.0  # angular twist-rate of the parent
    b0, b1, b2 = base_accel[0], base_accel[1], base_accel[2]  # linear twist-rate of the parent
    qs = 0  # joint k's first configuration index minus its first velocity index
    # forward: k = 1..nb, parents first
    for k in range(along.shape[0]):
        if not serial and parent[k] != k - 1:  # the parent's frame and motion: arrays or base
            p = parent[k]
            if p < 0:
                r00 = r11 = r22 = 1.0
                r01 = r02 = r10 = r12 = r20 = r21 = 0.0
                O0 = O1 = O2 = 0.0
                w0 = w1 = w2 = v0 = v1 = v2 = a0 = a1 = a2 = 0.0
                b0, b1, b2 = base_accel[0], base_accel[1], base_accel[2]
            else:
                R = oR[p]
                r00, r01, r02 = R[0, 0], R[0, 1], R[0, 2]
                r10, r11, r12 = R[1, 0], R[1, 1], R[1, 2]
                r20, r21, r22 = R[2, 0], R[2, 1], R[2, 2]
                O0, O1, O2 = oO[p, 0], oO[p, 1], oO[p, 2]
                w0, w1, w2 = t[p, 0], t[p, 1], t[p, 2]
                if not local_rates:
                    v0, v1, v2 = t[p, 3], t[p, 4], t[p, 5]
                    a0, a1, a2 = td[p, 0], td[p, 1], td[p, 2]
                    b0, b1, b2 = td[p, 3], td[p, 4], td[p, 5]
        # s = O_k - O_p: the placement in the parent's frame, then the slide of any prismatic axis
        if serial or placement_code[k] == ALONG_X:
            lp = along[k]
            s0, s1, s2 = lp * r00, lp * r10, lp * r20
        else:  # R_p times the placement: s = R_p p, frame R_p R_pl
            pp = placement_p[k]
            s0 = r00 * pp[0] + r01 * pp[1] + r02 * pp[2]
            s1 = r10 * pp[0] + r11 * pp[1] + r12 * pp[2]
            s2 = r20 * pp[0] + r21 * pp[1] + r22 * pp[2]
            G = placement_R[k]
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = turned(
                (r00, r01, r02, r10, r11, r12, r20, r21, r22),
                (G[0, 0], G[0, 1], G[0, 2], G[1, 0], G[1, 1], G[1, 2], G[2, 0], G[2, 1], G[2, 2]))
        if not serial:
            qs = qshift[k]
        # joint k: columns, frame update; accumulate P qd and P qdd + Pd qd
        dv0 = dv1 = dv2 = 0.0
        da0 = da1 = da2 = db0 = db1 = db2 = 0.0
        bw0 = bw1 = bw2 = 0.0  # a ball's P qd, gathered (axis_rates)
        # the angular velocity of the frame the next axis is fixed in; w_k after the last axis
        om0, om1, om2 = w0, w1, w2
        q1 = q2 = q3 = 0.0
        for j in range(joint_voff[k], joint_voff[k + 1]):
            if not serial and dof_kind[j] == BALL and dof_axis[j] == 0:  # its quaternion
                q1, q2, q3 = q[j + qs + 1], q[j + qs + 2], q[j + qs + 3]
            p0, p1, p2, p3, p4, p5, s0, s1, s2, frame = jcalc(
                dof_kind[j], dof_axis[j], dof_u[j], q[j + qs], q1, q2, q3, s0, s1, s2,
                (r00, r01, r02, r10, r11, r12, r20, r21, r22))
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = frame
            oP[j, 0] = p0
            oP[j, 1] = p1
            oP[j, 2] = p2
            oP[j, 3] = p3
            oP[j, 4] = p4
            oP[j, 5] = p5
            # P qd into the twist, P qdd + Pd qd into the local twist-rate (Pd = om x P)
            (om0, om1, om2, dv0, dv1, dv2, da0, da1, da2, db0, db1, db2, bw0, bw1, bw2) = \
                axis_rates(dof_kind[j], dof_axis[j], p0, p1, p2, p3, p4, p5, qd[j], qdd[j], True,
                           om0, om1, om2, dv0, dv1, dv2, da0, da1, da2, db0, db1, db2,
                           bw0, bw1, bw2)
        O0 += s0
        O1 += s1
        O2 += s2
        # e = v_k - v_p = w_p x s + the prismatic part
        e0 = (w1 * s2 - w2 * s1) + dv0
        e1 = (w2 * s0 - w0 * s2) + dv1
        e2 = (w0 * s1 - w1 * s0) + dv2
        # the local twist-rate: [0; w_p x (v_k - v_p)] + P qdd + Pd qd
        cb0 = (w1 * e2 - w2 * e1) + db0
        cb1 = (w2 * e0 - w0 * e2) + db1
        cb2 = (w0 * e1 - w1 * e0) + db2
        w0, w1, w2 = om0, om1, om2
        R = oR[k]
        R[0, 0] = r00
        R[0, 1] = r01
        R[0, 2] = r02
        R[1, 0] = r10
        R[1, 1] = r11
        R[1, 2] = r12
        R[2, 0] = r20
        R[2, 1] = r21
        R[2, 2] = r22
        oO[k, 0] = O0
        oO[k, 1] = O1
        oO[k, 2] = O2
        t[k, 0] = w0
        t[k, 1] = w1
        t[k, 2] = w2
        if local_rates:  # RGE-A's passes need w_k and c_k only: t_k's linear part left unset
            td[k, 0] = da0
            td[k, 1] = da1
            td[k, 2] = da2
            td[k, 3] = cb0
            td[k, 4] = cb1
            td[k, 5] = cb2
        else:  # t_k = A t_p + P qd;  td_k = A td_p + the local twist-rate
            v0 += e0
            v1 += e1
            v2 += e2
            t[k, 3] = v0
            t[k, 4] = v1
            t[k, 5] = v2
            b0 += (a1 * s2 - a2 * s1) + cb0
            b1 += (a2 * s0 - a0 * s2) + cb1
            b2 += (a0 * s1 - a1 * s0) + cb2
            a0 += da0
            a1 += da1
            a2 += da2
            td[k, 0] = a0
            td[k, 1] = a1
            td[k, 2] = a2
            td[k, 3] = b0
            td[k, 4] = b1
            td[k, 5] = b2
