"""A long run that survives being stopped: the core integrated with checkpoints, resumed on restart.

For chains whose runs take hours (RE-U50000-L1000: 100,000 DOF, steps of ~1e-5 s limited by
waves along the chain). Every ``--every`` seconds of wall time, and at the end, the solver's
whole state (t, y, f(t, y), the next step, the counters, the CPU and wall time so far) and the
samples so far are written to ONE ``.npz`` file atomically (temp file, fsync, ``os.replace``),
the previous one kept beside it: a run killed at any moment, even by ``kill -9``, loses at most
the work since the last checkpoint, and resuming continues bit for bit the same step sequence.

    python -m redysim.harness.longrun RE-U50000-L1000 [--t-end 5] [--every 120] [--out DIR]
    python -m redysim.harness.longrun RE-U50000-L1000 --status  # what the checkpoint holds, ETA

The integrator and its tolerances (or step) are the case file's ``[simulation]`` settings, or
the flags': one of ours (ode45, rk45, dop853, rk4, midpoint alias implicit, midpoint-fixed), whose
state can be saved; SciPy's cannot. ``--sample`` sets the sample interval (default the case's).
A checkpoint is resumed only by the same code, case file (its SHA-256 and DOF), integrator,
tolerances, horizon and sample interval; anything else is refused, naming both sides. A
checkpoint that cannot be read is moved aside and the previous one (or a fresh start) is used,
saying so.

Samples (every ``sample_interval`` of the case): t, tip position, E and delta_M (with a damped
case under our Runge-Kutta steps, the balance (E - W - E0) / M, W the dampers' work carried in
the checkpointed state; :class:`redysim.simulation.Simulation`'s ``work``).
Exit codes: 0 done (or stopped by ``--stop-after``), 1 the run failed, 2 bad input.
"""

from __future__ import annotations

import argparse
import math
import os
import sys
import time
import zipfile
from pathlib import Path

import numpy as np

from redysim import load_case, tip
from redysim.errors import CaseError, RedysimError, SettingsError
from redysim.integrators.explicit import (
    ALIASES,
    FIXED_STEP,
    IMPLICIT,
    TABLEAU_NAMES,
    Counters,
    OdeSolver,
    SolverState,
    canonical,
    check_settings,
)

from .cli import positive, time_to_go
from .provenance import code_digest, peak_rss_mib, reset_peak_rss
from .reference import results_dir
from .store import (
    check_kinds,
    check_writable,
    read_json,
    remove_temp_files,
    sha256_file,
    writable,
    write_json_atomic,
    write_npz_atomic,
)

CHECKPOINT = "checkpoint.npz"
PREVIOUS = "checkpoint.prev.npz"  # the checkpoint before the last, kept in case it is damaged
MANIFEST = "manifest.json"  # the checkpoints written, their SHA-256, the run's t and status
FINISHED = ("done", "failed")  # a checkpoint's status that is the run's record: never rewritten
STATUSES = ("in progress", "stopped", *FINISHED)  # every status a run writes
DEFAULT_EVERY_S = 120.0   # wall seconds between checkpoints
SAMPLE_FIELDS = ("t", "tip_x", "tip_y", "tip_z", "E", "delta_M")
INTEGRATORS = (*TABLEAU_NAMES, *IMPLICIT)  # ours (their state can be saved)
EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


class LongrunError(RedysimError):
    """A long run cannot start or resume as asked (the message says why and what to do)."""


class OtherRunError(LongrunError):
    """The checkpoint found was written by other code, or for another case or other settings:
    resuming it would not continue this run."""


def out_dir_for(case_name: str, integrator: str = "ode45") -> Path:
    """results/longrun/<case> for ode45 (the paper's), <case>-<integrator> for another."""
    name = case_name if integrator == "ode45" else f"{case_name}-{integrator}"
    return results_dir() / "longrun" / name


def save_checkpoint(path: Path, solver: OdeSolver, samples: list, meta: dict) -> None:
    """Everything to resume, in one file, atomically; the file it replaces is kept as
    ``checkpoint.prev.npz``."""
    st = solver.state()
    if path.exists():
        os.replace(path, path.with_name(PREVIOUS))
    write_npz_atomic(path, t=st.t, y=st.y, f=st.f, h=st.h, steps=st.counters.steps,
                     rejected=st.counters.rejected, nfev=st.counters.nfev,
                     samples=np.array(samples, dtype=float).reshape(-1, len(SAMPLE_FIELDS)),
                     **{k: np.asarray(v) for k, v in meta.items()})
    files = {p.name: sha256_file(p) for p in (path, path.with_name(PREVIOUS)) if p.exists()}
    write_json_atomic({"files": files, "t": float(st.t),
                       "status": str(meta.get("status", "in progress"))},
                      path.with_name(MANIFEST))


