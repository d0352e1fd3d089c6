"""``redysim compare MODEL``: what a user with their own model runs to choose an engine and an
integrator for it.

For any scenario (:mod:`redysim.io.scenarios`: a .urdf, an MJCF .xml, a DH robot or linkage
.toml, a scenario file, a rope case), it

1. builds the model in every reference engine and checks single-state agreement with the core
   at seeded random states (qdd, the GIM, the bias, the energy), or says why an engine cannot
   build it (its ``limits``);
2. runs the scenario's passive motion through the harness (:func:`redysim.harness.sweep.run_sweep`,
   so the runs are cached and resumable like any sweep's): the core with its integrators, every
   engine through ode45 (its qdd) and with each of its own integrators over a ladder of steps or
   tolerances, each measured against the scenario's reference solution (DOP853 at 1e-10,
   checked by SciPy's DOP853 at 1e-13: :mod:`redysim.harness.reference`);
3. writes a short page, ``compare.html`` and ``compare.pdf`` in ``--out``, opening with its
   answer (:func:`redysim.reports.trade.trade_table`: per path tolerance, the cheapest engine and
   setting, the core's lead over the best engine, the engines that do not reach it); then the
   agreement table,
   the observed path's error and the energy drift over time, a work-precision plot, every run,
   and the advice "for this accuracy, this engine and setting was cheapest here": among the runs
   whose path error is within it, the least cost by :mod:`redysim.harness.cost` (the
   integration's CPU, least of repeats, sampling excluded, with its uncertainty), and the runs
   indistinguishable from it, measured here, on this machine; then ``compare.json``, the record
   of a finished comparison (its runs and the pages' SHA-256). Run again on a finished folder, it
   is read as it is: the record printed, nothing computed or rewritten (a read-only folder too).
   A folder it cannot write is refused before any work, and so is a reference cache
   (``$REDYSIM_RESULTS/reference``, which ``--out`` does not move) that cannot take the
   reference it needs.

    python -m redysim.reports.compare ur5_robot.urdf --out results/compare/ur5
"""

from __future__ import annotations

import argparse
import math
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd

from redysim.harness.spec import CORE, RunSpec
from redysim.io.importers import SAME_MOTION

from .content import DIFFER, INFO, MATCH, NOT_RUN, Headline, Report, Row, Section, Table
from .figures import ERROR_FLOOR, FONT_PT, PANEL_H, PANEL_W, WP_MARKERS, _figure, new_figure
from .results import momentum_drift_series
from .robots import STAGES, TOLERANCE, agreement
from .text import provenance_line
from .trade import trade_table

HTML_FILE, PDF_FILE = "compare.html", "compare.pdf"
RECORD_FILE = "compare.json"  # written last: the runs planned and the pages' SHA-256
CORE_RTOLS = (1e-4, 1e-7, 1e-10)
ENGINE_RTOLS = (1e-4, 1e-7)
STEP_DIVISIONS = (5, 25, 125)  # fixed steps h = sample / n: they land on every sample
NATIVE_RTOLS = (1e-4, 1e-7)
ADVICE_TOLS = (1e-2, 1e-4, 1e-6)  # m: path tolerances the advice answers for
MAX_CPU_S = 120.0  # a run's CPU limit here [s]
REASON_CHARS = 400  # an engine's refusal in the agreement table, cut at a word (was 160: mid-word)


def engine_names(model) -> list[str]:
    """One adapter per engine for ``model`` (a tree): Pinocchio's ``pin.aba``, with each U joint
    (and the U part of an S joint) as two revolute joints where the model has any
    (``pinocchio-aba-ryrz``: its ``JointModelUniversal`` loses the articulated inertia's symmetry
    on long chains, references/pinocchio_engine.py), and the other engines' one adapter."""
    from redysim import references

    split = any(t in ("U", "S") for t in model.joint_types)
    drop = ("pinocchio-crba", "pinocchio-aba" if split else "pinocchio-aba-ryrz")
    if model.couplings:  # pin.aba refuses mimic joints; its CRBA builds them
        drop = ("pinocchio-aba", "pinocchio-aba-ryrz")
    return [n for n in references.ENGINES if n not in drop]


