"""The report as a reader sees it: captions say what is drawn, figures print in the order of their
numbers, legends readable at print size, vector figures and an outline in the PDF, the same
colour for a row in HTML and PDF, counts of what is on disk, a partial sweep said so, Table 10's
infinities of the other sign not scored a match.

Every check builds its data here (small synthetic results, tiny figures): nothing runs a sweep.
"""

from __future__ import annotations

import json
import math

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
import pytest

from redysim.harness.provenance import provenance
from redysim.harness.store import write_parquet_atomic
from redysim.reports import figures as F
from redysim.reports import pdf as P
from redysim.reports import precision_tables as pt
from redysim.reports.build import (
    OUTSIDE_BOUND,
    TRUTH_RTOL,
    render_html,
    robots_section,
    scenarios_section,
)
from redysim.reports.content import DIFFER, MATCH, Report, Row, Section, Table
from redysim.reports.paper_tables import Ctx, table10
from redysim.reports.results import Results
from redysim.reports.text import clip

pypdf = pytest.importorskip("pypdf")


def _run(run_id: str, **kw) -> dict:
    row = {"run_id": run_id, "case": "RE-U125-L1", "engine": "redysim", "method": "rge-a",
           "integrator": "ode45", "rtol": 1e-6, "atol": 1e-8, "h": 0.0, "t_end": 0.05,
           "status": "ok", "reason": "", "cpu_s": 0.1, "max_tip_err": 1e-6,
           "max_abs_delta_M": 1e-9, "n_dof": 250, "t_reached": 0.05}
    row.update(kw)
    return row


def _sweep(root, name: str, rows: list[dict], planned: list[dict] | None = None) -> None:
    """A sweep folder as redysim.harness.sweep leaves it: one parquet per finished run and the
    plan (sweep.json) of ``planned`` (default: the finished ones)."""
    d = root / "sweeps" / name
    (d / "runs").mkdir(parents=True)
    for r in rows:
        write_parquet_atomic(pd.DataFrame([r]), d / "runs" / f"{r['run_id']}.parquet")
    plan = planned if planned is not None else rows
    (d / "sweep.json").write_text(json.dumps({"name": name, "n_runs": len(plan),
                                              "runs": [{k: r[k] for k in ("run_id", "case",
                                                                          "t_end")}
                                                       for r in plan]}))


# --------------------------------------------------------------------------- captions, order
def test_captions_of_figs_7_to_9_name_the_curves_drawn(tmp_path):
    core = F.Series(F.CORE_LABEL, pd.DataFrame(), pd.Series(dtype=object))
    pin = F.Series("Pinocchio", pd.DataFrame(), pd.Series(dtype=object))
    muj = F.Series("MuJoCo (to 0.5 s of 1 s)", pd.DataFrame(), pd.Series(dtype=object))
    assert F.beside_what([core, pin, muj]) == "our core beside Pinocchio and MuJoCo (to 0.5 s " \
                                              "of 1 s)"
    assert F.beside_what([core]).startswith("our core alone")
    # with no engine run on disk, the captions do not claim "every reference engine"
    figs = {f.id: f for f in F.paper_figures(Ctx(Results(tmp_path)))}
    for fid in ("fig7", "fig8", "fig9"):
        assert "every reference engine" not in figs[fid].caption
        assert "our core alone" in figs[fid].caption, fid


def test_paper_figures_print_in_the_order_of_their_numbers(tmp_path):
    ids = [f.id for f in F.paper_figures(Ctx(Results(tmp_path)))]
    numbers = [int(i[3:]) for i in ids]
    assert numbers == sorted(numbers) and {11, 12} <= set(numbers)


# --------------------------------------------------------------------------- counts, partial
def test_results_found_counts_each_sweeps_runs_on_disk(tmp_path):
    shared = _run("r-shared")
    _sweep(tmp_path, "a", [_run("r-a1"), shared])
    _sweep(tmp_path, "b", [_run("r-b1"), _run("r-b2"), shared],
           planned=[_run("r-b1"), _run("r-b2"), shared, _run("r-b3")])
    res = Results(tmp_path)
    assert res.sweep_counts() == {"a": (2, 2, 2), "b": (3, 4, 2)}
    where = dict(res.sources())
    assert where["sweep a"] == "sweeps/a: 2 runs"
    assert where["sweep b"].startswith("sweeps/b: 3 runs of 4 planned (partial")
    assert "1 of them also made by another sweep" in where["sweep b"]


