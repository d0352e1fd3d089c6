"""Execute one run: a scenario, simulated by one engine and algorithm with one integrator.

:func:`execute` never raises for a run that goes wrong: a NaN, an energy blow-up past the spec's
bound, an engine's refusal or a missing package, the spec's CPU-time limit, any exception: the
result's ``status`` is ``"failed"`` and ``reason`` says why, with the samples finished before it.
A run stopped by the caller's wall-clock limit (``execute(max_wall_s=...)``: the user's patience,
``redysim simulate --max-wall``) is ``"stopped"``: not a result, and never kept as one by a
sweep (which sets no wall-clock limit).

Per sample (the spec's interval): the observed path's position, velocity and acceleration (the
``tip_*`` columns: a rope's tip, or the scenario's first observed frame, named in the row's
``frame``), E = T + V, delta_M = (E - E0) / M (Eq. 11; for a damped scenario stepped by the
core's Runge-Kutta integrators the balance (E - W - E0) / M, W the dampers' work stepped with the
motion: :class:`redysim.simulation.Simulation`'s ``work``) and the centre of mass, all computed by
the core from the run's state (a measurement, the same for every engine). The path's
acceleration needs qdd at the sample: one extra call of the run's own qdd per sample, not
counted in ``nfev`` (the integrator's count).

Per run: the model's size (links, DOF, and for the core the bytes of its Workspace: every array
the kernels read or write), steps, rejected steps, RHS evaluations, CPU and wall time of the
integration, the JIT compile (or cache load) of the first qdd call and an engine's model build,
both timed apart and excluded from ``cpu_s``/``wall_s``; the integration's cost by
:mod:`redysim.harness.cost` (``cost_s``: the least CPU of repeated runs, the sampling's
``sample_cpu_s`` excluded, ``cost_repeats``, ``cost_spread``, one RHS call's ``rhs_s`` and the
work ``work_s``); peak RSS of the process; provenance;
and, when a cached reference solution exists for the case, horizon and sampling
(:mod:`redysim.harness.reference`), the max tip-position error over the samples and the final-state
error against it.
"""

from __future__ import annotations

import functools
import math
import time
import traceback
from dataclasses import dataclass

import numpy as np

from redysim.algorithms.system import System
from redysim.errors import SettingsError
from redysim.integrators.explicit import sample_times
from redysim.io.scenarios import Scenario, load_scenario
from redysim.simulation import Integrator, Simulator, frame_observer, momentum_observer

from . import cost
from .provenance import peak_rss_mib, provenance, reset_peak_rss
from .reference import load_reference
from .spec import CORE, RunSpec, is_native, native_name

# the observed path (tip_*), the energy, the centre of mass, and the momentum: linear (p_*,
# kg m/s) and angular about the centre of mass (h_*, kg m^2/s), both world frame
# (redysim.momentum): constant where no external force acts (h_G also under uniform gravity)
SAMPLE_COLUMNS = ("run_id", "t", "tip_x", "tip_y", "tip_z", "tip_vx", "tip_vy", "tip_vz",
                  "tip_ax", "tip_ay", "tip_az", "E", "delta_M", "com_x", "com_y", "com_z",
                  "p_x", "p_y", "p_z", "h_x", "h_y", "h_z")
PROGRESS_EVERY_S = 5.0  # wall seconds between two progress reports of a run


@dataclass
class RunResult:
    """``summary``: one row (dict); ``rows``: the samples, one tuple per sample in
    :data:`SAMPLE_COLUMNS` order; ``samples``: the same as a pandas DataFrame, made on first
    use (pandas: the ``harness`` extra; a run itself needs only the core)."""

    spec: RunSpec
    summary: dict
    rows: list
    states: np.ndarray | None = None  # (n_samples, n_q + n_v) with execute(states=True)

    @functools.cached_property
    def samples(self):
        import pandas as pd

        return pd.DataFrame(self.rows, columns=SAMPLE_COLUMNS)

    @property
    def ok(self) -> bool:
        return self.summary["status"] == "ok"


class RunFailed(Exception):
    """Raised inside a run to stop it with a reason (caught by :func:`execute`)."""


class RunStopped(RunFailed):
    """Raised inside a run stopped by the caller's wall-clock limit: status "stopped"."""


