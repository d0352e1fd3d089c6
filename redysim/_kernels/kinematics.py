"""Kinematics: link rotations and positions, motion subspaces, twists and twist-rates.

One forward pass (k = 1..nl) shared by inverse dynamics, RGE-A forward dynamics, the GIM, the
energy and the tip. Twist propagation, Eq. (4):
    t_k = A_{k,k-1} t_{k-1} + P_k qd_k,
and its time derivative
    td_k = A_{k,k-1} td_{k-1} + [0; w_{k-1} x (v_k - v_{k-1})] + P_k qdd_k + Pd_k qd_k,
with Pd's column j = w_j x p_j, w_j the angular velocity of the frame axis j is fixed in. The base's
twist-rate is ``base_accel`` ([0; -g] for dynamics, 0 for true accelerations): gravity enters as an
acceleration of the base (paper, Appendix A.1).

References:
    Agarwal et al., Eq. (4)-(8) (DeNOC: t = N_l N_d qd); Table A.1's note on gravity.
"""

from __future__ import annotations

from .._jit import jit
from .joints import jcalc


@jit
def kinematics(length, dof_kind, dof_axis, dof_u, joint_qoff, q, qd, qdd, base_accel,
               oR, oO, oP, t, td):
    """Fill oR (nl,3,3), oO (nl,3), oP (n,6), t (nl,6), td (nl,6) for the state (q, qd, qdd).

    base_accel: (3,) linear acceleration of the fixed base (pass -gravity for dynamics).
    """
    nl = length.shape[0]
    # forward: k = 1..nl
    for k in range(nl):
        R = oR[k]
        O = oO[k]
        if k == 0:
            for i in range(3):
                for j in range(3):
                    R[i, j] = 1.0 if i == j else 0.0
                O[i] = 0.0
            wp0 = wp1 = wp2 = 0.0
            vp0 = vp1 = vp2 = 0.0
            ap0 = ap1 = ap2 = 0.0
            bp0, bp1, bp2 = base_accel[0], base_accel[1], base_accel[2]
            Op0 = Op1 = Op2 = 0.0
        else:
            Rp = oR[k - 1]
            lp = length[k - 1]
            for i in range(3):
                for j in range(3):
                    R[i, j] = Rp[i, j]
            Op0 = oO[k - 1, 0]
            Op1 = oO[k - 1, 1]
            Op2 = oO[k - 1, 2]
            O[0] = Op0 + lp * Rp[0, 0]
            O[1] = Op1 + lp * Rp[1, 0]
            O[2] = Op2 + lp * Rp[2, 0]
            wp0, wp1, wp2 = t[k - 1, 0], t[k - 1, 1], t[k - 1, 2]
            vp0, vp1, vp2 = t[k - 1, 3], t[k - 1, 4], t[k - 1, 5]
            ap0, ap1, ap2 = td[k - 1, 0], td[k - 1, 1], td[k - 1, 2]
            bp0, bp1, bp2 = td[k - 1, 3], td[k - 1, 4], td[k - 1, 5]
        # joint k: its axes' columns, the frame's rotation (and the joint origin, if prismatic);
        # accumulate P qd (twist) and P qdd + Pd qd (twist-rate)
        dw0 = dw1 = dw2 = dv0 = dv1 = dv2 = 0.0
        da0 = da1 = da2 = db0 = db1 = db2 = 0.0
        om0, om1, om2 = wp0, wp1, wp2  # angular velocity of the frame the next axis is fixed in
        for j in range(joint_qoff[k], joint_qoff[k + 1]):
            p = oP[j]
            jcalc(dof_kind[j], dof_axis[j], dof_u[j], q[j], R, O, p)
            qdj = qd[j]
            qddj = qdd[j]
            # Pd column = om x p (both halves rotate with the frame the axis is fixed in)
            pd0 = om1 * p[2] - om2 * p[1]
            pd1 = om2 * p[0] - om0 * p[2]
            pd2 = om0 * p[1] - om1 * p[0]
            pd3 = om1 * p[5] - om2 * p[4]
            pd4 = om2 * p[3] - om0 * p[5]
            pd5 = om0 * p[4] - om1 * p[3]
            dw0 += p[0] * qdj
            dw1 += p[1] * qdj
            dw2 += p[2] * qdj
            dv0 += p[3] * qdj
            dv1 += p[4] * qdj
            dv2 += p[5] * qdj
            da0 += p[0] * qddj + pd0 * qdj
            da1 += p[1] * qddj + pd1 * qdj
            da2 += p[2] * qddj + pd2 * qdj
            db0 += p[3] * qddj + pd3 * qdj
            db1 += p[4] * qddj + pd4 * qdj
            db2 += p[5] * qddj + pd5 * qdj
            om0 += p[0] * qdj
            om1 += p[1] * qdj
            om2 += p[2] * qdj
        # r = O_k - O_{k-1} = -a_{k,k-1}
        r0 = O[0] - Op0
        r1 = O[1] - Op1
        r2 = O[2] - Op2
        # t_k = A t_{k-1} + P qd: v_k = v_{k-1} + w_{k-1} x r + (prismatic part)
        v0 = vp0 + (wp1 * r2 - wp2 * r1) + dv0
        v1 = vp1 + (wp2 * r0 - wp0 * r2) + dv1
        v2 = vp2 + (wp0 * r1 - wp1 * r0) + dv2
        t[k, 0] = wp0 + dw0
        t[k, 1] = wp1 + dw1
        t[k, 2] = wp2 + dw2
        t[k, 3] = v0
        t[k, 4] = v1
        t[k, 5] = v2
        # td_k = A td_{k-1} + [0; w_{k-1} x (v_k - v_{k-1})] + P qdd + Pd qd
        e0 = v0 - vp0
        e1 = v1 - vp1
        e2 = v2 - vp2
        td[k, 0] = ap0 + da0
        td[k, 1] = ap1 + da1
        td[k, 2] = ap2 + da2
        td[k, 3] = bp0 + (ap1 * r2 - ap2 * r1) + (wp1 * e2 - wp2 * e1) + db0
        td[k, 4] = bp1 + (ap2 * r0 - ap0 * r2) + (wp2 * e0 - wp0 * e2) + db1
        td[k, 5] = bp2 + (ap0 * r1 - ap1 * r0) + (wp0 * e1 - wp1 * e0) + db2
