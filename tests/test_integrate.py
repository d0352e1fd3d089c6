"""The integrator family: tableau consistency, convergence orders, ode45's step control rules,
counting, dense output and resuming from a saved state."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

from redysim.harness.provenance import openblas_coretypes
from redysim.integrators.explicit import (
    DOP853,
    DP45,
    IMPLICIT,
    INTEGRATORS,
    MAX_GROWTH,
    NTRP45_BI,
    RK4,
    TABLEAUS,
    Solver,
    integrate,
    sample_times,
)


def oscillator(t, y):
    """y'' = -y: y = cos t, y' = -sin t."""
    return np.array([y[1], -y[0]])


def exact(t):
    return np.array([np.cos(t), -np.sin(t)])


def nonautonomous(t, y):
    """y' = y cos t: y = exp(sin t) (exercises the nodes c)."""
    return y * np.cos(t)


@pytest.mark.parametrize("tab", TABLEAUS.values(), ids=list(TABLEAUS))
def test_tableau_consistency(tab):
    s = tab.stages
    assert tab.A.shape == (s, s) and tab.c.shape == (s,)
    assert np.allclose(np.triu(tab.A), 0.0), "explicit: A strictly lower triangular"
    assert np.allclose(tab.A.sum(axis=1), tab.c, atol=1e-14), "row sums equal the nodes"
    assert tab.b.sum() == pytest.approx(1.0, abs=1e-14)
    # order conditions up to 4 (all three schemes are at least 4th order)
    c, A, b = tab.c, tab.A, tab.b
    assert b @ c == pytest.approx(1 / 2, abs=1e-14)
    assert b @ c**2 == pytest.approx(1 / 3, abs=1e-14)
    assert b @ (A @ c) == pytest.approx(1 / 6, abs=1e-14)
    assert b @ c**3 == pytest.approx(1 / 4, abs=1e-14)
    assert b @ (c * (A @ c)) == pytest.approx(1 / 8, abs=1e-14)
    assert b @ (A @ c**2) == pytest.approx(1 / 12, abs=1e-14)
    assert b @ (A @ (A @ c)) == pytest.approx(1 / 24, abs=1e-14)
    if tab.adaptive:
        # an error estimate is a difference of two consistent weight sets: it sums to zero
        assert tab.E.size == s + 1 and tab.E.sum() == pytest.approx(0.0, abs=1e-14)
        if tab.E3 is not None:
            assert tab.E3.sum() == pytest.approx(0.0, abs=1e-14)


def test_ntrp45_interpolant_ends_at_the_step():
    # at s = 1 the interpolant's weights are the propagated solution's (b, and 0 for f_new)
    w = NTRP45_BI @ np.ones(4)
    assert np.allclose(w, np.append(DP45.b, 0.0), atol=1e-14)


@pytest.mark.parametrize("method, order", [("ode45", 5), ("dop853", 8), ("rk4", 4)])
def test_convergence_order_at_fixed_steps(method, order):
    """The observed order of the global error at fixed steps is the scheme's order."""
    errs = []
    hs = [0.2, 0.1] if order < 8 else [0.4, 0.2]
    for h in hs:
        sol = integrate(nonautonomous, (0.0, 2.0), [1.0], method, h=h, t_eval=[2.0])
        errs.append(abs(sol.y[-1, 0] - np.exp(np.sin(2.0))))
    observed = np.log2(errs[0] / errs[1])
    assert observed == pytest.approx(order, abs=0.35)


@pytest.mark.parametrize("method", [m for m in INTEGRATORS if m not in IMPLICIT])
def test_every_integrator_reaches_its_tolerance(method):
    """(The implicit midpoint, second order, has its own: tests/test_implicit.py.)"""
    kw = {"h": 1e-3} if method == "rk4" else {}
    ts = np.linspace(0, 10, 11)
    sol = integrate(oscillator, (0.0, 10.0), [1.0, 0.0], method, rtol=1e-8, atol=1e-10,
                    t_eval=ts, **kw)
    assert sol.status == 0 and np.array_equal(sol.t, ts)
    assert np.abs(sol.y - exact(ts).T).max() < 1e-6
    assert sol.steps > 0 and sol.nfev > sol.steps


