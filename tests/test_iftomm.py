"""The IFToMM benchmark problems (cases/iftomm/) in the core: each against a reference that is
not the core's (A01: the closed form; A02: the parallelogram's one-degree-of-freedom equation by
SciPy; A03: the Test Set for IVP Solvers' published solution of Andrews' squeezer, and its
equations by SciPy; A04: Bricard's full revolute joint, all 5 equations, and the energy), at the
library's "high" precision (harness/iftomm.py)."""

from __future__ import annotations

import numpy as np
import pytest

from redysim import load_linkage, mass_matrix, simulate
from redysim.algorithms.loops import ClosedLoops
from redysim.errors import CaseError
from redysim.harness.iftomm import (
    A03_ORDER,
    A03_REFERENCE,
    A03_T_END,
    A03_Y0,
    HIGH,
    a01_p1,
    a02_b0,
    a03_equations,
    a03_forces,
    a03_scipy,
    a03_simulator,
    a03_tree,
    library_error,
)
from redysim.io.linkage_files import linkage_from_dict
from redysim.io.scenarios import load_scenario
from redysim.model.tree import CutJoint

CASES = "cases/iftomm"


def _a01(t_end):
    s = load_scenario(f"{CASES}/A01-SIMPLE-PENDULUM.toml")
    sim = simulate(s.model, t_end, q0=s.q0, v0=s.v0, integrator="dop853", rtol=1e-12,
                   atol=1e-12, sample=s.sample_interval)
    assert sim.status == 0, sim.message
    p1 = np.column_stack((np.cos(sim.q[:, 0]), np.sin(sim.q[:, 0])))  # P1 at 1 m on the link
    return sim, p1


def test_a01_closed_form_is_the_pendulum():
    """The closed form itself: released at (1, 0) at rest, it keeps |P1| = 1 and its energy
    (g y + v^2 / 2 = 0), and at a quarter period K / w it is at the bottom."""
    from scipy.special import ellipk

    t = np.linspace(0.0, 10.0, 100001)
    p = a01_p1(t)
    assert np.allclose(p[0], [1.0, 0.0], atol=1e-15)
    assert np.abs(np.hypot(p[:, 0], p[:, 1]) - 1.0).max() < 1e-13
    v = np.gradient(p, t, axis=0, edge_order=2)
    energy = 9.81 * p[:, 1] + 0.5 * (v ** 2).sum(axis=1)
    assert np.abs(energy).max() < 1e-5  # central differences of step 0.1 ms: O(h^2)
    quarter = float(ellipk(0.5)) / np.sqrt(9.81)
    assert np.allclose(a01_p1([quarter])[0], [0.0, -1.0], atol=1e-14)
    # and SciPy's DOP853 on the pendulum's equation, phi'' = -g sin(phi) from the vertical
    from scipy.integrate import solve_ivp

    t = np.linspace(0.0, 10.0, 21)
    sol = solve_ivp(lambda _, y: (y[1], -9.81 * np.sin(y[0])), (0.0, 10.0), (np.pi / 2, 0.0),
                    method="DOP853", rtol=1e-13, atol=1e-13, t_eval=t)
    scipy_p1 = np.column_stack((np.sin(sol.y[0]), -np.cos(sol.y[0])))
    assert library_error(a01_p1(t), scipy_p1) < 1e-10


def test_a01_core_meets_high_precision():
    """The first 20 s of the library's 2000 s at its 0.5 s output steps: P1 within the high
    precision (1e-3) of the closed form, by far (measured 2e-12), energy kept."""
    sim, p1 = _a01(20.0)
    err = library_error(p1, a01_p1(sim.t))
    assert err < 1e-9 < HIGH, err
    assert np.abs(sim.energy - sim.energy[0]).max() < 1e-10


@pytest.mark.slow
def test_a01_core_meets_high_precision_over_the_library_horizon():
    """All 2000 s, 4000 output steps (measured 1.7e-7 at dop853 1e-12; 1e-5 at 1e-10)."""
    sim, p1 = _a01(2000.0)
    assert len(sim.t) == 4001
    assert library_error(p1, a01_p1(sim.t)) < HIGH


