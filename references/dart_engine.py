"""DART adapter (dartpy): a Skeleton of one Joint + BodyNode pair per body, no massless bodies.

What the model contains and why (docs/design.md, "Reference engines"):

- per body one ``create...JointAndBodyNodePair`` whose joint is the body's whole joint, chosen
  by its elementary axes (``redysim.references.base.joint_axes``), its parent BodyNode the parent
  body's (None for a root: a Skeleton holds several trees):

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
    the core's S joint, with the body frame (the BodyNode's) unrotated;
  * a free joint: ``FreeJoint`` at the identity (its coordinates converted, below);
  * anything else is refused by ``limits()`` (no joint type in DART composes it). Building it
    from several joints needs massless intermediate BodyNodes, which DART warns against ("A
    negative or zero mass [0] is set to BodyNode [...], which can cause invalid physical behavior
    or segfault"; its ``Inertia`` also warns that zero moments are invalid), so this adapter does
    not. No joint of ``redysim.model.parts.JOINT_TYPES`` needs that.

  ``mT_ParentBodyToJoint`` is the placement (R, p) (times P for an EulerJoint; for a chain's
  link k a translation of l_{k-1} along the parent's x, the identity for the first);
  ``mT_ChildBodyToJoint`` is the identity (the body frame is at the joint) but for the
  EulerJoint's rotation P. A PrismaticJoint moves the BodyNode (the body frame) by u q, so the
  next joint starts at its placement in the moved frame, as in the core.
- ``BodyNode.setInertia(Inertia(m, c, I_C))`` (inertia about the COM in the body frame);
- ``skel.setGravity(model.gravity)``.
- No ShapeNodes (so no collision or visual geometry), self-collision check off (DART's default),
  joint damping, spring stiffness, friction and position-limit enforcement left at their
  zero/off defaults and asserted off after the build.

``qdd``: ``setPositions/setVelocities/setForces(tau)`` then ``computeForwardDynamics()``
(articulated-body algorithm) and ``getAccelerations()``; ``mass_matrix``: ``getMassMatrix()``;
``bias``: ``-getCoriolisAndGravityForces()``; ``energy``: ``computeKineticEnergy()`` and
``computePotentialEnergy()``; ``position``: the body's BodyNode world transform applied to the
point. DART numbers DOF tree by tree; the adapter maps them by ``getIndexInSkeleton``.

Free joint, converted both ways (``redysim.references.base``): dartpy 6.20's FreeJoint has positions
(rotation vector, translation) and velocities (w_world, v_world), the angular velocity in the
WORLD frame first (its relative Jacobian is diag(R^T, R^T), measured). Positions come from
``FreeJoint.convertToPositions(Isometry3(R, p))`` (and go back by ``convertToTransform``); the two
halves of the velocity are swapped by the index map, so that y = (v_world, w_world) in the
core's slots, and then B = diag(1, R^T) and c = 0, as d/dt (R^T w_world) = R^T dw_world/dt
(w x w = 0).

Native integrator (``DART.integrators``): a ``dartpy.simulation.World`` holding only this
skeleton, ``World.step()`` at the fixed time step h:

| name                | what                     | step  | order | note                         |
|---------------------|--------------------------|-------|-------|------------------------------|
| semi-implicit-euler | World.step (setTimeStep) | fixed | 1     | forward dynamics (ABA), then |
|                     |                          |       |       | v += h a, then q by the new  |
|                     |                          |       |       | v; the only one DART has     |

DART 6.20 has no other integrator to choose from Python, checked: ``World`` has no
``setIntegrator`` (its methods: step, setTimeStep, setTime, setGravity, the collision detector,
the constraint solver, deactivation, threads), dartpy has no ``integration`` module (its
modules: collision, common, constraint, dynamics, gui, math, optimizer, simulation, utils), and
the only integration calls are ``Skeleton/Joint.integratePositions`` and
``integrateVelocities``, the two halves of this same step (an RK4 built from them would be this
adapter's integrator, not DART's; DART 6's C++ ``integration::RK4Integrator`` needs an
``IntegrableSystem``, which no ``World`` or ``Skeleton`` is and dartpy does not bind).
With no shapes the collision detector (FCL) finds nothing and the constraint solver
(``BoxedLcpConstraintSolver``, Dantzig, PGS as its fallback) has no constraint to solve.
``World`` deactivation (sleeping of slow bodies; dartpy 6.20 enables it by default, 0.01 m/s
and 0.05 rad/s for 0.5 s) is turned off: it put nothing to sleep here (a free box at 1 mm/s and
a chain at 2e-3 rad/s ran the same with and without it, measured), but a reference run must not
depend on it. ``sim_counts``: the steps, no rejections, one forward dynamics a step;
``manifest``: the time step, the deactivation, the collision detector, the LCP solvers, split
impulse and the threads.

Limit: building the skeleton costs ~n^3 in time (docs/notes/2026-11-reference-engines.md), so time,
not memory, stops it (references/limits.toml). ``limits`` refuses a massless body (no massless
BodyNodes, above) and a joint no DART joint composes (none of the core's joint types).
"""

