"""The implicit integrator on the 100,000- and 1,000,000-DOF chains: long runs beside the
explicit ones, and one step's cost against DOF.

Reads the checkpointed long runs of :data:`CASE` and :data:`MEGA`
(``results/longrun/<folder>/checkpoint.npz``, :mod:`redysim.harness.longrun`): the implicit
midpoint's and every ode45 run of the same case (the explicit reference, to a shorter horizon:
~35 ms a step at ~1e-5 s on CASE, ~0.4 s at ~1e-6 s on MEGA). Each case's table gives each run's
steps, calls, Newton and GMRES iterations, CPU, wall, peak memory, energy drift and, for the
implicit runs, the largest tip distance from the explicit run over the times both sampled; its
figure redraws the paper's Figs. 15 and 17(b) (tip X, Y, Z and delta_M against time) with both
runs, and the tip distance between them. Then :mod:`.implicit_scaling`'s table and figure (its
``results/implicit_scaling.json``).

    python -m redysim.harness.longrun RE-U50000-L1000 --integrator implicit --t-end 5 \
        --sample 0.01                                  # ~1 min
    python -m redysim.harness.longrun RE-U50000-L1000 --t-end 0.48 --sample 0.01 \
        --out results/longrun/RE-U50000-L1000-ode45-0.48   # ~35 min of CPU
    python -m redysim.harness.longrun cases/huge/RE-U500000-L10000.toml --sample 0.001 \
        --out results/longrun/RE-U500000-L10000-midpoint-1   # ~1 min, 1.8 GiB
"""

from __future__ import annotations

import json

import numpy as np
import pandas as pd

from redysim.integrators.explicit import FIXED_STEP, IMPLICIT

from .content import INFO, NOT_RUN, Figure, Row, Section, Table
from .figures import _figure, missing, new_figure
from .results import LONGRUN_DIR, Results
from .text import integer, provenance_line, sci, seconds

CASE = "RE-U50000-L1000"
MEGA = "RE-U500000-L10000"  # 1,000,000 DOF: the same rod ten times as long
MEGA_FILE = f"huge/{MEGA}.toml"  # under cases/
TIP = ["tip_x", "tip_y", "tip_z"]
MATCH_T = 1e-9  # s: samples at the same time


def _runs(res: Results, case: str = CASE) -> pd.DataFrame:
    runs = res.runs
    if runs.empty or "sweep" not in runs:
        return runs.iloc[:0]
    return runs[(runs["sweep"] == LONGRUN_DIR) & (runs["case"] == case)]


def tip_distance(a: pd.DataFrame, b: pd.DataFrame) -> pd.DataFrame:
    """|tip_a - tip_b| at the times both sampled (columns t, distance)."""
    m = pd.merge_asof(a.sort_values("t"), b.sort_values("t"), on="t", direction="nearest",
                      tolerance=MATCH_T, suffixes=("", "_ref")).dropna(subset=["tip_x_ref"])
    d = np.linalg.norm(m[TIP].to_numpy() - m[[f"{c}_ref" for c in TIP]].to_numpy(), axis=1)
    return pd.DataFrame({"t": m["t"].to_numpy(), "distance": d})


def _settings(r) -> str:
    if r["integrator"] in FIXED_STEP:
        return f"{r['integrator']} h {float(r['h']):g}"
    return f"{r['integrator']} rtol {float(r['rtol']):g} atol {float(r['atol']):g}"


