"""The compiled kernels are cached on disk: a second process loads forward dynamics' entry point
and the kernels it calls, it does not compile them. ``benchmarks/jit_times.py`` reports the two
times (compile with an empty cache, load with a warm one)."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np

PROBE = """
import json, numpy as np, redysim
from redysim.algorithms._kernels import entry
c = redysim.Chain.uniform(3, "U", length=1.0, linear_density=1.0, radius=0.1)
redysim.forward_dynamics(c, np.zeros(6), np.zeros(6))
point = entry.RGE_A
print(json.dumps({d.py_func.__name__: [sum(d.stats.cache_hits.values()),
                                       sum(d.stats.cache_misses.values())]
                  for d in [point.compiled, *(k for k, _ in point.callees)]}))
"""


def probe() -> dict:
    out = subprocess.run([sys.executable, "-c", PROBE], capture_output=True, text=True,
                         check=True)
    return json.loads(out.stdout)


def test_a_second_process_loads_the_kernels_from_disk():
    probe()  # loads, or compiles and writes the cache
    second = probe()
    assert set(second) == {"rge_a_entry", "kinematics", "rge_a_backward", "rge_a_forward"}
    for name, (hits, misses) in second.items():
        assert hits >= 1 and misses == 0, (name, hits, misses)


def test_forward_dynamics_runs_with_numba_disabled():
    """NUMBA_DISABLE_JIT=1 (debugging, coverage) runs the kernels' Python source: the entry
    point must not ask its kernels to compile (they are plain functions then)."""
    code = ("import numpy as np, redysim; c = redysim.Chain.uniform(3, 'U', length=1.0, "
            "linear_density=1.0, radius=0.1); q = np.full(6, 0.1); "
            "print(redysim.forward_dynamics(c, q, q).tolist())")
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    plain = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True, env=env)
    jitted = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                            check=True)
    np.testing.assert_allclose(json.loads(plain.stdout), json.loads(jitted.stdout), rtol=1e-12)
