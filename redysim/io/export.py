"""Models to files: MJCF and URDF, so that a rope or a tree built here can be taken elsewhere.

Each writer either writes a file that reads back (:func:`redysim.load_model`, and MuJoCo itself
for MJCF) with the same GIM and qdd to round-off as functions of q, or refuses the model with an
:class:`ExportError` naming the body, link or joint, the value and what the format (or its
reader) cannot hold. ``tests/test_export.py`` checks both on every shipped case.

:func:`to_mjcf` writes MuJoCo's MJCF: nested ``<body>`` elements placed by ``pos`` and ``xyaxes``
(the rotation's first two columns), the joint's elementary axes as ``hinge`` and ``slide`` joints in
order, a ball joint as a ``ball`` joint at its anchor (its initial quaternion must be the identity:
MJCF's ball has no ``ref``), a free joint as ``<freejoint/>`` whose body's ``pos`` and ``quat`` are
the model's initial pose (:meth:`Model.initial`; MuJoCo's qpos0), the inertia as ``<inertial>``
(mass, COM, principal moments ``diaginertia`` and, unless the tensor is diagonal, their axes
``quat``: MuJoCo checks A + B >= C on principal moments strictly, so a lamina's, which round-off
may break by an ulp, get their largest set to the sum of the others), gravity as ``<option
gravity>``, a coupling (:attr:`Model.couplings`) as a joint ``<equality>`` of degree 1 (MuJoCo's
y - y0 = a0 + a1 (x - x0) about the joints' refs; solimp at MuJoCo's hardest), a joint's
armature (:attr:`Model.armature`) as its ``armature`` (a free joint's, when its six are one
number, on a ``<joint type="free">``; a ball's when its three are one number; else
refused), its damping, stiffness and spring_ref
(:attr:`Model.damping`, ...) as ``damping``, ``stiffness`` and ``springref``, a body's
:attr:`Model.gravcomp` as its ``gravcomp``. No geometry, so no contacts; no limits. MuJoCo
composes a body's joints one after the other, each about its own anchor ``pos`` and ``axis``,
fixed in the body's frame: body pose = P * prod_i [T(a_i) Rot(u_i, q_i - ref_i) T(-a_i)]. So:

- A massless body (mass 0, inertia 0) with exactly one child is merged into that child, which
  MuJoCo requires (a moving body needs mass): P1 J1(q1) P2 J2(q2) = (P1 P2) [Q^-1 J1(q1) Q]
  J2(q2) with Q = P2, i.e. joint 1 about the axis R2^T u1 through the anchor -R2^T p2 (a slide
  along R2^T u1); a chain of massless bodies likewise, each joint conjugated by the placements
  and joints that follow it. Its joints keep their names; the body, its name.
- A joint's initial value r (:attr:`Model.initial_q`, say from an MJCF ``ref``) is written as the
  joint's ``ref`` (qpos0), its motion J(r) folded into what comes before it, so that MuJoCo's qpos
  is the model's q.

Refused (:class:`ExportError`), because MuJoCo's compiler or reader refuses the file: a massless
body with no child or several children, or a massless free body; a merged body with more than 6
DOFs; a body with mass 0 but rotational inertia; a ball joint followed, within merged massless
bodies, by a rotated placement or a hinge (MuJoCo's ball turns the body's own axes: its qpos would
differ); a mass or principal moment below MuJoCo's ``mjMINVAL`` = 1e-15 (a point mass, a bar with no
radius); principal moments that break the triangle inequality A + B >= C (the paper's ``rod`` model)
by more than round-off; bodies nested deeper than :data:`MJCF_MAX_DEPTH` (MuJoCo's XML reader
refuses deeper elements); a body named ``world`` or repeated body or joint names.

:func:`to_urdf` writes URDF: one ``<link>`` per body and one ``<joint>`` per elementary axis from
the root link ``world``. A U or S joint has several axes and URDF one per joint, so its axes but
the last hang from massless links (``<body>_axis<i>``); a free joint is left out (URDF has none
that parsers agree on: load the file with ``floating=True``, as :func:`redysim.load_model` offers;
an XML comment in the file says so). A coupling is the follower's ``<mimic joint multiplier
offset>``. The placement is written as ``xyz`` and ``rpy`` (roll-pitch-yaw, converted from the
rotation to round-off). URDF carries no gravity and its readers assume (0, 0, -9.81): a model whose
gravity points elsewhere is turned, by the rotation that takes its gravity's direction to -z, in
the origins of the joints from ``world`` (an XML comment says which); the dynamics as functions of
q are unchanged. Refused: a gravity whose magnitude is not 9.81 m/s^2 (zero included), a floating
model whose gravity is not along -z (turning the world would change its free joint's coordinates),
a floating model with another root, a body named ``world`` (URDF readers take a link of that name
as the world itself), repeated link or joint names, and armature (:attr:`Model.armature`: URDF has
no field for a joint's own inertia), joint springs and gravity compensation (no field either; a
joint's damping is its ``<dynamics damping>``, a free joint's refused as the free joint is left
out) and a ball joint (URDF has none). URDF holds no initial configuration: a model's
:attr:`Model.initial_q` is said in an XML comment only. A prismatic joint gets the ``<limit>`` the
URDF specification requires of it (urdfdom, the reader of Pinocchio and ROS, refuses the file
without one), written wide (:data:`URDF_WIDE_LIMIT`: +-1e9 m, and effort and velocity 1e9), never
reached, and said so in an XML comment; a model holds no joint limits (the importers announce the
ones they drop), so none is lost. Revolute axes are ``continuous``, which takes none. Every file is
read by urdfdom (Pinocchio's ``buildModelFromXML``) and redysim's own reader with the model's
dynamics, and by MuJoCo's URDF reader unless it has a U or S joint, whose massless links between
axes MuJoCo's compiler refuses (export to MJCF for MuJoCo: :func:`to_mjcf` merges them), or a body
MuJoCo's compiler refuses in any format: the ones :func:`to_mjcf` refuses by name (a moving body's
mass or principal moment below ``mjMINVAL``, moments breaking A + B >= C; the PUMA 560 of the talk,
whose waist has no mass, is one). URDF holds them, and urdfdom and redysim read them
(``tests/test_export.py``); the file then says so in an XML comment, with to_mjcf's reason for each
such body.

Numbers are written as Python's shortest exact ``repr`` (at most 17 significant digits); the XML
is written without recursion, so a model of any depth is written (or refused) at once.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Any
from xml.sax.saxutils import escape

import numpy as np

from redysim.errors import FieldError
from redysim.io.importers import URDF_GRAVITY
from redysim.model import door
from redysim.model.parts import KIND_CODES
from redysim.model.tree import BALL, BALL_JOINT, FREE, Model, joint_transform

PRISMATIC = KIND_CODES["P"]
MJMINVAL = 1e-15  # MuJoCo's mjMINVAL: the least mass and principal moment of a moving body
# Bodies MuJoCo's XML reader takes nested in one another, as this module writes them (mujoco >
# worldbody > body^n > inertial): tinyxml2 refuses an element nested 500 deep
# (TINYXML2_MAX_ELEMENT_DEPTH, "XML_ELEMENT_DEPTH_EXCEEDED"); measured with mujoco 4.0.0: 496
# nested bodies load, 497 do not (tests/test_export.py checks both sides).
MJCF_MAX_DEPTH = 496
MJCF_MAX_DOFS = 6  # DOFs MuJoCo's compiler takes in one body
MJCF_HARD_SOLIMP = "0.9999 0.9999 0.001 0.5 2"  # a coupling's equality: MuJoCo's hardest
TRIANGLE_RTOL = 1e-12  # a principal moment above the sum of the others by round-off (a lamina)
GRAVITY_RTOL = 1e-14  # |g| = 9.81 to round-off, for URDF
URDF_ROOT = "world"
# A prismatic joint's <limit>, which the URDF specification requires (urdfdom, Pinocchio's reader,
# refuses the joint without one) and a Model does not hold: written wide, never reached (lower
# and upper in metres, effort in newtons, velocity in m/s), and said so in the file
URDF_WIDE_LIMIT = 1e9


class ExportError(FieldError):
    """A model the format (or its reader) cannot hold: ``to_mjcf: body 'b'.mass = 0.0: <why>``.
    ``source`` is ``to_mjcf`` or ``to_urdf``, ``field`` names the body, link or joint."""


# --------------------------------------------------------------------------- helpers
def _num(x: float) -> str:
    return repr(float(x)) if x != 0 else "0"


def _vec(v) -> str:
    return " ".join(_num(x) for x in v)


def _plain(v):
    """A value for a message: a float or a tuple of floats (no numpy reprs)."""
    a = np.asarray(v, dtype=float)
    return float(a) if a.ndim == 0 else tuple(float(x) for x in a.ravel())


def _as_model(model: Model, source: str = "export") -> Model:
    door.require_model(model, source)  # ModelTypeError (a TypeError) naming what was given
    if model.cuts:
        raise ExportError(source, "cuts", [c.name for c in model.cuts],
                          "a closed mechanism: the exporters write trees, and would drop its "
                          "cut joints; export the open tree (model.with_cuts(()))")
    if model.gravcomp_loads.shape[0]:
        k = int(model.gravcomp_loads[0, 0])
        raise ExportError(source, f"body {model.body_names[k]!r}.gravcomp_loads",
                          _plain(model.gravcomp_loads[0]), "a body fused from parts whose "
                          "gravity compensation fractions differ (each held at its part's "
                          "centre of mass): a file's body holds one fraction, and the exporters "
                          "write the fused body; export model.without_passive(), or give the "
                          "parts one fraction")
    return model


def _axes(model: Model, k: int) -> list[tuple[str, np.ndarray, int]]:
    """Joint k's elementary axes: ("hinge" | "slide", unit vector, velocity index), the free
    joint's ball left out."""
    return [("slide" if model.dof_kind[j] == PRISMATIC else "hinge", model.dof_u[j], int(j))
            for j in range(model.joint_voff[k], model.joint_voff[k + 1])
            if model.dof_kind[j] != BALL]


