"""Pinocchio adapters: ABA (``pin.aba``) and CRBA + Cholesky, with two ways to model a U joint.

Engines (``references.ENGINES``):

- ``pinocchio-aba``: ``pin.aba`` on a model with one ``JointModelUniversal(y, z)`` per U joint
  (R = Ry(q1) Rz(q2)) and for the first two axes of an S joint. Known defect: on long U chains
  its articulated inertia drifts from symmetry (the 2x2 D = S^T Ia S is inverted unsymmetrised):
  5.9e-6 relative error at 100 U-links of the RE-U rod near straight (test
  ``test_pinocchio_universal_aba_defect``), 1.1e-3 at 50 random S-links.
- ``pinocchio-aba-ryrz``: ``pin.aba`` with every elementary axis its own 1-DOF joint: a U joint
  is ``JointModelRY`` -> a massless body -> ``JointModelRZ`` (the link's inertia on the RZ joint),
  an S joint RY -> massless -> RZ -> massless -> RX. Stable; agrees with CRBA.
- ``pinocchio-crba``: ``pin.crba`` (fills the upper triangle) + ``pin.nonLinearEffects``, solved
  by ``scipy.linalg.cho_factor(lower=False)``, which reads only that upper triangle; the model is
  ``pinocchio-aba``'s. The Pinocchio reference to use where memory allows.

What the model contains and why: joints, joint placements, link inertias and gravity, nothing
else. Each joint of the chain is its elementary axes (``references.base.joint_axes``) in order,
one Pinocchio joint per axis, the axes after the first at an identity placement on the previous
axis's joint with no body of their own (a massless body: Pinocchio's joint frames carry no
inertia unless a body is appended). Per axis: ``JointModelRX``/``RY``/``RZ`` or
``JointModelPX``/``PY``/``PZ`` for an axis exactly +x, +y, +z of its frame;
``JointModelRevoluteUnaligned(u)`` / ``JointModelPrismaticUnaligned(u)`` for any other direction,
-x, -y, -z included (so an R joint about -z is never built as RZ). In ``pinocchio-aba`` and
``pinocchio-crba`` two leading orthogonal revolute axes (U, and the U part of S) are one
``JointModelUniversal(u1, u2)`` instead, which rotates about u1 and then the rotated u2, as the
core does. The first axis of joint k sits at the placement translating l_{k-1} along the parent
link's x (the parent's last axis's joint frame is the parent link's frame); a prismatic joint
moves its frame, and so the link and everything after it, by u q along the axis, as in the core.
Link inertias ``pin.Inertia(m, c, I_C)`` (about the COM) on the joint of the link's last axis;
gravity ``model.gravity.linear = chain.gravity``. Pinocchio models have no contacts, collision or
visual geometry unless asked for; joint limits, damping, friction, armature and effort/velocity
limits are left at their defaults, which ``aba``/``crba``/``rnea`` ignore (they apply no limit,
damping or armature). ``pin.Data(model)`` is used, not ``model.createData()``, which copies
through the bindings and doubles the peak memory (docs/design.md, "Reference engines").

Limit (references/limits.toml): ``pin.Data`` allocates the second-order-derivative tensors
(nv^3 each) whatever algorithm is called, so memory, not time, stops it.

``simulate``: Pinocchio has no time integrator; the adapter steps semi-implicit (symplectic)
Euler with a fixed step h: qd += h qdd(q, qd); q = pin.integrate(q, h qd) (plain addition for
these joints, whose configuration is the angle or displacement vector).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from .base import Engine


def _axis_model(pin, axis):
    """The 1-DOF Pinocchio joint model of one elementary axis (``references.base.Axis``)."""
    if axis.coordinate is not None:  # exactly +x, +y or +z: RX, RY, RZ, PX, PY, PZ
        return getattr(pin, f"JointModel{axis.kind}{'XYZ'[axis.coordinate]}")()
    if axis.kind == "R":
        return pin.JointModelRevoluteUnaligned(axis.vector)
    return pin.JointModelPrismaticUnaligned(axis.vector)


class _PinocchioBase(Engine):
    package = "pin"
    module = "pinocchio"
    integrator = "semi-implicit Euler (fixed step; pin.aba/crba for qdd, pin.integrate for q)"
    universal = "universal"  # "universal": JointModelUniversal; "ryrz": one joint per axis

    @classmethod
    def package_version(cls) -> str:
        from .base import import_engine
        return import_engine(cls.name, cls.package, cls.module).__version__

    def _build(self):
        pin = self.lib
        c = self.chain
        model = pin.Model()
        model.gravity.linear = np.asarray(c.gravity, dtype=float)
        parent = 0
        for k, joint in enumerate(self.joints):
            offset = np.array([c.length[k - 1], 0.0, 0.0]) if k > 0 else np.zeros(3)
            placement = pin.SE3(np.eye(3), offset)
            inertia = pin.Inertia(float(c.mass[k]), np.array(c.com[k]),
                                  np.array(c.inertia_com[k]))
            for i, jm in enumerate(self._joint_models(joint.axes)):
                parent = model.addJoint(parent, jm, placement if i == 0 else pin.SE3.Identity(),
                                        f"j{k}_{i}")
            model.appendBodyToJoint(parent, inertia, pin.SE3.Identity())
        self.model = model
        self.data = pin.Data(model)
        self.last = parent
        if model.nv != c.n_dof or model.nq != c.n_dof:
            raise AssertionError(f"model has nq={model.nq}, nv={model.nv}; chain {c.n_dof} DOF")

    def _joint_models(self, axes) -> list:
        """The Pinocchio joint models of one joint's elementary axes, in order."""
        pin = self.lib
        if (self.universal == "universal" and len(axes) >= 2 and axes[0].kind == "R"
                and axes[1].kind == "R" and float(np.dot(axes[0].u, axes[1].u)) == 0.0):
            return ([pin.JointModelUniversal(axes[0].vector, axes[1].vector)]
                    + [_axis_model(pin, a) for a in axes[2:]])
        return [_axis_model(pin, a) for a in axes]

    # ------------------------------------------------------------------ stages
    def _mass_matrix(self, q):
        M = self.lib.crba(self.model, self.data, q).copy()
        return np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle only

    def _bias(self, q, qd):
        return -self.lib.nonLinearEffects(self.model, self.data, q, qd).copy()

    def _energy(self, q, qd):
        pin = self.lib
        T = pin.computeKineticEnergy(self.model, self.data, q, qd)
        V = pin.computePotentialEnergy(self.model, self.data, q)
        return T, V

    def _tip(self, q, qd):
        pin = self.lib
        pin.forwardKinematics(self.model, self.data, q)
        return self.data.oMi[self.last].act(np.array([self.chain.length[-1], 0.0, 0.0])).copy()

    # ------------------------------------------------------------------ native stepping
    def _sim_reset(self, q0, qd0, h):
        self._q, self._qd, self._h = q0.copy(), qd0.copy(), h

    def _sim_step(self):
        self._qd = self._qd + self._h * self._qdd(self._q, self._qd, None)
        self._q = self.lib.integrate(self.model, self._q, self._h * self._qd)

    def _sim_state(self):
        return self._q.copy(), self._qd.copy()


class PinocchioABA(_PinocchioBase):
    """Pinocchio ``pin.aba`` with ``JointModelUniversal`` U joints (see the module docstring)."""

    name = "pinocchio-aba"
    universal = "universal"

    def _qdd(self, q, qd, tau):
        tau = np.zeros(self.chain.n_dof) if tau is None else tau
        return self.lib.aba(self.model, self.data, q, qd, tau).copy()


class PinocchioABARyRz(PinocchioABA):
    """Pinocchio ``pin.aba`` with each U joint as RY -> massless body -> RZ."""

    name = "pinocchio-aba-ryrz"
    universal = "ryrz"


class PinocchioCRBA(_PinocchioBase):
    """Pinocchio ``pin.crba`` + ``pin.nonLinearEffects`` + upper Cholesky (scipy)."""

    name = "pinocchio-crba"
    universal = "universal"

    def _qdd(self, q, qd, tau):
        pin = self.lib
        M = pin.crba(self.model, self.data, q)  # upper triangle filled
        rhs = -pin.nonLinearEffects(self.model, self.data, q, qd)
        if tau is not None:
            rhs = rhs + tau
        return scipy.linalg.cho_solve(scipy.linalg.cho_factor(M, lower=False), rhs)
