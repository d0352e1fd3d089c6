"""The closed forms of harness/truths.py that the hanging-mode and catenary scenarios are judged
by: each checked against an independent computation (the core's mass matrix, the linkage
module's own catenary, the A^2 law of a mode's nonlinearity), and a damped scenario's damping
reaching every run but never silently an engine's own stepper."""

from __future__ import annotations

import math

import numpy as np
import pytest

from redysim import load_case, mass_matrix
from redysim.algorithms.linkages import discrete_catenary, pinned_chain
from redysim.errors import SettingsError
from redysim.harness.refine import continuum_modes, hanging_modes
from redysim.harness.run import execute
from redysim.harness.spec import RunSpec
from redysim.harness.truths import (
    _hanging_matrices,
    catenary_point,
    hanging_mode,
    hanging_straight,
    mode_deviation,
    pinned_catenary,
    pinned_chain_of,
)
from redysim.io.cases import CASES_DIR
from redysim.io.scenarios import load_scenario


@pytest.fixture(scope="module")
def r16():
    return load_case(f"{CASES_DIR}/scenarios/models/hanging-R16.toml").chain


def test_the_hand_written_mass_matrix_is_the_cores(r16):
    """GIM two ways: T^T M_abs T from the linearised kinetic energy against the core's
    composite-body GIM at the hanging state, on the rod chain and on one with a tip mass."""
    M, _ = _hanging_matrices(r16)
    core = mass_matrix(r16, hanging_straight(r16))
    assert np.abs(M - core).max() <= 1e-14 * np.abs(core).max()
    hook = load_case(f"{CASES_DIR}/refine/pulled-R128.toml").chain
    M, _ = _hanging_matrices(hook)
    core = mass_matrix(hook, hanging_straight(hook))
    assert np.abs(M - core).max() <= 1e-13 * np.abs(core).max()


def test_the_modes_tend_to_the_continuums(r16):
    """omega_1 of 16 links equals the refinement study's (the core's M), and the first three
    frequencies of the 1 m rod chain tend to the heavy string's (z_k / 2) sqrt(g / L) at second
    order in the link length (measured: 4.7e-7, 1.6e-5, 6.8e-5 off at 256 links)."""
    from redysim import coarsen

    assert hanging_mode(r16, 1)[0] == pytest.approx(float(hanging_modes(r16, 1)[0]), rel=1e-13)
    chain = load_case(f"{CASES_DIR}/refine/hanging-R1024.toml").chain
    exact = continuum_modes(1.0, 9.81, 3)
    err = {n: np.array([abs(hanging_mode(coarsen(chain, links=n).coarse, k)[0] / exact[k - 1]
                            - 1.0) for k in (1, 2, 3)]) for n in (128, 256)}
    assert (err[256] < 1e-4).all()
    assert np.allclose(err[128] / err[256], 4.0, rtol=0.02), err


def test_the_scenarios_state_is_its_first_mode(r16):
    scn = load_scenario("HANGING-MODE")
    _, shape = hanging_mode(r16, 1)
    assert np.abs(scn.q0 - (hanging_straight(r16) + 1e-3 * shape)).max() <= 1e-15
    assert not scn.v0.any()


def test_a_mode_leaves_its_closed_form_at_second_order_in_the_amplitude(r16):
    """Released from mode 1 at amplitude A, the tip strays from x0 cos(omega_1 t) by c A^2 (the
    nonlinearity): the ratio of two amplitudes' deviations is 100 for a factor 10 in A. A
    wrong omega_1 or shape would leave a deviation of first order, the same ratio 10."""
    _, shape = hanging_mode(r16, 1)
    scn = load_scenario("HANGING-MODE")
    dev = []
    for amp in (1e-3, 1e-4):
        q0 = hanging_straight(r16) + amp * shape
        sim = scn.simulator(2.0, q0=q0, integrator="dop853", rtol=1e-12, atol=1e-11 * amp,
                            sample=0.01).run()
        x = (r16.length * np.sin(np.cumsum(sim.q, axis=1) + math.pi / 2)).sum(axis=1)
        dev.append(mode_deviation(r16, q0, sim.t, x))
    assert dev[0] / dev[1] == pytest.approx(100.0, rel=0.02), dev
    assert dev[0] < 3e-6


