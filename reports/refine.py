"""The report's "Model size" section: refinement studies (redysim.harness.refine), as tables and
figures.

Reads ``results/refine/refine.json`` (written by ``python -m redysim.harness.refine``, which
``make reproduce`` runs): per scene the error of every run against the finest model, the observed
order in the link count, the Richardson-extrapolated tip position, the advice at the scene's
tolerances and its check, float32 beside float64; the hanging chain's modes against the
continuum's.
"""

from __future__ import annotations

import numpy as np

from .content import DIFFER, INFO, MATCH, NOT_RUN, Figure, Row, Section, Table
from .figures import (
    ERROR_FLOOR,
    FONT_PT,
    PANEL_H,
    PANEL_W,
    WP_MARKERS,
    _figure,
    missing,
    new_figure,
)
from .results import finite
from .text import integer, num, provenance_line, sci, seconds

NOT_RAN = "not run: python -m redysim.harness.refine (make reproduce runs it)"
SCENE_ORDER = ("spin", "fall", "whip", "pulled")


def _fmt_err(x) -> str:
    return sci(x, 2) if x is not None and finite(x) else ""


def refine_section(res) -> Section:
    """Model size against accuracy: what a scene needs, measured."""
    sec = Section("refine", "Model size: how many links a scene needs")
    sec.intro.append(
        "One physical rope at several link counts: the finest model's links lumped k at a time "
        "(redysim.coarsen: exact mass, first moment and inertia about the new joint), each "
        "integrated by ode45 and DOP853 at rtol 1e-3 to 1e-8 (atol = rtol / 100). Error = the "
        "largest distance of the tip from the reference's (the finest model, DOP853 at 1e-10) "
        "over the samples. The advice is the run of least CPU that met a tolerance; its check "
        "runs it again and measures it also against a model twice as fine as the finest.")
    doc = res.refine
    conv = Table("refine-convergence", "Tip-path error against links, at the tightest "
                 "tolerance of each level", ["scene", "links", "DOF", "tip error [m]",
                                             "at the horizon [m]", "peak tip speed [m/s]",
                                             "CPU", "steps", "memory"])
    orders = Table("refine-orders", "Observed order in the link count and Richardson "
                   "extrapolation", ["scene", "order p", "fitted on links",
                                     "finest's error, Richardson estimate [m]",
                                     "tip at the horizon, extrapolated [m]"])
    advice = Table("refine-advice", "Advice: the cheapest measured model and setting for a "
                   "tip-path tolerance, checked", ["scene", "tolerance [m]", "advised",
                                                   "error (check) vs finest [m]",
                                                   "vs 2x finer [m]", "CPU", "finest's CPU",
                                                   "saved"])
    f32 = Table("refine-float32", "float32 dynamics beside float64 (the integrator in float64)",
                ["scene", "links", "rtol", "float32: error [m]", "float64: error [m]",
                 "paths apart [m]", "steps 32 / 64", "status"])
    modes = Table("refine-modes", "Hanging chain: relative error of the first frequencies "
                  "against the continuum's", ["links"])
    figs: list[Figure] = []
    if doc is None:
        for t in (conv, orders, advice, f32, modes):
            t.not_run = NOT_RAN
        sec.items += [conv, orders, advice, f32, modes,
                      missing("refine-fig", "refinement", "Refinement", "", NOT_RAN)]
        return sec
    prov = provenance_line(doc.get("provenance"), what="results/refine/refine.json")
    for scene in SCENE_ORDER:
        s = doc["scenes"].get(scene)
        if s is None:
            continue
        c = s["convergence"]
        for lv in c["levels"]:
            run = next(r for r in s["runs"] if r["run_id"] == lv["run_id"])
            conv.rows.append(Row([scene, integer(lv["links"]), integer(_dof(run, scene)),
                                  _fmt_err(lv["tip_err"]), _fmt_err(lv["end_tip_err"]),
                                  num(lv["peak_tip_speed"], 3), seconds(lv["cpu_s"]),
                                  integer(run["steps"]), _kib(lv.get("model_mib"))]))
        ref = s["reference"]
        conv.rows.append(Row([scene, integer(ref["n_links"]), integer(_dof(ref, scene)),
                              "reference", "", num(c["finest_peak_tip_speed"], 3),
                              seconds(ref["cpu_s"]), integer(ref["steps"]),
                              _kib(ref.get("model_mib"))], INFO))
        rich = c.get("richardson")
        orders.rows.append(Row([s["title"], num(c["order"], 3) if finite(c["order"]) else "",
                                ", ".join(str(n) for n in c["order_levels"]),
                                _fmt_err(rich["finest_error_estimate"]) if rich else "",
                                ("(" + ", ".join(f"{x:.6f}" for x in rich["tip_end"]) + ")")
                                if rich else ""]))
        for a in s["advice"]:
            adv = a["advice"]
            if adv is None:
                advice.rows.append(Row([scene, f"{a['tol']:g}", "no run met it", "", "", "",
                                        "", ""], NOT_RUN))
                continue
            chk = a.get("check") or {}
            met = chk and chk["error_vs_finest"] <= a["tol"] and chk["error_vs_finer"] <= a["tol"]
            advice.rows.append(Row([
                scene, f"{a['tol']:g}",
                f"{adv['links']} links, {adv['integrator']} rtol {adv['rtol']:g}",
                _fmt_err(chk.get("error_vs_finest")) or _fmt_err(adv["tip_err"]),
                _fmt_err(chk.get("error_vs_finer")),
                seconds(adv["cpu_s"]), seconds(adv["finest_cpu_s"])
                if finite(adv["finest_cpu_s"]) else "none met it",
                f"{adv['saved']:.0f}x" if adv["saved"] and finite(adv["saved"]) else ""],
                (MATCH if met else DIFFER) if chk else INFO))
        for p in s["float32"]:
            ok = p["status"] == "ok"
            f32.rows.append(Row([scene, integer(p["links"]), f"{p['rtol']:g}",
                                 _fmt_err(p["tip_err32"]), _fmt_err(p["tip_err64"]),
                                 _fmt_err(p["apart"]),
                                 f"{p['steps32']:,} / {p['steps64']:,}" if ok and p["steps64"]
                                 else "",
                                 "ok" if ok else f"failed at t = {p['t_reached']:.3g} s: "
                                 f"{p['reason'][:60]}"], INFO if ok else DIFFER))
        figs.append(_scene_figure(scene, s, prov))
    conv.notes.append("DOF: 2 per link for the spinning rope's universal joints, 1 for the "
                      "planar chains. Each level's row is its tightest tolerance (the smaller "
                      "error of ode45 and DOP853); its error is then the model's, not the "
                      "integrator's, down to the reference's own. Peak tip speed: the largest "
                      "over the samples (every 0.01 s; 0.02 s for the spinning rope). Memory: "
                      "the model's Workspace, every array the kernels read or write (O(n)).")
    orders.notes.append("p: the slope of log(error) against log(links) on the levels at most a "
                        "quarter of the finest (where the finest's own error biases the "
                        "difference by at most 4^-p). Richardson: Q_inf = Q_f + (Q_f - Q_c) / "
                        "(r^p - 1) from the two finest levels, Q the tip at the horizon; "
                        "|Q_inf - Q_f| estimates what the finest model itself misses.")
    advice.notes.append("Advised: of the study's runs whose tip-path error met the tolerance, "
                        "the one of least CPU (the coarsest model and cheapest setting that "
                        "meet it, as measured). Check: the advised model run again by the "
                        "Python stepping loop and compared with the reference and with the rope "
                        "at twice the finest's links (DOP853 at 1e-8); green when both errors "
                        "are within the tolerance. Saved: the finest model's cheapest run that "
                        "met the tolerance over the advised run's CPU.")
    pairs = [p for sc in SCENE_ORDER for p in doc["scenes"].get(sc, {}).get("float32", [])
             if p["status"] == "ok" and p["apart"] is not None and p["steps64"]]
    if pairs:
        tight = min(p["rtol"] for p in pairs)
        ratios = [p["steps32"] / p["steps64"] for p in pairs if p["rtol"] == tight]
        f32.notes.append(
            "float32: every operation of the core's qdd rounded to IEEE single "
            "(redysim.algorithms.precision.ieee_qdd, the core's fused formulation, "
            "numpy-emulated: its CPU is not float32's speed); the state and the integrator's "
            "stage sums in float64. "
            f"Tip paths within {max(p['apart'] for p in pairs):.1e} m of float64's, far below "
            "these models' own errors. But the rounding noise of qdd (eps32 x cond(GIM), cond ~ "
            "links^4) is what the adaptive error test sees: at rtol "
            f"{tight:g} float32 took {min(ratios):.1f} to {max(ratios):.1f} times float64's "
            "steps, and a run stopped by its limit of 30 s of CPU time (max_cpu_s, which "
            "does not depend on the machine's load) is listed as failed.")
    hang = doc.get("hanging")
    if hang:
        _fill_modes(modes, hang)
        figs.append(_modes_figure(hang, prov))
    else:
        modes.not_run = NOT_RAN
    own, reduced = own_table(doc), reduce_table(doc)
    for t in (conv, orders, advice, f32, modes, own, reduced):
        t.provenance = prov
    sec.items += [*figs, conv, orders, advice, f32, float32_speed_table(res), modes, own,
                  reduced, adaptive_figure(res), adaptive_table(res)]
    return sec


