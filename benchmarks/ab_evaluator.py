"""The evaluator's lean entries of two git revisions side by side in one process: small systems.

    .venv/bin/python benchmarks/ab_evaluator.py --base be08d5d [--rounds 9] [--calls 25]

``redysim.evaluator`` calls a lean entry (``redysim/algorithms/_kernels/lean.py``: kinematics
and RGE-A's passes inlined into one compiled function, or the planar or DH kernel) from a
builtin of its own; the builtin's C code is the same in both revisions, so what a kernel change
moves is the entry's time, timed here through its compiled wrapper (``EntryPoint.call``, numba's
dispatch bypassed, as the builtin calls the entry's address). The base revision's kernels and
workspace are copied out of git into a temporary package (``benchmarks/ab_kernels.py``'s copier)
and both revisions compile afresh into one temporary numba cache. Each side gets its own
workspace of the same model (the working tree's Model) and the same state; a measurement is
``--batch`` calls in a row (one call is ~0.2-2 us, near the timer's resolution), the sides
alternate measurement by measurement, a round is ``--calls`` measurements a side, each side read
as its fastest in the round; the table gives the median over the rounds of each side's time per
call and of the ratio base / head (> 1: the head is faster), with the lowest and highest round's
ratio, and whether both sides' results are the same bits.

Speed changes to the lean entries are claimed from this script's output, never from two runs.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.insert(0, str(ROOT / "tests"))
from ab_kernels import base_kernels  # noqa: E402  (sets a temporary NUMBA_CACHE_DIR first)

from redysim import Chain, Workspace, load_model  # noqa: E402


def models() -> dict:
    """The systems timed: a rope (the serial chain entry), a planar chain (the planar kernel), a
    branched tree with a free joint (the tree entry), the PUMA 560 (the DH kernels)."""
    from test_trees import random_tree
    return {
        "U 20": Chain.uniform(10, "U", length=0.02, linear_density=7850 * np.pi * 0.05**2,
                              radius=0.05, inertia="rod"),
        "U 200": Chain.uniform(100, "U", length=0.02, linear_density=7850 * np.pi * 0.05**2,
                               radius=0.05, inertia="rod"),
        "R 20 planar": Chain.uniform(20, "R", length=0.5, linear_density=2.0, radius=0.02),
        "tree 30": random_tree(3, n_bodies=12, free=True),
        "PUMA 560": load_model(str(ROOT / "cases" / "robots" / "puma560.toml")),
    }


def entry(lean, ws, kind: str):
    """The lean entry the evaluator of this workspace's model takes for ``kind``."""
    if kind == "forward":
        if ws.planar is not None:
            return lean.FORWARD_PLANAR
        return lean.FORWARD_DH if ws.dh else (
            lean.FORWARD_CHAIN if ws.tree.serial else lean.FORWARD_TREE)
    return lean.INVERSE_DH if ws.dh else (
        lean.INVERSE_CHAIN if ws.tree.serial else lean.INVERSE_TREE)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="git revision to compare the working tree with")
    ap.add_argument("--rounds", type=int, default=9)
    ap.add_argument("--calls", type=int, default=25, help="measurements a side in a round")
    ap.add_argument("--batch", type=int, default=200, help="calls in a measurement")
    ap.add_argument("--kinds", nargs="+", default=["forward", "inverse"],
                    choices=["forward", "inverse"])
    a = ap.parse_args(argv)
    import redysim.algorithms._kernels.lean as head_lean

    with tempfile.TemporaryDirectory() as tmp:
        with contextlib.redirect_stderr(io.StringIO()):  # its note is on ab_kernels' passes
            base_ws_class = base_kernels(a.base, Path(tmp))[3]
        import ab_base._kernels.lean as base_lean  # noqa: PLC0415  (made by base_kernels)

        print(f"base {a.base} vs working tree; lean entries (the evaluator's), load "
              f"{os.getloadavg()[0]:.2f}; median of {a.rounds} rounds of {a.calls} "
              f"measurements a side of {a.batch} calls (each side's fastest in a round)")
        print(f"{'system':>12} {'kind':>8} {'base us':>9} {'head us':>9} {'base/head':>10} "
              f"{'min':>6} {'max':>6}  result")
        for name, model in models().items():
            rng = np.random.default_rng(4)
            q = model.neutral() + 0.0
            q[:] = q + np.where(model.neutral() == 0.0, rng.uniform(-1, 1, model.n_q), 0.0)
            v, x = rng.normal(size=model.n_v), rng.normal(size=model.n_v)
            for kind in a.kinds:
                sides = {}
                for s, lean, ws_class in (("base", base_lean, base_ws_class),
                                          ("head", head_lean, Workspace)):
                    ws = ws_class(model)
                    out = np.empty(model.n_v)
                    call = entry(lean, ws, kind).call
                    args = (q, v, x, out, ws.kernel_f, ws.kernel_i, ws.scratch)
                    call(*args)  # compile (or load) before the timing
                    sides[s] = (call, args, out)

                def measure(s, sides=sides):
                    call, args, _ = sides[s]
                    t0 = time.perf_counter()
                    for _ in range(a.batch):
                        call(*args)
                    return (time.perf_counter() - t0) / a.batch

                best = {s: [] for s in sides}
                for _ in range(a.rounds):
                    round_best = {s: np.inf for s in sides}
                    for c in range(a.calls):
                        for s in (("base", "head") if c % 2 else ("head", "base")):
                            round_best[s] = min(round_best[s], measure(s))
                    for s in sides:
                        best[s].append(round_best[s])
                ratio = np.array(best["base"]) / np.array(best["head"])
                ob, oh = sides["base"][2], sides["head"][2]
                same = "identical" if ob.tobytes() == oh.tobytes() else (
                    f"DIFFER (max {np.abs(ob - oh).max():.1e})")
                print(f"{name:>12} {kind:>8} {np.median(best['base']) * 1e6:9.3f} "
                      f"{np.median(best['head']) * 1e6:9.3f} {np.median(ratio):10.3f} "
                      f"{ratio.min():6.3f} {ratio.max():6.3f}  {same}")
    print(f"load after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
