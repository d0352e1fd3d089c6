"""The model's passive elements in the engines' own integrators, and armature where an engine has
no field for it (issue 56, items 2-4).

A damped, sprung arm held partly up by gravity compensation (Menagerie's UR5e, its armature
taken off, with damping on every joint, springs on three, gravcomp 0.5 on every body) is stepped
by DART's World.step, Drake's Simulator and Exudyn's own solvers, each holding the damping, the
springs and the gravcomp in its own model (``holds_passive``), and compared with the core's
right-hand side (the core's rigid qdd with ``passive_forces`` as tau) integrated by SciPy's
DOP853 at 1e-11: every native run must land on it (DART first order, its joint springs and
damping implicit in its step), and the same runs of the rigid arm must not (so the passive
elements are what makes them agree). The engines' qdd stays the rigid body's after a native run
(the core's System applies the passive forces around it). A damped free joint is refused by
name by the three. Last, Pinocchio's mimic joint with armature (Menagerie's Panda: the finger
that Pinocchio makes the mimic has armature): its armature reflected into its leader gives
Drake's and DART's coupled qdd (the adapter's projection of their own M + armature), and
MuJoCo's within its soft equality's regularisation.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.integrate
from conftest import stable_seed
from engine_chains import engine_or_skip

import redysim
from redysim.algorithms.system import passive_forces

MENAGERIE = Path(__file__).parent / "models" / "menagerie"
T_END = 0.5


def passive_arm():
    m = redysim.load_model(MENAGERIE / "universal_robots_ur5e" / "ur5e.xml")
    return m.with_armature(None).with_passive(
        damping=[0.5, 1.0, 2.0, 0.3, 0.2, 0.1], stiffness=[3.0, 0.0, 5.0, 0.0, 2.0, 0.0],
        spring_ref=[0.1, 0.0, -0.2, 0.0, 0.3, 0.0], gravcomp=0.5)


def start(m):
    rng = np.random.default_rng(stable_seed("passive-arm", m.n_v))
    return m.neutral() + rng.uniform(-0.5, 0.5, m.n_q), rng.uniform(-1.0, 1.0, m.n_v)


def core_path_end(m, q0, v0):
    """q at T_END from the core's right-hand side: rigid qdd with the passive forces as tau."""
    def f(_, y):
        q, v = y[:m.n_q], y[m.n_q:]
        return np.concatenate([v, redysim.forward_dynamics(m, q, v, passive_forces(m, q, v))])
    sol = scipy.integrate.solve_ivp(f, (0.0, T_END), np.concatenate([q0, v0]), method="DOP853",
                                    rtol=1e-11, atol=1e-12)
    return sol.y[:m.n_q, -1]


# engine -> (integrator, settings, tolerance on q at T_END [rad])
NATIVE = {"dart": ("semi-implicit-euler", {"h": 2.5e-4}, 1e-3),
          "drake": ("runge_kutta5", {"h": 1e-3, "rtol": 1e-9}, 1e-7),
          "exudyn": ("rk44", {"h": 1e-3}, 1e-8)}


@pytest.mark.engine
@pytest.mark.parametrize("name", sorted(NATIVE))
def test_the_engines_own_integrators_hold_the_passive_elements(name):
    cls = engine_or_skip(name)
    m = passive_arm()
    q0, v0 = start(m)
    want = core_path_end(m, q0, v0)
    integrator, settings, tol = NATIVE[name]
    eng = cls(m)
    assert eng.no_native_passive() == ""
    probe = (q0 + 0.1, -v0)
    rigid_qdd = eng.qdd(*probe)
    got = eng.simulate(q0, v0, T_END, settings["h"], integrator=integrator,
                       rtol=settings.get("rtol")).q[-1]
    err = np.abs(got - want).max()
    assert err < tol, (name, err)
    # its qdd is still the rigid body's (the passive forces are a run's, around it)
    assert np.array_equal(eng.qdd(*probe), rigid_qdd)
    core = redysim.forward_dynamics(m, *probe)
    assert np.abs(rigid_qdd - core).max() < 1e-10 * np.abs(core).max()
    # the rigid arm's run lands elsewhere: the passive elements are what agrees
    rigid = cls(m.without_passive()).simulate(q0, v0, T_END, settings["h"],
                                              integrator=integrator,
                                              rtol=settings.get("rtol")).q[-1]
    assert np.abs(rigid - want).max() > 100 * tol


