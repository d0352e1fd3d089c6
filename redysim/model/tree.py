"""Kinematic trees: bodies with a parent, joints placed by a fixed transform in the parent's frame.

A :class:`Model` is an immutable tree of rigid bodies. Body k (k = 0..nb-1, parents before children:
``parent[k] < k``, -1 for the base) hangs from its parent by joint k, whose frame sits at the
placement (rotation ``placement_R[k]``, translation ``placement_p[k]``) in the parent body's frame;
the joint's motion then carries body k's frame away from the joint frame. Joint types are those of
:data:`redysim.model.parts.JOINT_TYPES` (R and P about any axis, U, S: sequences of elementary axes,
each in the frame the axes before it leave) and two more:

- ``fixed``: no motion. Fused when the model is built: the body's mass, centre of mass and
  inertia are added to its parent's, its children and frames are re-placed on the parent, so a
  fixed joint costs nothing per call.
- ``free``: a floating body (the base of a legged or flying robot), allowed only where the parent
  is the base. Configuration q = (x, y, z, qw, qx, qy, qz): the body origin's world position and a
  unit quaternion (n_q = 7); velocity v = (v_x, v_y, v_z, w_x, w_y, w_z): the body origin's
  velocity in the world frame and the body's angular velocity in its own frame (n_v = 6): the
  convention of MuJoCo's free joint. dq/dt = (v_world, q (x) [0; w_body] / 2).
- ``ball``: a spherical joint, the free joint's rotation alone (MuJoCo's ``ball``), anywhere in
  the tree: q = (qw, qx, qy, qz), a unit quaternion turning the joint frame into the body's
  (n_q = 4); v = (w_x, w_y, w_z), the body's angular velocity relative to its parent, in the
  body's own frame (n_v = 3); dq/dt = q (x) [0; w] / 2.

Everything a chain is, a tree is: a :class:`~redysim.model.tree.Chain` is a Model (parent k - 1,
each joint placed at the parent's length along its x axis).

Per-DOF tables follow the chain's (``dof_kind``, ``dof_axis``, ``dof_u``) over the n_v velocity
coordinates, with a third kind, ``BALL`` (the three rotational DOF of a free or ball joint, about
the body's own axes). ``joint_qoff`` and ``joint_voff`` give each joint's first configuration and
velocity coordinate.
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any, ClassVar, NoReturn

import numpy as np

from redysim.errors import CaseError
from redysim.model import door
from redysim.model.parts import (
    GENERAL_AXIS,
    JOINT_TYPES,
    KIND_CODES,
    STANDARD_GRAVITY,
    Joint,
    Link,
    _readonly,
    check_inertia,
    check_positive,
    check_vector,
    numeric_array,
)

BALL = 2  # dof_kind of a free or ball joint's rotational DOF (about the body's own x, y, z)
FREE, FIXED, BALL_JOINT = "free", "fixed", "ball"
TREE_JOINT_TYPES = (*JOINT_TYPES, FREE, FIXED, BALL_JOINT)
QUATERNION_JOINTS = (FREE, BALL_JOINT)  # joints whose q holds a unit quaternion (w, x, y, z)
MAX_GRAVCOMP = 1e6  # a body's gravcomp (its weight's fraction held up): more is a unit slip
MAX_MULTIPLIER = 1e6  # |a coupling's multiplier|: a gear ratio beyond it is a unit slip
ROTATION_TOL = 1e-9  # |R^T R - 1| allowed in a placement rotation given by the user
THREAD_WORKSPACES = "_thread_workspaces"  # a model's per-thread workspaces (Model.__getstate__)


def _fail(source, field_name, value, problem) -> NoReturn:
    raise CaseError(source, field_name, value, problem)


@dataclass(frozen=True)
class Body:
    """A rigid body: mass, centre of mass and inertia about the COM, all in the body's frame.

    ``physical``: the inertia must satisfy the triangle inequality (see :class:`redysim.Link`).
    A body may be massless (mass 0, zero inertia), e.g. a frame between two joints, as long as
    something it carries gives every joint axis inertia to move. ``gravcomp``: the fraction of
    its weight held up at its centre of mass (MuJoCo's body ``gravcomp``; :attr:`Model.gravcomp`).
    """

    name: str
    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),) * 3
    physical: bool = True
    gravcomp: float = 0.0


@dataclass(frozen=True)
class TreeJoint:
    """The joint that carries a body: its name, type (a key of :data:`TREE_JOINT_TYPES`), the
    axis of an R or P joint, and its placement in the parent body's frame (rotation (3, 3),
    translation (3,); identity and zero by default)."""

    name: str
    type: str
    axis: tuple[float, float, float] | str | None = None
    rotation: tuple[tuple[float, float, float], ...] | None = None
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)


def _rotation(source, field_name, value) -> np.ndarray:
    if value is None:
        return np.eye(3)
    R = np.asarray(value, dtype=float)
    if R.shape != (3, 3) or not np.isfinite(R).all():
        _fail(source, field_name, value, "must be a finite 3x3 rotation matrix")
    if np.abs(R.T @ R - np.eye(3)).max() > ROTATION_TOL or np.linalg.det(R) < 0:
        _fail(source, field_name, value, "must be a rotation (orthonormal, determinant +1)")
    return R


def drop_world_fixed(bodies: Sequence[Body], joints: Sequence[TreeJoint], parents: Sequence[int]
                     ) -> tuple[list[Body], list[TreeJoint], list[int], dict[int, int]]:
    """Leave out the bodies welded to the world (a fixed joint from the base, or from such a
    body): they do not move. Their children hang from the world instead, their placements
    composed. Returns the kept bodies, joints and parents and {old index: new index}."""
    joints = list(joints)
    keep = [True] * len(bodies)
    R = [np.eye(3)] * len(bodies)
    p = [np.zeros(3)] * len(bodies)
    new_parent = list(parents)
    for k, (j, par) in enumerate(zip(joints, parents, strict=True)):
        Rk = np.asarray(j.rotation if j.rotation is not None else np.eye(3), dtype=float)
        pk = np.asarray(j.translation, dtype=float)
        if par >= 0 and not keep[par]:  # its parent is welded to the world: compose
            Rk, pk = R[par] @ Rk, R[par] @ pk + p[par]
            new_parent[k] = -1
            joints[k] = TreeJoint(j.name, j.type, j.axis, tuple(map(tuple, Rk)), tuple(pk))
        if new_parent[k] == -1 and joints[k].type == FIXED:
            keep[k] = False
            R[k], p[k] = Rk, pk
    kept = [k for k in range(len(bodies)) if keep[k]]
    index = {k: i for i, k in enumerate(kept)}
    return ([bodies[k] for k in kept], [joints[k] for k in kept],
            [-1 if new_parent[k] == -1 else index[new_parent[k]] for k in kept], index)


def quaternion_matrix(qw, qx, qy, qz) -> np.ndarray:
    """The rotation of a unit quaternion (w, x, y, z)."""
    return np.array([
        [1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qw * qz), 2 * (qx * qz + qw * qy)],
        [2 * (qx * qy + qw * qz), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qw * qx)],
        [2 * (qx * qz - qw * qy), 2 * (qy * qz + qw * qx), 1 - 2 * (qx * qx + qy * qy)]])


def joint_transform(axes: Sequence[tuple[int, np.ndarray]],
                    values: Sequence[float] | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(R, p): the motion of a joint's elementary axes (kind, unit vector, each in the frame the
    axes before it leave) at the given coordinates: a revolute axis turns, a prismatic one
    slides."""
    R, p = np.eye(3), np.zeros(3)
    for (kind, u), x in zip(axes, values, strict=True):
        if kind == KIND_CODES["P"]:
            p = p + R @ (np.asarray(u) * x)
        else:
            u = np.asarray(u)
            c, s = math.cos(x), math.sin(x)
            C = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
            R = R @ (c * np.eye(3) + s * C + (1 - c) * np.outer(u, u))
    return R, p


def _combine(m1, c1, I1, m2, c2, I2):
    """Mass, COM and inertia about the COM of two bodies in one frame."""
    m = m1 + m2
    if m == 0.0:
        return 0.0, np.zeros(3), I1 + I2
    c = (m1 * c1 + m2 * c2) / m
    I = np.zeros((3, 3))
    for mi, ci, Ii in ((m1, c1, I1), (m2, c2, I2)):
        d = ci - c
        I += Ii + mi * (d @ d * np.eye(3) - np.outer(d, d))
    return m, c, 0.5 * (I + I.T)


