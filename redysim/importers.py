"""Models from files: URDF and MJCF read by MuJoCo's parser, case files by redysim's.

:func:`load_model` turns a ``.urdf``, an MJCF ``.xml`` or a case ``.toml`` into a
:class:`~redysim.model.Model`. URDF and MJCF are read by MuJoCo's own parser (``mujoco.MjSpec``,
the one MuJoCo compiles its models from; the ``models`` extra installs it): a URDF is taken as
written, before MuJoCo's compiler touches it (its compiler would refuse or rebalance inertias
that real robot files carry, such as a triangle inequality broken by rounding); an MJCF model
is compiled first, because MuJoCo's meaning of one depends on its compiler (inertias from
geometry, default classes, angles in degrees). Only the tree's kinematics and inertias are kept;
what is dropped is listed in :attr:`Model.notes` (visual and collision geometry, joint limits,
damping, friction, actuators, sensors). What the tree cannot hold is refused with a
:class:`ModelFileError` naming the file, the element and the attribute: a mimic joint, a planar
joint, a kinematic loop (a link that is the child of two joints), a free joint below the base, a
body without the inertia its joint needs to move (a massless leaf: the GIM would be singular).
"""

from __future__ import annotations

import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from .errors import FieldError
from .model import FIXED, FREE, Body, Model, TreeJoint, drop_world_fixed
from .rbda import quaternion_matrix

URDF_GRAVITY = (0.0, 0.0, -9.81)  # URDF has no gravity; robots are described z up


class ModelFileError(FieldError):
    """A URDF or MJCF file the importer cannot take: ``<file>: <element>.<attribute> = <value>:
    <what is wrong>``."""


def _mujoco(path):
    try:
        import mujoco
    except ImportError as exc:
        raise ModelFileError(str(path), "<file>", None, "reading URDF and MJCF needs MuJoCo's "
                             "parser: pip install 'redysim[models]' (" + str(exc) + ")") from None
    return mujoco


def _quat_matrix(q) -> np.ndarray:
    """The rotation of a quaternion (w, x, y, z) as MuJoCo stores it (normalised here)."""
    q = np.asarray(q, dtype=float)
    return quaternion_matrix(*(q / np.linalg.norm(q)))


# --------------------------------------------------------------------------- URDF
# elements the tree does not hold: dropped before MuJoCo's parser sees them (it would look for
# the meshes of visual and collision geometry, and warn about limits it cannot use)
DROPPED = ("visual", "collision", "limit", "dynamics", "safety_controller", "calibration",
           "transmission", "gazebo")
MIMIC = ("refuse", "independent")


def _check_urdf(path: Path, mimic: str = "refuse") -> tuple[ET.Element, list[str]]:
    """Parse the XML, refuse what the tree cannot hold, and drop what it does not hold.
    Returns the stripped root and notes of what was dropped."""
    src = str(path)
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ModelFileError(src, "<xml>", None, f"not well-formed XML: {exc}") from None
    if root.tag != "robot":
        raise ModelFileError(src, f"<{root.tag}>", None, "a URDF's root element is <robot>")
    children: dict[str, str] = {}
    for joint in root.findall("joint"):
        name = joint.get("name", "?")
        jtype = joint.get("type")
        where = f"joint[@name='{name}']"
        if joint.find("mimic") is not None and mimic == "refuse":
            raise ModelFileError(src, f"{where}/mimic.joint", joint.find("mimic").get("joint"),
                                 "a mimic joint couples two joints, which a tree of independent "
                                 "joints cannot hold; load with mimic='independent' to let it "
                                 "move on its own (Pinocchio's default), or remove the <mimic>")
        if jtype not in ("revolute", "continuous", "prismatic", "fixed", "floating"):
            raise ModelFileError(src, f"{where}.type", jtype, "unsupported joint type; supported: "
                                 "revolute, continuous, prismatic, fixed, floating")
        child = joint.find("child")
        cname = child.get("link") if child is not None else None
        if cname in children:
            raise ModelFileError(src, f"{where}/child.link", cname,
                                 f"is already the child of joint {children[cname]!r}: a "
                                 "kinematic loop, which a tree cannot hold")
        children[cname] = name
    counts: dict[str, int] = {}
    for parent in root.iter():
        for element in list(parent):
            if element.tag in (*DROPPED, "mimic"):
                counts[element.tag] = counts.get(element.tag, 0) + 1
                parent.remove(element)
    notes = [f"{n} <{tag}> element{'s' if n > 1 else ''}"
             + (" (those joints move independently)" if tag == "mimic" else "")
             for tag, n in sorted(counts.items())]
    return root, notes


