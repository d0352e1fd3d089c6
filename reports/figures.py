"""The report's figures: the paper's (tip paths, speeds, energy drift, Figs. 3-19) and ours beyond
it (conditioning, CPU scaling, work-precision, true error), as PNG bytes.

Every figure carries a footer with the versions, machine, commit and dates of the data it shows
(:func:`redysim.reports.text.provenance_line`), drawn into the image so it survives copying. A
figure without data is a :class:`~redysim.reports.content.Figure` with ``png = None`` and a
``not_run`` that says which make target produces it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from redysim.harness.spec import CORE, NATIVE  # noqa: E402

from .content import DPI, Figure  # noqa: E402
from .paper_tables import ENGINE_LABELS, Ctx, Pick, make_target  # noqa: E402
from .results import momentum_drift, momentum_kept  # noqa: E402
from .scaling import SLOPE_MIN_DOF, slopes  # noqa: E402
from .text import clip, footer_lines, provenance_line  # noqa: E402

PANEL_W = 4.3          # inches per panel
PANEL_H = 3.0
FOOTER_PT = 6.0        # footer font size
FONT_PT = 8.0
EPS = float(np.finfo(float).eps)
ERROR_FLOOR = 1e-17    # errors of exactly 0 are drawn here on log axes
OPS_DOF = np.unique(np.geomspace(10, 5000, 60).round())  # the paper's Fig. 18(b) runs to 5,000
CORE_LABEL = "redysim (RGE-A)"
WP_MARKERS = "osD^v<>ph*"
FAILED_REASON_CHARS = 90  # a failed run's reason, shortened, in a work-precision caption
LEGEND_PRINT_PT = 7.2  # a legend's text at print size (the PDF's page), at least
PRINT_W_IN = 10.75     # the PDF's figure frame, at most [in] (reports/pdf.py: WIDTH,
PRINT_H_IN = 6.14      # MAX_FIGURE_H; tests/test_report.py checks they agree)

plt.rcParams.update({"font.size": FONT_PT, "axes.titlesize": FONT_PT + 1,
                     "legend.fontsize": FONT_PT - 1, "axes.grid": True, "grid.alpha": 0.3,
                     "lines.linewidth": 1.2})


@dataclass
class Series:
    """One curve's data: a label, the run's samples, the run's summary row."""

    label: str
    samples: pd.DataFrame
    run: pd.Series


def new_figure(ncols: int, nrows: int = 1, *, width: float | None = None,
               height: float | None = None, footer: str = ""):
    """A figure of ``nrows`` x ``ncols`` panels with room for the provenance footer."""
    w = width or PANEL_W * ncols
    h = height or PANEL_H * nrows
    lines = footer_lines(footer, w)
    bottom = (len(lines) * FOOTER_PT * 1.45 + 4) / 72 / h
    fig, axes = plt.subplots(nrows, ncols, figsize=(w, h), squeeze=False)
    fig.set_layout_engine("constrained", rect=(0, bottom, 1, 1 - bottom))
    fig.text(0.005, 0.004, "\n".join(lines), fontsize=FOOTER_PT, color="0.35", va="bottom",
             ha="left", family="monospace")
    return fig, axes.ravel()


def print_scale(fig) -> float:
    """How much the PDF shrinks ``fig`` (its frame: at most PRINT_W_IN x PRINT_H_IN)."""
    w, h = fig.get_size_inches()
    return float(min(PRINT_W_IN / w, PRINT_H_IN / h))


def print_pt(fig, pt: float) -> float:
    """The font size in ``fig`` that prints at ``pt`` points (at least ``pt``)."""
    return pt / min(1.0, print_scale(fig))


def _figure(fid, family, title, caption, fig) -> Figure:
    """The report's figure of the matplotlib figure ``fig`` (released from pyplot's registry:
    it is kept, and rendered when a page asks for it)."""
    w, h = (fig.get_size_inches() * DPI).round().astype(int)
    plt.close(fig)
    return Figure(fid, family, title, caption, fig, width_px=int(w), height_px=int(h))


def missing(fid, family, title, caption, how) -> Figure:
    return Figure(fid, family, title, caption, None, not_run=how)


def series(ctx: Ctx, picks: Sequence[tuple[str, Pick]]) -> list[Series]:
    """The curves of the picks that have samples (shortened runs are labelled so)."""
    out = []
    for label, p in picks:
        if p.run is None:
            continue
        s = ctx.res.samples(p.run["run_id"])
        if s is None or s.empty:
            continue
        short = "" if p.full else f" {p.shortened()}"
        out.append(Series(label + short, s.sort_values("t"), p.run))
    return out


def _footer(curves: Sequence[Series]) -> str:
    return provenance_line(pd.DataFrame([c.run for c in curves]))


def _speed(s: pd.DataFrame, part: str) -> np.ndarray:
    cols = [f"tip_{part}{k}" for k in "xyz"]
    return np.linalg.norm(s[cols].to_numpy(), axis=1)


