"""Closed loops in every reference engine (``references/loops.py``): each engine builds the loops'
tree with its one adapter (the cuts open) and closes the cut joints with its OWN constraint
(Pinocchio's ``RigidConstraintModel`` + ``constraintDynamics``, MuJoCo's ``connect`` equality,
DART's ``BallJointConstraint``, Exudyn's ``ObjectJointSpherical``); its constrained accelerations
and loop forces are compared with the core's ``ClosedLoops.forward_dynamics``.

Mechanisms: the crank-rocker four-bar of tests/test_loops.py (a "planar" cut), the spatial loop
of four links on U and S joints held at a world point (a "point" cut) and a pinned chain of 20
rods (planar). States: assembled, at rest and moving with a velocity in the loops' null space
(v = N c, N spanning the null space of J from ``loops.evaluate``), with and without joint
torques; the chain also off its equilibrium (a perturbed catenary projected back onto the loop).

Differences: qdd as max|qdd_e - qdd| / max(max|qdd|, max|qdd_tree|), qdd_tree the tree's
acceleration with the loops open (near the chain's equilibrium qdd is the small remainder of
large cancelling terms: the tree's acceleration is the scale the solve works at); forces as
max|lam_e - lam| / max|lam|. One tolerance per engine, for both (measured values with each).
Where an engine cannot answer, its refusal and reason are asserted, and the error it would have
made is measured to show the refusal is needed.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_loops import spatial_loop

import redysim
from redysim import Body, CutJoint, Model, TreeJoint, references
from redysim.algorithms.linkages import four_bar, pinned_chain
from redysim.algorithms.loops import ClosedLoops
from redysim.model.shapes import catenary_angles
from redysim.references import EngineLimitExceeded
from redysim.references.loops import (
    LOOP_ENGINES,
    LoopStateUnsupported,
    inert_moments,
    loop_engine,
)

pytestmark = pytest.mark.engine

# --------------------------------------------------------------------------- tolerances
# Measured 2026-11-24 over every state below, worst qdd / force (README, "Loops"):
# pinocchio: 8.9e-12 / 4.8e-14 (chain off equilibrium, cond(M) = 5.1e5, cond * eps = 1e-10;
# its KKT Cholesky) -> 1e-10.
TOL_PINOCCHIO = 1e-10
# mujoco: 1.7e-3 / 3.3e-4 (chain), 2.7e-5 / 4.4e-5 (four-bar), 1.8e-5 / 1.2e-4 (spatial):
# MuJoCo's constraints are soft, (A + R) f = -(J a0 + Jdot v) with R = 1e-4 diagApprox at its
# hardest impedance (mjMAXIMP = 0.9999): a relative force error ~ R / lambda_min(A) = 4.4e-5,
# 1.2e-4, 3.4e-4 on the three mechanisms, the force errors measured. That this IS the whole
# difference is checked tightly by test_mujoco_is_the_hard_answer_plus_its_regulariser.
TOL_MUJOCO = 5e-3
TOL_MUJOCO_REGULARISED = 1e-7  # MuJoCo vs the core solving (A + R) f: measured 1.4e-8
# dart (v = 0 only): 2.2e-9 / 2.5e-9: its constraint force mixing multiplies the diagonal of
# J M^-1 J^T by 1 + 1e-9, the smallest DART accepts ("is lower than 1e-9. It is set to 1e-9").
TOL_DART = 1e-8
# exudyn: <= 2.4e-12 at rest; moving 3.3e-8 (spatial force), 1.4e-8 (chain qdd): Exudyn
# differentiates the constraint Jacobian numerically for the velocity term d2g/dq2 qd^2
# (relative epsilon 1e-7; test_exudyn_velocity_term_is_a_finite_difference).
TOL_EXUDYN = 1e-7
TOLERANCE = {"pinocchio": TOL_PINOCCHIO, "mujoco": TOL_MUJOCO, "dart": TOL_DART,
             "exudyn": TOL_EXUDYN}
assert set(TOLERANCE) == set(LOOP_ENGINES)


# --------------------------------------------------------------------------- mechanisms
def null_velocity(loops, q, speed, seed) -> np.ndarray:
    """A velocity in the null space of J at q (so J v = 0), max |v| = speed."""
    _, J, _, _ = loops.evaluate(q, np.zeros(loops.model.n_v))
    _, s, Vt = np.linalg.svd(J)
    N = Vt[int(np.sum(s > 1e-12 * s[0])):].T
    v = N @ np.random.default_rng(seed).normal(size=N.shape[1])
    return speed * v / np.abs(v).max()


def _states():
    """mechanism -> (loops, [(label, q, v, tau)])."""
    out = {}
    fb = four_bar(0.3, 0.1, 0.35, 0.3, rp=0.2, gamma=0.4, density=2.0)
    states = []
    for angle in (0.3, 2.0, 4.5):
        q = fb.configuration(angle)
        states.append((f"crank {angle} rest", q, np.zeros(3), None))
        states.append((f"crank {angle} moving", q, null_velocity(fb.loops, q, 4.0, 1), None))
    q = fb.configuration(1.0)
    tau = np.array([0.05, -0.02, 0.03])
    states.append(("crank 1.0 rest, torques", q, np.zeros(3), tau))
    states.append(("crank 1.0 moving, torques", q, null_velocity(fb.loops, q, 4.0, 2), tau))
    out["four-bar"] = (fb.loops, states)

    loops, q0 = spatial_loop()
    tau = np.random.default_rng(3).normal(scale=0.5, size=10)
    out["spatial U/S"] = (loops, [
        ("rest", q0, np.zeros(10), None),
        ("moving", q0, null_velocity(loops, q0, 2.0, 4), None),
        ("rest, torques", q0, np.zeros(10), tau),
        ("moving, torques", q0, null_velocity(loops, q0, 2.0, 5), tau)])

    chain = pinned_chain(20, 0.1, 0.1, 1.6)
    q = catenary_angles(20, 2.0, 1.6)
    off = chain.loops.project(q + 0.05 * np.sin(np.arange(20)), np.zeros(20))[0]
    tau = 0.01 * np.cos(np.arange(20))
    out["pinned chain 20"] = (chain.loops, [
        ("catenary rest", q, np.zeros(20), None),
        ("catenary moving", q, null_velocity(chain.loops, q, 2.0, 6), None),
        ("off equilibrium rest, torques", off, np.zeros(20), tau),
        ("off equilibrium moving", off, null_velocity(chain.loops, off, 2.0, 7), None)])
    return out


STATES = _states()
CASES = [(mech, i) for mech, (_, states) in STATES.items() for i in range(len(states))]
_ENGINES: dict = {}


def _engine(name, mech):
    cls = LOOP_ENGINES[name]
    pytest.importorskip(cls.module, reason=f"engine {name!r} needs {cls.package!r}")
    key = (name, mech)
    if key not in _ENGINES:
        loops = STATES[mech][0]
        assert cls.limits(loops).ok, cls.limits(loops).reason
        _ENGINES[key] = loop_engine(name, loops)
    return _ENGINES[key]


def differences(loops, qdd, lam, q, v, tau) -> tuple[float, float]:
    """(qdd difference, force difference) from the core's (module docstring)."""
    qdd_c, lam_c = loops.forward_dynamics_and_forces(q, v, tau)
    qdd_tree = redysim.forward_dynamics(loops.tree, q, v, tau)
    scale = max(np.abs(qdd_c).max(), np.abs(qdd_tree).max())
    return (float(np.abs(qdd - qdd_c).max() / scale),
            float(np.abs(lam - lam_c).max() / np.abs(lam_c).max()))


