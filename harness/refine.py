"""Model size against accuracy: refinement studies, their observed orders, and advice.

A refinement study is one physical rope at several link counts (a fine case file, coarse-grained
by :func:`redysim.coarsen` through ``RunSpec.links``), each integrated at several tolerances:
``sweeps/refine-*.toml``. This module reads a study's results and measures, per run, the tip-path
error against the study's reference (the finest model at the tightest tolerance, DOP853 at
1e-10): the largest distance between the two tips over the samples. From that:

- the error against the link count at the tightest tolerance, its observed order p (the slope of
  log error against log links, error ~ C links^-p, fitted on the levels at most a quarter of the
  finest, where the finest model's own error biases the difference by at most 4^-p), and the
  Richardson-extrapolated tip position at the horizon from the two finest levels;
- :func:`advise`: for a tip-path tolerance, the run that meets it at the least cost (measured
  CPU by default; RHS calls or steps, which no machine's noise changes, on request): the
  coarsest model and cheapest integrator setting, from measured data;
- :func:`check_advice`: runs the advised model afresh and compares it with the study's reference
  and with a model twice as fine as the finest, by DOP853 at 1e-8 (so that the advice is checked
  against a reference it was not chosen with).

The hanging chain's small oscillations need no time integration: :func:`hanging_modes` linearises
a planar chain about its straight hanging state, and :func:`modes_study` compares its frequencies
at every level with the continuum's, omega_k = (z_k / 2) sqrt(g / L) (z_k: zeros of J0).

    python -m redysim.harness.refine [--quick] [--out DIR]   # all scenes, then the JSON summary
"""

from __future__ import annotations

import argparse
import json
import math
import time
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path

import numpy as np
import pandas as pd

from redysim import coarsen, load_case, mass_matrix
from redysim.io.cases import CASES_DIR, case_with_links, read_toml

from .provenance import provenance
from .store import write_json_atomic

SWEEPS = Path(str(resources.files("redysim.sweep_files")))  # package data
# scene -> its sweep file's stem. The falling chain is two scenes: its smooth fall (to 0.4 s),
# and through the whip (to 0.8 s), whose continuum limit is singular: the tip speed grows with
# the link count, and the path after it does not converge pointwise.
SCENES = {"spin": "refine-spin", "fall": "refine-fall", "whip": "refine-whip",
          "pulled": "refine-pulled"}
SCENE_TITLES = {
    "spin": "Spinning rope (RE-U125-L1's rod), falling: 0 to 0.4 s",
    "fall": "Chain released from horizontal: the fall (0 to 0.4 s)",
    "whip": "Chain released from horizontal: through the whip (0 to 0.8 s)",
    "pulled": "Hanging chain with a hook, pulled at the hook: 0 to 1 s",
    "hanging": "Small oscillations of a hanging chain (modes)",
}
HANGING_CASE = CASES_DIR / "refine" / "hanging-R1024.toml"
HANGING_LEVELS = (1024, 512, 256, 128, 64, 32, 16, 8, 4, 2)
N_MODES = 5
ORDER_FRACTION = 4  # fit the order on levels at most finest / 4
# DOP853's tolerance for the rope at twice the finest's links (the advice's second check): at
# 1e-10 the 500-link spinning rod took 5 minutes here; on the finest models 1e-8 is within 1e-13 m
# of 1e-10 before a whip (each study measures and reports it: rtol_error_on_finest)
FINER_RTOL = 1e-8
ADVICE_TOLERANCES = {"spin": (1e-2, 1e-3), "fall": (1e-2, 1e-3), "whip": (5e-2,),
                     "pulled": (1e-2, 1e-3)}
RESULTS_FILE = "refine.json"
# advise's measures of a run's cost: columns of the runs, and "work", RHS calls x links (the
# O(n) recursions' work: no machine's load changes it, and it compares models of any size)
COSTS = ("cpu_s", "nfev", "steps", "work")


class StudyError(Exception):
    """A study's results cannot be read as a refinement study (named: folder and why)."""


# --------------------------------------------------------------------------- reading a study
def study_folder(results: Path, scene: str) -> Path:
    """Where a scene's sweep writes: ``results/refine/<sweep name without refine->``."""
    return Path(results) / "refine" / SCENES[scene].removeprefix("refine-")


@dataclass
class Study:
    """A refinement study's runs with their errors. ``runs``: one row per run (the sweep's
    summary columns plus ``tip_err`` [m], the max tip distance to the reference over the samples,
    and ``end_tip_err`` at the horizon); ``reference``: the reference run's row; ``tips``:
    run_id -> (m, 3) tip positions at the samples; ``t``: the sample times."""

    scene: str
    case: str
    runs: pd.DataFrame
    reference: pd.Series
    tips: dict
    t: np.ndarray
    folder: Path


def load_study(out_dir: str | Path, scene: str = "") -> Study:
    """Read a finished refinement sweep's folder (runs.parquet and samples.parquet, made by
    :func:`redysim.harness.sweep.collect`)."""
    from .sweep import collect

    out = Path(out_dir)
    if not (out / "runs").is_dir():
        raise StudyError(f"{out}: no runs/ folder: not a sweep's results (run the study's sweep "
                         "first, e.g. redysim sweep sweeps/refine-fall.toml --out DIR)")
    runs = collect(out)
    samples = pd.read_parquet(out / "samples.parquet")
    ok = runs[runs["status"] == "ok"]
    if ok.empty:
        raise StudyError(f"{out}: no finished run")
    if runs["case"].nunique() > 1:
        raise StudyError(f"{out}: runs of {runs['case'].nunique()} cases; a refinement study is "
                         "one case at several link counts")
    full = ok[(ok["precision"] == "float64") & (ok["n_links"] == ok["n_links"].max())]
    ref = full.sort_values(["rtol", "integrator"], ascending=[True, True]).iloc[0]
    by_run = {k: g.sort_values("t") for k, g in samples.groupby("run_id")}
    t = by_run[ref["run_id"]]["t"].to_numpy()
    tips = {k: g[["tip_x", "tip_y", "tip_z"]].to_numpy() for k, g in by_run.items()}
    speeds = {k: float(np.linalg.norm(g[["tip_vx", "tip_vy", "tip_vz"]].to_numpy(),
                                      axis=1).max()) for k, g in by_run.items()}
    ref_tip = tips[ref["run_id"]]
    errs, ends = [], []
    for _, row in runs.iterrows():
        tip = tips.get(row["run_id"])
        if row["status"] != "ok" or tip is None or tip.shape != ref_tip.shape:
            errs.append(math.nan)
            ends.append(math.nan)
            continue
        d = np.linalg.norm(tip - ref_tip, axis=1)
        errs.append(float(d.max()))
        ends.append(float(d[-1]))
    runs = runs.assign(tip_err=errs, end_tip_err=ends,
                       peak_tip_speed=[speeds.get(i, math.nan) for i in runs["run_id"]])
    ref = runs[runs["run_id"] == ref["run_id"]].iloc[0]
    return Study(scene, str(ref["case"]), runs, ref, tips, t, out)