def _spec_inertia(body):
    """(mass, com, inertia about the COM in the body frame) of an MjSpec body."""
    m = float(body.mass)
    ipos = np.asarray(body.ipos, dtype=float)
    if not m or np.isnan(ipos).any():
        return 0.0, np.zeros(3), np.zeros((3, 3))
    full = np.asarray(body.fullinertia, dtype=float)
    if not np.isnan(full).any():
        xx, yy, zz, xy, xz, yz = full
        I = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
    else:
        I = np.diag(np.asarray(body.inertia, dtype=float))
    R = _quat_matrix(body.iquat)
    return m, ipos, R @ I @ R.T


def load_urdf(path: str | os.PathLike, *, floating: bool = False,
              mimic: str = "refuse") -> Model:
    """A URDF's tree, gravity -Z. ``floating``: the root link gets a free joint (a legged or
    flying robot), else it is fixed to the world. ``mimic``: "refuse" (the default) a mimic
    joint, or let it move "independent"ly (noted in :attr:`Model.notes`)."""
    path = Path(path)
    src = str(path)
    if mimic not in MIMIC:
        raise ModelFileError(src, "mimic", mimic, f"must be one of {', '.join(MIMIC)}")
    root, notes = _check_urdf(path, mimic)
    mj = _mujoco(path)
    try:
        spec = mj.MjSpec.from_string(ET.tostring(root, encoding="unicode"))
    except Exception as exc:  # MuJoCo's parser reports a bad file with a ValueError
        raise ModelFileError(src, "<urdf>", None, f"MuJoCo's parser: {exc}") from None
    return _from_spec(spec, src, floating=floating, gravity=URDF_GRAVITY, name=root.get("name"),
                      notes=notes)


def _joint(mj, src, jtype_code, axis, jname, at_base) -> tuple[str, tuple | None]:
    """(type, axis) of one MuJoCo joint in the tree's terms."""
    if jtype_code == mj.mjtJoint.mjJNT_FREE:
        if not at_base:
            raise ModelFileError(src, f"joint[@name='{jname}'].type", "free",
                                 "a free (floating) joint must join a root body to the world")
        return FREE, None
    if jtype_code == mj.mjtJoint.mjJNT_HINGE:
        return "R", tuple(float(x) for x in axis)
    if jtype_code == mj.mjtJoint.mjJNT_SLIDE:
        return "P", tuple(float(x) for x in axis)
    raise ModelFileError(src, f"joint[@name='{jname}'].type", str(jtype_code).split(".")[-1],
                         "unsupported joint type (hinge, slide and free are read)")


