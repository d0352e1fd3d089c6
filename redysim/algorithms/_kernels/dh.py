"""Inverse and forward dynamics specialised to serial robots in Denavit-Hartenberg form.

A DH robot (:mod:`redysim.algorithms.dh_form`) places joint k in body k - 1 by Rx(alpha) Tx(a)
Rz(theta) Tz(d) and turns (slides) it about (along) its own z. Every quantity of body k is kept in
its own frame F_k, about its origin O_k on the joint's axis, and is moved between frames by those
four elementary steps instead of a general rotation and shift: a rotation about x or z mixes two
components of a vector (4 multiplications, 2 additions instead of 9 and 6), and a shift along x or
z touches two (docs/design.md, "DH robots"). Angular quantities come first; accelerations are the
classical ones (omega-dot, and the acceleration of O_k), gravity enters as the base's acceleration
-g, so a body's Newton-Euler wrench about O_k is

    f = m a + omega-dot x h + omega x (omega x h),   n = J omega-dot + omega x J omega + h x a,

h = m c its first moment and J its inertia about O_k, i.e. a 6 x 6 inertia [[J, h~], [h~^T, m 1]]
and a velocity bias (omega x J omega, omega x (omega x h)).

``dh_inverse_dynamics``: Newton-Euler in these frames (the forward pass moves omega, omega-dot
and a by the four steps; a shift of an acceleration by r is W r with W = omega-dot~ + omega~
omega~, whose first column the parent's wrench already computed).

``dh_forward_dynamics``: the articulated-body recursion (Featherstone's; Agarwal et al.'s RGE-A
written in these frames): an articulated inertia projected for a revolute about z has a zero
angular-z row and column, which shifting along z and turning about z keep, so that its moves to
the parent's frame work on 15 numbers where they can. A prismatic joint's projection zeroes the
linear-z row and column, and its moves work on all 21.

A twist that is a right angle's multiple (the constants' twist code) turns vectors and inertias
about x by a signed permutation of their y and z parts, without arithmetic; the base's body (its
parent at rest) and its child skip the products of the zeros they are known to hold. In the
forward kernel, the base's body, if revolute, needs only its articulated inertia's angular-z
column and its bias's moment about z (its parent does not move), so its child moves only those
to it; and the last body's articulated inertia is its own, so for a revolute joint its
projection (and shift along z) is a constant of the robot, read from the DH table
(:func:`redysim.algorithms.dh_form.tip_columns`). Both kernels are IEEE as written
(``redysim._jit.jit_exact``), so every caller gets the same bits.

A joint's armature (the DH table's ``armature`` column) enters where the joint-space inertia is
formed (:func:`.joints.joint_inertia`; :func:`.joints.joint_force` in the inverse kernel). It
leaves the projected inertia a row and column along the joint's axis, which the zero-structured
steps above assume away: a joint with armature takes the general step, the elimination of
:mod:`.articulated` (:func:`.articulated.eliminate_axis`) on all 21 numbers, then the moves on all
21 (a prismatic joint's steps). The forward kernel is its three passes, each a function.

Both are equal to the general kernels (:mod:`.kinematics`, :mod:`.inverse_dynamics`,
:mod:`.rge_a`) to rounding. Their Python source is what ``redysim.reports.opcount`` counts.
"""

from __future__ import annotations

import math

from redysim._jit import inline, jit_exact

from .articulated import add6, articulated_bias, eliminate_axis
from .bundles import DH_A as A
from .bundles import DH_ARMATURE as ARMATURE
from .bundles import DH_C2 as C2
from .bundles import DH_CA as CA
from .bundles import DH_CMS as CMS
from .bundles import DH_CS as CS
from .bundles import DH_CS2 as CS2
from .bundles import DH_D as D
from .bundles import DH_HX as HX
from .bundles import DH_HY as HY
from .bundles import DH_HZ as HZ
from .bundles import DH_JXX as JXX
from .bundles import DH_JXY as JXY
from .bundles import DH_JXZ as JXZ
from .bundles import DH_JYY as JYY
from .bundles import DH_JYZ as JYZ
from .bundles import DH_JZZ as JZZ
from .bundles import DH_KIND as KIND
from .bundles import DH_M as M
from .bundles import DH_S2 as S2
from .bundles import DH_SA as SA
from .bundles import DH_SCRATCH
from .bundles import DH_TH as TH
from .bundles import DH_TIP_A00 as TIP_A00
from .bundles import DH_TIP_A01 as TIP_A01
from .bundles import DH_TIP_A11 as TIP_A11
from .bundles import DH_TIP_B00 as TIP_B00
from .bundles import DH_TIP_B01 as TIP_B01
from .bundles import DH_TIP_B10 as TIP_B10
from .bundles import DH_TIP_B11 as TIP_B11
from .bundles import DH_TIP_D0 as TIP_D0
from .bundles import DH_TIP_D1 as TIP_D1
from .bundles import DH_TIP_D3 as TIP_D3
from .bundles import DH_TIP_D4 as TIP_D4
from .bundles import DH_TIP_INV as TIP_INV
from .bundles import DH_TIP_M00 as TIP_M00
from .bundles import DH_TIP_M01 as TIP_M01
from .bundles import DH_TIP_M11 as TIP_M11
from .bundles import DH_TIP_ZA00 as TIP_ZA00
from .bundles import DH_TIP_ZA01 as TIP_ZA01
from .bundles import DH_TIP_ZA11 as TIP_ZA11
from .bundles import DH_TIP_ZB00 as TIP_ZB00
from .bundles import DH_TIP_ZB01 as TIP_ZB01
from .bundles import DH_TIP_ZB10 as TIP_ZB10
from .bundles import DH_TIP_ZB11 as TIP_ZB11
from .bundles import DH_TW as TW
from .joints import PRISMATIC, REVOLUTE, joint_force, joint_inertia

# the forward kernel's scratch columns, per body
(S_C, S_S, S_C0, S_C1, S_C3, S_C4, S_C5, S_P, S_CHILD_I, S_CHILD_P, S_UD, S_UDIV, S_PIVOT) = (
    0, 1, 2, 3, 4, 5, 6, 7, 13, 34, 40, 46, 47)
