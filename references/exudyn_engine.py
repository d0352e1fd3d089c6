"""Exudyn adapter: one ``ObjectKinematicTree`` (minimal coordinates) on a ``NodeGenericODE2``.

What the model contains and why (DESIGN.md section 6):

- ``ObjectKinematicTree`` has only 1-DOF joints, so a U joint is two tree links: a massless
  ``RevoluteY`` link (zero mass and inertia) at the joint's offset, then a ``RevoluteZ`` link at
  zero offset carrying the link's mass, COM and inertia about the COM; an R joint is one
  ``RevoluteZ`` link. ``jointHTs`` translate l_{k-1} along the parent's x; ``linkParents`` is the
  chain (-1 = ground). ``gravity = chain.gravity`` (the tree's own gravity parameter).
- No markers, loads, connectors, contacts or graphics; visualisation off (``show=False``); no
  joint P/D control, force vectors or user functions (all empty/zero by default).
- Solver settings: ``linearSolver.solverType = EigenDense`` (the default EXUdense was ~17x slower
  and inaccurate at 1,000 links, DESIGN.md section 6); no solution file, no sensors written,
  verbose off.

``qdd`` uses Exudyn's own solver (DESIGN.md section 6's trick): the state is written as the
initial state, one ``ExplicitEuler`` step of 1e-12 s is taken with
``timeIntegration.explicit.computeEndOfStepAccelerations = False``, and
``GetODE2Coordinates_tt()`` then holds the acceleration at the start of the step, i.e. at the
given state. ``tau`` enters through the tree's ``jointForceVector``.
``mass_matrix`` and ``bias`` are the solver's ``ComputeMassMatrix`` and ``ComputeODE2RHS`` (the
ODE2 right-hand side, which is phi with tau = 0). ``energy``: T = qd^T M qd / 2 with Exudyn's M,
V = sum m g y_C with the COM positions from ``SensorKinematicTree`` (Exudyn has no energy call
for the tree). ``tip``: a ``SensorKinematicTree`` on the last link at (l, 0, 0).
``simulate``: Exudyn's explicit ``RK44`` at the fixed step h.

Limit: the tree's mass matrix is dense (O(n^2) memory) and factorised every right-hand side
(O(n^3) time): time stops it first (references/limits.toml).
"""

from __future__ import annotations

import numpy as np

from .base import Engine

QDD_STEP = 1e-12  # length of the single explicit Euler step whose start-acceleration is qdd