@dataclass(frozen=True, eq=False)
class Model:
    """An immutable kinematic tree. Build it with :meth:`Model.build` (a chain with
    :meth:`Chain.build` or :meth:`Chain.uniform`, from a file with :func:`redysim.load_model`).

    Attributes (nb bodies, n_v velocity and n_q configuration coordinates):
        name:             a label.
        body_names:       (nb,) names of the bodies; joint_names: (nb,) of their joints.
        joint_types:      (nb,) each joint's type.
        parent:           (nb,) index of the parent body, -1 for the base.
        placement_R:      (nb, 3, 3) rotation of joint k's frame in the parent's frame.
        placement_p:      (nb, 3) its translation.
        placement_code:   (nb,) 0 when the rotation is the identity and the translation lies
                          along the parent's x (a chain's link), 1 otherwise.
        joint_qoff, joint_voff: (nb + 1,) first configuration / velocity coordinate of joint k.
        dof_kind, dof_axis, dof_u: (n_v,) as a Chain's, with BALL for a free or ball joint's
                          rotation.
        mass, com, inertia_com, inertia_O, mass_com: per body, as a Chain's per link.
        gravity:          (3,) world gravity [m/s^2].
        frames:           name -> (body, point in its frame): points of interest (a chain's tip,
                          an MJCF site, an MJCF body whose origin is not its body's here, a
                          body fused into its parent by a fixed joint: a URDF's tool0).
        frame_rotations:  name -> (3, 3) rotation of a frame's axes in its body's frame, for
                          frames that have axes of their own (an MJCF site); a frame not listed
                          has its body's axes.
        notes:            what the model's file holds and the model does not, one line each
                          (:mod:`redysim.io.importers`: dropped attributes, things not read).
        cuts:             the cut joints that close the model's loops (:meth:`with_cuts`; none
                          for a tree).
        couplings:        joints whose coordinate follows another's, q_f = m q_l + offset
                          (:class:`Coupling`, :meth:`with_couplings`: a URDF mimic joint); the
                          coordinates stay the tree's, n_v, of which the couplings hold
                          len(couplings): the mechanism moves with n_v - len(couplings) DOF.
        armature:         (n_v,) each velocity coordinate's own inertia [kg m^2 for a rotation,
                          kg for a translation], added to the diagonal of the joint-space inertia
                          I(q) (a motor's rotor inertia reflected through its gear: MuJoCo's
                          ``dof_armature``, Pinocchio's ``Model.armature``); zeros unless given
                          (:meth:`with_armature`, or ``armature=`` to the constructors). Every
                          transformation keeps it (:meth:`with_cuts`, :meth:`with_couplings`,
                          :attr:`free_tree`, :meth:`locked`).
        damping, stiffness, spring_ref: (n_v,) the joints' passive forces as the model's file
                          gives them (MuJoCo's ``dof_damping``, ``jnt_stiffness`` and
                          ``qpos_spring``, a URDF's ``<dynamics damping>``): a viscous force
                          -damping v [N m s / rad, N s / m] and a spring's -stiffness (q -
                          spring_ref) [N m / rad, N / m] on each velocity coordinate (no spring
                          on a free joint's); zeros unless given (:meth:`with_passive`).
        gravcomp:         (nb,) the fraction of each body's weight held up at its centre of mass
                          (MuJoCo's body ``gravcomp``), zeros unless given.
        gravcomp_loads:   (k, 5) more held-up weights, each (body, held mass [kg], point (3,) in
                          the body's frame): a body fused from parts whose gravcomp fractions
                          differ (a jointless MJCF body of another fraction than its parent's)
                          holds each part's fraction of its mass at the part's centre of mass
                          (its gravcomp entry then 0); (0, 5) unless so. These five are forces,
                          not inertia: :func:`redysim.forward_dynamics` stays the rigid body's map
                          tau -> qdd and :meth:`energy` its T + V; :func:`redysim.passive_forces`
                          gives them, and a run (:class:`redysim.algorithms.system.System`,
                          :func:`redysim.simulate`) applies them (:meth:`without_passive`: a
                          model without them). Kept as armature is.

    A model also carries its own scratch: a dynamics function called without ``ws=`` uses the
    calling thread's :class:`~redysim.algorithms.workspace.Workspace` of the model, made on the
    thread's first such call and kept (:func:`redysim.algorithms.workspace.model_workspace`; one per
    thread, never shared between threads). It is not a field: not in ``repr``, equality (by
    identity) or hashing, and neither pickles nor copies carry it (:meth:`__getstate__`): an
    unpickled or copied model makes its own.
    """

    # what redysim.model.door.require_model looks for (the door imports no model class)
    __redysim_model__: ClassVar[bool] = True

    name: str
    body_names: Sequence[str]  # a tuple; a Chain's numbered names hold no strings (_Numbered)
    joint_names: Sequence[str]
    joint_types: tuple[str, ...]
    parent: np.ndarray
    placement_R: np.ndarray
    placement_p: np.ndarray
    placement_code: np.ndarray
    joint_qoff: np.ndarray
    joint_voff: np.ndarray
    dof_kind: np.ndarray
    dof_axis: np.ndarray
    dof_u: np.ndarray
    mass: np.ndarray
    com: np.ndarray
    inertia_com: np.ndarray
    inertia_O: np.ndarray
    mass_com: np.ndarray
    gravity: np.ndarray
    frames: Mapping[str, tuple[int, tuple[float, float, float]]] = field(default_factory=dict)
    frame_rotations: Mapping[str, tuple] = field(default_factory=dict)  # name -> 3 x 3 rows
    notes: tuple[str, ...] = ()  # what the file holds and the model does not, one line each
    initial_q: np.ndarray | None = None  # a configuration the file gives (MJCF's qpos0)
    cuts: tuple = ()  # the cut joints that close its loops (CutJoint)
    couplings: tuple = ()  # joints that follow others (Coupling: a URDF mimic joint)
    armature: np.ndarray = None  # type: ignore[assignment]  # (n_v,); None given: zeros
    damping: np.ndarray = None  # type: ignore[assignment]  # (n_v,); None given: zeros
    stiffness: np.ndarray = None  # type: ignore[assignment]  # (n_v,); None given: zeros
    spring_ref: np.ndarray = None  # type: ignore[assignment]  # (n_v,); None given: zeros
    gravcomp: np.ndarray = None  # type: ignore[assignment]  # (nb,); None given: zeros
    # (k, 5): (body, held mass, point) of fused parts' differing gravcomp; None given: none
    gravcomp_loads: np.ndarray = None  # type: ignore[assignment]
    # The per-thread workspaces (a threading.local), in the instance's __dict__ once made
    # (redysim.algorithms.workspace.model_workspace); declared here for the type checker only (a
    # ClassVar is no dataclass field, and the class itself has no such attribute).
    _thread_workspaces: ClassVar[threading.local]

    def __post_init__(self) -> None:
        """The armature and the passive elements checked (or zeros when none is given): finite,
        >= 0 but for spring_ref, one number per velocity coordinate (gravcomp: per body); no
        spring on a free joint."""
        zeros: dict[int, np.ndarray] = {}  # one read-only zeros per length, shared
        for key, n in (("armature", self.n_v), ("damping", self.n_v), ("stiffness", self.n_v),
                       ("spring_ref", self.n_v), ("gravcomp", self.n_bodies)):
            value = getattr(self, key)
            if value is None:
                if n not in zeros:
                    zeros[n] = _readonly(np.zeros(n))
                object.__setattr__(self, key, zeros[n])
            elif not (isinstance(value, np.ndarray) and value.dtype == np.float64
                      and not value.flags.writeable and value.shape == (n,)
                      and (key == "spring_ref" or not (value < 0).any())
                      and np.isfinite(value).all()):  # (a checked one is kept, not copied)
                object.__setattr__(self, key, check_armature(self.name, key, value, n))
        if (self.gravcomp > MAX_GRAVCOMP).any():
            k = int(np.flatnonzero(self.gravcomp > MAX_GRAVCOMP)[0])
            _fail(self.name, f"gravcomp[{k}] (body {self.body_names[k]!r})",
                  float(self.gravcomp[k]), f"must be <= {MAX_GRAVCOMP:g}: the fraction of the "
                  "body's weight held up (1: all of it); a larger one is a unit slip")
        self._check_gravcomp_loads()
        if not self.stiffness.any() or FREE not in self.joint_types:
            return  # (a long chain's construction pays no loop over its joints)
        for k, t in enumerate(self.joint_types):
            sl = slice(self.joint_voff[k], self.joint_voff[k + 1])
            if t in (FREE, BALL_JOINT) and np.any(self.stiffness[sl]):
                _fail(self.name, f"stiffness[{int(self.joint_voff[k])}]",
                      self.stiffness[sl].tolist(), f"joint {self.joint_names[k]!r} is a {t} "
                      "joint: the core's springs act on joints whose coordinates are their "
                      "velocities'")

    # ----------------------------------------------------------------------- building
    @classmethod
    def build(cls, bodies: Sequence[Body], joints: Sequence[TreeJoint], parents: Sequence[int], *,
              gravity: Sequence[float] | np.ndarray = (0.0, -STANDARD_GRAVITY, 0.0),
              name: str = "model",
              frames: Mapping[str, tuple[int, Sequence[float]]] | None = None,
              frame_rotations: Mapping[str, Sequence] | None = None,
              source: str = "model", armature=None, damping=None, stiffness=None,
              spring_ref=None) -> Model:
        """Validate and freeze a tree: body k hangs from ``parents[k]`` (-1: the base) by
        ``joints[k]``; ``parents[k] < k``. Fixed joints are fused into their parents here (a
        body's ``gravcomp`` with it: where the fused parts' fractions differ, each part's share
        of its weight is held at its own centre of mass, :attr:`gravcomp_loads`).
        ``armature``, ``damping``, ``stiffness``, ``spring_ref``: as :meth:`with_armature` and
        :meth:`with_passive` take them (of the built model's joints).
        ``frame_rotations``: the axes of some of the ``frames`` (a rotation in the body's frame).
        Raises CaseError naming ``source``, the field (a body or joint by its name and index:
        ``body 'arm' (bodies[1]).mass``, ``joint 'elbow' (joints[1]).axis``) and the value."""
        nb = len(bodies)
        if nb == 0:
            _fail(source, "bodies", 0, "a model needs at least one body")
        if len(joints) != nb or len(parents) != nb:
            _fail(source, "joints/parents", (len(joints), len(parents)),
                  f"need one joint and one parent per body ({nb} bodies)")
        body_name: list[str] = []
        jname: list[str] = []
        mass, com, inertia, gravcomp = [], [], [], []
        jtype, axes, par, plR, plp = [], [], [], [], []
        for k, (b, j, p) in enumerate(zip(bodies, joints, parents, strict=True)):
            if not isinstance(b, Body):
                _fail(source, f"bodies[{k}]", b, "must be a redysim.Body")
            if not isinstance(j, TreeJoint):
                _fail(source, f"joints[{k}]", j, "must be a redysim.TreeJoint")
            where, jwhere = f"body {b.name!r} (bodies[{k}])", f"joint {j.name!r} (joints[{k}])"
            if isinstance(p, bool) or not isinstance(p, int | np.integer) or not -1 <= p < k:
                _fail(source, f"parents[{k}]", p, f"must be -1 (the base) or a body before it "
                      f"(0..{k - 1}): bodies are listed parents first")
            m_k = check_positive(source, f"{where}.mass", b.mass, allow_zero=True)
            c = check_vector(source, f"{where}.com", b.com, 3)
            I_c = check_inertia(source, f"{where}.inertia", b.inertia, physical=b.physical)
            gravcomp.append(float(check_armature(source, f"{where}.gravcomp", [b.gravcomp],
                                                 1)[0]))
            if j.type not in TREE_JOINT_TYPES:
                _fail(source, f"{jwhere}.type", j.type,
                      f"unknown joint type; known: {', '.join(TREE_JOINT_TYPES)}")
            if j.type == FREE and p != -1:
                _fail(source, f"{jwhere}.type", j.type, "a free joint must hang from the base "
                      "(parent -1): it gives the body its world pose")
            if j.type == FREE and (np.abs(_rotation(source, f"{jwhere}.rotation", j.rotation)
                                          - np.eye(3)).max() > 0 or any(j.translation)):
                _fail(source, f"{jwhere}.translation", j.translation, "a free joint's body "
                      "pose is its configuration q, not a placement: give the pose in q")
            if str(b.name) in body_name:
                _fail(source, f"{where}.name", b.name, "repeats the name of bodies["
                      f"{body_name.index(str(b.name))}]: a body is found by its name (frames, "
                      "gravcomp, body forces), so each must be unique")
            if str(j.name) in jname:
                _fail(source, f"{jwhere}.name", j.name, "repeats the name of joints["
                      f"{jname.index(str(j.name))}]: a joint is found by its name (locked, "
                      "with_armature, couplings), so each must be unique")
            body_name.append(str(b.name))
            mass.append(m_k)
            com.append(c)
            inertia.append(I_c)
            jname.append(str(j.name))
            jtype.append(j.type)
            axes.append(None if j.type in (FREE, FIXED, BALL_JOINT) else
                        Joint(j.type, j.axis).axes(source, jwhere))
            par.append(int(p))
            plR.append(_rotation(source, f"{jwhere}.rotation", j.rotation))
            plp.append(check_vector(source, f"{jwhere}.translation", j.translation, 3))
        points = {fname: (int(fb), np.asarray(fp, dtype=float))
                  for fname, (fb, fp) in (frames or {}).items()}
        for fname, (fb, fp) in points.items():
            if not 0 <= fb < nb:
                _fail(source, f"frames.{fname}", fb, f"body index must be in 0..{nb - 1}")
            check_vector(source, f"frames.{fname}", fp, 3)
        frame_axes = {}
        for fname, R_f in (frame_rotations or {}).items():
            if fname not in points:
                _fail(source, f"frame_rotations.{fname}", None, "no such frame in frames")
            frame_axes[fname] = _rotation(source, f"frame_rotations.{fname}", R_f)

        # fuse fixed joints, children after parents: body k moves into its (kept) ancestor
        into = list(range(nb))  # the kept body each body ends in
        to_kept_R = [np.eye(3) for _ in range(nb)]  # body frame -> that kept body's frame
        to_kept_p = [np.zeros(3) for _ in range(nb)]
        parts: dict[int, list] = {}  # a body fused from parts of different gravcomp: its parts
        for k in range(nb):
            if jtype[k] != FIXED:
                continue
            if par[k] == -1:
                _fail(source, f"joint {jname[k]!r} (joints[{k}]).type", FIXED, "a body fixed to "
                      "the base does not move: leave it out (or give the model a frame for it)")
            a = into[par[k]]
            R = to_kept_R[par[k]] @ plR[k]
            p = to_kept_R[par[k]] @ plp[k] + to_kept_p[par[k]]
            if mass[k] > 0 and (a in parts or gravcomp[k] != gravcomp[a]):
                if a not in parts and mass[a] == 0:
                    gravcomp[a] = gravcomp[k]  # a massless body takes its fused child's
                else:  # each part's fraction held at its own centre of mass (gravcomp_loads)
                    parts.setdefault(a, [(mass[a], np.array(com[a]), gravcomp[a])]).append(
                        (mass[k], R @ com[k] + p, gravcomp[k]))
            into[k], to_kept_R[k], to_kept_p[k] = a, R, p
            mass[a], com[a], inertia[a] = _combine(mass[a], com[a], inertia[a], mass[k],
                                                   R @ com[k] + p, R @ inertia[k] @ R.T)
        kept = [k for k in range(nb) if jtype[k] != FIXED]
        index = {k: i for i, k in enumerate(kept)}
        loads = [(index[a], f * m_, *c) for a, held in parts.items() for m_, c, f in held
                 if f * m_ > 0]
        for a in parts:
            gravcomp[a] = 0.0
        new_parent, new_R, new_p = [], [], []
        for k in kept:
            pk = par[k]
            if pk == -1:
                new_parent.append(-1)
                new_R.append(plR[k])
                new_p.append(plp[k])
            else:
                a = into[pk]
                new_parent.append(index[a])
                new_R.append(to_kept_R[pk] @ plR[k])
                new_p.append(to_kept_R[pk] @ plp[k] + to_kept_p[pk])
        kept_frames = {fname: (index[into[fb]], tuple(to_kept_R[fb] @ fp + to_kept_p[fb]))
                       for fname, (fb, fp) in points.items()}
        kept_axes = {}  # a frame's axes: its own, or its body's where that body is fused
        for fname, (fb, _) in points.items():
            R_f = to_kept_R[fb] @ frame_axes.get(fname, np.eye(3))
            if fname in frame_axes or np.abs(R_f - np.eye(3)).max() > 0:
                kept_axes[fname] = tuple(map(tuple, R_f))
        for k in range(nb):  # a fused body stays a frame by its name (a URDF's tool0, ee_link:
            fused = str(body_name[k])  # frame_motion(frame=...), as Pinocchio's frames)
            if jtype[k] == FIXED and fused not in kept_frames:
                kept_frames[fused] = (index[into[k]], tuple(to_kept_p[k]))
                if np.abs(to_kept_R[k] - np.eye(3)).max() > 0:
                    kept_axes[fused] = tuple(map(tuple, to_kept_R[k]))

        # per-DOF tables
        qoff, voff, kinds, codes, units = [0], [0], [], [], []
        for k in kept:
            if jtype[k] == FREE:
                for i in range(3):  # translation along the world axes, then the ball
                    kinds.append(KIND_CODES["P"])
                    codes.append(i)
                    units.append(np.eye(3)[i])
                for i in range(3):
                    kinds.append(BALL)
                    codes.append(i)
                    units.append(np.eye(3)[i])
                qoff.append(qoff[-1] + 7)
                voff.append(voff[-1] + 6)
                continue
            if jtype[k] == BALL_JOINT:  # the free joint's rotation alone
                for i in range(3):
                    kinds.append(BALL)
                    codes.append(i)
                    units.append(np.eye(3)[i])
                qoff.append(qoff[-1] + 4)
                voff.append(voff[-1] + 3)
                continue
            axes_k = axes[k]
            assert axes_k is not None  # None only for free, ball and fixed joints: none here
            for kind, u in axes_k:
                kinds.append(KIND_CODES[kind])
                codes.append(next((i for i in range(3) if np.array_equal(u, np.eye(3)[i])),
                                  GENERAL_AXIS))
                units.append(u)
            qoff.append(qoff[-1] + len(axes_k))
            voff.append(voff[-1] + len(axes_k))
        m = np.array([mass[k] for k in kept], dtype=float)
        c = np.array([com[k] for k in kept], dtype=float).reshape(-1, 3)
        I_c = np.array([inertia[k] for k in kept], dtype=float).reshape(-1, 3, 3)
        R_pl = np.array(new_R, dtype=float).reshape(-1, 3, 3)
        p_pl = np.array(new_p, dtype=float).reshape(-1, 3)
        along_x = (np.abs(R_pl - np.eye(3)).max(axis=(1, 2)) == 0) & (p_pl[:, 1] == 0) \
            & (p_pl[:, 2] == 0)
        cc = np.einsum("ki,kj->kij", c, c)
        sq = np.einsum("ki,ki->k", c, c)
        I_O = I_c + m[:, None, None] * (sq[:, None, None] * np.eye(3) - cc)
        I_O = 0.5 * (I_O + I_O.transpose(0, 2, 1))
        return cls(
            name=name, body_names=tuple(body_name[k] for k in kept),
            joint_names=tuple(jname[k] for k in kept),
            joint_types=tuple(jtype[k] for k in kept),
            parent=_readonly(np.array(new_parent, dtype=np.int64)),
            placement_R=_readonly(R_pl), placement_p=_readonly(p_pl),
            placement_code=_readonly((~along_x).astype(np.int64)),
            joint_qoff=_readonly(np.array(qoff, dtype=np.int64)),
            joint_voff=_readonly(np.array(voff, dtype=np.int64)),
            dof_kind=_readonly(np.array(kinds, dtype=np.int64)),
            dof_axis=_readonly(np.array(codes, dtype=np.int64)),
            dof_u=_readonly(np.array(units, dtype=float).reshape(-1, 3)),
            mass=_readonly(m), com=_readonly(c), inertia_com=_readonly(I_c),
            inertia_O=_readonly(I_O), mass_com=_readonly(m[:, None] * c),
            gravity=_readonly(check_vector(source, "gravity", gravity, 3)),
            frames=kept_frames, frame_rotations=kept_axes,
            armature=armature_values(source, armature, voff[-1], [jname[k] for k in kept],
                                     voff),
            damping=armature_values(source, damping, voff[-1], [jname[k] for k in kept], voff,
                                    "damping"),
            stiffness=armature_values(source, stiffness, voff[-1], [jname[k] for k in kept],
                                      voff, "stiffness"),
            spring_ref=armature_values(source, spring_ref, voff[-1],
                                       [jname[k] for k in kept], voff, "spring_ref"),
            gravcomp=_readonly(np.array([gravcomp[k] for k in kept], dtype=float)),
            gravcomp_loads=np.array(loads, dtype=float).reshape(-1, 5))

    def with_cuts(self, cuts: Sequence, *, source: str | None = None) -> Model:
        """The model with these cut joints (:class:`CutJoint`: each keeps a point
        of one body on a point of another, or frames aligned), checked against it: the closed
        mechanism. :func:`redysim.simulate` closes its loops;
        :class:`redysim.algorithms.loops.ClosedLoops` is the algorithm (constrained forward
        dynamics, projection); :func:`redysim.forward_dynamics` and
        :func:`redysim.inverse_dynamics` refuse it (the tree's answer would ignore the loops),
        the GIM and energy are the tree's. ``with_cuts(())`` is the open tree. Raises CaseError
        naming a bad cut (``source``: where they come from)."""
        import dataclasses

        if cuts is not None and not isinstance(cuts, str | CutJoint) and len(cuts) == 0:
            return dataclasses.replace(self, cuts=())
        check_cuts(self, cuts, source or f"{self.name}.with_cuts")
        return dataclasses.replace(self, cuts=tuple(cuts))

    def with_couplings(self, couplings: Sequence, *, source: str | None = None) -> Model:
        """The model with these couplings (:class:`Coupling`: a joint's coordinate held at a
        multiple of another's plus an offset, q_f = m q_l + offset, as a URDF mimic joint),
        checked against it. :func:`redysim.forward_dynamics` then gives the coupled motion
        (Featherstone's method on the tree's recursions: the tree's qdd, corrected by the
        coupling forces), :func:`redysim.simulate` keeps the followers on their leaders; the GIM,
        phi, inverse dynamics and energy are the tree's, in its coordinates. ``with_couplings(())``
        is the uncoupled tree. Raises CaseError naming a bad coupling (``source``: where they
        come from): an unknown joint, a joint that is not R or P, a follower that follows twice
        or leads another (give each follower its first leader: q_f = m1 m2 q_l + ...), a joint
        that follows itself, or a number that is not finite."""
        import dataclasses

        where = source or f"{self.name}.with_couplings"
        if isinstance(couplings, Coupling | str) or not isinstance(couplings, Sequence):
            _fail(where, "couplings", type(couplings).__name__, "must be a list of Coupling")
        if len(couplings) == 0:
            return dataclasses.replace(self, couplings=())
        index = {name: k for k, name in enumerate(self.joint_names)}
        followers: set[str] = set()
        for i, c in enumerate(couplings):
            if not isinstance(c, Coupling):
                _fail(where, f"couplings[{i}]", type(c).__name__, "must be a redysim.Coupling")
            for side in ("follower", "leader"):
                name = getattr(c, side)
                if name not in index:
                    shown = ", ".join(self.joint_names[:12]) + (", ..." if self.n_bodies > 12
                                                                else "")
                    _fail(where, f"couplings[{i}].{side}", name, f"no such joint; joints: {shown}")
                jt = self.joint_types[index[name]]
                if jt not in ("R", "P"):
                    _fail(where, f"couplings[{i}].{side}", name, f"a {jt} joint: a coupling "
                          "holds one R or P joint's coordinate to another's")
            if c.follower == c.leader:
                _fail(where, f"couplings[{i}].leader", c.leader, "a joint cannot follow itself")
            if c.follower in followers:
                _fail(where, f"couplings[{i}].follower", c.follower, "follows twice")
            followers.add(c.follower)
        for i, c in enumerate(couplings):
            if c.leader in followers:
                _fail(where, f"couplings[{i}].leader", c.leader, "itself follows another joint: "
                      "give the follower that joint's leader (multipliers multiplied, offsets "
                      "carried)")
        return dataclasses.replace(self, couplings=tuple(couplings))

    def with_armature(self, armature, *, source: str | None = None) -> Model:
        """The model with this armature: the joints' own inertia, added to the diagonal of
        the joint-space inertia I(q) (:attr:`armature`). ``armature``: one number for every
        velocity coordinate, a sequence of n_v numbers, or a mapping joint name -> a number (for
        each of its axes) or a sequence (one per axis; joints not named keep 0). Every kernel
        honours it (forward and inverse dynamics, the GIM and its factors, the energy and the
        generalized momentum). Raises CaseError naming the field and the value (not finite,
        negative, a wrong count, an unknown joint)."""
        import dataclasses

        where = source or f"{self.name}.with_armature"
        return dataclasses.replace(self, armature=armature_values(
            where, armature, self.n_v, self.joint_names, self.joint_voff))

    def with_passive(self, *, damping=None, stiffness=None, spring_ref=None, gravcomp=None,
                     source: str | None = None) -> Model:
        """The model with these passive elements (:attr:`damping`, :attr:`stiffness`,
        :attr:`spring_ref`, :attr:`gravcomp`); each one given replaces the model's, the others
        are kept. ``damping``, ``stiffness``, ``spring_ref``: as :meth:`with_armature` takes
        armature (a number, n_v numbers, or joint name -> value(s)); ``gravcomp``: a number, one
        per body, or body name -> fraction. Raises CaseError naming the field and the value
        (not finite, negative but for spring_ref, a wrong count, an unknown joint or body, a
        spring on a free joint)."""
        import dataclasses

        where = source or f"{self.name}.with_passive"
        changes: dict[str, Any] = {
            key: armature_values(where, value, self.n_v, self.joint_names, self.joint_voff, key)
            for key, value in (("damping", damping), ("stiffness", stiffness),
                               ("spring_ref", spring_ref)) if value is not None}
        if gravcomp is not None:
            changes["gravcomp"] = gravcomp_values(where, gravcomp, self.body_names)
            # (the fractions given replace the file's parts')
            changes["gravcomp_loads"] = _readonly(np.zeros((0, 5)))
        return dataclasses.replace(self, **changes) if changes else self

    def without_passive(self) -> Model:
        """The model without damping, springs and gravity compensation (:meth:`with_passive`
        with zeros): a run of it is the rigid body's alone (armature, an inertia, is kept)."""
        import dataclasses

        if not self.has_passive:
            return self
        zeros = _readonly(np.zeros(self.n_v))
        return dataclasses.replace(self, damping=zeros, stiffness=zeros, spring_ref=zeros,
                                   gravcomp=_readonly(np.zeros(self.n_bodies)),
                                   gravcomp_loads=_readonly(np.zeros((0, 5))))

    @property
    def has_passive(self) -> bool:
        """Whether the model has damping, springs or gravity compensation (a spring_ref alone,
        without stiffness, acts on nothing)."""
        return bool(np.any(self.damping) or np.any(self.stiffness) or np.any(self.gravcomp)
                    or self.gravcomp_loads.shape[0])

    def _check_gravcomp_loads(self) -> None:
        """:attr:`gravcomp_loads` as a read-only (k, 5) array (none: (0, 5)), CaseError naming
        a bad entry: a body index out of range, a negative or non-finite held mass or point."""
        loads = self.gravcomp_loads
        if loads is None:
            object.__setattr__(self, "gravcomp_loads", _readonly(np.zeros((0, 5))))
            return
        a = np.asarray(loads, dtype=float) if isinstance(loads, np.ndarray | list | tuple) \
            else None
        if a is not None and a.size == 0:
            a = a.reshape(0, 5)
        if a is None or a.ndim != 2 or a.shape[1] != 5 or not np.isfinite(a).all():
            _fail(self.name, "gravcomp_loads", _plain(loads), "must be rows (body, held mass "
                  "[kg], point x, y, z [m] in the body's frame) of finite numbers")
        for i, row in enumerate(a):
            if row[0] != int(row[0]) or not 0 <= row[0] < self.n_bodies or row[1] < 0:
                _fail(self.name, f"gravcomp_loads[{i}]", row.tolist(), f"needs a body index "
                      f"in 0..{self.n_bodies - 1} and a held mass >= 0")
        object.__setattr__(self, "gravcomp_loads", _readonly(a))

    @cached_property
    def coupling_index(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                                      np.ndarray, np.ndarray]:
        """The couplings as arrays: (follower q index, leader q index, follower v index, leader
        v index, multiplier, offset), one entry per coupling."""
        index = {name: k for k, name in enumerate(self.joint_names)}
        f = [index[c.follower] for c in self.couplings]
        ld = [index[c.leader] for c in self.couplings]
        out = (self.joint_qoff[f], self.joint_qoff[ld], self.joint_voff[f], self.joint_voff[ld],
               np.array([c.multiplier for c in self.couplings], dtype=float),
               np.array([c.offset for c in self.couplings], dtype=float))
        for a in out:
            a.flags.writeable = False
        return out  # type: ignore[return-value]

    def couple(self, q, v=None):
        """(q, v) with every follower's coordinate and velocity set from its leader's
        (q_f = m q_l + offset, v_f = m v_l): copies; q alone when ``v`` is None. The identity
        for a model without couplings. StateError for a q or v of another length (or not
        finite), as the dynamics functions refuse them."""
        owner = f"{type(self).__name__.lower()} {self.name!r}"
        q = door.vector("q", q, self.n_q, owner=owner, what="configuration coordinates").copy()
        fq, lq, fv, lv, m, off = self.coupling_index
        q[fq] = m * q[lq] + off
        if v is None:
            return q
        v = door.vector("v", v, self.n_v, owner=owner, what="DOF").copy()
        v[fv] = m * v[lv]
        return q, v

    @cached_property
    def tree(self) -> Model:
        """The model without its couplings (itself when it has none)."""
        import dataclasses

        return dataclasses.replace(self, couplings=()) if self.couplings else self

    @cached_property
    def free_tree(self) -> Model:
        """:attr:`tree` without gravity: M^-1 x is its forward dynamics at v = 0, tau = x."""
        import dataclasses

        return dataclasses.replace(self.tree, gravity=_readonly(np.zeros(3)))

    def locked(self, values: Mapping[str, float | Sequence[float]]) -> Model:
        """The model with the named joints held at the given coordinates (a reduced model, as
        Pinocchio's ``buildReducedModel``): each becomes a fixed joint placed where its motion
        at those values leaves its body, fused into its parent (a body so welded to the world
        is left out). ``values``: a mapping joint name -> its coordinate (R, P) or coordinates
        (U: 2, S: 3, ball: the 4 of its quaternion, free: the 7 of q). Raises CaseError naming
        ``values`` when it is not such a mapping, an unknown joint, or a value that is not the
        joint's count of finite numbers."""
        where = f"{self.name}.locked"
        coupled = {n for c in self.couplings for n in (c.follower, c.leader)}
        if isinstance(values, Mapping) and coupled & set(values):
            _fail(where, "values", sorted(coupled & set(values)), "a coupled joint (a follower "
                  "or a leader of model.couplings): lock the uncoupled model "
                  "(model.with_couplings(())), then couple what is left")
        if self.gravcomp_loads.shape[0]:
            _fail(where, "gravcomp_loads", sorted({self.body_names[int(b)] for b in
                                                   self.gravcomp_loads[:, 0]}),
                  "bodies fused from parts whose gravcomp fractions differ (each part's held "
                  "at its own centre of mass): locking would fuse them again with one "
                  "fraction; lock the model without them (model.without_passive()), or give "
                  "the parts one fraction in the file")
        if self.cuts:
            _fail(where, "cuts", [c.name for c in self.cuts], "a model with cut joints: lock "
                  "joints of the open tree (model.with_cuts(())), then cut it again (the cuts "
                  "name bodies by index, which locking renumbers)")
        if not isinstance(values, Mapping):
            _fail(where, "values", values, "must be a mapping joint name -> coordinate(s), e.g. "
                  f"{{{self.joint_names[0]!r}: 0.0}}")
        index = {name: k for k, name in enumerate(self.joint_names)}
        for name, value in values.items():
            if name not in index:
                shown = ", ".join(self.joint_names[:12]) + (", ..." if self.n_bodies > 12 else "")
                _fail(where, "joint", name, f"no such joint; joints: {shown}")
            k = index[name]
            want = int(self.joint_qoff[k + 1] - self.joint_qoff[k])
            got = numeric_array(value)
            got = None if got is None else np.atleast_1d(got)
            if got is None or got.shape != (want,) or not np.isfinite(got).all():
                _fail(where, f"values[{name!r}]", value, f"a {self.joint_types[k]} joint takes "
                      f"{want} finite coordinate{'s' if want > 1 else ''}"
                      + ("; this is not a number" if got is None else ""))
        bodies, joints = [], []
        for k in range(self.n_bodies):
            bodies.append(Body(self.body_names[k], float(self.mass[k]), tuple(self.com[k]),
                               tuple(map(tuple, self.inertia_com[k])), physical=False,
                               gravcomp=float(self.gravcomp[k])))
            R, p, jt, name = self.placement_R[k], self.placement_p[k], self.joint_types[k], \
                self.joint_names[k]
            sl = slice(self.joint_voff[k], self.joint_voff[k + 1])
            if name in values:
                x = np.atleast_1d(np.asarray(values[name], dtype=float))
                if jt == FREE:
                    Rj, pj = quaternion_matrix(*(x[3:7] / np.linalg.norm(x[3:7]))), x[:3]
                elif jt == BALL_JOINT:
                    Rj, pj = quaternion_matrix(*(x / np.linalg.norm(x))), np.zeros(3)
                else:
                    Rj, pj = joint_transform(list(zip(self.dof_kind[sl], self.dof_u[sl],
                                                      strict=True)), x)
                joints.append(TreeJoint(name, FIXED, rotation=tuple(map(tuple, R @ Rj)),
                                        translation=tuple(p + R @ pj)))
            else:
                axis = tuple(self.dof_u[sl][0]) if jt in ("R", "P") else None
                joints.append(TreeJoint(name, jt, axis, tuple(map(tuple, R)), tuple(p)))
        bodies, joints, parents, kept = drop_world_fixed(bodies, joints, list(self.parent))
        if not bodies:
            _fail(where, "values", sorted(values), "every joint is locked: nothing moves")
        frames = {f: (kept[b], tuple(pt)) for f, (b, pt) in self.frames.items() if b in kept}
        axes = {f: R_f for f, R_f in self.frame_rotations.items() if f in frames}
        per_joint = {key: {name: tuple(getattr(self, key)[self.joint_voff[k]:
                                                          self.joint_voff[k + 1]])
                           for k, name in enumerate(self.joint_names) if name not in values}
                     for key in ("armature", "damping", "stiffness", "spring_ref")}
        out = Model.build(bodies, joints, parents, gravity=tuple(self.gravity),
                          name=f"{self.name} ({len(values)} joints locked)", frames=frames,
                          frame_rotations=axes,
                          source=where, **per_joint)
        return out.with_couplings(self.couplings, source=where) if self.couplings else out

    # ----------------------------------------------------------------------- derived facts
    @cached_property
    def n_bodies(self) -> int:
        return int(self.parent.shape[0])

    @cached_property
    def n_q(self) -> int:
        """Length of the configuration q (7 per free joint, 4 per ball joint)."""
        return int(self.joint_qoff[-1])

    @cached_property
    def n_v(self) -> int:
        """Length of the velocity v (6 per free joint, 3 per ball joint)."""
        return int(self.joint_voff[-1])

    @property
    def n_dof(self) -> int:
        """The number of degrees of freedom, n_v."""
        return self.n_v

    @property
    def total_mass(self) -> float:
        return float(self.mass.sum())

    @cached_property
    def is_chain(self) -> bool:
        """Every body hangs from the one before it (a serial chain)."""
        return bool(np.array_equal(self.parent, np.arange(-1, self.n_bodies - 1)))

    @cached_property
    def chain_layout(self) -> str | None:
        """None when the model is laid out as a chain of links (:class:`Chain`'s layout: each
        body hanging from the one before it by an R, P, U or S joint placed, unrotated, at the
        parent's length along its x axis, the first at the origin, and a frame ``tip`` at the
        last link's length along its x), else what breaks it (for messages)."""
        if not self.is_chain:
            k = int(np.flatnonzero(self.parent != np.arange(-1, self.n_bodies - 1))[0])
            return f"body {self.body_names[k]!r} hangs from body {int(self.parent[k])}: a tree"
        bad = [t for t in self.joint_types if t not in JOINT_TYPES]
        if bad:
            return f"it has a {bad[0]} joint (a chain's are {', '.join(JOINT_TYPES)})"
        p = self.placement_p
        rotated = (self.placement_R != np.eye(3)).any(axis=(1, 2))
        off = (p[:, 1] != 0) | (p[:, 2] != 0) | rotated
        off[0] |= p[0, 0] != 0
        off[1:] |= ~(p[1:, 0] > 0)
        if off.any():
            k = int(np.flatnonzero(off)[0])
            return (f"joint {self.joint_names[k]!r} is not placed, unrotated, at its parent's "
                    "length along the parent's x")
        b, point = self.frames.get("tip", (-1, None))
        if b != self.n_bodies - 1 or point is None or point[1] != 0 or point[2] != 0 \
                or not point[0] > 0:
            return "it has no frame 'tip' at (length, 0, 0) on its last body"
        return None

    def _chain_only(self, what: str) -> None:
        if self.chain_layout is not None:
            raise CaseError(f"model {self.name!r}", what, None, f"defined for a chain of links "
                            f"(Chain's layout); here {self.chain_layout}")

    @cached_property
    def length(self) -> np.ndarray:
        """(nl,) a chain's link lengths l_k [m] (CaseError for a model that is not laid out as
        a chain: :attr:`chain_layout`)."""
        self._chain_only("length")
        out = np.append(self.placement_p[1:, 0], self.frames["tip"][1][0])
        out.flags.writeable = False
        return out

    @property
    def n_links(self) -> int:
        """The number of bodies (a chain's links)."""
        return self.n_bodies

    @cached_property
    def joints(self) -> tuple[Joint, ...]:
        """Each body's joint as a :class:`~redysim.model.parts.Joint` (type, and the axis of an R or
        P joint); CaseError for a free or fixed joint, which a Joint does not describe."""
        out: list[Joint] = []
        shared: dict[tuple[str, tuple[float, float, float] | None], Joint] = {}
        for k, jt in enumerate(self.joint_types):
            if jt not in JOINT_TYPES:
                raise CaseError(f"model {self.name!r}", f"joint {self.joint_names[k]!r}", jt,
                                f"a {jt} joint is not a Joint ({', '.join(JOINT_TYPES)})")
            u = self.dof_u[self.joint_voff[k]]
            axis = None if jt not in ("R", "P") or np.array_equal(u, Joint(jt).axes()[0][1]) \
                else (float(u[0]), float(u[1]), float(u[2]))
            out.append(shared.setdefault((jt, axis), Joint(jt, axis)))
        return tuple(out)

    @cached_property
    def is_planar(self) -> bool:
        """True for a chain (:attr:`chain_layout`) whose joints are each a single revolute about
        their frame's z axis: every axis then stays parallel to the world Z, every link moves in
        the XY plane, and the planar specialisation of the recursion applies. (Out-of-plane
        inertia products, COM offsets along z and a gravity component along Z only load the
        joints with reaction moments and forces normal to the plane; they do not change qdd.)"""
        return bool(self.n_v == self.n_bodies and np.all(self.dof_kind == 0)
                    and np.all(self.dof_axis == 2) and self.chain_layout is None)

    @cached_property
    def quaternions(self) -> np.ndarray:
        """Index in q of the first (w) component of each free or ball joint's quaternion, in
        joint order."""
        return np.array([self.joint_qoff[k] + (3 if t == FREE else 0)
                         for k, t in enumerate(self.joint_types) if t in QUATERNION_JOINTS],
                        dtype=np.int64)

    @cached_property
    def quaternion_rates(self) -> tuple[tuple[int, int], ...]:
        """(q index of the quaternion's w, v index of its angular velocity) of each free or ball
        joint, in joint order: dq/dt there is q (x) [0; w] / 2."""
        return tuple((int(self.joint_qoff[k]) + (3 if t == FREE else 0),
                      int(self.joint_voff[k]) + (3 if t == FREE else 0))
                     for k, t in enumerate(self.joint_types) if t in QUATERNION_JOINTS)

    def neutral(self) -> np.ndarray:
        """The configuration with every joint at zero and every quaternion the identity (a
        follower at its coupling's offset)."""
        q = np.zeros(self.n_q)
        q[self.quaternions] = 1.0
        return self.couple(q) if self.couplings else q

    def initial(self) -> np.ndarray:
        """The configuration the model's file gives (MJCF: MuJoCo's qpos0, joint refs and free
        bodies' poses; URDF: a floating base's pose), else :meth:`neutral`."""
        if self.initial_q is None:
            return self.neutral()
        return self.couple(self.initial_q) if self.couplings else self.initial_q.copy()

    def __getstate__(self) -> dict:
        """Pickling and copying: the model's data, without its per-thread workspaces (scratch,
        never data; a threading.local does not pickle)."""
        state = dict(self.__dict__)
        state.pop(THREAD_WORKSPACES, None)
        return state

    def __setstate__(self, state: dict) -> None:
        """Unpickling: numpy restores arrays writeable; make them read-only views again."""
        for key, value in state.items():
            object.__setattr__(self, key,
                               _readonly(value) if isinstance(value, np.ndarray) else value)
        for key in ("armature", "damping", "stiffness", "spring_ref", "gravcomp"):
            if state.get(key) is None:  # pickled before models had one
                n = self.n_bodies if key == "gravcomp" else self.n_v
                object.__setattr__(self, key, _readonly(np.zeros(n)))
        if state.get("gravcomp_loads") is None:  # pickled before models had them
            object.__setattr__(self, "gravcomp_loads", _readonly(np.zeros((0, 5))))

    def __repr__(self) -> str:
        return (f"Model({self.name!r}, bodies={self.n_bodies}, n_q={self.n_q}, n_v={self.n_v}, "
                f"mass={self.total_mass:.6g} kg)")


