"""Batches: forward and inverse dynamics of (B, n) arrays, row for row the single calls
(forward dynamics with ``simd=False``; the SIMD tiles are tests/test_tiles.py's).

The expected values are the single calls' own results (one state at a time, through the checked
public functions), so these tests pin the batch's row handling, threading and checks; the
single calls' correctness is the other files' business.
"""

from __future__ import annotations

import re

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


# --------------------------------------------------------------------------- threads A batch's rows
# go out in chunks from a shared counter: the calling thread takes chunks until none are left,
# helper threads take chunks when they get to run (redysim.algorithms.threads.run_blocks). These
# pin what that must not change: every row done, each row's bits whatever the chunking and whoever
# ran it, errors raised on a helper reaching the caller, and threads=1 one call.

CHUNKINGS = [1, 37, 250, 10**6]  # CHUNK_WORK: a chunk a row (or tile), uneven, ~, one chunk


@pytest.fixture
def idle(monkeypatch):
    """Helpers whatever they buy (a workspace pauses helpers that do not pay: on a busy test
    machine these tests would otherwise run on one thread)."""
    from redysim.algorithms import threads as runtime

    monkeypatch.setattr(runtime, "ADAPT", False)  # (no batch alone to measure its time)


@pytest.mark.parametrize("chunk_work", CHUNKINGS)
@pytest.mark.parametrize("system", SYSTEMS)
def test_every_row_is_its_single_call_whatever_the_chunks(system, chunk_work, monkeypatch,
                                                          idle):
    from redysim.algorithms import threads as runtime

    monkeypatch.setattr(runtime, "CHUNK_WORK", chunk_work)
    s = SYSTEMS[system]()
    Q, QD, TAU = states(s, 45, 8)
    singles = np.array([forward_dynamics(s, Q[i], QD[i], TAU[i]) for i in range(len(Q))])
    tau = np.array([inverse_dynamics(s, Q[i], QD[i], singles[i]) for i in range(len(Q))])
    for threads in (2, 3):
        out = np.full(QD.shape, np.nan)  # every row written
        assert forward_dynamics(s, Q, QD, TAU, threads=threads, simd=False, out=out) is out
        assert np.array_equal(out, singles)
        assert np.array_equal(inverse_dynamics(s, Q, QD, singles, threads=threads), tau)


@pytest.mark.parametrize("rows", [64, 16 * 5 + 9, 16 * 3 + 5])  # tiles; a tail tile; tail rows
@pytest.mark.parametrize("chunk_work", CHUNKINGS)
def test_the_tiles_bits_do_not_depend_on_threads_or_chunks(rows, chunk_work, monkeypatch,
                                                           idle):
    """Chunks are whole tiles from row 0 (no lane left empty but in the last tile) and the rows
    after the last tile one more chunk: the same rows run in tiles as on one thread, the same
    rows one by one, and each row has the same bits."""
    from redysim.algorithms import threads as runtime
    from redysim.algorithms._kernels import tiles
    from redysim.algorithms.dynamics import TILE_MIN_ROWS

    s = rope(30)
    Q, QD, TAU = states(s, rows, 9)
    one = forward_dynamics(s, Q, QD, TAU, threads=1)
    split = rows - rows % 16 if rows % 16 < TILE_MIN_ROWS else rows
    monkeypatch.setattr(runtime, "CHUNK_WORK", chunk_work)
    kernel, chunks = tiles.forward_tiles, []

    def spy(*args):  # the rows each call runs, in rows of Q (args[2]; a helper gets slices of it)
        at = (args[2].ctypes.data - Q.ctypes.data) // Q.strides[0]
        chunks.append((at + args[-3], at + args[-2]))
        return kernel(*args)

    monkeypatch.setattr(tiles, "forward_tiles", spy)
    for threads in (2, 3, 8):
        chunks.clear()
        out = np.full_like(Q, np.nan)
        forward_dynamics(s, Q, QD, TAU, threads=threads, out=out)
        assert np.array_equal(out, one)
        assert sorted(chunks)[0][0] == 0 and max(last for _, last in chunks) == split
        assert all(first % 16 == 0 and (last % 16 == 0 or last == split)
                   for first, last in chunks), chunks


def test_one_thread_is_one_call_on_the_calling_thread(monkeypatch):
    """threads=1: the kernels see the whole batch in one call, on the caller's thread (as
    before chunks), in tiles and in rows."""
    import threading

    from redysim.algorithms._kernels import batch, tiles

    calls = []

    def spy(name, kernel):
        def wrapped(*args):
            calls.append((name, args[-3:-1] if name == "tiles" else args[-2:],
                          threading.get_ident()))
            return kernel(*args)
        return wrapped

    monkeypatch.setattr(tiles, "forward_tiles", spy("tiles", tiles.forward_tiles))
    monkeypatch.setattr(batch, "forward_rows", spy("rows", batch.forward_rows))
    s = rope(30)
    Q, QD, _ = states(s, 16 * 3 + 5, 10)  # three tiles, then 5 rows one by one
    forward_dynamics(s, Q, QD, threads=1)
    me = threading.get_ident()
    assert calls == [("tiles", (0, 48), me), ("rows", (48, 53), me)]
    calls.clear()
    forward_dynamics(s, Q, QD, threads=1, simd=False)
    assert calls == [("rows", (0, 53), me)]


