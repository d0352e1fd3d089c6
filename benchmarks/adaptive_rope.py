"""Does a rope whose resolution follows the motion pay, on the whip and the pulled hook?

An experiment, not a feature (docs/design.md, "Adaptive resolution: measured, not built"). The
issue "model only what a scene requires" asks for a rope whose groups of links are welded where
it moves as a rigid piece and released where it bends, at least 2x cheaper than the best static
coarse model at the tolerance that model meets, on the whip (``cases/refine/fall-R256.toml`` over
0.8 s, tip-path tolerance 5e-2 m) and on the pulled hook (``cases/refine/pulled-R128.toml`` over
1 s, 1e-3 m). Before building it in compiled code this script measures, in work that no machine's
load changes (RHS calls x links: the O(n) recursions' work, as ``redysim advise --cost work``):

1. **The best static model at any link count**: the same physical rope rebuilt with N uniform
   links (its case file with ``[chain] links = N``), not only the divisors of the fine model's
   count that :func:`redysim.coarsen` can lump to.
2. **Resolution chosen by an indicator**: the fine rope's links grouped along a binary tree of
   link ranges; a group is welded (its relative angles held: :meth:`redysim.Model.locked`) or
   split into its two halves. Every interval (the samples' 0.01 s) the accelerations of the
   joints' points under the fine model are compared with those under the current grouping (the
   motion metric of Redon, Galoppo and Lin 2005): a group whose points would drift apart by more
   than ``eps`` within a horizon (0.05 s), counting the drift already accumulated while welded,
   is split (repeatedly, within the interval); two sibling groups whose joint is quiet (its rate
   and the pair's deviation under a quarter of ``eps``) are welded. Welding is an inelastic
   impulse: the velocities become argmin (v - G u)^T M (v - G u), which keeps G^T M v (the
   angular momentum about every remaining joint, the pin's included) and loses kinetic energy
   (recorded); a release changes nothing. Between switches ode45 steps the welded model, its
   step size carried over from interval to interval.
3. **An oracle over time**: uniform models switched at chosen times (coarse during the fall,
   finer through the whip, coarse again after), no indicator: what time-adaptivity alone could
   give.

Errors are the largest tip distance over the samples to the study's reference (the fine model by
DOP853 at 1e-10, as ``sweeps/refine-*.toml``). Intervals cost extra steps (each ends on a sample
time and restarts the RK stages): the script measures that overhead on a fixed uniform grouping
run through the same machinery and reports each adaptive run's work also divided by it.

    python benchmarks/adaptive_rope.py [--scene whip|pulled] [--out results/bench]

Writes ``adaptive_rope.json`` (every run: error, work, switches, mean and largest group count,
energy lost at welds, largest momentum residual) into ``--out``. About 3 minutes for both scenes
on 2 cores.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from redysim.algorithms.dynamics import forward_dynamics, mass_matrix
from redysim.algorithms.loads import tip_force_torques
from redysim.algorithms.workspace import Workspace
from redysim.harness.provenance import provenance
from redysim.integrators.explicit import Solver
from redysim.io.cases import CASES_DIR, case_from_dict, load_case, read_toml

SCENES = {  # case, horizon [s], tip tolerance [m], reference atol (as its refinement sweep)
    "whip": ("fall-R256.toml", 0.8, 5e-2, 1e-12),
    "pulled": ("pulled-R128.toml", 1.0, 1e-3, 1e-10),
}
RTOL = 1e-3  # ode45's tolerance: the static advice's setting on both scenes
INTERVAL = 0.01  # s: the samples; switches are decided at their times
HORIZON = 0.05  # s: the indicator's look-ahead
KAPPA = 0.25  # weld only below KAPPA * eps (hysteresis)
STATIC_LINKS = {"whip": (6, 7, 8, 9, 10, 12, 16), "pulled": (4, 6, 8, 10, 11, 12, 16)}
INDICATOR = {"whip": [(eps, lo, hi) for eps in (1e-2, 3e-2, 1e-1)
                      for lo, hi in ((4, 16), (8, 16), (4, 32))],
             "pulled": [(eps, lo, hi) for eps in (1e-4, 1e-3, 1e-2)
                        for lo, hi in ((4, 16), (4, 64))]}
ORACLE = {"whip": ([(0.0, 8)], [(0.0, 8), (0.4, 16)], [(0.0, 8), (0.4, 16), (0.6, 8)],
                   [(0.0, 4), (0.3, 16)], [(0.0, 8), (0.4, 32), (0.55, 8)]),
          "pulled": ([(0.0, 8)], [(0.0, 4), (0.5, 16)], [(0.0, 8), (0.5, 16)],
                     [(0.0, 16), (0.5, 8)])}


def tip(q, lengths):
    """The planar chain's tip (x, y) for relative angles q."""
    phi = np.cumsum(q)
    return np.array([lengths @ np.cos(phi), lengths @ np.sin(phi)])


