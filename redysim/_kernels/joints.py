"""Joint calculations: the one place that knows joint kinds and axes (spatial_v2's ``jcalc``).

A joint is a sequence of elementary axes (see :data:`redysim.chain.JOINT_TYPES`); this module maps
(kind, axis, q_j) to the axis's motion-subspace column P (a 6-vector in the world frame) and its
effect on the link frame: a rotation of the frame (revolute) or a translation of the joint's origin
(prismatic). The recursions call :func:`jcalc` and never branch on the joint type themselves.

References:
    Agarwal et al., Eq. (4): P_k = [e_k; 0] for a revolute and [0; e_k] for a prismatic axis.
"""

from __future__ import annotations

import math

from .._jit import inline

REVOLUTE = 0
PRISMATIC = 1


@inline
def rotate_about_axis(R, code, u, qj):
    """R <- R Rot(u, qj) in place. ``code`` 0, 1, 2 is the x, y or z axis (two columns mix);
    3 is a general unit vector u (Rodrigues)."""
    c = math.cos(qj)
    s = math.sin(qj)
    if code < 3:
        ia = (code + 1) % 3
        ib = (code + 2) % 3
        for r in range(3):
            xa = R[r, ia]
            xb = R[r, ib]
            R[r, ia] = c * xa + s * xb
            R[r, ib] = c * xb - s * xa
    else:
        u0, u1, u2 = u[0], u[1], u[2]
        t = 1.0 - c
        g00 = c + t * u0 * u0
        g01 = t * u0 * u1 - s * u2
        g02 = t * u0 * u2 + s * u1
        g10 = t * u1 * u0 + s * u2
        g11 = c + t * u1 * u1
        g12 = t * u1 * u2 - s * u0
        g20 = t * u2 * u0 - s * u1
        g21 = t * u2 * u1 + s * u0
        g22 = c + t * u2 * u2
        for r in range(3):
            x0 = R[r, 0]
            x1 = R[r, 1]
            x2 = R[r, 2]
            R[r, 0] = x0 * g00 + x1 * g10 + x2 * g20
            R[r, 1] = x0 * g01 + x1 * g11 + x2 * g21
            R[r, 2] = x0 * g02 + x1 * g12 + x2 * g22


@inline
def jcalc(kind, code, u, qj, R, O, p):
    """Apply one elementary joint axis.

    Writes the axis's motion-subspace column p = [e; 0] (revolute) or [0; e] (prismatic), with e
    the axis in the world frame (R u, R the frame before this axis), then moves the frame: R <- R
    Rot(u, qj) for a revolute, O <- O + e qj for a prismatic axis.
    """
    if code < 3:
        e0 = R[0, code]
        e1 = R[1, code]
        e2 = R[2, code]
    else:
        e0 = R[0, 0] * u[0] + R[0, 1] * u[1] + R[0, 2] * u[2]
        e1 = R[1, 0] * u[0] + R[1, 1] * u[1] + R[1, 2] * u[2]
        e2 = R[2, 0] * u[0] + R[2, 1] * u[1] + R[2, 2] * u[2]
    if kind == REVOLUTE:
        p[0] = e0
        p[1] = e1
        p[2] = e2
        p[3] = 0.0
        p[4] = 0.0
        p[5] = 0.0
        rotate_about_axis(R, code, u, qj)
    else:
        p[0] = 0.0
        p[1] = 0.0
        p[2] = 0.0
        p[3] = e0
        p[4] = e1
        p[5] = e2
        O[0] += e0 * qj
        O[1] += e1 * qj
        O[2] += e2 * qj