def test_the_states_are_assembled():
    for mech, (loops, states) in STATES.items():
        for label, q, v, _ in states:
            assert max(loops.residuals(q, v)) < 1e-13, (mech, label)


# --------------------------------------------------------------------------- the comparison
@pytest.mark.parametrize("name", list(LOOP_ENGINES))
@pytest.mark.parametrize("mech, i", CASES, ids=[f"{m}-{STATES[m][1][i][0]}" for m, i in CASES])
def test_engine_matches_the_core(name, mech, i):
    """Each engine's constrained qdd and loop forces against the core's, at one state; where
    the engine refuses the state, the refusal and its reason."""
    eng = _engine(name, mech)
    loops = STATES[mech][0]
    label, q, v, tau = STATES[mech][1][i]
    why = eng.refusal(q, v)
    if why:
        assert name == "dart" and np.any(v != 0), why  # the only refusal expected here
        assert "Jdot v" in why
        with pytest.raises(LoopStateUnsupported, match="velocity impulse"):
            eng.forward_dynamics(q, v, tau)
        return
    qdd, lam = eng.forward_dynamics_and_forces(q, v, tau)
    assert qdd.shape == (loops.model.n_v,) and lam.shape == (loops.m,)
    dq, df = differences(loops, qdd, lam, q, v, tau)
    assert dq < TOLERANCE[name] and df < TOLERANCE[name], (mech, label, dq, df)


