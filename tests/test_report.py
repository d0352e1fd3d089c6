"""The comparison report, built from a tiny results folder: every section, every paper table, every
figure family in the HTML; a PDF with pages; verdicts where there is data and "not run" where
there is none; provenance on every table and figure.

The results folder is made here in seconds: two small sweeps (Table 1's first chain at the paper's
settings, RE-U125-L1 shortened, and a work-precision pair measured against a reference solution),
a second of Table 5's first chain as a checkpointed long run, the small producers at small sizes
(precision Tables 10, 11, A.2 and IEEE, Table 9 and the conditioning, operation counts, CPU
scaling up to 20 DOF), and a synthetic true-error file.
"""

from __future__ import annotations

import re

import pandas as pd
import pytest

from redysim import load_published
from redysim.harness import longrun
from redysim.harness.provenance import provenance
from redysim.harness.spec import RunSpec
from redysim.harness.store import write_parquet_atomic
from redysim.harness.sweep import run_sweep
from redysim.reports import figures as F
from redysim.reports import gim_study, implicit_scaling, opcount, scaling
from redysim.reports import precision_tables as pt
from redysim.reports.build import (
    build_report,
    loops_section,
    render_html,
    robots_section,
    write_report,
)
from redysim.reports.content import DIFFER, MATCH, NOT_RUN, PARTIAL
from redysim.reports.pdf import write_pdf
from redysim.reports.results import Results
from redysim.reports.text import provenance_line

pypdf = pytest.importorskip("pypdf")

SMALL_LINKS = 10
LONG_CASE = "RE-U5000-L100"  # Table 5's first chain, as a long run stopped after LONG_RUN_S
LONG_RUN_S = 1.0
SCALING_MAX_DOF = 20
SECTIONS = ("headline", "setup", "paper", "figures", "beyond", "robots", "loops")
PAPER_TABLES = ("table1", "table2", "table3", "table4", "table5", "table6", "table7", "table8",
                "table9", "table10", "table11", "tableA2")
FIGURE_FAMILIES = ("tip-path", "tip-speed", "drift", "conditioning", "scaling", "opcount",
                   "work-precision", "true-error")
SPECS = [
    RunSpec(case="RE-R229-L1.02-DX1.02", sample=0.05),              # Table 1, the paper's run
    *[RunSpec(case="RE-R229-L1.02-DX1.02", sample=0.05, perturb=k * 1e-13)  # its drift spread
      for k in (1, 2, 3)],
    RunSpec(case="RE-U125-L1", t_end=0.1, sample=0.05),             # Tables 2/3, shortened
    RunSpec(case="RE-U125-L1", t_end=0.02, sample=0.01, integrator="rk4", h=1e-3),
    RunSpec(case="RE-U125-L1", t_end=0.02, sample=0.01, rtol=1e-6, atol=1e-8),
]


def synthetic_error_study() -> pd.DataFrame:
    rows = []
    for n in (10, 100):
        for method, err in (("rge-a", 1e-14 * n), ("cholesky", 1e-13 * n**2)):
            rows.append({"chain": "U", "n_links": n, "n_dof": 2 * n, "config": "stretched",
                         "method": method, "precision": "float64", "status": "ok",
                         "rel2": err, "cond2": 4.0 * n**4, "cond2_lanczos": 4.0 * n**4,
                         "engine_version": "redysim 0.1.0", "date": "2026-11-22T00:00:00",
                         "host": "test"})
    return pd.DataFrame(rows)


@pytest.fixture(scope="module")
def results(tmp_path_factory):
    root = tmp_path_factory.mktemp("results")
    mp = pytest.MonkeyPatch()
    mp.setenv("REDYSIM_RESULTS", str(root))  # reference solutions (inherited by the workers)
    try:
        run_sweep(SPECS[:5], root / "sweeps" / "tiny", name="tiny", workers=2, progress=False)
        run_sweep(SPECS[5:], root / "sweeps" / "tiny-wp", name="tiny-wp", workers=2,
                  progress=False, reference=True)
        longrun.run(LONG_CASE, stop_after_s=LONG_RUN_S, log=lambda _msg: None)  # a checkpoint
    finally:
        mp.undo()
    pub = load_published()
    refs: dict = {}
    for name, table in (("table10", pt.table10(pub)), ("tableA2", pt.tableA2(pub)),
                        ("table11", pt.table11(pub, max_links=SMALL_LINKS, refs=refs)),
                        ("ieee", pt.ieee_table(max_links=SMALL_LINKS, refs=refs))):
        pt.write(root / "precision", name, table)
    gim_study.run(root / "gim_study", SMALL_LINKS)
    opcount.run(root / "opcount")
    scaling.run(root / "scaling", "quick", SCALING_MAX_DOF, log=lambda _msg: None)
    implicit_scaling.run(root / implicit_scaling.RESULT_FILE, (5, 10), steps=2,
                         say=lambda _msg: None)
    write_parquet_atomic(synthetic_error_study(), root / "error_study" / "error_study.parquet")
    return root


@pytest.fixture(scope="module")
def report(results):
    return build_report(Results(results))


