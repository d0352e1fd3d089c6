"""Serial robots from Denavit-Hartenberg tables: standard (distal) and modified (Craig) DH.

A DH table has one row per joint k = 1..n: the link length ``a``, twist ``alpha``, offset ``d``
(Saha's ``b``), angle ``theta`` and the joint type, R (revolute: q_k is added to theta_k) or P
(prismatic: q_k is added to d_k), with each link's mass, centre of mass and inertia about the
centre of mass, both in that link's DH frame. The base is fixed at the world origin (frame 0 is
the world frame) and gravity is given in the world frame: by default 9.81 m/s^2 along -z, the
usual robot convention (z up). That is not the rope cases' default (-y): a robot file says its
gravity when it differs.

The two conventions (4x4 homogeneous transforms; Rz, Rx rotations, Tz, Tx translations)::

    standard  (Denavit-Hartenberg 1955, Paul 1981, Saha, Corke's DHRobot):
              0T_k = 0T_{k-1} Rz(theta_k) Tz(d_k) Tx(a_k) Rx(alpha_k)
              joint k turns about (slides along) z_{k-1}; link k carries frame k at its far end.
    modified  (Craig 1986, Khalil; Corke's RevoluteMDH): row k holds alpha_{k-1}, a_{k-1}:
              0T_k = 0T_{k-1} Rx(alpha_{k-1}) Tx(a_{k-1}) Rz(theta_k) Tz(d_k)
              joint k turns about (slides along) z_k; link k carries frame k at its near end.

How the tree is built. A :class:`~redysim.model.tree.Model` joint turns body k about an axis through
body k's origin, so body k's frame must lie on joint k's axis. Every body frame here is Craig's
frame of its link: origin on joint k's axis, z along it, x along the common normal to the next
joint's axis. For a **modified** table these are the table's own frames: body k's frame IS DH
frame k, its joint placed at Rx(alpha_{k-1}) Tx(a_{k-1}) Rz(theta_k) Tz(d_k) in body k-1, the
link's inertia taken as written. For a **standard** table, DH frame k sits at the far end of
link k, on joint k+1's axis (z_k), not on joint k's (z_{k-1}) unless a_k = 0: no tree body frame
can be it. Body k's frame is then the standard frame k moved back along the common normal,
0T_{k-1} Rz(theta_k) Tz(d_k), and

    DH frame k = body k's frame . Tx(a_k) Rx(alpha_k)          (a constant transform)

so the a/alpha part of row k is carried into joint k+1's placement, Tx(a_k) Rx(alpha_k)
Rz(theta_{k+1}) Tz(d_{k+1}), and link k's centre of mass and inertia, given in DH frame k, are
re-expressed in body k's frame once, when the model is built (c = a_k x + Rx(alpha_k) c_DH,
I = Rx(alpha_k) I_DH Rx(alpha_k)^T). Standard row k and modified row k+1 then hold the same
(a, alpha): a standard table and its modified equivalent give the same tree, body for body.

:class:`DHRobot` keeps that constant transform: :meth:`DHRobot.dh_frames` gives the DH frames' world
poses. The model also has named frames (points, :func:`redysim.algorithms.rbda.frame_position`):
``dh1`` .. ``dhN``, the DH frames' origins, and ``flange``, the end effector: a point given in the
last DH frame (the flange's offset beyond frame n, default its origin).

Robot files (TOML, ``cases/robots/README.md``)::

    [robot]
    name = "PUMA 560"
    convention = "standard"            # or "modified"; required
    gravity = [0.0, 0.0, -9.81]        # world frame, m/s^2; the default
    flange = [0.0, 0.0, 0.056]         # in the last DH frame, m; default [0, 0, 0]

    [[link]]                           # one per joint, base to tip
    joint = "R"                        # R or P
    a = 0.4318                         # m
    alpha_deg = 0.0                    # deg
    d = 0.0                            # m (for P: the offset added to q)
    theta_deg = 0.0                    # deg (for R: the offset added to q)
    mass = 17.4                        # kg
    com = [-0.3638, 0.006, 0.2275]     # m, in this link's DH frame
    inertia = [0.13, 0.524, 0.539]     # kg m^2 about the COM, in the DH frame: [Ixx, Iyy, Izz]
                                       # or a 3x3 matrix
    # physical = false                 # allow an inertia that is no rigid body's (see below)
    # name = "upper arm"

Every bad value is refused with a :class:`~redysim.errors.CaseError` naming the file, the field
(``link[2].alpha_deg``, 0-based: ``link[0]`` is DH row 1) and the value. An inertia must be
symmetric and positive semi-definite, and its principal moments must satisfy the triangle
inequality unless the link says ``physical = false``: published tables sometimes give only the
moment about the joint axis (the PUMA 560's link 1) or moments no rigid body has.
"""

