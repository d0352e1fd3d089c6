"""Sweeps as data: TOML files declare cross products of runs, run resumably, locally or on Dask.

A sweep file has one table, ``[sweep]``, whose lists multiply into runs (every case x engine x
method x integrator x tolerance or step)::

    [sweep]
    name = "smoke"
    description = "two chains, two integrators, two tolerances"
    cases = ["STUDY-R3", "RE-U125-L1"]   # scenarios: names from cases/ and cases/scenarios/,
                                         # or paths of case, scenario or model files
    engines = ["redysim"]                # default ["redysim"]; others: redysim.references.ENGINES
    methods = ["rge-a"]                  # the core's methods (default ["rge-a"]); engines take none
    integrators = ["ode45", "rk4"]       # redysim.integrators.explicit.INTEGRATORS, "native" or
                                         # "native:NAME" (an engine's own: each engine of the
                                         # table that has it; the others skip it)
    rtols = [1e-4, 1e-6]                 # adaptive integrators: one run per rtol
    atol_ratio = 1e-2                    # atol = rtol * atol_ratio (default); or atols = [...],
                                         # paired with rtols one to one
    h = [1e-3]                           # fixed-step integrators (rk4, native): one run per h
    perturbs = [0, 1e-13]                # optional: one run per initial-state perturbation
                                         # (RunSpec.perturb; default [0], the case's state)
    links = [0, 25, 5]                   # optional: one run per model size (RunSpec.links: the
                                         # case's chain coarse-grained; 0 = the case's own)
    precisions = ["float64", "float32"]  # optional: the arithmetic of the core's qdd
    t_end = 0.01                         # scalars shared by every run (RunSpec's meanings)
    sample = 0.005
    energy_bound = 1e3
    max_cpu_s = 60                       # a run's CPU-time limit [s] (RunSpec.max_cpu_s)

    [[sweep.product]]                    # another cross product: what it does not give, it
    engines = ["mujoco", "dart"]         # takes from [sweep]
    integrators = ["ode45"]

    [[sweep.extra]]                      # one explicit run: RunSpec's fields; t_end, sample,
    case = "STUDY-R10"                   # energy_bound and max_cpu_s default to [sweep]'s
    integrator = "dop853"
    rtol = 1e-8
    atol = 1e-10

A bad file raises :class:`SweepError` naming the file, the field and the value. Runs are
identified by :attr:`RunSpec.run_id`; a run declared twice is run once. The id includes the
code's digest (``redysim/`` and ``references/``), so after a change to the code a resumed sweep
runs everything again instead of mixing results of two versions.

:func:`run_sweep` writes into ``out_dir``::

    sweep.json                   the plan: name, source and every planned run (atomically)
    samples/<run_id>.parquet     a finished run's samples (written first)
    manifest/<run_id>.json       the run's files and their SHA-256 (written next)
    runs/<run_id>.parquet        its summary row (moved into place last: it marks the run done)
    runs.parquet, samples.parquet  everything, in plan order (:func:`collect`)

Every file is written atomically (:mod:`redysim.harness.store`), so a sweep killed at any moment
(even ``kill -9``) and started again skips the runs it finished and redoes only those in flight.
A finished run whose files are not those its manifest lists (one deleted, or changed), or whose
manifest is missing or damaged, is said on stderr and done again; a finished sweep read again
rewrites nothing. A folder that cannot be written is refused by name
(:class:`redysim.harness.store.FolderError`) before any run, unless every run in it is
finished: then it is read as it is. At most ``workers`` runs are in flight on the local pool.
A run that fails is a row with ``status = "failed"`` and its ``reason``; so is a run whose
worker raised or died.
"""

from __future__ import annotations

import contextlib
import fcntl
import io
import itertools
import json
import logging
import math
import multiprocessing
import os
import re
import sys
import threading
import time
import tomllib
from collections import deque
from collections.abc import Callable, Iterable, Iterator, Sequence
from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pandas as pd
from tqdm import tqdm

from redysim import list_cases, references
from redysim.errors import FieldError, RedysimError, SettingsError
from redysim.integrators.explicit import ALIASES, INTEGRATORS
from redysim.io.cases import is_case_name
from redysim.io.kinds import by_suffix
from redysim.io.robots import PREFIX as ROBOT_DATA
from redysim.io.scenarios import list_scenarios, load_scenario

from . import REDYSIM_THREADS, worker_threads
from .run import SAMPLE_COLUMNS, execute
from .spec import (
    CORE,
    CORE_METHODS,
    NATIVE,
    PRECISIONS,
    STEPPED,
    RunSpec,
    is_native,
    native_integrator,
    stepped,
)
from .store import (
    FILE_MODE,
    PARQUET_SUFFIX,
    FolderError,
    check_kinds,
    check_writable,
    parquet_files,
    parquet_metadata,
    read_json,
    read_parquet,
    remove_temp_files,
    sha256_file,
    writable,
    write_json_atomic,
    write_parquet_atomic,
)

# a run's settings, and the sweep-file list each comes from
SETTINGS = ("integrator", "rtol", "atol", "h", "t_end", "sample", "links", "precision")
LIST_NAMES = {"integrator": "integrators", "rtol": "rtols", "atol": "atols", "h": "h",
              "t_end": "t_end", "sample": "sample", "links": "links",
              "precision": "precisions"}
SWEEP_TABLE = "sweep"
PRODUCT_TABLE = "product"
EXTRA_TABLE = "extra"
LIST_FIELDS = ("cases", "engines", "methods", "integrators", "rtols", "atols", "h", "perturbs",
               "links", "precisions")
SCALAR_FIELDS = ("atol_ratio", "t_end", "sample", "energy_bound", "max_cpu_s")
SHARED_SCALARS = ("t_end", "sample", "energy_bound", "max_cpu_s")  # handed down to extra runs
# fields renamed, and why: a sweep file that still gives one is told its new name
RENAMED = {"max_wall_s": ("max_cpu_s", "a run's time limit counts seconds of CPU time: a "
                          "wall-clock limit made a sweep's recorded results depend on the "
                          "machine's load")}
TEXT_FIELDS = ("name", "description")
BOOL_FIELDS = ("reference",)  # reference = true: compute the cases' reference solutions first
STRICTLY_POSITIVE = ("atol_ratio", "energy_bound", "rtol", "atol")  # the others may be 0
STEPPED_INTEGRATORS = STEPPED  # take h values; all others take rtols
KNOWN_INTEGRATORS = (*INTEGRATORS, *ALIASES, NATIVE)
DEFAULT_ATOL_RATIO = 1e-2  # the paper's ode45 setting: rtol 1e-4, atol 1e-6
TOL_DIGITS = 12  # atol = rtol * atol_ratio is rounded to 12 significant digits: 1e-06, not
#                  1.0000000000000002e-06 (the run_id hashes the exact float)

SWEEP_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._-]*")  # a folder name, never a path
PLAN_FILE = "sweep.json"
CLAIMS_DIR = ".claims"  # one lock file per run in flight (Claims)
DAMAGED_DIR = "damaged"  # result files that could not be read, kept for a look
RUNS_DIR = "runs"
SAMPLES_DIR = "samples"
STAGED_SUFFIX = ".staged"  # a summary row written, to be moved into place after its manifest
MANIFEST_DIR = "manifest"  # manifest/<run_id>.json: a finished run's files and their SHA-256
RUNS_FILE = "runs.parquet"
SAMPLES_FILE = "samples.parquet"
# the columns a finished run's summary row always has (redysim.harness.run.execute writes them)
ROW_COLUMNS = ("run_id", "label", "status", "reason", "steps", "rejected", "nfev", "cpu_s",
               "E0", "avg_abs_delta_M", "max_abs_delta_M", "t_reached", "n_samples",
               "max_tip_err")

