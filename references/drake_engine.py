"""Drake adapter: a continuous ``MultibodyPlant`` (``time_step = 0``) built from the Model's arrays.

What the plant contains and why (docs/design.md, "Reference engines"):

- one Drake rigid body per elementary axis of each body's joint
  (``redysim.references.base.joint_axes``), in order: a ``RevoluteJoint`` for an R axis and a
  ``PrismaticJoint`` for a P axis, ``axis = u`` as given (-z stays -z; Drake keeps the
  direction of the vector it is handed); the first axis's joint hangs from the parent body's
  frame (the world's for a root) at a ``FixedOffsetFrame`` of ``RigidTransform(placement_R,
  placement_p)`` (the parent's frame itself when the placement is the identity), each next
  axis from the body frame of the axis before it. The bodies between the axes of a U or S
  joint are massless (``SpatialInertia.Zero()``); the last one is the Model's body and carries
  its inertia. Drake's ``RevoluteJoint`` turns its child frame M about the axis through the
  parent frame F's origin (``R_FM = Rot(u, q)``, ``p_FM = 0``) and its ``PrismaticJoint`` moves
  it along the axis (``R_FM = 1``, ``p_FM = u q``): the core's convention, so a U joint is
  Ry(q1) Rz(q2) and an S joint Ry Rz Rx, as in the core. Drake's own ``UniversalJoint`` (x then
  y) and ``BallRpyJoint`` (space-fixed x-y-z) number other axes; they are not used.
- ``SpatialInertia(m, com, G_Bo)`` about the body origin, with the unit inertia ``G_Bo = (I_C +
  m (|c|^2 1 - c c^T)) / m`` (the parallel-axis shift done here from the Model's ``inertia_com``
  and ``com``); a body of zero mass and zero inertia is ``SpatialInertia.Zero()``. A body whose
  inertia violates the triangle inequality (the paper's rod model) fails Drake's
  ``IsPhysicallyValid`` and is built with ``skip_validity_check=True``, its numbers unchanged
  (the manifest lists those bodies: ``_settings``).
- gravity: ``mutable_gravity_field().set_gravity_vector(model.gravity)``. Nothing else: no
  SceneGraph (the plant is never registered as a geometry source, so there is no geometry, no
  contact and no query port), no actuators (an applied force goes through the
  ``applied_generalized_force`` input port) but one per 1-DOF joint with armature
  (``Model.armature``: its ``set_default_rotor_inertia``, gear ratio 1, so that the reflected
  inertia in M and in ``CalcKineticEnergy`` is the armature; its actuation input left
  unconnected, which Drake 1.51 takes as zero), no joint limits (a joint built without limits
  has none), damping 0, no force elements but gravity, no constraints. A free joint with
  armature is refused (a JointActuator drives a single-DOF joint).
- free joint: one ``QuaternionFloatingJoint`` from the world frame to the body frame.

Drake numbers bodies and coordinates by depth in its own forest; the adapter maps them to the
Model's order with each joint's ``position_start`` and ``velocity_start`` (a chain's order is
Drake's: nothing is converted).

Free joint, converted both ways (``redysim.references.base``): Drake's q is (qw, qx, qy, qz, x,
y, z) (quaternion first, w first) and its v = (w_world, v_world): the angular velocity of the
body in the WORLD frame and then the origin's velocity in the world frame (the joint's parent
frame F is the world frame, in which both are expressed). Gathered into the core's slot order,
y = (v_world, w_world), and v = (v_world, w_body) = B y with B = diag(1, R^T), R the body's
rotation. c = (dB/dt) y = (0, d(R^T)/dt w_world) = (0, -w_body x R^T w_world) = (0, -w_body x
w_body) = 0: B is a rotation of the angular part and the derivative term vanishes, so
vdot = B ydot. The applied force's angular part turns by R (tau_engine = B^T tau). Energies are
invariant.

Stages, on ONE double-valued Context reused for every call (no AutoDiff plant, no SceneGraph):
``qdd`` is the plant's ``generalized_acceleration`` output port evaluated on it: Drake's O(n)
articulated-body forward dynamics of a continuous plant (what ``CalcTimeDerivatives`` and so its
own integrators use), the joint force through a fixed value of the ``applied_generalized_force``
input port: of the three ways to qdd (the port, ``EvalTimeDerivatives``, ``CalcMassMatrix`` +
gravity - bias + a dense solve) the fastest at every size timed, the adapter's own checks and
setting of tau small beside it (references/README.md, "Each engine's fastest honest
configuration"). ``mass_matrix`` is ``CalcMassMatrix``; ``bias`` is
``CalcGravityGeneralizedForces - CalcBiasTerm`` (``redysim.phi``: the gravity forces minus
C(q, v) v); ``energy`` is (``CalcKineticEnergy``, ``CalcPotentialEnergy``), whose zero is the
core's (Drake's uniform-gravity potential is -sum m g . p_WBcm: no offset); ``position`` is
``CalcPointsPositions`` of the point in the body's frame, in the world frame.

Native integration: Drake's ``Simulator`` on the plant alone (no Diagram: the plant is the only
system; its applied-force ports are left unconnected, i.e. zero, in the simulator's own
Context), its integrator set by ``ApplySimulatorConfig(SimulatorConfig(...))`` as Drake intends
(``integration_scheme``, ``max_step_size``, ``accuracy``, ``use_error_control``,
``publish_every_time_step = False``, ``target_realtime_rate = 0``: as fast as it goes, no
publishing), then ``Simulator.Initialize()`` and the statistics reset (the warm-up, in the
manifest). Error-controlled ones (``DRAKE_ADAPTIVE``) take ``set_target_accuracy(rtol)`` and land
on each sample time by ``Simulator.AdvanceTo(t)``, ``max_step_size`` = h when given (else
SimulatorConfig's 0.1 s). How Drake reads the accuracy (``IntegratorBase::CalcStateChangeNorm``
and ``CalcAdjustedStepSize``): a step is accepted when the infinity norm of its error estimate,
with unit weights on every generalized velocity and on the positions (mapped through N(q)) and a
characteristic time of 1 s, is at most the accuracy, so it is an ABSOLUTE bound on each step's
local error in the state's own units, like an atol with rtol = 0, not a relative one; Drake has
no second number (``atol`` is recorded, not used). An accuracy looser than an integrator's
loosest is clamped by Drake (the manifest records ``accuracy_in_use``). The fixed-step ones
(``DRAKE_FIXED``: Drake's integrators without an error estimate, and RK3/RK5 in fixed-step mode)
take ``max_step_size = h`` and one ``AdvanceTo`` per step of h, exactly one Drake step each. The
implicit integrators' Jacobian is Drake's default (forward differences; pydrake's IntegratorBase
offers no other). Counts: the integrator's ``get_num_steps_taken``,
``get_num_step_shrinkages_from_error_control`` and ``get_num_derivative_evaluations`` (the
derivatives not found in the cache, the implicit ones' Jacobian columns included). A free
joint's quaternion is integrated as four numbers (Drake's mobilizer normalises it where it reads
it); the core reads its direction only.

Two Drake defects, measured (tests/test_engines_drake.py, ``known_engine_defect``):

- the FSAL integrators (``runge_kutta5``, ``bogacki_shampine3``) end a step with the plant's
  caches valid at its end; a rejected step is undone by ``StepOnceErrorControlledAtMost``
  writing the saved state through a live reference without an out-of-date notice, so the retried
  step's first derivative uses the rejected state's kinematics (which depend on q, not on time).
  On the 3-link pendulum over 1 s, RK5 at accuracy 1e-8 errs by 2.3e-5 (172 rejected steps)
  against 4.4e-8 (21 rejected) with the simulator Context's cache off (``sim_caching = False``,
  recorded in the manifest; ~6x the cost of a derivative). ``runge_kutta3`` invalidates the
  caches at the end of its step and is not affected. The default is Drake's (cache on).
- From Drake's own first step (``FIRST_STEP``) ``runge_kutta5`` rejected its first step without
  end on a 250-DOF rope and ``radau3`` stalled near 1e-5; from 1e-5 of ``max_step_size`` neither.

Loops: none. Drake's constraints (ball, weld, coupler, distance) exist for a discrete plant with
the SAP solver only: a continuous plant takes them and finalizes, then its first
``EvalTimeDerivatives`` raises "Continuous time does not support constraints" (measured; test
``test_a_continuous_plant_takes_no_loop_constraint``). SAP's are compliant and act by a step's
impulses, not the hard constraint forces the loop adapters compare (``references/README.md``).

Limits (references/limits.toml): memory. ``MultibodyPlant.Finalize()`` allocates ~n^2 bytes in
the number of Drake bodies (one per axis); measured with ``references/measure_limits.py``.
"""