def _axis_names(model: Model, k: int) -> list[str]:
    """The file's name of each elementary axis of joint k: the joint's own name for one axis (or
    a free or ball joint), ``<joint>_<i>`` for a U or S joint's."""
    n = int(model.joint_voff[k + 1] - model.joint_voff[k])
    name = model.joint_names[k]
    return [name] if n == 1 or model.joint_types[k] in (FREE, BALL_JOINT) else \
        [f"{name}_{i}" for i in range(n)]


def _joint_names(model: Model, free: bool = True) -> list[tuple[str, str]]:
    """(name in the file, what it names) of every joint the file writes: a hinge or slide per
    elementary axis, and (``free``) the free joints."""
    out = []
    for k, jn in enumerate(model.joint_names):
        if model.joint_types[k] == FREE and not free:
            continue
        names = _axis_names(model, k)
        out += [(n, f"joint {jn!r}" if len(names) == 1 else f"axis {i} of joint {jn!r}")
                for i, n in enumerate(names)]
    return out


def _children(model: Model) -> list[list[int]]:
    children: list[list[int]] = [[] for _ in range(model.n_bodies)]
    for k in range(model.n_bodies):
        if model.parent[k] >= 0:
            children[model.parent[k]].append(k)
    return children


def _unique(source: str, what: str, names: list[tuple[str, str]]) -> None:
    """Refuse a name given twice. ``names``: (name, where it comes from)."""
    seen: dict[str, str] = {}
    for name, origin in names:
        if name in seen:
            raise ExportError(source, f"{what} {name!r}", None,
                              f"the name is given twice ({seen[name]}; {origin}): the file's "
                              f"{what}s need distinct names; rename one")
        seen[name] = origin


