"""DART adapter (dartpy): a Skeleton of one Joint + BodyNode pair per link, no massless bodies.

What the model contains and why (docs/design.md, "Reference engines"):

- per link one ``create...JointAndBodyNodePair`` whose joint is the link's whole joint, chosen by
  its elementary axes (``references.base.joint_axes``):

  * one R axis: ``RevoluteJoint``, ``mAxis = u``; one P axis: ``PrismaticJoint``, ``mAxis = u``
    (any unit u, -z included: DART rotates about, or slides along, exactly the given vector);
  * two R axes (U): ``UniversalJoint``, ``mAxis = [u1, u2]``; DART's transform is
    Rot(u1, q1) Rot(u2, q2), the second axis in the rotated frame (R = Ry(q1) Rz(q2) for U);
  * three R axes forming a right-handed orthonormal triad (S: y, then z, then x):
    ``EulerJoint``, whose only axis order reachable from Python (``mAxisOrder`` is an unregistered
    type in dartpy 6.20) is its default XYZ, R = Rx(q1) Ry(q2) Rz(q3), checked numerically when
    the first one is built. With P = [u1 u2 u3] (a rotation), P Rx P^T = Rot(u1, .), ..., so
    ``mT_ParentBodyToJoint`` rotated by P and ``mT_ChildBodyToJoint`` rotated by P give the
    child frame the rotation P Rx(q1) Ry(q2) Rz(q3) P^T = Rot(u1, q1) Rot(u2, q2) Rot(u3, q3),
    the core's S joint, with the link frame (the BodyNode's) unrotated.
  * anything else is refused by ``limits()`` (no joint type in DART composes it). Building it
    from several joints needs massless intermediate BodyNodes, which DART warns against ("A
    negative or zero mass [0] is set to BodyNode [...], which can cause invalid physical behavior
    or segfault"; its ``Inertia`` also warns that zero moments are invalid), so this adapter does
    not. No joint of ``redysim.chain.JOINT_TYPES`` needs that.

  ``mT_ParentBodyToJoint`` translates l_{k-1} along the parent's x (identity for the first joint,
  whose parent is the world); ``mT_ChildBodyToJoint`` is the identity (the link frame is at the
  joint) but for the EulerJoint's rotation P. A PrismaticJoint moves the BodyNode (the link
  frame) by u q, so the next joint starts l_k further along the moved frame's x, as in the core.
- ``BodyNode.setInertia(Inertia(m, c, I_C))`` (inertia about the COM in the link frame);
- ``skel.setGravity(chain.gravity)``.
- No ShapeNodes (so no collision or visual geometry), self-collision check off (DART's default),
  joint damping, spring stiffness, friction and position-limit enforcement left at their
  zero/off defaults and asserted off after the build.

``qdd``: ``setPositions/setVelocities/setForces(tau)`` then ``computeForwardDynamics()``
(articulated-body algorithm) and ``getAccelerations()``; ``mass_matrix``: ``getMassMatrix()``;
``bias``: ``-getCoriolisAndGravityForces()``; ``energy``: ``computeKineticEnergy()`` and
``computePotentialEnergy()``; ``tip``: the last BodyNode's world transform applied to (l, 0, 0).

``simulate``: a ``dartpy.simulation.World`` holding only this skeleton, ``World.step()`` at the
fixed time step h (DART's semi-implicit Euler). With no shapes the collision detector finds
nothing and the constraint solver has no constraint to solve.

Limit: building the skeleton costs ~n^3 in time (54 s at 2,000 DOF; docs/design.md, "Reference
engines"), so time, not memory, stops it (references/limits.toml).

Trees (``references.trees``): ``DARTTree`` builds a :class:`redysim.Model` with the same
joints, each at ``mT_ParentBodyToJoint`` = its placement, roots on the world (a Skeleton holds
several trees), a free joint as ``FreeJoint``, whose coordinates differ from the core's
(rotation vector and translation; velocity (w_world, v_world)): converted both ways (class
docstring). It refuses a massless body (no massless BodyNodes, as above).
"""

from __future__ import annotations

import numpy as np

from redysim.model import FREE

from .base import Engine
from .trees import FreeBlock, TreeEngine, free_rotation


