"""Joint calculations: the one place that knows joint kinds and axes (spatial_v2's ``jcalc``).

A joint is a sequence of elementary axes (see :data:`redysim.model.parts.JOINT_TYPES`); this module
maps (kind, axis, q_j) and the frame before the axis to the axis's motion-subspace column P =
[p_ang; p_lin] in the world frame and the frame after it: a rotation of the frame (revolute) or a
translation of the joint's origin (prismatic), and a third kind, BALL: the three rotational DOF of a
free joint, about the body's own axes, its rotation given by a unit quaternion in q. The recursions
call :func:`jcalc`, :func:`axis_rates` and :func:`.articulated.column_mass` and never branch on
the joint type themselves; each skips the half of P that is zero for its kind (work a revolute
chain does not need). Also here, the joint's own inertia (armature): :func:`joint_inertia` forms
the joint-space inertia of an axis wherever a kernel needs it (the pivot of every elimination,
the GIM's diagonal), :func:`joint_force` its part of a joint force.

jcalc is built from smaller steps that the SIMD tiles (:mod:`.tiles`) call too, per state inside
their loops over states: :func:`axis_column` (the axis in the world frame), :func:`turn_frame`
(the frame turned about it), :func:`ball_frame` (a free joint's quaternion), gathered in
:func:`axis_transform`, given cos and sin (the tiles compute theirs without branches).

Everything is scalars (and tuples of them) in and out: the kinematics pass keeps its running frame
in registers rather than reading it back from arrays (docs/design.md, "Performance notes").

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
GENERAL = 3  # dof_axis of an axis that is no coordinate axis (redysim.model.parts)


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

    Why: two libm calls per axis were a large part of the kinematics pass, each call also spilling
    the pass's running scalars (docs/notes/2026-11-kernels-speed.md). The polynomials are libm's
    own (fdlibm, error < 1 ulp); ``tests/test_identities.py`` checks them against ``math`` to 1
    ulp.
    """
    def impl(x):
        if abs(x) <= PI_4:
            return fdlibm_sincos(x)
        return math.cos(x), math.sin(x)
    return impl


@inline
def fdlibm_sincos(x):
    """(cos x, sin x) by fdlibm's kernels (k_cos.c, k_sin.c), for |x| <= pi/4; compiled
    :func:`sincos` and the SIMD tiles' branch-free one (after their reduction) call it."""
    z = x * x
    r = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))
    s = x + x * z * (S1 + z * r)
    rc = z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    return w + (((1.0 - w) - hz) + z * rc), s


@inline
def turned(R, G):
    """The frame R turned by G in its own axes: R G (both 9-tuples, row by row)."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    g00, g01, g02, g10, g11, g12, g20, g21, g22 = G
    return (r00 * g00 + r01 * g10 + r02 * g20, r00 * g01 + r01 * g11 + r02 * g21,
            r00 * g02 + r01 * g12 + r02 * g22,
            r10 * g00 + r11 * g10 + r12 * g20, r10 * g01 + r11 * g11 + r12 * g21,
            r10 * g02 + r11 * g12 + r12 * g22,
            r20 * g00 + r21 * g10 + r22 * g20, r20 * g01 + r21 * g11 + r22 * g21,
            r20 * g02 + r21 * g12 + r22 * g22)


@inline
def axis_column(code, u0, u1, u2, R):
    """e = R u, the axis in the world frame: for ``code`` 0, 1, 2 the frame R's x, y or z
    column (u unread), for 3 (a general unit vector u) the product."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    if code == 0:
        return r00, r10, r20
    if code == 1:
        return r01, r11, r21
    if code == 2:
        return r02, r12, r22
    return (r00 * u0 + r01 * u1 + r02 * u2, r10 * u0 + r11 * u1 + r12 * u2,
            r20 * u0 + r21 * u1 + r22 * u2)


