"""An experiment toward an O(n) implicit integrator (not the integrator): implicit midpoint in
joint coordinates, its Newton systems solved matrix-free by GMRES, preconditioned in O(n).

    .venv/bin/python benchmarks/implicit_prototype.py [--case RE-U750-L6] [--t-end 0.3]
        [--h 1e-3 2.5e-3 5e-3 1e-2] [--no-precondition] [--out results/bench/implicit.json]

The scheme (docs/design.md, "Toward an implicit integrator"): with w the midpoint velocity,
q1 = q0 + h w, v1 = 2 w - v0, and w solves

    R(w) = w - v0 - (h/2) a(q0 + (h/2) w, w) = 0,        a = the core's qdd (RGE-A, O(n)).

Newton on R from w = v0 (an explicit predictor overshoots the stiff modes), each correction by
GMRES (relative tolerance 1e-3) on the preconditioned system P^-1 J u = -P^-1 R, with
J u = u - (h/2) [a(q_m + (h/2) e u, w + e u) - a] / e (one qdd a product, e |u| = 1e-3 (1 + |w|));
Newton stops when |P^-1 R| <= 1e-6 |w| (``--newton-tol``): with P^-1 J ~ 1 that is the size of the
next correction; or when it stops contracting below 1e-4 |w| (qdd's round-off floor).
Preconditioner: the tension stiffens each link's orientation (a string's geometric stiffness; for a
hanging chain it is the exact K), so J ~ M^-1 (M + c K), c = h^2/4, with K = sum_k J_k^T (T_k l_k (1
- d d^T)) J_k (J_k: link k's angular Jacobian, d its axis): the GIM of the chain whose links carry
the added rotational inertia c T_k l_k about their transverse axes. Applied as P^-1 r = (M + c K)^-1
M r = r - (M + c K)^-1 (c K r): c K r is a torque on every link from its rotation J_k r (one pass
down the chain and one back, numpy), and the solve one RGE-A call on a workspace with augmented
inertias: O(n), no matrix. T_k: the mean axial tension of link k from the Newton-Euler wrenches at
the step's start (clipped at 0).

Three things the first version did otherwise, and why they matter at 100,000 DOF (docs/design.md,
"Toward an implicit integrator"): it formed M r by inverse dynamics and solved (M + c K) x = M r,
which loses the smooth components of r entirely there (the GIM's condition number: M^-1 (M r)
came back 150x off for a smooth r); its finite-difference products took e |u| = 1e-7, at which a
smooth u's product is pure round-off (it scaled as 1/e), and Newton then fed that noise back into
the motion; and it tested |R|, which the stiff modes dominate long after the correction they
ask for is below round-off, so GMRES ran to its cap at every step.

A long run (``--long OUT.npz``) keeps the tip and delta_M every sample as it goes:

    .venv/bin/python benchmarks/implicit_prototype.py --case RE-U50000-L1000 --h 5e-4 \
        --t-end 5 --sample 0.01 --long results/bench/implicit-U50000-5s.npz
    .venv/bin/python benchmarks/implicit_prototype.py --case RE-U50000-L1000 --h 0 \
        --t-end 0.48 --sample 0.01 --long results/bench/ode45-U50000-0.48s.npz

Compared with the core's ode45 at the paper's tolerances and with DOP853 at 1e-10 as the
reference: CPU, qdd calls, Newton and GMRES iterations, max tip error over the samples. The
Newton-Krylov loop here is plain Python and SciPy; a production version would compile it.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np
from scipy.sparse.linalg import LinearOperator, gmres

from redysim import Workspace, energy, forward_dynamics, inverse_dynamics, load_case, tip
from redysim.integrate import CompiledSolver, advance

# Newton stops short of newton_tol when |P^-1 R| no longer halves and is below this (relative to
# |w|): the residual has reached the round-off floor of qdd. On RE-U50000-L1000 at h = 5e-4 the
# floor rises from 4e-8 at the start to 1.0e-6 at t = 0.31 s, where a tolerance of 1e-6 alone
# stalled Newton for 20 iterations at |P^-1 R| = 1.02e-6 to 1.07e-6.
FLOOR_TOL = 1e-4


class ImplicitMidpoint:
    """Fixed-step implicit midpoint on a chain, Newton-Krylov with the O(n) preconditioner."""

    def __init__(self, chain, precondition: bool = True, newton_tol: float = 1e-6,
                 fd_eps: float = 1e-3):
        self.chain, self.n = chain, chain.n_dof
        self.ws, self.ws_id = Workspace(chain), Workspace(chain)
        self.ws_p = Workspace(chain)  # augmented inertias, for the linear solves: no gravity
        self.ws_p.base_accel[:] = 0.0
        self.ws_p.gravity[:] = 0.0
        self.inertia0 = self.ws_p.tree.inertia_O.copy()
        self.precondition = precondition
        self.newton_tol = newton_tol
        self.fd_eps = fd_eps
        self.ws_k = Workspace(chain)  # frames at the Newton iterate
        off = chain.joint_qoff
        self.link_of = np.repeat(np.arange(len(off) - 1), np.diff(off))  # each DOF's link
        self.last_dof = off[1:] - 1
        self.zeros = np.zeros(self.n)
        self.stats = {"steps": 0, "newton": 0, "krylov": 0, "qdd_calls": 0}

    def _count(self, _residual):
        self.stats["krylov"] += 1

    def qdd(self, q, v):
        self.stats["qdd_calls"] += 1
        return forward_dynamics(self.chain, q, v, ws=self.ws)

    def tensions(self, q, v):
        """Mean axial tension of each link (>= 0) from the Newton-Euler wrenches."""
        inverse_dynamics(self.chain, q, v, self.qdd(q, v), ws=self.ws_id)
        force = self.ws_id.s.W[:, 3:]  # the force each joint passes to its link and beyond
        d = self.ws_id.oR[:, :, 0]  # link axes (world)
        t_in = -np.einsum("ki,ki->k", force, d)
        t_out = -np.einsum("ki,ki->k", np.vstack([force[1:], np.zeros((1, 3))]), d)
        return np.maximum(0.5 * (t_in + t_out), 0.0)

    def set_preconditioner(self, q, v, h):
        self.add = (h * h / 4.0) * self.tensions(q, v) * self.chain.length  # c T_k l_k
        inertia = self.ws_p.tree.inertia_O  # a view of the workspace's packed arrays
        inertia[:] = self.inertia0
        inertia[:, 1, 1] += self.add
        inertia[:, 2, 2] += self.add

    def set_frames(self, q):
        """Joint axes and link axes (world) at q, for c K r."""
        forward_dynamics(self.chain, q, self.zeros, ws=self.ws_k, planar=False)
        self.axes = self.ws_k.oP[:, :3].copy()
        self.link_x = self.ws_k.oR[:, :, 0].copy()

    def apply_preconditioner(self, q, r):
        """r - (M + c K)^-1 (c K r), at the frames of :meth:`set_frames`."""
        e, d = self.axes, self.link_x
        turn = np.cumsum(e * r[:, None], axis=0)[self.last_dof]  # link k's rotation J_k r
        turn -= d * np.einsum("ki,ki->k", d, turn)[:, None]  # its transverse part
        torque = -self.add[:, None] * turn
        outboard = np.cumsum(torque[::-1], axis=0)[::-1]  # the torques at and beyond link k
        Q = np.einsum("ji,ji->j", e, outboard[self.link_of])  # generalized forces
        return r + forward_dynamics(self.chain, q, self.zeros, Q, ws=self.ws_p, planar=False)

    def step(self, q0, v0, h):
        w = v0.copy()
        if self.precondition:
            self.set_preconditioner(q0, v0, h)
        n = self.n
        last = np.inf
        for _ in range(20):
            qm = q0 + 0.5 * h * w
            am = self.qdd(qm, w)
            R = w - v0 - 0.5 * h * am
            if self.precondition:
                self.set_frames(qm)

            def pre(r, qm=qm):
                return self.apply_preconditioner(qm, r) if self.precondition else r

            pr = pre(R)
            size = np.linalg.norm(pr)
            if size <= self.newton_tol * (np.linalg.norm(w) + 1e-30):
                break
            if size > 0.5 * last and size <= FLOOR_TOL * np.linalg.norm(w):
                break  # no longer contracting: the round-off floor of qdd, accepted
            last = size

            def jv(u, qm=qm, w=w, am=am, pre=pre):
                u = np.asarray(u).ravel()
                nu = np.linalg.norm(u)
                if nu == 0.0:
                    return np.zeros_like(u)
                e = self.fd_eps * (1.0 + np.linalg.norm(w)) / nu
                return pre(u - 0.5 * h * (self.qdd(qm + 0.5 * h * e * u, w + e * u) - am) / e)

            du, _ = gmres(LinearOperator((n, n), matvec=jv), -pr, rtol=1e-3, atol=0.0,
                          restart=60, maxiter=20, callback=self._count,
                          callback_type="pr_norm")
            self.stats["newton"] += 1
            w = w + du
        else:
            raise RuntimeError(f"Newton did not converge in 20 iterations (h = {h:g})")
        self.stats["steps"] += 1
        return q0 + h * w, 2.0 * w - v0


def implicit_run(case, t_end, h, sample, precondition=True, newton_tol=1e-6):
    chain = case.chain
    integ = ImplicitMidpoint(chain, precondition, newton_tol)
    q, v = case.q0.copy(), case.qd0.copy()
    every = int(round(sample / h))
    tips = []
    cpu0 = time.process_time()
    for i in range(int(round(t_end / h))):
        if i % every == 0:
            tips.append(tip(chain, q, v).position)
        q, v = integ.step(q, v, h)
    tips.append(tip(chain, q, v).position)
    return np.array(tips), time.process_time() - cpu0, integ.stats


def explicit_run(case, t_end, sample, method, rtol):
    chain, n = case.chain, case.chain.n_dof
    ws = Workspace(chain)

    def rhs(_t, y):
        return np.concatenate((y[n:], forward_dynamics(chain, y[:n], y[n:], ws=ws)))

    s = CompiledSolver(rhs, 0.0, np.concatenate((case.q0, case.qd0)), t_end, method, ws=ws,
                       planar=chain.is_planar, rtol=rtol, atol=rtol * 1e-2)
    tips = []
    cpu0 = time.process_time()
    advance(s, np.arange(0.0, t_end + 1e-12, sample),
            on_sample=lambda _t, y: tips.append(tip(chain, y[:n], y[n:]).position))
    return np.array(tips), time.process_time() - cpu0, s.counters


def long_run(case, t_end, sample, h, out: Path) -> dict:
    """One long run, the implicit prototype at step h (or ode45 at the case's tolerances when h
    is None): tip and delta_M every ``sample`` s, saved to ``out`` (.npz) every 10 samples and at
    the end, so that a killed run keeps what it did. Returns its counts, CPU and peak RSS."""
    import resource

    chain, n = case.chain, case.chain.n_dof
    E0, mass = sum(energy(chain, case.q0, case.qd0)), chain.total_mass
    times, tips, dM, stats = [], [], [], {}
    cpu0 = time.process_time()

    def record(t, q, v):
        times.append(t)
        tips.append(tip(chain, q, v).position)
        dM.append((sum(energy(chain, q, v)) - E0) / mass)
        stats.update(cpu_s=time.process_time() - cpu0,
                     peak_rss_mib=resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024)
        print(f"t = {t:.3f} s, CPU {stats['cpu_s']:.0f} s, {stats}", flush=True)
        if len(times) % 10 == 0 or t >= t_end - 1e-12:
            np.savez(out, t=np.array(times), tip=np.array(tips), delta_M=np.array(dM),
                     stats=json.dumps(stats))

    if h is None:
        ws = Workspace(chain)

        def rhs(_t, y):
            return np.concatenate((y[n:], forward_dynamics(chain, y[:n], y[n:], ws=ws)))

        s = CompiledSolver(rhs, 0.0, np.concatenate((case.q0, case.qd0)), t_end, "ode45",
                           ws=ws, planar=chain.is_planar, rtol=case.rtol, atol=case.atol)

        def on_sample(t, y):
            stats.update(steps=s.counters.steps, qdd_calls=s.counters.nfev)
            record(t, y[:n], y[n:])

        advance(s, np.arange(0.0, t_end + 1e-12, sample), on_sample=on_sample)
        return stats
    integ = ImplicitMidpoint(chain)
    q, v = case.q0.copy(), case.qd0.copy()
    every = int(round(sample / h))
    record(0.0, q, v)
    for i in range(int(round(t_end / h))):
        q, v = integ.step(q, v, h)
        if (i + 1) % every == 0:
            stats.update(integ.stats)
            record((i + 1) * h, q, v)
    return stats


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--case", default="RE-U750-L6")
    ap.add_argument("--t-end", type=float, default=0.3)
    ap.add_argument("--sample", type=float, default=0.05)
    ap.add_argument("--h", type=float, nargs="+", default=[1e-3, 2.5e-3, 5e-3, 1e-2])
    ap.add_argument("--no-precondition", action="store_true")
    ap.add_argument("--newton-tol", type=float, default=1e-6,
                    help="Newton stops at |R| <= tol |w| (default 1e-6: on RE-U750-L6 1e-8 and "
                         "1e-10 gave the same tip error, at 1.2x and 5x the qdd calls)")
    ap.add_argument("--out", type=Path, default=Path("results/bench/implicit.json"))
    ap.add_argument("--long", type=Path, metavar="OUT.npz",
                    help="one long run instead (the first --h, or ode45 with --h 0), its "
                         "samples kept in OUT.npz as it goes")
    args = ap.parse_args(argv)
    case = load_case(args.case)
    if args.long is not None:
        args.long.parent.mkdir(parents=True, exist_ok=True)
        h = args.h[0] or None
        print(long_run(case, args.t_end, args.sample, h, args.long))
        return 0
    ref, ref_cpu, ref_c = explicit_run(case, args.t_end, args.sample, "dop853", 1e-10)
    rows = []
    tips, cpu, c = explicit_run(case, args.t_end, args.sample, "ode45", case.rtol)
    rows.append({"scheme": f"ode45 rtol {case.rtol:g}", "cpu_s": cpu, "steps": c.steps,
                 "qdd_calls": c.nfev, "tip_err": float(np.linalg.norm(tips - ref, axis=1).max())})
    for h in args.h:
        try:
            tips, cpu, st = implicit_run(case, args.t_end, h, args.sample,
                                         not args.no_precondition, args.newton_tol)
            err = float(np.linalg.norm(tips - ref, axis=1).max())
        except Exception as exc:  # Newton may diverge at large steps: report, go on
            rows.append({"scheme": f"implicit midpoint h {h:g}", "failed": str(exc)[:120]})
            continue
        rows.append({"scheme": f"implicit midpoint h {h:g}", "cpu_s": cpu, **st,
                     "tip_err": err})
    for r in rows:
        print(r)
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps({"case": case.name, "t_end": args.t_end,
                                    "reference": {"cpu_s": ref_cpu, "steps": ref_c.steps},
                                    "runs": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
