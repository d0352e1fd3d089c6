"""Reproduce the paper: run what the comparison report needs, then build it (``make reproduce``).

    python -m redysim.reports.reproduce                 # quick: minutes
    python -m redysim.reports.reproduce --full          # every table to the paper's horizons: hours
    python -m redysim.reports.reproduce --table 4 --table 9   # only what those tables need
    python -m redysim.reports.reproduce --build-only    # rebuild the report from the results

Options: ``--results DIR`` (default ``results``; also where reference solutions are cached),
``--out DIR`` (the report, default ``reports/out``), ``--workers N`` (sweep processes, default
one per core).

Quick mode (the default): the sweeps ``sweeps/quick-tables.toml`` (Tables 1-4 up to 2,500 DOF
at the paper's horizons, RE-U3750-L30 shortened, Table 6's GE-N on RE-U125-L1) and
``sweeps/quick-work-precision.toml`` (every integrator and engine on RE-U125-L1 over 0.05 s)
and ``sweeps/quick-drift-ensemble.toml`` (RE-U125-L1's drift from 8 perturbed initial states),
``sweeps/quick-work-precision-robots.toml`` (the UR5, the Panda and Talos floating, 0.5 s: the
core, every engine through ode45 and with its own integrators) and
``sweeps/quick-scenarios.toml`` (the truth scenarios of ``cases/scenarios/`` that fit the budget
in every engine, each over a ladder of three settings);
the precision tables 8, 10, 11, A.2 and IEEE (:mod:`redysim.reports.precision_tables`, Table 8
without its sensitivity runs); Table 9 and the conditioning study
(:mod:`redysim.reports.gim_study`); the operation counts (:mod:`redysim.reports.opcount`); the
true-error study at 10 and 100 links (:mod:`redysim.harness.error_study`); the CPU scaling under
the quick budget (:mod:`redysim.reports.scaling`); robots and trees in the core and every engine
(:mod:`redysim.reports.robots`); closed loops (:mod:`redysim.reports.loops`); model size against
accuracy, the refinement studies of ``sweeps/refine-*.toml`` with their advice checked
(:mod:`redysim.harness.refine`); the implicit integrator on RE-U50000-L1000 to 5 s beside ode45
to 0.01 s, on the 1,000,000-DOF ``cases/huge/RE-U500000-L10000.toml`` to 0.05 s, and one of its
steps against DOF from 1,000 to 1,000,000 (:mod:`redysim.reports.implicit`,
:mod:`redysim.reports.implicit_scaling`); then the report (:mod:`redysim.reports.build`).

Full mode: ``sweeps/table1.toml`` .. ``table4.toml``, ``table6.toml``,
``drift-ensemble.toml``, ``work-precision-RE-U125-L1.toml`` and
``work-precision-RE-U750-L6.toml`` (Table 6's GE-N on the larger chains takes hours), the
implicit integrator's ode45 reference to 0.48 s, the 1,000,000-DOF chain to 1 s beside ode45 to
0.01 s (~1 h of CPU), Table 5's huge chains as checkpointed long
runs (:mod:`redysim.harness.longrun`: hours each, resumed from the last checkpoint when stopped),
everything above at full size.

Everything resumes: a sweep skips the runs it has finished (redysim.harness.sweep), the error
study the cells it has, and the other steps take seconds to minutes. Progress and each step's wall
and CPU time are printed, and ``results/reproduce-<kind>.json`` (kind: quick, full or tables)
records them for the report. A failed step is reported and the others still run; the exit code
is then 1.
"""

from __future__ import annotations

import argparse
import contextlib
import datetime as _dt
import os
import resource
import subprocess
import sys
import time
import traceback
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path

from redysim.harness.provenance import provenance
from redysim.harness.store import write_json_atomic

QUICK = "quick"
FULL = "full"
SWEEPS = Path(str(resources.files("redysim.sweep_files")))  # package data
QUICK_SWEEPS = ("quick-tables", "quick-work-precision", "quick-drift-ensemble",
                "quick-work-precision-robots", "quick-scenarios")
TABLE_SWEEPS = {"1": "table1", "2": "table2", "3": "table3", "4": "table4", "6": "table6"}
# Full mode: the cheap sweeps first, so an interrupted run leaves the most tables done; then
# Table 5's checkpointed long runs (hours each).
FULL_SWEEPS = ("table1", "table3", "table2", "table4", "drift-ensemble",
               "work-precision-RE-U125-L1", "work-precision-RE-U750-L6", "table6",
               "quick-work-precision-robots", "quick-scenarios", "scenarios-truths",
               "scenarios-round")
