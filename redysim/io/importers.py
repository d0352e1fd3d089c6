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
The XML is read as urdfdom reads it (no namespace processing), so an undeclared prefix in an
element redysim does not read (``<sensor:camera>`` in ``<gazebo>``) stops nothing. A placeholder
link (tiny but positive mass and inertia, Gazebo's 1e-10) is loaded as written, announced when
its pivot is below 1e-12 of the largest. Refused, naming the file and the element: not
well-formed XML, a link or joint name used twice,
a joint whose parent or child link does not exist, a link that is the child of two joints or a
cycle of joints (a kinematic loop), two root links, a planar joint, a floating joint below a
link that moves, a malformed number, an <inertial> without its <mass> or <inertia> (urdfdom
refuses them too). A mimic joint (``<mimic joint multiplier offset>``: q = multiplier q_joint +
offset) is a coupling of the model (:class:`~redysim.model.tree.Coupling`; a mimic of a mimic is
composed onto the first leader), as Pinocchio's ``mimic=True`` reads it: the default,
``mimic="couple"``; ``mimic="independent"`` lets it move on its own (announced; what
Pinocchio's and MuJoCo's URDF readers do by default), ``mimic="refuse"`` refuses it. A mimic on
a fixed joint moves nothing and is announced. A joint's ``<dynamics damping>`` is the model's
(:attr:`Model.damping`; a floating joint's announced); armature, which URDF has no tag for, is
``load_urdf(..., armature=)``'s.

**MJCF** is compiled by MuJoCo first (``mujoco.MjSpec``; the ``models`` extra installs it),
because a file's meaning is its compiler's: inertias from geometry, default classes, angles in
degrees, ``ref`` and ``springref``. The tree is read from the compiled model: hinge, slide, ball
and free joints; a joint's anchor (``pos``) and reference (``ref``) as MuJoCo moves the body:
pose = P_body prod_i [T(a_i) Rot(u_i, q_i - ref_i) T(-a_i)] (a slide: T(u_i (q_i - ref_i)); a
ball: T(a_i) Rot(q_i) T(-a_i), its quaternion q_i (w, x, y, z) MuJoCo's qpos, its velocity the
body's angular velocity in its own frame, MuJoCo's qvel; a ball has no ``ref``),
so that q is MuJoCo's qpos and :meth:`Model.initial` its qpos0; ``<flag gravity="disable"/>``.
A body with several joints, or a joint away from its body's origin, becomes a chain: one
massless body named ``f"{body}_{joint}"`` per joint but the last, joint 1 placed at
P_body T(a_1) Rot(u_1, -ref_1), joint i > 1 at T(a_i - a_(i-1)) Rot(u_i, -ref_i) (a ball:
T(a_i - a_(i-1)); a slide:
T(-ref_i u_i), its anchor the previous one's), and the body's own frame at its last joint's
anchor a_n: its centre of mass is ``ipos - a_n`` there, its children and frames are shifted by
-a_n; a frame by the body's name keeps its origin where the file puts it (also for a jointless
body, fused into its parent), so ``frame_motion(frame=body)`` is MuJoCo's xpos and xmat, and
every named site on a moving body is a frame with its axes (``Model.frame_rotations``).
Equalities are held exactly (MuJoCo's softness announced), by default
(``equality="close"``): a joint equality of degree 1 between two hinge or slide joints is a
coupling of the model (:class:`~redysim.model.tree.Coupling`; a chain of them composed onto its
first leader), as is a tendon equality of one fixed tendon of two joints; a ``connect`` or
``weld`` is a cut joint of the model (:class:`~redysim.model.tree.CutJoint`,
:attr:`Model.cuts`: :class:`redysim.ClosedLoops` and :func:`redysim.simulate` close it; a
connect of a mechanism moving in a plane keeps its two in-plane equations, a 'planar' or
'plane' cut). ``equality="refuse"`` refuses a loop closure, ``equality="drop"`` drops every
equality (announced). Refused: a free joint below the root, an equality the core
cannot hold (a polynomial of degree > 1, a cycle of equalities, a joint that follows two, a
flex's, redundant loop equations) naming the
``<equality>``, a file nested deeper than MuJoCo's XML reader takes (:data:`MJCF_MAX_DEPTH`
elements), and what MuJoCo's compiler refuses (its message kept, the element named).
The passive elements are the model's, as MuJoCo applies them
with its disable flags: ``armature`` (``dof_armature``, :attr:`Model.armature`), ``damping``
(``dof_damping``, unless DAMPER is off), ``stiffness`` with ``springref`` on hinges and slides
(``jnt_stiffness`` and ``qpos_spring``, unless SPRING is off), body ``gravcomp`` (unless gravity
is off or zero, or SPRING and DAMPER both are: MuJoCo's mj_passive then computes nothing); a
jointless body fused into its parent with another gravcomp fraction keeps its own share of its
weight held at its own centre of mass (:attr:`Model.gravcomp_loads`).

**Honoured, announced or refused.** Every attribute of a file that changes the motion is
honoured, refused, or announced: a line of :attr:`Model.notes` names the element, its name and
the value, e.g. ``joint 'knee': frictionloss = 0.3 dropped (no joint friction in the core)``.
Announced (only values that act: a zero, or one MuJoCo's flags disable, is no news): the
nonlinear terms of damping and springs (``dampingpoly``, ``stiffnesspoly``), a free joint's
spring, ``springyield``, ``actuatorgravcomp`` (MuJoCo routes that share of gravity compensation
through the clamped actuator force; the core applies it whole), frictionloss, limits (MJCF
``range``, URDF ``<limit lower upper>``), URDF ``<dynamics friction>`` and a floating joint's
damping, fluid forces (``density``,
``viscosity``), tendons, actuators with a force at ctrl 0 (a position or velocity servo),
contact geometry (MJCF geoms that can touch one another, URDF ``<collision>``), flex,
plugins and plugin actuators (a PID servo pushes at ctrl 0). ``strict=True`` refuses each of
these instead (ModelFileError naming the element and attribute), except what the caller chose
to drop by name (``mimic="independent"``, ``equality="drop"``). Things that do not act on the
motion are one summary line: visual geometry, materials, sites on the world, cameras, lights,
sensors, keyframes, transmissions, Gazebo tags, a URDF joint's effort and velocity bounds (tau
is the caller's), actuators without a force at ctrl 0 (a motor: give its force as tau).

``floating=True``: a URDF's root link (the link fixed to a root link named ``world``), or the
one MJCF root body without joints, gets a free joint, its pose in the file the initial q; a
file whose root already floats is taken as it is; an MJCF root body that already moves on other
joints, or several jointless roots, are refused by name.

**A singular GIM** is refused naming the first joint, from the tip, whose pivot vanishes at the
neutral configuration (:func:`redysim.algorithms.rbda.singular_axes`: zero, not finite, or
round-off of the articulated mass it is computed from) and the massless body that makes it so.
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

from redysim.errors import CaseError, ModelFileError, StateError
from redysim.io.robots import resolve
from redysim.model.parts import KIND_CODES, check_inertia, check_positive
from redysim.model.tree import (
    BALL_JOINT,
    FIXED,
    FREE,
    KINDS,
    QUATERNION_JOINTS,
    Body,
    Coupling,
    CutJoint,
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
EQUALITY = ("close", "refuse", "drop")
# MuJoCo's XML reader (tinyxml2) refuses a document nested deeper than this many elements
# (measured with MuJoCo 4.0: <mujoco><worldbody>, 496 nested <body>, a <joint> in the last)
MJCF_MAX_DEPTH = 499
# a point closure whose J M^-1 J^T has a singular value ratio below this at the file's
# configuration and near it moves in a plane: two of its three equations are kept
PLANE_RANK = 1e-8
LOOP_GAP = 1e-6  # a closure further open than this at qpos0 (relative to the model's size): noted
LISTED = 6  # names (and values) a note lists before "and N more"
# in every note of what was read or closed without changing the motion (what a file has and the
# run does not simulate is every other note: redysim.reports.compare.acting_notes)
SAME_MOTION = "no effect on the motion"


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
            notes.append(f"not read ({SAME_MOTION}): " + ", ".join(
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


def _urdf_unread(report: _Report, root, mimic: str) -> dict[str, float]:
    """What the URDF holds that the tree does not: announced (friction, limits, collision
    geometry) or counted as not read; returns the joints' ``<dynamics damping>`` (joint name ->
    coefficient), which the model holds (a floating joint's is announced: URDF gives one number
    for six coordinates of two units)."""
    damping: list[tuple[str, float]] = []
    friction: list[tuple[str, float]] = []
    limits, collision = [], []
    mimics: list[tuple[str, str]] = []  # (joint, "leader * multiplier + offset")
    fixed_mimics: list[tuple[str, str]] = []
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
            (fixed_mimics if jtype == "fixed" else mimics).append(
                (name, f"{mim.get('joint')!r} * {mim.get('multiplier', '1')} + "
                       f"{mim.get('offset', '0')}"))
    for link in root.findall("link"):
        n = len(link.findall("collision"))
        if n:
            collision.append((link.get("name"), None))
        report.unread_count("<visual>", len(link.findall("visual")))
    report.drop("joint", mimics, "mimic", "it moves independently: mimic='independent'",
                motion=False)
    report.drop("joint", fixed_mimics, "mimic", f"a fixed joint moves nothing to couple; "
                f"{SAME_MOTION}", motion=False)
    types = {j.get("name"): j.get("type") for j in root.findall("joint")}
    report.drop("joint", [(n, x) for n, x in damping if types[n] == "floating"],
                "<dynamics> damping", "one number for a floating joint's six coordinates (m/s "
                "and rad/s): give the model's damping with Model.with_passive")
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
    return {n: x for n, x in damping if types[n] in ("revolute", "continuous", "prismatic")}


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


def _read_xml(src: str, path: Path) -> ET.Element:
    """A URDF's element tree as urdfdom reads it (TinyXML: no namespace processing), so a prefix
    never declared (``<sensor:camera>`` inside ``<gazebo>``, where Gazebo's old files put them)
    stays part of the name of an element redysim does not read, instead of stopping the load as
    ElementTree's "unbound prefix". Refuses XML that is not well-formed."""
    import xml.parsers.expat

    builder = ET.TreeBuilder()
    parser = xml.parsers.expat.ParserCreate()  # no namespace_separator: names as written
    parser.buffer_text = True
    parser.StartElementHandler = builder.start
    parser.EndElementHandler = builder.end
    parser.CharacterDataHandler = builder.data
    try:
        with open(path, "rb") as fh:
            parser.ParseFile(fh)
        return builder.close()
    except xml.parsers.expat.ExpatError as exc:
        raise ModelFileError(src, "<xml>", None, f"not well-formed XML: {exc}") from None
    except OSError as exc:
        raise ModelFileError(src, "<file>", None, f"cannot be read: {exc}") from None


def load_urdf(path: str | os.PathLike, *, floating: bool = False, mimic: str = "couple",
              strict: bool = False, armature=None) -> Model:
    """A URDF's tree, gravity -9.81 along z (module doc), with its joints' ``<dynamics
    damping>`` (:attr:`Model.damping`).

    ``floating``: the root link gets a free joint (a legged or flying robot; initial q its
    pose at the origin), else it is fixed to the world. ``mimic``: "couple" (the default) a
    mimic joint to its leader (:attr:`Model.couplings`), let it move "independent"ly
    (announced), or "refuse" it. ``strict``: refuse, instead of
    announcing in :attr:`Model.notes`, what would change the motion and the core does not
    model (friction, limits, collision geometry). ``armature``: the joints' own inertia, which
    URDF has no tag for (:meth:`Model.with_armature`'s values: a number, n_v numbers, or joint
    name -> value). ``path`` may name a robot of example-robot-data
    (``"example-robot-data:ur5"``, :mod:`redysim.io.robots`). Raises ModelFileError naming the
    file, the element (``joint 'elbow'``, ``link 'base'``) and the value; FileNotFoundError for
    a robot name the package does not have."""
    path = Path(resolve(path))
    src = str(path)
    _check_flags(src, floating=floating, strict=strict)
    _check_choice(src, "mimic", mimic, MIMIC)
    root = _read_xml(src, path)
    if root.tag != "robot":
        raise ModelFileError(src, f"<{root.tag}>", None, "a URDF's root element is <robot>")
    links, children, base = _urdf_graph(src, root)
    couplings = _urdf_mimics(src, root, mimic)
    report = _Report(src)
    damping = _urdf_unread(report, root, mimic)

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
    damping = {n: x for n, x in damping.items() if n in model.joint_names}
    if damping:
        model = model.with_passive(damping=damping, source=src)
    if armature is not None:
        model = model.with_armature(armature, source=src)
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


def _mjcf_tree(mj, m, src, gravcomp=False):
    """Bodies, joints and parents of a compiled MjModel (module doc: a body's joints become a
    chain of massless bodies, its frame at the last joint's anchor, refs folded in); with
    ``gravcomp`` (MuJoCo applies it: :func:`_mjcf_acting`), each body's ``gravcomp``."""
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
            if jtype == JNT.mjJNT_BALL:  # T(a_i - a_(i-1)): its quaternion turns the body
                a = np.array(m.jnt_pos[j], dtype=float)  # about its anchor (no ref: qpos0 is
                specs.append((BALL_JOINT, None, jname, np.eye(3), a - anchor))  # the identity)
                anchor = a
                continue
            if jtype not in (JNT.mjJNT_HINGE, JNT.mjJNT_SLIDE):
                raise ModelFileError(src, f"joint {jname!r}.type", int(jtype), "unsupported "
                                     "joint type (hinge, slide, ball and free are read)")
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
                           tuple(map(tuple, inertia)), physical=False,
                           gravcomp=float(m.body_gravcomp[b]) if gravcomp else 0.0))
        ours[b] = len(bodies) - 1
        shift[b] = anchor
    return bodies, joints, parents, _mjcf_frames(mj, m, ours, shift)


def _mjcf_frames(mj, m, ours: dict, shift: dict) -> tuple[dict, dict]:
    """The frames of an MJCF model (``Model.frames`` and ``Model.frame_rotations``): a body whose
    origin is not its body's origin here (its frame moved to its last joint's anchor, or the
    body fused into its parent by a weld) by its name, at its origin (MuJoCo's xpos, xmat); every
    named site on a moving body by its name (``f"{name}_site"`` if a body has that name), with
    its axes (site_xmat)."""
    frames: dict[str, tuple[int, tuple]] = {}
    axes: dict[str, tuple] = {}
    names = {_name(mj, m, "body", b) for b in range(m.nbody)}
    for b in range(1, m.nbody):
        if np.any(shift[b]) or not int(m.body_jntnum[b]):
            frames[_name(mj, m, "body", b)] = (ours[b], tuple(map(float, -shift[b])))
    for i in range(m.nsite):
        name = mj.mj_id2name(m, mj.mjtObj.mjOBJ_SITE, i)
        b = int(m.site_bodyid[i])
        if not name or ours[b] < 0:
            continue  # unnamed, or on the world: nothing to observe
        name = f"{name}_site" if name in names else name
        frames[name] = (ours[b], tuple(map(float, np.asarray(m.site_pos[i]) - shift[b])))
        axes[name] = tuple(map(tuple, quaternion_matrix(
            *(m.site_quat[i] / np.linalg.norm(m.site_quat[i])))))
    return frames, axes


def _mjcf_acting(mj, m) -> dict[str, bool]:
    """Which passive elements MuJoCo applies, by its disable flags: ``damping`` (not DAMPER),
    ``stiffness`` (not SPRING), ``gravcomp`` (gravity on and not zero, and not both SPRING and
    DAMPER off: then mj_passive computes nothing at all)."""
    DS = mj.mjtDisableBit
    off = m.opt.disableflags
    spring, damper = not off & DS.mjDSBL_SPRING, not off & DS.mjDSBL_DAMPER
    gravity = not off & DS.mjDSBL_GRAVITY and bool(np.any(m.opt.gravity))
    return {"damping": bool(damper), "stiffness": bool(spring),
            "gravcomp": bool(gravity and (spring or damper))}


def _mjcf_passive(mj, m, model: Model) -> dict:
    """The joints' armature, damping, stiffness and springref of a compiled MjModel, per joint
    name (as :meth:`Model.with_armature` and :meth:`Model.with_passive` take them), those
    MuJoCo's flags disable left out; q is qpos, so a springref is ``qpos_spring``."""
    JNT = mj.mjtJoint
    acting = _mjcf_acting(mj, m)
    out: dict[str, dict[str, object]] = {"armature": {}, "damping": {}, "stiffness": {},
                                         "spring_ref": {}}
    for j in range(m.njnt):
        name = _name(mj, m, "joint", j)
        if name not in model.joint_names:
            continue
        k = model.joint_names.index(name)
        width = int(model.joint_voff[k + 1] - model.joint_voff[k])
        d0 = int(m.jnt_dofadr[j])
        dofs = slice(d0, d0 + width)
        out["armature"][name] = tuple(float(x) for x in m.dof_armature[dofs])
        if acting["damping"]:
            out["damping"][name] = tuple(float(x) for x in m.dof_damping[dofs])
        if acting["stiffness"] and int(m.jnt_type[j]) in (JNT.mjJNT_HINGE, JNT.mjJNT_SLIDE):
            out["stiffness"][name] = float(m.jnt_stiffness[j])
            out["spring_ref"][name] = float(m.qpos_spring[m.jnt_qposadr[j]])
    return out


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

    friction, yields, limits, frc, polys, free_springs, actgc = [], [], [], [], [], [], []
    gravcomp = _mjcf_acting(mj, m)["gravcomp"] and bool(np.any(m.body_gravcomp))
    for j in range(m.njnt):
        name = _name(mj, m, "joint", j)
        d0 = int(m.jnt_dofadr[j])
        dofs = slice(d0, d0 + ndof[int(m.jnt_type[j])])
        if not off["DAMPER"] and np.any(m.dof_dampingpoly[dofs]):
            polys.append((name, "dampingpoly", value(m.dof_dampingpoly[dofs])))
        if constraint and not off["FRICTIONLOSS"] and np.any(m.dof_frictionloss[dofs]):
            friction.append((name, value(m.dof_frictionloss[dofs])))
        if not off["SPRING"] and np.any(m.jnt_stiffnesspoly[j]):
            polys.append((name, "stiffnesspoly", value(m.jnt_stiffnesspoly[j])))
        if not off["SPRING"] and m.jnt_stiffness[j] and \
                int(m.jnt_type[j]) not in (JNT.mjJNT_HINGE, JNT.mjJNT_SLIDE):
            free_springs.append((name, float(m.jnt_stiffness[j])))
        if not off["SPRING"] and (m.jnt_stiffness[j] or np.any(m.jnt_stiffnesspoly[j])) \
                and m.jnt_springyield[j]:
            yields.append((name, float(m.jnt_springyield[j])))
        if constraint and not off["LIMIT"] and m.jnt_limited[j]:
            limits.append((name, [float(x) for x in m.jnt_range[j]]))
        if m.nu and m.jnt_actfrclimited[j]:
            frc.append((name, [float(x) for x in m.jnt_actfrcrange[j]]))
        if gravcomp and m.jnt_actgravcomp[j]:
            actgc.append((name, True))
    for key in ("dampingpoly", "stiffnesspoly"):
        report.drop("joint", [(n, v) for n, k, v in polys if k == key], key, "the core's "
                    "damping and springs are linear: the nonlinear terms are left out, the "
                    "linear one kept")
    report.drop("joint", free_springs, "stiffness", "the core's springs act on hinge and slide "
                "joints; a free joint's spring is left out")
    report.drop("joint", actgc, "actuatorgravcomp", "MuJoCo routes this joint's gravity "
                "compensation through its actuator force (clamped by actuatorfrcrange, none "
                "when actuation is disabled); the core applies it whole, as a passive force")
    report.drop("joint", friction, "frictionloss", "no joint friction in the core")
    report.drop("joint", yields, "springyield", "the core's springs do not yield")
    report.drop("joint", limits, "range", "no joint limits in the core: the joint moves "
                "through them")
    report.drop("joint", frc, "actuatorfrcrange", "bounds actuator forces; the core takes tau "
                "as given", motion=False)

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
    plugins: list[tuple[str, str]] = []  # (actuator, its plugin instance)
    if not off["ACTUATION"]:
        for a in range(m.nu):
            if m.opt.disableactuator & (1 << int(m.actuator_group[a])):
                continue
            name = _name(mj, m, "actuator", a)
            if int(m.actuator_plugin[a]) >= 0:  # its force is the plugin's: a PID pushes at 0
                plugins.append((name, _name(mj, m, "plugin", int(m.actuator_plugin[a]))))
            elif int(m.actuator_biastype[a]) and np.any(m.actuator_biasprm[a]):
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
    report.drop("actuator", plugins, "plugin", "a plugin actuator's force is the plugin's "
                "(mujoco.pid: a PID servo towards ctrl) and pushes even at ctrl 0, like a "
                "position servo; the core takes tau as given")
    report.drop("actuator", inputs, "force", "an input: give it as tau", motion=False)

    if constraint and not off["CONTACT"]:
        _mjcf_contacts(mj, m, report, filterparent=not off["FILTERPARENT"])
    report.drop("flex", [(_name(mj, m, "flex", i), None) for i in range(m.nflex)],
                "elasticity and contacts", "deformable bodies: the core's bodies are rigid")
    report.drop("plugin", [(_name(mj, m, "plugin", i), None) for i in range(m.nplugin)],
                "forces", "a plugin's forces are not modelled in the core")
    world_sites = int(np.sum(np.asarray(m.site_bodyid) == 0))
    for what, n in (("sites on the world", world_sites), ("cameras", m.ncam), ("lights", m.nlight),
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


def _mjcf_rule(mj, m, e: int, what: str, src: str, name: str
               ) -> tuple[str, str, float, float] | None:
    """(follower, leader, multiplier, offset) of an active joint or tendon equality, or None for
    another kind; ModelFileError naming the equality for one that is no coupling of two R or P
    joints. A joint equality: MuJoCo's y - y0 = a0 + a1 (x - x0) (y joint1, x joint2, x0 and y0
    their qpos0), i.e. q_y = a1 q_x + a0 + y0 - a1 x0, of degree 1 at most. A tendon equality
    of one fixed tendon of two joints, L = c1 q1 + c2 q2 (no tendon2): L - L0 = a0, L0 its
    length at qpos0, i.e. q1 = -(c2 / c1) q2 + (a0 + L0) / c1."""
    EQ, JNT = mj.mjtEq, mj.mjtJoint
    kind = int(m.eq_type[e])
    if kind not in (int(EQ.mjEQ_JOINT), int(EQ.mjEQ_TENDON)):
        return None
    field = f"equality {name!r}"
    a = np.asarray(m.eq_data[e][:5], dtype=float)
    scalar = (int(JNT.mjJNT_HINGE), int(JNT.mjJNT_SLIDE))
    o1, o2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
    if kind == int(EQ.mjEQ_JOINT):
        if o2 < 0:
            raise ModelFileError(src, f"{field}.joint1", what, "a joint equality without "
                                 "joint2 holds the joint still (a lock): lock it with "
                                 "Model.locked, or load with equality='drop'")
        for j in (o1, o2):
            if int(m.jnt_type[j]) not in scalar:
                raise ModelFileError(src, field, what, f"joint {_name(mj, m, 'joint', j)!r} "
                                     "is no hinge or slide: a coupling holds one hinge or slide "
                                     "joint's coordinate to another's")
        if np.any(a[2:]):
            raise ModelFileError(src, f"{field}.polycoef", [float(x) for x in a],
                                 "a polynomial of degree > 1: the core's couplings are linear "
                                 "(q1 = a1 q2 + a0); load with equality='drop' to drop it")
        y0, x0 = float(m.qpos0[m.jnt_qposadr[o1]]), float(m.qpos0[m.jnt_qposadr[o2]])
        return (_name(mj, m, "joint", o1), _name(mj, m, "joint", o2), float(a[1]),
                float(a[0] + y0 - a[1] * x0))
    # a tendon equality: one fixed tendon of two hinge or slide joints, held at a length
    if o2 >= 0:
        raise ModelFileError(src, f"{field}.tendon2", what, "an equality between two tendons: "
                             "not a coupling of two joints the core holds; load with "
                             "equality='drop' to drop it")
    adr, num = int(m.tendon_adr[o1]), int(m.tendon_num[o1])
    wraps = [(int(m.wrap_type[i]), int(m.wrap_objid[i]), float(m.wrap_prm[i]))
             for i in range(adr, adr + num)]
    joints = [(j, c) for t, j, c in wraps if t == int(mj.mjtWrap.mjWRAP_JOINT)]
    if len(joints) != 2 or len(wraps) != 2 or any(
            int(m.jnt_type[j]) not in scalar for j, _ in joints) or not all(c for _, c in joints):
        raise ModelFileError(src, f"{field}.tendon1", _name(mj, m, "tendon", o1), "a tendon "
                             "equality couples two joints when its tendon is a <fixed> one of "
                             "two hinge or slide joints with nonzero coefs; load with "
                             "equality='drop' to drop it")
    if np.any(a[1:]):
        raise ModelFileError(src, f"{field}.polycoef", [float(x) for x in a], "a tendon "
                             "equality of one tendon holds its length at L0 + a0; the other "
                             "terms must be 0")
    (j1, c1), (j2, c2) = joints
    q1, q2 = (float(m.qpos0[m.jnt_qposadr[j]]) for j in (j1, j2))
    # c1 (q1 - q1_0) + c2 (q2 - q2_0) = a0 (L0 = c1 q1_0 + c2 q2_0, the length at qpos0)
    return (_name(mj, m, "joint", j1), _name(mj, m, "joint", j2), -c2 / c1,
            (float(a[0]) + c1 * q1 + c2 * q2) / c1)


def _compose(src: str, rules: list[tuple[str, tuple[str, str, float, float]]]
             ) -> list[tuple[str, Coupling]]:
    """The couplings of (equality name, rule) pairs, each composed onto its first leader (a
    follower of a follower: multipliers multiplied, offsets carried); ModelFileError naming the
    equality for a joint that follows twice, or equalities that follow one another in a
    cycle."""
    rule: dict[str, tuple[str, str, float, float]] = {}
    for name, (follower, leader, mult, off) in rules:
        if follower in rule:
            raise ModelFileError(src, f"equality {name!r}", follower, f"joint {follower!r} "
                                 f"already follows joint {rule[follower][1]!r} (equality "
                                 f"{rule[follower][0]!r}): a joint follows one leader; load "
                                 "with equality='drop' to drop them")
        rule[follower] = (name, leader, mult, off)
    out = []
    for follower, (name, leader, mult, off) in rule.items():
        seen = [follower]
        while leader in rule:  # q = m (m2 q2 + o2) + o
            if leader in seen:
                chain = " -> ".join(map(repr, seen[seen.index(leader):] + [leader]))
                raise ModelFileError(src, f"equality {name!r}", leader, "joint equalities "
                                     f"follow one another in a cycle ({chain}): no joint leads "
                                     "them; load with equality='drop' to drop them")
            seen.append(leader)
            _, leader, m2, o2 = rule[leader]
            mult, off = mult * m2, mult * o2 + off
        out.append((name, Coupling(follower, leader, mult, off)))
    return out


@dataclass(frozen=True)
class _Closure:
    """A loop closure of the file (a connect or weld equality), in MuJoCo's bodies: point
    ``p1`` of body ``b1`` on point ``p2`` of body ``b2`` (body frames; 0: the world), for a
    weld also the frames ``R1``, ``R2`` aligned."""

    name: str
    what: str
    kind: str  # "point" or "weld"
    b1: int
    p1: np.ndarray
    b2: int
    p2: np.ndarray
    R1: np.ndarray | None = None
    R2: np.ndarray | None = None


def _mjcf_closure(mj, m, e: int, name: str, what: str, report: _Report) -> _Closure | None:
    """The loop closure of a connect or weld equality (None for another kind), as MuJoCo's
    engine reads it: a connect keeps body1's point data[0:3] on body2's data[3:6] (site1 on
    site2); a weld keeps body1's point data[3:6] on body2's data[0:3] and body2's frame at
    body1's turned by relpose (data[6:10]) (sites: the two sites' frames). A weld with
    torquescale 0 leaves the rotation free: a point closure (announced)."""
    EQ = mj.mjtEq
    kind = int(m.eq_type[e])
    if kind not in (int(EQ.mjEQ_CONNECT), int(EQ.mjEQ_WELD)):
        return None
    data = np.asarray(m.eq_data[e], dtype=float)
    o1, o2 = int(m.eq_obj1id[e]), int(m.eq_obj2id[e])
    sites = int(m.eq_objtype[e]) == int(mj.mjtObj.mjOBJ_SITE)
    if sites:
        b1, b2 = int(m.site_bodyid[o1]), int(m.site_bodyid[o2])
        p1, p2 = np.array(m.site_pos[o1]), np.array(m.site_pos[o2])
        R1, R2 = (quaternion_matrix(*(m.site_quat[o] / np.linalg.norm(m.site_quat[o])))
                  for o in (o1, o2))
    else:
        b1, b2 = o1, max(o2, 0)
        if kind == int(EQ.mjEQ_CONNECT):
            p1, p2 = data[0:3].copy(), data[3:6].copy()
        else:
            p1, p2 = data[3:6].copy(), data[0:3].copy()
        R1 = R2 = np.eye(3)
        if kind == int(EQ.mjEQ_WELD):  # relpose (w, x, y, z)
            R1 = quaternion_matrix(*(data[6:10] / np.linalg.norm(data[6:10])))
    if kind == int(EQ.mjEQ_CONNECT):
        return _Closure(name, what, "point", b1, p1, b2, p2)
    if data[10] == 0.0:
        report.drop("equality", [(name, 0.0)], "torquescale", "a weld with torquescale 0 "
                    "leaves the rotation free: closed as a point (a connect)", motion=False)
        return _Closure(name, what, "point", b1, p1, b2, p2)
    return _Closure(name, what, "weld", b1, p1, b2, p2, R1, R2)


def _mjcf_equality(mj, m, src: str, report: _Report, equality: str
                   ) -> tuple[list[Coupling], list[_Closure]]:
    """The couplings of the active joint equalities (and tendon equalities of one fixed tendon
    of two joints), composed onto their first leaders, and the loop closures (connect, weld)
    with equality='close' (the default); equality='refuse' refuses a loop closure,
    equality='drop' drops every equality (announced). Each held exactly: MuJoCo's soft
    constraint without its softness, announced. Refused by name: any other active equality
    (a flex's, a polynomial of degree > 1, a cycle, two tendons). An inactive one is
    announced."""
    off = m.opt.disableflags & (mj.mjtDisableBit.mjDSBL_EQUALITY |
                                mj.mjtDisableBit.mjDSBL_CONSTRAINT)
    dropped: list[tuple[str, str]] = []
    inactive: list[tuple[str, str]] = []
    rules: list[tuple[str, tuple[str, str, float, float]]] = []
    closures: list[_Closure] = []
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
        if not m.eq_active0[e] or off:
            inactive.append((name, what))
            continue
        if equality == "drop":
            dropped.append((name, what))
            continue
        rule = _mjcf_rule(mj, m, e, what, src, name)
        if rule is not None:
            rules.append((name, rule))
            continue
        closure = _mjcf_closure(mj, m, e, name, what, report)
        if closure is None:
            raise ModelFileError(src, f"equality {name!r}", what, f"a {kind} equality, which "
                                 "the core cannot hold (it holds joint couplings, connect and "
                                 "weld loop closures); load with equality='drop' to drop it "
                                 "(announced in Model.notes)")
        if equality == "refuse":
            raise ModelFileError(src, f"equality {name!r}", what, "a loop closure, refused "
                                 "with equality='refuse'; load with equality='close' (the "
                                 "default) to close it (docs/design.md, 'Closed loops'), or "
                                 "equality='drop' to drop it (announced in Model.notes)")
        closures.append(closure)
    couplings = _compose(src, rules)
    report.drop("equality", dropped, "constraint", "equality='drop': the tree moves without "
                "it", motion=False)
    report.drop("equality", inactive, "constraint", "inactive in the file (active = false, "
                "or equality disabled by a flag)", motion=False)
    report.drop("equality", [(n, f"{c.follower!r} = {c.multiplier:g} {c.leader!r} + "
                             f"{c.offset:g}") for n, c in couplings], "solref, solimp",
                "a joint coupling, held exactly (Model.couplings), not softly as MuJoCo does")
    report.drop("equality", [(c.name, c.what) for c in closures], "solref, solimp",
                "a loop closure, held exactly (Model.cuts), not softly as MuJoCo does")
    return [c for _, c in couplings], closures


def _mjcf_cuts(mj, m, model: Model, closures: list[_Closure], src: str
               ) -> tuple[list[CutJoint], list[str]]:
    """The cut joints of the loop closures, in the model's bodies (a MuJoCo body fused into
    an ancestor or the world, its points and frames carried there through the poses at qpos0);
    connects of the same two bodies merged (:func:`_hinges_of_pairs`: two on a hinge line are
    one revolute cut), then each cut's equations that repeat others dropped
    (:func:`_independent_cuts`: a point closure of a mechanism that moves in a plane keeps 2
    of its 3, a 'planar' or 'plane' cut; the second bar of a parallelogram 1, a 'line' cut);
    ModelFileError naming the equality for a closure of the world to itself, or equations
    still redundant (at the file's configuration only: a change point). Also the notes: what
    was merged or dropped as dependent on what, and each closure open at qpos0 (MuJoCo pulls
    it shut softly)."""
    from redysim.algorithms import rbda
    from redysim.algorithms.loops import ClosedLoops

    d = mj.MjData(m)
    d.qpos[:] = m.qpos0
    mj.mj_kinematics(m, d)
    q0 = np.array(m.qpos0, dtype=float)
    kin = rbda.kinematics(model, q0, np.zeros(model.n_v))

    def ours(b: int) -> int:
        while b and not int(m.body_jntnum[b]):
            b = int(m.body_parentid[b])
        if not b:
            return -1
        j = int(m.body_jntadr[b]) + int(m.body_jntnum[b]) - 1
        return model.joint_names.index(_name(mj, m, "joint", j))

    def local(b: int, p, R):
        """Body b's point p and frame R (MuJoCo's body frame) in our body's frame."""
        Rw = np.asarray(d.xmat[b], dtype=float).reshape(3, 3)
        x, F = d.xpos[b] + Rw @ p, Rw @ (np.eye(3) if R is None else R)
        k = ours(b)
        if k < 0:
            return k, x, F
        return k, kin.R[k].T @ (x - kin.O[k]), kin.R[k].T @ F

    cuts = []
    for c in closures:
        (k1, p1, R1), (k2, p2, R2) = local(c.b1, c.p1, c.R1), local(c.b2, c.p2, c.R2)
        if k1 < 0:  # body_a moves; the world is body_b
            (k1, p1, R1), (k2, p2, R2) = (k2, p2, R2), (k1, p1, R1)
        if k1 < 0 or k1 == k2:
            raise ModelFileError(src, f"equality {c.name!r}", c.what, "joins two bodies that "
                                 "do not move relative to each other (both fixed to the world, "
                                 "or to one body): it closes no loop")
        rots = {"rot_a": tuple(map(tuple, R1)), "rot_b": tuple(map(tuple, R2))} \
            if c.kind == "weld" else {}
        cuts.append(CutJoint(c.name, k1, tuple(p1), k2, tuple(p2), c.kind, **rots))
    cuts, merged = _hinges_of_pairs(cuts, closures, src,
                                    max(1.0, float(np.abs(model.placement_p).sum())))
    qc = model.couple(q0)  # (qpos0 is off a coupling whose a0 is not 0)
    cuts, reduced = _independent_cuts(model, cuts, qc, src)
    loops = ClosedLoops(model, cuts, source=src)
    try:
        loops.forward_dynamics(qc, np.zeros(model.n_v))
    except StateError as exc:
        names = [c.name for c in cuts if repr(c.name) in str(exc)] or [cuts[0].name]
        c = next(x for x in closures if x.name == names[0])
        why = ("its equations are redundant at the file's configuration" if "redundant" in
               str(exc) else "the loops cannot be closed at the file's configuration")
        raise ModelFileError(src, f"equality {c.name!r}", c.what, f"{why} ({exc}); MuJoCo's "
                             "soft constraints take redundant rows, the core's exact ones do "
                             "not; load with equality='drop' to drop it") from None
    gap = loops.evaluate(qc, np.zeros(model.n_v))[0]
    worst: dict[str, float] = {}
    for r, (i, _) in enumerate(loops.rows):
        if abs(gap[r]) > LOOP_GAP * loops.size:
            worst[cuts[i].name] = max(worst.get(cuts[i].name, 0.0), abs(float(gap[r])))
    notes = [f"equality {name!r}: open at the file's configuration by up to {g:.3g} (m, or rad "
             "for a weld's frames; MuJoCo pulls it shut softly): a run starts from an assembled "
             "q (ClosedLoops.project moves q onto the loops)" for name, g in worst.items()]
    return cuts, merged + reduced + notes


def _frame_with_z(z) -> np.ndarray:
    """A rotation whose z axis is the unit vector z (its x and y any, fixed)."""
    z = np.asarray(z, dtype=float) / np.linalg.norm(z)
    x = np.cross(z, np.eye(3)[int(np.argmin(np.abs(z)))])
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(z, x), z])


def _hinges_of_pairs(cuts: list[CutJoint], closures: list[_Closure], src: str, size: float
                     ) -> tuple[list[CutJoint], list[str]]:
    """The point cuts that join the same two bodies, merged: two or more whose points lie on
    one line become one 'revolute' cut about that line (pinned at two points, the bodies turn
    about the line through them: 5 independent equations where the connects write 6 or more);
    one that repeats another's point is dropped. Refused by name: points whose distances
    differ on the two bodies (the connects cannot all hold), or three or more not on a line
    (they weld the bodies: a <weld> says so)."""
    what = {c.name: c.what for c in closures}
    tol = LOOP_GAP * size
    groups: dict[tuple[int, int], list[int]] = {}
    for i, c in enumerate(cuts):
        if c.kind == "point":
            groups.setdefault((min(c.body_a, c.body_b), max(c.body_a, c.body_b)), []).append(i)
    gone: set[int] = set()
    merged: dict[int, CutJoint] = {}
    notes = []
    for members in groups.values():
        if len(members) < 2:
            continue
        first = cuts[members[0]]
        pa, pb = [np.array(first.point_a)], [np.array(first.point_b)]
        for i in members[1:]:  # each as (first's body a, first's body b)
            c = cuts[i]
            same = c.body_a == first.body_a
            pa.append(np.array(c.point_a if same else c.point_b))
            pb.append(np.array(c.point_b if same else c.point_a))
        for j, i in enumerate(members[1:], 1):
            for k in range(j):
                da, db = np.linalg.norm(pa[j] - pa[k]), np.linalg.norm(pb[j] - pb[k])
                if abs(da - db) > tol:
                    c = cuts[i]
                    raise ModelFileError(src, f"equality {c.name!r}", what[c.name],
                                         f"a connect of the same two bodies as equality "
                                         f"{cuts[members[k]].name!r}, their points {da:.6g} m "
                                         f"apart on one body and {db:.6g} m on the other: the "
                                         "two cannot both hold; load with equality='drop' to "
                                         "drop them")
        far = [j for j in range(1, len(pa)) if np.linalg.norm(pa[j] - pa[0]) > tol]
        names = [cuts[i].name for i in members]
        if not far:  # every point the first's: the others repeat it
            gone.update(members[1:])
            notes.append(f"equality {', '.join(map(repr, names[1:]))}: repeats the connect of "
                         f"equality {names[0]!r} (the same points): closed once, by its "
                         f"independent equations ({SAME_MOTION})")
            continue
        axis_a = pa[far[0]] - pa[0]
        axis_a /= np.linalg.norm(axis_a)
        for j in far[1:]:
            off = pa[j] - pa[0]
            if np.linalg.norm(off - (off @ axis_a) * axis_a) > tol:
                c = cuts[members[j]]
                raise ModelFileError(src, f"equality {c.name!r}", what[c.name],
                                     "a third connect of the same two bodies, its point off "
                                     f"the line through those of {names[0]!r} and "
                                     f"{names[far[0]]!r}: together they weld the bodies, which "
                                     "the connects' 9 or more equations do redundantly; write "
                                     "one <weld> instead, or load with equality='drop'")
        axis_b = pb[far[0]] - pb[0]
        axis_b /= np.linalg.norm(axis_b)
        merged[members[0]] = CutJoint(first.name, first.body_a, first.point_a, first.body_b,
                                      first.point_b, "revolute",
                                      rot_a=tuple(map(tuple, _frame_with_z(axis_a).tolist())),
                                      rot_b=tuple(map(tuple, _frame_with_z(axis_b).tolist())))
        gone.update(members[1:])
        notes.append(f"equality {', '.join(map(repr, names))}: connects of the same two "
                     f"bodies, their points on one line: closed as one 'revolute' cut about "
                     f"that line, named {names[0]!r} (the bodies turn about it; the same motion "
                     f"as the {3 * len(names)} equations, by its 5 independent equations; "
                     f"{SAME_MOTION})")
    return [merged.get(i, c) for i, c in enumerate(cuts) if i not in gone], notes


def _near_on_loops(model: Model, loops, J, q0):
    """A configuration near q0 that keeps the loops to second order: q0 moved up to 1e-3 rad
    (or m) per coordinate along the null space of J and the couplings (fixed pseudo-random
    directions)."""
    n = model.n_v
    rows = [J] + [np.eye(n)[int(fv)] - m * np.eye(n)[int(lv)]
                  for fv, lv, m in zip(*model.coupling_index[2:5], strict=True)]
    A = np.vstack(rows)
    _, s, Vt = np.linalg.svd(A)
    rank = int(np.sum(s > 1e-6 * s[0])) if s.size and s[0] > 0 else 0
    null = Vt[rank:]
    if not null.shape[0]:
        return q0
    dv = null.T @ np.random.default_rng(20261207).uniform(-1.0, 1.0, null.shape[0])
    dv *= 1e-3 / max(np.abs(dv).max(), np.finfo(float).tiny)
    return model.couple(loops._moved(np.asarray(q0, dtype=float), dv))


def _independent_cuts(model: Model, cuts: list[CutJoint], q0, src: str
                      ) -> tuple[list[CutJoint], list[str]]:
    """The cuts with their dependent equations dropped: in order, each cut's equations that
    repeat its own others or earlier cuts' (the Schur complement of J M^-1 J^T on them, given
    the rows kept before, has an eigenvalue below PLANE_RANK of its largest diagonal, at the
    file's configuration and near it, on the loops) are dropped, where what is left is a cut:
    a point's (or a revolute's or weld's whose rotation rows all repeat) independent directions
    kept as a 'point', 'planar' (the plane's normal the world's z, at q0 and near), 'plane' or
    'line' cut (the directions fixed on body b: a planar loop's plane turns with its bodies),
    a cut with none dropped; notes say which equations were
    dropped as dependent on which. A cut dependent only at q0 (a change point), or whose
    rotation rows are in part independent, is left whole (ClosedLoops then refuses it)."""
    from redysim.algorithms import rbda
    from redysim.algorithms.loops import ClosedLoops

    loops = ClosedLoops(model, cuts)
    zeros = np.zeros(model.n_v)
    J0 = loops.evaluate(q0, zeros)[1]
    near = _near_on_loops(model, loops, J0, q0)
    grams = []
    for q in (q0, near):
        J = loops.evaluate(q, zeros)[1]
        grams.append(J @ loops._mobility(q, J))
    start = np.concatenate([[0], np.cumsum([KINDS[c.kind] for c in cuts])])
    kept: list[np.ndarray] = []  # each kept row as coefficients of the rows of J
    kept_by: list[int] = []  # the cut each kept row is of
    out: list[CutJoint] = []
    notes = []
    R0, R_near = (rbda.kinematics(model, q, zeros).R for q in (q0, near))

    def schur(G, idx):
        """(eigenvalues relative to the rows' largest diagonal, eigenvectors, projection
        coefficients on the kept rows) of rows idx given the kept rows."""
        T = np.eye(G.shape[0])[idx]
        S = T @ G @ T.T
        coef = np.zeros((len(idx), 0))
        if kept:
            C = np.vstack(kept)
            GK = C @ G @ C.T
            coef = np.linalg.lstsq(GK, C @ G @ T.T, rcond=None)[0].T
            S = S - T @ G @ C.T @ coef.T
        lam, V = np.linalg.eigh(0.5 * (S + S.T))
        scale = max(float(np.max(np.diag(T @ G @ T.T))), np.finfo(float).tiny)
        return lam / scale, V, coef

    def schur_alone(G, idx):
        """The eigenvalues of rows idx's own J M^-1 J^T, relative to its largest diagonal."""
        S = G[np.ix_(idx, idx)]
        return np.linalg.eigvalsh(S) / max(float(np.max(np.diag(S))), np.finfo(float).tiny)

    for i, c in enumerate(cuts):
        t = KINDS[c.kind]
        rows = np.arange(start[i], start[i + 1])
        trans = rows[:min(t, 3)] if c.kind in ("point", "revolute", "weld") else rows
        ranks = []
        for G in grams:
            lam, _, _ = schur(G, rows)
            lam_t, _, _ = schur(G, trans)
            ranks.append((int(np.sum(lam > PLANE_RANK)), int(np.sum(lam_t > PLANE_RANK))))
        r, r_t = ranks[0]
        if r == t or ranks[0] != ranks[1] or r != r_t:
            out.append(c)  # whole: independent, dependent at q0 only, or not a cut's rows
            kept.extend(np.eye(start[-1])[rows])
            kept_by.extend([i] * t)
            continue
        lam, V, coef = schur(grams[0], trans)
        keep, drop = V[:, lam > PLANE_RANK], V[:, lam <= PLANE_RANK]
        whom: list[str] = []
        if kept:
            weight = np.abs(drop.T @ coef).max(axis=0)
            whom = sorted({cuts[kept_by[k]].name for k in
                           np.flatnonzero(weight > 1e-3 * max(weight.max(), 1e-300))})
        for col in keep.T:
            row = np.zeros(start[-1])
            row[trans] = col
            kept.append(row)
            kept_by.append(i)
        own = int(np.sum(schur_alone(grams[0], rows) > PLANE_RANK)) < t
        on = " and ".join((["its others"] if own or not whom else [])
                          + ([f"those of {', '.join(map(repr, whom))}"] if whom else []))
        head = f"equality {c.name!r}: {t - r} of its {t} equations repeat {on} (dependent " \
            "at the file's configuration and near it, on the loops)"
        if r == 0:
            notes.append(f"{head}: dropped, the loop is closed by {on}, its independent "
                         f"equations ({SAME_MOTION})")
            continue
        if c.kind in ("planar", "plane"):  # directions in the plane's frame on body b
            F = np.eye(3) if c.kind == "planar" else np.asarray(c.rot_b, dtype=float)
            if c.kind == "planar" and c.body_b >= 0:
                F = R0[c.body_b].T
            dirs = F[:, :2] @ keep
        else:  # world directions at q0, carried onto body b
            dirs = keep if c.body_b < 0 else R0[c.body_b].T @ keep
            F = None
        if r == 3:
            cut = CutJoint(c.name, c.body_a, c.point_a, c.body_b, c.point_b, "point")
        elif r == 2:
            n = np.cross(dirs[:, 0], dirs[:, 1])
            n_world = [n] if c.body_b < 0 else [R[c.body_b] @ n for R in (R0, R_near)]
            if c.kind == "point" and all(abs(abs(x[2]) - 1.0) < 1e-9 for x in n_world):
                cut = CutJoint(c.name, c.body_a, c.point_a, c.body_b, c.point_b, "planar")
            else:
                cut = CutJoint(c.name, c.body_a, c.point_a, c.body_b, c.point_b, "plane",
                               rot_b=tuple(map(tuple, _frame_with_z(n).tolist())))
        else:
            F = _frame_with_z(dirs[:, 0])[:, [2, 0, 1]]  # its x the line (a turn of the axes)
            cut = CutJoint(c.name, c.body_a, c.point_a, c.body_b, c.point_b, "line",
                           rot_b=tuple(map(tuple, F.tolist())))
        out.append(cut)
        if c.kind == "point" and r == 2 and not whom:
            notes.append(f"equality {c.name!r}: a connect of a mechanism that moves in a "
                         f"plane, closed by its two in-plane equations (a {cut.kind!r} cut: "
                         f"the third repeats them; {SAME_MOTION})")
        else:
            notes.append(f"{head}: closed by its independent equations ({r} of {t}: a "
                         f"{cut.kind!r} cut; {SAME_MOTION})")
    return out, notes


def load_mjcf(path: str | os.PathLike, *, floating: bool = False, equality: str = "close",
              strict: bool = False) -> Model:
    """An MJCF model's tree as MuJoCo compiles it, with its gravity (module doc): q is MuJoCo's
    qpos, :meth:`Model.initial` its qpos0.

    ``floating``: the one root body without joints gets a free joint (its file pose the
    initial q); refused when a root body already moves on other joints or several roots have
    none. ``equality``: "close" (the default) keeps the active equalities exactly: joint
    equalities of degree 1 as couplings (:attr:`Model.couplings`, chains composed onto their
    first leader), connect and weld equalities as the model's cut joints (:attr:`Model.cuts`,
    closed by :class:`redysim.ClosedLoops` and :func:`redysim.simulate`); "refuse" refuses a
    connect or weld (couplings kept); "drop" drops every equality (announced). ``strict``:
    refuse, instead of announcing in :attr:`Model.notes`, what would change the motion and the
    core does not model. Raises ModelFileError naming the file, the element (``joint 'knee'``,
    ``body 'torso'``, ``equality 'loop'``) and the value. ``path`` may name a robot of
    example-robot-data as :func:`load_urdf`'s does."""
    path = Path(resolve(path))
    src = str(path)
    _check_flags(src, floating=floating, strict=strict)
    _check_choice(src, "equality", equality, EQUALITY)
    mj = _mujoco(path)
    m = _compile_mjcf(mj, path, floating)
    bodies, joints, parents, (frames, axes) = _mjcf_tree(mj, m, src,
                                                         _mjcf_acting(mj, m)["gravcomp"])
    report = _Report(src)
    couplings, closures = _mjcf_equality(mj, m, src, report, equality)
    _mjcf_unread(mj, m, report)
    gravity = (0.0, 0.0, 0.0) if m.opt.disableflags & mj.mjtDisableBit.mjDSBL_GRAVITY else \
        tuple(float(g) for g in m.opt.gravity)
    model = _finish(bodies, joints, parents, gravity, path.stem, src, report.notes(strict),
                    frames=frames, frame_rotations=axes)
    passive = _mjcf_passive(mj, m, model)
    model = model.with_armature(passive.pop("armature"), source=src).with_passive(
        **passive, source=src)
    if couplings:
        model = model.with_couplings(couplings, source=src)
    object.__setattr__(model, "initial_q", np.array(m.qpos0, dtype=float))
    if closures:
        cuts, reduced = _mjcf_cuts(mj, m, model, closures, src)
        notes = model.notes + tuple(reduced)
        initial = model.initial_q
        model = model.with_cuts(cuts, source=src)
        object.__setattr__(model, "notes", notes)
        object.__setattr__(model, "initial_q", initial)
    return model


# --------------------------------------------------------------------------- the tree
def _finish(bodies, joints, parents, gravity, name, src, notes, *, frames=None,
            frame_rotations=None) -> Model:
    """Build the Model (bodies fixed to the world dropped, with their frames), check that every
    joint has inertia to move, record what the importer dropped."""
    bodies, joints, parents, kept = drop_world_fixed(bodies, joints, parents)
    if not bodies:
        raise ModelFileError(src, "<model>", None, "no body moves: every joint is fixed")
    frames = {f: (kept[b], pt) for f, (b, pt) in (frames or {}).items() if b in kept}
    frame_rotations = {f: R for f, R in (frame_rotations or {}).items() if f in frames}
    model = Model.build(bodies, joints, parents, gravity=gravity, name=name, source=src,
                        frames=frames, frame_rotations=frame_rotations)
    placeholders = _check_inertia_to_move(model, src)
    object.__setattr__(model, "notes", (*notes, *placeholders))
    return model


def _same_motion(model: Model, j: int) -> int | None:
    """Another DOF whose motion (the unit twist of its axis, about the world origin, at the
    neutral configuration) is DOF ``j``'s, up to its sign and size: two hinges on one axis
    line, or two slides along one direction (free and ball joints' axes left out: theirs is a
    massless body's case). None when there is none."""
    from redysim.algorithms.rbda import kinematics

    kin = kinematics(model, model.neutral(), np.zeros(model.n_v))
    body = np.searchsorted(model.joint_voff, np.arange(model.n_v), side="right") - 1
    S = kin.S.copy()
    S[3:] -= np.cross(S[:3].T, kin.O[body]).T  # each axis's twist about the world origin
    unit = S / np.maximum(np.linalg.norm(S, axis=0), np.finfo(float).tiny)
    single = np.array([model.joint_types[int(k)] not in QUATERNION_JOINTS for k in body])
    if not single[j]:  # (a free or ball joint's axes: a massless body, not a repeated joint)
        return None
    for other in np.flatnonzero(single):
        if other != j and min(np.abs(unit[:, j] - unit[:, other]).max(),
                              np.abs(unit[:, j] + unit[:, other]).max()) < 1e-9:
            return int(other)
    return None


def _check_inertia_to_move(model: Model, src: str) -> list[str]:
    """Refuse a model whose GIM is singular at the neutral configuration, naming the first
    joint whose pivot vanishes in elimination order (from the tip, :func:`rbda.singular_axes
    <redysim.algorithms.rbda.singular_axes>`) and the massless body that makes it so; a tiny but
    positive inertia (a placeholder link: Gazebo's 1e-10 kg) is loaded, and announced in the
    notes returned when its pivot is below MASSLESS_TOL of the largest."""
    from redysim.algorithms.rbda import MASSLESS_TOL, pivots, singular_axes

    pivoted = pivots(model)
    bad = singular_axes(model, pivoted)
    if bad.size:
        j = int(bad[0])
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
                             _singular_text(model, k, j - int(model.joint_voff[k])))
    D = pivoted[0]
    largest = float(np.max(D)) if D.size else 0.0
    small = np.flatnonzero(D < MASSLESS_TOL * largest)
    notes = []
    for j in small[::-1][:LISTED]:
        k = int(np.searchsorted(model.joint_voff, j, side="right") - 1)
        what = "inertia" if model.dof_kind[j] != KIND_CODES["P"] else "mass"
        notes.append(f"joint {model.joint_names[k]!r}: moves {_carried(model, k)} with "
                     f"{what} {float(D[j]):.3g} about its axis {j - int(model.joint_voff[k])}, "
                     f"{float(D[j]) / largest:.2g} of the largest (a placeholder's?): loaded as "
                     "written (its pivot is finite); its accelerations are as ill-conditioned "
                     "as that ratio")
    if small.size > LISTED:
        notes.append(f"and {small.size - LISTED} more joints whose pivot is below "
                     f"{MASSLESS_TOL:g} of the largest (placeholders?), loaded as written")
    return notes


def _subtree(model: Model, k: int) -> list[int]:
    """Body k and its descendants (parents come before children)."""
    inside = {k}
    for b in range(k + 1, model.n_bodies):
        if int(model.parent[b]) in inside:
            inside.add(b)
    return sorted(inside)


def _massless(model: Model, b: int) -> bool:
    return model.mass[b] == 0 and not np.any(model.inertia_com[b])


def _carried(model: Model, k: int) -> str:
    """Body k, with what it carries: 'link 'a' (1e-10 kg)' or 'links 'a' and 3 more (...)'."""
    sub = _subtree(model, k)
    mass = float(sum(model.mass[b] for b in sub))
    head = f"body {model.body_names[k]!r}"
    return head + (f" ({mass:.3g} kg)" if len(sub) == 1 else
                   f" and {len(sub) - 1} bodies it carries ({mass:.3g} kg in all)")


def _singular_text(model: Model, k: int, axis: int) -> str:
    """Why joint k's axis has no inertia to move: the massless body responsible."""
    name = repr(model.body_names[k])
    kids = [b for b in range(k + 1, model.n_bodies) if int(model.parent[b]) == k]
    if _massless(model, k) and kids and model.joint_types[k] == FREE:
        joints = ", ".join(repr(model.joint_names[b]) for b in kids[:LISTED])
        return (f"its body {name} is massless and floats: what it carries turns on its own "
                f"joints ({joints}), so the base moves without moving any mass (axis {axis} of "
                f"the free joint, in elimination order the first pivot that vanishes): the GIM "
                f"is singular; give body {name} an <inertial> (mass and inertia)")
    if _massless(model, k) and kids:
        joints = ", ".join(repr(model.joint_names[b]) for b in kids[:LISTED])
        return (f"moves body {name}, which is massless, and what it carries turns on its own "
                f"joints ({joints}) without moving about axis {axis}: no inertia about it, the "
                f"GIM is singular; give body {name} an <inertial> or fix the joint")
    sub = _subtree(model, k)
    if all(_massless(model, b) for b in sub):
        what = "which is" if len(sub) == 1 else "and what it carries, which are"
        about = "mass along" if model.dof_kind[int(model.joint_voff[k]) + axis] == \
            KIND_CODES["P"] else "inertia about"
        return (f"moves body {name} {what} massless: no {about} its axis {axis} (a "
                f"massless body at the end of a joint), the GIM is singular; give body {name} "
                "an <inertial> or fix the joint")
    return (f"moves {_carried(model, k)}, which have no inertia about its axis {axis} (their "
            "mass lies on the axis, without rotational inertia about it): the GIM is "
            f"singular; give body {name} a rotational inertia or fix the joint")
