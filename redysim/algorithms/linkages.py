"""Closed-loop mechanisms as trees with cut joints, and the closed forms they are checked with.

- :func:`four_bar`: a planar four-bar (ground, crank, coupler, rocker; uniform bars), cut at the
  coupler-rocker pin; :func:`four_bar_position` its position analysis in closed form (the
  coupler point for a crank angle, on a chosen assembly branch).
- :func:`hoekens_linkage`: Hoeken's straight-line four-bar (ground 2, crank 1, coupler 2.5,
  rocker 2.5, the tracing point at 5 on the coupler line extended: the proportions of
  Chebyshev's lambda linkage), a straight-line generator of the kind the seed talk's "carpet
  scrapper" is (the talk gives that one no dimensions); :func:`hoekens_path` its coupler point
  in explicit closed form and :func:`straight_band` the straightness of a path (the narrowest
  strip that holds it).
- :func:`jansen_leg`: Theo Jansen's walking leg (one crank, seven moving links, ten pins: three
  independent loops), a tree of seven bodies cut at three pins; :func:`jansen_points` every
  joint by circle intersections, on the branches of Jansen's figure.
- :func:`pinned_chain`: a uniform chain of rods pinned at both ends at the same height, cut at
  the far pin; :func:`discrete_catenary` its static equilibrium in closed form (up to a 1-D root
  for the horizontal tension), which the continuous catenary approaches as O(1/n^2).
- :func:`assemble`: close the loops from a nearby configuration with chosen coordinates (the
  driving crank) held, by Gauss-Newton steps on the cut joints' equations.

Everything in the world's xy plane, joints about z, gravity -y; the cut joints are "planar".
The same mechanisms as data files: :mod:`redysim.io.linkage_files` and ``cases/loops/``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from redysim.algorithms.loops import PROJECTION_TOL, ClosedLoops
from redysim.errors import StateError
from redysim.model.parts import STANDARD_GRAVITY
from redysim.model.tree import Body, CutJoint, Model, TreeJoint


def bar_body(name: str, length: float, mass: float) -> Body:
    """A uniform slender bar along its frame's x from the origin: COM at the middle, inertia
    m L^2 / 12 about y and z (none about its own axis)."""
    i = mass * length ** 2 / 12.0
    return Body(name, mass, (length / 2, 0.0, 0.0), ((0.0, 0.0, 0.0), (0.0, i, 0.0),
                                                     (0.0, 0.0, i)))


def bars_body(name: str, segments, density: float) -> Body:
    """A rigid body made of uniform slender bars of ``density`` [kg/m], each from point p to
    point q of the body's frame (``segments``: pairs of 3-vectors): a ternary link drawn as its
    three sides, say. Mass, centre of mass and inertia about it summed over the bars (a bar's
    own inertia m L^2 / 12 across it, none along it)."""
    mass, first, second = 0.0, np.zeros(3), np.zeros((3, 3))
    for p, q in segments:
        p, q = np.asarray(p, dtype=float), np.asarray(q, dtype=float)
        length = float(np.linalg.norm(q - p))
        m = density * length
        c = (p + q) / 2
        u = (q - p) / length if length else np.zeros(3)
        own = m * length ** 2 / 12.0 * (np.eye(3) - np.outer(u, u))
        mass += m
        first += m * c
        second += own + m * (c @ c * np.eye(3) - np.outer(c, c))  # about the frame's origin
    com = first / mass if mass else np.zeros(3)
    inertia = second - mass * (com @ com * np.eye(3) - np.outer(com, com))
    inertia = 0.5 * (inertia + inertia.T)
    return Body(name, mass, tuple(com), tuple(map(tuple, inertia)))


def circle_meet(p1, r1: float, p2, r2: float, side: int) -> np.ndarray:
    """The point (2,) at distance r1 from p1 and r2 from p2, on the left (``side`` +1) or the
    right (-1) of the directed line p1 -> p2: the two circles' intersection, the construction
    with compasses of a planar dyad. ValueError when the circles do not meet."""
    p1, p2 = np.asarray(p1, dtype=float)[:2], np.asarray(p2, dtype=float)[:2]
    d = p2 - p1
    dist = float(np.hypot(d[0], d[1]))
    if not abs(r1 - r2) <= dist <= r1 + r2 or dist == 0:
        raise ValueError(f"circles of radii {r1!r} and {r2!r} with centres {dist!r} apart do "
                         "not meet")
    along = (r1 ** 2 - r2 ** 2 + dist ** 2) / (2 * dist)
    across = math.sqrt(max(r1 ** 2 - along ** 2, 0.0))
    left = np.array([-d[1], d[0]]) / dist
    return p1 + along * d / dist + side * across * left


def assemble(loops: ClosedLoops, q, *, hold=(), tol: float | None = None,
             iterations: int = 50, max_step: float = 0.5) -> np.ndarray:
    """A configuration on the loops near ``q`` with the coordinates ``hold`` (indices: the
    driving crank) kept as given: Gauss-Newton on the cut joints' equations phi(q) = 0, each
    step the least-norm change of the other coordinates (``np.linalg.lstsq`` of J's free
    columns), steps longer than ``max_step`` shortened to it. Converges quadratically from a
    configuration near the loops and stays on the assembly branch of that configuration.

    tol: |phi| [m] to reach (default the projection's, 1e-12 relative to the model's size).
    Raises StateError, naming the worst cut joint, when ``iterations`` steps do not close the
    loops (the guess too far, or the driving angle one at which the mechanism cannot
    assemble)."""
    q = np.array(q, dtype=float)
    n = loops.model.n_v
    held = {int(i) for i in hold}
    free = np.array([i for i in range(n) if i not in held], dtype=np.int64)
    tol = PROJECTION_TOL * loops.size if tol is None else tol
    zeros = np.zeros(n)

    def step(q, phi):
        J = loops.evaluate(q, zeros)[1]
        dq = np.linalg.lstsq(J[:, free], -phi, rcond=None)[0]
        longest = float(np.abs(dq).max())
        out = q.copy()
        out[free] += dq * (min(1.0, max_step / longest) if longest else 1.0)
        return out, loops.evaluate(out, zeros)[0]

    phi = loops.evaluate(q, zeros)[0]
    for it in range(iterations + 1):
        if np.abs(phi).max() <= tol:
            # one more step, kept if it helps: a quadratic step from within tol lands at
            # rounding level
            polished, phi2 = step(q, phi)
            return polished if np.abs(phi2).max() < np.abs(phi).max() else q
        if it == iterations:
            break
        q, phi = step(q, phi)
    worst = int(np.argmax(np.abs(phi)))
    cut = loops.cuts[loops.rows[worst][0]]
    raise StateError(f"the loops do not close: after {iterations} Gauss-Newton steps the cut "
                     f"joint {cut.name!r} is still {abs(phi[worst]):.3g} m open (tolerance "
                     f"{tol:.3g}); start nearer an assembled configuration, or the mechanism "
                     "cannot assemble with the held coordinates at these values")


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
        from redysim.algorithms.rbda import kinematics

        kin = kinematics(self.model, np.asarray(q, dtype=float), np.zeros(3))
        p = kin.O[1] + kin.R[1] @ np.array([self.rp * math.cos(self.gamma),
                                            self.rp * math.sin(self.gamma), 0.0])
        return p[:2]


def four_bar(d: float, a: float, b: float, c: float, *, rp: float | None = None,
             gamma: float = 0.0, density: float = 1.0, branch: int = 1,
             gravity: float = STANDARD_GRAVITY) -> FourBar:
    """A planar four-bar: crank a about the world origin, rocker c about (d, 0), coupler b from
    the crank's end to the rocker's, uniform bars of ``density`` kg/m (module docstring)."""
    bodies = [bar_body("crank", a, density * a), bar_body("coupler", b, density * b),
              bar_body("rocker", c, density * c)]
    joints = [TreeJoint("crank", "R", "z"),
              TreeJoint("coupler", "R", "z", translation=(a, 0.0, 0.0)),
              TreeJoint("rocker", "R", "z", translation=(d, 0.0, 0.0))]
    model = Model.build(bodies, joints, [-1, 0, -1], gravity=(0.0, -gravity, 0.0),
                        name=f"four-bar {d:g}/{a:g}/{b:g}/{c:g}")
    cut = CutJoint("coupler-rocker pin", 1, (b, 0.0, 0.0), 2, (c, 0.0, 0.0), "planar")
    model = model.with_cuts([cut])  # the closed mechanism
    return FourBar(d, a, b, c, b if rp is None else rp, gamma, branch, model,
                   ClosedLoops(model, source=model.name))


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


def hoekens_linkage(a: float = 1.0, *, density: float = 1.0, branch: int = 1,
                    gravity: float = STANDARD_GRAVITY) -> FourBar:
    """Hoeken's straight-line linkage with crank ``a`` [m]: ground 2a, coupler 2.5a, rocker 2.5a,
    the tracing point at 5a from the crank pin on the coupler line extended through the rocker
    pin (the coupler's middle, were the coupler drawn to the tracing point), as
    :func:`four_bar` builds it (crank about the world origin, rocker pivot at (2a, 0); the
    coupler bar's mass over its 2.5a, the extension to the tracing point massless).

    These are the proportions of Chebyshev's lambda linkage (Wikipedia, "Chebyshev lambda
    linkage": link 2 a, link 4 2.5a, link 3 2.5a + 2.5a, ground 2a), a cognate of Chebyshev's
    straight-line linkage. On ``branch`` 1 the straight part is the bottom of the path,
    y = -4a, traced from x = 0 to 4a as the crank turns from 90 to 270 deg and held to within
    a strip 0.975 % of a wide from 75.5 to 284.5 deg (:func:`hoekens_path`)."""
    return four_bar(2.0 * a, a, 2.5 * a, 2.5 * a, rp=5.0 * a, gamma=0.0, density=density,
                    branch=branch, gravity=gravity)


def hoekens_path(crank, a: float = 1.0, branch: int = 1) -> np.ndarray:
    """The tracing point (x, y) of :func:`hoekens_linkage` for crank angles ``crank`` [rad] (any
    shape; a trailing axis of 2 is added), in explicit closed form.

    Coupler and rocker are equal (2.5a), so the rocker pin B is the apex of the isosceles
    triangle on the crank pin A = a (cos t, sin t) and the rocker pivot D = (2a, 0):
    B = (A + D)/2 - s h n with |AD|^2 = a^2 (5 - 4 cos t), h = sqrt((2.5a)^2 - |AD|^2 / 4)
    = a sqrt(5 + cos t), n = (sin t, 2 - cos t) / sqrt(5 - 4 cos t) the unit normal on AD's left
    and s = ``branch`` (:func:`four_bar_position`'s). The tracing point is A mirrored in B,
    P = 2B - A = D - 2 s h n:

        P(t) = a (2 - 2 s r sin t,  -2 s r (2 - cos t)),   r = sqrt((5 + cos t) / (5 - 4 cos t)).

    At t = 90, 180 and 270 deg, P = (0, -4sa), (2a, -4sa), (4a, -4sa) exactly: the straight
    part's ends and middle are on the line y = -4sa, as Chebyshev's design puts them.
    """
    t = np.asarray(crank, dtype=float)
    r = np.sqrt((5.0 + np.cos(t)) / (5.0 - 4.0 * np.cos(t)))
    return a * np.stack((2.0 - 2.0 * branch * r * np.sin(t),
                         -2.0 * branch * r * (2.0 - np.cos(t))), axis=-1)


def straight_band(points) -> tuple[float, np.ndarray, np.ndarray]:
    """The straightness of a planar path: the narrowest strip that holds ``points`` (m, 2), as
    (its width, a point of its middle line, the middle line's unit direction).

    This is the minimum-zone straightness (the tolerance zone of ISO 1101); the middle line is
    the path's best straight line in Chebyshev's (minimax) sense, every point within width / 2
    of it. The narrowest strip holding a convex polygon lies flush with one of its edges, so
    the width is the least, over the edges of the points' convex hull, of the hull's greatest
    distance from the edge's line (exact; no fitting)."""
    from scipy.spatial import ConvexHull, QhullError

    P = np.asarray(points, dtype=float)[:, :2]
    try:
        H = P[ConvexHull(P).vertices]
    except QhullError:  # fewer than 3 points, or all on one line
        u = P[-1] - P[0]
        u = u / np.linalg.norm(u) if np.linalg.norm(u) else np.array([1.0, 0.0])
        return 0.0, P[0].copy(), u
    best: tuple[float, np.ndarray | None, np.ndarray | None] = (math.inf, None, None)
    for i in range(len(H)):
        p, q = H[i], H[(i + 1) % len(H)]
        u = (q - p) / np.linalg.norm(q - p)
        n = np.array([-u[1], u[0]])
        d = (H - p) @ n
        width = float(d.max() - d.min())
        if width < best[0]:
            best = (width, p + n * (d.max() + d.min()) / 2, u)
    width, middle, direction = best
    # finite points give every edge a finite width: the first one replaced (inf, None, None)
    assert middle is not None and direction is not None
    return width, middle, direction


# Theo Jansen's "holy numbers": the eleven bar lengths b..k and m of his leg, and the frame's a
# (horizontal) and l (vertical) from the fixed pivot to the crank axle, in his units. Published
# by Jansen (strandbeest.com, "The Legsystem"; Jansen, The Great Pretender, 2007) and drawn with
# these letters in Wikipedia's figure "Strandbeest Leg Proportions" (article "Jansen's linkage").
def crossings(points, centre, direction) -> int:
    """How many times a path crosses the line through ``centre`` along ``direction``."""
    normal = np.array([-direction[1], direction[0]])
    side = np.sign((np.asarray(points) - centre) @ normal)
    return int(np.count_nonzero(np.diff(side[side != 0])))


def hoekens_straight_part(a: float = 1.0) -> tuple[float, float, np.ndarray, np.ndarray]:
    """The straight part of Hoeken's path, read the way the published statement is: the
    narrowest strip holding the path between the crank angles (90 and 270 deg) that put it
    exactly on the line y = -4a, and the crank range theta1 .. 360 - theta1 [deg] over which the
    path stays in that strip. Returns (theta1, width, centre, direction)."""
    from scipy.optimize import brentq

    t = np.radians(np.linspace(90.0, 270.0, 20001))
    width, centre, direction = straight_band(hoekens_path(t, a))
    bottom = centre[1] - width / 2
    theta1 = brentq(lambda deg: hoekens_path(math.radians(deg), a)[1] - bottom, 60.0, 89.99,
                    xtol=1e-13)
    return theta1, width, centre, direction


JANSEN_HOLY_NUMBERS = {"a": 38.0, "b": 41.5, "c": 39.3, "d": 40.1, "e": 55.8, "f": 39.4,
                       "g": 36.7, "h": 65.7, "i": 49.0, "j": 50.0, "k": 61.9, "l": 7.8,
                       "m": 15.0}
# The leg's joints, each a dyad on two known ones: (its name, first centre, its radius, second
# centre, its radius, side: +1 on the left of the line first -> second, -1 on its right). The
# sides are those of Jansen's figure (crank axle O, fixed pivot P = (-a, -l) on its left and
# below it, foot F at the bottom) and stay so over the whole turn.
JANSEN_DYADS = (("A", "P", "b", "C", "j", +1),   # upper joint: the triangle b-d-e's top corner
                ("B", "P", "c", "C", "k", -1),   # lower joint: bars c and k, the foot's top
                ("D", "P", "d", "A", "e", +1),   # the triangle b-d-e's outer corner
                ("E", "D", "f", "B", "g", -1),   # the knee: bar f, the foot triangle g-h-i
                ("F", "E", "h", "B", "i", -1))   # the foot


def jansen_points(crank: float, lengths: dict[str, float] | None = None
                  ) -> dict[str, np.ndarray]:
    """The joints (2,) of Jansen's leg for a crank angle [rad], by circle intersections
    (:data:`JANSEN_DYADS`): O the crank axle (the origin), P the fixed pivot (-a, -l), C the
    crank pin, A and B the joints of bars j and k from C, D the outer corner of the triangle
    P-A-D (sides b, e, d), E the knee, F the foot (triangle B-E-F: sides g, h, i). ``lengths``:
    the letters' values (default :data:`JANSEN_HOLY_NUMBERS`)."""
    L = JANSEN_HOLY_NUMBERS if lengths is None else lengths
    pts = {"O": np.zeros(2), "P": np.array([-L["a"], -L["l"]]),
           "C": L["m"] * np.array([math.cos(crank), math.sin(crank)])}
    for name, c1, r1, c2, r2, side in JANSEN_DYADS:
        pts[name] = circle_meet(pts[c1], L[r1], pts[c2], L[r2], side)
    return pts


def _angle(v) -> float:
    return math.atan2(v[1], v[0])


def _wrap(x: float) -> float:
    return (x + math.pi) % (2 * math.pi) - math.pi


@dataclass(frozen=True)
class JansenLeg:
    """Jansen's leg as a tree cut at three pins (:func:`jansen_leg`): ``lengths`` the letters'
    values [m], the model and its loops."""

    lengths: dict
    model: Model
    loops: ClosedLoops

    def points(self, crank: float) -> dict[str, np.ndarray]:
        """The joints for a crank angle, by circle intersections (:func:`jansen_points`)."""
        return jansen_points(crank, self.lengths)

    def configuration(self, crank: float) -> np.ndarray:
        """q (7,) of the tree for a crank angle, from the circle intersections."""
        p = self.points(crank)
        a1, a2 = _angle(p["A"] - p["C"]), _angle(p["P"] - p["A"])
        a3, a4 = _angle(p["B"] - p["C"]), _angle(p["B"] - p["P"])
        a5, a6 = _angle(p["E"] - p["B"]), _angle(p["E"] - p["D"])
        return np.array([_wrap(x) for x in (crank, a1 - crank, a2 - a1, a3 - crank, a4,
                                            a5 - a3, a6 - a2)])

    def foot(self, q) -> np.ndarray:
        """The foot F (2,) of a configuration q, by the model's kinematics."""
        from redysim.algorithms.rbda import kinematics

        kin = kinematics(self.model, np.asarray(q, dtype=float), np.zeros(self.model.n_v))
        return (kin.O[5] + kin.R[5] @ self._foot_local)[:2]

    @property
    def _foot_local(self) -> np.ndarray:
        L = self.lengths
        return np.append(circle_meet((0.0, 0.0), L["i"], (L["g"], 0.0), L["h"], +1), 0.0)


def jansen_leg(unit: float = 0.01, *, density: float = 1.0,
               gravity: float = STANDARD_GRAVITY) -> JansenLeg:
    """Theo Jansen's leg with the holy numbers (:data:`JANSEN_HOLY_NUMBERS`) times ``unit``
    [m], every bar of ``density`` [kg/m]: seven moving bodies on ten pins (one degree of
    freedom, three independent loops), built as a tree of seven revolute joints cut at three
    pins ("planar"). Bodies and their frames (x along the first side named):

        0 crank  O -> C  (m)        about the axle O, the world origin
        1 j      C -> A  (j)        from the crank pin
        2 bde    A -> P, D (b, e, d) the triangle, from A; its corner P is cut to the pivot P
        3 k      C -> B  (k)        from the crank pin
        4 c      P -> B  (c)        about the fixed pivot P = (-a, -l); its end cut to k's end B
        5 ghi    B -> E, F (g, i, h) the foot triangle, from k's end B
        6 f      D -> E  (f)        from the triangle's corner D; its end cut to the foot's E

    :meth:`JansenLeg.configuration` assembles it for a crank angle from circle intersections.
    """
    L = {key: value * unit for key, value in JANSEN_HOLY_NUMBERS.items()}
    D = np.append(circle_meet((0.0, 0.0), L["e"], (L["b"], 0.0), L["d"], -1), 0.0)
    F = np.append(circle_meet((0.0, 0.0), L["i"], (L["g"], 0.0), L["h"], +1), 0.0)
    O, P, E = np.zeros(3), np.array([L["b"], 0.0, 0.0]), np.array([L["g"], 0.0, 0.0])
    def bar(name):
        return bar_body(name, L[name], density * L[name])

    bodies = [bar_body("crank", L["m"], density * L["m"]), bar("j"),
              bars_body("bde", [(O, P), (P, D), (O, D)], density), bar("k"), bar("c"),
              bars_body("ghi", [(O, E), (E, F), (O, F)], density), bar("f")]
    joints = [TreeJoint("crank", "R", "z"),
              TreeJoint("j", "R", "z", translation=(L["m"], 0.0, 0.0)),
              TreeJoint("bde", "R", "z", translation=(L["j"], 0.0, 0.0)),
              TreeJoint("k", "R", "z", translation=(L["m"], 0.0, 0.0)),
              TreeJoint("c", "R", "z", translation=(-L["a"], -L["l"], 0.0)),
              TreeJoint("ghi", "R", "z", translation=(L["k"], 0.0, 0.0)),
              TreeJoint("f", "R", "z", translation=tuple(D))]
    model = Model.build(bodies, joints, [-1, 0, 1, 0, -1, 3, 2], gravity=(0.0, -gravity, 0.0),
                        name=f"Jansen's leg ({unit:g} m per unit)")
    cuts = [CutJoint("pivot P", 2, tuple(P), -1, (-L["a"], -L["l"], 0.0), "planar"),
            CutJoint("pin B", 4, (L["c"], 0.0, 0.0), 3, (L["k"], 0.0, 0.0), "planar"),
            CutJoint("knee E", 6, (L["f"], 0.0, 0.0), 5, tuple(E), "planar")]
    model = model.with_cuts(cuts)  # the closed mechanism
    return JansenLeg(L, model, ClosedLoops(model, source=model.name))


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
    bodies = [bar_body(f"link{k + 1}", length, mass) for k in range(n)]
    joints = [TreeJoint(f"joint{k + 1}", "R", "z",
                        translation=(length if k else 0.0, 0.0, 0.0)) for k in range(n)]
    model = Model.build(bodies, joints, list(range(-1, n - 1)), gravity=(0.0, -gravity, 0.0),
                        name=f"pinned chain {n} x {length:g} m, span {span:g} m")
    cut = CutJoint("far pin", n - 1, (length, 0.0, 0.0), -1, (span, 0.0, 0.0), "planar")
    model = model.with_cuts([cut])  # the closed mechanism
    return PinnedChain(n, length, mass, span, model, ClosedLoops(model, source=model.name))


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
