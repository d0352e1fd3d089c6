"""Execute one run: a case, simulated by one engine and algorithm with one integrator.

:func:`execute` never raises for a run that goes wrong: a NaN, an energy blow-up past the spec's
bound, an engine's refusal or a missing package, the spec's CPU-time limit, any exception: the
result's ``status`` is ``"failed"`` and ``reason`` says why, with the samples finished before it.
A run stopped by the caller's wall-clock limit (``execute(max_wall_s=...)``: the user's patience,
``redysim simulate --max-wall``) is ``"stopped"``: not a result, and never kept as one by a
sweep (which sets no wall-clock limit).

Per sample (the spec's interval): tip position, velocity and acceleration, E = T + V and
delta_M = (E - E0) / M (Eq. 11), all computed by the core from the run's state (the energy is a
measurement, the same for every engine). The tip acceleration needs qdd at the sample: one extra
call of the run's own qdd per sample, not counted in ``nfev`` (the integrator's count).

Per run: the model's size (links, DOF, and for the core the bytes of its Workspace: every array
the kernels read or write), steps, rejected steps, RHS evaluations, CPU and wall time of the
integration, the JIT compile (or cache load) of the first qdd call and an engine's model build,
both timed apart and excluded from ``cpu_s``/``wall_s``; peak RSS of the process; provenance;
and, when a cached reference solution exists for the case, horizon and sampling
(:mod:`harness.reference`), the max tip-position error over the samples and the final-state error
against it.
"""

from __future__ import annotations

import math
import time
import traceback
from dataclasses import dataclass

import numpy as np

from redysim import StateError, energy, forward_dynamics, load_case, tip
from redysim.integrate import (
    IMPLICIT,
    TABLEAU_NAMES,
    CompiledSolver,
    advance,
    compile_kernels,
    make_solver,
    sample_times,
)

from .provenance import peak_rss_mib, provenance, reset_peak_rss
from .reference import load_reference
from .spec import CORE, NATIVE, RunSpec

SAMPLE_COLUMNS = ("run_id", "t", "tip_x", "tip_y", "tip_z", "tip_vx", "tip_vy", "tip_vz",
                  "tip_ax", "tip_ay", "tip_az", "E", "delta_M")
PROGRESS_EVERY_S = 5.0  # wall seconds between two progress reports of a run


@dataclass
class RunResult:
    """``summary``: one row (dict); ``samples``: a pandas DataFrame with :data:`SAMPLE_COLUMNS`."""

    spec: RunSpec
    summary: dict
    samples: object  # pandas.DataFrame

    @property
    def ok(self) -> bool:
        return self.summary["status"] == "ok"


class RunFailed(Exception):
    """Raised inside a run to stop it with a reason (caught by :func:`execute`)."""


class RunStopped(RunFailed):
    """Raised inside a run stopped by the caller's wall-clock limit: status "stopped"."""


def run_case(spec: RunSpec, case):
    """The case as the run models it, and its coarsening (None for the case's own chain):
    with ``spec.links``, the chain coarse-grained to that many links and the initial state mapped
    by the coarsening's chord projection (:mod:`redysim.coarse`)."""
    return coarse_case(case, spec.links)


def coarse_case(case, links: int):
    """``case`` with its chain coarse-grained to ``links`` links (0 or its own count: as it
    is) and its initial state mapped along the chords; and the coarsening (None: none)."""
    if not links or links == case.chain.n_links:
        return case, None
    from dataclasses import replace

    from redysim.coarse import coarsen

    cz = coarsen(case.chain, links=links, name=f"{case.name}@{links}")
    q0, qd0 = cz.to_coarse(case.q0, case.qd0)
    q0.flags.writeable = qd0.flags.writeable = False
    return replace(case, chain=cz.coarse, q0=q0, qd0=qd0), cz


