"""How a batch's threads wait for one another for a short while, without the GIL and without
going to sleep (:mod:`redysim.algorithms.threads`; moved from :mod:`.batch`)."""

from __future__ import annotations

import sys

import numba
from numba import types

from redysim._jit import jit

# libc's sched_yield and clock_gettime, resolved by name in the process when a kernel calling
# them is compiled or loaded from the disk cache (Linux: CLOCK_MONOTONIC is 1 there). A
# sched_yield gives the core to any other thread that wants it; being opaque to the compiler,
# the calls make the loop below read its flag from memory every round.
# (With NUMBA_DISABLE_JIT, wait_change is Python and cannot call them: no spinning then.)
SPIN_OK = sys.platform == "linux" and not getattr(numba.config, "DISABLE_JIT", 0)
CLOCK_MONOTONIC = 1
sched_yield = types.ExternalFunction("sched_yield", types.int32())
clock_gettime = types.ExternalFunction("clock_gettime", types.int32(types.int32, types.uintp))


@jit
def wait_change(flags, i, value, limit_ns, away_ns, clock, polite):
    """Wait for flags[i] to differ from ``value`` (another thread writes it), without the GIL
    and without sleeping: 1 when it changed; 0 after ``limit_ns``; -1 as soon as this thread
    was kept off its core for over ``away_ns`` (another thread wanted the core). ``polite``:
    a sched_yield each round, which gives the core to any thread that wants it (a helper
    watching for work); else the core is kept (a batch's caller, whose core it is). ``clock``:
    two int64 of the calling thread's. (Waking a sleeping thread took ~60-80 us on our VMs,
    longer than a chunk of a batch: docs/design.md, "Threads under load".)"""
    addr = clock.ctypes.data
    clock_gettime(CLOCK_MONOTONIC, addr)
    start = clock[0] * 1_000_000_000 + clock[1]
    last = start
    while flags[i] == value:
        if polite:
            sched_yield()
        clock_gettime(CLOCK_MONOTONIC, addr)
        now = clock[0] * 1_000_000_000 + clock[1]
        if flags[i] != value:
            break
        if now - last > away_ns:
            return -1
        if now - start > limit_ns:
            return 0
        last = now
    return 1
