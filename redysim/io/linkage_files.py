"""Closed-loop mechanisms as TOML data: a tree of bodies, the joints cut to open its loops,
gravity, and an initial configuration that the loader assembles from a driving angle.

A linkage file has these tables (``cases/loops/README.md`` describes every field):

    [linkage]   name, description, source, length_unit ("m", "cm" or "mm"), gravity
    [ground]    points: named world points (the fixed pivots)
    [[body]]    one per body, parents first: name, parent ("ground" or an earlier body), at (a
                point of the parent), joint ("R" or "P"), axis, angle, repeat; the body as a
                uniform bar (length, with mass or density), as bars between its points (bars,
                density: a ternary link drawn as its sides), or as a general rigid body (mass,
                com, inertia); its named points
    [[cut]]     one per cut joint: name, a = "body.point", b = "body.point" or "ground.point",
                kind ("planar": a pin of a mechanism in the xy plane, "point", or "line" with its
                direction in body b's frame: one equation, the points level along it)
    [initial]   driver (a joint) and angle, with a guess of the other joints that picks the
                assembly branch; or q for every joint; or shape = "catenary" for a hanging chain

:func:`load_linkage` reads one into a :class:`Linkage`, which unpacks as ``(model, loops, q0)``;
q0 closes every cut joint to 1e-12 m (relative to the model's size;
:func:`redysim.algorithms.linkages.assemble`) with the driver at its angle. Every bad value raises
:class:`~redysim.errors.CaseError` naming the file, the field and the value, e.g.
``crank_rocker.toml: body[1].length = -0.35: must be > 0``.
"""

from __future__ import annotations

import math
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import NoReturn

import numpy as np

from redysim.algorithms.linkages import assemble, bar_body, bars_body, circle_meet
from redysim.algorithms.loops import ClosedLoops
from redysim.errors import CaseError, SettingsError, StateError
from redysim.model.parts import STANDARD_GRAVITY, check_inertia, check_vector, numeric_array
from redysim.model.tree import KINDS, Body, CutJoint, Model, TreeJoint

UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}  # length_unit -> metres
GROUND, ORIGIN, END = "ground", "origin", "end"
DEFAULT_MAX_CHANGE = 30.0  # deg (or length units for a P joint) an assembled joint may move
# Linkage.at: at most this many assemblies per call (a driver sent 1e5 rad at 5 deg a step
# would take 1.1e6, ~45 minutes: a mechanism that comes back after a turn is followed through
# at most two turns instead, 144 steps at the default 5 deg)
MAX_AT_STEPS = 10_000
PERIOD_TOL = 1e-9  # rad (relative to |q|): a turn brings every joint back to within this
AXES = ("x", "y", "z")
_FIELDS = {
    "linkage": {"name", "description", "source", "length_unit", "gravity"},
    "ground": {"points"},
    "body": {"name", "parent", "at", "joint", "axis", "angle", "repeat", "length", "mass",
             "density", "bars", "com", "inertia", "points"},
    "cut": {"name", "a", "b", "kind", "direction"},
    "initial": {"driver", "angle", "guess", "q", "shape", "max_change"},
}
_ARRAYS = ("body", "cut")  # arrays of tables; the others are single tables


def _fail(source, field_name, value, problem) -> NoReturn:
    raise CaseError(source, field_name, value, problem)


def _listing(names) -> str:
    """Names for a message: all of a few, the first and last of many (a 100-link chain)."""
    names = list(names)
    if len(names) <= 12:
        return ", ".join(names)
    return f"{', '.join(names[:8])}, ... ({len(names) - 10} more), {', '.join(names[-2:])}"


