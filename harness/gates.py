"""Accuracy gates: measure what ``gates.toml`` declares and check each value against its threshold.

    python -m redysim.harness.gates [--only NAME ...] [--json FILE] [--strict] [--list]

Every gate in ``gates.toml`` (beside this module; package data) names a measured quantity, the
measuring function (a key of :data:`MEASURES`), a comparison (``<=``, ``>=``, ``==`` or
``within``), a threshold and the reason for that threshold. This module measures each one, prints a
table (gate, value, threshold, result, where, time, reason) and exits 1 when any gate fails.

A gate whose measurement raises (a broken core that returns NaN, say) is a FAIL row carrying the
error, not a crash: the table always prints. A gate that cannot be measured on this machine (an
engine's package is not installed) is a SKIP row saying why; it is never counted as a pass, and
``--strict`` counts it as a failure. A gate that has used :data:`GATE_TIME_LIMIT_S` of CPU time
is a FAIL row ("time limit"); one still going after :data:`GATE_WALL_GUARD_S` of wall time (it
waits, or the machine is too busy) is given up as a SKIP row: a wall clock decides no result.

The measurements reuse the project's own machinery: :func:`redysim.harness.run.execute` for the
integration gates, :mod:`redysim.harness.reference` for the reference solution (computed afresh
in a temporary results directory: its cache is keyed by the case, not the code),
:mod:`redysim.harness.hiprec` for the 50-digit qdd, the engine adapters of
:mod:`redysim.references` on the chains of :mod:`redysim.harness.random_chains` (those of
``tests/test_engines_agreement.py``).

Exit codes: 0 every gate passed (skips allowed unless ``--strict``), 1 a gate failed, 2 bad usage
or a malformed ``gates.toml`` (the message names the file, the gate and the field).
"""

from __future__ import annotations

import argparse
import contextlib
import fnmatch
import math
import os
import shutil
import signal
import sys
import tempfile
import textwrap
import time
import tomllib
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np

from redysim.algorithms.dynamics import METHODS
from redysim.errors import FieldError

from .provenance import provenance

GATES_FILE = Path(str(resources.files("redysim.harness"))) / "gates.toml"  # package data
RESULTS_ENV = "REDYSIM_RESULTS"  # redysim.harness.reference.results_dir() reads it
COMPARISONS = ("<=", ">=", "==", "within")
PASS, FAIL, SKIP = "pass", "FAIL", "SKIP"
EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2
GATE_FIELDS = {"name", "quantity", "measure", "params", "compare", "threshold", "reason"}
REQUIRED_FIELDS = ("name", "quantity", "measure", "compare", "threshold", "reason")
DEFAULT_WIDTH = 170  # table width when stdout is not a terminal
MIN_REASON_WIDTH = 40  # the reason column wraps, but never narrower than this
MAX_WHERE_WIDTH = 36  # the where column wraps beyond this
# A gate that has used this much CPU time fails with "time limit" and the next one runs: each
# gate takes a small part of it, and a broken core can make an integration crawl for far longer
# (docs/notes/2026-11-costs-in-the-code.md). CPU time, not wall time: a limit that decides a
# gate's result must not depend on the machine's load.
GATE_TIME_LIMIT_S = 300
# Wall time after which a gate is given up for the user's patience only (it waits, or the machine
# is too busy to finish it): a SKIP row that says so, never a measurement or a FAIL.
GATE_WALL_GUARD_S = 3600

# Engine agreement: the chains (joint, links) and states of tests/test_engines_agreement.py.
ENGINE_CHAINS = ("R10", "R50", "U10", "U50")
ENGINE_STATES = (("spread", 0), ("straight", 0))
ENGINE_STAGES = ("gim", "phi", "qdd")


class GatesError(FieldError):
    """A malformed gates file: the message reads ``<file>: <gate>.<field> = <value>: <problem>``."""


class Skip(Exception):
    """Raised by a measure that cannot run here (e.g. an engine package is not installed)."""


# --------------------------------------------------------------------------- the gates file
@dataclass(frozen=True)
class Gate:
    """One ``[[gate]]`` of ``gates.toml``."""

    name: str
    quantity: str
    measure: str
    compare: str
    threshold: float | tuple[float, float]
    reason: str
    params: dict = field(default_factory=dict)

    def check(self, value: float) -> bool:
        """True when ``value`` clears the threshold (NaN never does)."""
        if not math.isfinite(value) and self.compare != "==":
            return False
        if self.compare == "<=":
            return value <= self.threshold
        if self.compare == ">=":
            return value >= self.threshold
        if self.compare == "==":
            return value == self.threshold
        lo, hi = self.threshold
        return lo <= value <= hi

    @property
    def threshold_text(self) -> str:
        return threshold_text(self.compare, self.threshold)


