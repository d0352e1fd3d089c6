"""The ``redysim`` command: simulate one case, run a sweep file, list the cases.

A thin layer over :func:`harness.run.execute` and :mod:`harness.sweep`; the harness (pandas,
pyarrow, Dask) is imported only inside the commands that need it. Exit codes: 0 all runs ok,
1 a run failed, 2 bad usage or input (the message names what is wrong; no traceback).
"""

from __future__ import annotations

import argparse
import math
import sys
import tomllib
from pathlib import Path

from redysim.cases import CASES_DIR, list_cases, load_case
from redysim.errors import RedysimError
from redysim.integrate import FIXED_STEP, INTEGRATORS

PROG = "redysim"
EXIT_OK, EXIT_RUN_FAILED, EXIT_USAGE = 0, 1, 2
DEFAULT_SWEEP_ROOT = Path("results") / "sweeps"  # redysim sweep's --out default: <root>/<name>
MAX_FAILED_SHOWN = 20  # failed runs listed after a sweep

DESCRIPTION = """\
redysim: O(n) dynamics of very long serial chains (ReDySim: DeNOC + Reverse Gaussian
Elimination), with reference engines and a validation harness.

examples:
  redysim cases                                   # the chains of the paper
  redysim simulate RE-U125-L1 --t-end 0.1         # one run, printed
  redysim sweep sweeps/smoke.toml                 # a declared set of runs, saved as Parquet

`redysim COMMAND --help` explains each command."""

SIMULATE_HELP = """\
Simulate one case and print its summary: E(0), steps, rejected steps, RHS calls, CPU time, JIT
compile time (timed apart), average |delta_M| (energy drift per unit mass) and the tip position
at every sample. Horizon and sample interval default to the case file's.

examples:
  redysim simulate RE-U125-L1 --t-end 0.1 --sample 0.01
  redysim simulate STUDY-R3 --integrator rk4 --h 1e-3 --t-end 1
  redysim simulate RE-U125-L1 --engine mujoco --rtol 1e-6 --atol 1e-8 --out tip.parquet"""

SWEEP_HELP = """\
Run a sweep file: a TOML [sweep] table whose lists (cases, engines, methods, integrators, rtols,
h) multiply into runs; see sweeps/smoke.toml. Each finished run is saved at once under
OUT/runs/ and OUT/samples/; at the end everything is gathered into OUT/runs.parquet and
OUT/samples.parquet. Started again, a sweep skips the runs it has finished, so an interrupted
sweep (even a killed one) resumes where it stopped.

examples:
  redysim sweep sweeps/smoke.toml
  redysim sweep sweeps/work-precision-RE-U125-L1.toml --out results/wp --workers 2
  redysim sweep sweeps/smoke.toml --dask local           # a 2-worker Dask cluster on this machine
  redysim sweep big.toml --dask tcp://scheduler:8786     # an existing Dask cluster"""

CASES_HELP = """\
List the case files in cases/ (every chain of the paper) with their descriptions. Any of these
names, or the path of your own case file, can be given to `redysim simulate`.

example:
  redysim cases"""


def _number(minimum_exclusive: bool):
    """An argparse type: a float > 0 (``minimum_exclusive``) or >= 0."""
    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not (value > 0 if minimum_exclusive else value >= 0):
            raise argparse.ArgumentTypeError(
                f"{text!r} must be {'> 0' if minimum_exclusive else '>= 0'}")
        return value
    return parse