def test_tighter_tolerance_smaller_error_more_work():
    prev_err, prev_nfev = np.inf, 0
    for rtol in (1e-4, 1e-6, 1e-8, 1e-10):
        sol = integrate(oscillator, (0.0, 10.0), [1.0, 0.0], "ode45", rtol=rtol, atol=rtol,
                        t_eval=[10.0])
        err = np.abs(sol.y[-1] - exact(10.0)).max()
        assert err < prev_err and sol.nfev > prev_nfev
        prev_err, prev_nfev = err, sol.nfev


def test_ode45_counts_and_controls_like_matlab():
    """nfev = 1 + 6 (steps + rejected); first step by the rh rule; h <= 0.1 span; growth <= 5x;
    every accepted step passes the per-component test |e_i| <= max(rtol |y_i|, atol)."""
    rtol, atol, t_end = 1e-6, 1e-9, 10.0
    s = Solver(oscillator, 0.0, [1.0, 0.0], t_end, "ode45", rtol=rtol, atol=atol)
    y0, f0 = np.array([1.0, 0.0]), oscillator(0.0, [1.0, 0.0])
    rh = np.max(np.abs(f0) / np.maximum(np.abs(y0), atol / rtol)) / (0.8 * rtol ** 0.2)
    assert s.h_next == pytest.approx(min(0.1 * t_end, 1 / rh))
    hs = []
    while not s.done:
        s.step()
        h = s.t - s.t_old
        hs.append(h)
        assert h <= 0.1 * t_end * (1 + 1e-12)
        err = h * np.abs(DP45.E @ s.K)
        assert np.all(err <= np.maximum(rtol * np.maximum(np.abs(s.y_old), np.abs(s.y)), atol)
                      * (1 + 1e-12))
    c = s.counters
    assert c.nfev == 1 + 6 * (c.steps + c.rejected)
    assert s.t == t_end
    growth = np.array(hs[1:-1]) / np.array(hs[:-2])
    assert growth.max() <= MAX_GROWTH * (1 + 1e-12)


def test_rejections_are_counted_and_shrink_the_step():
    # a kink in the right-hand side at t = 0.5: steps across it fail the error test
    def kinked(t, y):
        return np.array([np.sin(40 * t) if t > 0.5 else 0.0])

    sol = integrate(kinked, (0.0, 1.0), [0.0], "ode45", rtol=1e-8, atol=1e-10, t_eval=[1.0])
    assert sol.rejected > 0
    assert sol.y[-1, 0] == pytest.approx((np.cos(20) - np.cos(40)) / 40, abs=1e-7)
    assert sol.nfev == 1 + 6 * (sol.steps + sol.rejected)


def test_dense_output_matches_the_solution_between_steps():
    for method in ("ode45", "dop853"):
        ts = np.linspace(0.0, 10.0, 101)  # many samples per step
        sol = integrate(oscillator, (0.0, 10.0), [1.0, 0.0], method, rtol=1e-10, atol=1e-12,
                        t_eval=ts)
        assert np.abs(sol.y - exact(ts).T).max() < 1e-8, method


def test_sampling_does_not_change_the_steps():
    """ode45 outputs by interpolation: the sample times do not alter the step sequence."""
    a = integrate(oscillator, (0.0, 5.0), [1.0, 0.0], "ode45", rtol=1e-7, t_eval=[5.0])
    b = integrate(oscillator, (0.0, 5.0), [1.0, 0.0], "ode45", rtol=1e-7,
                  t_eval=np.linspace(0, 5, 51))
    assert (a.steps, a.nfev) == (b.steps, b.nfev)
    assert np.array_equal(a.y[-1], b.y[-1])