SCRATCH_COLUMNS = DH_SCRATCH  # c, s; c_k (5); own bias (6); the child's inertia (21) and
# bias (6); U/D (6); u/D; the pivot D (the articulated inertia about or along the joint's axis)
IA = 21  # an inertia's numbers: A (6: xx xy xz yy yz zz), B (9, row major), M (6)
NO_J = (0.0,) * 15  # (no projected inertia of a revolute body's 15 numbers)
# a joint's twist (the DH constants' "twist" column): any, or a right angle's multiple, which
# turns a vector's y and z components into each other (a signed permutation: no arithmetic)
ANY_TWIST, TWIST_0, TWIST_90, TWIST_M90, TWIST_180 = 0, 1, 2, 3, 4


@inline
def _xt(y, z, tw, ca, sa):
    """The y and z components of Rx(alpha)^T v (from the parent's frame into F')."""
    if tw == ANY_TWIST:
        return ca * y + sa * z, ca * z - sa * y
    if tw == TWIST_0:
        return y, z
    if tw == TWIST_90:
        return z, -y
    if tw == TWIST_M90:
        return -z, y
    return -y, -z


@inline
def _x(y, z, tw, ca, sa):
    """The y and z components of Rx(alpha) v (from F' into the parent's frame)."""
    if tw == ANY_TWIST:
        return ca * y - sa * z, sa * y + ca * z
    if tw == TWIST_0:
        return y, z
    if tw == TWIST_90:
        return -z, y
    if tw == TWIST_M90:
        return z, -y
    return -y, -z


@inline
def _sym_x(p, r, t, tw):
    """The symmetric [[p, r], [r, t]] (y and z) turned by a right-angle Rx: R X R^T."""
    if tw == TWIST_90 or tw == TWIST_M90:
        return t, -r, p
    return p, r, t


@inline
def _gen_x(g00, g01, g10, g11, tw):
    """A general 2 x 2 (y and z) turned by a right-angle Rx: R G R^T."""
    if tw == TWIST_90 or tw == TWIST_M90:
        return g11, -g10, -g01, g00
    return g00, g01, g10, g11


@inline
def _armature(dh, k):
    """Joint k's armature as :func:`.joints.joint_inertia` takes it: a view of its one number,
    or an empty one when it has none."""
    return dh[k:k + 1, ARMATURE] if dh[k, ARMATURE] != 0.0 else dh[k:k, ARMATURE]


@inline
def _joint(dh, q, k):
    """Joint k at q: (prismatic, its offset d along z (d + q for a prismatic), cos and sin of its
    angle (theta + q for a revolute))."""
    prismatic = dh[k, KIND] != 0.0
    ld = dh[k, D]
    if prismatic:
        th = dh[k, TH]
        ld = ld + q[k]
    else:
        th = dh[k, TH] + q[k]
    return prismatic, ld, math.cos(th), math.sin(th)


@inline
def _to_parent(dh, q, k, c, s, f0, f1, f2, n0, n1, n2):
    """A wrench (force f, moment n about O_k, in F_k) moved to the parent's frame, about its
    origin: Tz(d), Rz(theta), Tx(a), Rx(alpha) of joint k (cos, sin of its angle c, s)."""
    ld = dh[k, D] + q[k] if dh[k, KIND] != 0.0 else dh[k, D]
    ca, sa, la, tw = dh[k, CA], dh[k, SA], dh[k, A], dh[k, TW]
    # Tz(d): about O' = O_k - d z: n + d z x f
    n0 = n0 - ld * f1
    n1 = n1 + ld * f0
    # Rz(theta)
    f0, f1 = c * f0 - s * f1, s * f0 + c * f1
    n0, n1 = c * n0 - s * n1, s * n0 + c * n1
    # Tx(a): about O_{k-1}: n + a x x f
    n1 = n1 - la * f2
    n2 = n2 + la * f1
    # Rx(alpha)
    f1, f2 = _x(f1, f2, tw, ca, sa)
    n1, n2 = _x(n1, n2, tw, ca, sa)
    return f0, f1, f2, n0, n1, n2


@inline
def _to_parent_nz(dh, q, k, c, s, f0, f1, f2, n0, n1, n2):
    """:func:`_to_parent`'s moment about the parent's z alone (the same operations)."""
    ld = dh[k, D] + q[k] if dh[k, KIND] != 0.0 else dh[k, D]
    ca, sa, la, tw = dh[k, CA], dh[k, SA], dh[k, A], dh[k, TW]
    n0 = n0 - ld * f1
    n1 = n1 + ld * f0
    f1 = s * f0 + c * f1
    n1 = s * n0 + c * n1
    n1 = n1 - la * f2
    n2 = n2 + la * f1
    _, n2 = _x(n1, n2, tw, ca, sa)
    return n2