def read_manifest(folder: Path) -> dict | None:
    """The long run's manifest in ``folder`` (:data:`MANIFEST`), or None: none, or unreadable."""
    try:
        m = read_json(folder / MANIFEST)
        return m if isinstance(m, dict) and isinstance(m.get("files"), dict) else None
    except (OSError, ValueError):
        return None


def _read(path: Path) -> dict:
    with np.load(path) as z:
        ck = {k: z[k] for k in z.files}
    missing = {"t", "y", "f", "h", "steps", "samples", "case", "t_end"} - set(ck)
    if missing:
        raise KeyError(f"no {', '.join(sorted(missing))}")
    return ck


def load_checkpoint(path: Path, *, repair: bool = False, log=print) -> dict | None:
    """The checkpoint at ``path`` (a dict of its arrays), or None when there is none.

    A checkpoint that cannot be read (truncated, corrupted, not ours) or is not one the
    folder's manifest recorded (:data:`MANIFEST`, by SHA-256) is skipped for the previous one
    beside it, if that one reads; with ``repair`` the damaged file is also moved aside
    (``<name>.damaged-<time>``), and ``log`` says what happened either way; a checkpoint the
    manifest lists but that is missing is said too."""
    manifest = read_manifest(path.parent)
    known = set(manifest["files"].values()) if manifest else None
    for candidate in (path, path.with_name(PREVIOUS)):
        if not candidate.exists():
            if manifest and candidate.name in manifest["files"]:
                log(f"{candidate} is missing (listed in {path.parent / MANIFEST})")
            continue
        try:
            if known is not None and sha256_file(candidate) not in known:
                raise ValueError(f"not a checkpoint {MANIFEST} recorded (its SHA-256 differs: "
                                 "changed, or written as the run was stopped)")
            return _read(candidate)
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as exc:
            what = f"{candidate} could not be read ({type(exc).__name__}: {str(exc)[:200]})"
            if repair:
                aside = candidate.with_name(f"{candidate.name}.damaged-{int(time.time())}")
                os.replace(candidate, aside)
                what += f"; moved to {aside}"
            log(what)
    return None


def _refuse_other(path: Path, ck: dict, now: dict) -> None:
    """Refuse to resume a checkpoint written for another case, code, integrator or horizon."""
    if str(ck.get("code", "")) != now["code"]:
        raise OtherRunError(f"{path}: the checkpoint was written by other code (digest "
                           f"{str(ck.get('code', ''))[:12] or 'not recorded'}, now "
                           f"{now['code'][:12]}): resuming would not continue the same "
                           "computation; use another --out, delete it or --set-aside")
    then_case = (f"case {str(ck['case'])!r} ({int(ck['n_dof']):,} DOF, case file "
                 f"{str(ck.get('case_digest', 'not recorded'))[:12]})")
    now_case = (f"case {now['case']!r} ({now['n_dof']:,} DOF, case file "
                f"{now['case_digest'][:12]})")
    if str(ck.get("case_digest", "")) != now["case_digest"] or int(ck["n_dof"]) != now["n_dof"]:
        raise OtherRunError(f"{path}: the checkpoint was written for {then_case}; this is "
                           f"{now_case}: resuming would continue one chain's state with another's "
                           "dynamics; use another --out, delete it or --set-aside")
    for key in ("t_end", "integrator", "rtol", "atol", "fixed_h", "sample"):
        then = ck.get(key)
        then = then.item() if isinstance(then, np.ndarray) else then
        if then != now[key]:
            raise OtherRunError(f"{path}: a checkpoint for {key} = {then!r} exists (now "
                               f"{now[key]!r}); use another --out, delete it or --set-aside")


