"""CPU time of one qdd call against the number of DOF, per engine and algorithm (Fig. 18).

    python -m redysim.reports.scaling [--out results/scaling] [--max-dof 100000]
                                      [--budget quick|full]

The chain is the RE-U steel rod (l = 0.02 m, rod inertia) at a seeded small-angle state, as in
``benchmarks/test_bench_engines.py``. Per algorithm (the core's RGE-A, GE-N and RGE-N, and every
reference engine's qdd) the DOF grid :data:`DOF_GRID` is walked upwards; each point is warmed up
(JIT compile or model build, timed apart) and then timed as the fastest of batches of calls.

A size is not attempted when the engine's measured limits (``references/limits.toml``) refuse it,
or when the next point, extrapolated from the last two measured (exponent fitted between them;
3 after the first), would exceed the budget's time per call, build time or memory growth: the row
then records which budget stopped it. "Measure rather than guess": nothing is assumed about an
engine's complexity beyond the points it has shown.

Output: ``scaling.parquet``, one row per (algorithm, DOF): seconds per call, ns per DOF, build
seconds, resident memory growth of the build, status (``ok``, ``refused``, ``budget``,
``failed``) and reason, with provenance.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
import psutil

from redysim import Chain, Model, Workspace, __version__, forward_dynamics, references
from redysim.harness.provenance import provenance
from redysim.harness.spec import CORE
from redysim.harness.store import write_parquet_atomic

DEFAULT_OUT = Path("results") / "scaling"
OUT_FILE = "scaling.parquet"
DOF_GRID = (20, 50, 100, 200, 500, 1_000, 2_000, 5_000, 10_000, 20_000, 50_000, 100_000)
LINK_LENGTH = 0.02                      # the RE-U chains' link
LINEAR_DENSITY = 7850 * np.pi * 0.05**2
RADIUS = 0.05
STATE_SPREAD = 0.1                      # q, qd ~ U(-0.1, 0.1), as the engine benchmark
SEED = 0
BATCH_S = 0.05                          # a timing batch lasts about this long
BATCHES = 5                             # the fastest of this many batches
FIRST_EXPONENT = 3.0                    # growth assumed after the first point of an algorithm
CORE_ALGORITHMS = ("rge-a", "ge-n", "rge-n")
SLOPE_MIN_DOF = 100                     # slopes are fitted from here on (below, fixed costs)
MIB = 2**20


@dataclass(frozen=True)
class Budget:
    """What one point may cost: a qdd call, a model build, the build's memory growth."""

    call_s: float
    build_s: float
    memory_mib: float


BUDGETS = {
    "quick": Budget(call_s=0.5, build_s=10.0, memory_mib=2048.0),
    # references/limits.toml [budget]: 10 s per call, 120 s to build, 12 GiB
    "full": Budget(call_s=10.0, build_s=120.0, memory_mib=12 * 1024.0),
}


def make_chain(dof: int) -> Chain:
    return Chain.uniform(dof // 2, "U", length=LINK_LENGTH, linear_density=LINEAR_DENSITY,
                         radius=RADIUS, inertia="rod", name=f"U{dof // 2}")


def make_state(model: Model) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(SEED)
    return (rng.uniform(-STATE_SPREAD, STATE_SPREAD, model.n_dof),
            rng.uniform(-STATE_SPREAD, STATE_SPREAD, model.n_dof))


def time_call(call) -> float:
    """Seconds per call: the fastest of :data:`BATCHES` batches of about :data:`BATCH_S` each.

    The fastest, not the median: the calls are deterministic and a shared machine only ever adds
    time; sets of batches timed one after another moved their medians far more than their
    fastest batches (docs/notes/2026-11-costs-in-the-code.md). Every algorithm is timed alike, so
    the ratios stay fair; pytest-benchmark's tables (``make bench``) lead with the minimum too.
    """
    t0 = time.perf_counter()
    call()
    one = max(time.perf_counter() - t0, 1e-9)
    per_batch = max(1, int(BATCH_S / one))
    times = []
    for _ in range(BATCHES if one < BATCH_S else 1):
        t0 = time.perf_counter()
        for _ in range(per_batch):
            call()
        times.append((time.perf_counter() - t0) / per_batch)
    return float(min(times))


def extrapolate(points: list[tuple[int, float]], dof: int) -> float:
    """The value at ``dof`` from the last two (dof, value) points, power law between them."""
    if not points:
        return 0.0
    (n1, v1), (n0, v0) = points[-1], points[-2] if len(points) > 1 else (None, None)
    if n0 is None or v0 <= 0 or v1 <= 0:
        exponent = FIRST_EXPONENT
    else:
        exponent = max(1.0, math.log(v1 / v0) / math.log(n1 / n0))
    return v1 * (dof / n1) ** exponent


class _Core:
    """The core's qdd by one method."""

    def __init__(self, method: str, model: Model):
        self.method, self.model, self.ws = method, model, Workspace(model)
        self.version = __version__

    def qdd(self, q, qd):
        return forward_dynamics(self.model, q, qd, method=self.method, ws=self.ws)