_ATTR = {'"': "&quot;", "\n": "&#10;", "\r": "&#13;", "\t": "&#9;"}  # escaped in attributes


def _xml(root: ET.Element) -> str:
    """The text of an element tree, indented by two spaces, written with a stack rather than
    recursion (ElementTree's writer recurses once per level: 1,000 nested bodies overflow)."""
    out = []
    stack: list[tuple[ET.Element, int, bool]] = [(root, 0, False)]
    while stack:
        el, depth, closing = stack.pop()
        pad = "  " * depth
        if closing:
            out.append(f"{pad}</{el.tag}>")
        elif el.tag is ET.Comment:
            out.append(f"{pad}<!-- {el.text} -->")
        else:
            attrs = "".join(f' {key}="{escape(str(value), _ATTR)}"'
                            for key, value in el.attrib.items())
            if len(el):
                out.append(f"{pad}<{el.tag}{attrs}>")
                stack.append((el, depth, True))
                stack.extend((child, depth + 1, False) for child in reversed(el))
            else:
                out.append(f"{pad}<{el.tag}{attrs} />")
    return "\n".join(out) + "\n"


def _compose(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray]
             ) -> tuple[np.ndarray, np.ndarray]:
    """The transform a * b of two (R, p)."""
    return a[0] @ b[0], a[0] @ b[1] + a[1]


def _quaternion(R: np.ndarray) -> np.ndarray:
    """The unit quaternion (w, x, y, z) of a rotation."""
    from scipy.spatial.transform import Rotation

    x, y, z, w = Rotation.from_matrix(R).as_quat()
    return np.array([w, x, y, z])


# --------------------------------------------------------------------------- MJCF
def _mujoco_refuses(source: str, model: Model) -> list[str]:
    """What MuJoCo's compiler refuses of the model's bodies, whatever the format, as
    :func:`to_mjcf` refuses it (:func:`_mjcf_inertial`), one ``field = value: problem`` each;
    a massless body (no mass, no inertia) is left out (to_mjcf merges it into its child)."""
    said = []
    for k in range(model.n_bodies):
        if model.mass[k] == 0 and not np.any(model.inertia_com[k]):
            continue
        try:
            _mjcf_inertial(source, model, k)
        except ExportError as exc:  # (an XML comment may not hold "--")
            said.append(f"{exc.field} = {_plain(exc.value)}: {exc.problem}".replace("--", "- -"))
    return said