def threshold_text(compare: str, threshold) -> str:
    """``<= 1e-08`` or ``in [lo, hi]``."""
    if compare == "within":
        lo, hi = threshold
        return f"in [{lo:.6g}, {hi:.6g}]"
    return f"{compare} {threshold:.3g}"


def _number(x) -> bool:
    return isinstance(x, int | float) and not isinstance(x, bool) and math.isfinite(x)


def load_gates(path: str | Path = GATES_FILE) -> list[Gate]:
    """The gates of ``path``, validated (a :class:`GatesError` names file, gate, field, value)."""
    src = str(path)
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise GatesError(src, "<toml syntax>", None, str(exc)) from None
    entries = doc.get("gate")
    if set(doc) - {"gate"}:
        raise GatesError(src, sorted(set(doc) - {"gate"})[0], None, "unknown table; use [[gate]]")
    if not isinstance(entries, list) or not entries:
        raise GatesError(src, "gate", entries, "need at least one [[gate]] table")
    gates, seen = [], set()
    for i, e in enumerate(entries):
        where = f"gate[{i}]"
        for k in e:
            if k not in GATE_FIELDS:
                raise GatesError(src, f"{where}.{k}", e[k],
                                 f"unknown field; expected one of {', '.join(sorted(GATE_FIELDS))}")
        for k in REQUIRED_FIELDS:
            if k not in e:
                raise GatesError(src, f"{where}.{k}", None, "missing field")
        name = e["name"]
        if not isinstance(name, str) or not name:
            raise GatesError(src, f"{where}.name", name, "must be a non-empty string")
        where = f"gate {name!r}"
        if name in seen:
            raise GatesError(src, f"{where}.name", name, "duplicate gate name")
        seen.add(name)
        for k in ("quantity", "reason"):
            if not isinstance(e[k], str) or not e[k].strip():
                raise GatesError(src, f"{where}.{k}", e[k], "must be a non-empty string")
        if e["measure"] not in MEASURES:
            raise GatesError(src, f"{where}.measure", e["measure"],
                             f"unknown measure; known: {', '.join(sorted(MEASURES))}")
        if e["compare"] not in COMPARISONS:
            raise GatesError(src, f"{where}.compare", e["compare"],
                             f"must be one of {', '.join(COMPARISONS)}")
        thr = e["threshold"]
        if e["compare"] == "within":
            if not (isinstance(thr, list) and len(thr) == 2 and all(map(_number, thr))
                    and thr[0] <= thr[1]):
                raise GatesError(src, f"{where}.threshold", thr,
                                 "'within' needs [lo, hi], two finite numbers with lo <= hi")
            thr = (float(thr[0]), float(thr[1]))
        elif not _number(thr):
            raise GatesError(src, f"{where}.threshold", thr, "must be a finite number")
        else:
            thr = float(thr)
        params = e.get("params", {})
        if not isinstance(params, dict):
            raise GatesError(src, f"{where}.params", params, "must be a table")
        gates.append(Gate(name, e["quantity"], e["measure"], e["compare"], thr, e["reason"],
                          params))
    return gates


# --------------------------------------------------------------------------- measurements
@dataclass
class Measurement:
    """One measured value of a gate; ``label`` names it when a gate measures several things
    (the row is then ``gate/label``); ``where`` says where the worst value came from."""

    value: float
    label: str = ""
    where: str = ""


def _published() -> dict:
    from redysim import load_published

    return load_published()


