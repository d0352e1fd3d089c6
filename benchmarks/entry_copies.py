"""RGE-A's entry point loaded from numba's disk cache, with and without its kernels loaded first.

    .venv/bin/python benchmarks/entry_copies.py [--dof 2000 20000 100000] [--reps 30]

numba links a copy of every kernel an entry calls into the entry's machine code, optimised a
second time there. An entry loaded from the disk cache calls those copies unless the kernels'
own code is already loaded, in which case the JIT linker prefers that (as it does for an entry
compiled afresh, which compiles its kernels first). ``redysim._jit.EntryPoint`` therefore loads
the kernels first; this script measures what that buys, both entries in one process, called in
turn on the same workspace, each read as its fastest call:

    copies   the entry alone from the disk cache (its own copies of the kernels) own
    ``redysim.algorithms._kernels.entry.RGE_A``: the kernels first, then the entry from the cache

The disk cache is warmed in a subprocess first, so that both are loads, not compiles.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

WARM = ("import numpy as np, redysim; c = redysim.Chain.uniform(2, 'U', length=1.0, "
        "linear_density=1.0, radius=0.1, inertia='rod'); "
        "redysim.forward_dynamics(c, np.zeros(4), np.zeros(4))")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dof", type=int, nargs="+", default=[2000, 20000, 100_000])
    ap.add_argument("--reps", type=int, default=30, help="calls per entry (x 20,000 / DOF)")
    a = ap.parse_args(argv)
    subprocess.run([sys.executable, "-c", WARM], cwd=ROOT, check=True)

    import numba
    from test_bench_core import state, u_chain  # make bench's chain and state

    from redysim import Workspace
    from redysim._jit import OPTIONS
    from redysim.algorithms._kernels import entry

    copies = numba.njit(entry.SIGNATURE, **OPTIONS)(entry.rge_a_entry)  # before the kernels
    own = entry.RGE_A.compiled
    if not sum(copies.stats.cache_hits.values()):
        sys.exit("the entry was compiled, not loaded from the disk cache: nothing to compare")
    print(f"numba {numba.__version__}; U chain, fastest call, ns/DOF")
    print(f"{'DOF':>8} {'copies':>9} {'own':>9} {'copies/own':>11}")
    for dof in a.dof:
        chain = u_chain(dof)
        q, qd = state(chain)
        ws = Workspace(chain)
        out = {"copies": np.empty(chain.n_dof), "own": np.empty(chain.n_dof)}
        best = {"copies": np.inf, "own": np.inf}
        fns = {"copies": copies, "own": own}
        for r in range(a.reps * max(1, 20_000 // dof)):
            for k in (("copies", "own") if r % 2 else ("own", "copies")):
                t0 = time.perf_counter()
                fns[k](ws.kernel_f, ws.kernel_i, q, qd, ws.zeros, ws.scratch, out[k])
                best[k] = min(best[k], time.perf_counter() - t0)
        assert np.array_equal(out["copies"], out["own"])
        c, o = (best[k] / dof * 1e9 for k in ("copies", "own"))
        print(f"{dof:>8,} {c:9.2f} {o:9.2f} {c / o:11.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
