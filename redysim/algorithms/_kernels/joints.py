"""Joint calculations: the one place that knows joint kinds and axes (spatial_v2's ``jcalc``).

A joint is a sequence of elementary axes (see :data:`redysim.model.parts.JOINT_TYPES`); this module
maps (kind, axis, q_j) and the frame before the axis to the axis's motion-subspace column P =
[p_ang; p_lin] in the world frame and the frame after it: a rotation of the frame (revolute) or a
translation of the joint's origin (prismatic), and a third kind, BALL: the three rotational DOF of a
free joint, about the body's own axes, its rotation given by a unit quaternion in q. The recursions
call :func:`jcalc`, :func:`axis_rates` and :func:`column_mass` and never branch on the joint type
themselves; each skips the half of P that is zero for its kind (work a revolute chain does not
need).

Everything is scalars in and out: the kinematics pass keeps its running frame in registers rather
than reading it back from arrays (docs/design.md, "Performance notes").

References:
    Agarwal et al., Eq. (4): P_k = [e_k; 0] for a revolute and [0; e_k] for a prismatic axis.
"""

from __future__ import annotations

import math

from numba.extending import overload

from redysim._jit import inline

REVOLUTE = 0
PRISMATIC = 1
BALL = 2


def sincos(x):
    """(cos x, sin x).

    This Python definition is what the kernels' Python source runs, in any arithmetic
    (``redysim.algorithms.precision`` and ``redysim.harness.hiprec`` rebind its ``math`` as they do
    a kernel's: the ``py_func`` attribute marks it). Compiled code runs :func:`_sincos_compiled`
    instead.
    """
    return math.cos(x), math.sin(x)


sincos.py_func = sincos  # type: ignore[attr-defined]  # a mark on a plain function


# fdlibm's minimax polynomials on [-pi/4, pi/4] (FreeBSD msun k_sin.c, k_cos.c)
S1, S2, S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
S4, S5, S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
C1, C2, C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
C4, C5, C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11
PI_4 = 0.7853981633974483


@overload(sincos, inline="always")
def _sincos_compiled(x):
    """Compiled (cos x, sin x): for |x| <= pi/4 (every joint angle of a gently bent chain)
    fdlibm's kernels inline, without a call to libm; else libm's cos and sin.

    Why: two libm calls per axis were half of the kinematics pass, each call also spilling the
    pass's running scalars (docs/design.md, "Performance notes"). The polynomials are libm's own
    (fdlibm, error < 1 ulp); ``tests/test_identities.py`` checks them against ``math`` to 1 ulp.
    """
    def impl(x):
        if abs(x) <= PI_4:
            z = x * x
            r = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))
            s = x + x * z * (S1 + z * r)
            rc = z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))
            hz = 0.5 * z
            w = 1.0 - hz
            return w + (((1.0 - w) - hz) + z * rc), s
        return math.cos(x), math.sin(x)
    return impl


@inline
def turned(r00, r01, r02, r10, r11, r12, r20, r21, r22,
           g00, g01, g02, g10, g11, g12, g20, g21, g22):
    """The frame R turned by G in its own axes: R G, row by row (9 scalars in the order of
    R's entries)."""
    return (r00 * g00 + r01 * g10 + r02 * g20, r00 * g01 + r01 * g11 + r02 * g21,
            r00 * g02 + r01 * g12 + r02 * g22,
            r10 * g00 + r11 * g10 + r12 * g20, r10 * g01 + r11 * g11 + r12 * g21,
            r10 * g02 + r11 * g12 + r12 * g22,
            r20 * g00 + r21 * g10 + r22 * g20, r20 * g01 + r21 * g11 + r22 * g21,
            r20 * g02 + r21 * g12 + r22 * g22)


