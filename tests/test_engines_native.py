"""Every reference engine's own time integrators (``Engine.integrators``; issue 31, item 3).

For every (engine, native integrator), on a 3-link pendulum chain (R joints about z, uniform
rods, gravity -y) and on a tumbling free box (asymmetric inertia, off-centre COM, gravity -z;
every engine with an integrator has a free joint), from seeded states, against the core's
motion (``redysim.simulate``, dop853, rtol = atol = 1e-12):

- fixed step: the observed order p = log2(err(h) / err(h/2)) at the steps of ``STEPS`` is the
  method's order within ``ORDER_MARGIN`` (measured, 0.4 s: below);
- adaptive: the error at rtol 1e-8 is at least 100x below the one at rtol 1e-4 and below 1e-6,
  and the engine's step count grows;
- ``sim_counts`` and ``manifest`` (version, integrator, h or rtol/atol, the flags a fair
  comparison needs) are there and say what ran;
- an unknown integrator, tolerances for a fixed-step one, a fixed-step one without h and an
  adaptive one without rtol raise ValueError naming them; Pinocchio, which has no integrator,
  is refused naming the way to run it;
- ``Simulator(..., integrator=eng.stepper("NAME", ...))`` runs end to end, fixed-step
  (``native:implicitfast``) and adaptive (``native:dopri5``), giving the engine's own run;
- what each module's docstring claims about its engine (MuJoCo: implicitfast is euler here and
  implicit on a free body, a blow-up is NaN not a reset; Exudyn: fixed steps are one continuous
  solve, a qdd call between steps changes nothing, a step accepted at minimumStepSize raises).

Measured observed orders (2026-11-27, T = 0.4 s, at the steps used here; chain / box): mujoco
euler 0.99 / 1.00, implicitfast 0.99 / 1.00, implicit 0.96 / 1.00, rk4 4.10 / 4.02; dart
semi-implicit-euler 0.99 / 1.00; exudyn explicit-euler 0.98 / 1.01, explicit-midpoint
2.03 / 2.00, rk33 2.92 / 3.00, rk44 4.10 / 4.13, rk67 6.16 / 6.10, velocity-verlet 1.00 / 1.01
(first order: the module docstring of references/exudyn_engine.py), generalized-alpha and
trapezoidal 2.00 / 1.99. Errors at rtol 1e-4 and 1e-8 (chain; box): ode23 1.3e-3, 1.7e-7;
8.8e-4, 1.1e-7. dopri5 2.2e-4, 3.6e-8; 2.1e-4, 3.0e-8.
"""

from __future__ import annotations

import functools
import warnings

import numpy as np
import pytest
from conftest import stable_seed
from engine_chains import engine_or_skip

import redysim
from redysim import references
from redysim.algorithms.rbda import quaternion_matrix
from redysim.errors import SettingsError
from redysim.model.tree import Body, Model, TreeJoint
from redysim.simulation import Simulator, simulator

pytestmark = pytest.mark.engine

T_END = 0.4
# each (engine, integrator) and its order: nominal, but velocity-verlet's, which is first order
# with velocity-dependent forces (Exudyn evaluates the end-of-step qdd at the half-step
# velocity; references/exudyn_engine.py)
ORDER = {("mujoco", "euler"): 1, ("mujoco", "implicitfast"): 1, ("mujoco", "implicit"): 1,
         ("mujoco", "rk4"): 4, ("dart", "semi-implicit-euler"): 1,
         ("exudyn", "explicit-euler"): 1, ("exudyn", "explicit-midpoint"): 2,
         ("exudyn", "rk33"): 3, ("exudyn", "rk44"): 4, ("exudyn", "rk67"): 6,
         ("exudyn", "velocity-verlet"): 1, ("exudyn", "generalized-alpha"): 2,
         ("exudyn", "trapezoidal"): 2}
ADAPTIVE = (("exudyn", "ode23"), ("exudyn", "dopri5"))
# steps n over T_END (and 2n): the error at these is in the asymptotic range and far above the
# reference's (>= 6e-9; rk67 at 320 steps meets the reference to 3e-13); the margin covers the
# measured spread (module docstring)
STEPS = {1: 160, 2: 80, 3: 40, 4: 40, 6: 20}
ORDER_MARGIN = {1: 0.15, 2: 0.15, 3: 0.2, 4: 0.3, 6: 0.5}
MODELS = ("chain", "box")
WITH_INTEGRATORS = [n for n, c in references.ENGINES.items() if c.integrators]


