"""MuJoCo adapter, built programmatically with ``mujoco.MjSpec`` (no XML).

What the model contains and why (docs/design.md, "Reference engines"):

- one body per link, nested (a chain), at ``pos = (l_{k-1}, 0, 0)`` in its parent, holding one
  joint per elementary axis of the link's joint (``references.base.joint_axes``), in order: a
  ``hinge`` for an R axis, a ``slide`` for a P axis, ``axis = u`` as given (-z stays -z; a
  general direction is passed as the unit vector the core uses) and ``pos = 0``. MuJoCo composes
  a body's joints in order, each axis in the frame left by the joints before it (``mj_kinematics``
  rotates the next joint's axis by the body's quaternion so far; a slide moves the body's origin
  by the rotated axis times q, a hinge turns the frame about the current origin), which is the
  core's convention: a U joint is two hinges, y then the rotated z (R = Ry(q1) Rz(q2)), an S
  joint three (y, z, x), an R or P joint one.
- ``explicitinertial`` with mass, ``ipos`` = COM and the inertia's principal moments + ``iquat``
  (the eigen-decomposition of ``chain.inertia_com``, done here). No geoms at all: nothing to
  collide, nothing to draw, and no inertia inferred from geometry.
- ``option.disableflags = CONTACT | CONSTRAINT``: the scene has no contacts, limits or equality
  constraints, so the constraint solver must not run (``qacc`` then equals ``qacc_smooth``); and
  every other stage it has nothing for (actuation, sensors, springs, ...: ``_DISABLED``). The
  energy is computed on demand (``mj_energyPos``, ``mj_energyVel``), not by every ``mj_forward``
  (the ENERGY flag). Joint damping, armature, friction
  loss, stiffness and limits are left at their zero/off defaults and asserted zero after compile.
- ``compiler.balanceinertia`` only when a link's inertia violates the triangle inequality (the
  paper's rod model does; docs/design.md, "Chain conventions"); the exact principal moments are
  then written back into ``model.body_inertia`` after compiling.
- ``option.gravity = chain.gravity``.

``qdd`` is ``mj_forward``'s ``qacc`` with ``qfrc_applied = tau``; ``mass_matrix`` is ``mj_fullM``;
``bias`` is ``-qfrc_bias``; ``energy`` is ``mj_energyPos``/``mj_energyVel``'s (V, T), reordered.
``simulate`` uses ``mj_step`` with ``mjINT_RK4`` at the fixed step h.

Limits: MuJoCo refuses a body tree deeper than 1,024 ("depth limit exceeded in signature
computation"), and compile time grows ~n^3 (references/limits.toml).

Trees (``references.trees``): ``MuJoCoTree`` builds a :class:`redysim.Model` as nested
bodies at their placements (``pos``, ``quat``), MuJoCo's ``freejoint`` for a free joint (its
convention is the core's: no conversion), and maps MuJoCo's depth-first DOF order to the Model's
by joint name. It refuses a body with mass or a principal moment below mjMINVAL (1e-15), which
MuJoCo's compiler rejects even with massive children (class docstring).
"""

from __future__ import annotations

import numpy as np

from redysim.model import FREE

from .base import Engine
from .trees import TreeEngine

# Pipeline stages the models here have nothing for (no contacts, constraints, actuators, sensors,
# springs, dampers, friction loss, limits or equalities): disabled, so mj_forward skips their
# bookkeeping. Measured (U chains, 2026-11-23): 367 -> 308 us a call at 200 DOF, 3.9 -> 3.5 us at
# 20, the same qacc to the bit; at 2,000 DOF the dense factorisation of M is all there is.
_DISABLED = ("mjDSBL_CONTACT", "mjDSBL_CONSTRAINT", "mjDSBL_ACTUATION", "mjDSBL_SENSOR",
             "mjDSBL_SPRING", "mjDSBL_DAMPER", "mjDSBL_FRICTIONLOSS", "mjDSBL_LIMIT",
             "mjDSBL_EQUALITY", "mjDSBL_ISLAND", "mjDSBL_EULERDAMP")


