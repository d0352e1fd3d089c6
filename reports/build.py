"""The comparison report: the results on disk -> one self-contained HTML page and the same as PDF.

    python -m redysim.reports.build [--results results] [--out reports/out] [--history FILE]

Writes ``report.html`` (figures embedded as PNG data URIs: it opens from disk, offline) and
``report.pdf`` (reportlab) into ``--out``. Reads only what is on disk
(:mod:`redysim.reports.results`): a table or figure without data says which make target produces
it. Sections:

1. headline: the numbers a reader wants first;
2. the trade: per system family and accuracy, the cheapest engine and setting that reaches it,
   the core's lead over the best engine, the engines that do not reach it
   (:mod:`redysim.reports.trade`);
3. setup and provenance: this machine, versions, settings, where every result came from;
4. paper vs ours: Tables 1-11 and A.2, a verdict per row (:mod:`redysim.reports.paper_tables`);
5. the paper's figures, from our runs (:mod:`redysim.reports.figures`);
6. beyond the paper: conditioning, CPU scaling, operation counts, work-precision, engine limits,
   the precision study in IEEE formats, the true error against a 50-digit reference, benchmarks
   and their history across commits (:mod:`redysim.reports.history`: the checkout's
   ``benchmarks/history/bench.jsonl``, ``--history``).
"""

from __future__ import annotations

import argparse
import base64
import math
import sys
import time
import tomllib
from pathlib import Path

import jinja2
import numpy as np
import pandas as pd

from redysim import references
from redysim.harness.provenance import provenance
from redysim.harness.spec import CORE
from redysim.io.cases import CASES_DIR

from . import figures as F
from . import history as H
from .content import DIFFER, INFO, MATCH, NOT_RUN, PARTIAL, Headline, Report, Row, Section, Table
from .implicit import implicit_section
from .paper_tables import Ctx, nonfinite_sign_differs, paper_tables, printed_match
from .precision_tables import sig_decimals
from .proteins import proteins_section
from .refine import refine_section
from .results import Results, finite
from .scaling import slopes
from .text import clip, integer, num, provenance_line, sci, seconds
from .trade import headline_trade, trade_section

DEFAULT_RESULTS = Path("results")
DEFAULT_OUT = Path("reports") / "out"
HTML_FILE = "report.html"
PDF_FILE = "report.pdf"
TEMPLATES = Path(__file__).with_name("templates")
TEMPLATE = "report.html.j2"
TITLE = "redysim: speed against accuracy, and the paper reproduced"
REFERENCE_ENGINES = ("Pinocchio", "MuJoCo", "Exudyn", "DART", "Drake")  # (test_report checks)
SUBTITLE = ("Which engine and setting reaches which accuracy at what cost, measured in redysim "
            f"and five reference engines ({', '.join(REFERENCE_ENGINES)}); then Agarwal, Shah, "
            "Bandyopadhyay, Saha: Dynamics of serial kinematic chains with large number of "
            "degrees-of-freedom, reproduced")
SPIN_RATE = 1.0  # rad/s: w_Y0 of every RE-U case (published.toml [conventions])
ENERGY_TABLES = ("table2", "table3", "table4", "table5", "table6")
HEADLINE_CASE = "RE-U125-L1"


# --------------------------------------------------------------------------- headline

STEP_DETAIL_CHARS = 600  # a step's detail in the table (a sweep's list of failed runs can fill
# pages: the PDF's table cell then outgrows a page); the whole text is in the results' record


def _step_detail(detail: str) -> str:
    """A reproduction step's detail, cut at STEP_DETAIL_CHARS with where the rest is."""
    detail = str(detail)
    if len(detail) <= STEP_DETAIL_CHARS:
        return detail
    head = clip(detail, STEP_DETAIL_CHARS)[:-len(" ...")]  # cut at a word's end
    return (head + f" ... ({len(detail) - len(head):,} more characters: the step's whole "
            "detail is in results/reproduce-*.json)")


def closed_form_e0(case: str) -> float | None:
    """rho_l L^3 w^2 / 6: E(0) of a straight rod spinning about its end (rod inertia)."""
    path = CASES_DIR / f"{case}.toml"
    if not path.is_file():
        return None
    with open(path, "rb") as fh:
        ch = tomllib.load(fh)["chain"]
    if not {"total_length", "density", "radius"} <= ch.keys():
        return None
    rho_l = ch["density"] * math.pi * ch["radius"] ** 2
    return rho_l * ch["total_length"] ** 3 * SPIN_RATE**2 / 6


def headline_e0(ctx: Ctx) -> Headline:
    ours, every = {}, set()
    for key in ENERGY_TABLES:
        for row in ctx.pub[key]["rows"]:
            case = row.get("case", ctx.pub[key].get("case"))
            if "E0_J" not in row or case is None:
                continue
            every.add(case)
            c = ctx.candidates(case)
            c = c[c["status"] == "ok"] if len(c) else c
            # compare with the most digits the paper prints for the case (Table 2 or 6)
            if len(c) and (case not in ours
                           or sig_decimals(row["E0_J"]) > sig_decimals(ours[case][1])):
                ours[case] = (float(c["E0"].iloc[0]), row["E0_J"])
    if not ours:
        return Headline("E(0)", "not run", "make reproduce", NOT_RUN)
    n_match = sum(printed_match(o, p)[0] for o, p in ours.values())
    devs = [abs(o - cf) / cf for case, (o, _) in ours.items() if (cf := closed_form_e0(case))]
    total = len(every)
    detail = (f"{n_match}/{len(ours)} RE-U chains run match the paper's printed E(0) "
              f"({total - len(ours)} of the paper's {total} not run yet)")
    if devs:
        detail += f"; |ours - rho_l L^3 w^2/6| / E(0) <= {max(devs):.1e}"
    return Headline("E(0) of the spinning rods", f"{n_match}/{len(ours)} match", detail,
                    MATCH if n_match == len(ours) else DIFFER)


def headline_precision(res: Results, tables: dict[str, Table]) -> Headline:
    parts, kinds = [], []
    for key, label in (("table9", "Table 9"), ("table10", "Table 10"), ("table11", "Table 11"),
                       ("tableA2", "Table A.2")):
        t = tables[key]
        if t.not_run:
            parts.append(f"{label}: {t.not_run}")
            kinds.append(NOT_RUN)
            continue
        c = t.counts()
        parts.append(f"{label}: {c[MATCH]}/{len(t.rows)} rows match")
        kinds.append(MATCH if c[MATCH] == len(t.rows) else PARTIAL)
    doc = res.precision("table10")
    value = parts[0]  # Table 9's count, unless Table 10's values are on disk
    if doc is not None:
        c = doc["counts"]
        # an infinity of the other sign is not exact (documents written before the verdict
        # told the sign apart counted it so)
        flipped = {m: sum(nonfinite_sign_differs(r[f"ours_{p}"], r[f"paper_{p}"])
                          and r[f"verdict_{p}"] == "exact" for r in doc["rows"]
                          if r["arithmetic"] == "double" and r["method"] == m
                          for p in ("qdd", "dq")) for m in ("GE-N", "RGE-N", "RGE-A")}
        exact = {m: c[f"double/{m}"]["qdd"]["exact"] + c[f"double/{m}"]["dq"]["exact"]
                 - flipped[m] for m in ("GE-N", "RGE-N", "RGE-A")}
        value = "Table 10 values exact: " + ", ".join(f"{m} {n}/36" for m, n in exact.items())
    return Headline("Precision study (Tables 9, 10, 11, A.2)", value, "; ".join(parts),
                    MATCH if set(kinds) == {MATCH} else PARTIAL)