@pytest.mark.parametrize("name", list(LOOP_ENGINES))
def test_answers_are_new_arrays(name):
    """(qdd, lam) belong to the caller: a later call leaves them as they were (the adapters
    answer from the engines' own buffers, MuJoCo's ``qacc`` say, which the next call
    overwrites)."""
    eng = _engine(name, "four-bar")
    states = STATES["four-bar"][1]
    _, q, v, tau = states[0]  # crank 0.3 at rest: every engine answers
    qdd, lam = eng.forward_dynamics_and_forces(q, v, tau)
    before = qdd.copy(), lam.copy()
    _, q, v, tau = states[2]  # crank 2.0 at rest
    eng.forward_dynamics(q, v, tau)
    assert np.array_equal(qdd, before[0]) and np.array_equal(lam, before[1])


def test_dart_refusal_is_needed():
    """DART's one-step answer at v != 0 is the hard answer WITHOUT the velocity term: J qdd = 0
    instead of J qdd = -Jdot v. Measured on the moving states: it equals that answer to ~1e-9
    and misses the core's by 1e-4 (four-bar) to ~7 (the chain), far outside any tolerance."""
    pytest.importorskip("dartpy")
    worst = 0.0
    for mech, (loops, states) in STATES.items():
        eng = _engine("dart", mech)
        for label, q, v, tau in states:
            if not np.any(v != 0):
                continue
            qdd, _ = eng._solve(q, v, tau)  # bypassing the refusal, to measure
            _, J, _, Jdv = loops.evaluate(q, v)
            qdd_tree = redysim.forward_dynamics(loops.tree, q, v, tau)
            X = np.linalg.solve(redysim.mass_matrix(loops.model, q), J.T)
            without = qdd_tree + X @ np.linalg.solve(J @ X, -J @ qdd_tree)  # Jdot v left out
            scale = np.abs(qdd_tree).max()
            assert np.abs(qdd - without).max() / scale < TOL_DART, (mech, label)
            qdd_c, _ = loops.forward_dynamics_and_forces(q, v, tau)
            worst = max(worst, float(np.abs(qdd - qdd_c).max() / scale))
    assert worst > 1e3 * TOL_DART


# --------------------------------------------------------------------------- trajectories
# Passive motion for 0.5 s with each engine's own integrator and its own handling of the loops,
# against the core's (ode45 at rtol 1e-11, projected onto the loops), max |q - q_core| [rad]
# over the samples every 0.1 s. Measured 2026-11-24 at h = 1e-3 / 1e-4 s, four-bar from rest at
# crank 0.3 and the spatial loop moving:
# mujoco (RK4):          2.6e-5 / 2.6e-5 and 1.7e-5 / 1.7e-5: its soft constraint's, not h's
# dart (semi-implicit Euler + impulses): 2.3e-2 / 1.1e-3 and 8.7e-3 / 6.3e-4: first order
# exudyn (GeneralizedAlpha, index 3):    1.5e-4 / 1.5e-6 and 1.5e-4 / 1.5e-6: second order
TRAJECTORY = {"mujoco": 1e-4, "dart": 5e-3, "exudyn": 1e-5}  # at h = 1e-4
ORDER = {"mujoco": None, "dart": 1, "exudyn": 2}
RUNS = {"four-bar": 0, "spatial U/S": 1}  # mechanism -> state


@pytest.fixture(scope="module")
def core_runs():
    out = {}
    for mech, i in RUNS.items():
        loops, states = STATES[mech]
        _, q0, v0, _ = states[i]
        sim = redysim.simulate(loops.model, 0.5, q0=q0, v0=v0, loops=loops, rtol=1e-11,
                               atol=1e-13, sample=0.1)
        assert sim.status == 0, sim.message
        out[mech] = (q0, v0, sim)
    return out