def _options(mj, spec) -> None:
    """The options of every model here: unused stages off (above); no ENERGY flag, which would
    make every mj_forward compute the energy (13 % of a call at 200 DOF): :func:`_energy` asks for
    it when it is wanted."""
    for name in _DISABLED:
        spec.option.disableflags |= int(getattr(mj.mjtDisableBit, name))


def _energy(mj, model, data) -> tuple[float, float]:
    """(T, V) of the state ``data`` holds after mj_forward: MuJoCo's mj_energyPos and
    mj_energyVel, called here rather than in every mj_forward (stored as (potential, kinetic))."""
    mj.mj_energyPos(model, data)
    mj.mj_energyVel(model, data)
    return data.energy[1], data.energy[0]


def _principal(I):
    """Principal moments and the (w, x, y, z) quaternion of the principal axes (det +1)."""
    w, V = np.linalg.eigh(I)
    if np.linalg.det(V) < 0:
        V[:, 0] = -V[:, 0]
    import mujoco
    quat = np.zeros(4)
    mujoco.mju_mat2Quat(quat, np.ascontiguousarray(V).ravel())
    return w, quat


class MuJoCo(Engine):
    """MuJoCo ``mj_forward`` on an MjSpec-built chain (see the module docstring)."""

    name = "mujoco"
    package = "mujoco"
    module = "mujoco"
    integrator = "mj_step, mjINT_RK4, fixed step"

    def _build(self):
        mj = self.lib
        c = self.chain
        spec = mj.MjSpec()
        spec.option.gravity = np.asarray(c.gravity, dtype=float)
        _options(mj, spec)
        spec.option.integrator = int(mj.mjtIntegrator.mjINT_RK4)
        spec.compiler.inertiafromgeom = int(mj.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE)
        principal = []
        balance = False
        parent = spec.worldbody
        hinge, slide = mj.mjtJoint.mjJNT_HINGE, mj.mjtJoint.mjJNT_SLIDE
        for k, joint in enumerate(self.joints):
            body = parent.add_body()
            body.name = f"link{k}"
            body.pos = [c.length[k - 1], 0.0, 0.0] if k > 0 else [0.0, 0.0, 0.0]
            body.explicitinertial = True
            body.mass = float(c.mass[k])
            body.ipos = np.array(c.com[k])
            w, quat = _principal(np.array(c.inertia_com[k]))
            principal.append(w)
            balance |= bool(w[0] + w[1] < w[2] or w[0] + w[2] < w[1] or w[1] + w[2] < w[0])
            body.inertia = w
            body.iquat = quat
            for i, axis in enumerate(joint.axes):
                j = body.add_joint()
                j.name = f"j{k}_{i}"
                j.type = hinge if axis.kind == "R" else slide
                j.axis = axis.u
            parent = body
        spec.compiler.balanceinertia = balance
        model = spec.compile()
        model.body_inertia[1:] = np.array(principal)  # exact moments (balanceinertia moved them)
        for name in ("dof_damping", "dof_armature", "dof_frictionloss", "jnt_stiffness",
                     "qpos0", "jnt_pos"):
            assert not np.any(getattr(model, name)), name
        axes = [a for joint in self.joints for a in joint.axes]
        # the compiled axes are the chain's (MuJoCo normalises them: a unit vector stays within
        # rounding of itself, and a -z axis must not have become +z)
        assert np.abs(model.jnt_axis - np.array([a.u for a in axes])).max() < 1e-15
        self.model, self.data = model, mj.MjData(model)
        self.last_body = model.nbody - 1
        if model.nv != c.n_dof:
            raise AssertionError(f"model has nv={model.nv}, chain {c.n_dof}")

    def _forward(self, q, qd, tau=None):
        d = self.data
        d.qpos[:] = q
        d.qvel[:] = qd
        d.qfrc_applied[:] = 0.0 if tau is None else tau
        self.lib.mj_forward(self.model, d)
        return d

    def _qdd(self, q, qd, tau):
        return self._forward(q, qd, tau).qacc.copy()

    def _mass_matrix(self, q):
        d = self._forward(q, np.zeros_like(q))
        n = self.model.nv
        M = np.zeros((n, n))
        self.lib.mj_fullM(self.model, d, M)
        return M

    def _bias(self, q, qd):
        return -self._forward(q, qd).qfrc_bias.copy()

    def _energy(self, q, qd):
        return _energy(self.lib, self.model, self._forward(q, qd))

    def _tip(self, q, qd):
        d = self._forward(q, qd)
        R = d.xmat[self.last_body].reshape(3, 3)
        return d.xpos[self.last_body] + R @ np.array([self.chain.length[-1], 0.0, 0.0])

    def _sim_reset(self, q0, qd0, h):
        self.model.opt.timestep = h
        self.lib.mj_resetData(self.model, self.data)
        self.data.qpos[:] = q0
        self.data.qvel[:] = qd0

    def _sim_step(self):
        self.lib.mj_step(self.model, self.data)

    def _sim_state(self):
        return self.data.qpos.copy(), self.data.qvel.copy()