from __future__ import annotations

import math
from importlib import metadata
from typing import Any

import numpy as np

from redysim.model.tree import FIXED, FREE

from .base import (
    Engine,
    EnginePackage,
    FreeBlock,
    NativeIntegrator,
    free_rotation,
    import_engine,
)

# Drake's integration schemes (pydrake.systems.analysis.GetIntegrationSchemes()) offered here:
# (name, scheme, use_error_control, order, note)
_SCHEMES = (
    ("runge_kutta3", "runge_kutta3", True, 3,
     "explicit RK3 with an embedded 2nd-order error estimate; Drake's default scheme"),
    ("bogacki_shampine3", "bogacki_shampine3", True, 3,
     "explicit Bogacki-Shampine 3(2), FSAL; Drake defect: a stale cache after a rejected step "
     "(sim_caching = False avoids it)"),
    ("runge_kutta5", "runge_kutta5", True, 5,
     "explicit Dormand-Prince 5(4), the 5th-order solution propagated, FSAL; Drake defect: a "
     "stale cache after a rejected step (sim_caching = False avoids it)"),
    ("radau3", "radau3", True, 3,
     "implicit two-stage Radau IIA (order 3), Newton on a forward-difference Jacobian (from "
     "Drake's own first step its error stalled near 1e-5; the adapter starts it small)"),
    ("implicit_euler", "implicit_euler", True, 1,
     "implicit Euler by step doubling: two half steps propagated, their difference from one "
     "full step the O(h^2) error estimate; Newton on a finite-difference Jacobian"),
    ("explicit_euler", "explicit_euler", False, 1, "Drake's explicit Euler"),
    ("semi_explicit_euler", "semi_explicit_euler", False, 1,
     "Drake's semi-explicit (symplectic) Euler: v then q from the new v"),
    ("runge_kutta2", "runge_kutta2", False, 2, "Drake's explicit trapezoid rule (Heun), RK2"),
    ("runge_kutta3-fixed", "runge_kutta3", False, 3,
     "runge_kutta3 in fixed-step mode (set_fixed_step_mode(True): no error control)"),
    ("runge_kutta5-fixed", "runge_kutta5", False, 5,
     "runge_kutta5 in fixed-step mode (set_fixed_step_mode(True): no error control)"),
)
SCHEME = {name: scheme for name, scheme, *_ in _SCHEMES}
ORDER = {name: order for name, _, _, order, _ in _SCHEMES}
DRAKE_ADAPTIVE = tuple(name for name, _, adaptive, *_ in _SCHEMES if adaptive)
DRAKE_FIXED = tuple(name for name, _, adaptive, *_ in _SCHEMES if not adaptive)
# an adaptive integrator's largest step when the run gives no h: SimulatorConfig's default
DEFAULT_MAX_STEP = 0.1
# An error-controlled scheme's first step, as a fraction of max_step_size. Drake's own first try
# (its initial step target, 0.01 s) sent runge_kutta5 on the 250-DOF rope of the ladder
# (cases/ladder/swing-U125-L1.toml) into a loop of rejections without end: after 24 s of CPU no
# step taken, 10,747 shrinkages, and a monitor (called at the end of a step) never called.
# Started at 1e-6 s it takes 1,522 steps to 1 s at accuracy 1e-4.
FIRST_STEP = 1e-5