def headline_speed(res: Results) -> Headline:
    df = res.scaling
    if df is None or df.empty:
        return Headline("Core speed", "not run",
                        "python -m redysim.reports.scaling (make reproduce)", NOT_RUN)
    ok = df[df["status"] == "ok"]
    core = ok[(ok["engine"] == CORE) & (ok["algorithm"] == "rge-a")].set_index("n_dof")
    if core.empty:
        return Headline("Core speed", "no core timing", "", NOT_RUN)
    top = core.index.max()
    value = f"{core.loc[top, 'ns_per_dof']:.0f} ns/DOF at {top:,} DOF"
    best = None
    for engine, g in ok[ok["engine"] != CORE].groupby("engine"):
        d = g["n_dof"].max()
        if d in core.index:
            r = float(g.set_index("n_dof").loc[d, "seconds_per_call"] / core.loc[d,
                                                                                   "seconds_per_call"])
            if best is None or r < best[1]:
                best = (engine, r, d)
    load = core["load_avg_1min"].max() if "load_avg_1min" in core else math.nan
    detail = "RGE-A qdd per call, one core, warm" + (
        f", load average {load:.1f} while timed ({core['machine'].iloc[0]})"
        if finite(load) else "")
    if best:
        detail += (f"; the fastest engine at its largest timed size, {best[0]}, takes "
                   f"{best[1]:.2g}x the core's time at {best[2]:,} DOF")
    sl = slopes(df).get("rge-a")
    if sl is not None:
        detail += f"; fitted slope {sl:.2f} (O(n))"
    return Headline("Core speed", value, detail, INFO)


def headline_accuracy(res: Results) -> Headline:
    """The core's true error at the largest chain studied, beside Table A.1 as printed and the
    best engine there (error study, double precision)."""
    title = "True error of qdd (50-digit reference)"
    df = res.error_study
    if df is None or df.empty:
        return Headline(title, "not run", "python -m redysim.harness.error_study (make reproduce)",
                        NOT_RUN)
    ok = df[(df["precision"] == "float64") & (df["status"] == "ok")]
    core = ok[ok["method"] == "rge-a"]
    if core.empty:
        return Headline(title, "no core rows", "results/error_study", NOT_RUN)
    top = int(core["n_links"].max())
    at = ok[ok["n_links"] == top]
    worst = at[at["method"] == "rge-a"].sort_values("rel2").iloc[-1]
    value = f"{worst['rel2']:.1e} at {top:,} links"
    detail = (f"core RGE-A, worst of {', '.join(sorted(set(at['chain'])))} chains, straight and "
              f"random ({worst['chain']} {worst['config']}, {int(worst['n_dof']):,} DOF)")
    phi = at[at["method"] == "rge-a-phi"]
    if len(phi):
        detail += f"; Table A.1 as printed (gravity inside phi): up to {phi['rel2'].max():.1e}"
    engines = ok[ok["method"].isin(list(references.ENGINES))]
    if len(engines):
        counts = engines.groupby("n_links")["method"].nunique()
        n_e = int(counts[counts >= min(3, counts.max())].index.max())
        per = engines[engines["n_links"] == n_e].groupby("method")["rel2"].max().sort_values()
        e_core = ok[(ok["method"] == "rge-a") & (ok["n_links"] == n_e)]["rel2"].max()
        detail += (f"; at {n_e:,} links ({len(per)} engines): core {e_core:.1e}, most accurate "
                   f"engine {per.index[0]} {per.iloc[0]:.1e}")
    return Headline(title, value, detail, INFO)


def headline_limits(res: Results) -> Headline:
    lim = references.load_limits()["engine"]
    parts = [f"{e} {v['max_dof']:,}" for e, v in lim.items()]
    biggest = 0
    runs = res.runs
    if not runs.empty:
        ok = runs[(runs["engine"] == CORE) & (runs["status"] == "ok")]
        if len(ok):
            biggest = int(ok["n_dof"].max())
    value = f"engines up to {max(v['max_dof'] for v in lim.values()):,} DOF"
    detail = "largest DOF each engine takes (references/limits.toml): " + ", ".join(parts)
    detail += f"; the core has simulated {biggest:,} DOF here" if biggest else ""
    return Headline("Largest chain per engine", value, detail, INFO)


def headline_drift(ctx: Ctx) -> Headline:
    row = next(r for r in ctx.pub["table3"]["rows"] if r["case"] == HEADLINE_CASE)
    p = ctx.pick(HEADLINE_CASE, row["t_end"])
    if not p.ok:
        return Headline(f"Energy drift {HEADLINE_CASE}", "not run", "make table3", NOT_RUN)
    ours, paper = p.value("avg_abs_delta_M"), row["avg_abs_delta_M"]
    kind = MATCH if 1 / 10 <= ours / paper <= 10 else DIFFER
    return Headline(f"Energy drift {HEADLINE_CASE}, {row['t_end']:g} s",
                    f"{ours:.2e} J/kg (paper {paper:.2e})",
                    f"avg |delta_M| with ode45 at rtol 1e-4 (ours/paper {ours / paper:.2g}); "
                    f"{int(p.value('steps')):,} steps, CPU {seconds(p.value('cpu_s'))} "
                    f"(paper {row['cpu_s']} s)", kind)


def headline_verdicts(tables: list[Table]) -> Headline:
    total = {k: 0 for k in (MATCH, DIFFER, PARTIAL, NOT_RUN)}
    for t in tables:
        for k, n in t.counts().items():
            if k in total:
                total[k] += n
    empty = [t.id for t in tables if t.not_run]
    value = f"{total[MATCH]} rows match, {total[DIFFER]} differ"
    detail = (f"over Tables 1-11 and A.2: {total[PARTIAL]} partial (shortened runs), "
              f"{total[NOT_RUN]} rows not run" + (f"; tables without data: {', '.join(empty)}"
                                                   if empty else ""))
    return Headline("Verdicts", value, detail, INFO)


def headline_reproduction(res: Results) -> Headline:
    docs = [d for d in res.reproductions if d.get("mode") in ("quick", "full")] \
        or res.reproductions
    if not docs:
        return Headline("Reproduction", "not recorded", "python -m redysim.reports.reproduce", INFO)
    value = "; ".join(f"{d.get('mode', '')}: {seconds(d.get('wall_s'))}" for d in docs)
    last = docs[-1]
    return Headline("Reproduction", value,
                    f"wall time of `python -m redysim.reports.reproduce` up to the report, from "
                    f"empty "
                    f"results or resumed (last finished {last.get('finished', '')}, "
                    f"{last.get('machine', '')})", INFO)


# --------------------------------------------------------------------------- setup
def setup_section(ctx: Ctx) -> Section:
    here = provenance()
    sec = Section("setup", "Setup and provenance")
    sec.intro.append("Every number below comes from files under the results folder; each table "
                     "and figure names its source and the versions, machine, commit and date "
                     "of its data. The paper's numbers are in paper/published.toml, "
                     "transcribed from the text.")
    t = Table("provenance", "This build", ["item", "value"])
    for k, v in here.items():
        if k != "executable" and v:
            t.rows.append(Row([k, str(v)]))
    for name, cls in references.ENGINES.items():
        try:
            version = cls.package_version() if cls.available() else "not installed"
        except Exception as exc:  # a broken engine install is reported, not fatal
            version = f"unavailable ({type(exc).__name__})"
        t.rows.append(Row([f"engine {name}", f"{cls.package} {version}"]))
    t.provenance = f"report built {here['date']}"
    sec.items.append(t)
    conv = ctx.pub["conventions"]
    s = Table("settings", "The paper's settings, used for every paper-vs-ours run",
              ["setting", "value"])
    for key in ("integrator", "rtol", "atol", "sample_interval_s", "energy_drift",
                "rod_mass_per_length", "rod_inertia_note", "spatial_initial_state"):
        s.rows.append(Row([key, str(conv[key])]))
    s.notes.append("Our ode45 is Dormand-Prince 4(5) with MATLAB's step-size rules (max-norm "
                   "error, first step, 5x growth cap, refine; redysim/integrators/explicit.py).")
    s.notes.append("RE-U chains use the rod inertia (Ixx = m r^2/2, Iyy = Izz = m l^2/12): the "
                   "paper's E(0) needs it. It violates the triangle inequality of inertia for "
                   "l < sqrt(3) r, i.e. in every RE-U case; MuJoCo's compiler rejects it, so its "
                   "adapter compiles with balanceinertia and writes the exact values back "
                   "(docs/design.md, 'Chain conventions'). The physical cylinder model is "
                   "available in the case files' `inertia` field.")
    s.notes.append("Timings run one BLAS thread per process (redysim.harness sets it with "
                   "threadpoolctl unless the environment sets a thread count): with OpenBLAS's "
                   "default threads on this shared 2-core machine SciPy's Cholesky of a 250 x 250 "
                   "GIM took 0.23 s instead of 1.5 ms.")
    sec.items.append(s)
    src = Table("sources", "Results found", ["result", "where"],
                [Row([a, b]) for a, b in ctx.res.sources()])
    if not src.rows:
        src.not_run = "no results yet: make reproduce"
    sec.items.append(src)
    for doc in ctx.res.reproductions:
        r = Table(f"reproduction-{doc.get('mode', '')}".replace(" ", "-").replace(",", ""),
                  f"Reproduction: {doc.get('mode')}",
                  ["step", "wall time", "CPU time", "status", "detail"],
                  [Row([s["step"], seconds(s["wall_s"]), seconds(s.get("cpu_s")), s["status"],
                        _step_detail(s.get("detail", ""))],
                       MATCH if s["status"] == "ok" else DIFFER) for s in doc.get("steps", [])])
        cpu = sum(s.get("cpu_s", math.nan) for s in doc["steps"]) if doc.get("steps") \
            else math.nan
        r.notes.append(f"Total wall time {seconds(doc.get('wall_s'))} up to the report"
                       + (f", CPU {seconds(cpu)} (this process's and its ended children's: sweep "
                          "workers, long runs)" if math.isfinite(cpu) else "")
                       + f", started {doc.get('started', '')}.")
        r.provenance = provenance_line(doc.get("provenance"), what="results/reproduce-*.json")
        sec.items.append(r)
    return sec