def measure_table9(gate: Gate) -> list[Measurement]:
    """Table 9's GIM, phi, qdd (max |round(x, 4) - printed|) or cond2, at STUDY-R3-TABLE9."""
    from redysim import forward_dynamics, load_case, mass_matrix, phi

    item = gate.params["item"]
    case = load_case("STUDY-R3-TABLE9")
    chain, q, v = case.chain, case.q0, case.v0
    if item == "cond2":
        return [Measurement(float(np.linalg.cond(mass_matrix(chain, q))))]
    printed = np.array(_published()["table9"][item])
    if item == "gim":
        got = {"": mass_matrix(chain, q)}
    elif item == "phi":
        got = {"": phi(chain, q, v)}
    elif item == "qdd":
        got = {m: forward_dynamics(chain, q, v, method=m) for m in METHODS}
        got["rge-a spatial"] = forward_dynamics(chain, q, v, planar=False)
    else:
        raise ValueError(f"params.item = {item!r}: one of gim, phi, qdd, cond2")
    diffs = {k: float(np.abs(np.round(x, 4) - printed).max()) for k, x in got.items()}
    worst = max(diffs, key=diffs.get)
    return [Measurement(diffs[worst], where=worst if diffs[worst] > 0 else "")]


def measure_table11_cond2(gate: Gate) -> list[Measurement]:
    """|cond2 - printed| / printed of each Table 11 chain (STUDY-R<links> at q = 0)."""
    from redysim import load_case, mass_matrix

    out = []
    for row in _published()["table11"]["rows"]:
        case = load_case(f"STUDY-R{row['links']}")
        cond = float(np.linalg.cond(mass_matrix(case.chain, case.q0)))
        out.append(Measurement(abs(cond - row["cond2"]) / row["cond2"], f"R{row['links']}",
                               f"{cond:.6g} vs {row['cond2']:g}"))
    return out


def measure_initial_energy(gate: Gate) -> list[Measurement]:
    """|T + V - expected| / expected at each case's initial state."""
    from redysim import energy, load_case

    out = []
    for name, expected in gate.params["cases"].items():
        case = load_case(name)
        T, V = energy(case.chain, case.q0, case.v0)
        out.append(Measurement(abs(T + V - expected) / expected, name, f"E(0) = {T + V:.9g} J"))
    return out


def _worse(new: float, old: float) -> bool:
    """True when ``new`` should replace the worst value so far (a NaN always wins and stays)."""
    return math.isnan(new) or (not math.isnan(old) and new > old)


def _engine_errors(model, eng, stages, states) -> dict[str, tuple[float, str]]:
    """{stage: (max relative difference to the core, the state where it was largest)}."""
    import redysim

    from .random_chains import random_state

    out = {}
    drawn = [random_state(model, kind, seed) for kind, seed in states]
    if "qdd" in stages:  # the core's qdd of every state in one batch
        qdd = redysim.forward_dynamics(model, *(np.array(x) for x in zip(*drawn, strict=True)))
    for stage in stages:
        worst = (-1.0, "")
        for i, (kind, _seed) in enumerate(states):
            q, v, tau = drawn[i]
            if stage == "gim":
                ref, got = redysim.mass_matrix(model, q), eng.mass_matrix(q)
            elif stage == "phi":
                ref, got = redysim.phi(model, q, v), eng.bias(q, v)
            elif stage == "qdd":
                ref, got = qdd[i], eng.qdd(q, v, tau)
            else:
                raise ValueError(f"stage {stage!r}: one of {', '.join(ENGINE_STAGES)}")
            err = float(np.abs(np.asarray(got) - ref).max() / np.abs(ref).max())
            if _worse(err, worst[0]):
                worst = (err, kind)
        out[stage] = worst
    return out


def measure_engine_agreement(gate: Gate) -> list[Measurement]:
    """One row per stage: the max relative difference engine vs core over the chains and states
    (``params``: engine; chains, stages, exclude = [[chain, stage], ...] optional)."""
    from redysim import references

    from .random_chains import engine_test_chain

    name = gate.params["engine"]
    cls = references.get(name)
    if not cls.available():
        raise Skip(f"not installed: engine {name!r} needs the Python package {cls.package!r}")
    chains = gate.params.get("chains", ENGINE_CHAINS)
    stages = gate.params.get("stages", ENGINE_STAGES)
    exclude = {tuple(x) for x in gate.params.get("exclude", ())}
    worst: dict[str, tuple[float, str]] = {s: (-1.0, "") for s in stages}
    for label in chains:
        joint, nl = label[0], int(label[1:])
        todo = [s for s in stages if (label, s) not in exclude]
        if not todo:
            continue
        chain = engine_test_chain(joint, nl)
        errs = _engine_errors(chain, cls(chain), todo, ENGINE_STATES)
        for s, (err, kind) in errs.items():
            if _worse(err, worst[s][0]):
                worst[s] = (err, f"{label} {kind}")
    return [Measurement(v, s if len(stages) > 1 else "", w) for s, (v, w) in worst.items()]