# engines whose integrators are checked in a file of their own (their convergence and defects)
OWN_FILE = {"drake": "tests/test_engines_drake.py"}


def test_the_tables_cover_every_native_integrator():
    """A new integrator in an adapter must get its order (or its adaptive check) here, or in
    its engine's own test file (OWN_FILE, whose table must then name it)."""
    registered = {(n, i) for n in WITH_INTEGRATORS if n not in OWN_FILE
                  for i in references.get(n).integrators}
    assert registered == set(ORDER) | set(ADAPTIVE)
    # Drake's own file checks that its tables name every Drake integrator
    # (test_engines_drake.py::test_the_integrators_are_drakes_own)
    for name, integrator in ORDER:
        assert not references.get(name).integrators[integrator].adaptive
    for name, integrator in ADAPTIVE:
        assert references.get(name).integrators[integrator].adaptive
    for name in WITH_INTEGRATORS:
        cls = references.get(name)
        assert cls.integrator in cls.integrators
        for key, info in cls.integrators.items():
            assert info.name == key and info.what and info.note, (name, key)


# --------------------------------------------------------------------------- the runs
@functools.cache
def model_of(model_id: str):
    """(model, q0, v0, (q, v) of the core at T_END by dop853, rtol = atol = 1e-12)."""
    rng = np.random.default_rng(stable_seed("native-integrators", model_id))
    if model_id == "chain":
        chain = redysim.Chain.uniform(3, "R", length=0.5, mass=1.0, radius=0.02,
                                      inertia="cylinder")
        model = chain
        q0, v0 = rng.uniform(-0.5, 0.5, 3), 0.5 * rng.normal(size=3)
    else:
        inertia = np.diag([0.1, 0.2, 0.3])
        model = Model.build([Body("box", 1.0, (0.05, 0.0, -0.02), tuple(map(tuple, inertia)))],
                            [TreeJoint("base", "free", None)], [-1], gravity=(0.0, 0.0, -9.81),
                            name="box")
        q0 = model.neutral()
        quat = rng.normal(size=4)
        q0[:3], q0[3:7] = rng.normal(size=3), quat / np.linalg.norm(quat)
        v0 = np.concatenate([rng.normal(size=3), 3.0 * rng.normal(size=3)])
    ref = redysim.simulate(model, T_END, q0=q0, v0=v0, integrator="dop853", rtol=1e-12,
                           atol=1e-12, sample=T_END)
    return model, q0, v0, (ref.q[-1], ref.v[-1])


def state_error(model: Model, q, v, ref) -> float:
    """max |q - q_ref| (a free joint's rotation as its matrix: the quaternion's sign is free)
    and max |v - v_ref|."""
    qr, vr = ref
    errs = [np.abs(v - vr).max()]
    if model.joint_types[0] == "free":
        R, Rr = (quaternion_matrix(*(x[3:7] / np.linalg.norm(x[3:7]))) for x in (q, qr))
        errs += [np.abs(q[:3] - qr[:3]).max(), np.abs(R - Rr).max()]
    else:
        errs.append(np.abs(q - qr).max())
    return float(max(errs))


_ENGINES: dict = {}


def engine_of(name: str, model_id: str):
    if (name, model_id) not in _ENGINES:
        _ENGINES[name, model_id] = engine_or_skip(name)(model_of(model_id)[0])
    return _ENGINES[name, model_id]


