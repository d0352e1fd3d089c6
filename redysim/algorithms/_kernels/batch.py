"""Many states per call: the single-state dynamics run row by row in compiled code.

A batch is (B, n) arrays, one state a row. :func:`forward_rows` and :func:`inverse_rows` take rows
``first`` to ``last - 1`` of them through the same compiled passes as one call of
:func:`redysim.forward_dynamics` (:mod:`.entry`) or :func:`redysim.inverse_dynamics`, on one
workspace's packed arrays and one scratch array, without returning to Python between rows; the
results are those of the single calls bit for bit. :mod:`redysim.algorithms.dynamics` splits a
batch's rows over threads, each with its own scratch (the kernels release the GIL).

A serial chain's forward dynamics runs its states in SIMD tiles instead (:mod:`.tiles`), unless
asked for these rows' bits (:func:`redysim.forward_dynamics`, ``simd=False``).

``TAU`` (forward) has B rows or one (the same joint forces, zeros when none are given, for every
state). Both return -1, or the first row whose result is not finite or whose lengths do not match
(its single call then says why; :mod:`redysim.algorithms.dynamics` checks the shapes before).

:func:`wait_change` is how the batch's threads wait for one another for a short while without
the GIL and without going to sleep (docs/design.md, "Threads under load").
"""

from __future__ import annotations

import sys

import numba
from numba import types

from redysim._jit import jit, jit_borrowed

from .entry import (
    F_BASE_ACCEL,
    H_NV,
    bundles,
    dh_entry,
    dh_inverse_entry,
    planar_entry,
    rge_a_entry,
)
from .inverse_dynamics import rnea_backward
from .kinematics import kinematics

rge_a_call = jit_borrowed(rge_a_entry)
planar_call = jit_borrowed(planar_entry)
dh_call = jit_borrowed(dh_entry)
dh_inverse_call = jit_borrowed(dh_inverse_entry)


@jit_borrowed
def forward_rows(fdata, idata, Q, QD, TAU, scratch, QDD, first, last):
    """QDD[i] = qdd(Q[i], QD[i], TAU[i] or TAU[0]) by RGE-A, for first <= i < last (module
    docstring)."""
    every = TAU.shape[0] > 1
    for i in range(first, last):
        if rge_a_call(fdata, idata, Q[i], QD[i], TAU[i] if every else TAU[0], scratch,
                      QDD[i]) != 0.0:
            return i
    return -1


@jit_borrowed
def planar_rows(fdata, idata, Q, QD, TAU, scratch, QDD, first, last):
    """:func:`forward_rows` by the planar kernel (a planar chain). A function of its own rather
    than a flag of :func:`forward_rows`: one function calling both kernels compiled both, ~20 s
    on first use, and a factory of the two would give numba's disk cache two functions of one
    name."""
    every = TAU.shape[0] > 1
    for i in range(first, last):
        if planar_call(fdata, idata, Q[i], QD[i], TAU[i] if every else TAU[0], scratch,
                       QDD[i]) != 0.0:
            return i
    return -1


@jit_borrowed
def dh_rows(fdata, idata, Q, QD, TAU, scratch, QDD, first, last):
    """:func:`forward_rows` by the DH kernel (a robot in DH form; a function of its own, as
    :func:`planar_rows` is)."""
    every = TAU.shape[0] > 1
    for i in range(first, last):
        if dh_call(fdata, idata, Q[i], QD[i], TAU[i] if every else TAU[0], scratch,
                   QDD[i]) != 0.0:
            return i
    return -1


@jit_borrowed
def dh_inverse_rows(fdata, idata, Q, QD, QDD, scratch, TAU, first, last):
    """:func:`inverse_rows` by the DH kernel (a robot in DH form)."""
    for i in range(first, last):
        if dh_inverse_call(fdata, idata, Q[i], QD[i], QDD[i], scratch, TAU[i]) != 0.0:
            return i
    return -1


@jit_borrowed
def inverse_rows(fdata, idata, Q, QD, QDD, scratch, TAU, first, last):
    """TAU[i] = tau(Q[i], QD[i], QDD[i]) for first <= i < last, by the kinematics pass and the
    Newton-Euler backward pass (:func:`redysim.inverse_dynamics`)."""
    h = idata
    tree, s = bundles(fdata, idata, scratch)
    base_accel = fdata[h[F_BASE_ACCEL]:h[F_BASE_ACCEL] + 3]
    nv = h[H_NV]
    for i in range(first, last):
        kinematics(tree, Q[i], QD[i], QDD[i], base_accel, s, False)
        rnea_backward(tree, s, QDD[i], TAU[i])
        bad = 0.0
        tau = TAU[i]
        for j in range(nv):
            bad += tau[j] * 0.0
        if bad != 0.0:
            return i
    return -1


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