def test_resume_from_saved_state_is_bit_identical():
    whole = Solver(oscillator, 0.0, [1.0, 0.0], 10.0, "ode45", rtol=1e-7)
    part = Solver(oscillator, 0.0, [1.0, 0.0], 10.0, "ode45", rtol=1e-7)
    for _ in range(10):
        part.step()
    saved = part.state()
    resumed = Solver(oscillator, 0.0, [1.0, 0.0], 10.0, "ode45", rtol=1e-7, state=saved)
    while not whole.done:
        whole.step()
    while not resumed.done:
        resumed.step()
    assert np.array_equal(whole.y, resumed.y)
    assert whole.counters == resumed.counters


def test_rk4_lands_on_sample_times():
    sol = integrate(oscillator, (0.0, 1.0), [1.0, 0.0], "rk4", h=0.03, t_eval=[0, 0.1, 0.5, 1.0])
    assert np.array_equal(sol.t, [0, 0.1, 0.5, 1.0])
    assert np.abs(sol.y - exact(sol.t).T).max() < 1e-6
    assert sol.nfev == 1 + 4 * sol.steps  # 3 new stages + f(t + h), reused as the next K[0]


def test_bad_arguments_are_named():
    with pytest.raises(ValueError, match="method = 'ode23'"):
        integrate(oscillator, (0, 1), [1.0, 0.0], "ode23")
    with pytest.raises(ValueError, match="needs h > 0"):
        integrate(oscillator, (0, 1), [1.0, 0.0], "rk4")
    with pytest.raises(ValueError, match="rtol = 0.0: must be at least"):
        integrate(oscillator, (0, 1), [1.0, 0.0], "ode45", rtol=0.0)
    with pytest.raises(ValueError, match="rtol = 2.0: must be < 1"):
        integrate(oscillator, (0, 1), [1.0, 0.0], "ode45", rtol=2.0)
    with pytest.raises(ValueError, match="forward in time"):
        integrate(oscillator, (1, 0), [1.0, 0.0], "ode45")


@pytest.mark.parametrize("method", ["ode45", "rk45", "dop853", "rk4", "scipy-RK45"])
@pytest.mark.parametrize("t_eval, fragment", [
    ([0.5, 0.2, 1.0], "not properly sorted"),  # ode45 returned values 0.5 % off
    ([0.2, 0.2, 1.0], "not properly sorted"),
    ([-0.1, 0.5], "not within t_span"),  # returned y0 labelled -0.1
    ([0.5, 1.5], "not within t_span"),  # 1.5 was dropped, status ok
    ([[0.1, 0.2]], "1-dimensional"),
    ([0.1, np.nan], "finite"),
])
def test_t_eval_outside_the_span_or_unsorted_is_refused(method, t_eval, fragment):
    kw = {"h": 0.01} if method == "rk4" else {}
    with pytest.raises(ValueError, match=fragment):
        integrate(oscillator, (0.0, 1.0), [1.0, 0.0], method, t_eval=t_eval, **kw)


def test_t_eval_at_both_ends_of_the_span_is_accepted():
    sol = integrate(oscillator, (0.0, 1.0), [1.0, 0.0], "ode45", rtol=1e-8, atol=1e-10,
                    t_eval=[0.0, 0.3, 1.0])
    assert sol.status == 0 and np.array_equal(sol.t, [0.0, 0.3, 1.0])
    assert np.abs(sol.y - exact(sol.t).T).max() < 1e-7


def test_non_finite_rhs_fails_with_a_reason():
    def blows_up(t, y):
        return np.array([np.nan if t > 0.5 else 1.0])

    sol = integrate(blows_up, (0.0, 1.0), [0.0], "ode45", t_eval=[1.0])
    assert sol.status == -1 and "not finite" in sol.message


def test_callback_stops_the_run():
    sol = integrate(oscillator, (0.0, 10.0), [1.0, 0.0], "ode45", t_eval=np.arange(11.0),
                    callback=lambda t, y: "enough" if t >= 3 else None)
    assert sol.status == 1 and sol.message == "enough" and sol.t[-1] == 3.0


def test_sample_times():
    assert np.allclose(sample_times(0.0, 1.0, 0.25), [0, 0.25, 0.5, 0.75, 1.0])
    assert np.allclose(sample_times(0.0, 1.0, 0.3), [0, 0.3, 0.6, 0.9, 1.0])
    assert sample_times(0.0, 0.3, 0.1)[-1] == 0.3


