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
- A03 (Andrews' squeezer): the Test Set for IVP Solvers' published solution at t = 0.03 s
  (A03_REFERENCE), and its equations by SciPy (a03_equations, a03_scipy); the spring and the
  motor, which no model or scenario file writes, as a System's tau and potential (a03_forces).
  Where each number comes from: the A03 section below.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from redysim.io.cases import CASES_DIR

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


# --------------------------------------------------------------------------- A03: Andrews' squeezer
# The Test Set for IVP Solvers' problem "andrews" (F. Mazzia, F. Iavernaro, C. Magherini, Univ. of
# Bari, www.dm.uniba.it/~testset/src/problems/andrews.f; E. Hairer, G. Wanner, "Solving Ordinary
# Differential Equations II", Sect. VII.7), as read in github.com/rforge/bvpsolve:
# pkg/deTestSet/R/ex_andrews.R (commit 14b319e0: the parameters, `parameter <- c(...)`, and the
# initial values, `yini`) and pkg/deTestSet/src/Ex_andrews.f (commit 0007f922: the equations,
# `andfunc`, and the reference solution at t = 0.03 s, `andsoln`, "computed at Cray C90, using
# Cray double precision ... PSIDE ... relative error tolerance: 1d-14, absolute error tolerance:
# 1d-14"). The test set's angles are y(1..7) = (beta, Theta, gamma, Phi, delta, Omega, epsilon);
# the linkage file's tree (cases/iftomm/models/a03_andrews.toml) lists them as (beta, Theta,
# gamma, delta, Phi, epsilon, Omega).
A03 = {  # ex_andrews.R's `parameter`: kg, m, kg m^2, N/m, N m
    "m1": 0.04325, "m2": 0.00365, "m3": 0.02373, "m4": 0.00706, "m5": 0.07050, "m6": 0.00706,
    "m7": 0.05498, "xa": -0.06934, "ya": -0.00227, "xb": -0.03635, "yb": 0.03273, "xc": 0.014,
    "yc": 0.072, "c0": 4530.0, "i1": 2.194e-6, "i2": 4.410e-7, "i3": 5.255e-6, "i4": 5.667e-7,
    "i5": 1.169e-5, "i6": 5.667e-7, "i7": 1.912e-5, "d": 28e-3, "da": 115e-4, "e": 2e-2,
    "ea": 1421e-5, "rr": 7e-3, "ra": 92e-5, "l0": 7785e-5, "ss": 35e-3, "sa": 1874e-5,
    "sb": 1043e-5, "sc": 18e-3, "sd": 2e-2, "ta": 2308e-5, "tb": 916e-5, "u": 4e-2,
    "ua": 1228e-5, "ub": 449e-5, "zf": 2e-2, "zt": 4e-2, "fa": 1421e-5, "mom": 33e-3}
# the tree's coordinate k is the test set's angle A03_ORDER[k] (a swap of two pairs: its own
# inverse, so the same index maps the test set's vectors onto the tree's and back)
A03_ORDER = (0, 1, 2, 4, 3, 6, 5)
A03_NAMES = ("beta", "Theta", "gamma", "Phi", "delta", "Omega", "epsilon")  # the test set's
A03_T_END = 0.03  # s: andsoln's time (the test set's interval [0, 0.03])
A03_Y0 = np.array([  # ex_andrews.R's yini[1:7] (Ex_andrews.f's y(1..7) at t = 0), rad; at rest
    -0.0617138900142764496358948458001, 0.0, 0.455279819163070380255912382449,
    0.222668390165885884674473185609, 0.487364979543842550225598953530,
    -0.222668390165885884674473185609, 1.23054744454982119249735015568])
A03_REFERENCE = np.array([  # Ex_andrews.f's andsoln, y(1..14) at t = 0.03 s: rad, rad/s
    0.1581077119629904e+2, -0.1575637105984298e+2, 0.4082224013073101e-1,
    -0.5347301163226948e+0, 0.5244099658805304e+0, 0.5347301163226948e+0,
    0.1048080741042263e+1, 0.1139920302151208e+4, -0.1424379294994111e+4,
    0.1103291221937134e+2, 0.1929337464421385e+2, 0.5735699284790808e+0,
    -0.1929337464421385e+2, 0.3231791658026955e+0])


def a03_tree(y) -> np.ndarray:
    """The test set's 7 angles (or velocities), its order, in the linkage file's tree order
    (and back: A03_ORDER is its own inverse)."""
    return np.asarray(y, dtype=float)[..., list(A03_ORDER)]


def a03_forces(link, p: dict | None = None):
    """The squeezer's applied forces on the linkage ``link`` (a03_andrews.toml) as a
    :class:`~redysim.algorithms.system.System`'s ``tau(t, q, v)`` and ``potential(q)``:

    - the motor torque mom on the crank b1 (the test set's ff(1): mom on beta), potential
      -mom beta;
    - the spring of stiffness c0 and rest length l0 between the triangle's point b3.D and the
      ground point C: force F = -c0 (L - l0) / L (D - C) at D, L = |D - C| (the test set's fx,
      fy), whose generalized force is its torque about b3's ground pivot B, (D - B) x F, on
      b3's angle gamma (ff(3) = fx (sc cos gamma - sd sin gamma) + fy (sd cos gamma + sc sin
      gamma), the same); potential c0 (L - l0)^2 / 2.

    D, B, C are the file's points, D at q by the model's kinematics."""
    p = A03 if p is None else p
    c0, l0, mom = p["c0"], p["l0"], p["mom"]
    k_crank, k_triangle = link.model.body_names.index("b1"), link.model.body_names.index("b3")
    b, c = link.point(link.q0, "ground.B")[:2], link.point(link.q0, "ground.C")[:2]
    n = link.model.n_v

    def tau(_t, q, _v):
        d = link.point(q, "b3.D")[:2]
        r = d - c
        length = float(np.hypot(r[0], r[1]))
        f = -c0 * (length - l0) / length * r
        out = np.zeros(n)
        out[k_crank] = mom
        arm = d - b
        out[k_triangle] = arm[0] * f[1] - arm[1] * f[0]
        return out

    def potential(q):
        d = link.point(q, "b3.D")[:2]
        return 0.5 * c0 * (float(np.hypot(*(d - c))) - l0) ** 2 - mom * float(q[k_crank])

    return tau, potential


A03_SAMPLE = 0.001  # s: ex_andrews.R's output times, seq(0, 0.03, by = 0.001)
A03_FILE = Path(CASES_DIR) / "iftomm" / "models" / "a03_andrews.toml"


def a03_simulator(t_end: float = A03_T_END, **settings):
    """Andrews' squeezer as the test set poses it: the mechanism of ``A03_FILE`` (its loops
    closed) from the test set's initial angles at rest, driven by its motor and loaded by its
    spring (:func:`a03_forces`), over [0, ``t_end``] sampled every ``A03_SAMPLE``. Returns (the
    :class:`redysim.simulation.Simulator`, the linkage). ``settings``: the simulator's keywords
    (``integrator``, ``rtol``, ``atol``, ...).

    There is no scenario file for A03: neither a linkage file nor a scenario file writes a
    point-to-point spring or a joint torque, and a scenario without them would run the
    squeezer at rest under its name."""
    from redysim import load_linkage
    from redysim.simulation import simulator

    link = load_linkage(A03_FILE)
    tau, potential = a03_forces(link)
    sim = simulator(link.model, t_end, q0=link.q0, v0=np.zeros(link.model.n_v),
                    sample=A03_SAMPLE, loops=link.loops, tau=tau, potential=potential,
                    source=str(A03_FILE), **settings)
    return sim, link


def a03_equations(y, p: dict | None = None):
    """The test set's own model at the angles y (its order, rad): the mass matrix M (7, 7),
    the loop equations g (6,) [m] and their Jacobian G (6, 7), and the spring's and motor's
    generalized forces (the parts of ff without velocities, (7,)): Ex_andrews.f's andfunc,
    written out here to check the linkage file against (tests/test_iftomm.py)."""
    p = A03 if p is None else p
    be, th, ga, ph, de, om, ep = np.asarray(y, dtype=float)
    m1, m2, m3, m4, m5, m6, m7 = (p[f"m{k}"] for k in range(1, 8))
    i1, i2, i3, i4, i5, i6, i7 = (p[f"i{k}"] for k in range(1, 8))
    rr, d, da, ra, ss, e, ea, zt = (p[k] for k in ("rr", "d", "da", "ra", "ss", "e", "ea", "zt"))
    zf, fa, u = p["zf"], p["fa"], p["u"]
    M = np.zeros((7, 7))
    M[0, 0] = m1 * ra ** 2 + m2 * (rr ** 2 - 2 * da * rr * np.cos(th) + da ** 2) + i1 + i2
    M[1, 0] = M[0, 1] = m2 * (da ** 2 - da * rr * np.cos(th)) + i2
    M[1, 1] = m2 * da ** 2 + i2
    M[2, 2] = m3 * (p["sa"] ** 2 + p["sb"] ** 2) + i3
    M[3, 3] = m4 * (e - ea) ** 2 + i4
    M[4, 3] = M[3, 4] = m4 * ((e - ea) ** 2 + zt * (e - ea) * np.sin(ph)) + i4
    M[4, 4] = (m4 * (zt ** 2 + 2 * zt * (e - ea) * np.sin(ph) + (e - ea) ** 2)
               + m5 * (p["ta"] ** 2 + p["tb"] ** 2) + i4 + i5)
    M[5, 5] = m6 * (zf - fa) ** 2 + i6
    M[6, 5] = M[5, 6] = m6 * ((zf - fa) ** 2 - u * (zf - fa) * np.sin(om)) + i6
    M[6, 6] = (m6 * ((zf - fa) ** 2 - 2 * u * (zf - fa) * np.sin(om) + u ** 2)
               + m7 * (p["ua"] ** 2 + p["ub"] ** 2) + i6 + i7)
    # the pin P by body 2, and by bodies 3, 5+4, 7+6 (g = P(1, 2) - P(other)), and d/dy of each
    P = np.array([rr * np.cos(be) - d * np.cos(be + th), rr * np.sin(be) - d * np.sin(be + th)])
    dP = np.array([[-rr * np.sin(be) + d * np.sin(be + th), d * np.sin(be + th)],
                   [rr * np.cos(be) - d * np.cos(be + th), -d * np.cos(be + th)]])
    g = np.concatenate([
        P - (p["xb"] + ss * np.sin(ga), p["yb"] - ss * np.cos(ga)),
        P - (p["xa"] + zt * np.cos(de) + e * np.sin(ph + de),
             p["ya"] + zt * np.sin(de) - e * np.cos(ph + de)),
        P - (p["xa"] + u * np.sin(ep) + zf * np.cos(om + ep),
             p["ya"] - u * np.cos(ep) + zf * np.sin(om + ep))])
    G = np.zeros((6, 7))
    for r in (0, 2, 4):
        G[r:r + 2, 0:2] = dP
    G[0:2, 2] = (-ss * np.cos(ga), -ss * np.sin(ga))
    G[2:4, 3] = (-e * np.cos(ph + de), -e * np.sin(ph + de))
    G[2:4, 4] = (-e * np.cos(ph + de) + zt * np.sin(de), -e * np.sin(ph + de) - zt * np.cos(de))
    G[4:6, 5] = (zf * np.sin(om + ep), -zf * np.cos(om + ep))
    G[4:6, 6] = (zf * np.sin(om + ep) - u * np.cos(ep), -zf * np.cos(om + ep) - u * np.sin(ep))
    xd = p["sd"] * np.cos(ga) + p["sc"] * np.sin(ga) + p["xb"]
    yd = p["sd"] * np.sin(ga) - p["sc"] * np.cos(ga) + p["yb"]
    length = np.hypot(xd - p["xc"], yd - p["yc"])
    force = -p["c0"] * (length - p["l0"]) / length
    fx, fy = force * (xd - p["xc"]), force * (yd - p["yc"])
    f = np.zeros(7)
    f[0] = p["mom"]
    f[2] = (fx * (p["sc"] * np.cos(ga) - p["sd"] * np.sin(ga))
            + fy * (p["sd"] * np.cos(ga) + p["sc"] * np.sin(ga)))
    return M, g, G, f


def a03_scipy(t_end: float = A03_T_END, rtol: float = 1e-13, p: dict | None = None):
    """The test set's equations (:func:`a03_equations` with andfunc's velocity terms) by SciPy's
    DOP853 from its initial values: M q'' = f(q, q') - G^T lambda with G q'' = -(G' q')
    (the loops' equations differentiated twice; no projection: their drift is returned),
    a reference that shares nothing with the core but the equations' source. Returns y(1..14)
    at t_end (the test set's order, as A03_REFERENCE) and |g| there [m]."""
    from scipy.integrate import solve_ivp

    p = A03 if p is None else p
    zt, e, ea, zf, fa, u = (p[k] for k in ("zt", "e", "ea", "zf", "fa", "u"))
    rr, d, ss, m2, m4, m6 = (p[k] for k in ("rr", "d", "ss", "m2", "m4", "m6"))
    k2, k4, k6 = m2 * p["da"] * rr, m4 * zt * (e - ea), m6 * u * (zf - fa)

    def rhs(_t, y):
        be, th, ga, ph, de, om, ep = y[:7]
        b1, t1, g1, p1, d1, o1, e1 = y[7:]
        M, _, G, f = a03_equations(y[:7], p)
        f = f + (-k2 * t1 * (t1 + 2 * b1) * np.sin(th), k2 * b1 ** 2 * np.sin(th), 0.0,
                 k4 * d1 ** 2 * np.cos(ph), -k4 * p1 * (p1 + 2 * d1) * np.cos(ph),
                 -k6 * e1 ** 2 * np.cos(om), k6 * o1 * (o1 + 2 * e1) * np.cos(om))
        # each loop point's acceleration at q'' = 0: the pin by bodies 1-2, less the other's
        a_p = (-rr * b1 ** 2 * np.array([np.cos(be), np.sin(be)])
               + d * (b1 + t1) ** 2 * np.array([np.cos(be + th), np.sin(be + th)]))
        a3 = -ss * g1 ** 2 * np.array([np.sin(ga), -np.cos(ga)])
        a54 = (-zt * d1 ** 2 * np.array([np.cos(de), np.sin(de)])
               - e * (p1 + d1) ** 2 * np.array([np.sin(ph + de), -np.cos(ph + de)]))
        a76 = (-u * e1 ** 2 * np.array([np.sin(ep), -np.cos(ep)])
               - zf * (o1 + e1) ** 2 * np.array([np.cos(om + ep), np.sin(om + ep)]))
        c = np.concatenate((a_p - a3, a_p - a54, a_p - a76))
        A = np.block([[M, G.T], [G, np.zeros((6, 6))]])
        qdd = np.linalg.solve(A, np.concatenate((f, -c)))[:7]
        return np.concatenate((y[7:], qdd))

    sol = solve_ivp(rhs, (0.0, t_end), np.concatenate((A03_Y0, np.zeros(7))), method="DOP853",
                    rtol=rtol, atol=rtol)
    y = sol.y[:, -1]
    return y, float(np.abs(a03_equations(y[:7], p)[1]).max())