def convergence(study: Study) -> dict:
    """Error against links at the tightest tolerance of each level (float64; ode45 and DOP853
    both, the smaller error kept per level), the observed order and the Richardson-extrapolated
    tip position at the horizon."""
    r = study.runs
    ok = r[(r["status"] == "ok") & (r["precision"] == "float64")]
    ok = ok[ok["run_id"] != study.reference["run_id"]]
    finest = int(study.reference["n_links"])
    levels = []
    for n, g in ok.groupby("n_links"):
        tight = g[g["rtol"] == g["rtol"].min()].sort_values("tip_err").iloc[0]
        levels.append({"links": int(n), "tip_err": float(tight["tip_err"]),
                       "peak_tip_speed": float(tight["peak_tip_speed"]),
                       "end_tip_err": float(tight["end_tip_err"]), "rtol": float(tight["rtol"]),
                       "integrator": tight["integrator"], "cpu_s": float(tight["cpu_s"]),
                       "model_mib": float(tight["model_mib"]), "run_id": tight["run_id"]})
    levels.sort(key=lambda d: d["links"])
    fit = [d for d in levels if d["links"] * ORDER_FRACTION <= finest and d["tip_err"] > 0]
    order = math.nan
    if len(fit) >= 2:
        x = np.log([d["links"] for d in fit])
        y = np.log([d["tip_err"] for d in fit])
        order = float(-np.polyfit(x, y, 1)[0])
    # Richardson: Q_inf = Q_f + (Q_f - Q_c) / (r^p - 1), Q = tip at the horizon
    rich = None
    coarser = [d for d in levels if d["links"] < finest]
    if coarser and math.isfinite(order) and order > 0:
        c = coarser[-1]
        ratio = finest / c["links"]
        q_f = study.tips[study.reference["run_id"]][-1]
        q_c = study.tips[c["run_id"]][-1]
        q_inf = q_f + (q_f - q_c) / (ratio ** order - 1.0)
        rich = {"from_links": [c["links"], finest], "tip_end": q_inf.tolist(),
                "finest_tip_end": q_f.tolist(),
                "finest_error_estimate": float(np.linalg.norm(q_inf - q_f))}
    return {"finest": finest, "finest_peak_tip_speed": float(study.reference["peak_tip_speed"]),
            "t_end": float(study.t[-1]), "levels": levels, "order": order,
            "order_levels": [d["links"] for d in fit], "richardson": rich}


# --------------------------------------------------------------------------- advice
@dataclass
class Advice:
    """The cheapest measured run that met a tip-path tolerance, and what the finest model cost
    for the same tolerance."""

    scene: str
    tol: float
    links: int
    integrator: str
    rtol: float
    tip_err: float
    cpu_s: float
    steps: int
    finest_links: int
    finest_cpu_s: float  # the cheapest run of the finest model that meets tol (nan: none does)
    finest_rtol: float
    candidates: int  # runs that met tol
    # the runs whose measured cost cannot be told from the advised run's
    # (redysim.harness.cost: their cost intervals overlap; "cpu_s" ranking only): "links
    # integrator rtol", cheapest first
    indistinguishable: tuple[str, ...] = ()

    @property
    def saved(self) -> float:
        """CPU of the finest model's cheapest run meeting tol, over the advised run's."""
        return self.finest_cpu_s / self.cpu_s if self.cpu_s > 0 else math.nan


def advise(study: Study, tol: float, *, precision: str = "float64",
           cost: str = "cpu_s") -> Advice | None:
    """The coarsest model and cheapest integrator setting, from measured data, whose tip path
    stays within ``tol`` [m] of the reference's: of the study's runs that met ``tol``, the one
    of least ``cost`` (a column of the runs: ``"cpu_s"``, the measured CPU time, by default,
    ranked by :mod:`redysim.harness.cost`: the integration's least CPU of repeats, sampling
    excluded, with its uncertainty, the runs it cannot tell from the pick listed in
    ``Advice.indistinguishable`` and the pick among them the one of least work;
    ``"nfev"`` or ``"steps"`` count work without the machine's noise, ``"work"`` RHS calls x
    links, across models of different sizes too), ties broken by fewer
    links, then by the run id. None when no run met it. Raises SettingsError for a ``tol`` that
    is not a distance > 0, a ``precision`` not in the study's runs' or an unknown ``cost``."""
    from redysim.errors import SettingsError

    from .spec import PRECISIONS

    if isinstance(tol, bool) or not isinstance(tol, int | float) or not tol > 0 or \
            not math.isfinite(tol):
        raise SettingsError("advise", "tol", _shown(tol), "must be a tip distance > 0 [m] "
                            "(finite)")
    if precision not in PRECISIONS:
        raise SettingsError("advise", "precision", precision,
                            f"choose one of {', '.join(PRECISIONS)}")
    if cost not in COSTS:
        raise SettingsError("advise", "cost", cost, f"choose one of {', '.join(COSTS)}")
    r = study.runs.assign(work=study.runs["nfev"] * study.runs["n_links"])
    ok = r[(r["status"] == "ok") & (r["precision"] == precision)
           & (r["run_id"] != study.reference["run_id"]) & (r["tip_err"] <= tol)]
    if ok.empty:
        return None
    tied: tuple[str, ...] = ()
    if cost == "cpu_s":
        from . import cost as costs

        ok = ok.sort_values(["n_links", "run_id"])
        rows = [r for _, r in ok.iterrows()]
        ranking = costs.rank([costs.cost_of(r) for r in rows])
        best = rows[ranking.pick] if ranking is not None else ok.iloc[0]
        if ranking is not None:
            tied = tuple(f"{int(rows[i]['n_links'])} links {rows[i]['integrator']} rtol "
                         f"{float(rows[i]['rtol']):g}"
                         for i in sorted(ranking.indistinguishable,
                                         key=lambda i: ranking.costs[i].value))
        fine_rows = [r for r in rows if int(r["n_links"]) == int(study.reference["n_links"])]
        fr = costs.rank([costs.cost_of(r) for r in fine_rows])
        fine = pd.DataFrame([fine_rows[fr.pick]]) if fr is not None else ok.iloc[:0]
        finest = int(study.reference["n_links"])
    else:
        best = ok.sort_values([cost, "n_links", "run_id"]).iloc[0]
        finest = int(study.reference["n_links"])
        fine = ok[ok["n_links"] == finest].sort_values([cost, "run_id"])
    from .cost import cost_of  # the integration's cost (cpu_s for rows from before it)

    return Advice(study.scene, float(tol), int(best["n_links"]), str(best["integrator"]),
                  float(best["rtol"]), float(best["tip_err"]), cost_of(best).value,
                  int(best["steps"]), finest,
                  cost_of(fine.iloc[0]).value if len(fine) else math.nan,
                  float(fine["rtol"].iloc[0]) if len(fine) else math.nan, int(len(ok)), tied)