# --------------------------------------------------------------------------- the paper's figures
def tip_paths(fid: str, title: str, caption: str, curves: list[Series], how: str) -> Figure:
    """Tip X, Y and Z against time, one panel per coordinate, one line per curve."""
    if not curves:
        return missing(fid, "tip-path", title, caption, how)
    fig, axes = new_figure(3, footer=_footer(curves))
    for ax, k in zip(axes, "xyz", strict=True):
        for c in curves:
            ax.plot(c.samples["t"], c.samples[f"tip_{k}"], label=c.label)
        ax.set(xlabel="time [s]", ylabel=f"tip {k.upper()} [m]", title=f"tip {k.upper()}")
    axes[0].legend()
    return _figure(fid, "tip-path", title, caption, fig)


def tip_paths_planar(fid: str, title: str, caption: str, curves: list[Series],
                     how: str) -> Figure:
    """Fig. 3's form: one panel per curve (case), tip X and Y against time."""
    if not curves:
        return missing(fid, "tip-path", title, caption, how)
    fig, axes = new_figure(len(curves), footer=_footer(curves), width=PANEL_W * 1.3 * len(curves))
    for ax, c in zip(axes, curves, strict=True):
        ax.plot(c.samples["t"], c.samples["tip_x"], label="X")
        ax.plot(c.samples["t"], c.samples["tip_y"], label="Y")
        ax.set(xlabel="time [s]", ylabel="tip coordinates [m]", title=c.label)
        ax.legend()
    return _figure(fid, "tip-path", title, caption, fig)


def tip_speed(fid: str, title: str, caption: str, curves: list[Series], how: str) -> Figure:
    """Tip speed and acceleration magnitudes against time (of the runs that sampled them: a
    checkpointed long run keeps positions and energy only)."""
    sampled = [c for c in curves if "tip_vx" in c.samples]
    if not sampled:
        return missing(fid, "tip-speed", title, caption, how if not curves else
                       "no tip speeds: checkpointed long runs (harness.longrun) keep tip "
                       "position and energy only")
    curves = sampled
    fig, axes = new_figure(2, footer=_footer(curves), width=PANEL_W * 2.6)
    for c in curves:
        axes[0].plot(c.samples["t"], _speed(c.samples, "v"), label=c.label)
        axes[1].plot(c.samples["t"], _speed(c.samples, "a"), label=c.label)
    axes[0].set(xlabel="time [s]", ylabel="|v| [m/s]", title="(a) tip velocity magnitude")
    axes[1].set(xlabel="time [s]", ylabel="|a| [m/s$^2$]",
                title="(b) tip acceleration magnitude")
    axes[0].legend()
    return _figure(fid, "tip-speed", title, caption, fig)


def drift(fid: str, title: str, caption: str, panels: list[tuple[str, list[Series]]],
          how: str) -> Figure:
    """delta_M(t), one panel per (title, curves)."""
    panels = [(t, cs) for t, cs in panels if cs]
    if not panels:
        return missing(fid, "drift", title, caption, how)
    every = [c for _, cs in panels for c in cs]
    fig, axes = new_figure(len(panels), footer=_footer(every),
                           width=PANEL_W * max(2.6, 1.3 * len(panels)))
    for ax, (ptitle, cs) in zip(axes, panels, strict=True):
        for c in cs:
            ax.plot(c.samples["t"], c.samples["delta_M"], label=c.label)
        ax.set(xlabel="time [s]", ylabel="$\\delta_M(t)$ [J/kg]", title=ptitle)
        ax.ticklabel_format(axis="y", style="sci", scilimits=(-2, 3))
        ax.legend()
    return _figure(fid, "drift", title, caption, fig)


def plotted_engines(curves: Sequence[Series]) -> list[str]:
    """The reference engines among ``curves`` (their labels, as drawn), the core's left out."""
    return [c.label for c in curves if not c.label.startswith(CORE_LABEL)]


def beside_what(curves: Sequence[Series]) -> str:
    """What a core-and-engines figure draws, from its curves: 'our core beside X and Y' or
    'our core alone (no engine run of this case in the results)'."""
    engines = plotted_engines(curves)
    if not engines:
        return "our core alone (no reference engine's run of this case in the results)"
    return ("our core beside " + (", ".join(engines[:-1]) + " and " if len(engines) > 1 else "")
            + engines[-1])


def paper_order(figs: list[Figure]) -> list[Figure]:
    """The paper's figures in the order of their numbers (fig<N>), so that the print order is
    the numbers' (the loop over Tables 3-5 makes Fig. 12 before Fig. 11)."""
    def number(f: Figure) -> float:
        digits = f.id[3:] if f.id.startswith("fig") else ""
        return float(digits) if digits.isdigit() else float("inf")
    return sorted(figs, key=number)


def _engine_curves(ctx: Ctx, case: str, horizon: float) -> list[tuple[str, Pick]]:
    return [(label, ctx.pick(case, horizon, engine=e)) for e, label in ENGINE_LABELS.items()]


