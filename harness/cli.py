"""The ``redysim`` command: simulate one case, run a sweep file, list the cases.

A thin layer over :func:`redysim.harness.run.execute` and :mod:`redysim.harness.sweep`. An
install without extras (numpy, scipy, numba) runs ``--help``, ``cases``, ``info`` and
``simulate`` on the core; what needs an extra imports it only inside the command that needs it,
and refuses, naming the extra to install, when it is missing (:data:`EXTRA_OF`): ``sweep`` and
``advise`` and ``simulate --out`` need ``harness`` (pandas, pyarrow, ...), ``--engine`` needs
``engines``, an MJCF file needs ``models`` (URDF is read by redysim itself). Exit codes: 0 all
runs ok, 1 a run failed, 2 bad usage or input, or an extra missing (the message names what is
wrong; no traceback), 3 a run stopped by your ``--max-wall`` (its samples so far kept), 130
interrupted.
"""

from __future__ import annotations

import argparse
import importlib.util
import math
import os
import sys
from collections.abc import Callable, Sequence
from pathlib import Path

from redysim.errors import RedysimError, SettingsError
from redysim.integrators.explicit import (
    ALIASES,
    DEFAULT_ATOL,
    DEFAULT_METHOD,
    DEFAULT_RTOL,
    INTEGRATORS,
)
from redysim.io.cases import CASES_DIR, list_cases, load_case
from redysim.io.kinds import KINDS, FileKind, either, kind_of
from redysim.io.robots import PREFIX as ROBOT_DATA

PROG = "redysim"
EXIT_OK, EXIT_RUN_FAILED, EXIT_USAGE, EXIT_STOPPED, EXIT_INTERRUPTED = 0, 1, 2, 3, 130
DEFAULT_SWEEP_ROOT = Path("results") / "sweeps"  # redysim sweep's --out default: <root>/<name>
# (results/ is $REDYSIM_RESULTS when set: redysim.harness.reference.results_dir)
MAX_FAILED_SHOWN = 20  # failed runs listed after a sweep
# The extra that installs each optional package a command may import, by import name
# (pyproject.toml's [project.optional-dependencies]; dask comes with distributed; mujoco is in
# 'engines' too, and a missing engine is refused naming 'engines' by --engine's own check)
EXTRA_OF = {**dict.fromkeys(("pandas", "pyarrow", "distributed", "dask", "tqdm", "matplotlib",
                             "jinja2", "reportlab", "psutil", "mpmath", "threadpoolctl",
                             "tomli_w"),
                            "harness"),
            "mujoco": "models",
            **dict.fromkeys(("pinocchio", "dartpy", "exudyn", "pydrake"), "engines")}

DESCRIPTION = """\
redysim: O(n) dynamics of very long serial chains (ReDySim: DeNOC + Reverse Gaussian
Elimination), with reference engines and a validation harness.

examples:
  redysim cases                                   # the chains of the paper
  redysim simulate RE-U125-L1 --t-end 0.1         # one run, printed
  redysim sweep sweeps/smoke.toml                 # a declared set of runs, saved as Parquet
  redysim simulate UR5-FALL --engine mujoco --integrator native:implicit --h 1e-3
  redysim compare example-robot-data:ur5          # your model in every engine: a page
  redysim robots                                  # robots by name: example-robot-data:NAME
  redysim engines                                 # the engines and their own integrators

`redysim COMMAND --help` explains each command. Without extras, cases, info and simulate run
on the core; sweep, advise, compare and simulate --out need 'redysim[harness]', --engine
needs 'redysim[engines]', an MJCF file 'redysim[models]'."""

ENGINES_HELP = """\
List the reference engines: whether each is installed (its version), and its own integrators
(native:NAME for `redysim simulate --integrator` and sweep files): fixed-step ones take --h,
error-controlled ones --rtol/--atol."""

SIMULATE_HELP = """\
Simulate one scenario and print its summary: E(0), steps, rejected steps, RHS calls, CPU time,
JIT compile time (timed apart), average |delta_M| (energy drift per unit mass), and at every
sample the observed frame's position (a rope's tip) and the centre of mass. Horizon and sample
interval default to the scenario's.

A scenario is a rope case (its name or file), a scenario file (cases/scenarios/: a model file,
a state, a horizon and what to observe; its name, e.g. UR5-FALL, or its path), or a model file
by itself: a robot (a .urdf, an MJCF .xml, a DH robot file such as cases/robots/puma560.toml,
or a robot of example-robot-data by name, example-robot-data:ur5: `redysim robots`) falls
passively under gravity from its file's configuration at rest (a floating base tumbles from
seeded random velocities), a linkage (cases/loops/*.toml) moves with its loops closed; the
summary says what the importer dropped from the file (damping, friction, limits: not simulated).
With --floating, a URDF's or MJCF's root body gets a free joint. --lock holds joints at given
values (a reduced model). Horizon 1 s and 20 samples unless given. A flag that the kind of file
given has no use for (--links or --precision float32 on a robot, --floating on a rope case,
--mimic on anything but a URDF) is refused by name, never ignored.

Every engine runs every scenario: --engine E computes qdd (redysim's integrators step it), and
--integrator native:NAME lets the engine step itself with one of its own integrators (`redysim
engines` lists them; a fixed-step one takes --h, an error-controlled one --rtol/--atol).

Time limits: --max-cpu S is part of the run (a run past S seconds of CPU time fails, whatever
else the machine is doing); --max-wall S is your patience (the run is stopped after S seconds
of wall time, its samples kept, and reported as stopped, exit code 3).

examples:
  redysim simulate RE-U125-L1 --t-end 0.1 --sample 0.01
  redysim simulate STUDY-R3 --integrator rk4 --h 1e-3 --t-end 1
  redysim simulate RE-U125-L1 --engine mujoco --rtol 1e-6 --atol 1e-8 --out tip.parquet
  redysim simulate UR5-FALL --engine mujoco --integrator native:implicit --h 1.25e-3
  redysim simulate TALOS-FALL --engine drake --integrator native:runge_kutta3 --rtol 1e-6
  redysim simulate example-robot-data:ur5 --t-end 1 --rtol 1e-8 --atol 1e-10
  redysim simulate example-robot-data:solo12 --floating --engine pinocchio-aba
  redysim simulate cases/robots/puma560.toml --lock joint1=0 --lock joint4=0 --lock joint5=0 \\
      --lock joint6=0                           # the talk's free fall of joints 2 and 3
  redysim simulate cases/loops/hoekens_straight_line.toml --rtol 1e-10 --atol 1e-12
                                                # a linkage file: its loops closed"""

SWEEP_HELP = """\
Run a sweep file: a TOML [sweep] table whose lists (cases, engines, methods, integrators, rtols,
h) multiply into runs; see sweeps/smoke.toml (the repository's sweeps/ comes with redysim as
the package data redysim.sweep_files). Needs the 'harness' extra. Each finished run is saved at
once under OUT/runs/ and OUT/samples/; at the end everything is gathered into OUT/runs.parquet
and OUT/samples.parquet. Started again, a sweep skips the runs it has finished, so an
interrupted sweep (even a killed one) resumes where it stopped. OUT/manifest/ lists each
finished run's files with their SHA-256: a file deleted, damaged or replaced is said and its
run done again. A finished sweep run again writes nothing; an OUT that cannot be written is
refused before any run, unless every run in it is finished (then it is read as it is).

examples:
  redysim sweep sweeps/smoke.toml
  redysim sweep sweeps/work-precision-RE-U125-L1.toml --out results/wp --workers 2
  redysim sweep sweeps/smoke.toml --dask local           # a 2-worker Dask cluster on this machine
  redysim sweep big.toml --dask tcp://scheduler:8786     # an existing Dask cluster"""

