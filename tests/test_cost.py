"""The cost model (redysim.harness.cost): repeats, intervals, the "indistinguishable" verdict,
and compare's advice on synthetic costs; that a run's repeats happen and are recorded.

No timed assertion: the ranking is tested on given costs, the repeats by their count and their
bookkeeping (which hold on any machine under any load)."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from redysim.harness import cost


def test_a_cost_measured_once_has_the_single_run_uncertainty():
    c = cost.make_cost(1.0)
    assert (c.lo, c.hi) == pytest.approx((1 / 1.25, 1.25))
    # repeated: its spread, at least the noise floor
    assert cost.make_cost(1.0, 5, 0.02).hi == pytest.approx(1.10)
    assert cost.make_cost(1.0, 5, 0.30).hi == pytest.approx(1.30)
    assert cost.make_cost(2.0, 5, 0.0).lo == pytest.approx(2.0 / 1.1)


def test_overlapping_costs_are_indistinguishable_and_distant_ones_are_not():
    a, b = cost.make_cost(1.0, 10, 0.0), cost.make_cost(1.15, 10, 0.0)
    assert a.overlaps(b) and cost.compare_two(a, b) == cost.INDISTINGUISHABLE
    c = cost.make_cost(1.5, 10, 0.0)  # 1.1 < 1.5 / 1.1
    assert not a.overlaps(c)
    assert cost.compare_two(a, c) == "cheaper" and cost.compare_two(c, a) == "dearer"


def test_the_issues_ur5_costs_are_indistinguishable_measured_once():
    """rtol 1e-7 at 4.29 ms against rtol 1e-4 at 5.08 ms, one CPU sample each (the issue's
    numbers): within each other's noise. Among them the one of least work is the pick: 199 RHS
    calls against 661 at the same per-call cost."""
    tight = cost.make_cost(4.29e-3, work=661 * 4e-6)
    loose = cost.make_cost(5.08e-3, work=199 * 4e-6)
    r = cost.rank([tight, loose])
    assert r.verdict == cost.INDISTINGUISHABLE
    assert r.pick == 1 and r.indistinguishable == (0,)


def test_rank_picks_the_least_and_names_only_the_overlapping():
    costs = [cost.make_cost(v, 10, 0.0) for v in (3.0, 1.0, 1.05, 2.0, math.nan)]
    r = cost.rank(costs)
    assert r.pick == 1 and r.indistinguishable == (2,)
    assert r.verdict == cost.INDISTINGUISHABLE
    alone = cost.rank([cost.make_cost(1.0, 10, 0.0), cost.make_cost(2.0, 10, 0.0)])
    assert alone.pick == 0 and alone.indistinguishable == () and alone.verdict == "cheapest"
    assert cost.rank([cost.make_cost(math.nan)]) is None and cost.rank([]) is None
    # work orders the group only when every member has it
    mixed = [cost.make_cost(1.0, 10, 0.0, work=5.0), cost.make_cost(1.05, 10, 0.0)]
    assert cost.rank(mixed).pick == 0
    both = [cost.make_cost(1.0, 10, 0.0, work=5.0), cost.make_cost(1.05, 10, 0.0, work=1.0)]
    assert cost.rank(both).pick == 1


def test_a_busy_neighbour_inside_the_noise_does_not_reorder_the_pick():
    """The same two runs, the second's least measure pushed past the first's by load within the
    interval: the pick (least work among the indistinguishable) stays."""
    quiet = [cost.make_cost(1.00, 10, 0.05, work=0.9), cost.make_cost(1.08, 10, 0.05, work=0.5)]
    busy = [cost.make_cost(1.12, 10, 0.05, work=0.9), cost.make_cost(1.05, 10, 0.05, work=0.5)]
    assert cost.rank(quiet).pick == cost.rank(busy).pick == 1


def test_cost_of_a_row_uses_the_repeats_and_falls_back_to_cpu_s():
    row = {"cpu_s": 5.0, "cost_s": 1.0, "cost_repeats": 7, "cost_spread": 0.2, "work_s": 0.4}
    c = cost.cost_of(row)
    assert (c.value, c.repeats, c.spread, c.work) == (1.0, 7, 0.2, 0.4)
    assert c.hi == pytest.approx(1.2)
    old = cost.cost_of(pd.Series({"cpu_s": 5.0}))  # a row from before the cost columns
    assert (old.value, old.repeats) == (5.0, 1) and old.hi == pytest.approx(6.25)
    nan = cost.cost_of({"cpu_s": 5.0, "cost_s": float("nan")})
    assert nan.value == 5.0


def test_repeat_until_the_total_with_at_least_min_repeats():
    calls = []

    def once():
        calls.append(1)
        return 0.05

    times = cost.repeat(once, 0.05, total_s=0.2, min_repeats=3, max_repeats=20)
    assert times == [0.05] * 4 and len(calls) == 3  # 4 x 0.05 = 0.2
    # tiny runs: at most max_repeats
    assert len(cost.repeat(lambda: 1e-6, 1e-6, total_s=0.2, max_repeats=20)) == 20
    # a long run: once
    assert cost.repeat(lambda: pytest.fail("repeated"), 0.5, total_s=0.2) == [0.5]
    # min_repeats even when the first run nearly fills the total
    assert len(cost.repeat(lambda: 0.01, 0.19, total_s=0.2, min_repeats=3)) == 3
    # a repeat that did not repeat the run (nan) ends the repeats
    assert cost.repeat(lambda: math.nan, 0.01, total_s=0.2) == [0.01]


def test_summary_keeps_the_least_the_count_and_the_spread():
    s = cost.summary([0.3, 0.1, 0.2, 0.5])
    assert s["cost_s"] == 0.1 and s["cost_repeats"] == 4
    assert s["cost_spread"] == pytest.approx((0.3 - 0.1) / 0.1)  # median (upper) - min
    one = cost.summary([0.4])
    assert one["cost_repeats"] == 1 and math.isnan(one["cost_spread"])


def test_per_call_is_the_least_batch_time_per_call():
    """A clock that advances 1 ms a call and 5 ms once (a neighbour's interruption, in the
    first batch): the per-call cost is 1 ms, the interruption left out by the least batch."""
    t = [0.0]
    hits = [0]

    def call():
        hits[0] += 1
        t[0] += 1e-3 + (5e-3 if hits[0] == 3 else 0.0)

    got = cost.per_call(call, batch_s=0.016, batches=3, clock=lambda: t[0])
    assert got == pytest.approx(1e-3)


def _runs(rows):
    base = {"status": "ok", "engine": "redysim", "h": 0.0, "max_tip_err": 1e-3,
            "cost_repeats": 10, "cost_spread": 0.0, "work_s": math.nan, "cpu_s": 1.0}
    return pd.DataFrame([{**base, **r} for r in rows])


def test_compares_advice_says_indistinguishable_where_costs_overlap():
    from redysim.reports.compare import advice

    runs = _runs([
        {"integrator": "ode45", "rtol": 1e-7, "cost_s": 4.29e-3, "work_s": 661 * 4e-6},
        {"integrator": "ode45", "rtol": 1e-4, "cost_s": 4.50e-3, "work_s": 199 * 4e-6},
        {"integrator": "rk4", "rtol": 0.0, "h": 0.01, "cost_s": 9e-3, "work_s": 1e-3},
        {"integrator": "ode45", "rtol": 1e-4, "cost_s": 1e-3, "engine": "mujoco",
         "max_tip_err": 0.5},  # fast, but misses every tolerance
    ])
    a = advice(runs, tols=(1e-2, 1e-6))
    best, tied = a[0]["best"], a[0]["tied"]
    assert best["rtol"] == 1e-4 and [float(r["rtol"]) for r in tied] == [1e-7]
    assert set(a[0]["per_engine"]) == {"redysim"}
    assert a[1]["best"] is None and a[1]["tied"] == []


def test_compares_page_shows_the_verdict():
    from redysim.reports.compare import _cost_text

    row = pd.Series({"cost_s": 1e-3, "cost_repeats": 12, "cost_spread": 0.05})
    assert _cost_text(row) == "1 ms +-10% (12 runs)"
    assert _cost_text(pd.Series({"cpu_s": 2e-3})) == "2 ms +-25% (1 run)"


def test_a_runs_repeats_happen_and_are_recorded(monkeypatch):
    """A short run is repeated (at least MIN_REPEATS timed runs, unless its first run alone
    filled TOTAL_S), its least integration CPU is at most the first run's, the sampling is
    timed apart, and the work is the RHS calls times one call's cost."""
    from redysim.harness.run import execute
    from redysim.harness.spec import RunSpec

    monkeypatch.setattr(cost, "TOTAL_S", 0.2)  # (the suite measures once: tests/conftest.py)
    spec = RunSpec(case="DOUBLE-PENDULUM", integrator="rk4", h=0.01, t_end=0.5, sample=0.05)
    row = execute(spec, reference=False).summary
    assert row["status"] == "ok", row["reason"]
    first = row["cpu_s"] - row["sample_cpu_s"]
    assert 0.0 < row["sample_cpu_s"] <= row["cpu_s"]
    if first >= cost.TOTAL_S:
        assert row["cost_repeats"] == 1
    else:
        assert cost.MIN_REPEATS <= row["cost_repeats"] <= cost.MAX_REPEATS
        assert row["cost_spread"] >= 0.0
    assert row["cost_s"] <= first
    assert row["rhs_s"] > 0 and row["work_s"] == pytest.approx(row["nfev"] * row["rhs_s"])
    assert row["steps"] == 50 and row["nfev"] >= 4 * 50  # rk4: four calls a step


def test_the_repeat_total_is_read_from_the_environment(monkeypatch):
    from redysim.errors import SettingsError

    monkeypatch.setenv(cost.REPEAT_ENV, "0.5")
    assert cost._total_s() == 0.5
    monkeypatch.delenv(cost.REPEAT_ENV)
    assert cost._total_s() == 0.2
    for bad in ("-1", "nan", "soon"):
        monkeypatch.setenv(cost.REPEAT_ENV, bad)
        with pytest.raises(SettingsError, match=f"{cost.REPEAT_ENV} = '{bad}'"):
            cost._total_s()