class _Dynamics:
    """The run's qdd: the core (RGE-A, GE-N or RGE-N, in float64 or float32) or a reference
    engine's; with the case's tip force, if it has one."""

    def __init__(self, spec: RunSpec, case):
        self.chain = case.chain
        self.n = self.chain.n_dof
        self.build_s = 0.0
        self.engine = None
        self.force = case.tip_force
        self.precision = spec.precision
        if self.force is not None and spec.engine != CORE:
            raise RunFailed(f"the case's [load] tip_force is applied by the core only, not by "
                            f"engine {spec.engine!r}")
        if spec.engine == CORE:
            from redysim import Workspace

            self.ws = Workspace(self.chain)
            self.load_ws = Workspace(self.chain)
            self.method = spec.method or "rge-a"
            self.version = ""
        else:
            from redysim import references

            cls = references.get(spec.engine)
            lim = cls.limits(case)
            if not lim.ok:
                raise RunFailed(f"refused by the engine: {lim.reason}")
            t0 = time.perf_counter()
            self.engine = cls(case)
            self.build_s = time.perf_counter() - t0
            self.version = self.engine.version

    def compiled_steps(self, integrator: str) -> bool:
        """Whether ``integrator`` steps in compiled code here: one of ours (ode45, dop853,
        rk4) on the core's RGE-A (the same steps as the Python loop, bit for bit)."""
        return (self.engine is None and self.method == "rge-a" and integrator in TABLEAU_NAMES
                and self.force is None and self.precision == "float64")

    def qdd(self, q, qd) -> np.ndarray:
        if self.engine is not None:
            return self.engine.qdd(q, qd)
        tau = None
        if self.force is not None:
            from redysim.loads import tip_force_torques
            tau = tip_force_torques(self.chain, q, self.force, ws=self.load_ws)
        if self.precision == "float32":
            from redysim.precision import ieee_qdd
            # fused_phi: the core's own formulation, bias terms inside the recursion, every
            # operation in float32 (not Table A.1's float64 phi rounded to float32)
            return ieee_qdd(self.chain, q, qd, self.method, np.float32, tau=tau,
                            fused_phi=True)
        return forward_dynamics(self.chain, q, qd, tau, method=self.method, ws=self.ws)

    def load_potential(self, q) -> float:
        """The tip force's potential -F . p_tip (0 without one), part of the run's energy."""
        if self.force is None:
            return 0.0
        from redysim.loads import tip_force_potential
        return tip_force_potential(self.chain, q, self.force, ws=self.load_ws)

    def rhs(self, _t, y):
        n = self.n
        return np.concatenate((y[n:], self.qdd(y[:n], y[n:])))


