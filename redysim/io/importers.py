"""Models from URDF and MJCF (read by MuJoCo's compiler) files: :func:`load_urdf`,
:func:`load_mjcf`. :func:`redysim.load_model` reads any kind of model file, these two among them
(:mod:`redysim.io.kinds`: the file kinds).

**URDF** is read here, from the XML as written: a flat list of links and joints, walked
without recursion in time linear in their number (MuJoCo's URDF parser, which read them before,
grows quadratically and crashes on very long chains: docs/design.md, "Files in and out"). The
inertias are taken as the file gives them (real robot files break the triangle inequality by
rounding; a link of mass 0 keeps its rotational inertia, as Pinocchio reads it), rotations from
``rpy`` as urdfdom's, Rz(yaw) Ry(pitch) Rx(roll); gravity -9.81 along z (URDF has none; robots
are described z up). A root link named ``world`` is the world, as MuJoCo and Gazebo read it.
Refused, naming the file and the element: not well-formed XML, a link or joint name used twice,
a joint whose parent or child link does not exist, a link that is the child of two joints or a
cycle of joints (a kinematic loop), two root links, a planar joint, a floating joint below a
link that moves, a malformed number, an <inertial> without its <mass> or <inertia> (urdfdom
refuses them too). A mimic joint (``<mimic joint multiplier offset>``: q = multiplier q_joint +
offset) is a coupling of the model (:class:`~redysim.model.tree.Coupling`; a mimic of a mimic is
composed onto the first leader), as Pinocchio's ``mimic=True`` reads it: the default,
``mimic="couple"``; ``mimic="independent"`` lets it move on its own (announced; what
Pinocchio's and MuJoCo's URDF readers do by default), ``mimic="refuse"`` refuses it. A mimic on
a fixed joint moves nothing and is announced.

**MJCF** is compiled by MuJoCo first (``mujoco.MjSpec``; the ``models`` extra installs it),
because a file's meaning is its compiler's: inertias from geometry, default classes, angles in
degrees, ``ref`` and ``springref``. The tree is read from the compiled model: hinge, slide and
free joints; a joint's anchor (``pos``) and reference (``ref``) as MuJoCo moves the body:
pose = P_body prod_i [T(a_i) Rot(u_i, q_i - ref_i) T(-a_i)] (a slide: T(u_i (q_i - ref_i))),
so that q is MuJoCo's qpos and :meth:`Model.initial` its qpos0; ``<flag gravity="disable"/>``.
A body with several joints, or a joint away from its body's origin, becomes a chain: one
massless body named ``f"{body}_{joint}"`` per joint but the last, joint 1 placed at
P_body T(a_1) Rot(u_1, -ref_1), joint i > 1 at T(a_i - a_(i-1)) Rot(u_i, -ref_i) (a slide:
T(-ref_i u_i), its anchor the previous one's), and the body's own frame at its last joint's
anchor a_n: its centre of mass is ``ipos - a_n`` there, its children and frames are shifted by
-a_n. A joint equality of degree 1 between two hinge or slide joints is a coupling of the model
(:class:`~redysim.model.tree.Coupling`, held exactly: MuJoCo's softness announced). Refused: a
ball joint, a free joint below the root, any other active equality constraint (a loop closure;
closed loops are built with :func:`redysim.load_linkage` and :class:`redysim.ClosedLoops`) unless
``equality="drop"`` (which drops every equality, couplings too), a file nested deeper than MuJoCo's
XML reader takes (:data:`MJCF_MAX_DEPTH` elements), and what MuJoCo's compiler refuses (its
message kept, the element named).

**Honoured, announced or refused.** Every attribute of a file that changes the motion is
honoured, refused, or announced: a line of :attr:`Model.notes` names the element, its name and
the value, e.g. ``joint 'knee': damping = 0.5 dropped (no joint damping in the core)``. Announced
(only values that act: a zero damping, or one MuJoCo's flags disable, is no news): joint
damping, armature, stiffness (with springref), frictionloss, limits (MJCF ``range``, URDF
``<limit lower upper>``), URDF ``<dynamics>``, body ``gravcomp``, fluid forces (``density``,
``viscosity``), tendons, actuators with a force at ctrl 0 (a position or velocity servo),
contact geometry (MJCF geoms that can touch one another, URDF ``<collision>``), flex and
plugins. ``strict=True`` refuses each of these instead (ModelFileError naming the element and
attribute), except what the caller chose to drop by name (``mimic="independent"``,
``equality="drop"``). Things that do not act on the motion are one summary line: visual
geometry, materials, sites, cameras, lights, sensors, keyframes, transmissions, Gazebo tags,
a URDF joint's effort and velocity bounds (tau is the caller's), actuators without a force at
ctrl 0 (a motor: give its force as tau).

``floating=True``: a URDF's root link (the link fixed to a root link named ``world``), or the
one MJCF root body without joints, gets a free joint, its pose in the file the initial q; a
file whose root already floats is taken as it is; an MJCF root body that already moves on other
joints, or several jointless roots, are refused by name.
"""

from __future__ import annotations

import math
import os
import re
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from redysim.errors import CaseError, ModelFileError
from redysim.model.parts import KIND_CODES, check_inertia, check_positive
from redysim.model.tree import (
    FIXED,
    FREE,
    Body,
    Coupling,
    Model,
    TreeJoint,
    drop_world_fixed,
    joint_transform,
    quaternion_matrix,
)

__all__ = ["ModelFileError", "load_urdf", "load_mjcf", "MIMIC", "EQUALITY",
           "MJCF_MAX_DEPTH", "URDF_GRAVITY"]

URDF_GRAVITY = (0.0, 0.0, -9.81)  # URDF has no gravity; robots are described z up
MIMIC = ("couple", "independent", "refuse")
EQUALITY = ("refuse", "drop")
# MuJoCo's XML reader (tinyxml2) refuses a document nested deeper than this many elements
# (measured with MuJoCo 4.0: <mujoco><worldbody>, 496 nested <body>, a <joint> in the last)
MJCF_MAX_DEPTH = 499
LISTED = 6  # names (and values) a note lists before "and N more"


def _mujoco(path):
    try:
        import mujoco
    except ImportError as exc:
        raise ModelFileError(str(path), "<file>", None, "reading MJCF needs MuJoCo's compiler: "
                             "pip install 'redysim[models]' (" + str(exc) + ")") from None
    return mujoco


def _check_flags(src: str, **flags) -> None:
    for key, value in flags.items():
        if not isinstance(value, bool | np.bool_):
            raise ModelFileError(src, key, value, "must be True or False")


def _check_choice(src: str, key: str, value, choices: Sequence[str]) -> None:
    if not isinstance(value, str) or value not in choices:
        raise ModelFileError(src, key, value, f"must be one of {', '.join(map(repr, choices))}")