# --------------------------------------------------------------------------- beyond the paper
def limits_table(res: Results) -> Table:
    lim = references.load_limits()
    t = Table("limits", "Engine limits: the largest case each engine takes, and what stops it",
              ["engine", "max DOF", "max links", "what stops it", "measured",
               "timed here up to", "timing stopped by"])
    sc = res.scaling
    for engine, v in lim["engine"].items():
        timed, why = "", ""
        if sc is not None:
            g = sc[sc["engine"] == engine]
            ok = g[g["status"] == "ok"]
            timed = f"{int(ok['n_dof'].max()):,} DOF" if len(ok) else ""
            stop = g[g["status"] != "ok"]
            why = str(stop["reason"].iloc[0]) if len(stop) else ""
        t.rows.append(Row([engine, integer(v["max_dof"]), integer(v.get("max_links")),
                           v["stops"], v["measured"], timed, why]))
    b = lim["budget"]
    t.notes.append(f"Budgets (references/limits.toml): {b['memory_gib']} GiB memory, "
                   f"{b['build_s']} s to build, {b['qdd_s']} s per qdd call. None takes "
                   "RE-U50000-L1000 (100,000 DOF); the core does (O(n) time and memory). "
                   "'Timed here' is the CPU-scaling measurement of this report, under its own "
                   "smaller budget.")
    t.provenance = "references/limits.toml (measured " + ", ".join(
        sorted({v["date"] for v in lim["engine"].values()})) + ")"
    return t


def scaling_table(res: Results) -> Table:
    t = Table("scaling", "CPU of one qdd call per engine and algorithm",
              ["algorithm", "engine", "version", "DOF timed", "ns/DOF at the smallest",
               "ns/DOF at the largest", "slope", "stopped at", "why"])
    df = res.scaling
    if df is None or df.empty:
        t.not_run = "not run: python -m redysim.reports.scaling (make reproduce)"
        return t
    sl = slopes(df)
    for label, g in df.groupby("algorithm", sort=False):
        ok = g[g["status"] == "ok"].sort_values("n_dof")
        stop = g[g["status"] != "ok"]
        t.rows.append(Row([
            label, g["engine"].iloc[0], str(ok["version"].iloc[0]) if len(ok) else "",
            f"{int(ok['n_dof'].min()):,}-{int(ok['n_dof'].max()):,}" if len(ok) else "",
            f"{ok['ns_per_dof'].iloc[0]:,.0f}" if len(ok) else "",
            f"{ok['ns_per_dof'].iloc[-1]:,.0f}" if len(ok) else "",
            f"{sl[label]:.2f}" if label in sl else "",
            integer(stop["n_dof"].iloc[0]) if len(stop) else "",
            (f"{stop['status'].iloc[0]}: {stop['reason'].iloc[0]}" if len(stop) else "")]))
    if "load_avg_1min" in df:
        t.notes.append(f"Load average of the machine during the timing: "
                       f"{df['load_avg_1min'].min():.1f}-{df['load_avg_1min'].max():.1f} "
                       "(2 cores, shared): timings of a loaded machine are upper bounds.")
    t.provenance = provenance_line(df, what="results/scaling/scaling.parquet")
    return t


def ieee_table(res: Results) -> Table:
    t = Table("ieee", "The precision study in IEEE float32: relative error of qdd at q = 0",
              ["links", "cond2", "u x cond2"])
    doc = res.precision("ieee")
    if doc is None:
        t.not_run = "not run: make table11"
        return t
    rows = [r for r in doc["rows"] if r["dtype"] == "float32"]
    methods = list(dict.fromkeys(r["method"] for r in rows))
    t.columns += methods
    for n in dict.fromkeys(r["links"] for r in rows):
        rr = {r["method"]: r for r in rows if r["links"] == n}
        r0 = next(iter(rr.values()))
        t.rows.append(Row([str(n), num(r0["cond2"], 4), sci(r0["u_cond2"], 1)]
                          + [sci(rr[m]["rel_error"], 1) if rr[m]["status"] == "ok"
                             else rr[m]["status"] for m in methods]))
    t.notes.append("Every operation of each method in float32 (the kernels' own source on "
                   "float32 scalars; redysim/algorithms/precision.py); the reference is the "
                   "same inputs in 40-place decimal arithmetic. u = 2^-24, the unit roundoff.")
    t.provenance = provenance_line(doc.get("meta"), what="results/precision/ieee.json")
    return t


CONFIG_TITLES = {"stretched": "straight chain (q = 0)",
                 "random": "random state (q, qd ~ U(-0.3, 0.3), seeded)"}


def true_error_table(res: Results, config: str = "stretched") -> Table:
    tid = "true-error" if config == "stretched" else f"true-error-{config}"
    t = Table(tid, f"True relative error of qdd, double precision, {CONFIG_TITLES[config]}",
              ["chain", "links", "DOF", "cond2"])
    df = res.error_study
    if df is None or df.empty:
        t.not_run = "not run: python -m redysim.harness.error_study (make reproduce)"
        return t
    sel = df[(df["precision"] == "float64") & (df["config"] == config)]
    ran = sel[sel["status"].isin(["ok", "nonfinite", "failed"])]
    methods = list(dict.fromkeys(ran["method"]))
    t.columns += methods
    for (chain, nl), g in sel.groupby(["chain", "n_links"]):
        by = g.set_index("method")
        cond = g["cond2"].dropna()
        cond = cond.iloc[0] if len(cond) else g["cond2_lanczos"].dropna().iloc[0] \
            if g["cond2_lanczos"].notna().any() else math.nan
        cells = [chain, f"{nl:,}", f"{int(g['n_dof'].iloc[0]):,}", sci(cond, 1)]
        for m in methods:
            if m not in by.index:
                cells.append("")
                continue
            r = by.loc[m]
            r = r.iloc[0] if isinstance(r, pd.DataFrame) else r
            cells.append(sci(r["rel2"], 1) if r["status"] == "ok" else
                         {"nonfinite": "NaN", "failed": "FAIL"}.get(r["status"], ""))
        t.rows.append(Row(cells))
    t.notes.append("||qdd - ref||_2 / ||ref||_2 with ref the exact solution of the double-"
                   "precision input (mpmath, 50 digits; harness/error_study.py). NaN: the method "
                   "returned "
                   "NaN/Inf; FAIL: it raised (Cholesky: not positive definite); blank: not run "
                   "(beyond the method's or engine's limit).")
    t.provenance = provenance_line(df, what="results/error_study/error_study.parquet")
    return t


