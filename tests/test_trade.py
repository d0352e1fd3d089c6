"""The trade (reports/trade.py): the cheapest run that reaches each accuracy, the core's lead over
the best engine and the engines that do not reach it, on small hand-made run rows whose answers
are worked out by hand below; and the report opens with it."""

from __future__ import annotations

import json
import math

import pandas as pd
import pytest

from redysim.reports.build import build_report, render_html
from redysim.reports.content import NOT_RUN, PARTIAL
from redysim.reports.results import Results
from redysim.reports.trade import answer, headline_trade, trade_section, trade_table


def _row(engine, integrator, setting, err, cost_ms, repeats=1, spread=math.nan,
         status="ok", case="UR5-FALL"):
    h = setting if integrator.startswith("native") or integrator == "rk4" else 0.0
    rtol = 0.0 if h else setting
    return {"run_id": f"{case}:{engine}:{integrator}:{setting:g}", "case": case,
            "engine": engine, "method": "rge-a" if engine == "redysim" else "",
            "integrator": integrator, "rtol": rtol, "h": h, "t_end": 0.5, "status": status,
            "reason": "" if status == "ok" else "refused", "max_tip_err": err,
            "cost_s": cost_ms * 1e-3, "cost_repeats": repeats, "cost_spread": spread,
            "cpu_s": cost_ms * 1e-3, "work_s": math.nan}


# Intervals (harness/cost.py): one run: value / 1.25 .. value x 1.25; 5 repeats of spread 0.05:
# value / 1.1 .. value x 1.1 (the 10 % floor).
ROWS = pd.DataFrame([
    _row("redysim", "ode45", 1e-5, 1e-4, 1.0),                    # [0.8, 1.25] ms
    _row("redysim", "ode45", 1e-8, 5e-7, 10.0, 5, 0.05),          # [9.09, 11]
    _row("redysim", "rk4", 1e-3, 2e-7, 10.5, 5, 0.05),            # [9.55, 11.55]: overlaps
    _row("mujoco", "native", 1e-3, 1e-3, 2.0),                    # [1.6, 2.5]
    _row("mujoco", "ode45", 1e-8, 4e-6, 40.0, 5, 0.05),
    _row("pinocchio-aba", "ode45", 1e-8, 3e-7, 25.0, 5, 0.05),    # [22.7, 27.5]
    _row("pinocchio-aba", "ode45", 1e-10, 5e-10, 60.0, 5, 0.05),
    _row("dart", "ode45", 1e-8, math.nan, 0.1, status="failed"),
])


def test_loose_accuracy_the_core_beats_mujoco_by_two():
    a = answer(ROWS, 1e-3)
    # within 1e-3: everything that finished; least cost: the core's ode45 at 1e-5 (1 ms);
    # mujoco native (2 ms, its error 1e-3 exactly within) is the best engine; intervals
    # [0.8, 1.25] and [1.6, 2.5] do not overlap: cheaper, lead 2.0
    assert (a.cheapest.row["engine"], a.cheapest.row["rtol"]) == ("redysim", 1e-5)
    assert not a.cheapest.tied
    assert (a.engine.row["engine"], a.engine.row["integrator"]) == ("mujoco", "native")
    assert a.lead == pytest.approx(2.0)
    assert a.lead_verdict == "cheaper"
    assert a.not_reached == {}
    assert a.never_ran == ["dart"]


def test_middle_accuracy_ties_and_not_reached():
    a = answer(ROWS, 1e-6)
    # within 1e-6: core ode45 1e-8 (10 ms), core rk4 (10.5 ms, overlapping: indistinguishable),
    # pinocchio-aba 1e-8 (25 ms) and 1e-10 (60 ms); mujoco's best is 4e-6: not reached
    assert (a.cheapest.row["integrator"], a.cheapest.row["rtol"]) == ("ode45", 1e-8)
    assert [r["integrator"] for r in a.cheapest.tied] == ["rk4"]
    assert (a.engine.row["engine"], a.engine.row["rtol"]) == ("pinocchio-aba", 1e-8)
    assert a.lead == pytest.approx(2.5)
    assert a.lead_verdict == "cheaper"  # 11 < 22.7
    assert a.not_reached == {"mujoco": pytest.approx(4e-6)}


