"""Kinematic trees: bodies with a parent, joints placed by a fixed transform in the parent's frame.

A :class:`Model` is an immutable tree of rigid bodies. Body k (k = 0..nb-1, parents before
children: ``parent[k] < k``, -1 for the base) hangs from its parent by joint k, whose frame sits
at the placement (rotation ``placement_R[k]``, translation ``placement_p[k]``) in the parent
body's frame; the joint's motion then carries body k's frame away from the joint frame. Joint
types are those of :data:`redysim.chain.JOINT_TYPES` (R and P about any axis, U, S: sequences of
elementary axes, each in the frame the axes before it leave) and two more:

- ``fixed``: no motion. Fused when the model is built: the body's mass, centre of mass and
  inertia are added to its parent's, its children and frames are re-placed on the parent, so a
  fixed joint costs nothing per call.
- ``free``: a floating body (the base of a legged or flying robot), allowed only where the parent
  is the base. Configuration q = (x, y, z, qw, qx, qy, qz): the body origin's world position and a
  unit quaternion (n_q = 7); velocity v = (v_x, v_y, v_z, w_x, w_y, w_z): the body origin's
  velocity in the world frame and the body's angular velocity in its own frame (n_v = 6): the
  convention of MuJoCo's free joint. dq/dt = (v_world, q (x) [0; w_body] / 2).

Everything a chain is, a tree is: :meth:`Model.from_chain` gives the tree of a
:class:`~redysim.chain.Chain` (parent k - 1, each joint placed at the parent's length along its x
axis), with the same numbers.

Per-DOF tables follow the chain's (``dof_kind``, ``dof_axis``, ``dof_u``) over the n_v velocity
coordinates, with a third kind, ``BALL`` (the three rotational DOF of a free joint, about the
body's own axes). ``joint_qoff`` and ``joint_voff`` give each joint's first configuration and
velocity coordinate.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from .chain import (
    GENERAL_AXIS,
    JOINT_TYPES,
    KIND_CODES,
    STANDARD_GRAVITY,
    Chain,
    Joint,
    _readonly,
    check_inertia,
    check_positive,
    check_vector,
    numeric_array,
)
from .errors import CaseError

BALL = 2  # dof_kind of a free joint's rotational DOF (about the body's own x, y, z)
FREE, FIXED = "free", "fixed"
TREE_JOINT_TYPES = (*JOINT_TYPES, FREE, FIXED)
ROTATION_TOL = 1e-9  # |R^T R - 1| allowed in a placement rotation given by the user


def _fail(source, field_name, value, problem):
    raise CaseError(source, field_name, value, problem)


@dataclass(frozen=True)
class Body:
    """A rigid body: mass, centre of mass and inertia about the COM, all in the body's frame.

    ``physical``: the inertia must satisfy the triangle inequality (see :class:`redysim.Link`).
    A body may be massless (mass 0, zero inertia), e.g. a frame between two joints, as long as
    something it carries gives every joint axis inertia to move.
    """

    name: str
    mass: float
    com: tuple[float, float, float] = (0.0, 0.0, 0.0)
    inertia: tuple[tuple[float, float, float], ...] = ((0.0, 0.0, 0.0),) * 3
    physical: bool = True


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


def joint_transform(axes: Sequence[tuple[int, np.ndarray]], values: Sequence[float]
                    ) -> tuple[np.ndarray, np.ndarray]:
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
    """An immutable kinematic tree. Build it with :meth:`Model.build` (or from a chain with
    :meth:`Model.from_chain`, from a file with :func:`redysim.load_model`).

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
        dof_kind, dof_axis, dof_u: (n_v,) as a Chain's, with BALL for a free joint's rotation.
        mass, com, inertia_com, inertia_O, mass_com: per body, as a Chain's per link.
        gravity:          (3,) world gravity [m/s^2].
        frames:           name -> (body, point in its frame): points of interest (a chain's tip).
        notes:            what the model's file holds and the model does not, one line each
                          (:mod:`redysim.importers`: dropped attributes, things not read).
    """

    name: str
    body_names: tuple[str, ...]
    joint_names: tuple[str, ...]
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
    notes: tuple[str, ...] = ()  # what the file holds and the model does not, one line each
    initial_q: np.ndarray | None = None  # a configuration the file gives (MJCF's qpos0)

    # ----------------------------------------------------------------------- building
    @classmethod
    def build(cls, bodies: Sequence[Body], joints: Sequence[TreeJoint], parents: Sequence[int], *,
              gravity: Sequence[float] = (0.0, -STANDARD_GRAVITY, 0.0), name: str = "model",
              frames: Mapping[str, tuple[int, Sequence[float]]] | None = None,
              source: str = "model") -> Model:
        """Validate and freeze a tree: body k hangs from ``parents[k]`` (-1: the base) by
        ``joints[k]``; ``parents[k] < k``. Fixed joints are fused into their parents here.
        Raises CaseError naming ``source``, the field (a body or joint by its name and index:
        ``body 'arm' (bodies[1]).mass``, ``joint 'elbow' (joints[1]).axis``) and the value."""
        nb = len(bodies)
        if nb == 0:
            _fail(source, "bodies", 0, "a model needs at least one body")
        if len(joints) != nb or len(parents) != nb:
            _fail(source, "joints/parents", (len(joints), len(parents)),
                  f"need one joint and one parent per body ({nb} bodies)")
        body_name, mass, com, inertia = [], [], [], []
        jname, jtype, axes, par, plR, plp = [], [], [], [], [], []
        for k, (b, j, p) in enumerate(zip(bodies, joints, parents, strict=True)):
            if not isinstance(b, Body):
                _fail(source, f"bodies[{k}]", b, "must be a redysim.Body")
            if not isinstance(j, TreeJoint):
                _fail(source, f"joints[{k}]", j, "must be a redysim.TreeJoint")
            where, jwhere = f"body {b.name!r} (bodies[{k}])", f"joint {j.name!r} (joints[{k}])"
            if isinstance(p, bool) or not isinstance(p, int | np.integer) or not -1 <= p < k:
                _fail(source, f"parents[{k}]", p, f"must be -1 (the base) or a body before it "
                      f"(0..{k - 1}): bodies are listed parents first")
            m = check_positive(source, f"{where}.mass", b.mass, allow_zero=True)
            c = check_vector(source, f"{where}.com", b.com, 3)
            I_c = check_inertia(source, f"{where}.inertia", b.inertia, physical=b.physical)
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
            body_name.append(str(b.name))
            mass.append(m)
            com.append(c)
            inertia.append(I_c)
            jname.append(str(j.name))
            jtype.append(j.type)
            axes.append(None if j.type in (FREE, FIXED) else
                        Joint(j.type, j.axis).axes(source, jwhere))
            par.append(int(p))
            plR.append(_rotation(source, f"{jwhere}.rotation", j.rotation))
            plp.append(check_vector(source, f"{jwhere}.translation", j.translation, 3))
        frames = {fname: (int(fb), np.asarray(fp, dtype=float))
                  for fname, (fb, fp) in (frames or {}).items()}
        for fname, (fb, fp) in frames.items():
            if not 0 <= fb < nb:
                _fail(source, f"frames.{fname}", fb, f"body index must be in 0..{nb - 1}")
            check_vector(source, f"frames.{fname}", fp, 3)

        # fuse fixed joints, children after parents: body k moves into its (kept) ancestor
        into = list(range(nb))  # the kept body each body ends in
        to_kept_R = [np.eye(3) for _ in range(nb)]  # body frame -> that kept body's frame
        to_kept_p = [np.zeros(3) for _ in range(nb)]
        for k in range(nb):
            if jtype[k] != FIXED:
                continue
            if par[k] == -1:
                _fail(source, f"joint {jname[k]!r} (joints[{k}]).type", FIXED, "a body fixed to "
                      "the base does not move: leave it out (or give the model a frame for it)")
            a = into[par[k]]
            R = to_kept_R[par[k]] @ plR[k]
            p = to_kept_R[par[k]] @ plp[k] + to_kept_p[par[k]]
            into[k], to_kept_R[k], to_kept_p[k] = a, R, p
            mass[a], com[a], inertia[a] = _combine(mass[a], com[a], inertia[a], mass[k],
                                                   R @ com[k] + p, R @ inertia[k] @ R.T)
        kept = [k for k in range(nb) if jtype[k] != FIXED]
        index = {k: i for i, k in enumerate(kept)}
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
        frames = {fname: (index[into[fb]], tuple(to_kept_R[fb] @ fp + to_kept_p[fb]))
                  for fname, (fb, fp) in frames.items()}

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
            for kind, u in axes[k]:
                kinds.append(KIND_CODES[kind])
                codes.append(next((i for i in range(3) if np.array_equal(u, np.eye(3)[i])),
                                  GENERAL_AXIS))
                units.append(u)
            qoff.append(qoff[-1] + len(axes[k]))
            voff.append(voff[-1] + len(axes[k]))
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
            frames=frames)

    @classmethod
    def from_chain(cls, chain: Chain) -> Model:
        """The tree of a serial chain: body k is link k, hanging from link k - 1 by joint k,
        placed at l_{k-1} along the parent's x; the frame ``tip`` is the last link's distal end."""
        nl = chain.n_links
        bodies = [Body(f"link{k + 1}", float(chain.mass[k]), tuple(chain.com[k]),
                       tuple(map(tuple, chain.inertia_com[k])), physical=False)
                  for k in range(nl)]
        joints = [TreeJoint(f"joint{k + 1}", j.type, j.axis,
                            translation=(float(chain.length[k - 1]) if k else 0.0, 0.0, 0.0))
                  for k, j in enumerate(chain.joints)]
        return cls.build(bodies, joints, list(range(-1, nl - 1)), gravity=chain.gravity,
                         name=chain.name, frames={"tip": (nl - 1, (chain.length[-1], 0, 0))})

    def locked(self, values: Mapping[str, float | Sequence[float]]) -> Model:
        """The model with the named joints held at the given coordinates (a reduced model, as
        Pinocchio's ``buildReducedModel``): each becomes a fixed joint placed where its motion
        at those values leaves its body, fused into its parent (a body so welded to the world
        is left out). ``values``: a mapping joint name -> its coordinate (R, P) or coordinates
        (U: 2, S: 3, free: the 7 of q). Raises CaseError naming ``values`` when it is not such a
        mapping, an unknown joint, or a value that is not the joint's count of finite numbers."""
        where = f"{self.name}.locked"
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
                               tuple(map(tuple, self.inertia_com[k])), physical=False))
            R, p, jt, name = self.placement_R[k], self.placement_p[k], self.joint_types[k], \
                self.joint_names[k]
            sl = slice(self.joint_voff[k], self.joint_voff[k + 1])
            if name in values:
                x = np.atleast_1d(np.asarray(values[name], dtype=float))
                if jt == FREE:
                    Rj, pj = quaternion_matrix(*(x[3:7] / np.linalg.norm(x[3:7]))), x[:3]
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
        return Model.build(bodies, joints, parents, gravity=tuple(self.gravity),
                           name=f"{self.name} ({len(values)} joints locked)", frames=frames,
                           source=where)

    # ----------------------------------------------------------------------- derived facts
    @cached_property
    def n_bodies(self) -> int:
        return int(self.parent.shape[0])

    @cached_property
    def n_q(self) -> int:
        """Length of the configuration q (7 per free joint)."""
        return int(self.joint_qoff[-1])

    @cached_property
    def n_v(self) -> int:
        """Length of the velocity v (6 per free joint)."""
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
    def quaternions(self) -> np.ndarray:
        """Index in q of the first (w) component of each free joint's quaternion."""
        return np.array([self.joint_qoff[k] + 3 for k, t in enumerate(self.joint_types)
                         if t == FREE], dtype=np.int64)

    def neutral(self) -> np.ndarray:
        """The configuration with every joint at zero and every quaternion the identity."""
        q = np.zeros(self.n_q)
        q[self.quaternions] = 1.0
        return q

    def initial(self) -> np.ndarray:
        """The configuration the model's file gives (MJCF: MuJoCo's qpos0, joint refs and free
        bodies' poses; URDF: a floating base's pose), else :meth:`neutral`."""
        return self.neutral() if self.initial_q is None else self.initial_q.copy()

    def __repr__(self) -> str:
        return (f"Model({self.name!r}, bodies={self.n_bodies}, n_q={self.n_q}, n_v={self.n_v}, "
                f"mass={self.total_mass:.6g} kg)")