def _fill_modes(modes: Table, hang: dict) -> None:
    """The hanging chain's frequencies table: each level's relative errors, the observed
    orders, Richardson's, and the continuum and the advice in its notes."""
    m = hang["modes"]
    modes.columns = ["links"] + [f"mode {k + 1}" for k in range(m)]
    for lv in hang["levels"]:
        modes.rows.append(Row([integer(lv["links"])] + [_fmt_err(e) if finite(e) else ""
                                                        for e in lv["rel_err"]]))
    modes.rows.append(Row(["observed order"] + [num(p, 3) for p in hang["orders"]], INFO))
    modes.rows.append(Row(["Richardson, 512 and 1,024"] +
                          [_fmt_err(e) for e in hang["richardson_rel_err"]], INFO))
    modes.notes.append(
        "Continuum: a heavy hanging string, omega_k = (z_k / 2) sqrt(g / L), z_k the zeros "
        "of J0: " + ", ".join(f"{w:.5f}" for w in hang["continuum"]) + " rad/s for L = "
        f"{hang['length']:g} m. The chain (rod links, "
        f"{hang['case']}) linearised about hanging straight down: K exact, M the core's "
        "GIM. Orders fitted on links >= 8 per mode number.")
    for a in hang.get("advice", []):
        if a:
            modes.notes.append(f"Advice: the first {a['modes']} frequencies within "
                               f"{a['tol']:.1%} need {a['links']} links (worst "
                               f"{a['max_rel_err']:.2e}).")