def implicit_section(res: Results) -> Section:
    sec = Section("implicit", f"The implicit integrator: {CASE} (100,000 DOF) to 5 s, and "
                  f"{MEGA} (1,000,000 DOF)")
    sec.intro.append(
        "The explicit integrators' steps on this chain are bound by the transverse waves the "
        "centrifugal tension carries (a 2 cm link crossed in ~3e-5 s: ode45 steps ~1e-5 s, ~35 "
        "ms each, ~10 h for 5 s). The implicit midpoint rule (integrator midpoint, alias "
        "implicit; redysim.integrators.implicit) solves each step by Newton-Krylov in O(n), "
        "preconditioned by the chain's tension stiffness, with an error estimate filtered so "
        "that a wave the step does not resolve counts by its amplitude. Below, its run to 5 s "
        "beside the explicit ode45 run where both exist, at the case's tolerances (rtol 1e-4, "
        "atol 1e-6); then the same rod ten times as long, cut into the same 20 mm links "
        f"({MEGA}: 500,000 U joints, 1,000,000 DOF), and the CPU and memory of one step against "
        "DOF from 1,000 to 1,000,000. docs/notes/2026-11-implicit-integrator.md discusses what "
        "the error means.")
    sec.items += _case_items(res, CASE, "implicit-huge", f"{CASE}: implicit midpoint{{beside}} "
                             "(Figs. 15, 17b)", "--t-end 5 --sample 0.01",
                             "--t-end 0.48 --sample 0.01")
    sec.items += _case_items(res, MEGA, "implicit-mega", f"{MEGA} (1,000,000 DOF): implicit "
                             "midpoint{beside}", "--t-end 1 --sample 0.001",
                             "--t-end 0.01 --sample 0.001")
    sec.items += _scaling_items(res)
    return sec


def _case_items(res: Results, case: str, fig_id: str, title: str, run_flags: str,
                ref_flags: str) -> list:
    """The table of ``case``'s long runs and the figure of its run at the case's tolerances
    (folder ``<case>-midpoint``) beside its longest ode45 run if there is one (``run_flags``,
    ``ref_flags``: the long run's flags that make each). ``title``'s ``{beside}``: ' beside
    ode45' when an ode45 run is drawn, else nothing."""
    source = f"cases/{MEGA_FILE}" if case == MEGA else case
    how = (f"not run: make reproduce (python -m redysim.harness.longrun {source} "
           f"--integrator implicit {run_flags})")
    runs = _runs(res, case)
    table = Table(f"{fig_id}-runs", f"Long runs of {case}",
                  ["run", "integrator", "t reached [s]", "steps (rejected)", "qdd calls",
                   "Newton / GMRES", "CPU", "wall", "peak RSS [MiB]", "max |delta_M| [J/kg]",
                   "max tip distance from ode45 [m]"])
    implicit = runs[runs["integrator"].isin(IMPLICIT)] if len(runs) else runs
    explicit = runs[runs["integrator"] == "ode45"].sort_values("t_reached") if len(runs) \
        else runs
    ref = explicit.iloc[-1] if len(explicit) else None
    title = title.format(beside=" beside ode45" if ref is not None else "")
    caption = _caption(ref is not None)
    if implicit.empty:
        table.not_run = how
        return [table, missing(fig_id, "tip-path", title, caption, how)]
    ref_s = res.samples(ref["run_id"]) if ref is not None else None
    for _, r in pd.concat([implicit, explicit]).iterrows():
        s = res.samples(r["run_id"])
        dist = ""
        if r["integrator"] in IMPLICIT and ref_s is not None:
            d = tip_distance(s, ref_s)
            if len(d) > 1:
                dist = f"{sci(d['distance'].max())} (to t = {d['t'].max():.3g} s)"
        newton = (f"{integer(r['newton'])} / {integer(r['krylov'])}"
                  if r["integrator"] in IMPLICIT else "")
        table.rows.append(Row([r["run_id"].split(":", 1)[1], _settings(r),
                               f"{float(r['t_reached']):.4g} of {float(r['t_end']):g}",
                               f"{integer(r['steps'])} ({integer(r['rejected'])})",
                               integer(r["nfev"]), newton, seconds(r["cpu_s"]),
                               seconds(r["wall_s"]), f"{float(r['peak_rss_mib']):,.0f}",
                               sci(r["max_abs_delta_M"]), dist],
                              INFO if r["status"] == "ok" else NOT_RUN))
    table.notes.append("CPU and wall: the runs' own (harness.longrun), JIT compile excluded; "
                       "peak RSS: the process's, numba's compiled kernels included. The "
                       "implicit run's Newton and GMRES counts are those of its last session "
                       "(a resumed run restarts them).")
    if ref is None:
        table.notes.append("No ode45 long run of this case: python -m redysim.harness.longrun "
                           f"{source} {ref_flags} makes one (make reproduce-full).")
    table.provenance = provenance_line(runs, what="results/longrun")
    # the figure's run: at the case's tolerances (folder <case>-midpoint), else the longest
    main = implicit[implicit["run_id"] == f"{LONGRUN_DIR}:{case}-midpoint"]
    main = main.iloc[0] if len(main) else \
        implicit.sort_values("t_reached", kind="stable").iloc[-1]
    return [table, _figure_of(res, main, implicit, ref_s, fig_id, title, caption, ref=ref)]