def _check_state(path: Path, ck: dict, t_end: float, n_state: int,
                 case_name: str | None = None) -> None:
    """Refuse a checkpoint whose state is not one this run can have reached: its t outside
    [0, t_end], "done" before t_end, y and f not the system's length (``n_state``), a status
    not a long run's, another case's name (``case_name``), h not > 0, a count below 0, or
    samples not rows of :data:`SAMPLE_FIELDS` at increasing times up to t."""
    t = float(ck["t"])
    status = str(ck.get("status", ""))
    way = "delete it (and checkpoint.prev.npz, manifest.json) or give another --out"
    if not (math.isfinite(t) and 0.0 <= t <= t_end):
        raise LongrunError(f"{path}: t = {t:g} is outside [0, t_end = {t_end:g}] s: not a state "
                           f"of this run; {way}")
    if status == "done" and t < t_end:
        raise LongrunError(f"{path}: status = 'done' at t = {t:g} s, before t_end = {t_end:g} "
                           f"s; {way}")
    for key in ("y", "f"):
        shape = np.shape(ck[key])
        if shape != (n_state,):
            raise LongrunError(f"{path}: {key} has shape {shape}, the system's state has "
                               f"{n_state} entries; {way}")
        if not np.all(np.isfinite(ck[key])):
            raise LongrunError(f"{path}: {key} is not finite; {way}")
    # the rest of its fields, as the run's own spec would have them (a damaged field found at
    # the end, when the record is written, would lose the work of the whole run)
    if "status" in ck and status not in STATUSES:  # (a checkpoint in progress has none)
        raise LongrunError(f"{path}: status = {status!r}: not a long run's status (one of "
                           f"{', '.join(map(repr, STATUSES))}); {way}")
    if case_name is not None and str(ck["case"]) != case_name:
        raise LongrunError(f"{path}: case = {str(ck['case'])!r}: this run is case "
                           f"{case_name!r}; {way}")
    h = np.asarray(ck["h"])
    if h.shape != () or h.dtype.kind != "f" or not (math.isfinite(float(h)) and float(h) > 0):
        raise LongrunError(f"{path}: h = {h.tolist()!r}: the next step must be a finite "
                           f"number > 0; {way}")
    for key in ("steps", "rejected", "nfev"):
        c = np.asarray(ck.get(key, 0))
        if c.shape != () or c.dtype.kind not in "iu" or int(c) < 0:
            raise LongrunError(f"{path}: {key} = {c.tolist()!r}: must be a count (an integer "
                               f">= 0); {way}")
    samples = np.asarray(ck["samples"])
    fields = len(SAMPLE_FIELDS)
    if samples.ndim != 2 or samples.shape[1] != fields or samples.dtype.kind != "f":
        raise LongrunError(f"{path}: samples has shape {samples.shape} ({samples.dtype}); a "
                           f"long run's samples are rows of {fields} numbers "
                           f"({', '.join(SAMPLE_FIELDS)}); {way}")
    ts = samples[:, 0]
    if samples.shape[0] and not (np.all(np.isfinite(ts)) and np.all(np.diff(ts) > 0)
                                 and ts[0] >= 0.0 and ts[-1] <= t):
        raise LongrunError(f"{path}: the samples' times do not increase from 0 to t = {t:g} s; "
                           f"{way}")


def set_aside_other(path: Path) -> Path:
    """Rename a checkpoint of another run (and the one before it) beside it, as
    ``checkpoint.aside-<UTC time>.npz`` (``.prev`` before ``.npz`` for the earlier one): kept,
    never resumed; its manifest too (``.manifest.json``), so that the new run's own is the
    only one. Returns the new name of the checkpoint."""
    stamp = time.strftime("%Y%m%dT%H%M%S", time.gmtime())
    moved = path.with_name(f"checkpoint.aside-{stamp}.npz")
    k = 1
    while moved.exists():  # two in one second
        k += 1
        moved = path.with_name(f"checkpoint.aside-{stamp}-{k}.npz")
    prev = path.with_name(PREVIOUS)
    if prev.exists():
        prev.replace(moved.with_suffix(".prev.npz"))
    manifest = path.with_name(MANIFEST)
    if manifest.exists():
        manifest.replace(moved.with_suffix(".manifest.json"))
    path.replace(moved)
    return moved