@dataclass(frozen=True, eq=False)
class Linkage:
    """A loaded linkage file: the tree (``model``), its cut joints (``loops``) and the assembled
    initial configuration ``q0``; unpacks as ``(model, loops, q0)``.

    ``driver``: the index of the driving coordinate (None without one); ``points``: every named
    point, ``"body.point"`` or ``"ground.point"`` -> (body index, -1 for the world; position in
    that body's frame [m]); ``unit``: metres per length unit of the file (``[linkage]
    length_unit``), which a P joint's values in the file are in."""

    name: str
    path: Path
    model: Model
    loops: ClosedLoops
    q0: np.ndarray
    description: str = ""
    source: str = ""
    driver: int | None = None
    points: dict[str, tuple[int, np.ndarray]] = field(default_factory=dict)
    unit: float = 1.0

    def __iter__(self):
        return iter((self.model, self.loops, self.q0))

    def point(self, q, ref: str) -> np.ndarray:
        """World position (3,) of the named point ``ref`` ("body.point") at configuration q."""
        from redysim.algorithms.rbda import kinematics

        if ref not in self.points:
            raise KeyError(f"{self.name}: no point {ref!r}; known: {_listing(self.points)}")
        body, p = self.points[ref]
        if body < 0:
            return p.copy()
        kin = kinematics(self.model, np.asarray(q, dtype=float), np.zeros(self.model.n_v))
        return kin.O[body] + kin.R[body] @ p

    def at(self, value: float, q=None, *, step: float | None = None) -> np.ndarray:
        """The configuration with the driver at ``value`` [rad, or m for a P joint], reached
        from q (default q0) on its assembly branch: the driver moved there in steps of at most
        ``step`` (default 5 deg; for a P joint 1 % of the model's size), the loops closed after each
        with the driver held (:func:`redysim.algorithms.linkages.assemble`), so that the mechanism
        is followed as it moves rather than jumped to a far angle, where Gauss-Newton could close it
        on another branch.

        A revolute driver more than a turn away is not stepped through every turn: the
        mechanism is followed through one whole turn, and when that brings every joint back to
        its start (each revolute joint to within a whole number of turns: the motion is
        periodic) the whole turns are added and only the rest is followed; so the cost is at
        most two turns' steps, whatever ``value``. Raises SettingsError for a ``value`` or
        ``step`` that is not a finite number (step > 0), or a move that would take more than
        :data:`MAX_AT_STEPS` steps (a mechanism that does not come back after a turn, a P
        driver sent far, a tiny step); StateError for a bad q or a driver value at which the
        mechanism does not assemble (:func:`~redysim.algorithms.linkages.assemble`)."""
        from redysim.algorithms.dynamics import check_state

        where = f"{self.name}: Linkage.at"
        if self.driver is None:
            raise ValueError(f"{self.name}: the file names no [initial] driver")
        revolute = self.model.joint_types[self.driver] == "R"
        for name, x in (("value", value), ("step", step)):
            if x is None and name == "step":
                continue
            if isinstance(x, bool) or not isinstance(x, int | float | np.integer | np.floating) \
                    or not math.isfinite(x) or (name == "step" and not x > 0):
                raise SettingsError(where, name, float(x) if isinstance(x, np.generic) else x,
                                    "must be a finite number" + (" > 0" if name == "step" else "")
                                    + (" [rad]" if revolute else " [m]"))
        if step is None:
            step = math.radians(5.0) if revolute else 0.01 * self.loops.size
        q = np.array(check_state(self.model, "q", self.q0 if q is None else q), dtype=float)
        value, step = float(value), float(step)
        start = float(q[self.driver])
        turns, rest = 0, value - start
        if revolute and abs(rest) > 2 * math.pi:
            turns = math.floor(rest / (2 * math.pi))
            rest -= turns * 2 * math.pi
            self._check_steps(where, value, step, 2 * math.pi + rest, "value")
            offset = self._turn(q, start, step, where)
            q = self._follow(q, start, start + rest, step)
            q += turns * offset
        else:
            self._check_steps(where, value, step, abs(rest), "value")
            q = self._follow(q, start, value, step)
        q[self.driver] = value
        return q

    def _check_steps(self, where, value, step, span, name):
        count = math.ceil(span / step)
        if count > MAX_AT_STEPS:
            raise SettingsError(where, "step" if span <= 4 * math.pi else name,
                                step if span <= 4 * math.pi else value,
                                f"the driver would move {span:.6g} in {count:,} steps of "
                                f"{step:.3g}, more than {MAX_AT_STEPS:,} assemblies; give a "
                                "value nearer the start or a longer step")

    def _follow(self, q, start: float, value: float, step: float) -> np.ndarray:
        """q with the driver moved from ``start`` to ``value`` in steps of at most ``step``,
        the loops closed after each (the driver held)."""
        count = max(1, math.ceil(abs(value - start) / step))
        for k in range(1, count + 1):
            q[self.driver] = start + (value - start) * k / count
            q = assemble(self.loops, q, hold=[self.driver])
        return q

    def _turn(self, q, start: float, step: float, where: str) -> np.ndarray:
        """What one whole turn of the driver adds to q: a whole number of turns per revolute
        joint, and nothing to a prismatic one; SettingsError when the turn does not bring the
        mechanism back (it switched branches: no period to use)."""
        after = self._follow(q.copy(), start, start + 2 * math.pi, step)
        change = after - q
        turns = np.where(self._revolute, np.round(change / (2 * math.pi)), 0.0)
        offset = turns * 2 * math.pi
        off = np.abs(change - offset)
        if not off.max() <= PERIOD_TOL * max(1.0, float(np.abs(q).max())):
            k = int(np.argmax(off))
            raise SettingsError(where, "value", q[self.driver], f"a whole turn of the driver "
                                f"does not bring the mechanism back (joint "
                                f"{self.model.joint_names[k]!r} is {off[k]:.3g} away from its "
                                "start, modulo whole turns: it switched branches, at a change "
                                "point?), so a driver angle turns away cannot be reached by "
                                "following it; give one within a turn of the start")
        return offset

    @property
    def _revolute(self) -> np.ndarray:
        return np.array([t == "R" for t in self.model.joint_types])