def _caption(with_ode45: bool) -> str:
    """The long-run figure's caption, its panels lettered as :func:`_figure_of` draws them."""
    if with_ode45:
        return ("(a)-(c) tip X, Y, Z against time; (d) the distance between the two runs' tips "
                "at the times both sampled; (e) |delta_M(t)|, the change of energy per unit "
                "mass (Fig. 17b). Solid: implicit midpoint at the case's tolerances; dashed: "
                "ode45 (to the horizon its run reached). (f) every implicit run in the table: "
                "its CPU against its largest tip distance from the ode45 run.")
    return ("(a)-(c) tip X, Y, Z against time; (d) |delta_M(t)|, the change of energy per unit "
            "mass (Fig. 17b); the implicit midpoint at the case's tolerances. No ode45 run of "
            "this case in the results, so no distance between the two (the table's note says "
            "how to make one).")


def _scaling_items(res: Results) -> list:
    """The table and figure of :mod:`.implicit_scaling`'s document, when it has run."""
    from .implicit_scaling import RESULT_FILE

    fig_id, title = "implicit-scaling", "One implicit step against DOF: CPU and memory"
    caption = ("(a) CPU per step and per qdd call (the step's CPU over its qdd calls) against "
               "DOF; (b) peak RSS above the process's before the chain was built. Dotted: "
               "slope 1 (O(n)).")
    table = Table("implicit-scaling-table", "Implicit steps against DOF (midpoint-fixed from "
                  "the straight spinning rod)",
                  ["DOF", "h [s]", "steps", "qdd calls", "Newton / GMRES", "CPU per step",
                   "CPU per qdd call", "peak RSS [MiB]", "RSS before the chain [MiB]"])
    path = res.root / RESULT_FILE
    how = "not run: make reproduce (python -m redysim.reports.implicit_scaling)"
    if not path.is_file():
        table.not_run = how
        return [table, missing(fig_id, "scaling", title, caption, how)]
    doc = json.loads(path.read_text())
    rows = doc["rows"]
    for r in rows:
        table.rows.append(Row([integer(r["n_dof"]), f"{r['h']:g}", integer(r["steps"]),
                               integer(r["qdd_calls"]),
                               f"{integer(r['newton'])} / {integer(r['krylov'])}",
                               seconds(r["cpu_per_step_s"]),
                               f"{r['cpu_per_call_ms']:.3g} ms",
                               f"{r['rss_peak_mib']:,.0f}", f"{r['rss_before_mib']:,.0f}"],
                              INFO))
    if doc.get("slopes"):
        sl = {k: "n/a" if v is None or not np.isfinite(v) else f"{v:.2f}"
              for k, v in doc["slopes"].items()}
        table.notes.append(
            "Log-log slopes against DOF (1: O(n)): CPU per qdd call "
            f"{sl['cpu_per_call_ms']}, per step {sl['cpu_per_step_s']} (the Newton and GMRES "
            f"counts vary with the chain), memory added {sl['rss_added_mib']}; the fixed costs "
            "(Python around the kernels, the kernels' own memory) weigh at the small sizes."
            + _last_two(rows) + " Each size in a fresh process; CPU is the process's own "
            "(time.process_time), so a busy machine changes the wall time, not these.")
    table.provenance = provenance_line(doc, what=RESULT_FILE)
    dof = np.array([r["n_dof"] for r in rows], dtype=float)
    fig, axes = new_figure(1, 2, footer=table.provenance)
    per_step = np.array([r["cpu_per_step_s"] for r in rows])
    per_call = np.array([r["cpu_per_call_ms"] for r in rows]) / 1e3
    added = np.array([r["rss_peak_mib"] - r["rss_before_mib"] for r in rows])
    axes[0].loglog(dof, per_step, "o-", label="CPU per step")
    axes[0].loglog(dof, per_call, "s-", label="CPU per qdd call")
    axes[0].loglog(dof, per_step[-1] * dof / dof[-1], ":", color="grey", label="slope 1")
    axes[0].set(xlabel="DOF", ylabel="CPU [s]", title="(a) CPU")
    axes[0].legend()
    shown = added > 0  # a small chain may add nothing to the imports' high-water mark
    if shown.any():
        axes[1].loglog(dof[shown], added[shown], "o-")
        axes[1].loglog(dof, added[shown][-1] * dof / dof[shown][-1], ":", color="grey")
    axes[1].set(xlabel="DOF", ylabel="peak RSS added [MiB]", title="(b) memory")
    return [table, _figure(fig_id, "scaling", title, caption, fig)]