def bench_table(res: Results) -> Table:
    from redysim.references.report_bench import rows as bench_rows

    t = Table("bench", "Benchmarks (pytest-benchmark): qdd per call, core vs engines; batches "
              "of 64 states (the core's batch in SIMD tiles and row by row, the core and "
              "pin.aba state by state)",
              ["kind", "system", "engine", "version", "DOF", "fastest per call",
               "ns/DOF (a batch: per state)", "x core (a batch: x core's batch)"])
    doc = res.bench("engines")
    if doc is None:
        t.not_run = "not run: make bench-engines"
        return t
    for r in bench_rows(doc):
        t.rows.append(Row([r["kind"], r["robot"] or "U chain", r["engine"], r["version"],
                           f"{r['dof']:,}",
                           seconds(r["min_s"]), num(r["ns_per_dof"], 3),
                           num(r["ratio"], 3)]))
    info = doc.get("machine_info", {})
    t.provenance = (f"results/bench/engines.json: {info.get('cpu', {}).get('brand_raw', '')}, "
                    f"Python {info.get('python_version', '')}, {doc.get('datetime', '')}")
    return t


LADDER_RUNGS = {1: "call from Python", 2: "inside compiled code", 3: "batch of 64",
                4: "a simulated second"}


def ladder_core_reference(rows: list[dict]) -> dict:
    """(system, rung) -> the core's time per state that the rung's rows are divided by: its
    first row of the rung (benchmarks/ladder.py writes them so: the evaluator, the kernel's
    loop, the default batch, the cheapest run)."""
    ref: dict = {}
    for r in rows:
        if r["engine"] == "core" and "per_state_s" in r:
            ref.setdefault((r["system"], r["rung"]), r["per_state_s"])
    return ref


def ladder_table(res: Results) -> Table:
    """The latency/throughput ladder (benchmarks/ladder.py, make bench-engines)."""
    t = Table("ladder", "Latency and throughput ladder: forward dynamics per state, from a call "
              "from Python to a whole simulated second, the core beside every engine",
              ["system", "DOF", "rung", "engine", "version", "how", "per state",
               "ns/DOF", "x core", "note"])
    doc = res.bench("ladder")
    if doc is None:
        t.not_run = "not run: make bench-engines (benchmarks/ladder.py)"
        return t
    tol = doc.get("tolerance_m", math.nan)
    for r in doc["rows"]:
        rung = LADDER_RUNGS.get(r["rung"], str(r["rung"]))
        head = [r["system"], f"{r['dof']:,}", rung, r["engine"], str(r.get("version", "")),
                r.get("call", "")]
        if "per_state_s" not in r:
            t.rows.append(Row(head + ["", "", "", r.get("note", "")], NOT_RUN))
            continue
        note = (f"path error {r['error_m']:.1e} m, {r['steps']:,} steps" if r["rung"] == 4
                else r.get("note", ""))
        t.rows.append(Row(head + [seconds(r["per_state_s"]), num(r["ns_per_dof"], 3),
                                  num(r.get("x_core", math.nan), 3), note], INFO))
    m = doc.get("machine", {})
    t.notes += [
        "Rungs 1-3 timed side by side in one process (every callable alternating within each "
        "round), the median per state over the rounds. 1: one state's qdd from Python (the "
        "core's evaluator and its default call; pin.aba; MuJoCo's qpos and qvel set and "
        "mj_forward; DART, Exudyn and Drake as their adapters call them). 2: the computation "
        "repeated inside compiled code (the core's kernel in a numba loop; pin.abaInParallel on "
        "one thread over 64 states; mj_step with nstep, Euler: mj_forward and the update). 3: 64 "
        "states in one call on every core (the core's batch; pin.abaInParallel; MuJoCo's "
        "rollout of one step from each).",
        f"4: the CPU time per simulated second of the engine's cheapest run (among redysim "
        f"compare's: the core's integrators, the engine through ode45 and with each of its "
        f"own integrators over a ladder of steps or tolerances) whose observed path stays "
        f"within {tol:g} m of the scenario's reference solution over "
        f"{doc.get('t_end_s', 1.0):g} s; 'how' names that run.",
        "x core: per state over the core's of the same rung (its evaluator, its kernel's loop, "
        "its default batch, its cheapest run). The systems: the xArm7 (XARM7-FALL, 7 DOF), "
        "Talos reduced on a floating base (TALOS-FALL, 38 DOF), RE-U125-L1's rope swinging from "
        "30 degrees off the vertical (cases/ladder/swing-U125-L1.toml, 250 DOF); each engine "
        "builds the core's own model (one adapter an engine: Pinocchio's with a U joint as two "
        "revolute joints on the rope).",
    ]
    t.provenance = (f"results/bench/ladder.json: {m.get('cpu', '')}, {m.get('cores', '')} "
                    f"cores, Python {m.get('python', '')}, redysim {m.get('redysim', '')}, "
                    f"{doc.get('date', '')}, load average {doc.get('load', [[math.nan]])[0][0]:.2f}"
                    " at start")
    return t


def ladder_figure(res: Results):
    """The ladder as lines: per system, time per state against the rung, a line per engine
    through the rungs it has (the core: the rows its table divides by)."""
    from .figures import PANEL_H, PANEL_W, WP_MARKERS, _figure, missing, new_figure

    title = "Latency and throughput ladder"
    caption = ("Forward dynamics per state, log scale, on each rung of the ladder table: 1 a call "
               "from Python, 2 the same inside compiled code, 3 a batch of 64 states on every "
               "core, 4 the CPU time per simulated second at the stated path accuracy (the "
               "engine's cheapest run: another unit, not joined to the rest). A line per engine "
               "through the rungs 1-3 it has; the core's evaluator, kernel loop, default batch "
               "and cheapest run.")
    doc = res.bench("ladder")
    if doc is None:
        return missing("ladder", "perf-ladder", title, caption,
                       "not run: make bench-engines (benchmarks/ladder.py)")
    rows = [r for r in doc["rows"] if "per_state_s" in r]
    systems = list(dict.fromkeys(r["system"] for r in rows))
    m = doc.get("machine", {})
    fig, axes = new_figure(len(systems), width=PANEL_W * len(systems), height=PANEL_H * 1.3,
                           footer=f"results/bench/ladder.json: {m.get('cpu', '')}, "
                                  f"{doc.get('date', '')}")
    engines = list(dict.fromkeys(r["engine"] for r in rows))
    for ax, system in zip(np.atleast_1d(axes), systems, strict=True):
        for i, engine in enumerate(engines):
            first: dict = {}
            for r in rows:  # an engine's first row of each rung (the core's reference rows)
                if r["system"] == system and r["engine"] == engine:
                    first.setdefault(r["rung"], r["per_state_s"])
            if not first:
                continue
            # rungs 1-3 (time per state) joined; rung 4 (CPU per simulated second) a marker
            xs = sorted(x for x in first if x < 4)
            style = dict(marker=WP_MARKERS[i % len(WP_MARKERS)], color=f"C{i % 10}", ms=4)
            if xs:
                ax.semilogy(xs, [first[x] for x in xs], lw=2.0 if engine == "core" else 1.0,
                            label=engine, **style)
            if 4 in first:
                ax.semilogy([4], [first[4]], linestyle="none", ms=6,
                            **({} if xs else {"label": engine}), **{k: v for k, v in
                                                                     style.items() if k != "ms"})
        dof = next(r["dof"] for r in rows if r["system"] == system)
        ax.set(title=f"{system} ({dof:,} DOF)", xticks=list(LADDER_RUNGS),
               xticklabels=["call", "compiled", "batch 64", "1 s"], ylabel="s per state "
               "(rung 4: CPU s per simulated s)")
    handles: dict = {}  # every panel's engines, once (Pinocchio's adapter differs on the rope)
    for ax in np.atleast_1d(axes):
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    np.atleast_1d(axes)[-1].legend(handles.values(), handles.keys(), loc="upper left",
                                   bbox_to_anchor=(1.0, 1.0))
    return _figure("ladder", "perf-ladder", title, caption, fig)


# --------------------------------------------------------------------------- robots and trees
ROBOTS_NOT_RUN = "not run: python -m redysim.reports.robots (make reproduce runs it)"
MUJOCO_SOFT_COUPLING = ("qdd only: MuJoCo holds a mimic coupling softly, a joint equality with its "
                        "regulariser R; the core's coupled qdd with R added gives MuJoCo's to "
                        "1e-9, tests/test_couplings.py")


