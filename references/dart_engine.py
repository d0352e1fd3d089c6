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
"""

from __future__ import annotations

import numpy as np

from .base import Engine


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
