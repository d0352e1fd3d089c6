"""A batch on threads while another process keeps a core busy: never slower than one thread.

    .venv/bin/python benchmarks/busy_batch.py [--dof 250] [--states 64] [--rounds 9]
        [--calls 30] [--busy 1]

A batch of ``--states`` states of a U rope (``--dof`` DOF, a list) through
``forward_dynamics``: in SIMD tiles (the default) and row by row (``simd=False``),
each at the default thread count and at ``threads=1``, beside the same states as single calls in
a Python loop. Two phases: quiet (whatever else the machine runs: its load from other processes
is printed) and busy, with ``--busy`` competitors (``python -c 'while True: pass'``, each in a
session of its own, killed at the end whatever happens). Each phase: ``--rounds`` rounds of
``--calls`` calls of every variant, in turns of 5 calls of each (in an order drawn afresh each
turn, so that every variant meets the same load and follows every other), every call timed
alone. Prints per variant
the median and mean time of a call and the ratio of the median to ``threads=1``'s (> 1.10: the
threads cost more than 10 %); writes ``results/bench/busy_batch.json``.
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
from conftest import machine

import redysim.algorithms.threads
from redysim import Chain, forward_dynamics
from redysim.algorithms.threads import default_threads

BUSY = "while True: pass"
BLOCK = 5  # calls of a variant back to back


def rope(dof: int) -> Chain:
    return Chain.uniform(dof // 2, "U", length=0.02, linear_density=7850 * np.pi * 0.05**2,
                         radius=0.05, inertia="rod", name=f"U{dof // 2}")


def variants(model, Q, QD, chunks: list[int] | None) -> dict:
    """name -> call. With ``chunks`` (values of redysim.algorithms.threads.CHUNK_WORK), the
    default-thread batches once per chunk size, side by side."""
    out = np.empty_like(Q)

    def singles():
        for i in range(Q.shape[0]):
            forward_dynamics(model, Q[i], QD[i], out=out[i])

    def chunked(work, **kw):
        def call():
            if work is not None:
                redysim.algorithms.threads.CHUNK_WORK = work
            forward_dynamics(model, Q, QD, out=out, **kw)
        return call

    calls = {}
    for kind, kw in (("tiles", {}), ("rows", {"simd": False})):
        for work in chunks or [None]:
            label = f"{kind}, default threads" + (f", chunk {work}" if chunks else "")
            calls[label] = chunked(work, **kw)
        calls[f"{kind}, threads=1"] = chunked(None, threads=1, **kw)
    calls[f"{Q.shape[0]} single calls"] = singles
    return calls


def cpu_jiffies() -> tuple[int, int]:
    """(busy, total) jiffies of the whole machine so far (/proc/stat)."""
    with open("/proc/stat") as fh:
        v = [int(x) for x in fh.readline().split()[1:]]
    idle = v[3] + v[4]
    return sum(v) - idle, sum(v)


def phase(calls: dict, rounds: int, per_round: int) -> tuple[dict, float]:
    """Per-call seconds of each variant, and the machine's load from processes other than this
    one over the phase (in cores)."""
    times: dict[str, list[float]] = {k: [] for k in calls}
    names = list(calls)
    busy0, total0 = cpu_jiffies()
    own0, wall0 = os.times(), time.perf_counter()
    order = random.Random(0)
    for _ in range(rounds):
        for c in range(0, per_round, BLOCK):  # short blocks of each variant in turn: all see
            # the same load, each runs back to back; in an order drawn afresh each turn, since
            # a block pays for what the block before it left in the caches
            for name in order.sample(names, len(names)):
                fn, record = calls[name], times[name]
                for _ in range(min(BLOCK, per_round - c)):
                    t0 = time.perf_counter()
                    fn()
                    record.append(time.perf_counter() - t0)
    busy1, total1 = cpu_jiffies()
    own1, wall1 = os.times(), time.perf_counter()
    hz = os.sysconf("SC_CLK_TCK")
    own = (own1.user - own0.user) + (own1.system - own0.system)
    others = (busy1 - busy0) / hz - own
    return times, others / (wall1 - wall0)


def others_load(seconds: float) -> float:
    """The machine's load from processes other than this one over ``seconds``, in cores."""
    busy0, own0, wall0 = cpu_jiffies()[0], os.times(), time.perf_counter()
    time.sleep(seconds)
    busy1, own1, wall1 = cpu_jiffies()[0], os.times(), time.perf_counter()
    own = (own1.user - own0.user) + (own1.system - own0.system)
    return ((busy1 - busy0) / os.sysconf("SC_CLK_TCK") - own) / (wall1 - wall0)


def wait_quiet(limit_s: float) -> None:
    end = time.monotonic() + limit_s
    while time.monotonic() < end and others_load(0.5) > 0.25:
        pass


def paired(a: list[float], b: list[float]) -> float:
    """The median over turns of (median of a's calls in the turn) / (b's): a ratio of calls
    made a few milliseconds apart, which the machine's drifts over a phase do not move."""
    blocks = [slice(i, i + BLOCK) for i in range(0, min(len(a), len(b)), BLOCK)]
    return float(np.median([np.median(a[k]) / np.median(b[k]) for k in blocks]))