def paper_figures(ctx: Ctx) -> list[Figure]:
    """Figs. 3-5, 7-17 and 19 in the paper's form, from the runs on disk."""
    pub = ctx.pub
    figs = []
    t1 = pub["table1"]
    t1_curves = series(ctx, [(f"dX = {r['dX']:g} m", ctx.pick(f"{t1['case']}-DX{r['dX']:g}",
                                                             r["t_end"])) for r in t1["rows"]])
    how1 = f"not run: {make_target('table1')}"
    figs.append(tip_paths_planar(
        "fig3", "Fig. 3: tip position of RE-R229-L1.02",
        "Tip X and Y of the falling chain for both initial separations (the paper compares with "
        "the experiment of Tomaszewski et al. 2006, which we do not have).", t1_curves, how1))
    figs.append(tip_speed(
        "fig4", "Fig. 4: tip speed and acceleration of RE-R229-L1.02",
        "Peaks near 10-15 m/s and 1,500-2,000 m/s^2 around t = 0.3-0.4 s in the paper for "
        "dX = 1.02 m; samples every 0.05 s miss the sharpest peaks.", t1_curves, how1))
    figs.append(drift("fig5", "Fig. 5: energy drift of RE-R229-L1.02",
                      "delta_M(t) = (E(t) - E(0)) / M; the paper's is of order 1e-5 (dX = 1.02) "
                      "and 1e-6 (dX = 0.765).",
                      [(c.label, [c]) for c in t1_curves], how1))

    case = pub["table2"]["case"]
    h2 = pub["table2"]["rows"][0]["t_end"]
    c7 = series(ctx, [(CORE_LABEL, ctx.pick(case, h2))] + _engine_curves(ctx, case, h2))
    how2 = f"not run: {make_target('table2')}"
    drawn = beside_what(c7)
    figs.append(tip_paths(
        "fig7", f"Fig. 7: tip position of {case}",
        f"Plotted: {drawn}" + (", through the same ode45" if plotted_engines(c7) else "")
        + " (the paper: ReDySim beside RecurDyn). The tip reaches its lowest point near "
        "t = 0.45 s.", c7, how2))
    figs.append(tip_speed(
        "fig8", f"Fig. 8: tip speed and acceleration of {case}",
        f"Plotted: {drawn}. The paper's RecurDyn acceleration departs from ReDySim's after "
        "0.45 s, where joint accelerations reach ~100 g.", c7, how2))
    long = series(ctx, [(CORE_LABEL, ctx.pick(case, pub["table2"]["long_run"]["t_end"],
                                               shorter=False))])
    figs.append(drift(
        "fig9", f"Fig. 9: energy drift of {case}",
        f"(a) 1.0 s, {drawn} (the paper: ReDySim and RecurDyn); (b) "
        f"{pub['table2']['long_run']['t_end']} s, "
        + ("our core" if long else "not drawn: no run of ours to that horizon in the results")
        + f" (the paper's ReDySim drifted "
        f"{pub['table2']['long_run']['redysim_avg_abs_delta_M']} J/kg on average).",
        [("(a) 1.0 s", c7), (f"(b) {pub['table2']['long_run']['t_end']} s", long)], how2))

    for key, fig_path, fig_speed, fig_drift, label in (
            ("table3", "fig10", "fig12", None, "moderate-DOF"),
            ("table4", "fig11", "fig13", "fig14", "large-DOF"),
            ("table5", "fig15", "fig16", "fig17", "huge-DOF")):
        rows = pub[key]["rows"]
        cs = series(ctx, [(r["case"], ctx.pick(r["case"], r["t_end"])) for r in rows])
        how = f"not run: {make_target(key)}"
        num_p = fig_path[3:]
        figs.append(tip_paths(fig_path, f"Fig. {num_p}: tip position of the {label} chains",
                              f"{', '.join(r['case'] for r in rows)} (samples every "
                              f"{ctx.sample} s, as the paper).", cs, how))
        figs.append(tip_speed(fig_speed, f"Fig. {fig_speed[3:]}: tip speed and acceleration "
                                         f"of the {label} chains",
                              "The acceleration peaks when the tip passes its lowest point and "
                              "grows with the chain's length.", cs, how))
        if fig_drift:
            shown = rows[1:] if key == "table4" else [rows[3], rows[4]]
            panel = series(ctx, [(r["case"], ctx.pick(r["case"], r["t_end"])) for r in shown])
            figs.append(drift(fig_drift, f"Fig. {fig_drift[3:]}: energy drift of the {label} "
                                         "chains",
                              "The paper shows these two chains: delta_M of order 1e-5 and "
                              "1e-4 (Fig. 14), bounded by 0.2 J/kg (Fig. 17).",
                              [(c.label, [c]) for c in panel], how))
    figs.append(fig19(ctx))
    return paper_order(figs)