ADAPTIVE_HOW = "not run: make bench (benchmarks/adaptive_rope.py)"


def _adaptive_label(row: dict) -> str:
    if "eps" in row:
        return (f"grouped by the indicator, eps {row['eps']:g} m, {row['coarsest']}-"
                f"{row['finest']} groups")
    plan = row["plan"]
    return "schedule: " + ", then ".join(
        f"{n} links" + (f" from {t:g} s" if t else "") for t, n in plan)


def adaptive_table(res) -> Table:
    """Does a rope whose resolution follows the motion pay? benchmarks/adaptive_rope.py's
    measurements (docs/design.md, "Adaptive resolution: measured, not built")."""
    t = Table("refine-adaptive", "Resolution that follows the motion, measured: the best static "
              "model against welded and released groups of links and against switched "
              "schedules (work: RHS calls x links)",
              ["scene", "model", "tip error [m]", "within", "work", "work, normalised",
               "groups (mean, max)", "switches", "energy lost at welds [J]",
               "momentum residual"])
    doc = res.bench("adaptive_rope")
    if doc is None:
        t.not_run = ADAPTIVE_HOW
        return t
    for sc in doc["scenes"]:
        tol = sc["tip_tol"]
        best = sc["best_static"]
        for r in sc["static"]:
            t.rows.append(Row([sc["scene"], f"static, {r['links']} links (the rope rebuilt)",
                               _fmt_err(r["error"]), "yes" if r["error"] <= tol else "no",
                               integer(r["work"]), integer(r["work"]), "", "", "", ""],
                              MATCH if r == best else INFO))
        for r in sc["oracle"] + sc["indicator"]:
            t.rows.append(Row([sc["scene"], _adaptive_label(r), _fmt_err(r["error"]),
                               "yes" if r["error"] <= tol else "no", integer(r["work"]),
                               integer(round(r["work_normalised"])),
                               f"{r['mean_groups']:.1f}, {r['max_groups']}",
                               integer(r["switches"]), _fmt_err(r["weld_energy_J"]),
                               _fmt_err(r["momentum_residual"])],
                              DIFFER if r["error"] <= tol and r["work_normalised"]
                              > 0.5 * best["work"] else INFO))
        a = sc.get("best_adaptive")
        t.notes.append(
            f"{sc['scene']} ({sc['case']}, {sc['t_end']:g} s, ode45 {sc['rtol']:g}, tolerance "
            f"{tol:g} m): the best static model meets it with {best['links']} links, work "
            f"{best['work']:,}; " + (f"the cheapest adaptive run that meets it does "
                                     f"{a['work_normalised']:,.0f} normalised, "
                                     f"{a['work_normalised'] / best['work']:.2f}x the static's "
                                     "(the target was 0.5x)" if a else
                                     "no adaptive run meets it") + ".")
    t.notes.append(
        "Static: the scene's rope rebuilt with N uniform links. Grouped: the fine rope's links "
        "welded in groups along a binary tree, split where the accelerations of the joints' "
        "points leave the fine rope's by more than a drift of eps in 0.05 s, welded where "
        "quiet, decided every 0.01 s; a weld is an inelastic impulse that keeps G^T M v (the "
        "momentum residual: its largest violation) and loses the energy shown. Schedule: "
        "uniform models switched at fixed times. Adaptive runs restart ode45's stages at every "
        "sample time: 'normalised' divides their work by that overhead, measured on a fixed "
        "grouping. Green: the best static model; red: an adaptive run within the tolerance "
        "but not at half the static's work. docs/design.md, 'Adaptive resolution: measured, "
        "not built'.")
    t.provenance = "benchmarks/adaptive_rope.py: " + provenance_line(doc.get("provenance"))
    return t