@inline
def turn_frame(code, u0, u1, u2, c, s, R):
    """R Rot(u, q), the frame R turned about its own axis u by the angle whose cos and sin are
    (c, s): for ``code`` 0, 1, 2 (x, y, z) two of R's columns mix; for 3 Rodrigues' Rot =
    c 1 + s C(u) + (1 - c) u u^T."""
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = R
    if code == 0:  # columns y, z mix
        return (r00, c * r01 + s * r02, c * r02 - s * r01,
                r10, c * r11 + s * r12, c * r12 - s * r11,
                r20, c * r21 + s * r22, c * r22 - s * r21)
    if code == 1:  # columns z, x mix
        return (c * r00 - s * r02, r01, c * r02 + s * r00,
                c * r10 - s * r12, r11, c * r12 + s * r10,
                c * r20 - s * r22, r21, c * r22 + s * r20)
    if code == 2:  # columns x, y mix
        return (c * r00 + s * r01, c * r01 - s * r00, r02,
                c * r10 + s * r11, c * r11 - s * r10, r12,
                c * r20 + s * r21, c * r21 - s * r20, r22)
    t = 1.0 - c
    return turned(R, (c + t * u0 * u0, t * u0 * u1 - s * u2, t * u0 * u2 + s * u1,
                      t * u1 * u0 + s * u2, c + t * u1 * u1, t * u1 * u2 - s * u0,
                      t * u2 * u0 - s * u1, t * u2 * u1 + s * u0, c + t * u2 * u2))


@inline
def ball_frame(qw, qx, qy, qz, R):
    """The frame R turned by the quaternion (w, x, y, z), normalised (as MuJoCo does: an
    integrator's stage may leave it slightly off the unit sphere)."""
    two = 2.0 / (qw * qw + qx * qx + qy * qy + qz * qz)
    return turned(R, (1.0 - two * (qy * qy + qz * qz), two * (qx * qy - qw * qz),
                      two * (qx * qz + qw * qy),
                      two * (qx * qy + qw * qz), 1.0 - two * (qx * qx + qz * qz),
                      two * (qy * qz - qw * qx),
                      two * (qx * qz - qw * qy), two * (qy * qz + qw * qx),
                      1.0 - two * (qx * qx + qy * qy)))


@inline
def axis_transform(kind, code, u0, u1, u2, qj, c, s, q1, q2, q3, s0, s1, s2, R):
    """One elementary axis, its cos and sin given: returns (p0..p5, s0, s1, s2, R) as
    :func:`jcalc` (whose body it is; the SIMD tiles call it with their own branch-free cos and
    sin). c, s are read for a revolute axis only, q1..q3 for a ball's first axis only."""
    if kind == BALL:
        if code == 0:
            R = ball_frame(qj, q1, q2, q3, R)
        e0, e1, e2 = axis_column(code, u0, u1, u2, R)
        return e0, e1, e2, 0.0, 0.0, 0.0, s0, s1, s2, R
    e0, e1, e2 = axis_column(code, u0, u1, u2, R)
    if kind == PRISMATIC:
        return 0.0, 0.0, 0.0, e0, e1, e2, s0 + e0 * qj, s1 + e1 * qj, s2 + e2 * qj, R
    return e0, e1, e2, 0.0, 0.0, 0.0, s0, s1, s2, turn_frame(code, u0, u1, u2, c, s, R)


@inline
def jcalc(kind, code, u, qj, q1, q2, q3, s0, s1, s2, R):
    """One elementary axis: returns (p0..p5, s0, s1, s2, R), R the frame as a 9-tuple.

    p = [e; 0] (revolute, ball) or [0; e] (prismatic) with e = R u the axis in the world frame;
    s the joint origin's offset, moved by e q_j along a prismatic axis (else as given); R the
    frame after the axis: R Rot(u, q_j) for a revolute axis, R for a prismatic one. ``code`` 0,
    1, 2 names the x, y or z axis of the frame (two columns mix), 3 a general unit vector u
    (Rodrigues). ``u`` is the axis's row of ``dof_u``, read only for code 3: a chain of x, y and
    z axes never loads it (48 bytes a U joint less to stream).

    BALL (codes 0, 1, 2: the body's x, y, z): the first of the three turns the frame by the
    quaternion (w, x, y, z) = (q_j, q1, q2, q3) (the caller reads q1..q3 for it alone),
    normalised, and each gives the turned frame's column. Scalars and tuples only: an array
    passed to an inlined helper costs a reference count per call where numba counts them.
    """
    u0 = u1 = u2 = 0.0
    if code == GENERAL:
        u0, u1, u2 = u[0], u[1], u[2]
    cq = sq = 0.0
    if kind == REVOLUTE:
        cq, sq = sincos(qj)
    return axis_transform(kind, code, u0, u1, u2, qj, cq, sq, q1, q2, q3, s0, s1, s2, R)