POOL_START_METHOD = "spawn"  # fresh interpreters: safe with numba and with threads in the parent
DASK_LOCAL = "local"  # dask= value that starts a LocalCluster on this machine
DASK_LOCAL_WORKERS = 2
DASK_KEY_PREFIX = "redysim-run-"
DASK_IN_FLIGHT = 256  # runs submitted (and claimed) at a time
DASK_CONNECT_TIMEOUT_S = 10
DASK_WORKERS_TIMEOUT_S = 60  # how long a sweep waits for a scheduler's first worker
PARENT_POLL_S = 1.0  # how often a pool worker checks that its sweep is still there
DIED = "worker process died (out of memory, a crash in native code, or a signal)"


class SweepError(FieldError):
    """A sweep file is malformed: ``<file>: <field> = <value>: <what is wrong>``."""


@dataclass(frozen=True)
class Sweep:
    """A loaded sweep file: its name and the runs it declares, in declaration order."""

    name: str
    specs: tuple[RunSpec, ...]
    description: str = ""
    source: str = ""
    reference: bool = False


# --------------------------------------------------------------------------- the sweep file
def load_sweep(path: str | os.PathLike) -> Sweep:
    """Read and expand a sweep file; case paths in it are relative to the file's folder."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"sweep file {str(path)!r} does not exist")
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except tomllib.TOMLDecodeError as exc:
        raise SweepError(str(path), "<toml syntax>", None, str(exc)) from None
    except UnicodeDecodeError as exc:  # a sweep file is UTF-8 text
        raise SweepError(str(path), "<toml syntax>", None,
                         f"not UTF-8 text (byte {exc.object[exc.start]:#04x} at offset "
                         f"{exc.start})") from None
    return sweep_from_dict(doc, source=str(path), base=path.parent)


def sweep_from_dict(doc: dict, *, source: str = "<dict>", base: Path | None = None) -> Sweep:
    """Expand a parsed sweep document (see the module docstring) into a :class:`Sweep`."""
    check = _Checker(source, Path.cwd() if base is None else base)
    for key in doc:
        if key != SWEEP_TABLE:
            check.fail(key, None, f"unknown table; a sweep file has only [{SWEEP_TABLE}]")
    table = doc.get(SWEEP_TABLE)
    if not isinstance(table, dict):
        check.fail(SWEEP_TABLE, table, f"a sweep file needs a [{SWEEP_TABLE}] table")
    top = check.fields(table, SWEEP_TABLE, (*TEXT_FIELDS, *BOOL_FIELDS, *LIST_FIELDS,
                                            *SCALAR_FIELDS, PRODUCT_TABLE, EXTRA_TABLE))
    reference = table.get("reference", False)
    if not isinstance(reference, bool):
        check.fail(f"{SWEEP_TABLE}.reference", reference, "must be true or false")
    if "cases" not in top:
        check.fail(f"{SWEEP_TABLE}.cases", None, "missing: list the cases to run")
    products = [(SWEEP_TABLE, top, "h" in top)]  # (where, settings, whether it gives h itself)
    for i, sub in enumerate(check.tables(table, PRODUCT_TABLE)):
        where = f"{SWEEP_TABLE}.{PRODUCT_TABLE}[{i}]"
        given = check.fields(sub, where, (*LIST_FIELDS, *SCALAR_FIELDS))
        inherited = {k: v for k, v in top.items() if k in LIST_FIELDS + SCALAR_FIELDS}
        if "atols" in given or "atol_ratio" in given:
            inherited.pop("atols", None)
            inherited.pop("atol_ratio", None)
        products.append((where, {**inherited, **given}, "h" in given))
    if len(products) > 1:  # the top table's h may be there for its products' fixed steps
        products[0] = (SWEEP_TABLE, top, False)
    specs = [spec for where, settings, own_h in products
             for spec in check.expand(where, settings, own_h=own_h)]
    shared = {k: top[k] for k in SHARED_SCALARS if k in top}
    for i, sub in enumerate(check.tables(table, EXTRA_TABLE)):
        specs.append(check.extra(f"{SWEEP_TABLE}.{EXTRA_TABLE}[{i}]", sub, shared))
    name = top.get("name") or Path(source).stem
    if not SWEEP_NAME.fullmatch(name):
        check.fail(f"{SWEEP_TABLE}.name" if "name" in top else "<file name>", name,
                   "must be a plain folder name (letters, digits, '.', '_', '-'; no '/'): it "
                   "names the sweep's folder under the results folder")
    return Sweep(name=name, specs=tuple(unique(specs)), description=top.get("description", ""),
                 source=source, reference=reference)


def unique(specs: Iterable[RunSpec]) -> list[RunSpec]:
    """``specs`` without repeats (same run_id), in first-seen order."""
    seen: dict[str, RunSpec] = {}
    for spec in specs:
        seen.setdefault(spec.run_id, spec)
    return list(seen.values())


class _Checker:
    """Validates the fields of one sweep file; every error names the file, field and value."""

    def __init__(self, source: str, base: Path):
        self.source = source
        self.base = base
        self.case_names = set(list_cases()) | set(list_scenarios())
        self.engines = (CORE, *references.ENGINES)
        self.loaded: dict[str, Any] = {}  # case -> its loaded Case

    def resolved(self, where: str, spec: RunSpec, fields_: dict[str, str]) -> RunSpec:
        """``spec`` with the case's settings filled in and every setting checked; a bad one
        fails naming the sweep file's field (``fields_``: RunSpec field -> sweep field)."""
        if spec.case not in self.loaded:
            self.loaded[spec.case] = load_scenario(spec.case)
        names = {k: f"{where}.{v}" for k, v in fields_.items()}
        try:
            return spec.resolved(self.loaded[spec.case], source=self.source, names=names)
        except SettingsError as exc:
            raise SweepError(self.source, exc.field, exc.value,
                             f"{exc.problem} (case {spec.case})") from None

    def fail(self, field: str, value: Any, problem: str):
        raise SweepError(self.source, field, value, problem)

    def renamed(self, field: str, key: str, value: Any) -> None:
        """Refuse a field by its old name, giving the new one (:data:`RENAMED`)."""
        if key in RENAMED:
            new, why = RENAMED[key]
            self.fail(field, value, f"renamed {new}: {why}")

    def tables(self, table: dict, key: str) -> list[dict]:
        subs = table.get(key, [])
        if not isinstance(subs, list) or not all(isinstance(s, dict) for s in subs):
            self.fail(f"{SWEEP_TABLE}.{key}", subs, f"must be tables: [[{SWEEP_TABLE}.{key}]]")
        return subs

    def fields(self, node: dict, where: str, allowed: Sequence[str]) -> dict:
        """The checked values of ``node``'s fields (lists and scalars, not sub-tables)."""
        out = {}
        for key, value in node.items():
            field = f"{where}.{key}"
            self.renamed(field, key, value)
            if key not in allowed:
                self.fail(field, value, f"unknown field; allowed: {', '.join(allowed)}")
            if key in TEXT_FIELDS:
                out[key] = self.text(field, value)
            elif key in LIST_FIELDS:
                out[key] = self.values(field, key, value)
            elif key in SCALAR_FIELDS:
                out[key] = self.scalar(field, key, value)
        return out

    # ----------------------------------------------------------------------- single values
    def text(self, field: str, value: Any) -> str:
        if not isinstance(value, str):
            self.fail(field, value, "must be a string")
        return value

    def number(self, field: str, value: Any, *, strict: bool) -> float:
        """A finite number > 0 (``strict``) or >= 0."""
        if isinstance(value, bool) or not isinstance(value, int | float):
            self.fail(field, value, "must be a number")
        value = float(value)
        if not math.isfinite(value) or not (value > 0 if strict else value >= 0):
            self.fail(field, value, "must be a finite number " + ("> 0" if strict else ">= 0"))
        return value

    def scalar(self, field: str, key: str, value: Any) -> float:
        return self.number(field, value, strict=key in STRICTLY_POSITIVE)

    def case(self, field: str, value: Any) -> str:
        """A case name from ``cases/``, or the path of a valid case file (made absolute;
        relative to the sweep file's folder). A name without a folder or ``.toml`` is a
        built-in case only (:func:`redysim.io.cases.case_path`)."""
        name = self.text(field, value)
        if name.startswith(ROBOT_DATA):  # a robot of example-robot-data, kept by its name
            try:
                self.loaded[name] = load_scenario(name)
            except (RedysimError, OSError) as exc:
                self.fail(field, value, str(exc))
            return name
        if is_case_name(name) and not by_suffix(name):  # a name, not a model file
            if name not in self.case_names:
                self.fail(field, value, f"no such case or scenario; known: "
                                        f"{', '.join(sorted(self.case_names))} (a file is "
                                        "given by its path, e.g. ./mine.toml)")
            return name
        path = Path(name) if Path(name).is_absolute() else self.base / name
        if not path.is_file():
            self.fail(field, value, "no such file")
        resolved = str(path.resolve())
        try:
            self.loaded[resolved] = load_scenario(resolved)
        except (RedysimError, OSError) as exc:
            self.fail(field, value, f"bad scenario file: {exc}")
        return resolved

    def integrator(self, field: str, value: Any) -> str:
        """One of redysim's integrators, "native", or "native:NAME" of at least one engine."""
        value = self.text(field, value)
        if is_native(value) and value != NATIVE:
            own = {f"native:{n}" for cls in references.ENGINES.values() for n in cls.integrators}
            if value not in own:
                self.fail(field, value, f"no engine has this integrator; engines' own: "
                                        f"{', '.join(sorted(own))}")
            return value
        return self.choice(field, value, KNOWN_INTEGRATORS, "integrator")

    def choice(self, field: str, value: Any, known: Sequence[str], what: str) -> str:
        value = self.text(field, value)
        if value not in known:
            self.fail(field, value, f"unknown {what}; choose from {', '.join(known)}")
        return value

    def item(self, field: str, key: str, value: Any):
        if key == "cases":
            return self.case(field, value)
        if key == "engines":
            return self.choice(field, value, self.engines, "engine")
        if key == "methods":
            return self.choice(field, value, CORE_METHODS, "method of the core")
        if key == "integrators":
            return self.integrator(field, value)
        if key == "precisions":
            return self.choice(field, value, PRECISIONS, "precision")
        if key == "links":
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                self.fail(field, value, "must be a whole number of links >= 1 (0: the case's)")
            return value
        return self.number(field, value, strict=key != "perturbs")  # rtols, atols, h; perturbs >= 0

    def values(self, field: str, key: str, value: Any) -> list:
        if not isinstance(value, list):
            self.fail(field, value, f"must be a list, e.g. {json.dumps([value], default=str)}")
        if not value:
            self.fail(field, value, "must not be empty")
        return [self.item(f"{field}[{i}]", key, v) for i, v in enumerate(value)]

    # ----------------------------------------------------------------------- expansion
    def tolerances(self, where: str, settings: dict) -> list[tuple[float, float]]:
        rtols = settings.get("rtols", [RunSpec.rtol])
        if "atols" in settings and "atol_ratio" in settings:
            self.fail(f"{where}.atols", settings["atols"], "give atols or atol_ratio, not both")
        if "atols" in settings:
            atols = settings["atols"]
            if len(atols) != len(rtols):
                self.fail(f"{where}.atols", atols, f"{len(atols)} atols for {len(rtols)} rtols: "
                                                   "atols pair with rtols one to one")
            return list(zip(rtols, atols, strict=True))
        ratio = settings.get("atol_ratio", DEFAULT_ATOL_RATIO)
        return [(r, float(f"{r * ratio:.{TOL_DIGITS}g}")) for r in rtols]

    def expand(self, where: str, settings: dict, *, own_h: bool = True) -> list[RunSpec]:
        """The cross product one [sweep] or [[sweep.product]] table declares; ``own_h``: the
        table gives ``h`` itself (an inherited one is for the fixed-step integrators of the
        tables that have some)."""
        integrators = settings.get("integrators", [RunSpec.integrator])
        engines = settings.get("engines", [CORE])
        fixed = [i for i in integrators if i in STEPPED_INTEGRATORS or (
            is_native(i) and any(stepped(e, i) for e in engines if e != CORE))]
        if fixed and "h" not in settings:
            self.fail(f"{where}.h", None, f"missing: integrator {fixed[0]!r} is fixed-step "
                                          "and needs step sizes, e.g. h = [1e-3]")
        if own_h and "h" in settings and not fixed:
            self.fail(f"{where}.h", settings["h"], "only fixed-step integrators take a step h; "
                      f"{', '.join(map(repr, integrators))} adapt their own steps (give rtols), "
                      "or add a fixed-step integrator such as 'rk4'")
        tols = self.tolerances(where, settings)
        common = {k: settings[k] for k in SHARED_SCALARS if k in settings}
        specs = []
        for case in settings["cases"]:
            for engine in settings.get("engines", [CORE]):
                methods = settings.get("methods", [RunSpec.method]) if engine == CORE else [""]
                for method in methods:
                    for integrator in integrators:
                        if is_native(integrator) and (engine == CORE or (
                                integrator != NATIVE and native_integrator(
                                    engine, integrator) is None)):
                            continue  # an engine's own integrator: the engines that have it
                        for perturb, links, precision in itertools.product(
                                settings.get("perturbs", [RunSpec.perturb]),
                                settings.get("links", [RunSpec.links]),
                                settings.get("precisions", [RunSpec.precision])):
                            run = dict(case=case, engine=engine, method=method,
                                       integrator=integrator, perturb=perturb, links=links,
                                       precision=precision, **common)
                            if stepped(engine, integrator):
                                runs = [RunSpec(**run, h=h) for h in settings.get("h", [0.0])]
                            else:
                                runs = [RunSpec(**run, rtol=r, atol=a) for r, a in tols]
                            specs += [self.resolved(where, s, LIST_NAMES) for s in runs]
        return specs

    def extra(self, where: str, node: dict, shared: dict) -> RunSpec:
        """One explicit run of a [[sweep.extra]] table."""
        allowed = RunSpec.field_names()
        run = dict(shared)
        for key, value in node.items():
            field = f"{where}.{key}"
            self.renamed(field, key, value)
            if key not in allowed:
                self.fail(field, value, f"unknown field; allowed: {', '.join(allowed)}")
            if key == "case":
                run[key] = self.case(field, value)
            elif key == "engine":
                run[key] = self.choice(field, value, self.engines, "engine")
            elif key == "method":
                run[key] = self.choice(field, value, CORE_METHODS, "method of the core")
            elif key == "integrator":
                run[key] = self.integrator(field, value)
            elif key == "precision":
                run[key] = self.choice(field, value, PRECISIONS, "precision")
            elif key == "links":
                run[key] = self.item(field, "links", value)
            else:
                run[key] = self.scalar(field, key, value)
        if "case" not in run:
            self.fail(f"{where}.case", None, "missing: an extra run needs a case")
        return self.resolved(where, RunSpec(**run), {k: k for k in SETTINGS})