def _from_spec(spec, src, *, floating, gravity, name, notes) -> Model:
    """The tree of an uncompiled MjSpec (a URDF as written)."""
    mj = _mujoco(src)
    bodies, joints, parents = [], [], []
    poses: dict[int, tuple] = {}  # free bodies' poses in the file

    def add(body, parent_index):
        k = len(bodies)
        jlist = list(body.joints)
        if len(jlist) > 1:
            raise ModelFileError(src, f"body[@name='{body.name}']", len(jlist),
                                 "several joints in one body are not read yet")
        if jlist and np.abs(np.asarray(jlist[0].pos, dtype=float)).max() > 0:
            raise ModelFileError(src, f"joint[@name='{jlist[0].name}'].pos", list(jlist[0].pos),
                                 "a joint away from its body's origin is not read yet")
        if jlist:
            jtype, axis = _joint(mj, src, jlist[0].type, jlist[0].axis, jlist[0].name,
                                 parent_index == -1)
            jname = jlist[0].name
        elif parent_index == -1 and floating:
            jtype, axis, jname = FREE, None, f"{body.name}_free"
        else:
            jtype, axis, jname = FIXED, None, f"{body.name}_fixed"
        m, c, I = _spec_inertia(body)
        bodies.append(Body(body.name, m, tuple(c), tuple(map(tuple, I)), physical=False))
        if jtype == FREE:  # the body's pose is the joint's initial configuration
            poses[k] = (np.array(body.pos, dtype=float), np.array(body.quat, dtype=float))
            joints.append(TreeJoint(jname, jtype))
        else:
            joints.append(TreeJoint(jname, jtype, axis,
                                    rotation=tuple(map(tuple, _quat_matrix(body.quat))),
                                    translation=tuple(float(x) for x in body.pos)))
        parents.append(parent_index)
        for child in body.bodies:
            add(child, k)

    for top in spec.worldbody.bodies:
        add(top, -1)
    if floating and sum(p == -1 for p in parents) != 1:
        raise ModelFileError(src, "<robot>", None, "floating needs one root link")
    model = _finish(bodies, joints, parents, gravity, name or Path(src).stem, src, notes)
    if poses:
        q = model.neutral()
        free = [k for k, t in enumerate(model.joint_types) if t == FREE]
        for k, (pos, quat) in zip(free, (poses[i] for i in sorted(poses)), strict=True):
            qs = model.joint_qoff[k]
            q[qs:qs + 3], q[qs + 3:qs + 7] = pos, quat / np.linalg.norm(quat)
        object.__setattr__(model, "initial_q", q)
    return model


def _finish(bodies, joints, parents, gravity, name, src, notes) -> Model:
    """Build the Model (bodies fixed to the world dropped), check that every joint has inertia
    to move, record what the importer dropped."""
    model = _build_dropping_world_fixed(bodies, joints, parents, gravity, name, src)
    _check_inertia_to_move(model, src)
    object.__setattr__(model, "notes", tuple(notes))
    return model


def _build_dropping_world_fixed(bodies, joints, parents, gravity, name, src) -> Model:
    bodies, joints, parents, _ = drop_world_fixed(bodies, joints, parents)
    if not bodies:
        raise ModelFileError(src, "<model>", None, "no body moves: every joint is fixed")
    return Model.build(bodies, joints, parents, gravity=gravity, name=name, source=src)


def _check_inertia_to_move(model: Model, src: str) -> None:
    """Refuse a model whose GIM is singular at the neutral configuration, naming the joint:
    a massless body at the end of a joint (its subtree has no inertia about the joint's axis)."""
    from .rbda import massless_axis

    j = massless_axis(model)
    if j is not None:
        k = int(np.searchsorted(model.joint_voff, j, side="right") - 1)
        raise ModelFileError(src, f"joint[@name='{model.joint_names[k]}']", None,
                             f"moves body {model.body_names[k]!r} and what it carries, which "
                             f"have no inertia about its axis {j - int(model.joint_voff[k])}: a "
                             "massless body at the end of a joint; give it an <inertial> or "
                             "fix the joint")