def algorithms() -> list[tuple[str, str]]:
    """(engine, algorithm label) of every algorithm timed."""
    return [(CORE, m) for m in CORE_ALGORITHMS] + [(e, e) for e in references.ENGINES]


def measure(budget: Budget, max_dof: int, log=print) -> pd.DataFrame:
    rows = []
    proc = psutil.Process()
    for engine, label in algorithms():
        calls: list[tuple[int, float]] = []
        builds: list[tuple[int, float]] = []
        mems: list[tuple[int, float]] = []
        cls = None if engine == CORE else references.get(engine)
        if cls is not None and not cls.available():
            rows.append({"engine": engine, "algorithm": label, "n_dof": 0, "status": "refused",
                         "reason": f"package {cls.package!r} not installed"})
            continue
        for dof in (d for d in DOF_GRID if d <= max_dof):
            chain = make_chain(dof)
            row = {"engine": engine, "algorithm": label, "n_dof": dof,
                   "n_links": chain.n_links, "status": "ok", "reason": ""}
            why = ""
            if cls is not None and not (lim := cls.limits(chain)).ok:
                row.update(status="refused", reason=lim.reason)
                rows.append(row)
                break
            for what, pts, limit, unit in (("qdd call", calls, budget.call_s, "s"),
                                           ("build", builds, budget.build_s, "s"),
                                           ("build memory", mems, budget.memory_mib, "MiB")):
                guess = extrapolate(pts, dof)
                if guess > limit:
                    why = (f"{what} extrapolated to {guess:.3g} {unit} at {dof:,} DOF, over the "
                           f"budget of {limit:g} {unit}")
                    break
            if why:
                row.update(status="budget", reason=why)
                rows.append(row)
                break
            q, qd = make_state(chain)
            rss0 = proc.memory_info().rss
            try:
                t0 = time.perf_counter()
                impl = _Core(label, chain) if cls is None else cls(chain)
                impl.qdd(q, qd)  # JIT compile / cache load or first call, timed with the build
                build_s = time.perf_counter() - t0
                per_call = time_call(lambda impl=impl, q=q, qd=qd: impl.qdd(q, qd))
            except Exception as exc:  # an engine's failure is a result, not a crash
                row.update(status="failed", reason=f"{type(exc).__name__}: {exc}"[:300])
                rows.append(row)
                break
            mem = (proc.memory_info().rss - rss0) / MIB
            row.update(seconds_per_call=per_call, ns_per_dof=per_call / dof * 1e9,
                       build_s=build_s, build_mem_mib=mem, version=impl.version,
                       load_avg_1min=os.getloadavg()[0])
            rows.append(row)
            log(f"{label:20} {dof:>7,} DOF  {per_call * 1e6:12.1f} us/call  "
                f"{per_call / dof * 1e9:9.1f} ns/DOF  build {build_s:6.2f} s  +{mem:7.0f} MiB")
            calls.append((dof, per_call))
            if engine != CORE:  # the core builds nothing; its first call is the JIT
                builds.append((dof, build_s))
                mems.append((dof, max(mem, 1.0)))
            del impl
    df = pd.DataFrame(rows)
    for k, v in provenance().items():
        df[k] = v
    return df


def slopes(df: pd.DataFrame, min_dof: int = SLOPE_MIN_DOF) -> dict[str, float]:
    """Fitted exponent of seconds per call against DOF (log-log least squares) per algorithm,
    over the points at or above ``min_dof``."""
    out = {}
    ok = df[(df.status == "ok") & (df.n_dof >= min_dof)]
    for label, g in ok.groupby("algorithm", sort=False):
        if len(g) >= 2:
            out[label] = float(np.polyfit(np.log(g.n_dof), np.log(g.seconds_per_call), 1)[0])
    return out


def run(out: Path, budget: str = "quick", max_dof: int = max(DOF_GRID), log=print) -> pd.DataFrame:
    """Time every algorithm under ``budget`` and write ``scaling.parquet`` into ``out``."""
    df = measure(BUDGETS[budget], max_dof, log=log)
    write_parquet_atomic(df, out / OUT_FILE)
    return df


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory")
    ap.add_argument("--max-dof", type=int, default=max(DOF_GRID), help="largest size timed")
    ap.add_argument("--budget", choices=list(BUDGETS), default="quick",
                    help="cost limits per point (quick: 0.5 s/call, 10 s build, 2 GiB)")
    args = ap.parse_args(argv)
    df = run(args.out, args.budget, args.max_dof)
    for label, s in slopes(df).items():
        print(f"slope {label:20} {s:5.2f}")
    stops = df[df.status != "ok"]
    for _, r in stops.iterrows():
        print(f"{r.algorithm:20} stopped at {r.n_dof:,} DOF: {r.status}: {r.reason}")
    print(f"written to {args.out / OUT_FILE}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