def robots_section(res: Results) -> Section:
    """Robots no one here wrote, in the core and every engine (reports/robots.py)."""
    from .robots import STAGES

    sec = Section("robots", "Robots and trees")
    sec.intro.append("The core runs kinematic trees (fixed or floating base) with the same "
                     "compiled kernels as the rope. Here: robots of the example-robot-data "
                     "package (URDF read by redysim's own reader) and the DH robots of "
                     "cases/robots, "
                     "in the core and in every engine, each engine building the core's own tree "
                     "(redysim.references); per-call cost beside pin.aba; passive falls.")
    doc = res.robots
    agree = Table("robots-agreement", "Agreement with the engines: worst relative difference "
                  "over seeded random states", ["robot", "engine", *STAGES, "verdict"])
    percall = Table("robots-percall", "qdd per call from Python: the core (forward_dynamics "
                    "and the evaluator) and pin.aba, side by side",
                    ["robot", "DOF", "forward_dynamics", "core, general kernels", "evaluator",
                     "pin.aba", "pin.aba / forward_dynamics", "pin.aba / evaluator"])
    falls = Table("robots-falls", "Passive falls, 1 s (ode45, rtol 1e-8, atol 1e-10)",
                  ["robot", "DOF", "steps", "CPU", "max |delta_M| [J/kg]",
                   "COM off its parabola [m]"])
    if doc is None:
        for t in (agree, percall, falls):
            t.not_run = ROBOTS_NOT_RUN
        sec.items += [agree, percall, falls]
        return sec
    tol = doc["tolerance"]
    for r in doc["agreement"]:
        if r["status"] != "ok":
            agree.rows.append(Row([r["robot"], r["engine"], *([""] * len(STAGES)),
                                   f"{r['status']}: {r['reason']}"], NOT_RUN))
            continue
        worst = max(r[s] for s in STAGES)
        ok = worst <= tol
        soft = not ok and r.get("couplings") and r["engine"] == "mujoco" and \
            max(r[s] for s in STAGES if s != "qdd") <= tol
        verdict = (f"agree within {tol:g}" if ok else f"differ: {sci(worst, 1)}"
                   + (f" ({MUJOCO_SOFT_COUPLING})" if soft else ""))
        agree.rows.append(Row([r["robot"], r["engine"], *(sci(r[s], 1) for s in STAGES),
                               verdict], MATCH if ok else INFO if soft else DIFFER))
    agree.notes.append(f"max |engine - core| / max |core| over {doc['states']} seeded states "
                       "(joint angles in [-1.2, 1.2] rad, random velocities and torques, a "
                       "random base pose); bias = phi with tau = 0; energy = (T, V). A row "
                       "without numbers: the engine refused the model before building it (its "
                       "limits say why) or failed (its words). Mimic joints are couplings "
                       "(redysim.Coupling, the default of load_model): qdd is the coupled "
                       "motion, the GIM, bias and energy the tree's; Pinocchio's CRBA adapter "
                       "builds them as Pinocchio's mimic joints, MuJoCo as joint equalities; "
                       "the other engines refuse them by name.")
    for r in doc["per_call"]:
        general = r.get("general_s", math.nan)
        timed = finite(r.get("evaluator_s"))
        percall.rows.append(Row([r["robot"], integer(r["n_v"]),
                                 seconds(r["core_s"]) + (" (DH kernels)" if r.get("dh") else ""),
                                 "" if not finite(general) else seconds(general),
                                 seconds(r["evaluator_s"]) if timed else "not timed",
                                 seconds(r["pin_aba_s"]), num(r["ratio"], 3),
                                 num(r["evaluator_ratio"], 3) if timed else "not timed"]))
    if any(not finite(r.get("evaluator_s")) for r in doc["per_call"]):
        percall.notes.append("Evaluator 'not timed': results/robots/robots.json was written "
                             "before the robots step timed it; python -m redysim.reports.robots "
                             "(make reproduce) times it beside the others.")
    percall.notes.append("The fastest of 9 rounds of 2,000 calls each, alternating; the core's "
                         "forward_dynamics with a reused Workspace (a checked call: its "
                         "arguments' types, shapes and values), its evaluator "
                         "(fd = redysim.evaluator(model); fd(q, v, None, out): bound once, the "
                         "fastest call from Python, the README's figure), "
                         "pin.aba on Pinocchio's own model of the same "
                         "URDF (tests/test_trees.py: the two agree to 1e-13), or for the DH "
                         "robots of cases/robots on the model redysim.references builds from "
                         "the core's (the robots' agreement rows above). On a robot in DH form "
                         "the core runs its DH kernels; 'core, general kernels' is the same call "
                         "with dh=False. make bench-engines measures the same with "
                         "pytest-benchmark; benchmarks/lean_call.py the evaluator's calls.")
    for r in doc["falls"]:
        falls.rows.append(Row([r["robot"], integer(r["n_v"]), integer(r["steps"]),
                               seconds(r["cpu_s"]), sci(r["max_abs_delta_M"], 2),
                               "" if not finite(r["parabola_m"]) else sci(r["parabola_m"], 1)],
                              INFO if r["status"] == "ok" else DIFFER))
    falls.notes.append("A fixed base falls from rest; a floating base tumbles (seeded joint and "
                       "base velocities), its quaternion projected onto the unit sphere after "
                       "every step. In free fall the centre of mass must follow c0 + cdot0 t + "
                       "g t^2 / 2 whatever the joints do: its distance from that parabola "
                       "checks the floating-base dynamics without a reference solution. The "
                       "Stanford arm's joint 3 slides, and the models carry no joint limits: "
                       "from rest its arm drops freely along that joint (4.9 m in 1 s).")
    for t in (agree, percall, falls):
        t.provenance = provenance_line(doc.get("provenance"), what="results/robots/robots.json")
    sec.items += [agree, percall, falls, robot_opcount_table(res)]
    return sec


def robot_opcount_table(res: Results) -> Table:
    """Our counted operations on a serial robot beside the talk's (reports/opcount.py)."""
    from .robots import TALK_COUNTS, TALK_N

    t = Table("robots-opcount", f"Operation counts, serial robot of n revolute joints (DH), "
              f"ours beside the talk's; totals at n = {TALK_N}",
              ["algorithm", "multiplications", "additions", f"at n = {TALK_N}", "x talk"])
    oc = res.opcount
    if oc is None or "robots" not in oc:
        t.not_run = "not run: make table7 (reports/opcount.py)"
        return t
    fits = oc["robots"]["fits"]
    if any("kind" not in f for f in fits):  # counted before the DH kernels
        t.not_run = "stale: counted before the DH kernels existed; run make table7"
        return t
    for kind in ("forward", "inverse"):
        (tm, tm0), (ta, ta0) = TALK_COUNTS[kind]
        talk = (tm * TALK_N + tm0) + (ta * TALK_N + ta0)
        t.rows.append(Row([f"talk (DeNOC): {kind} dynamics", f"{tm}n - {-tm0}",
                           f"{ta}n - {-ta0}", f"{tm * TALK_N + tm0}M {ta * TALK_N + ta0}A", ""],
                          INFO))
        for f in fits:
            if f["kind"] != kind:
                continue
            ours = sum(np.polyval(f[c], TALK_N) for c in ("mult_coef", "add_coef"))
            t.rows.append(Row([f"ours: {f['algorithm']}", f["mult"], f["add"],
                               f"{np.polyval(f['mult_coef'], TALK_N):.0f}M "
                               f"{np.polyval(f['add_coef'], TALK_N):.0f}A",
                               f"{ours / talk:.2f}"], INFO))
    t.notes.append("Ours counted in the kernels' own Python source on numbers that tally every "
                   "*, /, + and - (reports/opcount.py), on serial robots of revolute joints "
                   "built from DH tables with seeded values (no length or offset zero); "
                   "fitted on 4 and 8 joints, checked on 13. The DH kernels are what "
                   "forward_dynamics and inverse_dynamics run on a robot in DH form: on "
                   "twists that are right angles' multiples (0, +-90, 180 degrees: the PUMA "
                   "560's and the Stanford arm's, and most industrial arms') they turn vectors "
                   "and inertias about x without arithmetic; 'any twists' is their count on "
                   "twists that are not. The general kernels (dh=False) take any joint "
                   "placement (a full rotation and shift per joint). The talk's counts are for "
                   "Saha's recursive DeNOC algorithms specialised to DH frames. cos/sin, the "
                   "constants of the robot computed once from its table (the DH kernels' "
                   "columns, the last body's projected inertia among them: its own, so "
                   "constant in its frame) and the checks for non-finite results not "
                   "counted; 'x talk' is the ratio of totals (multiplications + additions) "
                   "at n = 6.")
    t.provenance = provenance_line(oc.get("provenance"), what="results/opcount/opcount.json")
    return t