INFO_HELP = """\
Print a model's kinematic tree: each body under its parent, its joint (type, name, axes) and
mass, the named frames, and what the importer dropped from the file (geometry, limits, ...).
URDF is read by redysim; MJCF by MuJoCo's compiler (the 'models' extra).

examples:
  redysim info RE-U125-L1
  redysim info example-robot-data:ur5
  redysim info example-robot-data:solo12 --floating"""

ADVISE_HELP = """\
How many links does a scene need? From a refinement study (one rope at several link counts, each
at several integrator tolerances, measured against the finest model: `python -m
redysim.harness.refine`, which `make reproduce` runs), print the run of least CPU whose tip
path stayed within --tip-tol of the finest model's, what the finest model cost for the same
tolerance, and the command that runs the advised model.

Any rope case (a case name or your own case file): the study is run for it, here, and stopped
once the answer is known: your model by DOP853 at 1e-10 (the reference) and every coarser model
(link counts that divide yours; for a count with no divisor, such as 5, the straight rope
rebuilt at coarser counts spaced alike) by ode45 at 1e-8; the reference's own error by
Richardson where the observed order is steady, else against the rope at twice your links.
Searched: every count between the finest divisor that misses the tolerance and the coarsest
count that meets it (the coarsest divisor that meets it, or your own count when none does), by
bisection on the rope rebuilt at each count tried (a straight rope's file; a rope that starts
bent is searched over divisors only, and says so); then every setting on the least count within
the tolerance, the coarsest divisor within it and your own model. The advice is checked by
running it again. Runs are cached in --out (default results/advise/CASE): ask again, with
another tolerance too, and only what is new runs.

A robot's scenario (a scenario's name or file, or a robot file): which joints can be locked at
their initial values (their bodies fused) with the path of --observe (default: the scenario's
first observed frame) within --tip-tol: each joint locked alone and run, ranked by its effect,
then locked together from the least effect up while the set, run again, stays within it; the
costs of the full and the reduced model; a scenario file of the reduced model, checked by running
it. For the hanging chain, the coarsest
model whose first --modes frequencies are within --freq-tol of the continuum's (a chain of n
links has n modes: a model with fewer than --modes cannot meet it, and more modes than the
study's finest model has are refused). Needs the 'harness' extra.

examples:
  redysim advise fall --tip-tol 0.01
  redysim advise spin --tip-tol 1e-3
  redysim advise hanging --modes 3 --freq-tol 0.001
  redysim advise results/refine/pulled --tip-tol 0.05
  redysim advise RE-U125-L1 --tip-tol 1e-3 --t-end 0.3
  redysim advise my_rope.toml --tip-tol 0.01
  redysim advise TALOS-FALL --tip-tol 1e-3 --observe arm_left_7_link"""

ROBOTS_HELP = """\
List the robots that can be given by name wherever a model file is taken (simulate, info,
compare, advise, a sweep's cases, a scenario's [model] file, load_model): the model files of
the example-robot-data package (installed with redysim[test]), as example-robot-data:NAME, or
by the end of their path in the package (example-robot-data:ur_description/urdf/ur5_robot.urdf;
the only form for a file whose stem another file shares), and the built-in scenarios, which
run by their own names.

example:
  redysim robots
  redysim info example-robot-data:ur5"""

CASES_HELP = """\
List the case files that come with redysim (every chain of the paper: the repository's cases/,
installed as the package data redysim.case_files) with their descriptions. Any of these names,
or the path of your own case file, can be given to `redysim simulate`.

example:
  redysim cases"""


def positive(text: str) -> float:
    """An argparse type: a finite number > 0 (the ranges of each setting are checked later, by
    the run's settings check, which names the flag)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"{text!r} must be a finite number > 0")
    return value


def _whole(text: str) -> int:
    """An argparse type: a whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be at least 1")
    return value


