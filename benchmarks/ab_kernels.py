"""RGE-A kernels of two git revisions side by side in one process: per pass and whole, ns/DOF.

    .venv/bin/python benchmarks/ab_kernels.py --base 4e53e17 [--dof 2000 100000] [--reps 40]

The base revision's ``redysim/_jit.py`` and ``redysim/_kernels/`` are copied out of git into a
temporary package and imported beside the working tree's kernels; both are called on the same
chain (the RE-U steel rod, as ``make bench``) and state, alternating base and head call by call so
that the machine's drift falls on both alike, and each is read as its fastest call. JIT compile
happens before the timing. The passes are timed through their own numba dispatch (~1 us each), so
at small sizes they add up to more than the whole call.

Speed changes to the kernels are claimed from this script's output, never from two separate runs.
"""

from __future__ import annotations

import argparse
import importlib
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from redysim import Chain, Workspace  # noqa: E402

PASSES = ("whole", "kinematics", "backward", "forward")


def base_kernels(rev: str, into: Path):
    """Import the kernels of ``rev`` as the package ``ab_base`` (copied from git into ``into``)."""
    pkg = into / "ab_base"
    (pkg / "_kernels").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    names = subprocess.run(["git", "-C", str(ROOT), "ls-tree", "--name-only", rev,
                            "redysim/_kernels/"], capture_output=True, text=True,
                           check=True).stdout.split()
    for name in [*names, "redysim/_jit.py"]:
        if name.endswith(".py"):
            text = subprocess.run(["git", "-C", str(ROOT), "show", f"{rev}:{name}"],
                                  capture_output=True, text=True, check=True).stdout
            (pkg / Path(name).relative_to("redysim")).write_text(text)
    sys.path.insert(0, str(into))
    return (importlib.import_module("ab_base._kernels.rge_a"),
            importlib.import_module("ab_base._kernels.kinematics"))


def calls(rge_a, kin, chain: Chain, q, qd) -> tuple[list, np.ndarray]:
    """The four timed calls (whole, kinematics, backward, forward) and the qdd they write."""
    ws = Workspace(chain)
    out = np.empty(chain.n_dof)
    head = ws.rge_a_head  # length, mass, inertia_O, mass_com, dof_kind, dof_axis, dof_u, qoff
    whole = (*head, q, qd, ws.zeros, ws.base_accel, ws.zeros, *ws.rge_a_tail, out)
    kin_args = (head[0], head[4], head[5], head[6], head[7], q, qd, ws.zeros, ws.base_accel,
                ws.oR, ws.oO, ws.oP, ws.t, ws.td, True)
    bw_args = (head[1], head[2], head[3], head[4], head[7], ws.oR, ws.oO, ws.oP, ws.t, ws.td,
               ws.zeros, ws.Ihat, ws.Psihat, ws.phitil, ws.phihat)
    fw_args = (head[7], ws.oO, ws.oP, ws.Psihat, ws.phitil, ws.td, ws.base_accel, out)
    fns = [lambda: rge_a.rge_a_forward_dynamics(*whole), lambda: kin.kinematics(*kin_args),
           lambda: rge_a.rge_a_backward(*bw_args), lambda: rge_a.rge_a_forward(*fw_args)]
    for f in fns:
        f()  # compile or load
    fns[0]()
    return fns, out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--base", required=True, help="git revision to compare the working tree with")
    ap.add_argument("--dof", type=int, nargs="+", default=[200, 2000, 100_000])
    ap.add_argument("--reps", type=int, default=0, help="calls per pass (default: by size)")
    a = ap.parse_args(argv)
    import redysim._kernels.kinematics as head_kin
    import redysim._kernels.rge_a as head_rge_a

    with tempfile.TemporaryDirectory() as tmp:
        base_rge_a, base_kin = base_kernels(a.base, Path(tmp))
        print(f"base {a.base} vs working tree; U chain, fastest call, ns/DOF")
        print(f"{'DOF':>8} {'':5} " + " ".join(f"{p:>11}" for p in PASSES))
        for dof in a.dof:
            chain = Chain.uniform(dof // 2, "U", length=0.02,
                                  linear_density=7850 * np.pi * 0.05**2, radius=0.05,
                                  inertia="rod")
            rng = np.random.default_rng(0)
            q, qd = rng.uniform(-0.3, 0.3, chain.n_dof), rng.normal(size=chain.n_dof)
            sides = {"base": calls(base_rge_a, base_kin, chain, q, qd),
                     "head": calls(head_rge_a, head_kin, chain, q, qd)}
            best = {s: [np.inf] * len(PASSES) for s in sides}
            reps = a.reps or max(20, 2_000_000 // dof)
            for r in range(reps):
                for s in (("base", "head") if r % 2 else ("head", "base")):
                    for i, f in enumerate(sides[s][0]):
                        t0 = time.perf_counter()
                        f()
                        best[s][i] = min(best[s][i], time.perf_counter() - t0)
            for s in sides:
                print(f"{dof:>8,} {s:5} " + " ".join(f"{b / dof * 1e9:11.2f}" for b in best[s]))
            ratio = [b / h for b, h in zip(best["base"], best["head"], strict=True)]
            qb, qh = sides["base"][1], sides["head"][1]
            diff = np.abs(qb - qh).max() / np.abs(qb).max()
            print(f"{'':>8} {'x':5} " + " ".join(f"{x:11.3f}" for x in ratio)
                  + f"   max |qdd diff| / max |qdd| = {diff:.1e}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
