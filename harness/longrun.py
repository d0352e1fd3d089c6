"""A long run that survives being stopped: ode45 on the core with checkpoints, resumed on restart.

For chains whose runs take hours (RE-U50000-L1000: 100,000 DOF, ~8 ms per qdd, steps of ~1e-5 s
limited by waves along the chain, DESIGN.md section 4). Every ``--every`` seconds of wall time,
and at the end, the solver's whole state (t, y, f(t, y), the next step, the counters, the CPU and
wall time so far) and the samples so far are written to ONE ``.npz`` file atomically (temp file,
fsync, ``os.replace``): a run killed at any moment, even by ``kill -9``, loses at most the work
since the last checkpoint, and resuming continues bit for bit the same step sequence.

    python -m redysim.harness.longrun RE-U50000-L1000 [--t-end 5] [--every 120] [--out DIR]
    python -m redysim.harness.longrun RE-U50000-L1000 --status  # what the checkpoint holds, ETA

Samples (every ``sample_interval`` of the case): t, tip position, E and delta_M.
"""

from __future__ import annotations

import argparse
import math
import resource
import sys
import time
from pathlib import Path

import numpy as np

from redysim import Workspace, energy, forward_dynamics, load_case, tip
from redysim.integrate import Counters, Solver, SolverState, advance, sample_times

from .provenance import code_digest
from .reference import results_dir
from .store import write_npz_atomic

CHECKPOINT = "checkpoint.npz"
DEFAULT_EVERY_S = 120.0   # wall seconds between checkpoints
SAMPLE_FIELDS = ("t", "tip_x", "tip_y", "tip_z", "E", "delta_M")


def out_dir_for(case_name: str) -> Path:
    return results_dir() / "longrun" / case_name


def save_checkpoint(path: Path, solver: Solver, samples: list, meta: dict) -> None:
    """Everything to resume, in one file, atomically."""
    st = solver.state()
    write_npz_atomic(path, t=st.t, y=st.y, f=st.f, h=st.h, steps=st.counters.steps,
                     rejected=st.counters.rejected, nfev=st.counters.nfev,
                     samples=np.array(samples, dtype=float).reshape(-1, len(SAMPLE_FIELDS)),
                     **{k: np.asarray(v) for k, v in meta.items()})


def load_checkpoint(path: Path) -> dict | None:
    if not path.exists():
        return None
    with np.load(path) as z:
        return {k: z[k] for k in z.files}