def test_tight_accuracy_only_an_engine_reaches_it():
    a = answer(ROWS, 1e-9)
    # only pinocchio-aba at 1e-10 (5e-10); the core's best is rk4's 2e-7
    assert a.cheapest.row["engine"] == "pinocchio-aba" and a.core is None
    assert math.isnan(a.lead) and a.lead_verdict == ""
    assert a.not_reached == {"mujoco": pytest.approx(4e-6), "redysim": pytest.approx(2e-7)}
    cells = trade_table(ROWS).rows[2].cells
    assert cells[0] == "1e-09" and cells[3] == "not reached"
    assert cells[5] == "the core does not reach it"
    assert "mujoco: not reached (best 4.0e-06)" in cells[6]
    assert "dart: no run finished" in cells[6]


def test_nothing_reaches_it():
    a = answer(ROWS, 1e-12)
    assert a.cheapest is None and a.core is None and a.engine is None
    row = trade_table(ROWS, accuracies=(1e-12,)).rows[0]
    assert row.kind == NOT_RUN and row.cells[1] == "not reached by any run"


def _folder(root, sweep, rows, planned):
    d = root / "sweeps" / sweep
    (d / "runs").mkdir(parents=True)
    for r in rows:
        pd.DataFrame([r]).to_parquet(d / "runs" / f"{r['run_id']}.parquet")
    ids = [r["run_id"] for r in rows] + [f"missing-{k}" for k in range(planned - len(rows))]
    (d / "sweep.json").write_text(json.dumps({"runs": [{"run_id": i} for i in ids]}))


def test_the_section_reads_the_results_and_marks_a_partial_sweep(tmp_path):
    _folder(tmp_path, "quick-work-precision-robots", ROWS.to_dict("records"), len(ROWS) + 2)
    t = trade_section(Results(tmp_path)).items[0]
    ur5 = [r for r in t.rows if r.cells[1].startswith("UR5-FALL")]
    assert [r.cells[2] for r in ur5] == ["0.001", "1e-06", "1e-09"]
    assert all(r.kind == PARTIAL and "partial sweep" in r.cells[1] for r in ur5)
    assert ur5[1].cells[7] == "x2.5"
    # the families without results say so, with what runs them
    chains = [r for r in t.rows if r.cells[0] == "the paper's chains"]
    assert len(chains) == 1 and chains[0].kind == NOT_RUN
    assert "make reproduce" in chains[0].cells[-1]
    mega = [r for r in t.rows if r.cells[0] == "the 1,000,000-DOF rod"]
    assert len(mega) == 1 and mega[0].kind == NOT_RUN


def test_the_first_card_is_the_trade(tmp_path):
    """By hand from ROWS (the tests above): the core is the cheapest at 1e-3 and 1e-6, not at
    1e-9 (2 of 3); its leads 2.0 and 2.5 (neither within the noise); not reached: mujoco at 1e-6,
    the core and mujoco at 1e-9 (3)."""
    _folder(tmp_path, "quick-work-precision-robots", ROWS.to_dict("records"), len(ROWS))
    card = headline_trade(Results(tmp_path))
    assert card.value == "the core cheapest in 2 of 3"
    assert "x2 to x2.5" in card.detail and "within the noise" not in card.detail
    assert "not reached 3 times" in card.detail
    assert headline_trade(Results(tmp_path / "empty")).value == "no results"


def test_the_report_opens_with_the_trade(tmp_path):
    report = build_report(Results(tmp_path / "empty"))
    assert report.sections[0].id == "trade"
    assert report.headline[0].label.startswith("the trade")
    assert report.title.startswith("redysim: speed against accuracy")
    html = render_html(report)
    assert html.index('id="trade"') < html.index('id="setup"') < html.index('id="paper"')


def test_the_overall_pick_is_its_sides_pick_too():
    """Within the noise, rank orders a group by work only when every run of it has work: the
    core's two runs alone go by work (dop853, 2.1 ms, less work), but with MuJoCo's own stepper
    (no work; 2.4 ms, overlapping ode45's [1.33, 1.92]) in the group they go by cost (ode45).
    The core's cheapest shown beside the overall pick is that same ode45 run, not dop853."""
    rows = pd.DataFrame([
        _row("redysim", "ode45", 1e-7, 3e-9, 1.6, 20, 0.2) | {"work_s": 3e-3},
        _row("redysim", "dop853", 1e-7, 3e-9, 2.1, 20, 0.1) | {"work_s": 2e-3},
        _row("mujoco", "native", 5e-3, 5e-9, 2.4, 20, 0.3),  # [1.85, 3.12]
    ])
    a = answer(rows, 1e-6)
    assert a.cheapest.row["integrator"] == "ode45"
    assert a.core.row["integrator"] == "ode45"
    assert a.engine.row["engine"] == "mujoco"
    assert a.lead_verdict == "indistinguishable"