@jit_exact
def dh_inverse_dynamics(dh, q, qd, qdd, base_accel, tau, scr):
    """tau for (q, qd, qdd) of a DH robot (module docstring): ``dh`` its constants
    (:data:`redysim.algorithms.dh_form.COLUMNS`), ``base_accel`` -g in the base frame, ``scr``
    (nb, >= 8) scratch: each body's wrench (f, n) and cos, sin of its theta."""
    n = q.shape[0]
    w0 = w1 = w2 = 0.0      # the parent's angular velocity, acceleration and the acceleration
    e0 = e1 = e2 = 0.0      # of its origin, in its frame; then body k's in F_k
    a0, a1, a2 = base_accel[0], base_accel[1], base_accel[2]
    x0 = x1 = x2 = 0.0      # the parent's W's first column (W = e~ + w~ w~)
    for k in range(n):
        ca, sa, la = dh[k, CA], dh[k, SA], dh[k, A]
        prismatic, ld, c, s = _joint(dh, q, k)
        scr[k, 6] = c
        scr[k, 7] = s
        tw = dh[k, TW]
        if k == 0:  # the base is at rest: only its acceleration -g turns into F_1
            a1, a2 = _xt(a1, a2, tw, ca, sa)
            a0, a1 = c * a0 + s * a1, c * a1 - s * a0
            if prismatic:
                a2 = a2 + qdd[k]
            else:
                w2 = qd[k]
                e2 = qdd[k]
        else:
            # Tx(a): the acceleration of the point a x of the parent: a + W (a x)
            a0 = a0 + la * x0
            a1 = a1 + la * x1
            a2 = a2 + la * x2
            # Rx(alpha)^T
            w1, w2 = _xt(w1, w2, tw, ca, sa)
            e1, e2 = _xt(e1, e2, tw, ca, sa)
            a1, a2 = _xt(a1, a2, tw, ca, sa)
            # Tz(d): + W' (d z), W' the parent's W in this frame
            a0 = a0 + ld * (w0 * w2 + e1)
            a1 = a1 + ld * (w1 * w2 - e0)
            a2 = a2 - ld * (w0 * w0 + w1 * w1)
            # Rz(theta)^T
            w0, w1 = c * w0 + s * w1, c * w1 - s * w0
            e0, e1 = c * e0 + s * e1, c * e1 - s * e0
            a0, a1 = c * a0 + s * a1, c * a1 - s * a0
            if prismatic:  # + 2 w x (qd z) + qdd z
                t = qd[k] + qd[k]
                a0 = a0 + t * w1
                a1 = a1 - t * w0
                a2 = a2 + qdd[k]
            else:  # w + qd z, e + w x (qd z) + qdd z
                e0 = e0 + w1 * qd[k]
                e1 = e1 - w0 * qd[k]
                e2 = e2 + qdd[k]
                w2 = w2 + qd[k]
        # body k's wrench about O_k
        m = dh[k, M]
        hx, hy, hz = dh[k, HX], dh[k, HY], dh[k, HZ]
        jxx, jxy, jxz, jyy, jyz, jzz = dh[k, JXX], dh[k, JXY], dh[k, JXZ], dh[k, JYY], \
            dh[k, JYZ], dh[k, JZZ]
        xx = w0 * w0
        yy = w1 * w1
        zz = w2 * w2
        xy = w0 * w1
        xz = w0 * w2
        yz = w1 * w2
        x0 = -(yy + zz)
        x1 = xy + e2
        x2 = xz - e1
        W01 = xy - e2
        W11 = -(xx + zz)
        W21 = yz + e0
        W02 = xz + e1
        W12 = yz - e0
        W22 = -(xx + yy)
        scr[k, 0] = m * a0 + (x0 * hx + W01 * hy + W02 * hz)
        scr[k, 1] = m * a1 + (x1 * hx + W11 * hy + W12 * hz)
        scr[k, 2] = m * a2 + (x2 * hx + W21 * hy + W22 * hz)
        g0 = jxx * w0 + jxy * w1 + jxz * w2
        g1 = jxy * w0 + jyy * w1 + jyz * w2
        g2 = jxz * w0 + jyz * w1 + jzz * w2
        scr[k, 3] = (jxx * e0 + jxy * e1 + jxz * e2) + (w1 * g2 - w2 * g1) + (hy * a2 - hz * a1)
        scr[k, 4] = (jxy * e0 + jyy * e1 + jyz * e2) + (w2 * g0 - w0 * g2) + (hz * a0 - hx * a2)
        scr[k, 5] = (jxz * e0 + jyz * e1 + jzz * e2) + (w0 * g1 - w1 * g0) + (hx * a1 - hy * a0)
    # backward: each body's resultant wrench, its joint's force, the wrench moved to the parent
    for k in range(n - 1, -1, -1):
        f0, f1, f2 = scr[k, 0], scr[k, 1], scr[k, 2]
        n0, n1, n2 = scr[k, 3], scr[k, 4], scr[k, 5]
        tau[k] = joint_force(f2 if dh[k, KIND] != 0.0 else n2, _armature(dh, k), 0, qdd[k])
        if k == 0:
            break
        # moved to the parent's frame, added to the parent's own
        f0, f1, f2, n0, n1, n2 = _to_parent(dh, q, k, scr[k, 6], scr[k, 7], f0, f1, f2, n0, n1,
                                            n2)
        scr[k - 1, 0] += f0
        scr[k - 1, 1] += f1
        scr[k - 1, 2] += f2
        scr[k - 1, 3] += n0
        scr[k - 1, 4] += n1
        scr[k - 1, 5] += n2


@inline
def _tz(I, d):
    """A full inertia I (IA numbers, about O_k) moved to O_k - d z (same axes)."""
    b0, b1, b2, b3, b4, b5 = I[6], I[7], I[8], I[9], I[10], I[11]
    # B' = B + d z~ M: rows x, y
    I[6] = b0 - d * I[16]
    I[7] = b1 - d * I[18]
    I[8] = b2 - d * I[19]
    I[9] = b3 + d * I[15]
    I[10] = b4 + d * I[16]
    I[11] = b5 + d * I[17]
    # A' = A + Z, Z = r~ B'^T - B r~
    I[0] = I[0] - d * (I[7] + b1)
    I[3] = I[3] + d * (I[9] + b3)
    I[1] = I[1] + d * (b0 - I[10])
    I[2] = I[2] - d * I[13]
    I[4] = I[4] + d * I[12]


@inline
def _tx(I, a):
    """A full inertia I moved to O - a x (same axes)."""
    b1, b2, b4, b5, b7 = I[7], I[8], I[10], I[11], I[13]
    I[9] = I[9] - a * I[17]
    I[10] = b4 - a * I[19]
    I[11] = b5 - a * I[20]
    I[12] = I[12] + a * I[16]
    I[13] = b7 + a * I[18]
    I[14] = I[14] + a * I[19]
    I[1] = I[1] - a * b2
    I[2] = I[2] + a * b1
    I[3] = I[3] - a * (I[11] + b5)
    I[5] = I[5] + a * (I[13] + b7)
    I[4] = I[4] + a * (b4 - I[14])


@inline
def _sym_turn(p, r, t, ss, cs, cs2, cms):
    """The symmetric 2 x 2 [[p, r], [r, t]] turned by R = [[c, -s], [s, c]]: R X R^T, from
    ss = s^2, cs = c s, cs2 = 2 c s and cms = c^2 - s^2."""
    dl = t - p
    u = ss * dl - cs2 * r
    return p + u, cms * r - cs * dl, t - u


@inline
def _gen_turn(g00, g01, g10, g11, ss, cs):
    """A general 2 x 2 turned by R = [[c, -s], [s, c]]: R G R^T (returns g00, g01, g10, g11)."""
    dl = g11 - g00
    sg = g01 + g10
    u = ss * dl - cs * sg
    v = -(cs * dl + ss * sg)
    return g00 + u, g01 + v, g10 + v, g11 - u


# a full inertia's numbers that a turn about z (about x) mixes: A's symmetric 2 x 2 block and the
# pair beside it, M's likewise, B's general 2 x 2 block, its column and its row along the axis
Z_TURN = (0, 1, 3, 2, 4, 15, 16, 18, 17, 19, 6, 7, 9, 10, 8, 11, 12, 13)
X_TURN = (3, 4, 5, 1, 2, 18, 19, 20, 16, 17, 10, 11, 13, 14, 9, 12, 7, 8)