def test_a02_core_follows_the_parallelogram_until_its_first_flat_position():
    """N = 40: B0's position and velocity against the parallelogram's own equation (no loops)
    over the 1.2 s before the bars first lie flat (1.243 s), loops at round-off, energy kept."""
    s = load_scenario(f"{CASES}/A02-N-FOUR-BAR.toml")
    link = load_linkage(f"{CASES}/models/a02_n_four_bar.toml")
    assert s.model.n_v == 81 and len(s.model.cuts) == 40
    sim = simulate(s.model, 1.2, q0=s.q0, v0=s.v0, integrator="dop853", rtol=1e-12,
                   atol=1e-12, sample=s.sample_interval)
    assert sim.status == 0, sim.message
    ref = a02_b0(sim.t)
    b0 = np.array([link.point(q, "a0.end")[:2] for q in sim.q])
    assert np.allclose(ref[0], [0.0, 1.0, 1.0, 0.0], atol=1e-15)
    assert library_error(b0, ref[:, :2]) < 1e-9
    assert np.max(sim.residual_q) < 1e-12
    assert np.abs(sim.energy - sim.energy[0]).max() < 1e-9 * abs(sim.energy[0])


def test_a02_core_stops_at_the_flat_position_naming_the_change_point():
    """What the core does where the four-bars go flat (the specification's singular position,
    1 + N degrees of freedom for an instant): the loops' J M^-1 J^T is singular there and the run
    stops, saying so, rather than choose a motion (docs/notes/2026-12-08-iftomm.md)."""
    s = load_scenario(f"{CASES}/A02-N-FOUR-BAR.toml")
    sim = simulate(s.model, 1.5, q0=s.q0, v0=s.v0, integrator="dop853", rtol=1e-12,
                   atol=1e-12, sample=s.sample_interval)
    assert sim.status == -1 and "change point" in sim.message, sim.message
    assert 1.2 < sim.t[-1] < 1.25


def _bricard():
    link = load_linkage(f"{CASES}/models/a04_bricard.toml")
    # the joint J6 whole: rod 5's frame turned so that its z is the pin's axis, world x
    R = ((0.0, 0.0, 1.0), (0.0, 1.0, 0.0), (-1.0, 0.0, 0.0))
    full = ClosedLoops(link.model, [CutJoint("J6 revolute", 4, (0.0, 1.0, 0.0), -1,
                                             (0.0, 0.0, 1.0), "revolute", rot_a=R, rot_b=R)])
    return link, full


def test_a04_bricard_is_overconstrained_with_one_degree_of_freedom():
    """At the start the whole joint J6 gives 5 equations of rank 4 on 5 coordinates (Grubler's
    0 degrees of freedom, Bricard's 1), and the file's 4 equations are those independent ones."""
    link, full = _bricard()
    s_full = np.linalg.svd(full.evaluate(link.q0, 0 * link.q0)[1], compute_uv=False)
    assert s_full.size == 5 and s_full[3] > 0.1 and s_full[4] < 1e-12
    s_file = np.linalg.svd(link.loops.evaluate(link.q0, 0 * link.q0)[1], compute_uv=False)
    assert s_file.size == 4 and s_file[-1] > 0.5


def test_a04_bricard_moves_with_one_degree_of_freedom_for_10_s():
    """Released at rest under gravity: the rods fold through the whole cycle (rod 1 turns
    through 180 deg), the full joint J6 (all 5 equations) holds to 1e-11 m at every sample,
    the Jacobian keeps rank 4 (one degree of freedom), the energy is kept to 1e-11."""
    link, full = _bricard()
    s = load_scenario(f"{CASES}/A04-BRICARD.toml")
    sim = simulate(s.model, s.t_end, q0=s.q0, v0=s.v0, integrator="dop853", rtol=1e-12,
                   atol=1e-12, sample=s.sample_interval)
    assert sim.status == 0, sim.message
    assert len(sim.t) == 201
    assert np.ptp(sim.q[:, 0]) > 3.0
    assert np.max(sim.residual_q) < 1e-12
    worst = max(max(full.residuals(q, v)) for q, v in zip(sim.q, sim.v, strict=True))
    assert worst < 1e-11, worst
    for q in sim.q[::10]:
        sv = np.linalg.svd(full.evaluate(q, 0 * q)[1], compute_uv=False)
        assert sv[3] > 1e-2 * sv[0] and sv[4] < 1e-10 * sv[0], sv
    assert np.abs(sim.energy - sim.energy[0]).max() < 1e-11 * abs(sim.energy[0])