def run_case(spec: RunSpec, scn: Scenario):
    """The scenario as the run models it, and its coarsening (None for its own model): with
    ``spec.links``, a rope's chain coarse-grained to that many links and the initial state
    mapped by the coarsening's chord projection (:mod:`redysim.algorithms.coarse`)."""
    if scn.case is None or not spec.links:
        return scn, None
    case, cz = coarse_case(scn.case, spec.links)
    return Scenario.from_case(case), cz


def coarse_case(case, links: int):
    """``case`` at ``links`` links (0 or its own count: as it is), and the coarsening (None:
    none): lumped when ``links`` divides its count (its chain coarse-grained, its initial state
    mapped along the chords), else the same rope rebuilt with that many links
    (:func:`rebuilt_case`; a straight rope's only)."""
    if not links or links == case.chain.n_links:
        return case, None
    from dataclasses import replace

    from redysim.algorithms.coarse import coarsen

    if case.chain.n_links % links:
        from redysim.io.cases import rebuilt_case

        return rebuilt_case(case, links), None

    cz = coarsen(case.chain, links=links, name=f"{case.name}@{links}")
    q0, v0 = cz.to_coarse(case.q0, case.v0)
    q0.flags.writeable = v0.flags.writeable = False
    return replace(case, chain=cz.coarse, q0=q0, v0=v0), cz


class _Dynamics:
    """The run's accelerations, as :class:`redysim.simulation.Simulator` takes them: the core
    (RGE-A, GE-N or RGE-N) in float64 (``qdd`` None: the simulator calls the core itself, in
    compiled steps where it can), the core in emulated float32, or a reference engine's; and
    a rope's tip force as generalized forces with its potential."""

    def __init__(self, spec: RunSpec, case: Scenario):
        self.chain = case.model
        self.build_s = 0.0
        self.engine = None
        self.force = case.tip_force
        self.method = spec.method or "rge-a"
        self.version = ""
        if self.force is not None and spec.engine != CORE:
            raise RunFailed(f"the case's [load] tip_force is applied by the core only, not by "
                            f"engine {spec.engine!r}")
        if spec.engine == CORE:
            self.qdd = None
            if spec.precision == "float32":
                from redysim.algorithms.precision import ieee_qdd

                def qdd(q, v, tau):
                    # fused_phi: the core's own formulation, bias terms inside the recursion,
                    # every operation in float32 (not Table A.1's float64 phi rounded to float32)
                    return ieee_qdd(self.chain, q, v, self.method, np.float32, tau=tau,
                                    fused_phi=True)
                self.qdd = qdd
        else:
            from redysim import references

            if case.model.cuts:  # the engine's loop adapter: its own constraints
                self.qdd = _loop_engine_of(spec, case, self)
            else:
                cls = references.get(spec.engine)
                lim = cls.limits(case.model)
                if not lim.ok:
                    raise RunFailed(f"refused by the engine: {lim.reason}")
                t0 = time.perf_counter()
                self.engine = cls(case.model)
                self.build_s = time.perf_counter() - t0
                self.version = self.engine.version
                engine = self.engine
                self.qdd = lambda q, v, tau: engine.qdd(q, v, tau)
        # the case's tip force: the Simulator's tip_force (its torques and potential)


def _loop_engine_of(spec: RunSpec, case: Scenario, dyn: _Dynamics):
    """The constrained accelerations of an engine's loop adapter on a closed-loop scenario
    (:mod:`redysim.references.loops`: the engine's own loop constraints), at each stage's state
    projected onto the loops; RunFailed when the engine has none, cannot build the loops, or is
    asked to step natively."""
    from redysim import references
    from redysim.algorithms.loops import ClosedLoops

    if is_native(spec.integrator):
        raise RunFailed(f"integrator {spec.integrator!r}: an engine's own stepper on closed "
                        "loops does not run in the harness (its loop adapter gives qdd: run it "
                        "through redysim's integrators)")
    cls = next((c for c in references.LOOP_ENGINES.values()
                if spec.engine in (c.name, c.adapter.name)), None)
    if cls is None:
        why = getattr(references.ENGINES.get(spec.engine), "no_loops", "")
        raise RunFailed(f"engine {spec.engine!r} has no loop adapter"
                        + (f" ({why})" if why else "") + "; engines with one: "
                        f"{', '.join(c.adapter.name for c in references.LOOP_ENGINES.values())}")
    loops = ClosedLoops(case.model)
    lim = cls.limits(loops)
    if not lim.ok:
        raise RunFailed(f"refused by the engine: {lim.reason}")
    t0 = time.perf_counter()
    eng = references.loop_engine(cls.name, loops)
    dyn.build_s = time.perf_counter() - t0
    dyn.version = eng.version

    def qdd(q, v, tau):
        # the adapters take assembled states only (1e-6 of the model's size), and a Runge-Kutta
        # stage, a rejected trial step's above all, leaves the loops by its own error: the
        # engine is asked at the stage's state projected onto the loops (the core's projection,
        # as after every step), a change of the order of that error
        qp, vp = loops.project(q, v)[:2]
        return eng.forward_dynamics(qp, vp, tau)
    return qdd


