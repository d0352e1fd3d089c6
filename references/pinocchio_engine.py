"""Pinocchio adapters: ABA (``pin.aba``) and CRBA + Cholesky, with two ways to model a U joint.

Engines (``references.ENGINES``):

- ``pinocchio-aba``: ``pin.aba`` on a model with one ``JointModelUniversal(y, z)`` per U joint
  (R = Ry(q1) Rz(q2), DESIGN.md section 6). Known defect: on long U chains its articulated inertia
  drifts from symmetry (the 2x2 D = S^T Ia S is inverted unsymmetrised): 5.8e-4 relative error at
  100 U-links, NaN at 1,000 (test ``test_pinocchio_universal_aba_defect``).
- ``pinocchio-aba-ryrz``: ``pin.aba`` with each U joint built as ``JointModelRY`` -> a massless
  body -> ``JointModelRZ`` (the link's inertia on the RZ joint). Stable; agrees with CRBA.
- ``pinocchio-crba``: ``pin.crba`` (fills the upper triangle) + ``pin.nonLinearEffects``, solved
  by ``scipy.linalg.cho_factor(lower=False)``, which reads only that upper triangle. The
  Pinocchio reference to use where memory allows.

What the model contains and why: only joints (R about z: ``JointModelRZ``), joint placements
(translation l_{k-1} along the parent's x), link inertias (``pin.Inertia(m, c, I_C)``, about the
COM) and gravity ``model.gravity.linear = chain.gravity``. Pinocchio models have no contacts,
collision or visual geometry unless asked for; joint limits, damping, friction, armature and
effort/velocity limits are left at their defaults, which ``aba``/``crba``/``rnea`` ignore (they
apply no limit, damping or armature). ``pin.Data(model)`` is used, not ``model.createData()``,
which copies through the bindings and doubles the peak memory (DESIGN.md section 6).

Limit (references/limits.toml): ``pin.Data`` allocates the second-order-derivative tensors
(nv^3 each) whatever algorithm is called, so memory, not time, stops it.

``simulate``: Pinocchio has no time integrator; the adapter steps semi-implicit (symplectic)
Euler with a fixed step h: qd += h qdd(q, qd); q = pin.integrate(q, h qd) (plain addition for
these joints, whose configuration is the angle vector).
"""

from __future__ import annotations

import numpy as np
import scipy.linalg

from .base import Engine


class _PinocchioBase(Engine):
    package = "pin"
    module = "pinocchio"
    integrator = "semi-implicit Euler (fixed step; pin.aba/crba for qdd, pin.integrate for q)"
    universal = "composite"  # "universal": JointModelUniversal; "ryrz": RY -> massless -> RZ

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
        for k, kind in enumerate(self.kinds):
            offset = np.array([c.length[k - 1], 0.0, 0.0]) if k > 0 else np.zeros(3)
            placement = pin.SE3(np.eye(3), offset)
            inertia = pin.Inertia(float(c.mass[k]), np.array(c.com[k]),
                                  np.array(c.inertia_com[k]))
            if kind == "R":
                jid = model.addJoint(parent, pin.JointModelRZ(), placement, f"j{k}")
            elif self.universal == "universal":
                jm = pin.JointModelUniversal(np.array([0.0, 1.0, 0.0]), np.array([0.0, 0.0, 1.0]))
                jid = model.addJoint(parent, jm, placement, f"j{k}")
            else:  # RY -> massless body -> RZ
                jy = model.addJoint(parent, pin.JointModelRY(), placement, f"j{k}y")
                jid = model.addJoint(jy, pin.JointModelRZ(), pin.SE3.Identity(), f"j{k}z")
            model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
            parent = jid
        self.model = model
        self.data = pin.Data(model)
        self.last = parent
        if model.nv != c.n_dof:
            raise AssertionError(f"model has nv={model.nv}, chain {c.n_dof}")

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
