"""Benchmarks record the versions and the machine with every result."""

from __future__ import annotations

import os
import platform
import statistics
import time
import timeit

import numba
import numpy as np
import pytest

import redysim


def machine() -> dict:
    cpu = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(line.split(":", 1)[1].strip() for line in fh
                       if line.startswith("model name"))
    except (OSError, StopIteration):
        pass
    return {"cpu": cpu, "cores": os.cpu_count(), "python": platform.python_version(),
            "numpy": np.__version__, "numba": numba.__version__, "redysim": redysim.__version__}


def loop_of(kernel):
    """A compiled loop calling ``kernel`` (a lean entry: q, v, tau, out, fdata, idata, scratch)
    ``count`` times on the same arguments: the kernel's cost inside compiled code."""
    from redysim._jit import LEAN_OPTIONS

    @numba.njit(**dict(LEAN_OPTIONS, cache=False))
    def loop(q, v, tau, out, f, i, s, count):
        for _ in range(count):
            kernel(q, v, tau, out, f, i, s)
        return out

    return loop


def side_by_side(fns: dict, rounds: int, round_s: float, per: dict | None = None) -> dict:
    """Seconds per call of each callable (per state: divided by ``per[name]``, the states or
    calls one invocation does), the callables alternating within every round (the order
    reversed every other round, so that a neighbour's load falls on all of them); each round a
    ``timeit`` loop of ~``round_s``. Returns name -> {median_s, min_s, number}."""
    per = per or {}
    numbers = {}
    for k, fn in fns.items():
        fn()
        number, _ = timeit.Timer(fn).autorange()
        t0 = time.perf_counter()
        timeit.Timer(fn).timeit(number)
        numbers[k] = max(1, int(number * round_s / max(time.perf_counter() - t0, 1e-9)))
    times: dict[str, list[float]] = {k: [] for k in fns}
    items = list(fns.items())
    for r in range(rounds):
        for k, fn in items if r % 2 == 0 else items[::-1]:
            times[k].append(timeit.Timer(fn).timeit(numbers[k]) / numbers[k] / per.get(k, 1))
    return {k: {"median_s": statistics.median(v), "min_s": min(v), "number": numbers[k]}
            for k, v in times.items()}


@pytest.fixture
def record(benchmark):
    """benchmark.extra_info with the machine, plus a helper to add ns/DOF after the run."""
    benchmark.extra_info.update(machine())
    return benchmark.extra_info