# --------------------------------------------------------------------------- announcements
def _fmt(value) -> str:
    """A value in a note: numbers to 6 significant digits, lists of them, strings as they are."""
    if isinstance(value, str):
        return value
    if isinstance(value, bool | np.bool_):
        return "true" if value else "false"
    if isinstance(value, int | np.integer):
        return str(int(value))
    if isinstance(value, float | np.floating):
        return f"{float(value):.6g}"
    return "[" + ", ".join(_fmt(v) for v in value) + "]"


def _plural(word: str) -> str:
    return word[:-1] + "ies" if word.endswith("y") else word + "s"


@dataclass(frozen=True)
class _Dropped:
    """One attribute the core does not model, on the elements that give it a value that acts.
    ``motion``: it changes the motion (``strict=True`` refuses it)."""

    element: str  # "joint", "body", "link", "tendon", "actuator", "<option>", ...
    items: tuple  # ((name, value or None), ...)
    attribute: str
    why: str
    motion: bool = True

    def text(self) -> str:
        def one(name, value):
            return (repr(name) if name is not None else "") + \
                ("" if value is None else f" = {_fmt(value)}")

        if len(self.items) == 1:
            name, value = self.items[0]
            head = self.element if name is None else f"{self.element} {name!r}"
            val = "" if value is None else f" = {_fmt(value)}"
            return f"{head}: {self.attribute}{val} dropped ({self.why})"
        listed = ", ".join(one(*item) for item in self.items[:LISTED])
        more = f" and {len(self.items) - LISTED} more" if len(self.items) > LISTED else ""
        return (f"{self.element} {self.attribute} dropped ({self.why}): {listed}{more} "
                f"({len(self.items)} {_plural(self.element)})")


class _Report:
    """What a file holds that the tree does not: announced in Model.notes, or refused with
    ``strict``."""

    def __init__(self, src: str):
        self.src = src
        self.dropped: list[_Dropped] = []
        self.unread: dict[str, int] = {}  # what does not act on the motion -> count

    def drop(self, element, items, attribute, why, motion=True) -> None:
        items = tuple(items)
        if items:
            self.dropped.append(_Dropped(element, items, attribute, why, motion))

    def unread_count(self, what: str, n: int) -> None:
        if n:
            self.unread[what] = self.unread.get(what, 0) + int(n)

    def notes(self, strict: bool) -> tuple[str, ...]:
        """The notes; with ``strict``, a ModelFileError for the first attribute that changes
        the motion (naming how many more there are)."""
        acting = [d for d in self.dropped if d.motion]
        if strict and acting:
            d = acting[0]
            name, value = d.items[0]
            field = (d.element if name is None else f"{d.element} {name!r}") + f".{d.attribute}"
            others = [f"{x.element} {x.attribute}" for x in acting[1:]]
            more = f"{len(d.items) - 1} more {_plural(d.element)}" if len(d.items) > 1 else ""
            also = "; ".join(x for x in (more, ", ".join(others[:LISTED])) if x)
            raise ModelFileError(self.src, field, value, f"{d.why}; strict=True refuses what "
                                 "would change the motion and the core does not model (with "
                                 "strict=False it is dropped and announced in Model.notes)"
                                 + (f"; also: {also}" if also else ""))
        notes = [d.text() for d in self.dropped]
        if self.unread:
            notes.append("not read (no effect on the motion): " + ", ".join(
                f"{n} {what}" for what, n in self.unread.items()))
        return tuple(notes)


# --------------------------------------------------------------------------- URDF
def _numbers(src: str, field: str, text: str | None, n: int, default: Sequence[float]
             ) -> np.ndarray:
    """``n`` finite numbers from a URDF attribute (``default`` when it is absent)."""
    if text is None:
        return np.array(default, dtype=float)
    try:
        values = [float(x) for x in text.split()]
    except ValueError:
        values = []
    if len(values) != n or not all(math.isfinite(x) for x in values):
        raise ModelFileError(src, field, text, f"must be {n} finite number{'s' if n > 1 else ''}")
    return np.array(values)


def _xyz(a) -> tuple[float, float, float]:
    """A 3-vector as a tuple of floats."""
    x, y, z = map(float, a)
    return x, y, z


def _end_link(joint: ET.Element, end: str) -> str:
    """The link a joint's <parent> or <child> (``end``) names, once :func:`_urdf_graph` has
    refused a joint without one."""
    el = joint.find(end)
    link = None if el is None else el.get("link")
    assert link is not None, "_urdf_graph checks every joint's links"
    return link


def _rpy_matrix(rpy) -> np.ndarray:
    """URDF's roll-pitch-yaw: Rz(yaw) Ry(pitch) Rx(roll) (fixed axes x, y, z)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = math.cos(r), math.sin(r), math.cos(p), math.sin(p), \
        math.cos(y), math.sin(y)
    return np.array([[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
                     [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
                     [-sp, cp * sr, cp * cr]])


def _origin(src: str, where: str, element) -> tuple[np.ndarray, np.ndarray]:
    """(R, p) of an element's ``<origin xyz rpy>`` (identity when absent)."""
    origin = element.find("origin")
    if origin is None:
        return np.eye(3), np.zeros(3)
    xyz = _numbers(src, f"{where}/origin.xyz", origin.get("xyz"), 3, (0, 0, 0))
    rpy = _numbers(src, f"{where}/origin.rpy", origin.get("rpy"), 3, (0, 0, 0))
    return _rpy_matrix(rpy), xyz


def _as_file_error(check, src, field, value, **kwargs):
    """A check of redysim.model.parts (which raises CaseError) as a ModelFileError."""
    try:
        return check(src, field, value, **kwargs)
    except CaseError as exc:
        raise ModelFileError(exc.source, exc.field, exc.value, exc.problem) from None


def _link_body(src: str, link) -> Body:
    """The Body of a URDF link: its <inertial> (mass 0 keeps its rotational inertia)."""
    name = link.get("name")
    where = f"link {name!r}/inertial"
    inertial = link.find("inertial")
    if inertial is None:
        return Body(name, 0.0, physical=False)
    R, c = _origin(src, where, inertial)
    mass_el, inertia_el = inertial.find("mass"), inertial.find("inertia")
    if mass_el is None or mass_el.get("value") is None:
        raise ModelFileError(src, f"{where}/mass.value", None, "missing: an <inertial> gives "
                             "<mass value=...> (urdfdom and Pinocchio refuse it too)")
    m = _numbers(src, f"{where}/mass.value", mass_el.get("value"), 1, (0,))[0]
    _as_file_error(check_positive, src, f"{where}/mass.value", float(m), allow_zero=True)
    keys = ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")
    missing = [k for k in keys if inertia_el is None or inertia_el.get(k) is None]
    if missing:
        raise ModelFileError(src, f"{where}/inertia", None, f"missing {', '.join(missing)}: an "
                             "<inertial> gives <inertia ixx ixy ixz iyy iyz izz> (urdfdom and "
                             "Pinocchio refuse it too)")
    xx, xy, xz, yy, yz, zz = (_numbers(src, f"{where}/inertia.{k}", inertia_el.get(k), 1,
                                       (0,))[0] for k in keys)
    I_in = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    _as_file_error(check_inertia, src, f"{where}/inertia", I_in, physical=False)
    I_c = R @ I_in @ R.T
    return Body(name, float(m), _xyz(c), tuple(map(tuple, 0.5 * (I_c + I_c.T))),
                physical=False)