@inline
def jcalc(kind, code, u, qj, q1, q2, q3, s0, s1, s2, r00, r01, r02, r10, r11, r12, r20, r21,
          r22):
    """One elementary axis: returns (p0..p5, s0..s2, r00..r22).

    p = [e; 0] (revolute, ball) or [0; e] (prismatic) with e = R u the axis in the world frame;
    s the joint origin's offset, moved by e q_j along a prismatic axis (else as given); r the
    frame after the axis: R Rot(u, q_j) for a revolute axis, R for a prismatic one. ``code`` 0,
    1, 2 names the x, y or z axis of the frame (two columns mix), 3 a general unit vector u
    (Rodrigues). ``u`` is the axis's row of ``dof_u``, read only for code 3: a chain of x, y and
    z axes never loads it (48 bytes a U joint less to stream).

    BALL (codes 0, 1, 2: the body's x, y, z): the first of the three turns the frame by the
    quaternion (w, x, y, z) = (q_j, q1, q2, q3) (the caller reads q1..q3 for it alone),
    normalised (as MuJoCo does: an integrator's stage may leave it slightly off the unit
    sphere), and each gives the turned frame's column. Scalars only: an array passed to an
    inlined helper costs a reference count per call, more than a rope's whole axis.
    """
    if kind == BALL:
        if code == 0:
            qw, qx, qy, qz = qj, q1, q2, q3
            two = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
            g00, g01, g02 = (1.0 - two * (qy * qy + qz * qz), two * (qx * qy - qw * qz),
                             two * (qx * qz + qw * qy))
            g10, g11, g12 = (two * (qx * qy + qw * qz), 1.0 - two * (qx * qx + qz * qz),
                             two * (qy * qz - qw * qx))
            g20, g21, g22 = (two * (qx * qz - qw * qy), two * (qy * qz + qw * qx),
                             1.0 - two * (qx * qx + qy * qy))
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = turned(
                r00, r01, r02, r10, r11, r12, r20, r21, r22,
                g00, g01, g02, g10, g11, g12, g20, g21, g22)
            e0, e1, e2 = r00, r10, r20
        elif code == 1:
            e0, e1, e2 = r01, r11, r21
        else:
            e0, e1, e2 = r02, r12, r22
        return (e0, e1, e2, 0.0, 0.0, 0.0, s0, s1, s2,
                r00, r01, r02, r10, r11, r12, r20, r21, r22)
    if code == 0:
        e0, e1, e2 = r00, r10, r20
    elif code == 1:
        e0, e1, e2 = r01, r11, r21
    elif code == 2:
        e0, e1, e2 = r02, r12, r22
    else:
        u0, u1, u2 = u[0], u[1], u[2]
        e0 = r00 * u0 + r01 * u1 + r02 * u2
        e1 = r10 * u0 + r11 * u1 + r12 * u2
        e2 = r20 * u0 + r21 * u1 + r22 * u2
    if kind == PRISMATIC:
        return (0.0, 0.0, 0.0, e0, e1, e2, s0 + e0 * qj, s1 + e1 * qj, s2 + e2 * qj,
                r00, r01, r02, r10, r11, r12, r20, r21, r22)
    c, s = sincos(qj)
    if code == 0:  # columns y, z mix
        n01, n11, n21 = c * r01 + s * r02, c * r11 + s * r12, c * r21 + s * r22
        n02, n12, n22 = c * r02 - s * r01, c * r12 - s * r11, c * r22 - s * r21
        r01, r11, r21, r02, r12, r22 = n01, n11, n21, n02, n12, n22
    elif code == 1:  # columns z, x mix
        n02, n12, n22 = c * r02 + s * r00, c * r12 + s * r10, c * r22 + s * r20
        n00, n10, n20 = c * r00 - s * r02, c * r10 - s * r12, c * r20 - s * r22
        r02, r12, r22, r00, r10, r20 = n02, n12, n22, n00, n10, n20
    elif code == 2:  # columns x, y mix
        n00, n10, n20 = c * r00 + s * r01, c * r10 + s * r11, c * r20 + s * r21
        n01, n11, n21 = c * r01 - s * r00, c * r11 - s * r10, c * r21 - s * r20
        r00, r10, r20, r01, r11, r21 = n00, n10, n20, n01, n11, n21
    else:  # R Rot(u, q), Rot = c 1 + s C(u) + (1 - c) u u^T
        u0, u1, u2 = u[0], u[1], u[2]
        t = 1.0 - c
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = turned(
            r00, r01, r02, r10, r11, r12, r20, r21, r22,
            c + t * u0 * u0, t * u0 * u1 - s * u2, t * u0 * u2 + s * u1,
            t * u1 * u0 + s * u2, c + t * u1 * u1, t * u1 * u2 - s * u0,
            t * u2 * u0 - s * u1, t * u2 * u1 + s * u0, c + t * u2 * u2)
    return (e0, e1, e2, 0.0, 0.0, 0.0, s0, s1, s2,
            r00, r01, r02, r10, r11, r12, r20, r21, r22)