@pytest.mark.parametrize("name", list(TRAJECTORY))
@pytest.mark.parametrize("mech", list(RUNS))
def test_trajectories_follow_the_core(name, mech, core_runs):
    """At h = 1e-4 each engine's trajectory is within its tolerance of the core's; from h = 1e-3
    the error falls as the integrator's order says (DART x >= 5, Exudyn x >= 50), and MuJoCo's
    does not fall (its soft constraint, not its RK4, sets it)."""
    eng = _engine(name, mech)
    q0, v0, sim = core_runs[mech]
    err = {}
    for h in (1e-3, 1e-4):
        tr = eng.simulate(q0, v0, 0.5, h, every=int(round(0.1 / h)))
        assert np.allclose(tr.t, sim.t, rtol=0, atol=1e-12) and tr.integrator
        err[h] = float(np.abs(tr.q - sim.q).max())
    assert err[1e-4] < TRAJECTORY[name], (mech, err)
    if ORDER[name] is None:
        assert 0.5 < err[1e-3] / err[1e-4] < 2
    else:
        assert err[1e-3] / err[1e-4] > 10 ** ORDER[name] / 2


def test_pinocchio_has_no_integrator():
    pytest.importorskip("pinocchio")
    _, q, v, _ = STATES["four-bar"][1][0]
    with pytest.raises(LoopStateUnsupported, match="no time integrator"):
        _engine("pinocchio", "four-bar").simulate(q, v, 0.1, 1e-3)


# --------------------------------------------------------------------------- MuJoCo
def test_mujoco_is_the_hard_answer_plus_its_regulariser():
    """MuJoCo's soft constraint solves (A + R) f = -(J a0 + Jdot v) with its own regulariser R
    (``efc_R``); the core's A = J M^-1 J^T and a0 with MuJoCo's R reproduce MuJoCo's qdd and
    forces to TOL_MUJOCO_REGULARISED: the model, the cuts and the velocity term are MuJoCo's
    as the core's, and the only difference from the hard answer is the documented softness."""
    pytest.importorskip("mujoco")
    worst = 0.0
    for mech, (loops, states) in STATES.items():
        eng = _engine("mujoco", mech)
        for label, q, v, tau in states:
            qdd, lam = eng.forward_dynamics_and_forces(q, v, tau)
            R = eng.regularisation(q, v)
            assert np.all(R > 0)
            _, J, _, Jdv = loops.evaluate(q, v)
            qdd_tree = redysim.forward_dynamics(loops.tree, q, v, tau)
            X = np.linalg.solve(redysim.mass_matrix(loops.model, q), J.T)
            f = np.linalg.solve(J @ X + np.diag(R), -(J @ qdd_tree + Jdv))
            soft = qdd_tree + X @ f
            dq = np.abs(qdd - soft).max() / np.abs(qdd_tree).max()
            df = np.abs(lam - f).max() / np.abs(f).max()
            worst = max(worst, dq, df)
            assert dq < TOL_MUJOCO_REGULARISED and df < TOL_MUJOCO_REGULARISED, (mech, label)
    print(f"mujoco vs the core + MuJoCo's R: worst {worst:.2g}")


# --------------------------------------------------------------------------- Pinocchio
def test_pinocchio_needs_the_proximal_iterations_for_a_planar_cut():
    """A planar cut is a 3-D contact whose z row is zero: with mu = 0 Pinocchio's KKT Cholesky
    gives NaN; the adapter's mu = 1e-8 converges, in a few iterations, to the core's answer."""
    pin = pytest.importorskip("pinocchio")
    eng = _engine("pinocchio", "four-bar")
    _, q, v, tau = STATES["four-bar"][1][1]
    t = eng.tree
    qp, _ = t._state(q, v)
    qdd = pin.constraintDynamics(t.pm, t.data, qp, t._to_engine(v, []), np.zeros(3),
                                 eng.cmodels, eng.cdatas, pin.ProximalSettings(1e-13, 0.0, 1))
    assert np.isnan(qdd).all()
    eng.forward_dynamics(q, v)
    assert 1 < eng.settings.iter < eng.MAX_ITER


