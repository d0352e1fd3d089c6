"""A run's fixed cost cut without changing a bit (docs/design.md, "A run"): the samples' energy
and centre of mass past the door's checks and numba's dispatch are the checked path's, a state
that is not finite still stops a run with the checked path's message, and a kernel pinned past
numba's dispatch re-dispatches when its arguments' types change."""

from __future__ import annotations

import numba
import numpy as np
import pytest
from conftest import stable_seed
from test_ball import ball_robot, random_state
from test_passive import sprung_arm

from redysim import energy
from redysim._jit import INTERNALS_OK, JIT_ENABLED, Pinned
from redysim.algorithms.system import System
from redysim.errors import StateError
from redysim.io.scenarios import load_scenario
from redysim.simulation import simulate, simulator


def _runs():
    """(model, keywords of simulator()) of three systems: the UR5 falling (no passive forces),
    a floating robot with ball joints, damped (its work W rides in the state), and a sprung
    arm (the springs' potential in E)."""
    sc = load_scenario("UR5-FALL")
    robot = ball_robot()
    q0, v0, _ = random_state(np.random.default_rng(stable_seed("fixed-cost-robot")), robot)
    return {"ur5": (sc.model, dict(q0=sc.q0, v0=sc.v0)),
            "robot": (robot, dict(q0=q0, v0=v0, damping=0.3)),
            "arm": (sprung_arm(), dict(q0=[0.3, 0.2, -0.1, 0.4, 0.1],
                                       v0=[1.0, -1.0, 0.5, 0.3, 0.2]))}


@pytest.mark.parametrize("name", ["ur5", "robot", "arm"])
def test_a_runs_samples_are_the_checked_energy_and_com_bit_for_bit(name):
    """Each sample's E and com are those of System.energy_and_com (a fresh system: the door's
    checks, numba's dispatch) at the sample's own q and v, and, without potentials other than
    gravity's, of the public energy's T + V; E0 too."""
    model, kw = _runs()[name]
    run = simulate(model, 0.2, integrator="ode45", rtol=1e-6, atol=1e-8, **kw)
    assert run.status == 0 and run.t.size == 11
    fresh = System(model, damping=kw.get("damping", 0.0))
    for i in range(run.t.size):
        q, v = run.q[i].copy(), run.v[i].copy()
        E, com = fresh.energy_and_com(q, v)
        assert run.energy[i] == E, (i, run.energy[i], E)
        assert np.array_equal(run.com[i], com), (i, run.com[i], com)
        if name == "ur5":
            T, V = energy(model, q, v)
            assert run.energy[i] == T + V
    assert run.E0 == fresh.energy_and_com(run.q[0].copy(), run.v[0].copy())[0]


@pytest.mark.parametrize("bad", [np.nan, np.inf])
@pytest.mark.parametrize("where", ["q", "v"])
def test_a_sample_that_is_not_finite_raises_the_checked_paths_error(bad, where):
    """A state the run produced that is not finite: run_energy_and_com raises the very
    StateError (message included) that the checked energy_and_com raises."""
    model, kw = _runs()["robot"]
    system = simulator(model, 0.2, **kw).system  # (y = (q, v, W): W after v)
    y = system.initial_state(kw["q0"], kw["v0"])
    nq = system.n_q
    y[2 if where == "q" else nq + 1] = bad
    with pytest.raises(StateError) as checked:
        system.energy_and_com(y[:nq], y[nq:system.motion_size])
    with pytest.raises(StateError) as run:
        system.run_energy_and_com(y)
    assert str(run.value) == str(checked.value) and where in str(run.value)


def test_a_sample_of_another_layout_goes_the_checked_way():
    """A y that is not a C-contiguous writable float64 vector (an engine's stepper's, say) gets
    the checked path's answer, the same bits."""
    model, kw = _runs()["ur5"]
    system = System(model)
    y = system.initial_state(kw["q0"], kw["v0"])
    E, com = system.energy_and_com(y[:system.n_q], y[system.n_q:])
    strided = np.repeat(y, 2)[::2]
    readonly = y.copy()
    readonly.flags.writeable = False
    for other in (strided, readonly, y):
        E2, com2 = system.run_energy_and_com(other)
        assert E2 == E and np.array_equal(com2, com)


@numba.njit(cache=False)
def _scaled_sum(x, scale=2.0):
    return x.sum() * scale


@pytest.mark.skipif(not (INTERNALS_OK and JIT_ENABLED), reason="the dispatch bypass is off")
def test_a_pinned_kernel_re_dispatches_when_its_argument_types_change():
    """Pinned: the first call's overload past the dispatch (its omitted default filled in), the
    same answer; a key with another object whose type differs (a strided, then an int vector)
    is typed again, compiled by numba's dispatch, and answered right, never unboxed as the
    first type."""
    pinned = Pinned(_scaled_sum)
    a = np.arange(6.0)
    assert pinned.call((a,), a) == 30.0  # (compiled by numba's dispatch, then pinned)
    assert pinned.entry is not None
    assert pinned.call((a,), a) == 30.0
    first = pinned.entry
    assert pinned.omitted == (2.0,)
    b = np.arange(12.0)[::2]  # another layout: numba's type 'A', not 'C'
    assert pinned.call((b,), b) == 2.0 * b.sum()
    assert pinned.entry is not first
    c = np.arange(5, dtype=np.int64)
    assert pinned.call((c,), c) == 20.0
    assert pinned.call((a,), a) == 30.0