# --------------------------------------------------------------------------- closed loops
LOOPS_NOT_RUN = "not run: python -m redysim.reports.loops (make reproduce runs it)"
LOOP_TOLERANCES = {"path": 1e-8, "settled": 1e-10, "drift": 1e-8}  # the issue's and ours


SCENARIOS_SWEEP = "quick-scenarios"
FULL_SCENARIOS_SWEEP = "scenarios-truths"  # the truths that do not fit the quick budget
SCENARIO_SWEEPS = (SCENARIOS_SWEEP, FULL_SCENARIOS_SWEEP, "scenarios-round")  # the last two:
#                                                                           make reproduce-full
FULL_SCENARIOS = ("DZHANIBEKOV", "UBIQUITIN-FREE", "CATENARY")  # sweeps/scenarios-truths.toml
# the truth table's settings: the sweeps run a ladder of settings for the work-precision figures;
# the table shows ode45 at this rtol and an engine's own stepper at this step
TRUTH_RTOL = 1e-8
TRUTH_H = 1e-3
SCENARIO_BOUNDS = {  # the truth each scenario has, its measure and its bound
    "TALOS-FALL": ("COM off its free-fall parabola [m]", 1e-9),
    "TALOS-ZERO-G": ("COM off a straight line (2nd difference) [m]", 1e-10),
    "DZHANIBEKOV": ("max |delta_M| [J/kg]", 1e-6),
    "DOUBLE-PENDULUM": ("max |delta_M| [J/kg]", 1e-6),
    "HANGING-MODE": ("tip off x0 cos(omega_1 t), relative", 3e-6),
    "FOUR-BAR": ("largest loop residual [m]", 1e-8),
    "JANSEN-LEG": ("largest loop residual [m]", 1e-8),
    "FOUR-BAR-ROUND": ("largest loop residual [m]", 1e-8),
    "JANSEN-LEG-ROUND": ("largest loop residual [m]", 1e-8),
    "CATENARY": ("sag point off the discrete catenary at 8 s [m]", 1e-11),
    "UBIQUITIN-FREE": ("max |delta_E| / E(0)", 1e-6),
}
LOOP_SCENARIOS = ("FOUR-BAR", "JANSEN-LEG", "FOUR-BAR-ROUND", "JANSEN-LEG-ROUND", "CATENARY")
LOOP_FINDINGS = {  # an engine's loop adapter outside a loop scenario's bound: the cause
    "mujoco": "MuJoCo's loop constraints are soft (its constrained qdd carries a regularisation "
              "of 1e-4 of A's diagonal: references/loops.py), so the loop is kept to that, not "
              "to the step's error",
    "exudyn": "Exudyn forms the loops' velocity term d2g/dq2 v^2 by numerical differentiation "
              "(relative epsilon 1e-7: references/loops.py), so at speed its constrained qdd is "
              "off by ~1.6e-7 of its size (measured on FOUR-BAR-ROUND), which the loop and the "
              "path then carry",
}
FAILED_FINDINGS = {  # (engine, scenario) -> the measured cause of a run that stopped
    ("mujoco", "CATENARY"): (
        "under the damping MuJoCo's loop adapter takes ~17x the core's steps, at 1.5 ms a "
        "call: its soft constraint leaves J qdd + Jdot v = 1.4e-3 m/s^2 at every state (the "
        "core's 1e-14; d qdd / dy has the core's eigenvalues), which each stage's projection "
        "onto the loops removes in a jump of order h; as the chain comes to rest the error "
        "control runs on atol alone and those jumps set the step"),
}
MOMENTUM_BOUND = 1e-8  # max |h_G(t) - h_G(0)| / max |h_G(0)| where it is kept
OUTSIDE_BOUND = "outside bound"  # a finished run's status in the scenarios table, past its bound
SCENARIO_REASON_CHARS = 200  # a failed run's reason in the scenarios table, cut at a word


def _truth(res: Results, r) -> float:
    """A run's value of its scenario's truth (SCENARIO_BOUNDS), from its summary or samples."""
    import math

    import numpy as np

    case = r["case"]
    if case in ("FOUR-BAR", "JANSEN-LEG", "FOUR-BAR-ROUND", "JANSEN-LEG-ROUND"):
        return float(r["residual_q"])
    if case in ("DZHANIBEKOV", "DOUBLE-PENDULUM"):
        return float(r["max_abs_delta_M"])
    if case == "UBIQUITIN-FREE":  # relative: its energy is in kJ/mol (nm, u, ps)
        from redysim import energy

        from .results import _case

        scn = _case(case)
        e0 = sum(energy(scn.model, scn.q0, scn.v0)) / scn.model.total_mass
        return float(r["max_abs_delta_M"]) / e0
    s = res.samples(r["run_id"])
    if case in ("HANGING-MODE", "CATENARY"):  # closed forms of redysim.harness.truths
        if s is None or not len(s):
            return math.nan
        from redysim.harness.truths import catenary_point, mode_deviation

        from .results import _case

        scn = _case(case)  # (loaded once for the table's rows)
        if case == "HANGING-MODE":
            return mode_deviation(scn.model, scn.q0, s["t"].to_numpy(), s["tip_x"].to_numpy())
        last = s.sort_values("t").iloc[-1]
        if not np.isclose(float(last["t"]), scn.t_end):
            return math.nan
        p = last[["tip_x", "tip_y", "tip_z"]].to_numpy(dtype=float)
        return float(np.linalg.norm(p - catenary_point(scn.model, scn.frame)))
    if s is None or len(s) < 3 or "com_x" not in s:
        return math.nan
    t = s["t"].to_numpy()
    c = s[["com_x", "com_y", "com_z"]].to_numpy()
    if case == "TALOS-ZERO-G":
        return float(np.abs(c[2:] - 2 * c[1:-1] + c[:-2]).max())
    from .results import scenario_gravity

    g = np.asarray(scenario_gravity(case), dtype=float)
    cdot0 = (c[1] - c[0]) / (t[1] - t[0]) - 0.5 * g * (t[1] - t[0])
    return float(np.abs(c - (c[0] + np.outer(t, cdot0) + 0.5 * np.outer(t ** 2, g))).max())


