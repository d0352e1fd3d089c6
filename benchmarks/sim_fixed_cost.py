"""The Simulator's fixed cost per run: a small robot's whole ``simulate()`` against its integration.

UR5-FALL (example-robot-data's UR5 from a seeded random posture at rest) over 1 s by ode45 at
rtol 1e-5, atol 1e-7 (48 steps, 11 samples): the whole :func:`redysim.simulate` call (System,
Simulator, samples, energies, result) against the same steps by
:class:`redysim.integrators.explicit.Solver` alone from the same state. Each figure is the
fastest of 6 batches of 50 runs (wall time), after 3 warm-up runs.

    python benchmarks/sim_fixed_cost.py
"""

from __future__ import annotations

import time

from redysim.integrators.explicit import Solver
from redysim.io.scenarios import load_scenario
from redysim.simulation import simulate, simulator

RTOL, ATOL, T_END, BATCH, BATCHES = 1e-5, 1e-7, 1.0, 50, 6


def best(fn) -> float:
    """The fastest of BATCHES batches of BATCH calls, per call [ms]."""
    times = []
    for _ in range(BATCHES):
        t0 = time.perf_counter()
        for _ in range(BATCH):
            fn()
        times.append((time.perf_counter() - t0) / BATCH * 1e3)
    return min(times)


def main() -> None:
    sc = load_scenario("UR5-FALL")
    kw = dict(q0=sc.q0, v0=sc.v0, integrator="ode45", rtol=RTOL, atol=ATOL)
    sim = simulator(sc.model, T_END, **kw)

    def whole():
        return simulate(sc.model, T_END, **kw)

    def integrate_only():
        s = Solver(sim.system, 0.0, sim.y0, T_END, "ode45", rtol=RTOL, atol=ATOL)
        while not s.done:
            s.step()
        return s

    for _ in range(3):
        whole(), integrate_only()
    a, b = best(whole), best(integrate_only)
    print(f"simulate() {a:.3f} ms, integration alone {b:.3f} ms, ratio {a / b:.2f} "
          f"({whole().steps} steps)")


if __name__ == "__main__":
    main()
