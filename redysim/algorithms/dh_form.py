"""A serial robot's Denavit-Hartenberg form: when a model is one, and its constants for the
DH-specialised kernels (:mod:`redysim.algorithms._kernels.dh`).

A model has the DH form when it is a serial chain (body k hangs from body k - 1) whose every joint
is one revolute (R) or prismatic (P) axis along its frame's z, placed in the parent's frame by

    Rx(alpha) Tx(a) Rz(theta) Tz(d)            (Craig's, modified, DH transform)

with any constants alpha, a, theta, d: the joint frame's rotation is Rx(alpha) Rz(theta) (its
(0, 2) entry zero), its origin a x + d z' (z' = Rx(alpha) z, the joint's axis in the parent).
Every model :mod:`redysim.io.dh` builds from a standard or modified DH table has it, and so may a
URDF or MJCF robot whose frames are DH frames. A joint's q is added to theta (R) or to d (P).

The test is exact up to rounding: the decomposition must give back the model's placement to
``PLACEMENT_TOL`` (a few units in the last place of its numbers), so that the specialised kernels
compute the model the general ones do. A placement off by more (a frame misaligned by 1e-9 rad,
say) is not DH, and the general kernels run it.

Per joint, the constants (:data:`COLUMNS`, one row each): the joint type (0 R, 1 P), cos and sin
of alpha with their squares and product (the kernels rotate symmetric blocks about x with them),
a, d, theta, the body's mass, first moment m c and inertia about its origin (the joint's axis
point O_k), in its own frame, and whether alpha is a right angle's multiple (0, 90, -90 or 180
degrees to rounding: most industrial arms' twists, the PUMA 560's and the Stanford arm's among
them), whose turns about x the kernels do without arithmetic; and, on the last row when the
last joint is revolute, that body's articulated inertia projected for its joint
(:func:`tip_columns`: the body's own, so a constant in its frame): the numbers the kernels
read, arithmetic done once here.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from redysim.algorithms._kernels.bundles import DH_COLUMNS, DH_TIP

if TYPE_CHECKING:
    from redysim.model.tree import Model

COLUMNS = DH_COLUMNS
"""The constants' columns (:data:`redysim.algorithms._kernels.bundles.DH_COLUMNS`, the kernels'
layout table)."""
PLACEMENT_TOL = 8 * np.finfo(float).eps  # relative to the placement's largest number (and 1)
# twists that are right angles' multiples: the twist column's code -> (cos, sin) alpha; their
# turns about x are signed permutations (redysim.algorithms._kernels.dh)
RIGHT_ANGLES = {1.0: (1.0, 0.0), 2.0: (0.0, 1.0), 3.0: (0.0, -1.0), 4.0: (-1.0, 0.0)}


def dh_constants(model: Model) -> np.ndarray | None:
    """(nb, len(COLUMNS)) the DH kernels' constants of ``model``, or None when it does not have
    the DH form (module docstring): it is no serial chain of single R and P axes along z, has
    loops or couplings, or some joint's placement is no DH transform."""
    return None if dh_problem(model) else _constants(model)


def dh_problem(model: Model) -> str | None:
    """Why ``model`` does not have the DH form (for messages), or None when it does."""
    if model.cuts or model.couplings:
        return "it has closed loops or coupled joints"
    if not model.is_chain:
        return "it is not a serial chain"
    if model.n_v != model.n_bodies or any(t not in ("R", "P") for t in model.joint_types):
        return "not every joint is one revolute or prismatic axis"
    u = np.asarray(model.dof_u)
    if not np.array_equal(u, np.tile([0.0, 0.0, 1.0], (model.n_v, 1))):
        k = int(np.flatnonzero((u != [0.0, 0.0, 1.0]).any(axis=1))[0])
        return f"joint {model.joint_names[k]!r} does not turn or slide along its frame's z"
    for k in range(model.n_bodies):
        if _decompose(model.placement_R[k], model.placement_p[k]) is None:
            return (f"joint {model.joint_names[k]!r} is not placed by a DH transform "
                    "Rx(alpha) Tx(a) Rz(theta) Tz(d)")
    return None