@pytest.mark.parametrize("model_id", MODELS)
@pytest.mark.parametrize(("name", "integrator"), list(ORDER))
def test_fixed_step_converges_at_its_order(name, integrator, model_id):
    """Halving h divides the error by 2^order (observed order within ORDER_MARGIN); the
    counts and the manifest say what ran; a step at a time is the same run."""
    model, q0, v0, ref = model_of(model_id)
    eng = engine_of(name, model_id)
    order = ORDER[name, integrator]
    n = STEPS[order]
    errs = []
    for steps in (n, 2 * n):
        h = T_END / steps
        tr = eng.simulate(q0, v0, T_END, h, integrator=integrator, every=steps)
        assert tr.integrator == integrator and tr.t[-1] == pytest.approx(T_END, abs=1e-12)
        errs.append(state_error(model, tr.q[-1], tr.v[-1], ref))
        done, rejected, nfev = eng.sim_counts()
        assert (done, rejected) == (steps, 0)
        assert nfev == -1 or nfev >= steps
    observed = float(np.log2(errs[0] / errs[1]))
    assert abs(observed - order) <= ORDER_MARGIN[order], (errs, observed)
    assert errs[1] > 1e-9  # far above the reference's own error
    m = eng.manifest()
    assert (m["engine"], m["version"], m["integrator"]) == (name, eng.version, integrator)
    assert (m["adaptive"], m["h"]) == (False, T_END / (2 * n)) and "rtol" not in m
    assert m["integrator_what"] == eng.integrators[integrator].what and m["integrator_note"]
    # step by step, the same run
    eng.sim_reset(q0, v0, T_END / n, integrator=integrator)
    for _ in range(3):
        eng.step_once()
    q, v = eng.sim_state()
    three = eng.simulate(q0, v0, 3 * T_END / n, T_END / n, integrator=integrator)
    assert np.array_equal(q, three.q[-1]) and np.array_equal(v, three.v[-1])


@pytest.mark.parametrize("model_id", MODELS)
@pytest.mark.parametrize(("name", "integrator"), ADAPTIVE)
def test_adaptive_error_falls_with_its_tolerance(name, integrator, model_id):
    """rtol 1e-4 -> 1e-8 (atol = rtol): the error falls at least 100x, to below 1e-6, with
    more steps; the engine counts its steps, rejections and qdd calls; one sim_advance to
    the end lands on it."""
    model, q0, v0, ref = model_of(model_id)
    eng = engine_of(name, model_id)
    errs, counts = [], []
    for rtol in (1e-4, 1e-8):
        tr = eng.simulate(q0, v0, T_END, T_END, integrator=integrator, rtol=rtol)
        assert tr.t.tolist() == [0.0, T_END]
        errs.append(state_error(model, tr.q[-1], tr.v[-1], ref))
        counts.append(eng.sim_counts())
        m = eng.manifest()
        assert (m["integrator"], m["adaptive"], m["rtol"], m["atol"]) == (
            integrator, True, rtol, rtol)
    assert errs[1] <= 1e-6 and errs[0] >= 100 * errs[1], errs
    (s4, r4, f4), (s8, r8, f8) = counts
    assert 0 < s4 < s8 and r4 >= 0 and r8 >= 0 and f4 > s4 and f8 > s8, counts


@pytest.mark.parametrize("name", WITH_INTEGRATORS)
def test_bad_integrator_settings_are_refused_by_name(name):
    """An unknown integrator, tolerances for a fixed-step one, no h for a fixed-step one and
    no rtol for an adaptive one: ValueError naming it, before any step."""
    eng = engine_of(name, "chain")
    _, q0, v0, _ = model_of("chain")
    with pytest.raises(ValueError, match=rf"engine '{name}' has no integrator 'nope'; its own: "):
        eng.sim_reset(q0, v0, 1e-3, integrator="nope")
    with pytest.raises(ValueError, match="no integrator 'nope'"):
        eng.simulate(q0, v0, 0.01, 1e-3, integrator="nope")
    fixed = next(i for i, info in eng.integrators.items() if not info.adaptive)
    with pytest.raises(ValueError, match=rf"'{fixed}' is fixed-step: it takes a step h, not "):
        eng.sim_reset(q0, v0, 1e-3, integrator=fixed, rtol=1e-6)
    with pytest.raises(ValueError, match=rf"'{fixed}' is fixed-step: it takes a step h, not "):
        eng.simulate(q0, v0, 0.01, 1e-3, integrator=fixed, atol=1e-6)
    with pytest.raises(ValueError, match=rf"'{fixed}' is fixed-step: give its step h"):
        eng.sim_reset(q0, v0, integrator=fixed)
    for integrator, info in eng.integrators.items():
        if info.adaptive:
            with pytest.raises(ValueError, match=rf"'{integrator}' is adaptive: give rtol > 0"):
                eng.sim_reset(q0, v0, integrator=integrator)
            with pytest.raises(ValueError, match="atol must be > 0"):
                eng.sim_reset(q0, v0, integrator=integrator, rtol=1e-6, atol=-1.0)
            eng.sim_reset(q0, v0, integrator=integrator, rtol=1e-6)
            with pytest.raises(ValueError, match="is adaptive: advance it to a time"):
                eng.step_once()


