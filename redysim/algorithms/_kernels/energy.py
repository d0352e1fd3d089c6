"""Kinetic and potential energy of the chain, for the energy-drift check of Eq. (11).

    T = 1/2 sum_k t_k^T M_k t_k + 1/2 sum_j armature_j v_j^2 = 1/2 v^T I(q) v,
    t_k^T M_k t_k = w . I_O w + 2 w . (m d x v) + m v . v
    V = - sum_k m_k g . (O_k + d_k)
delta_M(t) = (E(t) - E(0)) / M with E = T + V and M the total mass.

References:
    Agarwal et al., Eq. (11) and section 3 (energy checks).
"""

from __future__ import annotations

from redysim._jit import jit_borrowed

from .joints import joint_force


@jit_borrowed
def energy(tree, gravity, s, qd):
    """(T, V) from the kinematics pass (s.oR, s.oO, s.t) at the rates qd (the joints' own
    inertia's part, :func:`.joints.joint_force`)."""
    mass, inertia_O, mass_com, oR, oO, t = tree.mass, tree.inertia_O, tree.mass_com, s.oR, \
        s.oO, s.t
    nl = mass.shape[0]
    T = 0.0
    V = 0.0
    for k in range(nl):
        R = oR[k]
        IO = inertia_O[k]
        mc = mass_com[k]
        m = mass[k]
        md0 = R[0, 0] * mc[0] + R[0, 1] * mc[1] + R[0, 2] * mc[2]
        md1 = R[1, 0] * mc[0] + R[1, 1] * mc[1] + R[1, 2] * mc[2]
        md2 = R[2, 0] * mc[0] + R[2, 1] * mc[1] + R[2, 2] * mc[2]
        w0, w1, w2 = t[k, 0], t[k, 1], t[k, 2]
        v0, v1, v2 = t[k, 3], t[k, 4], t[k, 5]
        # w in the link frame, then w . I_O w
        wl0 = R[0, 0] * w0 + R[1, 0] * w1 + R[2, 0] * w2
        wl1 = R[0, 1] * w0 + R[1, 1] * w1 + R[2, 1] * w2
        wl2 = R[0, 2] * w0 + R[1, 2] * w1 + R[2, 2] * w2
        rot = (wl0 * (IO[0, 0] * wl0 + IO[0, 1] * wl1 + IO[0, 2] * wl2)
               + wl1 * (IO[1, 0] * wl0 + IO[1, 1] * wl1 + IO[1, 2] * wl2)
               + wl2 * (IO[2, 0] * wl0 + IO[2, 1] * wl1 + IO[2, 2] * wl2))
        cross = w0 * (md1 * v2 - md2 * v1) + w1 * (md2 * v0 - md0 * v2) + w2 * (md0 * v1 - md1 * v0)
        T += 0.5 * (rot + 2.0 * cross + m * (v0 * v0 + v1 * v1 + v2 * v2))
        V -= gravity[0] * (m * oO[k, 0] + md0) + gravity[1] * (m * oO[k, 1] + md1) \
            + gravity[2] * (m * oO[k, 2] + md2)
    armature = tree.armature
    if armature.shape[0] != 0:  # the joints' own inertia's: 1/2 sum_j v_j (armature_j v_j)
        Ta = 0.0
        for j in range(qd.shape[0]):
            Ta += qd[j] * joint_force(0.0, armature, j, qd[j])
        T += 0.5 * Ta
    return T, V