@dataclass(frozen=True)
class Coupling:
    """Joint ``follower``'s coordinate held at ``multiplier`` times joint ``leader``'s plus
    ``offset``: q_f = m q_l + offset [rad or m] (a URDF ``<mimic>``, an MJCF joint equality of
    first degree); both R or P joints of the model, named."""

    follower: str
    leader: str
    multiplier: float = 1.0
    offset: float = 0.0

    def __post_init__(self):
        source = f"Coupling {self.follower!r}" if isinstance(self.follower, str) else "Coupling"
        for side in ("follower", "leader"):
            if not isinstance(getattr(self, side), str) or not getattr(self, side):
                raise CaseError(source, side, getattr(self, side), "must be a joint's name")
        for key in ("multiplier", "offset"):
            x = getattr(self, key)
            if isinstance(x, bool) or not isinstance(x, int | float | np.floating | np.integer) \
                    or not math.isfinite(x):
                raise CaseError(source, key, _plain(x), "must be a finite number")
            if key == "multiplier" and abs(x) > MAX_MULTIPLIER:
                raise CaseError(source, key, _plain(x), f"|multiplier| must be <= "
                                f"{MAX_MULTIPLIER:g}: a larger ratio is a unit slip (its "
                                "reflected inertia m^2 I swamps the model, and a run crawls)")
            object.__setattr__(self, key, float(x))


