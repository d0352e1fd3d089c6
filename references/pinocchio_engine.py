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

Trees (``references.trees``): ``PinocchioTreeABA``, ``PinocchioTreeABARyRz``,
``PinocchioTreeCRBA`` build a :class:`redysim.Model` the same way, body by body, each body's
first joint at ``pin.SE3(placement_R, placement_p)`` on its parent body's last joint, a free joint
as ``JointModelFreeFlyer``. Bodies are added depth-first: Pinocchio's CRBA assumes each subtree's
DOF contiguous (``Model.check`` fails otherwise; stack-of-tasks/pinocchio#1897, "expected
behavior"), and on a tree in the Model's parents-first order it gave a GIM wrong by 5e-2 while
``pin.aba`` was right. Free joint: Pinocchio's q is (x, y, z, qx, qy, qz, qw) and v the
origin's velocity and the angular velocity in the BODY frame; converted both ways (class
docstring).
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from redysim.model import FREE
from redysim.rbda import quaternion_matrix

from .base import Engine
from .trees import FreeBlock, TreeEngine, depth_first


def _axis_model(pin, axis):
    """The 1-DOF Pinocchio joint model of one elementary axis (``references.base.Axis``)."""
    if axis.coordinate is not None:  # exactly +x, +y or +z: RX, RY, RZ, PX, PY, PZ
        return getattr(pin, f"JointModel{axis.kind}{'XYZ'[axis.coordinate]}")()
    if axis.kind == "R":
        return pin.JointModelRevoluteUnaligned(axis.vector)
    return pin.JointModelPrismaticUnaligned(axis.vector)


def _joint_models(pin, axes, universal: str) -> list:
    """The Pinocchio joint models of one joint's elementary axes, in order: one per axis, or
    (``universal == "universal"``) one ``JointModelUniversal`` for two leading orthogonal
    revolute axes."""
    if (universal == "universal" and len(axes) >= 2 and axes[0].kind == "R"
            and axes[1].kind == "R" and float(np.dot(axes[0].u, axes[1].u)) == 0.0):
        return ([pin.JointModelUniversal(axes[0].vector, axes[1].vector)]
                + [_axis_model(pin, a) for a in axes[2:]])
    return [_axis_model(pin, a) for a in axes]


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
        return _joint_models(self.lib, axes, self.universal)

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


def _upper_cholesky_solve(M, rhs):
    """M x = rhs by the upper Cholesky factor, which reads only M's upper triangle (SciPy's
    linalg imported here, on first use: 0.12 s that ``redysim --help`` does not need)."""
    from scipy.linalg import cho_factor, cho_solve

    return cho_solve(cho_factor(M, lower=False), rhs)


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
        return _upper_cholesky_solve(M, rhs)