def fig19(ctx: Ctx) -> Figure:
    title = "Fig. 19: energy drift with reduced floating-point accuracy"
    caption = ("delta_M(t) of the study chains under ode45 with every operation of qdd rounded: "
               "(a) 3 links at 1e-3, (b) 10 links at 1e-5 (Table 8's runs). The paper: 3-link "
               "GE-N swings to about -0.06 J/kg, RGE-A stays smallest.")
    doc = ctx.res.precision("table8")
    if doc is None or not doc.get("series"):
        return missing("fig19", "drift", title, caption, f"not run: {make_target('table8')}")
    chains = list(dict.fromkeys(s["chain"] for s in doc["series"]))
    fig, axes = new_figure(len(chains), width=PANEL_W * 2.6,
                           footer=provenance_line(doc.get("meta"),
                                                  what="results/precision/table8.json"))
    for ax, (i, chain) in zip(axes, enumerate(chains), strict=True):
        for s in (s for s in doc["series"] if s["chain"] == chain):
            ax.plot(s["t"], s["delta_M"], label=s["method"])
            acc = s["accuracy"]
        ax.set(xlabel="time [s]", ylabel="$\\delta_M(t)$ [J/kg]",
               title=f"({'ab'[i]}) {chain}, accuracy {acc:g}")
        ax.legend()
    return _figure("fig19", "drift", title, caption, fig)


# --------------------------------------------------------------------------- beyond the paper
def conditioning(ctx: Ctx) -> Figure:
    title = "Conditioning: cond2 of the GIM against the number of links"
    caption = ("cond2 of the GIM at q = 0 (the straight chain) by SVD, for the section-5 study "
               "chain (R) and the RE-U rod (U), beside Featherstone's ~4 nl^4 and the paper's "
               "Tables 9 and 11; dashed: cond2 of the unit upper factor U of RGE-A's "
               "I = U D U^T. Dotted: 1/eps, where double precision has no digit left.")
    df = ctx.res.cond
    if df is None or df.empty:
        return missing("cond", "conditioning", title, caption,
                       "not run: python -m redysim.reports.gim_study (make reproduce)")
    fig, axes = new_figure(1, width=PANEL_W * 1.9, height=PANEL_H * 1.35,
                           footer=provenance_line(df, what="results/gim_study/cond.parquet"))
    ax = axes[0]
    for chain, g in df.groupby("chain"):
        g = g.sort_values("n_links")
        line, = ax.loglog(g["n_links"], g["cond2_gim"], "o-", ms=3,
                          label=f"GIM, {g['what'].iloc[0]}")
        ax.loglog(g["n_links"], g["cond2_udu_U"], "s--", ms=3, color=line.get_color(),
                  label=f"RGE-A factor U, {chain} chain")
    nl = np.geomspace(df["n_links"].min(), df["n_links"].max(), 50)
    ax.loglog(nl, 4 * nl**4, "k-", lw=0.8, label="Featherstone ~4 nl$^4$")
    ax.axhline(1 / EPS, color="0.5", ls=":", lw=0.8, label="1/eps")
    paper = [(3, ctx.pub["table9"]["cond2"])] + [(r["links"], r["cond2"])
                                                 for r in ctx.pub["table11"]["rows"]]
    ax.loglog(*zip(*paper, strict=True), "x", color="k", ms=6, label="paper, Tables 9 and 11")
    ax.set(xlabel="links nl", ylabel="cond2")
    ax.legend(loc="upper left")
    return _figure("cond", "conditioning", title, caption, fig)


