"""The batch thread runtime of two revisions side by side in one process, one thread beside.

    .venv/bin/python benchmarks/ab_threads.py --base 435b390 [--dof 250 1000] [--states 64]
        [--rounds 12] [--calls 30] [--kinds tiles rows talos] [--phases quiet busy bursty]
        [--busy 1] [--wait-quiet 300]

The base revision's ``redysim/algorithms/threads.py`` and ``redysim/algorithms/_kernels/spin.py``
(revisions from 435b390 on, where the runtime has a module of its own; 435b390 is main's runtime
of 2026-12-07 moved there unchanged) are read from git and imported beside the working tree's;
each call of the variant ``base`` hands the working tree's batch code
(``redysim.algorithms.dynamics``) the base's ``run_blocks`` and plan, ``head`` the working
tree's, ``threads=1`` neither. Kinds: a U rope of ``--dof`` DOF in SIMD tiles and row by row;
``xarm7`` and ``talos`` (the ladder's 64 states, a tree's tiles: one chunk, so one thread).

Phases: quiet (waiting up to ``--wait-quiet`` s for the load from other processes to fall under
0.25 cores), busy (``--busy`` processes ``while True: pass``, as ``benchmarks/busy_batch.py``)
and bursty (as many, each busy 30 ms then asleep 30 ms: the load comes and goes faster than a
workspace's record of what helpers buy follows). Each phase: turns of BLOCK + 1 calls of each
variant, in an order drawn afresh each turn, the first call of a turn not counted (it meets the
helper threads as the variant before left them, awake or asleep); each turn the variants take
the workspaces and outputs in a rotation drawn afresh (where a batch's arrays lie moved its time
by up to 6 %), each variant with its own record of what helpers buy. Prints per variant the
median call, the median over turns of the turn's median over threads=1's, and the total time
over threads=1's; and the load from other processes over each phase. The bits of every variant
are checked against threads=1's first. Writes ``results/bench/ab_threads.json``.
"""

from __future__ import annotations

import argparse
import importlib.util
import json
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
from busy_batch import cpu_jiffies, rope, stop_competitors, wait_quiet
from conftest import machine

import redysim.algorithms.dynamics as dynamics
from redysim import Workspace, forward_dynamics
from redysim.algorithms import threads as head

ROOT = Path(__file__).resolve().parents[1]
KINDS = ("tiles", "rows")  # a rope's batch in SIMD tiles, row by row
ROBOTS = {"xarm7": "XARM7-FALL", "talos": "TALOS-FALL"}  # as benchmarks/test_bench_core.py
COMPETITOR = {"busy": "while True: pass",
              "bursty": "import time\nwhile True:\n    t = time.perf_counter()\n"
                        "    while time.perf_counter() - t < 0.03: pass\n    time.sleep(0.03)"}
BLOCK = 5  # timed calls of a variant back to back (after one untimed)


