"""A flag that the batch threads wait on for a short while, without the GIL and without
sleeping (:mod:`redysim.algorithms.threads`): the runtime's one primitive of shared memory.

Contract. ``flags`` is a 1-D int64 array shared by threads. Every write of one of its elements
goes through :func:`add` (an atomic read-modify-write, sequentially consistent) and every read
through :func:`load` (an acquire load), and :func:`wait_change` reads it the same way: a thread
that sees a value also sees what its writer did before writing it, by the memory model rather
than by x86's habit of keeping aligned loads whole (for LLVM a plain load racing with a store
is undefined, and it may hoist a plain load out of a loop). Spin on a flag only where
:func:`ready`: it is False where there is no spinning here (not Linux; ``NUMBA_DISABLE_JIT``; a
numba or llvmlite that refuses the two intrinsics below), and a thread must then wait asleep
(``threading``), never spin in Python (a Python loop holds the GIL that the thread it waits for
needs).

Why in a box (STYLE 19 of the team's notes). numba has no public atomic operations on the CPU.
:func:`load_acquire` and :func:`add_seq_cst` are ``numba.extending.intrinsic`` s (numba's
supported door for such code) emitting LLVM's ``load atomic ... acquire`` and ``atomicrmw add
... seq_cst`` through llvmlite's IRBuilder (``load_atomic``, ``atomic_rmw``), known to work with
numba 0.68 and llvmlite 0.45. ``sched_yield`` and ``clock_gettime`` are libc's, resolved by name
when a kernel calling them is compiled or loaded from numba's disk cache (CLOCK_MONOTONIC is 1
on Linux). :func:`ready` compiles and tries them once; a failure turns spinning off, the reason
in :data:`UNAVAILABLE`, instead of failing a batch (``tests/test_threads.py`` fails if that guard
goes).
"""

from __future__ import annotations

import sys
import threading

import numba
import numpy as np
from numba import types
from numba.core import cgutils
from numba.extending import intrinsic
from numba.np.arrayobj import make_array

from redysim._jit import JIT_ENABLED, OPTIONS, jit

CLOCK_MONOTONIC = 1
sched_yield = types.ExternalFunction("sched_yield", types.int32())
clock_gettime = types.ExternalFunction("clock_gettime", types.int32(types.int32, types.uintp))


def _slot(context, builder, sig, args):
    """A pointer to ``args[0][args[1]]`` (a 1-D int64 array, an index)."""
    array = make_array(sig.args[0])(context, builder, args[0])
    return cgutils.get_item_pointer(context, builder, sig.args[0], array, [args[1]])


def _flags(flags, i) -> bool:
    return (isinstance(flags, types.Array) and flags.dtype == types.int64 and flags.ndim == 1
            and isinstance(i, types.Integer))


@intrinsic
def load_acquire(typingctx, flags, i):
    """flags[i], by an atomic load with acquire ordering."""
    if not _flags(flags, i):
        return None

    def codegen(context, builder, sig, args):
        return builder.load_atomic(_slot(context, builder, sig, args), "acquire", 8)
    return types.int64(flags, i), codegen


@intrinsic
def add_seq_cst(typingctx, flags, i, delta):
    """flags[i] += delta atomically (sequentially consistent); the new value."""
    if not (_flags(flags, i) and isinstance(delta, types.Integer)):
        return None

    def codegen(context, builder, sig, args):
        step = context.cast(builder, args[2], sig.args[2], types.int64)
        old = builder.atomic_rmw("add", _slot(context, builder, sig, args), step, "seq_cst")
        return builder.add(old, step)
    return types.int64(flags, i, delta), codegen


# From Python the flag is read and written holding the GIL: a batch's caller that posts a batch
# keeps its turn and takes the first chunk before a watching helper can (it needs the GIL too)
keep_gil = numba.njit(**{**OPTIONS, "nogil": False})


@keep_gil
def _load(flags, i):
    return load_acquire(flags, i)


@keep_gil
def _add(flags, i, delta):
    return add_seq_cst(flags, i, delta)


def load(flags, i: int) -> int:
    """flags[i]: an atomic load where :func:`ready`, else a plain one (no thread then reads the
    flag without the GIL)."""
    return int(_load(flags, i)) if ready() else int(flags[i])


def add(flags, i: int, delta: int) -> int:
    """flags[i] += delta, atomically where :func:`ready`; the new value (else a plain numpy
    update: no thread then reads the flag without the GIL, and one lost between two threads
    only leaves it changed)."""
    if ready():
        return int(_add(flags, i, delta))
    flags[i] += delta
    return int(flags[i])


@jit
def wait_change(flags, i, value, limit_ns, away_ns, clock, polite):
    """Wait for flags[i] to differ from ``value`` (another thread :func:`add` s to it), without
    the GIL and without sleeping: 1 when it changed; 0 after ``limit_ns``; -1 as soon as this
    thread was kept off its core for over ``away_ns`` (another thread wanted the core).
    ``polite``: a sched_yield each round, which gives the core to any thread that wants it (a
    helper watching for work); else the core is kept (a batch's caller, whose core it is).
    ``clock``: two int64 of the calling thread's."""
    addr = clock.ctypes.data
    clock_gettime(CLOCK_MONOTONIC, addr)
    start = clock[0] * 1_000_000_000 + clock[1]
    last = start
    while load_acquire(flags, i) == value:
        if polite:
            sched_yield()
        clock_gettime(CLOCK_MONOTONIC, addr)
        now = clock[0] * 1_000_000_000 + clock[1]
        if load_acquire(flags, i) != value:
            break
        if now - last > away_ns:
            return -1
        if now - start > limit_ns:
            return 0
        last = now
    return 1


UNAVAILABLE: str | None = (  # why there is no spinning here, or None (ready() decides)
    "not Linux" if sys.platform != "linux" else None if JIT_ENABLED else "NUMBA_DISABLE_JIT")
_READY: list[bool] = []  # ready()'s answer, once known
_LOCK = threading.Lock()


def ready() -> bool:
    """True when the atomic flag and its wait run here (compiled, or loaded from numba's cache,
    and tried, on the first call): threads may spin on a flag. Else False, the reason in
    :data:`UNAVAILABLE`."""
    if not _READY:
        with _LOCK:
            if not _READY:
                _READY.append(_try())
    return _READY[0]


def _try() -> bool:
    global UNAVAILABLE
    if UNAVAILABLE is not None:
        return False
    try:
        flags, clock = np.zeros(1, dtype=np.int64), np.empty(2, dtype=np.int64)
        if _add(flags, 0, 2) != 2 or _load(flags, 0) != 2 or \
                wait_change(flags, 0, 0, 0, 10**9, clock, True) != 1:
            raise RuntimeError("the flag did not read back what was written")
    except Exception as exc:  # (numba's and llvmlite's errors derive from Exception)
        UNAVAILABLE = f"the spin primitive failed: {type(exc).__name__}: {exc}"
        return False
    return True