def point_accelerations(q, v, qdd, lengths):
    """(n + 1, 2): the accelerations of the joints' points and of the tip."""
    phi, w, alpha = np.cumsum(q), np.cumsum(v), np.cumsum(qdd)
    e = np.stack([np.cos(phi), np.sin(phi)], 1)
    n = np.stack([-np.sin(phi), np.cos(phi)], 1)
    da = lengths[:, None] * (alpha[:, None] * n - (w ** 2)[:, None] * e)
    return np.vstack([np.zeros(2), np.cumsum(da, 0)])


class Scene:
    def __init__(self, name: str):
        file, self.t_end, self.tol, ref_atol = SCENES[name]
        self.name, self.path = name, CASES_DIR / "refine" / file
        self.case = load_case(self.path)
        self.fine = self.case.chain
        self.n = self.fine.n_links
        self.lengths = self.fine.length.copy()
        self.force = None if self.case.tip_force is None else np.asarray(self.case.tip_force)
        self.ts = np.linspace(0.0, self.t_end, int(round(self.t_end / INTERVAL)) + 1)
        ref = self.case.simulator(self.t_end, integrator="dop853", rtol=1e-10, atol=ref_atol,
                                  sample=INTERVAL).run()
        self.ref = np.array([tip(q, self.lengths) for q in ref.q])

    def error(self, tips) -> float:
        return float(np.linalg.norm(np.asarray(tips) - self.ref, axis=1).max())

    def tau(self, q):
        return None if self.force is None else tip_force_torques(self.fine, q, self.force)

    # ------------------------------------------------------------------ static, any N
    def static(self, links: int) -> dict:
        doc, _ = read_toml(self.path)
        doc = {**doc, "chain": {**doc["chain"], "links": links}}
        case = case_from_dict(doc, source=str(self.path))
        run = case.simulator(self.t_end, integrator="ode45", rtol=RTOL, atol=RTOL * 1e-2,
                             sample=INTERVAL).run()
        tips = [tip(q, case.chain.length) for q in run.q]
        return {"links": links, "error": self.error(tips), "nfev": run.nfev,
                "work": run.nfev * links}

    # ------------------------------------------------------------------ grouped runs
    def grouped(self, policy) -> dict:
        """A run whose grouping ``policy(k, q, v, groups, state) -> groups`` decides at each
        interval's start; welds project the velocities (module docstring)."""
        q, v = self.case.q0.copy(), self.case.v0.copy()
        groups = policy(0, q, v, None, {})
        state: dict = {}
        work, switches, welds_dE, residual, counts = 0, 0, [], 0.0, []
        tips = [tip(q, self.lengths)]
        h_next = 0.0
        for k in range(len(self.ts) - 1):
            new = policy(k, q, v, groups, state)
            starts_old = {a for a, _ in groups}
            starts_new = {a for a, _ in new}
            switches += len(starts_old ^ starts_new)
            if starts_old - starts_new:  # a weld: the impulse that keeps G^T M v
                free = sorted(starts_new)
                M = mass_matrix(self.fine, q)
                G = np.zeros((self.n, len(free)))
                G[free, np.arange(len(free))] = 1.0
                p = G.T @ M @ v
                e0 = 0.5 * v @ M @ v
                v = G @ np.linalg.solve(G.T @ M @ G, p)
                welds_dE.append(0.5 * v @ M @ v - e0)
                residual = max(residual, float(np.abs(G.T @ M @ v - p).max()))
            groups = new
            free = [a for a, _ in groups]
            welded = {self.fine.joint_names[j]: float(q[j])
                      for j in sorted(set(range(self.n)) - set(free))}
            model = self.fine.locked(welded) if welded else self.fine
            ws, nf, frozen = Workspace(model), len(free), q.copy()

            def rhs(_t, y, free=free, nf=nf, frozen=frozen, model=model, ws=ws):
                tau = None
                if self.force is not None:
                    full = frozen.copy()
                    full[free] = y[:nf]
                    tau = self.tau(full)[free]
                return np.concatenate((y[nf:], forward_dynamics(model, y[:nf], y[nf:], tau,
                                                                ws=ws)))

            solver = Solver(rhs, self.ts[k], np.concatenate((q[free], v[free])),
                            self.ts[k + 1], "ode45", rtol=RTOL, atol=RTOL * 1e-2,
                            hmax=0.1 * self.t_end)  # ode45's default for the whole run
            if h_next:
                solver.h_next = h_next
            while solver.t < self.ts[k + 1]:
                solver.step()
                if solver.t < self.ts[k + 1]:  # not the step cut to land on the sample
                    h_next = solver.h_next
            work += solver.counters.nfev * nf
            counts.append(nf)
            q, v = q.copy(), v.copy()
            q[free], v[free] = solver.y[:nf], solver.y[nf:]
            tips.append(tip(q, self.lengths))
        return {"error": self.error(tips), "work": work, "switches": switches,
                "mean_groups": float(np.mean(counts)), "max_groups": int(max(counts)),
                "weld_energy_J": float(sum(welds_dE)), "momentum_residual": residual,
                "groups_every_0.1s": counts[::10]}

    def uniform(self, count):
        return [(i * self.n // count, (i + 1) * self.n // count) for i in range(count)]

    def schedule(self, plan):
        """A policy: uniform groupings switched at the plan's times [(t, count), ...]."""
        def policy(k, _q, _v, _groups, _state):
            count = [c for t, c in plan if self.ts[k] >= t - 1e-12][-1]
            return self.uniform(count)
        return policy

    def indicator(self, eps, coarsest, finest):
        """A policy: split where the grouping's motion leaves the fine rope's, weld where quiet
        (module docstring); never fewer than ``coarsest`` or more than ``finest`` groups."""
        lo_size, hi_size = self.n // finest, self.n // coarsest

        def deviation(q, v, groups, fine_acc, tau):
            free = [a for a, _ in groups]
            welded = {self.fine.joint_names[j]: float(q[j])
                      for j in sorted(set(range(self.n)) - set(free))}
            model = self.fine.locked(welded) if welded else self.fine
            qdd = np.zeros(self.n)
            qdd[free] = forward_dynamics(model, q[free], v[free],
                                         None if tau is None else tau[free])
            acc = point_accelerations(q, v, qdd, self.lengths)
            return np.linalg.norm(fine_acc - acc, axis=1)  # (n + 1,) m/s^2

        def policy(k, q, v, groups, state):
            if groups is None:
                return self.uniform(coarsest)
            tau = self.tau(q)
            fine_acc = point_accelerations(q, v, forward_dynamics(self.fine, q, v, tau),
                                           self.lengths)
            drift = state.setdefault("drift", {})  # group -> (rate, distance) drifted welded
            for _ in range(32):
                dev = deviation(q, v, groups, fine_acc, tau)
                out, split = [], False
                for a, b in groups:
                    da = float(dev[a:b + 1].max())
                    u, d = drift.get((a, b), (0.0, 0.0))
                    if b - a > lo_size and d + u * HORIZON + 0.5 * da * HORIZON ** 2 > eps:
                        m = (a + b) // 2
                        out += [(a, m), (m, b)]
                        split = True
                    else:
                        out.append((a, b))
                groups = out
                if not split:
                    break
            for a, b in groups:  # the drift a welded group accumulates this interval
                if b - a > 1:
                    da = float(dev[a:b + 1].max())
                    u, d = drift.get((a, b), (0.0, 0.0))
                    drift[(a, b)] = (u + da * INTERVAL, d + u * INTERVAL + 0.5 * da * INTERVAL ** 2)
            out, i = [], 0
            while i < len(groups):
                if i + 1 < len(groups):
                    (a, m), (_, b) = groups[i], groups[i + 1]
                    if self._siblings(a, m, b) and b - a <= hi_size:
                        quiet = (abs(v[m]) * HORIZON * self.lengths[a:b].sum() / 2
                                 + 0.5 * float(dev[a:b + 1].max()) * HORIZON ** 2)
                        if quiet < KAPPA * eps:
                            out.append((a, b))
                            drift.pop((a, b), None)
                            i += 2
                            continue
                out.append(groups[i])
                i += 1
            return out
        return policy

    def _siblings(self, a, m, b) -> bool:
        """Whether [a, m) and [m, b) are the two halves of one range of the binary tree."""
        lo, hi = 0, self.n
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if (lo, mid, hi) == (a, m, b):
                return True
            if b <= mid:
                hi = mid
            elif a >= mid:
                lo = mid
            else:
                return False
        return False


def study(name: str) -> dict:
    scene = Scene(name)
    out: dict = {"scene": name, "case": scene.path.name, "t_end": scene.t_end,
                 "tip_tol": scene.tol, "rtol": RTOL, "static": [], "indicator": [],
                 "oracle": []}
    for links in STATIC_LINKS[name]:
        row = scene.static(links)
        out["static"].append(row)
        print(f"{name} static {links:3d} links: error {row['error']:.3e} m, work {row['work']}",
              flush=True)
    # the interval machinery's own overhead: a fixed uniform grouping through it
    base = min((r for r in out["static"] if r["links"] == 8), key=lambda r: r["work"])
    fixed = scene.grouped(scene.schedule([(0.0, 8)]))
    out["interval_overhead"] = fixed["work"] / base["work"]
    for plan in ORACLE[name]:
        row = {"plan": plan, **scene.grouped(scene.schedule(plan))}
        row["work_normalised"] = row["work"] / out["interval_overhead"]
        out["oracle"].append(row)
        print(f"{name} oracle {plan}: error {row['error']:.3e} m, work {row['work']} "
              f"({row['work_normalised']:.0f} normalised)", flush=True)
    for eps, lo, hi in INDICATOR[name]:
        row = {"eps": eps, "coarsest": lo, "finest": hi,
               **scene.grouped(scene.indicator(eps, lo, hi))}
        row["work_normalised"] = row["work"] / out["interval_overhead"]
        out["indicator"].append(row)
        print(f"{name} indicator eps {eps:g} [{lo}, {hi}] groups: error {row['error']:.3e} m, "
              f"work {row['work']} ({row['work_normalised']:.0f} normalised), mean groups "
              f"{row['mean_groups']:.1f}, switches {row['switches']}, weld energy "
              f"{row['weld_energy_J']:.2e} J, momentum residual "
              f"{row['momentum_residual']:.1e}", flush=True)
    within = [r for r in out["static"] if r["error"] <= scene.tol]
    best = min(within, key=lambda r: r["work"])
    adaptive = [r for r in out["indicator"] + out["oracle"] if r["error"] <= scene.tol]
    out["best_static"] = best
    out["best_adaptive"] = (min(adaptive, key=lambda r: r["work_normalised"]) if adaptive
                            else None)
    print(f"{name}: best static within {scene.tol:g} m: {best['links']} links, work "
          f"{best['work']}; best adaptive: "
          + (f"work {out['best_adaptive']['work_normalised']:.0f} normalised "
             f"({out['best_adaptive']['work_normalised'] / best['work']:.2f}x the static)"
             if adaptive else "none within the tolerance"), flush=True)
    return out


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scene", choices=sorted(SCENES), action="append",
                    help="a scene (default: both)")
    ap.add_argument("--out", default="results/bench", help="folder for adaptive_rope.json")
    args = ap.parse_args(argv)
    results = {"provenance": provenance(), "scenes": [study(s) for s in
                                                      (args.scene or sorted(SCENES))]}
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "adaptive_rope.json").write_text(json.dumps(results, indent=1, default=float))
    print(f"wrote {out / 'adaptive_rope.json'}")


if __name__ == "__main__":
    main()