def _construction(axes) -> str | None:
    """Which DART joint builds these elementary axes as one joint: "revolute", "prismatic",
    "universal", "euler" (three revolute axes, a right-handed orthonormal triad), or None."""
    kinds = "".join(a.kind for a in axes)
    if kinds == "R":
        return "revolute"
    if kinds == "P":
        return "prismatic"
    if kinds == "RR":
        return "universal"
    if kinds == "RRR":
        P = np.array([a.u for a in axes]).T
        if np.abs(P.T @ P - np.eye(3)).max() < 1e-12 and np.linalg.det(P) > 0:
            return "euler"
    return None


_EULER_XYZ: list[bool] = []  # checked once per process


def _check_euler_order(dart) -> None:
    """Assert that a default EulerJoint turns as Rx(q1) Ry(q2) Rz(q3) (XYZ, DART's default
    ``mAxisOrder``, which dartpy cannot read or set)."""
    if _EULER_XYZ:
        return
    dyn = dart.dynamics
    skel = dyn.Skeleton("euler-order-check")
    _, body = skel.createEulerJointAndBodyNodePair(None, dyn.EulerJointProperties())
    q = np.array([0.3, -0.7, 1.1])
    skel.setPositions(q)
    got = np.array(body.getWorldTransform().matrix())[:3, :3]
    c, s = np.cos(q), np.sin(q)
    rx = np.array([[1, 0, 0], [0, c[0], -s[0]], [0, s[0], c[0]]])
    ry = np.array([[c[1], 0, s[1]], [0, 1, 0], [-s[1], 0, c[1]]])
    rz = np.array([[c[2], -s[2], 0], [s[2], c[2], 0], [0, 0, 1]])
    err = np.abs(got - rx @ ry @ rz).max()
    if not err < 1e-14:
        raise AssertionError(f"DART's default EulerJoint is not XYZ (differs by {err:.2e})")
    _EULER_XYZ.append(True)


class DART(Engine):
    """DART ``computeForwardDynamics`` (ABA) on a skeleton of one joint per link (module doc)."""

    name = "dart"
    package = "dartpy"
    module = "dartpy"
    integrator = "World.step, semi-implicit Euler, fixed step"

    @classmethod
    def unsupported(cls, joint):
        if _construction(joint.axes) is None:
            return ("DART has one joint type per BodyNode and none that composes these axes; "
                    "splitting the joint needs massless BodyNodes, which DART warns 'can cause "
                    "invalid physical behavior or segfault'")
        return ""

    def _build(self):
        dart = self.lib
        dyn = dart.dynamics
        c = self.chain
        skel = dyn.Skeleton(c.name)
        parent = None
        bodies = []
        makers = {"revolute": (dyn.RevoluteJointProperties,
                               skel.createRevoluteJointAndBodyNodePair),
                  "prismatic": (dyn.PrismaticJointProperties,
                                skel.createPrismaticJointAndBodyNodePair),
                  "universal": (dyn.UniversalJointProperties,
                                skel.createUniversalJointAndBodyNodePair),
                  "euler": (dyn.EulerJointProperties, skel.createEulerJointAndBodyNodePair)}
        for k, joint in enumerate(self.joints):
            how = _construction(joint.axes)
            props_cls, make = makers[how]
            props = props_cls()
            T = dart.math.Isometry3()
            T.set_identity()
            if k > 0:
                T.set_translation(np.array([c.length[k - 1], 0.0, 0.0]))
            if how == "euler":
                _check_euler_order(dart)
                P = np.array([a.u for a in joint.axes]).T  # columns u1, u2, u3: a rotation
                T.set_rotation(P)
                C = dart.math.Isometry3()
                C.set_identity()
                C.set_rotation(P)
                props.mT_ChildBodyToJoint = C
            elif how == "universal":
                props.mAxis = [joint.axes[0].vector, joint.axes[1].vector]
            else:
                props.mAxis = joint.axes[0].vector
            props.mT_ParentBodyToJoint = T
            props.mName = f"j{k}"
            _, body = make(parent, props)
            body.setInertia(dyn.Inertia(float(c.mass[k]), np.array(c.com[k]),
                                        np.array(c.inertia_com[k])))
            bodies.append(body)
            parent = body
        skel.setGravity(np.asarray(c.gravity, dtype=float))
        for j in skel.getJoints():
            assert not j.areLimitsEnforced()
            for i in range(j.getNumDofs()):
                assert j.getDampingCoefficient(i) == 0 and j.getSpringStiffness(i) == 0
                assert j.getCoulombFriction(i) == 0
        assert not skel.getSelfCollisionCheck()
        self.skel, self.tip_body = skel, bodies[-1]
        self.world = None
        if skel.getNumDofs() != c.n_dof:
            raise AssertionError(f"skeleton has {skel.getNumDofs()} DOF, chain {c.n_dof}")

    def _set(self, q, qd, tau=None):
        s = self.skel
        s.setPositions(q)
        s.setVelocities(qd)
        s.setForces(np.zeros_like(q) if tau is None else tau)

    def _qdd(self, q, qd, tau):
        self._set(q, qd, tau)
        self.skel.computeForwardDynamics()
        return np.array(self.skel.getAccelerations())

    def _mass_matrix(self, q):
        self._set(q, np.zeros_like(q))
        return np.array(self.skel.getMassMatrix())

    def _bias(self, q, qd):
        self._set(q, qd)
        return -np.array(self.skel.getCoriolisAndGravityForces())

    def _energy(self, q, qd):
        self._set(q, qd)
        return self.skel.computeKineticEnergy(), self.skel.computePotentialEnergy()

    def _tip(self, q, qd):
        self._set(q, qd)
        M = np.array(self.tip_body.getWorldTransform().matrix())
        return M[:3, :3] @ np.array([self.chain.length[-1], 0.0, 0.0]) + M[:3, 3]

    def _sim_reset(self, q0, qd0, h):
        if self.world is None:
            self.world = self.lib.simulation.World()
            self.world.setGravity(np.asarray(self.chain.gravity, dtype=float))
            self.world.addSkeleton(self.skel)
        self.world.setTimeStep(h)
        self.world.setTime(0.0)
        self._set(q0, qd0)

    def _sim_step(self):
        self.world.step()

    def _sim_state(self):
        return np.array(self.skel.getPositions()), np.array(self.skel.getVelocities())


