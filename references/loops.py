"""The reference engines on closed loops: a :class:`redysim.algorithms.loops.ClosedLoops` in each
engine.

Each adapter builds the loops' tree (its :class:`redysim.Model`) with the engine's own adapter
(:class:`.base.Engine`, the one class per engine: ``self.tree``), then adds every cut joint
(:class:`redysim.algorithms.loops.CutJoint`) as the engine's OWN loop-closure constraint, and
answers in the core's names and coordinates:

==============================  ===============================================================
``forward_dynamics(q, v, tau)`` (qdd, lam), as :meth:`ClosedLoops.forward_dynamics`: the
                                constrained accelerations (n_v,) and the loop forces (m,): on
                                body a at its point, world frame, per equation of each cut, in
                                the order of ``ClosedLoops.rows`` (-lam on body b)
``qdd(q, v, tau=None)``         the first of the two
``refusal(q, v)``               "" when the engine can answer at this state, else why not
                                (``forward_dynamics`` then raises :class:`LoopStateUnsupported`)
``limits(loops)``               decided before building: can the engine build these loops
``simulate(q0, v0, t_end, h)``  the engine's own integrator with its own loop constraints ->
                                :class:`.base.Trajectory` (Pinocchio: refused, it has none)
``available()``, ``version``    as the other adapters'
==============================  ===============================================================

What each engine builds (details and measurements in ``references/README.md``, "Loops"):

- ``pinocchio``: the tree of ``pinocchio-crba`` (``JointModelUniversal`` for U), one
  ``RigidConstraintModel(CONTACT_3D, joint_a, SE3(1, point_a), joint_b, SE3(1, point_b),
  LOCAL_WORLD_ALIGNED)`` per cut (joint 0, the universe, for a world point), solved by
  ``pin.constraintDynamics`` (the KKT system, ``ProximalSettings`` mu = 1e-8, iterated to
  1e-13). A "planar" cut is the same 3-D constraint: its z row is identically zero in a planar
  mechanism, a rank deficiency the proximal iterations absorb (without them, mu = 0, Pinocchio's
  Cholesky returns NaN). ``data.lambda_c`` is already the core's lam (world-aligned force on
  joint a's point); a planar cut's z multiplier is returned as 0 and dropped.
- ``mujoco``: the tree of ``mujoco`` with constraints enabled, one site at each point and one
  ``mjEQ_CONNECT`` equality between the two sites per cut (a ball joint), ``solimp`` at
  MuJoCo's hardest, d = mjMAXIMP = 0.9999, Newton solver. MuJoCo's constraints are soft: it
  solves (A + R) f = -(J a0 + Jdot v) on an assembled state with J v = 0 (A = J M^-1 J^T;
  aref = 0 there; the velocity term is in, measured), R = (1 - d)/d diagApprox = 1e-4 diagApprox
  (``efc_R``; diagApprox is MuJoCo's estimate of A's diagonal from the bodies' ``invweight0``),
  so its qdd and forces differ from the hard answer by that regularisation, ~R / lambda_min(A);
  :meth:`MuJoCoLoops.regularisation` returns R for the test to predict it. ``mjENBL_DIAGEXACT``
  (the exact diagonal) makes R larger here, and so MuJoCo softer (measured): not set.
  ``efc_force`` of the equality rows is the core's lam (world frame, force on body a). A
  "planar" cut is a connect too: its z row has J = 0 and gets f = 0 (the soft solve needs no
  full rank).
- ``dart``: the tree of ``dart`` in a ``World`` with one ``BallJointConstraint`` per cut (rebuilt
  at every call, at the given assembled state, since DART takes the joint's world position and
  derives each body's offset from the current pose), error reduction 0, the default constraint
  force mixing 1e-9 (DART's floor); DART resolves constraints only inside ``World.step()``, by
  velocity impulses, so qdd = (v_new - v) / h of one step (h = 1e-3 s; at v = 0 the result does
  not depend on h). The impulse makes J v_new = 0, i.e. J qdd = 0, not J qdd = -Jdot v: at a
  nonzero velocity the answer lacks the velocity-product term, an O(|Jdot v|) error no step size
  removes, so ``refusal`` refuses any v != 0. The loop forces: DART's ``getConstraintForces``
  drops the impulse on body b when both bodies are in one Skeleton (measured on the four-bar:
  0 on the rocker), so lam is solved from DART's own generalized constraint force M (qdd - qdd0)
  = J^T lam, M, qdd0 and J (``Skeleton.getLinearJacobian`` of the two points) all DART's.
- ``exudyn``: the tree of ``exudyn``, one ``ObjectJointSpherical`` per cut between a
  ``MarkerKinematicTreeRigid`` on each body (a ``MarkerBodyPosition`` on an ``ObjectGround`` for a
  world point), ``constrainedAxes = [1, 1, 0]`` for a planar cut (Exudyn's own 2-equation
  form); qdd from Exudyn's implicit solver (``MainSolverImplicitSecondOrder``, GeneralizedAlpha)
  computing its consistent initial accelerations (``computeInitialAccelerations``: the index-1
  system with M, the constraint Jacobian and -d2g/dq2 v^2) in ``InitializeSolver``, no step
  taken; the Lagrange multipliers (``GetAECoordinates``) are the core's lam. Exudyn's explicit
  solvers (which the engine's adapter uses) cannot close a loop: by default they abort ("contains
  constraints that cannot be solved"), with ``explicit.eliminateConstraints = False`` they warn
  "WILL IGNORE CONSTRAINTS" and return the open tree's qdd (measured). Exudyn forms the velocity
  term d2g/dq2 v^2 by numerical differentiation
  (``newton.numericalDifferentiation.relativeEpsilon``, 1e-7): its error at v != 0 follows that
  epsilon (README).

Planar cuts: Pinocchio, MuJoCo and DART hold a point in all three directions only, so they
build a "planar" cut as a ball joint, which is the cut only when the world z equation is void:
``limits`` refuses the loops when anything on the cut bodies' paths moves their points along z
(:func:`non_planar`), and ``forward_dynamics`` a state whose cut points are apart in z. Exudyn
builds the planar cut itself (``constrainedAxes = [1, 1, 0]``) and takes it on any mechanism.

Thin bodies: the linkages' slender bars have a zero moment about their own axis. MuJoCo's
compiler refuses a moment below mjMINVAL and DART calls it invalid. Where such a moment is about
an axis e normal to EVERY revolute axis on the body's path to the base, and those axes are all
parallel (a planar mechanism turning about n, so the body's angular velocity is always along n),
the moment cannot enter the dynamics: I w = w_n I n and w x I w involve I only through I n,
and I + delta e e^T has the same I n for e normal to n. There (and only there) the MuJoCo and
DART adapters add delta = 1e-6 x the body's largest moment about e (:func:`inert_moments`);
anywhere else the engine adapter's own refusal stands.
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from redysim.algorithms.loops import ClosedLoops
from redysim.algorithms.vectors import cross
from redysim.model.tree import Model

from .base import (
    Engine,
    EngineLimitExceeded,
    EnginePackage,
    Limits,
    Trajectory,
    import_engine,
)
from .dart_engine import DART
from .exudyn_engine import Exudyn
from .mujoco_engine import MuJoCo
from .pinocchio_engine import PinocchioCRBA

THIN = 1e-15  # a principal moment below this is "zero" (MuJoCo's mjMINVAL)
THIN_RAISE = 1e-6  # the inert moment's value, relative to the body's largest moment
PARALLEL = 1e-12  # |u x n| below which two unit axes are parallel, |e . n| for normal


class LoopStateUnsupported(RuntimeError):
    """The engine cannot give the constrained dynamics at this state (the message says why)."""


# --------------------------------------------------------------------------- thin bodies
def inert_moments(model: Model) -> tuple[Model, list[int], str]:
    """(model', bodies changed, why not): the model with each zero principal moment that cannot
    enter the dynamics raised to THIN_RAISE x the body's largest moment (module docstring), or
    the model unchanged and the reason when a zero moment could enter them."""
    from redysim.algorithms.rbda import kinematics

    kin = kinematics(model, model.neutral(), np.zeros(model.n_v))
    inertia = np.array(model.inertia_com, dtype=float)
    changed = []
    for k in range(model.n_bodies):
        w, E = np.linalg.eigh(inertia[k])
        thin = np.flatnonzero(w < THIN)
        if thin.size == 0 or model.mass[k] <= 0.0:
            continue
        axes, b = [], k  # the revolute axes on the body's path, in body k's frame at q = 0
        while b >= 0:
            for i in range(int(model.joint_voff[b]), int(model.joint_voff[b + 1])):
                if int(model.dof_kind[i]) == 0:  # R (a free joint's BALL turns about anything)
                    axes.append(kin.R[k].T @ kin.R[b] @ np.asarray(model.dof_u[i], dtype=float))
                elif int(model.dof_kind[i]) != 1:
                    axes.append(None)
            b = int(model.parent[b])
        name = f"body {k} ({model.body_names[k]})"
        if not axes or any(a is None for a in axes):
            return model, [], f"{name} has a zero principal moment and turns about any axis"
        n = axes[0] / np.linalg.norm(axes[0])
        if np.any(np.linalg.norm(cross(np.array(axes), n), axis=-1) > PARALLEL):
            return model, [], (f"{name} has a zero principal moment and turns about "
                               "non-parallel axes, so the moment can enter its dynamics")
        for j in thin:
            e = E[:, j]
            if abs(e @ n) > PARALLEL:
                return model, [], f"{name} has a zero principal moment about its axis of rotation"
            delta = THIN_RAISE * float(w.max()) - float(w[j])
            inertia[k] = inertia[k] + delta * np.outer(e, e)
        inertia[k] = 0.5 * (inertia[k] + inertia[k].T)
        changed.append(k)
    if not changed:
        return model, [], ""
    return dataclasses.replace(model, inertia_com=inertia), changed, ""


# --------------------------------------------------------------------------- planar cuts
def non_planar(loops: ClosedLoops, cut) -> str:
    """Why a "planar" cut's third equation (world z) is NOT void on these loops ("" when it is):
    an engine that can only hold a point in all three directions builds a planar cut as a ball
    joint, which is the cut only when nothing on the paths of its two bodies moves the points
    along z (revolute axes along z, prismatic axes normal to it: their z stays constant)."""
    from redysim.algorithms.rbda import kinematics

    model = loops.model
    kin = kinematics(model, model.neutral(), np.zeros(model.n_v))
    z = plane_normal(loops, cut, kin)
    axis = "world z" if cut.kind == "planar" else f"its plane's normal {np.round(z, 6)}"
    for body in (cut.body_a, cut.body_b):
        while body >= 0:
            for i in range(int(model.joint_voff[body]), int(model.joint_voff[body + 1])):
                u = kin.R[body] @ np.asarray(model.dof_u[i], dtype=float)  # world, at q = 0
                kind = int(model.dof_kind[i])
                if (kind == 0 and np.linalg.norm(cross(u, z)) > PARALLEL) or \
                        (kind == 1 and abs(u @ z) > PARALLEL) or kind not in (0, 1):
                    return (f"the {cut.kind} cut {cut.name!r} leaves {axis} free, but body "
                            f"{body} ({model.body_names[body]}) moves its points along it; this "
                            "engine's ball constraint would hold it too")
            body = int(model.parent[body])
    return ""


def plane_normal(loops: ClosedLoops, cut, kin) -> np.ndarray:
    """The direction a "planar" or "plane" cut leaves free, in the world at the kinematics
    ``kin``: world z for a planar cut; for a plane cut the z axis of its frame ``rot_b`` on body
    b (the world's when b is the world), R_b rot_b e_z."""
    if cut.kind == "planar":
        return np.array([0.0, 0.0, 1.0])
    rot = np.asarray(cut.rot_b, dtype=float)
    return (rot if cut.body_b < 0 else kin.R[cut.body_b] @ rot)[:, 2]


def plane_axes(loops: ClosedLoops, q) -> list[np.ndarray | None]:
    """Per cut, the world axes (3, 2) its two rows run along for a "plane" cut (u_k = R_b rot_b
    e_k, k = x, y: the core's rows u_k . (x_a - x_b)), None for any other cut."""
    from redysim.algorithms.rbda import kinematics

    if not any(c.kind == "plane" for c in loops.cuts):
        return [None] * len(loops.cuts)
    kin = kinematics(loops.model, np.asarray(q, dtype=float), np.zeros(loops.model.n_v))
    out: list[np.ndarray | None] = []
    for c in loops.cuts:
        if c.kind != "plane":
            out.append(None)
            continue
        rot = np.asarray(c.rot_b, dtype=float)
        out.append((rot if c.body_b < 0 else kin.R[c.body_b] @ rot)[:, :2])
    return out


# --------------------------------------------------------------------------- base class
class LoopEngine(EnginePackage):
    """Base class of the loop adapters (module docstring). A subclass sets ``name``, ``adapter``
    (the engine's adapter class, which builds the tree: ``self.tree``), ``package``, ``module``
    and implements ``_build`` and ``_solve`` (and ``_simulate`` with ``integrator`` where the
    engine has one)."""

    name: ClassVar[str] = ""
    adapter: ClassVar[type[Engine]] = Engine
    package: ClassVar[str] = ""
    module: ClassVar[str] = ""
    thin_ok: ClassVar[bool] = False  # raise the inert zero moments (module docstring)
    planar_exact: ClassVar[bool] = False  # has a 2-equation (x, y) point constraint of its own
    PLANAR_GAP = 1e-9  # |z_a - z_b| [m, relative to the model's size] a ball may hold as planar

    def __init__(self, loops: ClosedLoops, *, check_limits: bool = True):
        self.lib = import_engine(self.name, self.package, self.module)
        if not isinstance(loops, ClosedLoops):
            raise TypeError("expected a redysim.algorithms.loops.ClosedLoops, got "
                            f"{type(loops).__name__}")
        if check_limits:
            lim = self.limits(loops)
            if not lim.ok:
                raise EngineLimitExceeded(f"{self.name}: {lim.reason}")
        self.loops = loops
        self.model, self.thin_bodies, _ = (inert_moments(loops.model) if self.thin_ok
                                           else (loops.model, [], ""))
        self.tree = self.adapter(self.model, check_limits=False)
        self._build()

    @classmethod
    def limits(cls, loops: ClosedLoops) -> Limits:
        """Can this engine build the loops? The engine adapter's verdict on the tree (after the
        inert moments are raised, for the engines that need it), then the cuts'."""
        if not isinstance(loops, ClosedLoops):
            raise TypeError("expected a redysim.algorithms.loops.ClosedLoops, got "
                            f"{type(loops).__name__}")
        model, why = loops.model, ""
        if cls.thin_ok:
            model, _, why = inert_moments(model)
        lim = cls.adapter.limits(model)
        if not lim.ok:
            return Limits(False, lim.reason + (f" ({why})" if why else ""))
        if model.couplings and not cls.couples:
            return Limits(False, f"{cls.name}: the model couples joints "
                                 f"({', '.join(c.follower for c in model.couplings)} follow "
                                 f"others: mimic joints), which this loop adapter does not "
                                 f"build with its loops (its constraints close the cuts only)")
        if np.any(model.armature) and not (cls.adapter.armature_native or cls.holds_armature):
            j = int(np.flatnonzero(model.armature)[0])
            return Limits(False, f"{cls.name}: the model has armature (armature[{j}] = "
                                 f"{float(model.armature[j]):g}), which the engine's tree adapter "
                                 f"holds in its own qdd only ({cls.adapter.no_armature}); this "
                                 f"loop adapter solves with the engine's own dynamics, without it")
        for c in loops.cuts:
            if c.kind not in cls.kinds:
                return Limits(False, f"{cls.name}: cut {c.name!r} is {c.kind!r}, which this "
                                     f"adapter has no construction for")
            why = ("" if c.kind not in ("planar", "plane")
                   or (c.kind == "planar" and cls.planar_exact) else non_planar(loops, c))
            if why:
                return Limits(False, f"{cls.name}: {why}")
        return Limits(True, "")

    kinds: ClassVar[tuple[str, ...]] = ("point", "planar")
    # how the loop adapter holds a model's couplings (Model.couplings) beside its cuts; "" when
    # it does not (limits then refuses a coupled model: never dropped)
    couples: ClassVar[str] = ""
    # True: the loop adapter holds armature its tree adapter holds in its qdd only (DART's)
    holds_armature: ClassVar[bool] = False

    def refusal(self, q, v) -> str:
        """Why the engine cannot answer at (q, v) ("" when it can)."""
        return ""

    def _check(self, q, v, tau):
        m = self.model
        q = np.asarray(q, dtype=float)
        v = np.asarray(v, dtype=float)
        if q.shape != (m.n_q,) or v.shape != (m.n_v,):
            raise ValueError(f"q, v have shapes {q.shape}, {v.shape}; the model has n_q = "
                             f"{m.n_q}, n_v = {m.n_v}")
        if tau is not None:
            tau = np.asarray(tau, dtype=float)
            if tau.shape != (m.n_v,):
                raise ValueError(f"tau has shape {tau.shape}; the model has n_v = {m.n_v}")
        return q, v, tau

    def forward_dynamics(self, q, v, tau=None) -> np.ndarray:
        """qdd with the loops closed (as :meth:`ClosedLoops.forward_dynamics`)."""
        return self.forward_dynamics_and_forces(q, v, tau)[0]

    def forward_dynamics_and_forces(self, q, v, tau=None) -> tuple[np.ndarray, np.ndarray]:
        """(qdd, lam) with the loops closed, in the core's coordinates and convention (as
        :meth:`ClosedLoops.forward_dynamics_and_forces`)."""
        q, v, tau = self._check(q, v, tau)
        why = self.refusal(q, v) or self._planar_gap(q)
        if why:
            raise LoopStateUnsupported(f"{self.name}: {why}")
        self.loops.check_start(q)  # every engine here takes an assembled state only
        return self._solve(q, v, tau)

    def _planar_gap(self, q) -> str:
        """A planar or plane cut built as a ball: its points must also meet along the direction
        it leaves free (world z, or the plane's normal: constant on such a mechanism, see
        :func:`non_planar`)."""
        as_ball = [c.kind == "plane" or (c.kind == "planar" and not self.planar_exact)
                   for c in self.loops.cuts]
        if not any(as_ball):
            return ""
        from redysim.algorithms.rbda import kinematics

        kin = kinematics(self.model, np.asarray(q, dtype=float), np.zeros(self.model.n_v))
        for c, ball, (pa, pb) in zip(self.loops.cuts, as_ball, self.loops.cut_points(q),
                                     strict=True):
            if not ball:
                continue
            n = plane_normal(self.loops, c, kin)
            gap = abs(float(n @ (np.asarray(pa) - np.asarray(pb))))
            if gap > self.PLANAR_GAP * self.loops.size:
                where = "in world z" if c.kind == "planar" else "along its plane's normal"
                return (f"the {c.kind} cut {c.name!r} has its points {gap:.3g} m apart {where}, "
                        "which it leaves free; this engine's ball constraint would close that "
                        "gap")
        return ""

    def qdd(self, q, v, tau=None) -> np.ndarray:
        return self.forward_dynamics(q, v, tau)

    integrator: ClassVar[str] = ""  # the native integrator simulate() uses ("": none)

    def simulate(self, q0, v0, t_end: float, h: float, *, every: int = 1) -> Trajectory:
        """The passive motion (no joint torques) from the assembled (q0, v0) to t_end with the
        engine's own fixed-step integrator and its own handling of the loops, step h; every
        ``every``-th step is kept (and the start). Raises LoopStateUnsupported for an engine
        without an integrator."""
        if not self.integrator:
            raise LoopStateUnsupported(f"{self.name}: {self.no_integrator}")
        q0, v0, _ = self._check(q0, v0, None)
        if not (h > 0 and t_end > 0 and every >= 1):
            raise ValueError(f"need h > 0, t_end > 0, every >= 1; got {h}, {t_end}, {every}")
        self.loops.check_start(q0)
        steps = int(round(t_end / h))
        ts, qs, vs = self._simulate(q0, v0, h, steps, every)
        return Trajectory(np.asarray(ts), np.asarray(qs), np.asarray(vs), self.integrator)

    no_integrator: ClassVar[str] = ""

    def _simulate(self, q0, v0, h, steps, every):
        """(times, q samples, v samples) in the core's coordinates, the start included."""
        raise NotImplementedError

    def _rows(self, per_cut: np.ndarray, q=None) -> np.ndarray:
        """(n_cuts, 3) per-cut 3-D world values (a ball's force) -> the core's rows: the first 2
        of a planar cut, a plane cut's along its axes u_k at q (:func:`plane_axes`)."""
        axes = plane_axes(self.loops, q) if q is not None else [None] * len(self.loops.cuts)
        return np.array([per_cut[i, r] if axes[i] is None else axes[i][:, r] @ per_cut[i]
                         for i, r in self.loops.rows])

    def __repr__(self) -> str:
        return (f"{type(self).__name__}({self.model.name!r}, {len(self.loops.cuts)} cuts, "
                f"m = {self.loops.m})")

    def _build(self) -> None:
        raise NotImplementedError

    def _solve(self, q, v, tau):
        raise NotImplementedError


# --------------------------------------------------------------------------- Pinocchio
class PinocchioLoops(LoopEngine):
    """``pin.constraintDynamics`` with one CONTACT_3D ``RigidConstraintModel`` per cut; a
    coupled model's: ``pin.forwardDynamics``, Pinocchio's KKT solve, on the cuts' rows and one
    row per coupling (module docstring of ``couples``)."""

    name = "pinocchio"
    adapter = PinocchioCRBA
    package = "pin"
    module = "pinocchio"
    no_integrator = ("Pinocchio has no time integrator (its constraintDynamics gives qdd only; "
                     "any trajectory would be this adapter's integrator, not Pinocchio's)")
    kinds = ("point", "planar", "plane")  # a planar or plane cut as a ball (non_planar)
    couples = ("pin.forwardDynamics (Pinocchio's KKT solve with its own M, armature included, "
               "and nonlinear effects: constraintDynamics refuses mimic joints, 'This algorithm "
               "does not support Joint Mimic type in the model', 4.1.0) on the tree, with the "
               "cuts' rows from Pinocchio's frame Jacobians and classical accelerations at the "
               "cut points (the core's rows of each cut) and one row e_f - m e_l per coupling")
    MU = 1e-8  # proximal parameter (any small value: the iterations converge to mu = 0's answer)
    ACCURACY = 1e-13
    MAX_ITER = 50

    def _build(self):
        pin, t = self.lib, self.tree
        models = pin.StdVec_RigidConstraintModel()
        for c in self.loops.cuts:  # a body's frame is its last axis's joint, t.body_joint
            ja = t.body_joint[c.body_a]
            jb = 0 if c.body_b < 0 else t.body_joint[c.body_b]
            models.append(pin.RigidConstraintModel(
                pin.ContactType.CONTACT_3D, t.pm, ja, pin.SE3(np.eye(3), np.array(c.point_a)),
                jb, pin.SE3(np.eye(3), np.array(c.point_b)),
                pin.ReferenceFrame.LOCAL_WORLD_ALIGNED))
        datas = pin.StdVec_RigidConstraintData()
        for cm in models:
            datas.append(cm.createData())
        pin.initConstraintDynamics(t.pm, t.data, models, datas)
        self.cmodels, self.cdatas = models, datas
        self.settings = pin.ProximalSettings(self.ACCURACY, self.MU, self.MAX_ITER)
        self.frames: list[tuple[int, int | None]] = []
        if self.model.couplings:  # the cut points as Pinocchio frames (the KKT path's rows)
            se3, op = pin.SE3, pin.FrameType.OP_FRAME
            for i, c in enumerate(self.loops.cuts):
                fa = t.pm.addFrame(pin.Frame(f"cut{i}a", t.body_joint[c.body_a],
                                             se3(np.eye(3), np.array(c.point_a)), op))
                fb = None if c.body_b < 0 else t.pm.addFrame(pin.Frame(
                    f"cut{i}b", t.body_joint[c.body_b], se3(np.eye(3), np.array(c.point_b)),
                    op))
                self.frames.append((fa, fb))
            t.data = pin.Data(t.pm)
            _, _, fv, lv, mult, _ = self.model.coupling_index
            self.coupling_rows = np.zeros((len(fv), self.model.n_v))
            for r, (f, ld, mu) in enumerate(zip(fv, lv, mult, strict=True)):
                self.coupling_rows[r, t.eidx[f]] = 1.0
                self.coupling_rows[r, t.eidx[ld]] -= mu

    def _solve_coupled(self, q, v, tau):
        """qdd and the cuts' forces of a coupled model by Pinocchio's KKT forward dynamics
        (``couples``): J qdd = -gamma, J the cuts' rows (a ball's three, a planar cut's world x
        and y, a plane cut's along its axes) and the couplings', gamma their classical
        accelerations at qdd = 0 (zero for a coupling; a plane cut's rows also carry 2 (w_b x
        u_k) . (v_a - v_b), zero on an assembled state of a mechanism moving in that plane)."""
        pin, t = self.lib, self.tree
        pm, data = t.pm, t.data
        qp, blocks = t._state(q, v)
        y = t._to_engine(v, blocks)
        tau_e = np.zeros(self.model.n_v) if tau is None else t._to_engine(tau, blocks)
        pin.forwardKinematics(pm, data, qp, y, np.zeros(self.model.n_v))
        pin.computeJointJacobians(pm, data, qp)
        pin.updateFramePlacements(pm, data)
        world = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
        Js, gs = [], []
        for fa, fb in self.frames:
            J = pin.getFrameJacobian(pm, data, fa, world)[:3]
            g = pin.getFrameClassicalAcceleration(pm, data, fa, world).linear
            if fb is not None:
                J = J - pin.getFrameJacobian(pm, data, fb, world)[:3]
                g = g - pin.getFrameClassicalAcceleration(pm, data, fb, world).linear
            Js.append(J)
            gs.append(g)
        J = np.vstack([self._rows(np.array(Js), q), self.coupling_rows])
        gamma = np.concatenate([self._rows(np.array(gs), q),
                                np.zeros(len(self.coupling_rows))])
        a = pin.forwardDynamics(pm, data, qp, y, tau_e, J, gamma, 0.0)
        lam = np.asarray(data.lambda_c, dtype=float)[:self.loops.m]
        return t._from_engine(np.array(a), blocks), lam

    def _solve(self, q, v, tau):
        if self.model.couplings:
            return self._solve_coupled(q, v, tau)
        pin, t = self.lib, self.tree
        qp, blocks = t._state(q, v)
        y = t._to_engine(v, blocks)
        tau_e = np.zeros(self.model.n_v) if tau is None else t._to_engine(tau, blocks)
        a = pin.constraintDynamics(t.pm, t.data, qp, y, tau_e, self.cmodels, self.cdatas,
                                   self.settings)
        if self.settings.iter >= self.MAX_ITER or not np.all(np.isfinite(a)):
            raise LoopStateUnsupported(
                f"{self.name}: constraintDynamics did not converge in {self.MAX_ITER} proximal "
                f"iterations (residual {self.settings.absolute_residual:.3g})")
        lam = np.asarray(t.data.lambda_c, dtype=float).reshape(-1, 3)
        return t._from_engine(a, blocks), self._rows(lam, q)


# --------------------------------------------------------------------------- MuJoCo
class MuJoCoLoops(LoopEngine):
    """MuJoCo's ``mjEQ_CONNECT`` between two sites per cut, solimp at mjMAXIMP (module doc)."""

    name = "mujoco"
    adapter = MuJoCo
    package = "mujoco"
    module = "mujoco"
    thin_ok = True
    kinds = ("point", "planar", "plane")  # a planar or plane cut as a ball (non_planar)
    couples = ("the MuJoCo adapter's own joint equalities (mjEQ_JOINT, solimp at mjMAXIMP), "
               "solved with the cuts' connects in one constraint solve")
    TOLERANCE = 1e-15  # opt.tolerance; Newton stops after 1 iteration on these problems

    def _build(self):
        mj, t = self.lib, self.tree
        spec, bodies = t.spec, t.spec_bodies
        for stage in ("mjDSBL_CONSTRAINT", "mjDSBL_EQUALITY"):  # the cuts; contacts stay off
            spec.option.disableflags &= ~int(getattr(mj.mjtDisableBit, stage))
        spec.option.solver = mj.mjtSolver.mjSOL_NEWTON
        spec.option.tolerance = self.TOLERANCE
        solimp = np.array([mj.mjMAXIMP, mj.mjMAXIMP, 0.001, 0.5, 2.0])
        for i, c in enumerate(self.loops.cuts):
            sites = []
            for side, body, point in (("a", c.body_a, c.point_a), ("b", c.body_b, c.point_b)):
                s = (spec.worldbody if body < 0 else bodies[body]).add_site()
                s.name, s.pos = f"cut{i}{side}", np.array(point, dtype=float)
                sites.append(s.name)
            eq = spec.add_equality()
            eq.name, eq.type, eq.objtype = f"cut{i}", mj.mjtEq.mjEQ_CONNECT, mj.mjtObj.mjOBJ_SITE
            eq.name1, eq.name2 = sites
            eq.solimp = solimp
        t._compile()
        mm = t.mjmodel
        assert mm.neq == len(self.loops.cuts) + len(self.model.couplings)
        assert not np.any(mm.opt.disableflags & int(mj.mjtDisableBit.mjDSBL_CONSTRAINT
                                                     | mj.mjtDisableBit.mjDSBL_EQUALITY))
        self.eq_ids = [mm.equality(f"cut{i}").id for i in range(len(self.loops.cuts))]

    def _forward(self, q, v, tau):
        t = self.tree
        qe, blocks = t._state(q, v)
        d = t._forward(qe, t._to_engine(v, blocks),
                       None if tau is None else t._to_engine(tau, blocks))
        n = d.nefc
        eq = int(self.lib.mjtConstraint.mjCNSTR_EQUALITY)
        rows = 3 * len(self.loops.cuts) + len(self.model.couplings)  # connects, joint equalities
        if n != rows or np.any(d.efc_type[:n] != eq):
            raise AssertionError(f"expected {rows} equality rows, got {n}")
        cuts = [i for i in range(n) if int(d.efc_id[i]) in self.eq_ids]  # the connects' rows
        order = np.array(cuts)[np.argsort([self.eq_ids.index(int(d.efc_id[i])) for i in cuts],
                                          kind="stable")]
        return d, blocks, order

    def _solve(self, q, v, tau):
        t = self.tree
        d, blocks, order = self._forward(q, v, tau)
        f = np.asarray(d.efc_force[:d.nefc])[order].reshape(-1, 3)
        return t._from_engine(d.qacc, blocks), self._rows(f, q)

    integrator = "mj_step, mjINT_RK4 (soft connect constraints, default solref)"

    def _simulate(self, q0, v0, h, steps, every):
        """The engine adapter's own stepper (mj_step, RK4) on the model with the cuts; the time
        step is restored after, as it enters the soft constraints' reference acceleration."""
        t = self.tree
        saved = t.mjmodel.opt.timestep
        try:
            tr = t.simulate(q0, v0, steps * h, h, every=every)
        finally:
            t.mjmodel.opt.timestep = saved
        return tr.t, tr.q, tr.v

    def regularisation(self, q, v) -> np.ndarray:
        """MuJoCo's constraint regulariser R (``efc_R``) at (q, v), one per core row: MuJoCo's
        forces solve (A + R) f = aref - J a0 instead of A f = -J a0 - Jdot v (aref = 0 and the
        velocity term is in a0's J a0, measured, on an assembled state with J v = 0)."""
        d, _, order = self._forward(*self._check(q, v, None)[:2], None)
        return self._rows(np.asarray(d.efc_R[:d.nefc])[order].reshape(-1, 3))


# --------------------------------------------------------------------------- DART
class DARTLoops(LoopEngine):
    """DART's ``BallJointConstraint`` per cut, resolved in one ``World.step()`` (module doc); a
    coupled model or one with armature: the adapter's KKT solve on DART's own dynamics and
    point kinematics (``couples``, :meth:`_solve_kkt`)."""

    name = "dart"
    adapter = DART
    package = "dartpy"
    module = "dartpy"
    thin_ok = True
    kinds = ("point", "planar", "plane")  # a planar or plane cut as a ball (non_planar)
    couples = ("the adapter's KKT solve on DART's own dynamics: M (with the armature the DART "
               "adapter adds) and -(C + g) from getMassMatrix and getCoriolisAndGravityForces, "
               "the cuts' rows from getLinearJacobian and getLinearJacobianDeriv at the cut "
               "points, one row e_f - m e_l per coupling (dartpy 6.20 reaches no mimic joint, "
               "and World.step's constraint solver would run on a model without the armature)")
    holds_armature = True  # by the same KKT solve (couples)
    STEP = 1e-3  # s; at v = 0 (the only state taken) the answer does not depend on it
    CFM = 1e-9  # DART's default and floor; its relative error in qdd and lam is ~CFM (measured)

    def _build(self):
        dart, t = self.lib, self.tree
        self.world = dart.simulation.World()
        self.world.setGravity(np.asarray(self.model.gravity, dtype=float))
        self.world.addSkeleton(t.skel)  # also sets the skeleton's gravity to the world's
        self.world.setTimeStep(self.STEP)
        self.bodynodes = t.bodynodes
        # a coupled model or one with armature: the KKT solve on DART's dynamics (couples)
        self.kkt = bool(self.model.couplings) or bool(np.any(self.model.armature))

    def refusal(self, q, v) -> str:
        if self.kkt and self.tree.free:
            return ("the KKT path (a coupled model, or one with armature) takes a tree without "
                    "a free joint")
        if np.any(np.asarray(v) != 0.0) and not self.kkt:
            return ("DART resolves a loop by a velocity impulse inside World.step() (J v_new = 0, "
                    "so J qdd = 0): at v != 0 its (v_new - v)/h lacks the loop's velocity-product "
                    "term -Jdot v, an error of O(|Jdot v|) that no step size removes; only v = 0 "
                    "is taken")
        return ""

    def _constraints(self, q, erp=0.0):
        """Rebuild the ball constraints at the assembled q, with error reduction ``erp``: DART
        derives each body's offset from the skeleton's pose at construction, so it is set to q
        first."""
        from redysim.algorithms.rbda import kinematics

        dart, t = self.lib, self.tree
        t.skel.setPositions(t._state(q, np.zeros(self.model.n_v))[0])
        kin = kinematics(self.model, q, np.zeros(self.model.n_v))
        solver = self.world.getConstraintSolver()
        solver.removeAllConstraints()
        for c in self.loops.cuts:
            a = self.bodynodes[c.body_a]
            if c.body_b < 0:
                con = dart.constraint.BallJointConstraint(a, np.array(c.point_b, dtype=float))
            else:
                x = kin.O[c.body_a] + kin.R[c.body_a] @ np.asarray(c.point_a, dtype=float)
                con = dart.constraint.BallJointConstraint(a, self.bodynodes[c.body_b], x)
            con.setErrorReductionParameter(erp)
            con.setConstraintForceMixing(self.CFM)  # a static in DART: set it every time
            solver.addConstraint(con)

    integrator = ("World.step: semi-implicit Euler, BallJointConstraint impulses, DART's default "
                  "error reduction 0.01")
    ERP = 0.01  # DART's default (JointConstraint), for simulate: its drift correction

    def _simulate(self, q0, v0, h, steps, every):
        if self.kkt:
            raise LoopStateUnsupported(
                f"{self.name}: World.step would step the model without its "
                f"{'couplings' if self.model.couplings else 'armature'} (its qdd holds them by "
                f"the adapter's KKT solve, couples)")
        t = self.tree
        self._constraints(q0, self.ERP)
        qe, blocks = t._state(q0, v0)
        t._set(qe, t._to_engine(v0, blocks))
        self.world.setTimeStep(h)
        try:
            ts, qs, vs = [0.0], [q0.copy()], [v0.copy()]
            for i in range(1, steps + 1):
                self.world.step()
                if i % every == 0 or i == steps:
                    q, v = t.sim_state()  # the skeleton's state, in the core's coordinates
                    ts.append(i * h)
                    qs.append(q)
                    vs.append(v)
        finally:
            self.world.setTimeStep(self.STEP)
        return ts, qs, vs

    def _jacobian(self):
        """(3 n_cuts, n_v): DART's world-frame Jacobian of point a minus point b, per cut."""
        skel, rows = self.tree.skel, []
        for c in self.loops.cuts:
            Ja = np.array(skel.getLinearJacobian(self.bodynodes[c.body_a],
                                                 np.array(c.point_a, dtype=float)))
            if c.body_b >= 0:
                Ja = Ja - np.array(skel.getLinearJacobian(self.bodynodes[c.body_b],
                                                          np.array(c.point_b, dtype=float)))
            rows.append(Ja)
        return np.vstack(rows)

    def _solve_kkt(self, q, v, tau):
        """(qdd, lam) from DART's M (armature in), bias and point kinematics by the adapter's
        solve (``couples``): M a = phi + J^T lam, J a = -gamma, J the cuts' rows (J_a - J_b
        along the core's rows of each cut) and the couplings' (e_f - m e_l), gamma their
        classical accelerations at qdd = 0 (Jdot v; zero for a coupling). The engine's
        coordinates are the core's here (no free joint: ``refusal``)."""
        t, m = self.tree, self.model
        M, phi = t.mass_matrix(q), t.bias(q, v)
        if tau is not None:
            phi = phi + tau
        qe, _ = t._state(q, v)
        y = t._to_engine(v, [])
        t._set(qe, y)
        skel = t.skel
        Js, gs = [], []
        for c in self.loops.cuts:
            sides = [(c.body_a, c.point_a, 1.0)] + ([(c.body_b, c.point_b, -1.0)]
                                                     if c.body_b >= 0 else [])
            J, g = np.zeros((3, m.n_v)), np.zeros(3)
            for body, point, sign in sides:
                p = np.array(point, dtype=float)
                Jb = np.array(skel.getLinearJacobian(self.bodynodes[body], p))
                Jd = np.array(skel.getLinearJacobianDeriv(self.bodynodes[body], p))
                J += sign * Jb[:, t.eidx]
                g += sign * (Jd @ y)
            Js.append(J)
            gs.append(g)
        rows = [self._rows(np.array(Js), q)]
        gamma = [self._rows(np.array(gs), q)]
        if m.couplings:
            _, _, fv, lv, mult, _ = m.coupling_index
            C = np.zeros((len(fv), m.n_v))
            C[np.arange(len(fv)), fv] = 1.0
            C[np.arange(len(fv)), lv] -= mult
            rows.append(C)
            gamma.append(np.zeros(len(fv)))
        J, g = np.vstack(rows), np.concatenate(gamma)
        X = np.linalg.solve(M, np.column_stack([phi, J.T]))
        a0, X = X[:, 0], X[:, 1:]
        lam = np.linalg.solve(J @ X, -g - J @ a0)
        return a0 + X @ lam, lam[:self.loops.m]

    def _solve(self, q, v, tau):
        if self.kkt:
            return self._solve_kkt(q, v, tau)
        t = self.tree
        qe, blocks = t._state(q, v)
        y = t._to_engine(v, blocks)
        tau_e = None if tau is None else t._to_engine(tau, blocks)
        t._set(qe, y, tau_e)
        skel = t.skel
        skel.computeForwardDynamics()
        a0 = np.array(skel.getAccelerations())
        M = np.array(skel.getMassMatrix())
        J = self._jacobian()
        self._constraints(q)
        t._set(qe, y, tau_e)
        self.world.step()
        a = (np.array(skel.getVelocities()) - y) / self.STEP
        rows = self._rows(J.reshape(len(self.loops.cuts), 3, -1), q)  # the core's rows of J
        lam, *_ = np.linalg.lstsq(rows.T, M @ (a - a0), rcond=None)
        return t._from_engine(a, blocks), lam


# --------------------------------------------------------------------------- Exudyn
class ExudynLoops(LoopEngine):
    """Exudyn's ``ObjectJointSpherical`` per cut; qdd = the implicit solver's initial
    accelerations (module docstring)."""

    name = "exudyn"
    adapter = Exudyn
    package = "exudyn"
    module = "exudyn"
    planar_exact = True  # ObjectJointSpherical's constrainedAxes = [1, 1, 0]

    def _build(self):
        exu, t = self.lib, self.tree
        from exudyn.itemInterface import (
            MarkerBodyPosition,
            MarkerKinematicTreeRigid,
            ObjectGround,
            ObjectJointSpherical,
            VObjectJointSpherical,
        )

        from .exudyn_engine import _settings

        mbs = t.mbs
        ground = None

        def marker(body, point):
            nonlocal ground
            p = np.asarray(point, dtype=float)
            if body < 0:
                if ground is None:
                    ground = mbs.AddObject(ObjectGround())
                return mbs.AddMarker(MarkerBodyPosition(bodyNumber=ground,
                                                        localPosition=[float(x) for x in p]))
            A = t.turn_of_body[body]
            p = p if A is None else A.T @ p
            return mbs.AddMarker(MarkerKinematicTreeRigid(
                objectNumber=t.tree, linkNumber=t.link_of_body[body],
                localPosition=[float(x) for x in p]))

        self.joints = []
        for c in self.loops.cuts:
            pair = [marker(c.body_a, c.point_a), marker(c.body_b, c.point_b)]
            self.joints.append(mbs.AddObject(ObjectJointSpherical(
                markerNumbers=pair, constrainedAxes=[1, 1, 1] if c.kind == "point" else [1, 1, 0],
                visualization=VObjectJointSpherical(show=False))))
        mbs.Assemble()
        ss = _settings(exu, exu.DynamicSolverType.GeneralizedAlpha, 1e-6, 1)
        ss.timeIntegration.generalizedAlpha.computeInitialAccelerations = True
        self.settings = ss
        self.solver = exu.MainSolverImplicitSecondOrder()
        self._sensors = None

    def _solve(self, q, v, tau):
        from .exudyn_engine import _without_sparse_advice

        exu, t = self.lib, self.tree
        qe, blocks = t._state(q, v)
        t._set_state(qe, t._to_engine(v, blocks),
                     None if tau is None else t._to_engine(tau, blocks))
        with _without_sparse_advice():
            self.solver.InitializeSolver(t.mbs, self.settings)  # computes the initial qdd
        sd, cur = t.mbs.systemData, exu.ConfigurationType.Current
        a = np.array(sd.GetODE2Coordinates_tt(configuration=cur))
        lam = np.array(sd.GetAECoordinates(configuration=cur)).reshape(-1, 3)
        return t._from_engine(a, blocks), self._rows(lam)


    integrator = ("GeneralizedAlpha (Exudyn's defaults: index-3 constraints, spectral radius 0.9), "
                  "Newton tolerances 1e-12")

    def _simulate(self, q0, v0, h, steps, every):
        from exudyn.itemInterface import SensorNode

        from .exudyn_engine import _settings, _without_sparse_advice

        exu, t = self.lib, self.tree
        mbs = t.mbs
        if self._sensors is None:
            ovt = exu.OutputVariableType
            self._sensors = [mbs.AddSensor(SensorNode(nodeNumber=t.node, storeInternal=True,
                                                      writeToFile=False, outputVariableType=o))
                             for o in (ovt.Coordinates, ovt.Coordinates_t)]
            mbs.Assemble()
        ss = _settings(exu, exu.DynamicSolverType.GeneralizedAlpha, steps * h, steps)
        ss.timeIntegration.newton.relativeTolerance = 1e-12
        ss.timeIntegration.newton.absoluteTolerance = 1e-12
        ss.solution.sensors.writePeriod = every * h
        qe, blocks = t._state(q0, v0)
        t._set_state(qe, t._to_engine(v0, blocks), None)
        with _without_sparse_advice():
            if not exu.MainSolverImplicitSecondOrder().SolveSystem(mbs, ss):
                raise LoopStateUnsupported(f"{self.name}: the GeneralizedAlpha solve failed")
        v, vd = (np.array(mbs.GetSensorStoredData(s)) for s in self._sensors)
        want = [i * h for i in range(0, steps + 1, every)]
        if steps % every:
            want.append(steps * h)
        rows = [int(np.argmin(np.abs(v[:, 0] - w))) for w in want]
        if any(abs(v[r, 0] - w) > 0.5 * h for r, w in zip(rows, want, strict=True)):
            raise AssertionError(f"Exudyn's sensor samples {v[:, 0]} miss the times {want}")
        return (want, [v[r, 1:][t.eidx] for r in rows], [vd[r, 1:][t.eidx] for r in rows])


LOOP_ENGINES: dict[str, type[LoopEngine]] = {
    cls.name: cls for cls in (PinocchioLoops, MuJoCoLoops, DARTLoops, ExudynLoops)}


def loop_engine(name: str, loops: ClosedLoops, *, check_limits: bool = True) -> LoopEngine:
    """Engine ``name`` (a key of :data:`LOOP_ENGINES`) on ``loops``: raises
    EngineLimitExceeded with the reason when its ``limits`` refuse them, EngineUnavailable when
    its package is missing."""
    try:
        cls = LOOP_ENGINES[name]
    except KeyError:
        raise KeyError(f"no loop engine {name!r}; known: {', '.join(LOOP_ENGINES)}") from None
    return cls(loops, check_limits=check_limits)
