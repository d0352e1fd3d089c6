"""Measure one engine at one chain size in THIS process, guarded: build + one qdd call.

    .venv/bin/python -m redysim.references.measure_limits ENGINE N_LINKS [--joint U] [--mem-gib 12]

Prints one JSON line: engine, links, dof, build_s (the engine's build from the chain's Model,
converted before timing), qdd_s, peak_rss_mib (growth over the process's peak after importing
the engine), ok and error. ``--mem-gib`` caps the address space
(RLIMIT_AS) so a size past the memory limit ends in a MemoryError here instead of taking the
machine's memory from other work. Run one at a time (the machine is shared); the results are
summarised in references/limits.toml.
"""

from __future__ import annotations

import argparse
import json
import resource
import sys
import time

import numpy as np


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("engine")
    ap.add_argument("n_links", type=int)
    ap.add_argument("--joint", default="U")
    ap.add_argument("--mem-gib", type=float, default=12.0)
    ap.add_argument("--no-qdd", action="store_true")
    a = ap.parse_args(argv)

    import redysim
    from redysim import references

    cls = references.get(a.engine)
    cls.package_version()  # import the engine before the baseline
    # the adapters' input (a Chain is a Model)
    chain = model = redysim.Chain.uniform(a.n_links, a.joint, length=0.02,
                                          linear_density=61.6538, radius=0.05,
                                          inertia="cylinder")
    base = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    cap = int(a.mem_gib * 2**30)
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
    out = {"engine": a.engine, "joint": a.joint, "links": a.n_links, "dof": chain.n_dof,
           "mem_cap_gib": a.mem_gib, "ok": False, "error": ""}
    try:
        t0 = time.perf_counter()
        eng = cls(model, check_limits=False)
        out["build_s"] = time.perf_counter() - t0
        if not a.no_qdd:
            rng = np.random.default_rng(0)
            q = rng.uniform(-0.1, 0.1, chain.n_dof)
            v = rng.uniform(-0.1, 0.1, chain.n_dof)
            t0 = time.perf_counter()
            x = eng.qdd(q, v)
            out["qdd_s"] = time.perf_counter() - t0
            out["qdd_finite"] = bool(np.all(np.isfinite(x)))
        out["ok"] = True
    except BaseException as exc:  # MemoryError, engine errors: report, do not crash
        out["error"] = f"{type(exc).__name__}: {exc}"[:300]
    out["peak_rss_mib"] = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024 - base
    print(json.dumps(out), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