def build_parser(extra: Sequence[Callable] = ()) -> argparse.ArgumentParser:
    """The argument parser of every command; ``extra``: functions that add the commands of the
    layer above (``add(subparsers)``: :func:`redysim.reports.commands.main` adds ``compare``,
    whose page the reports render; the harness never imports the reports)."""
    from redysim import references
    from redysim.harness.spec import CORE, CORE_METHODS, NATIVE, RunSpec

    fmt = argparse.RawDescriptionHelpFormatter
    ap = argparse.ArgumentParser(prog=PROG, description=DESCRIPTION, formatter_class=fmt)
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    sim = sub.add_parser("simulate", description=f"{SIMULATE_HELP}\n\n{files_help()}",
                         formatter_class=fmt,
                         help="run one scenario (a rope case, a scenario file, a robot or "
                              "linkage file) with one engine and integrator; print energy "
                              "drift and the observed path")
    sim.add_argument("case", metavar="CASE", help=FILE_ARGUMENT)
    sim.add_argument("--engine", default=CORE, choices=(CORE, *references.ENGINES), metavar="E",
                     help=f"who computes qdd: {CORE} (the core) or a reference engine: "
                          f"{', '.join(references.ENGINES)} (default: {CORE})")
    sim.add_argument("--method", default=RunSpec.method, choices=CORE_METHODS, metavar="M",
                     help=f"the core's algorithm: {', '.join(CORE_METHODS)}; rge-a is O(n) "
                          f"(default: {RunSpec.method})")
    sim.add_argument("--integrator", type=_integrator, metavar="I",
                     help=f"{', '.join((*INTEGRATORS, NATIVE))} or native:NAME (one of the "
                          f"engine's own integrators, listed by `redysim engines`); adaptive "
                          f"ones take --rtol/--atol, rk4, midpoint-fixed and an engine's "
                          f"fixed-step ones take --h; implicit is midpoint, the implicit "
                          f"midpoint rule with error control, for chains whose explicit steps "
                          f"are bound by waves (default: the scenario's, else {DEFAULT_METHOD})")
    sim.add_argument("--rtol", type=positive, metavar="R",
                     help=f"relative tolerance of an adaptive integrator, in [100 eps, 1) "
                          f"(default: the case file's, else {DEFAULT_RTOL:g})")
    sim.add_argument("--atol", type=positive, metavar="A",
                     help=f"absolute tolerance of an adaptive integrator (default: the case "
                          f"file's, else {DEFAULT_ATOL:g})")
    sim.add_argument("--h", type=positive, metavar="H",
                     help="step [s] of a fixed-step integrator (rk4, midpoint-fixed, "
                          "native); adaptive "
                          "integrators choose their own steps and refuse one")
    sim.add_argument("--t-end", type=positive, metavar="T",
                     help="horizon [s] (default: the case's)")
    sim.add_argument("--sample", type=positive, metavar="S",
                     help="sample interval [s] (default: the case's)")
    sim.add_argument("--max-wall", type=positive, metavar="S",
                     help="your patience: stop the run after S seconds of wall time, keeping "
                          "its samples so far; the run is reported as stopped (exit code 3), "
                          "not as a result (default: no limit; a run longer than a few seconds "
                          "prints its progress on stderr)")
    sim.add_argument("--max-cpu", type=positive, metavar="S",
                     help="a limit that is part of the run (RunSpec.max_cpu_s): a run that has "
                          "used S seconds of CPU time is stopped and recorded as failed, "
                          "whatever else the machine is doing (default: no limit)")
    sim.add_argument("--links", type=_whole, metavar="N",
                     help="a rope case: coarse-grain its chain to N links (each coarse link "
                          "lumps the same number of fine ones, its initial state mapped along "
                          "the chords); an N that does not divide its link count rebuilds a "
                          "straight rope from its file at N links; see `redysim advise`")
    sim.add_argument("--precision", choices=PRECISION_CHOICES,
                     help="a rope case: the arithmetic of the core's qdd: float64 (default) or "
                          "float32 (numpy-emulated IEEE single: slow, for accuracy studies)")
    sim.add_argument("--out", type=Path, metavar="FILE.parquet|FILE.csv",
                     help="also save the samples to FILE and the summary row to "
                          "FILE.summary.parquet (or .summary.csv): Parquet or CSV by suffix")
    _model_flags(sim)
    sim.add_argument("--lock", type=_lock, action="append", default=[], metavar="JOINT=VALUE",
                     help=f"{kinds_taking('lock')}: hold a joint at a coordinate (radians, "
                          "metres; several comma-separated for a U, S or free joint); repeat "
                          "for more joints")
    sim.set_defaults(func=cmd_simulate)

    sw = sub.add_parser("sweep", description=SWEEP_HELP, formatter_class=fmt,
                        help="run every run of a sweep file (cases x engines x integrators x "
                             "tolerances), resumable, on a process pool or Dask")
    sw.add_argument("sweep_file", metavar="SWEEP.toml", type=Path, help="the sweep file")
    sw.add_argument("--out", type=Path, metavar="DIR",
                    help=f"results folder (default: {DEFAULT_SWEEP_ROOT}/<sweep name>)")
    sw.add_argument("--workers", type=_whole, metavar="N",
                    help="processes of the local pool (default: the number of CPU cores; "
                         "refused with --dask, whose cluster has its own workers)")
    sw.add_argument("--dask", metavar="ADDRESS|local",
                    help="run on a Dask cluster: a scheduler address, or 'local' for a "
                         "2-worker cluster on this machine")
    sw.add_argument("--no-progress", dest="progress", action="store_false",
                    help="no progress bar")
    sw.add_argument("--retry-failed", action="store_true",
                    help="run the failed runs again too (without it, only runs whose worker "
                         "died or raised are run again: the others fail the same way)")
    sw.set_defaults(func=cmd_sweep)

    cs = sub.add_parser("cases", description=CASES_HELP, formatter_class=fmt,
                        help="list the chains of the paper that come with redysim")
    cs.set_defaults(func=cmd_cases)

    rb = sub.add_parser("robots", description=ROBOTS_HELP, formatter_class=fmt,
                        help="list the robots given by name (example-robot-data:NAME) and the "
                             "built-in scenarios")
    rb.set_defaults(func=cmd_robots)

    adv = sub.add_parser("advise", description=ADVISE_HELP, formatter_class=fmt,
                         help="the coarsest model and cheapest integrator setting that meet a "
                              "tolerance, from a refinement study's measurements")
    adv.add_argument("scene", metavar="SCENE",
                     help="spin, fall, whip, pulled (their studies under RESULTS/refine/), "
                          "hanging (the hanging chain's modes), the folder of a refinement "
                          "sweep's results, or a rope case (name or file): its own study")
    adv.add_argument("--tip-tol", type=positive, metavar="M",
                     help="tip-path tolerance [m]: the largest distance from the finest "
                          "model's tip over the samples")
    adv.add_argument("--modes", type=_whole, metavar="M",
                     help="hanging: how many of the lowest frequencies must be within "
                          "--freq-tol")
    adv.add_argument("--freq-tol", type=positive, metavar="F",
                     help="hanging: relative tolerance of those frequencies against the "
                          "continuum's (0.01 = 1 %%)")
    adv.add_argument("--results", type=Path, metavar="DIR",
                     help="where the studies of spin, fall, whip and pulled are (default: "
                          "results)")
    adv.add_argument("--t-end", type=positive, metavar="T",
                     help="a rope case's study: its horizon [s] (default: the case's t_end)")
    adv.add_argument("--out", type=Path, metavar="DIR",
                     help="a rope case's study: where its runs are cached (default "
                          "results/advise/CASE)")
    adv.add_argument("--workers", type=_whole, metavar="N",
                     help="a rope case's study: processes (default: every core)")
    adv.add_argument("--no-progress", action="store_true",
                     help="a rope case's study: no progress bar")
    adv.add_argument("--observe", metavar="FRAME",
                     help="a robot scenario: the frame whose path --tip-tol bounds (default: "
                          "the scenario's first observed frame)")
    adv.set_defaults(func=cmd_advise)

    eng = sub.add_parser("engines", description=ENGINES_HELP, formatter_class=fmt,
                         help="the reference engines, their versions and their own integrators")
    eng.set_defaults(func=cmd_engines)

    info = sub.add_parser("info", description=f"{INFO_HELP}\n\n{files_help()}",
                          formatter_class=fmt,
                          help="print a model's tree: bodies, joints, masses, what was dropped")
    info.add_argument("model", metavar="MODEL",
                      help=FILE_ARGUMENT)
    _model_flags(info)
    info.set_defaults(func=cmd_info)
    for add in extra:
        add(sub)
    return ap


def _integrator(text: str) -> str:
    """An argparse type: one of redysim's integrators, "native" or "native:NAME" (whether the
    engine has NAME is checked with the engine, naming its own)."""
    from redysim.harness.spec import NATIVE

    if text in (*INTEGRATORS, *ALIASES, NATIVE) or (text.startswith(NATIVE + ":") and
                                                    len(text) > len(NATIVE) + 1):
        return text
    raise argparse.ArgumentTypeError(f"invalid choice: {text!r} (choose from "
                                     f"{', '.join((*INTEGRATORS, *ALIASES, NATIVE))}, or "
                                     "native:NAME)")


def _lock(text: str) -> tuple[str, list[float]]:
    """An argparse type: NAME=VALUE or NAME=V1,V2,... (a joint held at its coordinates)."""
    name, sep, values = text.partition("=")
    try:
        numbers = [float(v) for v in values.split(",")]
    except ValueError:
        numbers = []
    if not (sep and name and numbers and all(math.isfinite(x) for x in numbers)):
        raise argparse.ArgumentTypeError(f"{text!r}: give NAME=VALUE (radians or metres), or "
                                         "NAME=V1,V2,... for a joint of several coordinates")
    return name, numbers


def _model_flags(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--floating", action="store_true",
                        help=f"the root body of {kinds_taking('floating')} gets a free joint (a "
                             "legged or flying robot)")
    parser.add_argument("--mimic", choices=("couple", "independent", "refuse"),
                        help="a URDF's mimic joints: couple them to their leaders (default), "
                             "let them move independently, or refuse them")


# --------------------------------------------------------------------------- commands
# simulate's flags by the RunSpec field they set (in a refusal's message)
FLAGS = {"integrator": "--integrator", "rtol": "--rtol", "atol": "--atol", "h": "--h",
         "t_end": "--t-end", "sample": "--sample", "links": "--links",
         "precision": "--precision"}
PRECISION_CHOICES = ("float64", "float32")  # redysim.harness.spec.PRECISIONS
OUT_SUFFIXES = (".parquet", ".csv")
SOURCE = "command line"  # where a bad flag came from, in its message


