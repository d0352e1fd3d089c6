"""Initial shapes computed from a case's parameters (never typed in as angles)."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq


def catenary_angles(n_links: int, arc_length: float, dX: float) -> np.ndarray:
    """Relative joint angles of a planar chain laid on a catenary through (0, 0) and (dX, 0).

    The catenary y = a cosh((x - dX/2)/a) - a cosh(dX/(2a)) hangs below the X axis (gravity -Y)
    and has the chain's arc length: 2 a sinh(dX/(2a)) = arc_length. The joints O_1..O_nl+1 are put
    at equal arc length s_i = i arc_length / nl along it, and each link follows its chord; q_1 is
    the first chord's angle from +X, q_k the change of chord angle at joint k. dX = arc_length is
    the straight chain (q = 0).

    References: Agarwal et al., section 3.1 and Table 1 (RE-R229-L1.02, after Tomaszewski et al.).
    """
    if not (0 < dX <= arc_length):
        raise ValueError(f"dX = {dX!r}: the span must be in (0, arc_length = {arc_length}]")
    if math.isclose(dX, arc_length, rel_tol=1e-12):
        return np.zeros(n_links)
    # sinh(u)/u = arc_length/dX with u = dX/(2a)
    ratio = arc_length / dX
    u = brentq(lambda x: math.sinh(x) / x - ratio, 1e-12, 50.0, xtol=1e-15, rtol=1e-15)
    a = dX / (2 * u)
    s = np.linspace(0.0, arc_length, n_links + 1)
    x = dX / 2 + a * np.arcsinh(s / a - math.sinh(u))
    y = a * np.cosh((x - dX / 2) / a) - a * math.cosh(u)
    theta = np.arctan2(np.diff(y), np.diff(x))
    return np.diff(theta, prepend=0.0)