def execute(spec: RunSpec, *, reference=True, progress=None,
            max_wall_s: float | None = None, states: bool = False) -> RunResult:
    """Run ``spec`` and return its summary row and samples (never raises for a failing run).

    The row holds the run's settings as run (:meth:`RunSpec.resolved`: the case's where the
    spec leaves them to it) under the spec's own ``run_id``.
    ``reference``: compare with the cached reference solution when one exists (True), or not.
    ``progress``: called as ``progress(t, t_end, steps, wall_s)`` at most every
    ``PROGRESS_EVERY_S`` seconds of wall time while the run integrates.
    ``max_wall_s``: the caller's patience: after this many seconds of wall time the run is
    stopped, its samples so far kept, with status ``"stopped"`` (not a result: what a run
    reaches in a given wall time depends on the machine's load). The spec's own limit is
    ``spec.max_cpu_s``, in CPU time: a run past it is ``"failed"``.
    ``states``: keep (q, v) at every sample too (``RunResult.states``; ``redysim simulate
    --out`` saves them); a sweep keeps none.
    """
    reset_peak_rss()  # this run's peak, not the worker's before it
    row = {**spec.to_dict(), "run_id": spec.run_id, "label": spec.label, "status": "ok",
           "reason": "", "steps": 0, "rejected": 0, "nfev": 0, "cpu_s": math.nan,
           "wall_s": math.nan, "jit_s": math.nan, "build_s": math.nan, "peak_rss_mib": math.nan,
           "n_dof": 0, "n_links": 0, "model_mib": math.nan, "E0": math.nan, "frame": "",
           "engine_config": "",
           "avg_abs_delta_M": math.nan, "max_abs_delta_M": math.nan,
           "t_reached": 0.0, "n_samples": 0, "max_tip_err": math.nan, "final_state_err": math.nan,
           "ref_tol_estimate": math.nan, "ref_engine_check": math.nan,
           "quaternion_error": 0.0, "residual_q": 0.0,
           "residual_v": 0.0, "max_loop_force": math.nan, "near_change_point": math.nan,
           "cost_s": math.nan, "cost_repeats": 0, "cost_spread": math.nan,
           "sample_cpu_s": math.nan, "rhs_s": math.nan, "work_s": math.nan}
    samples: list[tuple] = []
    last: dict = {"states": [] if states else None}  # the last state (final-state error)
    engine_version = ""
    coarsening = scn = None
    dyn_engine = [None]  # the engine built, for its manifest
    try:
        scn = case = load_scenario(spec.case, options=spec.model_options())
        spec = spec.resolved(case)
        case, coarsening = run_case(spec, case)
        row.update(n_dof=case.model.n_v, n_links=case.model.n_bodies, frame=case.frame)
        row.update(spec.to_dict(), label=spec.label)
        dyn = _Dynamics(spec, case)
        dyn_engine[0] = dyn.engine
        engine_version = dyn.version
        row["build_s"] = dyn.build_s
        _integrate(spec, case, dyn, row, samples, last, progress, max_wall_s)
    except RunStopped as exc:
        row.update(status="stopped", reason=str(exc))
    except RunFailed as exc:
        row.update(status="failed", reason=str(exc))
    except Exception as exc:  # an engine's or the core's error: recorded, never raised
        where = traceback.extract_tb(exc.__traceback__)[-1]
        row.update(status="failed", reason=f"{type(exc).__name__}: {exc} "
                                           f"(at {where.filename.rsplit('/', 1)[-1]}:"
                                           f"{where.lineno})")
    if samples:
        abs_dM = np.abs([s[SAMPLE_COLUMNS.index("delta_M")] for s in samples])
        row["avg_abs_delta_M"] = float(abs_dM.mean())
        row["max_abs_delta_M"] = float(abs_dM.max())
        row["t_reached"] = float(samples[-1][SAMPLE_COLUMNS.index("t")])
    row["n_samples"] = len(samples)
    row["peak_rss_mib"] = peak_rss_mib()
    if reference and row["status"] == "ok" and samples:
        tip = SAMPLE_COLUMNS.index("tip_x")
        pos = np.array([s[tip:tip + 3] for s in samples])
        _compare_with_reference(scn, row, pos, last.get("y"), coarsening)
    if dyn_engine[0] is not None:
        import json

        row["engine_config"] = json.dumps(dyn_engine[0].manifest(), sort_keys=True,
                                          default=str)
    row.update(provenance(engine_version))
    kept = last.get("states")
    return RunResult(spec, row, samples, None if kept is None else np.array(kept))


