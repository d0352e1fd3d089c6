"""cProfile of the Simulator's fixed cost: 200 runs of :func:`redysim.simulate` on UR5-FALL (1 s,
ode45 at rtol 1e-5, atol 1e-7, as ``benchmarks/sim_fixed_cost.py``), after 5 warm-up runs, the
35 functions of most own time (docs/notes/2026-12-08-fixed-cost.md).

    python benchmarks/sim_profile.py
"""

from __future__ import annotations

import cProfile
import pstats

from redysim.io.scenarios import load_scenario
from redysim.simulation import simulate


def main() -> None:
    sc = load_scenario("UR5-FALL")
    kw = dict(q0=sc.q0, v0=sc.v0, integrator="ode45", rtol=1e-5, atol=1e-7)
    for _ in range(5):
        simulate(sc.model, 1.0, **kw)
    profile = cProfile.Profile()
    profile.enable()
    for _ in range(200):
        simulate(sc.model, 1.0, **kw)
    profile.disable()
    pstats.Stats(profile).sort_stats("tottime").print_stats(35)


if __name__ == "__main__":
    main()