def _check_out(out: Path) -> None:
    """--out must name a file (.parquet or .csv) in an existing folder, and what writes it
    (pandas; pyarrow for Parquet: the 'harness' extra) must be installed: checked before the
    run, so that a long run is never lost to a bad path or a missing package."""
    if out.is_dir():
        raise SettingsError(SOURCE, "--out", str(out), "is a folder; give a file name in it")
    if out.suffix not in OUT_SUFFIXES:
        raise SettingsError(SOURCE, "--out", str(out), f"must end in {' or '.join(OUT_SUFFIXES)} "
                            "(the format is chosen by the suffix)")
    if not out.parent.is_dir():
        missing = next((p for p in reversed([out.parent, *out.parent.parents])
                        if p.exists() and not p.is_dir()), None)
        raise SettingsError(SOURCE, "--out", str(out), f"{str(missing)!r} is a file, not a "
                            "folder" if missing is not None else f"its folder "
                            f"{str(out.parent)!r} does not exist")
    writers = ("pandas", "pyarrow") if out.suffix == ".parquet" else ("pandas",)
    for package in writers:
        if importlib.util.find_spec(package) is None:
            raise SettingsError(SOURCE, "--out", str(out), "saving " +
                                needs_extra(package, EXTRA_OF[package]))
    from redysim.harness.store import check_writable

    check_writable(out.parent, what=f"folder of {out.name}")
    summary = out.with_suffix(".summary" + out.suffix)
    for path in (out, summary):  # a file there that may not be written is not replaced
        if path.exists() and not os.access(path, os.W_OK):
            raise SettingsError(SOURCE, "--out", str(out), f"{str(path)!r} exists and may not "
                                "be written (read-only): it is kept; give another --out, or "
                                "make it writable")


def needs_extra(package: str, extra: str) -> str:
    """The end of a refusal for want of ``package``: which extra installs it, and how."""
    return (f"needs {package}, which is not installed: it comes with the {extra!r} extra, "
            f"pip install 'redysim[{extra}]'")


def _check_engine(engine: str) -> None:
    """A reference engine's package must be installed (the 'engines' extra): checked before the
    run, which would otherwise fail for want of it (a package installed but broken fails the run,
    with the reason). Not imported here: its import belongs to the engine's build time."""
    from redysim import references

    cls = references.get(engine)
    if importlib.util.find_spec(cls.module or cls.package) is None:
        raise SettingsError(SOURCE, "--engine", engine, f"the engine {engine} " +
                            needs_extra(cls.package, "engines"))


def _save(df, path: Path) -> None:
    from redysim.harness.store import write_csv_atomic, write_parquet_atomic

    (write_csv_atomic if path.suffix == ".csv" else write_parquet_atomic)(df, path)


MAX_TO_GO_S = 1e7  # s (116 days): a longer time to go is shown as unknown, not as a number


def time_to_go(seconds: float) -> str:
    """A time to go as people read it: "about 40 s", "about 12 min", "about 5.3 h", "about 9.1
    days"; "unknown (more than 116 days at this rate)" beyond :data:`MAX_TO_GO_S` (a rate
    measured over a few seconds says nothing of years, and never a 200-digit number)."""
    if not seconds >= 0:  # NaN: no rate yet
        return "unknown"
    if seconds > MAX_TO_GO_S:
        return f"unknown (more than {MAX_TO_GO_S / 86400:.0f} days at this rate)"
    for unit, size, digits in (("days", 86400.0, 1), ("h", 3600.0, 1), ("min", 60.0, 0)):
        if seconds >= 2 * size:
            return f"about {seconds / size:.{digits}f} {unit}"
    return f"about {seconds:.0f} s"


def _report_progress(t: float, t_end: float, steps: int, wall: float) -> None:
    """A progress line on stderr: simulated time, steps, wall time, time to go."""
    rate = t / wall if wall > 0 else 0.0
    to_go = f", time to go {time_to_go((t_end - t) / rate)}" if rate > 0 else ""
    print(f"{PROG}: t = {t:.6g} of {t_end:g} s, {steps:,} steps, {wall:,.0f} s{to_go}",
          file=sys.stderr, flush=True)


FLAG_USES = {"links": "coarse-grains a rope case's chain",
             "precision": "sets the arithmetic of a rope case's run (robot and linkage files "
                          "run in float64)",
             "mimic": "applies to a URDF's <mimic> joints",
             "floating": "gives the root body of {floating} a free joint"}


def file_kind(name: str) -> FileKind:
    """The kind of file ``redysim simulate``, ``info``, ``advise`` or ``compare`` is given
    (:func:`redysim.io.kinds.kind_of`): a built-in scenario's name is a scenario file's, any
    other name a rope case's."""
    from redysim.io.scenarios import scenario_path

    robot = name.startswith(ROBOT_DATA)  # example-robot-data:NAME, a file of the package
    p = scenario_path(name) if robot or not Path(name).suffix else None
    return kind_of(p if p is not None else name)


# the command-line flag of each model option (redysim.io.kinds.FileKind.options)
OPTION_FLAGS = {"floating": "--floating", "mimic": "--mimic", "lock": "--lock"}
ROPE_FLAGS = ("--links", "--precision")  # a rope case's (FileKind.rope)
FILE_ARGUMENT = ("a rope case's or a built-in scenario's name, or a file of any kind listed "
                 "under files, above")


def kinds_taking(option: str) -> str:
    """The kinds of file that take a model option, as a phrase: "a URDF, an MJCF file or a
    protein file"."""
    return either(k.noun for k in KINDS if option in k.options)


def files_help() -> str:
    """The kinds of file the commands take (:data:`redysim.io.kinds.KINDS`, in the order they
    are told apart), how each is told, and the model flags each takes: the end of the help of
    simulate, info and compare."""
    lines = ["files (the first kind that fits; the flags each takes):"]
    for k in KINDS:
        flags = [OPTION_FLAGS[o] for o in k.options if o in OPTION_FLAGS]
        flags += ROPE_FLAGS if k.rope else ()
        lines.append(f"  {k.noun:<16} {k.files:<52} {' '.join(flags)}".rstrip())
    return "\n".join(lines)


def _refuse_unused_flags(args: argparse.Namespace, kind: FileKind) -> None:
    """A flag that this kind of file would ignore is refused, by name; and so is a joint locked
    twice."""
    given = {"links": getattr(args, "links", None) is not None,
             "precision": getattr(args, "precision", None) not in (None, "float64"),
             "mimic": args.mimic is not None, "floating": args.floating}
    uses = {"links": kind.rope, "precision": kind.rope, "mimic": "mimic" in kind.options,
            "floating": "floating" in kind.options}
    for flag in given:
        if given[flag] and not uses[flag]:
            value = getattr(args, flag)
            use = FLAG_USES[flag].format(floating=kinds_taking("floating"))
            raise SettingsError(SOURCE, f"--{flag}", None if value is True else value,
                                f"{use}; {kind.noun} has no use for it")
    seen: dict[str, list[float]] = {}
    for name, values in getattr(args, "lock", []):
        if name in seen:
            raise SettingsError(SOURCE, "--lock", name,
                                f"the joint {name!r} is locked twice (at "
                                f"{','.join(f'{x:g}' for x in seen[name])} and at "
                                f"{','.join(f'{x:g}' for x in values)}): give each joint once")
        seen[name] = values