URDF_TYPES = {"revolute": "R", "continuous": "R", "prismatic": "P", "fixed": FIXED,
              "floating": FREE}


def _urdf_graph(src: str, root):
    """Links (name -> element, file order), the joint of each child link, the joints of each
    parent link (file order) and the root link, refusing what is not one tree."""
    links: dict[str, ET.Element] = {}
    for i, link in enumerate(root.findall("link")):
        name = link.get("name")
        if not name:
            raise ModelFileError(src, f"link #{i + 1}", None, "has no name")
        if name in links:
            raise ModelFileError(src, f"link {name!r}", None, "is defined twice: link names "
                                 "must be unique")
        links[name] = link
    if not links:
        raise ModelFileError(src, "<robot>", None, "has no <link>")
    parent_joint: dict[str, ET.Element] = {}
    children: dict[str, list[ET.Element]] = {}
    names: set[str] = set()
    for i, joint in enumerate(root.findall("joint")):
        name = joint.get("name")
        if not name:
            raise ModelFileError(src, f"joint #{i + 1}", None, "has no name")
        where = f"joint {name!r}"
        if name in names:
            raise ModelFileError(src, where, None, "is defined twice: joint names must be unique")
        names.add(name)
        jtype = joint.get("type")
        if jtype not in URDF_TYPES:
            raise ModelFileError(src, f"{where}.type", jtype, "unsupported joint type; "
                                 "supported: revolute, continuous, prismatic, fixed, floating"
                                 + (" (a planar joint has no counterpart in the core)"
                                    if jtype == "planar" else ""))
        ends: dict[str, str] = {}
        for end in ("parent", "child"):
            el = joint.find(end)
            end_link = None if el is None else el.get("link")
            if end_link is None:
                raise ModelFileError(src, f"{where}/{end}.link", None, f"missing: a joint "
                                     f"names its {end} link")
            if end_link not in links:
                raise ModelFileError(src, f"{where}/{end}.link", end_link, "no such link")
            ends[end] = end_link
        child = ends["child"]
        if child in parent_joint:
            raise ModelFileError(src, f"{where}/child.link", child, f"is already the child of "
                                 f"joint {parent_joint[child].get('name')!r}: a kinematic "
                                 "loop, which a tree cannot hold")
        parent_joint[child] = joint
        children.setdefault(ends["parent"], []).append(joint)
    roots = [n for n in links if n not in parent_joint]
    if len(roots) > 1:
        shown = ", ".join(map(repr, roots[:LISTED])) + (" ..." if len(roots) > LISTED else "")
        raise ModelFileError(src, f"link {roots[0]!r}", None, f"and link {roots[1]!r} are both "
                             f"root links (no joint has them as child; roots: {shown}): a URDF "
                             "is one tree (urdfdom and Pinocchio refuse it too); join them by "
                             "a joint")
    reached = _reach(roots, children)
    if len(reached) < len(links):  # every other link has a parent: they close a cycle
        link = next(n for n in links if n not in reached)
        cycle, seen = [], set()
        while link not in seen:
            seen.add(link)
            joint = parent_joint[link]
            cycle.append(joint.get("name"))
            link = _end_link(joint, "parent")
        loop = cycle[cycle.index(parent_joint[link].get("name")):][::-1]  # downwards
        order = {j.get("name"): i for i, j in enumerate(root.findall("joint"))}
        first = min(loop, key=order.__getitem__)
        loop = loop[loop.index(first):] + loop[:loop.index(first)]  # from the first in the file
        raise ModelFileError(src, f"joint {loop[0]!r}", None, "joints " + " -> ".join(
            map(repr, loop)) + f" form a cycle (link {link!r} is its own ancestor): a "
            "kinematic loop, which a tree cannot hold")
    return links, children, roots[0]


def _reach(roots, children) -> set:
    """The links reached from ``roots`` through the joints (an iterative walk)."""
    reached, stack = set(roots), list(roots)
    while stack:
        for joint in children.get(stack.pop(), ()):
            child = joint.find("child").get("link")
            if child not in reached:
                reached.add(child)
                stack.append(child)
    return reached


def _urdf_unread(report: _Report, root, mimic: str) -> None:
    """What the URDF holds that the tree does not: announced (dynamics, limits, collision
    geometry) or counted as not read."""
    damping: list[tuple[str, float]] = []
    friction: list[tuple[str, float]] = []
    limits, collision, mimics = [], [], []
    bounds = 0
    for joint in root.findall("joint"):
        name, jtype = joint.get("name"), joint.get("type")
        dyn = joint.find("dynamics")
        if dyn is not None:
            for key, out in (("damping", damping), ("friction", friction)):
                x = _numbers(report.src, f"joint {name!r}/dynamics.{key}", dyn.get(key), 1,
                             (0,))[0]
                if x:
                    out.append((name, float(x)))
        lim = joint.find("limit")
        if lim is not None:
            if jtype in ("revolute", "prismatic") and (lim.get("lower") or lim.get("upper")):
                lo, hi = (_numbers(report.src, f"joint {name!r}/limit.{k}", lim.get(k), 1,
                                   (0,))[0] for k in ("lower", "upper"))
                limits.append((name, [float(lo), float(hi)]))
            bounds += any(lim.get(k) is not None for k in ("effort", "velocity"))
        mim = joint.find("mimic")
        if mim is not None and (mimic == "independent" or jtype == "fixed"):
            mimics.append((name, f"{mim.get('joint')!r} * {mim.get('multiplier', '1')} + "
                                 f"{mim.get('offset', '0')}"))
    for link in root.findall("link"):
        n = len(link.findall("collision"))
        if n:
            collision.append((link.get("name"), None))
        report.unread_count("<visual>", len(link.findall("visual")))
    report.drop("joint", mimics, "mimic", "it moves independently: mimic='independent'"
                if mimic == "independent" else "a fixed joint moves nothing to couple",
                motion=False)
    report.drop("joint", damping, "<dynamics> damping", "no joint damping in the core")
    report.drop("joint", friction, "<dynamics> friction", "no joint friction in the core")
    report.drop("joint", limits, "<limit> lower, upper", "no joint limits in the core: the "
                "joint moves through them")
    report.drop("link", collision, "<collision>", "no contacts in the core")
    report.unread_count("joint effort/velocity bounds (tau is the caller's)", bounds)
    for tag in ("safety_controller", "calibration"):
        report.unread_count(f"<{tag}>", sum(len(j.findall(tag)) for j in root.findall("joint")))
    for element in root:
        if element.tag not in ("link", "joint"):
            report.unread_count(f"<{element.tag}>", 1)