# cut joint -> constraint equations
KINDS = {"point": 3, "planar": 2, "plane": 2, "line": 1, "revolute": 5, "weld": 6}
WORLD = -1  # a cut joint's body_b: the world


@dataclass(frozen=True)
class CutJoint:
    """Point ``point_a`` of body ``body_a`` kept on point ``point_b`` of body ``body_b`` (each
    in its body's frame; ``body_b = -1``: the world, ``point_b`` in world coordinates); for a
    revolute or weld cut also the frames ``rot_a``, ``rot_b`` (3 x 3 rotations in the bodies'
    frames, default the bodies' own; the revolute axis is their z) kept aligned. A ``"plane"``
    cut keeps the points together along the x and y axes of frame ``rot_b`` on body b (the
    plane a mechanism moves in, its normal z: a ``"planar"`` cut in a plane of any
    orientation, which may move with body b); a ``"line"`` cut along the x axis of ``rot_b``
    only (1 equation: what is left of a pin whose other equations repeat other cuts', as the
    second bar of a parallelogram's)."""

    name: str
    body_a: int
    point_a: tuple[float, float, float]
    body_b: int
    point_b: tuple[float, float, float]
    kind: str = "point"
    rot_a: tuple | None = None
    rot_b: tuple | None = None

    def __post_init__(self):
        """Each field checked at construction (CaseError naming it and its value); which
        bodies exist is :func:`check_cuts`'s (a model's) to check."""
        source = f"CutJoint {self.name!r}" if isinstance(self.name, str) else "CutJoint"
        if not isinstance(self.name, str) or not self.name:
            raise CaseError(source, "name", self.name, "must be a non-empty string")
        for side in ("body_a", "body_b"):
            body = getattr(self, side)
            if isinstance(body, bool) or not isinstance(body, int | np.integer):
                raise CaseError(source, side, _plain(body), "must be a body index (a whole "
                                "number" + (", -1 for the world)" if side == "body_b" else ")"))
            object.__setattr__(self, side, int(body))
        if self.kind not in KINDS:
            raise CaseError(source, "kind", self.kind, f"unknown; known: {', '.join(KINDS)}")
        for side in ("point_a", "point_b"):
            p = getattr(self, side)
            a = _numbers(p)
            if a is None or a.shape != (3,) or not np.isfinite(a).all():
                raise CaseError(source, side, _plain(p), "must be 3 finite numbers [m]")
            object.__setattr__(self, side, tuple(float(x) for x in a))
        for side in ("rot_a", "rot_b"):
            R = getattr(self, side)
            if R is None:
                continue
            a = _numbers(R)
            if a is None or a.shape != (3, 3) or not np.isfinite(a).all() or \
                    np.abs(a.T @ a - np.eye(3)).max() > ROTATION_TOL or np.linalg.det(a) < 0:
                raise CaseError(source, side, _plain(R), "must be a 3 x 3 rotation")
            if self.kind not in ("revolute", "weld") and \
                    (self.kind, side) not in (("plane", "rot_b"), ("line", "rot_b")):
                raise CaseError(source, side, _plain(R), f"a frame is aligned by a 'revolute' "
                                f"or 'weld' cut only (a 'plane' cut's rot_b gives its plane, "
                                f"a 'line' cut's its line, x); "
                                f"a {self.kind!r} cut would ignore it")


