"""Reference solutions: each scenario integrated at tight tolerance with the core, cached on disk.

The reference of (scenario, horizon, sample interval) is the core's RGE-A integrated by our DOP853
(Hairer's error norm over the whole vector) at ``REF_RTOL`` (atol = ``REF_ATOL``); it is checked
by an independent integrator, SciPy's DOP853 at ``CHECK_RTOL``, and the max distance
between the two observed paths (a rope's tip, a robot's observed frame) is stored as
``tol_estimate``, an estimate of the reference's own error.

Why 1e-11: under the max norm dop853 had until issue 51, 1e-10 was the tightest setting that did
not take tiny steps for the rounding noise of qdd (of order eps x cond(GIM) x |qdd|, cond ~
4 nl^4); under Hairer's whole-vector norm the same tolerance is looser (UR5-FALL's path 1.6e-11 m
from SciPy's DOP853 at 1e-13 instead of 1.7e-12, the double pendulum's 2.4e-9 instead of 3.0e-10),
and 1e-11 gives the former accuracy back (1.7e-12 m, 4.2e-10 m) in no more steps
(docs/notes/2026-12-07-norm.md; docs/design.md, "Integrators": reference solutions). Error
measures of a run against the reference: the max tip-position error over the samples and the
final-state error (``redysim.harness.run``).

The cache key is a hash of the scenario's bytes (its file and its model's), the horizon, the
interval, the settings and the core's source (every ``.py`` of ``redysim/``), so editing a
scenario, a model file or the core invalidates its references. Each file has its SHA-256 beside
it (``<name>.sha256``, written after it); a cached reference whose digest is missing or differs,
whose arrays are not the scenario's shapes (samples from 0 to the horizon, the full state, a
3-D path) or not finite, or that cannot be read, is said on stderr and recomputed. A folder
where the cache file goes (or a file where its folder goes) is refused by name
(:func:`check_cache`) before any run. Files are ``.npz`` written atomically (temp file +
``os.replace``) under ``results/reference/`` (``REDYSIM_RESULTS`` moves ``results/``).
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import zipfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from redysim.integrators.explicit import Counters
from redysim.io.scenarios import Scenario
from redysim.simulation import frame_observer

from .provenance import code_digest
from .store import (
    FolderError,
    check_kinds,
    probe_write,
    sha256_file,
    write_npz_atomic,
    write_text_atomic,
)

DIGEST_SUFFIX = ".sha256"  # beside each cached reference: its SHA-256, written after it

REF_METHOD = "dop853"
REF_RTOL = 1e-11
REF_ATOL = 1e-11
CHECK_METHOD = "scipy-DOP853"
CHECK_RTOL = 1e-13
# A second method for a scenario that is not a rope: the same DOP853 on another engine's qdd
# (Pinocchio's ABA: an independent implementation of the dynamics), when installed and able.
CONFIRM_ENGINE = "pinocchio-aba"
# a coupled model's (pin.aba refuses mimic joints): Pinocchio's CRBA on its own mimic joints
CONFIRM_ENGINE_COUPLED = "pinocchio-crba"


RESULTS_ENV = "REDYSIM_RESULTS"  # moves results/ (the reference cache is under it)


def results_dir() -> Path:
    """Where results go: ``$REDYSIM_RESULTS``, else ``results/`` in the working directory."""
    return Path(os.environ.get("REDYSIM_RESULTS") or "results")


@dataclass
class Reference:
    """Samples ``t`` (m,), full states ``y`` (m, n_q + n_v), positions of the observed path
    ``tip`` (m, 3); ``tol_estimate``: the path's largest distance from SciPy's DOP853 at 1e-13
    (a second integrator on the core's qdd); ``engine_check``: from DOP853 on another engine's
    qdd (:data:`CONFIRM_ENGINE`, a second implementation of the dynamics; scenarios that are
    not ropes), ``engine_check_by`` naming it (or why there is none)."""

    t: np.ndarray
    y: np.ndarray
    tip: np.ndarray
    tol_estimate: float
    steps: int
    nfev: int
    cpu_s: float
    engine_check: float = float("nan")  # max path distance from the engine's own solution
    engine_check_by: str = ""  # the engine and its version, or why there is none


def _scenario(case) -> Scenario:
    return case if isinstance(case, Scenario) else Scenario.from_case(case)


def _key(case, t_end: float, interval: float, rtol: float = REF_RTOL) -> str:
    case = _scenario(case)
    blob = json.dumps({"case": case.digest, "frame": case.frame, "t_end": t_end, "dt": interval,
                       "method": REF_METHOD, "rtol": rtol, "check": [CHECK_METHOD, CHECK_RTOL],
                       "core": code_digest()})
    return hashlib.sha256(blob.encode()).hexdigest()[:16]


def reference_path(case, t_end: float, interval: float) -> Path:
    name = "".join(c if c.isalnum() or c in "-_." else "_" for c in _scenario(case).name)
    return results_dir() / "reference" / f"{name}-{_key(case, t_end, interval)}.npz"


def check_cache(case, t_end: float, interval: float) -> Path:
    """Refuse by name (:class:`redysim.harness.store.FolderError`), before any work, a folder
    where ``case``'s cached reference goes or a file where its folder goes; returns its path."""
    p = reference_path(case, t_end, interval)
    check_kinds(files=[p, p.with_name(p.name + DIGEST_SUFFIX)], folders=[p.parent],
                why="the reference cache; nothing was run")
    if not (p.is_file() and p.with_name(p.name + DIGEST_SUFFIX).is_file()):
        # to be computed: its folder must take it, said before the work (--out does not move
        # it: $REDYSIM_RESULTS does)
        try:
            probe_write(p.parent)
        except OSError as exc:
            raise FolderError(
                f"{str(p.parent)!r}: the reference cache cannot be written "
                f"({exc.strerror or type(exc).__name__}); it is "
                f"$REDYSIM_RESULTS/reference ({RESULTS_ENV} = "
                f"{os.environ.get(RESULTS_ENV)!r}; results/reference in the working folder "
                "when unset), which --out does not move: make it writable, or set "
                f"{RESULTS_ENV} to a folder you can write; nothing was run") from None
    return p


def _damage(ref: Reference, case, t_end: float) -> str:
    """Why ``ref`` is not a reference of ``case`` over [0, t_end] ('' when it is)."""
    model = _scenario(case).model
    m, n = len(ref.t), model.n_q + model.n_v
    if ref.t.ndim != 1 or m < 2:
        return f"t has shape {ref.t.shape}, not two samples or more"
    if ref.y.shape != (m, n):
        return f"y has shape {ref.y.shape}, not ({m}, {n}) (the samples by the state)"
    if ref.tip.shape != (m, 3):
        return f"tip has shape {ref.tip.shape}, not ({m}, 3)"
    for name in ("t", "y", "tip"):
        if not np.all(np.isfinite(getattr(ref, name))):
            return f"{name} is not finite"
    if ref.t[0] != 0.0 or abs(ref.t[-1] - t_end) > 1e-9 * max(1.0, t_end) or \
            np.any(np.diff(ref.t) <= 0):
        return f"t runs from {ref.t[0]:g} to {ref.t[-1]:g} s, not from 0 to {t_end:g} s"
    return ""


def load_reference(case, t_end: float, interval: float) -> Reference | None:
    """The cached reference, or None: none, or damaged (said on stderr: then recomputed by
    :func:`compute_reference`)."""
    p = reference_path(case, t_end, interval)
    if not p.exists():
        return None
    digest = p.with_name(p.name + DIGEST_SUFFIX)
    try:
        if not digest.is_file() or digest.read_text().strip() != sha256_file(p):
            raise ValueError(f"its SHA-256 is not the one {digest.name} recorded")
        with np.load(p) as z:
            ref = Reference(z["t"], z["y"], z["tip"], float(z["tol_estimate"]),
                            int(z["steps"]), int(z["nfev"]), float(z["cpu_s"]),
                            float(z["engine_check"]), str(z["engine_check_by"]))
        if why := _damage(ref, case, t_end):
            raise ValueError(why)
        return ref
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as exc:
        # (the writer is atomic, so only outside damage does this)
        print(f"redysim: the cached reference {p} is damaged ({str(exc)[:200]}); it is "
              "recomputed", file=sys.stderr)
        return None


def _solve(case, t_end, interval, method, rtol, qdd=None):
    """The scenario integrated by the one simulation driver (a rope's tip force included; an
    engine's ``qdd`` instead of the core's when given): samples, states, observed positions,
    counts, CPU time."""
    case = _scenario(case)
    sim = case.simulator(t_end, integrator=method, rtol=rtol, atol=rtol, sample=interval,
                         observe={"tip": frame_observer(case.model, case.frame)}, qdd=qdd)
    res = sim.run(clock="process")
    if res.status != 0:
        raise RuntimeError(f"reference of {case.name} failed: {res.message}")
    P = res.observed["tip"][:, :3]
    Y = np.concatenate((res.q, res.v), axis=1)
    return res.t, Y, P, Counters(res.steps, res.rejected, res.nfev), res.cpu_s


def compute_reference(case, t_end: float, interval: float, *, force: bool = False) -> Reference:
    """Compute (or load) and cache the reference of ``case`` over [0, t_end], sampled at
    ``interval``."""
    p = check_cache(case, t_end, interval)
    if not force and (ref := load_reference(case, t_end, interval)) is not None:
        return ref
    ts, Y, P, cnt, cpu = _solve(case, t_end, interval, REF_METHOD, REF_RTOL)
    _, _, P_check, _, _ = _solve(case, t_end, interval, CHECK_METHOD, CHECK_RTOL)
    est = float(np.linalg.norm(P - P_check, axis=1).max())
    by, engine_est = _confirm(case, t_end, interval, P)
    p.parent.mkdir(parents=True, exist_ok=True)
    write_npz_atomic(p, t=ts, y=Y, tip=P, tol_estimate=est, steps=cnt.steps, nfev=cnt.nfev,
                     cpu_s=cpu, engine_check=engine_est, engine_check_by=by)
    write_text_atomic(sha256_file(p) + "\n", p.with_name(p.name + DIGEST_SUFFIX))
    return Reference(ts, Y, P, est, cnt.steps, cnt.nfev, cpu, engine_est, by)


def _confirm(case, t_end: float, interval: float, P) -> tuple[str, float]:
    """(who, the largest path distance) of the reference against the same DOP853 on
    :data:`CONFIRM_ENGINE`'s qdd (a coupled model: :data:`CONFIRM_ENGINE_COUPLED`'s): a second
    implementation of the dynamics. Ropes (their numbers checked against the paper and the
    engines elsewhere) and closed loops are not confirmed so; an engine that is missing or
    refuses says why."""
    scn = _scenario(case)
    if scn.case is not None:
        return "none: a rope case, checked against the paper's tables and the engines", math.nan
    if scn.model.cuts:
        return "none: closed loops, which the engines' loop adapters take assembled only", \
            math.nan
    from redysim import references

    name = CONFIRM_ENGINE_COUPLED if scn.model.couplings else CONFIRM_ENGINE
    cls = references.get(name)
    if not cls.available():
        return f"none: {cls.package} is not installed", math.nan
    lim = cls.limits(scn.model)
    if not lim.ok:
        return f"none: {lim.reason}", math.nan
    eng = cls(scn.model)
    _, _, P_engine, _, _ = _solve(scn, t_end, interval, REF_METHOD, REF_RTOL, qdd=eng.qdd)
    return (f"{name} {eng.version}",
            float(np.linalg.norm(P - P_engine, axis=1).max()))


def ensure_references(specs) -> dict[tuple, Reference]:
    """Compute the missing references of a list of RunSpecs (once per scenario, horizon,
    interval). A spec whose scenario or settings are bad is skipped: its run fails with the
    reason."""
    from redysim.errors import RedysimError
    from redysim.io.scenarios import load_scenario

    out = {}
    for spec in specs:
        try:
            case = load_scenario(spec.case, options=spec.model_options())
            run = spec.resolved(case)
        except (RedysimError, OSError):
            continue
        key = (spec.case, spec.options, run.t_end, run.sample)
        if key not in out:
            out[key] = compute_reference(case, run.t_end, run.sample)
    return out