def _urdf_mimics(src: str, root, mimic: str) -> list[Coupling]:
    """The couplings of a URDF's mimic joints (``mimic="couple"``; none for "independent"),
    each composed onto its first leader (a mimic of a mimic: multipliers multiplied, offsets
    carried); ModelFileError naming the element for a mimic ``mimic="refuse"`` refuses, a
    leader that is no joint or not one R or P axis, a mimic cycle or a bad number. A mimic on a
    fixed joint moves nothing: left out (announced by :func:`_urdf_unread`)."""
    types = {j.get("name"): j.get("type") for j in root.findall("joint")}
    rule: dict[str, tuple[str, float, float]] = {}
    for joint_el in root.findall("joint"):
        mimic_el = joint_el.find("mimic")
        if mimic_el is None:
            continue
        name = joint_el.get("name")
        where = f"joint {name!r}/mimic"
        if mimic == "refuse":
            raise ModelFileError(src, f"{where}.joint", mimic_el.get("joint"), "a mimic joint "
                                 "couples two joints; load with mimic='couple' (the default) to "
                                 "keep the coupling, mimic='independent' to let it move on its "
                                 "own, or remove the <mimic>")
        if mimic == "independent" or types.get(name) == "fixed":
            continue
        leader = mimic_el.get("joint")
        if leader not in types:
            raise ModelFileError(src, f"{where}.joint", leader, "no joint of that name")
        for who, jt in ((name, types[name]), (leader, types[leader])):
            if jt not in ("revolute", "continuous", "prismatic"):
                raise ModelFileError(src, f"{where}.joint" if who == leader else
                                     f"joint {name!r}.type", jt, f"joint {who!r} is {jt}: a "
                                     "mimic couples one revolute, continuous or prismatic "
                                     "joint to another")
        m = float(_numbers(src, f"{where}.multiplier", mimic_el.get("multiplier"), 1, (1,))[0])
        off = float(_numbers(src, f"{where}.offset", mimic_el.get("offset"), 1, (0,))[0])
        rule[name] = (leader, m, off)
    out = []
    for name, (leader, m, off) in rule.items():
        seen = {name}
        while leader in rule:  # compose onto the first leader: q = m (m2 q2 + o2) + o
            if leader in seen:
                raise ModelFileError(src, f"joint {name!r}/mimic.joint", leader, "the mimic "
                                     f"joints {sorted(seen)} follow one another in a cycle")
            seen.add(leader)
            leader, m2, o2 = rule[leader]
            m, off = m * m2, m * o2 + off
        out.append(Coupling(name, leader, m, off))
    return out


def load_urdf(path: str | os.PathLike, *, floating: bool = False, mimic: str = "couple",
              strict: bool = False) -> Model:
    """A URDF's tree, gravity -9.81 along z (module doc).

    ``floating``: the root link gets a free joint (a legged or flying robot; initial q its
    pose at the origin), else it is fixed to the world. ``mimic``: "couple" (the default) a
    mimic joint to its leader (:attr:`Model.couplings`), let it move "independent"ly
    (announced), or "refuse" it. ``strict``: refuse, instead of
    announcing in :attr:`Model.notes`, what would change the motion and the core does not
    model (damping, friction, limits, collision geometry). Raises ModelFileError naming the
    file, the element (``joint 'elbow'``, ``link 'base'``) and the value."""
    path = Path(path)
    src = str(path)
    _check_flags(src, floating=floating, strict=strict)
    _check_choice(src, "mimic", mimic, MIMIC)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ModelFileError(src, "<xml>", None, f"not well-formed XML: {exc}") from None
    if root.tag != "robot":
        raise ModelFileError(src, f"<{root.tag}>", None, "a URDF's root element is <robot>")
    links, children, base = _urdf_graph(src, root)
    couplings = _urdf_mimics(src, root, mimic)
    report = _Report(src)
    _urdf_unread(report, root, mimic)

    # floating: the root link floats; a root link named "world" is the world (as MuJoCo and
    # Gazebo read it): the one link fixed to it floats
    float_joint = None
    if floating and base == "world":
        kids = children.get(base, [])
        types = [k.get("type") for k in kids]
        if types == ["fixed"]:
            float_joint = kids[0]
        elif types != ["floating"]:  # a floating joint from the world already floats
            raise ModelFileError(src, "link 'world'", [k.get("name") for k in kids],
                                 "floating=True floats the link fixed to the world link, and "
                                 "these joints leave it (one fixed joint is needed)")
        floating = False  # the world link itself stays the world

    # the tree, depth first (children in file order), without recursion
    bodies: list[Body] = []
    joints: list[TreeJoint] = []
    parents: list[int] = []
    welded: list[bool] = []  # welded to the world?
    world: list[tuple[np.ndarray, np.ndarray] | None] = []  # its pose in the world if so
    free_poses: dict[int, tuple[np.ndarray, np.ndarray]] = {}
    stack: list[tuple[str, ET.Element | None, int]] = [(base, None, -1)]
    while stack:
        name, joint, parent = stack.pop()
        k = len(bodies)
        bodies.append(_link_body(src, links[name]))
        if joint is None:  # the root link
            floats = floating
            jtype = FREE if floats else FIXED
            joints.append(TreeJoint(f"{name}_{jtype}", jtype))
            parents.append(-1)
            welded.append(not floats)
            root_pose = (np.eye(3), np.zeros(3))
            world.append(root_pose)
            if floats:
                free_poses[k] = root_pose
        else:
            jname = joint.get("name", "")  # (never absent: _urdf_graph checks names, types)
            where = f"joint {jname!r}"
            R, p = _origin(src, where, joint)
            jtype = URDF_TYPES[joint.get("type", "")]
            parent_pose = world[parent] if welded[parent] else None  # known when welded
            pose = None if parent_pose is None else \
                (parent_pose[0] @ R, parent_pose[0] @ p + parent_pose[1])
            if joint is float_joint:
                jtype, jname = FREE, f"{name}_free"
            if jtype == FREE:
                if not welded[parent]:
                    raise ModelFileError(src, f"{where}.type", "floating", "a floating joint "
                                         "must join a link fixed to the world (the base) to the "
                                         f"world; link {_end_link(joint, 'parent')!r} "
                                         "moves" + (" (floating=True gave the root a free "
                                                    "joint)" if floating else ""))
                joints.append(TreeJoint(jname, FREE))
                parents.append(-1)  # its parent is welded to the world
                assert pose is not None  # as its parent is welded
                free_poses[k] = pose
            else:
                axis = None
                if jtype in ("R", "P"):
                    axis_el = joint.find("axis")
                    xyz = None if axis_el is None else axis_el.get("xyz")
                    u = _numbers(src, f"{where}/axis.xyz", xyz, 3, (1, 0, 0))
                    if not np.linalg.norm(u) > 0:
                        raise ModelFileError(src, f"{where}/axis.xyz", xyz,
                                             "must not be the zero vector")
                    axis = _xyz(u)
                joints.append(TreeJoint(jname, jtype, axis, tuple(map(tuple, R)), _xyz(p)))
                parents.append(parent)
            welded.append(jtype == FIXED and welded[parent])
            world.append(pose if welded[-1] else None)
        for child_joint in reversed(children.get(name, ())):
            stack.append((child_joint.find("child").get("link"), child_joint, k))

    model = _finish(bodies, joints, parents, URDF_GRAVITY, root.get("name") or path.stem, src,
                    report.notes(strict))
    if couplings:
        model = model.with_couplings(couplings, source=src)
    if free_poses:
        q = model.neutral()
        kept = [k for k, j in enumerate(joints) if j.type == FREE]
        for k, kk in zip(kept, (model.joint_names.index(joints[k].name) for k in kept),
                         strict=True):
            R, p = free_poses[k]
            qs = model.joint_qoff[kk]
            q[qs:qs + 3], q[qs + 3:qs + 7] = p, _matrix_quaternion(R)
        object.__setattr__(model, "initial_q", q)
    return model