@pytest.mark.engine
def test_dart_converges_at_first_order_on_the_passive_arm():
    """DART's semi-implicit Euler with its implicit joint springs and damping: error /4 when h
    does (first order), toward the core's path, not elsewhere."""
    cls = engine_or_skip("dart")
    m = passive_arm()
    q0, v0 = start(m)
    want = core_path_end(m, q0, v0)
    errs = [np.abs(cls(m).simulate(q0, v0, T_END, h).q[-1] - want).max() for h in (1e-3, 2.5e-4)]
    assert 3.0 < errs[0] / errs[1] < 5.0, errs


@pytest.mark.engine
@pytest.mark.parametrize("name", sorted(NATIVE))
def test_a_damped_free_joint_is_refused_by_name(name):
    cls = engine_or_skip(name)
    m = redysim.load_model(MENAGERIE / "unitree_g1" / "g1.xml").with_armature(None)
    damping = np.zeros(m.n_v)
    damping[3:6] = 0.2  # the pelvis's free joint's rotations
    eng = cls(m.with_passive(damping=damping))
    why = eng.no_native_passive()
    assert "free joint" in why and m.joint_names[0] in why, why
    integrator, settings, _ = NATIVE[name]
    with pytest.raises(ValueError, match="free joint"):
        eng.sim_reset(m.initial(), np.zeros(m.n_v), settings["h"], integrator=integrator,
                      rtol=settings.get("rtol"))


@pytest.mark.engine
def test_pinocchios_mimic_joint_reflects_its_armature_into_its_leader():
    """Menagerie's Panda: finger_joint1 follows finger_joint2 and comes first, so Pinocchio's
    mimic joint is finger_joint2, which has armature 0.1; reflected into finger_joint1 it gives
    Drake's and DART's coupled qdd (their own M with the armature, projected by the adapter),
    and MuJoCo's within its soft equality; without the reflection it would differ."""
    m = redysim.load_model(MENAGERIE / "franka_emika_panda" / "panda.xml")
    assert np.all(m.armature[-2:] > 0) and m.couplings
    pin = engine_or_skip("pinocchio-crba")(m)
    others = {n: engine_or_skip(n)(m) for n in ("drake", "dart", "mujoco")}
    rng = np.random.default_rng(stable_seed("panda-mimic-armature"))
    for _ in range(3):
        q, v = m.couple(m.initial() + rng.uniform(-0.5, 0.5, m.n_q), rng.normal(size=m.n_v))
        tau = rng.normal(size=m.n_v)
        got = pin.qdd(q, v, tau)
        scale = np.abs(got).max()
        for n, eng in others.items():
            tol = 1e-3 if n == "mujoco" else 1e-9  # MuJoCo's equality is soft (regularised)
            assert np.abs(eng.qdd(q, v, tau) - got).max() < tol * scale, n
        # Pinocchio without the mimic's armature would be this model: measurably apart
        assert m.joint_names[-1] == "finger_joint2"  # the mimic (after its leader)
        bare = m.with_armature(np.where(np.arange(m.n_v) == m.n_v - 1, 0.0, m.armature))
        off = engine_or_skip("drake")(bare).qdd(q, v, tau)
        assert np.abs(off - got).max() > 1e-6 * scale


def test_compare_runs_dart_and_exudyn_through_their_qdd_only_with_armature():
    """`redysim compare` on the G1 (armature on every hinge): DART and Exudyn run through
    redysim's integrators with their qdd (which holds the armature), and none of their own
    integrators, which would step the engine's model without it; the other engines keep theirs."""
    from redysim.io.scenarios import load_scenario
    from redysim.reports.compare import plan

    target = str(MENAGERIE / "unitree_g1" / "g1.xml")
    scn = load_scenario(target, options={})
    specs = plan(target, scn, options={}, t_end=0.05, sample=0.01)
    by_engine: dict[str, set[str]] = {}
    for s in specs:
        by_engine.setdefault(s.engine, set()).add(s.integrator)
    for name in ("dart", "exudyn"):
        assert by_engine[name] == {"ode45"}, by_engine[name]
    assert any(i.startswith("native:") for i in by_engine["mujoco"])
    assert any(i.startswith("native:") for i in by_engine["drake"])
