"""Closed loops: the checks against closed forms, the cost of a call against n, and a long
pinned chain (the report's "Closed loops" section).

    python -m redysim.reports.loops [--out results/loops] [--full]

- four-bar (crank-rocker, ground 0.3, crank 0.1, coupler 0.35, rocker 0.3 m): released from rest
  for 2 s (ode45, rtol 1e-10, atol 1e-12); the coupler point against the closed-form position
  analysis at every sample, the energy drift, the loop residuals;
- Hoeken's straight-line linkage (crank 0.1 m) set turning, passive: its tracing point against
  the closed-form path, and its straight part against the published "within 1 %" and "6 times";
- pinned chain of 10 rods (1 m, span 0.8 m): released with joint damping from the continuous
  catenary, against the discrete catenary's closed form after 10 s; and, from the closed forms
  alone, how the discrete catenary approaches the continuous one as n grows (joint positions;
  the observed order);
- cost: :meth:`ClosedLoops.forward_dynamics` per call on pinned chains of 100 to 10,000 rods
  (fastest of repeated calls, this process), and its log-log slope; each engine's constrained
  qdd on pinned chains of 20 to 300 rods (``--full``: 1,000) up to its limits;
- the engines' own integrators on the four-bar (0.5 s at h = 1e-3 and 1e-4 s) against the core;
- the pinned chain at 10,000 rods (100 m, span 80 m) simulated from the continuous catenary at
  rest: 0.2 s (``--full``: 1 s), steps, CPU, residuals, energy drift.

Writes ``loops.json`` into ``--out``.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

SIZES = (100, 300, 1000, 3000, 10000)
LONG_N = 10000


def four_bar_check() -> dict:
    from redysim import simulate
    from redysim.algorithms.linkages import four_bar, four_bar_position

    fb = four_bar(0.3, 0.1, 0.35, 0.3, rp=0.2, gamma=0.4, density=2.0)
    sim = simulate(fb.model, 2.0, q0=fb.configuration(0.3), loops=fb.loops, rtol=1e-10,
                   atol=1e-12, sample=0.05)
    path = max(float(np.abs(fb.coupler_point(q) - four_bar_position(fb, q[0])[0]).max())
               for q in sim.q)
    return {"status": sim.status, "message": sim.message, "steps": sim.steps,
            "cpu_s": sim.cpu_s, "path_error_m": path,
            "max_abs_delta_M": float(np.abs(sim.delta_M).max()),
            "residual_q": sim.residual_q, "residual_v": sim.residual_v,
            "crank_range_rad": float(np.ptp(sim.q[:, 0])),
            "max_force_N": float(np.abs(sim.forces).max())}


# Hoeken's (Chebyshev's lambda) linkage, published: "stays within 1% positional tolerance while
# intersecting the ideal straight line 6 times" (Wikipedia, "Chebyshev lambda linkage"; the 1 %
# read as of the crank a, cases/loops/README.md)
HOEKEN_PUBLISHED = {"percent": 1, "crossings": 6}


def hoekens_check() -> dict:
    """Hoeken's linkage (crank 0.1 m) set turning at 10 rad/s, passive, loop closed: its
    tracing point against the closed-form path, and its straight part's strip and crossings."""
    from redysim import simulate
    from redysim.algorithms.linkages import (
        crossings,
        hoekens_linkage,
        hoekens_path,
        hoekens_straight_part,
        straight_band,
    )

    a = 0.1
    fb = hoekens_linkage(a)
    q0 = fb.configuration(math.radians(60.0))
    null = np.linalg.svd(fb.loops.evaluate(q0, np.zeros(3))[1])[2][-1]
    sim = simulate(fb.model, 0.45, q0=q0, v0=10.0 * null / null[0], loops=fb.loops,
                   rtol=1e-10, atol=1e-12, sample=0.002)
    points = np.array([fb.coupler_point(q) for q in sim.q])
    theta1 = math.radians(hoekens_straight_part()[0])
    crank = np.unwrap(sim.q[:, 0])
    straight = (crank >= theta1) & (crank <= 2 * math.pi - theta1)
    width, centre, direction = straight_band(points[straight])
    return {"path_error_m": float(np.abs(points - hoekens_path(sim.q[:, 0], a)).max()),
            "width_percent_of_crank": float(100 * width / a),
            "crossings": crossings(points[straight], centre, direction),
            "max_abs_delta_M": float(np.abs(sim.delta_M).max()), "steps": sim.steps,
            "published": HOEKEN_PUBLISHED}