def load_base(rev: str, folder: Path):
    """The base revision's runtime as a module of its own (its spin module beside it)."""
    def show(path: str) -> str:
        return subprocess.run(["git", "show", f"{rev}:{path}"], cwd=ROOT, check=True,
                              capture_output=True, text=True).stdout

    spin = show("redysim/algorithms/_kernels/spin.py")
    threads = show("redysim/algorithms/threads.py").replace(
        "from redysim.algorithms._kernels import spin as _spin", "import base_spin as _spin")
    (folder / "base_spin.py").write_text(spin)
    (folder / "base_threads.py").write_text(threads)
    sys.path.insert(0, str(folder))
    spec = importlib.util.spec_from_file_location("base_threads", folder / "base_threads.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


class _Holder:  # what an older runtime's plan reads from a workspace
    def __init__(self, speeds):
        self.batch_speed = speeds


def runtime_of(module):
    """(run_blocks, plan(speeds, key, threads, chunks)) of a runtime module, old or new."""
    if hasattr(module, "plan"):
        return module.run_blocks, module.plan
    return module.run_blocks, lambda speeds, *args: module._speed(_Holder(speeds), *args)


def variant(model, Q, QD, name: str, simd: bool, runtimes: dict):
    """call(ws, out): the batch into ``out`` on ``ws``, on the variant's runtime and with its
    own record of what helpers buy (swapped into ``ws``)."""
    if name == "threads=1":
        return lambda ws, out: forward_dynamics(model, Q, QD, ws=ws, out=out, threads=1,
                                                simd=simd)
    run_blocks, plan = runtimes[name]
    speeds: dict = {}

    def call(ws, out):
        dynamics.run_blocks, dynamics.plan = run_blocks, plan
        ws.batch_speed = speeds
        forward_dynamics(model, Q, QD, ws=ws, out=out, simd=simd)
    return call


def phase(calls: dict, places: list, rounds: int, per_round: int) -> tuple[dict, float]:
    """Per-call seconds of each variant, and the load from other processes over the phase."""
    times: dict[str, list[float]] = {k: [] for k in calls}
    names = list(calls)
    busy0, _ = cpu_jiffies()
    own0, wall0 = os.times(), time.perf_counter()
    order = random.Random(0)
    for _ in range(rounds):
        for _ in range(0, per_round, BLOCK):
            shift = order.randrange(len(places))
            for name in order.sample(names, len(names)):
                fn, record = calls[name], times[name]
                ws, out = places[(names.index(name) + shift) % len(places)]
                fn(ws, out)  # (not counted)
                for _ in range(BLOCK):
                    t0 = time.perf_counter()
                    fn(ws, out)
                    record.append(time.perf_counter() - t0)
    busy1, _ = cpu_jiffies()
    own1, wall1 = os.times(), time.perf_counter()
    own = (own1.user - own0.user) + (own1.system - own0.system)
    others = (busy1 - busy0) / os.sysconf("SC_CLK_TCK") - own
    return times, others / (wall1 - wall0)


def paired(a: list[float], b: list[float]) -> float:
    blocks = [slice(i, i + BLOCK) for i in range(0, min(len(a), len(b)), BLOCK)]
    return float(np.median([np.median(a[k]) / np.median(b[k]) for k in blocks]))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="revision whose runtime is the base")
    ap.add_argument("--dof", type=int, nargs="+", default=[250])
    ap.add_argument("--states", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=12)
    ap.add_argument("--calls", type=int, default=30, help="timed calls of each variant a round")
    ap.add_argument("--busy", type=int, default=1)
    ap.add_argument("--kinds", nargs="+", default=["tiles", "rows"])
    ap.add_argument("--phases", nargs="+", default=["quiet", "busy", "bursty"])
    ap.add_argument("--wait-quiet", type=float, default=0.0,
                    help="seconds to wait at most for others' load under 0.25 cores before "
                         "each quiet phase")
    ap.add_argument("--out", type=Path, default=Path("results/bench/ab_threads.json"))
    args = ap.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    date = time.strftime("%Y-%m-%d %H:%M")
    info = machine()
    print(", ".join(f"{k} {v}" for k, v in info.items()) + f", {date}, base {args.base}, "
          "load average " + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    report: dict = {"machine": info, "date": date, "args": {k: str(v) for k, v in
                                                            vars(args).items()}, "configs": []}
    with tempfile.TemporaryDirectory() as tmp:
        runtimes = {"base": runtime_of(load_base(args.base, Path(tmp))), "head": runtime_of(head)}
        names = ["base", "head", "threads=1"]
        configs = [(dof, kind) for dof in args.dof for kind in args.kinds if kind in KINDS]
        configs += [(None, kind) for kind in args.kinds if kind in ROBOTS]
        for dof, kind in configs:
            if dof is None:  # a robot: the ladder's states, in a tree's tiles
                from ladder import states

                from redysim.io.scenarios import load_scenario
                model = load_scenario(ROBOTS[kind]).model
                Q, QD = states(model, args.states)
                simd = True
            else:
                model = rope(dof)
                rng = np.random.default_rng(0)
                Q = rng.uniform(-0.3, 0.3, (args.states, model.n_v))
                QD = rng.normal(size=(args.states, model.n_v))
                simd = kind == "tiles"
            one = forward_dynamics(model, Q, QD, threads=1, simd=simd)
            places = [(Workspace(model), np.empty_like(QD)) for _ in names]
            calls = {name: variant(model, Q, QD, name, simd, runtimes) for name in names}
            for name in names:  # compile or load; the same bits every way, on every placement
                for ws, out in places:
                    calls[name](ws, out)
                    assert np.array_equal(out, one), name
            results = {}
            for label in args.phases:
                if label == "quiet" and args.wait_quiet:
                    wait_quiet(args.wait_quiet)
                procs = [subprocess.Popen([sys.executable, "-c", COMPETITOR[label]],
                                          start_new_session=True)
                         for _ in range(args.busy if label in COMPETITOR else 0)]
                try:
                    if procs:
                        time.sleep(0.5)
                    times, others = phase(calls, places, args.rounds, args.calls)
                finally:
                    stop_competitors(procs)
                one_t = times["threads=1"]
                results[label] = {
                    "others_cores": others,
                    "median_us": {k: float(np.median(v)) * 1e6 for k, v in times.items()},
                    "paired": {k: paired(v, one_t) for k, v in times.items()},
                    "total": {k: float(np.sum(v) / np.sum(one_t)) for k, v in times.items()}}
            report["configs"].append({"dof": dof, "kind": kind, "states": args.states,
                                      **results})
            what = f"U rope {dof} DOF, {kind}" if dof else f"{kind} ({model.n_v} DOF), tiles"
            print(f"\n{args.states} states, {what}: median call us; median over turns of "
                  "(variant / threads=1); total time over threads=1's")
            for label, res in results.items():
                print(f"  {label}: others' load {res['others_cores']:.2f} cores")
                for name in names:
                    print(f"    {name:10s} {res['median_us'][name]:8.0f} "
                          f"{res['paired'][name]:6.3f} {res['total'][name]:6.3f}")
    dynamics.run_blocks, dynamics.plan = head.run_blocks, head.plan
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