def initial_state(spec: RunSpec, case) -> np.ndarray:
    """y0 = (q0, v0) of the run: the scenario's, shifted by ``spec.perturb`` (RunSpec's
    meaning; a free joint's quaternion is normalised again by the simulator)."""
    y0 = np.concatenate((case.q0, case.v0))
    if spec.perturb:
        y0 = y0 + spec.perturb * np.maximum(np.abs(y0), 1.0)
    return y0


def _integrate(spec: RunSpec, case, dyn: _Dynamics, row: dict, samples: list, last: dict,
               progress=None, max_wall_s: float | None = None):
    """Integrate a resolved spec (every setting explicit) by the one simulation driver
    (:class:`redysim.simulation.Simulator`); past ``spec.max_cpu_s`` of CPU time the run fails
    (RunFailed), past ``max_wall_s`` of wall time it is stopped (RunStopped)."""
    chain, n = case.model, case.model.n_q
    y0 = initial_state(spec, case)
    native = is_native(spec.integrator)
    if native:
        if dyn.engine is None:
            raise RunFailed(f"integrator {spec.integrator!r} needs a reference engine (the core "
                            "has no native stepper: use 'rk4' with a step h)")
        if spec.stepped(spec.integrator):
            if not spec.h > 0:
                raise RunFailed(f"integrator {spec.integrator!r} needs a step h > 0")
            per = sample_times(0.0, spec.t_end, spec.sample) / spec.h
            if np.abs(per - np.round(per)).max() > 1e-6:
                raise RunFailed(f"native stepping: sample times must be whole multiples of "
                                f"h = {spec.h:g}")
    source = f"run {spec.label}"

    def new_stepper():
        if native:
            try:
                return dyn.engine.stepper(native_name(spec.integrator), h=spec.h or None,
                                          rtol=spec.rtol, atol=spec.atol)
            except ValueError as exc:
                raise SettingsError(source, "integrator", spec.integrator, str(exc)) from None
        return Integrator(spec.integrator, rtol=spec.rtol, atol=spec.atol, h=spec.h or None)

    system = System(chain, qdd=dyn.qdd, method=dyn.method, tip_force=dyn.force,
                    damping=case.damping, source=source)

    def new_sim(keep: bool) -> Simulator:
        return Simulator(system, spec.t_end, q0=y0[:n], v0=y0[n:], integrator=new_stepper(),
                         sample=spec.sample, keep_states=keep,
                         observe={"tip": frame_observer(chain, case.frame, acceleration=True),
                                  "momentum": momentum_observer(chain)})

    sim = new_sim(last.get("states") is not None)
    row["jit_s"], row["E0"] = sim.jit_s, sim.E0
    row["model_mib"] = system.ws.nbytes / 2**20 if dyn.engine is None else math.nan
    next_report = [time.perf_counter() + PROGRESS_EVERY_S]
    wall0 = time.perf_counter()

    def report(t, t_end, steps, _wall):
        now = time.perf_counter()
        if progress is not None and now >= next_report[0]:
            progress(t, t_end, steps, now - wall0)
            next_report[0] = now + PROGRESS_EVERY_S
        return None

    try:
        res = sim.run(progress=report, max_cpu_s=spec.max_cpu_s or None, max_wall_s=max_wall_s,
                      clock="process", energy_bound=spec.energy_bound, time_samples=True)
    except Exception as exc:  # an engine's error mid-run: its row keeps the samples before it
        if getattr(exc, "partial", None) is not None:
            _keep(spec, exc.partial, row, samples, last)
        raise
    _keep(spec, res, row, samples, last)
    if res.status == 0:
        _measure_cost(spec, system, sim.y0, res, row, lambda: new_sim(False))
    if res.status == 1 and res.message.startswith("stopped by the wall-clock limit"):
        raise RunStopped(res.message)
    if res.status != 0:
        raise RunFailed(res.message)