def settings(case, *, integrator=None, rtol=None, atol=None, h=None,
             names: dict | None = None) -> dict:
    """The run's integrator and its tolerances (``rtol``, ``atol``) or step (``fixed_h``): the
    arguments', else the case's; one of ours (its state can be checkpointed). Raises
    SettingsError naming the field."""
    method = canonical(integrator or case.integrator)
    if method not in INTEGRATORS:
        field = (names or {}).get("integrator", "integrator") if integrator else \
            "simulation.integrator"
        raise SettingsError(str(case.path), field, method,
                            f"a long run checkpoints our own integrators ({', '.join(INTEGRATORS)})"
                            "; SciPy's state cannot be saved and resumed")
    if method in FIXED_STEP:
        h = h or (case.h if method == case.integrator else None)
        check_settings(str(case.path), names, method=method, h=h, t_end=case.t_end)
        if not h:
            raise SettingsError(str(case.path), (names or {}).get("h", "h"), None,
                                f"missing: {method} is fixed-step and needs a step h")
        return {"integrator": method, "rtol": 0.0, "atol": 0.0, "fixed_h": float(h)}
    if h is not None:  # (was ignored: simulate refuses it, and so does a long run now)
        check_settings(str(case.path), names, method=method, h=h)
    rtol, atol = rtol or case.rtol, atol or case.atol
    check_settings(str(case.path), names, method=method, rtol=rtol, atol=atol)
    return {"integrator": method, "rtol": float(rtol), "atol": float(atol), "fixed_h": 0.0}


