"""Exudyn adapter: one ``ObjectKinematicTree`` (minimal coordinates) on a ``NodeGenericODE2``.

What the model contains and why (docs/design.md, "Reference engines"):

- ``ObjectKinematicTree`` has only 1-DOF joints, each ``RevoluteX/Y/Z`` or ``PrismaticX/Y/Z``
  of its own joint frame, so every elementary axis of a body's joint
  (``redysim.references.base.joint_axes``) is one tree link, in order: the axes before the last are
  massless links (zero mass and inertia) at zero offset from the previous one, the last carries
  the body's mass, COM and inertia about the COM. A U joint is thus a massless ``RevoluteY``
  link at the joint's placement, then a ``RevoluteZ`` link with the mass; an R joint about z one
  ``RevoluteZ`` link. Each body's first link hangs from its parent body's last link
  (``linkParents``, -1 = ground; the Model's order puts parents first, as Exudyn requires), its
  ``jointHTs`` entry the placement (R, p) in that link's frame (a chain's link k: l_{k-1} along
  the parent's x); ``gravity = model.gravity`` (the tree's own gravity parameter).
- An axis u that is not +x, +y or +z of its frame gets a rotated joint frame. The tree link's
  frame is then the core's frame after the axis times a constant rotation A (its columns the
  tree frame's axes in the core's frame), chosen with A e = u for the joint type's axis e:
  -x, -y, -z take the X, Y or Z joint type and A a half-turn about the next coordinate axis
  (entries 0 and +-1 only: exact), any other u the Z type and A = [a, u x a, u] with a a unit
  vector normal to u. With Rot(u, q) = A Rz(q) A^T, the tree link's rotation is
  R_before A Rz(q) = R_after A, and a prismatic link moves its origin by R_before u q, as in the
  core. Everything given in the tree link's frame is the core's quantity turned by A^T: the
  link's COM A^T c and inertia A^T I_C A, the sensors' local points, and the next axis's
  ``jointHTs`` entry (rotation A_prev^T R A_next, translation A_prev^T p for the next joint's
  first axis at the placement (R, p), the identity rotation and zero for the next axis of the
  same joint), which maps the next joint frame to the previous tree link's frame (position in
  parent = R p + o). For +x, +y, +z axes A is the identity and nothing is turned.
- No markers, loads, connectors, contacts or graphics; visualisation off (``show=False``); no
  joint P/D control, force vectors or user functions (all empty/zero by default).
- Solver settings: ``linearSolver.solverType = EigenDense`` (the default EXUdense was slower
  and inaccurate at 1,000 links; docs/notes/2026-11-reference-engines.md); no solution file, no
  sensors written, verbose off. Above 1,000 coordinates Exudyn prints, at every solve, a
  multi-line advice to consider a sparse solver: it does not apply here (a chain's kinematic tree
  couples every joint, so its mass matrix is dense, and EigenSparse was the slower at 1,200 DOF:
  references/README.md, "Each engine's fastest honest configuration"), so that one message is
  dropped (:func:`_without_sparse_advice`); anything else Exudyn prints passes through.

``qdd`` uses Exudyn's own solver (Exudyn has no public qdd call): the state is written as the
initial state, one ``ExplicitEuler`` step of 1e-12 s is taken with
``timeIntegration.explicit.computeEndOfStepAccelerations = False``, and
``GetODE2Coordinates_tt()`` then holds the acceleration at the start of the step, i.e. at the
given state. ``tau`` enters through the tree's ``jointForceVector``.
``mass_matrix`` and ``bias`` are the solver's ``ComputeMassMatrix`` and ``ComputeODE2RHS`` (the
ODE2 right-hand side, which is phi with tau = 0). ``energy``: T = v^T M v / 2 with Exudyn's M,
V = -sum m g . r_C with the COM positions from ``SensorKinematicTree`` (Exudyn has no energy call
for the tree). ``position``: a ``SensorKinematicTree`` on the body's last link at the point
(turned by A^T).

Native integrators (``Exudyn.integrators``; ``simulate``, ``sim_reset(..., integrator=NAME)``,
``redysim.simulation.Simulator(..., engine=eng, integrator="native:NAME")``): Exudyn's own
solvers of ``exudyn.DynamicSolverType`` on this model, each run one ``MainSolverExplicit`` or
``MainSolverImplicitSecondOrder`` initialised at ``sim_reset``. Orders measured on the 3-link
chain and a free box (tests/test_engines_native.py):

| name              | what (DynamicSolverType)  | step     | order | note                       |
|-------------------|---------------------------|----------|-------|----------------------------|
| explicit-euler    | ExplicitEuler             | fixed    | 1     |                            |
| explicit-midpoint | ExplicitMidpoint          | fixed    | 2     |                            |
| rk33              | RK33                      | fixed    | 3     | Heun's 3-stage             |
| rk44              | RK44                      | fixed    | 4     | classic; the default       |
| rk67              | RK67                      | fixed    | 6     | Butcher's 7-stage          |
| velocity-verlet   | VelocityVerlet            | fixed    | 1     | 2 only if qdd ignores v    |
| ode23             | ODE23, automaticStepSize  | adaptive | 3(2)  | Bogacki-Shampine           |
| dopri5            | DOPRI5, automaticStepSize | adaptive | 5(4)  | Dormand-Prince             |
| generalized-alpha | GeneralizedAlpha          | fixed    | 2     | rho_inf = 0.9, implicit    |
| trapezoidal       | TrapezoidalIndex2         | fixed    | 2     | Newmark 1/4, 1/2, implicit |

What a fair comparison must know (each entry's ``note`` and the ``manifest`` say it too):

- Explicit fixed steps (``computeEndOfStepAccelerations`` off, Lie-group integration on, which
  no coordinate of this tree uses) and the implicit ones are taken one at a time as
  ``SolveSteps``'s loop body takes them (``InitializeStep``, ``DiscontinuousIteration``,
  ``FinishStep``): bit for bit one continuous ``SolveSystem`` over the same steps, with the
  same Newton iterations and Jacobians (measured). Calling ``SolveSteps`` once a step instead
  asks for a new Jacobian every step (200 in 200 steps against 21), and restarting the solver
  every step (as the adapter once did for RK44) makes generalized-alpha first order for
  rho_inf < 1 (its algorithmic acceleration is history; observed order between h = 2.5 and
  1.25 ms: 1.02 at rho_inf = 0.5, 1.40 at 0.9, against 1.99 run through).
- ``VelocityVerlet`` evaluates the end-of-step acceleration at the half-step velocity, so it is
  first order wherever qdd depends on v (Coriolis and centripetal terms: measured 1.02, and
  reproduced bit for bit by that scheme written out); Exudyn prints "VelocityVerlet: still under
  development". ``DVERK6`` is in ``DynamicSolverType`` but Exudyn 1.13.6's explicit solver
  refuses it ("must be an explicit solver (ExplicitEuler, ..., VelocityVerlet), but it is
  DVERK6"): not registered.
- ``ODE23`` and ``DOPRI5`` (``automaticStepSize``; tolerances ``relativeTolerance``,
  ``absoluteTolerance``): each call of ``sim_advance(t)`` runs ``SolveSteps`` from the state kept
  to t, landing on t by a shortened last step (Exudyn's own end-time rule), the next call
  starting from Exudyn's proposed step; ``h``, when given, is the largest step, else the interval.
  Exudyn computes every stage of every step (no first-same-as-last: 7 qdd a DOPRI5 step where 6
  would do), counted in ``sim_counts`` as stages x (accepted + rejected) + 2 (below). Its error
  norm scales coordinate i by atol + max(y_old_i, y_new_i) rtol with SIGNED values (Hairer,
  Norsett & Wanner use |y|): a negative coordinate gets a tighter scale than atol, one near
  -atol/rtol a zero one (a 3-link chain hanging along x: its mirror image, q0 and v0 negated,
  took 508 ODE23 steps where the original took 569 at rtol = atol = 1e-6, measured). Its first
  step is the largest allowed (the whole interval without ``initialStepSize``); the adapter
  gives it the standard starting step (HNW I, II.4, from two qdd calls). When the proposed
  step reaches ``minimumStepSize`` (1e-8 s) Exudyn ACCEPTS the step with only a warning
  ("automatic stepsize control reached minStepSize; integration continued, but error will be
  larger than given tolerances"): on the 3-link chain with a velocity at -1 = -atol/rtol, ODE23
  took its own first step, the whole 0.5 s, as one step (error 29 rad, at every rtol from 1e-4
  to 1e-10; measured). The adapter raises RuntimeError instead.
- ``GeneralizedAlpha`` at rho_inf = 0.9, Exudyn's default: on these conservative, unconstrained
  systems rho_inf = 1 is marginally more accurate (3-link chain, 0.5 s, h = 5 ms: 7.06e-3
  against 7.18e-3; 1.16e-2 at 0.5) but is the trapezoidal rule, registered as ``trapezoidal``
  (``TrapezoidalIndex2`` as ``exudyn.solver.SolveDynamic`` sets it: ``useNewmark``,
  ``useIndex2Constraints``); 0.9 keeps the generalized-alpha's damping of unresolved high
  frequencies that its users run it for. Consistent initial accelerations; Newton (modified,
  numerical Jacobian) to relative 1e-10 and absolute 1e-12: with Exudyn's defaults, 1e-8 and
  1e-10, Newton's error shows at small steps (3-link chain, 0.5 s, h = 50 us: 9.2e-7 against
  7.2e-7, for 6 % fewer iterations; measured); ``adaptiveStep`` off, so the step stays
  h and a Newton failure fails the run instead of halving the step silently. ``sim_counts``
  gives no qdd count for them (-1); the manifest has the Newton iterations and Jacobians.
- A free joint: the explicit fixed steps centre its chart again after every step (as before);
  the adaptive ones after every interval, intervals cut so that the body turns at most 0.5 rad
  in one; the implicit ones keep the chart (their history lives in it) until an angle passes
  0.5 rad, then centre it and restart the solver (consistent accelerations again: a one-off
  O(h) perturbation of the algorithmic acceleration, order 2 kept, measured).
- Constraints: this tree has none, and every solver above steps it. A coupled model's couplings
  are ``CoordinateConstraint``s in a second system of the tree (``Exudyn._couple``): its qdd is
  the implicit solver's consistent initial accelerations, and only the implicit solvers step it
  (generalized-alpha, trapezoidal: ``holds_couplings_in``); the explicit ones are refused.
  With the loops' cut joints (``references/loops.py``) only the implicit ones apply: the
  explicit solvers abort ("explicit integrator detected object ... which contains constraints
  that cannot be solved") or, with ``explicit.eliminateConstraints = False``, ignore them
  (references/README.md, "Loops").
- The state stepped is kept by the adapter and written back before every step, so a ``qdd``,
  ``bias`` or ``position`` call between steps (which set the system's state and a free joint's
  chart) leaves the run as it was (tested).

Limit: the tree's mass matrix is dense (O(n^2) memory) and factorised every right-hand side
(O(n^3) time): time stops it first (references/limits.toml).

A free joint, which the tree's 1-DOF joints cannot be, is PrismaticX/Y/Z along the world axes
then RevoluteX/Y/Z in a frame turned by the body's rotation at the state asked (rewritten at
every call, and as the native integrators say above): a chart of the rotation centred at the state,
where its rates are exactly the body-frame angular velocity, so it is never near an Euler-angle
singularity; its one correction, dE/dt w, is added to the angular acceleration (class
docstring).
"""

