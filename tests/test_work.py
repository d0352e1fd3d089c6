"""The work of the forces without a potential, stepped with the motion: E(t) - W(t) = E(0).

A run's state carries W = int v . tau_nc dt (the damping's, a ``tau`` given without
``potential``) after (q, v) when the system has such forces (docs/design.md, "Passive
elements"); the core's Runge-Kutta steps integrate it by the same stages, its error left out of
the step control. Checked: the compiled and the Python stepping give the same bits (W too) on a
damped, sprung arm and a damped floating robot with ball joints; the balance E - W - E0 holds to
the tolerance and tightens with it; W against closed forms (a damped, sprung hinge's
-int c v^2 dt by quadrature of its exact motion; a constant torque's tau (q - q0)); the motion's
steps and bits are those of the same system stepped without W; a resumed run equals an unbroken
one bit for bit; the steppers that do not carry W say so.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from conftest import stable_seed
from scipy.integrate import quad
from test_ball import ball_robot, random_state
from test_integrate import _compiled_and_python_runs
from test_passive import sprung_arm

from redysim import Chain
from redysim.algorithms.system import System
from redysim.errors import SettingsError
from redysim.integrators.explicit import advance, make_solver
from redysim.simulation import Simulator, simulator

ARM_STATE = dict(q0=[0.3, 0.2, -0.1, 0.4, 0.1], v0=[1.0, -1.0, 0.5, 0.3, 0.2])


def robot_and_state():
    """The floating robot of tests/test_ball.py (ball hips and ankles, a U-jointed arm) from a
    random state, damped at every joint (its free joint too)."""
    model = ball_robot()
    q0, v0, _ = random_state(np.random.default_rng(stable_seed("work-robot")), model)
    return model, dict(q0=q0, v0=v0, damping=0.3)


SYSTEMS = {"arm": lambda: (sprung_arm(), dict(ARM_STATE)), "robot": robot_and_state}


@pytest.mark.parametrize("method, kw", [("ode45", {"rtol": 1e-8, "atol": 1e-10}),
                                        ("dop853", {"rtol": 1e-9, "atol": 1e-11}),
                                        ("rk4", {"h": 2e-3})])
@pytest.mark.parametrize("name", SYSTEMS)
def test_compiled_and_python_stepping_give_the_same_work(name, method, kw):
    """Same steps, same samples bit for bit (_compiled_and_python_runs), W and the balance
    too; and W is a real share of the energy (the damping took it)."""
    model, state = SYSTEMS[name]()
    a, b = _compiled_and_python_runs(model, 0.3, integrator=method, **state, **kw)
    assert a.work is not None and a.work_note == ""
    assert np.array_equal(a.work, b.work) and np.array_equal(a.delta_M, b.delta_M)
    assert a.work[0] == 0.0 and a.work[-1] < -0.1  # [J]: dissipated, never gained
    assert np.all(np.diff(a.work) <= 0.0)


@pytest.mark.parametrize("method", ["ode45", "dop853"])
@pytest.mark.parametrize("name", SYSTEMS)
def test_the_energy_balance_holds_to_the_tolerance_and_tightens_with_it(name, method):
    """max |E - W - E0| <= rtol |W(t_end)| at rtol 1e-6 and 1e-9 (atol rtol / 100), at least
    30x smaller at 1e-9 than at 1e-6 (measured: the arm 1050x (ode45) and 165x (dop853), the
    robot 118x and 55x, its balance at rounding, ~1e-12 J of E ~ 20 J, by 1e-9), and delta_M
    is that balance per unit mass; E - E0 alone is W's size."""
    model, state = SYSTEMS[name]()
    worst = {}
    for rtol in (1e-6, 1e-9):
        run = simulator(model, 1.0, integrator=method, rtol=rtol, atol=rtol / 100,
                        sample=0.01, **state).run()
        assert run.status == 0, run.message
        balance = run.energy - run.work - run.E0
        assert np.abs(run.delta_M * model.total_mass - balance).max() <= 1e-12 * abs(run.E0)
        worst[rtol] = np.abs(balance).max()
        assert worst[rtol] <= rtol * abs(run.work[-1]), (rtol, worst[rtol], run.work[-1])
        assert np.abs(run.energy - run.E0).max() > 0.5 * abs(run.work[-1])
    assert worst[1e-9] < worst[1e-6] / 30, worst