from __future__ import annotations

import os
import re
import sys
import tempfile

import numpy as np

from redysim.model.tree import FREE

from .base import (
    Engine,
    FreeBlock,
    NativeIntegrator,
    build_warnings,
    free_rotation,
    rotation_quaternion,
)

_ANSI = re.compile(r"\x1b\[[0-9;]*m")


class _StderrCapture:
    """Captures what C++ writes to the process's stderr (file descriptor 2) inside the block:
    DART warns there ("Warning [Inertia.cpp:279] [Inertia::verifyMoment] ..."), past Python's
    sys.stderr, so that a run printed ten such lines among the command's output. ``lines``:
    what was written, colour codes stripped, one entry per line."""

    def __enter__(self):
        sys.stderr.flush()
        self._file = tempfile.TemporaryFile()
        self._saved = os.dup(2)
        os.dup2(self._file.fileno(), 2)
        self.lines: list[str] = []
        return self

    def __exit__(self, *exc):
        sys.stderr.flush()
        os.dup2(self._saved, 2)
        os.close(self._saved)
        self._file.seek(0)
        text = _ANSI.sub("", self._file.read().decode("utf-8", "replace"))
        self._file.close()
        self.lines = [line.strip() for line in text.splitlines() if line.strip()]
        return False


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
    """DART ``computeForwardDynamics`` (ABA) on a Skeleton of one Joint + BodyNode pair per body
    (module docstring). ``skel``: the Skeleton; ``bodynodes[k]``: body k's BodyNode.

    Refused by ``limits``: a massless body (DART warns that a zero mass "can cause invalid
    physical behavior or segfault"), and joints no DART joint composes (none of the core's).
    """

    name = "dart"
    package = "dartpy"
    module = "dartpy"
    no_armature = ("dartpy 6.20 exposes no joint armature (a DOF's damping, spring stiffness "
                   "and rest position, nothing on its inertia: no rotor inertia on Joint or "
                   "its Properties, checked)")
    holds_armature = ("by the adapter, from DART's own getMassMatrix and "
                      "getCoriolisAndGravityForces: (M + diag(armature)) qdd = tau - (C + g), "
                      "the equations DART would solve had it the field (it has none: "
                      + no_armature + "); World.step does not hold it")
    armature_native = False
    holds_passive = ("on a clone of the skeleton that only World.step steps: each 1-DOF joint's "
                     "Joint.setDampingCoefficient, setSpringStiffness and setRestPosition (DART "
                     "takes them implicitly in its step: -K (q + h qdot - q_ref), the "
                     "articulated inertia raised by h D + h^2 K), each body's gravcomp a "
                     "BodyNode.setExtForce of -gravcomp m g at its COM before every step; the "
                     "qdd's skeleton stays the rigid body's")
    no_couplings = ("DART's mimic joints are out of reach from Python: dartpy 6.20 binds "
                    "Joint.setActuatorType(MIMIC) but not setMimicJoint (no such method on "
                    "dartpy.dynamics.Joint, checked), so a MIMIC joint has no leader")
    no_ball = ("DART's BallJoint has exponential-map coordinates; their conversion from the "
               "core's quaternion is not built in this adapter")
    integrator = "semi-implicit-euler"
    integrators = {"semi-implicit-euler": NativeIntegrator(
        "semi-implicit-euler", False, "World.step at World.setTimeStep(h)",
        "semi-implicit Euler: forward dynamics (ABA), v += h a, then q by the new v; first "
        "order; DART's only integrator (module docstring); no shapes, so no contacts; World "
        "deactivation (sleeping) off")}

    @classmethod
    def unsupported(cls, model, joints):
        for k, joint in enumerate(joints):
            if joint.type != FREE and _construction(joint.axes) is None:
                return (f"{joint.where()} cannot be built: DART has one joint type per BodyNode "
                        "and none that composes these axes; splitting the joint needs massless "
                        "BodyNodes, which DART warns 'can cause invalid physical behavior or "
                        "segfault'")
            if not model.mass[k] > 0.0:
                return (f"body {joint.body!r} is massless: DART warns that a zero mass 'can "
                        "cause invalid physical behavior or segfault'")
        return ""

    def _build(self):
        dart = self.lib
        dyn = dart.dynamics
        m = self.model
        skel = dyn.Skeleton(m.name)
        self.build_warnings: dict[str, int] = {}  # DART's warning -> how many bodies
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
                P = np.array([a.u for a in joint.axes]).T  # columns u1, u2, u3: a rotation
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
            with _StderrCapture() as said:  # DART's C++ warnings: kept for the manifest
                body.setInertia(dyn.Inertia(float(m.mass[k]), np.array(m.com[k]),
                                            np.array(m.inertia_com[k])))
            for line in said.lines:
                self.build_warnings[line] = self.build_warnings.get(line, 0) + 1
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
        self.free_dofs = []  # per free joint: (qs, vs, its DART DOF indices)
        for k, (joint, dj) in enumerate(zip(self.joints, djoints, strict=True)):
            vs = int(m.joint_voff[k])
            idx = [dj.getIndexInSkeleton(i) for i in range(dj.getNumDofs())]
            if joint.type == FREE:
                self.eidx[vs:vs + 6] = idx[3:] + idx[:3]
                self.free_dofs.append((int(m.joint_qoff[k]), vs, idx))
            else:
                self.eidx[vs:vs + len(idx)] = idx
        self.skel, self.bodynodes = skel, bodies
        # the armature in DART's DOF order, held in the qdd (holds_armature); None: none
        self.arm = self.armature_e if np.any(m.armature) else None
        self.world = None  # simulate's, made on first use
        self.sim_skel = skel  # the skeleton World.step steps (a clone with passive elements)

    def _engine_state(self, q, v):
        qe = self._scatter(q)
        blocks = []
        for qs, vs, idx in self.free_dofs:
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

    def passive_unheld(self) -> str:
        return self.passive_on_free()

    def _set(self, qe, y, tau_e=None, skel=None):
        s = self.skel if skel is None else skel
        s.setPositions(qe)
        s.setVelocities(y)
        s.setForces(np.zeros(self.model.n_v) if tau_e is None else tau_e)

    def _qdd(self, qe, y, tau_e):
        if self.arm is not None:  # (M + diag(armature)) qdd = tau - (C + g): holds_armature
            self._set(qe, y)
            rhs = -np.array(self.skel.getCoriolisAndGravityForces())
            if tau_e is not None:
                rhs = rhs + tau_e
            M = np.array(self.skel.getMassMatrix())
            return np.linalg.solve(M + np.diag(self.arm), rhs)
        self._set(qe, y, tau_e)
        self.skel.computeForwardDynamics()
        return np.array(self.skel.getAccelerations())

    def _mass_matrix(self, qe):
        self._set(qe, np.zeros(self.model.n_v))
        M = np.array(self.skel.getMassMatrix())
        return M if self.arm is None else M + np.diag(self.arm)

    def _bias(self, qe, y):
        self._set(qe, y)
        return -np.array(self.skel.getCoriolisAndGravityForces())

    def _energy(self, qe, y):
        self._set(qe, y)
        T = self.skel.computeKineticEnergy()
        if self.arm is not None:  # the joints' own inertia: 1/2 armature v^2
            T += 0.5 * float(self.arm @ (y * y))
        return T, self.skel.computePotentialEnergy()

    def _position(self, qe, body, point):
        self._set(qe, np.zeros(self.model.n_v))
        M = np.array(self.bodynodes[body].getWorldTransform().matrix())
        return M[:3, :3] @ point + M[:3, 3]

    # ------------------------------------------------------------------ native stepping
    def _sim_reset(self, q0, v0, h):
        if self.world is None:
            self.world = self.lib.simulation.World()
            self.world.setGravity(np.asarray(self.model.gravity, dtype=float))
            self.sim_skel = self._passive_skeleton()
            self.world.addSkeleton(self.sim_skel)
            sleep = self.world.getDeactivationOptions()  # a copy: set back (module docstring)
            sleep.mEnabled = False
            self.world.setDeactivationOptions(sleep)
        self.world.setTimeStep(h)
        self.world.setTime(0.0)
        qe, blocks = self._state(q0, v0)
        self._set(qe, self._to_engine(v0, blocks), skel=self.sim_skel)
        self._dart_steps = 0

    def _passive_skeleton(self):
        """The skeleton World.step steps: the qdd's own when the model has no passive element,
        else a clone holding them (``holds_passive``), so that a qdd, bias or mass matrix call
        between steps sees neither them nor the stepped state. ``_gravcomp``: (BodyNode, force
        [N, world], COM [m, body]) of each body with gravcomp, set again before every step
        (World.step clears external forces after it)."""
        m = self.model
        self._gravcomp = []
        if not m.has_passive:
            return self.skel
        skel = self.skel.clone()
        for k, (joint, dj) in enumerate(zip(self.joints, (self.bodynodes[i].getParentJoint()
                                                          for i in range(m.n_bodies)),
                                            strict=True)):
            if joint.type == FREE:  # (passive_unheld refuses damping there)
                continue
            cj = skel.getJoint(dj.getJointIndexInSkeleton())
            for i in range(cj.getNumDofs()):
                slot = int(m.joint_voff[k]) + i
                cj.setDampingCoefficient(i, float(m.damping[slot]))
                cj.setSpringStiffness(i, float(m.stiffness[slot]))
                cj.setRestPosition(i, float(m.spring_ref[slot]))
        g = np.asarray(m.gravity, dtype=float)
        for k in np.flatnonzero(m.gravcomp):
            body = skel.getBodyNode(self.bodynodes[k].getIndexInSkeleton())
            self._gravcomp.append((body, -float(m.gravcomp[k]) * float(m.mass[k]) * g,
                                   np.array(m.com[k], dtype=float)))
        return skel

    def _sim_step(self):
        for body, force, com in self._gravcomp:  # world force at the COM (in the body frame)
            body.setExtForce(force, com, False, True)
        self.world.step()
        self._dart_steps += 1

    def _sim_counts(self):
        return self._dart_steps, 0, self._dart_steps

    def _settings(self):
        out: dict = {"shape_nodes": sum(int(b.getNumShapeNodes()) for b in self.bodynodes)}
        if self.build_warnings:  # (a thin rod's zero moment about its axis: used as given)
            out["dart_warnings"] = build_warnings(self)
        if self.model.has_passive:
            out["passive"] = ("joint damping, springs and gravcomp forces on the skeleton's "
                              "clone that World.step steps (holds_passive)")
        if self.arm is not None:
            out["armature"] = "in the qdd only: (M + diag(a)) qdd = tau + phi (holds_armature)"
        w = self.world
        if w is None:
            return out
        sleep, cs = w.getDeactivationOptions(), w.getConstraintSolver()
        out.update({"World.timestep": w.getTimeStep(), "deactivation": bool(sleep.mEnabled),
                    "collision_detector": w.getCollisionDetector().getType(),
                    "constraint_solver": type(cs).__name__,
                    "lcp_solver": type(cs.getBoxedLcpSolver()).__name__,
                    "lcp_fallback": type(cs.getSecondaryBoxedLcpSolver()).__name__,
                    "split_impulse": bool(cs.isSplitImpulseEnabled()),
                    "constraints": int(cs.getNumConstraints()),
                    "threads": int(w.getNumSimulationThreads())})
        return out

    def _sim_state(self):
        qe = np.array(self.sim_skel.getPositions())
        y = np.array(self.sim_skel.getVelocities())
        if self.identity:
            return qe, y
        q = self._gather(qe)
        for qs, _, idx in self.free_dofs:
            T = np.array(self.lib.dynamics.FreeJoint.convertToTransform(qe[idx]).matrix())
            q[qs:qs + 3] = T[:3, 3]
            q[qs + 3:qs + 7] = rotation_quaternion(T[:3, :3])
        _, blocks = self._state(q, np.zeros(self.model.n_v))
        return q, self._from_engine(y, blocks)