def scenarios_section(res: Results) -> Section:
    """The scenarios with truths no engine supplies, in every engine that builds them (the
    sweep sweeps/quick-scenarios.toml), and the work-precision of robots (its figures are in
    the figures section, one per scenario)."""
    sec = Section("scenarios", "Scenarios: robots, floating bases and loops in every engine")
    sec.intro.append(
        "Every system runs through the same harness as the rope: a scenario file "
        "(cases/scenarios/) names a model file, a state, a horizon and the frame to observe; "
        "runs, sweeps, reference solutions, gates and this report take any scenario, and every "
        "engine runs it through redysim's integrators (its qdd) and with its own integrators "
        "(native:NAME; `redysim engines` lists them). The work-precision figures of the UR5, "
        "the Panda and Talos are in the figures section (sweeps/quick-work-precision-robots."
        "toml). Below: the truths no engine supplies, for every engine and integrator; a value "
        "outside its bound is a finding, its cause in the note.")
    tab = Table("scenarios-truths", "Truths no engine supplies, in every engine",
                ["scenario", "run", "status", "truth", "value", "bound",
                 f"h_G drift (<= {MOMENTUM_BOUND:g})", "path error [m]", "note"],
                notes=["Path error: the largest distance of the scenario's observed frame from "
                       "its reference solution (the core's DOP853 at 1e-10, checked by SciPy's "
                       "DOP853 at 1e-13) over the samples. COM values are computed from the "
                       "run's sampled centre of mass (every 0.025 or 0.05 s). A loop adapter "
                       "takes assembled states only, so it is asked at each Runge-Kutta stage's "
                       "state projected onto the loops (docs/design.md, 'Scenarios'); DART's "
                       "takes v = 0 only, and says so. HANGING-MODE: the tip's largest "
                       "distance from x0 cos(omega_1 t) over its amplitude x0, omega_1 from "
                       "the linearised energies by hand; the nonlinearity alone leaves 2.16e-6 "
                       "(2.16 A^2 at A = 1e-3 rad). CATENARY: the sag point's distance at 8 s "
                       "from its place on the discrete catenary (closed form); its damping is "
                       "applied by redysim's integrators, so the engines run it through ode45 "
                       "only (harness/truths.py). h_G drift: the largest change of the "
                       "angular momentum about the centre of mass over its size (the run's "
                       "p_* and h_* sample columns, redysim.momentum), kept exactly in free "
                       "fall and in zero gravity. UBIQUITIN-FREE: its units are nm, u and ps "
                       "(the runs' seconds are picoseconds, its path error nm), its energy "
                       "change relative to its energy. The sweeps run each engine over a ladder "
                       f"of settings (the work-precision figures); the table shows ode45 at "
                       f"rtol {TRUTH_RTOL:g} and each engine's own stepper at {TRUTH_H:g} s."])
    runs = res.runs
    sel = runs[runs["sweep"].isin(SCENARIO_SWEEPS)] if "sweep" in runs else runs.iloc[0:0]
    if sel.empty:
        tab.not_run = f"not run: make reproduce (sweeps/{SCENARIOS_SWEEP}.toml)"
        sec.items.append(tab)
        return sec
    import math

    from .results import momentum_drift, momentum_kept

    for case in SCENARIO_BOUNDS:
        what, bound = SCENARIO_BOUNDS[case]
        rows = sel[sel["case"] == case]
        # the runs at the table's settings (the ladders' other settings are the figures')
        h = rows["h"].astype(float)
        rows = rows[np.where(h > 0, np.isclose(h, TRUTH_H),
                             np.isclose(rows["rtol"].astype(float), TRUTH_RTOL))]
        if rows.empty:
            target = ("make reproduce-full (sweeps/scenarios-round.toml)" if case.endswith(
                "-ROUND") else f"make reproduce-full (sweeps/{FULL_SCENARIOS_SWEEP}.toml)"
                if case in FULL_SCENARIOS else f"make reproduce (sweeps/{SCENARIOS_SWEEP}.toml)")
            tab.rows.append(Row([case, "", "not run", what, "", f"<= {bound:g}", "", "",
                                 f"not run: {target}; the core's run is a gate "
                                 "(harness/gates.toml)" if case.endswith("-ROUND") else
                                 f"not run: {target}"], NOT_RUN))
            continue
        rows = rows.assign(_core=rows["engine"] != CORE).sort_values(
            ["_core", "engine", "integrator"])
        truth = {r["run_id"]: _truth(res, r) for _, r in rows.iterrows() if r["status"] == "ok"}
        within = {r["engine"] for _, r in rows.iterrows() if r["status"] == "ok"
                  and r["integrator"] == "ode45" and truth[r["run_id"]] <= bound}
        for _, r in rows.iterrows():
            setting = f"h {float(r['h']):g}" if float(r["h"]) > 0 else f"rtol {float(r['rtol']):g}"
            name = f"{r['engine']} {r['integrator']} {setting}"
            if r["status"] != "ok":
                reason = clip(r["reason"], SCENARIO_REASON_CHARS)
                if (r["engine"], case) in FAILED_FINDINGS:
                    reason += f" ({FAILED_FINDINGS[r['engine'], case]})"
                tab.rows.append(Row([case, name, r["status"], what, "", f"<= {bound:g}", "", "",
                                     reason], NOT_RUN))
                continue
            value = truth[r["run_id"]]
            ok = math.isfinite(value) and value <= bound
            known = LOOP_FINDINGS.get(r["engine"]) if r["engine"] != CORE and \
                case in LOOP_SCENARIOS else None
            kept = momentum_kept(case)
            drift = momentum_drift(res.samples(r["run_id"])) if kept else math.nan
            if kept:
                ok = ok and math.isfinite(drift) and drift <= MOMENTUM_BOUND
            note = ""
            if not ok:
                note = ("outside the bound; the engine's model is within it through ode45: "
                        "this is its own stepper's truncation error at this step (the path "
                        "error shows it)" if r["engine"] in within and
                        str(r["integrator"]).startswith("native") else
                        f"outside the bound: {known}" if known else "outside the bound")
            status = "ok" if ok else OUTSIDE_BOUND if math.isfinite(value) else "no value"
            tab.rows.append(Row([case, name, status, what, sci(value, 1),
                                 f"<= {bound:g}",
                                 sci(drift, 1) if kept else "",
                                 sci(float(r["max_tip_err"]), 1), note],
                                MATCH if ok else DIFFER))
    sec.items.append(tab)
    return sec