def test_a_partial_sweep_is_marked_in_its_work_precision_figure(tmp_path):
    done = [_run(f"r{i}", rtol=10.0 ** -k, cpu_s=0.1 * k, max_tip_err=10.0 ** -k)
            for i, k in enumerate((3, 5, 7))]
    later = [_run(f"r{i}", rtol=10.0 ** -k) for i, k in ((3, 9), (4, 11))]
    _sweep(tmp_path, "wp", done, planned=done + later)
    _sweep(tmp_path, "wp-other", [], planned=[_run("x1", case="UR5-FALL", t_end=0.5)])
    figs = F.work_precision(Ctx(Results(tmp_path)))
    fig = next(f for f in figs if f.id == "wp-RE-U125-L1-0.05")
    assert "partial sweep: 3 of 5 runs" in fig.title
    assert fig.caption.startswith("Partial sweep: 3 of the 5 runs")
    # legend text at print size: at least 7 pt (the PDF's frame is the one pdf.py lays out)
    legends = [*fig.drawing.legends, *(ax.get_legend() for ax in fig.drawing.axes)]
    legend = [t for lg in legends if lg is not None for t in lg.get_texts()]
    assert legend and min(t.get_fontsize() for t in legend) * min(
        1.0, F.print_scale(fig.drawing)) >= 7.0
    assert F.PRINT_W_IN == pytest.approx(P.WIDTH / 72, abs=0.01)
    assert F.PRINT_H_IN == pytest.approx(P.MAX_FIGURE_H / 72, abs=0.01)


def test_a_sub_decade_log_panel_draws_its_deviation_with_the_offset_stated():
    fig, ax = plt.subplots()
    y = 2.43759e-7 + np.array([0.0, 1e-14, 3e-14])
    ax.loglog([1.0, 2.0, 3.0], y, "o-")
    F._narrow(ax, [y], "max |delta_M| [J/kg]")
    fig.canvas.draw()
    labels = [t.get_text() for t in ax.get_yticklabels() if t.get_text()]
    assert ax.get_yscale() == "linear" and len(set(labels)) == len(labels) > 2
    assert ax.get_ylabel() == "max |delta_M| [J/kg] - 2.43759e-07"
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), [0.0, 1e-14, 3e-14], atol=1e-20)
    plt.close(fig)


# --------------------------------------------------------------------------- Table 10
def test_table10_says_an_infinity_of_the_other_sign_differs(tmp_path):
    assert pt.verdict(-math.inf, "Inf", 0)[0] == "sign"
    assert pt.verdict(math.inf, "Inf", 0)[0] == "exact"
    assert pt.verdict(math.nan, "Inf", 0)[0] == "differs"
    rows = [{"arithmetic": "double", "accuracy": 0.1, "method": "GE-N", "i": i,
             "paper_qdd": p, "ours_qdd": o, "verdict_qdd": "exact", "diff_qdd": None,
             "paper_dq": p, "ours_dq": p.lower(), "verdict_dq": "exact", "diff_dq": None}
            for i, (p, o) in enumerate((("NaN", "nan"), ("Inf", "inf"), ("Inf", "-inf")), 1)]
    (tmp_path / "precision").mkdir()
    (tmp_path / "precision" / "table10.json").write_text(json.dumps(
        {"rows": rows, "counts": {}, "meta": provenance()}))  # as written before the fix
    t = table10(Ctx(Results(tmp_path)))
    (row,) = t.rows
    assert row.kind == DIFFER
    assert "5/6 values match" in row.cells[-1]
    assert "non-finite, sign differs: qdd3 -inf vs Inf" in row.cells[-1]
    assert any(n.startswith("Non-finite, sign differs") for n in t.notes)


# --------------------------------------------------------------------------- scenarios table
class _Runs(Results):
    """Results whose runs are given (the scenarios table's truths of loop scenarios read only
    the run's residual)."""

    def __init__(self, root, runs: pd.DataFrame):
        super().__init__(root)
        self.__dict__["runs"] = runs

    def samples(self, run_id):
        return None