def measure_rge_a_true_error(gate: Gate) -> list[Measurement]:
    """RGE-A's relative 2-norm error against the 50-digit reference of
    :mod:`redysim.harness.hiprec`.

    ``params``: the uniform chain (n_links, joint, link_length, linear_density, radius, inertia)
    and the state, q and v drawn uniformly from (-amplitude, amplitude) by
    ``numpy.random.default_rng(seed)`` (seed a list, as the error study seeds its states).
    """
    from redysim import Chain, forward_dynamics

    from . import hiprec

    p = gate.params
    chain = Chain.uniform(int(p["n_links"]), p["joint"], length=float(p["link_length"]),
                          linear_density=float(p["linear_density"]), radius=float(p["radius"]),
                          inertia=p["inertia"], name=f"{p['joint']}{p['n_links']}")
    rng = np.random.default_rng(p["seed"])
    a, n = float(p["amplitude"]), chain.n_dof
    q, v = rng.uniform(-a, a, n), rng.uniform(-a, a, n)
    ref = hiprec.qdd_reference(chain, q, v, dps=int(p.get("dps", hiprec.DEFAULT_DPS)),
                               output="dd")
    rel2, relmax = hiprec.relative_errors(forward_dynamics(chain, q, v), ref)
    return [Measurement(rel2, where=f"{n:,} DOF; max-norm relative error {relmax:.2g}")]


def _run(spec, *, reference: bool):
    """execute(spec); a failed run raises with its reason (the gate's row shows it)."""
    from .run import execute

    res = execute(spec, reference=reference)
    if not res.ok:
        raise RuntimeError(f"run {spec.label} failed: {res.summary['reason']}")
    return res.summary


def measure_energy_drift(gate: Gate) -> list[Measurement]:
    """Average |delta_M| of one run (``params``: case, t_end, sample, integrator, rtol, atol)."""
    from .spec import RunSpec

    p = gate.params
    spec = RunSpec(case=p["case"], integrator=p["integrator"], rtol=float(p["rtol"]),
                   atol=float(p["atol"]), t_end=float(p["t_end"]), sample=float(p["sample"]))
    row = _run(spec, reference=False)
    return [Measurement(row["avg_abs_delta_M"],
                        where=f"max |delta_M| {row['max_abs_delta_M']:.2g}, {row['steps']} steps")]


_FRESH: list[Path] = []  # the fresh results directory while one is active


@contextlib.contextmanager
def _fresh_results_dir():
    """Point ``REDYSIM_RESULTS`` at a temporary directory for the duration.

    The reference cache is keyed by the case file and the settings, not by the code: a reference
    cached by an older (or broken) core would be reused. A gate computes its reference afresh
    with the code under test, and leaves the project's cache alone. Nested uses share the outer
    directory, so one ``make gates`` computes each reference once.
    """
    if _FRESH:
        yield _FRESH[-1]
        return
    old = os.environ.get(RESULTS_ENV)
    with tempfile.TemporaryDirectory(prefix="redysim-gates-") as tmp:
        _FRESH.append(Path(tmp))
        os.environ[RESULTS_ENV] = tmp
        try:
            yield Path(tmp)
        finally:
            _FRESH.pop()
            if old is None:
                os.environ.pop(RESULTS_ENV, None)
            else:
                os.environ[RESULTS_ENV] = old


def _tip_errors(case_name: str, t_end: float, sample: float, specs) -> list[float]:
    """Max tip error of each run against the reference of (case, t_end, sample), by
    :func:`redysim.harness.run.execute` and :func:`redysim.harness.reference.compute_reference` (the
    reference computed afresh, see :func:`_fresh_results_dir`)."""
    from redysim.io.scenarios import load_scenario

    from .reference import compute_reference

    out = []
    with _fresh_results_dir():
        compute_reference(load_scenario(case_name), t_end, sample)
        for spec in specs:
            err = _run(spec, reference=True)["max_tip_err"]
            if not math.isfinite(err):
                raise RuntimeError(f"{spec.label}: no tip error measured (no reference?)")
            out.append(err)
    return out


def _integration_specs(p: dict, integrator: str, rtols) -> list:
    from .spec import RunSpec

    return [RunSpec(case=p["case"], integrator=integrator, rtol=r, atol=r * float(p["atol_ratio"]),
                    t_end=float(p["t_end"]), sample=float(p["sample"])) for r in rtols]