# --------------------------------------------------------------------------- trees
class DARTTree(TreeEngine):
    """DART on a :class:`redysim.Model` (``references.trees``).

    One Joint + BodyNode pair per Model body, built as for chains (``_construction``), the
    parent BodyNode the parent body's (None for a root: a Skeleton holds several trees),
    ``mT_ParentBodyToJoint`` the placement (R, p) (times P for an EulerJoint); a free joint is a
    ``FreeJoint`` at the identity. DART numbers DOF tree by tree; the adapter maps them by
    ``getIndexInSkeleton``.

    Free joint, converted both ways: dartpy 6.20's FreeJoint has positions (rotation vector,
    translation) and velocities (w_world, v_world), the angular velocity in the WORLD frame first
    (its relative Jacobian is diag(R^T, R^T), measured). Positions come from
    ``FreeJoint.convertToPositions(Isometry3(R, p))``; the two halves of the velocity are
    swapped by the index map, so that y = (v_world, w_world) in the core's slots, and then
    B = diag(1, R^T) and c = 0, as d/dt (R^T w_world) = R^T dw_world/dt (w x w = 0).

    Refused by ``limits``: a massless body (DART warns that a zero mass "can cause invalid
    physical behavior or segfault"), and joints no DART joint composes (none of the Model's).
    """

    name = "dart"
    package = "dartpy"
    module = "dartpy"

    @classmethod
    def unsupported(cls, model, joints):
        for k, joint in enumerate(joints):
            if joint.type != FREE and _construction(joint.axes) is None:
                return (f"body {k} ({model.body_names[k]}), joint {joint.describe()}: DART has "
                        f"one joint type per BodyNode and none that composes these axes")
            if not model.mass[k] > 0.0:
                return (f"body {k} ({model.body_names[k]}) is massless: DART warns that a zero "
                        f"mass 'can cause invalid physical behavior or segfault'")
        return ""

    def _build(self):
        dart = self.lib
        dyn = dart.dynamics
        m = self.model
        skel = dyn.Skeleton(m.name)
        makers = {"revolute": (dyn.RevoluteJointProperties,
                               skel.createRevoluteJointAndBodyNodePair),
                  "prismatic": (dyn.PrismaticJointProperties,
                                skel.createPrismaticJointAndBodyNodePair),
                  "universal": (dyn.UniversalJointProperties,
                                skel.createUniversalJointAndBodyNodePair),
                  "euler": (dyn.EulerJointProperties, skel.createEulerJointAndBodyNodePair),
                  "free": (dyn.FreeJointProperties, skel.createFreeJointAndBodyNodePair)}
        bodies, djoints = [], []
        for k, joint in enumerate(self.joints):
            how = "free" if joint.type == FREE else _construction(joint.axes)
            props_cls, make = makers[how]
            props = props_cls()
            T = dart.math.Isometry3()
            T.set_identity()
            T.set_translation(joint.p)
            T.set_rotation(joint.R)
            if how == "euler":
                _check_euler_order(dart)
                P = np.array([a.u for a in joint.axes]).T
                T.set_rotation(joint.R @ P)
                C = dart.math.Isometry3()
                C.set_identity()
                C.set_rotation(P)
                props.mT_ChildBodyToJoint = C
            elif how == "universal":
                props.mAxis = [joint.axes[0].vector, joint.axes[1].vector]
            elif how in ("revolute", "prismatic"):
                props.mAxis = joint.axes[0].vector
            props.mT_ParentBodyToJoint = T
            props.mName = f"j{k}"
            dj, body = make(None if joint.parent < 0 else bodies[joint.parent], props)
            body.setInertia(dyn.Inertia(float(m.mass[k]), np.array(m.com[k]),
                                        np.array(m.inertia_com[k])))
            bodies.append(body)
            djoints.append(dj)
        skel.setGravity(np.asarray(m.gravity, dtype=float))
        for j in skel.getJoints():
            assert not j.areLimitsEnforced()
            for i in range(j.getNumDofs()):
                assert j.getDampingCoefficient(i) == 0 and j.getSpringStiffness(i) == 0
                assert j.getCoulombFriction(i) == 0
        assert not skel.getSelfCollisionCheck()
        if skel.getNumDofs() != m.n_v:
            raise AssertionError(f"skeleton has {skel.getNumDofs()} DOF, the tree {m.n_v}")
        # the core's slots -> DART's (a free joint's DART DOF are w_world, v_world: swapped)
        self.free = []
        for k, (joint, dj) in enumerate(zip(self.joints, djoints, strict=True)):
            vs = int(m.joint_voff[k])
            idx = [dj.getIndexInSkeleton(i) for i in range(dj.getNumDofs())]
            if joint.type == FREE:
                self.eidx[vs:vs + 6] = idx[3:] + idx[:3]
                self.free.append((int(m.joint_qoff[k]), vs, idx))
            else:
                self.eidx[vs:vs + len(idx)] = idx
        self.skel = skel

    def _engine_state(self, q, v):
        m = self.model
        qe = np.zeros(m.n_v)
        blocks = []
        for k, joint in enumerate(self.joints):
            if joint.type != FREE:
                qe[self.eidx[m.joint_voff[k]:m.joint_voff[k + 1]]] = \
                    q[m.joint_qoff[k]:m.joint_qoff[k + 1]]
        for qs, vs, idx in self.free:
            R = free_rotation(q, qs)
            T = self.lib.math.Isometry3()
            T.set_identity()
            T.set_rotation(R)
            T.set_translation(q[qs:qs + 3])
            qe[idx] = self.lib.dynamics.FreeJoint.convertToPositions(T)
            B = np.eye(6)  # y gathered in the core's slots (eidx) is (v_world, w_world)
            B[3:, 3:] = R.T
            blocks.append(FreeBlock(vs, B, np.zeros(6)))
        return qe, blocks

    def _set(self, qe, y, tau_e=None):
        s = self.skel
        s.setPositions(qe)
        s.setVelocities(y)
        s.setForces(np.zeros(self.n_e) if tau_e is None else tau_e)

    def _raw_qdd(self, qe, y, tau_e):
        self._set(qe, y, tau_e)
        self.skel.computeForwardDynamics()
        return np.array(self.skel.getAccelerations())

    def _raw_mass_matrix(self, qe):
        self._set(qe, np.zeros(self.n_e))
        return np.array(self.skel.getMassMatrix())

    def _raw_bias(self, qe, y):
        self._set(qe, y)
        return -np.array(self.skel.getCoriolisAndGravityForces())

    def _raw_energy(self, qe, y):
        self._set(qe, y)
        return self.skel.computeKineticEnergy(), self.skel.computePotentialEnergy()