@inline
def column_mass(kind, e0, e1, e2, x00, x01, x02, x11, x12, x22,
                y00, y01, y02, y10, y11, y12, y20, y21, y22, z00, z01, z02, z11, z12, z22):
    """Psi = Mhat p and Ihat = p^T Psi for the column p of one axis, Mhat = [[X, Y], [Y^T, Z]].

    p = [e; 0] (revolute): Psi = [X e; Y^T e], Ihat = e . X e;
    p = [0; e] (prismatic): Psi = [Y e; Z e], Ihat = e . Z e.
    Only the non-zero half of p is multiplied: half the work of a 6 x 6 product, and a shorter
    serial chain in RGE-A's backward pass. Returns (Psi_0..Psi_5, Ihat).
    """
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
def axis_rates(kind, code, p0, p1, p2, p3, p4, p5, x, y, om0, om1, om2,
               dv0, dv1, dv2, da0, da1, da2, db0, db1, db2, bw0, bw1, bw2):
    """One axis's part of the link's twist and local twist-rate, the column's zero half skipped.

    P = [p_ang; p_lin]; x, y: the axis's qd and qdd; om: the angular velocity of the frame the
    axis is fixed in (a revolute axis adds e x to it, the frame of the next axis). Adds P x to
    (om, dv) and P y + Pd x to (da, db), with Pd = om x P (both halves of the column rotate with
    that frame). A ball's columns are fixed in the body itself: Pd x summed over the three is
    (om + R w) x (R w) = om x (R w) with om the parent's angular velocity, so their P x gather
    in (bw), added to om with the last of the three (``code`` 2; a ball ends its joint). Returns
    (om, dv, da, db, bw) updated: 15 scalars.
    """
    if kind == BALL:
        da0 += p0 * y + (om1 * p2 - om2 * p1) * x
        da1 += p1 * y + (om2 * p0 - om0 * p2) * x
        da2 += p2 * y + (om0 * p1 - om1 * p0) * x
        bw0 += p0 * x
        bw1 += p1 * x
        bw2 += p2 * x
        if code == 2:
            om0 += bw0
            om1 += bw1
            om2 += bw2
    elif kind == PRISMATIC:
        dv0 += p3 * x
        dv1 += p4 * x
        dv2 += p5 * x
        db0 += p3 * y + (om1 * p5 - om2 * p4) * x
        db1 += p4 * y + (om2 * p3 - om0 * p5) * x
        db2 += p5 * y + (om0 * p4 - om1 * p3) * x
    else:
        da0 += p0 * y + (om1 * p2 - om2 * p1) * x
        da1 += p1 * y + (om2 * p0 - om0 * p2) * x
        da2 += p2 * y + (om0 * p1 - om1 * p0) * x
        om0 += p0 * x
        om1 += p1 * x
        om2 += p2 * x
    return (om0, om1, om2, dv0, dv1, dv2, da0, da1, da2, db0, db1, db2, bw0, bw1, bw2)
