"""Can the implicit midpoint step (q, p), p = I(q) qd, on a long chain? Measured, not built.

An experiment, not a feature (docs/design.md, "Symplectic in joint coordinates: measured, not
built"). The implicit midpoint rule on (q, v) with a configuration-dependent I(q) is not
symplectic; on (q, p) it is (and it is then the midpoint variational integrator). Its residual
for the midpoint velocity w of a step of size h from (q0, p0) is

    R(w) = w - I(q_m)^-1 (p0 + (h/2) F(q_m, w)),   q_m = q0 + (h/2) w,
    F = dp/dt = dL/dq + tau   (:func:`redysim.generalized_momentum`, O(n)),

then q1 = q0 + h w, p1 = p0 + h F. This script solves both rules' steps by Newton with a dense
finite-difference Jacobian (exact to its differences: no Krylov method or preconditioner to blame)
and measures:

``--part chain``: RE-U250-L2 (500 DOF, the case's spinning rope) at h = 1e-3 from its initial
state: the (q, p) residual at the (q, v) rule's solution; how far I(q)^-1 p0 moves when q moves
by a fraction s of that step's (h/2) w (the dense GIM's solve beside the O(n) one: the kernels
are not at fault); Newton on the (q, p) residual from there.

``--part robot``: the PUMA 560 at a fixed h = 1e-2 over 200 s from q = 0.3, qd = 0.5 (every
joint): both rules' largest |delta_M| and CPU.

    python benchmarks/symplectic_midpoint.py [--part chain|robot|both]

About 1 minute on one core.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from redysim import energy, forward_dynamics, generalized_momentum, mass_matrix
from redysim.algorithms.workspace import Workspace
from redysim.io.cases import load_case
from redysim.io.dh import load_robot

ROOT = Path(__file__).resolve().parents[1]


class Rules:
    """Both midpoint rules' residuals for one model (no applied forces)."""

    def __init__(self, model):
        self.model = model
        self.ws = Workspace(model)
        self.free = Workspace(model)  # I(q)^-1 p: at rest, no gravity
        self.free.base_accel[:] = 0.0
        self.free.gravity[:] = 0.0
        self.zeros = np.zeros(model.n_v)

    def velocity(self, q, p):
        return forward_dynamics(self.model, q, self.zeros, p, ws=self.free)

    def qv(self, q0, v0, h, w):
        qm = q0 + 0.5 * h * w
        return w - v0 - 0.5 * h * forward_dynamics(self.model, qm, w, ws=self.ws)

    def qp(self, q0, p0, h, w):
        qm = q0 + 0.5 * h * w
        F = generalized_momentum(self.model, qm, w, ws=self.ws, gradient=True)[1]
        return w - self.velocity(qm, p0 + 0.5 * h * F)


def newton(residual, w, *, iterations=30, tol=1e-13, e=1e-7, log=None):
    """Dense Newton with a forward-difference Jacobian; the residual's norms go to ``log``."""
    n = w.size
    for _ in range(iterations):
        r = residual(w)
        if log is not None:
            log.append(float(np.linalg.norm(r)))
        if np.linalg.norm(r) <= tol * (1.0 + np.linalg.norm(w)):
            return w
        J = np.empty((n, n))
        for i in range(n):
            wi = w.copy()
            wi[i] += e
            J[:, i] = (residual(wi) - r) / e
        w = w - np.linalg.solve(J, r)
    return w


def chain_part() -> None:
    case = load_case("RE-U250-L2")
    model, q0, v0, h = case.chain, case.q0, case.v0, 1e-3
    rules = Rules(model)
    p0 = generalized_momentum(model, q0, v0)
    wv = newton(lambda w: rules.qv(q0, v0, h, w), v0.copy())
    print(f"RE-U250-L2 ({model.n_dof} DOF), h = {h:g}, from the case's state")
    print(f"  (q, v) rule: |R_v| {np.linalg.norm(rules.qv(q0, v0, h, wv)):.2e} at its w "
          f"(|w - v0| {np.linalg.norm(wv - v0):.3f})")
    print(f"  (q, p) rule: |R_p| {np.linalg.norm(rules.qp(q0, p0, h, wv)):.3f} at that w")
    dq = 0.5 * h * wv
    print("  I(q0 + s dq)^-1 p0 - v0, dq = (h/2) w (|dq| max "
          f"{np.abs(dq).max():.1e} rad): O(n) recursion / dense GIM solve")
    for s in (0.0, 0.01, 0.1, 1.0):
        q = q0 + s * dq
        fast = np.abs(rules.velocity(q, p0) - v0).max()
        dense = np.abs(np.linalg.solve(mass_matrix(model, q), p0) - v0).max()
        print(f"    s = {s:<5g} {fast:.3e} / {dense:.3e} rad/s")
    links = model.n_bodies
    print(f"  I's condition number at q0: {np.linalg.cond(mass_matrix(model, q0)):.2e} "
          f"(links {links}: (L / l)^3 = {links ** 3:.2e})")
    log: list[float] = []
    newton(lambda w: rules.qp(q0, p0, h, w), wv.copy(), iterations=8, log=log)
    print("  Newton on R_p from the (q, v) solution, |R_p| by iteration: "
          + ", ".join(f"{x:.2g}" for x in log))


def robot_part(t_end=200.0, h=1e-2) -> None:
    model = load_robot(ROOT / "cases" / "robots" / "puma560.toml").model
    rules = Rules(model)
    q0, v0 = np.full(model.n_v, 0.3), np.full(model.n_v, 0.5)
    E0 = sum(energy(model, q0, v0))
    mass = model.total_mass
    print(f"PUMA 560, fixed h = {h:g} over {t_end:g} s (largest |delta_M| over the steps)")
    for name in ("(q, v)", "(q, p)"):
        q, v = q0.copy(), v0.copy()
        worst, cpu = 0.0, time.process_time()
        for _ in range(int(round(t_end / h))):
            if name == "(q, v)":
                w = newton(lambda w, q=q, v=v: rules.qv(q, v, h, w), v.copy())
                q, v = q + h * w, 2.0 * w - v
            else:
                p = generalized_momentum(model, q, v)
                w = newton(lambda w, q=q, p=p: rules.qp(q, p, h, w), v.copy())
                F = generalized_momentum(model, q + 0.5 * h * w, w, gradient=True)[1]
                q = q + h * w
                v = rules.velocity(q, p + h * F)
            worst = max(worst, abs(sum(energy(model, q, v)) - E0) / mass)
        print(f"  {name}: max |delta_M| {worst:.3e} J/kg, CPU {time.process_time() - cpu:.1f} s")


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--part", choices=("chain", "robot", "both"), default="both")
    args = ap.parse_args(argv)
    if args.part in ("chain", "both"):
        chain_part()
    if args.part in ("robot", "both"):
        robot_part()


if __name__ == "__main__":
    main()
