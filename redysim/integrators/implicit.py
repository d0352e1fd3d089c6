"""The implicit midpoint rule in joint coordinates, each step O(n): Newton-Krylov, no n x n matrix.

For chains whose explicit steps are bound by waves they need not resolve (RE-U50000-L1000: the
centrifugal tension carries transverse waves across a 2 cm link in ~3e-5 s). docs/design.md,
"The implicit integrator", says why this scheme; docs/notes/2026-11-implicit-integrator.md
measures what it trades.

For a second-order system y = (q, v), dq/dt = v, dv/dt = a(t, q, v), one step of size h is

    q1 = q0 + h w,    v1 = 2 w - v0,    where w solves
    R(w) = w - v0 - (h/2) a(t + h/2, q0 + (h/2) w, w) = 0.

Newton on R from w = v0, each correction by GMRES (SciPy) on the preconditioned system
P^-1 J du = -P^-1 R, with J u = u - (h/2) [a(q_m + (h/2) e u, w + e u) - a(q_m, w)] / e, a
finite-difference product (one call of the system's qdd, O(n)), e |u| = FD_EPS (1 + |w|).
Newton stops when |P^-1 R| <= newton_tol |w|, or when it stops contracting below FLOOR_TOL |w|
(the round-off floor of qdd).

The preconditioner of a chain (:class:`TensionPreconditioner`): a chain under tension (the
centrifugal or gravitational load along a rope) is stiff through its links' orientations, a
string's geometric stiffness K = sum_k J_k^T (T_k l_k (1 - d_k d_k^T)) J_k (J_k: link k's
angular Jacobian, d_k its axis, T_k its axial tension). Then J ~ M^-1 (M + c K), c = h^2 / 4,
and P^-1 r = (M + c K)^-1 M r = r - (M + c K)^-1 (c K r): c K r is one pass down the chain and
one back, and the solve is one RGE-A call on a workspace whose links carry the added rotational
inertia c T_k l_k about their transverse axes. O(n), no matrix, nothing multiplied by M (M's
conditioning at 100,000 DOF loses smooth components of M r). Other systems step without one.

Error control (``midpoint``) is on the positions q, as in structural dynamics (Zienkiewicz and
Xie): for y' = f(y) the step's local error is h^3 (f'f'f / 12 - f''(f, f) / 24) (its B-series),
and for q, whose f''(f, f) vanishes (dq/dt = v is linear), it is (q1 - P) / 3 with P = q0 + h v0 +
(h^2/2) a0 the second-order Taylor predictor (no extra qdd call). Like Radau5's (Hairer and
Wanner, IV.8), this estimate is filtered by the preconditioner, e <- P^-1 e: a wave the step
does not resolve then counts by its amplitude (the phase the step gets wrong), not by its
acceleration times h^2. The velocities' error is not controlled: for such a wave it is omega
times its amplitude, and a per-step test on v (tried: v's local error from the Taylor predictor,
with the jerk by one finite-difference call, and the trapezoidal rule) made RE-U50000-L1000
resolve its link-scale waves, with steps far shorter than the test on q takes
(docs/notes/2026-11-implicit-integrator.md). v's local error is of the same order, h^3, as q's,
so the global error still falls with rtol. The error is ode45's max-norm, |e_i| / max(|q0_i|,
|q1_i|, atol / rtol) <= rtol; the next step is h min(5, max(0.2, 0.8 (rtol / err)^(1/3))). A step
whose Newton iteration fails is retried at h / 4. ``midpoint-fixed`` steps at a fixed h (no
estimate), landing on the sample times.

References: E. Hairer, C. Lubich, G. Wanner, "Geometric Numerical Integration", 2nd ed. (2006),
I.1 and VI.3 (the implicit midpoint rule); E. Hairer, G. Wanner, "Solving Ordinary Differential
Equations II", 2nd ed. (1996), IV.8 (the filtered error estimate); D. A. Knoll, D. E. Keyes,
"Jacobian-free Newton-Krylov methods", J. Comput. Phys. 193 (2004).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable

import numpy as np

from redysim.integrators import protocol as steps  # the controller's constants, Hermite
from redysim.integrators.protocol import Counters, IntegrationError, OdeSolver, SolverState

ERROR_ORDER = 2           # the local error is O(h^3): the controller's exponent is 1/3
POWER = 1.0 / (ERROR_ORDER + 1)
MIN_SHRINK = 0.2          # an accepted or rejected step's next size is at least 0.2 h
NEWTON_FAIL_SHRINK = 0.25  # a step whose Newton iteration fails is retried at h / 4
MAX_NEWTON = 20
# Newton fails when |P^-1 R| grows more than this in one iteration: at 2 it refused RE-U750-L6
# steps of 1e-2 s that converge (docs/notes/2026-11-costs-in-the-code.md)
DIVERGENCE = 10.0
# |P^-1 R| <= newton_tol |w|: at fixed steps NEWTON_TOL, under error control
# min(NEWTON_TOL, NEWTON_RTOL rtol).
# (|P^-1 R| ~ the error left in w, which moves v1 by twice as much, and a 2-norm over |w|: under
# error control Newton must leave far less than rtol, or the global error stops falling with
# rtol. The energy asks for more: what Newton leaves in w's smooth components, where the momentum
# M v is large, moves the energy by 2 p . dw, and on RE-U50000-L1000 that, not the scheme, made
# delta_M; at 1e-6 rtol delta_M is the scheme's own, which a Newton converged further does not
# change. Fixed steps keep 1e-6: tighter is below qdd's round-off floor on the 1,000,000-DOF rod,
# where Newton then crawls. docs/design.md, "The implicit integrator"; the runs:
# docs/notes/2026-11-costs-in-the-code.md.)
NEWTON_TOL = 1e-6
NEWTON_RTOL = 1e-6
# Newton also stops when |P^-1 R| stalls (falls by less than 10 % in an iteration) below FLOOR_TOL
# |w|: the round-off floor of qdd, which rises during a long chain's run to where a tolerance alone
# would stall Newton. Under error control this floor is not tied to rtol: a floor of rtol / 10 left
# a run at rtol 1e-5 unable to converge at any step once qdd's round-off passed it, and a stall
# below 1e-4 |w| is no error the step can remove (docs/notes/2026-11-costs-in-the-code.md). (A stall
# test of "no longer halves" stopped slow, linear convergence too.)
FLOOR_TOL = 1e-4
STALL = 0.9
FD_EPS = 1e-3             # e |u| = FD_EPS (1 + |w|): at 1e-7 a smooth u's product was round-off
GMRES_RTOL, GMRES_RESTART, GMRES_MAXITER = 1e-3, 20, 20


class TensionPreconditioner:
    """P^-1 r = (M + c K)^-1 M r for a :class:`redysim.Chain` (module docstring): the chain's
    geometric stiffness from its links' axial tensions at the step's start."""

    def __init__(self, chain):
        from redysim.algorithms.workspace import Workspace

        self.chain, self.n = chain, chain.n_dof
        # ws_k: the tensions' inverse dynamics, then the frames of each Newton iterate
        self.ws_k, self.ws_p = Workspace(chain), Workspace(chain)
        self.ws_p.base_accel[:] = 0.0  # the linear solves: no gravity
        self.ws_p.gravity[:] = 0.0
        self.inertia0 = self.ws_p.tree.inertia_O.copy()
        off = chain.joint_qoff
        self.link_of = np.repeat(np.arange(len(off) - 1), np.diff(off))  # each DOF's link
        self.last_dof = off[1:] - 1
        self.zeros = np.zeros(self.n)
        self.solves = 0  # RGE-A calls on the augmented chain
        self.add = np.zeros(chain.n_links)

    def tensions(self, q, v, a) -> np.ndarray:
        """Mean axial tension of each link (>= 0) from the Newton-Euler wrenches at (q, v, a)."""
        from redysim.algorithms.dynamics import inverse_dynamics

        inverse_dynamics(self.chain, q, v, a, ws=self.ws_k)
        force = self.ws_k.s.W[:, 3:]  # the force each joint passes to its link and beyond
        d = self.ws_k.oR[:, :, 0]  # link axes (world)
        t_in = -np.einsum("ki,ki->k", force, d)
        t_out = -np.einsum("ki,ki->k", np.vstack([force[1:], np.zeros((1, 3))]), d)
        return np.maximum(0.5 * (t_in + t_out), 0.0)

    def setup(self, q, v, a, h) -> None:
        """The augmented inertias c T_k l_k for a step of size h from (q, v) with qdd a."""
        self.add = (h * h / 4.0) * self.tensions(q, v, a) * self.chain.length
        inertia = self.ws_p.tree.inertia_O  # a view of the workspace's packed arrays
        inertia[:] = self.inertia0
        inertia[:, 1, 1] += self.add
        inertia[:, 2, 2] += self.add

    def at(self, q) -> None:
        """Joint axes and link axes (world) at q, for c K r."""
        from redysim.algorithms.dynamics import forward_dynamics

        forward_dynamics(self.chain, q, self.zeros, ws=self.ws_k, planar=False)
        self.axes = self.ws_k.oP[:, :3].copy()
        self.link_x = self.ws_k.oR[:, :, 0].copy()
        self.q = q

    def apply(self, r) -> np.ndarray:
        """r - (M + c K)^-1 (c K r), at the frames of :meth:`at`."""
        from redysim.algorithms.dynamics import forward_dynamics

        e, d = self.axes, self.link_x
        turn = np.cumsum(e * r[:, None], axis=0)[self.last_dof]  # link k's rotation J_k r
        turn -= d * np.einsum("ki,ki->k", d, turn)[:, None]  # its transverse part
        torque = -self.add[:, None] * turn
        outboard = np.cumsum(torque[::-1], axis=0)[::-1]  # the torques at and beyond link k
        Q = np.einsum("ji,ji->j", e, outboard[self.link_of])  # generalized forces
        self.solves += 1
        return r + forward_dynamics(self.chain, self.q, self.zeros, Q, ws=self.ws_p,
                                    planar=False)


class _Identity:
    """No preconditioner (systems other than a chain)."""

    solves = 0

    def setup(self, q, v, a, h):
        pass

    def at(self, q):
        pass

    @staticmethod
    def apply(r):
        return r


class NewtonFailed(Exception):
    """The Newton iteration of one step did not converge (the message says how)."""


class MidpointSolver(OdeSolver):
    """The implicit midpoint rule on y = (q, v), dq/dt = v, with the interface of
    :class:`redysim.integrators.explicit.Solver` (step, dense, state, counters, done).

    ``rhs(t, y) -> (dq/dt, dv/dt)``; its first half must be v (a second-order system; checked
    at t0). ``h``: a fixed step (``midpoint-fixed``); None: error control by ``rtol`` and
    ``atol`` (``midpoint``). ``preconditioner``: a :class:`TensionPreconditioner` (or None).
    Besides steps, rejected steps and RHS calls, it counts Newton iterations (``newton``), GMRES
    iterations (``krylov``) and the preconditioner's solves.
    """

    def __init__(self, rhs: Callable, t0: float, y0, t_end: float, *, rtol: float = 1e-4,
                 atol: float = 1e-6, h: float | None = None, hmax: float | None = None,
                 state: SolverState | None = None, preconditioner=None,
                 newton_tol: float | None = None):
        self.rhs = rhs
        self.t_end = float(t_end)
        if not self.t_end > t0:
            raise ValueError(f"t_end = {t_end!r} must be greater than t0 = {t0!r}")
        y0 = np.array(y0, dtype=float)
        if y0.ndim != 1 or y0.size % 2:
            raise ValueError(f"y0 must be (q, v) of equal halves, got shape {y0.shape}")
        self.n = y0.size // 2
        self.adaptive = h is None
        span = self.t_end - t0
        if self.adaptive:
            if not (rtol > 0 and atol > 0):
                raise ValueError(f"need rtol > 0 and atol > 0, got rtol={rtol!r}, atol={atol!r}")
            self.rtol, self.atol = float(rtol), float(atol)
            self.hmax = float(hmax) if hmax else steps.HMAX_FRACTION * span
            self.newton_tol = newton_tol or min(NEWTON_TOL, NEWTON_RTOL * self.rtol)
        else:
            assert h is not None  # (not adaptive)
            if not h > 0:
                raise ValueError(f"a fixed step needs h > 0, got h={h!r}")
            self.rtol = self.atol = math.nan
            self.hmax = float(h)
            self.newton_tol = newton_tol or NEWTON_TOL
        self.pre = preconditioner if preconditioner is not None else _Identity()
        self.newton = self.krylov = 0
        self._y = np.empty(2 * self.n)
        if state is not None:
            state.resume(self)
        else:
            self.counters = Counters()
            self.t, self.y = float(t0), y0
            self.f = self._call(self.t, self.y[:self.n], self.y[self.n:], full=True)
            if not np.array_equal(self.f[:self.n], self.y[self.n:]):
                raise ValueError("the implicit midpoint steps second-order systems, y = (q, v) "
                                 "with dq/dt = v; this rhs's dq/dt differs from v (a free "
                                 "joint's quaternion moves otherwise: use ode45)")
            self.h_next = self._initial_step() if self.adaptive else self.hmax  # (= h)
        self.t_old, self.y_old, self.f_old = self.t, self.y, self.f

    # ----------------------------------------------------------------------- helpers
    def state(self) -> SolverState:
        return SolverState(self.t, self.y.copy(), self.f.copy(), self.h_next,
                           Counters(**vars(self.counters)))

    def _call(self, t, q, v, full=False):
        n = self.n
        self._y[:n], self._y[n:] = q, v
        self.counters.nfev += 1
        f = np.asarray(self.rhs(t, self._y), dtype=float)
        return f.copy() if full else f[n:].copy()

    def _initial_step(self) -> float:
        """ode45's rule at this scheme's order: min(hmax, span), cut to 1/rh."""
        absh = min(self.hmax, self.t_end - self.t)
        scale = np.maximum(np.abs(self.y), self.atol / self.rtol)
        rh = np.max(np.abs(self.f) / scale) / (steps.SAFETY * self.rtol ** POWER)
        if absh * rh > 1:
            absh = 1.0 / rh
        return max(absh, steps.HMIN_EPS * float(np.spacing(abs(self.t))))

    # ----------------------------------------------------------------------- one step
    def _solve(self, t, q0, v0, a0, h) -> np.ndarray:
        """w, the midpoint velocity of the step of size h (raises NewtonFailed)."""
        from scipy.sparse.linalg import LinearOperator, gmres

        n, pre, tm = self.n, self.pre, t + 0.5 * h
        pre.setup(q0, v0, a0, h)
        w = v0.copy()
        last = math.inf
        for _ in range(MAX_NEWTON):
            qm = q0 + 0.5 * h * w
            am = self._call(tm, qm, w)
            R = w - v0 - 0.5 * h * am
            if not np.isfinite(R).all():
                raise NewtonFailed("the residual is not finite")
            pre.at(qm)
            pr = pre.apply(R)
            size, wn = float(np.linalg.norm(pr)), float(np.linalg.norm(w))
            if size <= self.newton_tol * wn:
                return w
            if size > STALL * last and size <= FLOOR_TOL * wn:
                return w  # no longer contracting: the round-off floor of qdd, accepted
            if size > DIVERGENCE * last:
                raise NewtonFailed(f"diverging (|P^-1 R| {last:.3g} -> {size:.3g})")
            last = size
            e = FD_EPS * (1.0 + wn)

            def jv(u, qm=qm, w=w, am=am, e=e):
                u = np.asarray(u).ravel()
                nu = float(np.linalg.norm(u))
                if nu == 0.0:
                    return np.zeros_like(u)
                eu = e / nu
                d = (self._call(tm, qm + 0.5 * h * eu * u, w + eu * u) - am) / eu
                return pre.apply(u - 0.5 * h * d)

            def count(_residual):
                self.krylov += 1

            du, _ = gmres(LinearOperator((n, n), matvec=jv), -pr, rtol=GMRES_RTOL, atol=0.0,
                             restart=GMRES_RESTART, maxiter=GMRES_MAXITER, callback=count,
                             callback_type="pr_norm")
            if not np.isfinite(du).all():
                raise NewtonFailed("GMRES returned a non-finite correction")
            self.newton += 1
            w = w + du
        raise NewtonFailed(f"no convergence in {MAX_NEWTON} iterations (|P^-1 R| {last:.3g})")

    def _attempt(self, h):
        """(q1, v1, a1, err) of one step of size h from the current state (err 0 when fixed)."""
        n, t = self.n, self.t
        q0, v0, a0 = self.y[:n], self.y[n:], self.f[n:]
        w = self._solve(t, q0, v0, a0, h)
        q1, v1 = q0 + h * w, 2.0 * w - v0
        a1 = self._call(t + h, q1, v1)
        if not self.adaptive:
            return q1, v1, a1, 0.0
        # q1's local error from the Taylor predictor's difference (module docstring), filtered:
        # a wave the step does not resolve counts by its amplitude
        eq = self.pre.apply((q1 - (q0 + h * v0 + (0.5 * h * h) * a0)) / 3.0)
        sq = np.maximum(np.maximum(np.abs(q0), np.abs(q1)), self.atol / self.rtol)
        return q1, v1, a1, float(np.max(np.abs(eq) / sq))

    def step(self, t_stop: float | None = None) -> None:
        """One accepted step (retrying rejected ones); a fixed step stops at ``t_stop``."""
        t = self.t
        t_stop = self.t_end if t_stop is None else min(t_stop, self.t_end)
        hmin = steps.HMIN_EPS * float(np.spacing(abs(t)))
        if not self.adaptive:
            h, t_new = self.h_next, t + self.h_next
            if t_stop - t_new <= steps.SAMPLE_EPS * max(1.0, abs(t_stop)):  # land on it
                h, t_new = t_stop - t, t_stop
            try:
                q1, v1, a1, _ = self._attempt(h)
            except NewtonFailed as exc:
                raise IntegrationError(f"implicit midpoint at t = {t:.6g} (h = {h:.3g}): Newton "
                                       f"failed: {exc}; take a smaller h") from None
            self._accept(t_new, q1, v1, a1)
            return
        absh = min(self.hmax, max(hmin, self.h_next))
        nofailed = True
        while True:
            done = steps.FINISH_SLACK * absh >= self.t_end - t
            h = self.t_end - t if done else absh
            try:
                q1, v1, a1, err = self._attempt(h)
                ok = math.isfinite(err)
                if ok and err <= self.rtol:
                    break
                shrink = NEWTON_FAIL_SHRINK if not ok else \
                    max(MIN_SHRINK, steps.SAFETY * (self.rtol / err) ** POWER)
            except NewtonFailed:
                shrink = NEWTON_FAIL_SHRINK
            self.counters.rejected += 1
            if absh <= hmin:
                raise IntegrationError(f"step size {absh:.3g} fell below hmin = {hmin:.3g} at "
                                       f"t = {t:.6g}: tolerances cannot be met")
            absh = max(hmin, min(absh, h) * min(shrink, 0.5 if not nofailed else 1.0))
            nofailed = False
        grow = steps.MAX_GROWTH if err == 0.0 else \
            min(steps.MAX_GROWTH, steps.SAFETY * (self.rtol / err) ** POWER)
        self.h_next = h * (grow if nofailed else min(grow, 1.0))
        self._accept(self.t_end if done else t + h, q1, v1, a1)

    def _accept(self, t_new, q1, v1, a1):
        self.t_old, self.y_old, self.f_old = self.t, self.y, self.f
        self.t = t_new
        self.y = np.concatenate((q1, v1))
        self.f = np.concatenate((v1, a1))
        self.counters.steps += 1

    def dense(self, ts) -> np.ndarray:
        """y at times ``ts`` inside the last step: cubic Hermite on (q, v) with (v, a)."""
        ts = np.atleast_1d(np.asarray(ts, dtype=float))
        h = self.t - self.t_old
        return steps.hermite(self.y_old, self.f_old, self.y, self.f, h, (ts - self.t_old) / h)


@functools.cache  # once a process: after that a run would pay its set-up for nothing
def compile_kernels() -> None:
    """Load (or compile) the kernels an implicit step calls beyond qdd: inverse dynamics for the
    tensions and the spatial forward dynamics for the preconditioner, by one application on a
    one-link chain (its types are every chain's), so that a timed run does not include it. In place
    of :func:`redysim.integrators.explicit.compile_kernels`: the implicit step calls none of the
    Runge-Kutta kernels."""
    from redysim.model.tree import Chain

    chain = Chain.uniform(1, "U", mass=1.0)
    pre = TensionPreconditioner(chain)
    zero = np.zeros(chain.n_dof)
    pre.setup(zero, zero, zero, 1e-3)
    pre.at(zero)
    pre.apply(zero)