from __future__ import annotations

import contextlib
import io
import math
import re
import sys
from typing import Any, NamedTuple

import numpy as np

from redysim.algorithms.rbda import rotation
from redysim.model.tree import FREE

from .base import (
    Engine,
    FreeBlock,
    NativeIntegrator,
    axis,
    free_rotation,
    rotation_quaternion,
)

# the start of Exudyn's advice, printed at every solve of more than 1,000 coordinates
SPARSE_ADVICE = "The number of total coordinates (unknowns) is larger than 1000. Consider a sparse"


@contextlib.contextmanager
def _without_sparse_advice():
    """Run the block with stdout captured, then print what it printed without Exudyn's advice to
    use a sparse solver (module docstring); every other line passes through."""
    buf = io.StringIO()
    try:
        with contextlib.redirect_stdout(buf):
            yield buf  # what was printed, for a caller that reads Exudyn's warnings
    finally:
        # one message per "Python WARNING" (each starts on a new line)
        messages = re.split(r"(?=\nPython WARNING)", buf.getvalue())
        out = "".join(m for m in messages if SPARSE_ADVICE not in m)
        if out.strip():
            sys.stdout.write(out)

QDD_STEP = 1e-12  # length of the single explicit Euler step whose start-acceleration is qdd


def _ht(p, rot=None) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    if rot is not None:
        T[:3, :3] = rot
    return T


def joint_frame(axis) -> tuple[int, np.ndarray | None]:
    """(i, A) for one elementary axis: the tree joint's type axis i (0, 1, 2: X, Y, Z) and the
    rotation A of its joint frame in the core's frame before the axis, A e_i = u (None: the
    identity, for u exactly +e_i)."""
    if axis.coordinate is not None:
        return axis.coordinate, None
    sc = axis.signed_coordinate
    if sc is not None:  # -e_i: a half-turn about e_j, j the next axis (exact entries 0, +-1)
        i, _ = sc
        A = -np.eye(3)
        A[(i + 1) % 3, (i + 1) % 3] = 1.0
        return i, A
    u = axis.vector
    e = np.zeros(3)
    e[int(np.argmin(np.abs(u)))] = 1.0  # the coordinate axis farthest from u
    a = e - (e @ u) * u
    a /= np.linalg.norm(a)
    return 2, np.column_stack([a, np.cross(u, a), u])