TABLES = ("1", "2", "3", "4", "5", "6", "7", "8", "9", "10", "11", "A2")
QUICK_ERROR_SIZES = (10, 100)  # links; the full study runs redysim.harness.error_study's defaults
REPRODUCE_FILE = "reproduce-{}.json"  # {}: quick, full or tables
# the implicit integrator's long run is measured against ode45 to this horizon [s] (quick: 0.01 s,
# one sample, what the ten-minute budget affords: docs/notes/2026-11-costs-in-the-code.md)
IMPLICIT_REF_T = {QUICK: 0.01, FULL: 0.48}
IMPLICIT_SAMPLE = 0.01  # s
# the 1,000,000-DOF chain (redysim.reports.implicit.MEGA): its implicit run's horizon [s] (about
# a minute of CPU to 1 s: docs/notes/2026-11-million-links.md), and the full mode's ode45
# reference horizon [s]
MEGA_T = {QUICK: 0.05, FULL: 1.0}
MEGA_REF_T = 0.01
# one implicit step against DOF (redysim.reports.implicit_scaling): links of the sizes run
SCALING_LINKS = {QUICK: (500, 5_000, 50_000, 500_000),
                 FULL: (500, 1_500, 5_000, 15_000, 50_000, 150_000, 500_000)}
LOG_DIR = "logs"


def _cpu_s() -> float:
    """CPU seconds of this process, of its children that have ended (long runs, compiling
    processes) and of the sweep workers it keeps (:func:`redysim.harness.sweep.shared_pool`):
    what a step costs when another process shares the machine, which wall time is not."""
    from redysim.harness.sweep import shared_pool_cpu_s

    usage = (resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN))
    return sum(u.ru_utime + u.ru_stime for u in usage) + shared_pool_cpu_s()


STEPPING_FORMS = ("plain", "extras")


def warm_stepping(forms: tuple[str, ...] = STEPPING_FORMS) -> None:
    """Compile the compiled stepping (rk_steps) in its two forms: ``"plain"``, the one that
    serves every chain and tree, planar or not (its Motion bundle's types are the same), and
    ``"extras"``, the one with extras (couplings, closed loops, a tip force on a spatial chain:
    the robots' Panda, the scenarios' linkages), so that no sweep worker compiles either."""
    import numpy as np

    from redysim import Body, Chain, Coupling, Model, TreeJoint
    from redysim.algorithms.linkages import four_bar
    from redysim.simulation import simulator

    if "plain" in forms:
        chain = Chain.uniform(3, "U", mass=1.0)
        simulator(chain, 0.02, sample=0.01, compiled=True).run()
    if "extras" in forms:
        fb = four_bar(0.3, 0.1, 0.35, 0.3)
        simulator(fb.model, 0.02, q0=fb.configuration(0.5), loops=fb.loops, sample=0.01,
                  compiled=True).run()
        bars = [Body(name, 1.0, (0.3, 0.0, 0.0), ((0.01, 0, 0), (0, 0.03, 0), (0, 0, 0.03)))
                for name in ("bar0", "bar1")]  # (each body its own name: Model.build)
        arm = Model.build(bars, [TreeJoint("j0", "R", "z"),
                                       TreeJoint("j1", "R", "x", translation=(0.6, 0.0, 0.0))],
                          [-1, 0]).with_couplings([Coupling("j1", "j0", 1.0, 0.0)])
        simulator(arm, 0.02, q0=np.zeros(2), sample=0.01, compiled=True).run()


def _stepping_process(forms: tuple[str, ...]) -> subprocess.Popen:
    """:func:`warm_stepping` of ``forms`` in a process of its own (output piped)."""
    return subprocess.Popen(
        [sys.executable, "-c", "from redysim.reports.reproduce import warm_stepping; "
                               f"warm_stepping({forms!r})"],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)


@dataclass
class Plan:
    """What one invocation runs: named steps, in order. ``mode`` says what for ("quick",
    "full", "tables 4, 9", "report only"); ``kind`` names its record (quick, full, tables)."""

    mode: str
    kind: str
    steps: list[tuple[str, Callable[[], object]]] = field(default_factory=list)

    def add(self, name: str, fn: Callable[[], object]) -> None:
        if name not in {n for n, _ in self.steps}:
            self.steps.append((name, fn))