def _numbers(value) -> np.ndarray | None:
    """``value`` as a float array, or None when it is not numbers (strings, booleans, ...)."""
    try:
        a = np.asarray(value)
    except (ValueError, TypeError):
        return None
    if a.dtype.kind not in "iuf":
        return None
    return a.astype(float)


def _plain(value):
    """A value for a message: numpy scalars and arrays as plain numbers and lists."""
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, np.generic):
        return value.item()
    return value


def check_cuts(model: Model, cuts, source: str) -> None:
    """Refuse cut joints that do not fit ``model`` (CaseError naming the cut and the field): not
    a list of :class:`CutJoint`, none, two of one name, a body index out of range, a cut of a
    body to itself."""
    if isinstance(cuts, CutJoint) or not isinstance(cuts, Sequence) or \
            isinstance(cuts, str):
        raise CaseError(source, "cuts", type(cuts).__name__, "must be a list of CutJoint "
                        "(one per cut joint)")
    if not cuts:
        raise CaseError(source, "cuts", [], "give at least one cut joint")
    nb = model.n_bodies
    names = set()
    for i, c in enumerate(cuts):
        if not isinstance(c, CutJoint):
            raise CaseError(source, f"cuts[{i}]", type(c).__name__, "must be a "
                            "redysim.CutJoint")
        where = f"cut joint {c.name!r}"
        if c.name in names:
            raise CaseError(source, f"{where}.name", c.name, "two cut joints have this name")
        names.add(c.name)
        for side, body in (("body_a", c.body_a), ("body_b", c.body_b)):
            if not -1 <= body < nb or (side == "body_a" and body < 0):
                raise CaseError(source, f"{where}.{side}", body,
                                f"must be a body index in 0..{nb - 1}"
                                + (" or -1 (the world)" if side == "body_b" else ""))
        if c.body_a == c.body_b:
            raise CaseError(source, f"{where}.body_b", c.body_b, "a cut joint joins two "
                            "different bodies (here a body and itself)")