def run(case_name: str, *, t_end: float | None = None, every_s: float = DEFAULT_EVERY_S,
        out: Path | None = None, integrator: str | None = None, rtol: float | None = None,
        atol: float | None = None, h: float | None = None, sample: float | None = None,
        stop_after_s: float = math.inf, log=print, names: dict | None = None,
        set_aside: bool = False) -> dict:
    """Run (or resume) ``case_name`` to ``t_end``; return the final checkpoint. Raises
    :class:`LongrunError` (or a case or settings error) when it cannot start or resume; a
    checkpoint of another run (:class:`OtherRunError`: other code, case or settings) is refused,
    or with ``set_aside`` renamed beside it (:func:`set_aside_other`, kept, never resumed) and
    the run starts over."""
    reset_peak_rss()  # the run's own peak, not its caller's before it
    suffix = Path(str(case_name)).suffix.lower()
    if suffix in (".urdf", ".xml", ".mjcf", ".sdf"):  # (was read as TOML: "Invalid statement")
        raise CaseError(str(case_name), "case", str(case_name),
                        f"a {suffix} robot file: long runs take rope cases (redysim cases, or "
                        "a case .toml); run a robot with 'redysim simulate' (--max-wall, "
                        "--out) or a sweep")
    case = load_case(case_name)
    chain, n = case.chain, case.chain.n_dof
    if case.tip_force is not None:
        raise CaseError(str(case.path), "load.tip_force", [float(x) for x in case.tip_force],
                        "long runs integrate unloaded chains: run a loaded case with "
                        "'redysim simulate' or a sweep")
    t_end = float(t_end or case.t_end)
    check_settings(str(case.path), names, t_end=t_end, sample=sample)
    how = settings(case, integrator=integrator, rtol=rtol, atol=atol, h=h, names=names)
    interval = min(sample or case.sample_interval, t_end)
    path = (out or out_dir_for(case.name, how["integrator"])) / CHECKPOINT
    now = {"code": code_digest(), "case": case.name, "case_digest": case.digest, "n_dof": n,
           "t_end": t_end, "sample": interval, **how}
    kw = (dict(h=how["fixed_h"]) if how["fixed_h"] else
          dict(rtol=how["rtol"], atol=how["atol"]))
    # before anything is read or run: a folder where one of its files goes is refused by name
    check_kinds(files=[path, path.with_name(PREVIOUS), path.with_name(MANIFEST)],
                folders=[path.parent], why="nothing was run")
    can_write = writable(path.parent)  # (a finished run is read from a folder it cannot write)
    if can_write:  # a killed session's half-written checkpoint or manifest
        remove_temp_files(path.parent)
    ck = load_checkpoint(path, repair=can_write, log=log)
    state, samples, cpu_prev, wall_prev = None, [], 0.0, 0.0
    before = {"newton": 0, "krylov": 0, "peak_rss_mib": 0.0}  # the sessions' before this one
    if ck is not None:
        try:
            _refuse_other(path, ck, now)
        except OtherRunError as exc:
            if not set_aside:
                raise
            check_writable(path.parent)
            reason = str(exc).split("; use another --out")[0]
            log(f"{reason}: set aside as {set_aside_other(path).name}; starting over")
            ck = None
    if ck is not None:
        _check_state(path, ck, t_end, 2 * n, case.name)
    elif (path.parent / MANIFEST).exists() and read_manifest(path.parent) is None:
        # (a manifest that cannot be read, and no checkpoint: the run had started over from t
        # = 0 and written over that record; hold-out battery 6)
        raise LongrunError(f"{path.parent / MANIFEST} cannot be read (damaged) and no "
                           f"checkpoint of this run can be read beside it: what it recorded "
                           f"is not known, so the run is not started over unasked; to start "
                           f"over, delete {MANIFEST} (or give another --out)")
    elif (manifest := read_manifest(path.parent)) is not None and manifest["files"]:
        raise LongrunError(f"{path.parent / MANIFEST} lists the checkpoints of this run (t = "
                           f"{manifest.get('t', 0.0):.6g} s, {manifest.get('status', '')}), "
                           "but none of them can be read there: its record is lost, not "
                           f"started over unasked; to start over, delete {MANIFEST} (or give "
                           "another --out)")
    if ck is not None and str(ck.get("status", "")) in FINISHED:
        log(f"{case.name}: finished already ({ck['status']} at t = {float(ck['t']):.6g} s); "
            f"its record in {path} is kept as it is (another --out runs it again)")
        return ck
    check_writable(path.parent)  # before any step: a run that cannot be saved is not begun
    if ck is not None:
        samples = [tuple(r) for r in ck["samples"]]
        state = SolverState(float(ck["t"]), ck["y"], ck["f"], float(ck["h"]),
                            Counters(int(ck["steps"]), int(ck["rejected"]), int(ck["nfev"])),
                            sampled_until=samples[-1][0] if samples else None)
        cpu_prev, wall_prev = float(ck["cpu_s"]), float(ck["wall_s"])
        before = {k: ck[k].item() if k in ck else v for k, v in before.items()}
    def record(s):  # every sample: t, tip position, E, delta_M (the balance E - W - E0 / M)
        p = tip(chain, s.q, s.v, ws=s.ws).position
        W = 0.0 if s.W is None else s.W  # (None: the implicit midpoint, which does not carry it)
        samples.append((s.t, *p, s.E, (s.E - W - E0) / chain.total_mass))
        log(f"  sample t = {s.t:.4f} s: delta_M = {samples[-1][-1]:.3e} J/kg, "
            f"steps {sim.solver.counters.steps:,}")

    # the one simulation driver: the implicit midpoint with the chain's preconditioner, or our
    # Runge-Kutta steps in compiled code (the same steps, bit for bit, as the Python loop, so a
    # checkpoint of either resumes in the other)
    sim = case.simulator(t_end, integrator=how["integrator"], sample=interval,
                         keep_states=False, observe={"sample": record}, state=state, **kw)
    E0, solver = sim.E0, sim.solver
    if ck is not None:
        log(f"{case.name}: resuming at t = {state.t:.6g} s, {state.counters.steps:,} steps, "
            f"{len(samples)} samples ({wall_prev:,.0f} s of wall time so far)")
    else:
        step = (f"h {how['fixed_h']:g}" if how["fixed_h"] else
                f"rtol {how['rtol']:g} atol {how['atol']:g}")
        log(f"{case.name}: {n:,} DOF, {how['integrator']} {step} to t = {t_end:g} s, "
            f"E(0) = {E0:.9g} J; JIT/cache load {sim.jit_s:.2f} s")
    cpu0, wall0 = time.process_time(), time.perf_counter()
    t_start = solver.t
    last_ck = [wall0]

    def meta():
        return {**now, "E0": E0, "mass": chain.total_mass,
                "cpu_s": cpu_prev + time.process_time() - cpu0,
                "wall_s": wall_prev + time.perf_counter() - wall0,
                # the run's peak over its sessions, and the implicit midpoint's Newton and
                # GMRES iterations summed over them (a resumed session's own started at 0)
                "peak_rss_mib": max(float(before["peak_rss_mib"]), peak_rss_mib()),
                "newton": int(before["newton"]) + getattr(solver, "newton", 0),
                "krylov": int(before["krylov"]) + getattr(solver, "krylov", 0)}

    def on_step(s):
        wall = time.perf_counter()
        if wall - last_ck[0] >= every_s:
            save_checkpoint(path, s, samples, meta())
            last_ck[0] = wall
            rate = (s.t - t_start) / (wall - wall0)
            eta = (t_end - s.t) / rate if rate > 0 else math.inf
            log(f"  checkpoint t = {s.t:.6g} s, {s.counters.steps:,} steps, h = {s.h_next:.2e}, "
                f"wall {meta()['wall_s']:,.0f} s, time to finish {time_to_go(eta)}")
        if wall - wall0 > stop_after_s:
            return (f"stopped by --stop-after = {stop_after_s:g} s of wall time (your "
                    "patience, not a result)")
        return None

    res = sim.run(on_step=on_step, clock="process")
    status, msg = res.status, res.message
    final_meta = {**meta(), "status": "failed" if status < 0 else
                  ("done" if solver.t >= t_end else "stopped"), "message": msg}
    save_checkpoint(path, solver, samples, final_meta)
    final = load_checkpoint(path, log=log)
    if status < 0:
        log(f"{case.name}: FAILED: {msg}")
    elif solver.t >= t_end:
        log(f"{case.name}: done, t = {t_end:g} s")
    else:
        log(f"{case.name}: {msg} at t = {solver.t:.6g} s; the same command resumes it")
    return final


