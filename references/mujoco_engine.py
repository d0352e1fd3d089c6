"""MuJoCo adapter, built programmatically with ``mujoco.MjSpec`` (no XML).

What the model contains and why (docs/design.md, "Reference engines"):

- one MjSpec body per Model body, nested as the tree, at ``pos = placement_p`` and ``quat`` the
  placement's rotation (``mju_mat2Quat``; a chain's link k at ``pos = (l_{k-1}, 0, 0)`` in its
  parent, unrotated), holding one joint per elementary axis of the body's joint
  (``redysim.references.base.joint_axes``), in order: a ``hinge`` for an R axis, a ``slide`` for a P
  axis, ``axis = u`` as given (-z stays -z; a general direction is passed as the unit vector the
  core uses) and ``pos = 0``; or one ``freejoint``. MuJoCo composes a body's joints in order,
  each axis in the frame left by the joints before it (``mj_kinematics`` rotates the next
  joint's axis by the body's quaternion so far; a slide moves the body's origin by the rotated
  axis times q, a hinge turns the frame about the current origin), which is the core's
  convention: a U joint is two hinges, y then the rotated z (R = Ry(q1) Rz(q2)), an S joint
  three (y, z, x), an R or P joint one.
- ``explicitinertial`` with mass, ``ipos`` = COM and the inertia's principal moments + ``iquat``
  (the eigen-decomposition of ``model.inertia_com``, done here). No geoms at all: nothing to
  collide, nothing to draw, and no inertia inferred from geometry.
- ``option.disableflags = CONTACT | CONSTRAINT``: the scene has no contacts, limits or equality
  constraints, so the constraint solver must not run (``qacc`` then equals ``qacc_smooth``); and
  every other stage it has nothing for (actuation, sensors, springs, ...: ``_DISABLED``). The
  energy is computed on demand (``mj_energyPos``, ``mj_energyVel``), not by every ``mj_forward``
  (the ENERGY flag). Joint damping, armature, friction loss, stiffness, anchors and the hinges'
  and slides' ``qpos0`` are left at their zero/off defaults and asserted zero after compile;
  then the model's armature (``Model.armature``) is written into ``dof_armature`` (MuJoCo's dof
  of each of the core's velocity slots) and ``mj_setConst`` recomputes what depends on it
  (``dof_M0``); MuJoCo's M and its ``mj_energyVel`` include it. The model's passive elements
  (``Model.damping``, ``stiffness`` with ``spring_ref``, ``gravcomp``) are MuJoCo's own
  ``dof_damping``, ``jnt_stiffness`` with ``qpos_spring`` (written after compiling) and body
  ``gravcomp`` (in the spec: MuJoCo counts the compensated bodies when it compiles); they act
  only in its own stepping, which switches the SPRING and DAMPER stages on (``sim_reset``):
  ``qdd``, M and the bias stay the rigid body's, as the core's forward dynamics, and a run
  through redysim's integrators applies them around ``qdd`` (``System``).
- ``compiler.balanceinertia`` only when a body's inertia violates the triangle inequality (the
  paper's rod model does; docs/design.md, "Chain conventions"); the exact principal moments are
  then written back into ``model.body_inertia`` after compiling.
- ``option.gravity = model.gravity``; ``option.integrator`` is set by ``sim_reset`` to the native
  integrator asked (below; ``mjINT_RK4`` until then): none of these four enters ``mj_forward``'s
  ``qacc`` (checked: ``qdd`` is bit for bit the same under each).
- ``mjDSBL_AUTORESET`` for the native stepper: by default ``mj_step`` resets the state to
  ``qpos0`` (and the time to 0) when a position, velocity or acceleration is NaN or above 1e10,
  with only a warning, and steps on: a diverging run then LOOKS finite (measured: the 3-link
  chain at RK4, h = 0.2 s, ended at a finite state after a silent reset). Disabled, divergence
  shows as the NaN it is (``redysim.references.base.EngineStepper`` fails the run on it).

MuJoCo numbers bodies and DOF depth-first; the adapter maps them to the Model's order by joint
name (a chain's order is MuJoCo's). Free joint: MuJoCo's free joint IS the core's convention
(q = position, quaternion w first; v = world linear velocity of the origin, body-frame angular
velocity), so B = 1, c = 0 (``redysim.references.base``): no conversion but the order. A ball
joint is MuJoCo's ``mjJNT_BALL`` at the body's origin (qpos w, x, y, z; qvel the body-frame
angular velocity relative to the parent): the core's, no conversion but the order.

``qdd`` is ``mj_forward``'s ``qacc`` with ``qfrc_applied = tau``; ``mass_matrix`` is ``mj_fullM``;
``bias`` is ``-qfrc_bias``; ``energy`` is ``mj_energyPos``/``mj_energyVel``'s (V, T), reordered;
``position``: the body's ``xpos + xmat @ point``.

Native integrators (``MuJoCo.integrators``; ``simulate``, ``sim_reset(..., integrator=NAME)``,
``redysim.simulate(..., engine=eng, integrator="native:NAME")``): ``mj_step`` at the fixed step
``opt.timestep = h``, ``opt.integrator`` set by ``sim_reset``:

| name         | what (opt.integrator) | step  | order | note                                  |
|--------------|-----------------------|-------|-------|---------------------------------------|
| euler        | mjINT_EULER           | fixed | 1     | semi-implicit Euler: v += h qacc,     |
|              |                       |       |       | then q by the new v. MuJoCo's Euler   |
|              |                       |       |       | integrates joint damping implicitly;  |
|              |                       |       |       | there is none here (and               |
|              |                       |       |       | mjDSBL_EULERDAMP): plain semi-implicit|
| implicitfast | mjINT_IMPLICITFAST    | fixed | 1     | implicit in velocity for damping and  |
|              |                       |       |       | actuator derivatives, not the         |
|              |                       |       |       | Coriolis/centripetal (RNE) ones: bit  |
|              |                       |       |       | for bit euler on jointed models here; |
|              |                       |       |       | a standalone free body gets its       |
|              |                       |       |       | gyroscopic terms (= implicit)         |
| implicit     | mjINT_IMPLICIT        | fixed | 1     | implicit in velocity, D = velocity    |
|              |                       |       |       | derivative of the smooth forces (here |
|              |                       |       |       | the RNE terms)                        |
| rk4          | mjINT_RK4             | fixed | 4     | classic Runge-Kutta on (qpos, qvel);  |
|              |                       |       |       | the default                           |

(bit for bit: measured on the 3-link chain and a free box, 100 steps of 1 ms.)

``mjINT_DISCRETE`` (new in 4.0, "under active development" in its documentation) is not
registered: on these models (no damping, stiffness or constraints) it is bit for bit ``euler``
on a chain and ``implicitfast`` on a free body (measured), and it turns ``mj_forward``'s
``qacc`` into the step map (v+ - v)/h, which the adapter's ``qdd`` must not become.
``sim_counts``: steps counted here, no rejections, qdd evaluations 4 a step for RK4 (``mj_step``'s
``mj_forward`` and three ``mj_forwardSkip`` in ``mj_RungeKutta``) and 1 for the others (the
counts follow from MuJoCo's source; MuJoCo reports none). ``manifest`` records ``opt``: the
timestep, the integrator, the disabled and enabled flags by name (contacts and constraints off,
no warmstart relevance without a constraint solve), the constraint solver's settings and the
fluid (density, viscosity, wind: zero, so no fluid forces).

Limits: MuJoCo refuses a body tree deeper than 1,023 ("depth limit exceeded in signature
computation"), and compile time grows ~n^3 (references/limits.toml); its compiler refuses a
body with mass or a principal moment below mjMINVAL (1e-15), even with massive children
(:meth:`MuJoCo.unsupported`).
"""