def test_a_damped_sprung_hinges_work_is_the_quadrature_of_its_exact_motion():
    """A hinge without gravity, I thdd + c thd + k th = 0 (I = m L^2 / 3 for a uniform rod about
    its end): its exact motion e^{-at} (A cos wt + B sin wt) gives W(t) = -int_0^t c thd^2 by
    scipy's quad; the run's W (dop853 at rtol 1e-11) agrees to 1e-9 J, its q to 1e-9 rad."""
    m, L, c, k = 1.5, 0.8, 0.2, 2.0
    hinge = Chain.uniform(1, "R", length=L, mass=m, gravity=(0.0, 0.0, 0.0))
    hinge = hinge.with_passive(damping=c, stiffness=k)
    inertia = m * L * L / 3
    th0, v0 = 0.5, 0.3
    a = c / (2 * inertia)
    w = math.sqrt(k / inertia - a * a)
    A, B = th0, (v0 + a * th0) / w

    def theta(t):
        return math.exp(-a * t) * (A * math.cos(w * t) + B * math.sin(w * t))

    def rate(t):
        return math.exp(-a * t) * ((B * w - a * A) * math.cos(w * t)
                                   - (A * w + a * B) * math.sin(w * t))

    run = simulator(hinge, 4.0, q0=[th0], v0=[v0], integrator="dop853", rtol=1e-11,
                    atol=1e-13, sample=0.25).run()
    assert run.status == 0 and run.work is not None
    want = [-quad(lambda s: c * rate(s) ** 2, 0.0, t, epsabs=1e-14, epsrel=1e-13, limit=200)[0]
            for t in run.t]
    assert np.abs(run.q[:, 0] - [theta(t) for t in run.t]).max() < 1e-9
    assert np.abs(run.work - want).max() < 1e-9
    assert want[-1] < -0.5 * (0.5 * inertia * v0 ** 2 + 0.5 * k * th0 ** 2)  # most of E0


def test_a_torque_without_potential_is_recorded_and_one_with_it_is_not():
    """A constant torque tau on a free hinge does W = tau (q - q0) (a closed form); given with
    its potential -tau q it is conservative: W stays 0 and E (with the potential) is kept."""
    hinge = Chain.uniform(1, "R", length=0.5, mass=1.0, gravity=(0.0, 0.0, 0.0))
    tau = 0.7

    def torque(_t, _q, _v):
        return np.array([tau])

    run = simulator(hinge, 1.0, q0=[0.2], v0=[0.1], tau=torque, rtol=1e-10,
                    atol=1e-12, sample=0.1).run()
    assert run.status == 0 and run.work is not None
    assert np.abs(run.work - tau * (run.q[:, 0] - 0.2)).max() < 1e-9
    assert np.abs(run.delta_M).max() < 1e-9
    held = simulator(hinge, 1.0, q0=[0.2], v0=[0.1], tau=torque,
                     potential=lambda q: -tau * q[0], rtol=1e-10, atol=1e-12,
                     sample=0.1).run()
    assert not held.work.any() and np.abs(held.energy - held.E0).max() < 1e-9
    assert np.array_equal(held.q, run.q)  # the same motion, the same steps