def test_tableaus_are_the_named_ones():
    assert DP45.order == 5 and DP45.error_order == 4 and DP45.fsal
    assert DOP853.order == 8 and DOP853.stages == 12
    assert RK4.order == 4 and not RK4.adaptive


# A run whose every bit is printed: the core's qdd on a 6-link U chain, ode45 and DOP853 with
# their dense outputs at samples inside steps, and rk4.
BITWISE_RUN = """
import hashlib, numpy as np
from redysim import Chain, Workspace, forward_dynamics
from redysim.integrators.explicit import integrate
chain = Chain.uniform(6, "U", length=0.3, mass=0.5, radius=0.02)
ws, n = Workspace(chain), chain.n_dof
def rhs(t, y):
    return np.concatenate((y[n:], forward_dynamics(chain, y[:n], y[n:], ws=ws)))
y0 = np.concatenate((np.linspace(0.1, 0.6, n), np.zeros(n)))
h = hashlib.sha256()
for method, kw in (("ode45", dict(rtol=1e-6, atol=1e-8)), ("dop853", dict(rtol=1e-9, atol=1e-9)),
                   ("rk4", dict(h=1e-3))):
    sol = integrate(rhs, (0.0, 0.3), y0, method, t_eval=np.linspace(0, 0.3, 7), **kw)
    h.update(sol.y.tobytes())
    h.update(repr((sol.steps, sol.rejected, sol.nfev)).encode())
print(h.hexdigest())
"""


@pytest.mark.skipif(len(openblas_coretypes()) < 2, reason="one OpenBLAS kernel on this CPU")
def test_the_same_bits_whatever_openblas_kernel_runs():
    """The stage sums, error estimates and dense outputs leave BLAS out
    (redysim.algorithms._kernels.rk): every OpenBLAS kernel this CPU can run gives the same samples
    and counts, bit for bit. (Before, a matrix product formed each stage and Table 8's chaotic
    3-link GE-N count read 630, 636 or 650 steps from one start, by kernel.)"""
    digests = {}
    for coretype in openblas_coretypes():
        env = {**os.environ, "OPENBLAS_CORETYPE": coretype}
        out = subprocess.run([sys.executable, "-c", BITWISE_RUN], env=env, capture_output=True,
                             text=True, timeout=300, check=True)
        digests[coretype] = out.stdout.strip()
    assert len(set(digests.values())) == 1, digests


def test_compile_kernels_compiles_what_every_scheme_calls():
    """After compile_kernels (ode45 alone), DOP853 and RK4 with dense output add no signature
    to the stage-sum kernels: a timed run of any scheme compiles nothing."""
    from redysim.algorithms._kernels import rk
    from redysim.integrators.explicit import compile_kernels

    compile_kernels()
    before = {k: len(k.signatures) for k in (rk.combine, rk.error_norm)}
    for method, kw in (("dop853", {}), ("rk4", {"h": 1e-3})):
        integrate(lambda _t, y: -y, (0.0, 2e-3), [1.0, 0.5], method, t_eval=[0.0, 1e-3, 2e-3],
                  **kw)
    assert {k: len(k.signatures) for k in (rk.combine, rk.error_norm)} == before