def scaling(ctx: Ctx) -> Figure:
    title = "Fig. 18(a): CPU time against DOF, per engine and algorithm"
    caption = ("(a) CPU of one qdd call on U chains (the RE-U rod, seeded small-angle state), "
               f"log-log, with the slope fitted from {SLOPE_MIN_DOF} DOF on; each algorithm stops "
               "at its measured limit or budget (table below). (b) the same per DOF. (c) the "
               "paper's form: CPU of 1.0 s simulations (Table 6's runs, ours beside the "
               "paper's MATLAB times).")
    df = ctx.res.scaling
    if df is None or df.empty:
        return missing("fig18a", "scaling", title, caption,
                       "not run: python -m redysim.reports.scaling (make reproduce, make table6)")
    ok = df[df["status"] == "ok"]
    sl = slopes(df)
    fig, axes = new_figure(3, width=PANEL_W * 3.1, height=PANEL_H * 2.0,
                           footer=provenance_line(df, what="results/scaling/scaling.parquet"))
    for label, g in ok.groupby("algorithm", sort=False):
        name = f"{label} ({'core' if g['engine'].iloc[0] == CORE else 'engine'})"
        slope = f", slope {sl[label]:.2f}" if label in sl else ""
        line, = axes[0].loglog(g["n_dof"], g["seconds_per_call"], "o-", ms=3,
                               label=name + slope)
        axes[1].loglog(g["n_dof"], g["ns_per_dof"], "o-", ms=3, color=line.get_color())
    axes[0].set(xlabel="DOF", ylabel="seconds per qdd call", title="(a) qdd per call")
    axes[1].set(xlabel="DOF", ylabel="ns per DOF", title="(b) per DOF")
    # legends below their panels, outside the data (inside, (a)'s covered the core's curve)
    below = dict(loc="upper center", bbox_to_anchor=(0.5, -0.2), ncols=1,
                 fontsize=print_pt(fig, LEGEND_PRINT_PT))
    axes[0].legend(**below)
    ax = axes[2]
    t6 = ctx.pub["table6"]
    dof = [2 * int(r["case"].split("-")[1][1:]) for r in t6["rows"]]
    ax.loglog(dof, [r["cpu_s_On3"] for r in t6["rows"]], "x--", color="C3",
              label="paper O(n^3) (MATLAB, 2011)")
    ax.loglog(dof, [r["cpu_s_redysim"] for r in t6["rows"]], "x--", color="C0",
              label="paper ReDySim (MATLAB, 2011)")
    for method, color in (("ge-n", "C3"), ("rge-a", "C0")):
        # a shortened run (the quick mode's GE-N to 0.25 s) is drawn hollow, its CPU scaled to
        # the paper's 1.0 s by the simulated time it covered
        pts = [(d, p.value("cpu_s") * t6["t_end"] / float(p.value("t_reached")), p.full)
               for d, r in zip(dof, t6["rows"], strict=True)
               if (p := ctx.pick(r["case"], t6["t_end"], method=method)).ok
               and float(p.value("t_reached")) > 0]
        if pts:
            xs, ys, full = zip(*pts, strict=True)
            ax.loglog(xs, ys, "-", color=color)
            ax.loglog(xs, ys, "o", color=color, mfc="none" if not all(full) else color,
                      label=f"ours {method.upper()}" + ("" if all(full) else
                                                        " (shortened, scaled to 1.0 s)"))
    ax.set(xlabel="DOF", ylabel="CPU [s] for 1.0 s", title="(c) Table 6: 1.0 s simulations")
    ax.legend(**below)
    return _figure("fig18a", "scaling", title, caption, fig)


def op_counts(ctx: Ctx) -> Figure:
    from .paper_tables import parse_count

    title = "Fig. 18(b): arithmetic operations of forward dynamics against DOF"
    caption = ("Multiplications plus additions: the paper's Table 7 formulas (ReDySim for R and "
               "U joints, Mohan and Saha, Featherstone; Lilly and Orin's leading n^3/6) and ours "
               "as counted in our kernels (reports/opcount.py). Log-log: the paper's figure has "
               "linear axes, where every O(n) line lies on the floor.")
    oc = ctx.res.opcount
    t7 = ctx.pub["table7"]
    foot = provenance_line(oc.get("provenance") if oc else None,
                           what="results/opcount/opcount.json")
    fig, axes = new_figure(1, width=PANEL_W * 1.9, height=PANEL_H * 1.3, footer=foot)
    ax = axes[0]
    n = OPS_DOF
    for key, var, label in (("redysim", "nr", "ReDySim, R (paper)"),
                            ("redysim", "nu", "ReDySim, U (paper)"),
                            ("mohan_saha", "n", "Mohan and Saha (paper)"),
                            ("featherstone", "n", "Featherstone (paper)")):
        total = sum(parse_count(t7[key][k]).get(var, 0) * n + parse_count(t7[key][k]).get("", 0)
                    for k in ("mult", "add"))
        ax.loglog(n, total, "--", label=label)
    ax.loglog(n, n**3 / 6, "k--", lw=0.8, label="Lilly and Orin, n$^3$/6 (paper)")
    if oc is not None:
        for f in oc["fits"]:
            total = np.polyval(f["mult_coef"], n) + np.polyval(f["add_coef"], n)
            ax.loglog(n, total, "-", label=f"ours: {f['algorithm']}")
    ax.set(xlabel="DOF n", ylabel="multiplications + additions")
    ax.legend(fontsize=FONT_PT - 2)
    return _figure("fig18b", "opcount", title, caption, fig)


def _wp_label(r: pd.Series) -> str:
    who = CORE if r["engine"] == CORE else r["engine"]
    if r["engine"] == CORE and r["method"] not in ("", "rge-a"):
        who += f"/{r['method']}"
    return f"{who} {r['integrator']}"


def _failed_group(label: str, runs: pd.DataFrame) -> str:
    """'mujoco ode45 (rtol 1e-09, 1e-10): time limit ...' for the failed runs of one curve."""
    key = "h" if runs["h"].astype(float).gt(0).all() else "rtol"
    values = ", ".join(f"{v:g}" for v in sorted(runs[key], reverse=True))
    reason = clip(runs["reason"].iloc[0], FAILED_REASON_CHARS)
    return f"{label} ({key} {values}): {reason}" + (" (the first)" if len(runs) > 1 else "")