def test_an_error_on_a_helper_thread_reaches_the_caller():
    """A chunk that raises on a helper: the caller raises it; with several chunks raising, the
    lowest one's exception (as one thread would have met first)."""
    import threading

    from redysim.algorithms.threads import run_blocks

    helper_ran = threading.Event()
    ran = []

    def call(first, last, own):
        if own is None and first == 0:  # the caller's first chunk: held until a helper runs one
            assert helper_ran.wait(60), "no helper thread ran a chunk"
        elif own is not None:
            helper_ran.set()
        ran.append((first, own is None))
        if first in (3, 5):
            raise ValueError(f"chunk {first}, {'caller' if own is None else 'helper'}")
        return first

    for commit in (None, lambda first, last, result: None):
        helper_ran.clear()
        ran.clear()
        with pytest.raises(ValueError, match="chunk 3"):
            run_blocks(8, 2, lambda f, l, o, c=commit: call(f, l, o) if c is None or o is None
                       else (call(f, l, o), None), commit=commit)
        assert (0, True) in ran and any(not caller for _, caller in ran)
    # without errors: every chunk once, the values in row order, on both threads
    helper_ran.clear()
    ran.clear()
    assert run_blocks(8, 2, lambda f, l, o: call(f, l, o) if f not in (3, 5) else -f) == \
        [0, 1, 2, -3, 4, -5, 6, 7]
    assert sorted(first for first, _ in ran) == [0, 1, 2, 4, 6, 7]
    assert {caller for _, caller in ran} == {True, False}


def test_the_caller_takes_back_a_chunk_its_helper_is_late_with():
    """A helper held up in a chunk (by the OS, say) holds up nobody: the caller runs that chunk
    itself and returns; the helper's result, when it comes, is dropped."""
    import threading

    from redysim.algorithms.threads import run_blocks

    started, release = threading.Event(), threading.Event()
    committed, out = [], [None] * 6

    def call(first, last, own):
        if own is None:
            if first == 0:
                assert started.wait(60), "no helper thread ran a chunk"
            out[first] = ("caller", first)
            return first
        started.set()
        release.wait(60)  # held up until the caller has returned
        return first, ("helper", first)

    def commit(first, last, result):
        committed.append(first)
        out[first] = result

    try:
        values = run_blocks(6, 2, call, commit=commit)
    finally:
        release.set()
    assert values == list(range(6))
    assert out == [("caller", i) for i in range(6)] and committed == []


def test_a_bad_row_on_threads_is_the_lowest_bad_row(monkeypatch, idle):
    from redysim.algorithms import threads as runtime

    monkeypatch.setattr(runtime, "CHUNK_WORK", 1)  # a chunk a row: the bad rows far apart
    s = rope(8)
    Q, QD, _ = states(s, 40, 11)
    Q[33, 2] = Q[7, 1] = np.nan
    for simd in (True, False):
        with pytest.raises(StateError, match=r"state 7 of the batch.*q\[1\] = nan"):
            forward_dynamics(s, Q, QD, threads=2, simd=simd)


def test_a_batch_inside_a_batch_does_not_wait_for_busy_helpers(idle):
    """A batch run from a helper's chunk (simulate_batch rows calling batches, say): the inner
    caller works through its own chunks, whether or not a helper is free."""
    import threading

    from redysim.algorithms.threads import run_blocks

    s = rope(20)
    Q, QD, _ = states(s, 64, 12)
    want = forward_dynamics(s, Q, QD, threads=1)
    got = {}

    def outer(first, last, own):
        for i in range(first, last):
            got[i] = forward_dynamics(s, Q, QD, threads=3)

    t = threading.Thread(target=run_blocks, args=(4, 3, outer))
    t.start()
    t.join(120)
    assert not t.is_alive(), "nested batches deadlocked"
    assert sorted(got) == [0, 1, 2, 3] and all(np.array_equal(v, want) for v in got.values())


