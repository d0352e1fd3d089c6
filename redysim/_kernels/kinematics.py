"""Kinematics: link rotations and positions, motion subspaces, twists and twist-rates.

One forward pass (k = 1..nl) shared by inverse dynamics, RGE-A forward dynamics, the GIM, the
energy and the tip. Twist propagation, Eq. (4):
    t_k = A_{k,k-1} t_{k-1} + P_k qd_k,
and its time derivative
    td_k = A_{k,k-1} td_{k-1} + [0; w_{k-1} x (v_k - v_{k-1})] + P_k qdd_k + Pd_k qd_k,
with Pd's column j = w_j x p_j, w_j the angular velocity of the frame axis j is fixed in. The base's
twist-rate is ``base_accel`` ([0; -g] for dynamics, 0 for true accelerations): gravity enters as an
acceleration of the base (paper, Appendix A.1).

With ``local_rates`` the pass writes, instead of td_k, its local part
    td_k - A_{k,k-1} td_{k-1} = [0; w_{k-1} x (v_k - v_{k-1})] + P_k qdd_k + Pd_k qd_k
(with qdd = 0: the velocity-product twist-rate c_k of the articulated-body algorithm), so that
neither the base's twist-rate nor anything inboard of joint k is in it; and of t_k only the
angular velocity w_k, all that RGE-A's passes read (docs/design.md, "Performance notes").

The running frame, twist and twist-rate stay in scalars and are written out once per link.

References:
    Agarwal et al., Eq. (4)-(8) (DeNOC: t = N_l N_d qd); Table A.1's note on gravity.
"""

from __future__ import annotations

from .._jit import jit
from .joints import axis_rates, jcalc


@jit
def kinematics(length, dof_kind, dof_axis, dof_u, joint_qoff, q, qd, qdd, base_accel,
               oR, oO, oP, t, td, local_rates=False):
    """Fill oR (nl,3,3), oO (nl,3), oP (n,6), t (nl,6), td (nl,6) for the state (q, qd, qdd).

    base_accel: (3,) linear acceleration of the fixed base (pass -gravity for dynamics).
    local_rates: write each link's local twist-rate term in td (module docstring), not td_k,
        and leave t's linear part (t[:, 3:]) unset.
    """
    r00 = r11 = r22 = 1.0
    r01 = r02 = r10 = r12 = r20 = r21 = 0.0
    O0 = O1 = O2 = 0.0
    w0 = w1 = w2 = v0 = v1 = v2 = 0.0  # twist of link k-1
    a0 = a1 = a2 = 0.0  # angular twist-rate of link k-1
    b0, b1, b2 = base_accel[0], base_accel[1], base_accel[2]  # linear twist-rate of link k-1
    lp = 0.0
    # forward: k = 1..nl
    for k in range(length.shape[0]):
        # s = O_k - O_{k-1} = -a_{k,k-1}: l_{k-1} x_{k-1}, and the slide of any prismatic axis
        s0, s1, s2 = lp * r00, lp * r10, lp * r20
        # joint k: columns, frame update; accumulate P qd and P qdd + Pd qd
        dv0 = dv1 = dv2 = 0.0
        da0 = da1 = da2 = db0 = db1 = db2 = 0.0
        # the angular velocity of the frame the next axis is fixed in; w_k after the last axis
        om0, om1, om2 = w0, w1, w2
        for j in range(joint_qoff[k], joint_qoff[k + 1]):
            (p0, p1, p2, p3, p4, p5, s0, s1, s2,
             r00, r01, r02, r10, r11, r12, r20, r21, r22) = jcalc(
                dof_kind[j], dof_axis[j], dof_u[j], q[j], s0, s1, s2,
                r00, r01, r02, r10, r11, r12, r20, r21, r22)
            oP[j, 0] = p0
            oP[j, 1] = p1
            oP[j, 2] = p2
            oP[j, 3] = p3
            oP[j, 4] = p4
            oP[j, 5] = p5
            # P qd into the twist, P qdd + Pd qd into the local twist-rate (Pd = om x P)
            (om0, om1, om2, dv0, dv1, dv2, da0, da1, da2, db0, db1, db2) = axis_rates(
                dof_kind[j], p0, p1, p2, p3, p4, p5, qd[j], qdd[j], om0, om1, om2,
                dv0, dv1, dv2, da0, da1, da2, db0, db1, db2)
        O0 += s0
        O1 += s1
        O2 += s2
        # e = v_k - v_{k-1} = w_{k-1} x s + the prismatic part
        e0 = (w1 * s2 - w2 * s1) + dv0
        e1 = (w2 * s0 - w0 * s2) + dv1
        e2 = (w0 * s1 - w1 * s0) + dv2
        # the local twist-rate: [0; w_{k-1} x (v_k - v_{k-1})] + P qdd + Pd qd
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
        else:  # t_k = A t_{k-1} + P qd;  td_k = A td_{k-1} + the local twist-rate
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
        lp = length[k]