def measure_integration_error(gate: Gate) -> list[Measurement]:
    """Max tip error [m] against the reference, one row per integrator (``params``: case, t_end,
    sample, integrators, rtol, atol_ratio)."""
    p = gate.params
    out = []
    for integrator in p["integrators"]:
        specs = _integration_specs(p, integrator, [float(p["rtol"])])
        (err,) = _tip_errors(p["case"], float(p["t_end"]), float(p["sample"]), specs)
        out.append(Measurement(err, integrator, f"rtol {specs[0].rtol:g}, atol {specs[0].atol:g}"))
    return out


def measure_work_precision(gate: Gate) -> list[Measurement]:
    """err(tight_rtol) / err(loose_rtol) per integrator, err = the max tip error against the
    reference (``params``: case, t_end, sample, integrators, loose_rtol, tight_rtol,
    atol_ratio)."""
    p = gate.params
    out = []
    for integrator in p["integrators"]:
        specs = _integration_specs(p, integrator, [float(p["loose_rtol"]), float(p["tight_rtol"])])
        loose, tight = _tip_errors(p["case"], float(p["t_end"]), float(p["sample"]), specs)
        ratio = tight / loose if loose > 0 else math.inf
        out.append(Measurement(ratio, integrator, f"tip err {loose:.2g} -> {tight:.2g} m"))
    return out


SCENARIO_COLUMNS = {"path": "max_tip_err", "drift": "max_abs_delta_M",
                    "loop": "residual_q"}


def measure_scenario_runs(gate: Gate) -> list[Measurement]:
    """One value per run of a scenario (``params``: case, t_end, sample, what = "path" (the
    observed path's max error against the reference, computed afresh), "drift" (max
    |delta_M|) or "loop" (the largest loop residual after a step, before its projection), and
    runs = [{engine, integrator, rtol or h}, ...])."""
    from redysim.io.scenarios import load_scenario

    from .reference import compute_reference
    from .spec import RunSpec

    p = gate.params
    column = SCENARIO_COLUMNS[p["what"]]
    out = []
    with _fresh_results_dir():
        if p["what"] == "path":
            compute_reference(load_scenario(p["case"]), float(p["t_end"]), float(p["sample"]))
        for run in p["runs"]:
            tol = float(run.get("rtol", 0.0))
            spec = RunSpec(case=p["case"], engine=run.get("engine", "redysim"),
                           integrator=run["integrator"], rtol=tol, atol=tol * 1e-2,
                           h=float(run.get("h", 0.0)), t_end=float(p["t_end"]),
                           sample=float(p["sample"]))
            row = _run(spec, reference=p["what"] == "path")
            value = float(row[column])
            if not math.isfinite(value):
                raise RuntimeError(f"{spec.label}: no {column} measured")
            setting = f"h {spec.h:g}" if spec.h else f"rtol {spec.rtol:g}"
            out.append(Measurement(value, f"{spec.engine} {spec.integrator} {setting}",
                                   f"{row['steps']} steps"))
    return out