def model_options(args: argparse.Namespace, kind: FileKind) -> dict:
    """The model options the command line gives (--floating, --mimic, --lock) as the kind of
    file takes them (:attr:`FileKind.options <redysim.io.kinds.FileKind.options>`); a flag it
    has no use for, or a joint locked twice, refused by name."""
    _refuse_unused_flags(args, kind)
    lock = dict(getattr(args, "lock", []))
    if lock and "lock" not in kind.options:
        raise SettingsError(SOURCE, "--lock", next(iter(lock)), f"locks a joint of "
                            f"{kinds_taking('lock')}; "
                            f"{kind.fixed or kind.noun + ' has no use for it'}")
    options = {"floating": args.floating or None, "mimic": args.mimic, "lock": lock or None}
    return {k: v for k, v in options.items() if v is not None and k in kind.options}


def cmd_simulate(args: argparse.Namespace) -> int:
    """``redysim simulate``: one run of any scenario (a rope case, a scenario file, a robot or
    linkage file) by the core or an engine, through the harness's run
    (:func:`redysim.harness.run.execute`), printed."""
    from redysim.harness.spec import CORE, RunSpec
    from redysim.io.scenarios import load_scenario

    kind = file_kind(args.case)
    options = model_options(args, kind)
    scn = load_scenario(args.case, options=options)  # a bad file is bad input (exit 2)
    spec = RunSpec(case=args.case, engine=args.engine, method=args.method,
                   integrator=args.integrator or "", rtol=args.rtol or 0.0,
                   atol=args.atol or 0.0, h=args.h or 0.0,
                   t_end=args.t_end or 0.0, sample=args.sample or 0.0,
                   max_cpu_s=args.max_cpu or 0.0, links=args.links or 0,
                   precision=args.precision or "float64").with_options(**options)
    spec.resolved(scn, source=SOURCE, names=FLAGS)  # bad settings: exit 2, naming the flag
    if args.engine != CORE:
        _check_engine(args.engine)
    if args.out is not None:
        _check_out(args.out)
    from redysim.harness.run import execute

    if not kind.rope:
        print_scenario(scn, args.case)
    states = args.out is not None and not kind.rope
    res = execute(spec, progress=_report_progress, max_wall_s=args.max_wall, states=states)
    print_run(res.summary, res.rows)
    if args.out is not None:
        import pandas as pd

        samples = res.samples
        if states and res.states is not None and getattr(res.states, "ndim", 0) == 2 \
                and len(res.states):  # (a run that failed before its first sample has none)
            m = scn.model
            cols = {**{f"q{i}": res.states[:, i] for i in range(m.n_q)},
                    **{f"v{i}": res.states[:, m.n_q + i] for i in range(m.n_v)}}
            samples = pd.concat([samples, pd.DataFrame(cols)], axis=1)
        summary_path = args.out.with_suffix(".summary" + args.out.suffix)
        _save(samples, args.out)
        _save(pd.DataFrame([res.summary]), summary_path)
        what = "samples" + (": t, path, energy, delta_M, COM, momentum, q, v" if states else "")
        print(f"saved: {args.out} ({what}), {summary_path} (summary)")
    return _exit_code(res.summary["status"], res.summary["reason"])


def print_scenario(scn, given: str) -> None:
    """A scenario's model as a few lines: bodies, coordinates, mass, base, loops, and what its
    file holds that the model does not (``Model.notes``: never dropped in silence)."""
    m = scn.model
    base = "floating base" if "free" in m.joint_types else "fixed base"
    print(f"{m.name}   ({given}: {m.n_bodies} bodies, n_q = {m.n_q}, n_v = {m.n_v}, "
          f"{m.total_mass:.6g} kg, {base})")
    print(f"  scenario      {scn.description or scn.name}; observed: {', '.join(scn.observe)}")
    if m.cuts:
        from redysim.algorithms.loops import ClosedLoops

        loops = ClosedLoops(m)
        print(f"  loops         {len(m.cuts)} cut joint{'s' if len(m.cuts) > 1 else ''}, "
              f"{loops.m} equations")
    if m.couplings:
        print(f"  couplings     {len(m.couplings)} (mimic joints; {m.n_v - len(m.couplings)} "
              "DOF move): " + ", ".join(f"{c.follower} = {c.multiplier:g} * {c.leader} + "
                                        f"{c.offset:g}" for c in m.couplings[:4])
              + (", ..." if len(m.couplings) > 4 else ""))
    if m.notes:
        print("  dropped       from the file, not simulated (Model.notes):")
        for note in m.notes:
            print(f"    {note}")


def _exit_code(status: str, reason: str) -> int:
    """EXIT_OK, EXIT_STOPPED (your --max-wall: a note on stderr) or EXIT_RUN_FAILED (the
    reason on stderr)."""
    if status == "ok":
        return EXIT_OK
    if status == "stopped":
        print(f"{PROG}: run stopped: {reason}", file=sys.stderr)
        return EXIT_STOPPED
    print(f"{PROG}: run failed: {reason}", file=sys.stderr)
    return EXIT_RUN_FAILED


def print_run(summary: dict, samples: list[tuple]) -> None:
    """A run's summary and its samples (t, delta_M, the observed path's position, the centre
    of mass) as a readable table; ``samples``: one tuple per sample, in
    :data:`redysim.harness.run.SAMPLE_COLUMNS` order."""
    from redysim.harness.run import SAMPLE_COLUMNS

    s = summary
    frame = s.get("frame") or "tip"
    print(f"{s['label']}   (run {s['run_id']}, {s['n_dof']} DOF)")
    print(f"  status        {s['status']}{': ' + s['reason'] if s['reason'] else ''}")
    print(f"  E(0)          {s['E0']:.6f} J")
    rejected = "rejections not reported" if s["rejected"] < 0 else f"{s['rejected']} rejected"
    calls = ("RHS calls not reported by the engine" if s["nfev"] < 0 else
             f"{s['nfev']} RHS calls")
    print(f"  steps         {s['steps']} ({rejected}), {calls}")
    print(f"  CPU           {s['cpu_s']:.3f} s (wall {s['wall_s']:.3f} s; JIT compile or "
          f"cache load {s['jit_s']:.3f} s, timed apart)")
    print(f"  |delta_M|     average {s['avg_abs_delta_M']:.3e} J/kg, "
          f"max {s['max_abs_delta_M']:.3e} J/kg over {s['n_samples']} samples")
    if s.get("quaternion_error"):
        print(f"  quaternion    largest | |q| - 1 | after a step, before its projection: "
              f"{s['quaternion_error']:.1e}")
    if not math.isnan(s.get("max_loop_force", math.nan)):
        print(f"  loops         largest residual after a step, before its projection: "
              f"{s['residual_q']:.1e} m, {s['residual_v']:.1e} m/s; largest loop force "
              f"{s['max_loop_force']:.4g} N")
        if not math.isnan(s.get("near_change_point", math.nan)):
            print(f"  change point  the motion passed near one at t = "
                  f"{s['near_change_point']:.6g} s (a configuration where the mechanism can "
                  "switch branches: check the branch it left on)")
    if not math.isnan(s["max_tip_err"]):  # a reference solution exists
        print(f"  {frame[:12]:<12}  path error {s['max_tip_err']:.3e} m (max over the samples, "
              f"against the reference solution)")
    if len(samples):
        head = frame if len(frame) <= 10 else frame[:9] + "~"
        print(f"\n{'t [s]':>10} {'delta_M [J/kg]':>15} {head + ' x [m]':>16} "
              f"{head + ' y [m]':>16} {head + ' z [m]':>16} {'COM x [m]':>12} "
              f"{'COM y [m]':>12} {'COM z [m]':>12}")
        shown = [SAMPLE_COLUMNS.index(c) for c in ("t", "delta_M", "tip_x", "tip_y", "tip_z",
                                                   "com_x", "com_y", "com_z")]
        for row in samples:
            t, dM, x, y, z, cx, cy, cz = (row[i] for i in shown)
            print(f"{t:10.4f} {dM:15.3e} {x:16.6f} {y:16.6f} {z:16.6f} {cx:12.6f} {cy:12.6f} "
                  f"{cz:12.6f}")


