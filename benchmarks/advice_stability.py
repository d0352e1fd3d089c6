"""``redysim compare``'s advice, quiet and beside a busy process: does the load change it?

    .venv/bin/python benchmarks/advice_stability.py [--models ur5 panda rope]
        [--out results/bench/advice_stability] [--rope-t-end 0.2] [--workers 1] [--reuse]

For each model (the UR5-FALL scenario, the Menagerie Panda fixture, the 250-DOF rope
RE-U125-L1, over ``--rope-t-end`` s with the core and MuJoCo only, to keep it short) the whole
comparison (:func:`redysim.reports.compare.compare`: every run, its page) twice, each into a
folder of its own (no cached run is reused): quiet (whatever else the machine runs: its load
from other processes is printed) and busy, beside one competitor (``python -c 'while True:
pass'``, in a session of its own, killed at the end whatever happens). Prints, per path
tolerance, the advice of each phase (the pick and the runs indistinguishable from it, by
:mod:`redysim.harness.cost`) and whether it changed: "same pick", "another pick, within the
other's indistinguishable set" (the verdict held: both phases said the two cannot be told
apart) or "CHANGED" (the busy phase picked a run the quiet phase ranked distinguishably dearer).
Writes ``advice.json`` in ``--out``.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

from conftest import machine

BUSY = "while True: pass"
ROOT = Path(__file__).resolve().parent.parent
MODELS = {
    "ur5": ("UR5-FALL", {}, None),
    "panda": (str(ROOT / "tests/models/menagerie/franka_emika_panda/panda.xml"), {}, None),
    "rope": ("RE-U125-L1", {}, ("mujoco",)),
}


def cpu_jiffies() -> tuple[int, int]:
    with open("/proc/stat") as fh:
        v = [int(x) for x in fh.readline().split()[1:]]
    idle = v[3] + v[4]
    return sum(v) - idle, sum(v)


def load_since(j0) -> float:
    """Busy cores of the whole machine since ``j0`` (all processes, ours included)."""
    b1, t1 = cpu_jiffies()
    return (b1 - j0[0]) / max(1, t1 - j0[1]) * (os.cpu_count() or 1)


def run_phase(name: str, target: str, engines, t_end: float, out: Path, workers: int,
              reuse: bool = False) -> dict:
    from redysim.harness.sweep import collect
    from redysim.reports.compare import advice, compare, label, setting

    j0 = cpu_jiffies()
    wall = time.perf_counter()
    if not reuse:
        compare(target, out, t_end=t_end, workers=workers, engines=engines, progress=False,
                log=lambda *a: None)
    runs = collect(out)
    res = {"wall_s": time.perf_counter() - wall, "load": load_since(j0), "advice": []}
    for a in advice(runs):
        b = a["best"]
        res["advice"].append({
            "tol": a["tol"], "pick": None if b is None else f"{label(b)} {setting(b)}",
            "cost_s": None if b is None else float(b["cost_s"]),
            "tied": [f"{label(r)} {setting(r)}" for r in a["tied"]]})
    return res


def verdict(q: dict, b: dict) -> str:
    if q["pick"] == b["pick"]:
        return "same pick"
    if b["pick"] in q["tied"] or q["pick"] in b["tied"]:
        return "another pick, within the other's indistinguishable set"
    return "CHANGED"


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--models", nargs="+", default=list(MODELS), choices=list(MODELS))
    ap.add_argument("--out", type=Path, default=Path("results/bench/advice_stability"))
    ap.add_argument("--rope-t-end", type=float, default=0.2)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--reuse", action="store_true", help="rank the runs already in --out again "
                    "(the advice's logic changed, the measurements not): nothing is run")
    args = ap.parse_args()
    print(json.dumps(machine()))
    report = {}
    for key in args.models:
        target, _opts, engines = MODELS[key]
        t_end = args.rope_t_end if key == "rope" else 0.0
        phases = {}
        for phase in ("quiet", "busy"):
            busy = None
            if phase == "busy" and not args.reuse:
                busy = subprocess.Popen([sys.executable, "-c", BUSY], start_new_session=True)
            try:
                phases[phase] = run_phase(key, target, engines, t_end,
                                          args.out / key / phase, args.workers, args.reuse)
            finally:
                if busy is not None:
                    os.killpg(busy.pid, signal.SIGTERM)
                    busy.wait()
            p = phases[phase]
            print(f"{key} {phase}: {p['wall_s']:.0f} s wall, machine load {p['load']:.2f} "
                  f"busy cores of {os.cpu_count()}", flush=True)
        for q, b in zip(phases["quiet"]["advice"], phases["busy"]["advice"], strict=True):
            print(f"  {key} within {q['tol']:g} m: quiet {q['pick']} "
                  f"({(q['cost_s'] or 0) * 1e3:.3g} ms; indistinguishable: "
                  f"{', '.join(q['tied']) or 'none'}) | busy {b['pick']} "
                  f"({(b['cost_s'] or 0) * 1e3:.3g} ms; indistinguishable: "
                  f"{', '.join(b['tied']) or 'none'}) -> {verdict(q, b)}", flush=True)
        report[key] = phases
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "advice.json").write_text(json.dumps(report, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
