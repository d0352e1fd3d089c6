"""The batch thread runtime's own primitive (redysim.algorithms._kernels.spin) and its guard.

A batch's threads wait for one another on an int64 flag, spinning in compiled code without the
GIL. The flag is read by an atomic acquire load and written by an atomic add (numba has no
public atomics on the CPU: two ``numba.extending.intrinsic`` s emit LLVM's instructions), and
where that primitive does not compile or run, threads sleep instead: these pin the instructions,
the atomicity, the wait's three answers, and that the guard turns a failing primitive into
sleeping threads (not a failing batch). The runtime's behaviour (every row once, the bits, errors,
late helpers) is tests/test_batch.py's; its chunks also run here with spinning off.
"""

from __future__ import annotations

import threading

import numba
import numpy as np
import pytest

from redysim import forward_dynamics
from redysim.algorithms import threads as runtime
from redysim.algorithms._kernels import spin

needs_spin = pytest.mark.skipif(not spin.ready(), reason=f"no spinning here: {spin.UNAVAILABLE}")


@needs_spin
def test_the_flag_is_read_and_written_by_atomic_instructions():
    """Not plain loads and stores that x86 happens to keep whole: LLVM's atomic instructions, in
    the compiled code itself (a plain load racing with a store is undefined for LLVM)."""
    def llvm(kernel, *args):  # compiled afresh: numba shows no IR of code from its disk cache
        fresh = numba.njit(nogil=True)(kernel.py_func)
        fresh(*args)
        return fresh.inspect_llvm(fresh.signatures[0])

    flags, clock = np.zeros(1, dtype=np.int64), np.empty(2, dtype=np.int64)
    load, add = llvm(spin._load, flags, 0), llvm(spin._add, flags, 0, 1)
    wait = llvm(spin.wait_change, flags, 0, 0, 0, 10**9, clock, True)
    assert "load atomic i64" in load and "acquire" in load
    assert "atomicrmw add" in add and "seq_cst" in add
    assert wait.count("load atomic i64") >= 2  # (the loop's two looks at the flag)


@needs_spin
def test_adds_from_many_threads_are_not_lost():
    flags = np.zeros(1, dtype=np.int64)

    def adds():
        for _ in range(20_000):
            spin.add(flags, 0, 1)

    threads = [threading.Thread(target=adds) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert spin.load(flags, 0) == 80_000


@needs_spin
def test_the_wait_sees_another_threads_add_or_times_out():
    flags, clock = np.zeros(1, dtype=np.int64), np.empty(2, dtype=np.int64)
    assert spin.wait_change(flags, 0, 0, 1_000_000, 10**9, clock, False) == 0  # 1 ms: no change
    timer = threading.Timer(0.01, spin.add, (flags, 0, 1))
    timer.start()
    # (a wait of up to 10 s that returns 1 once the timer's thread has added; it may return -1
    # if this thread is kept off its core for 1 s, which the loop allows for)
    answers = [spin.wait_change(flags, 0, 0, 10**10, 10**9, clock, True)]
    while answers[-1] == -1:
        answers.append(spin.wait_change(flags, 0, 0, 10**10, 10**9, clock, True))
    timer.join()
    assert answers[-1] == 1 and spin.load(flags, 0) == 1


def rope(n):
    from redysim import Chain

    return Chain.uniform(n // 2, "U", length=0.1, linear_density=1.0, radius=0.01,
                         inertia="rod", name=f"U{n // 2}")


@pytest.fixture
def no_spin(monkeypatch):
    """The runtime as where the primitive failed: the guard's answer False, the helper threads
    of this process started afresh (they ask the guard when they start)."""
    monkeypatch.setattr(spin, "_READY", [False])
    monkeypatch.setattr(runtime, "_JOBS", __import__("queue").SimpleQueue())
    monkeypatch.setattr(runtime, "_HELPERS", [])
    monkeypatch.setattr(runtime, "ADAPT", False)
    monkeypatch.setattr(runtime, "CHUNK_WORK", 100)


def test_a_failing_primitive_turns_spinning_off_not_batches(monkeypatch):
    """The guard: a numba or llvmlite that refuses the intrinsics (here: their compiled
    function raising as numba's errors do) leaves ready() False with the reason, and batches run
    with sleeping threads, the same bits. Without the guard, ready() itself raises."""
    def refused(*args):
        raise TypeError("Failed in nopython mode pipeline (step: native lowering)")

    monkeypatch.setattr(spin, "_READY", [])
    monkeypatch.setattr(spin, "UNAVAILABLE", None)
    monkeypatch.setattr(spin, "_add", refused)
    assert spin.ready() is False
    assert "the spin primitive failed: TypeError" in spin.UNAVAILABLE
    flags = np.zeros(1, dtype=np.int64)
    assert spin.add(flags, 0, 3) == 3 and spin.load(flags, 0) == 3  # (plain, under the GIL)


@pytest.mark.parametrize("simd", [True, False])
def test_batches_on_sleeping_threads_have_the_bits(no_spin, simd):
    s = rope(30)
    rng = np.random.default_rng(3)
    Q, QD = rng.uniform(-1, 1, (64, 30)), rng.normal(size=(64, 30))
    one = forward_dynamics(s, Q, QD, threads=1, simd=simd)
    for threads in (2, 3):
        assert np.array_equal(forward_dynamics(s, Q, QD, threads=threads, simd=simd), one)
    assert runtime._HELPERS, "no helper thread ran"


def test_a_late_helper_is_taken_back_by_a_sleeping_caller(no_spin):
    """The caller's wait for a helper's chunk, asleep on the batch's condition, still ends by the
    deadline and takes the chunk back."""
    started, release = threading.Event(), threading.Event()

    def call(first, last, own):
        if own is None:
            if first == 0:
                assert started.wait(60), "no helper thread ran a chunk"
            return first
        started.set()
        release.wait(60)
        return first, None

    try:
        assert runtime.run_blocks(4, 2, call, commit=lambda *a: None) == [0, 1, 2, 3]
    finally:
        release.set()