def _settings(exu, solver_type, t_end, steps):
    """The solver settings of every solve here (module docstring)."""
    ss = exu.SimulationSettings()
    ti = ss.timeIntegration
    ti.solverType = solver_type
    ti.endTime = t_end
    ti.numberOfSteps = steps
    ti.verboseMode = 0
    ti.explicit.computeEndOfStepAccelerations = False
    ss.linearSolver.solverType = exu.LinearSolverType.EigenDense
    ss.solution.file.write = False
    ss.show.computationTime = False
    ss.show.statistics = False
    return ss


def _joint_kinds(exu) -> dict:
    """Exudyn's 1-DOF joint types by kind ("R", "P") and axis index (x, y, z)."""
    J = exu.JointType
    return {"R": (J.RevoluteX, J.RevoluteY, J.RevoluteZ),
            "P": (J.PrismaticX, J.PrismaticY, J.PrismaticZ)}


class _Solver(NamedTuple):
    """How one native integrator runs: its ``DynamicSolverType`` member, ``kind`` ("explicit":
    a fixed-step Runge-Kutta or Verlet step of MainSolverExplicit, "adaptive": one of its
    error-controlled ones, "implicit": MainSolverImplicitSecondOrder), its nominal order and its
    qdd evaluations per attempted step (its stages; -1: Newton iterations instead)."""

    solver_type: str
    kind: str
    order: int
    per_step: int


SPECTRAL_RADIUS = 0.9  # generalized-alpha's rho_inf: Exudyn's default (module docstring)
NEWTON_RTOL, NEWTON_ATOL = 1e-10, 1e-12  # the implicit solvers' Newton tolerances (docstring)
CHART_ANGLE = 0.5  # [rad]: a free joint's chart is centred again before it turns further
MIN_STEP_WARNING = "reached minStepSize"  # Exudyn's words when its step control gives up

_COMMON = ("EigenDense; ObjectKinematicTree, no constraints; a free joint steps in a chart "
           "centred at the state (module docstring)")
_SOLVERS = {
    "explicit-euler": _Solver("ExplicitEuler", "explicit", 1, 1),
    "explicit-midpoint": _Solver("ExplicitMidpoint", "explicit", 2, 2),
    "rk33": _Solver("RK33", "explicit", 3, 3),
    "rk44": _Solver("RK44", "explicit", 4, 4),
    "rk67": _Solver("RK67", "explicit", 6, 7),
    "velocity-verlet": _Solver("VelocityVerlet", "explicit", 1, 1),
    "ode23": _Solver("ODE23", "adaptive", 3, 4),
    "dopri5": _Solver("DOPRI5", "adaptive", 5, 7),
    "generalized-alpha": _Solver("GeneralizedAlpha", "implicit", 2, -1),
    "trapezoidal": _Solver("TrapezoidalIndex2", "implicit", 2, -1),
}
_ADAPTIVE_NOTE = (
    "Exudyn's step control (Hairer-Norsett-Wanner I, p. 168) scales each coordinate's error by "
    "atol + max(y_old, y_new) rtol with SIGNED values, not |y|: a negative coordinate is held "
    "tighter than atol, one near -atol/rtol infinitely so (mirrored motions take different "
    "steps, measured); when its proposal reaches minimumStepSize (1e-8 s) Exudyn accepts the "
    "step anyway with a warning: the adapter raises instead. The first step is the standard "
    "starting step (HNW I, II.4) from two qdd calls (Exudyn's own first step is the largest); "
    "each sample time is landed on by a shortened step and the next call starts from Exudyn's "
    "proposal; no FSAL: every stage computed every step")
_NOTES = {
    "explicit-euler": "explicit Euler, first order",
    "explicit-midpoint": "explicit midpoint rule, second order",
    "rk33": "Heun's third-order Runge-Kutta (3 stages)",
    "rk44": "classic fourth-order Runge-Kutta; the default",
    "rk67": "Butcher's 7-stage sixth-order Runge-Kutta",
    "velocity-verlet": (
        "kick-drift-kick Verlet, second order only when qdd does not depend on v: Exudyn "
        "evaluates the end-of-step qdd at the half-step velocity, so with Coriolis and "
        "centripetal terms it is FIRST order (measured, and reproduced bit for bit by that "
        "scheme); Exudyn prints 'VelocityVerlet: still under development'"),
    "ode23": "Bogacki-Shampine 3(2), 4 stages; " + _ADAPTIVE_NOTE,
    "dopri5": "Dormand-Prince 5(4), 7 stages; " + _ADAPTIVE_NOTE,
    "generalized-alpha": (
        f"Chung-Hulbert generalized-alpha, second order, spectral radius rho_inf = "
        f"{SPECTRAL_RADIUS} (Exudyn's default; rho_inf = 1 is 'trapezoidal'), consistent "
        f"initial accelerations; stepped as one continuous solve (restarting it every step, "
        f"as a one-step method, makes it first order for rho_inf < 1, measured); Newton "
        f"(modified, numerical Jacobian) to rtol {NEWTON_RTOL:g}, atol {NEWTON_ATOL:g}; fixed "
        f"step (adaptiveStep off: a failed Newton fails the run)"),
    "trapezoidal": (
        f"Exudyn's TrapezoidalIndex2 (as SolveDynamic sets it: its implicit solver with "
        f"useNewmark, beta = 1/4, gamma = 1/2, and index-2 constraints, none here): the "
        f"trapezoidal rule, second order, no numerical damping (generalized-alpha at rho_inf "
        f"= 1); Newton as generalized-alpha's (rtol {NEWTON_RTOL:g}, atol {NEWTON_ATOL:g})"),
}
NATIVE = {name: NativeIntegrator(
    name, sol.kind == "adaptive",
    f"DynamicSolverType.{sol.solver_type}, "
    + ("MainSolverImplicitSecondOrder" if sol.kind == "implicit" else "MainSolverExplicit")
    + (" with automaticStepSize" if sol.kind == "adaptive" else ", one step of h a call"),
    f"{_NOTES[name]}; {_COMMON}") for name, sol in _SOLVERS.items()}


# a free joint as six 1-DOF tree links: P along the world's x, y, z, then R about x, y, z of a
# frame turned by the body's rotation at the state (module docstring)
FREE_AXES = tuple(axis(kind, np.eye(3)[i]) for kind in "PR" for i in range(3))


