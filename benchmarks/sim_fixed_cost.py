"""The Simulator's fixed cost per run: a small robot's whole ``simulate()`` against its integration.

UR5-FALL (example-robot-data's UR5 from a seeded random posture at rest) over 1 s by ode45 at
rtol 1e-5, atol 1e-7 (48 steps, 11 samples): the whole :func:`redysim.simulate` call (System,
Simulator, samples, energies, result) against the same steps by
:class:`redysim.integrators.explicit.Solver` alone from the same state. Each figure is the
fastest of BATCHES batches of BATCH runs, wall time (``time.perf_counter``) and the process's CPU
time (``time.process_time``), after 3 warm-up runs. The two are measured interleaved, batch by
batch, so that both see the same load (the machine is shared): ``ratio`` is the fastest whole
run over the fastest integration. Then what the whole run spends besides the integration, per
piece (the same way, fastest batch, wall time): the System, the Simulator's set-up, the steps cut
at the samples (one compiled call per sample interval, against one for the whole horizon), one
sample (interpolation, projection, energy and centre of mass), and the result.

    python benchmarks/sim_fixed_cost.py
"""

from __future__ import annotations

import time

from redysim.algorithms.system import System
from redysim.integrators.explicit import Solver
from redysim.io.scenarios import load_scenario
from redysim.simulation import Simulator, simulate, simulator

RTOL, ATOL, T_END, BATCH, BATCHES = 1e-5, 1e-7, 1.0, 50, 6


def interleaved(fns: dict, batch: int = BATCH) -> dict:
    """name -> (wall, cpu) [us per call], the fastest of BATCHES batches of each, the batches of
    the functions taken in turn."""
    best = {k: [float("inf"), float("inf")] for k in fns}
    for _ in range(BATCHES):
        for name, fn in fns.items():
            w0, c0 = time.perf_counter(), time.process_time()
            for _ in range(batch):
                fn()
            w, c = time.perf_counter() - w0, time.process_time() - c0
            best[name][0] = min(best[name][0], w / batch * 1e6)
            best[name][1] = min(best[name][1], c / batch * 1e6)
    return best


def main() -> None:
    sc = load_scenario("UR5-FALL")
    kw = dict(q0=sc.q0, v0=sc.v0, integrator="ode45", rtol=RTOL, atol=ATOL)
    sim = simulator(sc.model, T_END, **kw)
    system, ts = sim.system, sim.ts

    def whole():
        return simulate(sc.model, T_END, **kw)

    def integrate_only():
        s = Solver(system, 0.0, sim.y0, T_END, "ode45", rtol=RTOL, atol=ATOL)
        while not s.done:
            s.step()
        return s

    def steps_at_samples():
        s = Solver(system, 0.0, sim.y0, T_END, "ode45", rtol=RTOL, atol=ATOL)
        for t in ts[1:]:
            s.step(t)
        return s

    last = integrate_only()

    def one_sample():  # interpolation (a step's end), projection, energy and com
        y = last.dense([last.t])[0].copy()
        system.project(y, record=False)
        if not hasattr(system, "run_energy_and_com"):  # (an older redysim, for comparison)
            return system.energy_and_com(y[:system.n_q], y[system.n_q:system.motion_size])
        return system.run_energy_and_com(y)

    def set_up():
        return Simulator(system, T_END, q0=sc.q0, v0=sc.v0, integrator=sim.integrator)

    for _ in range(3):
        whole(), integrate_only()
    run = whole()
    main_ = interleaved({"whole": whole, "integration": integrate_only})
    (aw, ac), (bw, bc) = main_["whole"], main_["integration"]
    print(f"UR5-FALL {T_END:g} s, ode45 rtol {RTOL:g} atol {ATOL:g}: {run.steps} steps, "
          f"{run.t.size} samples")
    print(f"simulate()        {aw / 1e3:.3f} ms wall, {ac / 1e3:.3f} ms CPU")
    print(f"integration alone {bw / 1e3:.3f} ms wall, {bc / 1e3:.3f} ms CPU")
    print(f"ratio             {aw / bw:.2f} wall, {ac / bc:.2f} CPU (interleaved)")
    pieces = interleaved({"System(model)": lambda: System(sc.model),
                          "Simulator set-up": set_up,
                          "steps cut at samples": steps_at_samples,
                          "integration alone": integrate_only,
                          "one sample": one_sample}, batch=BATCH)
    print("what the whole run adds (fastest batch, wall / CPU [us]):")
    for name, what in (("System(model)", ""), ("Simulator set-up", " (checks, E0, first "
                       "derivative, the solver's first f and step)")):
        print(f"  {name:22s} {pieces[name][0]:7.1f} / {pieces[name][1]:7.1f}{what}")
    cut = [pieces["steps cut at samples"][i] - pieces["integration alone"][i] for i in (0, 1)]
    print(f"  {'steps cut at samples':22s} {cut[0]:7.1f} / {cut[1]:7.1f} ({ts.size - 2} more "
          "compiled calls)")
    one = pieces["one sample"]
    print(f"  {'samples':22s} {one[0] * ts.size:7.1f} / {one[1] * ts.size:7.1f} ({ts.size} x "
          f"{one[0]:.1f} / {one[1]:.1f})")


if __name__ == "__main__":
    main()