# --------------------------------------------------------------------------- running
def failed_row(spec: RunSpec, reason: str, *, transient: bool = True) -> dict:
    """The summary row of a run that could not report one itself (its worker raised or died):
    ``transient``, so a resumed sweep runs it again."""
    return {**spec.to_dict(), "run_id": spec.run_id, "label": spec.label, "status": "failed",
            "reason": reason, "transient": transient}


def run_one(spec: RunSpec) -> tuple[dict, pd.DataFrame]:
    """Execute one run in a worker: (summary row, samples)."""
    res = execute(spec)
    return res.summary, res.samples


Result = tuple[RunSpec, dict, pd.DataFrame | None]  # what an executor yields per finished run


class Claims:
    """One lock per run (``<out>/.claims/<run_id>``, ``fcntl.flock``): a run is computed only
    by the sweep process that holds its claim, so two sweeps on one folder share the work
    instead of each computing everything. The kernel drops a dead process's locks, so a sweep
    killed mid-run leaves no stale claim. A claim file is removed by its holder once the run is
    stored; a process that locked a file just removed checks the path again (and retries)."""

    def __init__(self, out: Path):
        self.dir = out / CLAIMS_DIR
        self.dir.mkdir(parents=True, exist_ok=True)
        self.held: dict[str, int] = {}  # run_id -> fd

    def take(self, run_id: str, *, block: bool = False) -> bool:
        """Claim ``run_id``: True if this process holds it now. ``block``: wait for another
        process's claim to end (it finished the run, or died)."""
        path = self.dir / run_id
        while True:
            fd = os.open(path, os.O_RDWR | os.O_CREAT, FILE_MODE)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | (0 if block else fcntl.LOCK_NB))
            except BlockingIOError:
                os.close(fd)
                return False
            try:
                same = os.fstat(fd).st_ino == os.stat(path).st_ino
            except FileNotFoundError:
                same = False
            if same:
                self.held[run_id] = fd
                return True
            os.close(fd)  # the holder removed it as we locked it: lock the current file

    def release(self, run_id: str) -> None:
        fd = self.held.pop(run_id, None)
        if fd is not None:
            with contextlib.suppress(FileNotFoundError):
                os.unlink(self.dir / run_id)
            os.close(fd)

    def release_all(self) -> None:
        for run_id in list(self.held):
            self.release(run_id)

    def clear_stale(self) -> int:
        """Remove the claim files of processes that died holding them; returns how many."""
        stale = 0
        for path in self.dir.iterdir():
            if not path.is_file() or path.name.startswith("."):
                continue  # not a claim (run_sweep refuses a folder in a run's claim's place)
            if path.name not in self.held and self.take(path.name):
                self.release(path.name)
                stale += 1
        return stale


