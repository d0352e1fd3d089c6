"""The quick reproduction (``make reproduce``): RE-U125-L1 for 0.1 s with the core.

Prints E(0), the energy drift delta_M and the tip position at every sample. Integrator: SciPy's
RK45 at the paper's tolerances (rtol 1e-4, atol 1e-6) until the ode45-equivalent lands (issue 5);
SciPy's RMS error norm is looser than MATLAB's max norm (DESIGN.md section 4), so expect more
drift than the paper's ode45.
"""

from __future__ import annotations

import argparse
import sys
import time

import numpy as np
from scipy.integrate import solve_ivp

import redysim
from redysim import Workspace, energy, forward_dynamics, load_case, tip


def simulate_quick(name: str, t_end: float, sample: float) -> int:
    case = load_case(name)
    chain, n = case.chain, case.chain.n_dof
    ws = Workspace(chain)
    qdd = np.empty(n)
    rhs_calls = 0

    def rhs(_t, y):
        nonlocal rhs_calls
        rhs_calls += 1
        forward_dynamics(chain, y[:n], y[n:], ws=ws, out=qdd)
        return np.concatenate([y[n:], qdd])

    y0 = np.concatenate([case.q0, case.qd0])
    t0 = time.perf_counter()
    rhs(0.0, y0)  # JIT compile (or load from the on-disk cache), timed apart
    jit_s = time.perf_counter() - t0
    T0, V0 = energy(chain, case.q0, case.qd0)
    E0 = T0 + V0
    print(f"redysim {redysim.__version__}: {case.name}, {chain.n_links} links, {n} DOF, "
          f"mass {chain.total_mass:.4f} kg")
    print(f"E(0) = {E0:.6f} J   (paper, Table 3: {case.published()['table3']['E0_J']} J, "
          "printed truncated)")
    print(f"first qdd call (JIT compile or cache load): {jit_s:.2f} s")
    samples = np.arange(0.0, t_end + 1e-12, sample)
    rhs_calls = 0
    cpu0, wall0 = time.process_time(), time.perf_counter()
    sol = solve_ivp(rhs, (0.0, t_end), y0, method="RK45", rtol=case.simulation.get("rtol", 1e-4),
                    atol=case.simulation.get("atol", 1e-6), t_eval=samples)
    cpu, wall = time.process_time() - cpu0, time.perf_counter() - wall0
    if not sol.success:
        print(f"integration failed: {sol.message}", file=sys.stderr)
        return 1
    print(f"SciPy RK45, rtol {case.simulation.get('rtol')}, atol {case.simulation.get('atol')}: "
          f"{sol.t.size} samples, {sol.nfev} RHS calls, CPU {cpu:.2f} s, wall {wall:.2f} s")
    print(f"{'t [s]':>6} {'delta_M [J/kg]':>15} {'tip X':>10} {'tip Y':>10} {'tip Z':>10}")
    drifts = []
    for t, y in zip(sol.t, sol.y.T, strict=True):
        q, qd = y[:n], y[n:]
        T, V = energy(chain, q, qd, ws=ws)
        dM = (T + V - E0) / chain.total_mass
        drifts.append(abs(dM))
        p = tip(chain, q, qd, ws=ws).position
        print(f"{t:6.3f} {dM:15.3e} {p[0]:10.5f} {p[1]:10.5f} {p[2]:10.5f}")
    print(f"average |delta_M| over the samples: {np.mean(drifts):.3e} J/kg "
          f"(paper, 1 s with ode45: {case.published()['table3']['avg_abs_delta_M']} J/kg)")
    return 0


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="RE-U125-L1")
    ap.add_argument("--t-end", type=float, default=0.1)
    ap.add_argument("--sample", type=float, default=0.01)
    args = ap.parse_args(argv)
    return simulate_quick(args.case, args.t_end, args.sample)


if __name__ == "__main__":
    raise SystemExit(main())