def _what(scheme: str, adaptive: bool) -> str:
    return (f"Simulator + ApplySimulatorConfig(SimulatorConfig(integration_scheme={scheme!r}, "
            f"use_error_control={adaptive}))")


def _spatial_inertia(tree, mass: float, com, I_c):
    """Drake's SpatialInertia of a body about its origin, and whether Drake's validity check
    had to be skipped (an inertia outside the triangle inequality). Raises ValueError for a
    body with zero mass and nonzero inertia, which Drake's (mass, unit inertia) form cannot
    hold."""
    I_c = np.asarray(I_c, dtype=float)
    c = np.asarray(com, dtype=float)
    if mass == 0.0:
        if np.any(I_c):
            raise ValueError("zero mass with a nonzero inertia")
        return tree.SpatialInertia.Zero(), False
    G = (I_c + mass * (c @ c * np.eye(3) - np.outer(c, c))) / mass
    unit = tree.UnitInertia(G[0, 0], G[1, 1], G[2, 2], G[0, 1], G[0, 2], G[1, 2])
    try:
        return tree.SpatialInertia(mass, c, unit), False
    except RuntimeError:  # not physically valid (e.g. the rod model's inertia)
        return tree.SpatialInertia(mass, c, unit, skip_validity_check=True), True


class DrakePackage(EnginePackage):
    """Drake's package: pip's ``drake``, imported as ``pydrake``, which has no ``__version__``:
    its version is the installed distribution's (``importlib.metadata``), read once the module
    imports (:class:`EngineUnavailable` naming the package when it does not)."""

    name = "drake"
    package = "drake"
    module = "pydrake"

    @classmethod
    def package_version(cls) -> str:
        import_engine(cls.name, cls.package, cls.module)
        return metadata.version(cls.package)