class _Work:
    """The runs this sweep has to compute, handed out one claim at a time: a run another sweep
    holds is put off until nothing else is left, then waited for, and run only if that sweep
    did not finish it."""

    def __init__(self, specs: Sequence[RunSpec], claims: Claims,
                 is_done: Callable[[RunSpec], bool]):
        self.todo, self.later = deque(specs), deque()
        self.claims, self.is_done = claims, is_done

    @property
    def empty(self) -> bool:
        return not self.todo and not self.later

    def next(self, *, wait: bool) -> RunSpec | None:
        """The next run to compute (its claim taken), or None when there is none now (``wait``:
        wait for another sweep's claims; without it, None may come while runs are left)."""
        while self.todo:
            spec = self.todo.popleft()
            if not self.claims.take(spec.run_id):
                self.later.append(spec)
            elif self.is_done(spec):  # finished by another sweep since we looked
                self.claims.release(spec.run_id)
            else:
                return spec
        while self.later:
            spec = self.later[0]
            if not self.claims.take(spec.run_id, block=wait):
                return None
            self.later.popleft()
            if self.is_done(spec):
                self.claims.release(spec.run_id)
            else:
                return spec
        return None


def run_sweep(specs: Sequence[RunSpec], out_dir: str | os.PathLike, *, name: str = "sweep",
              workers: int | None = None, dask: str | None = None,
              progress: bool = True, reference: bool = False,
              retry_failed: bool = False,
              on_plan: Callable[[int, int], None] | None = None) -> pd.DataFrame:
    """Run every spec not yet done in ``out_dir``; return all runs' rows (see :func:`collect`).

    ``workers``: processes of the local pool (default ``os.cpu_count()``). ``dask``: a scheduler
    address (``"tcp://host:8786"``; its workers need this project installed) or ``"local"`` (a
    LocalCluster of 2 single-threaded worker processes) instead of the local pool; not given, a
    :func:`dask_default` block's address, if any. ``progress``:
    a progress bar on stderr (runs done, failed, time left). ``name`` goes into sweep.json.
    ``reference``: first compute (or load from the cache) the reference solution of every
    pending run's case, horizon and sampling (:mod:`redysim.harness.reference`), so that each run
    reports its error against it.

    Done runs are skipped: those that finished, and those that failed for a reason of their own
    (NaN, energy blow-up, an engine's refusal, the spec's CPU-time limit: the same inputs fail
    the same way). A run whose row says "stopped" (a wall-clock limit: the user's patience,
    which a sweep never sets) is not a result and is run again.
    Runs whose worker died or raised are marked ``transient`` and run again; ``retry_failed``
    runs every failed run again. A run file that cannot be read is moved to ``damaged/`` (with
    a note on stderr) and the run is done again. Several sweeps may share ``out_dir``: each run
    is claimed (:class:`Claims`) and computed once. The returned frame's ``attrs["ran"]`` counts
    the runs this call computed. ``on_plan(n_runs, n_done)`` is called once the finished runs
    are known (their files checked), before any run.

    Before anything is read or run, a folder where one of the sweep's files goes (or a file
    where one of its folders goes) is refused by name (:class:`FolderError`), and so is a
    folder it cannot write while runs are left to do.
    """
    specs = unique(specs)
    if dask is None:  # (a dask_default block's cluster, if any: its workers, not the pool's)
        dask = _DASK_DEFAULT[0]
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise SweepError(str(out), "<results folder>", None, "is a file, not a folder")
    for sub in (RUNS_DIR, SAMPLES_DIR, MANIFEST_DIR, DAMAGED_DIR, CLAIMS_DIR):
        if (out / sub).exists() and not (out / sub).is_dir():  # (a finished run's folder?)
            raise SweepError(str(out / sub), "<results subfolder>", None,
                             f"is a file where the sweep keeps its {sub} folder: move it away "
                             "(the runs it held, if any, are not there to reuse); nothing was "
                             "run")
    check_kinds(files=[out / PLAN_FILE, out / RUNS_FILE, out / SAMPLES_FILE,
                       *(out / MANIFEST_DIR / f"{s.run_id}.json" for s in specs),
                       *(out / CLAIMS_DIR / s.run_id for s in specs)])
    # (a folder it cannot write, or one of its subfolders, is read only if every run is
    # finished there: a damaged file cannot even be set aside)
    subs = [out / sub for sub in (RUNS_DIR, SAMPLES_DIR, MANIFEST_DIR, DAMAGED_DIR, CLAIMS_DIR)
            if (out / sub).is_dir()]
    repair = writable(out) and all(writable(sub) for sub in subs)

    def finished(spec: RunSpec) -> str | None:
        """'ok', 'failed' (a result), or None (not run, damaged, missing a file, stopped by a
        wall-clock limit, or to be run again)."""
        there = (out / RUNS_DIR / f"{spec.run_id}{PARQUET_SUFFIX}").exists()
        row = _read_run(out, spec.run_id, repair=repair)  # (a damaged one is said and set aside)
        if not there and (out / MANIFEST_DIR / f"{spec.run_id}.json").is_file():
            print(f"redysim: {out / RUNS_DIR / f'{spec.run_id}{PARQUET_SUFFIX}'} is missing "
                  f"(its manifest lists it: deleted, or its sweep stopped before moving it into "
                  "place): its run will be done again", file=sys.stderr)
        if row is not None and not _row_is_specs(out, spec, row, repair=repair):
            return None
        if (row is None or not _samples_readable(out, spec.run_id, repair=repair)
                or not _manifest_holds(out, spec.run_id, row, repair=repair)
                or not _files_match_row(out, spec.run_id, row, repair=repair)):
            return None
        if row["status"] == "ok":
            return "ok"
        if row["status"] != "failed":  # "stopped" (the user's patience) is never a result
            return None
        return None if retry_failed or bool(row.get("transient", False)) else "failed"

    status = {s.run_id: finished(s) for s in specs}
    pending = [s for s in specs if status[s.run_id] is None]
    failed = sum(v == "failed" for v in status.values())
    if on_plan is not None:
        on_plan(len(specs), len(specs) - len(pending))
    plan = {"name": name, "n_runs": len(specs),
            "runs": [{"run_id": s.run_id, "label": s.label, **s.to_dict()} for s in specs]}
    if not repair:
        if pending:
            try:
                for folder in (out, *subs):
                    check_writable(folder)
            except FolderError as exc:
                raise FolderError(f"{exc} ({len(pending)} of the sweep's {len(specs)} runs are "
                                  "not finished there; nothing was run)") from None
        runs = collect(out, plan=plan)  # finished: read as it is (it writes only what changed)
        runs.attrs["ran"] = 0
        return runs
    write_json_atomic(plan, out / PLAN_FILE, if_changed=True)
    for sub in (RUNS_DIR, SAMPLES_DIR):
        (out / sub).mkdir(parents=True, exist_ok=True)
        remove_temp_files(out / sub)
    if reference and pending:
        from .reference import ensure_references

        if progress:
            print(f"{name}: reference solutions (cached under results/reference/)",
                  file=sys.stderr)
        ensure_references(pending)
    claims = Claims(out)
    claims.clear_stale()

    def done_since(spec: RunSpec) -> bool:  # (said once already, in the first look: quiet now)
        with contextlib.redirect_stderr(io.StringIO()):
            return finished(spec) is not None

    work = _Work(pending, claims, done_since)
    if dask:
        results = _dask_results(work, dask, run_one)
    else:
        results = _pool_results(work, workers or os.cpu_count() or 1, run_one)
    ran = 0
    try:
        with tqdm(total=len(specs), initial=len(specs) - len(pending), desc=name, unit="run",
                  disable=not progress, file=sys.stderr, dynamic_ncols=True) as bar:
            bar.set_postfix(failed=failed)
            with contextlib.closing(results):
                for spec, summary, samples in results:
                    _store(out, spec, summary, samples)
                    claims.release(spec.run_id)
                    ran += 1
                    failed += summary["status"] != "ok"
                    bar.set_postfix(failed=failed, refresh=False)
                    bar.update()
    finally:
        claims.release_all()
    runs = collect(out)
    runs.attrs["ran"] = ran
    return runs


