"""Models to files: MJCF and URDF, so that a rope or a tree built here can be taken elsewhere.

:func:`to_mjcf` writes a model as MuJoCo's MJCF: one ``<body>`` per body, placed by its joint's
placement (``pos`` and ``xyaxes``: the rotation's first two columns, exact), its joint's
elementary axes as ``hinge`` and ``slide`` joints in order (MuJoCo composes a body's joints one
after the other, each axis in the frame the ones before it leave, as redysim does), a free joint
as ``<freejoint/>`` (the same q and v conventions), the inertia as ``<inertial>`` (mass, COM,
full tensor about the COM), gravity as ``<option gravity>``. No geometry, so no contacts; no
damping, armature or limits: the rigid-body problem redysim solves.

:func:`to_urdf` writes URDF: one ``<link>`` per body and one ``<joint>`` per elementary axis. A U
or S joint has several axes and URDF one per joint, so its axes but the last hang from massless
links (``<body>_axis<i>``); a free joint is left out (URDF has none that parsers agree on: load
the file with ``floating=True``, as :func:`redysim.load_model` offers). The placement is written
as ``xyz`` and ``rpy`` (roll-pitch-yaw, converted from the rotation to round-off).

Numbers are written with 17 significant digits, so a model read back (:func:`redysim.load_model`,
through MuJoCo's parser) has the same dynamics to round-off: ``tests/test_export.py`` checks
the GIM and qdd of exported models against the originals.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np

from .chain import Chain
from .model import BALL, FREE, Model

PRISMATIC = 1


def _num(x: float) -> str:
    return repr(float(x)) if x != 0 else "0"


def _vec(v) -> str:
    return " ".join(_num(x) for x in v)


def _as_model(system: Chain | Model) -> Model:
    if isinstance(system, Chain):
        return Model.from_chain(system)
    if not isinstance(system, Model):
        raise TypeError(f"export takes a redysim.Chain or redysim.Model, not "
                        f"{type(system).__name__}")
    return system


def _axes(model: Model, k: int) -> list[tuple[str, np.ndarray]]:
    """Joint k's elementary axes: ("hinge" | "slide", unit vector), the ball left out."""
    return [("slide" if model.dof_kind[j] == PRISMATIC else "hinge", model.dof_u[j])
            for j in range(model.joint_voff[k], model.joint_voff[k + 1])
            if model.dof_kind[j] != BALL]


def to_mjcf(system: Chain | Model) -> str:
    """The MJCF text of a chain or model (module docstring)."""
    model = _as_model(system)
    root = ET.Element("mujoco", model=model.name)
    ET.SubElement(root, "compiler", angle="radian", autolimits="true")
    ET.SubElement(root, "option", gravity=_vec(model.gravity))
    world = ET.SubElement(root, "worldbody")
    elements = []
    for k in range(model.n_bodies):
        parent = world if model.parent[k] < 0 else elements[model.parent[k]]
        R = model.placement_R[k]
        body = ET.SubElement(parent, "body", name=model.body_names[k],
                             pos=_vec(model.placement_p[k]), xyaxes=_vec([*R[:, 0], *R[:, 1]]))
        elements.append(body)
        if model.joint_types[k] == FREE:
            ET.SubElement(body, "freejoint", name=model.joint_names[k])
        else:
            axes = _axes(model, k)
            for i, (kind, u) in enumerate(axes):
                name = model.joint_names[k] + (f"_{i}" if len(axes) > 1 else "")
                ET.SubElement(body, "joint", name=name, type=kind, axis=_vec(u), pos="0 0 0")
        I = model.inertia_com[k]
        ET.SubElement(body, "inertial", pos=_vec(model.com[k]), mass=_num(model.mass[k]),
                      fullinertia=_vec([I[0, 0], I[1, 1], I[2, 2], I[0, 1], I[0, 2], I[1, 2]]))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"


def _rpy(R: np.ndarray) -> tuple[float, float, float]:
    """URDF's roll, pitch, yaw of R = Rz(yaw) Ry(pitch) Rx(roll)."""
    pitch = math.atan2(-R[2, 0], math.hypot(R[0, 0], R[1, 0]))
    if math.hypot(R[0, 0], R[1, 0]) < 1e-12:  # gimbal lock: yaw = 0
        return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0
    return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])


def to_urdf(system: Chain | Model) -> str:
    """The URDF text of a chain or model (module docstring)."""
    model = _as_model(system)
    root = ET.Element("robot", name=model.name)
    ET.SubElement(root, "link", name="world")

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

    def joint(name, kind, parent, child, xyz=(0, 0, 0), rpy=(0, 0, 0), axis=None):
        el = ET.SubElement(root, "joint", name=name, type=kind)
        ET.SubElement(el, "origin", xyz=_vec(xyz), rpy=_vec(rpy))
        ET.SubElement(el, "parent", link=parent)
        ET.SubElement(el, "child", link=child)
        if axis is not None:
            ET.SubElement(el, "axis", xyz=_vec(axis))

    for k in range(model.n_bodies):
        name = model.body_names[k]
        parent = "world" if model.parent[k] < 0 else model.body_names[model.parent[k]]
        xyz, rpy = model.placement_p[k], _rpy(model.placement_R[k])
        if model.joint_types[k] == FREE:  # the root of a floating model: load with floating
            link(name, k)
            continue
        axes = _axes(model, k)
        for i, (kind, u) in enumerate(axes):
            last = i == len(axes) - 1
            child = name if last else f"{name}_axis{i}"
            link(child, k if last else None)
            jname = model.joint_names[k] + (f"_{i}" if len(axes) > 1 else "")
            joint(jname, "prismatic" if kind == "slide" else "continuous", parent, child,
                  xyz if i == 0 else (0, 0, 0), rpy if i == 0 else (0, 0, 0), u)
            parent = child
    if FREE in model.joint_types:  # the free root is a link with no joint to the world
        root.remove(root.find("link[@name='world']"))
    ET.indent(root)
    return ET.tostring(root, encoding="unicode") + "\n"
