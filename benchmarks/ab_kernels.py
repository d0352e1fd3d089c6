"""RGE-A kernels of two git revisions side by side in one process: per pass and whole, ns/DOF.

    .venv/bin/python benchmarks/ab_kernels.py --base 4e53e17 [--dof 2000 100000] [--reps 40]

The base revision's ``redysim/_jit.py`` and ``redysim/algorithms/_kernels/`` (and ``workspace.py``,
for its entry point, and ``dh_form.py``, whose DH constants its workspace lays out) are copied out
of git into a temporary package and imported beside the working
tree's kernels, both compiled afresh (a temporary numba cache); both are called on the same chain
(the RE-U steel rod, as ``make bench``) and state, alternating base and head call by call so that
the machine's drift falls on both alike, and each is read as its fastest call. JIT compile happens
before the timing. "entry" is forward dynamics' compiled entry point (as ``forward_dynamics`` calls
it), "whole" ``rge_a_forward_dynamics`` (the three passes by their arrays: 23 positional ones before
the kernels took named bundles, the two bundles since). The passes are timed through their own numba
dispatch from Python (~1 us each; ~3 us with the bundles, whose 28 arrays the dispatcher unboxes one
by one), so at small sizes they add up to more than the whole call: compare passes at 100,000 DOF,
and the entry at every size. Each column is timed in a loop of its own, so that one column's slow
calls do not evict another's data from the caches.

Speed changes to the kernels are claimed from this script's output, never from two separate runs.
"""

from __future__ import annotations

import argparse
import importlib
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
# both sides compiled afresh, into a cache of their own: code loaded from numba's disk cache
# calls its own copies of the kernels, which ran ~3% slower (benchmarks/entry_copies.py), so a
# cached head against a compiled base was not a fair comparison
_CACHE = tempfile.TemporaryDirectory(prefix="ab_kernels-")
os.environ["NUMBA_CACHE_DIR"] = _CACHE.name

from test_bench_core import state, u_chain  # noqa: E402  (make bench's chain and state)

from redysim import Chain, Workspace  # noqa: E402

PASSES = ("entry", "whole", "kinematics", "backward", "forward")


def base_kernels(rev: str, into: Path):
    """Import the kernels of ``rev`` as the package ``ab_base`` (copied from git into ``into``),
    with its workspace if it has the packed entry points (the chain is the working tree's)."""
    pkg = into / "ab_base"
    (pkg / "_kernels").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    where = ws_path = None  # the kernels' folder in rev (redysim/_kernels until the layers)
    for kernels, ws_file in (("redysim/algorithms/_kernels/", "redysim/algorithms/workspace.py"),
                               ("redysim/_kernels/", "redysim/workspace.py")):
        names = subprocess.run(["git", "-C", str(ROOT), "ls-tree", "--name-only", rev, kernels],
                               capture_output=True, text=True, check=True).stdout.split()
        if names:
            where, ws_path = kernels, ws_file
            break
    if where is None:
        raise SystemExit(f"{rev}: no kernels found in redysim/algorithms/_kernels or "
                         "redysim/_kernels")
    has_entry = f"{where}entry.py" in names
    if has_entry:
        names.append(ws_path)
        # the DH kernels' constants, as that revision lays them out (its workspace makes them)
        dh_form = "redysim/algorithms/dh_form.py"
        if subprocess.run(["git", "-C", str(ROOT), "cat-file", "-e", f"{rev}:{dh_form}"],
                          capture_output=True).returncode == 0:
            names.append(dh_form)
        # the workspace's imports from outside the kernels: the working tree's
        shim = ("from redysim.model.parts import *  # noqa\n"
                "from redysim.model.parts import _readonly, kernel_alias  # noqa\n"
                "from redysim.model.tree import Chain  # noqa\n")
        for module in ("chain", "parts"):  # (chain.py until the Chain became a Model)
            (pkg / f"{module}.py").write_text(shim)
        (pkg / "errors.py").write_text("from redysim.errors import *  # noqa\n")
        (pkg / "model.py").write_text("from redysim.model.tree import *  # noqa\n")
    here_bundles = ROOT / "redysim/algorithms/_kernels/bundles.py"
    for name in [*names, "redysim/_jit.py"]:
        if not name.endswith(".py"):
            continue
        text = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:{name}"],
                              capture_output=True, text=True, check=True).stdout
        # a layered revision imports by absolute names: point them at the copy
        text = text.replace("redysim.algorithms._kernels", "ab_base._kernels")
        text = text.replace("redysim._jit", "ab_base._jit")
        text = text.replace("redysim.algorithms.dh_form", "ab_base.dh_form")
        if name == f"{where}bundles.py" and text != here_bundles.read_text().replace(
                "redysim._jit", "ab_base._jit"):
            print("note: the two revisions' bundles differ, so numba dispatches the second "
                  "side's pass calls by its slow path (~0.2 ms a call): compare the entry "
                  "column; the passes' columns only where the bundles are the same",
                  file=sys.stderr)
        elif name == f"{where}bundles.py":
            # the same bundles: the working tree's classes on both sides. Two NamedTuple
            # classes of one name and fields sent the second side's calls by them through
            # numba's slow dispatch, ~0.2 ms a call (the passes' columns; not the entry's)
            bundles = "redysim.algorithms._kernels.bundles"
            text = (f"from {bundles} import *  # noqa\n"
                    f"from {bundles} import GATHER_MASS, Scratch, Tree  # noqa\n")
        if name.startswith(where):
            target = pkg / "_kernels" / name[len(where):]
        else:
            target = pkg / Path(name).name  # workspace.py, _jit.py, dh_form.py
        target.write_text(text)
        if name == "redysim/_jit.py" and where.count("/") == 3:
            # the layered kernels' __init__ digests the _jit.py two folders above them
            # (redysim/algorithms/_kernels -> redysim/_jit.py), here the temporary folder
            (into / "_jit.py").write_text(text)
    sys.path.insert(0, str(into))
    return (importlib.import_module("ab_base._kernels.rge_a"),
            importlib.import_module("ab_base._kernels.kinematics"),
            importlib.import_module("ab_base._kernels.entry") if has_entry else None,
            importlib.import_module("ab_base.workspace").Workspace if has_entry else Workspace)