def test_helpers_are_taken_only_while_they_pay():
    """Each workspace measures, kind of batch by kind, its seconds a DOF-state alone and with
    helpers: the first two batches run alone; helpers are kept while the median of the last
    batches with them is under GAIN of the time alone (one slow batch decides nothing), else
    paused for 4, 8, 16, ... batches; a batch in REFRESH runs alone to keep that time fresh."""
    from redysim.algorithms.threads import GAIN, REFRESH, Speed

    speed = Speed()
    for per in (5.0, 1.0):  # the first two alone (the first slowed by first touches)
        assert speed.plan(2) == 1
        speed.record(False, per)
    assert speed.alone == 1.0  # (a faster batch alone is followed at once)
    assert speed.plan(2) == 2
    speed.record(True, 9.0)  # one slow batch with helpers (its helpers woke from sleep, say)
    for _ in range(REFRESH - 2):  # helpers that pay
        assert speed.plan(2) == 2
        speed.record(True, 0.6)
    assert speed.plan(2) == 2
    speed.record(True, 0.6)
    assert speed.plan(2) == 1  # the REFRESH-th: alone
    speed.record(False, 1.0)
    speed = Speed()
    speed.skip = 0
    speed.record(False, 1.0)
    pauses = []
    for _ in range(4):  # helpers that do not pay: longer and longer pauses
        for _ in range(3):
            assert speed.plan(2) == 2
            speed.record(True, GAIN * 1.0 + 0.01)
        alone = 0
        while speed.plan(2) == 1:
            speed.record(False, 1.0)
            alone += 1
        pauses.append(alone)
    assert pauses == [4, 8, 16, 32]
    for _ in range(3):  # paying again: no pause
        speed.record(True, 0.5)
        assert speed.plan(2) == 2
    assert speed.backoff == 0


def test_a_workspace_measures_each_kind_of_batch(monkeypatch):
    from redysim.algorithms import threads as runtime

    monkeypatch.setattr(runtime, "CHUNK_WORK", 100)
    s = rope(30)
    ws = Workspace(s)
    Q, QD, _ = states(s, 64, 16)
    for _ in range(3):
        forward_dynamics(s, Q, QD, ws=ws, threads=2)
        forward_dynamics(s, Q, QD, ws=ws, threads=2, simd=False)
        inverse_dynamics(s, Q, QD, QD, ws=ws, threads=2)
    assert len(ws.batch_speed) == 3
    assert all(v.alone is not None and v.alone > 0 for v in ws.batch_speed.values())
    forward_dynamics(s, Q, QD, ws=ws, threads=1)  # one thread: nothing to measure
    assert len(ws.batch_speed) == 3


def test_the_default_thread_count_follows_the_environment(monkeypatch):
    """A batch of more than one chunk reads REDYSIM_THREADS (one of one chunk runs on the
    caller without looking)."""
    from redysim.algorithms import threads as runtime
    from redysim.algorithms.threads import THREADS_VARIABLE, default_threads

    monkeypatch.setattr(runtime, "CHUNK_WORK", 100)
    monkeypatch.delenv(THREADS_VARIABLE, raising=False)
    cores = default_threads()
    assert cores >= 1
    monkeypatch.setenv(THREADS_VARIABLE, "1")
    assert default_threads() == 1
    s = rope(30)
    Q, QD, _ = states(s, 64, 13)
    assert np.array_equal(forward_dynamics(s, Q, QD), forward_dynamics(s, Q, QD, threads=2))
    for bad in ("0", "two", "-3", "1.5"):
        monkeypatch.setenv(THREADS_VARIABLE, bad)
        with pytest.raises(FieldError, match=f"REDYSIM_THREADS = '{re.escape(bad)}': must be"):
            forward_dynamics(s, Q, QD)
    monkeypatch.setenv(THREADS_VARIABLE, "two")
    assert forward_dynamics(s, Q, QD, threads=1).shape == Q.shape  # threads given: not read
    monkeypatch.setattr(runtime, "CHUNK_WORK", 10**6)
    assert forward_dynamics(s, Q, QD).shape == Q.shape  # one chunk: not read


def test_pool_workers_take_one_thread_unless_told(monkeypatch):
    pytest.importorskip("pandas")
    from redysim.algorithms.threads import THREADS_VARIABLE, default_threads
    from redysim.harness import REDYSIM_THREADS, worker_threads

    assert REDYSIM_THREADS == THREADS_VARIABLE
    monkeypatch.delenv(THREADS_VARIABLE, raising=False)
    worker_threads()
    assert default_threads() == 1
    monkeypatch.setenv(THREADS_VARIABLE, "3")
    worker_threads()
    assert default_threads() == 3


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="no fork here")
def test_a_forked_child_runs_threaded_batches():
    """The helper threads do not survive a fork: the child starts its own (os.register_at_fork),
    and its batches run (on the caller alone, were there no helpers)."""
    import os

    s = rope(30)
    Q, QD, _ = states(s, 64, 14)
    want = forward_dynamics(s, Q, QD, threads=1)
    forward_dynamics(s, Q, QD, threads=2)  # the parent's helpers exist
    pid = os.fork()
    if pid == 0:  # the child: exit 0 only if its threaded batch has the bits
        ok = False
        try:
            ok = np.array_equal(forward_dynamics(s, Q, QD, threads=2), want)
        finally:
            os._exit(0 if ok else 1)
    _, status = os.waitpid(pid, 0)
    assert os.waitstatus_to_exitcode(status) == 0