def finer_case(case_file: str | Path, factor: int):
    """The case's rope with ``factor`` times as many links (its [chain] links multiplied): the
    same physical rope at a finer discretisation, for checking advice against a reference it was
    not chosen with. The case's initial state must not depend on the link count (true of the
    refinement scenes: a first-joint angle or rate, the rest zero)."""
    doc = read_toml(case_file)[0]
    return case_with_links(case_file, int(doc["chain"]["links"]) * factor,
                           f"{doc['case']['name']}x{factor}", f"{case_file} (links x {factor})")


def _tips(case, links: int, integrator: str, rtol: float, atol: float, t_end: float,
          sample: float, *, compiled: bool = False):
    """Integrate ``case`` (coarse-grained to ``links``) and return (tips, cpu_s, steps);
    ``compiled``: step in compiled code where the case allows it (no tip force), else the
    Python loop (the same steps: an independent path for checking the sweep's runs)."""
    from redysim.simulation import frame_observer

    from .run import coarse_case

    case, _ = coarse_case(case, links)
    sim = case.simulator(t_end, integrator=integrator, rtol=rtol, atol=atol, sample=sample,
                         observe={"tip": frame_observer(case.chain, "tip")},
                         keep_states=False, compiled=None if compiled else False)
    res = sim.run(clock="process")
    if res.status != 0:
        raise RuntimeError(f"{case.name} at {links} links: {res.message}")
    return res.observed["tip"][:, :3], res.cpu_s, res.steps


def finer_reference(study: Study, finer: int = 2) -> dict:
    """The study's rope at ``finer`` times the finest model's links, integrated by DOP853 at
    :data:`FINER_RTOL` over the study's horizon and samples: a reference the advice was not
    chosen with. Also the study's own measure of what that tolerance costs in accuracy: the
    finest model's DOP853 run at FINER_RTOL against the reference (1e-10)."""
    ref = study.reference
    out = finer_tips(study.case, float(ref["t_end"]), float(ref["sample"]), finer)
    out["rtol_error_on_finest"] = _rtol_error_on_finest(study)
    return out


def _rtol_error_on_finest(study: Study) -> float:
    """The finest model's DOP853 run at FINER_RTOL against the reference (nan: none)."""
    ref, r = study.reference, study.runs
    same = r[(r["n_links"] == ref["n_links"]) & (r["integrator"] == "dop853")
             & (r["rtol"] == FINER_RTOL) & (r["precision"] == "float64")]
    return float(same["tip_err"].iloc[0]) if len(same) else math.nan


def finer_tips(case_file: str, t_end: float, sample: float, finer: int = 2) -> dict:
    """The tip path of the case's rope at ``finer`` times its links, DOP853 at FINER_RTOL (a
    plain function of plain arguments, for a process pool)."""
    fine_case = finer_case(case_file, finer)
    tips, cpu, steps = _tips(fine_case, fine_case.chain.n_links, "dop853", FINER_RTOL,
                             FINER_RTOL * 1e-2, t_end, sample, compiled=True)
    return {"links": int(fine_case.chain.n_links), "tips": tips, "cpu_s": cpu, "steps": steps,
            "rtol": FINER_RTOL}


def check_advice(study: Study, advice: Advice, finer: dict | None = None) -> dict:
    """Run the advised model afresh (the Python stepping loop, not the sweep's compiled one) and
    measure its tip-path error against the study's reference and against ``finer`` (from
    :func:`finer_reference`; computed here when not given)."""
    ref = study.reference
    case = load_case(study.case)
    t_end, sample = float(ref["t_end"]), float(ref["sample"])
    tips, cpu, steps = _tips(case, advice.links, advice.integrator, advice.rtol,
                             advice.rtol * 1e-2, t_end, sample)
    ref_tip = study.tips[ref["run_id"]]
    finer = finer or finer_reference(study)
    fine_tip, fine_cpu = finer["tips"], finer["cpu_s"]
    fine_case_links = finer["links"]
    return {"scene": study.scene, "tol": advice.tol, "links": advice.links,
            "integrator": advice.integrator, "rtol": advice.rtol,
            "error_vs_finest": float(np.linalg.norm(tips - ref_tip, axis=1).max()),
            "finer_links": fine_case_links,
            "error_vs_finer": float(np.linalg.norm(tips - fine_tip, axis=1).max()),
            "finest_vs_finer": float(np.linalg.norm(ref_tip - fine_tip, axis=1).max()),
            "cpu_s": cpu, "steps": int(steps), "sweep_cpu_s": advice.cpu_s,
            "finest_cpu_s": advice.finest_cpu_s, "finer_cpu_s": fine_cpu,
            "finer_rtol": finer["rtol"],
            "finer_rtol_error_on_finest": finer["rtol_error_on_finest"]}


def float32_pairs(study: Study) -> list[dict]:
    """Each float32 run beside its float64 twin (same links, integrator and tolerances): both
    errors against the reference, the distance between their tip paths, and their steps."""
    r = study.runs
    out = []
    for _, a in r[r["precision"] == "float32"].iterrows():
        twin = r[(r["precision"] == "float64") & (r["n_links"] == a["n_links"])
                 & (r["integrator"] == a["integrator"]) & (r["rtol"] == a["rtol"])]
        b = twin.iloc[0] if len(twin) else None
        apart = math.nan
        if b is not None and a["status"] == "ok" and b["status"] == "ok":
            ta, tb = study.tips.get(a["run_id"]), study.tips.get(b["run_id"])
            if ta is not None and tb is not None and ta.shape == tb.shape:
                apart = float(np.linalg.norm(ta - tb, axis=1).max())
        out.append({"links": int(a["n_links"]), "integrator": a["integrator"],
                    "rtol": float(a["rtol"]), "status": a["status"],
                    "reason": a["reason"], "t_reached": float(a["t_reached"]),
                    "tip_err32": _plain(float(a["tip_err"])),
                    "tip_err64": None if b is None else _plain(float(b["tip_err"])),
                    "apart": _plain(apart), "steps32": int(a["steps"]),
                    "steps64": None if b is None else int(b["steps"]),
                    "cpu32_s": float(a["cpu_s"]),
                    "cpu64_s": None if b is None else float(b["cpu_s"])})
    return out


