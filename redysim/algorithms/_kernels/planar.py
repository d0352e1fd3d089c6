"""RGE-A for planar chains: the same recursion specialised to revolute joints about parallel axes.

When every joint is a revolute about its frame's z axis the chain moves in the world XY plane, and
a twist has three non-zero components [w_z; v_x; v_y]. The extended mass matrix of Eq. (10a)
reduces to the symmetric 3 x 3

    M_k = [[I_zz, -m d_y, m d_x], [-m d_y, m, 0], [m d_x, 0, m]],

P_k = [1; 0; 0] and A_{k,k-1} = [[1, 0, 0], [-r_y, 1, 0], [r_x, 0, 1]] with r = O_k - O_{k-1}.
Then Psi_k is Mhat_k's first column, Ihat_k its (0, 0) entry, and Mbar_k = Mhat_k - Psi Psi^T /
Ihat has a zero first row and column: only its 2 x 2 translational block Zb is carried, and
A^T Mbar A = [[b^T Zb b, b^T Zb], [Zb b, Zb]] with b = (-r_y, r_x). One fused kernel does the
kinematics and both passes of Table A.1, with gravity and the velocity terms entered as the spatial
kernel ``rge_a.py`` enters them: gravity as the base's twist-rate in the forward pass, the
velocity terms as the local centripetal acceleration c_k = [0; -w_{k-1}^2 r] and the link's
centripetal force, never as phi (whose entries grow with the square of the chain's length).

A joint's armature a adds to its pivot, D = Ihat + a (:func:`.joints.joint_inertia`); Mbar_k's
first row (and column) is then a Psi / D, no longer zero: such a joint's parent takes it in too
(``_planar_backward``), and its qdd reads Psi's first entry.

Model only what the scene requires: 21 + 9 numbers per link become 3 + 3; see the benchmark
``benchmarks/test_bench_core.py::test_planar_gain`` for the measured gain over the spatial path.

References:
    Agarwal et al., Table A.1 and Eq. (9)-(12), specialised to planar motion (section 3.1 chains,
    section 5 study chains).
"""

from __future__ import annotations

import math

from redysim._jit import inline, jit_borrowed

from .joints import joint_inertia


@jit_borrowed
def planar_forward_dynamics(length, mass, izz_O, mc_x, mc_y, armature, gravity, q, qd, tau, qdd,
                            scratch):
    """qdd for a planar R chain; tau may be all zeros. scratch: (nl, 12) work array.

    Returns 0.0, or NaN when some qdd is not finite (the caller's check, without a pass over qdd).

    izz_O: (nl,) inertia about the joint axis through O_k; mc_x, mc_y: m c in the link frame;
    armature: (nl,) each joint's own inertia, or empty: none (.joints.joint_inertia).
    gravity: (3,) world gravity (only X and Y act in the plane).
    """
    # scratch columns: 0 c, 1 s, 2 Ox, 3 Oy, 4 w, 5 D (Ihat: psi0 + armature), 6 cx, 7 cy (c_k's
    # linear part), 8 psi0, 9 psi1, 10 psi2, 11 phitil
    _planar_kinematics(length, q, qd, scratch)
    _planar_backward(mass, izz_O, mc_x, mc_y, armature, tau, scratch)
    return _planar_forward(armature, gravity, qdd, scratch)


@inline
def _planar_kinematics(length, q, qd, scratch):
    """Angles, positions, angular velocities and local centripetal accelerations c_k into the
    scratch."""
    th = 0.0
    Ox = Oy = 0.0
    w = 0.0
    cp = 1.0
    sp = 0.0
    lp = 0.0
    # forward: k = 1..nl
    for k in range(length.shape[0]):
        rx = lp * cp
        ry = lp * sp
        # vd_k = A vd_{k-1} + c_k,  c_k = -w_{k-1}^2 r  (its rotational part is zero)
        ax = -w * w * rx
        ay = -w * w * ry
        Ox += rx
        Oy += ry
        th += q[k]
        c = math.cos(th)
        s = math.sin(th)
        w += qd[k]
        scratch[k, 0] = c
        scratch[k, 1] = s
        scratch[k, 2] = Ox
        scratch[k, 3] = Oy
        scratch[k, 4] = w
        scratch[k, 6] = ax
        scratch[k, 7] = ay
        cp = c
        sp = s
        lp = length[k]


