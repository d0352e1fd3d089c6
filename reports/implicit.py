"""The implicit integrator on the 100,000-DOF chain: its long run beside the explicit one.

Reads the checkpointed long runs of :data:`CASE` (``results/longrun/<folder>/checkpoint.npz``,
:mod:`redysim.harness.longrun`): the implicit midpoint's (folder ``<case>-midpoint``) and every
ode45 run of the same case (the explicit reference, to a shorter horizon: ~35 ms a step at ~1e-5 s).
The table gives each run's steps, calls, Newton and GMRES iterations, CPU, wall, peak memory, energy
drift and, for the implicit runs, the largest tip distance from the explicit run over the times
both sampled; the figure redraws the paper's Figs. 15 and 17(b) for this case (tip X, Y, Z and
delta_M against time) with both runs, and the tip distance between them.

    python -m redysim.harness.longrun RE-U50000-L1000 --integrator implicit --t-end 5 \
        --sample 0.01                                  # ~1 min
    python -m redysim.harness.longrun RE-U50000-L1000 --t-end 0.48 --sample 0.01 \
        --out results/longrun/RE-U50000-L1000-ode45-0.48   # ~35 min of CPU
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from redysim.integrators.explicit import FIXED_STEP, IMPLICIT

from .content import INFO, NOT_RUN, Figure, Row, Section, Table
from .figures import _figure, missing, new_figure
from .results import LONGRUN_DIR, Results
from .text import integer, provenance_line, sci, seconds

CASE = "RE-U50000-L1000"
HOW = ("not run: make reproduce (python -m redysim.harness.longrun RE-U50000-L1000 "
       "--integrator implicit --t-end 5 --sample 0.01)")
TIP = ["tip_x", "tip_y", "tip_z"]
MATCH_T = 1e-9  # s: samples at the same time


def _runs(res: Results) -> pd.DataFrame:
    runs = res.runs
    if runs.empty or "sweep" not in runs:
        return runs.iloc[:0]
    return runs[(runs["sweep"] == LONGRUN_DIR) & (runs["case"] == CASE)]


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
    sec = Section("implicit", f"The implicit integrator: {CASE} (100,000 DOF) to 5 s")
    sec.intro.append(
        "The explicit integrators' steps on this chain are bound by the transverse waves the "
        "centrifugal tension carries (a 2 cm link crossed in ~3e-5 s: ode45 steps ~1e-5 s, ~35 "
        "ms each, ~10 h for 5 s). The implicit midpoint rule (integrator midpoint, alias "
        "implicit; redysim.integrators.implicit) solves each step by Newton-Krylov in O(n), "
        "preconditioned by the chain's tension stiffness, with an error estimate filtered so "
        "that a wave the step does not resolve counts by its amplitude. Below, its run to 5 s "
        "beside the explicit ode45 run where both exist, at the case's tolerances (rtol 1e-4, "
        "atol 1e-6); docs/design.md, 'The implicit integrator', discusses what the error means.")
    runs = _runs(res)
    table = Table("implicit-runs", f"Long runs of {CASE}",
                  ["run", "integrator", "t reached [s]", "steps (rejected)", "qdd calls",
                   "Newton / GMRES", "CPU", "wall", "peak RSS [MiB]", "max |delta_M| [J/kg]",
                   "max tip distance from ode45 [m]"])
    fig_id, title = "implicit-huge", f"{CASE}: implicit midpoint beside ode45 (Figs. 15, 17b)"
    caption = ("(a)-(c) tip X, Y, Z against time (the paper's Fig. 15, which stops at 0.75 s); "
               "(d) the distance between the two runs' tips at the times both sampled; (e) "
               "|delta_M(t)|, the change of energy per unit mass (Fig. 17b). Solid: implicit "
               "midpoint at the case's tolerances; dashed: ode45 (to the horizon its run "
               "reached). (f) every implicit run in the table: CPU to 5 s against its largest "
               "tip distance from the ode45 run.")
    implicit = runs[runs["integrator"].isin(IMPLICIT)] if len(runs) else runs
    if implicit.empty:
        table.not_run = HOW
        sec.items += [table, missing(fig_id, "tip-path", title, caption, HOW)]
        return sec
    explicit = runs[runs["integrator"] == "ode45"].sort_values("t_reached")
    ref = explicit.iloc[-1] if len(explicit) else None
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
                           f"{CASE} --t-end 0.48 --sample 0.01 makes one (~35 min of CPU).")
    table.provenance = provenance_line(runs, what="results/longrun")
    # the figure: the run at the case's tolerances (folder <case>-midpoint) when there is one
    main = implicit[implicit["run_id"] == f"{LONGRUN_DIR}:{CASE}-midpoint"]
    main = main.iloc[0] if len(main) else implicit.iloc[0]
    sec.items += [table, _figure_of(res, main, implicit, ref_s, fig_id, title, caption,
                                    ref=ref)]
    return sec


def _figure_of(res, imp, implicit, ref_s, fig_id, title, caption, *, ref) -> Figure:
    s = res.samples(imp["run_id"])
    fig, axes = new_figure(3, 2, footer=provenance_line(what="results/longrun"))
    label = _settings(imp)
    for i, (ax, c) in enumerate(zip(axes[:3], TIP, strict=True)):
        ax.plot(s["t"], s[c], "-", label=label)
        if ref_s is not None:
            ax.plot(ref_s["t"], ref_s[c], "--", label=_settings(ref))
        ax.set(xlabel="time [s]", ylabel=f"tip {c[-1].upper()} [m]",
               title=f"({'abc'[i]}) tip {c[-1].upper()}")
    axes[0].legend()
    if ref_s is not None:
        d = tip_distance(s, ref_s)
        d = d[d["t"] > 0]
        if len(d):
            axes[3].semilogy(d["t"], np.maximum(d["distance"], 1e-16), "-o", ms=2)
    axes[3].set(xlabel="time [s]", ylabel="|tip - tip_ode45| [m]",
                title="(d) distance from the ode45 run")
    axes[4].semilogy(s["t"], np.maximum(s["delta_M"].abs(), 1e-16), "-", label=label)
    if ref_s is not None:
        axes[4].semilogy(ref_s["t"], np.maximum(ref_s["delta_M"].abs(), 1e-16), "--",
                         label=_settings(ref))
    axes[4].set(xlabel="time [s]", ylabel="$|\\delta_M(t)|$ [J/kg]", title="(e) energy drift")
    axes[4].legend()
    # (f) every implicit run: its CPU against its largest tip distance from ode45
    for _, r in implicit.iterrows():
        d = tip_distance(res.samples(r["run_id"]), ref_s) if ref_s is not None else None
        if d is not None and len(d) > 1:
            axes[5].loglog(float(r["cpu_s"]), max(float(d["distance"].max()), 1e-16), "o")
            axes[5].annotate(_settings(r).replace("midpoint", "").strip(),
                             (float(r["cpu_s"]), max(float(d["distance"].max()), 1e-16)),
                             fontsize=7, xytext=(3, 3), textcoords="offset points")
    if ref is not None:
        axes[5].set(xlabel="CPU to 5 s [s]",
                    ylabel=f"max |tip - tip_ode45| to {float(ref['t_reached']):.3g} s [m]",
                    title="(f) implicit runs: work against error")
    else:
        axes[5].axis("off")
    return _figure(fig_id, "tip-path", title, caption, fig)