# --------------------------------------------------------------------------- a user's rope
OWN_REFERENCE = ("dop853", 1e-10)  # the user's model at this setting: the study's reference
OWN_LEVEL = ("ode45", 1e-8)        # each coarser model at this setting: its model error
OWN_RTOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7)  # the settings tried on the models that meet tol
OWN_INTEGRATORS = ("ode45", "dop853")
MIN_LEVEL_RATIO = 1.8  # consecutive coarse levels at least this far apart in link count
STEADY = 0.25          # the last two local orders within this fraction of each other: steady
MIN_ORDER = 0.3        # below this the error does not fall with the links: no convergence


def coarse_levels(links: int) -> list[int]:
    """The coarser models of a study: divisors d of ``links`` (2 <= d < links, a coarse link
    lumps the same number of fine ones), finest first, each at most 1/MIN_LEVEL_RATIO of the
    one before it (the user's model the first)."""
    out, last = [], links
    for d in range(links - 1, 1, -1):
        if links % d == 0 and last / d >= MIN_LEVEL_RATIO:
            out.append(d)
            last = d
    return out


def rebuilt_levels(links: int) -> list[int]:
    """The coarser models of a straight rope whose count has no divisor (:func:`coarse_levels`
    empty): the rope rebuilt at counts spaced as the divisors are (each at most
    1/MIN_LEVEL_RATIO of the one before it, from the user's), or the next count down when none
    is so far; at least 2 links."""
    out, last = [], links
    for d in range(links - 1, 1, -1):
        if last / d >= MIN_LEVEL_RATIO:
            out.append(d)
            last = d
    return out or ([links - 1] if links > 2 else [])


def local_orders(levels: list[dict]) -> list[float]:
    """The order between each two consecutive levels (coarse to fine, ``convergence``'s),
    log(e_coarse / e_fine) / log(n_fine / n_coarse); nan where an error is 0 or missing."""
    out = []
    for a, b in zip(levels, levels[1:], strict=False):
        ea, eb = a["tip_err"], b["tip_err"]
        ok = ea > 0 and eb > 0 and math.isfinite(ea) and math.isfinite(eb)
        out.append(math.log(ea / eb) / math.log(b["links"] / a["links"]) if ok else math.nan)
    return out


def three_level_order(n1: int, n2: int, n3: int, d12: float, d23: float) -> float:
    """The order p with which errors C n^-p give the differences d12 between n1 and n2 links and
    d23 between n2 and n3 (n1 < n2 < n3): the root of (n1^-p - n2^-p) / (n2^-p - n3^-p) =
    d12 / d23, by bisection on (0, 16]; 0 when the differences do not shrink fast enough for
    any p > 0 (their ratio at most its limit ln(n2/n1) / ln(n3/n2) as p -> 0), nan when a
    difference is not a positive number."""
    if not (d12 > 0 and d23 > 0 and math.isfinite(d12) and math.isfinite(d23)):
        return math.nan
    target = d12 / d23

    def ratio(p):
        return (n1 ** -p - n2 ** -p) / (n2 ** -p - n3 ** -p)

    if target <= math.log(n2 / n1) / math.log(n3 / n2):
        return 0.0
    lo, hi = 1e-9, 16.0
    if target >= ratio(hi):
        return hi
    for _ in range(200):  # ratio rises with p
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if ratio(mid) < target else (lo, mid)
    return 0.5 * (lo + hi)


def verdict(levels: list[dict]) -> tuple[list[float], bool, bool]:
    """(local orders, converges, steady) of a study's levels (coarse to fine): it converges when
    every finer level's error is smaller and the last local orders are at least MIN_ORDER; its
    order is steady when the last two agree within STEADY (relative)."""
    orders = local_orders(levels)
    errs = [d["tip_err"] for d in levels]
    falls = all(a > b for a, b in zip(errs, errs[1:], strict=False))
    last = orders[-2:]
    converges = bool(falls and last and all(math.isfinite(o) and o >= MIN_ORDER for o in last))
    steady = bool(converges and len(last) == 2
                  and abs(last[0] - last[1]) <= STEADY * max(last))
    return orders, converges, steady


@dataclass
class OwnStudy:
    """A study :func:`own_study` ran on a user's rope, and what it concluded.

    ``ref_error``: the estimated tip-path error of the user's model (the reference) itself,
    ``ref_error_how`` says how (Richardson from a steady order, or a model of twice the
    links); ``advice`` (None: none met the tolerance, ``notes`` say why) for a tip path within
    ``tol - ref_error`` of the reference, so within ``tol`` of the converged path;
    ``check``: the advised run done afresh (Python stepping loop) against the reference;
    ``searched``: the counts between two levels the rope was rebuilt at, in the order tried,
    with their model errors (``links``, ``tip_err``)."""

    case: str
    tol: float
    study: Study
    conv: dict
    orders: list
    converges: bool
    ref_error: float
    ref_error_how: str
    advice: Advice | None
    check: dict | None
    notes: list
    searched: list = field(default_factory=list)  # the rebuilt counts bisected: links, tip_err


def _tip_error(out: Path, scene: str, run_id: str) -> float:
    """A finished run's tip-path error against its study's reference (max over the samples)."""
    runs = load_study(out, scene).runs
    return float(runs.loc[runs["run_id"] == run_id, "tip_err"].iloc[0])


def _refined(case_file: str, case, factor: int = 2):
    """The case at ``factor`` times its links, or (None, why) when it cannot be refined into
    the same physical rope (its file does not give a link count to multiply, or its initial
    state depends on the link count: mapped back, it is not the case's own)."""
    from redysim.algorithms.coarse import coarsen
    from redysim.errors import CaseError

    try:
        fine = finer_case(case_file, factor)
    except (CaseError, KeyError, TypeError, ValueError) as exc:
        return None, f"its file cannot be refined ({exc})"
    back = coarsen(fine.chain, links=case.chain.n_links)
    q0, v0 = back.to_coarse(fine.q0, fine.v0)
    off = max(float(np.abs(q0 - case.q0).max()), float(np.abs(v0 - case.v0).max()))
    if off > 1e-9:
        return None, (f"its initial state depends on the link count (the refined rope's, "
                      f"mapped back, is {off:.2g} off its own): a finer model would be another "
                      "motion")
    return fine, ""