@pytest.fixture(scope="module")
def written(report, tmp_path_factory):
    """The HTML and PDF files of the report (the model built once, as write_report does)."""
    out = tmp_path_factory.mktemp("report")
    html = out / "report.html"
    html.write_text(render_html(report), encoding="utf-8")
    return html, write_pdf(report, out / "report.pdf")


def test_table1_places_the_papers_drift_against_our_round_off_spread(report, results):
    t = {t.id: t for t in report.tables()}["table1"]
    row = t.rows[0]  # dX = 1.02: the paper's run and three runs from perturbed initial states
    verdict = row.cells[-1]
    assert "our 4 runs from initial states perturbed by <= 3e-13 give" in verdict, verdict
    # the perturbed runs never stand in for the run from the case's own state
    runs = Results(results).runs
    own = runs[(runs["case"] == "RE-R229-L1.02-DX1.02") & (runs["perturb"] == 0)]
    assert len(own) == 1 and row.cells[4] == f"{int(own['steps'].iloc[0]):,}"


def test_write_report_writes_both_files(tmp_path):
    empty = tmp_path / "results"  # no results at all: the report still builds, all "not run"
    html, pdf = write_report(empty, tmp_path / "out", log=lambda *_: None)
    assert html.is_file() and pdf.is_file()
    assert "not run: make table1" in html.read_text(encoding="utf-8")


def test_html_has_every_section_table_and_figure_family(written):
    html = written[0].read_text(encoding="utf-8")
    for sid in SECTIONS:
        assert f'id="{sid}"' in html, sid
    for tid in PAPER_TABLES:
        assert f'id="{tid}"' in html, tid
    for family in FIGURE_FAMILIES:
        assert f"figure-{family}" in html, family
    assert html.count("data:image/svg+xml;base64,") >= len(FIGURE_FAMILIES)  # vector figures
    assert "not run: make table5" in html  # a table without data says how to get it
    assert "not run: make table8" in html
    assert "<script" not in html  # self-contained, static


def test_pdf_exists_and_has_pages(written):
    pdf = written[1]
    assert pdf.read_bytes()[:5] == b"%PDF-"
    reader = pypdf.PdfReader(str(pdf))
    assert len(reader.pages) > len(SECTIONS)
    assert "Headline" in reader.pages[0].extract_text()


def test_every_figure_family_has_an_image(report):
    drawn = {f.family for f in report.figures() if f.drawing is not None}
    assert set(FIGURE_FAMILIES) <= drawn
    for f in report.figures():
        assert (f.drawing is not None) != bool(f.not_run), f.id


def test_verdicts_where_data_and_not_run_elsewhere(report):
    tables = {t.id: t for t in report.tables()}
    t1 = tables["table1"]
    assert t1.rows[0].kind in (MATCH, DIFFER)  # the run exists: a verdict
    assert t1.rows[1].kind == NOT_RUN and "make table1" in t1.rows[1].cells[-1]
    t3 = tables["table3"]
    assert t3.rows[0].kind == PARTIAL  # RE-U125-L1 ran to 0.1 s of 1.0 s
    assert "0.1 s of 1 s" in t3.rows[0].cells[-1]
    t5 = tables["table5"]
    assert t5.rows[0].kind == PARTIAL and "of 5 s" in t5.rows[0].cells[-1]  # its checkpoint
    assert all(r.kind == NOT_RUN for r in t5.rows[1:])
    assert tables["table8"].not_run == "not run: make table8"
    for tid in ("table9", "table10", "tableA2"):
        assert tables[tid].rows and not tables[tid].not_run, tid
    assert all(r.kind == MATCH for r in tables["table9"].rows)


def test_every_table_with_data_carries_provenance(report):
    for t in report.tables():
        if t.rows and t.id not in ("provenance", "settings", "sources"):
            assert t.provenance, t.id


def test_headline_comes_first_with_the_numbers(report, written):
    labels = [h.label for h in report.headline]
    assert any("E(0)" in lab for lab in labels)
    assert any("speed" in lab.lower() for lab in labels)
    html = written[0].read_text(encoding="utf-8")
    assert html.index('id="headline"') < html.index('id="setup"') < html.index('id="paper"')


def test_figure_footer_carries_versions_and_machine():
    line = provenance_line(provenance())
    fig, _ = F.new_figure(2, footer=line)
    text = " ".join(t.get_text() for t in fig.texts)
    here = provenance()
    for key in ("redysim", "numpy", "cpu"):
        assert here[key].split()[0] in text, key
    F.plt.close(fig)


def test_render_is_deterministic_given_the_model(report):
    a, b = render_html(report), render_html(report)
    assert a == b
    assert re.search(r"<h1>redysim: speed against accuracy, and the paper reproduced</h1>", a)