def summary(ck: dict) -> str:
    s = ck["samples"]
    dM = np.abs(s[:, -1]) if len(s) else np.array([np.nan])
    t = float(ck["t"])
    wall = float(ck["wall_s"])
    eta = (float(ck["t_end"]) - t) / (t / wall) if t > 0 else math.inf
    status = str(ck["status"]) if "status" in ck else "in progress"
    return (f"{ck['case']}: {status}, t = {t:.6g} of {float(ck['t_end']):g} s; steps "
            f"{int(ck['steps']):,}, rejected {int(ck['rejected']):,}, RHS {int(ck['nfev']):,}; "
            f"wall {wall:,.0f} s, CPU {float(ck['cpu_s']):,.0f} s; peak RSS "
            f"{float(ck['peak_rss_mib']):,.0f} MiB; avg |delta_M| {dM.mean():.3e} J/kg over "
            f"{len(s)} samples; time to finish at this rate: {time_to_go(eta)}")


FLAGS = {"t_end": "--t-end", "integrator": "--integrator", "rtol": "--rtol", "atol": "--atol",
         "h": "--h", "sample": "--sample"}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m redysim.harness.longrun",
        description="Run a case on the core, checkpointing so that a stopped run resumes where "
                    "it was. Example: python -m redysim.harness.longrun RE-U50000-L1000")
    ap.add_argument("case", help="a case name or the path of a case file")
    ap.add_argument("--t-end", type=positive, help="horizon [s] (default: the case's)")
    ap.add_argument("--integrator", choices=(*INTEGRATORS, *ALIASES),
                    help="default: the case file's (ode45 unless it says otherwise)")
    ap.add_argument("--rtol", type=positive, help="default: the case file's")
    ap.add_argument("--atol", type=positive, help="default: the case file's")
    ap.add_argument("--h", type=positive, help="step of rk4 or midpoint-fixed (default: the "
                    "case file's)")
    ap.add_argument("--sample", type=positive, help="sample interval [s] (default: the case "
                    "file's)")
    ap.add_argument("--every", type=positive, default=DEFAULT_EVERY_S,
                    help=f"wall seconds between checkpoints (default {DEFAULT_EVERY_S:g})")
    ap.add_argument("--out", type=Path, default=None, help="folder of the checkpoint")
    ap.add_argument("--stop-after", type=positive, default=math.inf,
                    help="stop (with a checkpoint) after this many wall seconds")
    ap.add_argument("--status", action="store_true", help="print the checkpoint and exit")
    ap.add_argument("--set-aside", action="store_true",
                    help="a checkpoint written by other code or for other settings is renamed "
                         "beside it (kept, not resumed) and the run starts over, instead of "
                         "refused")
    args = ap.parse_args(argv)

    def err(msg):
        print(msg, file=sys.stderr, flush=True)

    try:
        if args.status:
            case = load_case(args.case)
            method = settings(case, integrator=args.integrator, names=FLAGS)["integrator"]
            path = (args.out or out_dir_for(case.name, method)) / CHECKPOINT
            ck = load_checkpoint(path, log=err)
            print(summary(ck) if ck is not None else f"no readable checkpoint at {path}")
            return EXIT_OK if ck is not None else EXIT_FAILED
        ck = run(args.case, t_end=args.t_end, every_s=args.every, out=args.out,
                 integrator=args.integrator, rtol=args.rtol, atol=args.atol, h=args.h,
                 sample=args.sample, stop_after_s=args.stop_after,
                 log=lambda m: print(m, flush=True), names=FLAGS, set_aside=args.set_aside)
    except (RedysimError, FileNotFoundError) as exc:  # FolderError: a folder it cannot write
        err(f"longrun: error: {exc}")
        return EXIT_USAGE
    except KeyboardInterrupt:
        err("longrun: interrupted; the last checkpoint is kept and the same command resumes")
        return 130
    print(summary(ck))
    return EXIT_FAILED if str(ck.get("status")) == "failed" else EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