# --------------------------------------------------------------------------- trees
class _PinocchioTree(TreeEngine):
    """Pinocchio on a :class:`redysim.Model` (``references.trees``).

    One Pinocchio joint per elementary axis as for chains (``JointModelUniversal`` for U in
    ``pinocchio-aba``/``-crba``), the first at ``pin.SE3(placement_R, placement_p)`` on the
    parent body's last joint (0, the universe, for a root), the link's inertia
    ``pin.Inertia(m, c, I_C)`` on the body's last joint; a free joint is one
    ``JointModelFreeFlyer`` at the identity placement.

    Free joint, converted both ways: Pinocchio's q is (x, y, z, qx, qy, qz, qw) (w last) and its
    v = (R^T v_world, w_body), the origin's velocity in the BODY frame, so B = diag(R, 1) and
    c = (R (w_body x R^T v_world), 0): d/dt (R v_local) = R (a_local + w x v_local). The applied
    force's linear part turns by R^T. Energies are invariant.
    """

    package = "pin"
    module = "pinocchio"
    universal: ClassVar[str] = "universal"

    def _build(self):
        pin = self.lib
        m = self.model
        pm = pin.Model()
        pm.gravity.linear = np.asarray(m.gravity, dtype=float)
        last = {}  # the Pinocchio joint id of each body's last axis (the body's frame)
        first = {}  # the Pinocchio joint id of each body's first axis
        for k in depth_first(m):  # Pinocchio's CRBA needs each subtree's DOF contiguous
            joint = self.joints[k]
            parent = 0 if joint.parent < 0 else last[joint.parent]
            placement = pin.SE3(joint.R, joint.p)
            if joint.type == FREE:
                models = [pin.JointModelFreeFlyer()]
            else:
                models = _joint_models(pin, joint.axes, self.universal)
            for i, jm in enumerate(models):
                parent = pm.addJoint(parent, jm, placement if i == 0 else pin.SE3.Identity(),
                                     f"b{k}_{i}")
                if i == 0:
                    first[k] = parent
            pm.appendBodyToJoint(parent, pin.Inertia(float(m.mass[k]), np.array(m.com[k]),
                                                     np.array(m.inertia_com[k])),
                                 pin.SE3.Identity())
            last[k] = parent
        if pm.nv != m.n_v or pm.nq != m.n_q:
            raise AssertionError(f"model has nq={pm.nq}, nv={pm.nv}; the tree {m.n_q}, {m.n_v}")
        self.pm, self.data = pm, pin.Data(pm)
        assert pm.check(self.data), "Pinocchio's Model.check failed"
        # the core's slots -> Pinocchio's: each body's coordinates are consecutive in both
        self.qidx = np.zeros(m.n_q, dtype=np.int64)
        for k in range(m.n_bodies):
            jm = pm.joints[first[k]]
            nq, nv = m.joint_qoff[k + 1] - m.joint_qoff[k], m.joint_voff[k + 1] - m.joint_voff[k]
            self.qidx[m.joint_qoff[k]:m.joint_qoff[k + 1]] = jm.idx_q + np.arange(nq)
            self.eidx[m.joint_voff[k]:m.joint_voff[k + 1]] = jm.idx_v + np.arange(nv)
        self.free = [(int(m.joint_qoff[k]), int(m.joint_voff[k]))
                     for k, j in enumerate(self.joints) if j.type == FREE]

    def _engine_state(self, q, v):
        q = q.copy()
        blocks = []
        for qs, vs in self.free:
            quat = q[qs + 3:qs + 7] / np.linalg.norm(q[qs + 3:qs + 7])
            q[qs + 3:qs + 7] = [quat[1], quat[2], quat[3], quat[0]]  # Pinocchio's: w last
            R = quaternion_matrix(*quat)
            B = np.eye(6)
            B[:3, :3] = R
            w, v_local = v[vs + 3:vs + 6], R.T @ v[vs:vs + 3]
            c = np.zeros(6)
            c[:3] = R @ np.cross(w, v_local)
            blocks.append(FreeBlock(vs, B, c))
        qp = np.empty(self.model.n_q)
        qp[self.qidx] = q
        return qp, blocks

    def _raw_mass_matrix(self, qp):
        M = self.lib.crba(self.pm, self.data, qp).copy()
        return np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle only

    def _raw_bias(self, qp, y):
        return -self.lib.nonLinearEffects(self.pm, self.data, qp, y).copy()

    def _raw_energy(self, qp, y):
        pin = self.lib
        return (pin.computeKineticEnergy(self.pm, self.data, qp, y),
                pin.computePotentialEnergy(self.pm, self.data, qp))


class PinocchioTreeABA(_PinocchioTree):
    """``pin.aba`` on the tree, U joints as ``JointModelUniversal``."""

    name = "pinocchio-aba"
    universal = "universal"

    def _raw_qdd(self, qp, y, tau_e):
        tau_e = np.zeros(self.model.n_v) if tau_e is None else tau_e
        return self.lib.aba(self.pm, self.data, qp, y, tau_e).copy()


class PinocchioTreeABARyRz(PinocchioTreeABA):
    """``pin.aba`` on the tree, each elementary axis its own joint (massless bodies between)."""

    name = "pinocchio-aba-ryrz"
    universal = "ryrz"


class PinocchioTreeCRBA(_PinocchioTree):
    """``pin.crba`` + ``pin.nonLinearEffects`` + upper Cholesky (scipy) on the tree."""

    name = "pinocchio-crba"
    universal = "universal"

    def _raw_qdd(self, qp, y, tau_e):
        pin = self.lib
        M = pin.crba(self.pm, self.data, qp)  # upper triangle filled
        rhs = -pin.nonLinearEffects(self.pm, self.data, qp, y)
        if tau_e is not None:
            rhs = rhs + tau_e
        return _upper_cholesky_solve(M, rhs)
