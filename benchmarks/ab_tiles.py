"""The SIMD tiles of two git revisions side by side in one process: 64-state batches.

    .venv/bin/python benchmarks/ab_tiles.py --base d8bc20b [--rounds 7] [--calls 15] [--threads 1]

The base revision's kernels and workspace are copied out of git into a temporary package
(``benchmarks/ab_kernels.py``'s copier) and its ``_forward_tiled`` (the batch's tiles, in
``redysim/algorithms/dynamics.py``) taken from its source; both revisions compile afresh into one
temporary numba cache. Each side is timed as a user calls it, ``forward_dynamics(chain, Q, QD,
ws=ws, out=out, threads=1, planar=False)`` (``--threads``; the working tree's function, its
``_forward_tiled`` pointed at the side's and ``ws`` the side's workspace: the checks before the
tiles are the same Python for both), on the same 64 states (uniform in +-0.1, as ``make
bench-engines``). The calls alternate base and head; a round is ``calls`` calls a side, each side
read as its fastest; the table gives the median over the rounds of each side's time and of the
ratio base / head (> 1: the head is faster), with the lowest and highest round's ratio. Both
sides' qdd are compared bit for bit.

Both sides' tile buffers are put on a 64-byte boundary (``--misalign`` shifts them by that many
bytes): a thread's tile arrays are one buffer, and where malloc placed it (16 bytes past a cache
line, say) had changed the tiles' speed more than any change compared here
(docs/notes/2026-11-batches-and-tiles.md).

Speed changes to the tiles are claimed from this script's output, never from two separate runs.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import io
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))
from ab_kernels import base_kernels  # noqa: E402  (sets a temporary NUMBA_CACHE_DIR first)

from redysim import Chain, Workspace, forward_dynamics  # noqa: E402
from redysim.algorithms import dynamics, threads  # noqa: E402

STATES = 64
DENSITY = 7850 * np.pi * 0.05**2  # the RE-U steel rod (make bench)
# chains (links, joint), and a branched tree with a free joint (the tree passes: tests' random
# tree of 24 bodies, ~60 DOF)
CASES = {"U 20": (10, "U"), "R 250": (250, "R"), "U 250": (125, "U"), "U 2000": (1000, "U"),
         "tree": (24, "tree")}


def system(case: str):
    """The model of a case (module docstring)."""
    links, joint = CASES[case]
    if joint == "tree":
        sys.path.insert(0, str(ROOT / "tests"))
        from test_trees import random_tree
        return random_tree(3, n_bodies=links, free=True)
    return Chain.uniform(links, joint, length=0.02, linear_density=DENSITY, radius=0.05,
                         inertia="rod", name=case)


def base_forward_tiled(rev: str):
    """The base revision's ``_forward_tiled``, its module globals the working tree's dynamics
    with the base's tiles and rows kernels (imported by :func:`base_kernels` as ``ab_base``)."""
    import ab_base._kernels.batch as batch
    import ab_base._kernels.tiles as tiles

    source = subprocess.run(["git", "-C", str(ROOT), "show",
                             f"{rev}:redysim/algorithms/dynamics.py"],
                            capture_output=True, text=True, check=True).stdout
    node = next(n for n in ast.parse(source).body
                if isinstance(n, ast.FunctionDef) and n.name == "_forward_tiled")
    scope = {**vars(threads), **vars(dynamics), "_tiles": tiles, "_batch": batch}
    if "_speed" in source and "_speed" not in scope:
        # a revision whose runtime lived in dynamics (before 435b390): its record of whether
        # helpers pay, as the working tree's runtime keeps it (always a record: it reports to it)
        def _speed(ws, key, count_threads, chunks):
            count, speed = threads.plan({}, key, count_threads, chunks)
            return count, speed if speed is not None else threads.Speed()
        scope["_speed"] = _speed
    exec(compile(ast.Module([node], []), f"<{rev} _forward_tiled>", "exec"), scope)  # noqa: S102
    return scope["_forward_tiled"]