class Drake(DrakePackage, Engine):
    """Drake's continuous ``MultibodyPlant`` on a :class:`redysim.Model` (module docstring).
    ``plant``, ``context``: the finalized plant and the one Context the stages use;
    ``body_frames[k]``: the frame of body k (its last axis's Drake body); ``qidx``, ``eidx``:
    Drake's position and velocity index of each of the core's q and v slots."""

    integrator = "runge_kutta2"
    integrators = {
        name: NativeIntegrator(name, adaptive, _what(scheme, adaptive), note)
        for name, scheme, adaptive, _, note in _SCHEMES}
    holds_armature = "a JointActuator's rotor inertia, gear ratio 1, per 1-DOF joint"
    holds_passive = ("in the Simulator's Context only (the qdd's Context keeps the rigid "
                     "body's): each 1-DOF joint's damping (Joint.SetDampingVector), a "
                     "RevoluteSpring per sprung revolute axis (SetStiffness, SetNominalAngle; "
                     "stiffness 0 by default), each body's gravcomp a constant "
                     "ExternallyAppliedSpatialForce of -gravcomp m g at its COM on the applied "
                     "spatial force input port")
    no_couplings = ("Drake's coupler constraint (MultibodyPlant.AddCouplerConstraint) is for a "
                    "discrete plant with the SAP solver only (compliant, by a step's impulses); "
                    "this adapter's plant is continuous (time_step = 0), where the plant takes "
                    "it and then EvalTimeDerivatives raises 'Continuous time does not support "
                    "constraints' (Drake, measured)")
    no_ball = ("Drake's BallRpyJoint has roll-pitch-yaw coordinates, singular at pitch +-90 "
               "degrees, so it cannot stand in exactly for the core's quaternion")
    # the simulator Context's cache (Drake's default: on); False disables it (module docstring:
    # the FSAL integrators' stale cache after a rejected step), at ~6x the cost a derivative
    sim_caching: bool = True
    # why there is no loop adapter (references/README.md, "Loops"; measured in
    # tests/test_engines_drake.py, test_a_continuous_plant_takes_no_loop_constraint)
    no_loops = ("Drake's loop-closing constraints exist only for a discrete plant with its SAP "
                "solver: a continuous plant refuses them at its first dynamics evaluation, so it "
                "gives no constrained qdd, and SAP's compliant steps are not the model compared "
                "here")

    @classmethod
    def unsupported(cls, model, joints):
        for k, joint in enumerate(joints):
            if model.mass[k] == 0.0 and np.any(np.asarray(model.inertia_com[k])):
                return (f"body {joint.body!r} has zero mass and a nonzero inertia, which "
                        f"Drake's SpatialInertia (mass times a unit inertia) cannot hold")
            if joint.type == FREE and np.any(
                    model.armature[model.joint_voff[k]:model.joint_voff[k + 1]]):
                return (f"the free joint of body {joint.body!r} has armature: Drake holds "
                        f"armature as a JointActuator's rotor inertia, and a JointActuator "
                        f"drives a single-DOF joint only")
        return ""

    # ------------------------------------------------------------------ the plant
    def _build(self):
        from pydrake.math import RigidTransform, RotationMatrix
        from pydrake.multibody import tree
        from pydrake.multibody.plant import MultibodyPlant

        m = self.model
        plant = MultibodyPlant(time_step=0.0)
        plant.mutable_gravity_field().set_gravity_vector(np.asarray(m.gravity, dtype=float))
        body_frames: list[Any] = []
        drake_joints: list[list[Any]] = []
        self._springs: list[tuple[int, Any]] = []  # (v slot, RevoluteSpring)
        self.unchecked_inertia: list[str] = []
        for k, joint in enumerate(self.joints):
            inertia, skipped = _spatial_inertia(tree, float(m.mass[k]), m.com[k],
                                                m.inertia_com[k])
            if skipped:
                self.unchecked_inertia.append(joint.body)
            parent = (plant.world_frame() if joint.parent < 0 else body_frames[joint.parent])
            if joint.type == FREE:
                body = plant.AddRigidBody(f"b{k}", inertia)
                drake_joints.append([plant.AddJoint(tree.QuaternionFloatingJoint(
                    f"j{k}_free", plant.world_frame(), body.body_frame()))])
                body_frames.append(body.body_frame())
                continue
            frame = parent
            if not (np.array_equal(joint.R, np.eye(3)) and not np.any(joint.p)):
                frame = plant.AddFrame(tree.FixedOffsetFrame(
                    f"F{k}", parent, RigidTransform(RotationMatrix(joint.R), joint.p)))
            if joint.type == FIXED or not joint.axes:
                body = plant.AddRigidBody(f"b{k}", inertia)
                plant.WeldFrames(frame, body.body_frame())
                drake_joints.append([])
                body_frames.append(body.body_frame())
                continue
            js = []
            for i, axis in enumerate(joint.axes):
                last = i == len(joint.axes) - 1
                body = plant.AddRigidBody(f"b{k}" if last else f"b{k}_{i}",
                                          inertia if last else tree.SpatialInertia.Zero())
                cls = tree.RevoluteJoint if axis.kind == "R" else tree.PrismaticJoint
                js.append(plant.AddJoint(cls(f"j{k}_{i}", frame, body.body_frame(),
                                             axis.vector)))
                slot = int(m.joint_voff[k]) + i
                if axis.kind == "R" and m.stiffness[slot]:  # its stiffness set in the sim only
                    self._springs.append((slot, plant.AddForceElement(tree.RevoluteSpring(
                        js[-1], float(m.spring_ref[slot]), 0.0))))
                armature = float(m.armature[m.joint_voff[k] + i])
                if armature:  # a rotor's inertia reflected through a gear ratio of 1
                    actuator = plant.AddJointActuator(f"a{k}_{i}", js[-1])
                    actuator.set_default_rotor_inertia(armature)
                    actuator.set_default_gear_ratio(1.0)
                frame = body.body_frame()
            drake_joints.append(js)
            body_frames.append(frame)
        plant.Finalize()
        if plant.num_velocities() != m.n_v or plant.num_positions() != m.n_q:
            raise AssertionError(f"plant has nq={plant.num_positions()}, "
                                 f"nv={plant.num_velocities()}; the tree {m.n_q}, {m.n_v}")
        # the core's slots -> Drake's
        self.qidx = np.zeros(m.n_q, dtype=np.int64)
        for k, js in enumerate(drake_joints):
            qs, vs = int(m.joint_qoff[k]), int(m.joint_voff[k])
            if self.joints[k].type == FREE:
                ps, ws = js[0].position_start(), js[0].velocity_start()
                self.qidx[qs:qs + 7] = ps + np.array([4, 5, 6, 0, 1, 2, 3])
                self.eidx[vs:vs + 6] = ws + np.array([3, 4, 5, 0, 1, 2])
                continue
            for i, j in enumerate(js):
                self.qidx[qs + i] = j.position_start()
                self.eidx[vs + i] = j.velocity_start()
        self.plant, self.body_frames, self.drake_joints = plant, body_frames, drake_joints
        self.world = plant.world_frame()
        self.context = plant.CreateDefaultContext()
        self._tau_port = plant.get_applied_generalized_force_input_port()
        self._tau_value = self._tau_port.FixValue(self.context, np.zeros(m.n_v))
        self._tau_zero = True
        self._accel_port = plant.get_generalized_acceleration_output_port()
        self._sim = None

    def _engine_state(self, q, v):
        qe = np.empty(self.model.n_q)
        qe[self.qidx] = q
        blocks = []
        for _, qs, vs in self.free:
            quat = q[qs + 3:qs + 7] / np.linalg.norm(q[qs + 3:qs + 7])
            qe[self.qidx[qs + 3:qs + 7]] = quat
            B = np.eye(6)
            B[3:, 3:] = free_rotation(q, qs).T
            blocks.append(FreeBlock(vs, B, np.zeros(6)))
        return qe, blocks

    def _set(self, qe, y=None):
        """The one Context at (qe, y) (y None: positions only)."""
        if y is None:
            self.plant.SetPositions(self.context, qe)
        else:
            self.plant.SetPositionsAndVelocities(self.context, np.concatenate((qe, y)))

    # ------------------------------------------------------------------ stages
    def _qdd(self, qe, y, tau_e):
        if tau_e is not None:
            self._tau_value.GetMutableData().get_mutable_value().SetFromVector(tau_e)
            self._tau_zero = False
        elif not self._tau_zero:
            self._tau_value.GetMutableData().get_mutable_value().SetFromVector(np.zeros(self.model.n_v))
            self._tau_zero = True
        self._set(qe, y)
        return np.array(self._accel_port.Eval(self.context))

    def _mass_matrix(self, qe):
        self._set(qe)
        return self.plant.CalcMassMatrix(self.context)

    def _bias(self, qe, y):
        self._set(qe, y)
        p, c = self.plant, self.context
        return p.CalcGravityGeneralizedForces(c) - p.CalcBiasTerm(c)

    def _energy(self, qe, y):
        self._set(qe, y)
        return self.plant.CalcKineticEnergy(self.context), \
            self.plant.CalcPotentialEnergy(self.context)

    def _position(self, qe, body, point):
        self._set(qe)
        return self.plant.CalcPointsPositions(self.context, self.body_frames[body],
                                              point.reshape(3, 1), self.world)[:, 0]

    # ------------------------------------------------------------------ native integration
    def _simulator(self):
        if self._sim is None:
            from pydrake.systems.analysis import Simulator

            self._sim = Simulator(self.plant)  # its own Context: no applied force
        return self._sim

    def passive_unheld(self) -> str:
        why = self.passive_on_free()
        if why:
            return why
        m = self.model
        for k, joint in enumerate(self.joints):
            for i, axis in enumerate(joint.axes):
                slot = int(m.joint_voff[k]) + i
                if axis.kind == "P" and m.stiffness[slot]:
                    return (f"the spring of joint {joint.name!r} (stiffness[{slot}] = "
                            f"{float(m.stiffness[slot]):g}): a PrismaticSpring's stiffness is "
                            f"not a Context parameter in pydrake (no SetStiffness), so it would "
                            f"act in the qdd's Context too")
        return ""

    def _sim_passive(self, ctx) -> None:
        """The model's passive elements in the Simulator's Context (``holds_passive``)."""
        from pydrake.multibody.math import SpatialForce
        from pydrake.multibody.plant import ExternallyAppliedSpatialForce

        m = self.model
        if not m.has_passive:
            return
        for k, js in enumerate(self.drake_joints):
            if self.joints[k].type == FREE:
                continue
            for i, j in enumerate(js):
                j.SetDampingVector(ctx, [float(m.damping[int(m.joint_voff[k]) + i])])
        for slot, spring in self._springs:
            spring.SetStiffness(ctx, float(m.stiffness[slot]))
            spring.SetNominalAngle(ctx, float(m.spring_ref[slot]))
        forces = []
        g = np.asarray(m.gravity, dtype=float)
        for k in np.flatnonzero(m.gravcomp):
            f = ExternallyAppliedSpatialForce()
            f.body_index = self.body_frames[k].body().index()
            f.p_BoBq_B = np.array(m.com[k], dtype=float)
            f.F_Bq_W = SpatialForce(np.zeros(3), -float(m.gravcomp[k]) * float(m.mass[k]) * g)
            forces.append(f)
        if forces:
            self.plant.get_applied_spatial_force_input_port().FixValue(ctx, forces)

    def _sim_reset(self, q0, v0, h):
        from pydrake.systems.analysis import ApplySimulatorConfig, SimulatorConfig

        info, s = self.sim_integrator, self.sim_settings
        sim = self._simulator()
        config = SimulatorConfig(
            integration_scheme=SCHEME[info.name],
            max_step_size=float(h) if h is not None else DEFAULT_MAX_STEP,
            accuracy=float(s["rtol"]) if info.adaptive else SimulatorConfig().accuracy,
            use_error_control=info.adaptive, start_time=0.0, target_realtime_rate=0.0,
            publish_every_time_step=False)
        ApplySimulatorConfig(config, sim)
        self._sim_config = config
        qe, blocks = self._state(q0, v0)
        ctx = sim.get_mutable_context()
        ctx.SetTime(0.0)
        self._sim_passive(ctx)
        self.plant.SetPositionsAndVelocities(ctx, np.concatenate((qe,
                                                                  self._to_engine(v0, blocks))))
        if not self.sim_caching:
            ctx.DisableCaching()
        else:
            ctx.EnableCaching()
        if info.adaptive:  # a first step the controller grows by its own rule (FIRST_STEP)
            sim.get_mutable_integrator().request_initial_step_size_target(
                FIRST_STEP * config.max_step_size)
        sim.Initialize()
        sim.get_mutable_integrator().ResetStatistics()
        self._k = 0

    def _sim_step(self):
        # exactly one step of h per call: AdvanceTo(k h), unless t + h falls short of k h by
        # rounding, where Drake would take a full step h and then a sliver to k h (measured:
        # 2 steps a call at k = 7 and 10 with h = 2.5e-3); then AdvanceTo(t + h), one ulp off the
        # grid, which the next step rejoins
        self._k += 1
        h = self.sim_settings["h"]
        self._sim.AdvanceTo(min(self._k * h, self._sim.get_context().get_time() + h))

    def _sim_advance(self, t: float) -> None:
        sim = self._sim
        if math.isfinite(self._deadline[1]):  # a monitor at every step checks the CPU limit
            from pydrake.systems.framework import EventStatus

            def monitor(context):
                if self._past_deadline():
                    return EventStatus.ReachedTermination(None, "CPU-time limit")
                return EventStatus.DidNothing()

            sim.set_monitor(monitor)
        else:
            sim.clear_monitor()
        sim.AdvanceTo(t)
        now = sim.get_context().get_time()
        if now < t:
            raise TimeoutError(f"drake stopped its advance to t = {t:.6g} at t = {now:.6g}, "
                               "its CPU-time limit reached")

    def _sim_state(self):
        ctx = self._sim.get_context()
        x = self.plant.GetPositionsAndVelocities(ctx)
        m = self.model
        qe, ye = x[:m.n_q], x[m.n_q:]
        q = np.asarray(qe)[self.qidx]
        if self.identity:
            return q.copy(), np.array(ye, dtype=float)
        _, blocks = self._state(q, np.zeros(m.n_v))
        return q, self._from_engine(ye, blocks)

    def _sim_counts(self) -> tuple[int, int, int]:
        integ = self._sim.get_integrator()
        return (integ.get_num_steps_taken(), integ.get_num_step_shrinkages_from_error_control(),
                integ.get_num_derivative_evaluations())

    def _settings(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "plant_time_step": self.plant.time_step(),
            "scene_graph": False,
            "joint_limits": "none", "actuators": 0,
            "damping": (0.0 if not self.model.has_passive else "the model's damping, springs "
                        "and gravcomp in the Simulator's Context only (holds_passive)"),
            "unchecked_inertia_bodies": list(self.unchecked_inertia),
            "qdd": "generalized_acceleration output port (articulated-body forward dynamics), "
                   "one Context",
            "warm_up": "none: every call sets the Context's q, v (and tau) and evaluates",
        }
        if self._sim is not None and getattr(self, "sim_integrator", None) is not None:
            from pydrake.systems.analysis import ExtractSimulatorConfig

            integ = self._sim.get_integrator()
            used = ExtractSimulatorConfig(self._sim)
            out.update(
                integration_scheme=used.integration_scheme,
                max_step_size=integ.get_maximum_step_size(),
                fixed_step_mode=bool(integ.get_fixed_step_mode()),
                target_accuracy=(integ.get_target_accuracy()
                                 if self.sim_integrator.adaptive else None),
                accuracy_in_use=used.accuracy if used.use_error_control else None,
                atol_used=False,
                publish_every_time_step=used.publish_every_time_step,
                target_realtime_rate=used.target_realtime_rate,
                simulator_warm_up="Simulator.Initialize() at sim_reset; statistics reset "
                                  "after it",
                simulator_context_caching=bool(self.sim_caching),
                jacobian="Drake's default for the implicit ones: forward differences (not "
                         "settable through pydrake's IntegratorBase)",
                order=ORDER[self.sim_integrator.name])
            if math.isnan(out["max_step_size"]):
                out["max_step_size"] = None
        return out