def loops_section(res: Results) -> Section:
    """Closed loops: checks against closed forms, cost against n, a long pinned chain."""
    sec = Section("loops", "Closed loops")
    sec.intro.append("A closed-loop mechanism is a tree plus the joints cut to open it "
                     "(redysim.algorithms.loops): forward dynamics by Featherstone's method on "
                     "the tree's O(n) recursions ((1 + m) RGE-A calls and an m x m solve for m "
                     "constraint equations), the loop forces an output, positions and "
                     "velocities projected back onto the loops after every step (no Baumgarte "
                     "gains), and the residuals of every run reported.")
    doc = res.loops
    checks = Table("loops-checks", "Checks against closed forms",
                   ["check", "measured", "bound", "verdict"])
    cost = Table("loops-cost", "Cost of a constrained qdd call against n (pinned chains)",
                 ["rods n", "per call", "ns per rod"])
    run = Table("loops-long", "A long pinned chain: 10,000 rods (100 m, span 80 m)",
                ["simulated", "steps", "RHS calls", "CPU", "max |delta_M| [J/kg]",
                 "max residual [m]", "max velocity residual [m/s]"])
    if doc is None:
        for t in (checks, cost, run):
            t.not_run = LOOPS_NOT_RUN
        sec.items += [checks, cost, run]
        return sec
    fb, cat = doc["four_bar"], doc["catenary"]

    def check(name, value, bound):
        ok = value <= bound
        checks.rows.append(Row([name, sci(value, 1), f"<= {bound:g}", "pass" if ok else
                                "FAIL"], MATCH if ok else DIFFER))

    check(f"four-bar: coupler point off its closed-form path [m] (crank through "
          f"{fb['crank_range_rad']:.2f} rad in 2 s)", fb["path_error_m"],
          LOOP_TOLERANCES["path"])
    check("four-bar: energy drift, passive [J/kg]", fb["max_abs_delta_M"],
          LOOP_TOLERANCES["drift"])
    check("four-bar: loop residual after a step [m]", fb["residual_q"], LOOP_TOLERANCES["path"])
    hk = doc.get("hoekens")
    if hk is not None:
        check("Hoeken's linkage: tracing point off its closed-form path [m]", hk["path_error_m"],
              LOOP_TOLERANCES["path"])
        pub = hk["published"]
        ok = round(hk["width_percent_of_crank"]) == pub["percent"] and \
            hk["crossings"] == pub["crossings"]
        checks.rows.append(Row([
            "Hoeken's linkage: straight part (simulated) within a strip of the crank's "
            "length, crossing its middle line", f"{hk['width_percent_of_crank']:.3f} %, "
            f"{hk['crossings']} times", f"published: within {pub['percent']} %, "
            f"{pub['crossings']} times", "pass" if ok else "FAIL"], MATCH if ok else DIFFER))
    check(f"pinned chain, 10 rods: at rest after 10 s of damping, off the discrete catenary "
          f"[rad] (released {cat['start_off_rad']:.1e} rad off)", cat["settled_rad"],
          LOOP_TOLERANCES["settled"])
    gaps = ", ".join(f"n = {g['n']}: {g['max_joint_gap_m']:.2e} m" for g in cat["gaps"])
    checks.notes.append("The discrete catenary (each rod's moment balance: tan theta_k = m g "
                        "(k - 1/2 - n/2) / H, H from the span) approaches the continuous one "
                        f"through the pins as O(1/n^2): joint gaps {gaps}; observed orders "
                        + ", ".join(f"{o:.3f}" for o in cat["orders"]) + ".")
    for r in doc["cost"]:
        cost.rows.append(Row([integer(r["n"]), seconds(r["seconds"]),
                              num(r["seconds"] / r["n"] * 1e9, 3)]))
    cost.notes.append(f"Fastest of 5 rounds of repeated calls; log-log slope from 1,000 rods "
                      f"up: {doc['slope']:.2f} (1 is O(n); below 1 the fixed cost of the call "
                      "still shows). Each call: RGE-A three times (qdd and M^-1 J^T for the "
                      "two equations of the pin) and the Jacobian of the pin's path.")
    lr = doc["long"]
    run.rows.append(Row([f"{lr['t_end']:g} s", integer(lr["steps"]), integer(lr["nfev"]),
                         seconds(lr["cpu_s"]), sci(lr["max_abs_delta_M"], 2),
                         sci(lr["residual_q"], 1), sci(lr["residual_v"], 1)],
                        INFO if lr["status"] == 0 else DIFFER))
    run.notes.append("From the continuous catenary at rest (ode45 at the paper's tolerances); "
                     "make reproduce-full runs 1 s.")
    engines = Table("loops-engines", "The engines on the same loops: worst relative difference "
                    "from the core, at rest and moving", ["mechanism", "engine", "qdd",
                                                          "loop force", "note"])
    for r in doc.get("engines", []):
        done = finite(r["qdd"])
        engines.rows.append(Row([r["mechanism"], r["engine"], sci(r["qdd"], 1) if done else "",
                                 sci(r["force"], 1) if done else "", r["refused"].strip()],
                                INFO if done else NOT_RUN))
    engines.notes.append("Each engine closes the cut with its own constraint (references/"
                         "loops.py; references/README.md, 'Loops'): Pinocchio's "
                         "RigidConstraintModel, MuJoCo's connect equality (always softened by a "
                         "regulariser of 1e-4 of each constraint's diagonal, which sets its "
                         "difference), DART's BallJointConstraint (a velocity impulse inside a "
                         "step, without the -Jdot v term: refused in motion), Exudyn's "
                         "spherical joint (its velocity term by finite differences).")
    if not engines.rows:
        engines.not_run = LOOPS_NOT_RUN
    traj = Table("loops-trajectories", "The engines' own integrators on the four-bar: 0.5 s from "
                 "rest, max |q - q_core| at the samples", ["engine", "integrator", "h = 1e-3 s",
                                                         "h = 1e-4 s", "loop residual [m]"])
    for r in doc.get("engine_trajectories", []):
        if r.get("note"):
            traj.rows.append(Row([r["engine"], r["note"], "", "", ""], NOT_RUN))
            continue
        traj.rows.append(Row([r["engine"], r["integrator"], sci(r["q_error_h0.001"], 1),
                              sci(r["q_error_h0.0001"], 1),
                              sci(max(r["residual_h0.001"], r["residual_h0.0001"]), 1)]))
    traj.notes.append("Against the core's run at rtol 1e-11 with its loops projected. MuJoCo's "
                      "error does not fall with h (its soft constraint), DART's falls as h "
                      "(first order), Exudyn's as h^2.")
    scale = Table("loops-engine-cost", "Constrained qdd per call on pinned chains: the core and "
                  "each engine, up to its limits (at rest)", ["engine", "rods n", "per call",
                                                              "build", "note"])
    for r in doc.get("engine_scale", []):
        done = finite(r["seconds"])
        scale.rows.append(Row([r["engine"], integer(r["n"]),
                               seconds(r["seconds"]) if done else "",
                               seconds(r["build_s"]) if "build_s" in r else "", r["note"]],
                              INFO if done else NOT_RUN))
    largest = {}
    for r in doc.get("engine_scale", []):
        if finite(r["seconds"]):
            largest[r["engine"]] = max(largest.get(r["engine"], 0), r["n"])
    scale.notes.append("Largest chain each took here: " + ", ".join(
        f"{e} {n:,}" for e, n in largest.items()) + f" rods (the core: {doc['cost'][-1]['n']:,} "
        "in the table above, and the 10,000-rod run below); an engine slower than 0.5 s a call "
        "is not tried larger; make reproduce-full adds 1,000 rods.")
    for t in (checks, engines, traj, cost, scale, run):
        t.provenance = provenance_line(doc.get("provenance"), what="results/loops/loops.json")
    sec.items += [checks, engines, traj, cost, scale, run]
    return sec


# --------------------------------------------------------------------------- assembling
def build_report(res: Results, history: Path = H.HISTORY_FILE) -> Report:
    """The report of the results ``res``; the performance history from ``history`` (the
    checkout's benchmarks/history/bench.jsonl: not under the results folder, which is scratch)."""
    ctx = Ctx(res)
    tables = paper_tables(res)
    by_id = {t.id: t for t in tables}
    headline = [headline_trade(res), headline_e0(ctx), headline_drift(ctx),
                headline_precision(res, by_id), headline_speed(res), headline_accuracy(res),
                headline_limits(res), headline_verdicts(tables),
                headline_reproduction(res)]
    paper = Section("paper", "Paper vs ours: Tables 1-11 and A.2", items=list(tables))
    paper.intro.append("One table per table of the paper, a verdict per row. The paper "
                       "truncates printed values: ours matches when, truncated (or rounded) to "
                       "the printed digits, it equals the paper's. Energy drift is compared by "
                       "its ratio; CPU times are shown, not judged (MATLAB on a 2011 laptop).")
    figs = Section("figures", "The paper's figures, from our runs", items=F.paper_figures(ctx))
    figs.intro.append("Figs. 3-5, 7-17 and 19 in the paper's form (Fig. 18 is with the CPU "
                      "scaling below). Samples every 0.05 s, as the paper's; a curve from a "
                      "shortened run says so in its legend.")
    beyond = Section("beyond", "Beyond the paper: conditioning, cost, accuracy, engines",
                     items=[F.conditioning(ctx), F.scaling(ctx), scaling_table(res),
                            F.op_counts(ctx), *F.work_precision(ctx), limits_table(res),
                            ieee_table(res), F.true_error(ctx), true_error_table(res),
                            F.true_error(ctx, "random"), true_error_table(res, "random"),
                            bench_table(res), ladder_figure(res), ladder_table(res),
                            H.history_figure(history)])
    here = provenance()
    return Report(TITLE, SUBTITLE, here["date"], headline,
                  [trade_section(res), setup_section(ctx), paper, figs, beyond,
                   robots_section(res),
                   scenarios_section(res), loops_section(res), proteins_section(res),
                   refine_section(res), implicit_section(res)],
                  provenance_line(here, what="report built with"))


# --------------------------------------------------------------------------- rendering
def render_html(report: Report) -> str:
    env = jinja2.Environment(loader=jinja2.FileSystemLoader(TEMPLATES),
                             autoescape=jinja2.select_autoescape(["html", "j2"]),
                             trim_blocks=True, lstrip_blocks=True)
    env.filters["b64"] = lambda b: base64.b64encode(b).decode("ascii")
    env.tests["table"] = lambda x: isinstance(x, Table)
    return env.get_template(TEMPLATE).render(report=report)


def write_report(results: Path, out: Path, *, log=print,
                 history: Path = H.HISTORY_FILE) -> tuple[Path, Path]:
    """Build the report from ``results`` (and ``history``) and write HTML and PDF into ``out``."""
    from redysim.harness.store import write_text_atomic

    from .pdf import write_pdf

    t0 = time.perf_counter()
    report = build_report(Results(results), history)
    html = write_text_atomic(render_html(report), out / HTML_FILE)
    pdf = write_pdf(report, out / PDF_FILE)
    log(f"report: {html} and {pdf} ({len(report.tables())} tables, {len(report.figures())} "
        f"figures) in {time.perf_counter() - t0:.1f} s")
    return html, pdf


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--results", type=Path, default=DEFAULT_RESULTS,
                    help=f"results folder (default {DEFAULT_RESULTS})")
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT,
                    help=f"output folder (default {DEFAULT_OUT})")
    ap.add_argument("--history", type=Path, default=H.HISTORY_FILE,
                    help=f"the performance history (default {H.HISTORY_FILE})")
    args = ap.parse_args(argv)
    write_report(args.results, args.out, history=args.history)
    return 0


if __name__ == "__main__":
    sys.exit(main())
