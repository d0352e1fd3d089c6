"""Closed-loop mechanisms as trees with cut joints, and the closed forms they are checked with.

- :func:`four_bar`: a planar four-bar (ground, crank, coupler, rocker; uniform bars), cut at the
  coupler-rocker pin; :func:`four_bar_position` its position analysis in closed form (the
  coupler point for a crank angle, on a chosen assembly branch).
- :func:`pinned_chain`: a uniform chain of rods pinned at both ends at the same height, cut at
  the far pin; :func:`discrete_catenary` its static equilibrium in closed form (up to a 1-D root
  for the horizontal tension), which the continuous catenary approaches as O(1/n^2).

Everything in the world's xy plane, joints about z, gravity -y; the cut joints are "planar".
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .chain import STANDARD_GRAVITY
from .loops import ClosedLoops, CutJoint
from .model import Body, Model, TreeJoint


def _bar(name: str, length: float, mass: float) -> Body:
    """A uniform slender bar along its frame's x from the origin: COM at the middle, inertia
    m L^2 / 12 about y and z (none about its own axis)."""
    i = mass * length ** 2 / 12.0
    return Body(name, mass, (length / 2, 0.0, 0.0), ((0.0, 0.0, 0.0), (0.0, i, 0.0),
                                                     (0.0, 0.0, i)))


@dataclass(frozen=True)
class FourBar:
    """Link lengths [m] (ground d, crank a, coupler b, rocker c), the coupler point (distance
    ``rp`` from the coupler's crank pin, at ``gamma`` rad from the coupler line), the branch
    (+1 or -1) and the model, its cut joint and the loops."""

    d: float
    a: float
    b: float
    c: float
    rp: float
    gamma: float
    branch: int
    model: Model
    loops: ClosedLoops

    @property
    def grashof(self) -> bool:
        s = sorted((self.d, self.a, self.b, self.c))
        return s[0] + s[3] <= s[1] + s[2]

    def configuration(self, crank: float) -> np.ndarray:
        """q = (crank angle, coupler angle relative to the crank, rocker angle) for a crank
        angle, from the closed form."""
        _, theta3, theta4 = four_bar_position(self, crank)
        return np.array([crank, theta3 - crank, theta4])

    def coupler_point(self, q) -> np.ndarray:
        """The coupler point (x, y) of a configuration q, by the model's kinematics."""
        from .rbda import kinematics

        kin = kinematics(self.model, np.asarray(q, dtype=float), np.zeros(3))
        p = kin.O[1] + kin.R[1] @ np.array([self.rp * math.cos(self.gamma),
                                            self.rp * math.sin(self.gamma), 0.0])
        return p[:2]


def four_bar(d: float, a: float, b: float, c: float, *, rp: float | None = None,
             gamma: float = 0.0, density: float = 1.0, branch: int = 1,
             gravity: float = STANDARD_GRAVITY) -> FourBar:
    """A planar four-bar: crank a about the world origin, rocker c about (d, 0), coupler b from
    the crank's end to the rocker's, uniform bars of ``density`` kg/m (module docstring)."""
    bodies = [_bar("crank", a, density * a), _bar("coupler", b, density * b),
              _bar("rocker", c, density * c)]
    joints = [TreeJoint("crank", "R", "z"),
              TreeJoint("coupler", "R", "z", translation=(a, 0.0, 0.0)),
              TreeJoint("rocker", "R", "z", translation=(d, 0.0, 0.0))]
    model = Model.build(bodies, joints, [-1, 0, -1], gravity=(0.0, -gravity, 0.0),
                        name=f"four-bar {d:g}/{a:g}/{b:g}/{c:g}")
    cut = CutJoint("coupler-rocker pin", 1, (b, 0.0, 0.0), 2, (c, 0.0, 0.0), "planar")
    return FourBar(d, a, b, c, b if rp is None else rp, gamma, branch, model,
                   ClosedLoops(model, [cut], source=model.name))


def four_bar_position(fb: FourBar, crank: float) -> tuple[np.ndarray, float, float]:
    """(coupler point (2,), coupler angle theta3, rocker angle theta4) for a crank angle, in
    closed form: the pin B is where the circles of radius b about the crank's end A and of
    radius c about the rocker's pivot D meet, on the four-bar's branch."""
    A = np.array([fb.a * math.cos(crank), fb.a * math.sin(crank)])
    D = np.array([fb.d, 0.0])
    f = float(np.hypot(*(D - A)))
    delta = math.atan2(D[1] - A[1], D[0] - A[0])
    cos_psi = (fb.b ** 2 + f ** 2 - fb.c ** 2) / (2 * fb.b * f)
    if abs(cos_psi) > 1:
        raise ValueError(f"the four-bar does not assemble at crank angle {crank!r}")
    theta3 = delta - fb.branch * math.acos(cos_psi)
    B = A + fb.b * np.array([math.cos(theta3), math.sin(theta3)])
    theta4 = math.atan2(B[1] - D[1], B[0] - D[0])
    P = A + fb.rp * np.array([math.cos(theta3 + fb.gamma), math.sin(theta3 + fb.gamma)])
    return P, theta3, theta4


@dataclass(frozen=True)
class PinnedChain:
    """n uniform rods of length l and mass m, pinned at (0, 0) and (span, 0)."""

    n: int
    length: float
    mass: float
    span: float
    model: Model
    loops: ClosedLoops


def pinned_chain(n: int, length: float, mass: float, span: float, *,
                 gravity: float = STANDARD_GRAVITY) -> PinnedChain:
    """A chain of ``n`` rods of ``length`` [m] and ``mass`` [kg] each, hanging from (0, 0) and
    pinned at its far end to (span, 0): a tree (the chain from the first pin) cut at the far
    pin (module docstring)."""
    if not 0 < span < n * length:
        raise ValueError(f"span = {span!r} must be in (0, {n * length!r}) (the chain's length)")
    bodies = [_bar(f"link{k + 1}", length, mass) for k in range(n)]
    joints = [TreeJoint(f"joint{k + 1}", "R", "z",
                        translation=(length if k else 0.0, 0.0, 0.0)) for k in range(n)]
    model = Model.build(bodies, joints, list(range(-1, n - 1)), gravity=(0.0, -gravity, 0.0),
                        name=f"pinned chain {n} x {length:g} m, span {span:g} m")
    cut = CutJoint("far pin", n - 1, (length, 0.0, 0.0), -1, (span, 0.0, 0.0), "planar")
    return PinnedChain(n, length, mass, span, model, ClosedLoops(model, [cut], source=model.name))


def discrete_catenary(chain: PinnedChain, gravity: float = STANDARD_GRAVITY) -> np.ndarray:
    """The joint angles q of the chain's static equilibrium, in closed form.

    With H the (constant) horizontal tension and V_k the vertical force between rods k and
    k + 1, force balance gives V_k = V_{k-1} + m g, and each rod's moment balance about its first
    pin (its weight at its middle) gives tan(theta_k) = (V_{k-1} + m g / 2) / H for its absolute
    angle theta_k. By symmetry V_0 = -n m g / 2, so
        tan(theta_k) = m g (k - 1/2 - n/2) / H,     k = 1..n,
    and H is the root of sum_k l cos(theta_k) = span. q_1 = theta_1, q_k = theta_k - theta_{k-1}.
    """
    from scipy.optimize import brentq

    n, length, weight = chain.n, chain.length, chain.mass * gravity
    s = weight * (np.arange(1, n + 1) - 0.5 - n / 2)

    def gap(H):
        return length * np.sum(1.0 / np.sqrt(1.0 + (s / H) ** 2)) - chain.span

    H = brentq(gap, 1e-9 * weight, 1e9 * weight, xtol=1e-15 * weight, rtol=1e-15)
    theta = np.arctan(s / H)
    return np.concatenate(([theta[0]], np.diff(theta)))