def adaptive_figure(res) -> Figure:
    """Error against work: the static ropes, the grouped runs and the schedules, per scene."""
    title = "Model size: resolution that follows the motion"
    caption = ("Tip-path error against work (RHS calls x links, the adaptive runs' normalised) "
               "for the rope rebuilt at N links (line), the runs grouped by the indicator and "
               "the switched schedules; the dashed line is the scene's tolerance. An adaptive "
               "run pays where it lies left of the static line at the same error; the table's "
               "notes compare the cheapest run within the tolerance with the best static "
               "model.")
    doc = res.bench("adaptive_rope")
    if doc is None:
        return missing("refine-adaptive", "refinement", title, caption, ADAPTIVE_HOW)
    from matplotlib.ticker import NullFormatter

    scenes = doc["scenes"]
    fig, axes = new_figure(len(scenes), width=PANEL_W * len(scenes), height=PANEL_H * 1.2,
                           footer="benchmarks/adaptive_rope.py: "
                                  + provenance_line(doc.get("provenance")))
    for ax, sc in zip(np.atleast_1d(axes), scenes, strict=True):
        st = sorted(sc["static"], key=lambda r: r["work"])
        ax.loglog([r["work"] for r in st], [r["error"] for r in st], "-o", ms=3, color="k",
                  label="static, N links")
        for r in st:
            ax.annotate(str(r["links"]), (r["work"], r["error"]), fontsize=FONT_PT - 3,
                        xytext=(3, 3), textcoords="offset points")
        for rows, marker, label in ((sc["indicator"], "s", "grouped (indicator)"),
                                    (sc["oracle"], "^", "switched schedule")):
            ax.loglog([r["work_normalised"] for r in rows], [r["error"] for r in rows],
                      marker, ls="none", ms=4, label=label)
        ax.axhline(sc["tip_tol"], ls="--", lw=1, color="grey")
        ax.xaxis.set_minor_formatter(NullFormatter())  # (log minor labels overlap)
        ax.set(xlabel="work: RHS calls x links", ylabel="tip-path error [m]",
               title=f"{sc['scene']}: {sc['case']}, {sc['t_end']:g} s")
        ax.legend(fontsize=FONT_PT - 2)
    return _figure("refine-adaptive", "refinement", title, caption, fig)