def calls(rge_a, kin, entry, workspace, model: Chain, q, qd) -> tuple[list, np.ndarray]:
    """The timed calls (entry, whole, kinematics, backward, forward) and the qdd they write.

    entry: forward dynamics' compiled entry point, as ``forward_dynamics`` calls it (None for a
    revision without one: not timed); whole: ``rge_a_forward_dynamics``, the three passes by
    their arrays (a revision with named bundles: by its workspace's ``tree`` and ``s``; before
    them: by 23 positional arrays)."""
    ws = workspace(model)
    out = np.empty(model.n_dof)
    if hasattr(ws, "tree"):  # the kernels take named bundles
        tree, s = ws.tree, ws.s
        whole = (tree, q, qd, ws.zeros, ws.base_accel, ws.zeros, s, out)
        kin_args = (tree, q, qd, ws.zeros, ws.base_accel, s, True)
        bw_args = (tree, s, ws.zeros)
        fw_args = (tree, s, ws.base_accel, out)
    else:
        head = ws.rge_a_head  # length, mass, inertia_O, mass_com, dof_kind, dof_axis, dof_u, qoff
        whole = (*head, q, qd, ws.zeros, ws.base_accel, ws.zeros, *ws.rge_a_tail, out)
        kin_args = (head[0], head[4], head[5], head[6], head[7], q, qd, ws.zeros, ws.base_accel,
                    ws.oR, ws.oO, ws.oP, ws.t, ws.td, True)
        bw_args = (head[1], head[2], head[3], head[4], head[7], ws.oR, ws.oO, ws.oP, ws.t, ws.td,
                   ws.zeros, ws.Ihat, ws.Psihat, ws.phitil, ws.phihat)
        fw_args = (head[7], ws.oO, ws.oP, ws.Psihat, ws.phitil, ws.td, ws.base_accel, out)
    fns = [(lambda: entry.RGE_A.compiled(ws.kernel_f, ws.kernel_i, q, qd, ws.zeros, ws.scratch,
                                         out)) if entry else None,
           lambda: rge_a.rge_a_forward_dynamics(*whole), lambda: kin.kinematics(*kin_args),
           lambda: rge_a.rge_a_backward(*bw_args), lambda: rge_a.rge_a_forward(*fw_args)]
    for f in fns:
        if f:
            f()  # compile or load
    fns[1]()
    if fns[0]:
        fns[0]()
    return fns, out


def _cell(x: float, digits: int = 2) -> str:
    """A table cell: x, or "-" for a call not timed (the base revision has no entry point)."""
    return f"{x:11.{digits}f}" if np.isfinite(x) else f"{'-':>11}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="git revision to compare the working tree with")
    ap.add_argument("--dof", type=int, nargs="+", default=[200, 2000, 100_000])
    ap.add_argument("--reps", type=int, default=0, help="calls per pass (default: by size)")
    a = ap.parse_args(argv)
    import redysim.algorithms._kernels.entry as head_entry
    import redysim.algorithms._kernels.kinematics as head_kin
    import redysim.algorithms._kernels.rge_a as head_rge_a

    with tempfile.TemporaryDirectory() as tmp:
        base = base_kernels(a.base, Path(tmp))
        print(f"base {a.base} vs working tree; U chain, fastest call, ns/DOF")
        print(f"{'DOF':>8} {'':5} " + " ".join(f"{p:>11}" for p in PASSES))
        for dof in a.dof:
            chain = u_chain(dof)
            q, qd = state(chain)
            sides = {"base": calls(*base, chain, q, qd),
                     "head": calls(head_rge_a, head_kin, head_entry, Workspace, chain, q, qd)}
            best = {s: [np.inf] * len(PASSES) for s in sides}
            reps = a.reps or max(20, 2_000_000 // dof)
            for i in range(len(PASSES)):  # one column at a time: a slow call of one column
                for r in range(reps):       # (below) cannot evict another's data from cache
                    for s in (("base", "head") if r % 2 else ("head", "base")):
                        f = sides[s][0][i]
                        if f is None:
                            continue
                        t0 = time.perf_counter()
                        f()
                        best[s][i] = min(best[s][i], time.perf_counter() - t0)
            for s in sides:
                print(f"{dof:>8,} {s:5} " + " ".join(_cell(b / dof * 1e9) for b in best[s]))
            ratio = [b / h for b, h in zip(best["base"], best["head"], strict=True)]
            qb, qh = sides["base"][1], sides["head"][1]
            diff = np.abs(qb - qh).max() / np.abs(qb).max()
            print(f"{'':>8} {'x':5} " + " ".join(_cell(x, 3) for x in ratio)
                  + f"   max |qdd diff| / max |qdd| = {diff:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
