"""The parts every model is built from: joint types, joints, links, and the checks of their values.

A joint type is a sequence of elementary axes (revolute or prismatic), each fixed in the frame
the axes before it leave (:data:`JOINT_TYPES`: R, P, U, S); a :class:`Joint` is a type and, for
R and P, an axis; a :class:`Link` a chain's rigid link (length, mass, centre of mass, inertia
about it). The models built from them are :class:`redysim.model.tree.Model` and its serial-chain
form :class:`redysim.model.tree.Chain` (docs/design.md, "Chain conventions").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NoReturn

import numpy as np

from redysim.errors import CaseError

# --------------------------------------------------------------------------- joint types
# The one table of joint types. Every joint is a sequence of elementary 1-DOF axes; an axis is
# (kind, default direction), kind "R" (revolute about it) or "P" (prismatic along it), direction
# in the frame left by the axes before it. The kernels read the flattened per-DOF arrays built
# from this table and never branch on the joint's name (one dispatch point: _kernels/joints.py).
JOINT_TYPES: dict[str, tuple[tuple[str, str], ...]] = {
    "R": (("R", "z"),),  # revolute, 1 DOF; planar chains bend in the XY plane
    "P": (("P", "x"),),  # prismatic, 1 DOF; default along the link
    "U": (("R", "y"), ("R", "z")),  # universal: parent's y, then the rotated z (R = Ry Rz)
    "S": (("R", "y"), ("R", "z"), ("R", "x")),  # spherical: the U axes, then the link's own x
}
# Joint types whose single axis a case may choose ("axis" field).
AXIS_CHOOSABLE = ("R", "P")

AXIS_NAMES = {"x": 0, "y": 1, "z": 2}
KIND_CODES = {"R": 0, "P": 1}
GENERAL_AXIS = 3  # axis code of a direction that is not a coordinate axis

INERTIA_MODELS = ("rod", "cylinder", "explicit")
STANDARD_GRAVITY = 9.81


def _fail(source, field_name, value, problem) -> NoReturn:
    raise CaseError(source, field_name, value, problem)


def check_positive(source: str, field_name: str, value, *, allow_zero: bool = False) -> float:
    """Return ``value`` as a float if it is a finite number > 0 (>= 0 with ``allow_zero``)."""
    if isinstance(value, bool) or not isinstance(value, int | float | np.floating | np.integer):
        _fail(source, field_name, value, "must be a number")
    x = float(value)
    if not math.isfinite(x):
        _fail(source, field_name, value, "must be finite")
    if x < 0 or (x == 0 and not allow_zero):
        _fail(source, field_name, value, "must be >= 0" if allow_zero else "must be > 0")
    return x


# numpy dtype kinds accepted as numbers: signed and unsigned integers, floats. Not bool ("b"),
# strings ("U", "S": numpy would parse "1.5" silently), complex ("c": it would drop the imaginary
# part) or objects ("O": None would become NaN).
NUMERIC_KINDS = "iuf"


def numeric_array(value) -> np.ndarray | None:
    """``value`` as a float array if it is numbers (int or float) only, else None."""
    try:
        arr = np.asarray(value)
    except (TypeError, ValueError):  # ragged nesting
        return None
    if arr.dtype.kind not in NUMERIC_KINDS:
        return None
    return arr.astype(float, copy=False)


def check_vector(source: str, field_name: str, value, size: int) -> np.ndarray:
    """Return ``value`` as a finite float vector of the given size."""
    arr = numeric_array(value)
    if arr is None:
        _fail(source, field_name, value, f"must be a list of {size} numbers")
    if arr.shape != (size,):
        _fail(source, field_name, value, f"must be a list of {size} numbers, got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        _fail(source, field_name, value, "must be finite (no NaN or Inf)")
    return arr


# --------------------------------------------------------------------------- links and joints
@dataclass(frozen=True)
class Joint:
    """A joint: its type (a key of :data:`JOINT_TYPES`) and, for R and P, an optional axis."""

    type: str
    axis: tuple[float, float, float] | str | None = None

    def axes(self, source: str = "chain",
             field_name: str = "joint") -> list[tuple[str, np.ndarray]]:
        """The joint's elementary axes as (kind, unit vector) pairs."""
        if self.type not in JOINT_TYPES:
            _fail(source, f"{field_name}.type", self.type,
                  f"unknown joint type; known types: {', '.join(JOINT_TYPES)}")
        spec: tuple[tuple[str, tuple[float, float, float] | str], ...] = JOINT_TYPES[self.type]
        if self.axis is not None:
            if self.type not in AXIS_CHOOSABLE:
                _fail(source, f"{field_name}.axis", self.axis,
                      f"a {self.type} joint has fixed axes; only {AXIS_CHOOSABLE} take an axis")
            spec = ((spec[0][0], self.axis),)
        out = []
        for kind, direction in spec:
            if isinstance(direction, str):
                if direction not in AXIS_NAMES:
                    _fail(source, f"{field_name}.axis", direction,
                          "must be 'x', 'y', 'z' or a vector")
                u = np.zeros(3)
                u[AXIS_NAMES[direction]] = 1.0
            else:
                u = check_vector(source, f"{field_name}.axis", direction, 3)
                norm = float(np.linalg.norm(u))
                if norm < 1e-12:
                    _fail(source, f"{field_name}.axis", direction, "must not be the zero vector")
                u = u / norm
            out.append((kind, u))
        return out