def own_table(doc: dict) -> Table:
    """``redysim advise CASE``: a rope case's own study (redysim.harness.refine.own_study)."""
    t = Table("refine-own", "redysim advise on a rope case of no study above: its own study, "
              "run for the tolerance", ["what", "value"])
    o = doc.get("own")
    if not o:
        t.not_run = NOT_RAN
        return t
    t.rows.append(Row(["case, horizon, tolerance",
                       f"{o['case']} ({o['links']} links), {o['t_end']:g} s, tip path within "
                       f"{o['tol']:g} m"], INFO))
    t.rows.append(Row(["model error (ode45 1e-8) against the case's own model (DOP853 1e-10, "
                       f"{o['reference_cpu_s']:.3g} s CPU)",
                       ", ".join(f"{d['links']} links {_fmt_err(d['tip_err'])} m"
                                 for d in o["levels"])
                       + ("; local orders " + ", ".join(num(x, 3) for x in o["orders"])
                          if o["orders"] else "; one coarser model: no local order")], INFO))
    if o.get("searched"):
        t.rows.append(Row(["the rope rebuilt between two levels (bisected; ode45 1e-8)",
                           ", ".join(f"{d['links']} links {_fmt_err(d['tip_err'])} m"
                                     for d in o["searched"])], INFO))
    t.rows.append(Row(["the case's own error", (f"{_fmt_err(o['ref_error'])} m: "
                                                if o["ref_error"] is not None else "")
                       + o["ref_error_how"]], INFO))
    for note in o["notes"]:
        t.rows.append(Row(["note", note], INFO))
    a, chk = o["advice"], o["check"]
    if a is None:
        t.rows.append(Row(["advice", "none met the tolerance"], NOT_RUN))
        return t
    bound = chk["bound"] if chk else a["tip_err"] + (o["ref_error"] or 0.0)
    t.rows.append(Row(["advice", f"{a['links']} links, {a['integrator']} rtol {a['rtol']:g}: "
                       f"{seconds(a['cpu_s'])} of CPU, {a['steps']:,} steps"],
                      MATCH if bound <= o["tol"] else DIFFER))
    t.rows.append(Row(["checked (run again)", f"tip error {_fmt_err(chk['tip_err'])} m against "
                       f"the case's model, with its own error {_fmt_err(bound)} m"
                       if chk else "not checked"], MATCH if chk and bound <= o["tol"]
                      else DIFFER))
    if a["finest_cpu_s"] is not None and finite(a["finest_cpu_s"]):
        t.rows.append(Row(["the case's own model at its cheapest setting within the tolerance",
                           f"rtol {a['finest_rtol']:g}, {seconds(a['finest_cpu_s'])} of CPU: "
                           f"{a['saved']:.1f}x the advised run's"], INFO))
    t.notes.append("redysim advise CASE --tip-tol M (harness/refine.py, own_study): the case's "
                   "model and every coarser one (link counts that divide it), the case's own "
                   "error by Richardson where the order is steady or against the rope at twice "
                   "the links, the counts between the last level that misses the tolerance less "
                   "that error and the first that meets it bisected (the rope rebuilt at each), "
                   "then settings on the least count within it; the advice is the least RHS "
                   "calls x links within it. Green: the advice, run again, plus the case's own "
                   "error is within the tolerance.")
    return t


def reduce_table(doc: dict) -> Table:
    """``redysim advise SCENARIO``: the joints a robot's scene can lock (redysim.harness.reduce)."""
    t = Table("refine-reduce", "redysim advise on a robot's scenario: the joints it can lock "
              "for a path tolerance, ranked by their measured effect", ["what", "value"])
    r = doc.get("reduce")
    if not r:
        t.not_run = NOT_RAN
        return t
    if "skipped" in r:
        t.not_run = f"not run: {r['skipped']}"
        return t
    cands = r["candidates"]
    t.rows.append(Row(["scenario, frame, tolerance", f"{r['scenario']} ({r['full_dof']} DOF), "
                       f"the path of {r['frame']!r} over {r['t_end']:g} s within "
                       f"{r['tol']:g} m"], INFO))
    t.rows.append(Row(["each joint locked alone (least effect first)",
                       ", ".join(f"{n} {_fmt_err(e)}" for n, e in cands[:6]) + ", ..., "
                       + ", ".join(f"{n} {_fmt_err(e)}" for n, e in cands[-3:]) + " m"], INFO))
    p = r["practical"]
    ok = bool(r["locked"]) and r["error"] <= r["tol"]
    t.rows.append(Row(["locked together", f"{len(r['locked'])} joints, {r['full_dof']} -> "
                       f"{r['reduced_dof']} DOF: {', '.join(r['locked'])}"], INFO))
    t.rows.append(Row(["their path error (each set run)", f"{_fmt_err(r['error'])} m; the "
                       f"reduced scenario file run on its own: "
                       f"{_fmt_err(r['file_check'])} m from it"], MATCH if ok else DIFFER))
    t.rows.append(Row(["cost at ode45 1e-6", f"reduced {p['reduced']['nfev']:,} RHS calls of "
                       f"{p['reduced']['dof']} DOF, {seconds(p['reduced']['cpu_s'])}; full "
                       f"{p['full']['nfev']:,} of {p['full']['dof']} DOF, "
                       f"{seconds(p['full']['cpu_s'])}; the reduced model's error there "
                       f"{_fmt_err(p['error'])} m"], INFO))
    t.notes.append("redysim advise SCENARIO --tip-tol M (harness/reduce.py): each joint held at "
                   "its initial value (Model.locked, its body fused) and the reduced model run "
                   "by DOP853 1e-10 against the full model's run; then joints locked together, "
                   "least effect first, while the set, run again, stays within the tolerance.")
    return t