def test_a_scenario_outside_its_bound_is_said_and_coloured_alike_in_html_and_pdf(tmp_path):
    runs = pd.DataFrame([_run(f"s{i}", case="FOUR-BAR", sweep="quick-scenarios", t_end=1.0,
                              residual_q=r, max_tip_err=1e-9, rtol=TRUTH_RTOL)
                         for i, r in enumerate((1e-12, 1e-6))])
    (tab,) = scenarios_section(_Runs(tmp_path, runs)).items
    rows = [r for r in tab.rows if r.cells[0] == "FOUR-BAR"]
    assert [(r.cells[2], r.kind) for r in rows] == [("ok", MATCH), (OUTSIDE_BOUND, DIFFER)]
    report = Report("t", "s", "now", [], [Section("scenarios", "Scenarios", items=[tab])], "f")
    html = render_html(report)
    assert '<table class="rowkind">' in html and '<tr class="differ">' in html
    assert "table.rowkind tr.differ td { background: var(--differ); }" in html
    # the PDF colours the same row from its first cell
    colours = [c for c in P.table_flowables(tab)[1]._bkgrndcmds if c[0] == "BACKGROUND"]
    row_of_differ = 1 + tab.rows.index(rows[1])
    assert ("BACKGROUND", (0, row_of_differ), (-1, row_of_differ),
            P.KIND_COLOURS[DIFFER]) in colours


def test_reasons_are_cut_at_a_word():
    text = "the engine stopped: time limit of 120 s reached at t = 0.25 s of 1 s"
    assert clip(text, 30) == "the engine stopped: time limit ..."  # 30 characters kept
    assert clip(text, 29) == "the engine stopped: time ..."
    assert clip(text, 200) == text


def test_pdf_columns_are_as_wide_as_their_longest_word():
    t = Table("t", "t", ["accuracy", "method", "qdd ours", "verdict"],
              [Row(["0.1", "GE-N", "[nan, inf, -inf]", "x " * 400]),
               Row(["0.1", "FOUR-BAR-ROUND", "1", "y"])])
    widths = P._col_widths(t)
    head, cell = P.STYLES["head"], P.STYLES["cell"]
    assert widths[1] >= P.stringWidth("FOUR-BAR-ROUND", cell.fontName, cell.fontSize) + 5
    assert widths[1] >= P.stringWidth("method", head.fontName, head.fontSize) + 5


# --------------------------------------------------------------------------- PDF and HTML
def _figure(fid: str, title: str):
    fig, axes = F.new_figure(1, footer="test")
    axes[0].plot([0, 1], [0, 1], label="line")
    axes[0].set(xlabel="sentinel axis")
    return F._figure(fid, "scaling", title, "a caption", fig)


def test_pdf_has_an_outline_and_vector_figures_html_svg(tmp_path):
    fig = _figure("f1", "Figure one")
    tab = Table("t1", "Table one", ["a", "b"], [Row(["1", "2"])])
    report = Report("t", "s", "now", [], [Section("sec", "Section one", items=[tab, fig])],
                    "footer")
    path = P.write_pdf(report, tmp_path / "r.pdf")
    reader = pypdf.PdfReader(path)

    def titles(outline):
        return [t for o in outline for t in (titles(o) if isinstance(o, list) else [o.title])]

    assert titles(reader.outline) == ["Section one", "Table one", "Figure one"]
    page = next(p for p in reader.pages if "Figure one" in p.extract_text())
    assert not page.images  # drawn as vector paths, no raster
    assert b" re" in page.get_contents().get_data() or b" l" in page.get_contents().get_data()
    html = render_html(report)
    assert "data:image/svg+xml;base64," in html and "data:image/png" not in html


# --------------------------------------------------------------------------- robots
def test_the_robots_speed_table_shows_the_evaluator_beside_forward_dynamics(tmp_path):
    nan = float("nan")
    per_call = {"robot": "arm", "n_v": 6, "core_s": 2.0e-6, "pin_aba_s": 2.0e-6, "ratio": 1.0,
                "pinocchio": "4"}
    doc = {"tolerance": 1e-10, "states": 3, "fall": {}, "provenance": provenance(),
           "agreement": [], "falls": [{"robot": "arm", "n_v": 6, "status": "ok", "reason": "",
                                       "steps": 1, "cpu_s": 0.01, "max_abs_delta_M": 0.0,
                                       "parabola_m": nan}],
           "per_call": [{**per_call, "evaluator_s": 5.0e-7, "evaluator_ratio": 4.0},
                        {**per_call, "robot": "old"}]}
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "robots.json").write_text(json.dumps(doc))
    t = {t.id: t for t in robots_section(Results(tmp_path)).items}["robots-percall"]
    cols = t.columns
    new, old = (dict(zip(cols, r.cells, strict=True)) for r in t.rows)
    assert new["evaluator"] == "0.5 us"
    assert new["pin.aba / evaluator"] == "4" and new["pin.aba / forward_dynamics"] == "1"
    assert old["evaluator"] == "not timed" and any("not timed" in n for n in t.notes)