def cmd_sweep(args: argparse.Namespace) -> int:
    """``redysim sweep``: every run of a sweep file, resumable."""
    from redysim.harness.store import writable
    from redysim.harness.sweep import RUNS_FILE, SAMPLES_FILE, load_sweep, run_sweep

    if args.dask and args.workers is not None:
        raise SettingsError(SOURCE, "--workers", args.workers, "sets the local process pool; "
                            "with --dask the cluster's own workers run the runs")
    sweep = load_sweep(args.sweep_file)
    from redysim.harness.reference import results_dir

    out = args.out or results_dir() / "sweeps" / sweep.name
    if out.exists() and not out.is_dir():
        raise SettingsError(SOURCE, "--out", str(out), "is a file; a sweep's results go in a "
                            "folder")
    # (a folder it cannot write: refused by run_sweep before any run, unless finished there)
    where = f"Dask ({args.dask})" if args.dask else "a local process pool"
    if sweep.description:
        print(f"{sweep.name}: {sweep.description}")

    def announce(n_runs: int, n_done: int) -> None:  # (counted after each file was checked)
        rest = (f"running the rest on {where}" if writable(out) else
                "a folder it cannot write: read as it is if every run is finished there")
        print(f"{sweep.name}: {n_runs} runs, {n_done} already done in {out}; {rest}",
              flush=True)

    runs = run_sweep(sweep.specs, out, name=sweep.name, workers=args.workers, dask=args.dask,
                     progress=args.progress, reference=sweep.reference,
                     retry_failed=args.retry_failed, on_plan=announce)
    failed = runs[runs["status"] != "ok"] if len(runs) else runs
    print(f"{len(runs)} runs: {len(runs) - len(failed)} ok, {len(failed)} failed, "
          f"{runs.attrs.get('ran', 0)} run by this sweep -> {out / RUNS_FILE}, "
          f"{out / SAMPLES_FILE}")
    for r in failed.head(MAX_FAILED_SHOWN).itertuples(index=False):
        print(f"  failed: {r.label}: {r.reason}")
    if len(failed) > MAX_FAILED_SHOWN:
        print(f"  ... and {len(failed) - MAX_FAILED_SHOWN} more (see {out / RUNS_FILE})")
    return EXIT_RUN_FAILED if len(failed) else EXIT_OK


INFO_MAX_INDENT = 12  # redysim info: indentation levels shown


def cmd_info(args: argparse.Namespace) -> int:
    """``redysim info``: the model's tree, one line per body, children indented under parents:
    the model ``redysim simulate`` runs, of a file of any kind (or a case's or scenario's
    name)."""
    from redysim.io.scenarios import load_scenario

    options = model_options(args, file_kind(args.model))
    model = load_scenario(args.model, options=options).model
    print(f"{model.name}: {model.n_bodies} bodies, n_q = {model.n_q}, n_v = {model.n_v}, "
          f"mass {model.total_mass:.6g} kg, gravity {tuple(float(g) for g in model.gravity)}")
    children: dict[int, list[int]] = {}
    for k, p in enumerate(model.parent):
        children.setdefault(int(p), []).append(k)
    # children indented under parents, to INFO_MAX_INDENT levels (deeper bodies: their depth
    # in brackets, so a chain of 20,000 bodies does not print 20,000-deep indentation)
    deep = _depth(model) > INFO_MAX_INDENT
    width = max(map(len, model.body_names)) + 2 * min(_depth(model), INFO_MAX_INDENT) + \
        (8 if deep else 0)
    stack = [(root, 0) for root in reversed(children.get(-1, []))]
    while stack:  # depth first, parents before children (no recursion: chains are deep)
        k, depth = stack.pop()
        axes = ", ".join(_axis_text(model, j) for j in range(model.joint_voff[k],
                                                            model.joint_voff[k + 1]))
        label = f"{'  ' * min(depth, INFO_MAX_INDENT)}" + \
            (f"[{depth}] " if depth > INFO_MAX_INDENT else "") + model.body_names[k]
        print(f"  {label:<{width}}  {model.joint_types[k]:<5} {model.joint_names[k]} "
              f"[{axes}]  m = {model.mass[k]:.6g} kg")
        stack.extend((c, depth + 1) for c in reversed(children.get(k, [])))
    for name, (body, point) in model.frames.items():
        print(f"  frame {name}: on {model.body_names[body]} at {tuple(float(x) for x in point)}")
    for c in model.couplings:
        print(f"  coupling: {c.follower} = {c.multiplier:g} * {c.leader} + {c.offset:g}")
    for note in model.notes:
        print(f"  note: {note}")
    for c in model.cuts:
        where_b = "the world" if c.body_b < 0 else model.body_names[c.body_b]
        print(f"  cut joint {c.name}: {c.kind}, {model.body_names[c.body_a]} at "
              f"{tuple(float(x) for x in c.point_a)} to {where_b} at "
              f"{tuple(float(x) for x in c.point_b)}")
    return EXIT_OK


def _depth(model) -> int:
    depth = [0] * model.n_bodies
    for k, p in enumerate(model.parent):
        depth[k] = 0 if p < 0 else depth[p] + 1
    return max(depth, default=0)


def _axis_text(model, j: int) -> str:
    kind = ("R", "P", "ball")[int(model.dof_kind[j])]
    u = model.dof_u[j]
    names = {(1, 0, 0): "x", (0, 1, 0): "y", (0, 0, 1): "z", (-1, 0, 0): "-x", (0, -1, 0): "-y",
             (0, 0, -1): "-z"}
    key = tuple(int(x) if x in (-1.0, 0.0, 1.0) else None for x in u)
    return f"{kind} {names.get(key, '(' + ', '.join(f'{x:.4g}' for x in u) + ')')}"


