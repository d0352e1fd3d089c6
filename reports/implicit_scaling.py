"""CPU and memory of an implicit step against DOF, 1,000 to 1,000,000: is each step O(n)?

    python -m redysim.reports.implicit_scaling [--links 500 1500 ... 500000] [--steps 5]
        [--h 1e-3] [--out results/implicit_scaling.json]

(``make reproduce`` runs it; the report's implicit section shows its table and figure.)

Each size runs in a fresh process (so that its peak RSS is its own): ``cases/RE-U50000-L1000.toml``
with its link count changed and its length with it (the same steel rod in 20 mm U links, spinning
at 1 rad/s about the vertical: :func:`rod`), ``midpoint-fixed`` at ``--h`` for ``--steps`` steps
from the straight start, the chain's tension preconditioner. Per size: CPU per step and per
qdd call (the step's own work: Newton and GMRES iterations, which a fixed h need not keep
constant as the chain lengthens, are listed beside it), the process's peak RSS and its RSS
before the chain was built (the imports: the compiled kernels load after it, ~70 MiB at any
size, so the smallest sizes show that, not the chain). CPU counts the process's own time
(``time.process_time``), so a busy machine changes the wall time, not the figures. Writes one
JSON document (rows and provenance) to ``--out``.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROD = "RE-U50000-L1000"  # the case file whose rod, link length and initial spin every size takes
DEFAULT_LINKS = (500, 1_500, 5_000, 15_000, 50_000, 150_000, 500_000)
RESULT_FILE = "implicit_scaling.json"


def rod(links: int):
    """:data:`ROD`'s case with ``links`` links of its own length (so ``links`` x 2 cm long): its
    file read with ``[chain] links`` and ``total_length`` set (the file itself unchanged)."""
    from redysim.io.cases import case_from_dict, case_path, read_toml

    path = case_path(ROD)
    doc = json.loads(json.dumps(read_toml(path)[0]))  # a deep copy
    chain = doc["chain"]
    chain["total_length"] = links * chain["total_length"] / chain["links"]
    chain["links"] = links
    doc["case"]["name"] = f"{ROD}@{links}"
    return case_from_dict(doc, source=f"{path} ({links} links of its length)", path=path)


def one(links: int, steps: int, h: float) -> dict:
    """One size, in this process."""
    import redysim.io.cases  # noqa: F401  (the imports before the baseline, as documented)
    import redysim.simulation  # noqa: F401
    from redysim.harness.provenance import peak_rss_mib as rss_mib  # VmHWM: this program's own

    base = rss_mib()
    case = rod(links)
    chain = case.chain
    sim = case.simulator(steps * h, integrator="midpoint-fixed", h=h, sample=steps * h,
                         keep_states=False)
    built = rss_mib()
    cpu = time.process_time()
    res = sim.run()
    cpu = time.process_time() - cpu
    if res.status != 0:
        raise SystemExit(f"{links} links: {res.message}")
    solver = sim.solver
    return {"links": links, "n_dof": chain.n_dof, "h": h, "steps": res.steps,
            "qdd_calls": res.nfev, "newton": solver.newton, "krylov": solver.krylov,
            "cpu_s": cpu, "cpu_per_step_s": cpu / res.steps, "cpu_per_call_ms":
            1e3 * cpu / res.nfev, "rss_before_mib": base, "rss_built_mib": built,
            "rss_peak_mib": rss_mib(), "jit_s": res.jit_s,
            "max_abs_delta_M": float(np.abs(res.delta_M).max())}


def slopes(rows: list[dict]) -> dict[str, float]:
    """The log-log slopes against DOF of the CPU per call, per step and the peak RSS above the
    process's before the chain (1: O(n))."""
    dof = np.log([r["n_dof"] for r in rows])
    keys = {"cpu_per_call_ms": [r["cpu_per_call_ms"] for r in rows],
            "cpu_per_step_s": [r["cpu_per_step_s"] for r in rows],
            "rss_added_mib": [r["rss_peak_mib"] - r["rss_before_mib"] for r in rows]}
    # (a small chain may add nothing to the high-water mark the imports left: no slope then)
    return {k: float(np.polyfit(dof, np.log(v), 1)[0]) if min(v) > 0 else math.nan
            for k, v in keys.items()}


def run(out: Path, links=DEFAULT_LINKS, steps: int = 5, h: float = 1e-3, say=print) -> dict:
    """Every size in a fresh process; the document written to ``out`` (atomically) and
    returned."""
    from redysim.harness.provenance import provenance
    from redysim.harness.store import write_json_atomic

    rows = []
    for n in links:  # a fresh process each: its peak RSS is this size's
        done = subprocess.run([sys.executable, "-m", __spec__.name if __spec__ else __name__,
                               "--one", "--links", str(n), "--steps", str(steps), "--h", str(h)],
                              capture_output=True, text=True, check=False)
        if done.returncode != 0:
            raise RuntimeError(f"{n} links: {done.stderr.strip()[-2000:]}")
        row = json.loads(done.stdout.strip().splitlines()[-1])
        rows.append(row)
        say(f"{row['n_dof']:>9,} DOF: {row['steps']} steps, {row['qdd_calls']} qdd calls "
            f"({row['newton']} Newton, {row['krylov']} GMRES), "
            f"{row['cpu_per_step_s']:.3f} s a step, {row['cpu_per_call_ms']:.2f} ms a call, "
            f"peak RSS {row['rss_peak_mib']:,.0f} MiB ({row['rss_before_mib']:,.0f} before "
            f"the chain)")
    doc = {"rows": rows, "slopes": slopes(rows) if len(rows) > 1 else {},
           "machine": platform.processor() or platform.machine(), **provenance()}
    out.parent.mkdir(parents=True, exist_ok=True)
    write_json_atomic(doc, out)
    return doc


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--links", type=int, nargs="+", default=list(DEFAULT_LINKS))
    ap.add_argument("--steps", type=int, default=5)
    ap.add_argument("--h", type=float, default=1e-3)
    ap.add_argument("--one", action="store_true", help="run the one size given, print JSON")
    ap.add_argument("--out", type=Path, default=Path("results") / RESULT_FILE)
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(one(args.links[0], args.steps, args.h)))
        return 0
    doc = run(args.out, args.links, args.steps, args.h)
    for key, slope in doc["slopes"].items():
        print(f"log-log slope of {key} against DOF: {slope:.3f}")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