def _workers(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a whole number") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{text!r} must be at least 1")
    return value


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of every command."""
    from redysim.harness.spec import CORE, CORE_METHODS, NATIVE, RunSpec

    from redysim import references

    positive, nonnegative = _number(True), _number(False)
    fmt = argparse.RawDescriptionHelpFormatter
    ap = argparse.ArgumentParser(prog=PROG, description=DESCRIPTION, formatter_class=fmt)
    sub = ap.add_subparsers(dest="command", required=True, metavar="COMMAND")

    sim = sub.add_parser("simulate", description=SIMULATE_HELP, formatter_class=fmt,
                         help="run one case with one engine and integrator; print energy "
                              "drift and tip position")
    sim.add_argument("case", metavar="CASE",
                     help="a case name (see `redysim cases`) or the path of a case file")
    sim.add_argument("--engine", default=CORE, choices=(CORE, *references.ENGINES), metavar="E",
                     help=f"who computes qdd: {CORE} (the core) or a reference engine: "
                          f"{', '.join(references.ENGINES)} (default: {CORE})")
    sim.add_argument("--method", default=RunSpec.method, choices=CORE_METHODS, metavar="M",
                     help=f"the core's algorithm: {', '.join(CORE_METHODS)}; rge-a is O(n) "
                          f"(default: {RunSpec.method})")
    sim.add_argument("--integrator", default=RunSpec.integrator,
                     choices=(*INTEGRATORS, NATIVE), metavar="I",
                     help=f"{', '.join((*INTEGRATORS, NATIVE))}; adaptive ones take "
                          f"--rtol/--atol, rk4 and native (an engine's own stepper) take --h "
                          f"(default: {RunSpec.integrator})")
    sim.add_argument("--rtol", type=positive, metavar="R", default=RunSpec.rtol,
                     help=f"relative tolerance (default: {RunSpec.rtol:g})")
    sim.add_argument("--atol", type=positive, metavar="A", default=RunSpec.atol,
                     help=f"absolute tolerance (default: {RunSpec.atol:g})")
    sim.add_argument("--h", type=positive, metavar="H", default=RunSpec.h,
                     help="step [s] of a fixed-step integrator")
    sim.add_argument("--t-end", type=nonnegative, metavar="T", default=RunSpec.t_end,
                     help="horizon [s] (default: the case's)")
    sim.add_argument("--sample", type=nonnegative, metavar="S", default=RunSpec.sample,
                     help="sample interval [s] (default: the case's)")
    sim.add_argument("--out", type=Path, metavar="FILE.parquet",
                     help="also save the samples to FILE.parquet and the summary row to "
                          "FILE.summary.parquet")
    sim.set_defaults(func=cmd_simulate)

    sw = sub.add_parser("sweep", description=SWEEP_HELP, formatter_class=fmt,
                        help="run every run of a sweep file (cases x engines x integrators x "
                             "tolerances), resumable, on a process pool or Dask")
    sw.add_argument("sweep_file", metavar="SWEEP.toml", type=Path, help="the sweep file")
    sw.add_argument("--out", type=Path, metavar="DIR",
                    help=f"results folder (default: {DEFAULT_SWEEP_ROOT}/<sweep name>)")
    sw.add_argument("--workers", type=_workers, metavar="N",
                    help="processes of the local pool (default: the number of CPU cores; "
                         "ignored with --dask)")
    sw.add_argument("--dask", metavar="ADDRESS|local",
                    help="run on a Dask cluster: a scheduler address, or 'local' for a "
                         "2-worker cluster on this machine")
    sw.add_argument("--no-progress", dest="progress", action="store_false",
                    help="no progress bar")
    sw.set_defaults(func=cmd_sweep)

    cs = sub.add_parser("cases", description=CASES_HELP, formatter_class=fmt,
                        help="list the chains of the paper that come with redysim")
    cs.set_defaults(func=cmd_cases)
    return ap


# --------------------------------------------------------------------------- commands
def cmd_simulate(args: argparse.Namespace) -> int:
    """``redysim simulate``: one run, printed."""
    from redysim.harness.run import execute
    from redysim.harness.spec import NATIVE, RunSpec

    if args.case not in list_cases() and not Path(args.case).is_file():
        raise FileNotFoundError(f"no case named {args.case!r} and no such file; "
                                f"`{PROG} cases` lists the cases")
    load_case(args.case)  # a malformed case file is bad input (exit 2), not a failed run
    if args.integrator in (*FIXED_STEP, NATIVE) and not args.h:
        raise RedysimError(f"--integrator {args.integrator} is fixed-step: give its step, "
                           "e.g. --h 1e-3")
    spec = RunSpec(case=args.case, engine=args.engine, method=args.method,
                   integrator=args.integrator, rtol=args.rtol, atol=args.atol, h=args.h,
                   t_end=args.t_end, sample=args.sample)
    res = execute(spec)
    print_run(res.summary, res.samples)
    if args.out is not None:
        import pandas as pd
        from redysim.harness.store import write_parquet_atomic

        summary_path = args.out.with_suffix(".summary.parquet")
        write_parquet_atomic(res.samples, args.out)
        write_parquet_atomic(pd.DataFrame([res.summary]), summary_path)
        print(f"saved: {args.out} (samples), {summary_path} (summary)")
    if res.summary["status"] != "ok":
        print(f"{PROG}: run failed: {res.summary['reason']}", file=sys.stderr)
        return EXIT_RUN_FAILED
    return EXIT_OK


def print_run(summary: dict, samples) -> None:
    """A run's summary and its samples (t, delta_M, tip position) as a readable table."""
    s = summary
    print(f"{s['label']}   (run {s['run_id']}, {s['n_dof']} DOF)")
    print(f"  status        {s['status']}{': ' + s['reason'] if s['reason'] else ''}")
    print(f"  E(0)          {s['E0']:.6f} J")
    print(f"  steps         {s['steps']} ({s['rejected']} rejected), {s['nfev']} RHS calls")
    print(f"  CPU           {s['cpu_s']:.3f} s (wall {s['wall_s']:.3f} s; JIT compile or "
          f"cache load {s['jit_s']:.3f} s, timed apart)")
    print(f"  |delta_M|     average {s['avg_abs_delta_M']:.3e} J/kg, "
          f"max {s['max_abs_delta_M']:.3e} J/kg over {s['n_samples']} samples")
    if not math.isnan(s["max_tip_err"]):  # a reference solution exists
        print(f"  tip error     {s['max_tip_err']:.3e} m (max over the samples, against the "
              f"reference solution)")
    if len(samples):
        print(f"\n{'t [s]':>10} {'delta_M [J/kg]':>15} {'tip x [m]':>12} {'tip y [m]':>12} "
              f"{'tip z [m]':>12}")
        for r in samples.itertuples(index=False):
            print(f"{r.t:10.4f} {r.delta_M:15.3e} {r.tip_x:12.6f} {r.tip_y:12.6f} "
                  f"{r.tip_z:12.6f}")