class Reproduction:
    """The steps, bound to a results folder, a report folder and a number of workers."""

    def __init__(self, results: Path, out: Path, workers: int | None, mode: str):
        self.results = results.resolve()
        self.out = out
        self.workers = workers
        self.mode = mode
        self.t0 = time.perf_counter()
        self._extras: subprocess.Popen | None = None  # warm_up's late second form of rk_steps

    def say(self, msg: str) -> None:
        m, s = divmod(int(time.perf_counter() - self.t0), 60)
        print(f"[{m:02d}:{s:02d}] {msg}", flush=True)

    # ----------------------------------------------------------------------- steps
    def warm_up(self, extras_later: bool = False) -> None:
        """Compile (or load from numba's disk cache) every kernel once, before the sweep workers
        start: they then load machine code instead of compiling it each (every worker had
        compiled the compiled stepping, rk_steps, and the lean inverse entry again). rk_steps
        compiles in a second process (:func:`warm_stepping`) once what it calls (the entries it
        links, the energy at its samples) is cached, beside the other kernels here, where there is
        a second core. Its second form (``"extras"``: couplings, loops) with ``extras_later``
        starts in a third process once both are done, to run beside the next step
        (:meth:`join_stepping` waits for it: the quick and full plans put the precision tables
        between, which need no stepping); else the second process compiles both forms, one
        after the other, while the main process waits (the timings:
        docs/notes/2026-11-quick-reproduction-budget.md)."""
        import numpy as np

        from redysim import (
            Chain,
            energy,
            forward_dynamics,
            load_model,
            mass_matrix,
            tip,
            udu_factors,
        )
        from redysim.algorithms.dynamics import inverse_dynamics

        chains = (Chain.uniform(3, "U", mass=1.0), Chain.uniform(3, "R", mass=1.0))
        for chain in chains:  # first what the stepping process calls: the entries, energy
            q = np.full(chain.n_dof, 0.1)
            forward_dynamics(chain, q, q)
            energy(chain, q, q)
        side = None
        two = (self.workers or os.cpu_count() or 1) > 1
        forms = ("plain",) if extras_later and two else STEPPING_FORMS
        if two:
            side = _stepping_process(forms)
        try:
            for chain in chains:
                q = np.full(chain.n_dof, 0.1)
                for method in ("ge-n", "rge-n"):
                    forward_dynamics(chain, q, q, method=method)
                forward_dynamics(chain, q, q, planar=False)
                inverse_dynamics(chain, q, q, q)
                tip(chain, q, q, q)
                mass_matrix(chain, q)
                udu_factors(chain, q)
            # a robot in DH form (the robots' section, its scenarios): its own kernels' entries
            robot = load_model(str(resources.files("redysim.case_files.robots")
                                   / "puma560.toml"))
            q = np.zeros(robot.n_v)
            forward_dynamics(robot, q, q)
            inverse_dynamics(robot, q, q, q)
        except BaseException:  # (Ctrl-C too) leave no compiling process behind
            if side is not None:
                side.kill()
                side.communicate()
            raise
        if side is not None:
            output = side.communicate()[0]
            if side.returncode != 0:
                self.say(f"  compiling rk_steps in a second process failed ({side.returncode}: "
                         f"{output.strip()[-300:]}); compiling it here")
                warm_stepping(forms)
            if forms != STEPPING_FORMS:
                self._extras = _stepping_process(("extras",))
            return
        warm_stepping()

    def join_stepping(self) -> str:
        """Wait for the compiled stepping's second form (:meth:`warm_up` with ``extras_later``),
        compiling it here if its process failed; its CPU time is this step's."""
        side, self._extras = self._extras, None
        if side is None:  # (one core: the warm-up compiled both forms; or the warm-up failed)
            return "nothing to wait for"
        output = side.communicate()[0]
        if side.returncode != 0:
            self.say(f"  compiling rk_steps (extras) in its own process failed "
                     f"({side.returncode}: {output.strip()[-300:]}); compiling it here")
            warm_stepping(("extras",))
            return "compiled here"
        return "compiled beside the step before"

    def sweep(self, name: str) -> str:
        from redysim.harness.sweep import load_sweep, run_sweep

        sw = load_sweep(SWEEPS / f"{name}.toml")
        runs = run_sweep(sw.specs, self.results / "sweeps" / sw.name, name=sw.name,
                         workers=self.workers, progress=True, reference=sw.reference)
        bad = runs[runs["status"] != "ok"] if len(runs) else runs
        return f"{len(runs)} runs, {len(bad)} failed" + (
            ": " + "; ".join(f"{r.label}: {str(r.reason)[:80]}" for r in bad.itertuples())
            if len(bad) else "")

    def _longrun(self, case: str, out: Path | None = None, tag: str = "", **flags) -> dict:
        """One checkpointed long run (:mod:`redysim.harness.longrun`) in a process of its own, so
        that the peak RSS it records is its own, not this process's after every earlier step; its
        output goes to the log line by line (after ``tag``). Returns its final checkpoint."""
        from redysim import load_case
        from redysim.harness import longrun

        # a checkpoint of other code or settings (a reproduction after an edit) is set aside,
        # kept beside the new one, never resumed
        argv = [sys.executable, "-m", "redysim.harness.longrun", case, "--set-aside"]
        for key, value in flags.items():
            argv += [f"--{key.replace('_', '-')}", str(value)]
        if out is not None:
            argv += ["--out", str(out)]
        tail: list[str] = []
        with subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                              text=True) as proc:
            for line in proc.stdout:
                self.say(f"  {tag}{line.rstrip()}")
                tail = (tail + [line.rstrip()])[-5:]
        if proc.returncode != 0:
            raise RuntimeError(f"longrun {case} exited {proc.returncode}: " + " | ".join(tail))
        integrator = longrun.canonical(flags.get("integrator", "ode45"))
        path = (out or longrun.out_dir_for(load_case(case).name, integrator)) / longrun.CHECKPOINT
        ck = longrun.load_checkpoint(path, log=self.say)
        if ck is None:
            raise RuntimeError(f"longrun {case}: no readable checkpoint at {path}")
        return ck

    def long_runs(self) -> str:
        """Table 5: each huge chain to the paper's horizon as a checkpointed long run
        (:mod:`redysim.harness.longrun`, under the results folder): stopped at any point, it resumes
        from its last checkpoint."""
        from redysim import load_published
        from redysim.harness import longrun

        done = []
        for row in load_published()["table5"]["rows"]:  # one at a time: each holds one core
            done.append(longrun.summary(self._longrun(row["case"], t_end=row["t_end"])))
        return " | ".join(done)

    def implicit(self) -> str:
        """The implicit midpoint on RE-U50000-L1000 to 5 s (about a minute), and the explicit
        ode45 run it is measured against, to IMPLICIT_REF_T[mode] (its steps of ~1e-5 s make 0.48
        s a run of half an hour); the 1,000,000-DOF chain's implicit run to MEGA_T[mode]
        (and, full, its ode45 run to MEGA_REF_T); all checkpointed long runs sampled every 0.01
        s (the million-DOF pair every 1e-3 s), two at a time; then one implicit step against
        DOF (:mod:`.implicit_scaling`)."""
        from redysim.harness import longrun
        from redysim.io.cases import CASES_DIR

        from . import implicit_scaling
        from .implicit import CASE, MEGA, MEGA_FILE

        t_ref, t_mega = IMPLICIT_REF_T[self.mode], MEGA_T[self.mode]
        mega = str(Path(CASES_DIR) / MEGA_FILE)  # not a paper case: in a folder of its own
        runs = [(CASE, dict(integrator="midpoint", t_end=5.0, sample=IMPLICIT_SAMPLE),
                 f"{CASE}-midpoint"),
                (CASE, dict(t_end=t_ref, sample=IMPLICIT_SAMPLE), f"{CASE}-ode45-{t_ref:g}"),
                (mega, dict(integrator="midpoint", t_end=t_mega, sample=1e-3),
                 f"{MEGA}-midpoint-{t_mega:g}")]
        if self.mode == FULL:
            runs.append((mega, dict(integrator="ode45", t_end=MEGA_REF_T, sample=1e-3),
                         f"{MEGA}-ode45-{MEGA_REF_T:g}"))

        def one(case, kw, folder):
            return longrun.summary(self._longrun(
                case, out=self.results / "longrun" / folder, tag=f"[{folder}] ", every=60.0,
                **kw))

        def scaling():
            doc = implicit_scaling.run(self.results / implicit_scaling.RESULT_FILE,
                                       SCALING_LINKS[self.mode],
                                       say=lambda m: self.say(f"  [scaling] {m}"))
            return f"scaling: CPU per qdd call ~ DOF^{doc['slopes']['cpu_per_call_ms']:.2f}"

        # independent processes: side by side where there are two cores (each records its own
        # CPU time and peak RSS); one after the other with --workers 1
        tasks = [lambda r=r: one(*r) for r in runs] + [scaling]
        with ThreadPoolExecutor(max_workers=min(2, self.workers or os.cpu_count() or 1)) as ex:
            done = list(ex.map(lambda task: task(), tasks))
        return " | ".join(done)

    def precision(self, names: tuple[str, ...], sensitivity: bool) -> str:
        from redysim import load_published

        from . import precision_tables as pt

        pub, out, refs = load_published(), self.results / "precision", {}
        makers = {"table10": lambda: pt.table10(pub), "tableA2": lambda: pt.tableA2(pub),
                  "table11": lambda: pt.table11(pub, refs=refs),
                  "ieee": lambda: pt.ieee_table(refs=refs),
                  "table8": lambda: pt.table8(pub, sensitivity=sensitivity)}
        for name in names:
            pt.write(out, name, makers[name]())
            self.say(f"  precision {name} written")
        return f"{', '.join(names)} -> {out}"

    def gim_study(self) -> str:
        from . import gim_study

        t9, cond = gim_study.run(self.results / "gim_study")
        return (f"Table 9: cond2 {t9['ours']['cond2']:.4f} (paper {t9['paper']['cond2']}); "
                f"cond2 of {len(cond)} chains up to {cond['n_links'].max():,} links")

    def opcount(self) -> str:
        from . import opcount

        fits = opcount.run(self.results / "opcount")["fits"]
        return "; ".join(f"{f['algorithm']}: {f['mult']} mult, {f['add']} add" for f in fits)

    def error_study(self, sizes: tuple[int, ...] | None) -> str:
        try:
            from redysim.harness import error_study
        except ImportError as exc:
            return f"skipped: harness.error_study is not available ({exc})"
        log = self.results / LOG_DIR / "error_study.log"
        log.parent.mkdir(parents=True, exist_ok=True)
        argv = ["--out", str(self.results / "error_study")]
        if sizes:
            argv += ["--sizes", *map(str, sizes)]
        with open(log, "a", encoding="utf-8") as fh, contextlib.redirect_stdout(fh):
            error_study.main(argv)
        return f"log: {log}"

    def scaling(self) -> str:
        from . import scaling

        df = scaling.run(self.results / "scaling", FULL if self.mode == FULL else QUICK,
                         log=lambda _msg: None)
        ok = df[df["status"] == "ok"]
        return (f"{ok['algorithm'].nunique()} algorithms, {len(ok)} points; largest timed: "
                + ", ".join(f"{a} {g['n_dof'].max():,}" for a, g in ok.groupby("algorithm",
                                                                               sort=False)))

    def robots(self) -> str:
        from . import robots

        doc = robots.run(self.results / "robots", log=self.say)
        ok = [r for r in doc["agreement"] if r["status"] == "ok"]
        # MuJoCo's coupled qdd is soft by design (the report says so): counted apart
        soft = [r for r in ok if r.get("couplings") and r["engine"] == "mujoco"]
        hard = [r for r in ok if r not in soft]
        worst = max((max(r[s] for s in robots.STAGES) for r in hard), default=float("nan"))
        return (f"{len(doc['falls'])} robots, {len(ok)} robot x engine pairs built, worst "
                f"relative difference {worst:.1e}"
                + (f" (and MuJoCo's soft mimic couplings, {len(soft)} robots: up to "
                   f"{max(r['qdd'] for r in soft):.1e} in qdd)" if soft else ""))

    def loops(self, full: bool = False) -> str:
        from . import loops

        doc = loops.run(self.results / "loops", full=full, log=self.say)
        lr = doc["long"]
        return (f"four-bar path {doc['four_bar']['path_error_m']:.1e} m, slope "
                f"{doc['slope']:.2f}, {lr['n']:,} rods for {lr['t_end']:g} s in "
                f"{lr['cpu_s']:.0f} s")

    def proteins(self, full: bool = False) -> str:
        from . import proteins

        doc = proteins.run(self.results / "proteins", full=full, log=self.say)
        core = [r for r in doc["true_error"] if r["method"].startswith("redysim")]
        pc = doc["per_call"][-1]
        return (f"{len(doc['sizes'])} backbones, the core's worst true error "
                f"{max(r['rel2'] for r in core):.1e}; {pc['residues']:,} residues "
                f"{pc['backbone_ns_per_dof']:.0f} ns/DOF (the rope {pc['rope_ns_per_dof']:.0f})")

    def refine(self) -> str:
        from redysim.harness import refine

        doc = refine.run_all(self.results, workers=self.workers or os.cpu_count() or 1,
                             log=self.say)
        parts = []
        for scene, s in doc["scenes"].items():
            c = s["convergence"]
            parts.append(f"{scene} order {c['order']:.2f}")
        return ("; ".join(parts) + f"; hanging modes order "
                f"{min(doc['hanging']['orders']):.2f}-{max(doc['hanging']['orders']):.2f}")

    def build(self) -> str:
        from .build import write_report

        html, pdf = write_report(self.results, self.out, log=self.say)
        return f"{html}, {pdf}"

    # ----------------------------------------------------------------------- plans
    def plan(self, tables: list[str], build_only: bool) -> Plan:
        if build_only:
            p = Plan("report only", "report")
        elif tables:
            p = Plan(f"table{'s' if len(tables) > 1 else ''} {', '.join(tables)}", "tables")
        else:
            p = Plan(self.mode, self.mode)
        if build_only:
            p.add("report", self.build)
            return p
        if tables:
            p.add("JIT warm-up", self.warm_up)
            for t in tables:
                self._table_steps(p, t)
            p.add("report", self.build)
            return p
        # the precision tables (mpmath, no simulation) run beside the compiled stepping's second
        # form, compiled in a process of its own (warm_up, join_stepping)
        p.add("JIT warm-up", lambda: self.warm_up(extras_later=True))
        p.add("precision tables", lambda: self.precision(
            ("table10", "tableA2", "table11", "ieee", "table8"), sensitivity=self.mode == FULL))
        p.add("JIT warm-up, rk_steps with extras", self.join_stepping)
        if self.mode == QUICK:
            for name in QUICK_SWEEPS:
                p.add(f"sweep {name}", lambda name=name: self.sweep(name))
            p.add("Table 9, conditioning", self.gim_study)
            p.add("Table 7, operation counts", self.opcount)
            p.add("true-error study", lambda: self.error_study(QUICK_ERROR_SIZES))
            p.add("CPU scaling", self.scaling)
            p.add("robots and trees", self.robots)
            p.add("closed loops", self.loops)
            p.add("protein backbones", self.proteins)
            p.add("model size (refinement studies)", self.refine)
            p.add("implicit integrator, 100,000 and 1,000,000 DOF", self.implicit)
        else:
            for name in FULL_SWEEPS:
                p.add(f"sweep {name}", lambda name=name: self.sweep(name))
            p.add("Table 5, long runs", self.long_runs)
            p.add("Table 9, conditioning", self.gim_study)
            p.add("Table 7, operation counts", self.opcount)
            p.add("CPU scaling", self.scaling)
            p.add("true-error study", lambda: self.error_study(None))
            p.add("robots and trees", self.robots)
            p.add("closed loops", lambda: self.loops(full=True))
            p.add("protein backbones", lambda: self.proteins(full=True))
            p.add("model size (refinement studies)", self.refine)
            p.add("implicit integrator, 100,000 and 1,000,000 DOF", self.implicit)
        p.add("report", self.build)
        return p

    def _table_steps(self, p: Plan, table: str) -> None:
        if table == "5":
            p.add("Table 5, long runs", self.long_runs)
        elif table in TABLE_SWEEPS:
            name = TABLE_SWEEPS[table]
            p.add(f"sweep {name}", lambda: self.sweep(name))
            if table == "6":  # Fig. 18(a) goes with Table 6
                p.add("CPU scaling", self.scaling)
        elif table == "7":
            p.add("Table 7, operation counts", self.opcount)
        elif table == "9":
            p.add("Table 9, conditioning", self.gim_study)
        else:
            name = "tableA2" if table == "A2" else f"table{table}"
            names = (name, "ieee") if table == "11" else (name,)
            p.add(f"precision {', '.join(names)}",
                  lambda: self.precision(names, sensitivity=True))
            if table == "11":  # the conditioning figure goes with Table 11
                p.add("Table 9, conditioning", self.gim_study)

    def run(self, plan: Plan) -> int:
        started = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
        record = {"mode": plan.mode, "started": started, "steps": [], "provenance": provenance(),
                  "machine": provenance()["machine"]}
        from redysim.harness.sweep import shared_pool

        failed, cpu0 = 0, _cpu_s()
        try:
            # one pool of sweep workers for every step's sweeps: each worker starts once
            with shared_pool(self.workers):
                failed = self._run_steps(plan, record)
        finally:  # (Ctrl-C too) leave no compiling process behind
            if self._extras is not None:
                self._extras.kill()
                self._extras.communicate()
                self._extras = None
        total = time.perf_counter() - self.t0
        m, s = divmod(int(round(total)), 60)
        self.say(f"{plan.mode}: finished in {m} min {s} s, CPU {_cpu_s() - cpu0:.0f} s"
                 + (f"; {failed} step(s) failed" if failed else ""))
        return 1 if failed else 0

    def _run_steps(self, plan: Plan, record: dict) -> int:
        """Run the plan's steps in order, recording each (the failures counted)."""
        failed = 0
        for name, fn in plan.steps:
            self.say(f"{name} ...")
            t0, c0 = time.perf_counter(), _cpu_s()
            try:
                detail = fn() or ""
                status = "ok"
            except Exception as exc:  # report it, go on: the report shows what there is
                traceback.print_exc()
                detail, status = f"{type(exc).__name__}: {exc}", "failed"
                failed += 1
            wall, cpu = time.perf_counter() - t0, _cpu_s() - c0
            self.say(f"{name}: {status} in {wall:.1f} s (CPU {cpu:.1f} s). {detail}")
            record["steps"].append({"step": name, "wall_s": wall, "cpu_s": cpu, "status": status,
                                    "detail": str(detail)})
            record["wall_s"] = time.perf_counter() - self.t0
            record["finished"] = _dt.datetime.now(_dt.UTC).isoformat(timespec="seconds")
            if name != "report":
                write_json_atomic(record, self.results / REPRODUCE_FILE.format(plan.kind))
        return failed


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    mode = ap.add_mutually_exclusive_group()
    mode.add_argument("--full", action="store_true",
                      help="every table to the paper's horizons (hours)")
    mode.add_argument("--table", action="append", choices=TABLES, default=[], metavar="N",
                      help=f"only what table N needs ({', '.join(TABLES)}); repeatable")
    mode.add_argument("--build-only", action="store_true",
                      help="only rebuild the report from the results on disk")
    ap.add_argument("--results", type=Path, default=Path("results"), help="results folder")
    ap.add_argument("--out", type=Path, default=Path("reports") / "out", help="report folder")
    ap.add_argument("--workers", type=int, default=None,
                    help="sweep worker processes (default: one per core)")
    ap.add_argument("--dask", metavar="ADDRESS|local", default=None,
                    help="send every sweep's runs (the tables' sweeps, the scenarios, the "
                         "refinement studies) to this Dask scheduler (its workers with this "
                         "checkout installed and the results folder at the same path; 'local': "
                         "a LocalCluster); the long runs, the precision tables, the error study "
                         "and the figures run here")
    args = ap.parse_args(argv)
    if args.dask is not None and args.workers is not None:
        ap.error("--workers sets the local pool; with --dask the cluster's workers run the sweeps")
    rep = Reproduction(args.results, args.out, args.workers, FULL if args.full else QUICK)
    # reference solutions are cached under the results folder (redysim.harness.reference), also in
    # the sweep's worker processes, which inherit the environment
    os.environ["REDYSIM_RESULTS"] = str(rep.results)
    rep.say(f"{rep.mode} reproduction -> {rep.results}, report -> {args.out}"
            + (f"; sweeps on Dask ({args.dask})" if args.dask else ""))
    from redysim.harness.sweep import dask_default

    with dask_default(args.dask):
        return rep.run(rep.plan(args.table, args.build_only))


if __name__ == "__main__":
    sys.exit(main())