def _mjcf_inertial(source: str, model: Model, k: int) -> dict[str, str]:
    """The ``<inertial>`` attributes of body k, or ExportError when MuJoCo's compiler would
    refuse them: mass or a principal moment below mjMINVAL, or the triangle inequality broken
    by more than round-off (then no MJCF body holds the inertia: MuJoCo's ``balanceinertia``
    would change it)."""
    name, m, I = model.body_names[k], float(model.mass[k]), model.inertia_com[k]
    where = f"body {name!r}"
    if m < MJMINVAL:
        what = f"a body with mass {m}"
        if np.any(I):
            what += (f" but rotational inertia (principal moments "
                     f"{_plain(np.linalg.eigvalsh(I))} kg m^2), which no MJCF body holds")
        raise ExportError(source, f"{where}.mass", m,
                          f"{what}: MuJoCo's compiler refuses a moving body whose mass is below "
                          f"mjMINVAL = {MJMINVAL} ('mass and inertia of moving bodies must be "
                          "larger than mjMINVAL'); give the body a mass or export to URDF, "
                          "which holds it")
    diagonal = not np.any(I - np.diag(np.diag(I)))
    if diagonal:
        moments, V = np.diag(I).copy(), np.eye(3)
    else:
        moments, V = np.linalg.eigh(I)
        if np.linalg.det(V) < 0:
            V[:, 0] = -V[:, 0]
    small = int(np.argmin(moments))
    if moments[small] < MJMINVAL:
        raise ExportError(source, f"{where}.inertia", _plain(moments),
                          f"principal moment {float(moments[small])} kg m^2 about the body's "
                          f"axis {_plain(V[:, small])}: MuJoCo's compiler refuses a moving body "
                          f"whose principal moments are not all >= mjMINVAL = {MJMINVAL} ('mass "
                          "and inertia of moving bodies must be larger than mjMINVAL'): a point "
                          "mass, or a bar with no radius; give the body a rigid body's inertia "
                          "(a bar of some radius: a cylinder) or export to URDF, which holds it")
    big = int(np.argmax(moments))
    rest = [moments[i] for i in range(3) if i != big]
    if moments[big] > rest[0] + rest[1]:
        if moments[big] - (rest[0] + rest[1]) > TRIANGLE_RTOL * moments[big]:
            labels = ("Ixx", "Iyy", "Izz") if diagonal else ("I1", "I2", "I3")
            others = [labels[i] for i in range(3) if i != big]
            raise ExportError(
                source, f"{where}.inertia", _plain(moments),
                f"principal moments ({', '.join(labels)}) break the triangle inequality "
                f"{others[0]} + {others[1]} >= {labels[big]} ({float(rest[0] + rest[1]):.6g} < "
                f"{float(moments[big]):.6g}), which MuJoCo's compiler refuses ('inertia must "
                "satisfy A + B >= C'; its balanceinertia would change the inertia): not a rigid "
                "body's inertia, such as the paper's rod model (Ixx = m r^2/2 > Iyy + Izz = "
                "m l^2/6 when l < sqrt(3) r); use the cylinder model (inertia = 'cylinder') or "
                "export to URDF, which holds it")
        moments[big] = rest[0] + rest[1]  # round-off of a lamina: MuJoCo's check is strict
    attrs = {"pos": _vec(model.com[k]), "mass": _num(m), "diaginertia": _vec(moments)}
    if not diagonal:
        attrs["quat"] = _vec(_quaternion(V))
    return attrs


def _mjcf_groups(source: str, model: Model) -> list[list[int]]:
    """Model bodies -> MJCF bodies: each a list of model bodies, massless ones (mass and inertia
    0, one child) first, the body that carries them last; parents before children."""
    children = _children(model)
    massless = [model.mass[k] == 0 and not np.any(model.inertia_com[k])
                for k in range(model.n_bodies)]
    groups: list[list[int]] = []
    pending: dict[int, list[int]] = {}  # child -> the massless bodies to merge into it
    for k in range(model.n_bodies):
        group = pending.pop(k, []) + [k]
        if not massless[k]:
            groups.append(group)
            continue
        where = f"body {model.body_names[k]!r}"
        why = ("MuJoCo refuses a moving body without mass ('mass and inertia of moving bodies "
               "must be larger than mjMINVAL')")
        if model.joint_types[k] == FREE:
            raise ExportError(source, f"{where}.mass", 0.0,
                              f"a massless free body: {why}, and its child's joints cannot join "
                              "the free joint's 6 DOFs in one body (MuJoCo: 'more than 6 dofs "
                              "in body')")
        if len(children[k]) != 1:
            names = ", ".join(repr(model.body_names[c]) for c in children[k]) or "none"
            raise ExportError(source, f"{where}.mass", 0.0,
                              f"a massless body with {len(children[k])} children ({names}): "
                              f"{why}; only a massless body with exactly one child can be "
                              "merged into it (one MJCF body with several joints)")
        pending[children[k][0]] = group
    return groups