def own_steps_left_out(model, names) -> dict[str, tuple[list[str], str]]:
    """The engines of ``names`` with own integrators that do not hold ``model``'s couplings
    (none for a model without): those integrators and why. They are not run (they would
    simulate another mechanism); the engine runs through its qdd, which holds them, in
    redysim's integrators, and with its own integrators that hold them."""
    from redysim import references

    if not model.couplings:
        return {}
    out = {}
    for name in names:
        cls = references.get(name)
        left = [n for n, info in cls.integrators.items() if not cls.holds_couplings_in(info)]
        if left:
            out[name] = (left, cls.no_couplings)
    return out


def _integrators_named(name: str, left: list[str]) -> str:
    """'all' when ``left`` is every own integrator of engine ``name``, else their names."""
    from redysim import references

    return "all" if len(left) == len(references.get(name).integrators) else ", ".join(left)


NOT_MOTION = SAME_MOTION  # in the importers' notes of what was read without acting


def acting_notes(model) -> list[str]:
    """The lines of ``model.notes`` that change the motion: what the file has and the run does
    not simulate (the importers' summary of what has no effect on the motion left out)."""
    return [n for n in model.notes if NOT_MOTION not in n]


SHORT_NOTE = 80  # characters of a note's head on the first screen


def _short(note: str) -> str:
    """A note's head for the first screen: 'joint damping (9 joints)' of 'joint damping
    dropped (...): ... (9 joints)', "equality 'e0': solref, solimp" of "equality 'e0':
    solref, solimp = 'j1' = 1 'j2' + 0 dropped (...)"."""
    head = note.split(" dropped", 1)[0].split(" = ", 1)[0].strip()
    if len(head) > SHORT_NOTE:
        head = head[:SHORT_NOTE - 3].rstrip() + "..."
    tail = note.rstrip().rsplit("(", 1)
    count = f" ({tail[1]}" if len(tail) == 2 and tail[1][:1].isdigit() else ""
    return f"{head}{count}"


def plan(target: str, scn, *, options: dict, t_end: float, sample: float,
         engines=None) -> list[RunSpec]:
    """The runs of a comparison: the core (ode45, dop853 at CORE_RTOLS; rk4 at the steps
    sample / STEP_DIVISIONS), every engine through ode45 (ENGINE_RTOLS) and with each of its own
    integrators (fixed: those steps; adaptive: NATIVE_RTOLS); closed loops: no native stepping
    (the harness refuses it), nor for an engine whose qdd holds the model's armature by the
    adapter (its own steps would run without it; the page says so)."""
    from redysim import references

    steps = [sample / n for n in STEP_DIVISIONS]

    base = dict(case=target, t_end=t_end, sample=sample, max_cpu_s=MAX_CPU_S)
    specs = [RunSpec(**base, integrator=i, rtol=r, atol=r * 1e-2)
             for i in ("ode45", "dop853") for r in CORE_RTOLS]
    specs += [RunSpec(**base, integrator="rk4", h=h) for h in steps]
    # a closed mechanism: the engines with a loop adapter, by the adapter's tree engine's name
    # (Pinocchio's loops are built on its CRBA; Drake's continuous plant takes no constraints)
    names = ([c.adapter.name for c in references.LOOP_ENGINES.values()] if scn.model.cuts
             else engine_names(scn.model))
    left_out = own_steps_left_out(scn.model, names)
    # an engine whose armature is the adapter's (no field for it): its own steps lack it
    no_arm = {n for n in names if np.any(scn.model.armature)
              and not references.get(n).armature_native}
    for name in names:
        cls = references.get(name)
        if engines is not None and name not in engines:
            continue
        specs += [RunSpec(**base, engine=name, integrator="ode45", rtol=r, atol=r * 1e-2)
                  for r in ENGINE_RTOLS]
        if scn.model.cuts or name in no_arm:
            continue
        for own, info in cls.integrators.items():
            if own in left_out.get(name, ((), ""))[0]:
                continue
            if info.adaptive:
                specs += [RunSpec(**base, engine=name, integrator=f"native:{own}", rtol=r,
                                  atol=r * 1e-2) for r in NATIVE_RTOLS]
            else:
                specs += [RunSpec(**base, engine=name, integrator=f"native:{own}", h=h)
                          for h in steps]
    return [s.with_options(**options) for s in specs]


LOOP_STATES = 3