def _null_velocity(loops, q, speed: float) -> np.ndarray:
    """A velocity the loops allow: the first null-space direction of J, scaled."""
    J = loops.evaluate(q, np.zeros(loops.model.n_v))[1]
    null = np.linalg.svd(J)[2][-1]
    return speed * null / np.abs(null).max()


def engines_check() -> list[dict]:
    """Each engine's constrained qdd and loop forces against the core's
    (redysim.references.loops), on the four-bar and a 20-rod pinned chain, at rest and moving: the
    worst relative differences (qdd by the larger of the constrained and the open tree's |qdd|),
    or the refusal."""
    import redysim
    from redysim.algorithms.linkages import four_bar, pinned_chain
    from redysim.model.shapes import catenary_angles
    from redysim.references.loops import LOOP_ENGINES, loop_engine

    fb = four_bar(0.3, 0.1, 0.35, 0.3, rp=0.2, gamma=0.4, density=2.0)
    chain = pinned_chain(20, 0.1, 0.1, 1.6)
    mechanisms = {"four-bar": (fb.loops, fb.configuration(1.0)),
                  "pinned chain, 20 rods": (chain.loops, catenary_angles(20, 2.0, 1.6))}
    rows = []
    for mech, (loops, q) in mechanisms.items():
        states = {"rest": np.zeros(loops.model.n_v), "moving": _null_velocity(loops, q, 2.0)}
        for name, cls in LOOP_ENGINES.items():
            row = {"mechanism": mech, "engine": name, "qdd": math.nan, "force": math.nan,
                   "refused": ""}
            try:
                if not cls.available():
                    row["refused"] = f"package {cls.package!r} not installed"
                elif not (lim := cls.limits(loops)).ok:
                    row["refused"] = lim.reason
                else:
                    eng = loop_engine(name, loops)
                    for label, v in states.items():
                        if why := eng.refusal(q, v):
                            row["refused"] += f"{label}: {why} "
                            continue
                        qdd, lam = eng.forward_dynamics_and_forces(q, v)
                        qdd_c, lam_c = loops.forward_dynamics_and_forces(q, v)
                        tree = redysim.forward_dynamics(loops.tree, q, v)
                        scale = max(np.abs(qdd_c).max(), np.abs(tree).max())
                        row["qdd"] = np.nanmax([row["qdd"], np.abs(qdd - qdd_c).max() / scale])
                        row["force"] = np.nanmax([row["force"], np.abs(lam - lam_c).max()
                                                  / np.abs(lam_c).max()])
            except Exception as exc:  # an engine's failure is a result, in its own words
                row["refused"] = f"failed: {type(exc).__name__}: {exc}"
            rows.append({k: (float(x) if isinstance(x, np.floating) else x)
                         for k, x in row.items()})
    return rows


ENGINE_SIZES = (20, 100, 300)  # rods of the pinned chains the engines are timed on
ENGINE_SIZES_FULL = (20, 100, 300, 1000)  # --full: MuJoCo's and DART's builds of 1,000 are slow
ENGINE_CALL_CAP_S = 0.5  # an engine slower than this per call is not tried on a larger chain