@inline
def _turn(I, t, c, s, ss, cs, cs2, cms):
    """A full inertia I's axes turned about z (``t`` Z_TURN) or x (X_TURN) by the angle whose
    cos and sin are c, s (ss = s^2, cs = c s, cs2 = 2 c s, cms = c^2 - s^2): R I R^T blockwise,
    about the same point."""
    I[t[0]], I[t[1]], I[t[2]] = _sym_turn(I[t[0]], I[t[1]], I[t[2]], ss, cs, cs2, cms)
    I[t[3]], I[t[4]] = c * I[t[3]] - s * I[t[4]], s * I[t[3]] + c * I[t[4]]
    I[t[5]], I[t[6]], I[t[7]] = _sym_turn(I[t[5]], I[t[6]], I[t[7]], ss, cs, cs2, cms)
    I[t[8]], I[t[9]] = c * I[t[8]] - s * I[t[9]], s * I[t[8]] + c * I[t[9]]
    I[t[10]], I[t[11]], I[t[12]], I[t[13]] = _gen_turn(I[t[10]], I[t[11]], I[t[12]], I[t[13]],
                                                       ss, cs)
    I[t[14]], I[t[15]] = c * I[t[14]] - s * I[t[15]], s * I[t[14]] + c * I[t[15]]  # B's column
    I[t[16]], I[t[17]] = c * I[t[16]] - s * I[t[17]], s * I[t[16]] + c * I[t[17]]  # B's row


@inline
def _rx_right(I, tw):
    """:func:`_turn` about x for a right angle's multiple (a signed permutation of y and z)."""
    I[3], I[4], I[5] = _sym_x(I[3], I[4], I[5], tw)
    I[1], I[2] = _x(I[1], I[2], tw, 0.0, 0.0)
    I[18], I[19], I[20] = _sym_x(I[18], I[19], I[20], tw)
    I[16], I[17] = _x(I[16], I[17], tw, 0.0, 0.0)
    I[10], I[11], I[13], I[14] = _gen_x(I[10], I[11], I[13], I[14], tw)
    I[9], I[12] = _x(I[9], I[12], tw, 0.0, 0.0)
    I[7], I[8] = _x(I[7], I[8], tw, 0.0, 0.0)


@jit_exact
def dh_forward_dynamics(dh, q, qd, tau, base_accel, qdd, scr):
    """qdd of a DH robot by the articulated-body recursion (module docstring). ``dh``: its
    constants; ``base_accel``: -g in the base frame; ``scr`` (nb, SCRATCH_COLUMNS) scratch.
    (No check of the result: the entries (:mod:`.entry`) check it, and the operation counts are
    the dynamics' alone.)"""
    _velocities(dh, q, qd, scr)
    _articulated(dh, q, tau, scr)
    _accelerations(dh, q, base_accel, qdd, scr)


@inline
def _velocities(dh, q, qd, scr):
    """Pass 1, base to tip: angular velocities, the velocity-product accelerations c_k and the
    bodies' velocity biases into the scratch."""
    w0 = w1 = w2 = 0.0
    # forward: k = 1..n
    for k in range(q.shape[0]):
        la = dh[k, A]
        prismatic, ld, c, s = _joint(dh, q, k)
        scr[k, S_C] = c
        scr[k, S_S] = s
        c0 = c1 = c3 = c4 = c5 = 0.0
        hx, hy, hz = dh[k, HX], dh[k, HY], dh[k, HZ]
        if k == 0:  # the base is at rest: w = (0, 0, qd) or 0; the body's bias (zero, or
            # (-qd^2 (J_yz, -J_xz), 0; -qd^2 (h_x, h_y), 0)) has no part along its joint's axis,
            # the one part of the base's body that pass 2 uses
            w0 = w1 = w2 = 0.0
            if not prismatic:
                w2 = qd[k]
            for i in range(S_C0, S_P + 6):
                scr[k, i] = 0.0
            continue
        ca, sa, tw = dh[k, CA], dh[k, SA], dh[k, TW]
        if k == 1 and dh[0, KIND] == 0.0:  # the parent turns about its z alone: w0 = w1 = 0
            if tw == ANY_TWIST:
                w1, w2 = sa * w2, ca * w2                       # in F'
            else:
                w1, w2 = _xt(0.0, w2, tw, ca, sa)
            u0 = w1 * ld
            u1 = w2 * la
            u2 = -(w1 * la)
            v0 = w1 * u2 - w2 * u1
            v1 = w2 * u0
            v2 = -(w1 * u0)
            w0, w1 = s * w1, c * w1                              # in F_k
        else:
            w1, w2 = _xt(w1, w2, tw, ca, sa)                     # in F'
            # the acceleration of O_k as a point of the parent: w x (w x r), r = (a, 0, d)
            u0 = w1 * ld
            u1 = w2 * la - w0 * ld
            u2 = -(w1 * la)
            v0 = w1 * u2 - w2 * u1
            v1 = w2 * u0 - w0 * u2
            v2 = w0 * u1 - w1 * u0
            w0, w1 = c * w0 + s * w1, c * w1 - s * w0            # in F_k
        c3 = c * v0 + s * v1
        c4 = c * v1 - s * v0
        c5 = v2
        if prismatic:  # + 2 w x (qd z)
            t = qd[k] + qd[k]
            c3 = c3 + t * w1
            c4 = c4 - t * w0
        else:  # w x (qd z)
            c0 = w1 * qd[k]
            c1 = -(w0 * qd[k])
            w2 = w2 + qd[k]
        scr[k, S_C0] = c0
        scr[k, S_C1] = c1
        scr[k, S_C3] = c3
        scr[k, S_C4] = c4
        scr[k, S_C5] = c5
        # the body's bias (w x J w, w x (w x h))
        g0 = dh[k, JXX] * w0 + dh[k, JXY] * w1 + dh[k, JXZ] * w2
        g1 = dh[k, JXY] * w0 + dh[k, JYY] * w1 + dh[k, JYZ] * w2
        g2 = dh[k, JXZ] * w0 + dh[k, JYZ] * w1 + dh[k, JZZ] * w2
        scr[k, S_P] = w1 * g2 - w2 * g1
        scr[k, S_P + 1] = w2 * g0 - w0 * g2
        scr[k, S_P + 2] = w0 * g1 - w1 * g0
        y0 = w1 * hz - w2 * hy
        y1 = w2 * hx - w0 * hz
        y2 = w0 * hy - w1 * hx
        scr[k, S_P + 3] = w1 * y2 - w2 * y1
        scr[k, S_P + 4] = w2 * y0 - w0 * y2
        scr[k, S_P + 5] = w0 * y1 - w1 * y0


