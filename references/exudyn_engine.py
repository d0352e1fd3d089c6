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
- Solver settings: ``linearSolver.solverType = EigenDense`` (the default EXUdense was ~17x slower
  and inaccurate at 1,000 links; docs/design.md, "Reference engines"); no solution file, no
  sensors written, verbose off. Above 1,000 coordinates Exudyn prints, at every solve, a
  multi-line advice to consider a sparse solver: it does not apply here (a chain's kinematic tree
  couples every joint, so its mass matrix is dense; EigenSparse measured 0.144 s per qdd at
  1,200 DOF against EigenDense's 0.105 s, 2026-11-23), so that one message is dropped
  (:func:`_without_sparse_advice`); anything else Exudyn prints passes through.

``qdd`` uses Exudyn's own solver (Exudyn has no public qdd call): the state is written as the
initial state, one ``ExplicitEuler`` step of 1e-12 s is taken with
``timeIntegration.explicit.computeEndOfStepAccelerations = False``, and
``GetODE2Coordinates_tt()`` then holds the acceleration at the start of the step, i.e. at the
given state. ``tau`` enters through the tree's ``jointForceVector``.
``mass_matrix`` and ``bias`` are the solver's ``ComputeMassMatrix`` and ``ComputeODE2RHS`` (the
ODE2 right-hand side, which is phi with tau = 0). ``energy``: T = v^T M v / 2 with Exudyn's M,
V = -sum m g . r_C with the COM positions from ``SensorKinematicTree`` (Exudyn has no energy call
for the tree). ``position``: a ``SensorKinematicTree`` on the body's last link at the point
(turned by A^T). ``simulate``: Exudyn's explicit ``RK44`` at the fixed step h, the state written
back as the initial state after every step.

Limit: the tree's mass matrix is dense (O(n^2) memory) and factorised every right-hand side
(O(n^3) time): time stops it first (references/limits.toml).

A free joint, which the tree's 1-DOF joints cannot be, is PrismaticX/Y/Z along the world axes
then RevoluteX/Y/Z in a frame turned by the body's rotation at the state asked (rewritten at
every call, and after every step of ``simulate``): a chart of the rotation centred at the state,
where its rates are exactly the body-frame angular velocity, so it is never near an Euler-angle
singularity; its one correction, dE/dt w, is added to the angular acceleration (class
docstring).
"""

from __future__ import annotations

import contextlib
import io
import re
import sys

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
            yield
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
    The applied force is the core's (E(0)^T = 1). ``simulate`` steps in that chart and centres
    it again at the state reached after every step.
    """

    name = "exudyn"
    package = "exudyn"
    module = "exudyn"
    integrator = "rk44"
    integrators = {"rk44": NativeIntegrator("rk44", False, "DynamicSolverType.RK44")}

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
        mbs.Assemble()
        self._tau_set = False
        self.ss_qdd = _settings(exu, exu.DynamicSolverType.ExplicitEuler, QDD_STEP, 1)
        self.solver = exu.MainSolverExplicit()
        self._init_rhs = False

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

    def _set_state(self, qe, y, tau_e, which="Initial"):
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
        self._set_state(qe, y, tau_e)
        with _without_sparse_advice():
            self.solver.SolveSystem(self.mbs, self.ss_qdd)
        return np.array(self.mbs.systemData.GetODE2Coordinates_tt())

    def _mass_matrix(self, qe):
        self._current(qe, np.zeros(self.model.n_v))
        self.solver.ComputeMassMatrix(self.mbs)
        return np.array(self.solver.GetSystemMassMatrix())

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
    def _sim_reset(self, q0, v0, h):
        self.ss_step = _settings(self.lib, self.lib.DynamicSolverType.RK44, h, 1)
        qe, blocks = self._state(q0, v0)
        self._set_state(qe, self._to_engine(v0, blocks), None)
        self._sim_qv = (q0.copy(), v0.copy())

    def _sim_step(self):
        with _without_sparse_advice():
            self.solver.SolveSystem(self.mbs, self.ss_step)
        sd = self.mbs.systemData
        qe, ye = np.array(sd.GetODE2Coordinates()), np.array(sd.GetODE2Coordinates_t())
        if self.identity:
            self._set_state(qe, ye, None)
            return
        q, v = self._sim_qv = self._chart_to_core(qe, ye)
        qe, blocks = self._state(q, v)  # the chart centred at the state reached
        self._set_state(qe, self._to_engine(v, blocks), None)

    def _sim_state(self):
        if self.identity:
            sd = self.mbs.systemData
            return np.array(sd.GetODE2Coordinates()), np.array(sd.GetODE2Coordinates_t())
        return self._sim_qv[0].copy(), self._sim_qv[1].copy()