def _mjcf_body(model: Model, group: list[int], q0: np.ndarray):
    """(pose (R, p), joints [(type, name, axis, anchor, ref)]) of the MJCF body of ``group``:
    the placements and joint motions P1 J1 P2 J2 ... in the last body's frame (module
    docstring), each joint's initial value folded in front of it."""
    # X_0, axis 1, X_1, axis 2, ...: placements and elementary axes in order
    factors: list[list[Any]] = []
    for k in group:
        factors.append(["X", (model.placement_R[k], model.placement_p[k])])
        if model.joint_types[k] == BALL_JOINT:  # about its anchor, in the body's own frame
            factors.append(["J", "ball", None, model.joint_names[k], 0.0])
            factors.append(["X", (np.eye(3), np.zeros(3))])
            continue
        for (kind, u, j), name in zip(_axes(model, k), _axis_names(model, k), strict=True):
            r = float(q0[j + model.joint_qoff[k] - model.joint_voff[k]])
            factors.append(["J", kind, u, name, r])
            if r:  # J(q) = J(r) J(q - r): fold J(r) into the transform before it
                code = PRISMATIC if kind == "slide" else KIND_CODES["R"]
                Jr = joint_transform([(code, u)], [r])
                last_x = next(f for f in reversed(factors) if f[0] == "X")
                last_x[1] = _compose(last_x[1], Jr)
            factors.append(["X", (np.eye(3), np.zeros(3))])
    suffix = (np.eye(3), np.zeros(3))  # Q_i: the transforms after axis i
    joints: list[tuple[str, str, np.ndarray | None, np.ndarray, float]] = []
    for f in reversed(factors):
        if f[0] == "X":
            suffix = _compose(f[1], suffix)
            continue
        _, kind, u, name, r = f
        RQ, pQ = suffix
        anchor = -RQ.T @ pQ if kind != "slide" else np.zeros(3)
        if kind == "ball":
            # Q^-1 J(q) Q is a ball whose quaternion is not q; and MuJoCo's compiler refuses a
            # rotation after a ball in one body ("ball followed by rotation")
            if np.any(RQ != np.eye(3)) or any(j[0] != "slide" for j in joints):
                raise ExportError("to_mjcf", f"joint {name!r}", None, "a ball joint followed, "
                                  "in the massless bodies merged into one MJCF body, by a "
                                  "rotated placement, a hinge or a ball: MuJoCo turns a ball "
                                  "about the body's own axes (its qpos would not be the "
                                  "model's q) and refuses a rotation after a ball in one body; "
                                  "give the massless body a mass")
            joints.append((kind, name, None, anchor, r))
            continue
        joints.append((kind, name, RQ.T @ u, anchor, r))
    return suffix, joints[::-1]