@inline
def _articulated(dh, q, tau, scr):
    """Pass 2, tip to base: articulated inertias and biases, projected and moved to the parent
    (into its scratch row's child inertia and bias). A revolute joint without armature takes
    the zero-structured steps (module docstring); a prismatic joint, or any joint with armature
    (whose projection has no zero row), the general ones."""
    n = q.shape[0]
    base_turns = dh[0, KIND] == 0.0
    # backward: k = n..1
    for k in range(n - 1, -1, -1):
        revolute = dh[k, KIND] == 0.0
        tip = k == n - 1
        plain = dh[k, ARMATURE] == 0.0
        if revolute and k == 0 and not tip:
            _base_pivot(dh, tau, scr)
            break
        # the child's inertia and bias, sliced once here and handed to the helpers (a slice of
        # its own in each, with the armature's elimination inlined, made this pass 4 % slower
        # than be08d5d's one function: benchmarks/ab_evaluator.py's PUMA 560 forward row)
        I = scr[k, S_CHILD_I:S_CHILD_I + IA]
        P = scr[k, S_CHILD_P:S_CHILD_P + 6]
        p = _with_own(dh, k, tip, not (revolute and plain), I, P, scr)
        if revolute and plain and tip:
            p, J = _revolute_tip(dh, tau, k, p, scr)
        elif revolute and plain:
            p, J = _revolute_projection(dh, tau, k, p, I, scr)
        else:
            p, J = _general_step(dh, q, tau, k, revolute, p, scr), NO_J
        if k == 0:  # (the base's body: nothing moves on to a base at rest)
            break
        if revolute and plain:
            _revolute_move(dh, k, tip, base_turns, J, scr)
        # the bias moved to the parent, as the inverse dynamics moves a wrench (to a base's
        # body that turns about z, its moment about z alone)
        p0, p1, p2, p3, p4, p5 = p
        Q = scr[k - 1, S_CHILD_P:S_CHILD_P + 6]
        if k == 1 and base_turns:
            Q[2] = _to_parent_nz(dh, q, k, scr[k, S_C], scr[k, S_S], p3, p4, p5, p0, p1, p2)
        else:
            Q[3], Q[4], Q[5], Q[0], Q[1], Q[2] = _to_parent(dh, q, k, scr[k, S_C], scr[k, S_S],
                                                            p3, p4, p5, p0, p1, p2)


@inline
def _base_pivot(dh, tau, scr):
    """The base's body, revolute: only its articulated inertia's angular-z column (A_zz and B's
    z row, the body's own added to what its child moved here) and its bias's moment about z
    (its own is zero) are needed (pass 3 has nothing to move to a base at rest)."""
    I = scr[0, S_CHILD_I:S_CHILD_I + IA]
    hx, hy = dh[0, HX], dh[0, HY]
    pivot = joint_inertia(I[5] + dh[0, JZZ], _armature(dh, 0), 0)
    inv = 1.0 / pivot
    scr[0, S_PIVOT] = pivot
    scr[0, S_UD] = scr[0, S_UD + 1] = 0.0
    scr[0, S_UD + 2] = 1.0
    scr[0, S_UD + 3] = (I[12] - hy) * inv
    scr[0, S_UD + 4] = (I[13] + hx) * inv
    scr[0, S_UD + 5] = I[14] * inv
    scr[0, S_UDIV] = (tau[0] - scr[0, S_CHILD_P + 2]) * inv


@inline
def _with_own(dh, k, tip, full, I, P, scr):
    """Body k's own inertia and bias added to what its child moved here (at the tip: its own
    alone, its inertia written only when ``full``: the zero-structured tip reads constants).
    Returns the bias p = (n, f)."""
    m = dh[k, M]
    hx, hy, hz = dh[k, HX], dh[k, HY], dh[k, HZ]
    if tip:  # no child: the body's own bias
        if full:  # its own inertia [[J, h~], [h~^T, m 1]]
            I[0], I[1], I[2], I[3], I[4], I[5] = dh[k, JXX], dh[k, JXY], dh[k, JXZ], \
                dh[k, JYY], dh[k, JYZ], dh[k, JZZ]
            I[6], I[7], I[8], I[9], I[10], I[11] = 0.0, -hz, hy, hz, 0.0, -hx
            I[12], I[13], I[14] = -hy, hx, 0.0
            I[15], I[16], I[17], I[18], I[19], I[20] = m, 0.0, 0.0, m, 0.0, m
        return (scr[k, S_P], scr[k, S_P + 1], scr[k, S_P + 2], scr[k, S_P + 3],
                scr[k, S_P + 4], scr[k, S_P + 5])
    # the body's own added to its child's: A += J, B += h~, M += m 1
    I[0] = I[0] + dh[k, JXX]
    I[1] = I[1] + dh[k, JXY]
    I[2] = I[2] + dh[k, JXZ]
    I[3] = I[3] + dh[k, JYY]
    I[4] = I[4] + dh[k, JYZ]
    I[5] = I[5] + dh[k, JZZ]
    I[7] = I[7] - hz
    I[8] = I[8] + hy
    I[9] = I[9] + hz
    I[11] = I[11] - hx
    I[12] = I[12] - hy
    I[13] = I[13] + hx
    I[15] = I[15] + m
    I[18] = I[18] + m
    I[20] = I[20] + m
    return (P[0] + scr[k, S_P], P[1] + scr[k, S_P + 1], P[2] + scr[k, S_P + 2],
            P[3] + scr[k, S_P + 3], P[4] + scr[k, S_P + 4], P[5] + scr[k, S_P + 5])