def summary(times: dict) -> dict:
    return {k: {"median_s": float(np.median(v)), "mean_s": float(np.mean(v)),
                "p90_s": float(np.percentile(v, 90)), "calls": len(v)} for k, v in times.items()}


def start_competitors(count: int) -> list[subprocess.Popen]:
    procs = []
    for _ in range(count):
        procs.append(subprocess.Popen([sys.executable, "-c", BUSY], start_new_session=True))
    return procs


def stop_competitors(procs: list[subprocess.Popen]) -> None:
    for p in procs:
        try:
            os.killpg(p.pid, signal.SIGKILL)  # its own session and group: nothing else in it
        except ProcessLookupError:
            pass
        p.wait()


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dof", type=int, nargs="+", default=[250])
    ap.add_argument("--states", type=int, default=64)
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--calls", type=int, default=30, help="calls of each variant a round")
    ap.add_argument("--busy", type=int, default=1, help="busy competitor processes")
    ap.add_argument("--chunk-work", type=int, nargs="+", default=None,
                    help="DOF x states a chunk (redysim.algorithms.threads.CHUNK_WORK), "
                    "each a config")
    ap.add_argument("--wait-quiet", type=float, default=0.0,
                    help="seconds to wait at most for the machine to be quiet (others' load "
                         "under 0.25 cores) before each quiet phase")
    ap.add_argument("--out", type=Path, default=Path("results/bench/busy_batch.json"))
    args = ap.parse_args(argv)
    signal.signal(signal.SIGTERM, lambda *_: sys.exit(143))  # so that finally kills them

    info = {**machine(), "default_threads": default_threads()}
    date = time.strftime("%Y-%m-%d %H:%M")
    print(", ".join(f"{k} {v}" for k, v in info.items()) + f", {date}")
    report: dict = {"machine": info, "date": date, "args": {k: str(v) for k, v in
                                                            vars(args).items()}, "configs": []}
    default_chunk = redysim.algorithms.threads.CHUNK_WORK
    for dof in args.dof:
        chain = rope(dof)
        rng = np.random.default_rng(0)
        Q = rng.uniform(-0.3, 0.3, (args.states, chain.n_dof))
        QD = rng.normal(size=(args.states, chain.n_dof))
        calls = variants(chain, Q, QD, args.chunk_work)
        for fn in calls.values():  # compile or load the kernels; the threads and workspace
            fn()
        # the same bits on threads as on one
        assert np.array_equal(forward_dynamics(chain, Q, QD),
                              forward_dynamics(chain, Q, QD, threads=1))
        assert np.array_equal(forward_dynamics(chain, Q, QD, simd=False),
                              forward_dynamics(chain, Q, QD, simd=False, threads=1))
        results = {}
        for label in ("quiet", "busy"):
            if label == "quiet" and args.wait_quiet:
                wait_quiet(args.wait_quiet)
            procs = start_competitors(args.busy) if label == "busy" else []
            try:
                if procs:
                    time.sleep(0.5)  # let them be running
                times, others = phase(calls, args.rounds, args.calls)
            finally:
                stop_competitors(procs)
            results[label] = {"others_cores": others, "variants": summary(times),
                              "paired": {name: paired(times[name],
                                                      times[f"{name.split(',')[0]}, threads=1"])
                                         for name in times if "default threads" in name}}
        redysim.algorithms.threads.CHUNK_WORK = default_chunk
        report["configs"].append({"dof": dof, "states": args.states,
                                  "chunk_work": args.chunk_work or default_chunk, **results})
        chunk = ("" if args.chunk_work else
                 f", chunks of {default_chunk} DOF x states (CHUNK_WORK)")
        print(f"\n{args.states} states of a U rope, {dof} DOF{chunk}; per call, us: median "
              f"(mean) over {args.rounds} rounds x {args.calls} calls; ratio: median over "
              "threads=1's")
        width = max(len(name) for name in calls) + 1
        print(f"{'variant':{width}s}" + "".join(f"{label + ' median (mean) ratio':>32s}"
                                                for label in results))
        for name in calls:
            cells = []
            for label in results:
                v = results[label]["variants"]
                one = v[f"{name.split(',')[0]}, threads=1"] if "threads" in name else None
                ratio = f"{v[name]['median_s'] / one['median_s']:5.2f}" if one else "     "
                cells.append(f"{v[name]['median_s'] * 1e6:9.0f} ({v[name]['mean_s'] * 1e6:7.0f})"
                             f" {ratio}")
            print(f"{name:{width}s}" + "".join(f"{c:>32s}" for c in cells))
        for label, res in results.items():
            v = res["variants"]
            single = v[f"{args.states} single calls"]["median_s"]
            best = min(m["median_s"] for k, m in v.items() if k.startswith("tiles"))
            pairs = "; ".join(f"{name.replace(', default threads', '')} {r:.2f}"
                              for name, r in res["paired"].items())
            print(f"{label:5s}: others' load {res['others_cores']:.2f} cores; "
                  f"{args.states} single calls / fastest tiles {single / best:.1f}x; "
                  f"default / threads=1, turn by turn (median): {pairs}")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(report, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
