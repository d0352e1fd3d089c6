"""JIT compile time and on-disk cache load time of the core's kernels, measured in fresh processes,
and the peak memory of forward dynamics at 100,000 DOF.

1. a process with an empty numba cache (NUMBA_CACHE_DIR pointed at a new directory): first-call
   time = compile + run;
2. a second process with the cache the first one wrote: first-call time = load + run;
3. the steady-state call time, so compile and load can be read off apart;
4. peak RSS of a process that builds a 100,000-DOF chain and calls forward dynamics, beside the
   RSS of the same process before the call (O(n) memory: the workspace is ~30 doubles per DOF).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

PROBE = r"""
import json, resource, time
t0 = time.perf_counter()
import numpy as np
from redysim import Chain, Workspace, forward_dynamics
t_import = time.perf_counter() - t0
chain = Chain.uniform(DOF // 2, "U", length=0.02, linear_density=61.6538, radius=0.05)
ws, out = Workspace(chain), np.empty(chain.n_dof)
q = np.full(chain.n_dof, 0.1); qd = np.full(chain.n_dof, 0.2)
rss_before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
def timed():
    t0 = time.perf_counter()
    forward_dynamics(chain, q, qd, ws=ws, out=out)
    return time.perf_counter() - t0
first = timed()
best = min(timed() for _ in range(20))
print(json.dumps({"import_s": t_import, "first_call_s": first, "steady_call_s": best,
                  "rss_before_MiB": rss_before / 1024,
                  "peak_rss_MiB": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024,
                  "workspace_MiB": ws.nbytes / 2**20}))
"""


def run(dof: int, cache_dir: str) -> dict:
    env = dict(os.environ, NUMBA_CACHE_DIR=cache_dir)
    out = subprocess.run([sys.executable, "-c", PROBE.replace("DOF", str(dof))], env=env,
                         capture_output=True, text=True, check=True)
    return json.loads(out.stdout)


def main() -> None:
    with tempfile.TemporaryDirectory() as cache:
        cold = run(200, cache)
        warm = run(200, cache)
        big = run(100_000, cache)
    print("JIT (forward dynamics, RGE-A; fresh processes, 200 DOF):")
    print(f"  compile, empty cache : {cold['first_call_s'] - cold['steady_call_s']:.2f} s")
    print(f"  load, warm disk cache: {warm['first_call_s'] - warm['steady_call_s']:.3f} s")
    print(f"  steady call          : {warm['steady_call_s'] * 1e6:.1f} us")
    print("Memory at 100,000 DOF (one process):")
    print(f"  workspace            : {big['workspace_MiB']:.1f} MiB")
    print(f"  RSS before the call  : {big['rss_before_MiB']:.0f} MiB (Python, numpy, numba, chain)")
    print(f"  peak RSS             : {big['peak_rss_MiB']:.0f} MiB")
    print(f"  steady call          : {big['steady_call_s'] * 1e3:.2f} ms "
          f"({big['steady_call_s'] / 1e5 * 1e9:.1f} ns/DOF)")


if __name__ == "__main__":
    main()