def loop_agreement(name: str, model, q0) -> list[dict]:
    """One row per loop engine (:mod:`redysim.references.loops`): the worst relative difference
    of qdd with the loops closed, at the scenario's assembled configuration with seeded random
    velocities (projected onto the loops) and torques; and, on the open tree, the stages of
    :func:`redysim.reports.robots.agreement` ("tree:" rows)."""
    from redysim import references
    from redysim.algorithms.loops import ClosedLoops
    from redysim.references.base import build_warnings

    loops = ClosedLoops(model)
    rng = np.random.default_rng(20261127)
    q0 = loops.project(q0, np.zeros(model.n_v))[0]  # the scenario's assembled configuration
    states = []
    for _ in range(LOOP_STATES):
        # a coupled model's followers move with their leaders (model.couple), then the loops
        q, v = loops.project(*model.couple(q0, rng.normal(size=model.n_v)))[:2]
        states.append((q, v, rng.normal(size=model.n_v)))
    core = [loops.forward_dynamics(q, v, tau) for q, v, tau in states]
    rows = []
    for engine, cls in references.LOOP_ENGINES.items():
        row = {"robot": name, "engine": f"{engine} (loops)", "status": "ok", "reason": "",
               **dict.fromkeys(STAGES, math.nan)}
        try:
            if not cls.available():
                row.update(status="unavailable", reason=f"package {cls.package!r} missing")
            elif not (lim := cls.limits(loops)).ok:
                row.update(status="refused", reason=lim.reason)
            else:
                eng = references.loop_engine(engine, loops)
                row["warnings"] = build_warnings(eng)  # its C++ stderr, kept (the notes)
                worst = 0.0
                for (q, v, tau), ref in zip(states, core, strict=True):
                    got = eng.forward_dynamics(q, v, tau)
                    worst = max(worst, float(np.abs(got - ref).max() / np.abs(ref).max()))
                row["qdd"] = worst
        except Exception as exc:  # an engine's refusal or failure is a result, in its words
            row.update(status="failed", reason=f"{type(exc).__name__}: {exc}")
        rows.append(row)
    for r in agreement(name, model.with_cuts(())):
        rows.append({**r, "engine": f"{r['engine']} (open tree)"})
    return rows


def _loop_armature(names) -> str:
    """What the loop adapters of the engines ``names`` (whose tree adapters hold armature in
    their qdd only) do with a model's armature: hold it by their own solve, or refuse it."""
    from redysim import references

    loop = {c.adapter.name: c for c in references.LOOP_ENGINES.values()}
    held = [n for n in names if n in loop and loop[n].holds_armature]
    refused = [n for n in names if n in loop and not loop[n].holds_armature]
    out = []
    if held:
        out.append(f"the loop adapter of {', '.join(held)} holds it by its own KKT solve on "
                   "the engine's M with the armature")
    if refused:
        out.append(f"that of {', '.join(refused)}, whose constraint solve runs on the engine's "
                   "own model, refuses it")
    return "; ".join(out) + "." if out else "."


def setting(r) -> str:
    """'h 0.001' or 'rtol 1e-07' of a run row."""
    return f"h {float(r['h']):g}" if float(r["h"]) > 0 else f"rtol {float(r['rtol']):g}"


def label(r) -> str:
    return f"{r['engine']} {r['integrator']}"


def advice(runs: pd.DataFrame, tols=ADVICE_TOLS) -> list[dict]:
    """For each path tolerance: the cheapest run whose path error is within it, overall and per
    engine, by the cost model (:mod:`redysim.harness.cost`: the integration's CPU, least of
    repeats, sampling excluded, with its uncertainty); ``tied``: the runs indistinguishable
    from ``best`` (their costs overlap), ``per_engine_tied`` likewise per engine; None where no
    run met it."""
    from redysim.harness import cost

    if not len(runs) or "max_tip_err" not in runs or "cpu_s" not in runs:  # (none ran)
        return [{"tol": tol, "best": None, "tied": [], "per_engine": {},
                 "per_engine_tied": {}} for tol in tols]
    ok = runs[(runs["status"] == "ok") & pd.to_numeric(runs["max_tip_err"],
                                                        errors="coerce").notna()]
    out = []
    for tol in tols:
        met = ok[ok["max_tip_err"].astype(float) <= tol]
        best, tied = _cheapest(met, cost)
        per, per_tied = {}, {}
        for e, g in met.groupby("engine"):
            per[e], per_tied[e] = _cheapest(g, cost)
        out.append({"tol": tol, "best": best, "tied": tied, "per_engine": per,
                    "per_engine_tied": per_tied})
    return out