def float32_speed_table(res) -> Table:
    """What float32 buys in speed: benchmarks/float32_speed.py's measurements."""
    t = Table("refine-float32-speed", "What float32 buys in speed: qdd per DOF, fresh numba "
              "builds of the same kernel source side by side",
              ["chain", "DOF", "float64", "float32 (as written)", "float32 (strict)",
               "speed-up, strict", "float32 (strict) qdd vs float64"])
    doc = res.bench("float32")
    if doc is None:
        t.not_run = "not run: make bench (benchmarks/float32_speed.py)"
        return t
    for s in doc["sizes"]:
        ns = s["ns_per_dof"]
        diff = s.get("qdd_rel_diff_vs_f64", {}).get("f32-strict", {}).get("normwise")
        t.rows.append(Row([f"{s['kind']} x {s['links']:,}", integer(s["dof"]),
                           f"{ns['f64']:.1f} ns", f"{ns['f32']:.1f} ns",
                           f"{ns['f32-strict']:.1f} ns" if "f32-strict" in ns else "",
                           f"{s['speedup_f64_over_f32-strict']:.2f}x"
                           if "speedup_f64_over_f32-strict" in s else "",
                           _fmt_err(diff)]))
    ir = doc.get("llvm_ir_fp_ops", {}).get("U f32", {})
    ops = ir.get("double_ops", 0) + ir.get("float_ops", 0)
    t.notes.append("float32 (as written): the kernels' source on float32 arrays; numba types "
                   f"its float literals as float64, so {ir.get('double_ops', '?')} of its {ops} "
                   "floating-point operations (U chain, LLVM IR) stay double, with "
                   f"{ir.get('fpext', '?')} conversions: mixed precision, and slower. Strict: "
                   "every literal float32 (an AST rewrite inside the benchmark): all float. "
                   "qdd vs float64: normwise relative difference at a seeded random state. "
                   "Per DOF the recursions are chains of dependent scalar operations, as fast "
                   "in float as in double here; only the planar kernel gains.")
    m = doc.get("machine", {})
    t.provenance = (f"benchmarks/float32_speed.py: {m.get('cpu_model', '')} "
                    f"({m.get('llvm_cpu', '')}), numba {m.get('numba', '')}, numpy "
                    f"{m.get('numpy', '')}, Python {m.get('python', '')}")
    return t


def _kib(mib) -> str:
    return f"{mib * 1024:,.0f} KiB" if mib is not None and finite(mib) else ""


def _dof(run: dict, scene: str) -> int:
    return int(run["n_links"]) * (2 if scene == "spin" else 1)