from __future__ import annotations

import math
import os
import tomllib
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NoReturn

import numpy as np

from redysim.errors import CaseError
from redysim.model.parts import _readonly, check_inertia, check_positive, check_vector
from redysim.model.tree import Body, Model, TreeJoint

CONVENTIONS = ("standard", "modified")
DH_JOINTS = ("R", "P")
ROBOT_GRAVITY = (0.0, 0.0, -9.81)  # z up, the usual robot convention (not the rope cases' -y)

_ROBOT_FIELDS = {"name", "description", "convention", "gravity", "flange"}
_LINK_REQUIRED = ("joint", "a", "alpha_deg", "d", "theta_deg", "mass", "com", "inertia")
_LINK_FIELDS = {*_LINK_REQUIRED, "name", "physical"}


def _fail(source, field_name, value, problem) -> NoReturn:
    raise CaseError(source, field_name, value, problem)


@dataclass(frozen=True)
class DHLink:
    """One row of a DH table and the link it moves (SI units, angles in radians).

    ``a``, ``alpha``: for a standard table link k's own length and twist; for a modified table
    those of the link before (a_{k-1}, alpha_{k-1}). ``d``, ``theta``: the offset and angle of
    joint k, q_k added to ``theta`` (R) or to ``d`` (P). ``com`` and ``inertia`` (about the COM,
    [Ixx, Iyy, Izz] or 3x3) in link k's DH frame. ``physical``: the inertia must be a rigid
    body's (the triangle inequality of its principal moments)."""

    a: float = 0.0
    alpha: float = 0.0
    d: float = 0.0
    theta: float = 0.0
    joint: str = "R"
    mass: float = 0.0
    com: Sequence[float] = (0.0, 0.0, 0.0)
    inertia: Any = (0.0, 0.0, 0.0)
    physical: bool = True
    name: str | None = None


