"""The generalized momentum p = I(q) qd and the Lagrangian's gradient dL/dq, O(n), for the
implicit midpoint rule on (q, p) (:mod:`redysim.integrators.implicit`).

With the twists t_k of a kinematics pass, body k's momentum about O_k is M_k t_k (angular I_O w +
m d x v, linear m v + w x m d), and the momenta of the bodies at and beyond joint k, moved to O_k,
H_k = M_k t_k + sum over the children c of A_{c,k}^T H_c, is the inverse-dynamics pass's resultant
with t := 0 and td := t (its body wrench M_k td_k + W_k M_k t_k is then M_k t_k). So
p_j = P_j^T H_k (:func:`redysim.algorithms._kernels.inverse_dynamics.rnea_backward` does it).

Turning axis j of joint k by dq_j moves the bodies beyond it rigidly about P_j: their twists change
by P_j x (t_k - t_j^-), t_j^- = t_k - sum_{b >= j} P_b qd_b the twist of the frame axis j is fixed
in, and their inertias turn with them. Their kinetic energy then changes by

    dT/dq_j = (t_j^- x P_j) . H_k

(the two terms' parts in t_k cancel: a rigid turn of a moving body leaves t^T M t as it is but for
the relative motion's part), x the motion cross product [w; v] x [e; f] = [w x e; w x f + v x e],
the pairing of a motion [a; b] with a wrench [n; f] about the same point a . n + b . f. The
gravity terms dV/dq_j are the inverse-dynamics pass's with t := 0 and td := [0; -g].

References:
    R. Featherstone, "Rigid Body Dynamics Algorithms" (2008), 2.9 and 9.6 (the cross products and
    momentum of rigid bodies). A. De Luca, R. Mattone, "Sensorless robot collision detection and
    hybrid force/motion control" (ICRA 2005): p_dot = tau + C^T qd - g, the same quantity.
"""

from __future__ import annotations

from redysim._jit import jit_borrowed


@jit_borrowed
def momentum_gradient(tree, s, qd, H, out):
    """out[j] = dT/dq_j = (t_j^- x P_j) . H_k for every axis j of every body k, from the
    kinematics pass (s.t: full twists, s.oP) and the momenta H (nb, 6) about each O_k."""
    joint_voff, t, oP = tree.joint_voff, s.t, s.oP
    for k in range(t.shape[0]):
        w0, w1, w2 = t[k, 0], t[k, 1], t[k, 2]
        v0, v1, v2 = t[k, 3], t[k, 4], t[k, 5]
        n0, n1, n2 = H[k, 0], H[k, 1], H[k, 2]
        f0, f1, f2 = H[k, 3], H[k, 4], H[k, 5]
        for j in range(joint_voff[k + 1] - 1, joint_voff[k] - 1, -1):  # the last axis first
            p = oP[j]
            x = qd[j]
            e0, e1, e2, g0, g1, g2 = p[0], p[1], p[2], p[3], p[4], p[5]
            w0 -= e0 * x
            w1 -= e1 * x
            w2 -= e2 * x
            v0 -= g0 * x
            v1 -= g1 * x
            v2 -= g2 * x
            # [w; v] x [e; g] = [w x e; w x g + v x e], paired with [n; f]
            out[j] = (n0 * (w1 * e2 - w2 * e1) + n1 * (w2 * e0 - w0 * e2)
                      + n2 * (w0 * e1 - w1 * e0)
                      + f0 * (w1 * g2 - w2 * g1 + v1 * e2 - v2 * e1)
                      + f1 * (w2 * g0 - w0 * g2 + v2 * e0 - v0 * e2)
                      + f2 * (w0 * g1 - w1 * g0 + v0 * e1 - v1 * e0))