def _planned(ctx: Ctx, sweeps, case: str, horizon: float) -> int | None:
    """How many runs of ``case`` to ``horizon`` the plans of ``sweeps`` list (None: no plan)."""
    from .results import case_horizon

    plans = [ctx.res.sweep_plan(str(name)) for name in sweeps]
    if all(p is None for p in plans):
        return None
    ids = {r["run_id"] for p in plans if p for r in p if r["case"] == case and np.isclose(
        float(r["t_end"]) if float(r["t_end"]) > 0 else case_horizon(case), horizon)}
    return len(ids)


def _narrow(ax, ys: list[np.ndarray], what: str) -> None:
    """A log axis over less than a decade draws its ticks as one number repeated (2.43759e-7
    on every tick): draw the deviation from the smallest value instead, that value stated in
    the axis label, on a linear axis without an offset."""
    from matplotlib.ticker import ScalarFormatter

    every = np.concatenate(ys) if ys else np.array([])
    every = every[np.isfinite(every) & (every > 0)]
    if every.size == 0 or every.max() >= 10 * every.min():
        return
    base = float(every.min())
    for line in ax.get_lines():
        y = np.asarray(line.get_ydata(), dtype=float)
        line.set_ydata(y - base)
    ax.set_yscale("linear")
    fmt = ScalarFormatter(useOffset=False)
    fmt.set_powerlimits((-3, 3))
    ax.yaxis.set_major_formatter(fmt)
    ax.relim()
    ax.autoscale_view()
    ax.set_ylabel(f"{what} - {base:.6g}")


# Work-precision figures are drawn at the PDF's text width (landscape A4, 12 mm margins), so
# that the PDF shows them at scale 1 and a legend of WP_LEGEND_PT is that size in print.
WP_WIDTH_IN = 10.7
WP_HEIGHT_IN = 6.0
WP_LEGEND_PT = 7.5
WP_LEGEND_COLUMNS = 4
# a colour family per engine (the core, Pinocchio's three adapters, then the others), a shade per
# integrator within it: the same engine and integrator has the same colour in every figure
WP_ENGINE_MAPS = {CORE: "Blues", "pinocchio": "Greens", "mujoco": "Oranges", "dart": "Purples",
                  "exudyn": "Reds", "drake": "Greys"}
WP_LINESTYLES = ("-", (0, (5, 1, 1, 1)), "-.", ":")


def _wp_family(engine: str) -> str:
    return str(engine).split("-")[0] if str(engine) != CORE else CORE


def _wp_order(label: str) -> tuple[int, bool]:
    """A curve's place in the legend: the engine families in WP_ENGINE_MAPS's order, redysim's
    integrators before the engine's own."""
    fam = list(WP_ENGINE_MAPS)
    engine, _, integrator = label.partition(" ")
    f = _wp_family(engine.split("/")[0])
    return (fam.index(f) if f in fam else len(fam), integrator.startswith(NATIVE))


def wp_styles(runs: pd.DataFrame) -> dict[str, tuple]:
    """(colour, marker, linestyle) of every curve (:func:`_wp_label`) of ``runs``: a colour map
    per engine family (WP_ENGINE_MAPS, grey for another), a shade and a marker per curve within
    it, in sorted order (so the same set of curves is drawn the same way in every figure); an
    engine's own stepper (native:*) dashed, redysim's integrators solid."""
    labels = runs.assign(_label=runs.apply(_wp_label, axis=1)).drop_duplicates("_label")
    out: dict[str, tuple] = {}
    for family, f in labels.groupby(labels["engine"].map(_wp_family)):
        cmap = plt.get_cmap(WP_ENGINE_MAPS.get(family, "Greys"))
        names = sorted(f["_label"])
        for k, label in enumerate(names):
            shade = 0.45 + 0.5 * (k / (len(names) - 1) if len(names) > 1 else 0.5)
            native = label.split(" ", 1)[1].startswith(NATIVE)
            out[label] = (cmap(shade), WP_MARKERS[k % len(WP_MARKERS)],
                          WP_LINESTYLES[1 + k % 3] if native else WP_LINESTYLES[0])
    return out


