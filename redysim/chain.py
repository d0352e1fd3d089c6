"""The chain model: an immutable description of a serial chain of rigid links.

Conventions (shared by every engine adapter; docs/design.md, "Chain conventions"):

- World frame: gravity ``g`` (default 9.81 m/s^2 along -Y); base link #0 fixed at the origin.
- Link k = 1..nl has its frame at its proximal joint O_k, its x axis along the link, length l_k,
  mass m_k, centre of mass c_k (default (l_k/2, 0, 0)) and inertia about the COM in the link frame.
  O_{k+1} = O_k + l_k x_k.
- Joint k joins link k-1 to link k at O_k. Each joint type is a sequence of elementary axes
  (revolute or prismatic) fixed in the frame produced by the axes before it; see
  :data:`JOINT_TYPES`.
  All angles zero gives a straight chain along +X; q is ordered joint by joint.

The model holds only what describes the chain. Per-call scratch space lives in
:class:`redysim.workspace.Workspace` (Pinocchio's Model/Data split).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .errors import CaseError

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


def _fail(source, field_name, value, problem):
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
        spec = JOINT_TYPES[self.type]
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


@dataclass(frozen=True, eq=False)
class Chain:
    """An immutable serial chain: links, joints, gravity; fixed base at the origin.

    Build it with :meth:`Chain.build` (or from a case file with :func:`redysim.load_case`). The
    per-DOF and per-link arrays below are what the kernels read; they are read-only.

    Attributes (nl links, n DOF):
        name:          a label.
        joints:        the joints, one per link.
        length, mass:  (nl,) link lengths l_k [m] and masses m_k [kg].
        com:           (nl, 3) centre of mass c_k in the link frame [m].
        inertia_com:   (nl, 3, 3) inertia about the COM in the link frame [kg m^2].
        gravity:       (3,) gravitational acceleration in the world frame [m/s^2].
        joint_qoff:    (nl + 1,) index of joint k's first DOF in q (joint_qoff[nl] = n).
        dof_kind:      (n,) 0 revolute, 1 prismatic.
        dof_axis:      (n,) 0, 1, 2 when the axis is exactly +x, +y, +z of the frame before it,
                       3 for any other direction (-z and a tilted z included).
        dof_u:         (n, 3) the unit axis in the frame left by the axes before it.
        inertia_O:     (nl, 3, 3) inertia about O_k in the link frame (I_C + m (|c|^2 1 - c c^T)).
        mass_com:      (nl, 3) m_k c_k in the link frame.
    """

    name: str
    joints: tuple[Joint, ...]
    length: np.ndarray
    mass: np.ndarray
    com: np.ndarray
    inertia_com: np.ndarray
    gravity: np.ndarray
    joint_qoff: np.ndarray = field(repr=False)
    dof_kind: np.ndarray = field(repr=False)
    dof_axis: np.ndarray = field(repr=False)
    dof_u: np.ndarray = field(repr=False)
    inertia_O: np.ndarray = field(repr=False)
    mass_com: np.ndarray = field(repr=False)

    @classmethod
    def build(cls, links: Sequence[Link], joints: Sequence[Joint | str], *,
              gravity: Sequence[float] = (0.0, -STANDARD_GRAVITY, 0.0), name: str = "chain",
              source: str = "chain") -> Chain:
        """Validate and freeze a chain. ``joints`` may be Joint objects or type names."""
        if len(links) == 0:
            _fail(source, "links", len(links), "a chain needs at least one link")
        if len(joints) != len(links):
            _fail(source, "joints", len(joints), f"need one joint per link ({len(links)} links)")
        named: dict[str, Joint] = {}  # one Joint per type name, so that repeats are shared
        joints = tuple(j if isinstance(j, Joint) else named.setdefault(str(j), Joint(str(j)))
                       for j in joints)
        nl = len(links)

        # Links and joints are immutable: each distinct object is validated once (a uniform chain
        # repeats one Link and one Joint nl times) and its values are spread by index.
        link_of = np.empty(nl, dtype=np.int64)  # link k -> its distinct Link
        first: dict[int, int] = {}
        values = []
        for k, link in enumerate(links):
            u = first.get(id(link))
            if u is None:
                where = f"links[{k}]"
                if not isinstance(link, Link):
                    _fail(source, where, link, "must be a redysim.Link")
                values.append((check_positive(source, f"{where}.length", link.length),
                               check_positive(source, f"{where}.mass", link.mass),
                               check_vector(source, f"{where}.com", link.com, 3),
                               check_inertia(source, f"{where}.inertia", link.inertia,
                                             physical=link.physical)))
                u = first[id(link)] = len(values) - 1
            link_of[k] = u
        length = np.array([v[0] for v in values])[link_of]
        mass = np.array([v[1] for v in values])[link_of]
        com = np.array([v[2] for v in values])[link_of]
        inertia = np.array([v[3] for v in values])[link_of]
        grav = check_vector(source, "gravity", gravity, 3)

        # Per DOF: kind, axis code and unit axis of each distinct joint, then spread joint by joint.
        joint_of = np.empty(nl, dtype=np.int64)
        first = {}
        dofs = []  # per distinct joint: (kinds, codes, units)
        for k, joint in enumerate(joints):
            u = first.get(id(joint))
            if u is None:
                axes = joint.axes(source, f"joints[{k}]")
                # a coordinate axis's code only for exactly +x, +y or +z: the kernels' fast path
                # takes the frame's column as it is, so -z (or z tilted by 1e-9) must take the
                # general path, which uses the axis as given
                codes = [next((i for i in range(3) if np.array_equal(v, np.eye(3)[i])),
                              GENERAL_AXIS) for _, v in axes]
                dofs.append(([KIND_CODES[kind] for kind, _ in axes], codes, [v for _, v in axes]))
                u = first[id(joint)] = len(dofs) - 1
            joint_of[k] = u
        width = np.array([len(d[0]) for d in dofs], dtype=np.int64)  # DOF of each distinct joint
        start = np.concatenate(([0], np.cumsum(width)[:-1]))  # its first row in the flat tables
        per_joint = width[joint_of]
        qoff = np.concatenate(([0], np.cumsum(per_joint)))
        row = np.repeat(start[joint_of] - qoff[:-1], per_joint) + np.arange(qoff[-1])
        kinds = np.array([x for d in dofs for x in d[0]], dtype=np.int64)[row]
        codes = np.array([x for d in dofs for x in d[1]], dtype=np.int64)[row]
        units = np.array([x for d in dofs for x in d[2]], dtype=float).reshape(-1, 3)[row]

        # Inertia about O_k (parallel axis theorem) and first moment m c, both in the link frame.
        with np.errstate(over="ignore", invalid="ignore"):  # overflow is reported below
            cc = np.einsum("ki,kj->kij", com, com)
            sq = np.einsum("ki,ki->k", com, com)
            inertia_O = inertia + mass[:, None, None] * (sq[:, None, None] * np.eye(3) - cc)
            inertia_O = 0.5 * (inertia_O + inertia_O.transpose(0, 2, 1))
            mass_com = mass[:, None] * com
        bad = ~(np.isfinite(inertia_O).all(axis=(1, 2)) & np.isfinite(mass_com).all(axis=1))
        if bad.any():
            k = int(np.flatnonzero(bad)[0])
            _fail(source, f"links[{k}].com", [float(x) for x in com[k]],
                  f"the inertia about the joint, I_C + m (|c|^2 1 - c c^T) with m = {mass[k]}, "
                  "overflows: values too large")
        return cls(
            name=name, joints=joints, length=_readonly(length), mass=_readonly(mass),
            com=_readonly(com), inertia_com=_readonly(inertia), gravity=_readonly(grav),
            joint_qoff=_readonly(qoff.astype(np.int64)),
            dof_kind=_readonly(kinds), dof_axis=_readonly(codes), dof_u=_readonly(units),
            inertia_O=_readonly(inertia_O), mass_com=_readonly(mass_com),
        )

    @classmethod
    def uniform(cls, n_links: int, joint: str | Joint = "U", *, length: float = 1.0,
                mass: float | None = None, linear_density: float | None = None,
                radius: float = 0.0, inertia: str = "rod",
                gravity: Sequence[float] = (0.0, -STANDARD_GRAVITY, 0.0),
                name: str | None = None) -> Chain:
        """A chain of ``n_links`` identical uniform links with identical joints.

        Give the link ``mass`` or the ``linear_density`` (kg/m); ``length`` is per link.
        """
        if isinstance(n_links, bool) or not isinstance(n_links, int | np.integer) \
                or n_links < 1:
            raise CaseError("chain", "n_links", n_links, "must be a whole number >= 1")
        if (mass is None) == (linear_density is None):
            raise CaseError("chain", "mass/linear_density", (mass, linear_density),
                            "give exactly one of mass and linear_density")
        if mass is None:
            mass = check_positive("chain", "linear_density", linear_density) * length
        link = Link.uniform(length, mass, radius, inertia)
        joint = joint if isinstance(joint, Joint) else Joint(joint)
        return cls.build([link] * n_links, [joint] * n_links, gravity=gravity,
                         name=name or f"{joint.type}{n_links}")

    # ----------------------------------------------------------------------- derived facts
    @cached_property  # read on every call (the state checks): cached, the arrays are frozen
    def n_links(self) -> int:
        """nl, the number of moving links."""
        return int(self.length.shape[0])

    @cached_property
    def n_dof(self) -> int:
        """n, the number of degrees of freedom (length of q)."""
        return int(self.dof_kind.shape[0])

    @property
    def n_q(self) -> int:
        """Length of q (n: a chain's joints have one coordinate per DOF)."""
        return self.n_dof

    @property
    def n_v(self) -> int:
        """Length of qd, qdd and tau (n)."""
        return self.n_dof

    @property
    def total_mass(self) -> float:
        """M, the total mass [kg] (Eq. 11 divides the energy change by it)."""
        return float(self.mass.sum())

    @cached_property
    def is_planar(self) -> bool:
        """True when every joint is a single revolute about its frame's z axis: all the joint axes
        then stay parallel to the world Z, every link moves in the XY plane, and the planar
        specialisation of the recursion applies. (Out-of-plane inertia products, COM offsets along
        z and a gravity component along Z only load the joints with reaction moments and forces
        normal to the plane; they do not change qdd.)"""
        return bool(self.n_dof == self.n_links and np.all(self.dof_kind == 0)
                    and np.all(self.dof_axis == 2))

    def __setstate__(self, state: dict) -> None:
        """Unpickling: numpy restores arrays writeable; make them read-only views again."""
        for key, value in state.items():
            object.__setattr__(self, key,
                               _readonly(value) if isinstance(value, np.ndarray) else value)

    def __repr__(self) -> str:
        types = "".join(sorted({j.type for j in self.joints}))
        return (f"Chain({self.name!r}, links={self.n_links}, dof={self.n_dof}, joints={types}, "
                f"mass={self.total_mass:.6g} kg)")