def test_the_pinned_catenary_is_the_linkage_modules(tmp_path):
    scn = load_scenario("CATENARY")
    q = pinned_catenary(scn.model)
    assert np.array_equal(q, discrete_catenary(pinned_chain(10, 0.1, 0.1, 0.8)))
    # link5.end by hand: the sum of the first five rods along their absolute angles
    theta = np.cumsum(q)[:5]
    by_hand = 0.1 * np.array([np.cos(theta).sum(), np.sin(theta).sum(), 0.0])
    assert np.abs(catenary_point(scn.model, "link5.end") - by_hand).max() < 1e-15
    with pytest.raises(ValueError, match="not a chain of revolute joints with one cut"):
        pinned_chain_of(load_scenario("JANSEN-LEG").model)


def test_a_damped_scenario_damps_its_runs(tmp_path, monkeypatch):
    """CATENARY's damping reaches the harness's run: its energy falls, and delta_M, the balance
    (E - W - E0) / M with the dampers' work W recorded, stays at the integration's error."""
    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path))
    res = execute(RunSpec("CATENARY", t_end=1.0, sample=0.5), reference=False)
    assert res.ok, res.summary["reason"]
    from redysim.harness.run import SAMPLE_COLUMNS

    # the start's energy above the equilibrium is 2.4e-7 J/kg (6.6e-5 m off it): after 1 s
    # the dampers have taken nearly all of it; undamped, E would stay at rounding level
    mass = load_scenario("CATENARY").model.total_mass
    E = [row[SAMPLE_COLUMNS.index("E")] for row in res.rows]
    assert (E[-1] - E[0]) / mass < -2e-7
    assert abs(res.rows[-1][SAMPLE_COLUMNS.index("delta_M")]) < 1e-11  # measured 2.5e-13
    assert load_scenario("CATENARY").damping == 0.03


@pytest.mark.engine
def test_an_engines_own_stepper_refuses_damping():
    """The engine steps its own model, which has no damping of ours: refused, never run
    undamped."""
    from redysim.references import get

    dp = load_scenario("DOUBLE-PENDULUM")
    engine = get("mujoco")(dp.model)
    with pytest.raises(SettingsError, match="has none of damping"):
        dp.simulator(0.1, integrator=engine.stepper("rk4", h=1e-3), damping=0.1)



@pytest.mark.parametrize("name", ["TALOS-ZERO-G", "TALOS-FALL", "DZHANIBEKOV"])
def test_a_floating_systems_momentum_is_kept(name, tmp_path, monkeypatch):
    """No external force but uniform gravity: the angular momentum about the centre of mass is
    constant, and the linear momentum grows as M g t. From the run's own samples (the harness's
    p_* and h_* columns); measured within 1e-10 of their size."""
    from redysim.io.scenarios import robot_data_file

    if name.startswith("TALOS") and robot_data_file("talos_reduced.urdf") is None:
        pytest.skip("example-robot-data is not installed")
    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path))
    scn = load_scenario(name)
    res = execute(RunSpec(name, rtol=1e-10, atol=1e-12, t_end=min(scn.t_end, 0.5)),
                  reference=False)
    assert res.ok, res.summary["reason"]
    s = res.samples
    p = s[["p_x", "p_y", "p_z"]].to_numpy()
    h = s[["h_x", "h_y", "h_z"]].to_numpy()
    total = scn.model.total_mass
    expected_p = p[0] + np.outer(s["t"].to_numpy(), total * np.asarray(scn.model.gravity))
    scale_p = max(np.abs(p).max(), total)
    assert np.abs(p - expected_p).max() <= 1e-10 * scale_p
    assert np.abs(h - h[0]).max() <= 1e-10 * np.abs(h[0]).max()
    assert np.abs(h[0]).max() > 0.1  # something to keep


@pytest.mark.engine
def test_the_momentum_is_pinocchios_centroidal_momentum():
    """redysim.momentum against Pinocchio's computeCentroidalMomentum (the same frame: world
    axes, about the centre of mass) on Talos floating at a seeded random state."""
    pin = pytest.importorskip("pinocchio")
    from redysim import momentum
    from redysim.io.scenarios import robot_data_file
    from redysim.references import get

    if robot_data_file("talos_reduced.urdf") is None:
        pytest.skip("example-robot-data is not installed")
    scn = load_scenario("TALOS-ZERO-G")
    eng = get("pinocchio-aba")(scn.model)
    state, blocks = eng._state(scn.q0, scn.v0)
    hg = pin.computeCentroidalMomentum(eng.pm, eng.data, state,
                                       eng._to_engine(scn.v0, blocks))
    ours = momentum(scn.model, scn.q0, scn.v0)
    assert np.abs(ours.linear - hg.linear).max() <= 1e-12 * np.abs(hg.linear).max()
    assert np.abs(ours.angular - hg.angular).max() <= 1e-12 * np.abs(hg.angular).max()
    assert np.abs(ours.com - eng.data.com[0]).max() <= 1e-14