@pytest.mark.parametrize("name", ["pinocchio-aba", "pinocchio-aba-ryrz", "pinocchio-crba"])
def test_pinocchio_has_no_integrator(name):
    """Pinocchio has no time integrator: its adapter registers none, and a native run is
    refused naming the lack and the way to run it (its qdd in our integrators)."""
    cls = engine_or_skip(name)
    assert cls.integrators == {} and cls.integrator == ""
    model, q0, v0, _ = model_of("chain")
    eng = cls(model)
    why = (rf"engine '{name}' has no time integrator of its own \(Pinocchio has none.*"
           rf"--engine {name} --integrator ode45")
    for call in (lambda: eng.simulate(q0, v0, 0.01, 1e-3),
                 lambda: eng.sim_reset(q0, v0, 1e-3),
                 lambda: eng.sim_reset(q0, v0, 1e-3, integrator="semi-implicit-euler")):
        with pytest.raises(ValueError, match=why):
            call()
    with pytest.raises(ValueError, match=why):
        eng.stepper(h=1e-3)
    # what the message advises runs: Pinocchio's qdd in redysim's ode45
    sim = simulator(model, 0.05, q0=q0, v0=v0, integrator="ode45", rtol=1e-8, atol=1e-10,
                    qdd=eng.qdd).run()
    assert sim.status == 0


# --------------------------------------------------------------------------- the Simulator
def test_simulator_runs_a_fixed_step_native_integrator():
    """``Simulator(..., integrator=mujoco.stepper("implicitfast", h=...))``: the engine's own
    run, sampled; an unknown name is refused naming the engine's integrators, a fixed-step one
    without its step by name."""
    model, q0, v0, _ = model_of("box")
    eng = engine_of("mujoco", "box")
    sim = Simulator(model, 0.1, q0=q0, v0=v0, integrator=eng.stepper("implicitfast", h=1e-3),
                    sample=0.02).run()
    assert sim.status == 0 and sim.steps == 100 and len(sim.t) == 6
    own = eng.simulate(q0, v0, 0.1, 1e-3, integrator="implicitfast", every=20)
    # the same run, to rounding: the Simulator normalises q0's quaternion (and the samples'),
    # whose norm BLAS computes; on this CPU's default kernels that is exact here, under the
    # Haswell, Sandybridge and Zen kernels it moves q0 by an ulp and the whole run follows
    # (measured 4.4e-16 in q, 1.3e-15 in v of |v| 6.1)
    assert np.abs(sim.q - own.q).max() < 1e-15 and np.abs(sim.v - own.v).max() < 1e-14
    assert eng.manifest()["opt.integrator"] == "mjINT_IMPLICITFAST"
    with pytest.raises(ValueError, match=r"no integrator 'nope'; its own: euler, "
                                         r"implicitfast, implicit, rk4"):
        eng.stepper("nope", h=1e-3)
    with pytest.raises(SettingsError, match="fixed-step integrator: give its step h"):
        Simulator(model, 0.1, q0=q0, v0=v0, integrator=eng.stepper("rk4"))


@pytest.mark.parametrize("model_id", MODELS)
def test_simulator_runs_an_adaptive_native_integrator(model_id):
    """``Simulator(..., integrator=exudyn.stepper("dopri5", rtol=, atol=))`` lands on
    every sample by Exudyn's own step control; its counts are the engine's."""
    model, q0, v0, ref = model_of(model_id)
    eng = engine_of("exudyn", model_id)
    sim = Simulator(model, T_END, q0=q0, v0=v0,
                    integrator=eng.stepper("dopri5", rtol=1e-9, atol=1e-9), sample=0.05).run()
    assert sim.status == 0 and np.allclose(sim.t, np.arange(9) * 0.05, rtol=0, atol=1e-12)
    assert (sim.steps, sim.rejected, sim.nfev) == eng.sim_counts()
    assert sim.nfev == 7 * (sim.steps + sim.rejected) + 2  # 7 stages, no FSAL; the first step
    assert state_error(model, sim.q[-1], sim.v[-1], ref) < 1e-6
    own = eng.simulate(q0, v0, T_END, 0.05, integrator="dopri5", rtol=1e-9, atol=1e-9)
    assert np.abs(own.q[-1] - sim.q[-1]).max() < 1e-12
    m = eng.manifest()
    assert (m["solverType"], m["relativeTolerance"], m["absoluteTolerance"]) == (
        "DOPRI5", 1e-9, 1e-9)