def _read_run(out: Path, run_id: str, *, repair: bool = True) -> dict | None:
    """A finished run's summary row, or None: not there, or damaged (then moved aside, unless
    not ``repair``)."""
    path = out / RUNS_DIR / f"{run_id}{PARQUET_SUFFIX}"
    if path.exists() and not path.is_file():  # a folder (or other) where the file goes
        if repair:
            set_aside(path, IsADirectoryError("not a file"))
        return None
    if not path.is_file():
        return None
    try:
        rows = read_parquet(path).to_dict("records")
        if len(rows) != 1 or "status" not in rows[0]:
            raise ValueError(f"{len(rows)} rows, columns {sorted(rows[0]) if rows else []}")
        if rows[0].get("run_id") != run_id:  # (a row copied or edited under another's name)
            raise ValueError(f"its row is run {rows[0].get('run_id')!r}'s, not {run_id!r}'s")
        return rows[0]
    except Exception as exc:  # a truncated, empty or foreign file: pyarrow's errors vary
        if repair:
            set_aside(path, exc)
        return None


def _row_is_specs(out: Path, spec: RunSpec, row: dict, *, repair: bool = True) -> bool:
    """Whether a finished run's row records ``spec``'s settings (:meth:`RunSpec.unlike`): a
    row whose settings are another run's (copied or edited, its digest recomputed) is set
    aside (not when not ``repair``: said) and its run done again."""
    wrong = spec.unlike(row)
    if not wrong:
        return True
    path = out / RUNS_DIR / f"{spec.run_id}{PARQUET_SUFFIX}"
    why = ", ".join(f"{k} = {row.get(k)!r}, not {getattr(spec, k)!r}" for k in wrong[:4])
    if repair:
        set_aside(path, ValueError(f"its settings are not its run's: {why}"))
    else:
        print(f"redysim: {path} records other settings than its run's ({why})", file=sys.stderr)
    return False


def _files_of(out: Path, run_id: str) -> list[Path]:
    """A stored run's result files: its summary row and, if it has them, its samples."""
    files = [out / SAMPLES_DIR / f"{run_id}{PARQUET_SUFFIX}",
             out / RUNS_DIR / f"{run_id}{PARQUET_SUFFIX}"]
    return [f for f in files if f.is_file()]


def _write_manifest(out: Path, run_id: str, staged: dict | None = None) -> None:
    """Record a stored run's files and their SHA-256 (:data:`MANIFEST_DIR`): the run is done.
    ``staged``: {final path: staged path} of files still to be moved into place."""
    staged = staged or {}
    files = {f.relative_to(out).as_posix(): sha256_file(f) for f in _files_of(out, run_id)
             if f not in staged}
    files.update({f.relative_to(out).as_posix(): sha256_file(tmp) for f, tmp in staged.items()})
    write_json_atomic({"run_id": run_id, "files": files},
                      out / MANIFEST_DIR / f"{run_id}.json")