_LINE = {
    "ground": {"points": {"O": [0.0, 0.0], "D": [1.0, 0.0]}},
    "body": [{"name": "bar", "parent": "ground", "at": "O", "length": 1.0, "mass": 1.0}],
}


@pytest.mark.parametrize("cut, field, says", [
    ({"kind": "line"}, "cut[0].direction", "missing field"),
    ({"kind": "line", "direction": [0.0, 0.0, 0.0]}, "cut[0].direction", "zero vector"),
    ({"kind": "line", "direction": [1.0, 0.0]}, "cut[0].direction", ""),
    ({"kind": "planar", "direction": [1.0, 0.0, 0.0]}, "cut[0].direction", "only a 'line'"),
    ({"kind": "line", "direction": [0.0, 1.0, 0.0], "a": "ground.D", "b": "bar.end"},
     "cut[0].a", "write the ground's point as b"),
])
def test_a_line_cut_needs_its_direction(cut, field, says):
    doc = {**_LINE, "cut": [{"name": "tip", "a": "bar.end", "b": "ground.D", **cut}]}
    with pytest.raises(CaseError) as err:
        linkage_from_dict(doc, source="bar.toml")
    assert field in str(err.value) and says in str(err.value), str(err.value)


def test_a_line_cut_keeps_its_points_level_along_its_direction():
    """A bar pinned at O whose end is kept level with D = (1, 0) along y: one equation; the
    loop closes with the bar along x, and its Jacobian row is d(y_end)/dq = cos(q) = 1."""
    doc = {**_LINE, "cut": [{"name": "tip", "a": "bar.end", "b": "ground.D", "kind": "line",
                             "direction": [0.0, 1.0, 0.0]}],
           "initial": {"q": [3.0]}}
    link = linkage_from_dict(doc, source="bar.toml")
    assert abs(link.q0[0]) < 1e-12
    phi, J, _, _ = link.loops.evaluate(link.q0, np.zeros(1))
    assert phi.shape == (1,) and abs(J[0, 0] - 1.0) < 1e-12


@pytest.mark.slow
def test_a04_bricard_dop853_and_radau_agree():
    """Two integrators of different kinds on the same loops (12 s of CPU for Radau): the corner
    rod2.J3 over 10 s within 1e-10 m of each other (measured 3.7e-12)."""
    link, _ = _bricard()
    s = load_scenario(f"{CASES}/A04-BRICARD.toml")
    paths = []
    for integrator in ("dop853", "scipy-Radau"):
        sim = simulate(s.model, s.t_end, q0=s.q0, v0=s.v0, integrator=integrator, rtol=1e-12,
                       atol=1e-12, sample=s.sample_interval)
        assert sim.status == 0, sim.message
        paths.append(np.array([link.point(q, "rod2.J3") for q in sim.q]))
    assert np.abs(paths[0] - paths[1]).max() < 1e-10


# --------------------------------------------------------------------------- A03: Andrews' squeezer
A03_FILE = f"{CASES}/models/a03_andrews.toml"


def test_a03_linkage_file_is_the_test_sets_squeezer():
    """The file against the test set's own equations (andfunc, written out as a03_equations):
    at random angles the tree's mass matrix is the test set's M, the cut joints' residuals and
    Jacobian its g and G (same rows, columns in the tree's order), the spring's and motor's
    generalized forces (a03_forces) its ff without the velocity terms; and the file's
    configuration is the test set's initial one, its loops closed."""
    link = load_linkage(A03_FILE)
    model = link.model
    assert model.n_v == 7 and len(model.cuts) == 3 and not np.any(model.gravity)
    tau, potential = a03_forces(link)
    order = list(A03_ORDER)
    rng = np.random.default_rng(20261208)
    for y in rng.uniform(-np.pi, np.pi, (5, 7)):
        M, g, G, f = a03_equations(y)
        q = a03_tree(y)
        M_tree = M[np.ix_(order, order)]
        assert np.abs(mass_matrix(model, q) - M_tree).max() < 1e-15 * np.abs(M).max()
        phi, J, _, _ = link.loops.evaluate(q, np.zeros(7))
        assert np.abs(phi - g).max() < 1e-16
        assert np.abs(J - G[:, order]).max() < 1e-16
        assert np.abs(tau(0.0, q, np.zeros(7)) - a03_tree(f)).max() < 1e-12 * np.abs(f).max()
    assert np.abs(link.q0 - a03_tree(A03_Y0)).max() < 1e-15
    assert np.abs(a03_equations(A03_Y0)[1]).max() < 1e-16  # the test set's start closes g
    assert np.abs(link.loops.evaluate(link.q0, np.zeros(7))[0]).max() < 1e-16
    # the spring's potential is the one whose gradient is tau (central differences)
    q, h = link.q0, 1e-6
    grad = [(potential(q + h * e) - potential(q - h * e)) / (2 * h) for e in np.eye(7)]
    assert np.allclose(-np.array(grad), tau(0.0, q, np.zeros(7)), rtol=1e-6, atol=1e-9)


