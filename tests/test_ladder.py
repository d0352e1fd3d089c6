"""The latency/throughput ladder's bookkeeping (benchmarks/ladder.py) and its place in the report.

The timings themselves are benchmarks (make bench-engines), never asserted here: these tests
check what is done with them, on rows written by hand in the script's format."""

from __future__ import annotations

import json

import pytest

pytest.importorskip("matplotlib")


def row(system, rung, engine, per_state_s, call="c", **kw):
    return {"system": system, "scenario": "S", "dof": 7, "rung": rung, "engine": engine,
            "version": "1", "call": call, "per_state_s": per_state_s, "min_s": per_state_s,
            "ns_per_dof": per_state_s * 1e9 / 7, "note": "", **kw}


ROWS = [
    row("arm", 1, "core", 2e-6, "evaluator"), row("arm", 1, "core", 4e-6, "default call"),
    row("arm", 1, "pinocchio-aba", 3e-6), row("arm", 3, "core", 1e-6, "batch"),
    row("arm", 3, "pinocchio-aba", 5e-7),
    row("arm", 4, "core", 0.01, "ode45 rtol 1e-07", error_m=4e-7, steps=120),
    {"system": "arm", "scenario": "S", "dof": 7, "rung": 2, "engine": "dart", "call": "loop",
     "note": "no loop reachable from Python"},
]


def test_each_rung_is_divided_by_the_cores_first_row_of_that_rung():
    from redysim.reports.build import ladder_core_reference

    ref = ladder_core_reference(ROWS)
    assert ref == {("arm", 1): 2e-6, ("arm", 3): 1e-6, ("arm", 4): 0.01}


def test_the_report_shows_the_ladder_table_and_figure(tmp_path):
    from redysim.reports.build import ladder_core_reference, ladder_figure, ladder_table
    from redysim.reports.content import INFO, NOT_RUN
    from redysim.reports.results import Results

    res = Results(tmp_path)
    assert ladder_table(res).not_run and ladder_figure(res).not_run
    rows = [dict(r) for r in ROWS]
    ref = ladder_core_reference(rows)
    for r in rows:
        if "per_state_s" in r:
            r["x_core"] = r["per_state_s"] / ref[(r["system"], r["rung"])]
    (tmp_path / "bench").mkdir()
    (tmp_path / "bench" / "ladder.json").write_text(json.dumps(
        {"machine": {"cpu": "test CPU"}, "date": "2026-11-27 10:00", "tolerance_m": 1e-6,
         "t_end_s": 1.0, "load": [[0.5, 0.5, 0.5]], "rows": rows}))
    t = ladder_table(Results(tmp_path))
    assert len(t.rows) == len(ROWS)
    by = {(r.cells[0], r.cells[2], r.cells[3], r.cells[5]): r for r in t.rows}
    pin = by[("arm", "call from Python", "pinocchio-aba", "c")]
    assert pin.cells[8] == "1.5" and pin.kind == INFO  # 3 us over the evaluator's 2 us
    second = by[("arm", "a simulated second", "core", "ode45 rtol 1e-07")]
    assert "4.0e-07 m" in second.cells[9] and "120 steps" in second.cells[9]
    dart = by[("arm", "inside compiled code", "dart", "loop")]
    assert dart.kind == NOT_RUN and "no loop" in dart.cells[9]
    assert "within 1e-06 m" in " ".join(t.notes) and "test CPU" in t.provenance
    assert ladder_figure(Results(tmp_path)).png is not None
