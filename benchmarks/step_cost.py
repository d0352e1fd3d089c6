"""What one integrator step costs on a long chain: the Python stepping loop against the compiled.

    .venv/bin/python benchmarks/step_cost.py [--case RE-U50000-L1000] [--steps 40]
        [--integrator ode45] [--rounds 3]

From the case's initial state, each solver takes ``--steps`` steps (after one warm-up step),
alternating round by round in one process: :class:`redysim.integrators.explicit.Solver` stepping as
Python a plain function (the core's qdd through ``forward_dynamics``), and the same Solver stepping
the case's :class:`redysim.algorithms.system.System` in compiled code (stage sums and qdd calls in
compiled code, ``redysim.algorithms._kernels.rk_run``; what ``harness.run`` and
``harness.longrun`` use). Reports the fastest round's wall time per step and per qdd call, and
checks that both took the same steps to the same bits (t, h and y). Writes
``results/bench/step_cost.json``.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import numpy as np

from redysim import Workspace, forward_dynamics, load_case
from redysim.algorithms.system import System
from redysim.integrators.explicit import Solver, compile_kernels


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="RE-U50000-L1000")
    ap.add_argument("--steps", type=int, default=40)
    ap.add_argument("--integrator", default="ode45")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("results/bench/step_cost.json"))
    args = ap.parse_args(argv)

    case = load_case(args.case)
    chain, n = case.chain, case.chain.n_dof
    ws = Workspace(chain)

    def rhs(_t, y):
        return np.concatenate((y[n:], forward_dynamics(chain, y[:n], y[n:], ws=ws)))

    y0 = np.concatenate((case.q0, case.v0))
    kw = dict(rtol=case.rtol, atol=case.atol)
    rhs(0.0, y0)
    compile_kernels()

    def run(kind):
        if kind == "python":
            s = Solver(rhs, 0.0, y0, case.t_end, args.integrator, **kw)
            s.step()  # warm-up

            def go():
                for _ in range(args.steps):
                    s.step()
        else:
            s = Solver(System(chain), 0.0, y0, case.t_end, args.integrator, **kw)
            s.max_steps = 1
            s.step()

            def go():
                s.max_steps = args.steps
                s.step()
        nfev0 = s.counters.nfev
        steps0 = s.counters.steps
        t0 = time.perf_counter()
        go()
        wall = time.perf_counter() - t0
        taken = s.counters.steps - steps0
        return wall, taken, s.counters.nfev - nfev0, s

    best = {"python": np.inf, "compiled": np.inf}
    last = {}
    for _ in range(args.rounds):
        for kind in ("python", "compiled"):
            wall, taken, nfev, s = run(kind)
            best[kind] = min(best[kind], wall / taken)
            last[kind] = (s, nfev / taken)
    py, cc = last["python"][0], last["compiled"][0]
    same = (py.t == cc.t and py.h_next == cc.h_next and np.array_equal(py.y, cc.y)
            and py.counters.steps == cc.counters.steps)
    per_call = last["python"][1]
    out = {"case": case.name, "n_dof": n, "integrator": args.integrator, "steps": args.steps,
           "rounds": args.rounds, "qdd_calls_per_step": per_call,
           "python_ms_per_step": best["python"] * 1e3,
           "compiled_ms_per_step": best["compiled"] * 1e3,
           "ratio": best["python"] / best["compiled"], "same_steps_and_bits": bool(same),
           "machine": {"cpu": platform.processor() or platform.machine(),
                       "python": platform.python_version()}}
    print(f"{case.name} ({n:,} DOF), {args.integrator}, {args.steps} steps x {args.rounds} "
          f"rounds: Python loop {out['python_ms_per_step']:.2f} ms/step, compiled "
          f"{out['compiled_ms_per_step']:.2f} ms/step ({out['ratio']:.2f}x); "
          f"{per_call:.1f} qdd calls a step; same steps and bits: {same}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(out, indent=1) + "\n")
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