@inline
def _revolute_tip(dh, tau, k, p, scr):
    """The last body, revolute about z, without armature: its projected inertia and U/D are
    constants (dh_form's tip_* columns); of U, B's zz and M's xz, yz are zero, so U/D's linear
    z, and the projection leaves M's xz, yz zero, M_zz = m and B's z column (hy, -hx).
    Returns the projected bias and the projected inertia moved by Tz(d) (15 numbers)."""
    m, hx, hy = dh[k, M], dh[k, HX], dh[k, HY]
    p0, p1, p2, p3, p4, p5 = p
    c0, c1, c3, c4, c5 = scr[k, S_C0], scr[k, S_C1], scr[k, S_C3], scr[k, S_C4], scr[k, S_C5]
    scr[k, S_PIVOT] = dh[k, JZZ]
    inv = dh[k, TIP_INV]
    d3 = dh[k, TIP_D3]
    d4 = dh[k, TIP_D4]
    u = tau[k] - p2
    scr[k, S_UD + 2] = 1.0
    scr[k, S_UD + 3] = d3
    scr[k, S_UD + 4] = d4
    scr[k, S_UD + 5] = 0.0
    scr[k, S_UDIV] = u * inv
    if k == 0:  # the base's body (as _general_step's)
        scr[k, S_UD] = scr[k, S_UD + 1] = 0.0
        return p, NO_J
    d0 = dh[k, TIP_D0]
    d1 = dh[k, TIP_D1]
    scr[k, S_UD] = d0
    scr[k, S_UD + 1] = d1
    a00, a01, a11 = dh[k, TIP_A00], dh[k, TIP_A01], dh[k, TIP_A11]
    b00, b01, b10, b11 = dh[k, TIP_B00], dh[k, TIP_B01], dh[k, TIP_B10], dh[k, TIP_B11]
    m00, m01, m11 = dh[k, TIP_M00], dh[k, TIP_M01], dh[k, TIP_M11]
    p0 = p0 + (a00 * c0 + a01 * c1 + b00 * c3 + b01 * c4 + hy * c5) + d0 * u
    p1 = p1 + (a01 * c0 + a11 * c1 + b10 * c3 + b11 * c4 - hx * c5) + d1 * u
    p2 = tau[k]
    p3 = p3 + (b00 * c0 + b10 * c1 + m00 * c3 + m01 * c4) + d3 * u
    p4 = p4 + (b01 * c0 + b11 * c1 + m01 * c3 + m11 * c4) + d4 * u
    p5 = p5 + (hy * c0 - hx * c1 + m * c5)
    # moved by Tz(d): constants too
    return (p0, p1, p2, p3, p4, p5), (
        dh[k, TIP_ZA00], dh[k, TIP_ZA01], dh[k, TIP_ZA11], m00, m01, 0.0, m11, 0.0, m,
        dh[k, TIP_ZB00], dh[k, TIP_ZB01], hy, dh[k, TIP_ZB10], dh[k, TIP_ZB11], -hx)


@inline
def _revolute_projection(dh, tau, k, p, I, scr):
    """Body k, revolute about z, without armature: U = I[:, angular z], D = A_zz; the projected
    inertia (its angular-z row and column zero), the bias p + I^a c + (U/D) u, and the inertia
    moved by Tz(d) (returned as :func:`_revolute_tip`'s 15 numbers)."""
    p0, p1, p2, p3, p4, p5 = p
    c0, c1, c3, c4, c5 = scr[k, S_C0], scr[k, S_C1], scr[k, S_C3], scr[k, S_C4], scr[k, S_C5]
    scr[k, S_PIVOT] = I[5]
    inv = 1.0 / I[5]
    d3 = I[12] * inv
    d4 = I[13] * inv
    d5 = I[14] * inv
    u = tau[k] - p2
    scr[k, S_UD + 2] = 1.0
    scr[k, S_UD + 3] = d3
    scr[k, S_UD + 4] = d4
    scr[k, S_UD + 5] = d5
    scr[k, S_UDIV] = u * inv
    d0 = I[2] * inv
    d1 = I[4] * inv
    scr[k, S_UD] = d0
    scr[k, S_UD + 1] = d1
    # projected: I - (U/D) U^T; its angular-z row and column are zero
    a00 = I[0] - d0 * I[2]
    a01 = I[1] - d0 * I[4]
    a11 = I[3] - d1 * I[4]
    b00 = I[6] - d0 * I[12]
    b01 = I[7] - d0 * I[13]
    b02 = I[8] - d0 * I[14]
    b10 = I[9] - d1 * I[12]
    b11 = I[10] - d1 * I[13]
    b12 = I[11] - d1 * I[14]
    m00 = I[15] - d3 * I[12]
    m01 = I[16] - d3 * I[13]
    m02 = I[17] - d3 * I[14]
    m11 = I[18] - d4 * I[13]
    m12 = I[19] - d4 * I[14]
    m22 = I[20] - d5 * I[14]
    # bias: p + I^a c + (U/D) u; its angular z is tau
    p0 = p0 + (a00 * c0 + a01 * c1 + b00 * c3 + b01 * c4 + b02 * c5) + d0 * u
    p1 = p1 + (a01 * c0 + a11 * c1 + b10 * c3 + b11 * c4 + b12 * c5) + d1 * u
    p2 = tau[k]
    p3 = p3 + (b00 * c0 + b10 * c1 + m00 * c3 + m01 * c4 + m02 * c5) + d3 * u
    p4 = p4 + (b01 * c0 + b11 * c1 + m01 * c3 + m11 * c4 + m12 * c5) + d4 * u
    p5 = p5 + (b02 * c0 + b12 * c1 + m02 * c3 + m12 * c4 + m22 * c5) + d5 * u
    ld = dh[k, D]
    # Tz(d), on the zero-structured inertia: B rows x, y; A's xx, xy, yy
    nb00 = b00 - ld * m01
    nb01 = b01 - ld * m11
    nb02 = b02 - ld * m12
    nb10 = b10 + ld * m00
    nb11 = b11 + ld * m01
    nb12 = b12 + ld * m02
    a00 = a00 - ld * (nb01 + b01)
    a11 = a11 + ld * (nb10 + b10)
    a01 = a01 + ld * (b00 - nb11)
    return (p0, p1, p2, p3, p4, p5), (a00, a01, a11, m00, m01, m02, m11, m12, m22,
                                      nb00, nb01, nb02, nb10, nb11, nb12)