def _last_two(rows: list[dict]) -> str:
    """The growth between the two largest sizes, where the fixed costs weigh least."""
    if len(rows) < 2:
        return ""
    a, b = rows[-2], rows[-1]
    f = b["n_dof"] / a["n_dof"]
    added = [r["rss_peak_mib"] - r["rss_before_mib"] for r in (a, b)]
    mem = f", memory added {added[1] / added[0]:.1f}x" if added[0] > 0 else ""
    return (f" From {integer(a['n_dof'])} to {integer(b['n_dof'])} DOF ({f:.3g}x): CPU per "
            f"qdd call {b['cpu_per_call_ms'] / a['cpu_per_call_ms']:.1f}x, per step "
            f"{b['cpu_per_step_s'] / a['cpu_per_step_s']:.1f}x{mem}.")


def _figure_of(res, imp, implicit, ref_s, fig_id, title, caption, *, ref) -> Figure:
    """Tip X, Y, Z, the distance from the ode45 run, the energy drift and the implicit runs'
    work against error: the panels comparing with ode45 only when there is an ode45 run (no
    empty panel), lettered in the order drawn."""
    s = res.samples(imp["run_id"])
    both = ref_s is not None
    fig, axes = new_figure(3 if both else 2, 2, footer=provenance_line(what="results/longrun"))
    letters = iter("abcdef")
    label = _settings(imp)
    for ax, c in zip(axes[:3], TIP, strict=True):
        ax.plot(s["t"], s[c], "-", label=label)
        if both:
            ax.plot(ref_s["t"], ref_s[c], "--", label=_settings(ref))
        ax.set(xlabel="time [s]", ylabel=f"tip {c[-1].upper()} [m]",
               title=f"({next(letters)}) tip {c[-1].upper()}")
    axes[0].legend()
    rest = list(axes[3:])
    if both:
        ax = rest.pop(0)
        d = tip_distance(s, ref_s)
        d = d[d["t"] > 0]
        if len(d):
            ax.semilogy(d["t"], np.maximum(d["distance"], 1e-16), "-o", ms=2)
        ax.set(xlabel="time [s]", ylabel="|tip - tip_ode45| [m]",
               title=f"({next(letters)}) distance from the ode45 run")
    ax = rest.pop(0)
    ax.semilogy(s["t"], np.maximum(s["delta_M"].abs(), 1e-16), "-", label=label)
    if both:
        ax.semilogy(ref_s["t"], np.maximum(ref_s["delta_M"].abs(), 1e-16), "--",
                    label=_settings(ref))
    ax.set(xlabel="time [s]", ylabel="$|\\delta_M(t)|$ [J/kg]",
           title=f"({next(letters)}) energy drift")
    ax.legend()
    if both:  # every implicit run: its CPU against its largest tip distance from ode45
        ax = rest.pop(0)
        for _, r in implicit.iterrows():
            d = tip_distance(res.samples(r["run_id"]), ref_s)
            if len(d) > 1:
                ax.loglog(float(r["cpu_s"]), max(float(d["distance"].max()), 1e-16), "o")
                ax.annotate(_settings(r).replace("midpoint", "").strip(),
                            (float(r["cpu_s"]), max(float(d["distance"].max()), 1e-16)),
                            fontsize=7, xytext=(3, 3), textcoords="offset points")
        ax.set(xlabel="CPU to the run's end [s]",
               ylabel=f"max |tip - tip_ode45| to {float(ref['t_reached']):.3g} s [m]",
               title=f"({next(letters)}) implicit runs: work against error")
    return _figure(fig_id, "tip-path", title, caption, fig)