def engines_trajectories() -> list[dict]:
    """The four-bar from rest at crank 0.3 rad for 0.5 s in each engine's own integrator (h =
    1e-3 and 1e-4 s) against the core's (ode45, rtol 1e-11, projected): max |q - q_core| at the
    samples every 0.1 s, and the largest loop residual of the engine's run."""
    from redysim import simulate
    from redysim.algorithms.linkages import four_bar
    from redysim.references.loops import LOOP_ENGINES, loop_engine

    fb = four_bar(0.3, 0.1, 0.35, 0.3, rp=0.2, gamma=0.4, density=2.0)
    q0, v0 = fb.configuration(0.3), np.zeros(3)
    core = simulate(fb.model, 0.5, q0=q0, loops=fb.loops, rtol=1e-11, atol=1e-13, sample=0.1)
    rows = []
    for name, cls in LOOP_ENGINES.items():
        row = {"engine": name, "note": ""}
        if not cls.available() or not cls.integrator:
            row["note"] = ("not installed" if not cls.available()
                           else f"no integrator: {cls.no_integrator}")
            rows.append(row)
            continue
        eng = loop_engine(name, fb.loops)
        for h in (1e-3, 1e-4):
            traj = eng.simulate(q0, v0, 0.5, h, every=int(round(0.1 / h)))
            row[f"q_error_h{h:g}"] = float(np.abs(traj.q - core.q).max())
            row[f"residual_h{h:g}"] = max(fb.loops.residuals(q, v)[0]
                                          for q, v in zip(traj.q, traj.v, strict=True))
        row["integrator"] = traj.integrator
        rows.append(row)
    return rows


def engines_scale(sizes=ENGINE_SIZES) -> list[dict]:
    """Constrained qdd per call (at rest: DART takes no moving state) on pinned chains of
    ``sizes`` rods, each engine up to its limits or ENGINE_CALL_CAP_S a call; the core
    beside."""
    from redysim.algorithms.linkages import pinned_chain
    from redysim.model.shapes import catenary_angles
    from redysim.references.loops import LOOP_ENGINES, loop_engine

    rows, stopped = [], set()
    for n in sizes:
        chain = pinned_chain(n, 100.0 / n, 100.0 / n, 80.0)
        q, v = catenary_angles(n, 100.0, 80.0), np.zeros(n)
        for name, call in (("core", None), *LOOP_ENGINES.items()):
            row = {"engine": name, "n": n, "seconds": math.nan, "note": ""}
            if name in stopped:
                continue
            if name == "core":
                fn = lambda s=chain.loops, q=q, v=v: s.forward_dynamics(q, v)  # noqa: E731
            elif not call.available():
                continue
            elif not (lim := call.limits(chain.loops)).ok:
                row["note"] = lim.reason
                rows.append(row)
                stopped.add(name)
                continue
            else:
                t0 = time.perf_counter()
                eng = loop_engine(name, chain.loops)
                row["build_s"] = time.perf_counter() - t0
                fn = lambda eng=eng, q=q, v=v: eng.forward_dynamics(q, v)  # noqa: E731
            fn()
            best = math.inf
            for _ in range(3):
                t0 = time.perf_counter()
                fn()
                best = min(best, time.perf_counter() - t0)
            row["seconds"] = best
            rows.append(row)
            if best > ENGINE_CALL_CAP_S:
                stopped.add(name)
    return rows


def _joints(q, length):
    """Joint positions (n + 1, 2) of a planar chain of equal links from relative angles."""
    theta = np.cumsum(q)
    steps = length * np.column_stack([np.cos(theta), np.sin(theta)])
    return np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])


def catenary_checks() -> dict:
    from redysim import simulate
    from redysim.algorithms.linkages import discrete_catenary, pinned_chain
    from redysim.model.shapes import catenary_angles

    chain = pinned_chain(10, 0.1, 0.1, 0.8)
    start, rest = catenary_angles(10, 1.0, 0.8), discrete_catenary(chain)
    sim = simulate(chain.model, 10.0, q0=start, loops=chain.loops, damping=0.05, rtol=1e-9,
                   atol=1e-11, sample=1.0)
    settled = float(np.abs(sim.q[-1] - rest).max())
    gaps = []
    for n in (10, 20, 40, 80, 160):  # closed forms only: discrete against continuous
        c = pinned_chain(n, 1.0 / n, 0.1, 0.8)
        gaps.append({"n": n, "max_joint_gap_m": float(np.abs(
            _joints(discrete_catenary(c), 1.0 / n) - _joints(catenary_angles(n, 1.0, 0.8),
                                                             1.0 / n)).max())})
    orders = [math.log2(a["max_joint_gap_m"] / b["max_joint_gap_m"])
              for a, b in zip(gaps, gaps[1:], strict=False)]
    return {"settled_rad": settled, "start_off_rad": float(np.abs(start - rest).max()),
            "steps": sim.steps, "cpu_s": sim.cpu_s, "residual_q": sim.residual_q,
            "gaps": gaps, "orders": orders}