@inline
def _revolute_move(dh, k, tip, base_turns, J15, scr):
    """A revolute body's projected inertia (:func:`_revolute_projection`'s 15 numbers, moved by
    Tz(d)) turned by Rz(theta), then Rx(alpha) and Tx(a) into its parent's child inertia (to a
    base's body that turns about z, the four numbers it uses)."""
    a00, a01, a11, m00, m01, m02, m11, m12, m22, nb00, nb01, nb02, nb10, nb11, nb12 = J15
    c, s = scr[k, S_C], scr[k, S_S]
    la = dh[k, A]
    # Rz(theta)
    ss = s * s
    cs = c * s
    cs2 = cs + cs
    cms = 1.0 - (ss + ss)
    a00, a01, a11 = _sym_turn(a00, a01, a11, ss, cs, cs2, cms)
    m00, m01, m11 = _sym_turn(m00, m01, m11, ss, cs, cs2, cms)
    if not tip:  # (the tip's are zero)
        m02, m12 = c * m02 - s * m12, s * m02 + c * m12
    b00, b01, b10, b11 = _gen_turn(nb00, nb01, nb10, nb11, ss, cs)
    b02, b12 = c * nb02 - s * nb12, s * nb02 + c * nb12
    # Rx(alpha): A and B have no z row yet
    ca, sa, tw = dh[k, CA], dh[k, SA], dh[k, TW]
    J = scr[k - 1, S_CHILD_I:S_CHILD_I + IA]
    y1, y2 = _x(b11, b12, tw, ca, sa)    # B Rx^T, row y
    if k == 1 and base_turns:
        # the base's body uses A_zz and B's z row alone (_base_pivot): those four numbers
        # of the parent's, by the steps below (Rx, then _tx's rows for them)
        j16, _ = _x(m01, m02, tw, ca, sa)
        if tw == ANY_TWIST:
            j5 = dh[k, S2] * a11
            j12 = sa * b10
            j13 = sa * y1
            j14 = sa * y2
            j18, j19, _ = _sym_turn(m11, m12, m22, dh[k, S2], dh[k, CS], dh[k, CS2],
                                    dh[k, CMS])
        else:
            _, _, j5 = _sym_x(a11, 0.0, 0.0, tw)
            _, j12 = _x(b10, 0.0, tw, ca, sa)
            _, j13 = _x(y1, 0.0, tw, ca, sa)
            _, j14 = _x(y2, 0.0, tw, ca, sa)
            j18, j19, _ = _sym_x(m11, m12, m22, tw)
        J[12] = j12 + la * j16
        J[13] = j13 + la * j18
        J[14] = j14 + la * j19
        J[5] = j5 + la * (J[13] + j13)
        return
    J[0] = a00
    J[6] = b00
    J[15] = m00
    J[7], J[8] = _x(b01, b02, tw, ca, sa)    # row x
    J[16], J[17] = _x(m01, m02, tw, ca, sa)
    if tw == ANY_TWIST:
        s2, csa, cs2a, cmsa = dh[k, S2], dh[k, CS], dh[k, CS2], dh[k, CMS]
        J[1] = ca * a01
        J[2] = sa * a01
        J[3] = dh[k, C2] * a11
        J[4] = csa * a11
        J[5] = s2 * a11
        J[9] = ca * b10
        J[10] = ca * y1
        J[11] = ca * y2
        J[12] = sa * b10
        J[13] = sa * y1
        J[14] = sa * y2
        J[18], J[19], J[20] = _sym_turn(m11, m12, m22, s2, csa, cs2a, cmsa)
    else:  # a signed permutation of y and z
        J[1], J[2] = _x(a01, 0.0, tw, ca, sa)
        J[3], J[4], J[5] = _sym_x(a11, 0.0, 0.0, tw)
        J[9], J[12] = _x(b10, 0.0, tw, ca, sa)
        J[10], J[13] = _x(y1, 0.0, tw, ca, sa)
        J[11], J[14] = _x(y2, 0.0, tw, ca, sa)
        J[18], J[19], J[20] = _sym_x(m11, m12, m22, tw)
    _tx(J, la)


@inline
def _general_step(dh, q, tau, k, revolute, p, scr):
    """Body k's general step: a prismatic joint (U = I[:, linear z], D = M_zz), or either kind
    with armature (D = P^T I P + armature: :mod:`.articulated`'s elimination, whose projection
    keeps every number), then the projected inertia moved into the parent's child inertia by
    Tz(d), Rz(theta), Rx(alpha) and Tx(a) on all 21 numbers. Returns the projected bias."""
    if dh[k, ARMATURE] == 0.0:  # prismatic along z, its projection's linear-z row zero
        p = _prismatic_projection(dh, tau, k, p, scr)
    else:
        p = _armature_projection(dh, tau, k, revolute, p, scr)
    if k == 0:  # the base's body: nothing moves on
        return p
    J = scr[k - 1, S_CHILD_I:S_CHILD_I + IA]
    c, s = scr[k, S_C], scr[k, S_S]
    ld = dh[k, D] if revolute else dh[k, D] + q[k]
    ss = s * s
    cs = c * s
    cs2 = cs + cs
    cms = 1.0 - (ss + ss)
    _tz(J, ld)
    _turn(J, Z_TURN, c, s, ss, cs, cs2, cms)
    if dh[k, TW] == ANY_TWIST:
        _turn(J, X_TURN, dh[k, CA], dh[k, SA], dh[k, S2], dh[k, CS], dh[k, CS2], dh[k, CMS])
    else:
        _rx_right(J, dh[k, TW])
    _tx(J, dh[k, A])
    return p


@inline
def _prismatic_projection(dh, tau, k, p, scr):
    """A prismatic body without armature: U = I[:, linear z], D = M_zz; the projection (every
    number but the linear-z row and column, which are zero) into the parent's child inertia,
    and the bias p + I^a c + (U/D) u returned."""
    I = scr[k, S_CHILD_I:S_CHILD_I + IA]
    p0, p1, p2, p3, p4, p5 = p
    c0, c1, c3, c4 = scr[k, S_C0], scr[k, S_C1], scr[k, S_C3], scr[k, S_C4]
    scr[k, S_PIVOT] = I[20]
    inv = 1.0 / I[20]
    d3 = I[17] * inv
    d4 = I[19] * inv
    u = tau[k] - p5
    scr[k, S_UD + 3] = d3
    scr[k, S_UD + 4] = d4
    scr[k, S_UD + 5] = 1.0
    scr[k, S_UDIV] = u * inv
    if k == 0:  # (as for a revolute)
        scr[k, S_UD] = scr[k, S_UD + 1] = scr[k, S_UD + 2] = 0.0
        return p
    d0 = I[8] * inv
    d1 = I[11] * inv
    d2 = I[14] * inv
    scr[k, S_UD] = d0
    scr[k, S_UD + 1] = d1
    scr[k, S_UD + 2] = d2
    J = scr[k - 1, S_CHILD_I:S_CHILD_I + IA]
    # projected (every number but the linear-z row and column), then the bias
    u0, u1, u2, u3, u4 = I[8], I[11], I[14], I[17], I[19]
    J[0] = I[0] - d0 * u0
    J[1] = I[1] - d0 * u1
    J[2] = I[2] - d0 * u2
    J[3] = I[3] - d1 * u1
    J[4] = I[4] - d1 * u2
    J[5] = I[5] - d2 * u2
    J[6] = I[6] - d0 * u3
    J[7] = I[7] - d0 * u4
    J[8] = 0.0
    J[9] = I[9] - d1 * u3
    J[10] = I[10] - d1 * u4
    J[11] = 0.0
    J[12] = I[12] - d2 * u3
    J[13] = I[13] - d2 * u4
    J[14] = 0.0
    J[15] = I[15] - d3 * u3
    J[16] = I[16] - d3 * u4
    J[17] = 0.0
    J[18] = I[18] - d4 * u4
    J[19] = 0.0
    J[20] = 0.0
    p0 = p0 + (J[0] * c0 + J[1] * c1 + J[6] * c3 + J[7] * c4) + d0 * u
    p1 = p1 + (J[1] * c0 + J[3] * c1 + J[9] * c3 + J[10] * c4) + d1 * u
    p2 = p2 + (J[2] * c0 + J[4] * c1 + J[12] * c3 + J[13] * c4) + d2 * u
    p3 = p3 + (J[6] * c0 + J[9] * c1 + J[15] * c3 + J[16] * c4) + d3 * u
    p4 = p4 + (J[7] * c0 + J[10] * c1 + J[16] * c3 + J[18] * c4) + d4 * u
    p5 = tau[k]
    return p0, p1, p2, p3, p4, p5


