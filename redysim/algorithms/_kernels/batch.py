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
"""

from __future__ import annotations

from redysim._jit import jit_borrowed

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
    than a flag of :func:`forward_rows`: one function calling both kernels compiled both on
    first use, and a factory of the two would give numba's disk cache two functions of one
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