class _Numbered(Sequence):
    """The names prefix1 .. prefixN, as a sequence that holds none of them (a chain's bodies and
    joints: 500,000 strings would be ~30 MB)."""

    def __init__(self, prefix: str, n: int):
        self.prefix, self.n = prefix, int(n)

    def __len__(self) -> int:
        return self.n

    def __getitem__(self, k):
        if isinstance(k, slice):
            return tuple(self[i] for i in range(*k.indices(self.n)))
        k = int(k)
        if k < 0:
            k += self.n
        if not 0 <= k < self.n:
            raise IndexError(k)
        return f"{self.prefix}{k + 1}"

    def _number(self, name) -> int:
        if isinstance(name, str) and name.startswith(self.prefix):
            digits = name[len(self.prefix):]
            if digits.isdigit() and not digits.startswith("0") and 1 <= int(digits) <= self.n:
                return int(digits) - 1
        return -1

    def __contains__(self, name) -> bool:
        return self._number(name) >= 0

    def index(self, name, *args) -> int:
        k = self._number(name)
        if k < 0:
            raise ValueError(f"{name!r} is not in the list")
        return k

    def __eq__(self, other) -> bool:
        return isinstance(other, Sequence) and len(other) == self.n and all(
            a == b for a, b in zip(self, other, strict=True))

    __hash__ = None  # type: ignore[assignment]  # unhashable, as a list is

    def __repr__(self) -> str:
        return f"({self[0]!r}, ..., {self[self.n - 1]!r})" if self.n > 2 else repr(tuple(self))