from __future__ import annotations

import numpy as np

from redysim.model.tree import BALL_JOINT, FREE

from .base import Engine, NativeIntegrator

_NOTE_ALL = ("no damping, contacts or constraints (the stages off: manifest 'disabled'); "
             "mjDSBL_AUTORESET set: a blow-up is NaN, not a silent reset to qpos0")
# name -> (NativeIntegrator, its mjtIntegrator member, qdd evaluations per step)
_INTEGRATORS = {
    "euler": (NativeIntegrator(
        "euler", False, "mj_step, opt.integrator = mjINT_EULER",
        "semi-implicit Euler (v += h qacc, then q by the new v), first order; MuJoCo's Euler "
        "integrates joint damping implicitly, and these models have none (mjDSBL_EULERDAMP "
        "set too): plain semi-implicit Euler here; " + _NOTE_ALL), "mjINT_EULER", 1),
    "implicitfast": (NativeIntegrator(
        "implicitfast", False, "mj_step, opt.integrator = mjINT_IMPLICITFAST",
        "implicit in velocity for damping/actuator derivatives, not the Coriolis/centripetal "
        "(RNE) ones, first order: with none of those here it is bit for bit euler on jointed "
        "models; a standalone free body gets its gyroscopic derivatives (then bit for bit "
        "implicit); " + _NOTE_ALL), "mjINT_IMPLICITFAST", 1),
    "implicit": (NativeIntegrator(
        "implicit", False, "mj_step, opt.integrator = mjINT_IMPLICIT",
        "implicit in velocity, (M - h D) v' = ..., D the velocity derivative of the smooth "
        "forces (here the RNE Coriolis/centripetal terms), first order; " + _NOTE_ALL),
        "mjINT_IMPLICIT", 1),
    "rk4": (NativeIntegrator(
        "rk4", False, "mj_step, opt.integrator = mjINT_RK4",
        "classic 4-stage Runge-Kutta on (qpos, qvel), fourth order; " + _NOTE_ALL),
        "mjINT_RK4", 4),
}

