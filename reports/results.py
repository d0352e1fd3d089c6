"""Read every result on disk that the report uses; nothing here computes or runs anything.

Layout under the results folder (``results/`` by default; each producer's docstring has its own):

    sweeps/<name>/runs/<run_id>.parquet      one summary row per finished run
                                             (redysim.harness.sweep)
    sweeps/<name>/samples/<run_id>.parquet   its samples (tip, energy, delta_M)
    longrun/<case>/checkpoint.npz            a checkpointed long run (redysim.harness.longrun:
                                             Table 5)
    precision/<table>.json                   Tables 8, 10, 11, A.2, IEEE
                                             (redysim.reports.precision_tables)
    error_study/error_study.parquet          true error vs an mpmath reference
                                             (redysim.harness.error_study)
    gim_study/table9.json, cond.parquet      Table 9, cond2 vs links (redysim.reports.gim_study)
    opcount/opcount.json                     Table 7 (redysim.reports.opcount)
    scaling/scaling.parquet                  qdd per call vs DOF (redysim.reports.scaling)
    bench/core.json, bench/engines.json      pytest-benchmark (make bench, make bench-engines)
    reproduce-<kind>.json                    what the last reproduction of each kind (quick, full,
                                             tables) ran, and its wall time

Runs are read from the per-run files, not from runs.parquet, so an interrupted sweep's finished
runs count; as in :func:`redysim.harness.sweep.collect`, only the runs of a folder's current plan
(sweep.json). Runs of every sweep folder are pooled: the same run (same run_id) made by two
sweeps is one run.
"""

from __future__ import annotations

import functools
import json
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

from redysim.harness.longrun import CHECKPOINT as LONGRUN_CHECKPOINT
from redysim.harness.longrun import SAMPLE_FIELDS as LONGRUN_SAMPLE_FIELDS
from redysim.harness.longrun import load_checkpoint
from redysim.harness.spec import CORE
from redysim.harness.store import parquet_files, read_parquet
from redysim.harness.sweep import PLAN_FILE, RUNS_DIR, SAMPLES_DIR

SWEEPS_DIR = "sweeps"
PRECISION_DIR = "precision"
ERROR_STUDY_FILE = Path("error_study") / "error_study.parquet"
TABLE9_FILE = Path("gim_study") / "table9.json"
COND_FILE = Path("gim_study") / "cond.parquet"
OPCOUNT_FILE = Path("opcount") / "opcount.json"
SCALING_FILE = Path("scaling") / "scaling.parquet"
ROBOTS_FILE = Path("robots") / "robots.json"
LOOPS_FILE = Path("loops") / "loops.json"
PROTEINS_FILE = Path("proteins") / "proteins.json"
REFINE_FILE = Path("refine") / "refine.json"
BENCH_DIR = "bench"
REPRODUCE_GLOB = "reproduce-*.json"
LONGRUN_DIR = "longrun"
PARTIAL = "partial"   # status of a long run whose checkpoint has not reached t_end yet
HORIZON_SLACK = 1e-9  # a long run at t_end (1 - this) has reached t_end


def _json(path: Path):
    if not path.is_file():
        return None
    with open(path, encoding="utf-8") as fh:
        return json.load(fh)


def _parquet(path: Path) -> pd.DataFrame | None:
    return read_parquet(path) if path.is_file() else None


@functools.cache
def _case(case: str):
    """A loaded scenario, a rope case or another (cached: the report asks about each case many
    times)."""
    from redysim.io.scenarios import load_scenario

    return load_scenario(case)


def case_horizon(case: str) -> float:
    """A case's own t_end [s] (what a run with t_end = 0 runs to)."""
    return _case(case).t_end


def scenario_gravity(case: str):
    """A scenario's gravity (3,) [m/s^2], as its model has it."""
    return _case(case).model.gravity