def execute(spec: RunSpec, *, reference=True, progress=None,
            max_wall_s: float | None = None) -> RunResult:
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
    """
    import pandas as pd

    reset_peak_rss()  # this run's peak, not the worker's before it
    row = {**spec.to_dict(), "run_id": spec.run_id, "label": spec.label, "status": "ok",
           "reason": "", "steps": 0, "rejected": 0, "nfev": 0, "cpu_s": math.nan,
           "wall_s": math.nan, "jit_s": math.nan, "build_s": math.nan, "peak_rss_mib": math.nan,
           "n_dof": 0, "n_links": 0, "model_mib": math.nan, "E0": math.nan,
           "avg_abs_delta_M": math.nan, "max_abs_delta_M": math.nan,
           "t_reached": 0.0, "n_samples": 0, "max_tip_err": math.nan, "final_state_err": math.nan,
           "ref_tol_estimate": math.nan}
    samples: list[tuple] = []
    last = {}  # the state at the last sample, for the final-state error
    engine_version = ""
    coarsening = None
    try:
        case = load_case(spec.case)
        spec = spec.resolved(case)
        case, coarsening = run_case(spec, case)
        row.update(n_dof=case.chain.n_dof, n_links=case.chain.n_links)
        row.update(spec.to_dict(), label=spec.label)
        dyn = _Dynamics(spec, case)
        if dyn.engine is None:
            row["model_mib"] = dyn.ws.nbytes / 2**20
        engine_version = dyn.version
        row["build_s"] = dyn.build_s
        _integrate(spec, case, dyn, row, samples, last, progress, max_wall_s)
    except RunStopped as exc:
        row.update(status="stopped", reason=str(exc))
    except RunFailed as exc:
        row.update(status="failed", reason=str(exc))
    except Exception as exc:  # an engine's or the core's error: recorded, never raised
        last = traceback.extract_tb(exc.__traceback__)[-1]
        row.update(status="failed", reason=f"{type(exc).__name__}: {exc} "
                                           f"(at {last.filename.rsplit('/', 1)[-1]}:{last.lineno})")
    df = pd.DataFrame(samples, columns=SAMPLE_COLUMNS)
    if len(df):
        row["avg_abs_delta_M"] = float(df["delta_M"].abs().mean())
        row["max_abs_delta_M"] = float(df["delta_M"].abs().max())
        row["t_reached"] = float(df["t"].iloc[-1])
    row["n_samples"] = len(df)
    row["peak_rss_mib"] = peak_rss_mib()
    if reference and row["status"] == "ok" and len(df):
        _compare_with_reference(spec, row, df, last.get("y"), coarsening)
    row.update(provenance(engine_version))
    return RunResult(spec, row, df)


def initial_state(spec: RunSpec, case) -> np.ndarray:
    """y0 = (q0, qd0) of the run: the case's, shifted by ``spec.perturb`` (RunSpec's meaning)."""
    y0 = np.concatenate((case.q0, case.qd0))
    if spec.perturb:
        y0 = y0 + spec.perturb * np.maximum(np.abs(y0), 1.0)
    return y0


def _integrate(spec: RunSpec, case, dyn: _Dynamics, row: dict, samples: list, last: dict,
               progress=None, max_wall_s: float | None = None):
    """Integrate a resolved spec (every setting explicit); stop it past ``spec.max_cpu_s`` of
    CPU time (RunFailed) or ``max_wall_s`` of wall time (RunStopped)."""
    chain, n = case.chain, case.chain.n_dof
    t_end = spec.t_end
    ts = sample_times(0.0, t_end, spec.sample)
    y0 = initial_state(spec, case)
    T0, V0 = energy(chain, y0[:n], y0[n:])
    E0 = T0 + V0 + dyn.load_potential(y0[:n])
    row["E0"] = E0
    run_id, mass, bound = spec.run_id, chain.total_mass, spec.energy_bound

    def on_sample(t, y):
        q, qd = y[:n], y[n:]
        try:
            qdd = dyn.qdd(q, qd)
            tp = tip(chain, q, qd, qdd)
            T, V = energy(chain, q, qd)
            V += dyn.load_potential(q)
        except StateError as exc:  # the state overflowed (or went NaN) between samples
            return f"at t = {t:.6g}: {type(exc).__name__}: {exc}"
        dM = (T + V - E0) / mass
        samples.append((run_id, t, *tp.position, *tp.velocity, *tp.acceleration, T + V, dM))
        last["y"] = y
        if not math.isfinite(dM):
            return f"non-finite energy at t = {t:.6g}"
        if bound and abs(dM) > bound:
            return (f"energy blow-up: |delta_M| = {abs(dM):.3g} J/kg > bound {bound:g} "
                    f"at t = {t:.6g}")
        return None

    t0 = time.perf_counter()
    dyn.rhs(0.0, y0)  # the first qdd call: JIT compile or on-disk cache load, timed apart
    # and the integrators' stage sums (the implicit step's kernels instead: it calls none of them)
    if spec.integrator in IMPLICIT:
        from redysim.implicit import compile_kernels as implicit_kernels
        implicit_kernels()
    else:
        compile_kernels()
    row["jit_s"] = time.perf_counter() - t0
    cpu0, wall0 = time.process_time(), time.perf_counter()
    limits = _Limits(spec.max_cpu_s, max_wall_s, cpu0, wall0)

    if spec.integrator == NATIVE:
        status, msg = _native(spec, dyn, y0, t_end, ts, on_sample, limits, row)
    else:
        def rhs(t, y):
            # the limits are checked per RHS call: one step of an implicit solver (Newton
            # iterations, finite-difference Jacobians) can take far longer than a limit
            limits.check(t)
            return dyn.rhs(t, y)

        next_report = [time.perf_counter() + PROGRESS_EVERY_S]

        def on_step(s):
            now = time.perf_counter()
            if progress is not None and now >= next_report[0]:
                progress(s.t, t_end, s.counters.steps, now - wall0)
                next_report[0] = now + PROGRESS_EVERY_S
            limits.check(s.t)  # (a compiled solver's steps call no Python rhs to check them)
            return None

        solver = None
        try:  # the limit can strike inside the constructor too (its first RHS calls)
            if dyn.compiled_steps(spec.integrator):
                solver = CompiledSolver(rhs, 0.0, y0, t_end, spec.integrator, ws=dyn.ws,
                                        planar=dyn.chain.is_planar, rtol=spec.rtol,
                                        atol=spec.atol, h=spec.h or None)
            else:
                pre = None
                if spec.integrator in IMPLICIT:  # the chain's preconditioner, any engine's qdd
                    from redysim.implicit import TensionPreconditioner
                    pre = TensionPreconditioner(chain)
                solver = make_solver(rhs, 0.0, y0, t_end, spec.integrator, rtol=spec.rtol,
                                     atol=spec.atol, h=spec.h or None, preconditioner=pre)
            status, msg = advance(solver, ts, on_sample=on_sample, on_step=on_step)
        finally:
            if solver is not None:
                c = solver.counters
                row.update(steps=c.steps, rejected=c.rejected, nfev=c.nfev)
            row.update(cpu_s=time.process_time() - cpu0, wall_s=time.perf_counter() - wall0)
    row["cpu_s"] = time.process_time() - cpu0
    row["wall_s"] = time.perf_counter() - wall0
    if status != 0:
        raise RunFailed(msg)


class _Limits:
    """A run's time limits: the spec's CPU time (a result: RunFailed) and the caller's wall time
    (patience: RunStopped), each None or 0 for none."""

    def __init__(self, cpu_s, wall_s, cpu0: float, wall0: float):
        self.cpu_s, self.wall_s = cpu_s or 0.0, wall_s or 0.0
        self.cpu_end = cpu0 + self.cpu_s if self.cpu_s else math.inf
        self.wall_end = wall0 + self.wall_s if self.wall_s else math.inf

    def check(self, t: float) -> None:
        if time.process_time() > self.cpu_end:
            raise RunFailed(f"time limit: max_cpu_s = {self.cpu_s:g} s of CPU reached at "
                            f"t = {t:.6g}")
        if time.perf_counter() > self.wall_end:
            raise RunStopped(f"stopped by the wall-clock limit, max_wall_s = {self.wall_s:g} s "
                             f"(the caller's patience, not a result), at t = {t:.6g}; the "
                             "samples so far are kept")


def _native(spec, dyn, y0, t_end, ts, on_sample, limits: _Limits, row):
    """The engine's own fixed-step stepper; samples must fall on whole steps."""
    if dyn.engine is None:
        raise RunFailed("integrator 'native' needs a reference engine (the core has no native "
                        "stepper: use 'rk4' with a step h)")
    h = spec.h
    if not h > 0:
        raise RunFailed("integrator 'native' needs a step h > 0")
    per = ts / h
    if np.abs(per - np.round(per)).max() > 1e-6:
        raise RunFailed(f"native stepping: sample times must be whole multiples of h = {h:g}")
    marks = np.round(per).astype(int)
    eng = dyn.engine
    eng.sim_reset(y0[:dyn.n], y0[dyn.n:], h)
    n_steps = int(marks[-1])
    i = 0
    for step in range(n_steps + 1):
        if step:
            eng.step_once()
            row["steps"] = step
        while i < marks.size and marks[i] == step:
            q, qd = eng.sim_state()
            if not (np.isfinite(q).all() and np.isfinite(qd).all()):
                return -1, f"non-finite state at t = {ts[i]:.6g}"
            if msg := on_sample(float(ts[i]), np.concatenate((q, qd))):
                return 1, msg
            i += 1
        limits.check(step * h)
    row["nfev"] = -1  # the engine's stepper does not report its qdd calls
    return 0, "ok"


def _compare_with_reference(spec: RunSpec, row: dict, df, y_final, coarsening=None) -> None:
    """Errors against the case's reference solution. A coarse-grained run is compared with the
    case's own (fine) reference: its tip is the same point of the rope, and its final state is
    compared with the reference's mapped to the coarse model (the chord projection)."""
    case = load_case(spec.case)
    ref = load_reference(case, row["t_end"], row["sample"])
    if ref is None or len(ref.t) != len(df):
        return
    pos = df[["tip_x", "tip_y", "tip_z"]].to_numpy()
    row["max_tip_err"] = float(np.linalg.norm(pos - ref.tip, axis=1).max())
    row["ref_tol_estimate"] = ref.tol_estimate
    if y_final is not None:
        y_ref = ref.y[-1]
        if coarsening is not None:
            n = case.chain.n_dof
            y_ref = np.concatenate(coarsening.to_coarse(y_ref[:n], y_ref[n:]))
        row["final_state_err"] = float(np.abs(y_final - y_ref).max())