def to_mjcf(model: Model) -> str:
    """The MJCF text of a chain or model (module docstring).

    Raises ExportError naming the body or joint that MJCF (MuJoCo's compiler or XML reader)
    cannot hold, ModelTypeError (a TypeError) for anything but a Model.
    """
    source = "to_mjcf"
    model = _as_model(model, source)
    if URDF_ROOT in model.body_names:
        raise ExportError(source, f"body {URDF_ROOT!r}", None,
                          "MuJoCo's world body is named 'world', and its compiler refuses a "
                          "body of the same name ('repeated name'); rename the body")
    groups = _mjcf_groups(source, model)
    _unique(source, "body", [(model.body_names[g[-1]], "a body") for g in groups])
    _unique(source, "joint", _joint_names(model))
    q0 = model.initial()
    for g in groups:
        dofs = [(n, k) for k in g for n in _axis_names(model, k)]
        n_dofs = sum(int(model.joint_voff[k + 1] - model.joint_voff[k]) for k in g)
        if n_dofs > MJCF_MAX_DOFS:
            merged = ", ".join(repr(model.body_names[k]) for k in g[:-1])
            raise ExportError(source, f"body {model.body_names[g[-1]]!r}", None,
                              f"would carry {n_dofs} DOFs: the massless bodies {merged} "
                              "merged into it (MuJoCo "
                              f"refuses a moving body without mass) bring joints "
                              f"{', '.join(repr(n) for n, _ in dofs)}, and MuJoCo's compiler "
                              f"refuses more than {MJCF_MAX_DOFS} DOFs in one body ('more than "
                              "6 dofs in body'); give a massless body a mass")
    inertials = [_mjcf_inertial(source, model, g[-1]) for g in groups]
    group_of = {g[-1]: i for i, g in enumerate(groups)}  # a group's parent is a carrier body
    depth: list[int] = []
    for g in groups:
        p = model.parent[g[0]]
        depth.append(1 if p < 0 else depth[group_of[int(p)]] + 1)
        if depth[-1] > MJCF_MAX_DEPTH:
            raise ExportError(source, f"body {model.body_names[g[-1]]!r}", None,
                              f"nested {depth[-1]} bodies deep: MuJoCo's XML reader refuses "
                              f"bodies nested more than {MJCF_MAX_DEPTH} deep ('Element nesting "
                              "is too deep'; tinyxml2's element depth limit of 500, measured "
                              "with mujoco 4.0); export to URDF, which is flat")

    armature = {name: float(model.armature[j]) for k in range(model.n_bodies)
                if model.joint_types[k] not in (FREE, BALL_JOINT)
                for (_, _, j), name in zip(_axes(model, k), _axis_names(model, k), strict=True)}
    per_axis = {key: {name: float(getattr(model, key)[j]) for k in range(model.n_bodies)
                      if model.joint_types[k] not in (FREE, BALL_JOINT)
                      for (_, _, j), name in zip(_axes(model, k), _axis_names(model, k),
                                                 strict=True)}
                for key in ("damping", "stiffness", "spring_ref")}
    for k in range(model.n_bodies):
        for key in ("armature", "damping"):
            a = getattr(model, key)[model.joint_voff[k]:model.joint_voff[k + 1]]
            if model.joint_types[k] in (FREE, BALL_JOINT) and np.any(a != a[0]):
                raise ExportError(source, f"joint {model.joint_names[k]!r}.{key}", _plain(a),
                                  f"MJCF gives a {model.joint_types[k]} joint one {key} for its "
                                  f"{a.shape[0]} DOFs")
        if model.joint_types[k] == BALL_JOINT:
            v0, name = int(model.joint_voff[k]), model.joint_names[k]
            armature[name] = float(model.armature[v0])
            per_axis["damping"][name] = float(model.damping[v0])
            per_axis["stiffness"][name] = per_axis["spring_ref"][name] = 0.0  # (none: Model)
            qs = int(model.joint_qoff[k])
            if np.any(q0[qs:qs + 4] / np.linalg.norm(q0[qs:qs + 4]) != (1.0, 0.0, 0.0, 0.0)):
                raise ExportError(source, f"joint {model.joint_names[k]!r}", _plain(q0[qs:qs + 4]),
                                  "an initial quaternion (Model.initial) other than the "
                                  "identity: MJCF's ball joint has no ref (its qpos0 is the "
                                  "identity), so the file would hold another q")
    root = ET.Element("mujoco", model=model.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(root, "option", gravity=_vec(model.gravity))
    world = ET.SubElement(root, "worldbody")
    elements: list[ET.Element] = []
    for i, g in enumerate(groups):
        k = g[-1]
        p = model.parent[g[0]]
        parent = world if p < 0 else elements[group_of[int(p)]]
        if model.joint_types[k] == FREE:  # its pose is q: the initial one is MuJoCo's qpos0
            qs = model.joint_qoff[k]
            quat = q0[qs + 3:qs + 7] / np.linalg.norm(q0[qs + 3:qs + 7])
            body = ET.SubElement(parent, "body", name=model.body_names[k],
                                 pos=_vec(q0[qs:qs + 3]), quat=_vec(quat))
            free_armature = float(model.armature[model.joint_voff[k]])
            free_damping = float(model.damping[model.joint_voff[k]])
            if free_armature or free_damping:
                ET.SubElement(body, "joint", name=model.joint_names[k], type="free",
                              armature=_num(free_armature), damping=_num(free_damping))
            else:
                ET.SubElement(body, "freejoint", name=model.joint_names[k])
        else:
            (R, pos), joints = _mjcf_body(model, g, q0)
            body = ET.SubElement(parent, "body", name=model.body_names[k], pos=_vec(pos),
                                 xyaxes=_vec([*R[:, 0], *R[:, 1]]))
            for kind, name, axis, anchor, ref in joints:
                attrs = {"name": name, "type": kind, "pos": _vec(anchor)}
                if axis is not None:  # (a ball has none)
                    attrs["axis"] = _vec(axis)
                if ref:
                    attrs["ref"] = _num(ref)
                if armature[name]:
                    attrs["armature"] = _num(armature[name])
                if per_axis["damping"][name]:
                    attrs["damping"] = _num(per_axis["damping"][name])
                if per_axis["stiffness"][name]:  # springref in qpos, which is q
                    attrs["stiffness"] = _num(per_axis["stiffness"][name])
                    attrs["springref"] = _num(per_axis["spring_ref"][name])
                ET.SubElement(body, "joint", attrs)
        if model.gravcomp[k]:
            body.set("gravcomp", _num(model.gravcomp[k]))
        ET.SubElement(body, "inertial", inertials[i])
        elements.append(body)
    if model.couplings:  # MuJoCo's y - y0 = a0 + a1 (x - x0), y0 and x0 the joints' refs
        eq = ET.SubElement(root, "equality")
        fq, lq, _, _, m, off = model.coupling_index
        for c, f, ld, mult, o in zip(model.couplings, fq, lq, m, off, strict=True):
            a0 = o - q0[f] + mult * q0[ld]
            ET.SubElement(eq, "joint", joint1=c.follower, joint2=c.leader,
                          polycoef=f"{_num(a0)} {_num(mult)} 0 0 0", solimp=MJCF_HARD_SOLIMP)
    return _xml(root)


# --------------------------------------------------------------------------- URDF
def _rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF's roll, pitch, yaw of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if math.hypot(R[0, 0], R[1, 0]) < 1e-12:  # gimbal lock: yaw = 0
        return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def _turn_to_minus_z(g_hat: np.ndarray) -> np.ndarray:
    """A rotation taking the unit vector g_hat to (0, 0, -1): Rodrigues' least rotation, after
    half a turn about x when g_hat points up (so that 1 + cos never nears 0). Exact for the
    coordinate axes: -y turns by a quarter turn about x, +z by half a turn."""
    flip = np.diag([1.0, -1.0, -1.0]) if g_hat[2] > 0 else np.eye(3)
    g_hat = flip @ g_hat
    c = -float(g_hat[2])  # cos of the angle to -z, >= 0
    v = np.array([-g_hat[1], g_hat[0], 0.0])  # g_hat x (0, 0, -1)
    V = np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])
    return (np.eye(3) + V + V @ V / (1.0 + c)) @ flip