# Pipeline stages the models here have nothing for (no contacts, constraints, actuators, sensors,
# springs, dampers, friction loss, limits or equalities): disabled, so mj_forward skips their
# bookkeeping, the same qacc to the bit (its time saved: references/README.md, "Each engine's
# fastest honest configuration"); at 2,000 DOF the dense factorisation of M is all there is.
_DISABLED = ("mjDSBL_CONTACT", "mjDSBL_CONSTRAINT", "mjDSBL_ACTUATION", "mjDSBL_SENSOR",
             "mjDSBL_SPRING", "mjDSBL_DAMPER", "mjDSBL_FRICTIONLOSS", "mjDSBL_LIMIT",
             "mjDSBL_EQUALITY", "mjDSBL_ISLAND", "mjDSBL_EULERDAMP")
MJMINVAL = 1e-15  # MuJoCo's mjMINVAL: a moving body needs mass and inertia above it
COUPLING_TOLERANCE = 1e-15  # opt.tolerance of a coupled model's constraint solve (Newton)


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
    """MuJoCo ``mj_forward`` on an MjSpec-built Model (module docstring). ``spec``,
    ``spec_bodies``: the MjSpec and its bodies (kept so that an adapter can add to the spec and
    compile it again with :meth:`_compile`, ``references/loops.py``); ``mjmodel``, ``mjdata``:
    the compiled model and its data; ``qidx``, ``eidx``: MuJoCo's qpos and dof index of each of
    the core's q and v slots; ``body_ids[k]``: MuJoCo's id of body k.

    Refused by ``limits``: a body with mass or a principal moment below mjMINVAL = 1e-15 (a
    massless body between joints): MuJoCo's compiler stops with "mass and inertia of moving bodies
    must be larger than mjMINVAL", even when the body's children have mass (measured, 4.0.0).
    """

    name = "mujoco"
    package = "mujoco"
    module = "mujoco"
    couples = ("one mjEQ_JOINT equality per coupling (polycoef = offset, multiplier), solimp "
               "at MuJoCo's hardest (d = mjMAXIMP), Newton solver: MuJoCo's soft constraint, "
               "regularised as its loops are")
    couples_native = "the same joint equalities in mj_step, MuJoCo's constraint solver"
    integrator = "rk4"
    integrators = {name: entry[0] for name, entry in _INTEGRATORS.items()}
    depth_limited = True
    holds_armature = "dof_armature, then mj_setConst"
    holds_passive = ("dof_damping, jnt_stiffness, qpos_spring and body_gravcomp, its SPRING and "
                     "DAMPER stages switched on for its own stepping only")
    holds_ball = "mjJNT_BALL: MuJoCo's ball is the core's (qpos w, x, y, z; qvel body-frame)"

    @classmethod
    def unsupported(cls, model, joints):
        for k, joint in enumerate(joints):
            w = np.linalg.eigvalsh(np.asarray(model.inertia_com[k]))
            if model.mass[k] < MJMINVAL or w.min() < MJMINVAL:
                return (f"body {joint.body!r} has mass {float(model.mass[k]):.3g} kg and "
                        f"smallest principal moment {float(w.min()):.3g} kg m^2: MuJoCo's "
                        f"compiler refuses it ('mass and inertia of moving bodies must be larger "
                        f"than mjMINVAL' = 1e-15), even when its children have mass")
        return ""

    def _build(self):
        mj = self.lib
        m = self.model
        spec = mj.MjSpec()
        spec.option.gravity = np.asarray(m.gravity, dtype=float)
        for name in _DISABLED:
            spec.option.disableflags |= int(getattr(mj.mjtDisableBit, name))
        spec.option.integrator = int(mj.mjtIntegrator.mjINT_RK4)  # sim_reset sets the one asked
        # mj_step's silent reset to qpos0 on a NaN or huge state: off (module docstring)
        spec.option.disableflags |= int(mj.mjtDisableBit.mjDSBL_AUTORESET)
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
            if joint.type == BALL_JOINT:  # at the body's origin, about its own axes
                j = body.add_joint()
                j.name = f"j{k}_ball"
                j.type = mj.mjtJoint.mjJNT_BALL
            for i, axis in enumerate(joint.axes):
                j = body.add_joint()
                j.name = f"j{k}_{i}"
                j.type = hinge if axis.kind == "R" else slide
                j.axis = axis.u
            bodies.append(body)
        spec.compiler.balanceinertia = balance
        if m.couplings:  # each as a joint equality, q1 = polycoef[0] + polycoef[1] q2
            index = {name: k for k, name in enumerate(m.joint_names)}
            for stage in ("mjDSBL_CONSTRAINT", "mjDSBL_EQUALITY"):
                spec.option.disableflags &= ~int(getattr(mj.mjtDisableBit, stage))
            spec.option.solver = mj.mjtSolver.mjSOL_NEWTON
            spec.option.tolerance = COUPLING_TOLERANCE
            for i, c in enumerate(m.couplings):
                eq = spec.add_equality()
                eq.name, eq.type, eq.objtype = f"coupling{i}", mj.mjtEq.mjEQ_JOINT, \
                    mj.mjtObj.mjOBJ_JOINT
                eq.name1, eq.name2 = f"j{index[c.follower]}_0", f"j{index[c.leader]}_0"
                eq.data[:5] = [c.offset, c.multiplier, 0.0, 0.0, 0.0]
                eq.solimp = np.array([mj.mjMAXIMP, mj.mjMAXIMP, 0.001, 0.5, 2.0])
        self.spec, self.spec_bodies, self.principal = spec, bodies, np.array(principal)
        self._compile()

    def _compile(self):
        """Compile ``self.spec`` (built by ``_build``) and map the core's slots to MuJoCo's."""
        m = self.model
        if np.any(m.gravcomp):  # before compiling: MuJoCo counts the compensated bodies then
            for k in range(m.n_bodies):
                self.spec.body(f"b{k}").gravcomp = float(m.gravcomp[k])
        model = self.spec.compile()
        self.body_ids = [model.body(f"b{k}").id for k in range(m.n_bodies)]
        model.body_inertia[self.body_ids] = self.principal  # exact moments (balanceinertia)
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
            if joint.type == BALL_JOINT:
                mj_joint = model.joint(f"j{k}_ball")
                self.qidx[qs:qs + 4] = mj_joint.qposadr[0] + np.arange(4)
                self.eidx[vs:vs + 3] = mj_joint.dofadr[0] + np.arange(3)
                continue
            for i, axis in enumerate(joint.axes):
                mj_joint = model.joint(f"j{k}_{i}")
                # the compiled axis is the model's (MuJoCo normalises it: a unit vector stays
                # within rounding of itself, and a -z axis must not have become +z)
                assert np.abs(mj_joint.axis - axis.vector).max() < 1e-15
                assert model.qpos0[mj_joint.qposadr[0]] == 0.0
                self.qidx[qs + i] = mj_joint.qposadr[0]
                self.eidx[vs + i] = mj_joint.dofadr[0]
        self.mjmodel, self.mjdata = model, self.lib.MjData(model)
        if np.any(m.armature):  # per MuJoCo dof; mj_setConst recomputes dof_M0 from it
            model.dof_armature[self.eidx] = m.armature
            self.lib.mj_setConst(model, self.mjdata)
        # the passive elements, which act only when the native stepping switches the SPRING and
        # DAMPER stages on (qdd, M, bias stay the rigid body's: the flags off)
        self._rigid_flags = int(model.opt.disableflags)
        self._passive_flags = self._rigid_flags
        if m.has_passive:
            DS = self.lib.mjtDisableBit
            model.dof_damping[self.eidx] = m.damping
            jnt = model.dof_jntid[self.eidx]
            sprung = m.stiffness > 0
            model.jnt_stiffness[jnt[sprung]] = m.stiffness[sprung]
            model.qpos_spring[model.jnt_qposadr[jnt[sprung]]] = m.spring_ref[sprung]
            self._passive_flags &= ~(int(DS.mjDSBL_SPRING) | int(DS.mjDSBL_DAMPER))
        if model.nv != m.n_v or model.nq != m.n_q:
            raise AssertionError(f"model has nq={model.nq}, nv={model.nv}; the tree "
                                 f"{m.n_q}, {m.n_v}")

    def _engine_state(self, q, v):
        q = q.copy()
        for _, qs, _ in self.free:
            q[qs + 3:qs + 7] /= np.linalg.norm(q[qs + 3:qs + 7])
        for _, qs, _ in self.balls:
            q[qs:qs + 4] /= np.linalg.norm(q[qs:qs + 4])
        qe = np.empty(self.model.n_q)
        qe[self.qidx] = q
        return qe, []

    def _forward(self, qe, y, tau_e=None):
        if self.mjmodel.opt.disableflags != self._rigid_flags:  # after a native run
            self.mjmodel.opt.disableflags = self._rigid_flags
        d = self.mjdata
        d.qpos[:] = qe
        d.qvel[:] = y
        d.qfrc_applied[:] = 0.0 if tau_e is None else tau_e
        self.lib.mj_forward(self.mjmodel, d)
        return d

    def _qdd(self, qe, y, tau_e):
        return self._forward(qe, y, tau_e).qacc.copy()

    def _mass_matrix(self, qe):
        n = self.model.n_v
        d = self._forward(qe, np.zeros(n))
        M = np.zeros((n, n))
        self.lib.mj_fullM(self.mjmodel, d, M)
        return M

    def _bias(self, qe, y):
        return -self._forward(qe, y).qfrc_bias.copy()

    def _energy(self, qe, y):
        """(T, V): MuJoCo's mj_energyPos and mj_energyVel, called here rather than in every
        mj_forward (stored as (potential, kinetic))."""
        mj, d = self.lib, self._forward(qe, y)
        mj.mj_energyPos(self.mjmodel, d)
        mj.mj_energyVel(self.mjmodel, d)
        return d.energy[1], d.energy[0]

    def _position(self, qe, body, point):
        d = self._forward(qe, np.zeros(self.model.n_v))
        b = self.body_ids[body]
        return d.xpos[b] + d.xmat[b].reshape(3, 3) @ point

    # ------------------------------------------------------------------ native stepping
    def _sim_reset(self, q0, v0, h):
        m, d = self.mjmodel, self.mjdata
        m.opt.timestep = h
        m.opt.disableflags = self._passive_flags  # the model's own passive elements act
        m.opt.integrator = int(getattr(self.lib.mjtIntegrator,
                                       _INTEGRATORS[self.sim_integrator.name][1]))
        self.lib.mj_resetData(m, d)
        qe, blocks = self._state(q0, v0)
        d.qpos[:] = qe
        d.qvel[:] = self._to_engine(v0, blocks)
        self._mj_steps = 0

    def _sim_step(self):
        # a sample between steps runs mj_forward on the same data with the rigid flags and its
        # own qfrc_applied (_forward): the step takes the model's passive stages back, and no
        # applied force of a sample's
        if self.mjmodel.opt.disableflags != self._passive_flags:
            self.mjmodel.opt.disableflags = self._passive_flags
        self.mjdata.qfrc_applied[:] = 0.0
        self.lib.mj_step(self.mjmodel, self.mjdata)
        self._mj_steps += 1

    def _sim_counts(self):
        per_step = _INTEGRATORS[self.sim_integrator.name][2]
        return self._mj_steps, 0, per_step * self._mj_steps

    def _settings(self):
        """MuJoCo's ``opt`` as compiled (the loop adapter turns constraints on in the same
        model): flags by name, the constraint solver's settings, the fluid."""
        mj, opt = self.lib, self.mjmodel.opt
        disabled = [n for n, b in mj.mjtDisableBit.__members__.items()
                    if n != "mjNDISABLE" and opt.disableflags & int(b)]
        enabled = [n for n, b in mj.mjtEnableBit.__members__.items()
                   if n != "mjNENABLE" and opt.enableflags & int(b)]
        integ = {int(v): n for n, v in mj.mjtIntegrator.__members__.items()}
        return {"opt.integrator": integ[int(opt.integrator)], "opt.timestep": opt.timestep,
                "disabled": disabled, "enabled": enabled,
                "contacts": "off" if "mjDSBL_CONTACT" in disabled else "on",
                "constraints": "off" if "mjDSBL_CONSTRAINT" in disabled else "on",
                "warmstart": "mjDSBL_WARMSTART" not in disabled,
                "autoreset": "mjDSBL_AUTORESET" not in disabled,
                "solver": mj.mjtSolver(opt.solver).name, "iterations": int(opt.iterations),
                "tolerance": opt.tolerance, "ls_iterations": int(opt.ls_iterations),
                "noslip_iterations": int(opt.noslip_iterations),
                "jacobian": mj.mjtJacobian(opt.jacobian).name,
                "density": opt.density, "viscosity": opt.viscosity,
                "wind": [float(x) for x in opt.wind], "gravity": [float(x) for x in opt.gravity],
                "equalities": int(self.mjmodel.neq)}

    def _sim_state(self):
        d = self.mjdata
        if self.identity:
            return d.qpos.copy(), d.qvel.copy()
        return d.qpos[self.qidx], d.qvel[self.eidx]
