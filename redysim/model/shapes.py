"""Initial shapes computed from a case's parameters (never typed in as angles)."""

from __future__ import annotations

import math

import numpy as np

XTOL = 1e-15  # root-finding tolerance on x and on the catenary's parameter [m]


def _sag(dX: float, arc_length: float) -> float:
    """u = dX / (2 a) of the catenary through (0, 0) and (dX, 0) with this arc length:
    sinh(u) / u = arc_length / dX."""
    from scipy.optimize import brentq  # imported when needed: 0.27 s no command's start needs

    ratio = arc_length / dX
    return brentq(lambda x: math.sinh(x) / x - ratio, 1e-12, 50.0, xtol=1e-15, rtol=1e-15)


def catenary_angles(n_links: int, length: float, dX: float) -> np.ndarray:
    """Relative joint angles of a planar chain of n equal links hanging on a catenary from (0, 0)
    to (dX, 0).

    Every joint O_1..O_nl and the chain's end lie on one catenary
    y = a cosh((x - dX/2)/a) - a cosh(dX/(2a)) (below the X axis: gravity -Y), the end exactly at
    (dX, 0): the links are equal chords of it, and a is chosen so that n chords of length
    length / n span dX (the catenary's own arc length is then slightly more than the chain's,
    by O(1/n^2)). q_1 is the first chord's angle from +X, q_k the change of chord angle at joint
    k. dX = length is the straight chain (q = 0); one link spans only its own length.

    Raises ValueError when no such shape exists (dX outside (0, length], one link with
    dX < length, or a sag too deep for the root finder's bracket).

    References: Agarwal et al., section 3.1 and Table 1 (RE-R229-L1.02, after Tomaszewski et al.).
    """
    from scipy.optimize import brentq

    if not (0 < dX <= length):
        raise ValueError(f"dX = {dX!r}: the span must be in (0, length = {length}]")
    if math.isclose(dX, length, rel_tol=1e-12):
        return np.zeros(n_links)
    if n_links < 2:
        raise ValueError(f"one link of length {length} spans only its own length, not dX = {dX}")
    chord = length / n_links
    half = dX / 2

    def y(x, a, u):
        return a * math.cosh((x - half) / a) - a * math.cosh(u)

    def chord_gap(x, x0, y0, a, u):  # squared distance from (x0, y0) to the curve at x, minus c^2
        return (x - x0) ** 2 + (y(x, a, u) - y0) ** 2 - chord * chord

    def half_polygon(u):
        """The joints from (0, 0) to the middle, each one chord from the last."""
        a = half / u
        xs, ys = [0.0], [0.0]
        for _ in range(n_links // 2):
            x0, y0 = xs[-1], ys[-1]
            x1 = brentq(chord_gap, x0, x0 + chord, args=(x0, y0, a, u), xtol=XTOL)
            xs.append(x1)
            ys.append(y(x1, a, u))
        return xs, ys

    # the middle: a joint at dX/2 (n even), or a level middle chord centred on it (n odd)
    target = half if n_links % 2 == 0 else half - chord / 2

    def miss(u):
        return half_polygon(u)[0][-1] - target

    # on the catenary of the chain's own arc length the chords, each shorter than the arc it
    # spans, overshoot the middle; one twice as long has arc to spare
    u_lo, u_hi = _sag(dX, length), _sag(dX, 2 * length)
    u = brentq(miss, u_lo, u_hi, xtol=XTOL)
    xs, ys = half_polygon(u)
    xs = np.array(xs + [dX - x for x in reversed(xs[:len(xs) - (n_links % 2 == 0)])])
    ys = np.array(ys + list(reversed(ys[:len(ys) - (n_links % 2 == 0)])))
    theta = np.arctan2(np.diff(ys), np.diff(xs))
    return np.diff(theta, prepend=0.0)