def _scene_figure(scene: str, s: dict, prov: str) -> Figure:
    """(a) error against links, one line per tolerance (ode45); (b) error against CPU, one line
    per model size across tolerances: the work-precision diagram extended by model size."""
    runs = [r for r in s["runs"] if r["status"] == "ok" and r["precision"] == "float64"
            and r["tip_err"] is not None]
    fig, axes = new_figure(2, width=PANEL_W * 2.6, height=PANEL_H * 1.3, footer=prov)
    rtols = sorted({r["rtol"] for r in runs if r["integrator"] == "ode45"}, reverse=True)
    cmap = _cmap(len(rtols))
    finest = s["convergence"]["finest"]
    for i, rt in enumerate(rtols):
        pts = sorted((r["n_links"], r["tip_err"]) for r in runs
                     if r["integrator"] == "ode45" and r["rtol"] == rt and r["n_links"] < finest)
        if pts:
            x, y = zip(*pts, strict=True)
            axes[0].loglog(x, np.maximum(y, ERROR_FLOOR), "-o", ms=3, color=cmap[i],
                           label=f"ode45 rtol {rt:g}")
    order = s["convergence"]["order"]
    lv = s["convergence"]["levels"]
    fit = [d for d in lv if d["links"] in s["convergence"]["order_levels"]]
    if fit and finite(order):
        n0, e0 = fit[0]["links"], fit[0]["tip_err"]
        xs = np.array([d["links"] for d in lv], dtype=float)
        axes[0].loglog(xs, e0 * (xs / n0) ** -order, "k:", lw=1, label=f"links^-{order:.2f}")
    axes[0].set(xlabel="links", ylabel="max tip error [m]", title="(a) error against model size")
    sizes = sorted({r["n_links"] for r in runs})
    cm2 = _cmap(len(sizes))
    for i, n in enumerate(sizes):
        for integ, style in (("ode45", "-"), ("dop853", "--")):
            pts = sorted((r["rtol"], r["cpu_s"], r["tip_err"]) for r in runs
                         if r["n_links"] == n and r["integrator"] == integ)
            if not pts:
                continue
            _, cpu, err = zip(*pts, strict=True)
            axes[1].loglog(cpu, np.maximum(err, ERROR_FLOOR), style,
                           marker=WP_MARKERS[i % len(WP_MARKERS)], ms=3, color=cm2[i],
                           label=f"{n} links" if integ == "ode45" else None)
    axes[1].set(xlabel="CPU time [s]", ylabel="max tip error [m]",
                title="(b) error against CPU: ode45 (solid), DOP853 (dashed)")
    for ax in axes:
        ax.legend(fontsize=FONT_PT - 2, loc="center left", bbox_to_anchor=(1.0, 0.5))
    caption = (f"{s['title']} ({s['case']}): (a) the tip-path error of the coarser models "
               "against the number of links, one curve per ode45 tolerance (where they "
               "coincide, the model's error is all there is); (b) error against CPU, one curve "
               "per model size across tolerances (rtol 1e-3 to 1e-8; the finest model's "
               "points are its integrator's error alone): the work-precision diagram extended "
               "by model size. Reference: the finest model by DOP853 at 1e-10.")
    return _figure(f"refine-{scene}", "refinement", f"Model size: {s['title']}", caption, fig)


def _modes_figure(hang: dict, prov: str) -> Figure:
    fig, axes = new_figure(1, width=PANEL_W * 1.5, height=PANEL_H * 1.2, footer=prov)
    ax = axes[0]
    links = np.array([lv["links"] for lv in hang["levels"]], dtype=float)
    err = np.array([lv["rel_err"] for lv in hang["levels"]], dtype=float)
    for k in range(hang["modes"]):
        ok = np.isfinite(err[:, k])
        ax.loglog(links[ok], err[ok, k], "-o", ms=3, label=f"mode {k + 1} "
                  f"(p = {hang['orders'][k]:.2f})")
    ax.loglog(links, 0.5 * links ** -2.0, "k:", lw=1, label="links^-2")
    ax.set(xlabel="links", ylabel="|omega - omega_continuum| / omega_continuum",
           title="Hanging chain: frequencies against the continuum's")
    ax.legend(fontsize=FONT_PT - 2)
    caption = ("The first five small-oscillation frequencies of the hanging 1 m chain at 2 to "
               "1,024 links (rod links), relative to the heavy string's (Bessel zeros): "
               "second order in the link length; Richardson from 512 and 1,024 links reaches "
               + ", ".join(f"{e:.1e}" for e in hang["richardson_rel_err"]) + ".")
    return _figure("refine-modes", "refinement", "Model size: hanging chain modes", caption, fig)


def _cmap(n: int):
    import matplotlib

    cmap = matplotlib.colormaps["viridis"]
    return [cmap(x) for x in np.linspace(0.0, 0.9, max(n, 1))]


__all__ = ["refine_section"]
