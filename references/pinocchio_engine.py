"""Pinocchio adapter: ``pin.aba`` or CRBA + Cholesky on the Model, with two ways to model a U joint.

Engines (``redysim.references.ENGINES``), three variants of ONE construction
(:class:`PinocchioEngine`, which builds the model; each variant sets only how a U joint is modelled
and which algorithm gives qdd):

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

What the model contains and why: joints, joint placements, body inertias and gravity, nothing
else. Each body's joint is its elementary axes (``redysim.references.base.joint_axes``) in order,
one Pinocchio joint per axis, the first at ``pin.SE3(placement_R, placement_p)`` on the parent
body's last joint (0, the universe, for a root; a chain's link k: l_{k-1} along the parent
link's x), the axes after the first at an identity placement on the previous axis's joint with
no body of their own (a massless body: Pinocchio's joint frames carry no inertia unless a body
is appended). Per axis: ``JointModelRX``/``RY``/``RZ`` or ``JointModelPX``/``PY``/``PZ`` for an
axis exactly +x, +y, +z of its frame; ``JointModelRevoluteUnaligned(u)`` /
``JointModelPrismaticUnaligned(u)`` for any other direction, -x, -y, -z included (so an R joint
about -z is never built as RZ). In ``pinocchio-aba`` and ``pinocchio-crba`` two leading
orthogonal revolute axes (U, and the U part of S) are one ``JointModelUniversal(u1, u2)``
instead, which rotates about u1 and then the rotated u2, as the core does. A prismatic joint
moves its frame, and so the body and everything after it, by u q along the axis, as in the
core. A free joint is one ``JointModelFreeFlyer`` at the identity placement; a ball joint one
``JointModelSpherical`` (its q the quaternion (x, y, z, w), w last: reordered; its v the body's
angular velocity relative to its parent in the body's frame, the core's). Body inertias
``pin.Inertia(m, c, I_C)`` (about the COM) on the joint of the body's last axis; gravity
``model.gravity.linear = model.gravity``. Pinocchio models have no contacts, collision or visual
geometry unless asked for; joint limits, damping, friction and effort/velocity limits are left
at their defaults, which ``aba``/``crba``/``rnea`` ignore (they apply no limit or damping). The
model's armature (``Model.armature``) is ``pm.armature`` (per Pinocchio velocity coordinate),
which ``aba``, ``crba`` and ``rnea`` add (checked on 4.1: M's diagonal, tau's armature qdd); its
``computeKineticEnergy`` leaves out a ``JointModelRevoluteUnaligned``'s armature (every other
joint type's is in), so the adapter's energy is the bodies' plus 1/2 armature v^2 itself. A
mimic joint (a coupled follower, ``pinocchio-crba``) has no velocity of its own, so its armature
is reflected into the joint it mimics (m^2 a_f added to the leader's, G^T diag(a) G). Refused:
armature on a free joint's translations (the core's multiplies the rate of the world velocity;
Pinocchio's free flyer's, the rate of the body-frame velocity, which differs by w x v).
``pin.Data(model)`` is used, not ``model.createData()``, which copies through the bindings and
doubles the peak memory (docs/design.md, "Reference engines").

Bodies are added depth-first: Pinocchio's CRBA assumes each subtree's DOF contiguous
(``Model.check`` fails otherwise; stack-of-tasks/pinocchio#1897, "expected behavior"), and on a
tree in the Model's parents-first order it gave a GIM wrong by 5e-2 while ``pin.aba`` was right
(a chain's order is depth-first already). The coordinates are mapped to the Model's order.

Free joint, converted both ways (``redysim.references.base``): Pinocchio's q is (x, y, z, qx, qy,
qz, qw) (w last) and its v = (R^T v_world, w_body), the origin's velocity in the BODY frame, so
B = diag(R, 1) and c = (R (w_body x R^T v_world), 0): d/dt (R v_local) = R (a_local + w x
v_local). The applied force's linear part turns by R^T. Energies are invariant.

Limit (references/limits.toml): ``pin.Data`` allocates the second-order-derivative tensors
(nv^3 each) whatever algorithm is called, so memory, not time, stops it.

No native integrator (``integrators`` is empty): Pinocchio has no time integrator, only the
dynamics (``aba``, ``crba``, ...) and the Lie-group ``integrate`` of a configuration by a
velocity. ``simulate``, ``sim_reset`` and ``integrator="native"`` are refused with that reason,
naming the way to run Pinocchio: through redysim's integrators, its qdd in ours
(``redysim simulate CASE --engine pinocchio-aba --integrator ode45``). Until 2026-11 the adapter
stepped semi-implicit Euler itself (v += h qdd; q = pin.integrate(q, h v)) and called it
Pinocchio's native integrator: any such trajectory was this adapter's integrator, not the
engine's, which a comparison of engines' own integrators must not contain.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np

from redysim.algorithms.rbda import quaternion_matrix
from redysim.model.tree import BALL_JOINT, FREE

from .base import Engine, FreeBlock, depth_first


def _axis_model(pin, axis):
    """The 1-DOF Pinocchio joint model of one elementary axis (``redysim.references.base.Axis``)."""
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


def _upper_cholesky_solve(M, rhs):
    """M x = rhs by the upper Cholesky factor, which reads only M's upper triangle (SciPy's
    linalg imported here, on first use: an import that ``redysim --help`` does not need)."""
    from scipy.linalg import cho_factor, cho_solve

    return cho_solve(cho_factor(M, lower=False), rhs)


class PinocchioEngine(Engine):
    """Pinocchio on a :class:`redysim.Model` (module docstring); the variants below set
    ``universal`` ("universal": ``JointModelUniversal``; "ryrz": one joint per axis) and
    ``_qdd``. ``pm``, ``data``: Pinocchio's model and data; ``body_joint[k]``: the Pinocchio
    joint id of body k's last axis (the body's frame)."""

    package = "pin"
    module = "pinocchio"
    integrator = ""
    integrators = {}  # Pinocchio has none (module docstring)
    no_integrator = ("Pinocchio has none: it gives the dynamics, not a time stepping; any "
                     "trajectory would be an adapter's integrator, not Pinocchio's")
    universal: ClassVar[str] = "universal"
    holds_armature = "pm.armature, which aba, crba and rnea add"
    holds_ball = ("JointModelSpherical: q its quaternion (x, y, z, w), v the body-frame angular "
                  "velocity, as the core's")

    @classmethod
    def unsupported(cls, model, joints):
        for k, joint in enumerate(joints):
            a = model.armature[model.joint_voff[k]:model.joint_voff[k] + 3]
            if joint.type == FREE and np.any(a):
                return (f"the free joint of body {joint.body!r} has armature along its "
                        f"translations ({', '.join(f'{x:g}' for x in a)}): the model's is on "
                        f"the world velocity's rate, Pinocchio's free flyer's on the "
                        f"body-frame velocity's, which differs by w x v")
        for c, (follower, _, _, _) in zip(model.couplings, mimic_order(model), strict=True):
            if follower is None:
                return (f"joint {c.follower!r} follows {c.leader!r} with multiplier 0 and comes "
                        f"before it in the tree: Pinocchio's mimic joint must come after the "
                        f"joint it mimics, and a constant joint cannot be mimicked")
        mimics = {f for f, _, _, _ in mimic_order(model)}
        for f, ld, _, _ in mimic_order(model):
            if ld in mimics:
                return (f"joint {ld!r} is mimicked by {f!r} and itself a mimic joint once each "
                        f"coupling's mimic joint comes after its leader in the tree (as "
                        f"Pinocchio requires): Pinocchio does not chain mimic joints")
        return ""

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
            elif joint.type == BALL_JOINT:
                models = [pin.JointModelSpherical()]
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
        # the core's slots -> Pinocchio's: each body's coordinates are consecutive in both
        self.qidx = np.zeros(m.n_q, dtype=np.int64)
        for k in range(m.n_bodies):
            jm = pm.joints[first[k]]
            nq, nv = m.joint_qoff[k + 1] - m.joint_qoff[k], m.joint_voff[k + 1] - m.joint_voff[k]
            self.qidx[m.joint_qoff[k]:m.joint_qoff[k + 1]] = jm.idx_q + np.arange(nq)
            self.eidx[m.joint_voff[k]:m.joint_voff[k + 1]] = jm.idx_v + np.arange(nv)
        if np.any(m.armature):  # (Pinocchio's coordinates, as the core's slots map to them)
            armature = np.zeros(pm.nv)
            armature[self.eidx] = m.armature
            pm.armature = armature
        self.pm, self.data = pm, pin.Data(pm)
        assert pm.check(self.data), "Pinocchio's Model.check failed"
        self.body_joint = [last[k] for k in range(m.n_bodies)]
        if m.couplings:
            self._mimic(first)

    def _mimic(self, first):
        """Pinocchio's own coupled model (``pin.transformJointIntoMimic`` of each follower onto
        its leader: Pinocchio's mimic joints, with nq = nv = 0, as ``buildModelFromUrdf(...,
        mimic=True)`` makes them) beside the tree: ``pmm`` (a Data of its own at each call);
        ``mq``, ``mv``: the tree's engine q and v slot of each of its coordinates; ``G`` (tree
        nv, its nv): v_tree = G v."""
        pin, m, pm = self.lib, self.model, self.pm
        index = {name: k for k, name in enumerate(m.joint_names)}
        pmm = pm
        order = mimic_order(m)  # each coupling with its mimic joint after its leader
        for follower, leader, mult, offset in order:
            pmm = pin.transformJointIntoMimic(pmm, first[index[leader]], first[index[follower]],
                                              mult, offset)
        G = np.zeros((pm.nv, pmm.nv))
        mq, mv = np.zeros(pmm.nq, dtype=np.int64), np.zeros(pmm.nv, dtype=np.int64)
        rule = {first[index[f]]: (first[index[ld]], mult) for f, ld, mult, _ in order}
        for j in range(1, pm.njoints):
            full, red = pm.joints[j], pmm.joints[j]
            if j in rule:  # a mimic: its velocity m times its leader's
                leader, mult = rule[j]
                G[full.idx_v, pmm.joints[leader].idx_v] = mult
                continue
            mq[red.idx_q:red.idx_q + red.nq] = full.idx_q + np.arange(full.nq)
            mv[red.idx_v:red.idx_v + red.nv] = full.idx_v + np.arange(full.nv)
            G[full.idx_v + np.arange(full.nv), red.idx_v + np.arange(red.nv)] = 1.0
        if np.any(m.armature):
            # a mimic joint has no velocity of its own, so Pinocchio's coupled model holds no
            # armature of it: the mimic's is reflected into the joint it mimics, G^T diag(a) G
            # (diagonal: each tree velocity is one reduced velocity times its factor), a_l +
            # m^2 a_f at the leader, the coupled motion's own inertia (the core's, G^T I G)
            pmm.armature = np.einsum("ij,i,ij->j", G, np.asarray(pm.armature), G)
        self.pmm = pmm  # (its Data made at each call: _qdd)
        self.mq, self.mv, self.G = mq, mv, G

    def _engine_state(self, q, v):
        q = q.copy()
        blocks = []
        for _, qs, vs in self.free:
            quat = q[qs + 3:qs + 7] / np.linalg.norm(q[qs + 3:qs + 7])
            q[qs + 3:qs + 7] = [quat[1], quat[2], quat[3], quat[0]]  # Pinocchio's: w last
            R = quaternion_matrix(*quat)
            B = np.eye(6)
            B[:3, :3] = R
            w, v_local = v[vs + 3:vs + 6], R.T @ v[vs:vs + 3]
            c = np.zeros(6)
            c[:3] = R @ np.cross(w, v_local)
            blocks.append(FreeBlock(vs, B, c))
        for _, qs, _ in self.balls:  # v is Pinocchio's as it is; its quaternion is w last
            quat = q[qs:qs + 4] / np.linalg.norm(q[qs:qs + 4])
            q[qs:qs + 4] = [quat[1], quat[2], quat[3], quat[0]]
        qp = np.empty(self.model.n_q)
        qp[self.qidx] = q
        return qp, blocks

    # ------------------------------------------------------------------ stages
    def _qdd(self, qp, y, tau_e):
        tau_e = np.zeros(self.model.n_v) if tau_e is None else tau_e
        return self.lib.aba(self.pm, self.data, qp, y, tau_e).copy()

    def _mass_matrix(self, qp):
        M = self.lib.crba(self.pm, self.data, qp).copy()
        return np.triu(M) + np.triu(M, 1).T  # crba fills the upper triangle only

    def _bias(self, qp, y):
        return -self.lib.nonLinearEffects(self.pm, self.data, qp, y).copy()

    def _energy(self, qp, y):
        pin, pm = self.lib, self.pm
        if not np.any(self.model.armature):
            return (pin.computeKineticEnergy(pm, self.data, qp, y),
                    pin.computePotentialEnergy(pm, self.data, qp))
        # the bodies' energy, then the armature's 1/2 armature v^2: Pinocchio 4.1's
        # computeKineticEnergy leaves out a JointModelRevoluteUnaligned's armature (measured:
        # every other joint type's is in, as its crba and aba have them all)
        armature = pm.armature.copy()
        pm.armature = np.zeros(pm.nv)
        try:
            T = pin.computeKineticEnergy(pm, self.data, qp, y)
        finally:
            pm.armature = armature
        return (T + 0.5 * float(armature @ (y * y)),
                pin.computePotentialEnergy(pm, self.data, qp))

    def _position(self, qp, body, point):
        self.lib.forwardKinematics(self.pm, self.data, qp)
        return self.data.oMi[self.body_joint[body]].act(point).copy()


def mimic_order(model) -> list[tuple[str | None, str, float, float]]:
    """Each coupling of ``model`` as Pinocchio's mimic joint takes it, (mimic joint, the joint
    it mimics, multiplier, offset): ``pin.transformJointIntoMimic`` needs the mimicked joint
    before the mimic one in the joint order ('index_mimicking is greater than index_mimicked',
    4.1.0), which is the adapter's depth-first body order. A follower that comes before its
    leader (Menagerie's Panda: finger_joint1 follows finger_joint2) swaps the roles by the
    inverse map q_l = q_f / m - c / m, the same constraint and so the same dynamics; with
    m = 0 there is none (the mimic joint None: ``unsupported`` refuses it)."""
    rank = {k: i for i, k in enumerate(depth_first(model))}
    index = {name: k for k, name in enumerate(model.joint_names)}
    out: list[tuple[str | None, str, float, float]] = []
    for c in model.couplings:
        if rank[index[c.leader]] < rank[index[c.follower]]:
            out.append((c.follower, c.leader, c.multiplier, c.offset))
        elif c.multiplier == 0.0:
            out.append((None, c.leader, c.multiplier, c.offset))
        else:
            out.append((c.leader, c.follower, 1.0 / c.multiplier, -c.offset / c.multiplier))
    return out


ABA_NO_MIMIC = ("Pinocchio's ABA refuses mimic joints ('This algorithm does not support Joint "
                "Mimic type in the model', pin.aba, 4.1.0); pinocchio-crba builds them")


class PinocchioABA(PinocchioEngine):
    """Pinocchio ``pin.aba`` with ``JointModelUniversal`` U joints (module docstring)."""

    name = "pinocchio-aba"
    universal = "universal"
    no_couplings = ABA_NO_MIMIC
    projects_couplings = False  # pinocchio-crba couples with Pinocchio's own mimic joints


class PinocchioABARyRz(PinocchioEngine):
    """Pinocchio ``pin.aba`` with each elementary axis its own joint: a U joint is RY ->
    massless body -> RZ (module docstring)."""

    name = "pinocchio-aba-ryrz"
    universal = "ryrz"
    no_couplings = ABA_NO_MIMIC
    projects_couplings = False  # pinocchio-crba couples with Pinocchio's own mimic joints


class PinocchioCRBA(PinocchioEngine):
    """Pinocchio ``pin.crba`` + ``pin.nonLinearEffects`` + upper Cholesky (scipy), on
    ``pinocchio-aba``'s model (module docstring)."""

    name = "pinocchio-crba"
    universal = "universal"
    couples = ("Pinocchio's mimic joints (pin.transformJointIntoMimic of each follower onto its "
               "leader, as buildModelFromUrdf(..., mimic=True) reads a URDF; a follower before "
               "its leader in the tree swaps roles, q_l = q_f / m - c / m): qdd from that "
               "model's crba and nonLinearEffects, tau mapped as G^T tau")

    def _qdd(self, qp, y, tau_e):
        pin = self.lib
        if self.model.couplings:  # Pinocchio's coupled model, in its own coordinates
            qr, yr = qp[self.mq], y[self.mv]
            # a fresh Data each call: Pinocchio 4.1.0's crba on a mimic model adds its mimic
            # terms to what a reused Data holds (M[0, 1] twice, then three times, its value;
            # clearing data.M in place is not enough): the second call on was wrong
            dmm = pin.Data(self.pmm)
            M = pin.crba(self.pmm, dmm, qr)
            rhs = -pin.nonLinearEffects(self.pmm, dmm, qr, yr)
            if tau_e is not None:
                rhs = rhs + self.G.T @ tau_e
            return self.G @ _upper_cholesky_solve(M, rhs)
        M = pin.crba(self.pm, self.data, qp)  # upper triangle filled
        rhs = -pin.nonLinearEffects(self.pm, self.data, qp, y)
        if tau_e is not None:
            rhs = rhs + tau_e
        return _upper_cholesky_solve(M, rhs)