@pytest.mark.parametrize("case_name, method, t_end, kw", [
    ("RE-U125-L1", "ode45", 0.05, {"rtol": 1e-4, "atol": 1e-6}),
    ("RE-U125-L1", "dop853", 0.02, {"rtol": 1e-8, "atol": 1e-10}),
    ("RE-U125-L1", "rk4", 0.005, {"h": 1e-5}),
    ("STUDY-R10", "ode45", 1.0, {"rtol": 1e-6, "atol": 1e-8}),   # planar: the planar kernel
    ("RE-R229-L1.02-DX1.02", "ode45", 0.2, {"rtol": 1e-4, "atol": 1e-6}),
])
def test_compiled_stepping_takes_the_same_steps_in_the_same_bits(case_name, method, t_end, kw):
    """The compiled stepping of a system against the same stepping run as Python
    (:class:`Solver` given a plain function of the public forward dynamics) on the paper's
    cases: the same steps, rejections and qdd calls, and every sample equal bit for bit."""
    from redysim import Workspace, forward_dynamics, load_case
    from redysim.algorithms.system import System
    from redysim.integrators.explicit import Solver, advance, sample_times

    case = load_case(case_name)
    chain, n = case.chain, case.chain.n_dof
    ws = Workspace(chain)

    def rhs(_t, y):
        return np.concatenate((y[n:], forward_dynamics(chain, y[:n], y[n:], ws=ws)))

    y0 = np.concatenate((case.q0, case.v0))
    ts = sample_times(0.0, t_end, t_end / 7)
    runs = []
    for make in (lambda: Solver(rhs, 0.0, y0, t_end, method, **kw),
                 lambda: Solver(System(chain), 0.0, y0, t_end, method, max_steps=50, **kw)):
        solver, samples = make(), []
        assert advance(solver, ts, on_sample=lambda _t, y, s=samples: s.append(y.copy()))[0] == 0
        c = solver.counters
        runs.append(((c.steps, c.rejected, c.nfev), np.array(samples), solver.compiled))
    assert [r[2] for r in runs] == [False, True]
    assert runs[0][0] == runs[1][0] and runs[0][0][0] > 20
    assert np.array_equal(runs[0][1], runs[1][1])


@pytest.mark.parametrize("method, kw", [("ode45", {"rtol": 1e-8, "atol": 1e-10}),
                                        ("rk45", {"rtol": 1e-8, "atol": 1e-10}),
                                        ("dop853", {"rtol": 1e-9, "atol": 1e-11}),
                                        ("rk4", {"h": 1e-3})])
@pytest.mark.parametrize("free, damping", [(True, 0.0), (False, 0.3), (True, 0.3)])
def test_floating_and_damped_motions_step_in_compiled_code_in_the_same_bits(method, kw, free,
                                                                            damping):
    """A floating tree (its quaternion's rate and projection) and joint damping step in compiled
    code (Simulator.compiled), the same steps as the Python loop and every sample, the largest
    quaternion error and the energy equal bit for bit."""
    from conftest import stable_seed
    from test_trees import random_configuration, random_tree

    model = random_tree(stable_seed("compiled-free", free), n_bodies=10, free=free, fixed=1)
    rng = np.random.default_rng(7)
    q, v = random_configuration(rng, model), rng.normal(size=model.n_v)
    a, b = _compiled_and_python_runs(model, 0.25, q0=q, v0=v, integrator=method,
                                     damping=damping, **kw)
    assert a.quaternion_error == b.quaternion_error