def cmd_advise(args: argparse.Namespace) -> int:
    """``redysim advise``: the coarsest model and cheapest setting that meet a tolerance."""
    from redysim.harness import refine

    if args.scene == "hanging":
        for flag, value in (("--tip-tol", args.tip_tol), ("--results", args.results)):
            if value is not None:
                raise SettingsError(SOURCE, flag, str(value) if flag == "--results" else value,
                                    "the hanging chain's advice is computed, from --modes and "
                                    "--freq-tol: it has no use for it")
        if args.modes is None or args.freq_tol is None:
            raise SettingsError(SOURCE, "--modes/--freq-tol", None,
                                "the hanging chain's advice needs both (e.g. --modes 3 "
                                "--freq-tol 0.01)")
        finest = refine.modes_available()
        if args.modes > finest:
            raise SettingsError(SOURCE, "--modes", args.modes,
                                f"the study's finest model, {finest} links, has {finest} modes "
                                f"(a chain of n links has n): asking for {args.modes} needs a "
                                f"model of at least {args.modes} links; ask for at most "
                                f"{finest}")
        study = refine.modes_study(m=args.modes)
        a = refine.advise_modes(study, args.modes, args.freq_tol)
        if a is None:
            last = study["levels"][-1]
            print(f"no model up to {last['links']} links has its first {args.modes} "
                  f"frequencies within {args.freq_tol:g} (the finest: "
                  f"{max(last['rel_err'][:args.modes]):.3g})")
            return EXIT_RUN_FAILED
        print(f"hanging chain: {a['links']} links have the first {args.modes} frequencies within "
              f"{args.freq_tol:g} of the continuum's (worst {a['max_rel_err']:.3g})")
        fewer = [row["links"] for row in study["levels"] if row["links"] < args.modes]
        if fewer:
            print(f"  (the coarser models, {', '.join(map(str, fewer))} links, have fewer than "
                  f"{args.modes} modes: a chain of n links has n)")
        return EXIT_OK
    if args.modes is not None or args.freq_tol is not None:  # (said first: --tip-tol's absence
        # is then no news)
        raise SettingsError(SOURCE, "--modes/--freq-tol",
                            args.modes if args.modes is not None else args.freq_tol,
                            f"apply to the hanging chain only (advise hanging ...); "
                            f"{args.scene}'s advice is for a tip-path tolerance: --tip-tol M")
    if args.tip_tol is None:
        raise SettingsError(SOURCE, "--tip-tol", None, "missing: the tip-path tolerance [m]")
    if args.scene not in refine.SCENES and args.results is not None:
        raise SettingsError(SOURCE, "--results", str(args.results), f"says where the studies "
                            f"of {', '.join(refine.SCENES)} are; a folder given as SCENE is "
                            "read as it is")
    own = (args.t_end, args.out, args.workers, args.observe)
    if args.scene not in refine.SCENES and not (Path(args.scene) / "runs").is_dir():
        return _advise_own(args)
    if any(v is not None for v in own):
        raise SettingsError(SOURCE, "--t-end/--out/--workers/--observe",
                            next(v for v in own if v is not None),
                            "set a rope case's own study; a finished study is read as it is")
    from redysim.harness.reference import results_dir

    folder = (refine.study_folder(args.results or results_dir(), args.scene)
              if args.scene in refine.SCENES else Path(args.scene))
    try:
        study = refine.load_study(folder, args.scene)
    except refine.StudyError as exc:
        raise SettingsError(SOURCE, "SCENE", args.scene, str(exc)) from None
    a = refine.advise(study, args.tip_tol)
    ref = study.reference
    print(f"{study.case}: reference {int(ref['n_links'])} links, {ref['integrator']} rtol "
          f"{ref['rtol']:g} ({len(study.runs)} runs measured)")
    if a is None:
        best = study.runs["tip_err"].min()
        print(f"no measured run met {args.tip_tol:g} m (the best: {best:.3g} m): tighten the "
              "study (more links, tighter tolerances) or ask less")
        return EXIT_RUN_FAILED
    print(f"advice for a tip path within {a.tol:g} m: {a.links} links, {a.integrator} rtol "
          f"{a.rtol:g} (atol {a.rtol * 1e-2:g})")
    print(f"  measured: tip error {a.tip_err:.3g} m, CPU {a.cpu_s:.3g} s, {a.steps:,} steps "
          f"({a.candidates} runs met the tolerance)")
    _print_tied(a)
    if math.isfinite(a.finest_cpu_s):
        print(f"  the finest model ({a.finest_links} links) meets it at rtol {a.finest_rtol:g} "
              f"in {a.finest_cpu_s:.3g} s of CPU: {a.saved:.0f}x the advised run's")
    else:
        print(f"  no run of the finest model ({a.finest_links} links) met it")
    case = os.path.relpath(study.case) if study.case.startswith(os.getcwd() + os.sep) \
        else study.case
    print(f"  run it: redysim simulate {case} --links {a.links} --integrator {a.integrator} "
          f"--rtol {a.rtol:g} --atol {a.rtol * 1e-2:g} --t-end {study.reference['t_end']:g}")
    return EXIT_OK


def _print_tied(a) -> None:
    """advise's verdict: the runs whose measured cost cannot be told from the advised run's."""
    if a.indistinguishable:
        shown = list(a.indistinguishable[:4]) + (["..."] if len(a.indistinguishable) > 4 else [])
        print(f"  indistinguishable in cost (within the measurement's noise) from "
              f"{len(a.indistinguishable)} other run{'s' if len(a.indistinguishable) > 1 else ''}"
              f": {', '.join(shown)}; the advice is the one of least work among them")


def _advise_own(args: argparse.Namespace) -> int:
    """``redysim advise CASE --tip-tol M``: a rope case's own study (refine.own_study)."""
    from redysim.harness import refine
    from redysim.io.cases import case_path

    scene = args.scene
    if args.results is not None:
        raise SettingsError(SOURCE, "--results", str(args.results), "says where the studies "
                            f"of {', '.join(refine.SCENES)} are; a rope case's study goes to "
                            "--out")
    if not file_kind(scene).rope:  # a robot's (or linkage's, protein's) scenario
        return _advise_robot(args)
    if args.observe is not None:
        raise SettingsError(SOURCE, "--observe", args.observe, "a rope's study follows its tip; "
                            "--observe names a robot scenario's frame")
    try:
        path = case_path(scene)
    except FileNotFoundError as exc:
        raise SettingsError(SOURCE, "SCENE", scene, f"is no study ({', '.join(refine.SCENES)}, "
                            f"hanging), no study's folder (no runs/ folder there) and no rope "
                            f"case: {exc}") from None
    from redysim.harness.reference import results_dir

    out = args.out or results_dir() / "advise" / path.stem
    st = refine.own_study(path, args.tip_tol, out, t_end=args.t_end or 0.0,
                          workers=args.workers, progress=not args.no_progress)
    conv, ref = st.conv, st.study.reference
    print(f"{path.stem}: {int(ref['n_links'])} links over {float(ref['t_end']):g} s; reference "
          f"{ref['integrator']} rtol {ref['rtol']:g} ({ref['cpu_s']:.3g} s CPU)")
    print("  model error (tip path, max over the samples) at "
          + ", ".join(f"{d['links']} links {d['tip_err']:.2g} m" for d in conv["levels"])
          + ("; local orders " + ", ".join(f"{o:.2f}" for o in st.orders) if st.orders
             else "; one coarser model: no local order"))
    if st.searched:
        print("  the rope rebuilt between those counts: "
              + ", ".join(f"{d['links']} links {d['tip_err']:.2g} m" for d in st.searched))
    for note in st.notes:
        print(f"  {note}")
    if not st.converges or st.advice is None:
        if st.converges and not st.notes:
            print(f"  no measured run met {st.tol:g} m")
        return EXIT_RUN_FAILED
    print(f"  your model's own error: {st.ref_error:.2g} m ({st.ref_error_how})"
          if math.isfinite(st.ref_error) else f"  your model's own error: {st.ref_error_how}")
    a = st.advice
    print(f"advice for a tip path within {st.tol:g} m: {a.links} links, {a.integrator} rtol "
          f"{a.rtol:g} (atol {a.rtol * 1e-2:g})")
    print(f"  measured: tip error {a.tip_err:.3g} m against your model"
          + (f" (+ its own {st.ref_error:.2g} m)" if math.isfinite(st.ref_error) else "")
          + f", CPU {a.cpu_s:.3g} s, {a.steps:,} steps ({a.candidates} runs met it)")
    _print_tied(a)
    if math.isfinite(a.finest_cpu_s):
        print(f"  your model ({a.finest_links} links) meets it at rtol {a.finest_rtol:g} in "
              f"{a.finest_cpu_s:.3g} s of CPU: {a.saved:.1f}x the advised run's")
    if st.check is not None:
        c = st.check
        print(f"  checked: run again (the Python stepping loop), tip error {c['tip_err']:.3g} m "
              f"against your model, {c['cpu_s']:.3g} s CPU, {c['steps']:,} steps")
    case = os.path.relpath(path) if str(path).startswith(os.getcwd() + os.sep) else str(path)
    print(f"  run it: redysim simulate {case} --links {a.links} --integrator {a.integrator} "
          f"--rtol {a.rtol:g} --atol {a.rtol * 1e-2:g} --t-end {float(ref['t_end']):g}")
    return EXIT_OK