def own_study(case_file: str | Path, tol: float, out: str | Path, *, t_end: float = 0.0,
              workers: int | None = None, progress: bool = True, check: bool = True,
              log=print) -> OwnStudy:
    """:func:`_own_study`, its several sweeps on one pool of ``workers`` processes
    (:func:`redysim.harness.sweep.shared_pool`)."""
    from .sweep import shared_pool

    with shared_pool(workers):
        return _own_study(case_file, tol, out, t_end=t_end, workers=workers, progress=progress,
                          check=check, log=log)


def _own_study(case_file: str | Path, tol: float, out: str | Path, *, t_end: float = 0.0,
               workers: int | None = None, progress: bool = True, check: bool = True,
               log=print) -> OwnStudy:
    """A refinement study of a user's rope (a case file), run for a tip-path tolerance ``tol``
    [m] and stopped once the answer is known; the runs are cached in ``out`` (a sweep's
    folder: run again, only what changed runs).

    1. The user's model by DOP853 at 1e-10 (the reference) and each coarser model
       (:func:`coarse_levels`) by ode45 at 1e-8: the model error of every level, their local
       orders of convergence.
    2. The reference's own error: Richardson from the finest coarse level when the last two
       local orders agree (within STEADY); else from the rope at twice the links (DOP853 at
       FINER_RTOL) when the case can be refined into the same rope: its difference from the
       reference and the order that the finest coarse level, the reference and it show
       (:func:`three_level_order`) give the rest of the way to the converged path; else unknown
       (said). A study whose errors do not fall with the links, or whose three finest models
       show no positive order, does not converge (a singular scene): said, no advice.
    3. The coarsest level whose model error is within ``tol`` less the reference's (the user's
       own model when no coarser level is); between it and the next coarser level (which is
       not), the rope rebuilt at other counts, bisected
       (ode45 at 1e-8; a straight rope's file only: :func:`redysim.io.cases.rebuild_problem`)
       down to the least count that is; that count, the level, and the user's own model at
       every setting of OWN_INTEGRATORS x OWN_RTOLS;
       :func:`advise` on all the runs for ``tol`` less the reference's error, by their work
       (RHS calls x links: the choice does not depend on the machine's load), and the advice
       run afresh."""
    from redysim.errors import SettingsError

    from .spec import RunSpec

    if isinstance(tol, bool) or not isinstance(tol, int | float) or not (
            tol > 0 and math.isfinite(tol)):
        raise SettingsError("advise", "--tip-tol", _shown(tol), "must be a tip distance > 0 [m]")
    from redysim.io.cases import FILE_SAMPLES, case_path

    path = str(case_path(case_file))
    case = load_case(path)
    nl = case.chain.n_links
    levels = coarse_levels(nl)
    rebuilt = ""
    if not levels:  # no divisor (a prime count): the rope rebuilt at coarser counts, if it can be
        from redysim.io.cases import rebuild_problem

        why = rebuild_problem(case)
        levels = [] if why else rebuilt_levels(nl)
        if not levels:
            raise SettingsError("advise", "CASE", path, f"has {nl} links: no coarser model (a "
                                "coarse link lumps the same number of fine ones, so lumping "
                                "needs a divisor between 2 and itself, and "
                                + (f"the rope cannot be rebuilt at another count: {why})"
                                   if why else "a rope of fewer links than 2 is no model)"))
        rebuilt = (f"{nl} has no divisor between 2 and itself: the coarser models are the rope "
                   f"rebuilt at {', '.join(map(str, levels))} links")
    horizon = float(t_end or case.t_end)
    sample = min(case.sample_interval or horizon / FILE_SAMPLES, horizon)
    base = dict(case=path, t_end=horizon, sample=sample)
    ref_spec = RunSpec(**base, integrator=OWN_REFERENCE[0], rtol=OWN_REFERENCE[1],
                       atol=OWN_REFERENCE[1] * 1e-2)
    specs = [ref_spec] + [RunSpec(**base, links=n, integrator=OWN_LEVEL[0], rtol=OWN_LEVEL[1],
                                  atol=OWN_LEVEL[1] * 1e-2) for n in levels]
    out = Path(out)
    from .store import check_kinds

    # before a word of what it will run: a file where its folder goes is refused by name
    check_kinds(folders=[out], why="give a folder for --out; nothing was run")
    name = f"advise-{case.name}"
    log(f"advise: {case.name}: {nl} links over {horizon:g} s; the reference ({OWN_REFERENCE[0]} "
        f"{OWN_REFERENCE[1]:g}) and {len(levels)} coarser models ({', '.join(map(str, levels))} "
        f"links, {OWN_LEVEL[0]} {OWN_LEVEL[1]:g}); runs cached in {out}")
    runs = _kept_sweep(specs, out, name=name, workers=workers, progress=progress)
    ref_row = runs[runs["run_id"] == ref_spec.run_id].iloc[0]
    if ref_row["status"] != "ok":
        raise SettingsError("advise", "CASE", path, f"its reference run failed: "
                            f"{ref_row['reason']}")
    study = load_study(out, case.name)
    conv = convergence(study)
    lv = conv["levels"]
    orders, converges, steady = verdict(lv)
    notes: list[str] = [rebuilt] if rebuilt else []
    if not converges and len(lv) >= 2:  # (one level shows no order: the finer rope judges it)
        notes.append("the tip path does not settle as links are added (model errors "
                     + ", ".join(f"{d['tip_err']:.2g} m at {d['links']}" for d in lv)
                     + f" links; local orders {', '.join(f'{o:.2f}' for o in orders)}): a "
                     "singular scene (a whip's tip, a bare end pulled by a force) has no "
                     "converged path for a coarser model to approach")
        return OwnStudy(path, tol, study, conv, orders, False, math.nan, "", None, None, notes)
    ref_error, how, singular = _reference_error(path, case, study, lv, orders, steady, log)
    if singular:
        notes.append(singular)
        return OwnStudy(path, tol, study, conv, orders, False, math.nan, "", None, None, notes)
    budget = tol - ref_error if math.isfinite(ref_error) else tol
    if not math.isfinite(ref_error):
        notes.append("the reference's own error is not known: the advice is within the "
                     "tolerance of your model, not of the converged path")
    if budget <= 0:
        notes.append(f"your model itself is {ref_error:.2g} m from the converged path "
                     f"({how}): more than {tol:g} m; refine it (more links) or ask less")
        return OwnStudy(path, tol, study, conv, orders, True, ref_error, how, None, None, notes)
    # the coarsest level within the budget and the next finer one (the user's model when none
    # is): a finer model at a looser setting can be the cheaper
    # (and the user's own model, for what the advice saves)
    # (the user's model meets it when no coarser divisor does: the search then runs between
    # the finest divisor and the user's count, which it did not before)
    meeting = [d["links"] for d in lv if d["tip_err"] <= budget]
    chosen, searched = _counts_to_try(case, lv, meeting[0] if meeting else nl, budget, specs,
                                      base, out, name, workers, notes, log)
    log(f"advise: settings on {', '.join(map(str, chosen))} links "
        f"({len(OWN_INTEGRATORS) * len(OWN_RTOLS)} each)")
    specs += [RunSpec(**base, links=0 if n == nl else n, integrator=i, rtol=r, atol=r * 1e-2)
              for n in chosen for i in OWN_INTEGRATORS for r in OWN_RTOLS]
    _kept_sweep(specs, out, name=name, workers=workers, progress=progress)
    study = load_study(out, case.name)
    a = advise(study, budget, cost="work")
    result = OwnStudy(path, tol, study, conv, orders, True, ref_error, how, a, None, notes,
                      searched)
    if a is not None and check:
        ref = study.reference
        tips, cpu, steps = _tips(case, a.links, a.integrator, a.rtol, a.rtol * 1e-2,
                                 horizon, sample)
        err = float(np.linalg.norm(tips - study.tips[ref["run_id"]], axis=1).max())
        result.check = {"tip_err": err, "cpu_s": cpu, "steps": int(steps),
                        "bound": err + (ref_error if math.isfinite(ref_error) else 0.0)}
    return result