MEANING = {  # what each per-coordinate (gravcomp: per-body) value of a Model is, for messages
    "armature": "a joint's own inertia: kg m^2 about a rotation, kg along a translation",
    "damping": "a joint's viscous damping: N m s / rad about a rotation, N s / m along a "
               "translation",
    "stiffness": "a joint spring's stiffness: N m / rad about a rotation, N / m along a "
                 "translation",
    "spring_ref": "a joint spring's rest position [rad or m]",
    "gravcomp": "the fraction of a body's weight held up at its centre of mass",
}


def check_armature(source: str, field_name: str, value, n_v: int) -> np.ndarray:
    """``value`` as a read-only (n_v,) array of finite numbers, >= 0 unless ``field_name`` names
    a spring_ref, or CaseError naming ``field_name`` and the value (the armature's, and the
    passive elements' check: :data:`MEANING`)."""
    key = field_name.rsplit(".", 1)[-1].split("[")[0]
    per = "per body" if key == "gravcomp" else "per velocity coordinate (n_v)"
    a = numeric_array(value)
    if a is None or a.shape != (n_v,):
        _fail(source, field_name, _plain(value), f"must be {n_v} numbers, one {per}"
              if a is not None else "must be numbers")
    bad = ~np.isfinite(a) if key == "spring_ref" else ~(np.isfinite(a) & (a >= 0.0))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        _fail(source, f"{field_name}[{i}]", float(a[i]), "must be finite"
              + ("" if key == "spring_ref" else " and >= 0") + f" ({MEANING.get(key, key)})")
    return _readonly(a)


