"""The compiled stepping of two revisions side by side: a run's steps per second, base against head.

    .venv/bin/python benchmarks/ab_stepping.py --base be08d5d [--rounds 15] [--steps 200]

The base revision's ``redysim/`` (the core only: these runs need nothing else) is extracted from
git into a temporary folder; two worker processes, one importing it and one the working tree's
(each with a numba cache of its own, both compiling afresh), build the same runs by the scenario
API both revisions have: the RE-U125-L1 rope (250 DOF, ode45 as the paper's) and TALOS falling
(a floating robot: a free joint's quaternion and 32 joints, dop853), the UR5 and the PUMA 560 (a DH
robot) falling, compiled, and the UR5 falling with
its accelerations from a Python function (the stepping run as Python, as an engine's qdd is).
Each run's steps are timed ``--steps`` at a time from the same initial state, the two workers
taking turns round by round (the machine's drift falls on both alike); each side is read as its
fastest round, and the ratio base / head printed (> 1: head faster). Both sides take the same
steps to the same bits, checked on the last round's state. JIT compile happens before any
timing.

Speed changes to the stepping are claimed from this script's output, never from two runs.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tarfile
import tempfile
import time
from io import BytesIO
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
RUNS = {  # name -> (scenario, integrator, rtol, atol, qdd from Python)
    "rope RE-U125-L1 (250 DOF, ode45)": ("cases/RE-U125-L1.toml", "ode45", 1e-4, 1e-6, False),
    "TALOS-FALL (floating, dop853)": ("TALOS-FALL", "dop853", 1e-8, 1e-10, False),
    "UR5-FALL, qdd from Python (ode45)": ("UR5-FALL", "ode45", 1e-8, 1e-10, True),
    "UR5-FALL (6 DOF, ode45)": ("UR5-FALL", "ode45", 1e-8, 1e-10, False),
    "PUMA560-FALL (DH, ode45)": ("PUMA560-FALL", "ode45", 1e-8, 1e-10, False),
}

WORKER = r'''
import json, sys, time
import numpy as np
from redysim.io.scenarios import load_scenario
from redysim.io.cases import load_case

from redysim import forward_dynamics
T_END = 1e3  # s: far beyond the steps timed

def make(spec):
    name, integrator, rtol, atol, python = spec
    scn = load_scenario(name) if not name.endswith(".toml") else None
    src = scn if scn is not None else load_case(name)
    model = src.model if scn is not None else src.chain
    kw = {"qdd": lambda q, v, tau: forward_dynamics(model, q, v, tau)} if python else {}
    return lambda: src.simulator(T_END, integrator=integrator, rtol=rtol, atol=atol,
                                 sample=T_END, compiled=True, **kw)

def steps_of(solver, steps):
    """``steps`` steps (fewer if the run ends): one call in compiled code, one call a step as
    Python."""
    solver.max_steps = steps
    while solver.counters.steps < steps and not solver.done:
        solver.step(T_END)

runs = {k: make(v) for k, v in json.loads(sys.argv[1]).items()}
steps = int(sys.argv[2])
for make_sim in runs.values():  # compile (or load) everything first
    steps_of(make_sim().solver, 2)
print("ready", flush=True)
for line in sys.stdin:
    name = line.strip()
    solver = runs[name]().solver
    t0 = time.perf_counter()
    steps_of(solver, steps)
    wall = time.perf_counter() - t0
    print(json.dumps({"wall": wall, "steps": solver.counters.steps, "t": solver.t,
                      "y": float(np.abs(solver.y).sum())}), flush=True)
'''


def extract(rev: str, into: Path) -> None:
    """The revision's redysim/ folder into ``into``."""
    tar = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "redysim"],
                         capture_output=True, check=True).stdout
    with tarfile.open(fileobj=BytesIO(tar)) as t:
        t.extractall(into, filter="data")


def worker(path: Path, cache: Path, steps: int) -> subprocess.Popen:
    env = dict(os.environ, PYTHONPATH=str(path), NUMBA_CACHE_DIR=str(cache))
    p = subprocess.Popen([sys.executable, "-c", WORKER, json.dumps(RUNS), str(steps)],
                         stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env,
                         cwd=str(ROOT))
    assert p.stdout is not None and p.stdout.readline().strip() == "ready"
    return p


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="git revision to compare the working tree with")
    ap.add_argument("--rounds", type=int, default=15)
    ap.add_argument("--steps", type=int, default=200)
    a = ap.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="ab_stepping-") as tmp:
        base_src = Path(tmp) / "base"
        extract(a.base, base_src)
        t0 = time.perf_counter()
        sides = {"base": worker(base_src, Path(tmp) / "cache-base", a.steps),
                 "head": worker(ROOT, Path(tmp) / "cache-head", a.steps)}
        print(f"workers compiled in {time.perf_counter() - t0:.0f} s; base {a.base} vs working "
              f"tree; {a.steps} compiled steps a round, fastest of {a.rounds} rounds; "
              f"{platform.processor() or platform.machine()}, Python {platform.python_version()}")
        for name in RUNS:
            best = {s: float("inf") for s in sides}
            last = {}
            for r in range(a.rounds):
                for s in (("base", "head") if r % 2 else ("head", "base")):
                    p = sides[s]
                    assert p.stdin is not None and p.stdout is not None
                    p.stdin.write(name + "\n")
                    p.stdin.flush()
                    got = json.loads(p.stdout.readline())
                    best[s] = min(best[s], got["wall"] / got["steps"])
                    last[s] = (got["steps"], got["t"], got["y"])
            same = "same steps and state" if last["base"] == last["head"] else \
                f"DIFFERENT: {last}"
            print(f"{name}: base {best['base'] * 1e6:8.2f} us/step, head "
                  f"{best['head'] * 1e6:8.2f} us/step, base/head {best['base'] / best['head']:.3f}"
                  f" ({same})")
        for p in sides.values():
            assert p.stdin is not None
            p.stdin.close()
            p.wait()
    return 0


if __name__ == "__main__":
    sys.exit(main())