def measure_truth(gate: Gate) -> list[Measurement]:
    """A scenario's exact truth, measured on the core's run (``params``: case, truth, rtol,
    and t_end):

    - "free-fall": the largest distance of the centre of mass from its parabola c0 + cdot0 t +
      g t^2 / 2 [m] (cdot0 from the first sample interval, less its gravity part);
    - "straight-line": the largest second difference of the centre of mass over the samples [m]
      (zero on a line travelled at uniform speed);
    - "flip-period": |measured - closed form| / closed form of the half period of the
      Dzhanibekov flip (the time between sign changes of the body's spin about its middle axis;
      the closed form 2 K(k) / lambda of Landau and Lifshitz, Mechanics, section 37);
    - "momentum": max |h_G(t) - h_G(0)| / max |h_G(0)|, the angular momentum about the centre
      of mass (:func:`redysim.momentum`), kept without external forces but uniform gravity;
    - "mode": the largest |tip_x - x0 cos(omega_1 t)| / |x0| of a hanging chain released from
      its first mode (:func:`redysim.harness.truths.mode_deviation`);
    - "catenary": the observed frame's distance at t_end from its place on the pinned chain's
      static equilibrium [m] (:func:`redysim.harness.truths.catenary_point`; a damped run)
    (harness/truths.py has the closed forms)."""
    import numpy as np

    from redysim.io.scenarios import load_scenario

    from .truths import flip_half_period

    p = gate.params
    scn = load_scenario(p["case"])
    rtol = float(p["rtol"])
    if p["truth"] == "flip-period":
        sim = scn.simulator(float(p["t_end"]), rtol=rtol, atol=rtol * 0.1, sample=1e-3).run()
        w2 = sim.v[:, 4]
        idx = np.flatnonzero(np.sign(w2[1:]) != np.sign(w2[:-1]))
        cross = [sim.t[i] + (sim.t[i + 1] - sim.t[i]) * w2[i] / (w2[i] - w2[i + 1]) for i in idx]
        if len(cross) < 3:
            raise RuntimeError(f"{scn.name}: {len(cross)} flips in {p['t_end']} s; need 3")
        inertia = np.diag(scn.model.inertia_com[0])
        half = flip_half_period(*inertia, scn.v0[3:])  # harness/truths.py
        err = float(np.abs(np.diff(cross) / half - 1.0).max())
        return [Measurement(err, scn.name, f"half period {half:.6f} s, {len(cross)} flips")]
    if p["truth"] == "momentum":
        from redysim.simulation import momentum_observer

        sim = scn.simulator(rtol=rtol, atol=rtol * 0.1,
                            observe={"m": momentum_observer(scn.model)}).run()
        if sim.status != 0:
            raise RuntimeError(f"{scn.name}: {sim.message}")
        h = sim.observed["m"][:, 3:]
        return [Measurement(float(np.abs(h - h[0]).max() / np.abs(h[0]).max()), scn.name,
                            f"{sim.steps} steps, |h_G| {np.linalg.norm(h[0]):.3g} (the model's "
                            "units: kg m^2/s in SI)")]
    if p["truth"] in ("mode", "catenary"):
        from redysim.simulation import frame_observer

        from .truths import catenary_point, mode_deviation

        sim = scn.simulator(rtol=rtol, atol=rtol * 0.1,
                            observe={"p": frame_observer(scn.model, scn.frame)}).run()
        if sim.status != 0:
            raise RuntimeError(f"{scn.name}: {sim.message}")
        pos = sim.observed["p"][:, :3]
        if p["truth"] == "mode":
            dev = mode_deviation(scn.model, scn.q0, sim.t, pos[:, 0])
        else:
            dev = float(np.linalg.norm(pos[-1] - catenary_point(scn.model, scn.frame)))
        return [Measurement(dev, scn.name, f"{sim.steps} steps")]
    sim = scn.simulator(rtol=rtol, atol=rtol * 0.1).run()
    if sim.status != 0:
        raise RuntimeError(f"{scn.name}: {sim.message}")
    t, c, g = sim.t, sim.com, scn.model.gravity
    if p["truth"] == "free-fall":
        cdot0 = (c[1] - c[0]) / (t[1] - t[0]) - 0.5 * g * (t[1] - t[0])
        dev = c - (c[0] + np.outer(t, cdot0) + 0.5 * np.outer(t ** 2, g))
        return [Measurement(float(np.abs(dev).max()), scn.name, f"{sim.steps} steps")]
    second = c[2:] - 2 * c[1:-1] + c[:-2]
    return [Measurement(float(np.abs(second).max()), scn.name, f"{sim.steps} steps")]


MEASURES: dict[str, Callable[[Gate], list[Measurement]]] = {
    "table9": measure_table9,
    "table11_cond2": measure_table11_cond2,
    "initial_energy": measure_initial_energy,
    "engine_agreement": measure_engine_agreement,
    "rge_a_true_error": measure_rge_a_true_error,
    "energy_drift": measure_energy_drift,
    "integration_error": measure_integration_error,
    "work_precision": measure_work_precision,
    "scenario_runs": measure_scenario_runs,
    "truth": measure_truth,
}


# --------------------------------------------------------------------------- running
@dataclass
class Row:
    """One line of the table (and of ``--json``); ``seconds`` is the whole gate's time, on its
    first row."""

    gate: str
    group: str  # the gate's name (rows of one gate share it)
    value: float
    compare: str
    threshold: Any
    result: str  # PASS, FAIL or SKIP
    where: str
    seconds: float
    reason: str
    quantity: str

    @property
    def failed(self) -> bool:
        return self.result == FAIL