def _cheapest(runs: pd.DataFrame, cost) -> tuple[pd.Series | None, list]:
    """The pick of :func:`redysim.harness.cost.rank` among ``runs`` and the rows
    indistinguishable from it."""
    rows = [r for _, r in runs.iterrows()]
    ranking = cost.rank([cost.cost_of(r) for r in rows])
    if ranking is None:
        return None, []
    return rows[ranking.pick], [rows[i] for i in ranking.indistinguishable]


def _cost_text(r) -> str:
    """A run's cost as shown: '0.95 ms +- 10% (20 runs)'."""
    from redysim.harness import cost

    c = cost.cost_of(r)
    u = cost.uncertainty(c.repeats, c.spread)
    return f"{c.value * 1e3:.3g} ms +-{u:.0%} ({c.repeats} run{'s' if c.repeats > 1 else ''})"


def _samples(out: Path, run_id: str) -> pd.DataFrame | None:
    p = out / "samples" / f"{run_id}.parquet"
    return pd.read_parquet(p) if p.is_file() else None


def _path_figures(scn, runs: pd.DataFrame, out: Path, ref):
    """The observed path's distance from the reference and the energy drift over time, for the
    core's tightest run and each engine's tightest run of each integrator (the last of its
    ladder)."""
    kept = scn.momentum_kept  # a floating system under no force but gravity: (c) its h_G
    fig, axes = new_figure(3 if kept else 2, width=PANEL_W * (4.2 if kept else 3.0),
                           height=PANEL_H * 1.5, footer=provenance_line(runs))
    ok = runs[runs["status"] == "ok"]
    shown = []
    for _, g in ok.groupby(ok.apply(label, axis=1), sort=False):
        key = "h" if g["h"].astype(float).gt(0).all() else "rtol"
        shown.append(g.sort_values(key).iloc[0])  # the smallest step or tolerance
    for i, r in enumerate(shown):
        s = _samples(out, r["run_id"])
        if s is None or ref is None or len(s) != len(ref.t):
            continue
        err = np.linalg.norm(s[["tip_x", "tip_y", "tip_z"]].to_numpy() - ref.tip, axis=1)
        style = "-" if r["engine"] == CORE else "--"
        kw = dict(color=f"C{i % 10}", marker=WP_MARKERS[i % len(WP_MARKERS)], ms=2.5,
                  markevery=max(1, len(s) // 8), linestyle=style)
        axes[0].semilogy(s["t"], np.maximum(err, ERROR_FLOOR),
                         label=f"{label(r)} {setting(r)}", **kw)
        axes[1].semilogy(s["t"], np.maximum(np.abs(s["delta_M"]), ERROR_FLOOR), **kw)
        if kept and "h_x" in s:
            axes[2].semilogy(np.sort(s["t"].to_numpy()),
                             np.maximum(momentum_drift_series(s), ERROR_FLOOR), **kw)
    if kept:
        axes[2].set(title="(c) angular momentum about the COM", xlabel="t [s]",
                    ylabel="|h_G - h_G(0)| / |h_G(0)|")
    axes[0].set(title=f"(a) {scn.frame}: distance from the reference", xlabel="t [s]",
                ylabel="error [m]")
    axes[1].set(title="(b) energy drift", xlabel="t [s]", ylabel="|delta_M| [J/kg]")
    _legend_right(axes)
    return _figure("compare-paths", "tip-path", f"{scn.name}: the observed path and the energy",
                   f"The tightest run of each engine and integrator (its smallest step or "
                   f"tolerance): (a) the distance of {scn.frame!r} from the reference solution "
                   f"over time, (b) the energy drift per unit mass |delta_M| (computed by the core "
                   f"from each run's states, the same measurement for every engine)"
                   + ("; (c) the change of the angular momentum about the centre of mass over "
                      "its size, which the floating system keeps exactly (redysim.momentum of "
                      "the runs' states)" if kept else "") + ".", fig)


def _legend_right(axes) -> None:
    """The first panel's legend, right of the last panel (outside both)."""
    handles, labels = axes[0].get_legend_handles_labels()
    axes[-1].legend(handles, labels, fontsize=FONT_PT - 2.5, loc="upper left",
                    bbox_to_anchor=(1.02, 1.0))


def _wp_figure(scn, runs: pd.DataFrame):
    from redysim.harness.cost import cost_of

    fig, axes = new_figure(2, width=PANEL_W * 3.0, height=PANEL_H * 1.5,
                           footer=provenance_line(runs))
    ok = runs[(runs["status"] == "ok")]
    for i, (name, g) in enumerate(ok.groupby(ok.apply(label, axis=1), sort=False)):
        key = "h" if g["h"].astype(float).gt(0).all() else "rtol"
        g = g.sort_values(key, ascending=False)
        style = "-" if g["engine"].iloc[0] == CORE else "--"
        for ax, col in ((axes[0], "max_tip_err"), (axes[1], "max_abs_delta_M")):
            ax.loglog([cost_of(r).value for _, r in g.iterrows()],
                      np.maximum(g[col].astype(float), ERROR_FLOOR),
                      linestyle=style, color=f"C{i % 10}", marker=WP_MARKERS[i % len(WP_MARKERS)],
                      ms=3.5, label=name if ax is axes[0] else None)
    axes[0].set(title=f"(a) {scn.frame}: max error against CPU", xlabel="CPU time [s]",
                ylabel="max error [m]")
    axes[1].set(title="(b) energy drift against CPU", xlabel="CPU time [s]",
                ylabel="max |delta_M| [J/kg]")
    _legend_right(axes)
    return _figure("compare-wp", "work-precision", f"{scn.name}: work against precision",
                   "Every run: the largest distance of the observed frame from the reference "
                   "over the samples (a) and the largest energy drift (b), against the CPU time "
                   "of the integration (the least of repeated runs; the sampling, the JIT "
                   "compile and the engine build timed apart); one curve per "
                   "engine and integrator, from loose to tight. Solid: the core; dashed: an "
                   "engine.", fig)


def engine_warnings(agree: list[dict]) -> list[str]:
    """What the engines wrote to stderr while their adapters built the model in the agreement
    stage (:func:`redysim.references.base.build_warnings`: DART's Inertia wants every
    principal moment > 0 and says so for a thin rod; the moments are used as given), once per
    engine and warning: the page's notes, not the terminal."""
    out: dict[str, None] = {}
    for r in agree:
        if r.get("warnings"):
            out[f"{r['engine']}: {r['warnings']}"] = None
    return list(out)


def build(target: str, scn, runs: pd.DataFrame, agree: list[dict], out: Path, ref) -> Report:
    """The comparison page as a :class:`~redysim.reports.content.Report`."""
    from redysim.harness.provenance import provenance

    m = scn.model
    base = "floating base" if m.quaternions.size else "fixed base"
    intro = [f"{target}: {m.name}, {m.n_bodies} bodies, n_q = {m.n_q}, n_v = {m.n_v}, "
             f"{m.total_mass:.6g} kg, {base}{f', {len(m.cuts)} cut joints' if m.cuts else ''}. "
             f"Scenario: {scn.description or scn.name}; observed: {scn.frame}; "
             f"horizon {runs['t_end'].astype(float).max():g} s."]
    if ref is not None:
        check = (f"and by the same DOP853 on {ref.engine_check_by}'s qdd to "
                 f"{ref.engine_check:.1e} m" if math.isfinite(ref.engine_check)
                 else f"no second engine ({ref.engine_check_by.removeprefix('none: ')})")
        intro.append(f"The reference solution: the core's DOP853 at 1e-10 ({ref.steps} steps), "
                     f"confirmed by SciPy's DOP853 at 1e-13 to {ref.tol_estimate:.1e} m "
                     f"(the observed path's largest distance); {check}.")
    acting = acting_notes(m)
    if acting:
        intro.append("From the file, not simulated (Model.notes): " + "; ".join(acting))
    if len(acting) < len(m.notes):
        intro.append("From the file, read with no effect on the motion (Model.notes): "
                     + "; ".join(n for n in m.notes if n not in acting))
    said = engine_warnings(agree)
    if said:
        intro.append("The engines warned while building the model (their C++ output, kept "
                     "here rather than printed): " + "; ".join(said))
    if m.couplings:
        from redysim import references

        kept = [n for n in engine_names(m) if references.get(n).limits(m).ok]
        own = [f"{n}: {references.get(n).couples}" for n in kept if references.get(n).couples]
        projected = [n for n in kept if not references.get(n).couples]
        left_out = own_steps_left_out(m, kept)
        rules = ", ".join(f"{c.follower} = {c.multiplier:g} {c.leader} + {c.offset:g}"
                          for c in m.couplings)
        loops_note = ""
        if m.cuts:  # the runs are the loop adapters': say which of them hold the couplings
            held = [f"{n}: {c.couples}" for n, c in references.LOOP_ENGINES.items()
                    if c.couples]
            refused = [n for n, c in references.LOOP_ENGINES.items() if not c.couples]
            loops_note = (" With the loops closed (the runs below): "
                          + ("; ".join(held) or "no loop adapter holds them")
                          + (f"; {', '.join(refused)} refuse{'s' if len(refused) == 1 else ''} "
                             "the coupled model (a loop adapter that closes the cuts only)"
                             if refused else "") + ".")
        intro.append(
            f"Coupled joints ({rules}). "
            + ("On the open tree, each" if m.cuts else "Each") + " engine's qdd holds them: "
            + "; ".join(own)
            + (f"; {', '.join(projected)}: the engine's own M and bias restricted to the "
               f"coupled motion by the adapter, qdd = G (G^T M G)^-1 G^T phi, as it has no "
               f"coupling of its own (" + "; ".join(f"{n}: {references.get(n).no_couplings}"
                                                    for n in projected) + ")"
               if projected else "")
            + (". Own integrators not run, which would step the joints uncoupled: "
               + "; ".join(f"{n}: {_integrators_named(n, left)}"
                           for n, (left, _) in left_out.items()) if left_out and not m.cuts
               else "") + "." + loops_note)
    if np.any(m.armature):  # how each engine holds it: natively, or the adapter's M + diag(a)
        from redysim import references

        tree = m.with_cuts(()) if m.cuts else m
        by_adapter = [n for n in engine_names(tree) if references.get(n).limits(tree).ok
                      and not references.get(n).armature_native]
        if by_adapter:
            intro.append(
                "Armature (the joints' own inertia): held natively by "
                + ", ".join(n for n in engine_names(tree) if references.get(n).limits(tree).ok
                            and references.get(n).armature_native)
                + "; " + ", ".join(by_adapter) + " have no field for it, so their qdd is "
                "(M + diag(armature)) qdd = tau + phi from the engine's own M and bias (the "
                "adapter's solve), and "
                + (_loop_armature(by_adapter) if m.cuts else
                   "their own integrators, which step the engine's model without it, are not "
                   "run."))
    agree_t = Table("compare-agreement", "Single-state agreement with the core",
                    ["engine", "status", *STAGES, "note"],
                    notes=[f"Worst relative difference max|engine - core| / max|core| over "
                           f"seeded random states; within {TOLERANCE:g} is agreement. Closed "
                           f"loops: qdd with the loops closed by each engine's own constraints "
                           f"at the assembled configuration, velocities projected onto the "
                           f"loops ('loops' rows), and every stage on the open tree ('open "
                           f"tree' rows)."])
    for r in agree:
        vals = [r[s] for s in STAGES]
        good = r["status"] == "ok" and all(v <= TOLERANCE for v in vals if not math.isnan(v))
        agree_t.rows.append(Row([r["engine"], r["status"],
                                 *(f"{v:.1e}" if not math.isnan(v) else "" for v in vals),
                                 textwrap.shorten(r.get("reason", ""), REASON_CHARS,
                                                  placeholder=" [...]")],
                                MATCH if good else (NOT_RUN if r["status"] != "ok" else DIFFER)))
    adv = advice(runs)
    adv_t = Table("compare-advice", "For this accuracy, this engine and setting was cheapest "
                  "here", ["path tolerance [m]", "cheapest run", "cost", "error [m]",
                           "indistinguishable from it", "cheapest per engine"],
                  notes=["Measured on this machine in this comparison: the integration's CPU "
                         "time, the least of repeated runs (a run under 0.2 s is repeated until "
                         "its repeats add up to 0.2 s), the sampling (observers, energy) and "
                         "the JIT compile and engine build not counted, with its uncertainty "
                         "(the repeats' spread, at least 10%; 25% for a run measured once). Runs "
                         "whose cost intervals overlap are indistinguishable: no measurement "
                         "here says which is cheaper, and the pick among them is the one of "
                         "least work (RHS calls x one call's CPU) where all of them have it (an "
                         "engine's own stepper has none: then the least cost)."])
    heads = []
    for a in adv:
        b = a["best"]

        def per_text(e, r, a=a):
            tie = a["per_engine_tied"].get(e) or []
            return (f"{e}: {label(r).split(' ', 1)[1]} {setting(r)} ({_cost_text(r)})"
                    + (f", indistinguishable from {len(tie)} other" if tie else ""))
        per = "; ".join(per_text(e, r) for e, r in sorted(a["per_engine"].items())
                        if r is not None)
        if b is None:
            adv_t.rows.append(Row([f"{a['tol']:g}", "no run met it", "", "", "", ""], NOT_RUN))
            continue
        tied = "; ".join(f"{label(r)} {setting(r)} ({_cost_text(r)})" for r in a["tied"])
        adv_t.rows.append(Row([f"{a['tol']:g}", f"{label(b)} {setting(b)}", _cost_text(b),
                               f"{float(b['max_tip_err']):.2e}", tied or "none: cheapest",
                               per], INFO))
        verdict = (f"; indistinguishable from {len(a['tied'])} other run"
                   f"{'s' if len(a['tied']) > 1 else ''} (costs within the noise)"
                   if a["tied"] else "")
        heads.append(Headline(f"cheapest within {a['tol']:g} m", f"{label(b)} {setting(b)}",
                              f"{_cost_text(b)}, error {float(b['max_tip_err']):.1e} m"
                              + verdict))
    acting = acting_notes(m)
    if acting:  # first on the page: what the file has and this run does not simulate
        heads.insert(0, Headline("in the file, not simulated", f"{len(acting)} item"
                                 f"{'s' if len(acting) > 1 else ''}",
                                 "; ".join(_short(n) for n in acting)
                                 + " (each in full under 'The model')", DIFFER))
    ran = sorted({str(e) for e in runs.loc[runs["status"] == "ok", "engine"]} - {CORE})
    heads.insert(1 if acting else 0, Headline(
        "engines that ran", f"{len(ran)} + the core", ", ".join(ran) or "none",
        INFO if ran else NOT_RUN))
    runs_t = Table("compare-runs", "Every run", ["run", "status", "steps", "RHS calls",
                                                  "CPU [s]", "cost", "path error [m]",
                                                  "max |delta_M| [J/kg]", "reason"])
    for _, r in runs.iterrows():
        runs_t.rows.append(Row([f"{label(r)} {setting(r)}", r["status"], str(r["steps"]),
                                "" if int(r["nfev"]) < 0 else str(r["nfev"]),
                                f"{float(r['cpu_s']):.3g}", _cost_text(r),
                                f"{float(r['max_tip_err']):.2e}",
                                f"{float(r['max_abs_delta_M']):.2e}", str(r["reason"])[:140]],
                               INFO if r["status"] == "ok" else DIFFER))
    manifests = Table("compare-engines", "The engines as they ran",
                      ["engine", "version", "integrator", "configuration"])
    seen = set()
    for _, r in runs[runs["engine"] != CORE].iterrows():
        key = (r["engine"], r["integrator"])
        if key in seen or not str(r.get("engine_config", "")):
            continue
        seen.add(key)
        manifests.rows.append(Row([r["engine"], str(r.get("engine_version", "")),
                                   r["integrator"], str(r["engine_config"])[:400]], INFO))
    figs = [_path_figures(scn, runs, out, ref), _wp_figure(scn, runs)]
    here = provenance()
    answer = Section("answer", "The answer: the cheapest engine and setting for each accuracy",
                     [f"Measured here on {m.name}: at each path tolerance, the cheapest run of "
                      "any engine and integrator whose path error is within it, the core's "
                      "cheapest and the best engine's, the core's lead (the engine's cost over "
                      "the core's) and the engines that do not reach it (their best error). "
                      "The model, the engines' agreement and every run follow."],
                     [trade_table(runs, "compare-trade", "The trade for this model",
                                  accuracies=ADVICE_TOLS)])
    return Report(f"redysim compare: {scn.name}", f"{target}: every engine, every integrator, "
                  "against a reference solution", here["date"], heads,
                  [answer, Section("model", "The model and its agreement", intro, [agree_t]),
                   Section("advice", "What to run", [], [adv_t, *figs]),
                   Section("runs", "The runs", [], [runs_t, manifests])],
                  provenance_line(here, what="page built with"))


def compare(target: str, out: Path, *, options: dict | None = None, t_end: float = 0.0,
            workers: int | None = None, engines=None, progress: bool = True,
            log=print) -> tuple[Path, Path]:
    """Run the comparison of ``target`` into ``out`` and write its page (module docstring)."""
    from redysim.harness.reference import check_cache, compute_reference
    from redysim.harness.store import (
        check_kinds,
        check_writable,
        sha256_file,
        write_json_atomic,
        write_text_atomic,
    )
    from redysim.harness.sweep import run_sweep
    from redysim.io.scenarios import load_scenario

    from .build import render_html
    from .pdf import write_pdf

    options = options or {}
    scn = load_scenario(target, options=options)
    horizon = t_end or scn.t_end
    sample = scn.sample_for(horizon)
    specs = plan(target, scn, options=options, t_end=horizon, sample=sample, engines=engines)
    # before any engine runs: a folder where its pages or its reference go, by name
    check_kinds(files=[out / HTML_FILE, out / PDF_FILE, out / RECORD_FILE],
                why="nothing was run")
    record = finished_record(out, specs)
    if record is not None:  # finished: read as it is (as sweep and longrun do), nothing written
        log(f"compare: {scn.name}: finished in {out} ({record['n_runs']} runs, "
            f"{record['failed']} failed): {out / HTML_FILE} and {out / PDF_FILE}, as they are "
            "(nothing rewritten; delete compare.json to build them again)")
        return out / HTML_FILE, out / PDF_FILE
    check_writable(out, flag=None)  # before any engine runs: its pages and runs go there
    check_cache(scn, horizon, sample)
    log(f"compare: {scn.name}: single-state agreement in every engine")
    agree = (loop_agreement(scn.name, scn.model, scn.q0) if scn.model.cuts
             else agreement(scn.name, scn.model))
    log(f"compare: {len(specs)} runs over {horizon:g} s (cached in {out / 'runs'})")
    runs = run_sweep(specs, out, name=f"compare-{scn.name}", workers=workers,
                     progress=progress, reference=True)
    ref = compute_reference(scn, horizon, sample)
    report = build(target, scn, runs, agree, out, ref)
    html = write_text_atomic(render_html(report), out / HTML_FILE)
    pdf = write_pdf(report, out / PDF_FILE)
    bad = int((runs["status"] != "ok").sum())
    write_json_atomic({"run_ids": sorted(s.run_id for s in specs), "n_runs": len(runs),
                       "failed": bad, HTML_FILE: sha256_file(html),
                       PDF_FILE: sha256_file(pdf)}, out / RECORD_FILE)
    log(f"compare: {html} and {pdf} ({len(runs)} runs, {bad} failed)")
    return html, pdf


def finished_record(out: Path, specs) -> dict | None:
    """The record of a finished comparison in ``out`` (:data:`RECORD_FILE`, written last), or
    None: none, another plan of runs, its pages missing or not the ones it recorded (their
    SHA-256), or a run's manifest or summary row missing (then the comparison is done again,
    the sweep redoing what is missing or damaged)."""
    import json

    from redysim.harness.store import sha256_file
    from redysim.harness.sweep import MANIFEST_DIR, RUNS_DIR

    try:
        record = json.loads((out / RECORD_FILE).read_text())
        if record["run_ids"] != sorted(s.run_id for s in specs):
            return None
        for name in (HTML_FILE, PDF_FILE):
            if sha256_file(out / name) != record[name]:
                return None
        int(record["n_runs"]), int(record["failed"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    for s in specs:
        if not ((out / MANIFEST_DIR / f"{s.run_id}.json").is_file()
                and (out / RUNS_DIR / f"{s.run_id}.parquet").is_file()):
            return None
    return record


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("model")
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--floating", action="store_true")
    ap.add_argument("--t-end", type=float, default=0.0)
    args = ap.parse_args(argv)
    compare(args.model, args.out, options={"floating": True} if args.floating else {},
            t_end=args.t_end)
    return 0


if __name__ == "__main__":
    sys.exit(main())
