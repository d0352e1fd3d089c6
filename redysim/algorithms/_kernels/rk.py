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


NORM_MAX, NORM_RMS = 0, 1  # the norms of a scheme without E3 (ode45's, rk45's)


@jit_strict
def error_norm(h, E, E3, K, count, y, y_new, rtol, atol, err, err3, norm):
    """The step's error estimate, accepted when ``<= rtol`` (every scheme's controller compares
    it with rtol). e = sum_j E_j K_j and e3 = sum_j E3_j K_j, each summed in the order of j.

    - ode45 (E3 empty, ``norm`` NORM_MAX): MATLAB's max norm, |h| max_k |e_k| / max(|y_k|,
      |y_new_k|, atol/rtol) (the paper's integrator: these bits are the paper's reproduction's).
    - rk45 (E3 empty, ``norm`` NORM_RMS): SciPy's RK45 norm over the whole vector, with
      sc_k = atol + rtol max(|y_k|, |y_new_k|) and s = sum_k (e_k/sc_k)^2 (summed in order),
      rtol |h| sqrt(s / n): SciPy's error_norm, which it accepts at < 1, times rtol.
    - dop853 (E3 of size count): Hairer's DOP853 norm over the whole vector, as dop853.f and
      SciPy's DOP853: with sc_k = atol + rtol max(|y_k|, |y_new_k|), s5 = sum_k (e_k/sc_k)^2
      and s3 = sum_k (e3_k/sc_k)^2 (each summed k = 0, 1, ... in order), the estimate is
      rtol |h| s5 / sqrt((s5 + 0.01 s3) n) (0 when s5 + 0.01 s3 is 0): Hairer's err, which he
      accepts at <= 1, times rtol. The 3rd-order estimate makes the norm of the 5th-order one
      behave as an 8th-order estimate; over the whole vector, components that start at zero
      and carry only rounding noise weigh by their share, not as the worst one.

    err and err3 are (n,) scratch arrays. NaN when an estimate is not finite.
    """
    n = y.shape[0]
    empty = y[:0]
    combine(empty, 1.0, E, K, count, err)
    if E3.shape[0] > 0:
        combine(empty, 1.0, E3, K, count, err3)
        s5 = 0.0
        s3 = 0.0
        for k in range(n):
            sc = atol + rtol * max(abs(y[k]), abs(y_new[k]))
            r5 = err[k] / sc
            r3 = err3[k] / sc
            s5 += r5 * r5
            s3 += r3 * r3
        if not math.isfinite(s5 + s3):
            return math.nan
        deno = s5 + 0.01 * s3
        if deno <= 0.0:
            return 0.0
        return rtol * (abs(h) * s5 / math.sqrt(deno * n))
    if norm == NORM_RMS:
        s = 0.0
        for k in range(n):
            r = err[k] / (atol + rtol * max(abs(y[k]), abs(y_new[k])))
            s += r * r
        if not math.isfinite(s):
            return math.nan
        return rtol * (abs(h) * math.sqrt(s / n))
    threshold = atol / rtol
    worst = 0.0
    for k in range(n):
        scale = max(max(abs(y[k]), abs(y_new[k])), threshold)
        r = abs(err[k]) / scale
        if not r <= worst:  # also takes NaN, which then stays
            worst = r
            if math.isnan(r):
                break
    return abs(h) * worst