def rot_x(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass(frozen=True, eq=False)
class DHRobot:
    """A robot built from a DH table: its :class:`Model` and what ties the model to the table.

    Attributes:
        model:      the tree (body k = link k + 1, joint k = joint k + 1; see the module doc).
        convention: "standard" or "modified".
        links:      the table, as given.
        dh_R, dh_p: (n, 3, 3), (n, 3): DH frame k's rotation and origin in body k's frame
                    (Rx(alpha_k) and (a_k, 0, 0) for a standard table; identity and zero for a
                    modified one).
        flange:     (3,) the end effector in the last DH frame.
    """

    model: Model
    convention: str
    links: tuple[DHLink, ...]
    dh_R: np.ndarray
    dh_p: np.ndarray
    flange: np.ndarray

    @property
    def n(self) -> int:
        return len(self.links)

    def dh_frames(self, q) -> np.ndarray:
        """World poses (n, 4, 4) of DH frames 1..n at configuration q."""
        from redysim.algorithms.rbda import kinematics

        q = np.asarray(q, dtype=float)
        kin = kinematics(self.model, q, np.zeros(self.model.n_v))
        T = np.zeros((self.n, 4, 4))
        T[:, 3, 3] = 1.0
        T[:, :3, :3] = kin.R @ self.dh_R
        T[:, :3, 3] = kin.O + np.einsum("kij,kj->ki", kin.R, self.dh_p)
        return T

    def flange_pose(self, q) -> np.ndarray:
        """World pose (4, 4) of the end effector: the last DH frame's axes at the flange."""
        T = self.dh_frames(q)[-1]
        T[:3, 3] += T[:3, :3] @ self.flange
        return T


def _number(source, field_name, value) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        _fail(source, field_name, value, "must be a number")
    x = float(value)
    if not math.isfinite(x):
        _fail(source, field_name, value, "must be finite (no NaN or Inf)")
    return x


def _link_inertia(source, field_name, value, physical) -> np.ndarray:
    I_c = check_inertia(source, field_name, value, physical=False)
    if physical:
        eig = np.linalg.eigvalsh(I_c)
        if eig[2] > (eig[0] + eig[1]) * (1 + 1e-12):
            _fail(source, field_name, value,
                  f"is not a rigid body's: its largest principal moment {eig[2]:.6g} exceeds the "
                  f"sum of the other two ({eig[0]:.6g} + {eig[1]:.6g}; the triangle inequality)."
                  " A published table that gives only some moments (the moment about the joint "
                  "axis, say) can be taken as written with physical = false")
    return I_c


def dh_robot(links: Sequence[DHLink], *, convention: str,
             gravity: Sequence[float] | np.ndarray = ROBOT_GRAVITY, name: str = "robot",
             flange: Sequence[float] | np.ndarray = (0.0, 0.0, 0.0), source: str = "dh table",
             prefix: str = "dh", names: Mapping[str, str] | None = None) -> DHRobot:
    """The robot of a DH table (``convention``: "standard" or "modified"), fixed base at the
    world origin, ``gravity`` in the world frame (default 9.81 m/s^2 along -z), ``flange`` the
    end effector in the last DH frame. Raises CaseError naming ``source`` and the field
    (``dh[k].alpha``, k 0-based; ``prefix`` and ``names``, field -> its name in a file, let a
    file name its own)."""
    if convention not in CONVENTIONS:
        _fail(source, "convention", convention, f"must be one of {', '.join(CONVENTIONS)}")
    links = tuple(links)
    if not links:
        _fail(source, prefix, [], "a DH table needs at least one row")
    names = dict(names or {})
    bodies, joints, dh_R, dh_p = [], [], [], []
    prev_R, prev_p = np.eye(3), np.zeros(3)  # standard: the a/alpha of the row before
    for k, link in enumerate(links):
        row = f"{prefix}[{k}]"

        def fld(key, row=row):
            return f"{row}.{names.get(key, key)}"

        if not isinstance(link, DHLink):
            _fail(source, row, link, "must be a redysim.io.dh.DHLink")
        if link.joint not in DH_JOINTS:
            _fail(source, fld("joint"), link.joint,
                  f"unknown joint type (DH row {k + 1}); a DH joint is R (revolute about z) or "
                  "P (prismatic along z)")
        a = _number(source, fld("a"), link.a)
        alpha = _number(source, fld("alpha"), link.alpha)
        d = _number(source, fld("d"), link.d)
        theta = _number(source, fld("theta"), link.theta)
        mass = check_positive(source, fld("mass"), link.mass, allow_zero=True)
        com = check_vector(source, fld("com"), link.com, 3)
        if not isinstance(link.physical, bool):
            _fail(source, fld("physical"), link.physical, "must be true or false")
        inertia = _link_inertia(source, fld("inertia"), link.inertia, link.physical)
        # the body's frame: Craig's frame of link k (module doc)
        if convention == "standard":
            R_pl, p_pl = prev_R @ rot_z(theta), prev_p + prev_R @ np.array([0.0, 0.0, d])
            R_dh, p_dh = rot_x(alpha), np.array([a, 0.0, 0.0])
            prev_R, prev_p = R_dh, p_dh
        else:
            R_x = rot_x(alpha)
            R_pl, p_pl = R_x @ rot_z(theta), np.array([a, 0.0, 0.0]) + R_x @ np.array([0, 0, d])
            R_dh, p_dh = np.eye(3), np.zeros(3)
        c_body = p_dh + R_dh @ com
        I_body = R_dh @ inertia @ R_dh.T
        body_name = link.name if link.name is not None else f"link{k + 1}"
        bodies.append(Body(str(body_name), mass, tuple(c_body),
                           tuple(map(tuple, 0.5 * (I_body + I_body.T))), physical=False))
        joints.append(TreeJoint(f"joint{k + 1}", link.joint, "z",
                                rotation=tuple(map(tuple, R_pl)), translation=tuple(p_pl)))
        dh_R.append(R_dh)
        dh_p.append(p_dh)
    f = check_vector(source, "flange", flange, 3)
    g = check_vector(source, "gravity", gravity, 3)
    n = len(links)
    frames = {f"dh{k + 1}": (k, tuple(dh_p[k])) for k in range(n)}
    frames["flange"] = (n - 1, tuple(dh_p[-1] + dh_R[-1] @ f))
    model = Model.build(bodies, joints, list(range(-1, n - 1)), gravity=g, name=name,
                        frames=frames, source=source)
    _check_inertia_to_move(model, source, prefix)
    return DHRobot(model=model, convention=convention, links=links,
                   dh_R=_readonly(np.array(dh_R)), dh_p=_readonly(np.array(dh_p)),
                   flange=_readonly(f))


def dh_model(links: Sequence[DHLink], **kwargs) -> Model:
    """The :class:`Model` of a DH table: ``dh_robot(links, **kwargs).model``."""
    return dh_robot(links, **kwargs).model


def _check_inertia_to_move(model: Model, source: str, prefix: str) -> None:
    """Refuse a table whose GIM is singular at q = 0 because a joint moves nothing with inertia
    about its axis (massless links at the tip), naming the row."""
    from redysim.algorithms.rbda import massless_axis

    k = massless_axis(model)  # one axis per joint in a DH table: the joint's index
    if k is not None:
        what = "mass along" if model.joint_types[k] == "P" else "inertia about"
        _fail(source, f"{prefix}[{k}]", None,
              f"joint {k + 1} moves links {k + 1}..{model.n_bodies}, which have no {what} its "
              "axis: the GIM is singular; give them mass and inertia")


# --------------------------------------------------------------------------- robot files
def is_robot_document(doc: dict) -> bool:
    """A TOML document is a robot file when it has a [robot] table or [[link]] rows."""
    return isinstance(doc, dict) and ("robot" in doc or "link" in doc)


def is_robot_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a TOML robot file (False for a rope case file, or unreadable TOML:
    the case loader reports that)."""
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return False
    return is_robot_document(doc)


def load_robot(path: str | os.PathLike) -> DHRobot:
    """The robot of a TOML robot file (module doc; ``cases/robots/README.md``)."""
    from redysim.io.cases import read_toml

    path = Path(path)
    src = str(path)
    doc = read_toml(path)[0]
    return robot_from_dict(doc, source=src, default_name=path.stem)


def robot_from_dict(doc: dict, *, source: str = "<dict>", default_name: str = "robot") -> DHRobot:
    """The robot of a parsed robot file."""
    for key in doc:
        if key not in ("robot", "link"):
            _fail(source, key, doc[key], "unknown table; a robot file has [robot] and [[link]] "
                  "(a rope case file has [case] and [chain], and no [robot])")
    robot = doc.get("robot")
    if not isinstance(robot, dict):
        _fail(source, "robot", robot, "missing table [robot]" if robot is None else
              "[robot] must be a table")
    for key in robot:
        if key not in _ROBOT_FIELDS:
            _fail(source, f"robot.{key}", robot[key],
                  f"unknown field; expected one of {', '.join(sorted(_ROBOT_FIELDS))}")
    if "convention" not in robot:
        _fail(source, "robot.convention", None, "missing field: standard or modified DH")
    convention = robot["convention"]
    if convention not in CONVENTIONS:
        _fail(source, "robot.convention", convention,
              "must be 'standard' (distal: Denavit-Hartenberg, Paul, Saha, Corke's DHRobot) or "
              "'modified' (proximal: Craig)")
    name = robot.get("name", default_name)
    if not isinstance(name, str):
        _fail(source, "robot.name", name, "must be a string")
    if not isinstance(robot.get("description", ""), str):
        _fail(source, "robot.description", robot["description"], "must be a string")
    gravity = check_vector(source, "robot.gravity", robot.get("gravity", ROBOT_GRAVITY), 3)
    flange = check_vector(source, "robot.flange", robot.get("flange", (0.0, 0.0, 0.0)), 3)
    rows = doc.get("link")
    if not isinstance(rows, list) or not rows:
        _fail(source, "link", rows, "missing [[link]] rows" if rows is None else
              "must be a non-empty array of [[link]] tables, one per joint")
    links = []
    for k, row in enumerate(rows):
        where = f"link[{k}]"
        if not isinstance(row, dict):
            _fail(source, where, row, f"must be a table (DH row {k + 1})")
        for key in row:
            if key not in _LINK_FIELDS:
                _fail(source, f"{where}.{key}", row[key], f"unknown field (DH row {k + 1}); "
                      f"expected one of {', '.join(sorted(_LINK_FIELDS))}")
        for key in _LINK_REQUIRED:
            if key not in row:
                _fail(source, f"{where}.{key}", None, f"missing field (DH row {k + 1}); a row "
                      f"gives {', '.join(_LINK_REQUIRED)}")
        alpha = _number(source, f"{where}.alpha_deg", row["alpha_deg"])
        theta = _number(source, f"{where}.theta_deg", row["theta_deg"])
        link_name = row.get("name")
        if link_name is not None and not isinstance(link_name, str):
            _fail(source, f"{where}.name", link_name, "must be a string")
        links.append(DHLink(a=row["a"], alpha=math.radians(alpha), d=row["d"],
                            theta=math.radians(theta), joint=row["joint"], mass=row["mass"],
                            com=row["com"], inertia=row["inertia"],
                            physical=row.get("physical", True), name=link_name))
    return dh_robot(links, convention=convention, gravity=gravity, name=name, flange=flange,
                    source=source, prefix="link",
                    names={"alpha": "alpha_deg", "theta": "theta_deg"})