def work_precision(ctx: Ctx) -> list[Figure]:
    """One figure per (scenario, horizon) of runs measured against a reference solution: the
    observed path's error against CPU time, the core's integrators and the engines' (through
    ode45 and their own), and the energy drift of the same runs beside them. A curve has one
    colour, marker and line style in every panel, named once in the figure's legend. A sweep
    stopped part way is said so (its plan against its finished runs)."""
    runs = ctx.res.runs
    title0 = "Work-precision"
    how = ("not run: make reproduce (sweeps/quick-work-precision.toml, "
           "sweeps/quick-work-precision-robots.toml)")
    if runs.empty or "max_tip_err" not in runs:
        return [missing("wp", "work-precision", title0, "", how)]
    measured = runs[pd.to_numeric(runs["max_tip_err"], errors="coerce").notna()]
    # every scenario measured against its reference gets its diagram (the sweeps run each
    # engine and integrator over a ladder of settings: a curve each)
    groups = list(measured.groupby(["case", "horizon"]))
    if not groups:
        return [missing("wp", "work-precision", title0, "", how)]
    figs = []
    for (case, horizon), g in groups:
        cases = runs[(runs["case"] == case) & np.isclose(runs["horizon"].astype(float), horizon)
                     & runs["sweep"].isin(set(g["sweep"]))]
        failed = cases[cases["status"] != "ok"]
        frame = str(g["frame"].dropna().iloc[0]) if "frame" in g and \
            g["frame"].dropna().astype(str).str.len().gt(0).any() else "tip"
        kept = momentum_kept(str(case))  # a floating system: (d) its angular momentum
        npan = 4 if kept else 3
        fig, axes = new_figure(npan, width=WP_WIDTH_IN, height=WP_HEIGHT_IN,
                               footer=provenance_line(g))
        styles = wp_styles(g)  # one colour and marker per engine and integrator, every panel
        core = g[g["engine"] == CORE]
        handles = {}
        ys: dict[str, list[np.ndarray]] = {"max_abs_delta_M": [], "h_drift": []}
        for label, c in g.groupby(g.apply(_wp_label, axis=1)):
            key = "h" if c["h"].astype(float).gt(0).all() else "rtol"
            c = c.sort_values(key, ascending=False)
            colour, marker, style = styles[label]
            if kept:
                c = c.assign(h_drift=[momentum_drift(ctx.res.samples(r)) for r in c["run_id"]])
            ax = axes[0] if c["engine"].iloc[0] == CORE else axes[1]
            for a, y in ((ax, "max_tip_err"), (axes[2], "max_abs_delta_M")) + \
                    (((axes[3], "h_drift"),) if kept else ()):
                values = np.maximum(c[y].astype(float).to_numpy(), ERROR_FLOOR)
                if y in ys:
                    ys[y].append(values)
                line, = a.loglog(c["cpu_s"], values, linestyle=style, color=colour,
                                 marker=marker, ms=3.5)
                if a is ax:
                    handles[label] = line
        ref = core[core["integrator"] == "ode45"].sort_values("rtol", ascending=False)
        if len(ref):
            handles[f"{CORE} ode45 in (b), for scale"], = axes[1].loglog(
                ref["cpu_s"], np.maximum(ref["max_tip_err"], ERROR_FLOOR), "k:", lw=1.5)
        axes[0].set(title="(a) the core, every integrator")
        axes[1].set(title="(b) every engine")
        axes[2].set(title="(c) energy drift", xlabel="CPU time [s]",
                    ylabel="max |delta_M| [J/kg]")
        _narrow(axes[2], ys["max_abs_delta_M"], "max |delta_M| [J/kg]")
        if kept:
            axes[3].set(title="(d) angular momentum drift", xlabel="CPU time [s]",
                        ylabel="max |h_G - h_G(0)| / |h_G(0)|")
            _narrow(axes[3], ys["h_drift"], "max |h_G - h_G(0)| / |h_G(0)|")
        for ax in axes[:2]:
            ax.set(xlabel="CPU time [s]", ylabel=f"max {frame} error [m]")
        # the legend below the panels, above the footer: the panels' rect is raised by its rows
        order = sorted(handles, key=lambda lab: (_wp_order(lab), lab))
        rows = -(-len(order) // WP_LEGEND_COLUMNS)
        foot = len(footer_lines(provenance_line(g), WP_WIDTH_IN)) * FOOTER_PT * 1.45 + 4
        low = (foot + rows * WP_LEGEND_PT * 1.45 + 6) / 72 / WP_HEIGHT_IN
        fig.set_layout_engine("constrained", rect=(0, low, 1, 1 - low))
        fig.legend([handles[k] for k in order], order, loc="upper center",
                   bbox_to_anchor=(0.5, low), ncol=WP_LEGEND_COLUMNS, fontsize=WP_LEGEND_PT,
                   frameon=False, handlelength=3.0, borderaxespad=0.0, borderpad=0.2,
                   labelspacing=0.3)
        gone = "; ".join(_failed_group(label, f) for label, f in
                         failed.groupby(failed.apply(_wp_label, axis=1), sort=False)) \
            if len(failed) else ""
        planned = _planned(ctx, set(g["sweep"]), str(case), float(horizon))
        partial = planned is not None and len(cases) < planned
        path = "tip" if frame == "tip" else f"observed frame ({frame})"
        caption = ((f"Partial sweep: {len(cases)} of the {planned} runs its plan lists "
                    f"(sweeps/{', '.join(sorted(set(g['sweep'])))}/sweep.json) finished; the "
                    "others are not drawn. " if partial else "")
                   + f"{case} over {horizon:g} s: error = the largest distance of the {path} "
                   "from the reference solution (DOP853 at 1e-10, checked by SciPy's DOP853 at "
                   "1e-13) over the samples, against CPU time; one curve per engine and "
                   "integrator, points from loose to tight tolerance (or large to small step), "
                   "each with one colour in every panel (a hue per engine; solid: redysim's "
                   "integrators with the engine's qdd, dashed: the engine's own); (c): the "
                   "largest energy drift per unit mass of the same runs (a symplectic stepper can "
                   "keep it small while its path is far off)"
                   + ("; (d): the largest change of the angular momentum about the centre of "
                      "mass over its size, kept exactly by the floating system (redysim.momentum "
                      "of the runs' states)" if kept else "") + "."
                   + (" A panel whose values span less than a decade draws their deviation from "
                      "the smallest, stated in its axis label." if any(
                          a.get_yscale() == "linear" for a in axes[2:4 if kept else 3])
                      else "")
                   + (f" Failed runs (not drawn): {gone}." if gone else ""))
        title = f"{title0}: {case}, {horizon:g} s" + (
            f" (partial sweep: {len(cases)} of {planned} runs)" if partial else "")
        figs.append(_figure(f"wp-{case}-{horizon:g}", "work-precision", title, caption, fig))
    # a planned scenario of these sweeps without a finished run: said, not silently left out
    from .results import case_horizon

    for name in sorted(set(measured["sweep"])):
        made = runs[runs["sweep"] == name]
        done = {(str(c), float(h)) for c, h in zip(made["case"], made["horizon"], strict=True)}
        left: dict[tuple[str, float], int] = {}
        for r in ctx.res.sweep_plan(str(name)) or []:
            h = float(r["t_end"]) if float(r["t_end"]) > 0 else case_horizon(r["case"])
            if not any(c == r["case"] and np.isclose(h, d) for c, d in done):
                left[(r["case"], h)] = left.get((r["case"], h), 0) + 1
        for (c, h), n in left.items():
            figs.append(missing(f"wp-{c}-{h:g}", "work-precision",
                                f"{title0}: {c}, {h:g} s (partial sweep: 0 of {n} runs)", "",
                                f"not drawn: none of the {n} runs sweeps/{name}/sweep.json "
                                "plans for it finished (the sweep stopped part way; make "
                                "reproduce resumes it)"))
    return figs


def true_error(ctx: Ctx, config: str = "stretched") -> Figure:
    fid = "true-error" if config == "stretched" else f"true-error-{config}"
    where = {"stretched": "the straight chain (q = 0, where cond2 is largest)",
             "random": "a seeded random state (q, qd ~ U(-0.3, 0.3))"}[config]
    title = ("True error of qdd against a 50-digit reference"
             + ("" if config == "stretched" else ", random state"))
    caption = (f"||qdd - ref||_2 / ||ref||_2 in double precision on {where}, per method and "
               "engine, against DOF; dashed: eps x cond2(GIM), the error a backward-stable "
               "dense solve may have. rge-a-phi: Table A.1 as printed (gravity and velocity "
               "terms inside phi), beside the core's rge-a.")
    df = ctx.res.error_study
    if df is None or df.empty:
        return missing(fid, "true-error", title, caption,
                       "not run: python -m redysim.harness.error_study (make reproduce)")
    sel = df[(df["precision"] == "float64") & (df["config"] == config)
             & (df["status"] == "ok")]
    chains = sorted(set(sel["chain"]))
    methods = list(dict.fromkeys(sel["method"]))
    if not chains:
        return missing(fid, "true-error", title, caption,
                       "no finished double-precision rows in results/error_study")
    fig, axes = new_figure(len(chains), width=PANEL_W * 1.35 * len(chains) + 2.0,
                           height=PANEL_H * 1.4,
                           footer=provenance_line(df, what="results/error_study"))
    for ax, chain in zip(axes, chains, strict=True):
        g = sel[sel["chain"] == chain]
        for method, m in g.groupby("method", sort=False):
            i = methods.index(method)  # the same colour and marker for a method in every panel
            m = m.sort_values("n_dof")
            ax.loglog(m["n_dof"], np.maximum(m["rel2"], ERROR_FLOOR), "-",
                      marker=WP_MARKERS[i % len(WP_MARKERS)], color=plt.cm.tab20(i % 20), ms=3,
                      label=method)
        c = g.drop_duplicates("n_dof").sort_values("n_dof")
        cond = c["cond2"].fillna(c["cond2_lanczos"])  # the SVD's where there is one
        ax.loglog(c["n_dof"], np.minimum(EPS * cond, 1.0), "k--", lw=0.8,
                  label="eps x cond2 (capped at 1)")
        ax.set(xlabel="DOF", ylabel="relative error",
               title=f"{chain} chain, " + ("q = 0" if config == "stretched" else "random"))
    handles = {}
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(lab, h)
    fig.legend(handles.values(), handles.keys(), loc="outside right center",
               fontsize=FONT_PT - 1.5)
    return _figure(fid, "true-error", title, caption, fig)