def _kept_sweep(specs: list, out: Path, *, name: str, workers, progress: bool):
    """:func:`redysim.harness.sweep.run_sweep`, and once more when a run's row is not in its
    answer (its files set aside as damaged while the sweep ran: a row of another run id, as when
    the code changes between the plan and a worker; the sweep then redoes it); a run still
    without its row is refused by name (SweepError), never a KeyError later."""
    from .sweep import SweepError, run_sweep

    missing: list = []
    for _ in range(2):
        runs = run_sweep(specs, out, name=name, workers=workers, progress=progress)
        have = set(runs["run_id"]) if "run_id" in runs.columns else set()
        missing = [s for s in specs if s.run_id not in have]
        if not missing:
            return runs
    raise SweepError(str(out), "runs", [s.run_id for s in missing[:3]],
                     f"{len(missing)} of the study's {len(specs)} runs have no result there "
                     f"after being done twice (the first: {missing[0].label}; their files were "
                     "set aside as damaged, see damaged/: the code changing while the study "
                     "ran?); run the same command again")


def _reference_error(path: str, case, study, lv, orders, steady: bool, log
                     ) -> tuple[float, str, str]:
    """The user's model's own error from the converged path (:func:`_own_study`, step 2):
    (error [m] or NaN, how it was estimated, and a note when the scene is singular, else "")."""
    nl = case.chain.n_links
    if steady:
        c = lv[-1]
        p = orders[-1]
        return (c["tip_err"] / ((nl / c["links"]) ** p - 1.0),
                f"Richardson: order {p:.2f} steady over the last levels, from {c['links']} "
                f"links' error {c['tip_err']:.2g} m", "")
    fine, why = _refined(path, case)
    unsteady = (f"the order is not steady (local orders {', '.join(f'{o:.2f}' for o in orders)})"
                if orders else f"one coarser model ({lv[0]['links']} links) shows no order")
    if fine is None:
        return (math.nan, f"unknown: {unsteady} and {why}", "")
    log(f"advise: {unsteady}: the rope at {2 * nl} links (DOP853 {FINER_RTOL:g}) measures the "
        "reference's own error")
    finer = finer_references({study.scene: study}, workers=1, log=lambda *_: None)[study.scene]
    step = float(np.linalg.norm(study.tips[study.reference["run_id"]] - finer["tips"],
                                axis=1).max())
    c = lv[-1]
    p = three_level_order(c["links"], nl, finer["links"], c["tip_err"], step)
    if not p > 0:
        return (math.nan, "", f"the tip path does not settle as links are added: your model "
                f"and the rope at {finer['links']} links differ by {step:.2g} m, no less than "
                f"{c['links']} links and yours ({c['tip_err']:.2g} m) allow for a converging "
                "sequence: a singular scene (a whip's tip, a bare end pulled by a force), no "
                "converged path to advise for")
    return (step / ((finer["links"] / nl) ** p - 1.0),
            f"estimated from the rope at {finer['links']} links (DOP853 {FINER_RTOL:g}): "
            f"{step:.2g} m from yours, order {p:.2f} over {c['links']}, {nl} and "
            f"{finer['links']} links, the rest of the way by that order ({unsteady})", "")


def _counts_to_try(case, lv, first: int, budget: float, specs: list, base: dict, out: Path,
                   name: str, workers, notes: list, log) -> tuple[list[int], list[dict]]:
    """The link counts whose settings are tried (:func:`_own_study`, step 3): the coarsest
    level within the budget (``first``; the user's own count when no coarser divisor is) and the
    next finer one (the user's model when none is: a finer model at a looser setting can be the
    cheaper) and the user's own; between ``first`` and the next coarser level, the rope rebuilt
    at each count, bisected, down to the least that meets the budget. Returns (counts, the
    rebuilt counts' errors); ``specs`` grows with the rebuilt runs, ``notes`` with why a search
    stopped or was not made."""
    from redysim.io.cases import rebuild_problem

    from .spec import RunSpec

    nl = case.chain.n_links
    finer_levels = [d["links"] for d in lv if d["links"] > first]
    chosen = list(dict.fromkeys([first, (finer_levels or [nl])[0], nl]))
    coarser = [d for d in lv if d["links"] < first]
    searched: list[dict] = []
    if not coarser or first - coarser[-1]["links"] <= 1:
        return chosen, searched
    why = rebuild_problem(case)
    if why:
        notes.append(f"only link counts that divide yours were tried: {why}")
        return chosen, searched
    lo, hi = coarser[-1]["links"], first
    while hi - lo > 1:
        mid = (lo + hi) // 2
        specs.append(RunSpec(**base, links=mid, integrator=OWN_LEVEL[0], rtol=OWN_LEVEL[1],
                             atol=OWN_LEVEL[1] * 1e-2))
        runs = _kept_sweep(specs, out, name=name, workers=workers, progress=False)
        row = runs[runs["run_id"] == specs[-1].run_id].iloc[0]
        if row["status"] != "ok":
            notes.append(f"the rope rebuilt at {mid} links failed ({row['reason']}): the search "
                         "between the levels stopped there")
            break
        err = _tip_error(out, case.name, specs[-1].run_id)
        searched.append({"links": mid, "tip_err": err})
        log(f"advise: the rope rebuilt at {mid} links: model error {err:.3g} m")
        lo, hi = (lo, mid) if err <= budget else (mid, hi)
    if hi < first:
        chosen = list(dict.fromkeys([hi, first, nl]))
    return chosen, searched