def place(ws, misalign: int) -> None:
    """``ws``'s tile buffer (made by a first call) moved to ``misalign`` bytes past a 64-byte
    boundary."""
    buf = ws._tiles
    raw = np.zeros(buf.size + 16)
    start = ((-raw.ctypes.data) % 64 + misalign) % 64 // 8
    ws._tiles = raw[start:start + buf.size].reshape(buf.shape)
    assert ws._tiles.ctypes.data % 64 == misalign


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="git revision to compare the working tree with")
    ap.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--calls", type=int, default=15, help="calls a side in a round")
    ap.add_argument("--threads", type=int, default=1, help="threads a batch (numba's)")
    ap.add_argument("--misalign", type=int, default=0, choices=(0, 8, 16, 24, 32, 40, 48, 56),
                    help="bytes past a 64-byte boundary for both sides' tile buffers")
    a = ap.parse_args(argv)
    head_tiled = dynamics._forward_tiled
    with tempfile.TemporaryDirectory() as tmp:
        with contextlib.redirect_stderr(io.StringIO()):  # its note is on the passes' columns
            base_ws_class = base_kernels(a.base, Path(tmp))[3]
        base_tiled = base_forward_tiled(a.base)
        print(f"base {a.base} vs working tree; {STATES} states, threads={a.threads}, load "
              f"{os.getloadavg()[0]:.2f}; median of {a.rounds} rounds of {a.calls} calls a side "
              f"(each side's fastest call in a round); tile buffers {a.misalign} bytes past 64")
        print(f"{'chain':>8} {'base us':>9} {'head us':>9} {'ns/DOF/state':>13} {'base/head':>10}"
              f" {'min':>6} {'max':>6}  qdd")
        for case in a.cases:
            chain = system(case)
            rng = np.random.default_rng(2)
            Q = chain.neutral() + rng.uniform(-0.1, 0.1, (STATES, chain.n_q))
            QD = rng.uniform(-0.1, 0.1, (STATES, chain.n_dof))
            base_ws = base_ws_class(chain)
            if not hasattr(base_ws, "model"):  # a revision whose workspace called it chain
                base_ws.model = base_ws.chain
            sides = {"base": (base_tiled, base_ws), "head": (head_tiled, Workspace(chain))}
            outs = {s: np.empty((STATES, chain.n_dof)) for s in sides}

            def call(side, sides=sides, outs=outs, chain=chain, Q=Q, QD=QD):
                tiled, ws = sides[side]
                dynamics._forward_tiled = tiled
                t0 = time.perf_counter()
                forward_dynamics(chain, Q, QD, ws=ws, out=outs[side], threads=a.threads,
                                 planar=False)
                return time.perf_counter() - t0

            for s in sides:
                call(s)  # compile
                assert sides[s][1]._tiles is not None  # the tiles ran
                place(sides[s][1], a.misalign)
            best = {s: [] for s in sides}
            for _ in range(a.rounds):
                round_best = {s: np.inf for s in sides}
                for c in range(a.calls):
                    for s in (("base", "head") if c % 2 else ("head", "base")):
                        round_best[s] = min(round_best[s], call(s))
                for s in sides:
                    best[s].append(round_best[s])
            dynamics._forward_tiled = head_tiled
            ratio = np.array(best["base"]) / np.array(best["head"])
            head = np.median(best["head"])
            same = "identical" if np.array_equal(outs["base"], outs["head"]) else (
                f"DIFFER (max {np.abs(outs['base'] - outs['head']).max():.1e})")
            print(f"{case:>8} {np.median(best['base']) * 1e6:9.1f} {head * 1e6:9.1f} "
                  f"{head / (STATES * chain.n_dof) * 1e9:13.2f} {np.median(ratio):10.3f} "
                  f"{ratio.min():6.3f} {ratio.max():6.3f}  {same}")
    print(f"load after: {os.getloadavg()[0]:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