def _urdf_turn(source: str, model: Model) -> np.ndarray | None:
    """The rotation of the world that puts the model's gravity along -z (None: it is), or
    ExportError when URDF cannot hold the gravity."""
    g = np.asarray(model.gravity, dtype=float)
    norm, assumed = float(np.linalg.norm(g)), float(np.linalg.norm(URDF_GRAVITY))
    if abs(norm - assumed) > GRAVITY_RTOL * assumed:
        raise ExportError(source, "gravity", _plain(g),
                          f"magnitude {norm} m/s^2: URDF carries no gravity and its readers "
                          f"assume {URDF_GRAVITY}, so a model read back would fall at "
                          f"{assumed}; export to MJCF, which holds any gravity")
    if g[0] == 0 and g[1] == 0 and g[2] < 0:
        return None
    free = [k for k, t in enumerate(model.joint_types) if t == FREE]
    if free:
        raise ExportError(source, f"joint {model.joint_names[free[0]]!r}", None,
                          f"a floating model whose gravity {_plain(g)} is not along -z: URDF "
                          "carries no gravity (readers assume -z), and turning the world to put "
                          "it there would change this free joint's coordinates (its world "
                          "position and orientation); export to MJCF, which holds any gravity")
    return _turn_to_minus_z(g / norm)