def _manifest_holds(out: Path, run_id: str, row: dict, *, repair: bool = True) -> bool:
    """Whether a run's files are those its manifest lists, by SHA-256. A file missing is said on
    stderr, one changed is set aside (:func:`set_aside`; not when not ``repair``): its run is
    done again either way, as is a run whose manifest is missing (a sweep writes it before the
    summary row, so a row without one is not a finished run's) or cannot be read."""
    path = out / MANIFEST_DIR / f"{run_id}.json"
    if not path.is_file():  # (a sweep writes a run's manifest before its summary row)
        print(f"redysim: {path} is missing (run {row.get('label', run_id)} is recorded "
              f"{row['status']}, but without the record of its files): its run will be done "
              "again", file=sys.stderr)
        return False
    try:
        record = read_json(path)
        files = record["files"]
        if not isinstance(files, dict):
            raise ValueError(f"'files' is {type(files).__name__}, not a table")
        if record.get("run_id") != run_id:
            raise ValueError(f"it is run {record.get('run_id')!r}'s, not {run_id!r}'s")
        own = {f.relative_to(out).as_posix() for f in _files_of(out, run_id)}
        allowed = {f"{sub}/{run_id}{PARQUET_SUFFIX}" for sub in (RUNS_DIR, SAMPLES_DIR)}
        if foreign := sorted(set(files) - allowed):  # (never looked up: it may lead outside)
            raise ValueError(f"it lists {foreign[0]!r}, not one of its run's files")
        if not own <= set(files):  # (a run's files all listed: its summary row at least)
            raise ValueError(f"it does not list {sorted(own - set(files))}")
    except Exception as exc:  # truncated or foreign: the run's files are not known
        if repair:
            set_aside(path, exc)
        return False
    for name, digest in files.items():
        f = out / name
        if not f.is_file():
            print(f"redysim: {f} is missing (listed in {path} as a finished run's file); its "
                  "run will be done again", file=sys.stderr)
            return False
        if sha256_file(f) != digest:
            if repair:
                set_aside(f, ValueError(f"its SHA-256 is not the one {path} recorded"))
            else:
                print(f"redysim: {f} is not the file {path} recorded (SHA-256)",
                      file=sys.stderr)
            return False
    return True


def _files_match_row(out: Path, run_id: str, row: dict, *, repair: bool = True) -> bool:
    """Whether a finished run's files hold what its row says: the row every column a run
    writes, its samples file ``n_samples`` rows and every sample column. A file edited and its
    digest recomputed passes the manifest, not this: then both the run's files are set aside
    (not when not ``repair``: said) and its run done again."""
    if row.get("transient"):
        return True  # (done again anyway)
    path = out / RUNS_DIR / f"{run_id}{PARQUET_SUFFIX}"
    samples = out / SAMPLES_DIR / f"{run_id}{PARQUET_SUFFIX}"
    problem = ""
    if missing := [c for c in ROW_COLUMNS if c not in row]:
        problem = f"{path}: its row has no column {missing[0]!r}"
    else:
        try:
            n = int(row["n_samples"])
        except (TypeError, ValueError):
            n = -1
        if samples.is_file():
            meta = parquet_metadata(samples)
            names = set(meta.schema.names)
            if lacking := [c for c in SAMPLE_COLUMNS if c not in names]:
                problem = f"{samples}: it has no column {lacking[0]!r}"
            elif meta.num_rows != n:
                problem = (f"{samples}: {meta.num_rows} rows, but its run's row says "
                           f"n_samples = {row['n_samples']}")
        elif n != 0:
            problem = (f"{samples} is missing (its run's row says n_samples = "
                       f"{row['n_samples']})")
    if not problem:
        return True
    if repair and samples.is_file():
        _set_aside_run(samples, ValueError(problem))
    elif repair:
        set_aside(path, ValueError(problem))
    else:
        print(f"redysim: {problem}: its run is not finished", file=sys.stderr)
    return False


def set_aside(path: Path, exc: BaseException) -> Path | None:
    """Move a damaged result file into ``damaged/`` beside its folder, saying so on stderr."""
    target = path.parent.parent / DAMAGED_DIR / f"{path.name}.{int(time.time())}"
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        os.replace(path, target)
    except FileNotFoundError:  # another sweep moved it first
        return None
    except OSError as exc:  # (a folder it cannot write: run_sweep checks first, still)
        raise FolderError(f"{str(path)!r} could not be read, and cannot be set aside into "
                          f"{str(target.parent)!r} ({exc.strerror or type(exc).__name__}); "
                          "make the folder writable, or move the file away") from None
    print(f"redysim: {path} could not be read ({type(exc).__name__}: {str(exc)[:200]}); moved "
          f"to {target}, and its run will be done again", file=sys.stderr)
    return target


def _store(out: Path, spec: RunSpec, summary: dict, samples: pd.DataFrame | None) -> None:
    """Write one finished run: its samples first, then its summary row staged beside its place,
    then its manifest (the files' SHA-256, the row's taken from the staged file), and last the
    row moved into place. So a summary row is never there without its manifest: a row without
    one was not written by a sweep that finished it (the manifest removed), and is redone."""
    if samples is not None:
        write_parquet_atomic(samples, out / SAMPLES_DIR / f"{spec.run_id}.parquet")
    else:  # a samples file of an earlier try of this run is not this one's
        with contextlib.suppress(FileNotFoundError):
            os.unlink(out / SAMPLES_DIR / f"{spec.run_id}.parquet")
    summary = {"transient": False, **summary}
    final = out / RUNS_DIR / f"{spec.run_id}.parquet"
    staged = final.with_name(f".{final.name}{STAGED_SUFFIX}")
    write_parquet_atomic(pd.DataFrame([summary]), staged)
    _write_manifest(out, spec.run_id, staged={final: staged})
    os.replace(staged, final)


def _init_worker(parent: int) -> None:
    """A pool worker's start: one thread for batches (:func:`redysim.harness.worker_threads`:
    the pool already runs a process per core) and a watch on its sweep."""
    worker_threads()
    _watch_parent(parent)


def _watch_parent(parent: int) -> None:
    """In a pool worker: exit as soon as the sweep that started it is gone (a ``kill -9`` of the
    sweep had left its workers running for ever, each holding its memory)."""
    def watch():
        while os.getppid() == parent:
            time.sleep(PARENT_POLL_S)
        os._exit(1)

    threading.Thread(target=watch, name="redysim-parent-watch", daemon=True).start()


class _Lease:
    """A local process pool lent to one sweep (:func:`pool_lease`): the kept one of a
    :func:`shared_pool` block, or a fresh one of its own."""

    def __init__(self, workers: int):
        self.workers = workers
        self.kept = False
        self.pool: ProcessPoolExecutor | None = None

    def renew(self) -> ProcessPoolExecutor:
        """A working pool: this lease's, or a new one after a worker died (which breaks a pool
        for good); a kept pool's replacement is kept in its place."""
        if self.pool is not None:
            self.pool.shutdown(wait=True)
        self.pool = _new_pool(self.workers)
        if self.kept:
            with _KEPT.lock:
                _KEPT.pool = self.pool
        return self.pool


class _Kept:
    """The pool a :func:`shared_pool` block keeps, and whether a sweep is using it."""

    def __init__(self):
        self.lock = threading.Lock()
        self.pool: ProcessPoolExecutor | None = None
        self.workers = 0
        self.depth = 0  # shared_pool blocks open (nested ones keep the outer block's pool)
        self.busy = False


_KEPT = _Kept()


def _new_pool(workers: int) -> ProcessPoolExecutor:
    return ProcessPoolExecutor(max_workers=workers,
                               mp_context=multiprocessing.get_context(POOL_START_METHOD),
                               initializer=_init_worker, initargs=(os.getpid(),))


_DASK_DEFAULT: list[str | None] = [None]  # dask_default's address (the innermost block's)


