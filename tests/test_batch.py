"""Batches: forward and inverse dynamics of (B, n) arrays, row for row the single calls
(forward dynamics with ``simd=False``; the SIMD tiles are tests/test_tiles.py's).

The expected values are the single calls' own results (one state at a time, through the checked
public functions), so these tests pin the batch's row handling, threading and checks; the
single calls' correctness is the other files' business.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_trees import random_configuration, random_tree

import redysim
from redysim import StateError, Workspace, forward_dynamics, inverse_dynamics
from redysim.errors import FieldError


def rope(n_links=40, joint="U"):
    return redysim.Chain.uniform(n_links, joint, length=0.02, linear_density=61.6538,
                                 radius=0.05, inertia="rod")


def states(system, rows, seed):
    rng = np.random.default_rng(seed)
    if isinstance(system, redysim.Model):
        Q = np.array([random_configuration(rng, system) for _ in range(rows)])
    else:
        Q = rng.uniform(-2.0, 2.0, (rows, system.n_q))  # angles beyond pi/4 too
    return Q, rng.uniform(-1, 1, (rows, system.n_v)), rng.uniform(-1, 1, (rows, system.n_v))


SYSTEMS = {"U rope": lambda: rope(), "planar R rope": lambda: rope(30, "R"),
           "tree, free base": lambda: random_tree(3), "tree, fixed base":
           lambda: random_tree(4, free=False)}


@pytest.mark.parametrize("threads", [1, 2, None])
@pytest.mark.parametrize("system", SYSTEMS)
def test_a_batch_is_the_single_calls_bit_for_bit(system, threads):
    s = SYSTEMS[system]()
    Q, QD, TAU = states(s, 37, 1)  # 37: blocks of unequal length over the threads
    ws = Workspace(s)
    singles = np.array([forward_dynamics(s, Q[i], QD[i], TAU[i]) for i in range(len(Q))])
    # simd=False: the rows through the single-state kernel (the SIMD tiles, which agree to
    # rounding, are tests/test_tiles.py's)
    assert np.array_equal(forward_dynamics(s, Q, QD, TAU, ws=ws, threads=threads, simd=False),
                          singles)
    # one tau for every state, and none
    for tau in (TAU[5], None):
        got = forward_dynamics(s, Q, QD, tau, threads=threads, simd=False)
        want = np.array([forward_dynamics(s, Q[i], QD[i], tau) for i in range(len(Q))])
        assert np.array_equal(got, want)
    # inverse dynamics of the batch, row for row
    tau = inverse_dynamics(s, Q, QD, singles, ws=ws, threads=threads)
    want = np.array([inverse_dynamics(s, Q[i], QD[i], singles[i]) for i in range(len(Q))])
    assert np.array_equal(tau, want)


def test_a_batch_takes_lists_out_and_one_row():
    s = rope(6)
    Q, QD, TAU = states(s, 3, 2)
    out = np.empty_like(Q)
    got = forward_dynamics(s, Q.tolist(), QD.tolist(), TAU.tolist(), out=out)
    assert got is out
    assert np.array_equal(out[1], forward_dynamics(s, Q[1], QD[1], TAU[1]))
    assert forward_dynamics(s, Q[:1], QD[:1]).shape == (1, s.n_v)


def test_the_workspace_keeps_one_scratch_a_thread():
    s = rope(8)
    ws = Workspace(s)
    before = ws.nbytes
    Q, QD, _ = states(s, 16, 3)
    forward_dynamics(s, Q, QD, ws=ws, threads=2, simd=False)
    first, second = ws.scratches(2)
    assert first is ws.scratch and second.shape == ws.scratch.shape
    assert ws.nbytes == before + second.nbytes


@pytest.mark.parametrize("args, fragment", [
    (lambda Q, QD: (Q[:, :-1], QD), "q has shape (5, 15)"),
    (lambda Q, QD: (Q, QD[:4]), "v has shape (4, 16)"),
    (lambda Q, QD: (Q, QD[:, :, None]), "v has shape (5, 16, 1)"),
    (lambda Q, QD: (Q.astype(complex), QD), "need int or float"),
])
def test_a_batch_of_the_wrong_shape_is_refused_naming_it(args, fragment):
    s = rope(8)
    Q, QD, _ = states(s, 5, 4)
    with pytest.raises(StateError) as exc:
        forward_dynamics(s, *args(Q, QD))
    assert fragment in str(exc.value)


def test_a_bad_state_in_a_batch_is_named_by_its_row():
    s = rope(8)
    Q, QD, _ = states(s, 6, 5)
    Q[4, 3] = np.nan
    for threads in (1, 2):
        with pytest.raises(StateError, match=r"state 4 of the batch.*q\[3\] = nan"):
            forward_dynamics(s, Q, QD, threads=threads)
    with pytest.raises(StateError, match=r"q\[4, 3\] = nan.*state 4 of the batch"):
        inverse_dynamics(s, Q, QD, QD)


def test_batch_settings_are_checked():
    s = rope(8)
    Q, QD, _ = states(s, 4, 6)
    with pytest.raises(FieldError, match="threads"):
        forward_dynamics(s, Q, QD, threads=0)
    with pytest.raises(ValueError, match="batches run 'rge-a' only"):
        forward_dynamics(s, Q, QD, method="ge-n")
    with pytest.raises(StateError, match=r"out \(shape \(3, 16\)"):
        forward_dynamics(s, Q, QD, out=np.empty((3, 16)))


@pytest.mark.parametrize("threads", [1, 2])
def test_a_batch_of_motions_is_each_rows_own_simulation(threads):
    """simulate_batch: row i's motion is simulate's from row i, sample for sample, with its own
    steps (the rows start apart, so their step sizes differ)."""
    s = rope(10)
    rng = np.random.default_rng(7)
    Q0 = rng.uniform(-0.5, 0.5, (3, s.n_q))
    V0 = rng.uniform(-0.5, 0.5, (3, s.n_v))
    sims = redysim.simulate_batch(s, 0.05, q0=Q0, v0=V0, threads=threads, rtol=1e-6, atol=1e-8)
    for i, sim in enumerate(sims):
        one = redysim.simulate(s, 0.05, q0=Q0[i], v0=V0[i], rtol=1e-6, atol=1e-8)
        assert np.array_equal(sim.q, one.q) and np.array_equal(sim.v, one.v)
        assert (sim.steps, sim.nfev) == (one.steps, one.nfev)
    assert len({sim.steps for sim in sims}) > 1


def test_a_bad_row_of_a_batch_of_motions_is_named():
    s = rope(4)
    Q0 = np.zeros((3, s.n_q))
    Q0[2, 1] = np.inf
    with pytest.raises(StateError, match=r"row 2 of q0 and v0: q\[1\] = inf"):
        redysim.simulate_batch(s, 0.01, q0=Q0, threads=2)
    with pytest.raises(redysim.SettingsError, match="progress"):
        redysim.simulate_batch(s, 0.01, q0=Q0[:2], progress=print)