def to_urdf(model: Model) -> str:
    """The URDF text of a chain or model (module docstring).

    Raises ExportError naming what URDF (or its readers) cannot hold, ModelTypeError (a
    TypeError) for anything but a Model.
    """
    source = "to_urdf"
    model = _as_model(model, source)
    if np.any(model.armature):
        j = int(np.flatnonzero(model.armature)[0])
        k = int(np.searchsorted(model.joint_voff, j, side="right") - 1)
        raise ExportError(source, f"joint {model.joint_names[k]!r}.armature",
                          float(model.armature[j]), "URDF has no field for a joint's own "
                          "inertia (armature); export to MJCF, which has one")
    for key, what in (("stiffness", "a joint spring"), ("gravcomp", "gravity compensation")):
        if np.any(getattr(model, key)):
            i = int(np.flatnonzero(getattr(model, key))[0])
            k = i if key == "gravcomp" else \
                int(np.searchsorted(model.joint_voff, i, side="right") - 1)
            where = f"body {model.body_names[k]!r}" if key == "gravcomp" else \
                f"joint {model.joint_names[k]!r}"
            raise ExportError(source, f"{where}.{key}", float(getattr(model, key)[i]),
                              f"URDF has no field for {what}; export to MJCF, which has one")
    for k, t in enumerate(model.joint_types):
        if t == FREE and np.any(model.damping[model.joint_voff[k]:model.joint_voff[k + 1]]):
            raise ExportError(source, f"joint {model.joint_names[k]!r}.damping",
                              _plain(model.damping[model.joint_voff[k]:
                                                   model.joint_voff[k + 1]]),
                              "URDF leaves the free joint out (load with floating=True), and "
                              "its damping with it; export to MJCF, which holds it")
    balls = [k for k, t in enumerate(model.joint_types) if t == BALL_JOINT]
    if balls:
        raise ExportError(source, f"joint {model.joint_names[balls[0]]!r}.type", BALL_JOINT,
                          "URDF has no ball (spherical) joint, and three revolute joints in "
                          "its place would have other coordinates than its quaternion; export "
                          "to MJCF, which has one")
    free = [k for k, t in enumerate(model.joint_types) if t == FREE]
    roots = [k for k in range(model.n_bodies) if model.parent[k] < 0]
    if free and len(roots) > 1:
        other = next(k for k in roots if k != free[0])
        raise ExportError(source, f"body {model.body_names[other]!r}", None,
                          f"a second root beside the free body {model.body_names[free[0]]!r}: "
                          "a floating URDF has one root link, the free one (URDF has no free "
                          "joint: readers make the root float)")
    links = []
    for k in range(model.n_bodies):
        links.append((model.body_names[k], "a body"))
        if model.joint_types[k] != FREE:
            links += [(f"{model.body_names[k]}_axis{i}", f"the link after axis {i} of joint "
                       f"{model.joint_names[k]!r}") for i in range(len(_axes(model, k)) - 1)]
    if URDF_ROOT in model.body_names:
        raise ExportError(source, f"body {URDF_ROOT!r}", None,
                          "URDF readers (MuJoCo's parser, Gazebo) take a link named 'world' as "
                          "the fixed world itself, so this body would not move; rename it")
    _unique(source, "link", links)
    _unique(source, "joint", _joint_names(model, free=False))
    turn = _urdf_turn(source, model)

    root = ET.Element("robot", name=model.name)
    if turn is not None:
        root.append(ET.Comment(
            f"The model's gravity {_plain(model.gravity)} is turned to {URDF_GRAVITY}, the "
            "gravity URDF readers assume, by the world rotation R (rows: "
            f"{'; '.join(_vec(row) for row in turn)}), written into the origins of the joints "
            f"from '{URDF_ROOT}'; the dynamics in the joint coordinates are the model's."))
    if model.initial_q is not None and np.any(model.initial_q != model.neutral()):
        root.append(ET.Comment(
            "URDF holds no initial configuration; the model's (initial_q): "
            f"{_vec(model.initial_q)}"))
    if any(kind == "slide" for k in range(model.n_bodies) if model.joint_types[k] != FREE
           for kind, _, _ in _axes(model, k)):
        root.append(ET.Comment(
            "URDF requires a <limit> on a prismatic joint and the model has no joint limits: "
            f"each is written wide (lower {_num(-URDF_WIDE_LIMIT)}, upper "
            f"{_num(URDF_WIDE_LIMIT)} m, effort {_num(URDF_WIDE_LIMIT)} N, velocity "
            f"{_num(URDF_WIDE_LIMIT)} m/s), never reached: the motion is the model's."))
    if free:  # (read back without being told, every reader fixes the root: said in the file)
        root.append(ET.Comment(
            f"A floating model: its root link {model.body_names[free[0]]!r} moves freely (the "
            f"free joint {model.joint_names[free[0]]!r}, 7 q and 6 v), which URDF does not "
            "write: load it floating, redysim.load_model(path, floating=True), Pinocchio's "
            "buildModelFromUrdf(path, pinocchio.JointModelFreeFlyer()); read without that, "
            "every reader fixes the root to the world."))
    mujoco_refuses = _mujoco_refuses(source, model)
    if mujoco_refuses:
        root.append(ET.Comment(
            "MuJoCo's compiler refuses this file, in any format (to_mjcf refuses the same by "
            "name): " + "; ".join(mujoco_refuses) + ". URDF holds it: urdfdom (Pinocchio, ROS) "
            "and redysim read it with the model's dynamics."))
    if not free:
        ET.SubElement(root, "link", name=URDF_ROOT)

    def link(name, k=None):
        el = ET.SubElement(root, "link", name=name)
        if k is not None:
            inertial = ET.SubElement(el, "inertial")
            ET.SubElement(inertial, "origin", xyz=_vec(model.com[k]), rpy="0 0 0")
            ET.SubElement(inertial, "mass", value=_num(model.mass[k]))
            I = model.inertia_com[k]
            ET.SubElement(inertial, "inertia", ixx=_num(I[0, 0]), ixy=_num(I[0, 1]),
                          ixz=_num(I[0, 2]), iyy=_num(I[1, 1]), iyz=_num(I[1, 2]),
                          izz=_num(I[2, 2]))

    mimics = {c.follower: c for c in model.couplings}

    def joint(name, kind, parent, child, xyz, R, axis, damping=0.0):
        el = ET.SubElement(root, "joint", name=name, type=kind)
        ET.SubElement(el, "origin", xyz=_vec(xyz), rpy=_vec(_rpy(R)))
        ET.SubElement(el, "parent", link=parent)
        ET.SubElement(el, "child", link=child)
        ET.SubElement(el, "axis", xyz=_vec(axis))
        if kind == "prismatic":  # required by URDF; the model has none: wide (URDF_WIDE_LIMIT)
            ET.SubElement(el, "limit", lower=_num(-URDF_WIDE_LIMIT), upper=_num(URDF_WIDE_LIMIT),
                          effort=_num(URDF_WIDE_LIMIT), velocity=_num(URDF_WIDE_LIMIT))
        if damping:
            ET.SubElement(el, "dynamics", damping=_num(damping))
        if name in mimics:  # a coupling: q = multiplier q_joint + offset
            c = mimics[name]
            ET.SubElement(el, "mimic", joint=c.leader, multiplier=_num(c.multiplier),
                          offset=_num(c.offset))

    for k in range(model.n_bodies):
        name = model.body_names[k]
        if model.joint_types[k] == FREE:  # the root of a floating model: load with floating
            link(name, k)
            continue
        R, xyz = model.placement_R[k], model.placement_p[k]
        if model.parent[k] < 0:
            parent = URDF_ROOT
            if turn is not None:
                R, xyz = turn @ R, turn @ xyz
        else:
            parent = model.body_names[model.parent[k]]
        axes = _axes(model, k)
        for i, ((kind, u, j), jname) in enumerate(zip(axes, _axis_names(model, k),
                                                      strict=True)):
            last = i == len(axes) - 1
            child = name if last else f"{name}_axis{i}"
            link(child, k if last else None)
            joint(jname, "prismatic" if kind == "slide" else "continuous", parent, child,
                  xyz if i == 0 else (0, 0, 0), R if i == 0 else np.eye(3), u,
                  float(model.damping[j]))
            parent = child
    return _xml(root)