# --------------------------------------------------------------------------- hanging modes
def hanging_modes(chain, m: int = N_MODES) -> np.ndarray:
    """The ``m`` lowest small-oscillation frequencies [rad/s] of a planar chain hanging straight
    down (joint 1 at -90 degrees, the others at 0), gravity along -Y.

    The stiffness is exact (:func:`redysim.harness.truths.hanging_stiffness`); the mass matrix
    is the core's (composite bodies). Solved as the symmetric
    generalised eigenproblem K x = omega^2 M x."""
    from scipy.linalg import eigh

    from .truths import hanging_stiffness, hanging_straight

    K = hanging_stiffness(chain)
    M = mass_matrix(chain, hanging_straight(chain))
    lam = eigh(K, M, eigvals_only=True, subset_by_index=[0, min(m, chain.n_dof) - 1])
    return np.sqrt(lam)


def continuum_modes(length: float, g: float, m: int = N_MODES) -> np.ndarray:
    """A heavy hanging string's frequencies: omega_k = (z_k / 2) sqrt(g / L), z_k the zeros of
    the Bessel function J0."""
    from scipy.special import jn_zeros

    return jn_zeros(0, m) / 2.0 * math.sqrt(g / length)


def modes_study(case_file: str | Path = HANGING_CASE, levels=HANGING_LEVELS,
                m: int = N_MODES) -> dict:
    """The hanging chain's first ``m`` frequencies at every level (coarse-grained from the case),
    their relative error against the continuum, the observed order per mode and the Richardson
    extrapolation from the two finest levels."""
    case = load_case(case_file)
    chain = case.chain
    exact = continuum_modes(float(chain.length.sum()), -float(chain.gravity[1]), m)
    rows = []
    for n in sorted(levels):
        c = chain if n == chain.n_links else coarsen(chain, links=n).coarse
        t0 = time.process_time()
        w = hanging_modes(c, m)
        cpu = time.process_time() - t0
        w = np.concatenate((w, np.full(m - w.size, math.nan)))
        rows.append({"links": n, "omega": w.tolist(),
                     "rel_err": (np.abs(w - exact) / exact).tolist(), "cpu_s": cpu})
    links = np.array([r["links"] for r in rows], dtype=float)
    err = np.array([r["rel_err"] for r in rows])
    orders = []
    for k in range(m):
        ok = np.isfinite(err[:, k]) & (links >= 8 * (k + 1))
        orders.append(float(-np.polyfit(np.log(links[ok]), np.log(err[ok, k]), 1)[0])
                      if ok.sum() >= 2 else math.nan)
    w_f, w_c = np.array(rows[-1]["omega"]), np.array(rows[-2]["omega"])
    ratio = rows[-1]["links"] / rows[-2]["links"]
    p = np.array(orders)
    rich = w_f + (w_f - w_c) / (ratio ** p - 1.0)
    return {"case": case.name, "length": float(chain.length.sum()), "modes": m,
            "continuum": exact.tolist(), "levels": rows, "orders": orders,
            "richardson": rich.tolist(),
            "richardson_rel_err": (np.abs(rich - exact) / exact).tolist()}


def advise_modes(study: dict, m: int, tol: float) -> dict | None:
    """The coarsest level whose first ``m`` frequencies are all within ``tol`` (relative) of the
    continuum's; None when none is. A level of n links has n modes: one with fewer than ``m``
    cannot meet the request (its missing frequencies are NaN in the study, and NaN is never
    within a tolerance). Raises SettingsError for an ``m`` beyond the study's modes (more than
    :func:`modes_study` computed) or a ``tol`` that is not a number > 0."""
    from redysim.errors import SettingsError

    if isinstance(m, bool) or not isinstance(m, int | np.integer) or not 1 <= m <= \
            study["modes"]:
        raise SettingsError("advise_modes", "m", _shown(m), f"must be a whole number in "
                            f"1..{study['modes']} (the modes the study computed)")
    if isinstance(tol, bool) or not isinstance(tol, int | float) or not tol > 0 or \
            not math.isfinite(tol):
        raise SettingsError("advise_modes", "tol", _shown(tol), "must be a relative frequency "
                            "tolerance > 0 (finite)")
    for row in study["levels"]:  # coarsest first
        errors = row["rel_err"][:m]
        if row["links"] >= m and all(math.isfinite(e) and e <= tol for e in errors):
            return {"links": row["links"], "max_rel_err": max(errors), "modes": m, "tol": tol}
    return None


def modes_available(levels=HANGING_LEVELS) -> int:
    """How many modes the hanging chain's finest level has: a planar chain of n links (one
    revolute joint each) has n."""
    return max(levels)


# --------------------------------------------------------------------------- everything
def run_all(results: Path, *, workers: int = 2, scenes=tuple(SCENES), check: bool = True,
            log=print) -> dict:
    """Run (or resume) every scene's sweep, analyse it, advise at the scene's tolerances and
    check each advice; the modes study; write ``results/refine/refine.json``. Every sweep of it
    runs on one pool of ``workers`` processes (:func:`redysim.harness.sweep.shared_pool`)."""
    from .sweep import shared_pool

    with shared_pool(workers):
        return _run_all(results, workers=workers, scenes=scenes, check=check, log=log)