@dataclass(frozen=True)
class Link:
    """A rigid link: length, mass, centre of mass and inertia about the COM, in the link frame.

    ``physical``: the inertia must be a rigid body's (positive semi-definite, and each principal
    moment at most the sum of the other two: the triangle inequality), checked when a chain is
    built. ``False`` skips the triangle inequality only; the paper's ``rod`` model needs it
    (Ixx = m r^2 / 2 exceeds Iyy + Izz = m l^2 / 6 whenever l < sqrt(3) r).
    """

    length: float
    mass: float
    com: tuple[float, float, float]
    inertia: tuple[tuple[float, float, float], ...]  # 3x3 about the COM, link frame
    physical: bool = True

    @classmethod
    def uniform(cls, length: float, mass: float, radius: float = 0.0, model: str = "rod",
                source: str = "chain", field_name: str = "link") -> Link:
        """A straight uniform link with the COM at mid-length and a standard inertia model.

        ``rod``: Ixx = m r^2/2, Iyy = Izz = m l^2/12 (the paper's RE-U chains);
        ``cylinder``: Ixx = m r^2/2, Iyy = Izz = m (3 r^2 + l^2)/12 (the section-5 study chains).
        """
        length = check_positive(source, f"{field_name}.length", length)
        mass = check_positive(source, f"{field_name}.mass", mass)
        radius = check_positive(source, f"{field_name}.radius", radius, allow_zero=True)
        # products, not powers: a float ** 2 that overflows raises, a product gives inf
        ixx = mass * (radius * radius) / 2
        if model == "rod":
            iyy = mass * (length * length) / 12
        elif model == "cylinder":
            iyy = mass * (3 * radius * radius + length * length) / 12
        else:
            _fail(source, f"{field_name}.inertia", model,
                  "unknown inertia model; use 'rod', 'cylinder' or an explicit 3x3 / "
                  "[Ixx, Iyy, Izz]")
        if not (math.isfinite(ixx) and math.isfinite(iyy)):
            culprit = ("length" if not math.isfinite(length * length) else
                       "radius" if not math.isfinite(radius * radius) else "mass")
            _fail(source, f"{field_name}.{culprit}", locals()[culprit],
                  f"too large: the {model} inertia overflows (Ixx = {ixx}, Iyy = {iyy})")
        inertia = ((ixx, 0.0, 0.0), (0.0, iyy, 0.0), (0.0, 0.0, iyy))
        return cls(length, mass, (length / 2, 0.0, 0.0), inertia, physical=model != "rod")


def check_inertia(source: str, field_name: str, value, *, physical: bool = False) -> np.ndarray:
    """A 3x3 symmetric positive semi-definite inertia from a 3x3 list or [Ixx, Iyy, Izz];
    ``physical``: also the triangle inequality of its principal moments (a rigid body's)."""
    arr = numeric_array(value)
    if arr is None:
        _fail(source, field_name, value, "must be a 3x3 matrix or [Ixx, Iyy, Izz] of numbers")
    if arr.shape == (3,):
        arr = np.diag(arr)
    if arr.shape != (3, 3):
        _fail(source, field_name, value,
              f"must be a 3x3 matrix or [Ixx, Iyy, Izz], got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        _fail(source, field_name, value, "must be finite (no NaN or Inf)")
    scale = max(np.abs(arr).max(), np.finfo(float).tiny)
    if np.abs(arr - arr.T).max() > 1e-12 * scale:
        _fail(source, field_name, value, "must be symmetric")
    arr = 0.5 * (arr + arr.T)
    eig = np.linalg.eigvalsh(arr)
    if eig[0] < -1e-12 * max(1.0, abs(eig[-1])):
        _fail(source, field_name, value, f"must be positive semi-definite (eigenvalues {eig})")
    if physical and eig[2] > (eig[0] + eig[1]) * (1 + 1e-12):
        _fail(source, field_name, value,
              f"is not a rigid body's: its largest principal moment {eig[2]:.6g} exceeds the "
              f"sum of the other two ({eig[0]:.6g} + {eig[1]:.6g}; the triangle inequality). "
              "The paper's rod model, which breaks it on purpose, is inertia = 'rod' "
              "(Link.uniform(..., model='rod'), or Link(..., physical=False))")
    return arr


# --------------------------------------------------------------------------- the chain
def _readonly(a) -> np.ndarray:
    """A read-only view of a private C-contiguous copy of ``a`` (the view's ``base``).

    The copy stays writeable so that :func:`kernel_alias` can hand it to the kernels: numba's
    dispatcher does not take its fast typing path for read-only arrays (docs/design.md,
    "Performance notes"). Nothing writes through it.
    """
    owner = np.array(a, order="C")
    view = owner.view()
    view.flags.writeable = False
    return view


def kernel_alias(a: np.ndarray) -> np.ndarray:
    """The writeable array behind one of a chain's read-only arrays, for passing to a kernel
    (which only reads it); ``a`` itself when it is writeable, a copy when no such owner is at hand
    (an unpickled chain, say)."""
    if a.flags.writeable:
        return a
    owner = a.base
    if (isinstance(owner, np.ndarray) and owner.flags.writeable and owner.shape == a.shape
            and owner.dtype == a.dtype and owner.flags.c_contiguous
            and owner.ctypes.data == a.ctypes.data):
        return owner
    return np.array(a, order="C")