def cmd_sweep(args: argparse.Namespace) -> int:
    """``redysim sweep``: every run of a sweep file, resumable."""
    from redysim.harness.store import parquet_files
    from redysim.harness.sweep import RUNS_DIR, RUNS_FILE, SAMPLES_FILE, load_sweep, run_sweep

    sweep = load_sweep(args.sweep_file)
    out = args.out or DEFAULT_SWEEP_ROOT / sweep.name
    done = parquet_files(out / RUNS_DIR).keys() & {s.run_id for s in sweep.specs}
    where = f"Dask ({args.dask})" if args.dask else "a local process pool"
    if sweep.description:
        print(f"{sweep.name}: {sweep.description}")
    print(f"{sweep.name}: {len(sweep.specs)} runs, {len(done)} already done in {out}; "
          f"running the rest on {where}", flush=True)
    runs = run_sweep(sweep.specs, out, name=sweep.name, workers=args.workers, dask=args.dask,
                     progress=args.progress, reference=sweep.reference)
    failed = runs[runs["status"] != "ok"] if len(runs) else runs
    print(f"{len(runs)} runs: {len(runs) - len(failed)} ok, {len(failed)} failed -> "
          f"{out / RUNS_FILE}, {out / SAMPLES_FILE}")
    for r in failed.head(MAX_FAILED_SHOWN).itertuples(index=False):
        print(f"  failed: {r.label}: {r.reason}")
    if len(failed) > MAX_FAILED_SHOWN:
        print(f"  ... and {len(failed) - MAX_FAILED_SHOWN} more (see {out / RUNS_FILE})")
    return EXIT_RUN_FAILED if len(failed) else EXIT_OK


def cmd_cases(args: argparse.Namespace) -> int:
    """``redysim cases``: names and descriptions."""
    names = list_cases()
    width = max(map(len, names), default=0)
    for name in names:
        with open(CASES_DIR / f"{name}.toml", "rb") as fh:
            description = tomllib.load(fh).get("case", {}).get("description", "")
        print(f"{name:<{width}}  {description}")
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``redysim`` console script; returns the exit code."""
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except (RedysimError, FileNotFoundError) as exc:  # bad input: a case, a sweep file, a path
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE


if __name__ == "__main__":
    sys.exit(main())