def _run_all(results: Path, *, workers: int, scenes, check: bool, log) -> dict:
    from .sweep import load_sweep, run_sweep

    out = results / "refine"
    summary = {"scenes": {}, "provenance": provenance("")}
    studies = {}
    for scene in scenes:
        sweep = load_sweep(SWEEPS / f"{SCENES[scene]}.toml")
        folder = study_folder(results, scene)
        run_sweep(sweep.specs, folder, name=sweep.name, workers=workers)
        studies[scene] = load_study(folder, scene)
    finer = finer_references(studies, workers, log) if check else {}
    for scene, study in studies.items():
        conv = convergence(study)
        advice = []
        for tol in ADVICE_TOLERANCES[scene]:
            a = advise(study, tol)
            entry = {"tol": tol, "advice": None if a is None else {**asdict(a), "saved": a.saved}}
            if a is not None and check:
                log(f"refine: {scene}: checking the advice for {tol:g} m "
                    f"({a.links} links, {a.integrator} rtol {a.rtol:g})")
                entry["check"] = check_advice(study, a, finer[scene])
            advice.append(entry)
        cols = ["n_links", "integrator", "rtol", "precision", "status", "tip_err", "cpu_s",
                "steps", "nfev", "avg_abs_delta_M", "model_mib", "reason"]
        table = study.runs[cols + ["run_id"]].copy()
        summary["scenes"][scene] = {
            "title": SCENE_TITLES[scene], "case": Path(study.case).name,
            "reference": {k: _plain(study.reference[k]) for k in
                          ("n_links", "integrator", "rtol", "cpu_s", "steps", "model_mib")},
            "convergence": conv, "advice": advice,
            "runs": [{k: _plain(v) for k, v in row.items()} for row in
                     table.to_dict(orient="records")],
            "float32": float32_pairs(study)}
        log(f"refine: {scene}: order {conv['order']:.2f} on links {conv['order_levels']}")
    summary["hanging"] = modes_study()
    summary["hanging"]["advice"] = [advise_modes(summary["hanging"], m, tol)
                                    for m, tol in ((1, 0.01), (3, 0.01), (5, 0.001))]
    summary["own"] = own_summary(out, workers, log)
    summary["reduce"] = reduce_summary(out, log)
    write_json_atomic(summary, out / RESULTS_FILE)
    return summary


# what `redysim advise` is shown doing in the report: a rope case none of the studies above is,
# and a robot's scenario
OWN_EXAMPLE = ("RE-U125-L1", 1e-3, 0.3)    # case, tip tolerance [m], horizon [s]
REDUCE_EXAMPLE = ("TALOS-FALL", 1e-3)      # scenario, path tolerance [m] on its observed frame


def own_summary(out: Path, workers: int, log=print) -> dict:
    """:func:`own_study` of OWN_EXAMPLE, as the report shows it."""
    case, tol, t_end = OWN_EXAMPLE
    st = own_study(case, tol, out / f"own-{case}", t_end=t_end, workers=workers,
                   progress=False, log=log)
    a = st.advice
    return {"case": case, "tol": tol, "t_end": t_end, "links": int(st.study.reference["n_links"]),
            "reference_cpu_s": float(st.study.reference["cpu_s"]),
            "levels": [{k: _plain(d[k]) for k in ("links", "tip_err", "cpu_s")}
                       for d in st.conv["levels"]],
            "searched": [{k: _plain(d[k]) for k in ("links", "tip_err")} for d in st.searched],
            "orders": [_plain(o) for o in st.orders], "converges": st.converges,
            "ref_error": _plain(st.ref_error), "ref_error_how": st.ref_error_how,
            "advice": None if a is None else {**asdict(a), "saved": _plain(a.saved)},
            "check": st.check, "notes": st.notes}


def reduce_summary(out: Path, log=print) -> dict:
    """:func:`redysim.harness.reduce.reductions` of REDUCE_EXAMPLE, as the report shows it;
    ``{"skipped": why}`` without the robot's files (example-robot-data)."""
    from redysim.io.scenarios import robot_data_file

    from . import reduce

    scenario, tol = REDUCE_EXAMPLE
    if robot_data_file("talos_reduced.urdf") is None:
        return {"skipped": "example-robot-data is not installed (the test extra installs it)"}
    r = reduce.reductions(scenario, tol, out / f"reduce-{scenario}", log=log)
    return {"scenario": r.scenario, "frame": r.frame, "tol": r.tol, "t_end": r.t_end,
            "full_dof": r.full_dof, "reduced_dof": r.reduced_dof,
            "candidates": [[n, _plain(e)] for n, e in r.candidates],
            "locked": sorted(r.locked), "error": r.error, "practical": r.practical,
            "file_check": _plain(r.file_check), "notes": r.notes}


def finer_references(studies: dict, workers: int, log=print) -> dict:
    """:func:`finer_reference` of every study, on a process pool of ``workers``, each cached
    under its study's folder (keyed by the case file, the horizon and samples, the tolerance
    and the code): a resumed reproduction does not integrate them again."""
    import hashlib

    from .provenance import code_digest
    from .spec import case_digest
    from .store import write_npz_atomic

    out, todo = {}, {}
    for scene, study in studies.items():
        ref = study.reference
        args = (study.case, float(ref["t_end"]), float(ref["sample"]), 2)
        key = hashlib.sha256(json.dumps([case_digest(study.case), *args[1:], FINER_RTOL,
                                         code_digest()]).encode()).hexdigest()[:16]
        path = study.folder / f"finer-{key}.npz"
        if path.is_file():
            with np.load(path) as z:
                out[scene] = {"links": int(z["links"]), "tips": z["tips"],
                              "cpu_s": float(z["cpu_s"]), "steps": int(z["steps"]),
                              "rtol": FINER_RTOL}
        else:
            todo[scene] = (args, path)
    if todo:
        log(f"refine: the ropes at twice the finest's links (DOP853 {FINER_RTOL:g}): "
            f"{', '.join(todo)}")
        from .sweep import pool_lease

        with pool_lease(max(1, workers)) as lease:
            pool = lease.pool or lease.renew()
            futures = {scene: pool.submit(finer_tips, *args) for scene, (args, _) in
                       todo.items()}
            for scene, fut in futures.items():
                out[scene] = fut.result()
                write_npz_atomic(todo[scene][1], **{k: v for k, v in out[scene].items()
                                                    if k != "rtol"})
    for scene, study in studies.items():
        out[scene]["rtol_error_on_finest"] = _rtol_error_on_finest(study)
    return out


def _shown(v):
    """A value for a message: a numpy scalar as the plain number it is (nan and inf too)."""
    return v.item() if isinstance(v, np.generic) else v


def _plain(v):
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m redysim.harness.refine",
                                 description="Refinement studies: model size against accuracy.")
    ap.add_argument("--results", type=Path, default=Path("results"))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--scene", action="append", choices=tuple(SCENES),
                    help="only these scenes (default: all)")
    ap.add_argument("--no-check", action="store_true", help="advise without checking")
    args = ap.parse_args(argv)
    run_all(args.results, workers=args.workers, scenes=tuple(args.scene or SCENES),
            check=not args.no_check)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
