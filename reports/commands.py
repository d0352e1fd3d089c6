"""The ``redysim`` console script: the harness's commands (:mod:`redysim.harness.cli`) and the
one that renders a page, ``redysim compare`` (:mod:`redysim.reports.compare`).

The harness never imports the reports (tests/test_layout.py); the command line is the top of the
stack, so it lives here, above both, and hands the harness's parser the commands of this layer.
Importing this module imports no optional package: ``compare`` imports what it needs when it
runs, and refuses, naming the extra, when that is missing.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
from pathlib import Path

from redysim.harness.cli import (
    EXIT_OK,
    FILE_ARGUMENT,
    _lock,
    _model_flags,
    _whole,
    file_kind,
    files_help,
    kinds_taking,
    model_options,
    positive,
)
from redysim.harness.cli import main as harness_main

COMPARE_HELP = """\
Compare your model in every engine with every integrator, against a reference solution.

It builds the model in every reference engine and checks single-state agreement with the core
(qdd, GIM, bias, energy at seeded random states), then runs the scenario's passive motion: the
core with its integrators, every engine through ode45 and with each of its own integrators, over
a ladder of steps and tolerances, each measured against the reference solution (DOP853 at
1e-10, checked by SciPy's DOP853 at 1e-13). It writes compare.html and compare.pdf, opening
with the answer: for each accuracy, the engine and setting that was cheapest here, the core's
lead over the best engine and the engines that did not reach it; then the agreement, the
observed path's error and the energy drift over time, work against precision, every run with
each engine's configuration, and the advice per engine. The runs are cached: run it again and
only what changed runs.

examples:
  redysim compare example-robot-data:ur5
  redysim compare example-robot-data:talos_reduced --floating --t-end 0.5
  redysim compare cases/loops/jansen_leg.toml
  redysim compare UR5-FALL --engine mujoco --engine exudyn"""


def add_compare(sub) -> None:
    """Add ``redysim compare`` to the command's subparsers."""
    from redysim import references

    fmt = argparse.RawDescriptionHelpFormatter
    cmp_ = sub.add_parser("compare", description=f"{COMPARE_HELP}\n\n{files_help()}",
                          formatter_class=fmt,
                          help="your model in every engine with every integrator against a "
                               "reference: agreement, paths, drift, work-precision, advice "
                               "(an HTML page and a PDF)")
    cmp_.add_argument("model", metavar="MODEL", help=FILE_ARGUMENT)
    cmp_.add_argument("--t-end", type=positive, metavar="T",
                      help="horizon [s] (default: the scenario's; a model file's own: 1 s)")
    cmp_.add_argument("--out", type=Path, metavar="DIR",
                      help="where the runs and the page go (default: results/compare/<name>; "
                           "results/ is $REDYSIM_RESULTS when set)")
    cmp_.add_argument("--workers", type=_whole, metavar="N",
                      help="processes running the runs (default: the number of CPU cores)")
    cmp_.add_argument("--engine", dest="engines", action="append",
                      choices=tuple(references.ENGINES), metavar="E",
                      help="compare only these engines (repeat; default: every engine)")
    cmp_.add_argument("--no-progress", dest="progress", action="store_false",
                      help="no progress bar")
    _model_flags(cmp_)
    cmp_.add_argument("--lock", type=_lock, action="append", default=[], metavar="JOINT=VALUE",
                      help=f"{kinds_taking('lock')}: hold a joint at a coordinate; repeat "
                           "for more")
    cmp_.set_defaults(func=cmd_compare)


def cmd_compare(args: argparse.Namespace) -> int:
    """``redysim compare MODEL``: :func:`redysim.reports.compare.compare`."""
    from redysim.io.scenarios import load_scenario

    options = model_options(args, file_kind(args.model))
    scn = load_scenario(args.model, options=options)  # a bad file: exit 2, before any run
    for package in ("pandas", "pyarrow", "matplotlib", "jinja2", "reportlab"):
        if importlib.util.find_spec(package) is None:
            raise ModuleNotFoundError(name=package)
    from redysim.reports.compare import compare

    name = "".join(c if c.isalnum() or c in "-_." else "_" for c in scn.name)
    from redysim.harness.reference import results_dir

    out = args.out or results_dir() / "compare" / name
    from redysim.harness.store import check_writable

    check_writable(out, flag="--out" if args.out else None)  # before any engine runs
    html, pdf = compare(args.model, out, options=options, t_end=args.t_end or 0.0,
                        workers=args.workers, engines=args.engines, progress=args.progress,
                        log=lambda msg: print(msg, file=sys.stderr, flush=True))
    print(f"{html}\n{pdf}")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``redysim`` console script; returns the exit code."""
    return harness_main(argv, extra=(add_compare,))


if __name__ == "__main__":
    sys.exit(main())