class Exudyn(Engine):
    """Exudyn's ObjectKinematicTree with its own explicit solver and EigenDense (module
    docstring). ``mbs``, ``tree``, ``node``: Exudyn's system, the ObjectKinematicTree and its
    node; ``link_of_body[k]``, ``turn_of_body[k]``: body k's last tree link and that link's
    turn A (None: the identity); ``hts``: the tree's ``jointHTs``.

    Free joint: the tree has only 1-DOF joints (RevoluteX/Y/Z, PrismaticX/Y/Z), so a free body is
    six massless-but-the-last links: PrismaticX, Y, Z along the world axes (their coordinates are
    the origin's world position, their rates v_world), then RevoluteX, Y, Z in a joint frame
    turned by R0, the body's rotation AT THE STATE ASKED (its ``jointHTs`` entry is rewritten at
    every call), with the three angles zero. The angles are then a chart of the rotation centred
    at the state, R = R0 Rx(a) Ry(b) Rz(c), whose rates at the centre are exactly the body-frame
    angular velocity (w_body = E(a, b, c) (a, b, c)' with E(0) = 1): no Euler-angle singularity is
    ever near. So B = 1 and c = (0, dE/dt (a, b, c)') = (0, 0, 0, w_y w_z, -w_x w_z, w_x w_y)
    (d/dt of E at the centre applied to w), which the adapter adds to the angular acceleration.
    The applied force is the core's (E(0)^T = 1). The native integrators step in that chart and
    centre it again (module docstring: after every step, every interval, or past 0.5 rad).
    """

    name = "exudyn"
    package = "exudyn"
    module = "exudyn"
    no_armature = ("Exudyn 1.13's ObjectKinematicTree has no joint armature (no rotor "
                   "inertia of a joint found in its items)")
    holds_armature = ("by the adapter, from Exudyn's own ComputeMassMatrix and ComputeODE2RHS: "
                      "(M + diag(armature)) qdd = tau + RHS, the equations Exudyn would solve "
                      "had it the field (ObjectKinematicTree has none: jointTypes, linkMasses, "
                      "linkInertiasCOM, the P/D control and force vectors, checked); a coupled "
                      "model's: that M and RHS restricted to the coupled motion, G (G^T M G)^-1 "
                      "G^T (tau + RHS); its own solvers do not hold it")
    armature_native = False
    holds_passive = ("switched on for its own solvers' steps only (the qdd, M and bias stay "
                     "the rigid body's): each 1-DOF joint's damping and spring as the tree's own "
                     "joint P/D control, jointPControlVector = stiffness, jointDControlVector = "
                     "damping, jointPositionOffsetVector = spring_ref (force P (q_o - q) - D v), "
                     "each body's gravcomp a LoadForceVector of -gravcomp m g (global) on a "
                     "MarkerKinematicTreeRigid at its COM")
    couples = ("one CoordinateConstraint per coupling on the tree's coordinates (factor1 = m, "
               "offset = -c: Exudyn's factor1 q_m1 - q_m0 - offset = 0, measured), qdd from its "
               "implicit solver's consistent initial accelerations (GeneralizedAlpha "
               "computeInitialAccelerations), as the loops' constraints")
    no_couplings = ("Exudyn's explicit solvers (rk44, its default, and the rest) abort on a "
                    "constraint; its implicit ones (generalized-alpha, trapezoidal) hold the "
                    "CoordinateConstraints")
    no_ball = ("Exudyn 1.13's ObjectKinematicTree has revolute and prismatic joints only (no "
               "spherical joint)")
    integrator = "rk44"
    integrators = NATIVE

    def _build(self):
        exu = self.lib
        from exudyn.itemInterface import NodeGenericODE2, ObjectKinematicTree, VObjectKinematicTree
        m = self.model
        kinds = _joint_kinds(exu)
        types, parents, hts, inertias, coms, masses = [], [], [], [], [], []
        self.link_of_body, self.turn_of_body = [], []
        self.free_links = []  # (qs, vs, index of the link whose joint frame is turned by R0)
        for k, joint in enumerate(self.joints):
            link = -1 if joint.parent < 0 else self.link_of_body[joint.parent]
            turn = None if joint.parent < 0 else self.turn_of_body[joint.parent]
            axes = FREE_AXES if joint.type == FREE else joint.axes
            last = len(axes) - 1
            for i, ax in enumerate(axes):
                e, A = joint_frame(ax)
                Rj = np.eye(3) if A is None else A
                if i == 0:  # the joint's frame (R, p) in the parent body's last link's frame
                    Rj, pj = joint.R @ Rj, joint.p
                else:
                    pj = np.zeros(3)
                if turn is not None:
                    Rj, pj = turn.T @ Rj, turn.T @ pj
                if joint.type == FREE and i == 3:
                    self.free_links.append((int(m.joint_qoff[k]), int(m.joint_voff[k]),
                                            len(types)))
                types.append(kinds[ax.kind][e])
                parents.append(link)
                hts.append(_ht(pj, Rj))
                link, turn = len(types) - 1, A
                if i < last:
                    inertias.append(np.zeros((3, 3)))
                    coms.append([0.0, 0.0, 0.0])
                    masses.append(0.0)
            com, inertia = np.array(m.com[k]), np.array(m.inertia_com[k])
            if turn is not None:
                com, inertia = turn.T @ com, turn.T @ inertia @ turn
                inertia = 0.5 * (inertia + inertia.T)
            inertias.append(inertia)
            coms.append([float(x) for x in com])
            masses.append(float(m.mass[k]))
            self.link_of_body.append(link)
            self.turn_of_body.append(turn)
        n = len(types)
        if n != m.n_v:
            raise AssertionError(f"tree has {n} coordinates, the model {m.n_v}")
        self.hts = hts
        # the armature in the tree's coordinates, held in the qdd (holds_armature); None: none
        self.arm = self.armature_e if np.any(m.armature) else None
        self.SC = exu.SystemContainer()
        mbs = self.SC.AddSystem()
        self.node = mbs.AddNode(NodeGenericODE2(referenceCoordinates=[0.0] * n,
                                                initialCoordinates=[0.0] * n,
                                                initialCoordinates_t=[0.0] * n,
                                                numberOfODE2Coordinates=n))
        self.tree = mbs.AddObject(ObjectKinematicTree(
            nodeNumber=self.node, jointTypes=types, linkParents=parents, jointHTs=hts,
            linkInertiasCOM=exu.Matrix3DList(inertias), linkCOMs=exu.Vector3DList(coms),
            linkMasses=masses, gravity=[float(g) for g in m.gravity],
            jointForceVector=[0.0] * n, visualization=VObjectKinematicTree(show=False)))
        self.mbs = mbs
        self._sensors = {}  # (body, point) -> its position sensor
        self._build_passive()
        mbs.Assemble()
        self._tau_set = False
        self.ss_qdd = _settings(exu, exu.DynamicSolverType.ExplicitEuler, QDD_STEP, 1)
        self.solver = exu.MainSolverExplicit()
        self._init_rhs = False
        self.coupled = None
        if m.couplings:
            self._couple()

    def passive_unheld(self) -> str:
        return self.passive_on_free()

    def _build_passive(self):
        """The model's passive elements, built switched off (``holds_passive``): the tree's P/D
        control vectors at zero and one zero LoadForceVector on a COM marker per body with
        gravcomp; ``_passive(True)`` sets their values for a native step, ``_passive(False)``
        zeroes them again. ``_passive_on``: whether they are set now."""
        from exudyn.itemInterface import LoadForceVector, MarkerKinematicTreeRigid

        m, mbs = self.model, self.mbs
        self._passive_on = False
        self._gravcomp_loads: list[tuple[int, list[float]]] = []
        if not m.has_passive:
            return
        n = m.n_v
        for key in ("jointPControlVector", "jointDControlVector", "jointPositionOffsetVector",
                    "jointVelocityOffsetVector"):
            mbs.SetObjectParameter(self.tree, key, [0.0] * n)
        g = np.asarray(m.gravity, dtype=float)
        for k in np.flatnonzero(m.gravcomp):
            A = self.turn_of_body[k]
            com = np.asarray(m.com[k], dtype=float)
            marker = mbs.AddMarker(MarkerKinematicTreeRigid(
                objectNumber=self.tree, linkNumber=self.link_of_body[k],
                localPosition=list(map(float, com if A is None else A.T @ com))))
            load = mbs.AddLoad(LoadForceVector(markerNumber=marker, loadVector=[0.0] * 3,
                                               bodyFixed=False))
            force = -float(m.gravcomp[k]) * float(m.mass[k]) * g
            self._gravcomp_loads.append((load, [float(x) for x in force]))

    def _passive(self, on: bool) -> None:
        """Switch the model's passive elements on (a native step) or off (the qdd's rigid
        body): the tree's P/D control and the gravcomp loads (``_build_passive``)."""
        m = self.model
        if not m.has_passive or on == self._passive_on:
            return
        mbs, n = self.mbs, m.n_v
        vals = {"jointPControlVector": m.stiffness, "jointDControlVector": m.damping,
                "jointPositionOffsetVector": m.spring_ref}
        for key, val in vals.items():
            mbs.SetObjectParameter(self.tree, key, [float(x) for x in val] if on else [0.0] * n)
        for load, force in self._gravcomp_loads:
            mbs.SetLoadParameter(load, "loadVector", force if on else [0.0] * 3)
        self._passive_on = on

    def _couple(self):
        """The model's couplings as Exudyn's own constraints, in a second system of the same
        tree (``coupled``: the adapter built on the uncoupled tree), so that M, the bias and
        the energy stay this tree's (the core's, a coupled model's are the tree's) and the
        explicit solver that computes them sees no constraint: one ``CoordinateConstraint``
        (ObjectConnectorCoordinate) per coupling between a ``MarkerNodeCoordinate`` of the
        follower (m0) and one of the leader (m1), factor1 = m, offset = -c (its equation is
        factor1 q_m1 - q_m0 - offset = 0: measured, a GeneralizedAlpha step from a coupled
        state stays on q_f = m q_l + c with offset -c and is pulled off it with +c). qdd: the
        implicit solver's consistent initial accelerations (``computeInitialAccelerations``,
        in ``InitializeSolver``; no step taken), as references/loops.py's ExudynLoops."""
        from exudyn.itemInterface import MarkerNodeCoordinate, ObjectConnectorCoordinate

        exu, m = self.lib, self.model
        tree = type(self)(m.tree)
        mbs = tree.mbs
        _, _, fv, lv, mult, off = m.coupling_index
        for f, ld, mu, c in zip(fv, lv, mult, off, strict=True):
            pair = [mbs.AddMarker(MarkerNodeCoordinate(nodeNumber=tree.node,
                                                       coordinate=int(tree.eidx[k])))
                    for k in (f, ld)]
            mbs.AddObject(ObjectConnectorCoordinate(markerNumbers=pair, factor1=float(mu),
                                                    offset=-float(c)))
        mbs.Assemble()
        ss = _settings(exu, exu.DynamicSolverType.GeneralizedAlpha, QDD_STEP, 1)
        ss.timeIntegration.generalizedAlpha.computeInitialAccelerations = True
        self.coupled = (tree, ss, exu.MainSolverImplicitSecondOrder())

    @classmethod
    def holds_couplings_in(cls, info) -> bool:
        """Exudyn's implicit solvers hold the CoordinateConstraints (index 3, or index 2 for
        TrapezoidalIndex2); its explicit ones abort on a constraint."""
        return _SOLVERS[info.name].kind == "implicit"

    def set_sim_deadline(self, clock, deadline: float) -> None:
        super().set_sim_deadline(clock, deadline)
        if self.coupled is not None:  # (a coupled model steps on the coupled system)
            self.coupled[0].set_sim_deadline(clock, deadline)

    def _on_coupled(self, hook: str, *args):
        """A native stepping hook of a coupled model, run on the coupled system's adapter (its
        mbs holds the constraints), which takes this run's integrator, settings and deadline."""
        tree = self.coupled[0]
        if hook == "_sim_reset":
            tree.sim_integrator, tree.sim_settings = self.sim_integrator, self.sim_settings
            tree._deadline = self._deadline
        return getattr(tree, hook)(*args)

    # the engine's coordinates: the Model's order, a free joint's (x, y, z, a, b, c) in its six
    # slots (eidx is the identity); the "state" is the coordinate vector, the chart set already
    def _engine_state(self, q, v):
        qe = self._scatter(q)
        blocks = []
        for qs, vs, link in self.free_links:
            qe[vs:vs + 3] = q[qs:qs + 3]  # the angles are 0: the chart's centre
            self.hts[link] = _ht(np.zeros(3), free_rotation(q, qs))
            w = v[vs + 3:vs + 6]
            c = np.array([0.0, 0.0, 0.0, w[1] * w[2], -w[0] * w[2], w[0] * w[1]])
            blocks.append(FreeBlock(vs, np.eye(6), c))
        if self.free_links:
            self.mbs.SetObjectParameter(self.tree, "jointHTs", self.hts)
        return qe, blocks

    def _chart_to_core(self, qe, ye) -> tuple[np.ndarray, np.ndarray]:
        """(q, v) in the core's coordinates of the tree's coordinates and rates (qe, ye), each
        free joint's angles (a, b, c) in the chart its ``jointHTs`` entry holds now."""
        q, v = self._gather(qe), np.array(ye, dtype=float)
        ex, ey, ez = np.eye(3)
        for qs, vs, link in self.free_links:
            a, b, c = qe[vs + 3:vs + 6]
            Ry, Rz = rotation(ey, b), rotation(ez, c)
            q[qs:qs + 3] = qe[vs:vs + 3]
            q[qs + 3:qs + 7] = rotation_quaternion(self.hts[link][:3, :3] @ rotation(ex, a)
                                                   @ Ry @ Rz)
            da, db, dc = ye[vs + 3:vs + 6]  # w_body = E(a, b, c) (a, b, c)'
            v[vs + 3:vs + 6] = Rz.T @ (Ry.T @ (da * ex) + db * ey) + dc * ez
        return q, v

    def _set_state(self, qe, y, tau_e, which="Initial", passive=False):
        self._passive(passive)  # on for a native step only (holds_passive)
        cfg = getattr(self.lib.ConfigurationType, which)
        sd = self.mbs.systemData
        sd.SetODE2Coordinates(qe, configuration=cfg)
        sd.SetODE2Coordinates_t(y, configuration=cfg)
        if tau_e is not None or self._tau_set:
            f = np.zeros(self.model.n_v) if tau_e is None else tau_e
            self.mbs.SetObjectParameter(self.tree, "jointForceVector", list(map(float, f)))
            self._tau_set = tau_e is not None

    def _current(self, qe, y):
        if not self._init_rhs:
            with _without_sparse_advice():
                self.solver.InitializeSolver(self.mbs, self.ss_qdd)
            self._init_rhs = True
        self._set_state(qe, y, None, which="Current")

    def _qdd(self, qe, y, tau_e):
        if self.arm is not None:  # (M + diag(armature)) qdd = tau + RHS: holds_armature
            return self._armature_qdd(qe, y, tau_e)
        if self.coupled is not None:  # the constrained system's initial accelerations
            tree, ss, solver = self.coupled
            tree.hts = self.hts
            if self.free_links:  # the chart this call's state set
                tree.mbs.SetObjectParameter(tree.tree, "jointHTs", self.hts)
            tree._set_state(qe, y, tau_e)
            with _without_sparse_advice():
                solver.InitializeSolver(tree.mbs, ss)
            return np.array(tree.mbs.systemData.GetODE2Coordinates_tt(
                configuration=self.lib.ConfigurationType.Current))
        self._set_state(qe, y, tau_e)
        with _without_sparse_advice():
            self.solver.SolveSystem(self.mbs, self.ss_qdd)
        return np.array(self.mbs.systemData.GetODE2Coordinates_tt())

    def _armature_qdd(self, qe, y, tau_e):
        """qdd with the model's armature from Exudyn's M (``_mass_matrix`` adds the armature)
        and ODE2 right-hand side; a coupled model's restricted to the motions that keep the
        couplings, v = G u (the couplings join 1-DOF joints, whose engine slots are the core's:
        ``eidx`` is the identity here, and a free joint's slots are columns of G of their own,
        so its c term passes through unchanged)."""
        M = self._mass_matrix(qe)
        rhs = self._bias(qe, y)
        if tau_e is not None:
            rhs = rhs + tau_e
        if self.coupled is None:
            return np.linalg.solve(M, rhs)
        _, _, fv, lv, mult, _ = self.model.coupling_index
        free = np.setdiff1d(np.arange(self.model.n_v), fv)
        G = np.zeros((self.model.n_v, free.size))
        G[free, np.arange(free.size)] = 1.0
        for f, ld, mu in zip(fv, lv, mult, strict=True):
            G[f] = mu * G[ld]
        return G @ np.linalg.solve(G.T @ M @ G, G.T @ rhs)

    def _mass_matrix(self, qe):
        self._current(qe, np.zeros(self.model.n_v))
        self.solver.ComputeMassMatrix(self.mbs)
        M = np.array(self.solver.GetSystemMassMatrix())
        return M if self.arm is None else M + np.diag(self.arm)

    def _bias(self, qe, y):
        self._current(qe, y)
        self.solver.ComputeODE2RHS(self.mbs)
        return np.array(self.solver.GetSystemResidual())

    def _sensors_at(self, points) -> list[int]:
        """The SensorKinematicTree (world position) of each (body, point in the body's frame),
        made on first use on the body's last link at the point turned by A^T (one Assemble for
        all the new ones)."""
        from exudyn.itemInterface import SensorKinematicTree

        new = False
        for body, point in points:
            key = (body, tuple(float(x) for x in point))
            if key in self._sensors:
                continue
            A = self.turn_of_body[body]
            local = np.asarray(point, dtype=float) if A is None else A.T @ np.asarray(point,
                                                                                       float)
            self._sensors[key] = self.mbs.AddSensor(SensorKinematicTree(
                objectNumber=self.tree, linkNumber=self.link_of_body[body],
                localPosition=list(map(float, local)),
                outputVariableType=self.lib.OutputVariableType.Position, writeToFile=False))
            new = True
        if new:
            self.mbs.Assemble()
            self._init_rhs = False
        return [self._sensors[(b, tuple(float(x) for x in p))] for b, p in points]

    def _energy(self, qe, y):
        m = self.model
        sensors = self._sensors_at([(k, m.com[k]) for k in range(m.n_bodies)])
        M = self._mass_matrix(qe)
        self._current(qe, y)
        r = np.array([self.mbs.GetSensorValues(s) for s in sensors])
        V = -float(np.sum(m.mass[:, None] * r * m.gravity[None, :]))
        return 0.5 * y @ M @ y, V

    def _position(self, qe, body, point):
        sensor = self._sensors_at([(body, point)])[0]
        self._current(qe, np.zeros(self.model.n_v))
        return np.array(self.mbs.GetSensorValues(sensor))

    # ------------------------------------------------------------------ native stepping
    # One Exudyn solver per run, initialised at sim_reset. A fixed-step method takes each step
    # as SolveSteps's loop body does (InitializeStep, DiscontinuousIteration, FinishStep; bit
    # for bit one continuous SolveSystem, generalized-alpha's algorithmic acceleration and
    # modified Newton's Jacobian carried over, measured); SolveSteps itself would ask for a new
    # Jacobian at every call. An adaptive one runs SolveSteps up to each time asked. The state
    # stepped is kept here and written back before every solve, so that a qdd, bias or position
    # call between steps (which set the system's state) changes nothing.
    def _sim_reset(self, q0, v0, h):
        if self.coupled is not None:
            return self._on_coupled("_sim_reset", q0, v0, h)
        exu, info = self.lib, self.sim_integrator
        sol = _SOLVERS[info.name]
        qe, blocks = self._state(q0, v0)  # a free joint's chart centred at q0
        ye = self._to_engine(v0, blocks)
        rtol, atol = self.sim_settings["rtol"], self.sim_settings["atol"]
        ss = _settings(exu, getattr(exu.DynamicSolverType, sol.solver_type), h or 1.0, 1)
        ti = ss.timeIntegration
        ti.adaptiveStep = False  # a fixed step stays fixed: a failed step fails the run
        first = None
        if sol.kind == "adaptive":
            ti.automaticStepSize = True
            ti.relativeTolerance, ti.absoluteTolerance = rtol, atol
            first = self._starting_step(qe, ye, sol.order, rtol, atol, h)
            ti.initialStepSize = first
        if sol.kind == "implicit":
            ga = ti.generalizedAlpha
            ga.spectralRadius = SPECTRAL_RADIUS
            # TrapezoidalIndex2 is, as exudyn.solver.SolveDynamic sets it, this solver with
            # Newmark's beta = 1/4, gamma = 1/2 and index-2 constraints (none here)
            ga.useNewmark = ga.useIndex2Constraints = sol.solver_type == "TrapezoidalIndex2"
            ga.computeInitialAccelerations = True
            ti.newton.relativeTolerance, ti.newton.absoluteTolerance = NEWTON_RTOL, NEWTON_ATOL
            solver = exu.MainSolverImplicitSecondOrder()
        else:
            solver = exu.MainSolverExplicit()
        self._exu: dict[str, Any] = {
            "solver": solver, "ss": ss, "kind": sol.kind, "n": 0, "t": 0.0, "steps": 0,
            "rejected": 0, "first_step": first, "h_next": first, "restarts": 0,
            "newton": 0, "jacobians": 0}
        self._sim_start(qe, ye)
        self._sim_qv = (q0.copy(), v0.copy())

    def _sim_start(self, qe, ye):
        """Initialise the run's solver at the engine state (qe, ye) (consistent initial
        accelerations for the implicit ones) and keep that state and its chart."""
        ex = self._exu
        # the initial configuration, which InitializeSolver reads, passive elements on
        self._set_state(qe, ye, None, passive=True)
        with _without_sparse_advice():
            ex["solver"].InitializeSolver(self.mbs, ex["ss"])
        self._sim_keep()

    def _sim_keep(self):
        """Keep the solver's current state (coordinates, rates, accelerations) and chart."""
        sd, cur = self.mbs.systemData, self.lib.ConfigurationType.Current
        self._sim_e = tuple(np.array(f(configuration=cur)) for f in (
            sd.GetODE2Coordinates, sd.GetODE2Coordinates_t, sd.GetODE2Coordinates_tt))
        self._sim_hts = [self.hts[link].copy() for _, _, link in self.free_links]

    def _sim_restore(self, t0):
        """Write the kept state and chart back (a call between steps may have changed them),
        as the current state and the step's start at time t0."""
        sd, C = self.mbs.systemData, self.lib.ConfigurationType
        qe, ye, ae = self._sim_e
        self._set_state(qe, ye, None, which="Current", passive=True)
        for cfg in (C.Current, C.StartOfStep):
            sd.SetODE2Coordinates(qe, configuration=cfg)
            sd.SetODE2Coordinates_t(ye, configuration=cfg)
            sd.SetODE2Coordinates_tt(ae, configuration=cfg)
            sd.SetTime(t0, configurationType=cfg)
        changed = False
        for (_, _, link), T in zip(self.free_links, self._sim_hts, strict=True):
            if not np.array_equal(self.hts[link], T):
                self.hts[link], changed = T.copy(), True
        if changed:
            self.mbs.SetObjectParameter(self.tree, "jointHTs", self.hts)

    def _solve_to(self, t0, t1):
        """Advance the run's solver from the kept state at t0 to t1: one step (fixed step, t1 =
        t0 + h) or Exudyn's own steps (adaptive). Raises RuntimeError when the step fails or
        Exudyn's step size control gives up."""
        ex = self._exu
        s, ss, mbs = ex["solver"], ex["ss"], self.mbs
        self._sim_restore(t0)
        s.it.startTime, s.it.endTime = t0, t1
        with _without_sparse_advice() as out:
            if ex["kind"] == "adaptive":
                h_max = self.sim_settings["h"] or (t1 - t0)
                s.it.maxStepSize = h_max
                s.it.initialStepSize = min(ex["h_next"], h_max)
                limited = math.isfinite(self._deadline[1])
                if limited:  # the CPU limit checked before every step (False: stop)
                    mbs.SetPreStepUserFunction(lambda mbs, t: not self._past_deadline())
                try:
                    ok = s.SolveSteps(mbs, ss)
                finally:
                    if limited:
                        mbs.SetPreStepUserFunction(0)
                if limited and self._past_deadline():
                    raise TimeoutError(f"exudyn stopped its advance to t = {t1:.6g} at t = "
                                       f"{s.it.currentTime:.6g}, its CPU-time limit reached")
            else:  # SolveSteps's loop body, one step (the class comment above)
                s.it.currentStepIndex, s.it.currentStepSize = 1, self.sim_settings["h"]
                s.InitializeStep(mbs, ss)
                s.it.lastStepSize = s.it.currentStepSize
                ok = s.DiscontinuousIteration(mbs, ss)
                if ok:
                    s.FinishStep(mbs, ss)
                    s.it.currentStepIndex = 2
        name = self.sim_integrator.name
        if MIN_STEP_WARNING in out.getvalue():
            raise RuntimeError(
                f"exudyn {name}: its step size control reached minimumStepSize "
                f"({ss.timeIntegration.minimumStepSize:g} s) between t = {t0:.9g} and "
                f"{t1:.9g} s and Exudyn accepted the step anyway, its error above the tolerance "
                f"(rtol {self.sim_settings['rtol']:g}, atol {self.sim_settings['atol']:g}; its "
                f"error scale is atol + max(y_old, y_new) rtol, signed)")
        if not ok:
            why = ("Newton did not converge" if ex["kind"] == "implicit" else
                   s.GetErrorString() or "no reason given")
            raise RuntimeError(f"exudyn {name}: the step from t = {t0:.9g} to {t1:.9g} s "
                               f"failed ({why})")
        ex["steps"] += s.it.currentStepIndex - 1
        if ex["kind"] == "adaptive":
            ex["rejected"] = int(s.it.rejectedAutomaticStepSizeSteps)
            ex["h_next"] = float(s.it.currentStepSize)
        self._sim_keep()

    def _sim_recentre(self):
        """Centre each free joint's chart at the state reached (module docstring): the kept
        state in the new chart; False (nothing done) when there is no free joint."""
        if not self.free_links:
            return False
        qe, ye, _ = self._sim_e
        q, v = self._chart_to_core(qe, ye)
        qe, blocks = self._state(q, v)
        ye = self._to_engine(v, blocks)
        ae = np.zeros(self.model.n_v)
        if self.sim_integrator.name == "velocity-verlet":  # it reads qdd at the step's start
            ae = self._qdd(qe, ye, None)
        self._sim_e = (qe, ye, ae)
        self._sim_hts = [self.hts[link].copy() for _, _, link in self.free_links]
        return True

    def _chart_angle(self) -> float:
        """The largest chart angle of any free joint now (0 without one)."""
        qe = self._sim_e[0]
        return max((float(np.abs(qe[vs + 3:vs + 6]).max()) for _, vs, _ in self.free_links),
                   default=0.0)

    def _sim_step(self):
        if self.coupled is not None:
            return self._on_coupled("_sim_step")
        ex = self._exu
        h = self.sim_settings["h"]
        n = ex["n"]
        self._solve_to(n * h, (n + 1) * h)
        ex["n"] = n + 1
        if ex["kind"] == "implicit":
            s = ex["solver"]
            ex["newton_run"] = (int(s.it.newtonStepsCount), int(s.it.newtonJacobiCount))
            if self._chart_angle() > CHART_ANGLE:  # a new chart: a restart, re-initialised
                self._sim_counts_fold()
                self._sim_recentre()
                ex["restarts"] += 1
                self._sim_start(*self._sim_e[:2])
        else:  # one-step methods: the chart centred again after every step, as before
            self._sim_recentre()
        self._sim_qv = None

    def _sim_counts_fold(self):
        """Add the implicit solver's Newton counts so far to the run's (before a restart)."""
        ex = self._exu
        newton, jac = ex.pop("newton_run", (0, 0))
        ex["newton"] += newton
        ex["jacobians"] += jac

    def _sim_advance(self, t):
        if self.coupled is not None:
            return self._on_coupled("_sim_advance", t)
        ex = self._exu
        while ex["t"] < t:
            t1 = t
            if self.free_links:  # stop where a chart has turned CHART_ANGLE at most
                ye = self._sim_e[1]
                w = max(float(np.abs(ye[vs + 3:vs + 6]).max()) for _, vs, _ in self.free_links)
                if w * (t - ex["t"]) > CHART_ANGLE:
                    t1 = ex["t"] + CHART_ANGLE / w
            self._solve_to(ex["t"], t1)
            ex["t"] = t1
            self._sim_recentre()
            self._sim_qv = None

    def _starting_step(self, qe, ye, order, rtol, atol, h_max) -> float:
        """The standard starting step of an error-controlled method whose error estimate is of
        order ``order`` - 1 (Hairer, Norsett & Wanner I, II.4; scipy's select_initial_step),
        with Exudyn's own qdd at the start and after one Euler step."""
        a0 = self._qdd(qe, ye, None)
        y0, f0 = np.concatenate([qe, ye]), np.concatenate([ye, a0])
        scale = atol + np.abs(y0) * rtol

        def rms(x):
            return float(np.sqrt(np.mean((x / scale) ** 2)))

        d0, d1 = rms(y0), rms(f0)
        h0 = 1e-6 if d0 < 1e-5 or d1 < 1e-5 else 0.01 * d0 / d1
        if h_max:
            h0 = min(h0, h_max)
        n = self.model.n_v
        y1 = y0 + h0 * f0
        f1 = np.concatenate([y1[n:], self._qdd(y1[:n], y1[n:], None)])
        d2 = rms(f1 - f0) / h0
        big = max(d1, d2)
        h1 = max(1e-6, h0 * 1e-3) if big <= 1e-15 else (0.01 / big) ** (1.0 / order)
        h = min(100 * h0, h1)
        return float(min(h, h_max) if h_max else h)

    def _sim_counts(self):
        if self.coupled is not None:
            return self._on_coupled("_sim_counts")
        ex = self._exu
        sol = _SOLVERS[self.sim_integrator.name]
        if sol.kind == "implicit":
            return ex["steps"], 0, -1
        starting = 2 if sol.kind == "adaptive" else 0  # the starting step's qdd calls
        return (ex["steps"], ex["rejected"],
                sol.per_step * (ex["steps"] + ex["rejected"]) + starting)

    def _settings(self) -> dict[str, Any]:
        if self.coupled is not None and getattr(self.coupled[0], "_exu", None) is not None:
            return self._on_coupled("_settings")
        out: dict[str, Any] = {
            "linear_solver": "EigenDense", "threads": 1, "constraints": 0,
            "qdd": f"one ExplicitEuler step of {QDD_STEP:g} s, computeEndOfStepAccelerations "
                   "off (module docstring)"}
        if self.arm is not None:
            out["armature"] = "in the qdd only: (M + diag(a)) qdd = tau + RHS (holds_armature)"
        if self.model.has_passive:
            out["passive"] = ("the tree's P/D control (stiffness, damping, spring_ref) and COM "
                              "LoadForceVectors for gravcomp, on during its steps only")
        ex = getattr(self, "_exu", None)
        if ex is None:
            return out
        ss = ex["ss"]
        ti = ss.timeIntegration
        out.update({"threads": int(ss.parallel.numberOfThreads),
                    "linear_solver": str(ss.linearSolver.solverType).split(".")[-1],
                    "solverType": str(ti.solverType).split(".")[-1],
                    "adaptiveStep": bool(ti.adaptiveStep),
                    "constraints": int(ex["solver"].GetAEsize())})
        if ex["kind"] != "implicit":
            e = ti.explicit
            out.update({"useLieGroupIntegration": bool(e.useLieGroupIntegration),
                        "computeEndOfStepAccelerations": bool(e.computeEndOfStepAccelerations)})
        if ex["kind"] == "adaptive":
            out.update({"automaticStepSize": True, "relativeTolerance": ti.relativeTolerance,
                        "absoluteTolerance": ti.absoluteTolerance,
                        "minimumStepSize": ti.minimumStepSize,
                        "stepSizeSafety": ti.stepSizeSafety,
                        "stepSizeMaxIncrease": ti.stepSizeMaxIncrease,
                        "first_step": ex["first_step"],
                        "maxStepSize": self.sim_settings["h"] or "each interval asked",
                        "free_joint_chart": f"centred again after each interval, intervals cut "
                                            f"to turn {CHART_ANGLE} rad at most"})
        if ex["kind"] == "implicit":
            ga, nw = ti.generalizedAlpha, ti.newton
            newton, jac = ex.get("newton_run", (0, 0))
            out.update({"spectralRadius": 1.0 if ga.useNewmark else ga.spectralRadius,
                        "newmarkBeta": ga.newmarkBeta if ga.useNewmark else None,
                        "newmarkGamma": ga.newmarkGamma if ga.useNewmark else None,
                        "useNewmark": bool(ga.useNewmark),
                        "useIndex2Constraints": bool(ga.useIndex2Constraints),
                        "computeInitialAccelerations": bool(ga.computeInitialAccelerations),
                        "newton.relativeTolerance": nw.relativeTolerance,
                        "newton.absoluteTolerance": nw.absoluteTolerance,
                        "newton.maxIterations": int(nw.maxIterations),
                        "newton.useModifiedNewton": bool(nw.useModifiedNewton),
                        "newton.numericalDifferentiation.relativeEpsilon":
                            nw.numericalDifferentiation.relativeEpsilon,
                        "newton_iterations": ex["newton"] + newton,
                        "jacobians": ex["jacobians"] + jac,
                        "free_joint_chart": f"kept while it turns < {CHART_ANGLE} rad, then "
                                            f"centred again and the solver restarted",
                        "restarts": ex["restarts"]})
        elif ex["kind"] == "explicit":
            out["free_joint_chart"] = "centred again after every step"
        return out

    def _sim_state(self):
        if self.coupled is not None:
            return self._on_coupled("_sim_state")
        qe, ye, _ = self._sim_e
        if self.identity:
            return qe.copy(), ye.copy()
        if self._sim_qv is None:  # the kept state in its chart (the chart is the kept one)
            saved = [self.hts[link] for _, _, link in self.free_links]
            for (_, _, link), T in zip(self.free_links, self._sim_hts, strict=True):
                self.hts[link] = T
            try:
                self._sim_qv = self._chart_to_core(qe, ye)
            finally:
                for (_, _, link), T in zip(self.free_links, saved, strict=True):
                    self.hts[link] = T
        return self._sim_qv[0].copy(), self._sim_qv[1].copy()
