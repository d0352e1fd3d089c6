"""Each piece of the batch thread runtime against the same runtime without it, side by side.

    .venv/bin/python benchmarks/ab_threads.py [--dof 250] [--states 64] [--rounds 20]
        [--calls 30] [--busy 1] [--variants now simple ...] [--kinds tiles rows]

The policy pieces of :mod:`redysim.algorithms.threads` are switched per call through its
``AB`` table and ``ADAPT`` flag (each variant with a record of its own of what helpers buy, so
that one does not steer another; the workspaces and outputs rotate among the
variants, turn by turn). Variants: ``now`` (every piece), ``no-X``
(every piece but X), ``simple`` (none: a ``concurrent.futures.ThreadPoolExecutor`` whose
threads sleep between batches, helpers posted whatever the machine runs, the caller waiting for
a late helper's chunk on a ``threading.Condition`` and taking it back after 1.5x its own time
for the chunk by the wall clock), ``simple+X`` (simple with X), and ``threads=1``; ``#2`` after
a name makes a second copy of a variant (the noise between two copies). Kinds: a U rope of
``--dof`` DOF in tiles and row by row; ``xarm7`` and ``talos`` (the ladder's states, tiles).
Phases quiet, busy (``--busy`` processes ``while True: pass``, as ``benchmarks/busy_batch.py``)
and bursty (as many, each busy 30 ms then asleep 30 ms): turns of BLOCK + 1 calls of each
variant in an order drawn afresh each turn, the first call of a turn not counted (it meets the
helper threads as the variant before left them: awake or asleep). Prints per variant the median
call, the median over turns of the turn's median over threads=1's, the total time over
threads=1's, and the others' load over the phase; writes ``results/bench/ab_threads.json``.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from busy_batch import cpu_jiffies, rope, stop_competitors, wait_quiet
from conftest import machine

from redysim import Workspace, forward_dynamics
from redysim.algorithms import threads as runtime

# the competitors of the phases busy (a core kept busy) and bursty (busy 30 ms, asleep 30 ms:
# the load comes and goes while a workspace's record of what helpers buy lags behind)
COMPETITOR = {"busy": "while True: pass",
              "bursty": "import time\nwhile True:\n    t = time.perf_counter()\n"
                        "    while time.perf_counter() - t < 0.03: pass\n    time.sleep(0.03)"}
KINDS = ("tiles", "rows")  # a rope's batch in SIMD tiles, row by row
ROBOTS = {"xarm7": "XARM7-FALL", "talos": "TALOS-FALL"}  # as benchmarks/test_bench_core.py
BLOCK = 5  # timed calls of a variant back to back (after one untimed)
PIECES = {  # name -> (AB key or "adapt", value with the piece, value without)
    "spin": ("spin_watch", True, False),  # helpers watch for the next batch, spinning
    "loadavg": ("idle_check", True, False),  # sleeping helpers woken only for idle cores
    "batch": ("batch_sched", True, False),  # helpers SCHED_BATCH
    "adapt": ("adapt", True, False),  # per-workspace record: helpers only while they pay
    "callspin": ("caller_spin", True, False),  # the caller spins for a helper's chunk
    "cpuclock": ("cpu_clock", True, False),  # late judged by the helper's CPU time
    "own": ("pool", "own", "executor"),  # our own helper threads, not a ThreadPoolExecutor
    # a helper's own buffers on a 64-byte boundary (not in the runtime as first measured: now
    # and simple leave it out, simple+aligned has it)
    "aligned": ("aligned", True, False),
}


def settings(name: str) -> dict:
    """AB table and ADAPT of a variant (a name's ``#...`` suffix makes a second copy of one: the
    noise between two copies of one variant)."""
    name = name.split("#")[0]
    every = {key: on for key, on, _ in PIECES.values()} | {"aligned": False}
    none = {key: off for key, _, off in PIECES.values()}
    if name == "now":
        return every
    if name == "simple":
        return none
    if name.startswith("no-"):
        key, _, off = PIECES[name[3:]]
        return {**every, key: off}
    if name.startswith("simple+"):
        out = dict(none)
        for piece in name[len("simple+"):].split("+"):
            key, on, _ = PIECES[piece]
            out[key] = on
        return out
    raise SystemExit(f"unknown variant {name!r}")


def variant(model, Q, QD, name: str, simd: bool):
    """call(ws, out) of a variant: the batch into ``out`` on ``ws`` with the variant's own
    record of what helpers buy (``ws.batch_speed``, swapped in)."""
    if name.split("#")[0] == "threads=1":
        return lambda ws, out: forward_dynamics(model, Q, QD, ws=ws, out=out, threads=1,
                                                simd=simd)
    ab = settings(name)
    adapt = ab.pop("adapt")
    speeds: dict = {}

    def call(ws, out):
        runtime.AB.update(ab)
        runtime.ADAPT = adapt
        ws.batch_speed = speeds
        forward_dynamics(model, Q, QD, ws=ws, out=out, simd=simd)
    return call


def phase(calls: dict, places: list, rounds: int, per_round: int) -> tuple[dict, float]:
    """Per-call seconds of each variant, and the others' load over the phase (cores). Each turn
    the variants take the (workspace, out) pairs of ``places`` in a rotation drawn afresh: where
    a batch's arrays lie moved its time by up to 6 % (two copies of one variant, each on arrays
    of its own, in one process), and this way every variant meets every placement alike."""
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
                fn(ws, out)  # (not counted: it meets the helpers as the variant before left them)
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
    ap.add_argument("--dof", type=int, nargs="+", default=[250])
    ap.add_argument("--states", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=20)
    ap.add_argument("--calls", type=int, default=30, help="timed calls of each variant a round")
    ap.add_argument("--busy", type=int, default=1)
    ap.add_argument("--kinds", nargs="+", default=["tiles", "rows"])
    ap.add_argument("--phases", nargs="+", default=["quiet", "busy"])
    ap.add_argument("--variants", nargs="+",
                    default=["now", *(f"no-{p}" for p in PIECES if p != "own"), "simple"])
    ap.add_argument("--wait-quiet", type=float, default=0.0,
                    help="seconds to wait at most for others' load under 0.25 cores before "
                         "each quiet phase")
    ap.add_argument("--out", type=Path, default=Path("results/bench/ab_threads.json"))
    args = ap.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))
    date = time.strftime("%Y-%m-%d %H:%M")
    info = machine()
    print(", ".join(f"{k} {v}" for k, v in info.items()) + f", {date}, load average "
          + " ".join(f"{x:.2f}" for x in os.getloadavg()))
    report: dict = {"machine": info, "date": date, "args": {k: str(v) for k, v in
                                                            vars(args).items()}, "configs": []}
    configs = [(dof, kind) for dof in args.dof for kind in args.kinds if kind in KINDS]
    configs += [(None, kind) for kind in args.kinds if kind in ROBOTS]
    for dof, kind in configs:
        if dof is None:  # a robot: the ladder's states, in a tree's tiles
            from ladder import states

            from redysim.io.scenarios import load_scenario
            chain = load_scenario(ROBOTS[kind]).model
            Q, QD = states(chain, args.states)
            simd = True
        else:
            chain = rope(dof)
            rng = np.random.default_rng(0)
            Q = rng.uniform(-0.3, 0.3, (args.states, chain.n_dof))
            QD = rng.normal(size=(args.states, chain.n_dof))
            simd = kind == "tiles"
        if True:
            one = forward_dynamics(chain, Q, QD, threads=1, simd=simd)
            names = [*args.variants, "threads=1"]
            places = [(Workspace(chain), np.empty_like(QD)) for _ in names]
            calls = {name: variant(chain, Q, QD, name, simd) for name in names}
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
                    load = os.getloadavg()[0]
                    times, others = phase(calls, places, args.rounds, args.calls)
                finally:
                    stop_competitors(procs)
                one_t = times["threads=1"]
                results[label] = {
                    "others_cores": others, "loadavg_before": load,
                    "median_us": {k: float(np.median(v)) * 1e6 for k, v in times.items()},
                    "paired": {k: paired(v, one_t) for k, v in times.items()},
                    "total": {k: float(np.sum(v) / np.sum(one_t)) for k, v in times.items()}}
            report["configs"].append({"dof": dof, "kind": kind, "states": args.states,
                                      **results})
            what = f"U rope {dof} DOF, {kind}" if dof else f"{kind} ({chain.n_v} DOF), tiles"
            print(f"\n{args.states} states, {what}: median call us; median over turns of "
                  "(variant / threads=1); total time over threads=1's")
            for label, res in results.items():
                print(f"  {label}: others' load {res['others_cores']:.2f} cores (load average "
                      f"{res['loadavg_before']:.2f} at the start)")
                for name in calls:
                    print(f"    {name:40s} {res['median_us'][name]:8.0f} "
                          f"{res['paired'][name]:6.3f} {res['total'][name]:6.3f}")
    now = settings("now")
    runtime.ADAPT = now.pop("adapt")
    runtime.AB.update(now)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