def test_the_implicit_section_shows_one_step_against_dof(report, results):
    """implicit_scaling.json (each size in its own process) -> a row per size with its CPU and
    memory, the log-log slopes, and the figure; the long-run tables say how to get them."""
    import json

    doc = json.loads((results / implicit_scaling.RESULT_FILE).read_text())
    assert [r["n_dof"] for r in doc["rows"]] == [10, 20]
    assert all(r["steps"] == 2 and r["qdd_calls"] > 0 and r["cpu_s"] > 0
               and r["rss_peak_mib"] >= r["rss_before_mib"] > 0 for r in doc["rows"])
    tables = {t.id: t for t in report.tables()}
    scaling_table = tables["implicit-scaling-table"]
    assert [r.cells[0] for r in scaling_table.rows] == ["10", "20"]
    assert "slopes" in scaling_table.notes[0] and scaling_table.provenance
    assert any(f.id == "implicit-scaling" and f.png is not None for f in report.figures())
    assert "huge/RE-U500000-L10000.toml --integrator implicit --t-end 1 --sample 0.001" in \
        tables["implicit-mega-runs"].not_run


def test_the_robots_section_judges_each_engine_and_says_what_did_not_run(tmp_path):
    """robots.json (reports/robots.py) -> verdicts: within the tolerance a match, beyond it a
    difference with its size, a refused engine not run with its reason; no file: how to get it."""
    import json

    nan = float("nan")
    doc = {"tolerance": 1e-10, "states": 3, "fall": {}, "provenance": provenance(),
           "agreement": [
               {"robot": "arm", "engine": "mujoco", "n_v": 6, "status": "ok", "reason": "",
                "qdd": 3e-14, "GIM": 1e-15, "bias": 2e-14, "energy": 0.0},
               {"robot": "arm", "engine": "dart", "n_v": 6, "status": "ok", "reason": "",
                "qdd": 4e-9, "GIM": 1e-15, "bias": 2e-14, "energy": 0.0},
               {"robot": "arm", "engine": "exudyn", "n_v": 6, "status": "refused",
                "reason": "no free joint", "qdd": nan, "GIM": nan, "bias": nan,
                "energy": nan}],
           "per_call": [{"robot": "arm", "n_v": 6, "core_s": 1.6e-6, "pin_aba_s": 1.7e-6,
                         "ratio": 1.06, "pinocchio": "4"}],
           "falls": [{"robot": "arm", "n_v": 6, "status": "ok", "reason": "", "steps": 100,
                      "cpu_s": 0.01, "max_abs_delta_M": 1e-9, "parabola_m": nan,
                      "quaternion_error": 0.0}]}
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "robots.json").write_text(json.dumps(doc))
    tables = {t.id: t for t in robots_section(Results(tmp_path)).items}
    kinds = [r.kind for r in tables["robots-agreement"].rows]
    assert kinds == [MATCH, DIFFER, NOT_RUN]
    assert "4.0e-09" in tables["robots-agreement"].rows[1].cells[-1]
    assert "no free joint" in tables["robots-agreement"].rows[2].cells[-1]
    assert len(tables["robots-percall"].rows) == 1 and len(tables["robots-falls"].rows) == 1
    empty = {t.id: t for t in robots_section(Results(tmp_path / "none")).items}
    assert all("reports.robots" in t.not_run for t in empty.values())


def test_the_loops_section_checks_its_bounds(tmp_path):
    """loops.json (reports/loops.py) -> a verdict per check against its bound; no file: how to
    get it."""
    import json

    doc = {"four_bar": {"path_error_m": 7e-13, "max_abs_delta_M": 3e-8, "residual_q": 1e-12,
                        "crank_range_rad": 3.2},
           "catenary": {"settled_rad": 4e-13, "start_off_rad": 6e-4,
                        "gaps": [{"n": 10, "max_joint_gap_m": 6e-5},
                                 {"n": 20, "max_joint_gap_m": 1.5e-5}], "orders": [2.0]},
           "cost": [{"n": 100, "seconds": 1e-4}, {"n": 1000, "seconds": 4e-4}], "slope": 0.9,
           "long": {"t_end": 0.2, "steps": 10, "nfev": 70, "cpu_s": 1.0, "status": 0,
                    "max_abs_delta_M": 1e-12, "residual_q": 1e-12, "residual_v": 1e-14},
           "provenance": provenance()}
    (tmp_path / "loops").mkdir()
    (tmp_path / "loops" / "loops.json").write_text(json.dumps(doc))
    tables = {t.id: t for t in loops_section(Results(tmp_path)).items}
    kinds = [r.kind for r in tables["loops-checks"].rows]
    assert kinds == [MATCH, DIFFER, MATCH, MATCH]  # the drift 3e-8 is beyond its 1e-8
    empty = {t.id: t for t in loops_section(Results(tmp_path / "none")).items}
    assert all("reports.loops" in t.not_run for t in empty.values())


def test_the_subtitle_names_the_engines_the_registry_has():
    """The subtitle said "four reference engines" when there were five."""
    from redysim import references
    from redysim.reports.build import REFERENCE_ENGINES, SUBTITLE

    packages = {cls.package.lower() for cls in references.ENGINES.values()}
    assert {name.lower() for name in REFERENCE_ENGINES} == {
        {"dartpy": "dart", "pin": "pinocchio", "pydrake": "drake"}.get(p, p) for p in packages}
    assert "five reference engines" in SUBTITLE and len(REFERENCE_ENGINES) == 5
