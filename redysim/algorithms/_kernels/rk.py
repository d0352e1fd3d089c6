"""The Runge-Kutta integrators' stage sums, in a fixed order and in IEEE arithmetic as written.

An explicit Runge-Kutta step forms y + h sum_j a_ij K_j for each stage, the error estimate
sum_j E_j K_j and the dense output y + sum_j w_j K_j. With numpy these are matrix products, which
BLAS sums in an order (and with FMA or not) that depends on the CPU's kernel: the last bits of
every stage then differ from one machine to another, and an adaptive integrator's step-size
control turns last-bit differences into different step counts. Here every entry is summed
j = 0, 1, 2, ... in that order, skipping zero weights, with no fused multiply-add (``jit_strict``),
so a step is the same on every x86-64 CPU.
"""

from __future__ import annotations

import math

from redysim._jit import jit_strict


@jit_strict
def combine(y, h, w, K, count, out):
    """out = y + h * sum_{j < count, w_j != 0} w_j K_j, the sum taken in the order of j;
    returns out.

    y: (n,), or an empty array for out = h * sum ...; w: (>= count,); K: (>= count, n).
    """
    n = out.shape[0]
    first = True
    for j in range(count):
        wj = w[j]
        if wj == 0.0:
            continue
        Kj = K[j]
        if first:
            for k in range(n):
                out[k] = wj * Kj[k]
            first = False
        else:
            for k in range(n):
                out[k] += wj * Kj[k]
    if first:
        for k in range(n):
            out[k] = 0.0
    if y.shape[0] == n:
        for k in range(n):
            out[k] = y[k] + h * out[k]
    else:
        for k in range(n):
            out[k] = h * out[k]
    return out


@jit_strict
def error_norm(h, E, E3, K, count, y, y_new, threshold, err, err3):
    """|h| max_k |e_k| / max(|y_k|, |y_new_k|, threshold): ode45's max-norm error estimate.

    e = sum_j E_j K_j (in the order of j); with DOP853's 3rd-order estimate (E3 of size count,
    else empty) e_k becomes e_k |e_k| / hypot(e_k, 0.1 e3_k) where that is not 0/0. err and err3
    are (n,) scratch arrays. NaN when an estimate is not finite.
    """
    n = y.shape[0]
    empty = y[:0]
    combine(empty, 1.0, E, K, count, err)
    dop853 = E3.shape[0] > 0
    if dop853:
        combine(empty, 1.0, E3, K, count, err3)
    worst = 0.0
    for k in range(n):
        e = err[k]
        if dop853:
            d = math.hypot(e, 0.1 * err3[k])
            if d > 0.0:
                e = e * abs(e) / d
        scale = max(max(abs(y[k]), abs(y_new[k])), threshold)
        r = abs(e) / scale
        if not r <= worst:  # also takes NaN, which then stays
            worst = r
            if math.isnan(r):
                break
    return abs(h) * worst