def cost() -> list[dict]:
    from redysim.algorithms.linkages import pinned_chain
    from redysim.model.shapes import catenary_angles

    rows = []
    for n in SIZES:
        chain = pinned_chain(n, 100.0 / n, 100.0 / n, 80.0)
        q, v = catenary_angles(n, 100.0, 80.0), np.zeros(n)
        chain.loops.forward_dynamics(q, v)  # compile or load, not timed
        calls = max(3, int(2e5 // n))
        best = math.inf
        for _ in range(5):
            t0 = time.perf_counter()
            for _ in range(calls):
                chain.loops.forward_dynamics(q, v)
            best = min(best, (time.perf_counter() - t0) / calls)
        rows.append({"n": n, "seconds": best})
    return rows


def long_chain(t_end: float) -> dict:
    from redysim import simulate
    from redysim.algorithms.linkages import pinned_chain
    from redysim.model.shapes import catenary_angles

    chain = pinned_chain(LONG_N, 100.0 / LONG_N, 100.0 / LONG_N, 80.0)
    sim = simulate(chain.model, t_end, q0=catenary_angles(LONG_N, 100.0, 80.0),
                   loops=chain.loops, sample=t_end / 4)
    return {"n": LONG_N, "t_end": t_end, "status": sim.status, "message": sim.message,
            "steps": sim.steps, "nfev": sim.nfev, "cpu_s": sim.cpu_s,
            "max_abs_delta_M": float(np.abs(sim.delta_M).max()),
            "residual_q": sim.residual_q, "residual_v": sim.residual_v}


def run(out: Path, full: bool = False, log=print) -> dict:
    from redysim.harness.provenance import provenance
    from redysim.harness.store import write_json_atomic

    log("loops: four-bar")
    doc = {"four_bar": four_bar_check()}
    log("loops: Hoeken's straight-line linkage")
    doc["hoekens"] = hoekens_check()
    log("loops: the engines")
    doc["engines"] = engines_check()
    log("loops: the engines' trajectories and cost")
    doc["engine_trajectories"] = engines_trajectories()
    doc["engine_scale"] = engines_scale(ENGINE_SIZES_FULL if full else ENGINE_SIZES)
    log("loops: pinned chain and catenaries")
    doc["catenary"] = catenary_checks()
    log("loops: cost against n")
    doc["cost"] = cost()
    ns = np.log([r["n"] for r in doc["cost"]])
    ts = np.log([r["seconds"] for r in doc["cost"]])
    doc["slope"] = float(np.polyfit(ns[2:], ts[2:], 1)[0])  # the O(n) regime: 1,000 and up
    log(f"loops: {LONG_N:,} rods")
    doc["long"] = long_chain(1.0 if full else 0.05)  # quick: 0.05 s, for the quick budget
    doc["provenance"] = provenance()
    out.mkdir(parents=True, exist_ok=True)
    write_json_atomic(doc, out / "loops.json")
    return doc


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=Path("results") / "loops")
    ap.add_argument("--full", action="store_true", help="the 10,000-rod chain for 1 s")
    a = ap.parse_args(argv)
    doc = run(a.out, a.full)
    print(f"four-bar path {doc['four_bar']['path_error_m']:.1e} m; chain settled "
          f"{doc['catenary']['settled_rad']:.1e} rad; slope {doc['slope']:.2f}; "
          f"{LONG_N} rods: {doc['long']['steps']} steps, {doc['long']['cpu_s']:.1f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