# --------------------------------------------------------------------------- MJCF
def load_mjcf(path: str | os.PathLike) -> Model:
    """An MJCF model's tree as MuJoCo compiles it (inertias from geometry where the file gives
    none, default classes applied), with its gravity. A body with several hinge and slide joints
    (MuJoCo composes them in order, each axis in the frame the ones before it leave) becomes a
    chain of massless bodies, one joint each, the last carrying the body."""
    path = Path(path)
    src = str(path)
    mj = _mujoco(path)
    try:
        m = mj.MjModel.from_xml_path(src)
    except Exception as exc:  # MuJoCo reports a bad file with a ValueError
        raise ModelFileError(src, "<mujoco>", None, f"MuJoCo's compiler: {exc}") from None
    bodies, joints, parents = [], [], []
    ours = {0: -1}  # MuJoCo's body id -> our index of it (its last body); the world is -1
    for b in range(1, m.nbody):
        name = mj.mj_id2name(m, mj.mjtObj.mjOBJ_BODY, b) or f"body{b}"
        parent = ours[int(m.body_parentid[b])]
        specs = []  # (type, axis, name) of each of the body's joints, in order
        for j in map(int, np.flatnonzero(m.jnt_bodyid == b)):
            jname = mj.mj_id2name(m, mj.mjtObj.mjOBJ_JOINT, j) or f"joint{j}"
            if np.abs(m.jnt_pos[j]).max() > 0:
                raise ModelFileError(src, f"joint[@name='{jname}'].pos", list(m.jnt_pos[j]),
                                     "a joint away from its body's origin is not read yet")
            jtype, axis = _joint(mj, src, m.jnt_type[j], m.jnt_axis[j], jname, parent == -1)
            if jtype == FREE and len(np.flatnonzero(m.jnt_bodyid == b)) > 1:
                raise ModelFileError(src, f"body[@name='{name}']", "free",
                                     "a free joint must be its body's only joint")
            specs.append((jtype, axis, jname))
        if not specs:
            specs = [(FIXED, None, f"{name}_fixed")]
        placement = dict(rotation=tuple(map(tuple, _quat_matrix(m.body_quat[b]))),
                         translation=tuple(float(x) for x in m.body_pos[b]))
        for i, (jtype, axis, jname) in enumerate(specs[:-1]):  # massless, one joint each
            bodies.append(Body(f"{name}_{jname}", 0.0, physical=False))
            joints.append(TreeJoint(jname, jtype, axis, **(placement if i == 0 else {})))
            parents.append(parent)
            parent = len(bodies) - 1
        jtype, axis, jname = specs[-1]
        R = _quat_matrix(m.body_iquat[b])
        inertia = R @ np.diag(m.body_inertia[b]) @ R.T
        bodies.append(Body(name, float(m.body_mass[b]), tuple(m.body_ipos[b]),
                           tuple(map(tuple, inertia)), physical=False))
        if jtype == FREE:  # the body's pose is the joint's initial configuration (qpos0)
            joints.append(TreeJoint(jname, jtype))
        else:
            joints.append(TreeJoint(jname, jtype, axis, **(placement if len(specs) == 1 else {})))
        parents.append(parent)
        ours[b] = len(bodies) - 1
    notes = ["geometry, actuators, sensors, tendons, equality constraints, contacts",
             "joint limits, damping, armature and friction"]
    model = _finish(bodies, joints, parents, tuple(float(g) for g in m.opt.gravity), path.stem,
                    src, notes)
    object.__setattr__(model, "initial_q", np.array(m.qpos0, dtype=float))
    return model


# --------------------------------------------------------------------------- any file
def load_model(path: str | os.PathLike, *, floating: bool = False,
               mimic: str = "refuse") -> Model:
    """The model in ``path``: ``.urdf`` (``floating``: a free joint at the root; ``mimic``: see
    :func:`load_urdf`), MJCF ``.xml``, a robot ``.toml`` (a DH table, :mod:`redysim.dh`) or a
    case ``.toml`` (its chain). Raises
    FileNotFoundError, ModelFileError or CaseError."""
    p = Path(path)
    if not p.is_file():
        raise FileNotFoundError(f"model file {str(p)!r} does not exist")
    suffix = p.suffix.lower()
    if suffix == ".urdf":
        return load_urdf(p, floating=floating, mimic=mimic)
    if suffix == ".xml":
        return load_mjcf(p)
    if suffix == ".toml":  # a robot's DH table (redysim.dh), else a rope case file
        from .dh import is_robot_file, load_robot
        from .linkage_files import is_linkage_file
        if is_robot_file(p):
            return load_robot(p).model
        if is_linkage_file(p):
            raise ModelFileError(str(p), "[linkage]", None, "a closed-loop linkage: a tree alone "
                                 "would drop its cut joints; load it with "
                                 "redysim.load_linkage(path) -> (model, loops, q0)")
        from .cases import load_case
        return Model.from_chain(load_case(p).chain)
    raise ModelFileError(str(p), "<file>", suffix, "a model file is .urdf, MJCF .xml or a case "
                         ".toml")