@pytest.mark.slow
@pytest.mark.parametrize(("name", "integrator"), [("drake", "implicit_euler"),
                                                  ("exudyn", "dopri5")])
def test_an_engines_own_adaptive_advance_stops_at_the_cpu_limit(name, integrator):
    """An adaptive native integrator lands on each sample by its own steps: before the limit
    reached inside the engine's advance (Drake's monitor, Exudyn's pre-step function), a slow
    one on a 250-DOF rope ran one sample interval for over ten minutes past a 120 s limit. Now
    the run stops at the limit, failed, its message says where, and the engine is left with no
    limit for its next run."""
    engine_or_skip(name)
    from redysim.harness.run import execute
    from redysim.harness.spec import RunSpec

    res = execute(RunSpec("RE-U125-L1", engine=name, integrator=f"native:{integrator}",
                          rtol=1e-7, atol=1e-9, t_end=0.2, max_cpu_s=0.5), reference=False)
    s = res.summary
    assert not res.ok and s["reason"].startswith("time limit: max_cpu_s = 0.5 s")
    assert f"{name} stopped its advance" in s["reason"] and s["t_reached"] < 0.2
    assert s["cpu_s"] < 5.0  # one step past the limit at most (not minutes)


# --------------------------------------------------------------------------- MuJoCo
def test_mujoco_implicitfast_is_euler_on_a_chain_and_implicit_on_a_free_body():
    """Without damping or actuators MuJoCo's implicitfast has nothing to treat implicitly on a
    jointed model (bit for bit euler); a standalone free body gets its gyroscopic derivatives
    (bit for bit implicit). The integrator never enters qdd, and a manifest records the options
    that would change a run."""
    for model_id, twin in (("chain", "euler"), ("box", "implicit")):
        _, q0, v0, _ = model_of(model_id)
        eng = engine_of("mujoco", model_id)
        a = eng.qdd(q0, v0)
        runs = {i: eng.simulate(q0, v0, 0.05, 1e-3, integrator=i) for i in eng.integrators}
        assert np.array_equal(runs["implicitfast"].q, runs[twin].q), model_id
        other = "implicit" if twin == "euler" else "euler"
        assert not np.array_equal(runs["implicitfast"].q, runs[other].q), model_id
        assert np.array_equal(eng.qdd(q0, v0), a)
    m = eng.manifest()
    assert {"mjDSBL_CONTACT", "mjDSBL_CONSTRAINT", "mjDSBL_AUTORESET",
            "mjDSBL_EULERDAMP"} <= set(m["disabled"])
    assert (m["contacts"], m["constraints"], m["autoreset"], m["enabled"]) == (
        "off", "off", False, [])
    assert (m["density"], m["viscosity"], m["wind"]) == (0.0, 0.0, [0.0, 0.0, 0.0])
    assert m["opt.timestep"] == 1e-3 and m["opt.integrator"] == "mjINT_RK4"


def test_mujoco_blow_up_is_nan_not_a_reset():
    """A diverging run ends in NaN (autoreset off), and the Simulator fails it where it stops
    being finite; MuJoCo's default would put the state back at qpos0 and step on, finite and
    wrong."""
    model, q0, _, _ = model_of("chain")
    eng = engine_of("mujoco", "chain")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # MuJoCo's own "unstable" warnings
        tr = eng.simulate(q0, np.full(3, 50.0), 12.0, 0.2, integrator="rk4", every=20)
        assert np.isnan(tr.q[-1]).all()
        run = Simulator(model, 12.0, q0=q0, v0=np.full(3, 50.0),
                        integrator=eng.stepper("rk4", h=0.2), sample=0.2).run()
    assert run.status == -1 and "not finite" in run.message and run.t[-1] < 1.0