def test_a03_scipy_on_the_test_sets_equations_meets_its_reference():
    """The test set's equations by SciPy's DOP853 (no tree, no projection) against its
    published solution at 0.03 s (andsoln: PSIDE at 1e-14 on a Cray C90): the 7 angles to
    3e-10 relative (measured 2.7e-10, gamma), the 7 velocities to 5.1e-8 (epsilon'; 5.4e-7
    rad/s absolute): at rtol 1e-13 and 3e-14 alike, so it is the reference's own error (the
    test set scores only the angles: its SCD skips y(8..27))."""
    y, drift = a03_scipy(rtol=1e-13)
    rel = np.abs(y - A03_REFERENCE) / np.abs(A03_REFERENCE)
    assert drift < 1e-14
    assert rel[:7].max() < 5e-10, rel
    assert rel[7:].max() < 1e-7, rel


def _a03(tol):
    simulator, _ = a03_simulator(integrator="dop853", rtol=tol, atol=tol)
    sim = simulator.run()
    assert sim.status == 0, sim.message
    y = np.concatenate((a03_tree(sim.q[-1]), a03_tree(sim.v[-1])))
    return sim, y


def test_a03_core_meets_the_test_sets_reference():
    """dop853 at rtol = atol = 1e-12 over [0, 0.03] s (214 steps): the 7 angles within 3e-10
    relative of the published solution (measured 2.7e-10), the velocities within 1e-7
    (5.1e-8); the core within 1e-10 relative of SciPy on the test set's equations (1.6e-11:
    the published solution's own error is what is left); the energy with the spring's and the
    motor's potentials kept to 1e-11, the loops at round-off."""
    sim, y = _a03(1e-12)
    assert len(sim.t) == 31 and sim.t[-1] == A03_T_END
    rel = np.abs(y - A03_REFERENCE) / np.abs(A03_REFERENCE)
    assert rel[:7].max() < 5e-10, rel
    assert rel[7:].max() < 1e-7, rel
    ref, _ = a03_scipy(rtol=3e-14)
    assert (np.abs(y - ref) / np.abs(ref)).max() < 1e-10
    assert np.abs(sim.energy - sim.energy[0]).max() < 1e-11 * abs(sim.energy[0])
    assert np.max(sim.residual_q) < 1e-13
    assert np.ptp(sim.q[:, 0]) > 15.0  # the crank turns 2.5 times


def test_a03_is_run_with_its_forces_and_has_no_scenario_file_without_them():
    """The squeezer's spring and motor are not in any file (neither format writes them): it is
    run by a03_simulator, and no scenario file runs it under its name without them (it would
    stay at rest). The mechanism's own file says where its forces are."""
    import pathlib

    assert not list(pathlib.Path(CASES).glob("A03*"))
    assert "a03_forces" in pathlib.Path(A03_FILE).read_text()
    simulator, link = a03_simulator(t_end=0.002)
    sim = simulator.run()
    assert sim.status == 0 and np.abs(sim.q[-1] - link.q0).max() > 1e-6  # the motor turns it


@pytest.mark.slow
@pytest.mark.parametrize("tol, angles, velocities", [(1e-10, 5e-10, 1e-7), (1e-8, 1e-8, 1e-6),
                                                      (1e-6, 1e-5, 1e-3)])
def test_a03_core_at_looser_tolerances(tol, angles, velocities):
    """The largest relative errors against the published solution at looser tolerances
    (measured: 1e-10: 3.5e-10 and 5.4e-8; 1e-8: 3.4e-9 and 3.8e-7; 1e-6: 1.3e-6 and 1.4e-4)."""
    _, y = _a03(tol)
    rel = np.abs(y - A03_REFERENCE) / np.abs(A03_REFERENCE)
    assert rel[:7].max() < angles and rel[7:].max() < velocities, rel