# --------------------------------------------------------------------------- Exudyn
def test_exudyn_velocity_term_is_a_finite_difference():
    """At v != 0 Exudyn's error is that of a one-sided difference quotient in its relative
    epsilon (``newton.numericalDifferentiation.relativeEpsilon``, default 1e-7): with a larger
    epsilon it grows in proportion to it (x10 from 1e-5 to 1e-4) and with the square of the
    velocity (x4 for 2 v), as a forward-difference d2g/dq2 qd^2 does; at rest it is at rounding
    level. Measured on the four-bar: 1e-5 at epsilon 1e-4, 1e-6 at 1e-5, 8e-9 at 1e-7, then
    rounding takes over (8e-8 at 1e-10)."""
    pytest.importorskip("exudyn")
    loops, states = STATES["four-bar"]
    eng = _engine("exudyn", "four-bar")
    _, q, v, _ = states[3]  # crank 2.0 moving
    nd = eng.settings.timeIntegration.newton.numericalDifferentiation
    assert nd.relativeEpsilon == 1e-7

    def error(eps, v):
        nd.relativeEpsilon = eps
        try:
            return differences(loops, *eng.forward_dynamics_and_forces(q, v), q, v, None)[0]
        finally:
            nd.relativeEpsilon = 1e-7

    e4, e5 = error(1e-4, v), error(1e-5, v)
    assert 8 < e4 / e5 < 12
    assert 3.5 < error(1e-5, 2 * v) / e5 < 4.5
    assert error(1e-7, v) < 0.1 * e5
    assert error(1e-7, 0 * v) < 1e-13


def test_exudyn_explicit_solver_cannot_close_a_loop():
    """Why the implicit solver: the explicit one (the engine adapter's qdd) aborts on the
    loop."""
    exu = pytest.importorskip("exudyn")
    from redysim.references.exudyn_engine import _settings

    _, q, v, _ = STATES["four-bar"][1][0]
    t = _engine("exudyn", "four-bar").tree
    t._set_state(q, v, None)
    with pytest.raises(Exception, match="constraints that cannot be solved"):
        exu.MainSolverExplicit().SolveSystem(
            t.mbs, _settings(exu, exu.DynamicSolverType.ExplicitEuler, 1e-12, 1))


# --------------------------------------------------------------------------- thin bodies
def test_inert_moments_do_not_change_the_dynamics():
    """The bars' zero axial moment, raised for MuJoCo and DART, is about an axis the planar
    mechanism never turns about: the tree's GIM and qdd are unchanged (DART builds both)."""
    pytest.importorskip("dartpy")
    dart = references.get("dart")
    for mech in ("four-bar", "pinned chain 20"):
        loops, states = STATES[mech]
        model, changed, why = inert_moments(loops.model)
        assert changed == list(range(model.n_bodies)) and not why
        a, b = dart(loops.model), dart(model)
        for _, q, v, tau in states:
            assert np.array_equal(a.mass_matrix(q), b.mass_matrix(q))
            assert np.abs(a.qdd(q, v, tau) - b.qdd(q, v, tau)).max() < 1e-15 * \
                np.abs(a.qdd(q, v, tau)).max() + 1e-300
    # the spatial loop has no zero moment: nothing to raise
    assert inert_moments(STATES["spatial U/S"][0].model)[1] == []