# --------------------------------------------------------------------------- DART
def test_dart_manifest():
    """DART's one integrator; what its World does besides (nothing to collide, no sleeping)."""
    _, q0, v0, _ = model_of("chain")
    eng = engine_of("dart", "chain")
    eng.simulate(q0, v0, 0.01, 1e-3)
    m = eng.manifest()
    assert (m["integrator"], m["World.timestep"], m["deactivation"]) == (
        "semi-implicit-euler", 1e-3, False)
    assert (m["shape_nodes"], m["constraints"], m["threads"]) == (0, 0, 1)
    assert eng.sim_counts() == (10, 0, 10)


# --------------------------------------------------------------------------- Exudyn
def test_exudyn_fixed_steps_are_one_continuous_solve():
    """Generalized-alpha stepped here, a step a call, is bit for bit Exudyn's own continuous
    solve over the same steps (its algorithmic acceleration and Jacobian carried over), with
    the same Newton iterations."""
    exu = pytest.importorskip("exudyn")
    from redysim.references.exudyn_engine import NEWTON_ATOL, NEWTON_RTOL, SPECTRAL_RADIUS
    from redysim.references.exudyn_engine import _settings as exudyn_settings

    _, q0, v0, _ = model_of("chain")
    eng = engine_of("exudyn", "chain")
    tr = eng.simulate(q0, v0, 0.1, 1e-3, integrator="generalized-alpha")
    newton = eng.manifest()["newton_iterations"]
    ss = exudyn_settings(exu, exu.DynamicSolverType.GeneralizedAlpha, 0.1, 100)
    ti = ss.timeIntegration
    ti.adaptiveStep = False
    ti.generalizedAlpha.spectralRadius = SPECTRAL_RADIUS
    ti.newton.relativeTolerance, ti.newton.absoluteTolerance = NEWTON_RTOL, NEWTON_ATOL
    eng._set_state(q0, v0, None)
    solver = exu.MainSolverImplicitSecondOrder()
    assert solver.SolveSystem(eng.mbs, ss)
    sd = eng.mbs.systemData
    assert np.array_equal(tr.q[-1], np.array(sd.GetODE2Coordinates()))
    assert np.array_equal(tr.v[-1], np.array(sd.GetODE2Coordinates_t()))
    assert newton == solver.it.newtonStepsCount > 0


@pytest.mark.parametrize("integrator", ["generalized-alpha", "dopri5", "rk44"])
def test_exudyn_calls_between_steps_change_nothing(integrator):
    """qdd, bias and position set Exudyn's state (and a free joint's chart); between the
    native steps they leave the run as it was."""
    model, q0, v0, _ = model_of("box")
    eng = engine_of("exudyn", "box")
    adaptive = eng.integrators[integrator].adaptive
    kw = {"rtol": 1e-8} if adaptive else {}
    plain = eng.simulate(q0, v0, 0.2, 0.01, integrator=integrator, **kw)
    eng.sim_reset(q0, v0, 0.01, integrator=integrator, **kw)
    other = q0.copy()
    other[3:7] = [0.0, 1.0, 0.0, 0.0]
    for i in range(1, 21):
        eng.sim_advance(i * 0.01)
        eng.qdd(other, -v0)
        eng.bias(other, 2 * v0)
    q, v = eng.sim_state()
    assert np.array_equal(q, plain.q[-1]) and np.array_equal(v, plain.v[-1])


@pytest.mark.parametrize("integrator", ["ode23", "dopri5"])
def test_exudyn_step_accepted_at_its_minimum_step_raises(integrator, capfd):
    """Exudyn scales the error by atol + max(y_old, y_new) rtol, signed: a velocity starting at
    -atol/rtol and falling gets a zero scale, its step control gives up at minimumStepSize and
    Exudyn accepts the step with a warning. The adapter raises, naming it; at +1 it runs."""
    _, q0, _, _ = model_of("chain")
    eng = engine_of("exudyn", "chain")
    v0 = np.array([-1.0, 0.5, 0.8])
    assert eng.qdd(q0, v0)[0] < 0  # the velocity at -1 falls
    with pytest.raises(RuntimeError, match=rf"exudyn {integrator}: its step size control "
                                           r"reached minimumStepSize \(1e-08 s\)"):
        eng.simulate(q0, v0, 0.1, 0.1, integrator=integrator, rtol=1e-4)
    assert "reached minStepSize" in capfd.readouterr().out  # Exudyn's own warning, shown
    eng.simulate(q0, -v0, 0.1, 0.1, integrator=integrator, rtol=1e-4)