# --------------------------------------------------------------------------- small readers
def _number(src, name, value, *, positive=False, nonnegative=False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        _fail(src, name, value, "must be a number")
    x = float(value)
    if not math.isfinite(x):
        _fail(src, name, value, "must be finite (no NaN or Inf)")
    if positive and x <= 0:
        _fail(src, name, value, "must be > 0")
    if nonnegative and x < 0:
        _fail(src, name, value, "must be >= 0")
    return x


def _string(src, name, value, *, dotless=False) -> str:
    if not isinstance(value, str) or not value.strip():
        _fail(src, name, value, "must be a non-empty string")
    if dotless and "." in value:
        _fail(src, name, value, "must not contain '.' (points are named 'body.point')")
    return value


def _table(src, name, value) -> dict:
    if not isinstance(value, dict):
        _fail(src, name, value, "must be a table")
    return value


def _known_fields(src, where, table, kind):
    for key in table:
        if key not in _FIELDS[kind]:
            _fail(src, f"{where}.{key}", table[key],
                  f"unknown field; expected one of {', '.join(sorted(_FIELDS[kind]))}")


def _coordinates(src, name, value, unit) -> np.ndarray:
    """[x, y] or [x, y, z] in length units -> (3,) metres."""
    arr = numeric_array(value)
    if arr is None or arr.shape not in ((2,), (3,)):
        _fail(src, name, value, "must be [x, y] or [x, y, z] (numbers)")
    if not np.isfinite(arr).all():
        _fail(src, name, value, "must be finite (no NaN or Inf)")
    return np.append(arr, 0.0)[:3] * unit if arr.size == 2 else arr * unit


def _points(src, where, spec, unit, known: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A body's (or the ground's) ``points`` table, each [x, y(, z)] or, in the plane,
    {from = [p, q], distances = [r1, r2], side = "left" | "right"}: the point at r1 from p and r2
    from q, on that side of the line p -> q (a dyad drawn with compasses)."""
    out = dict(known)
    for pname, value in _table(src, f"{where}.points", spec).items():
        fname = f"{where}.points.{pname}"
        _string(src, fname, pname, dotless=True)
        if pname in out:
            _fail(src, fname, value, f"the point {pname!r} is already defined"
                  + (" (every body has 'origin', a bar 'end')" if pname in (ORIGIN, END) else ""))
        if isinstance(value, dict):
            for key in value:
                if key not in ("from", "distances", "side"):
                    _fail(src, f"{fname}.{key}", value[key], "unknown field; a point by "
                          "distances gives from = [p, q], distances = [r1, r2], side")
            ends = _point_pair(src, f"{fname}.from", value.get("from"), out)
            dist = value.get("distances")
            if not (isinstance(dist, list) and len(dist) == 2):
                _fail(src, f"{fname}.distances", dist, "must be two distances [r1, r2]")
            r1, r2 = (_number(src, f"{fname}.distances", d, positive=True) * unit for d in dist)
            side = value.get("side")
            if side not in ("left", "right"):
                _fail(src, f"{fname}.side", side, "must be 'left' or 'right' (of the line from "
                      "the first point to the second)")
            p, q = out[ends[0]], out[ends[1]]
            try:
                xy = circle_meet(p, r1, q, r2, 1 if side == "left" else -1)
            except ValueError:
                _fail(src, f"{fname}.distances", dist, f"no such point: {ends[0]} and "
                      f"{ends[1]} are {np.linalg.norm((q - p)[:2]) / unit:.6g} apart, which "
                      "distances of these lengths cannot span (not a triangle)")
            out[pname] = np.array([xy[0], xy[1], 0.0])
        else:
            out[pname] = _coordinates(src, fname, value, unit)
    return out


def _axis(src, name, value, joint):
    if value is None:
        return "z" if joint == "R" else "x"
    if isinstance(value, str):
        if value not in AXES:
            _fail(src, name, value, "must be 'x', 'y', 'z' or a vector [x, y, z]")
        return value
    arr = check_vector(src, name, value, 3)
    if not np.linalg.norm(arr) > 0:
        _fail(src, name, value, "must not be the zero vector")
    return tuple(arr / np.linalg.norm(arr))


# --------------------------------------------------------------------------- bodies
@dataclass
class _Body:
    name: str
    where: str      # its field prefix in the file, e.g. "body[2]"
    parent: int     # index, -1 the world
    body: Body
    joint: TreeJoint
    points: dict[str, np.ndarray]


def _inertial(src, where, row, unit, points, name) -> tuple[Body, dict]:
    """The body's mass properties, from ``length``, ``bars`` or ``mass``/``com``/``inertia``."""
    has = {key for key in ("length", "bars", "mass", "density", "com", "inertia") if key in row}
    if "length" in has:
        if has & {"bars", "com", "inertia"}:
            _fail(src, f"{where}.length", row["length"], "a bar (length) takes mass or density, "
                  f"not {', '.join(sorted(has & {'bars', 'com', 'inertia'}))}")
        length = _number(src, f"{where}.length", row["length"], positive=True) * unit
        if ("mass" in has) == ("density" in has):
            _fail(src, f"{where}.length", row["length"], "a bar needs exactly one of mass [kg] "
                  "or density [kg/m]")
        mass = (_number(src, f"{where}.mass", row["mass"], nonnegative=True) if "mass" in has
                else _number(src, f"{where}.density", row["density"], nonnegative=True) * length)
        points = dict(points, end=np.array([length, 0.0, 0.0]))
        return bar_body(name, length, mass), points
    if "bars" in has:
        if has & {"mass", "com", "inertia"} or "density" not in has:
            _fail(src, f"{where}.bars", row["bars"], "bars between points take density [kg/m] "
                  "only (their mass, centre and inertia follow)")
        density = _number(src, f"{where}.density", row["density"], nonnegative=True)
        bars = row["bars"]
        if not isinstance(bars, list) or not bars:
            _fail(src, f"{where}.bars", bars, "must be a list of point pairs [[p, q], ...]")
        segments = []
        for i, pair in enumerate(bars):
            pair = _point_pair(src, f"{where}.bars[{i}]", pair, points)
            segments.append((points[pair[0]], points[pair[1]]))
        return bars_body(name, segments, density), points
    if "mass" not in has:
        _fail(src, where, name, "give the body as a bar (length), as bars between its points "
              "(bars, density), or as a rigid body (mass, com, inertia)")
    if "density" in has:
        _fail(src, f"{where}.density", row["density"], "density goes with a bar (length) or "
              "bars; a general body gives mass, com and inertia")
    mass = _number(src, f"{where}.mass", row["mass"], nonnegative=True)
    com = (_coordinates(src, f"{where}.com", row["com"], unit) if "com" in has
           else np.zeros(3))
    inertia = check_inertia(src, f"{where}.inertia", row.get("inertia", [0.0, 0.0, 0.0]),
                            physical=True)
    return Body(name, mass, tuple(com), tuple(map(tuple, inertia))), points


def _bodies(src, rows, unit, ground: dict[str, np.ndarray]) -> list[_Body]:
    if not isinstance(rows, list) or not rows:
        _fail(src, "body", rows, "missing [[body]] tables" if rows is None else
              "must be an array of [[body]] tables, parents first")
    out: list[_Body] = []
    index: dict[str, int] = {}
    for k, row in enumerate(rows):
        where = f"body[{k}]"
        _known_fields(src, where, _table(src, where, row), "body")
        for key in ("name", "parent", "at"):
            if key not in row:
                _fail(src, f"{where}.{key}", None, "missing field")
        name = _string(src, f"{where}.name", row["name"], dotless=True)
        count = row.get("repeat", 1)
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            _fail(src, f"{where}.repeat", count, "must be a whole number >= 1")
        names = [name] if count == 1 else [f"{name}{i + 1}" for i in range(count)]
        for n in names:
            if n == GROUND or n in index:
                _fail(src, f"{where}.name", n, "is already a body's name" if n in index else
                      "'ground' is the world's name")
        joint = row.get("joint", "R")
        if joint not in ("R", "P"):
            _fail(src, f"{where}.joint", joint, "must be 'R' (revolute) or 'P' (prismatic)")
        axis = _axis(src, f"{where}.axis", row.get("axis"), joint)
        angle = math.radians(_number(src, f"{where}.angle", row.get("angle", 0.0)))
        c, s = math.cos(angle), math.sin(angle)
        rotation: tuple[tuple[float, float, float], ...] | None = \
            ((c, -s, 0.0), (s, c, 0.0), (0.0, 0.0, 1.0))
        body, points = _inertial(src, where, row, unit,
                                 _points(src, where, row.get("points", {}), unit,
                                         {ORIGIN: np.zeros(3)}), names[0])
        if count > 1 and END not in points:
            _fail(src, f"{where}.repeat", count, "a repeated body is a chain of bars: give it a "
                  "length (each copy hangs from the previous one's end)")
        parent_name = _string(src, f"{where}.parent", row["parent"])
        if parent_name == GROUND:
            parent, parent_points = -1, ground
        elif parent_name in index:
            parent = index[parent_name]
            parent_points = out[parent].points
        else:
            _fail(src, f"{where}.parent", parent_name, "unknown body; the parent is 'ground' or a "
                  "body listed before this one" + (f" ({_listing(index)})" if index else ""))
        at = row["at"]
        if isinstance(at, str):
            if at not in parent_points:
                _fail(src, f"{where}.at", at, f"no such point on {parent_name}; known: "
                      + _listing(parent_points))
            translation = parent_points[at]
        else:
            translation = _coordinates(src, f"{where}.at", at, unit)
        for i, n in enumerate(names):
            if i:  # a copy hangs from the previous copy's end
                parent, translation, rotation = len(out) - 1, points[END], None
                body = Body(n, body.mass, body.com, body.inertia)
            out.append(_Body(n, where, parent, body,
                             TreeJoint(n, joint, axis, rotation, tuple(translation)), points))
            index[n] = len(out) - 1
    return out


# --------------------------------------------------------------------------- cuts
def _reference(src, name, value, bodies, ground, index) -> tuple[int, np.ndarray]:
    text = _string(src, name, value)
    owner, dot, pname = text.rpartition(".")
    if not dot:
        _fail(src, name, value, "must name a point as 'body.point' or 'ground.point'")
    if owner == GROUND:
        if pname not in ground:
            _fail(src, name, value, "no such ground point; known: " + _listing(ground))
        return -1, ground[pname]
    if owner not in index:
        _fail(src, name, value, f"unknown body {owner!r}; known: {_listing(index)}")
    b = bodies[index[owner]]
    if pname not in b.points:
        _fail(src, name, value, f"no such point on {owner}; known: {_listing(b.points)}")
    return index[owner], b.points[pname]


def _cuts(src, rows, bodies, ground) -> list[CutJoint]:
    if not isinstance(rows, list) or not rows:
        _fail(src, "cut", rows, "missing [[cut]] tables: a linkage file describes closed loops"
              if rows is None else "must be an array of [[cut]] tables")
    index = {b.name: i for i, b in enumerate(bodies)}
    cuts = []
    for k, row in enumerate(rows):
        where = f"cut[{k}]"
        _known_fields(src, where, _table(src, where, row), "cut")
        for key in ("name", "a", "b"):
            if key not in row:
                _fail(src, f"{where}.{key}", None, "missing field")
        name = _string(src, f"{where}.name", row["name"])
        kind = row.get("kind", "planar")
        if kind not in KINDS:
            _fail(src, f"{where}.kind", kind, f"unknown; known: {', '.join(KINDS)} "
                  "('planar': a pin of a mechanism in the xy plane, 2 equations; 'point': a ball "
                  "joint, 3; 'line': the points kept level along one direction of body b, 1)")
        rot_b = None
        if kind == "line":
            if "direction" not in row:
                _fail(src, f"{where}.direction", None, "missing field: a 'line' cut keeps its "
                      "points level along this direction [x, y, z] of body b's frame (the "
                      "world's for the ground)")
            rot_b = _line_frame(check_vector(src, f"{where}.direction", row["direction"], 3),
                                src, f"{where}.direction", row["direction"])
        elif "direction" in row:
            _fail(src, f"{where}.direction", row["direction"], f"only a 'line' cut takes a "
                  f"direction (this one is {kind!r})")
        a, pa = _reference(src, f"{where}.a", row["a"], bodies, ground, index)
        b, pb = _reference(src, f"{where}.b", row["b"], bodies, ground, index)
        if a < 0:
            if b < 0:
                _fail(src, f"{where}.a", row["a"], "a cut joint joins a body to another body or "
                      "to the ground, not the ground to itself")
            if kind == "line":  # its direction is b's: swapped, it would turn to the world's
                _fail(src, f"{where}.a", row["a"], "a 'line' cut's direction is in body b's "
                      "frame: write the ground's point as b (the direction then the world's)")
            a, pa, b, pb = b, pb, a, pa
        if a == b:
            _fail(src, f"{where}.b", row["b"], f"a cut joint joins two different bodies (here "
                  f"{bodies[a].name} and itself)")
        cuts.append(CutJoint(name, a, tuple(pa), b, tuple(pb), kind, rot_b=rot_b))
    return cuts


def _line_frame(d, src, name, value) -> tuple[tuple[float, float, float], ...]:
    """A frame (rows of a rotation matrix) whose x axis is the unit vector along d: the
    ``rot_b`` of a 'line' cut (:class:`~redysim.model.tree.CutJoint`), whose one equation is
    along the frame's x axis."""
    n = float(np.linalg.norm(d))
    if not n > 0:
        _fail(src, name, value, "must not be the zero vector")
    x = d / n
    helper = np.eye(3)[int(np.argmin(np.abs(x)))]
    y = np.cross(x, helper)
    y /= np.linalg.norm(y)
    R = np.column_stack((x, y, np.cross(x, y)))
    return tuple((float(r[0]), float(r[1]), float(r[2])) for r in R)


# --------------------------------------------------------------------------- the initial state
def _joint_value(src, name, value, joint, unit) -> float:
    x = _number(src, name, value)
    return math.radians(x) if joint == "R" else x * unit


def _initial(src, spec, bodies, loops, unit, cuts) -> tuple[np.ndarray, int | None]:
    spec = _table(src, "initial", {} if spec is None else spec)
    _known_fields(src, "initial", spec, "initial")
    names = [b.name for b in bodies]
    types = [b.joint.type for b in bodies]
    n = len(bodies)
    q = np.zeros(n)
    written: dict[int, tuple[str, object]] = {}  # joint -> (its field, its value in the file)
    if "shape" in spec:
        if spec["shape"] != "catenary":
            _fail(src, "initial.shape", spec["shape"], "unknown; known: 'catenary'")
        for key in ("q", "guess", "driver"):
            if key in spec:
                _fail(src, f"initial.{key}", spec[key], "shape = 'catenary' gives every joint "
                      "angle; leave this out")
        q = _catenary(src, bodies, cuts)
    if "q" in spec:
        if "guess" in spec:
            _fail(src, "initial.guess", spec["guess"], "give q (every joint) or guess (some), "
                  "not both")
        values = spec["q"]
        if not isinstance(values, list) or len(values) != n:
            _fail(src, "initial.q", values, f"must be a list of {n} values, one per joint "
                  f"({_listing(names)}): deg for R, length units for P")
        q = np.array([_joint_value(src, f"initial.q[{k}]", v, types[k], unit)
                      for k, v in enumerate(values)])
        written.update({k: (f"initial.q[{k}]", v) for k, v in enumerate(values)})
    for jname, v in _table(src, "initial.guess", spec.get("guess", {})).items():
        if jname not in names:
            _fail(src, f"initial.guess.{jname}", v, f"unknown joint; known: {_listing(names)}")
        k = names.index(jname)
        q[k] = _joint_value(src, f"initial.guess.{jname}", v, types[k], unit)
        written[k] = (f"initial.guess.{jname}", v)
    driver = None
    if "driver" in spec or "angle" in spec:
        for key in ("driver", "angle"):
            if key not in spec:
                _fail(src, f"initial.{key}", None, "missing field: a driver (a joint's name) "
                      "goes with its angle (deg; length units for a P joint)")
        if spec["driver"] not in names:
            _fail(src, "initial.driver", spec["driver"], f"unknown joint; known: "
                  f"{_listing(names)}")
        driver = names.index(spec["driver"])
        q[driver] = _joint_value(src, "initial.angle", spec["angle"], types[driver], unit)
    max_change = _number(src, "initial.max_change", spec.get("max_change", DEFAULT_MAX_CHANGE),
                         positive=True)
    try:
        assembled = assemble(loops, q, hold=[] if driver is None else [driver])
    except StateError as exc:
        field_name = "initial.angle" if driver is not None else "initial"
        _fail(src, field_name, spec.get("angle"), f"the mechanism does not assemble: {exc}")
    moved = np.abs(assembled - q)  # an R joint's by its wrapped angle
    turns = np.array([t == "R" for t in types])
    moved[turns] = np.abs((assembled - q + math.pi) % (2 * math.pi) - math.pi)[turns]
    limit = np.array([math.radians(max_change) if t == "R" else max_change * unit
                      for t in types])
    worst = int(np.argmax(moved / limit))
    if moved[worst] > limit[worst]:
        shown = (f"{math.degrees(moved[worst]):.3g} deg" if types[worst] == "R"
                 else f"{moved[worst] / unit:.3g} length units")
        guessed = math.degrees(q[worst]) if types[worst] == "R" else q[worst] / unit
        field_name, value = written.get(worst, (f"initial (joint {names[worst]})", guessed))
        _fail(src, field_name, value, f"the loops closed {shown} away from it (more than "
              f"max_change = {max_change:g}): the guess is far from the configuration, or the "
              "loops closed on another assembly branch; give a closer guess")
    return assembled, driver


def _catenary(src, bodies, cuts) -> np.ndarray:
    """A chain of equal bars hanging from a ground point, its last end cut to another ground
    point at the same height: every joint on one catenary
    (:func:`redysim.model.shapes.catenary_angles`)."""
    from redysim.model.shapes import catenary_angles

    n = len(bodies)
    lengths = {float(b.points[END][0]) if END in b.points else None for b in bodies}
    chain = all(b.parent == k - 1 and b.joint.type == "R" and b.joint.axis == "z"
                for k, b in enumerate(bodies))
    if len(lengths) != 1 or None in lengths or not chain:
        _fail(src, "initial.shape", "catenary", "needs a chain of equal bars (length), each "
              "about z and hanging from the one before")
    length = lengths.pop()
    assert length is not None  # refused above
    ends = [c for c in cuts if c.body_a == n - 1 and c.body_b < 0
            and np.allclose(c.point_a, (length, 0.0, 0.0))]
    if len(cuts) != 1 or not ends:
        _fail(src, "initial.shape", "catenary", "needs one cut joint: the last bar's end to a "
              "ground point")
    base = np.asarray(bodies[0].joint.translation)
    gap = np.asarray(ends[0].point_b) - base
    if abs(gap[1]) > 1e-12 * max(1.0, abs(gap[0])) or gap[2] != 0 or not gap[0] > 0:
        _fail(src, "cut[0].b", tuple(ends[0].point_b), "shape = 'catenary' needs the far pin at "
              "the first joint's height, in +x from it")
    try:
        return catenary_angles(n, n * length, float(gap[0]))
    except ValueError as exc:
        _fail(src, "initial.shape", "catenary", str(exc))


# --------------------------------------------------------------------------- the file
def _point_pair(src: str, field_name: str, value, known) -> list:
    """``value`` as a pair of known point names [p, q], or a CaseError naming the field."""
    if not (isinstance(value, list) and len(value) == 2):
        _fail(src, field_name, value, "must be a pair of point names [p, q]")
    for e in value:
        if e not in known:
            _fail(src, field_name, e, "unknown point; known here: " + _listing(known))
    return value


def is_linkage_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a TOML linkage file (it has a ``[linkage]`` table); False for any
    other file, or unreadable TOML (the other loaders report that)."""
    try:
        with open(path, "rb") as fh:
            return "linkage" in tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return False


def load_linkage(path: str | os.PathLike) -> Linkage:
    """The linkage of a TOML file (module docstring, ``cases/loops/README.md``)."""
    from redysim.io.cases import read_toml

    if isinstance(path, bool) or not isinstance(path, str | os.PathLike):
        raise CaseError("load_linkage", "path", path, "must be the path of a linkage file "
                        "(a str or a pathlib.Path)")
    if isinstance(path, str) and path.startswith("example-robot-data:"):
        raise CaseError("load_linkage", "path", path, "is a robot's name, given to the linkage "
                        "loader: load a robot with redysim.load_model(path); load_linkage reads "
                        "a linkage file (a .toml with [linkage], as in cases/loops/)")
    path = Path(path)
    if path.is_dir():
        raise CaseError(str(path), "<file>", None, "is a folder, not a linkage file")
    if not path.is_file():
        raise FileNotFoundError(f"linkage file {str(path)!r} does not exist")
    doc = read_toml(path)[0]
    return linkage_from_dict(doc, source=str(path), default_name=path.stem, path=path)


def linkage_from_dict(doc: dict, *, source: str = "<dict>", default_name: str = "linkage",
                      path: Path | None = None) -> Linkage:
    """The linkage of a parsed linkage file."""
    src = source
    if not isinstance(doc, dict):
        _fail(src, "<top>", type(doc).__name__, "a linkage is a table (a parsed TOML document, "
              "a dict)")
    for key in doc:
        if key not in _FIELDS:
            _fail(src, key, doc[key], "unknown table; a linkage file has [linkage], [ground], "
                  "[[body]], [[cut]] and [initial]")
        if key not in _ARRAYS:
            _known_fields(src, key, _table(src, key, doc[key]), key)
    head = doc.get("linkage", {})
    name = _string(src, "linkage.name", head.get("name", default_name))
    texts = {key: head.get(key, "") for key in ("description", "source")}
    for key, value in texts.items():
        if not isinstance(value, str):
            _fail(src, f"linkage.{key}", value, "must be a string")
    unit_name = head.get("length_unit", "m")
    if unit_name not in UNITS:
        _fail(src, "linkage.length_unit", unit_name, f"must be one of {', '.join(UNITS)}")
    unit = UNITS[unit_name]
    gravity = check_vector(src, "linkage.gravity",
                           head.get("gravity", (0.0, -STANDARD_GRAVITY, 0.0)), 3)
    ground = _points(src, "ground", doc.get("ground", {}).get("points", {}), unit, {})
    bodies = _bodies(src, doc.get("body"), unit, ground)
    model = Model.build([b.body for b in bodies], [b.joint for b in bodies],
                        [b.parent for b in bodies], gravity=tuple(gravity), name=name, source=src)
    cuts = _cuts(src, doc.get("cut"), bodies, ground)
    model = model.with_cuts(cuts, source=src)  # the closed mechanism: the tree and its cuts
    loops = ClosedLoops(model, source=src)
    q0, driver = _initial(src, doc.get("initial"), bodies, loops, unit, cuts)
    points = {f"{GROUND}.{p}": (-1, x) for p, x in ground.items()}
    for k, b in enumerate(bodies):
        points.update({f"{b.name}.{p}": (k, x) for p, x in b.points.items()})
    return Linkage(name=name, path=path if path is not None else Path(src), model=model,
                   loops=loops, q0=q0, description=texts["description"],
                   source=texts["source"], driver=driver, points=points, unit=unit)