def _ht(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


class Exudyn(Engine):
    """Exudyn ObjectKinematicTree with its own explicit solver and EigenDense (module doc)."""

    name = "exudyn"
    package = "exudyn"
    module = "exudyn"
    integrator = "Exudyn explicit RK44, fixed step"

    def _build(self):
        exu = self.lib
        from exudyn.itemInterface import NodeGenericODE2, ObjectKinematicTree, VObjectKinematicTree
        c = self.chain
        types, hts, inertias, coms, masses, tree_of_link = [], [], [], [], [], []
        for k, kind in enumerate(self.kinds):
            off = [c.length[k - 1], 0.0, 0.0] if k > 0 else [0.0, 0.0, 0.0]
            if kind == "U":
                types.append(exu.JointType.RevoluteY)
                hts.append(_ht(off))
                inertias.append(np.zeros((3, 3)))
                coms.append([0.0, 0.0, 0.0])
                masses.append(0.0)
                off = [0.0, 0.0, 0.0]
            types.append(exu.JointType.RevoluteZ)
            hts.append(_ht(off))
            inertias.append(np.array(c.inertia_com[k]))
            coms.append([float(x) for x in c.com[k]])
            masses.append(float(c.mass[k]))
            tree_of_link.append(len(types) - 1)
        n = len(types)
        self.SC = exu.SystemContainer()
        mbs = self.SC.AddSystem()
        self.node = mbs.AddNode(NodeGenericODE2(referenceCoordinates=[0.0] * n,
                                                initialCoordinates=[0.0] * n,
                                                initialCoordinates_t=[0.0] * n,
                                                numberOfODE2Coordinates=n))
        self.tree = mbs.AddObject(ObjectKinematicTree(
            nodeNumber=self.node, jointTypes=types, linkParents=list(range(-1, n - 1)),
            jointHTs=hts, linkInertiasCOM=exu.Matrix3DList(inertias),
            linkCOMs=exu.Vector3DList(coms), linkMasses=masses,
            gravity=[float(g) for g in c.gravity], jointForceVector=[0.0] * n,
            visualization=VObjectKinematicTree(show=False)))
        self.tree_of_link = tree_of_link
        self.mbs = mbs
        self._tip_sensor = None
        self._com_sensors = None
        mbs.Assemble()
        if n != c.n_dof:
            raise AssertionError(f"tree has {n} coordinates, chain {c.n_dof}")
        self._tau_set = False
        # one-step settings for qdd
        self.ss_qdd = self._settings(exu.DynamicSolverType.ExplicitEuler, QDD_STEP, 1)
        self.solver = exu.MainSolverExplicit()
        self._init_rhs = False

    def _settings(self, solver_type, t_end, steps):
        exu = self.lib
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

    def _set_state(self, q, qd, tau, which="Initial"):
        cfg = getattr(self.lib.ConfigurationType, which)
        sd = self.mbs.systemData
        sd.SetODE2Coordinates(q, configuration=cfg)
        sd.SetODE2Coordinates_t(qd, configuration=cfg)
        if tau is not None or self._tau_set:
            f = np.zeros(self.chain.n_dof) if tau is None else tau
            self.mbs.SetObjectParameter(self.tree, "jointForceVector", list(map(float, f)))
            self._tau_set = tau is not None

    def _qdd(self, q, qd, tau):
        self._set_state(q, qd, tau)
        self.solver.SolveSystem(self.mbs, self.ss_qdd)
        return np.array(self.mbs.systemData.GetODE2Coordinates_tt())

    def _current(self, q, qd):
        if not self._init_rhs:
            self.solver.InitializeSolver(self.mbs, self.ss_qdd)
            self._init_rhs = True
        self._set_state(q, qd, None, which="Current")

    def _mass_matrix(self, q):
        self._current(q, np.zeros_like(q))
        self.solver.ComputeMassMatrix(self.mbs)
        return np.array(self.solver.GetSystemMassMatrix())

    def _bias(self, q, qd):
        self._current(q, qd)
        self.solver.ComputeODE2RHS(self.mbs)
        return np.array(self.solver.GetSystemResidual())

    def _sensor(self, link, point):
        from exudyn.itemInterface import SensorKinematicTree
        return self.mbs.AddSensor(SensorKinematicTree(
            objectNumber=self.tree, linkNumber=link, localPosition=list(map(float, point)),
            outputVariableType=self.lib.OutputVariableType.Position, writeToFile=False))

    def _positions(self, sensors):
        return np.array([self.mbs.GetSensorValues(s) for s in sensors])

    def _energy(self, q, qd):
        c = self.chain
        if self._com_sensors is None:
            self._com_sensors = [self._sensor(self.tree_of_link[k], c.com[k])
                                 for k in range(c.n_links)]
            self.mbs.Assemble()
            self._init_rhs = False
        M = self._mass_matrix(q)
        self._current(q, qd)
        y = self._positions(self._com_sensors)
        V = -float(np.sum(c.mass[:, None] * y * c.gravity[None, :]))
        return 0.5 * qd @ M @ qd, V

    def _tip(self, q, qd):
        if self._tip_sensor is None:
            self._tip_sensor = self._sensor(self.tree_of_link[-1],
                                            [self.chain.length[-1], 0.0, 0.0])
            self.mbs.Assemble()
            self._init_rhs = False
        self._current(q, qd)
        return self._positions([self._tip_sensor])[0]

    def _sim_reset(self, q0, qd0, h):
        self.ss_step = self._settings(self.lib.DynamicSolverType.RK44, h, 1)
        self._set_state(q0, qd0, None)

    def _sim_step(self):
        self.solver.SolveSystem(self.mbs, self.ss_step)
        sd = self.mbs.systemData
        self._set_state(np.array(sd.GetODE2Coordinates()), np.array(sd.GetODE2Coordinates_t()),
                        None)

    def _sim_state(self):
        sd = self.mbs.systemData
        return np.array(sd.GetODE2Coordinates()), np.array(sd.GetODE2Coordinates_t())