def gravcomp_values(source: str, value, body_names: Sequence[str]) -> np.ndarray:
    """The (nb,) gravcomp of :meth:`Model.with_passive`'s ``value``: a number (every body's),
    one per body, or a mapping body name -> fraction (bodies not named: 0), checked."""
    nb = len(body_names)
    if isinstance(value, Mapping):
        out = np.zeros(nb)
        for name, x in value.items():
            if name not in body_names:
                shown = ", ".join(body_names[i] for i in range(min(12, nb)))
                _fail(source, "gravcomp", name, "no such body; bodies: " + shown
                      + (", ..." if nb > 12 else ""))
            a = numeric_array(x)
            if a is None or a.shape != ():
                _fail(source, f"gravcomp[{name!r}]", _plain(x), "must be one number")
            out[body_names.index(name)] = float(a)
        return check_armature(source, "gravcomp", out, nb)
    a = numeric_array(value)
    if a is not None and a.shape == ():
        a = np.full(nb, float(a))
    return check_armature(source, "gravcomp", value if a is None else a, nb)


def armature_values(source: str, value, n_v: int, joint_names: Sequence[str],
                    joint_voff, key: str = "armature") -> np.ndarray:
    """The (n_v,) armature of :meth:`Model.with_armature`'s ``value`` (None: zeros; a number:
    every coordinate's; n_v numbers; a mapping joint name -> a number for each of its axes, or
    one per axis), checked (:func:`check_armature`); ``key``: which per-coordinate value it is
    (armature, damping, stiffness, spring_ref), for the checks and messages."""
    if value is None:
        return _readonly(np.zeros(n_v))
    if isinstance(value, Mapping):
        out = np.zeros(n_v)
        for name, x in value.items():
            try:
                k = joint_names.index(name)
            except ValueError:
                shown = ", ".join(joint_names[i] for i in range(min(12, len(joint_names))))
                _fail(source, key, name, "no such joint; joints: " + shown
                      + (", ..." if len(joint_names) > 12 else ""))
            width = int(joint_voff[k + 1] - joint_voff[k])
            a = numeric_array(x)
            if a is None or a.shape not in ((), (width,)):
                _fail(source, f"{key}[{name!r}]", x, f"joint {name!r} has {width} "
                      f"velocity coordinate{'s' if width != 1 else ''}: give one number for "
                      f"each, or one for all")
            out[joint_voff[k]:joint_voff[k + 1]] = a
        return check_armature(source, key, out, n_v)
    a = numeric_array(value)
    if a is not None and a.shape == ():
        a = np.full(n_v, float(a))
    return check_armature(source, key, value if a is None else a, n_v)


@dataclass(frozen=True, eq=False)
class Chain(Model):
    """A serial chain of rigid links: a :class:`Model` laid out as a chain, built from links and
    joints (:meth:`build`, :meth:`uniform`, or a case file: :func:`redysim.load_case`).

    Link k (body k, named ``link<k+1>``) hangs from link k - 1 by joint k (``joint<k+1>``),
    placed, unrotated, at the parent's length along its x axis; the frame ``tip`` is the last
    link's distal end. Everything a Model has, a chain has, with the same numbers a tree built
    body by body would have; besides, :attr:`length` (the link lengths) and :attr:`joints` (the
    Joint objects it was built from) are kept. Built in O(n) numpy operations (each distinct
    Link and Joint checked once), so 500,000 links build in seconds.
    """

    # a chain's own constructor, from links (not Model.build's bodies, joints and parents)
    @classmethod
    def build(  # type: ignore[override]
            cls, links: Sequence[Link], joints: Sequence[Joint | str], *,
            gravity: Sequence[float] = (0.0, -STANDARD_GRAVITY, 0.0), name: str = "chain",
            source: str = "chain", armature=None) -> Chain:
        """Validate and freeze a chain. ``joints`` may be Joint objects or type names;
        ``armature`` as :meth:`Model.with_armature` takes it (joints named ``joint<k+1>``)."""
        if len(links) == 0:
            raise CaseError(source, "links", len(links), "a chain needs at least one link")
        if len(joints) != len(links):
            raise CaseError(source, "joints", len(joints),
                            f"need one joint per link ({len(links)} links)")
        named: dict[str, Joint] = {}  # one Joint per type name, so that repeats are shared
        chain_joints = tuple(j if isinstance(j, Joint) else
                             named.setdefault(str(j), Joint(str(j))) for j in joints)
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
                    raise CaseError(source, where, link, "must be a redysim.Link")
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
        for k, joint in enumerate(chain_joints):
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
            raise CaseError(source, f"links[{k}].com", [float(x) for x in com[k]],
                            f"the inertia about the joint, I_C + m (|c|^2 1 - c c^T) with m = "
                            f"{mass[k]}, overflows: values too large")
        # the tree: link k hangs from link k - 1, placed at its length along the parent's x
        placement_p = np.zeros((nl, 3))
        placement_p[1:, 0] = length[:-1]
        eye = np.broadcast_to(np.eye(3), (nl, 3, 3))  # read-only, no memory: all unrotated
        qoff = _readonly(qoff.astype(np.int64))
        chain = cls(
            name=name, body_names=_Numbered("link", nl), joint_names=_Numbered("joint", nl),
            joint_types=tuple(j.type for j in chain_joints),
            parent=_readonly(np.arange(-1, nl - 1, dtype=np.int64)), placement_R=eye,
            placement_p=_readonly(placement_p),
            placement_code=_readonly(np.zeros(nl, dtype=np.int64)),
            joint_qoff=qoff, joint_voff=qoff, dof_kind=_readonly(kinds),
            dof_axis=_readonly(codes), dof_u=_readonly(units), mass=_readonly(mass),
            com=_readonly(com), inertia_com=_readonly(inertia), inertia_O=_readonly(inertia_O),
            mass_com=_readonly(mass_com), gravity=_readonly(grav),
            frames={"tip": (nl - 1, (float(length[-1]), 0.0, 0.0))},
            armature=armature_values(source, armature, int(qoff[-1]),
                                     _Numbered("joint", nl), qoff))
        # what the chain was built from, as Model's derived attributes would give them back
        object.__setattr__(chain, "length", _readonly(length))
        object.__setattr__(chain, "joints", chain_joints)
        object.__setattr__(chain, "chain_layout", None)
        return chain

    @classmethod
    def uniform(cls, n_links: int, joint: str | Joint = "U", *, length: float = 1.0,
                mass: float | None = None, linear_density: float | None = None,
                radius: float = 0.0, inertia: str = "rod",
                gravity: Sequence[float] = (0.0, -STANDARD_GRAVITY, 0.0),
                name: str | None = None, armature=None) -> Chain:
        """A chain of ``n_links`` identical uniform links with identical joints.

        Give the link ``mass`` or the ``linear_density`` (kg/m); ``length`` is per link;
        ``armature`` as :meth:`Chain.build` takes it.
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
                         name=name or f"{joint.type}{n_links}", armature=armature)

    def __repr__(self) -> str:
        types = "".join(sorted(set(self.joint_types)))
        return (f"Chain({self.name!r}, links={self.n_links}, dof={self.n_dof}, joints={types}, "
                f"mass={self.total_mass:.6g} kg)")
