"""A run's cost, measured so that the machine's load cannot reorder an advice, and the ranking of
runs by it (used by ``redysim compare``'s advice and by ``redysim advise``).

What is measured (:func:`redysim.harness.run.execute`, the row's columns):

- ``cost_s``: the integration's CPU time [s], the least over ``cost_repeats`` runs of the same
  spec in the same process. A run shorter than :data:`TOTAL_S` is repeated until its repeats
  add up to it (at least :data:`MIN_REPEATS`, at most :data:`MAX_REPEATS` runs); a longer run is
  measured once, and so is every run when ``REDYSIM_COST_REPEAT_S=0`` (the test suite's
  setting). The sampling (each sample's projection, energy and observers: the harness's
  measurement, ~80 us a sample in Python) is timed apart (``sample_cpu_s``) and excluded, and so
  are the JIT compile and an engine's build. The least of k repeats is the run's cost with the
  least of the machine's interference (another process can only add time).
- ``cost_spread``: (median - min) / min of the repeats' integration CPU (nan: one run).
- ``rhs_s``: one call of the run's derivative (its qdd and forces, through the harness's
  System), the least of a few timed batches in the same process; ``work_s`` = ``nfev`` x
  ``rhs_s``: the RHS calls' work, load-free in its count (nan for an engine's own stepper,
  whose calls are inside the engine).

How runs are ranked (:func:`cost_of`, :func:`rank`): each cost is an interval, its least measure
over (1 + u) to its least measure times (1 + u), with u the relative uncertainty: the repeats'
spread, at least :data:`NOISE_FLOOR` (what a busy neighbour adds to a minimum of repeats here:
caches and memory bandwidth are shared, not only cores), and :data:`SINGLE_RUN` for a cost
measured once. Two runs whose intervals overlap are **indistinguishable**: no measurement here
says which is cheaper. :func:`rank` orders by the least measure and names the runs
indistinguishable from the cheapest; among them, the pick is the one of least work (``work_s``)
when all of them have it, so that noise inside the interval does not reorder the advice (else
the least measure: an engine's own stepper has no work to compare).
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

REPEAT_ENV = "REDYSIM_COST_REPEAT_S"  # the environment's setting of TOTAL_S (0: measure once)


def _total_s() -> float:
    """:data:`TOTAL_S` from the environment (``REDYSIM_COST_REPEAT_S``; default 0.2 s): 0
    measures each run once (the test suite's setting: its runs are checks, not rankings, and the
    repeats would add ~0.2 s of CPU to each)."""
    text = os.environ.get(REPEAT_ENV, "").strip()
    if not text:
        return 0.2
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value >= 0.0):
        from redysim.errors import SettingsError

        raise SettingsError("environment", REPEAT_ENV, text, "must be a CPU time >= 0 [s] "
                            "(0: measure each run once)")
    return value


TOTAL_S = _total_s()  # repeat a run shorter than this until its repeats add up to it [s of CPU]
MIN_REPEATS = 3  # a short run's least number of timed runs
MAX_REPEATS = 20  # and most
NOISE_FLOOR = 0.10  # least relative uncertainty of a measured cost (a minimum of repeats)
SINGLE_RUN = 0.25  # relative uncertainty of a cost measured once (no spread to go by)
RHS_BATCH_S = 0.01  # CPU of one timed batch of derivative calls [s]
RHS_BATCHES = 3  # batches; the least per-call time is kept
INDISTINGUISHABLE = "indistinguishable"

COST_COLUMNS = ("cost_s", "cost_repeats", "cost_spread", "sample_cpu_s", "rhs_s", "work_s")


@dataclass(frozen=True)
class Cost:
    """A measured cost [s]: ``value`` the least measure, ``lo``..``hi`` its interval,
    ``repeats`` how many runs it is the least of, ``spread`` their (median - min) / min."""

    value: float
    lo: float
    hi: float
    repeats: int = 1
    spread: float = math.nan
    work: float = math.nan  # work_s: RHS calls x per-call cost (nan: not measured)

    @property
    def ok(self) -> bool:
        return math.isfinite(self.value) and self.value >= 0

    def overlaps(self, other: Cost) -> bool:
        """Whether no measurement says which of the two is cheaper."""
        return self.lo <= other.hi and other.lo <= self.hi


def uncertainty(repeats: int, spread: float) -> float:
    """The relative uncertainty of a cost that is the least of ``repeats`` runs whose relative
    spread is ``spread``: the spread, at least NOISE_FLOOR; SINGLE_RUN when measured once."""
    if repeats <= 1 or not math.isfinite(spread):
        return SINGLE_RUN
    return max(NOISE_FLOOR, float(spread))


def make_cost(value: float, repeats: int = 1, spread: float = math.nan,
              work: float = math.nan) -> Cost:
    """A Cost of least measure ``value`` with its interval (module docstring)."""
    value = float(value)
    u = uncertainty(int(repeats), float(spread))
    return Cost(value, value / (1.0 + u), value * (1.0 + u), int(repeats), float(spread),
                float(work))


def _num(row, key: str, default: float = math.nan) -> float:
    try:
        v = row[key]
    except (KeyError, IndexError):
        return default
    try:
        v = float(v)
    except (TypeError, ValueError):
        return default
    return v if math.isfinite(v) else default


def cost_of(row) -> Cost:
    """The Cost of a run's row (a dict or a pandas Series): ``cost_s`` with its repeats and
    spread; a row from before these columns (its ``cpu_s`` only, sampling included) counts as
    measured once."""
    value = _num(row, "cost_s")
    if math.isnan(value):
        return make_cost(_num(row, "cpu_s"), 1, math.nan, _num(row, "work_s"))
    return make_cost(value, int(_num(row, "cost_repeats", 1.0)), _num(row, "cost_spread"),
                     _num(row, "work_s"))


@dataclass(frozen=True)
class Ranking:
    """The pick (an index of the items ranked), the items indistinguishable from it (indices,
    the pick's own excluded) and each item's Cost, in the order given."""

    pick: int
    indistinguishable: tuple[int, ...]
    costs: tuple[Cost, ...]

    @property
    def verdict(self) -> str:
        """"indistinguishable" when another choice's cost overlaps the pick's, else
        "cheapest"."""
        return INDISTINGUISHABLE if self.indistinguishable else "cheapest"


def rank(costs: Sequence[Cost]) -> Ranking | None:
    """The cheapest of ``costs`` and those indistinguishable from it (None: no finite cost).
    The group is every cost whose interval overlaps the least measure's; the pick is the one of
    least work in it when every member's work is measured (else of least ``value``), ties by
    the least measure, then by position."""
    idx = [i for i, c in enumerate(costs) if c.ok]
    if not idx:
        return None
    least = min(idx, key=lambda i: (costs[i].value, i))
    group = [i for i in idx if costs[i].overlaps(costs[least])]

    # work orders the group only when every member has it (an engine's own stepper has none,
    # and work, measured through the Python entry, is not its CPU)
    by_work = all(math.isfinite(costs[i].work) for i in group)

    def key(i: int) -> tuple[float, float, int]:
        return (costs[i].work if by_work else costs[i].value, costs[i].value, i)

    pick = min(group, key=key)
    return Ranking(pick, tuple(i for i in group if i != pick), tuple(costs))


def compare_two(a: Cost, b: Cost) -> str:
    """How ``a`` stands against ``b``: "indistinguishable" when their intervals overlap, else
    "cheaper" or "dearer"."""
    if a.overlaps(b):
        return INDISTINGUISHABLE
    return "cheaper" if a.value < b.value else "dearer"


def repeat(once: Callable[[], float], first: float, *, total_s: float | None = None,
           min_repeats: int = MIN_REPEATS, max_repeats: int = MAX_REPEATS) -> list[float]:
    """The integration CPU times of a run: ``first`` (the run already made), then ``once()``
    (another run, returning its integration CPU) while the run is short: until the times add up
    to ``total_s`` with at least ``min_repeats`` of them, at most ``max_repeats``. A run of
    ``total_s`` or more is measured once. ``once()`` returning nan (the repeat did not repeat
    the run) ends the repeats, the times before it kept."""
    total_s = TOTAL_S if total_s is None else total_s
    times = [float(first)]
    if not math.isfinite(first) or first >= total_s:
        return times
    while len(times) < max_repeats and (sum(times) < total_s or len(times) < min_repeats):
        t = float(once())
        if not math.isfinite(t):
            break
        times.append(t)
    return times


def summary(times: Sequence[float]) -> dict:
    """The row's columns of repeated times: ``cost_s`` (the least), ``cost_repeats``,
    ``cost_spread`` ((median - min) / min: how far a typical repeat lies above the least; nan
    for one)."""
    lo = min(times)
    mid = sorted(times)[len(times) // 2]
    spread = (mid - lo) / lo if len(times) > 1 and lo > 0 else math.nan
    return {"cost_s": lo, "cost_repeats": len(times), "cost_spread": spread}


def per_call(call: Callable[[], object], *, batch_s: float = RHS_BATCH_S,
             batches: int = RHS_BATCHES, clock: Callable[[], float] = time.process_time) -> float:
    """One call's CPU time [s]: ``call()`` in batches of about ``batch_s`` each, the least
    per-call time over ``batches`` batches."""
    best = math.inf
    n = 1
    for _ in range(batches):
        while True:
            t0 = clock()
            for _ in range(n):
                call()
            dt = clock() - t0
            if dt >= batch_s or n >= 1 << 20:
                break
            n *= 2 if dt <= 0 else max(2, min(16, int(batch_s / dt) + 1))
        best = min(best, dt / n)
    return best