def _compiled_and_python_runs(model, t_end, **settings):
    """The same Simulator run stepped in compiled code and in the Python loop (each checked to
    be so): the same steps, RHS calls and every sample bit for bit; returns both."""
    from redysim.simulation import simulator

    runs = []
    for compiled in (True, False):
        sim = simulator(model, t_end, compiled=compiled, sample=0.05, **settings)
        assert sim.compiled is compiled
        runs.append(sim.run())
    a, b = runs
    assert a.status == b.status == 0 and a.steps == b.steps > 10 and a.nfev == b.nfev
    for name in ("t", "q", "v", "energy", "com"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    return a, b


def test_a_planar_chains_tip_torques_are_the_general_loads():
    """The compiled tip torques of a planar chain (the steps' own) equal the loads module's
    J^T F from the kinematics (tip_force_torques) to rounding, damping added on top."""
    from redysim import load_case
    from redysim.algorithms._kernels.planar import planar_tip_torques
    from redysim.algorithms.loads import tip_force_torques

    chain = load_case("cases/refine/pulled-R128.toml").chain
    rng = np.random.default_rng(5)
    F = np.array([4.905, -2.0, 0.7])  # (F_z does no work in the plane)
    for _ in range(3):
        q, v = rng.uniform(-1.0, 1.0, chain.n_dof), rng.normal(size=chain.n_dof)
        want = tip_force_torques(chain, q, F)
        got = np.empty(chain.n_dof)
        planar_tip_torques(chain.length, q, F, 0.0, v, got)
        assert np.abs(got - want).max() <= 1e-13 * np.abs(want).max()
        planar_tip_torques(chain.length, q, F, -0.3, v, got)
        assert np.abs(got - (want - 0.3 * v)).max() <= 1e-13 * np.abs(want).max()


@pytest.mark.parametrize("method, kw", [("ode45", {"rtol": 1e-8, "atol": 1e-10}),
                                        ("dop853", {"rtol": 1e-9, "atol": 1e-11}),
                                        ("rk4", {"h": 1e-3})])
@pytest.mark.parametrize("damping", [0.0, 0.05])
def test_a_spatial_chain_pulled_at_its_tip_steps_in_compiled_code_in_the_same_bits(method, kw,
                                                                                 damping):
    """A U chain (spatial: neither planar nor DH) pulled at its tip steps in compiled code: its
    generalized forces (the system's, which both steppings call: the tip's J^T F and the
    damping) equal the loads module's J^T F to rounding, the runs are the same bit for bit, and
    T + V - F . p_tip is kept when undamped."""
    from redysim import Chain
    from redysim.algorithms.loads import tip_force_torques
    from redysim.algorithms.system import System

    chain = Chain.uniform(6, "U", length=0.3, linear_density=2.0, radius=0.02)
    F = np.array([1.5, -0.7, 2.0])
    rng = np.random.default_rng(9)
    q0, v0 = rng.uniform(-0.8, 0.8, chain.n_dof), rng.normal(size=chain.n_dof)
    got = System(chain, tip_force=F, damping=damping).forces(0.0, q0, v0)
    want = tip_force_torques(chain, q0, F) - damping * v0
    assert np.abs(got - want).max() <= 1e-13 * np.abs(want).max()
    a, _ = _compiled_and_python_runs(chain, 0.3, q0=q0, v0=v0, integrator=method,
                                     damping=damping, tip_force=F, **kw)
    if damping:
        assert a.energy[-1] < a.energy[0]
    else:
        assert np.abs(a.delta_M).max() < (1e-4 if method == "rk4" else 1e-6)


@pytest.mark.parametrize("method, kw", [("ode45", {"rtol": 1e-8, "atol": 1e-10}),
                                        ("dop853", {"rtol": 1e-9, "atol": 1e-11}),
                                        ("rk4", {"h": 1e-3})])
@pytest.mark.parametrize("damping", [0.0, 0.02])
def test_a_pulled_chain_steps_in_compiled_code_in_the_same_bits(method, kw, damping):
    """A planar chain pulled at its tip (the case's [load] tip_force) steps in compiled code:
    the same steps as the Python loop, every sample and the energy (the force's potential in
    it) equal bit for bit; the energy balance holds."""
    from redysim import coarsen, load_case

    case = load_case("cases/refine/pulled-R128.toml")
    cz = coarsen(case.chain, links=8)
    q0, v0 = cz.to_coarse(case.q0, case.v0)
    a, _ = _compiled_and_python_runs(cz.coarse, 0.3, q0=q0, v0=v0, integrator=method,
                                     damping=damping, tip_force=case.tip_force, **kw)
    if damping:  # the damping takes energy out
        assert a.energy[-1] < a.energy[0]
    else:  # T + V - F . p_tip is conserved (rk4 at h = 1e-3: to its truncation)
        assert np.abs(a.delta_M).max() < (1e-4 if method == "rk4" else 1e-6)


def _random_step(seed: int, stages: int, n: int, h: float):
    """Random stages K (stages, n), y with half its components at zero (they carry only
    rounding noise in a run: the case the whole-vector norms are for) and y_new = y + h * noise."""
    rng = np.random.default_rng(seed)
    K = rng.normal(size=(stages, n))
    y = rng.normal(size=n)
    y[::2] = 0.0
    return K, y, y + h * rng.normal(size=n)


def test_dop853_error_norm_is_hairers_over_the_whole_vector():
    """The compiled dop853 norm against SciPy's DOP853 (Hairer's formula, an independent
    source, SciPy's own E5 and E3): the same value, in units of rtol, on random stages with half
    the components at zero; 0 for zero stages; NaN when not finite."""
    import types

    from scipy.integrate import DOP853 as SDOP853
    from scipy.integrate._ivp import dop853_coefficients as d

    from redysim.algorithms._kernels import rk

    n, rtol, atol, h = 40, 1e-9, 1e-11, 3e-3
    K, y, y_new = _random_step(5100, DOP853.E.size, n, h)
    ours = rk.error_norm(h, DOP853.E, DOP853.E3, K, DOP853.E.size, y, y_new, rtol, atol,
                         np.empty(n), np.empty(n), rk.NORM_MAX)
    scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol
    theirs = SDOP853._estimate_error_norm(types.SimpleNamespace(E5=d.E5, E3=d.E3), K, h, scale)
    assert ours == pytest.approx(rtol * theirs, rel=1e-12)
    # a zero step's stages: 0, not 0/0
    assert rk.error_norm(h, DOP853.E, DOP853.E3, np.zeros_like(K), DOP853.E.size, y, y_new,
                         rtol, atol, np.empty(n), np.empty(n), rk.NORM_MAX) == 0.0
    # not finite: NaN (the controller stops with a reason)
    K[5, 7] = np.inf  # (a stage with a nonzero weight)
    assert np.isnan(rk.error_norm(h, DOP853.E, DOP853.E3, K, DOP853.E.size, y, y_new, rtol,
                                  atol, np.empty(n), np.empty(n), rk.NORM_MAX))


def test_rk45_error_norm_is_scipys_rk45_over_the_whole_vector():
    """rk45's compiled norm against SciPy's RK45 (its own E and _estimate_error_norm, an
    independent source): the same value in units of rtol on random stages with half the
    components at zero; ode45's max norm on the same stages is larger (it is the worst
    component, not the RMS); NaN when not finite."""
    import types

    from scipy.integrate import RK45 as SRK45
    from scipy.integrate._ivp.common import norm as rms  # (SciPy's: RMS over the vector)

    from redysim.algorithms._kernels import rk
    from redysim.integrators.explicit import RK45

    n, rtol, atol, h = 40, 1e-8, 1e-10, 2e-3
    K, y, y_new = _random_step(5101, RK45.E.size, n, h)
    args = (K, RK45.E.size, y, y_new, rtol, atol, np.empty(n), np.empty(n))
    ours = rk.error_norm(h, RK45.E, np.empty(0), *args, rk.NORM_RMS)
    scale = atol + np.maximum(np.abs(y), np.abs(y_new)) * rtol
    theirs = rms(SRK45._estimate_error(types.SimpleNamespace(E=SRK45.E), K, h) / scale)
    assert ours == pytest.approx(rtol * theirs, rel=1e-12)
    assert rk.error_norm(h, RK45.E, np.empty(0), *args, rk.NORM_MAX) > 2 * ours
    K[3, 4] = np.nan
    assert np.isnan(rk.error_norm(h, RK45.E, np.empty(0), *args, rk.NORM_RMS))


def test_dop853_first_step_is_hairers():
    """dop853's first step is Hairer's HINIT, as SciPy's select_initial_step computes it."""
    from scipy.integrate._ivp.common import select_initial_step

    y0 = np.array([0.3, 0.0, 0.0, 1.0])

    def fun(t, y):
        return np.array([y[2], y[3], -np.sin(y[0]) - 0.1 * y[3], -y[1] ** 3 + np.cos(t)])

    for method, order in (("dop853", 7), ("rk45", 4)):  # (order: the error estimate's)
        for rtol in (1e-6, 1e-10):
            s = Solver(fun, 0.0, y0, 5.0, method, rtol=rtol, atol=rtol / 100)
            h = select_initial_step(fun, 0.0, y0, 5.0, 0.5, fun(0.0, y0), 1, order, rtol,
                                    rtol / 100)
            assert s.h_next == pytest.approx(h, rel=1e-12)
            assert s.counters.nfev == 2  # f(t0, y0) and HINIT's one call


@pytest.mark.parametrize("rtol", [1e-6, 1e-8, 1e-10, 1e-12])
@pytest.mark.parametrize("ours,theirs", [("dop853", "DOP853"), ("rk45", "RK45")])
def test_dop853_and_rk45_take_no_more_steps_than_scipys(rtol, ours, theirs):
    """Issue 51: on a 6-link spatial chain (12 DOF, velocities starting at zero) the core's
    dop853 and rk45 take at most 1.2x the steps of SciPy's DOP853 and RK45 on the same RHS at
    the same rtol and atol = rtol / 100 (dop853 before Hairer's norm: several times more at
    tight tolerances; ode45, MATLAB's max norm, 1.3-2x SciPy's RK45)."""
    from scipy.integrate import solve_ivp

    from redysim import Chain, Workspace, forward_dynamics

    chain = Chain.uniform(6, "U", length=0.3, mass=0.5, radius=0.02)
    ws, n = Workspace(chain), chain.n_dof

    def rhs(t, y):
        return np.concatenate((y[n:], forward_dynamics(chain, y[:n], y[n:], ws=ws)))

    y0 = np.concatenate((np.linspace(0.1, 0.6, n), np.zeros(n)))
    sol = integrate(rhs, (0.0, 0.5), y0, ours, rtol=rtol, atol=rtol / 100)
    ref = solve_ivp(rhs, (0.0, 0.5), y0, method=theirs, rtol=rtol, atol=rtol / 100)
    assert sol.steps <= 1.2 * (ref.t.size - 1)


def test_battery5_integrate_refuses_by_name():
    """Battery 5 (F5): an empty y0 raised numpy's "zero-size array" error, hmax = 0 was ignored
    silently, hmax < 0 was blamed on the tolerances, a complex rhs was cast to its real part
    with a warning, and the other refusals were plain ValueErrors: now SettingsError for a
    setting, StateError for y0 and rhs (both still ValueErrors)."""
    from redysim.errors import SettingsError, StateError

    y0 = [1.0, 0.0]
    with pytest.raises(StateError, match="^integrate: y0 is empty"):
        integrate(lambda t, y: y, (0, 1), np.empty(0))
    for hmax in (0, 0.0, -1.0, float("nan"), float("inf")):
        with pytest.raises(SettingsError, match=r"^integrate: hmax = .*must be a finite step > 0"):
            integrate(oscillator, (0, 1), y0, hmax=hmax)
    with pytest.raises(SettingsError, match="^integrate: hmax = '0.1': must be a number"):
        integrate(oscillator, (0, 1), y0, hmax="0.1")
    with pytest.raises(SettingsError, match=r"^integrate: h = -0.1: must be a finite step > 0"):
        integrate(oscillator, (0, 1), y0, "rk4", h=-0.1)
    with pytest.raises(StateError, match="^integrate: rhs.t0, y0. returns complex128 values"):
        integrate(lambda t, y: 1j * y, (0, 1), y0)
    with pytest.raises(StateError, match="^integrate: y0 has 3 entries; midpoint steps"):
        integrate(lambda t, y: -y, (0, 1), [1.0, 0.0, 0.0], "midpoint")
    for kw, field in (({"method": "x"}, "method"), ({"method": "rk4"}, "h"),
                      ({"t_span": (1, 0)}, "t_span"), ({"t_span": (0, np.nan)}, "t_span"),
                      ({"t_eval": [0.5, 0.2]}, "t_eval"), ({"t_eval": [2.0]}, "t_eval")):
        args = {"t_span": (0, 1), **kw}
        with pytest.raises(SettingsError, match=rf"^integrate: {field}"):
            integrate(oscillator, args.pop("t_span"), y0, **args)
    # hmax honoured: a bound below the steps ode45 takes alone makes it take more
    free = integrate(oscillator, (0, 1), y0, rtol=1e-6, atol=1e-9)
    bound = integrate(oscillator, (0, 1), y0, rtol=1e-6, atol=1e-9, hmax=0.01)
    assert bound.steps >= 100 > free.steps