def run(case_name: str, *, t_end: float | None = None, every_s: float = DEFAULT_EVERY_S,
        out: Path | None = None, rtol: float | None = None, atol: float | None = None,
        stop_after_s: float = math.inf, log=print) -> dict:
    """Run (or resume) ``case_name`` with ode45 to ``t_end``; return the final checkpoint."""
    case = load_case(case_name)
    chain, n = case.chain, case.chain.n_dof
    t_end = float(t_end or case.t_end)
    rtol = rtol or case.simulation.get("rtol", 1e-4)
    atol = atol or case.simulation.get("atol", 1e-6)
    interval = case.simulation.get("sample_interval", t_end / 20)
    path = (out or out_dir_for(case.name)) / CHECKPOINT
    ws = Workspace(chain)

    def rhs(_t, y):
        return np.concatenate((y[n:], forward_dynamics(chain, y[:n], y[n:], ws=ws)))

    y0 = np.concatenate((case.q0, case.qd0))
    E0 = sum(energy(chain, case.q0, case.qd0, ws=ws))
    t0 = time.perf_counter()
    rhs(0.0, y0)
    jit_s = time.perf_counter() - t0
    code = code_digest()
    ck = load_checkpoint(path)
    if ck is not None:
        if float(ck["t_end"]) != t_end or float(ck["rtol"]) != rtol:
            raise SystemExit(f"{path}: a checkpoint for t_end = {float(ck['t_end'])}, rtol = "
                             f"{float(ck['rtol'])} exists; use another --out or delete it")
        if str(ck.get("code", "")) != code:
            raise SystemExit(f"{path}: the checkpoint was written by other code (digest "
                             f"{str(ck.get('code', ''))[:12] or 'not recorded'}, now {code[:12]}):"
                             " resuming would not continue the same computation; use another "
                             "--out or delete it")
        state = SolverState(float(ck["t"]), ck["y"], ck["f"], float(ck["h"]),
                            Counters(int(ck["steps"]), int(ck["rejected"]), int(ck["nfev"])))
        solver = Solver(rhs, 0.0, y0, t_end, "ode45", rtol=rtol, atol=atol, state=state)
        samples = [tuple(r) for r in ck["samples"]]
        cpu_prev, wall_prev = float(ck["cpu_s"]), float(ck["wall_s"])
        log(f"{case.name}: resuming at t = {state.t:.6g} s, {state.counters.steps:,} steps, "
            f"{len(samples)} samples ({wall_prev:,.0f} s of wall time so far)")
    else:
        solver = Solver(rhs, 0.0, y0, t_end, "ode45", rtol=rtol, atol=atol)
        samples, cpu_prev, wall_prev = [], 0.0, 0.0
        log(f"{case.name}: {n:,} DOF, ode45 rtol {rtol:g} atol {atol:g} to t = {t_end:g} s, "
            f"E(0) = {E0:.9g} J; JIT/cache load {jit_s:.2f} s")
    ts = sample_times(0.0, t_end, interval)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    last_ck = [wall0]

    def meta():
        return {"case": case.name, "code": code, "t_end": t_end, "rtol": rtol, "atol": atol,
                "E0": E0, "mass": chain.total_mass, "n_dof": n,
                "cpu_s": cpu_prev + time.process_time() - cpu0,
                "wall_s": wall_prev + time.perf_counter() - wall0,
                "peak_rss_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024}

    def on_sample(t, y):
        if samples and t <= samples[-1][0]:
            return None  # already recorded before the checkpoint we resumed from
        p = tip(chain, y[:n], y[n:], ws=ws).position
        E = sum(energy(chain, y[:n], y[n:], ws=ws))
        samples.append((t, *p, E, (E - E0) / chain.total_mass))
        log(f"  sample t = {t:.4f} s: delta_M = {samples[-1][-1]:.3e} J/kg, "
            f"steps {solver.counters.steps:,}")
        return None

    def on_step(s):
        now = time.perf_counter()
        if now - last_ck[0] >= every_s:
            save_checkpoint(path, s, samples, meta())
            last_ck[0] = now
            m = meta()
            rate = (s.t - float(ck["t"]) if ck is not None else s.t) / (now - wall0)
            eta = (t_end - s.t) / rate if rate > 0 else math.inf
            log(f"  checkpoint t = {s.t:.6g} s, {s.counters.steps:,} steps, h = {s.h_next:.2e}, "
                f"wall {m['wall_s']:,.0f} s, ETA {eta / 3600:.1f} h")
        if now - wall0 > stop_after_s:
            return "stopped by --stop-after"
        return None

    status, msg = advance(solver, ts, on_sample=on_sample, on_step=on_step)
    save_checkpoint(path, solver, samples, meta())
    final = load_checkpoint(path)
    if status < 0:
        log(f"{case.name}: FAILED: {msg}")
    elif solver.t >= t_end:
        log(f"{case.name}: done, t = {t_end:g} s")
    return final


def summary(ck: dict) -> str:
    s = ck["samples"]
    dM = np.abs(s[:, -1]) if len(s) else np.array([np.nan])
    t = float(ck["t"])
    wall = float(ck["wall_s"])
    eta = (float(ck["t_end"]) - t) / (t / wall) if t > 0 else math.inf
    return (f"{ck['case']}: t = {t:.6g} of {float(ck['t_end']):g} s; steps {int(ck['steps']):,}, "
            f"rejected {int(ck['rejected']):,}, RHS {int(ck['nfev']):,}; wall {wall:,.0f} s, "
            f"CPU {float(ck['cpu_s']):,.0f} s; peak RSS {float(ck['peak_rss_mib']):,.0f} MiB; "
            f"avg |delta_M| {dM.mean():.3e} J/kg over {len(s)} samples; "
            f"time to finish at this rate {eta / 3600:.1f} h")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m redysim.harness.longrun",
        description="Run a case with ode45 on the core, checkpointing so that a stopped run "
                    "resumes where it was. Example: "
                    "python -m redysim.harness.longrun RE-U50000-L1000")
    ap.add_argument("case")
    ap.add_argument("--t-end", type=float, default=None, help="horizon [s] (the case's)")
    ap.add_argument("--every", type=float, default=DEFAULT_EVERY_S,
                    help="wall seconds between checkpoints")
    ap.add_argument("--out", type=Path, default=None, help="folder of the checkpoint")
    ap.add_argument("--stop-after", type=float, default=math.inf,
                    help="stop (with a checkpoint) after this many wall seconds")
    ap.add_argument("--status", action="store_true", help="print the checkpoint and exit")
    args = ap.parse_args(argv)
    path = (args.out or out_dir_for(args.case)) / CHECKPOINT
    if args.status:
        ck = load_checkpoint(path)
        print(summary(ck) if ck is not None else f"no checkpoint at {path}")
        return 0
    ck = run(args.case, t_end=args.t_end, every_s=args.every, out=args.out,
             stop_after_s=args.stop_after, log=lambda m: print(m, flush=True))
    print(summary(ck))
    return 0


if __name__ == "__main__":
    sys.exit(main())