@contextlib.contextmanager
def dask_default(address: str | None) -> Iterator[None]:
    """Inside the block, every :func:`run_sweep` not given ``dask`` sends its runs to the Dask
    cluster at ``address`` (``"local"``: a LocalCluster per sweep; its ``workers``, the local
    pool's size, then unused) instead of the local pool: how ``python -m
    redysim.reports.reproduce --dask ADDRESS`` sends every sweep of a reproduction. ``None``:
    the local pool, as outside a block."""
    before = _DASK_DEFAULT[0]
    _DASK_DEFAULT[0] = address
    try:
        yield
    finally:
        _DASK_DEFAULT[0] = before


@contextlib.contextmanager
def shared_pool(workers: int | None = None) -> Iterator[None]:
    """Inside the block, sweeps (:func:`run_sweep` on the local pool, and whatever takes a
    :func:`pool_lease`) share one process pool of ``workers`` (default ``os.cpu_count()``)
    instead of starting their own: each worker's start (a Python interpreter, NumPy, pandas,
    numba's cached kernels, an engine's module on its first run of it: over a second of CPU,
    docs/notes/2026-11-costs-in-the-code.md) is paid once for the block, not once per sweep.
    What a worker keeps between runs is what it already kept between the runs of one sweep
    (imported modules, compiled kernels); each run's CPU time and peak RSS are its own
    (:func:`redysim.harness.run.execute`).
    A sweep that starts while another holds the pool (a second thread) gets a pool of its own,
    as outside a block. Nested blocks keep the outermost's pool. Its workers' CPU time, live:
    :func:`shared_pool_cpu_s`."""
    with _KEPT.lock:
        _KEPT.depth += 1
        outer = _KEPT.depth == 1
        if outer:
            _KEPT.workers = max(1, workers or os.cpu_count() or 1)
    try:
        yield
    finally:
        with _KEPT.lock:
            _KEPT.depth -= 1
            pool = _KEPT.pool if outer else None
            if outer:
                _KEPT.pool, _KEPT.busy = None, False
        if pool is not None:
            pool.shutdown(wait=True, cancel_futures=True)


@contextlib.contextmanager
def pool_lease(workers: int) -> Iterator[_Lease]:
    """A local process pool of at least ``workers`` for one sweep: the :func:`shared_pool`
    block's when there is one and no other sweep holds it, else a new one, shut down at the
    end. Call ``lease.renew()`` for the pool (again after a worker died)."""
    lease = _Lease(workers)
    with _KEPT.lock:
        if _KEPT.depth and not _KEPT.busy and _KEPT.workers >= workers:
            _KEPT.busy = lease.kept = True
            lease.workers = _KEPT.workers
            lease.pool = _KEPT.pool
    try:
        yield lease
    except BaseException:  # (Ctrl-C, a sweep closed early): runs may still be in flight
        if lease.pool is not None:
            if lease.kept:  # not for the next sweep, which would wait behind them
                with _KEPT.lock:
                    _KEPT.pool = None
            lease.pool.shutdown(wait=False, cancel_futures=True)
            lease.pool = None
        raise
    finally:
        if lease.kept:
            with _KEPT.lock:
                _KEPT.busy = False
        elif lease.pool is not None:
            lease.pool.shutdown(wait=True)


