"""The compiled kernels are cached on disk: a second process loads forward dynamics' entry point
and the kernels it calls, it does not compile them. ``benchmarks/jit_times.py`` reports the two
times (compile with an empty cache, load with a warm one)."""

from __future__ import annotations

import json
import subprocess
import sys

PROBE = """
import json, numpy as np, redysim
from redysim._kernels import entry
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
