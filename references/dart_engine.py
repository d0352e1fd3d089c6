"""DART adapter (dartpy): a Skeleton of UniversalJoint / RevoluteJoint + BodyNode pairs.

What the model contains and why (DESIGN.md section 6):

- per link one ``create{Universal,Revolute}JointAndBodyNodePair``: ``UniversalJointProperties.mAxis
  = [y, z]`` (R = Ry(q1) Rz(q2)), ``RevoluteJointProperties.mAxis = z``; ``mT_ParentBodyToJoint``
  an ``Isometry3`` translating l_{k-1} along the parent's x (identity for the first joint, whose
  parent is the world), ``mT_ChildBodyToJoint`` identity (the link frame is at the joint);
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

Limit: building the skeleton costs ~n^3 in time (54 s at 2,000 DOF, DESIGN.md section 5), so
time, not memory, stops it (references/limits.toml).
"""

from __future__ import annotations

import numpy as np

from .base import Engine


class DART(Engine):
    """DART ``computeForwardDynamics`` (ABA) on a UniversalJoint/RevoluteJoint skeleton."""

    name = "dart"
    package = "dartpy"
    module = "dartpy"
    integrator = "World.step, semi-implicit Euler, fixed step"

    def _build(self):
        dart = self.lib
        dyn = dart.dynamics
        c = self.chain
        skel = dyn.Skeleton(c.name)
        parent = None
        bodies = []
        for k, kind in enumerate(self.kinds):
            if kind == "U":
                props = dyn.UniversalJointProperties()
                props.mAxis = [np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0])]
            else:
                props = dyn.RevoluteJointProperties()
                props.mAxis = np.array([0.0, 0.0, 1.0])
            T = dart.math.Isometry3()
            T.set_identity()
            if k > 0:
                T.set_translation(np.array([c.length[k - 1], 0.0, 0.0]))
            props.mT_ParentBodyToJoint = T
            props.mName = f"j{k}"
            make = (skel.createUniversalJointAndBodyNodePair if kind == "U"
                    else skel.createRevoluteJointAndBodyNodePair)
            joint, body = make(parent, props)
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