def momentum_kept(case: str) -> bool:
    """Whether a scenario's angular momentum about its centre of mass is constant: a floating
    system (a free root joint) under no force but uniform gravity (no tip force, damping or
    loops)."""
    return bool(_case(case).momentum_kept)


def momentum_drift_series(samples: pd.DataFrame) -> np.ndarray:
    """|h_G(t) - h_G(0)| / max |h_G(0)| (max over the components) at each of a run's samples,
    in the order of t (their h_* columns)."""
    h = samples.sort_values("t")[["h_x", "h_y", "h_z"]].to_numpy(dtype=float)
    size = np.abs(h[0]).max()
    return np.abs(h - h[0]).max(axis=1) / size if size > 0 else np.full(len(h), math.nan)


def momentum_drift(samples: pd.DataFrame | None) -> float:
    """The largest :func:`momentum_drift_series` over a run's samples; NaN without them."""
    if samples is None or len(samples) < 2 or "h_x" not in samples:
        return math.nan
    return float(momentum_drift_series(samples).max())


def case_sample_interval(case: str) -> float:
    """A case's own sample interval [s] (its file's, else t_end / FILE_SAMPLES, as a run takes
    it)."""
    scn = _case(case)
    return scn.sample_for(scn.t_end)


class Results:
    """Lazy, cached readers of one results folder."""

    def __init__(self, root: str | Path):
        self.root = Path(root)
        self._samples_paths: dict[str, Path] = {}
        self._longrun_samples: dict[str, pd.DataFrame] = {}

    # ----------------------------------------------------------------------- sweeps
    @functools.cached_property
    def runs(self) -> pd.DataFrame:
        """Every finished run of every sweep folder, one row per run_id, with ``sweep`` (the
        folder) and ``horizon`` (the t_end the run was asked for, the case's when 0)."""
        frames = []
        for sweep_dir in sorted((self.root / SWEEPS_DIR).glob("*/")):
            files = parquet_files(sweep_dir / RUNS_DIR)
            plan = sweep_dir / PLAN_FILE
            if plan.is_file():  # runs an earlier version of the sweep file planned are left out
                planned = {r["run_id"] for r in _json(plan)["runs"]}
                files = {k: v for k, v in files.items() if k in planned}
            if not files:
                continue
            df = pd.concat([read_parquet(p) for p in files.values()], ignore_index=True)
            df["sweep"] = sweep_dir.name
            frames.append(df)
            for run_id, path in parquet_files(sweep_dir / SAMPLES_DIR).items():
                self._samples_paths.setdefault(run_id, path)
        longruns = self.longruns()
        if len(longruns):
            frames.append(longruns)
        if not frames:
            return pd.DataFrame(columns=["run_id", "case", "engine", "method", "integrator",
                                         "status", "sweep", "horizon"])
        runs = pd.concat(frames, ignore_index=True).drop_duplicates("run_id", keep="first")
        # runs saved before RunSpec.perturb existed ran the case's own initial state
        runs["perturb"] = (runs["perturb"].astype(float).fillna(0.0) if "perturb" in runs
                           else 0.0)
        runs["horizon"] = [t if t > 0 else case_horizon(c)
                           for t, c in zip(runs["t_end"], runs["case"], strict=True)]
        return runs.reset_index(drop=True)

    def longruns(self) -> pd.DataFrame:
        """The checkpointed long runs (:mod:`redysim.harness.longrun`) as summary rows shaped like a
        sweep's: status ``ok`` once the checkpoint reached t_end, else ``partial``."""
        rows = []
        for path in sorted((self.root / LONGRUN_DIR).glob(f"*/{LONGRUN_CHECKPOINT}")):
            ck = load_checkpoint(path, log=lambda msg: print(f"report: {msg}", file=sys.stderr))
            if ck is None:  # damaged, and no readable previous one: not in the report
                continue
            case, t, t_end = str(ck["case"]), float(ck["t"]), float(ck["t_end"])
            integrator = str(ck["integrator"]) if "integrator" in ck else "ode45"
            # the folder names the run: a case's ode45 run is <case>, others <case>-<what>
            run_id = f"{LONGRUN_DIR}:{path.parent.name}"
            samples = pd.DataFrame(ck["samples"], columns=list(LONGRUN_SAMPLE_FIELDS))
            self._longrun_samples[run_id] = samples
            done = t >= t_end * (1 - HORIZON_SLACK)
            rows.append({
                "run_id": run_id, "case": case, "engine": CORE, "method": "rge-a",
                "integrator": integrator, "rtol": float(ck["rtol"]), "atol": float(ck["atol"]),
                "h": float(ck["fixed_h"]) if "fixed_h" in ck else 0.0, "t_end": t_end,
                "sample": float(ck["sample"]) if "sample" in ck else
                case_sample_interval(case),
                "newton": int(ck["newton"]) if "newton" in ck else 0,
                "krylov": int(ck["krylov"]) if "krylov" in ck else 0,
                "status": "ok" if done else PARTIAL,
                "reason": "" if done else (f"checkpoint at t = {t:.4g} of {t_end:g} s: "
                                           f"python -m redysim.harness.longrun {case} resumes it"),
                "steps": int(ck["steps"]), "rejected": int(ck["rejected"]),
                "nfev": int(ck["nfev"]), "cpu_s": float(ck["cpu_s"]),
                "wall_s": float(ck["wall_s"]), "peak_rss_mib": float(ck["peak_rss_mib"]),
                "n_dof": int(ck["n_dof"]), "E0": float(ck["E0"]),
                "avg_abs_delta_M": float(samples["delta_M"].abs().mean()),
                "max_abs_delta_M": float(samples["delta_M"].abs().max()),
                "t_reached": t, "n_samples": len(samples), "sweep": LONGRUN_DIR,
                "label": f"{case} redysim/rge-a {integrator} (checkpointed long run)"})
        return pd.DataFrame(rows)

    def samples(self, run_id: str) -> pd.DataFrame | None:
        """The samples of one run, or None (a long run's have no tip velocity or
        acceleration)."""
        self.runs  # noqa: B018 -- fills the run_id -> samples maps
        if run_id in self._longrun_samples:
            return self._longrun_samples[run_id]
        path = self._samples_paths.get(run_id)
        return read_parquet(path) if path else None

    def sweep_plan(self, name: str) -> list[dict] | None:
        """The runs a sweep folder's plan (its sweep.json) lists, or None without one."""
        doc = _json(self.root / SWEEPS_DIR / name / PLAN_FILE)
        return None if doc is None else list(doc.get("runs", []))

    def sweep_counts(self) -> dict[str, tuple[int, int | None, int]]:
        """{sweep folder: (its finished runs on disk that its plan lists, the runs its plan
        lists or None without a plan, those of them the report shows under this folder)}: a
        run two sweeps made is shown once, under the first folder."""
        shown = self.sweep_dirs()
        out = {}
        for sweep_dir in sorted((self.root / SWEEPS_DIR).glob("*/")):
            plan = self.sweep_plan(sweep_dir.name)
            files = parquet_files(sweep_dir / RUNS_DIR)
            planned = None if plan is None else {r["run_id"] for r in plan}
            done = len(files) if planned is None else len(planned & set(files))
            if done or planned:
                out[sweep_dir.name] = (done, None if planned is None else len(planned),
                                       shown.get(sweep_dir.name, 0))
        return out

    def sweep_dirs(self) -> dict[str, int]:
        """{sweep folder: its runs in the report}."""
        runs = self.runs
        return runs.groupby("sweep").size().to_dict() if len(runs) else {}

    # ----------------------------------------------------------------------- other producers
    def precision(self, name: str) -> dict | None:
        """``precision/<name>.json`` (table8, table10, table11, tableA2, ieee), or None."""
        return _json(self.root / PRECISION_DIR / f"{name}.json")

    @functools.cached_property
    def error_study(self) -> pd.DataFrame | None:
        return _parquet(self.root / ERROR_STUDY_FILE)

    @functools.cached_property
    def table9(self) -> dict | None:
        return _json(self.root / TABLE9_FILE)

    @functools.cached_property
    def cond(self) -> pd.DataFrame | None:
        return _parquet(self.root / COND_FILE)

    @functools.cached_property
    def opcount(self) -> dict | None:
        return _json(self.root / OPCOUNT_FILE)

    @functools.cached_property
    def robots(self) -> dict | None:
        """``robots/robots.json`` (:mod:`redysim.reports.robots`), or None."""
        return _json(self.root / ROBOTS_FILE)

    @functools.cached_property
    def refine(self) -> dict | None:
        """``refine/refine.json`` (:mod:`redysim.harness.refine`), or None."""
        return _json(self.root / REFINE_FILE)

    @functools.cached_property
    def proteins(self) -> dict | None:
        """``proteins/proteins.json`` (:mod:`redysim.reports.proteins`), or None."""
        return _json(self.root / PROTEINS_FILE)

    @functools.cached_property
    def loops(self) -> dict | None:
        """``loops/loops.json`` (:mod:`redysim.reports.loops`), or None."""
        return _json(self.root / LOOPS_FILE)

    @functools.cached_property
    def scaling(self) -> pd.DataFrame | None:
        return _parquet(self.root / SCALING_FILE)

    def bench(self, name: str) -> dict | None:
        """``bench/<name>.json`` (pytest-benchmark: core, engines), or None."""
        return _json(self.root / BENCH_DIR / f"{name}.json")

    @functools.cached_property
    def reproductions(self) -> list[dict]:
        """The records of the last reproduction of each kind, oldest first."""
        docs = [_json(p) for p in self.root.glob(REPRODUCE_GLOB)]
        return sorted((d for d in docs if d), key=lambda d: d.get("started", ""))

    def sources(self) -> list[tuple[str, str]]:
        """(what, where and how much) for everything found, for the setup section."""
        out = []
        for name, (done, planned, shown) in self.sweep_counts().items():
            where = f"{SWEEPS_DIR}/{name}: {done:,} runs"
            if planned is not None and done < planned:
                where += f" of {planned:,} planned (partial: the sweep stopped part way)"
            if shown < done:
                where += (f"; {done - shown:,} of them also made by another sweep, shown once "
                          "under the first folder")
            out.append((f"sweep {name}", where))
        n_long = self.sweep_dirs().get(LONGRUN_DIR)
        if n_long:
            out.append(("checkpointed long runs",
                        f"{LONGRUN_DIR}/*/{LONGRUN_CHECKPOINT}: {n_long} runs"))
        for name in ("table8", "table10", "table11", "tableA2", "ieee"):
            doc = self.precision(name)
            if doc is not None:
                out.append((f"precision {name}", f"{PRECISION_DIR}/{name}.json "
                                                 f"({doc.get('meta', {}).get('generated', '')})"))
        for label, path, value in (("error study", ERROR_STUDY_FILE, self.error_study),
                                   ("conditioning", COND_FILE, self.cond),
                                   ("CPU scaling", SCALING_FILE, self.scaling)):
            if value is not None:
                out.append((label, f"{path}: {len(value)} rows"))
        for label, path, value in (("Table 9", TABLE9_FILE, self.table9),
                                   ("Table 7 (operation counts)", OPCOUNT_FILE, self.opcount)):
            if value is not None:
                out.append((label, str(path)))
        for name in ("core", "engines"):
            doc = self.bench(name)
            if doc is not None:
                out.append((f"benchmarks {name}", f"{BENCH_DIR}/{name}.json "
                                                  f"({doc.get('datetime', '')})"))
        return out


def finite(x) -> bool:
    """True for a finite number (False for None, NaN, inf, strings)."""
    try:
        return math.isfinite(float(x))
    except (TypeError, ValueError):
        return False