@jit_exact
def _armature_projection(dh, tau, k, revolute, p, scr):
    """A joint with armature, either kind: its axis (angular or linear z) eliminated from the
    articulated inertia I by :func:`.articulated.eliminate_axis` (D = P^T I P + armature), the
    projection (all 21 numbers) into the parent's child inertia (unless the base's) and the
    bias p + I^a c + U phitil returned.

    Compiled on its own (IEEE as written, as the kernel) and called, not inlined: a robot
    without armature never takes it, and inlined, its code (the elimination's) shaped the
    machine code of the steps that robot takes in the same loop, which LLVM cannot tell are
    the hot ones (benchmarks/ab_evaluator.py: the PUMA 560's forward row 0.96 of be08d5d)."""
    I = scr[k, S_CHILD_I:S_CHILD_I + IA]
    Mhat = (I[0], I[1], I[2], I[3], I[4], I[5], I[6], I[7], I[8], I[9], I[10], I[11], I[12],
            I[13], I[14], I[15], I[16], I[17], I[18], I[19], I[20])
    if revolute:
        Mbar, nf, pivot, _, ptil, ud = eliminate_axis(REVOLUTE, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0,
                                                      tau[k], _armature(dh, k), 0, Mhat, p)
    else:
        Mbar, nf, pivot, _, ptil, ud = eliminate_axis(PRISMATIC, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
                                                      tau[k], _armature(dh, k), 0, Mhat, p)
    scr[k, S_PIVOT] = pivot
    for i in range(6):
        scr[k, S_UD + i] = ud[i]
    scr[k, S_UDIV] = ptil
    if k > 0:
        J = scr[k - 1, S_CHILD_I:S_CHILD_I + IA]
        for i in range(IA):
            J[i] = Mbar[i]
    return add6(nf, articulated_bias((scr[k, S_C0], scr[k, S_C1], 0.0, scr[k, S_C3],
                                      scr[k, S_C4], scr[k, S_C5]), Mbar))


@inline
def _accelerations(dh, q, base_accel, qdd, scr):
    """Pass 3, base to tip: accelerations and qdd (a joint with armature: U/D's every number;
    without, U/D's along its own axis is 1)."""
    e0 = e1 = e2 = 0.0
    a0, a1, a2 = base_accel[0], base_accel[1], base_accel[2]
    # forward: k = 1..n
    for k in range(q.shape[0]):
        c, s = scr[k, S_C], scr[k, S_S]
        ca, sa = dh[k, CA], dh[k, SA]
        tw = dh[k, TW]
        ud = scr[k, S_UD:S_UD + 6]
        revolute = dh[k, KIND] == 0.0
        plain = dh[k, ARMATURE] == 0.0
        if k == 0:  # the base is at rest: e = 0, a = -g in F_1
            a1, a2 = _xt(a1, a2, tw, ca, sa)
            a0, a1 = c * a0 + s * a1, c * a1 - s * a0
            if revolute:
                x = scr[k, S_UDIV] - (ud[3] * a0 + ud[4] * a1 + ud[5] * a2)
                e2 = x
            else:
                if plain:
                    x = scr[k, S_UDIV] - (ud[3] * a0 + ud[4] * a1 + a2)
                else:
                    x = scr[k, S_UDIV] - (ud[3] * a0 + ud[4] * a1 + ud[5] * a2)
                a2 = a2 + x
            qdd[k] = x
            continue
        la = dh[k, A]
        ld = dh[k, D] if revolute else dh[k, D] + q[k]
        if k == 1 and dh[0, KIND] == 0.0:  # the parent's e = (0, 0, e2)
            a1 = a1 + la * e2
            if tw == ANY_TWIST:
                e1, e2 = sa * e2, ca * e2
            else:
                e1, e2 = _xt(0.0, e2, tw, ca, sa)
            a1, a2 = _xt(a1, a2, tw, ca, sa)
            a0 = a0 + ld * e1
            e0, e1 = s * e1, c * e1
        else:
            a1 = a1 + la * e2
            a2 = a2 - la * e1
            e1, e2 = _xt(e1, e2, tw, ca, sa)
            a1, a2 = _xt(a1, a2, tw, ca, sa)
            a0 = a0 + ld * e1
            a1 = a1 - ld * e0
            e0, e1 = c * e0 + s * e1, c * e1 - s * e0
        a0, a1 = c * a0 + s * a1, c * a1 - s * a0
        e0 = e0 + scr[k, S_C0]
        e1 = e1 + scr[k, S_C1]
        a0 = a0 + scr[k, S_C3]
        a1 = a1 + scr[k, S_C4]
        a2 = a2 + scr[k, S_C5]
        if not plain:
            x = scr[k, S_UDIV] - (ud[0] * e0 + ud[1] * e1 + ud[2] * e2 + ud[3] * a0
                                  + ud[4] * a1 + ud[5] * a2)
        elif revolute:
            x = scr[k, S_UDIV] - (ud[0] * e0 + ud[1] * e1 + e2 + ud[3] * a0 + ud[4] * a1
                                  + ud[5] * a2)
        else:
            x = scr[k, S_UDIV] - (ud[0] * e0 + ud[1] * e1 + ud[2] * e2 + ud[3] * a0
                                  + ud[4] * a1 + a2)
        if revolute:
            e2 = e2 + x
        else:
            a2 = a2 + x
        qdd[k] = x