def test_a_thin_body_that_could_spin_is_refused_by_mujoco():
    """A slender bar on a U joint turns about two axes: its zero moment can enter the dynamics,
    so nothing is raised and MuJoCo's refusal stands, with the reason."""
    bars = [Body(name, 1.0, (0.5, 0, 0), ((0, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
            for name in ("bar", "bar2")]  # (names are unique: Model.build)
    model = Model.build(bars, [TreeJoint("a", "U"),
                                     TreeJoint("b", "R", "z", translation=(1.0, 0, 0))],
                        [-1, 0], gravity=(0.0, -9.81, 0.0))
    loops = ClosedLoops(model, [CutJoint("pin", 1, (1, 0, 0), -1, (1.5, 0, 0))])
    assert "non-parallel" in inert_moments(model)[2]
    lim = LOOP_ENGINES["mujoco"].limits(loops)
    assert not lim.ok and "mjMINVAL" in lim.reason and "non-parallel" in lim.reason
    if LOOP_ENGINES["mujoco"].available():
        with pytest.raises(EngineLimitExceeded, match="mjMINVAL"):
            loop_engine("mujoco", loops)


# --------------------------------------------------------------------------- planar cuts
def test_a_planar_cut_on_a_spatial_mechanism():
    """A "planar" cut leaves world z free. On the spatial loop (whose tip moves in z) the
    engines that can only build it as a ball joint refuse it, naming the cut; Exudyn builds it
    (constrainedAxes = [1, 1, 0]) and agrees with the core."""
    loops, states = STATES["spatial U/S"]
    (cut,) = loops.cuts
    planar = ClosedLoops(loops.model, [dataclasses.replace(cut, kind="planar")])
    for name in ("pinocchio", "mujoco", "dart"):
        lim = LOOP_ENGINES[name].limits(planar)
        assert not lim.ok and "'ball'" in lim.reason and "world z" in lim.reason, lim.reason
    pytest.importorskip("exudyn")
    eng = loop_engine("exudyn", planar)
    for _, q, v, tau in states:
        dq, df = differences(planar, *eng.forward_dynamics_and_forces(q, v, tau), q, v, tau)
        assert dq < TOL_EXUDYN and df < TOL_EXUDYN


def test_a_planar_cut_whose_points_are_apart_in_z_is_refused():
    """On the four-bar the z equation is constant; with the cut's points 1 mm apart in z a ball
    joint would pull them together, so the ball-only engines refuse that state."""
    loops, states = STATES["four-bar"]
    (cut,) = loops.cuts
    apart = ClosedLoops(loops.model, [dataclasses.replace(cut, point_b=(0.3, 0.0, 1e-3))])
    _, q, v, _ = states[0]
    for name in ("pinocchio", "mujoco", "dart"):
        cls = LOOP_ENGINES[name]
        if not cls.available():
            continue
        assert cls.limits(apart).ok
        with pytest.raises(LoopStateUnsupported, match="apart in world z"):
            loop_engine(name, apart).forward_dynamics(q, v)


# --------------------------------------------------------------------------- meaningful
@pytest.mark.parametrize("name", ["pinocchio", "dart", "exudyn"])
def test_a_wrong_model_is_caught(name):
    """The engines held to tight tolerances see a link 1e-5 heavier on the four-bar."""
    cls = LOOP_ENGINES[name]
    pytest.importorskip(cls.module)
    loops, states = STATES["four-bar"]
    heavier = np.array(loops.model.mass, dtype=float)
    heavier[1] *= 1 + 1e-5
    wrong = ClosedLoops(dataclasses.replace(loops.model, mass=heavier), loops.cuts)
    eng = loop_engine(name, wrong)
    _, q, v, tau = states[0]
    assert max(differences(loops, *eng.forward_dynamics_and_forces(q, v, tau), q, v, tau)) > \
        TOLERANCE[name]


# --------------------------------------------------------------------------- Menagerie 2F-85
MENAGERIE_2F85 = (__import__("pathlib").Path(__file__).parent / "models" / "menagerie"
                  / "robotiq_2f85" / "2f85.xml")


def robotiq():
    """Menagerie's Robotiq 2F-85 (issue 56): two 'plane' cuts (a connect of a mechanism moving
    in the plane normal to the fingers' axes, world y), a coupling of the two drivers, armature
    on every joint, as the scenario reads it (its assembled configuration)."""
    from redysim.io.scenarios import load_scenario

    scn = load_scenario(str(MENAGERIE_2F85), options={})
    m = scn.model
    assert [c.kind for c in m.cuts] == ["plane", "plane"] and m.couplings
    return m, scn.q0


def test_the_2f85s_plane_cuts_are_balls_in_the_ball_engines():
    """A plane cut whose normal every joint on its bodies' paths turns about leaves that normal
    equation void, so Pinocchio, MuJoCo and DART hold it as a ball (non_planar generalised):
    their qdd and the loop forces (projected on the plane's axes) are the core's, on the
    gripper without its coupling and armature (which those adapters do not all hold)."""
    m, q0 = robotiq()
    bare = ClosedLoops(dataclasses.replace(m, couplings=()).with_armature(None))
    rng = np.random.default_rng(20261207)
    q0 = bare.project(q0, np.zeros(m.n_v))[0]
    for name in ("pinocchio", "mujoco", "dart"):
        cls = LOOP_ENGINES[name]
        if not cls.available():
            continue
        assert cls.limits(bare).ok, cls.limits(bare).reason
        eng = loop_engine(name, bare)
        for _ in range(2):
            q = bare.project(q0 + 0.05 * rng.normal(size=m.n_q), np.zeros(m.n_v))[0]
            v = (np.zeros(m.n_v) if name == "dart"  # (DART takes v = 0 only)
                 else bare.project(q, rng.normal(size=m.n_v))[1])
            tau = 0.01 * rng.normal(size=m.n_v)
            assert max(differences(bare, *eng.forward_dynamics_and_forces(q, v, tau), q, v,
                                   tau)) < TOLERANCE[name], name
    # a plane cut's points apart along its normal: the ball would close that gap
    normal = np.asarray(bare.cuts[0].rot_b, dtype=float)[:, 2]  # in body b's frame
    cut = dataclasses.replace(bare.cuts[0], point_b=tuple(np.add(bare.cuts[0].point_b,
                                                                 1e-3 * normal)))
    apart = ClosedLoops(bare.model, [cut, bare.cuts[1]])
    if LOOP_ENGINES["pinocchio"].available():
        with pytest.raises(LoopStateUnsupported, match="along its plane's normal"):
            loop_engine("pinocchio", apart).forward_dynamics(q0, np.zeros(m.n_v))


def test_the_coupled_2f85_runs_in_three_loop_engines_and_is_refused_by_name_in_exudyn():
    """The whole gripper: Pinocchio by its KKT forward dynamics (its constraintDynamics refuses
    mimic joints) on the cuts' rows and the coupling's, its M holding the armature; DART by the
    adapter's KKT solve on its own M (with the armature), bias and point Jacobians, at moving
    states too; MuJoCo closes its loops with its connects and couples the drivers with its own
    joint equality (soft, so within TOL_MUJOCO of the core); Exudyn's loop adapter does not
    build couplings and says so, never answering for the uncoupled gripper."""
    m, q0 = robotiq()
    loops = ClosedLoops(m)
    rng = np.random.default_rng(20261208)
    q = loops.project(q0, np.zeros(m.n_v))[0]
    states = []
    for _ in range(3):
        qs = loops.project(m.couple(q + 0.05 * rng.normal(size=m.n_q)), np.zeros(m.n_v))[0]
        states.append((*loops.project(*m.couple(qs, rng.normal(size=m.n_v)))[:2],
                       0.01 * rng.normal(size=m.n_v)))
    for name, cls in LOOP_ENGINES.items():
        if not cls.available():
            continue
        lim = cls.limits(loops)
        if name == "exudyn":
            assert not lim.ok and "couples joints" in lim.reason, lim.reason
            continue
        assert lim.ok, lim.reason
        eng = loop_engine(name, loops)
        for q, v, tau in states:
            qdd, lam = eng.forward_dynamics_and_forces(q, v, tau)
            assert max(differences(loops, qdd, lam, q, v, tau)) < TOLERANCE[name], name
            _, _, fv, lv, mult, _ = m.coupling_index
            assert np.allclose(qdd[fv], mult * qdd[lv], rtol=TOL_MUJOCO if name == "mujoco"
                               else 1e-12, atol=0.0)


def test_compare_takes_the_coupled_2f85s_loops():
    """`redysim compare`'s loop agreement on the coupled gripper: its random velocities are
    coupled before they are projected on the loops (they were not: a StateError stopped the
    page), Pinocchio's, MuJoCo's and DART's loops answer, and Exudyn's refusal is named."""
    from redysim.reports.compare import loop_agreement

    m, q0 = robotiq()
    rows = {r["engine"]: r for r in loop_agreement("2f85", m, q0)}
    for name in ("pinocchio", "mujoco", "dart"):
        if LOOP_ENGINES[name].available():
            assert rows[f"{name} (loops)"]["status"] == "ok"
            assert rows[f"{name} (loops)"]["qdd"] < TOLERANCE[name]
    for name in ("exudyn",):
        if LOOP_ENGINES[name].available():
            r = rows[f"{name} (loops)"]
            assert r["status"] == "refused" and "couples joints" in r["reason"], r