def _advise_robot(args: argparse.Namespace) -> int:
    """``redysim advise SCENARIO --tip-tol M [--observe FRAME]``: the joints a robot's scene can
    do without (redysim.harness.reduce)."""
    from redysim.harness import reduce

    if args.workers is not None:
        raise SettingsError(SOURCE, "--workers", args.workers, "a robot's reductions run one "
                            "after another (each set is decided by the runs before it)")
    from redysim.harness.reference import results_dir

    scene = args.scene.removeprefix(ROBOT_DATA)  # a robot by name: its name, no colon
    name = Path(scene).stem if Path(scene).suffix or scene != args.scene else scene
    out = args.out or results_dir() / "advise" / name
    r = reduce.reductions(args.scene, args.tip_tol, out, frame=args.observe,
                          t_end=args.t_end or 0.0)
    print(f"{r.scenario}: {r.full_dof} DOF; the path of {r.frame!r} over {r.t_end:g} s, each "
          f"model by {reduce.REFERENCE[0]} rtol {reduce.REFERENCE[1]:g}")
    shown = (r.candidates if len(r.candidates) <= 12
             else r.candidates[:8] + [("...", math.nan)] + r.candidates[-3:])
    print("  each joint locked alone, least effect first: "
          + ", ".join(n if n == "..." else f"{n} {e:.2g} m" for n, e in shown))
    for note in r.notes:
        print(f"  {note}")
    if not r.locked:
        print(f"no joint can be locked within {r.tol:g} m (the least effect: "
              f"{r.candidates[0][0]} {r.candidates[0][1]:.2g} m)")
        return EXIT_RUN_FAILED
    p = r.practical
    full, red = p["full"], p["reduced"]
    print(f"advice for a path within {r.tol:g} m: lock {len(r.locked)} joints (their bodies "
          f"fused), {r.full_dof} -> {r.reduced_dof} DOF: {', '.join(r.locked)}")
    print(f"  measured: path error {r.error:.3g} m (each set run, never summed); at "
          f"{reduce.PRACTICAL[0]} rtol {reduce.PRACTICAL[1]:g} the reduced model's error is "
          f"{p['error']:.3g} m, {red['nfev']:,} RHS calls of {red['dof']} DOF in "
          f"{red['cpu_s']:.3g} s of CPU against the full model's {full['nfev']:,} of "
          f"{full['dof']} DOF in {full['cpu_s']:.3g} s")
    if "verdict" in p:
        from redysim.harness.cost import cost_of

        rc, fc = cost_of(red), cost_of(full)
        gain = 1.0 - rc.value / fc.value if fc.value > 0 else math.nan
        print(f"  cost of the integration (least of {rc.repeats} and {fc.repeats} runs, "
              f"sampling excluded): {rc.value:.3g} s against {fc.value:.3g} s, "
              f"{gain:+.0%} saved: "
              + ("indistinguishable, within the measurement's noise: locking saves no "
                 "measurable CPU here"
                 if p["verdict"] == "indistinguishable" else
                 f"the reduced model is {p['verdict']}"))
    if r.file is not None:
        print(f"  checked: the reduced scenario file, run on its own, follows the advised path "
              f"to {r.file_check:.2g} m")
        print(f"  run it: redysim simulate {r.file}")
    return EXIT_OK


def cmd_engines(args: argparse.Namespace) -> int:
    """``redysim engines``: each reference engine, whether it is installed (its version), and
    its own integrators (name, fixed step or tolerances, what the engine calls it)."""
    from redysim import references

    for name, cls in references.ENGINES.items():
        version = cls.package_version() if cls.available() else "not installed"
        print(f"{name}   ({cls.package} {version})")
        if not cls.integrators:
            print("  no integrator of its own: run it through redysim's (--integrator ode45)")
        for own, info in cls.integrators.items():
            takes = "rtol, atol" if info.adaptive else "h"
            default = " (default)" if own == cls.integrator else ""
            print(f"  native:{own:<24} takes {takes:<10} {info.what}{default}")
    return EXIT_OK


def cmd_cases(args: argparse.Namespace) -> int:
    """``redysim cases``: names and descriptions; a case file that does not load is listed with
    the reason (and the exit code is 1), the others still are."""
    names = list_cases()
    width = max(map(len, names), default=0)
    bad = 0
    for name in names:
        try:
            description = load_case(name).description
        except (RedysimError, OSError) as exc:
            description = f"(does not load: {exc})"
            bad += 1
        print(f"{name:<{width}}  {description}")
    if bad:
        print(f"{PROG}: {bad} case file{'s' if bad > 1 else ''} in {CASES_DIR} did not load",
              file=sys.stderr)
    return EXIT_RUN_FAILED if bad else EXIT_OK


def cmd_robots(args: argparse.Namespace) -> int:
    """``redysim robots``: example-robot-data's model files by name (with their paths in the
    package; a file without a name by its path), then the built-in scenarios' names."""
    from redysim.io.robots import PACKAGE, robots
    from redysim.io.scenarios import list_scenarios

    table = robots()
    if table:
        print(f"{PACKAGE} (give {ROBOT_DATA}NAME, or {ROBOT_DATA}PATH for those without a name):")
        width = max(len(ROBOT_DATA + n) for n, _ in table)
        for name, rel in table:
            print(f"  {ROBOT_DATA + name if name else '':<{width}}  {rel}")
    else:
        print(f"{PACKAGE} is not installed (pip install {PACKAGE}, or redysim[test]): no robots "
              "by name")
    print("built-in scenarios (give the name; redysim simulate NAME):")
    print("  " + " ".join(list_scenarios()))
    return EXIT_OK


def main(argv: list[str] | None = None, *, extra: Sequence[Callable] = ()) -> int:
    """The commands of the harness (``extra``: those of the layer above, see
    :func:`build_parser`); returns the exit code. The ``redysim`` console script is
    :func:`redysim.reports.commands.main`, which adds ``compare``."""
    args = build_parser(extra).parse_args(argv)
    try:
        return args.func(args)
    except (RedysimError, FileNotFoundError) as exc:  # bad input: a case, a sweep file, a path
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except ModuleNotFoundError as exc:  # an optional package: the extra that installs it
        package = (exc.name or "").partition(".")[0]
        if package not in EXTRA_OF:
            raise
        print(f"{PROG}: error: {PROG} {args.command} {needs_extra(package, EXTRA_OF[package])}",
              file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print(f"{PROG}: interrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:  # the reader went away (redysim ... | head): stop quietly
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())  # Python's own flush at exit would fail again
        return EXIT_OK


if __name__ == "__main__":
    sys.exit(main())
