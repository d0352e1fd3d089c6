"""The trade: for a system and an accuracy, the cheapest engine and setting that reaches it, the
core's lead over the best engine, and the engines that do not reach it at all.

The answer is computed from run rows (a sweep's, or ``redysim compare``'s): a row reaches an
accuracy when it finished (``status`` ok) and its path error (``max_tip_err``: the largest
distance of the observed frame from the reference solution over the samples) is within it. Among
the rows that reach it, the cheapest is :func:`redysim.harness.cost.rank`'s pick (the
integration's CPU, least of repeats, with its uncertainty; rows whose cost intervals overlap are
indistinguishable). The core's lead is the best engine's cost over the core's, with
:func:`redysim.harness.cost.compare_two`'s verdict ("indistinguishable" when the intervals
overlap). An engine (an adapter: ``pinocchio-aba`` and ``pinocchio-crba`` are two) none of whose
runs reaches the accuracy is "not reached", with the least error it got; one with no finished run
says so.

:func:`trade_section` is the report's first section (:mod:`redysim.reports.build`): the system
families of :data:`FAMILIES`, read from the results folder, and the 1,000,000-DOF rod's long run
(:mod:`redysim.reports.implicit`), whose error no reference measures in quick mode.
:func:`trade_table` serves ``redysim compare``'s page (:mod:`redysim.reports.compare`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import pandas as pd

from redysim.harness import cost as C
from redysim.harness.spec import CORE

from .content import INFO, NOT_RUN, PARTIAL, Headline, Row, Section, Table
from .text import provenance_line

ACCURACIES = (1e-3, 1e-6, 1e-9)  # path error [m] the trade answers for
TIED_NAMED = 3  # the runs indistinguishable from the cheapest named in its cell (then a count)
# (family, cases, sweeps whose runs measure them, the make target that runs them)
FAMILIES = (
    ("the paper's chains", ("RE-U125-L1",),
     ("quick-work-precision", "work-precision-RE-U125-L1"), "sweeps/quick-work-precision.toml"),
    ("serial robots", ("UR5-FALL", "PANDA-FALL"), ("quick-work-precision-robots",),
     "sweeps/quick-work-precision-robots.toml"),
    ("a floating humanoid", ("TALOS-FALL",), ("quick-work-precision-robots", "quick-scenarios"),
     "sweeps/quick-work-precision-robots.toml"),
    ("linkages (closed loops)", ("FOUR-BAR", "JANSEN-LEG"), ("quick-scenarios",),
     "sweeps/quick-scenarios.toml"),
)
COLUMNS = ["family", "system", "accuracy [m]", "cheapest that reaches it", "its cost",
           "the core's cheapest", "the best engine's cheapest", "core's lead",
           "not reached (the best error each got [m])"]


@dataclass
class Choice:
    """A run row that reaches an accuracy, its Cost, and the rows indistinguishable from it."""

    row: pd.Series
    cost: C.Cost
    tied: list[pd.Series] = field(default_factory=list)

    @property
    def error(self) -> float:
        return float(self.row["max_tip_err"])


@dataclass
class Answer:
    """The trade at one accuracy (module docstring)."""

    accuracy: float
    cheapest: Choice | None
    core: Choice | None
    engine: Choice | None
    not_reached: dict[str, float]  # engine -> the least error of its finished runs
    never_ran: list[str]  # engines with runs, none finished

    @property
    def lead(self) -> float:
        """The best engine's cost over the core's (nan: either reaches nothing)."""
        if self.core is None or self.engine is None or self.core.cost.value <= 0:
            return math.nan
        return self.engine.cost.value / self.core.cost.value

    @property
    def lead_verdict(self) -> str:
        """compare_two of the core against the best engine: "cheaper", "dearer" or
        "indistinguishable" ("" when either reaches nothing)."""
        if self.core is None or self.engine is None:
            return ""
        return C.compare_two(self.core.cost, self.engine.cost)


def setting(r) -> str:
    """'ode45 rtol 1e-07' or 'native:euler h 0.001' of a run row."""
    h = float(r["h"])
    return f"{r['integrator']} " + (f"h {h:g}" if h > 0 else f"rtol {float(r['rtol']):g}")


def choice_text(r) -> str:
    """'mujoco native:euler h 0.001' (the core's method too when it is not RGE-A)."""
    who = str(r["engine"])
    method = str(r.get("method", "") or "")
    if who == CORE and method not in ("", "rge-a"):
        who += f"/{method}"
    return f"{who} {setting(r)}"


def cost_text(c: C.Cost) -> str:
    """'0.95 ms +-10% (20 runs)'."""
    u = C.uncertainty(c.repeats, c.spread)
    v = c.value
    amount = f"{v:.3g} s" if v >= 1 else f"{v * 1e3:.3g} ms"
    return f"{amount} +-{u:.0%} ({c.repeats} run{'s' if c.repeats > 1 else ''})"


def _cheapest(rows: pd.DataFrame) -> Choice | None:
    items = [r for _, r in rows.iterrows()]
    costs = [C.cost_of(r) for r in items]
    ranking = C.rank(costs)
    if ranking is None:
        return None
    return Choice(items[ranking.pick], costs[ranking.pick],
                  [items[i] for i in ranking.indistinguishable])


def _errors(runs: pd.DataFrame) -> pd.Series:
    return pd.to_numeric(runs["max_tip_err"], errors="coerce") if "max_tip_err" in runs \
        else pd.Series(math.nan, index=runs.index)


def answer(runs: pd.DataFrame, accuracy: float) -> Answer:
    """The trade at ``accuracy`` among ``runs`` (rows of one system: case and horizon)."""
    err = _errors(runs)
    done = runs[(runs["status"] == "ok") & err.notna()]
    within = done[_errors(done) <= accuracy]
    not_reached = {}
    for engine, g in done.groupby("engine", sort=True):
        if not (_errors(g) <= accuracy).any():
            not_reached[str(engine)] = float(_errors(g).min())
    never = sorted({str(e) for e in runs["engine"]} - {str(e) for e in done["engine"]})
    best = _cheapest(within)
    core = _cheapest(within[within["engine"] == CORE])
    engine = _cheapest(within[within["engine"] != CORE])
    # the overall pick is its side's pick too (rank's tie-break by work applies only where every
    # run of a group has it, so a side ranked alone may pick another run of the same group)
    if best is not None and best.row["engine"] == CORE:
        core = best
    elif best is not None:
        engine = best
    return Answer(accuracy, best, core, engine, not_reached, never)


def trade(runs: pd.DataFrame, accuracies=ACCURACIES) -> list[Answer]:
    """:func:`answer` at each accuracy."""
    return [answer(runs, a) for a in accuracies]


def _lead_text(a: Answer) -> str:
    if a.core is None and a.engine is None:
        return "nothing reaches it"
    if a.engine is None:
        return "no engine reaches it"
    if a.core is None:
        return "the core does not reach it"
    verdict = a.lead_verdict
    return f"x{a.lead:.3g}" + (" (indistinguishable)" if verdict == C.INDISTINGUISHABLE else
                               "" if verdict == "cheaper" else " (the engine is cheaper)")


def _not_reached_text(a: Answer) -> str:
    parts = [f"{e}: not reached (best {v:.1e})" for e, v in a.not_reached.items()]
    parts += [f"{e}: no run finished" for e in a.never_ran]
    return "; ".join(parts) or "every engine reaches it"


def answer_cells(a: Answer) -> list[str]:
    """The cells from "accuracy" on (COLUMNS[2:])."""
    best = a.cheapest
    if best is None:
        pick = "not reached by any run"
    else:
        named = "; ".join(choice_text(r) for r in best.tied[:TIED_NAMED])
        more = len(best.tied) - TIED_NAMED
        pick = choice_text(best.row) + (f" (indistinguishable from {len(best.tied)} other"
                                        f"{'s' if len(best.tied) > 1 else ''}: {named}"
                                        + (f" and {more} more" if more > 0 else "") + ")"
                                        if best.tied else "")
    return [f"{a.accuracy:g}", pick, cost_text(best.cost) if best else "",
            f"{choice_text(a.core.row)}, {cost_text(a.core.cost)}" if a.core else
            "not reached",
            f"{choice_text(a.engine.row)}, {cost_text(a.engine.cost)}" if a.engine else
            "not reached",
            _lead_text(a), _not_reached_text(a)]


def trade_table(runs: pd.DataFrame, tid: str = "trade", title: str = "The trade",
                accuracies=ACCURACIES) -> Table:
    """One system's trade (``redysim compare``'s page): a row per accuracy."""
    t = Table(tid, title, COLUMNS[2:], notes=[NOTE])
    for a in trade(runs, accuracies):
        t.rows.append(Row(answer_cells(a), INFO if a.cheapest else NOT_RUN))
    return t


NOTE = ("Accuracy: the largest distance of the observed frame (the tip, or the scenario's frame) "
        "from the reference solution over the samples. Cost: the integration's CPU time, the "
        "least of repeated runs, sampling, JIT compile and engine build excluded, with its "
        "uncertainty (the repeats' spread, at least 10%; 25% for a run measured once); runs "
        "whose cost intervals overlap are indistinguishable (redysim.harness.cost). The core's "
        "lead: the best engine's cost over the core's, both the cheapest run of each that reaches "
        "the accuracy. Not reached: an engine (adapter) none of whose finished runs is within "
        "it, with the least error it got over every setting run.")


# --------------------------------------------------------------------------- the report's
def _planned(res, sweep: str) -> int | None:
    """How many runs the sweep folder's plan (sweep.json) has (None: no plan)."""
    plan = res.sweep_plan(sweep)
    return None if plan is None else len(plan)


def _systems(runs: pd.DataFrame, cases, sweeps) -> list[tuple[str, float, pd.DataFrame]]:
    """(case, horizon, its runs) of the families' runs measured against a reference."""
    sel = runs[runs["case"].isin(cases) & runs["sweep"].isin(sweeps)]
    sel = sel[_errors(sel).notna() | (sel["status"] != "ok")]
    out = []
    for case in cases:
        c = sel[sel["case"] == case]
        for horizon, g in c.groupby("horizon", sort=True):
            if _errors(g).notna().any():
                out.append((case, float(horizon), g))
    return out


def headline_trade(res) -> Headline:
    """The report's first card: over the families' systems and the accuracies, how often the
    core's cheapest run is the cheapest of all, its lead over the best engine (least and most,
    and how many leads are within the noise), and how many engines do not reach an accuracy."""
    runs = res.runs
    answers = []
    if len(runs) and "sweep" in runs:
        for _family, cases, sweeps, _source in FAMILIES:
            for _case, _horizon, g in _systems(runs, cases, sweeps):
                answers += trade(g)
    reached = [a for a in answers if a.cheapest is not None]
    if not reached:
        return Headline("the trade", "no results", "make reproduce runs the families' "
                        "work-precision sweeps", NOT_RUN)
    core_first = sum(1 for a in reached if a.cheapest.row["engine"] == CORE)
    leads = [a for a in reached if math.isfinite(a.lead)]
    noise = sum(1 for a in leads if a.lead_verdict == C.INDISTINGUISHABLE)
    missed = sum(len(a.not_reached) for a in answers)
    detail = (f"over {len({(a.cheapest.row['case']) for a in reached})} systems at path error "
              + ", ".join(f"{x:g}" for x in ACCURACIES) + " m")
    if leads:
        lo, hi = min(a.lead for a in leads), max(a.lead for a in leads)
        detail += (f"; the core's lead over the best engine x{lo:.2g} to x{hi:.2g}"
                   + (f" ({noise} of {len(leads)} within the noise)" if noise else ""))
    if missed:
        detail += (f"; not reached {missed} times (an engine, or the core, at an accuracy: "
                   "the table names each)")
    return Headline("the trade (first section)",
                    f"the core cheapest in {core_first} of {len(reached)}", detail + ".")


def trade_section(res) -> Section:
    """The report's first section: the trade per system family (module docstring)."""
    sec = Section("trade", "The trade: the cheapest engine and setting for each accuracy")
    sec.intro.append(
        "For each system family the quick reproduction measures against a reference solution: "
        "at each accuracy (path error " + ", ".join(f"{a:g}" for a in ACCURACIES) + " m), "
        "the cheapest run of any engine and integrator that reaches it, the core's cheapest "
        "and the best engine's, the core's lead (the engine's cost over the core's) and the "
        "engines that do not reach it at all. Every value is computed from the results folder; "
        "the work-precision figures below show every run.")
    t = Table("trade", "The trade, per system family", COLUMNS, notes=[NOTE])
    runs = res.runs
    used = []
    for family, cases, sweeps, source in FAMILIES:
        systems = _systems(runs, cases, sweeps) if len(runs) and "sweep" in runs else []
        if not systems:
            t.rows.append(Row([family, ", ".join(cases), "", "no results", "", "", "", "",
                               f"not run: make reproduce ({source})"], NOT_RUN))
            continue
        for case, horizon, g in systems:
            used.append(g)
            partial = []
            for sweep in sorted(set(g["sweep"])):
                planned = _planned(res, sweep)
                have = int((runs["sweep"] == sweep).sum())
                if planned is not None and have < planned:
                    partial.append(f"{sweep}: {have} of {planned} runs")
            name = f"{case}, {horizon:g} s" + (f" (partial sweep: {'; '.join(partial)})"
                                               if partial else "")
            for a in trade(g):
                kind = PARTIAL if partial else (INFO if a.cheapest else NOT_RUN)
                t.rows.append(Row([family, name, *answer_cells(a)], kind))
    t.rows.extend(_mega_rows(res))
    t.provenance = provenance_line(pd.concat(used) if used else None, what="results/sweeps")
    t.notes.append("A sweep whose folder holds fewer finished runs than its plan is marked "
                   "partial: its answer may change when the rest run.")
    sec.items.append(t)
    return sec


def _mega_rows(res) -> list[Row]:
    """The 1,000,000-DOF rod: what quick mode measures of it (the core's implicit long run)."""
    from .implicit import MEGA, MEGA_FILE, _runs, tip_distance

    family = "the 1,000,000-DOF rod"
    runs = _runs(res, MEGA)
    if runs.empty:
        return [Row([family, MEGA, "", "no results", "", "", "", "",
                     f"not run: make reproduce (python -m redysim.harness.longrun "
                     f"cases/{MEGA_FILE} --integrator implicit)"], NOT_RUN)]
    rows = []
    ref = runs[runs["integrator"] == "ode45"].sort_values("t_reached")
    ref_s = res.samples(ref.iloc[-1]["run_id"]) if len(ref) else None
    for _, r in runs[runs["integrator"] != "ode45"].iterrows():
        measured = "its error is not measured: no ode45 run of this size in this results " \
                   "folder (make reproduce-full runs one to 0.01 s)"
        if ref_s is not None:
            d = tip_distance(res.samples(r["run_id"]), ref_s)
            if len(d) > 1:
                measured = (f"tip within {d['distance'].max():.1e} m of ode45's to t = "
                            f"{d['t'].max():.3g} s (ode45, not a converged reference)")
        status = "" if r["status"] == "ok" else f" ({r['status']})"
        rows.append(Row([family, f"{MEGA}, {float(r['t_reached']):.3g} of "
                         f"{float(r['t_end']):g} s{status}", "not measured",
                         f"{CORE} {setting(r)} (the only run)",
                         f"{float(r['cpu_s']):.3g} s of CPU (one run)",
                         f"{CORE} {setting(r)}", "no engine runs at this size", "",
                         measured + "; no engine is run at 1,000,000 DOF (their limits: "
                         "'Engine limits' below)"], PARTIAL))
    return rows