@inline
def _planar_backward(mass, izz_O, mc_x, mc_y, armature, tau, scratch):
    """The articulated masses and biases; D, Psi and phitil of every joint into the scratch.

    Without armature Mbar_k = Mhat_k - Psi Psi^T / Ihat has a zero first row and column and only
    its translational block Zb is carried; a joint with armature (D = Ihat + armature,
    :func:`.joints.joint_inertia`) leaves a first row (m00, m01, m02) too, which its parent then
    takes in (``armed``)."""
    nl = mass.shape[0]
    nz = 0.0  # the articulated body's bias p: moment about O_k
    fx = fy = 0.0  # and force
    zxx = zxy = zyy = 0.0  # Mbar_{k+1}'s translational block Zb
    m00 = m01 = m02 = 0.0  # and its first row, when its joint has armature
    armed = False
    # backward: k = nl..1
    for k in range(nl - 1, -1, -1):
        c = scratch[k, 0]
        s = scratch[k, 1]
        w = scratch[k, 4]
        m = mass[k]
        mdx = c * mc_x[k] - s * mc_y[k]
        mdy = s * mc_x[k] + c * mc_y[k]
        # the link's centripetal wrench about O_k (zero twist-rate): f = -w^2 m d, n = 0
        lfx = -w * w * mdx
        lfy = -w * w * mdy
        # shift from O_{k+1} to O_k: r = O_{k+1} - O_k
        if k < nl - 1:
            rx = scratch[k + 1, 2] - scratch[k, 2]
            ry = scratch[k + 1, 3] - scratch[k, 3]
            nz += rx * fy - ry * fx  # p <- A^T p
            bx = -ry
            by = rx
        else:
            bx = by = 0.0
        fx += lfx
        fy += lfy
        # Mhat_k = M_k + A^T Mbar_{k+1} A  with Mbar_{k+1} = [[0, 0], [0, Zb]] (and, armed,
        # its first row: [[m00 + 2 b.m, m^T + b^T Zb], [m + Zb b, Zb]])
        zbx = zxx * bx + zxy * by
        zby = zxy * bx + zyy * by
        h00 = izz_O[k] + bx * zbx + by * zby
        h01 = -mdy + zbx
        h02 = mdx + zby
        if armed:
            h00 += m00 + 2.0 * (bx * m01 + by * m02)
            h01 += m01
            h02 += m02
        h11 = m + zxx
        h12 = zxy
        h22 = m + zyy
        # Psi = Mhat e0, D = h00 (+ armature); phihat = tau - P^T p, phitil; p <- p + Psi phitil
        d = joint_inertia(h00, armature, k)
        phihat = tau[k] - nz
        phit = phihat / d
        scratch[k, 5] = d
        scratch[k, 8] = h00
        scratch[k, 9] = h01
        scratch[k, 10] = h02
        scratch[k, 11] = phit
        nz += h00 * phit
        fx += h01 * phit
        fy += h02 * phit
        # Mbar_k = Mhat_k - Psi Psi^T / D (symmetric by construction)
        armed = armature.shape[0] != 0 and armature[k] != 0.0
        if armed:
            m00 = h00 - h00 * h00 / d
            m01 = h01 - h00 * h01 / d
            m02 = h02 - h00 * h02 / d
        zxx = h11 - h01 * h01 / d
        zxy = h12 - h01 * h02 / d
        zyy = h22 - h02 * h02 / d
        # the articulated body's bias: p <- p + Mbar_k c_k
        cx = scratch[k, 6]
        cy = scratch[k, 7]
        if armed:
            nz += m01 * cx + m02 * cy
        fx += zxx * cx + zxy * cy
        fy += zxy * cx + zyy * cy


@inline
def _planar_forward(armature, gravity, qdd, scratch):
    """qdd from the base's twist-rate [0; -g] (mu = [wd; vdx; vdy]); returns 0.0, or NaN when
    some qdd is not finite."""
    m0 = 0.0
    m1 = -gravity[0]
    m2 = -gravity[1]
    nonfinite = 0.0  # stays 0 unless a qdd is NaN or +-inf (x * 0 is then NaN)
    # forward: k = 1..nl
    for k in range(qdd.shape[0]):
        if k > 0:
            rx = scratch[k, 2] - scratch[k - 1, 2]
            ry = scratch[k, 3] - scratch[k - 1, 3]
            m1 += -ry * m0
            m2 += rx * m0
        m1 += scratch[k, 6]
        m2 += scratch[k, 7]
        h00 = scratch[k, 8]
        if armature.shape[0] != 0 and armature[k] != 0.0:  # qdd = phitil - Psi^T mu / D
            x = scratch[k, 11] - (h00 * m0 + scratch[k, 9] * m1 + scratch[k, 10] * m2) \
                / scratch[k, 5]
        else:  # (D = psi0: psi0 m0 / D is m0)
            x = scratch[k, 11] - (scratch[k, 9] * m1 + scratch[k, 10] * m2) / h00 - m0
        qdd[k] = x
        m0 += x
        nonfinite += x * 0.0
    return nonfinite


@jit_borrowed
def planar_tip_torques(length, q, force, d, qd, out):
    """out = J_tip(q)^T F + d * qd (nl,) for a planar R chain: the joint torques of a constant
    world force ``force`` (3,) at the tip (the distal end of the last link), tau_k = (p_tip -
    O_k) x F = sum_{i >= k} l_i (cos th_i F_y - sin th_i F_x), th_i = q_0 + ... + q_i, with a
    viscous ``d * qd`` added (d = -damping; 0: none). The Python loop and the compiled steps both
    call this function (:mod:`redysim.simulation`, :mod:`.rk_run`), so that they round alike."""
    nl = length.shape[0]
    th = 0.0
    for k in range(nl):
        th += q[k]
        out[k] = length[k] * (math.cos(th) * force[1] - math.sin(th) * force[0])
    acc = 0.0
    for k in range(nl - 1, -1, -1):
        acc += out[k]
        out[k] = acc
    if d != 0.0:
        for k in range(nl):
            out[k] = out[k] + d * qd[k]