def _matrix_quaternion(R) -> np.ndarray:
    """The unit quaternion (w, x, y, z), w >= 0, of a rotation matrix."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z]) * (1.0 if w >= 0 else -1.0)


# --------------------------------------------------------------------------- MJCF
def _xml_depth(path: Path) -> int:
    """The deepest element nesting of an XML file (iterative: expat's events)."""
    depth = deepest = 0
    for event, _ in ET.iterparse(path, events=("start", "end")):
        depth += 1 if event == "start" else -1
        deepest = max(deepest, depth)
    return deepest


def _mujoco_error(src: str, path: Path, exc: Exception, stage: str, spec=None
                  ) -> ModelFileError:
    """MuJoCo's message, with what it means and the element it names (its kind looked up in
    the ``spec`` when there is one)."""
    text = str(exc).strip()
    if "XML_ELEMENT_DEPTH_EXCEEDED" in text:
        try:
            depth = _xml_depth(path)
        except (ET.ParseError, OSError):
            depth = None
        return ModelFileError(src, "<mujoco>", depth, "elements nested this deep: MuJoCo's XML "
                              f"reader (tinyxml2) takes at most {MJCF_MAX_DEPTH} nested elements "
                              "(about 496 nested bodies below <worldbody>); a longer chain can "
                              "be written as URDF, a flat list that redysim reads at any length")
    named = re.search(r"Element name '([^']*)', id (\d+)(?:, line (\d+))?", text)
    field = "<mujoco>"
    if named:
        name = named.group(1)
        kind = next((k for k in ("body", "joint", "geom", "site", "tendon", "actuator",
                                 "equality", "sensor", "mesh", "flex")
                     if spec is not None and name and getattr(spec, k)(name) is not None),
                    "element")
        field = f"{kind} {name!r}" if name else f"element #{named.group(2)}"
        if named.group(3):
            field += f" (line {named.group(3)})"
    meaning = ""
    if "mass and inertia of moving bodies must be larger than mjMINVAL" in text:
        meaning = (": a body that moves needs mass and inertia in MuJoCo (it refuses a moving "
                   "body of mass 0, even with a rotational inertia, where URDF readers keep it)")
    first = text.splitlines()[0] if text else type(exc).__name__
    return ModelFileError(src, field, None, f"MuJoCo's {stage} refuses the file: {first}"
                          + meaning)


def _add_free_joint(mj, spec, src: str) -> None:
    """floating=True on MJCF: the one root body without joints gets a free joint."""
    roots = [b for b in spec.worldbody.bodies if not b.mocap]
    jointless = [b for b in roots if not list(b.joints)]
    moving = [b for b in roots if list(b.joints) and
              any(j.type != mj.mjtJoint.mjJNT_FREE for j in b.joints)]
    if len(jointless) > 1:
        raise ModelFileError(src, f"body {jointless[0].name!r}", None, f"and body "
                             f"{jointless[1].name!r} are both root bodies without joints: "
                             "floating=True floats one base; give the bodies that should "
                             "float a <freejoint/>")
    if not jointless:
        if moving:
            b = moving[0]
            raise ModelFileError(src, f"body {b.name!r}", [j.name for j in b.joints],
                                 "floating=True gives the root body a free joint, and this one "
                                 "already moves on these joints: load without floating=True, "
                                 "or replace its joints by a <freejoint/>")
        return  # every root already floats
    jointless[0].add_freejoint(name=f"{jointless[0].name or 'root'}_free")


def _compile_mjcf(mj, path: Path, floating: bool):
    src = str(path)
    try:
        spec = mj.MjSpec.from_file(src)
    except Exception as exc:  # MuJoCo's parser reports a bad file with a ValueError
        raise _mujoco_error(src, path, exc, "parser") from None
    if floating:
        _add_free_joint(mj, spec, src)
    try:
        return spec.compile()
    except Exception as exc:  # MuJoCo's compiler reports a bad model with a ValueError
        raise _mujoco_error(src, path, exc, "compiler", spec) from None


def _name(mj, m, obj: str, i: int) -> str:
    """An MJCF element's name, or ``f"{obj}{i}"`` for an unnamed one."""
    code = getattr(mj.mjtObj, f"mjOBJ_{obj.upper()}")
    return mj.mj_id2name(m, code, i) or f"{obj}{i}"


def _rotation_about(u, angle) -> np.ndarray:
    return joint_transform([(KIND_CODES["R"], np.asarray(u, dtype=float))], [angle])[0]


def _mjcf_tree(mj, m, src):
    """Bodies, joints and parents of a compiled MjModel (module doc: a body's joints become a
    chain of massless bodies, its frame at the last joint's anchor, refs folded in)."""
    JNT = mj.mjtJoint
    bodies, joints, parents = [], [], []
    ours = {0: -1}  # MuJoCo's body id -> our index of it (its last body); the world is -1
    shift = {0: np.zeros(3)}  # MuJoCo's body id -> its frame's origin in ours: a_n
    for b in range(1, m.nbody):
        name = _name(mj, m, "body", b)
        pb = int(m.body_parentid[b])
        parent = ours[pb]
        R_b = quaternion_matrix(*(m.body_quat[b] / np.linalg.norm(m.body_quat[b])))
        p_b = np.array(m.body_pos[b], dtype=float) - shift[pb]
        jids = range(int(m.body_jntadr[b]), int(m.body_jntadr[b]) + int(m.body_jntnum[b]))
        specs = []  # (type, axis, name, R, p) of each joint, placed in the previous frame
        anchor = np.zeros(3)
        for j in jids:
            jname = _name(mj, m, "joint", j)
            jtype = int(m.jnt_type[j])
            if jtype == JNT.mjJNT_FREE:
                if pb != 0 or len(jids) > 1:
                    raise ModelFileError(src, f"joint {jname!r}.type", "free", "a free joint "
                                         "must be the only joint of a root body (a child of "
                                         "<worldbody>)")
                specs.append((FREE, None, jname, None, None))
                continue
            if jtype not in (JNT.mjJNT_HINGE, JNT.mjJNT_SLIDE):
                raise ModelFileError(src, f"joint {jname!r}.type", "ball", "unsupported joint "
                                     "type (hinge, slide and free are read): a ball joint's "
                                     "quaternion has no counterpart in the core; write it as "
                                     "three hinges")
            u = np.array(m.jnt_axis[j], dtype=float)
            ref = float(m.qpos0[m.jnt_qposadr[j]])
            if jtype == JNT.mjJNT_HINGE:  # T(a_i - a_(i-1)) Rot(u, -ref)
                a = np.array(m.jnt_pos[j], dtype=float)
                specs.append(("R", tuple(u), jname, _rotation_about(u, -ref), a - anchor))
                anchor = a
            else:  # T(-ref u); a slide's motion does not depend on its anchor
                specs.append(("P", tuple(u), jname, np.eye(3), -ref * u))
        if not specs:
            specs = [(FIXED, None, f"{name}_fixed", np.eye(3), np.zeros(3))]
        for i, (jtype, axis, jname, R, p) in enumerate(specs):
            last = i == len(specs) - 1
            if jtype == FREE:
                joints.append(TreeJoint(jname, FREE))  # its pose is q (qpos0: the file's)
            else:
                if i == 0:
                    R, p = R_b @ R, p_b + R_b @ p
                joints.append(TreeJoint(jname, jtype, axis, tuple(map(tuple, R)),
                                        tuple(map(float, p))))
            parents.append(parent)
            if not last:  # massless, one joint each
                bodies.append(Body(f"{name}_{jname}", 0.0, physical=False))
                parent = len(bodies) - 1
        R_i = quaternion_matrix(*(m.body_iquat[b] / np.linalg.norm(m.body_iquat[b])))
        inertia = R_i @ np.diag(m.body_inertia[b]) @ R_i.T
        bodies.append(Body(name, float(m.body_mass[b]),
                           tuple(map(float, np.asarray(m.body_ipos[b]) - anchor)),
                           tuple(map(tuple, inertia)), physical=False))
        ours[b] = len(bodies) - 1
        shift[b] = anchor
    return bodies, joints, parents


def _mjcf_unread(mj, m, report: _Report) -> None:
    """Announce what the compiled model holds that the tree does not (only values that act,
    MuJoCo's disable flags considered)."""
    DS = mj.mjtDisableBit
    off = {bit: bool(m.opt.disableflags & getattr(DS, f"mjDSBL_{bit}"))
           for bit in ("CONSTRAINT", "EQUALITY", "FRICTIONLOSS", "LIMIT", "CONTACT", "SPRING",
                       "DAMPER", "GRAVITY", "ACTUATION", "FILTERPARENT")}
    constraint = not off["CONSTRAINT"]
    passive = not (off["SPRING"] and off["DAMPER"])  # both off: no passive force at all
    JNT = mj.mjtJoint
    ndof = {int(JNT.mjJNT_FREE): 6, int(JNT.mjJNT_BALL): 3, int(JNT.mjJNT_SLIDE): 1,
            int(JNT.mjJNT_HINGE): 1}

    def value(main, poly=()):
        """A number, or the list of a joint's DOF values followed by its polynomial terms (as
        the file writes them: damping="c1 c2 c3")."""
        vals = [float(x) for x in np.atleast_1d(main)]
        extra = [float(x) for x in np.trim_zeros(np.ravel(np.asarray(poly, dtype=float)), "b")]
        return vals[0] if len(vals) == 1 and not extra else vals + extra

    damping, armature, friction, stiffness, yields, limits, frc = [], [], [], [], [], [], []
    for j in range(m.njnt):
        name = _name(mj, m, "joint", j)
        d0 = int(m.jnt_dofadr[j])
        dofs = slice(d0, d0 + ndof[int(m.jnt_type[j])])
        if not off["DAMPER"] and (np.any(m.dof_damping[dofs]) or np.any(m.dof_dampingpoly[dofs])):
            damping.append((name, value(m.dof_damping[dofs], m.dof_dampingpoly[dofs])))
        if np.any(m.dof_armature[dofs]):
            armature.append((name, value(m.dof_armature[dofs])))
        if constraint and not off["FRICTIONLOSS"] and np.any(m.dof_frictionloss[dofs]):
            friction.append((name, value(m.dof_frictionloss[dofs])))
        if not off["SPRING"] and (m.jnt_stiffness[j] or np.any(m.jnt_stiffnesspoly[j])):
            k = value(m.jnt_stiffness[j], m.jnt_stiffnesspoly[j])
            if int(m.jnt_type[j]) in (JNT.mjJNT_HINGE, JNT.mjJNT_SLIDE):
                k = f"{_fmt(k)} (springref {_fmt(m.qpos_spring[m.jnt_qposadr[j]])})"
            stiffness.append((name, k))
            if m.jnt_springyield[j]:
                yields.append((name, float(m.jnt_springyield[j])))
        if constraint and not off["LIMIT"] and m.jnt_limited[j]:
            limits.append((name, [float(x) for x in m.jnt_range[j]]))
        if m.nu and m.jnt_actfrclimited[j]:
            frc.append((name, [float(x) for x in m.jnt_actfrcrange[j]]))
    report.drop("joint", damping, "damping", "no joint damping in the core")
    report.drop("joint", armature, "armature", "no rotor inertia in the core")
    report.drop("joint", friction, "frictionloss", "no joint friction in the core")
    report.drop("joint", stiffness, "stiffness", "no joint springs in the core")
    report.drop("joint", yields, "springyield", "no joint springs in the core")
    report.drop("joint", limits, "range", "no joint limits in the core: the joint moves "
                "through them")
    report.drop("joint", frc, "actuatorfrcrange", "bounds actuator forces; the core takes tau "
                "as given", motion=False)

    gravity = not off["GRAVITY"] and np.any(m.opt.gravity)
    report.drop("body", [(_name(mj, m, "body", int(b)), float(m.body_gravcomp[b]))
                         for b in np.flatnonzero(m.body_gravcomp) if gravity and passive],
                "gravcomp", "no gravity compensation in the core: the body falls")
    report.drop("body", [(_name(mj, m, "body", int(b)), None)
                         for b in np.flatnonzero(m.body_mocapid >= 0)], "mocap",
                "held at its file pose: the core has no mocap bodies", motion=False)
    for key in ("density", "viscosity"):
        if passive and getattr(m.opt, key):
            report.drop("<option>", [(None, float(getattr(m.opt, key)))], key,
                        "no fluid forces in the core")

    # tendons
    tendon: dict[str, list[tuple[str, object]]] = {
        "stiffness": [], "damping": [], "frictionloss": [], "range": [], "armature": []}
    for t in range(m.ntendon):
        name = _name(mj, m, "tendon", t)
        if not off["SPRING"] and (m.tendon_stiffness[t] or np.any(m.tendon_stiffnesspoly[t])):
            tendon["stiffness"].append((name, value(m.tendon_stiffness[t],
                                                    m.tendon_stiffnesspoly[t])))
        if not off["DAMPER"] and (m.tendon_damping[t] or np.any(m.tendon_dampingpoly[t])):
            tendon["damping"].append((name, value(m.tendon_damping[t], m.tendon_dampingpoly[t])))
        if constraint and not off["FRICTIONLOSS"] and m.tendon_frictionloss[t]:
            tendon["frictionloss"].append((name, float(m.tendon_frictionloss[t])))
        if constraint and not off["LIMIT"] and m.tendon_limited[t]:
            tendon["range"].append((name, [float(x) for x in m.tendon_range[t]]))
        if m.tendon_armature[t]:
            tendon["armature"].append((name, float(m.tendon_armature[t])))
    for key, items in tendon.items():
        report.drop("tendon", items, key, "no tendons in the core")

    # actuators: a force at ctrl 0 acts (a position servo is a spring); a motor is an input
    acting: list[tuple[str, list[float] | str]] = []
    inputs: list[tuple[str, None]] = []
    if not off["ACTUATION"]:
        for a in range(m.nu):
            if m.opt.disableactuator & (1 << int(m.actuator_group[a])):
                continue
            name = _name(mj, m, "actuator", a)
            if int(m.actuator_biastype[a]) and np.any(m.actuator_biasprm[a]):
                acting.append((name, [float(x) for x in
                                      np.trim_zeros(np.asarray(m.actuator_biasprm[a]), "b")]))
            elif np.any(m.actuator_damping[a]) or np.any(m.actuator_dampingpoly[a]) \
                    or np.any(m.actuator_armature[a]):
                damp = value(m.actuator_damping[a], m.actuator_dampingpoly[a])
                acting.append((name, f"damping {_fmt(damp)}, armature "
                                     f"{_fmt(value(m.actuator_armature[a]))}"))
            else:
                inputs.append((name, None))
    report.drop("actuator", acting, "biasprm", "a force even at ctrl 0 (a position or velocity "
                "servo is a spring or a damper); the core takes tau as given")
    report.drop("actuator", inputs, "force", "an input: give it as tau", motion=False)

    if constraint and not off["CONTACT"]:
        _mjcf_contacts(mj, m, report, filterparent=not off["FILTERPARENT"])
    report.drop("flex", [(_name(mj, m, "flex", i), None) for i in range(m.nflex)],
                "elasticity and contacts", "deformable bodies: the core's bodies are rigid")
    report.drop("plugin", [(_name(mj, m, "plugin", i), None) for i in range(m.nplugin)],
                "forces", "a plugin's forces are not modelled in the core")
    for what, n in (("sites", m.nsite), ("cameras", m.ncam), ("lights", m.nlight),
                    ("sensors", m.nsensor), ("materials", m.nmat), ("textures", m.ntex),
                    ("skins", m.nskin), ("keyframes (the initial q is qpos0)", m.nkey)):
        report.unread_count(what, n)


def _mjcf_contacts(mj, m, report: _Report, *, filterparent: bool) -> None:
    """Announce the geoms that can touch another body's (MuJoCo's contype/conaffinity rule,
    parent-child filter and <exclude>d pairs), and explicit <pair>s."""
    ct = np.asarray(m.geom_contype, dtype=np.int64)
    ca = np.asarray(m.geom_conaffinity, dtype=np.int64)
    weld = np.asarray(m.body_weldid, dtype=np.int64)
    gw = weld[np.asarray(m.geom_bodyid, dtype=np.int64)]
    colliding = (ct | ca) != 0
    report.unread_count("visual-only geoms", int((~colliding).sum()))
    CT: dict[int, int] = {}
    CA: dict[int, int] = {}
    for w, t, a in zip(gw[colliding].tolist(), ct[colliding].tolist(), ca[colliding].tolist(),
                       strict=True):
        CT[w] = CT.get(w, 0) | t
        CA[w] = CA.get(w, 0) | a
    cls: dict[tuple[int, int], list[int]] = {}
    for w in CT:
        cls.setdefault((CT[w], CA[w]), []).append(w)
    filtered = set()
    if filterparent:
        for w in CT:
            pw = int(weld[m.body_parentid[w]])
            if w and pw and pw != w:
                filtered.add((min(w, pw), max(w, pw)))
    for sig in np.asarray(m.exclude_signature, dtype=np.int64).tolist():
        b1, b2 = int(weld[sig >> 16]), int(weld[sig & 0xFFFF])
        filtered.add((min(b1, b2), max(b1, b2)))
    where = {w: sig for sig, ws in cls.items() for w in ws}

    def compatible(s1, s2):
        return bool(s1[0] & s2[1] or s2[0] & s1[1])

    # a weld body touches something when it has a compatible partner left after the filters:
    # count its partners by class, then take away its filtered pairs
    partners = {s1: sum(len(cls[s2]) - (s1 == s2) for s2 in cls if compatible(s1, s2))
                for s1 in cls}
    left = {w: partners[where[w]] for w in where}
    for a, b in filtered:
        if a != b and a in where and b in where and compatible(where[a], where[b]):
            left[a] -= 1
            left[b] -= 1
    touching = {w for w, n in left.items() if n > 0 and w != 0}
    report.drop("body", [(_name(mj, m, "body", w), None) for w in sorted(touching)],
                "contact geometry", "no contacts in the core")
    report.drop("contact", [(_name(mj, m, "pair", i), None) for i in range(m.npair)], "<pair>",
                "no contacts in the core")


def _mjcf_coupling(mj, m, e: int) -> Coupling | None:
    """The coupling an equality holds (a joint equality of two hinge or slide joints whose
    polynomial is of degree 1 at most: MuJoCo's y - y0 = a0 + a1 (x - x0), x0 and y0 the joints'
    qpos0, i.e. q_y = a1 q_x + a0 + y0 - a1 x0), else None."""
    if int(m.eq_type[e]) != int(mj.mjtEq.mjEQ_JOINT) or int(m.eq_obj2id[e]) < 0:
        return None
    j1, j2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
    scalar = (int(mj.mjtJoint.mjJNT_HINGE), int(mj.mjtJoint.mjJNT_SLIDE))
    a = np.asarray(m.eq_data[e][:5], dtype=float)
    if int(m.jnt_type[j1]) not in scalar or int(m.jnt_type[j2]) not in scalar or np.any(a[2:]):
        return None
    y0, x0 = float(m.qpos0[m.jnt_qposadr[j1]]), float(m.qpos0[m.jnt_qposadr[j2]])
    return Coupling(_name(mj, m, "joint", j1), _name(mj, m, "joint", j2), float(a[1]),
                    float(a[0] + y0 - a[1] * x0))


def _mjcf_equality(mj, m, src: str, report: _Report, equality: str) -> list[Coupling]:
    """The couplings of the active joint equalities of degree 1 between two hinge or slide
    joints (held exactly: MuJoCo's soft constraint without its softness, announced); refuse any
    other active equality constraint (or drop every one, announced, with equality='drop');
    announce an inactive one."""
    off = m.opt.disableflags & (mj.mjtDisableBit.mjDSBL_EQUALITY |
                                mj.mjtDisableBit.mjDSBL_CONSTRAINT)
    active: list[tuple[str, str, str]] = []
    inactive: list[tuple[str, str, str]] = []
    couplings: list[tuple[str, Coupling]] = []
    for e in range(m.neq):
        kind = mj.mjtEq(int(m.eq_type[e])).name.removeprefix("mjEQ_").lower()
        name = _name(mj, m, "equality", e)
        code = int(m.eq_objtype[e])
        if code == mj.mjtObj.mjOBJ_UNKNOWN:  # a joint, tendon or flex equality names its kind
            code = int(getattr(mj.mjtObj, f"mjOBJ_{kind.upper()}", code))
        obj = mj.mjtObj(code).name.removeprefix("mjOBJ_").lower()
        between = [mj.mj_id2name(m, code, int(i)) or f"{obj}{int(i)}"
                   for i in (m.eq_obj1id[e], m.eq_obj2id[e]) if int(i) >= 0]
        what = f"{kind} of " + " and ".join(f"{obj} {n!r}" for n in between)
        coupling = _mjcf_coupling(mj, m, e)
        if m.eq_active0[e] and not off and coupling is not None and equality == "refuse":
            couplings.append((name, coupling))
            continue
        (active if m.eq_active0[e] and not off else inactive).append((name, what, kind))
    if active and equality == "refuse":
        name, what, kind = active[0]
        raise ModelFileError(src, f"equality {name!r}", what, "a loop closure or a coupling, "
                             "which a tree of independent joints cannot hold: closed loops are "
                             "built with redysim.load_linkage (a linkage file) or "
                             "redysim.ClosedLoops (docs/design.md, 'Closed loops'); load with "
                             "equality='drop' to drop it (announced in Model.notes)"
                             + (f"; {len(active) - 1} more" if len(active) > 1 else ""))
    report.drop("equality", [(n, w) for n, w, _ in active], "constraint",
                "equality='drop': the tree moves without it", motion=False)
    report.drop("equality", [(n, w) for n, w, _ in inactive], "constraint", "inactive in the "
                "file (active = false, or equality disabled by a flag)", motion=False)
    report.drop("equality", [(n, f"{c.follower!r} = {c.multiplier:g} {c.leader!r} + "
                             f"{c.offset:g}") for n, c in couplings], "solref, solimp",
                "a joint coupling, held exactly (Model.couplings), not softly as MuJoCo does")
    return [c for _, c in couplings]


def load_mjcf(path: str | os.PathLike, *, floating: bool = False, equality: str = "refuse",
              strict: bool = False) -> Model:
    """An MJCF model's tree as MuJoCo compiles it, with its gravity (module doc): q is MuJoCo's
    qpos, :meth:`Model.initial` its qpos0.

    ``floating``: the one root body without joints gets a free joint (its file pose the
    initial q); refused when a root body already moves on other joints or several roots have
    none. ``equality``: "refuse" (the default) an active equality constraint that is no
    coupling (a joint equality of degree 1: kept as one, :attr:`Model.couplings`), or "drop"
    every one (announced). ``strict``: refuse, instead of announcing in :attr:`Model.notes`,
    what would change the motion and the core does not model. Raises ModelFileError naming the
    file, the element (``joint 'knee'``, ``body 'torso'``) and the value."""
    path = Path(path)
    src = str(path)
    _check_flags(src, floating=floating, strict=strict)
    _check_choice(src, "equality", equality, EQUALITY)
    mj = _mujoco(path)
    m = _compile_mjcf(mj, path, floating)
    bodies, joints, parents = _mjcf_tree(mj, m, src)
    report = _Report(src)
    couplings = _mjcf_equality(mj, m, src, report, equality)
    _mjcf_unread(mj, m, report)
    gravity = (0.0, 0.0, 0.0) if m.opt.disableflags & mj.mjtDisableBit.mjDSBL_GRAVITY else \
        tuple(float(g) for g in m.opt.gravity)
    model = _finish(bodies, joints, parents, gravity, path.stem, src, report.notes(strict))
    if couplings:
        model = model.with_couplings(couplings, source=src)
    object.__setattr__(model, "initial_q", np.array(m.qpos0, dtype=float))
    return model


# --------------------------------------------------------------------------- the tree
def _finish(bodies, joints, parents, gravity, name, src, notes) -> Model:
    """Build the Model (bodies fixed to the world dropped), check that every joint has inertia
    to move, record what the importer dropped."""
    bodies, joints, parents, _ = drop_world_fixed(bodies, joints, parents)
    if not bodies:
        raise ModelFileError(src, "<model>", None, "no body moves: every joint is fixed")
    model = Model.build(bodies, joints, parents, gravity=gravity, name=name, source=src)
    _check_inertia_to_move(model, src)
    object.__setattr__(model, "notes", tuple(notes))
    return model


def _same_motion(model: Model, j: int) -> int | None:
    """Another DOF whose motion (the unit twist of its axis, about the world origin, at the
    neutral configuration) is DOF ``j``'s, up to its sign and size: two hinges on one axis
    line, or two slides along one direction. None when there is none."""
    from redysim.algorithms.rbda import kinematics

    kin = kinematics(model, model.neutral(), np.zeros(model.n_v))
    body = np.searchsorted(model.joint_voff, np.arange(model.n_v), side="right") - 1
    S = kin.S.copy()
    S[3:] -= np.cross(S[:3].T, kin.O[body]).T  # each axis's twist about the world origin
    unit = S / np.maximum(np.linalg.norm(S, axis=0), np.finfo(float).tiny)
    for other in range(model.n_v):
        if other != j and min(np.abs(unit[:, j] - unit[:, other]).max(),
                              np.abs(unit[:, j] + unit[:, other]).max()) < 1e-9:
            return other
    return None


def _check_inertia_to_move(model: Model, src: str) -> None:
    """Refuse a model whose GIM is singular at the neutral configuration, naming the joint:
    a massless body at the end of a joint (its subtree has no inertia about the joint's axis)."""
    from redysim.algorithms.rbda import massless_axis

    j = massless_axis(model)
    if j is not None:
        k = int(np.searchsorted(model.joint_voff, j, side="right") - 1)
        twin = _same_motion(model, j)
        if twin is not None:  # (the massless body between them is the importer's, not the file's)
            k2 = int(np.searchsorted(model.joint_voff, twin, side="right") - 1)
            a, b = sorted((model.joint_names[k], model.joint_names[k2]))
            raise ModelFileError(src, f"joint {b!r}", None,
                                 f"moves along the same axis through the same point as joint "
                                 f"{a!r} (at the neutral configuration): one motion given twice, "
                                 "so the joint-space inertia is singular; remove one of them, or "
                                 "give it another axis or anchor (pos)")
        raise ModelFileError(src, f"joint {model.joint_names[k]!r}", None,
                             f"moves body {model.body_names[k]!r} and what it carries, which "
                             f"have no inertia about its axis {j - int(model.joint_voff[k])}: a "
                             "massless body at the end of a joint; give it an <inertial> or "
                             "fix the joint")