class GateTimeout(Exception):
    """A gate used more than its CPU-time limit."""


class GateWallGuard(Exception):
    """A gate ran past the wall-clock guard (the user's patience, not a result)."""


@contextlib.contextmanager
def _time_limit(seconds: float, wall_guard: float = 0.0):
    """Raise :class:`GateTimeout` in the main thread after ``seconds`` of the process's CPU
    time (SIGPROF: user and system time; the numba kernels return to Python at every qdd call,
    so the signal is handled within milliseconds), and :class:`GateWallGuard` after
    ``wall_guard`` seconds of wall time (SIGALRM; 0: none)."""
    if not hasattr(signal, "setitimer"):
        yield
        return

    def expire(_signum, _frame):
        raise GateTimeout(f"time limit: still measuring after {seconds:g} s of CPU time")

    def guard(_signum, _frame):
        raise GateWallGuard(f"given up after {wall_guard:g} s of wall time (the wall-clock "
                            "guard: your patience, not a measurement; the gate waited, or the "
                            "machine was too busy)")

    armed = []
    for which, signum, handler, after in ((signal.ITIMER_PROF, signal.SIGPROF, expire, seconds),
                                          (signal.ITIMER_REAL, signal.SIGALRM, guard,
                                           wall_guard)):
        if after and after > 0:
            armed.append((which, signum, signal.signal(signum, handler)))
            signal.setitimer(which, after)
    try:
        yield
    finally:
        for which, signum, previous in armed:
            signal.setitimer(which, 0)
            signal.signal(signum, previous)


def run_gate(gate: Gate, time_limit_s: float = GATE_TIME_LIMIT_S,
             wall_guard_s: float = GATE_WALL_GUARD_S) -> list[Row]:
    """Measure one gate; an exception (or using more than ``time_limit_s`` of CPU time) becomes
    a FAIL row carrying it, a :class:`Skip` a SKIP row, and running past ``wall_guard_s`` of
    wall time a SKIP row saying so (not measured: the user's patience decides nothing)."""
    t0 = time.perf_counter()

    def row(value, result, where, label=""):
        name = f"{gate.name}/{label}" if label else gate.name
        thr = list(gate.threshold) if isinstance(gate.threshold, tuple) else gate.threshold
        return Row(name, gate.name, value, gate.compare, thr, result, where, math.nan,
                   gate.reason, gate.quantity)

    try:
        with _time_limit(time_limit_s, wall_guard_s):
            measured = MEASURES[gate.measure](gate)
        rows = [row(m.value, PASS if gate.check(m.value) else FAIL, m.where, m.label)
                for m in measured]
    except (Skip, GateWallGuard) as exc:
        rows = [row(math.nan, SKIP, str(exc))]
    except Exception as exc:  # a broken core or engine: a FAIL row, never a crash
        rows = [row(math.nan, FAIL, f"error: {type(exc).__name__}: {exc}")]
    if not rows:
        rows = [row(math.nan, FAIL, "error: the measure returned no value")]
    rows[0].seconds = time.perf_counter() - t0
    return rows


def select(gates: list[Gate], patterns: list[str] | None) -> list[Gate]:
    """The gates whose name matches any pattern (exact or a glob); all when no pattern."""
    if not patterns:
        return gates

    def hit(g, p):
        return g.name == p or fnmatch.fnmatchcase(g.name, p)

    unmatched = [p for p in patterns if not any(hit(g, p) for g in gates)]
    if unmatched:
        raise GatesError("--only", "NAME", unmatched[0],
                         f"no such gate; known: {', '.join(g.name for g in gates)}")
    return [g for g in gates if any(hit(g, p) for p in patterns)]


# --------------------------------------------------------------------------- the table
def _fmt_value(x: float) -> str:
    if math.isnan(x):
        return "-"
    if x == 0:
        return "0"
    return f"{x:.6g}" if 1e-3 <= abs(x) < 1e6 else f"{x:.3e}"