def _decompose(R: np.ndarray, p: np.ndarray) -> tuple[float, float, float, float] | None:
    """(alpha, a, theta, d) with Rx(alpha) Rz(theta) = R and a x + d Rx(alpha) z = p to
    PLACEMENT_TOL, or None."""
    scale = max(1.0, float(np.abs(p).max()))
    alpha = math.atan2(-R[1, 2], R[2, 2])
    theta = math.atan2(-R[0, 1], R[0, 0])
    ca, sa, ct, st = math.cos(alpha), math.sin(alpha), math.cos(theta), math.sin(theta)
    back = np.array([[ct, -st, 0.0], [ca * st, ca * ct, -sa], [sa * st, sa * ct, ca]])
    a = float(p[0])
    d = float(-sa * p[1] + ca * p[2])
    off = max(abs(p[1] + sa * d), abs(p[2] - ca * d))
    if np.abs(back - R).max() > PLACEMENT_TOL or off > PLACEMENT_TOL * scale:
        return None
    return alpha, a, theta, d


def _constants(model: Model) -> np.ndarray:
    out = np.zeros((model.n_bodies, len(DH_COLUMNS)))
    for k in range(model.n_bodies):
        decomposed = _decompose(model.placement_R[k], model.placement_p[k])
        assert decomposed is not None  # dh_problem said so
        alpha, a, theta, d = decomposed
        ca, sa = math.cos(alpha), math.sin(alpha)
        twist = 0.0
        for code, (c, s) in RIGHT_ANGLES.items():  # within rounding of a right angle's multiple
            if abs(ca - c) <= PLACEMENT_TOL and abs(sa - s) <= PLACEMENT_TOL:
                twist, ca, sa = code, c, s
        J = model.inertia_O[k]
        out[k, :DH_TIP] = (0.0 if model.joint_types[k] == "R" else 1.0, ca, sa, ca * ca,
                           sa * sa, ca * sa, 2.0 * ca * sa, ca * ca - sa * sa, a, d, theta,
                           model.mass[k], *model.mass_com[k], J[0, 0], J[0, 1], J[0, 2],
                           J[1, 1], J[1, 2], J[2, 2], twist, model.armature[k])
    if model.joint_types[-1] == "R":
        out[-1, DH_TIP:] = tip_columns(out[-1])
    out.flags.writeable = False
    return out


def tip_columns(row):
    """The tip_* columns of a last row (:data:`COLUMNS`) whose joint is revolute: that body's
    articulated inertia, projected for its joint and moved by Tz(d), in its own frame. It is the
    body's own inertia [[J, h~], [h~^T, m 1]], so these are constants, computed here as the
    forward kernel computes a body's (the same operations in the same order, the products with
    the own inertia's zeros left out: B's diagonal, M's off-diagonal). In the row's own
    arithmetic: a table in another number type (:mod:`redysim.algorithms.precision`) recomputes
    them from its row, as the kernels read them as given."""
    jxx, jxy, jxz, jyy, jyz, jzz, m, hx, hy, hz, ld = (row[DH_COLUMNS.index(n)] for n in (
        "jxx", "jxy", "jxz", "jyy", "jyz", "jzz", "m", "hx", "hy", "hz", "d"))
    with np.errstate(all="ignore"):  # J_zz = 0: a singular robot, which its pivot names
        inv = 1.0 / jzz
        d0, d1, d3, d4 = jxz * inv, jyz * inv, -hy * inv, hx * inv
        # projected: I - (U / D) U^T, U = I's angular-z column (jxz, jyz, jzz, -hy, hx, 0)
        a00, a01, a11 = jxx - d0 * jxz, jxy - d0 * jyz, jyy - d1 * jyz
        b00, b01, b10, b11 = -(d0 * -hy), -hz - d0 * hx, hz - d1 * -hy, -(d1 * hx)
        m00, m01, m11 = m - d3 * -hy, -(d3 * hx), m - d4 * hx
        # Tz(d): B's rows x, y (its z column keeps hy, -hx: M's xz, yz are zero), then A
        nb00, nb01 = b00 - ld * m01, b01 - ld * m11
        nb10, nb11 = b10 + ld * m00, b11 + ld * m01
        za00 = a00 - ld * (nb01 + b01)
        za11 = a11 + ld * (nb10 + b10)
        za01 = a01 + ld * (b00 - nb11)
        return (inv, d0, d1, d3, d4, a00, a01, a11, b00, b01, b10, b11, m00, m01, m11,
                za00, za01, za11, nb00, nb01, nb10, nb11)
