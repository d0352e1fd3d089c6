"""The IFToMM benchmark problems' references and error measure (cases/iftomm/; docs/design.md,
"IFToMM benchmark problems").

The IFToMM TC for Multibody Dynamics' Library of Computational Benchmark Problems (Univ. A
Coruna; M. Gonzalez et al., Eng. with Computers 26, 2010) states for A01 and A02 "maximum
allowed errors 1.0E-1 (low precision) and 1.0E-3 (high precision), measured with N output steps
and a threshold value of 1.0E-3". Read here as the simEngine3D implementation of the benchmark
checks it (simEngine3D_BricardMechanism.m's A02 comparison, S. Acuna 2016): the largest
absolute error of each reference coordinate over the output steps (:func:`library_error`).
The "threshold" is not interpreted (its definition was not found): an absolute error is the
stricter reading wherever the coordinates are O(1 m), as here.

The library's own data files (A0x_solution_data.txt) could not be had; the references are
independent of the core's loops and integrators:

- A01: the pendulum released from the horizontal at rest in closed form (Jacobi's elliptic
  functions): with phi the angle from the downward vertical, k = sin(phi0 / 2),
  sin(phi / 2) = k sn(K(k) - w t, k), w = sqrt(g / L); so x = 2 k L sn dn, y = -L (1 - 2 k^2 sn^2).
- A02: the parallelogram's own equation. Every vertical bar turns by the same angle theta (from
  the upward vertical, clockwise) and every coupler translates, so T = m L^2 a theta'^2 / 2 and
  V = m g L b cos(theta), a = (N + 1) / 3 + N, b = (N + 1) / 2 + N: theta'' = (g / L) (b / a)
  sin(theta), B0 = L (sin theta, cos theta); integrated by SciPy's DOP853 at rtol 1e-13 (one
  degree of freedom: no loops, no singular positions).
"""

from __future__ import annotations

import numpy as np

LOW, HIGH = 1e-1, 1e-3  # the library's "low" and "high" precision [m]
G = 9.81  # the library's gravity [N/kg]


def library_error(x, x_ref) -> float:
    """The largest absolute difference of the output steps' coordinates (rows: steps, columns:
    coordinates) from the reference's: the error a run is held to (LOW, HIGH)."""
    x, x_ref = np.asarray(x, dtype=float), np.asarray(x_ref, dtype=float)
    if x.shape != x_ref.shape:
        raise ValueError(f"library_error: {x.shape} steps against a reference of {x_ref.shape}")
    return float(np.abs(x - x_ref).max())


def a01_p1(t, g: float = G, length: float = 1.0) -> np.ndarray:
    """A01's point P1 (x, y) at the times t (k, 2): the pendulum released at rest with P1 at
    (+L, 0), in closed form (module docstring); sn's argument reduced by its period 4K first."""
    from scipy.special import ellipj, ellipk

    m = 0.5  # k^2, k = sin(pi / 4): released from the horizontal
    K = float(ellipk(m))
    u = np.mod(K - np.sqrt(g / length) * np.asarray(t, dtype=float), 4.0 * K)
    sn, _, dn, _ = ellipj(u, m)
    k = np.sqrt(m)
    return np.column_stack((2.0 * k * length * sn * dn, -length * (1.0 - 2.0 * m * sn * sn)))


def a02_b0(t, n: int = 40, g: float = G, length: float = 1.0, vx0: float = 1.0,
           rtol: float = 1e-13) -> np.ndarray:
    """A02's point B0 (x, y, vx, vy) at the times t (k, 4) for n four-bars, B0 starting at
    (0, L) with x velocity vx0: the parallelogram's one-degree-of-freedom equation (module
    docstring) by SciPy's DOP853."""
    from scipy.integrate import solve_ivp

    a, b = (n + 1) / 3.0 + n, (n + 1) / 2.0 + n
    t = np.asarray(t, dtype=float)
    sol = solve_ivp(lambda _, y: (y[1], g / length * b / a * np.sin(y[0])), (0.0, t[-1]),
                    (0.0, vx0 / length), method="DOP853", rtol=rtol, atol=rtol, t_eval=t)
    th, w = sol.y
    return np.column_stack((length * np.sin(th), length * np.cos(th),
                            length * np.cos(th) * w, -length * np.sin(th) * w))