def format_table(rows: list[Row], width: int | None = None) -> str:
    """The rows as a fixed-width table. A gate's reason is printed once, wrapped over its rows
    (and more lines when needed); the ``where`` column wraps within :data:`MAX_WHERE_WIDTH`."""
    width = width or shutil.get_terminal_size((DEFAULT_WIDTH, 24)).columns
    head = ("gate", "value", "threshold", "result", "where", "time")
    cells = [(r.gate, _fmt_value(r.value), threshold_text(r.compare, r.threshold), r.result,
              r.where, "" if math.isnan(r.seconds) else f"{r.seconds:.1f}s") for r in rows]
    widths = [max(len(h), *(len(c[i]) for c in cells)) for i, h in enumerate(head)]
    widths[4] = min(widths[4], MAX_WHERE_WIDTH)
    lead = sum(widths) + 2 * len(widths)
    reason_w = max(MIN_REASON_WIDTH, width - lead)

    def line(parts, reason=""):
        text = "  ".join(x.ljust(w) for x, w in zip(parts, widths, strict=True))
        return (text + "  " + reason).rstrip()

    out = [line(head, "reason"), "-" * (lead + reason_w)]
    i = 0
    while i < len(rows):
        j = i
        while j < len(rows) and rows[j].group == rows[i].group:
            j += 1
        reason = textwrap.wrap(rows[i].reason, reason_w)
        k = 0  # the reason's next line
        for c in cells[i:j]:
            where = textwrap.wrap(c[4], widths[4]) or [""]
            for m, w in enumerate(where):
                parts = [*c[:4], w, c[5]] if m == 0 else ["", "", "", "", w, ""]
                out.append(line(parts, reason[k] if k < len(reason) else ""))
                k += 1
        out.extend(line([""] * len(head), rest) for rest in reason[k:])
        i = j
    return "\n".join(out)


def summary_line(rows: list[Row], seconds: float, strict: bool) -> str:
    """``N rows: P pass, F FAIL, S SKIP in T s``, and the skipped gates by name."""
    n = {k: sum(r.result == k for r in rows) for k in (PASS, FAIL, SKIP)}
    gates = len({r.group for r in rows})
    text = (f"{gates} gates, {len(rows)} rows: {n[PASS]} pass, {n[FAIL]} FAIL, {n[SKIP]} SKIP "
            f"in {seconds:.1f} s")
    skipped = [r.gate for r in rows if r.result == SKIP]
    if skipped:
        text += (f"\nSKIPPED (not measured, not passed{'; --strict: failing' if strict else ''}):"
                 f" {', '.join(skipped)}")
    failed = [r.gate for r in rows if r.result == FAIL]
    if failed:
        text += f"\nFAILED: {', '.join(failed)}"
    return text


# --------------------------------------------------------------------------- command line
def parse_args(argv=None) -> argparse.Namespace:
    ap = argparse.ArgumentParser(prog="python -m redysim.harness.gates", description=__doc__.split(
        "\n\n")[0], formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", action="append", metavar="NAME",
                    help="run only the gates named NAME (a glob such as 'engine.*'; repeatable)")
    ap.add_argument("--json", metavar="FILE", help="also write the rows and provenance to FILE")
    ap.add_argument("--gates", metavar="FILE", default=str(GATES_FILE),
                    help="the gates file (default: the gates that come with redysim, "
                         "harness/gates.toml)")
    ap.add_argument("--strict", action="store_true", help="count a SKIP row as a failure")
    ap.add_argument("--list", action="store_true", help="list the gates and exit")
    return ap.parse_args(argv)


def main(argv=None) -> int:
    a = parse_args(argv)
    try:
        gates = select(load_gates(a.gates), a.only)
    except (GatesError, OSError) as exc:
        print(f"error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    if a.list:
        try:
            for g in gates:
                print(f"{g.name:36s} {g.threshold_text:24s} {g.quantity}", flush=True)
        except BrokenPipeError:  # the reader went away (--list | head): stop quietly
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())  # Python's own flush at exit would fail again
        return EXIT_OK
    t0 = time.perf_counter()
    rows = []
    with _fresh_results_dir():  # every reference solution computed once, by the code under test
        for g in gates:
            rows.extend(run_gate(g))
    total = time.perf_counter() - t0
    print(format_table(rows))
    print(summary_line(rows, total, a.strict))
    if a.json:
        from .store import write_json_atomic

        def finite_or_none(x):
            return None if isinstance(x, float) and not math.isfinite(x) else x

        doc = {"gates_file": str(a.gates), "seconds": total, "provenance": provenance(),
               "rows": [{k: finite_or_none(v) for k, v in asdict(r).items()} for r in rows]}
        write_json_atomic(doc, a.json)
    failed = any(r.failed for r in rows) or (a.strict and any(r.result == SKIP for r in rows))
    return EXIT_FAILED if failed else EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