def shared_pool_cpu_s() -> float:
    """CPU seconds (user and system) of the :func:`shared_pool` block's live workers, from
    ``/proc`` (0 elsewhere, or with no pool): a worker's CPU reaches ``os.times()``'s children
    only once it has ended and been waited for, at the block's end."""
    pool = _KEPT.pool
    processes = dict(getattr(pool, "_processes", None) or {})  # (the executor's own table)
    total = 0.0
    for pid in processes:
        try:
            fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        except (OSError, IndexError):
            continue
        total += (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    return total


def _pool_results(work: _Work, workers: int,
                  task: Callable[[RunSpec], tuple[dict, pd.DataFrame]]) -> Iterator[Result]:
    """Run ``task`` on a local process pool (:func:`pool_lease`), yielding each run as it
    finishes.

    At most ``workers`` runs are submitted at a time, so at most that many are lost to a kill.
    When a worker process dies, the pool breaks and every run in flight fails with it: a lone
    one is recorded as failed; several are rerun one at a time in a fresh pool, so that only the
    run that kills its worker is recorded as failed.
    """
    suspects = deque()
    running: dict = {}  # future -> spec
    workers = max(1, min(workers, len(work.todo)))
    with pool_lease(workers) as lease:
        pool = None
        while not work.empty or suspects or running:
            if pool is None:  # (started only when there is a run to do)
                pool = lease.pool or lease.renew()
            broken = False
            while len(running) < (1 if suspects else workers):
                spec = (suspects.popleft() if suspects
                        else work.next(wait=not running))
                if spec is None:
                    break
                try:
                    running[pool.submit(task, spec)] = spec
                except BrokenProcessPool:  # a worker died since the last check: retry this run
                    suspects.appendleft(spec)
                    broken = True
                    break
            finished = wait(running, return_when=FIRST_COMPLETED)[0] if running else set()
            if broken or any(isinstance(fut.exception(), BrokenProcessPool) for fut in finished):
                wait(running)  # a broken pool fails every run in flight at once
                finished = set(running)
                pool = lease.renew()
            lost = []
            for fut in finished:
                spec = running.pop(fut)
                exc = fut.exception()
                if isinstance(exc, BrokenProcessPool):
                    lost.append(spec)
                elif exc is not None:
                    yield spec, failed_row(spec, f"worker raised {exc!r}"), None
                else:
                    yield spec, *fut.result()
            if len(lost) == 1:
                yield lost[0], failed_row(lost[0], DIED), None
            else:
                suspects.extend(lost)


def _on_worker(task: Callable[[RunSpec], tuple[dict, pd.DataFrame]], spec: RunSpec,
               results: str) -> tuple[str, str, bool, tuple[dict, pd.DataFrame]]:
    """One run on a Dask worker: (its address, its code digest, whether it sees the client's
    reference cache, the task's result). The run reads cached reference solutions from the
    client's results folder ``results`` (an absolute path: a shared filesystem on a cluster of
    several machines), as a local run does. The client stores what comes back (a worker's own
    disk is never written) and refuses a result of other code or of a worker blind to the
    references the client has."""
    from distributed import get_worker

    from .provenance import code_digest
    from .reference import RESULTS_ENV

    os.environ[RESULTS_ENV] = results
    sees = (Path(results) / "reference").is_dir()
    return get_worker().address, code_digest(), sees, task(spec)


def _other_code(worker: str, digest: str, ours: str, what: str) -> SweepError:
    """The refusal of a worker whose code digest is not this checkout's; ``what``: what
    becomes of the sweep's work."""
    return SweepError("--dask", "worker", worker,
                      f"runs other code (code digest {digest[:12]}, this checkout's {ours[:12]}: "
                      f"another version or local changes): install this checkout on it; {what}")


def _check_workers(client, address: str) -> str:
    """Every worker the scheduler has (waiting for a first one) runs this checkout's code:
    a worker that cannot import the project, or runs another version of it (the code digest
    differs), is refused by name before any run is submitted. Returns the code digest."""
    from .provenance import code_digest

    try:
        client.wait_for_workers(1, timeout=DASK_WORKERS_TIMEOUT_S)
    except TimeoutError:
        raise SweepError("--dask", "address", address,
                         f"the scheduler has no worker ({DASK_WORKERS_TIMEOUT_S} s waited): "
                         "start workers (dask worker ADDRESS) with this project installed"
                         ) from None
    ours = code_digest()
    # (each worker's own install's digest: the function goes by its name, imported there)
    for worker, digest in sorted(client.run(code_digest, on_error="return").items()):
        if isinstance(digest, BaseException):
            raise SweepError("--dask", "worker", worker,
                             f"cannot run this project's code ({type(digest).__name__}: "
                             f"{str(digest)[:200]}): install this checkout on every worker "
                             "(pip install -e .[harness]) and start it again; nothing was run")
        if digest != ours:
            raise _other_code(worker, str(digest), ours, "nothing was run")
    return ours


def _dask_results(work: _Work, address: str,
                  task: Callable[[RunSpec], tuple[dict, pd.DataFrame]]) -> Iterator[Result]:
    """Run ``task`` on a Dask cluster, yielding each run as it finishes (``as_completed``).

    Before any run: every worker runs this checkout's code (:func:`_check_workers`); each
    result comes back with its worker's code digest and is refused by name if it differs (a
    worker that joined later). At most ``DASK_IN_FLIGHT`` runs are submitted (and claimed) at a
    time. A worker that dies is retried by the scheduler on another worker (the run is done
    again from its start: a run is one task); a run that keeps killing workers
    (``KilledWorker``) or raises is recorded as failed (transient: a resumed sweep runs it
    again). A scheduler that goes away is a SweepError saying how many runs finished: they are
    stored already, and the sweep run again does the rest.
    """
    from concurrent.futures import CancelledError

    from distributed import Client, LocalCluster, as_completed

    from .reference import results_dir

    if work.empty:
        return
    with contextlib.ExitStack() as stack:
        if address == DASK_LOCAL:
            cluster = stack.enter_context(LocalCluster(
                n_workers=DASK_LOCAL_WORKERS, processes=True, threads_per_worker=1,
                dashboard_address=None, silence_logs=logging.ERROR,
                env={REDYSIM_THREADS: os.environ.get(REDYSIM_THREADS) or "1"}))
            client = stack.enter_context(Client(cluster))
        else:
            try:
                client = stack.enter_context(Client(address, timeout=DASK_CONNECT_TIMEOUT_S))
            except (OSError, TimeoutError, ValueError) as exc:
                raise SweepError("--dask", "address", address,
                                 f"no Dask scheduler answered there within "
                                 f"{DASK_CONNECT_TIMEOUT_S} s ({type(exc).__name__}: "
                                 f"{str(exc)[:200]})") from None
        ours = _check_workers(client, address)
        results = str(results_dir().resolve())  # (its reference cache: read by the runs)
        has_references = (Path(results) / "reference").is_dir()
        futures: dict = {}
        pending = as_completed()
        finished = 0

        def scheduler_lost(exc: BaseException) -> SweepError:
            return SweepError("--dask", "address", address,
                              f"the scheduler went away ({type(exc).__name__}) after {finished} "
                              "runs came back (stored: run the sweep again, with a "
                              "scheduler, to do the rest)")

        def submit() -> None:
            try:
                while len(futures) < DASK_IN_FLIGHT:
                    spec = work.next(wait=not futures)
                    if spec is None:
                        return
                    fut = client.submit(_on_worker, task, spec, results,
                                        key=DASK_KEY_PREFIX + spec.run_id, pure=False)
                    futures[fut] = spec
                    pending.add(fut)
            except (OSError, CancelledError) as exc:
                raise scheduler_lost(exc) from None

        submit()
        while futures:
            fut = next(pending)
            spec = futures.pop(fut)
            try:
                worker, digest, sees, (summary, samples) = fut.result()
            except CancelledError as exc:  # (the scheduler lost: every future is cancelled)
                raise scheduler_lost(exc) from None
            except Exception as exc:
                if client.status not in ("running", "connecting"):
                    raise scheduler_lost(exc) from None
                summary, samples = failed_row(spec, f"worker raised {exc!r}"), None
            else:
                if digest != ours:
                    raise _other_code(worker, digest, ours, f"its result of {spec.run_id} is "
                                      f"not kept ({finished} runs that came back are stored)")
                if has_references and not sees:
                    raise SweepError("--dask", "worker", worker,
                                     f"does not see the reference cache {results}/reference "
                                     f"that {spec.run_id} is compared with here: its result "
                                     "is not kept (a run there would lack its errors); give "
                                     "the workers this results folder (a shared filesystem, "
                                     f"the same path) ({finished} runs finished are stored)")
            fut.release()
            finished += 1
            yield spec, summary, samples
            submit()


# --------------------------------------------------------------------------- results
def collect(out_dir: str | os.PathLike, *, plan: dict | None = None) -> pd.DataFrame:
    """Consolidate ``out_dir``'s finished runs into runs.parquet and samples.parquet (each
    written only when it changes).

    Rows follow the plan's order (``plan``, else sweep.json; run_id order without one), so the
    tables do not depend on which run finished first. Runs not in the plan (left by an earlier
    version of the sweep) are left out; planned runs not yet finished are simply absent.
    Returns the runs.
    """
    out = Path(out_dir)
    run_files = parquet_files(out / RUNS_DIR)
    sample_files = parquet_files(out / SAMPLES_DIR)
    plan_file = out / PLAN_FILE
    if plan is None and plan_file.exists():
        plan = read_json(plan_file)
    order = [r["run_id"] for r in plan["runs"]] if plan is not None else list(run_files)
    ids = [run_id for run_id in order if run_id in run_files]
    rows = {i: row for i in ids if (row := _read_run(out, i)) is not None}
    runs = pd.DataFrame([rows[i] for i in ids if i in rows])
    samples = _concat(frame for i in ids if i in rows and i in sample_files
                      if (frame := _read_samples(sample_files[i])) is not None)
    write_parquet_atomic(samples, out / SAMPLES_FILE, if_changed=True)
    write_parquet_atomic(runs, out / RUNS_FILE, if_changed=True)
    return runs


def _samples_readable(out: Path, run_id: str, *, repair: bool = True) -> bool:
    """False when a run's samples file exists but its Parquet footer cannot be read (then both
    its files are set aside, unless not ``repair``, and the run is not done); True otherwise (a
    run whose worker died has no samples file)."""
    path = out / SAMPLES_DIR / f"{run_id}{PARQUET_SUFFIX}"
    if path.exists() and not path.is_file():  # a folder (or other) where the file goes
        if repair:
            _set_aside_run(path, IsADirectoryError("not a file"))
        return False
    if not path.is_file():
        return True
    try:
        parquet_metadata(path)
    except Exception as exc:  # pyarrow's errors for a damaged file vary
        if repair:
            _set_aside_run(path, exc)
        return False
    return True


def _set_aside_run(samples: Path, exc: BaseException) -> None:
    """Set a damaged samples file aside, and its run's summary with it: without its samples a
    run is not done."""
    set_aside(samples, exc)
    with contextlib.suppress(FileNotFoundError):
        (samples.parent.parent / DAMAGED_DIR).mkdir(exist_ok=True)
        os.replace(samples.parent.parent / RUNS_DIR / samples.name,
                   samples.parent.parent / DAMAGED_DIR / f"{samples.stem}.run{PARQUET_SUFFIX}")


def _read_samples(path: Path) -> pd.DataFrame | None:
    try:
        return read_parquet(path)
    except Exception as exc:  # damaged: set aside; its run is done again on resume
        _set_aside_run(path, exc)
        return None


def _concat(frames: Iterable[pd.DataFrame]) -> pd.DataFrame:
    frames = [f for f in frames if len(f)]
    return pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