@inline
def joint_inertia(ih, armature, j):
    """D_j = P_j^T Mhat_j P_j + armature[j]: the joint-space inertia of axis j, the pivot of its
    elimination (the D of I = U D U^T) and the GIM's diagonal entry. The one place where the
    joint's own inertia (a rotor's, reflected: MuJoCo's ``dof_armature``, Pinocchio's
    ``armature``) enters every kernel; see :func:`joint_force` for inverse dynamics.

    ``armature`` is empty for a model without any (the layout's ``na``: ``bundles.LAYOUT``),
    and nothing is read or added then: the branch is the same every call (predicted), and the
    load inside it keeps LLVM from turning it into a select that would wait for the addition
    on the elimination's critical path."""
    if armature.shape[0] != 0:
        return ih + armature[j]
    return ih


@inline
def joint_force(f, armature, j, a):
    """f + armature[j] a: a joint force P_j^T W with the joint's own inertia's part added (a the
    axis's acceleration; its velocity for the generalized momentum); ``armature`` empty: f."""
    if armature.shape[0] != 0:
        return f + armature[j] * a
    return f


@inline
def axis_rates(kind, code, p0, p1, p2, p3, p4, p5, x, y, accel, om0, om1, om2,
               dv0, dv1, dv2, da0, da1, da2, db0, db1, db2, bw0, bw1, bw2):
    """One axis's part of the link's twist and local twist-rate, the column's zero half skipped.

    P = [p_ang; p_lin]; x, y: the axis's qd and qdd (``accel`` False: qdd known zero, its term
    left out, as the SIMD tiles run); om: the angular velocity of the frame the axis is fixed
    in (a revolute axis adds e x to it, the frame of the next axis). Adds P x to (om, dv) and
    P y + Pd x to (da, db), with Pd = om x P (both halves of the column rotate with that frame).
    A ball's columns are fixed in the body itself: Pd x summed over the three is (om + R w) x
    (R w) = om x (R w) with om the parent's angular velocity, so their P x gather in (bw), added
    to om with the last of the three (``code`` 2; a ball ends its joint). Returns (om, dv, da,
    db, bw) updated: 15 scalars.
    """
    # (each branch computes its own increments, in this order of branches: LLVM fuses a
    # multiply into an add only within one basic block, and hoists what two branches begin
    # with alike out of them; so written, the bits are those of the kernels before the helper)
    if kind == BALL:
        r0, r1, r2 = axis_rate(p0, p1, p2, x, y, accel, om0, om1, om2)
        da0 += r0
        da1 += r1
        da2 += r2
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
        r0, r1, r2 = axis_rate(p3, p4, p5, x, y, accel, om0, om1, om2)
        db0 += r0
        db1 += r1
        db2 += r2
    else:
        r0, r1, r2 = axis_rate(p0, p1, p2, x, y, accel, om0, om1, om2)
        da0 += r0
        da1 += r1
        da2 += r2
        om0 += p0 * x
        om1 += p1 * x
        om2 += p2 * x
    return (om0, om1, om2, dv0, dv1, dv2, da0, da1, da2, db0, db1, db2, bw0, bw1, bw2)


@inline
def axis_rate(e0, e1, e2, x, y, accel, om0, om1, om2):
    """e y + (om x e) x: a column's P qdd + Pd qd (one half of it, e), qdd's part left out
    when ``accel`` is False."""
    if accel:
        return (e0 * y + (om1 * e2 - om2 * e1) * x, e1 * y + (om2 * e0 - om0 * e2) * x,
                e2 * y + (om0 * e1 - om1 * e0) * x)
    return (0.0 + (om1 * e2 - om2 * e1) * x, 0.0 + (om2 * e0 - om0 * e2) * x,
            0.0 + (om0 * e1 - om1 * e0) * x)