def _measure_cost(spec: RunSpec, system: System, y, res, row: dict, new_sim) -> None:
    """The integration's cost of a finished run, load-proof (:mod:`redysim.harness.cost`): a
    short run repeated (fresh simulators of the same spec, in this process) and the least of the
    repeats' CPU, the sampling excluded; one derivative call's CPU at the initial state ``y``
    (the simulator's) and the RHS calls' work. A repeat that does not make the same steps and
    calls (it would time other work) ends the repeats; the times before it are kept."""
    def once() -> float:
        again = new_sim().run(clock="process", time_samples=True)
        if again.status != 0 or again.nfev != res.nfev or again.steps != res.steps:
            return math.nan
        return again.cpu_s - again.sample_cpu_s

    times = cost.repeat(once, res.cpu_s - res.sample_cpu_s)
    row.update(cost.summary(times), sample_cpu_s=res.sample_cpu_s)
    out = np.empty_like(y)
    row["rhs_s"] = cost.per_call(lambda: system.derivative(0.0, y, out))
    row["work_s"] = (res.nfev * row["rhs_s"] if res.nfev >= 0 and not is_native(spec.integrator)
                     else math.nan)


def _keep(spec: RunSpec, res, row: dict, samples: list, last: dict) -> None:
    """A Simulation's samples as the run's rows (tip, E, delta_M, COM, momentum), its counts
    into ``row``."""
    # the summary row's id (the spec as given, which a sweep looks runs up by), not the
    # resolved spec's: redysim simulate --out wrote samples whose run_id no summary had
    tips, run_id = res.observed["tip"], row["run_id"]  # (read once: the id hashes files)
    mom = res.observed["momentum"]
    for i, t in enumerate(res.t):
        samples.append((run_id, float(t), *tips[i], float(res.energy[i]),
                        float(res.delta_M[i]), *res.com[i], *mom[i]))
    last["y"] = res.y_final
    if last.get("states") is not None and res.q.shape[0]:
        last["states"] = np.concatenate((res.q, res.v), axis=1)
    row.update(steps=res.steps, rejected=res.rejected, nfev=res.nfev, cpu_s=res.cpu_s,
               wall_s=res.wall_s, quaternion_error=res.quaternion_error,
               residual_q=res.residual_q, residual_v=res.residual_v)
    if res.forces is not None:
        row["max_loop_force"] = float(np.abs(res.forces).max()) if res.forces.size else 0.0
    if res.near_change_point is not None:
        row["near_change_point"] = float(res.near_change_point)


def _compare_with_reference(scn: Scenario, row: dict, pos, y_final, coarsening=None) -> None:
    """Errors against the reference solution of ``scn`` (the run's scenario as loaded, before
    any coarsening); ``pos``: the observed path's positions at the samples, (n_samples, 3). A
    coarse-grained rope is compared with the case's own (fine) reference: its tip is the same
    point of the rope, and its final state is compared with the reference's mapped to the coarse
    model (the chord projection)."""
    ref = load_reference(scn, row["t_end"], row["sample"])
    if ref is None or len(ref.t) != len(pos):
        return
    row["max_tip_err"] = float(np.linalg.norm(pos - ref.tip, axis=1).max())
    row["ref_tol_estimate"] = ref.tol_estimate
    row["ref_engine_check"] = ref.engine_check
    if y_final is not None:
        y_ref = ref.y[-1]
        if coarsening is not None:
            n = scn.model.n_q
            y_ref = np.concatenate(coarsening.to_coarse(y_ref[:n], y_ref[n:]))
        row["final_state_err"] = _state_error(scn.model, y_final, y_ref)


def _state_error(model, y, y_ref) -> float:
    """max |y - y_ref| over the coordinates, a free joint's quaternion compared up to its sign
    (q and -q are the same rotation)."""
    d = np.abs(np.asarray(y) - np.asarray(y_ref))
    for i in getattr(model, "quaternions", ()):
        other = np.abs(np.asarray(y)[i:i + 4] + np.asarray(y_ref)[i:i + 4])
        if other.max() < d[i:i + 4].max():
            d[i:i + 4] = other
    return float(d.max())