# --------------------------------------------------------------------------- trees
MJMINVAL = 1e-15  # MuJoCo's mjMINVAL: a moving body needs mass and inertia above it


class MuJoCoTree(TreeEngine):
    """MuJoCo on a :class:`redysim.Model` (``references.trees``).

    One MjSpec body per Model body, nested as the tree, at ``pos = placement_p`` and ``quat`` the
    placement's rotation (``mju_mat2Quat``), holding one hinge/slide per elementary axis as for
    chains, or one ``freejoint``; inertias, options and asserted zeros as for chains. MuJoCo
    numbers bodies and DOF depth-first; the adapter maps them to the Model's order by name.

    Free joint: MuJoCo's free joint IS the core's convention (q = position, quaternion w first;
    v = world linear velocity of the origin, body-frame angular velocity), so B = 1, c = 0: no
    conversion but the order.

    Refused by ``limits``: a body with mass or a principal moment below mjMINVAL = 1e-15 (a
    massless body between joints): MuJoCo's compiler stops with "mass and inertia of moving bodies
    must be larger than mjMINVAL", even when the body's children have mass (measured, 4.0.0).
    """

    name = "mujoco"
    package = "mujoco"
    module = "mujoco"
    depth_limited = True

    @classmethod
    def unsupported(cls, model, joints):
        for k in range(model.n_bodies):
            w = np.linalg.eigvalsh(np.asarray(model.inertia_com[k]))
            if model.mass[k] < MJMINVAL or w.min() < MJMINVAL:
                return (f"body {k} ({model.body_names[k]}) has mass {model.mass[k]:.3g} kg and "
                        f"smallest principal moment {w.min():.3g} kg m^2: MuJoCo's compiler "
                        f"refuses it ('mass and inertia of moving bodies must be larger than "
                        f"mjMINVAL' = 1e-15), even when its children have mass")
        return ""

    def _build(self):
        mj = self.lib
        m = self.model
        spec = mj.MjSpec()
        spec.option.gravity = np.asarray(m.gravity, dtype=float)
        _options(mj, spec)
        spec.compiler.inertiafromgeom = int(mj.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE)
        principal, balance, bodies = [], False, []
        hinge, slide = mj.mjtJoint.mjJNT_HINGE, mj.mjtJoint.mjJNT_SLIDE
        for k, joint in enumerate(self.joints):
            parent = spec.worldbody if joint.parent < 0 else bodies[joint.parent]
            body = parent.add_body()
            body.name = f"b{k}"
            body.pos = joint.p
            quat = np.zeros(4)
            mj.mju_mat2Quat(quat, np.ascontiguousarray(joint.R).ravel())
            body.quat = quat
            body.explicitinertial = True
            body.mass = float(m.mass[k])
            body.ipos = np.array(m.com[k])
            w, iquat = _principal(np.array(m.inertia_com[k]))
            principal.append(w)
            balance |= bool(w[0] + w[1] < w[2] or w[0] + w[2] < w[1] or w[1] + w[2] < w[0])
            body.inertia = w
            body.iquat = iquat
            if joint.type == FREE:
                j = body.add_freejoint()
                j.name = f"j{k}_free"
            for i, axis in enumerate(joint.axes):
                j = body.add_joint()
                j.name = f"j{k}_{i}"
                j.type = hinge if axis.kind == "R" else slide
                j.axis = axis.u
            bodies.append(body)
        spec.compiler.balanceinertia = balance
        # kept so that an adapter can add to the spec and compile it again (references/loops.py)
        self.spec, self.spec_bodies, self.principal = spec, bodies, np.array(principal)
        self._compile()

    def _compile(self):
        """Compile ``self.spec`` (built by ``_build``) and map the core's slots to MuJoCo's."""
        m = self.model
        model = self.spec.compile()
        ids = [model.body(f"b{k}").id for k in range(m.n_bodies)]
        model.body_inertia[ids] = self.principal  # exact moments (balanceinertia)
        for name in ("dof_damping", "dof_armature", "dof_frictionloss", "jnt_stiffness",
                     "jnt_pos"):
            assert not np.any(getattr(model, name)), name
        # the core's slots -> MuJoCo's, by joint name
        self.qidx = np.zeros(m.n_q, dtype=np.int64)
        for k, joint in enumerate(self.joints):
            qs, vs = int(m.joint_qoff[k]), int(m.joint_voff[k])
            if joint.type == FREE:
                mj_joint = model.joint(f"j{k}_free")
                self.qidx[qs:qs + 7] = mj_joint.qposadr[0] + np.arange(7)
                self.eidx[vs:vs + 6] = mj_joint.dofadr[0] + np.arange(6)
                continue
            for i, axis in enumerate(joint.axes):
                mj_joint = model.joint(f"j{k}_{i}")
                assert np.abs(mj_joint.axis - axis.vector).max() < 1e-15
                self.qidx[qs + i] = mj_joint.qposadr[0]
                self.eidx[vs + i] = mj_joint.dofadr[0]
        self.free = [int(m.joint_qoff[k]) for k, j in enumerate(self.joints) if j.type == FREE]
        self.mjmodel, self.mjdata = model, self.lib.MjData(model)
        if model.nv != m.n_v or model.nq != m.n_q:
            raise AssertionError(f"model has nq={model.nq}, nv={model.nv}; the tree "
                                 f"{m.n_q}, {m.n_v}")

    def _engine_state(self, q, v):
        qe = np.empty(self.model.n_q)
        q = q.copy()
        for qs in self.free:
            q[qs + 3:qs + 7] /= np.linalg.norm(q[qs + 3:qs + 7])
        qe[self.qidx] = q
        return qe, []

    def _forward(self, qe, y, tau_e=None):
        d = self.mjdata
        d.qpos[:] = qe
        d.qvel[:] = y
        d.qfrc_applied[:] = 0.0 if tau_e is None else tau_e
        self.lib.mj_forward(self.mjmodel, d)
        return d

    def _raw_qdd(self, qe, y, tau_e):
        return self._forward(qe, y, tau_e).qacc.copy()

    def _raw_mass_matrix(self, qe):
        d = self._forward(qe, np.zeros(self.n_e))
        M = np.zeros((self.n_e, self.n_e))
        self.lib.mj_fullM(self.mjmodel, d, M)
        return M

    def _raw_bias(self, qe, y):
        return -self._forward(qe, y).qfrc_bias.copy()

    def _raw_energy(self, qe, y):
        return _energy(self.lib, self.mjmodel, self._forward(qe, y))