@pytest.mark.parametrize("name", SYSTEMS)
def test_the_motion_is_the_same_with_or_without_the_work_in_the_state(name):
    """W rides outside the step control: the same system stepped from (q0, v0) and from (q0,
    v0, 0) takes the same steps to the same bits of (q, v), in compiled code and in Python."""
    model, state = SYSTEMS[name]()
    damping = state.pop("damping", 0.0)
    for compiled in (True, False):
        ends = []
        for work in (False, True):
            system = System(model, damping=damping)
            y0 = system.initial_state(state["q0"], state["v0"], work=work)
            assert y0.size == system.motion_size + work
            solver = make_solver(system, 0.0, y0, 0.4, "ode45", rtol=1e-7, atol=1e-9,
                                 compiled=compiled)
            assert solver.compiled is compiled
            assert advance(solver, [0.4], on_step=lambda s, p=system.project: p(s.y)) == (
                0, "ok")
            ends.append((solver.counters, solver.y[:system.motion_size].copy()))
        assert ends[0][0] == ends[1][0] and ends[0][0].steps > 10
        assert np.array_equal(ends[0][1], ends[1][1])


def test_a_resumed_run_keeps_its_work_bit_for_bit():
    """A checkpoint (the solver's state after a step, its samples taken) resumed by a new
    Simulator gives the unbroken run's later samples, W and the balance, bit for bit."""
    model, state = robot_and_state()
    saved = []

    def keep(solver):
        if solver.counters.steps >= 40 and not saved:
            st = solver.state()
            st.sampled_until = solver.t
            saved.append(st)

    whole = simulator(model, 0.5, sample=0.02, rtol=1e-7, atol=1e-9, compiled=False,
                      **state).run(on_step=keep)
    st = saved[0]
    assert st.y.size == model.n_q + model.n_v + 1 and st.y[-1] < 0.0  # W in the checkpoint
    rest = simulator(model, 0.5, sample=0.02, rtol=1e-7, atol=1e-9, state=st, **state).run()
    tail = whole.t > st.t
    assert rest.t.size == tail.sum() > 5
    for key in ("t", "q", "v", "energy", "work", "delta_M"):
        assert np.array_equal(getattr(rest, key), getattr(whole, key)[tail]), key
    assert (rest.steps, rest.nfev) == (whole.steps, whole.nfev)
    n = model.n_q + model.n_v
    with pytest.raises(SettingsError, match=rf"state = 'y of {n} components'.*steps {n + 1} "
                                            r"\(q, v, and the work W\)"):
        simulator(model, 0.5, state=replace(st, y=st.y[:-1], f=st.f[:-1]), **state)


@pytest.mark.parametrize("integrator", ["midpoint", "scipy-RK45"])
def test_a_stepper_without_the_work_says_so(integrator):
    """The implicit midpoint (its y is (q, v)) and SciPy's solvers (their error norm would
    count W) do not carry it: ``work`` is None, ``work_note`` names the forces and the stepper,
    and delta_M is the energy's change. A conservative system's W is zeros with any stepper of
    ours, and no note."""
    model = sprung_arm()
    run = simulator(model, 0.05, integrator=integrator, rtol=1e-6, atol=1e-8,
                    q0=ARM_STATE["q0"]).run()
    assert run.status == 0 and run.work is None
    assert f"the work of damping is not recorded by {integrator}" in run.work_note
    assert np.array_equal(run.delta_M, (run.energy - run.E0) / model.total_mass)
    rigid = simulator(model.without_passive(), 0.05, q0=ARM_STATE["q0"]).run()
    assert rigid.work_note == "" and not rigid.work.any()
    sim = Simulator(System(model), 0.05, integrator="ode45")
    assert sim.y0.size == model.n_q + model.n_v + 1


def test_a_providers_qdd_in_our_integrator_carries_the_work_too():
    """A system whose accelerations come from a provider (an engine's qdd is one; here the
    core's forward dynamics as a Python function) is stepped in Python, its forces still the
    system's: W is recorded, and agrees with the compiled run's to rounding."""
    from redysim import forward_dynamics

    model = sprung_arm()
    kw = dict(integrator="ode45", rtol=1e-9, atol=1e-11, sample=0.05, **ARM_STATE)
    core = simulator(model, 0.5, **kw).run()
    provided = simulator(model, 0.5, qdd=lambda q, v, tau: forward_dynamics(model, q, v, tau),
                         **kw).run()
    assert not provided.work_note and provided.work is not None
    assert np.abs(provided.work - core.work).max() < 1e-10
    assert np.abs(provided.delta_M).max() < 1e-9
