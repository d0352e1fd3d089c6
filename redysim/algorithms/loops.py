"""Closed loops: a kinematic tree plus cut joints, and their forward dynamics.

A closed-loop mechanism is a spanning tree (a :class:`~redysim.model.tree.Model`) and the joints cut
to open it (:class:`CutJoint`): each keeps a point of one body on a point of another body (or of
the world), in all three directions (``"point"``: a ball joint, 3 equations) or in the world's
x and y only (``"planar"``: a pin of a mechanism moving in the xy plane, 2 equations; the third
would repeat the other two), or along the x and y axes of a frame ``rot_b`` fixed on body b
(``"plane"``: the same pin in a plane of any orientation, moving with body b; its rows are
u_k . (x_a - x_b), u_k = R_b rot_b e_k, whose rates carry the frame's turning, w_b x u_k;
``"line"``: its first row only, what is left of a pin whose other rows repeat other cuts');
``"revolute"`` (5 equations) also keeps the z axes of two frames
fixed on the bodies (``rot_a``, ``rot_b``) aligned, ``"weld"`` (6) the whole frames. Their
rotation rows are velocity-level equations on the relative angular velocity: for a weld
w_a - w_b = 0 along the world axes, for a revolute joint its components along the x and y axes
of frame B; at position level the residuals 1/2 sum_k b_k x a_k (the frames' columns) and
(z_A . x_B, -z_A . y_B), whose rates are those equations on the constraint.

Forward dynamics with the loops closed (:meth:`ClosedLoops.forward_dynamics`, and with the loop
forces :meth:`ClosedLoops.forward_dynamics_and_forces`) is Featherstone's
method on the tree's O(n) recursions (Rigid Body Dynamics Algorithms, 2008, section 8.3):

    qdd0 = the tree's forward dynamics (RGE-A, O(n))
    X    = M^-1 J^T, one column per constraint equation: RGE-A with tau = a row of J, no gravity,
           no velocity (m solves, O(n) each)
    (J X) lambda = -(J qdd0 + Jdot v)                       a dense m x m solve
    qdd  = qdd0 + X lambda

with J (m, n) the cut joints' Jacobian (each point's velocity from the joints on its path to the
base) and Jdot v their velocity-product accelerations (the kinematics pass at qdd = 0, no
gravity). The cost is (1 + m) qdd calls and O(n m) more: O(n) for a fixed number of loops.
lambda is the loop force: on body a at its point, in the world frame (and -lambda on body b).

Drift. Integrated, q and v leave the constraint manifold by the integrator's error; after every
accepted step :meth:`ClosedLoops.project` moves them back along the mass-weighted normal
(q <- q - X (J X)^-1 phi, a few Newton steps; v <- v - X (J X)^-1 J v), the smallest change in
kinetic-energy metric. No Baumgarte gains to choose, and every run reports the residuals it met
(:func:`redysim.simulate` with ``loops``).

References:
    R. Featherstone, Rigid Body Dynamics Algorithms (2008), ch. 8 (closed loops).
    Agarwal et al. (the seed) and the talk's spanning tree with cut joints.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence

import numpy as np

from redysim.algorithms.vectors import cross
from redysim.errors import CaseError, StateError
from redysim.model import door
from redysim.model.tree import FREE, KINDS, CutJoint, Model, check_cuts

SINGULAR = 1e-10  # smallest / largest singular value of J X below which the loops are redundant
# A redundancy at q only is a change point: J X regular (ratio above REGULAR_NEAR) at q moved by
# up to CHANGE_POINT_STEP rad per coordinate, in fixed pseudo-random directions
CHANGE_POINT_STEP = 1e-3
CHANGE_POINT_SEED = 20240229
REGULAR_NEAR = 1e-8
NEAR_CHANGE_POINT = 1e-6  # a run that met J X this near singular passed near a change point
PROJECTION_TOL = 1e-12  # |phi| (m) the position projection aims at, relative to the model's size
PROJECTION_ITERATIONS = 8
PROJECTION_HALVINGS = 6  # a Newton step far from the loops halved at most this often (numpy path)


class ClosedLoops:
    """A tree and its cut joints (module docstring): ``cuts``, or the model's own
    (:meth:`Model.with_cuts`). Not thread-safe (it holds workspaces)."""

    def __init__(self, model: Model, cuts: Sequence[CutJoint] | None = None, *,
                 source: str = "loops"):
        from redysim.algorithms.workspace import Workspace

        if not isinstance(source, str):
            raise CaseError("ClosedLoops", "source", source, "must be a string (where the "
                            "model and its cuts come from, for messages)")
        door.require_model(model, source)
        if cuts is None:  # the model's own (Model.with_cuts)
            cuts = model.cuts
        check_cuts(model, cuts, source)
        self.model, self.cuts = model, tuple(cuts)
        # the open tree: redysim.forward_dynamics refuses a model with cuts (it would answer for
        # the tree, silently), so the tree's own recursions run on the model without them
        self.tree = model.with_cuts(())
        self.nearest_singular = math.inf  # the least s_min / s_max of J X met (a change point)
        self.rows = [(i, r) for i, c in enumerate(cuts) for r in range(KINDS[c.kind])]
        self.m = len(self.rows)
        self.ws = Workspace(self.tree)
        self.ws0 = Workspace(dataclasses.replace(self.tree, gravity=np.zeros(3)))
        self._paths = [(self._path(c.body_a), self._path(c.body_b)) for c in cuts]
        self._rots = [tuple(np.eye(3) if R is None else np.asarray(R, dtype=float)
                            for R in (c.rot_a, c.rot_b)) for c in cuts]
        self._zeros = np.zeros(model.n_v)
        self.size = max(1.0, float(np.abs(model.placement_p).sum()))  # for the tolerance
        # the compiled functions' bundle; None for a coupled tree, whose qdd is its couplings'
        # (numpy path)
        # (numpy path), as is one with a 'plane' or 'line' cut (the compiled functions have
        # neither)
        # and for a tree with quaternions (free or ball joints: q moves along v by the joints'
        # rates, :meth:`_moved`, which the compiled projection does not do)
        self._rate = _rate_layout(model)
        self.bundle = None if (model.couplings or any(c.kind in ("plane", "line")
                                                                for c in self.cuts)
                               or self._rate is not None) else self._bundle()

    def _bundle(self):
        """The compiled functions' bundle (:class:`redysim.algorithms._kernels.constraints.Loops`):
        the trees' packed arrays, the cuts, the paths and work arrays."""
        from redysim.algorithms._kernels import constraints as C

        ws, ws0, n, m, nc = self.ws, self.ws0, self.model.n_v, self.m, len(self.cuts)
        kind = C.PLANAR if ws.planar is not None else C.DH if ws.dh else C.RGE_A
        row0 = np.zeros(nc + 1, dtype=np.int64)
        row0[1:] = np.cumsum([KINDS[c.kind] for c in self.cuts])
        sides = [path for pair in self._paths for path in pair]
        pstart = np.zeros(2 * nc + 1, dtype=np.int64)
        pstart[1:] = np.cumsum([axes.size for axes, _ in sides])
        empty = np.zeros(0, dtype=np.int64)
        paxes = np.concatenate([axes for axes, _ in sides] or [empty]).astype(np.int64)
        powner = np.concatenate([own for _, own in sides] or [empty]).astype(np.int64)
        return C.Loops(
            kind, ws.kernel_f, ws.kernel_i, ws.scratch, ws0.kernel_f, ws0.kernel_i, ws0.scratch,
            np.array([C.CUT_KINDS[c.kind] for c in self.cuts], dtype=np.int64),
            np.array([[c.body_a, c.body_b] for c in self.cuts], dtype=np.int64),
            np.array([[c.point_a, c.point_b] for c in self.cuts], dtype=float).reshape(nc, 2, 3),
            np.array([list(r) for r in self._rots], dtype=float).reshape(nc, 2, 3, 3),
            row0, pstart, paxes, powner, np.zeros(n), np.zeros(3), np.zeros(m),
            np.zeros(m), np.zeros(m), np.zeros(m), np.zeros((m, n)), np.zeros((m, n)),
            np.zeros((m, m)), np.zeros((m, m)),
            np.array([PROJECTION_TOL * self.size, SINGULAR, PROJECTION_ITERATIONS]),
            np.full(1, np.inf), np.zeros(C.WORK), np.zeros(2))

    def _path(self, body: int) -> tuple[np.ndarray, np.ndarray]:
        """(axes, owner body of each axis) on the path from ``body`` to the base."""
        m = self.model
        axes: list[int] = []
        owners: list[int] = []
        while body >= 0:
            js = range(m.joint_voff[body], m.joint_voff[body + 1])
            axes.extend(js)
            owners.extend([body] * len(js))
            body = int(m.parent[body])
        return np.array(axes, dtype=np.int64), np.array(owners, dtype=np.int64)

    # ----------------------------------------------------------------------- the door
    def _state(self, name: str, x, *, finite: bool = True) -> np.ndarray:
        """``x`` checked at the door (:mod:`redysim.model.door`): a vector of the model's
        ``n_q`` (q) or ``n_v`` values, as the kernels take it, or StateError naming it."""
        model = self.model
        n, what = (model.n_q, "configuration coordinates") if name == "q" else (model.n_v, "DOF")
        return door.vector(name, x, n, owner=f"model {model.name!r} (closed loops)", what=what,
                           finite=finite)

    # ----------------------------------------------------------------------- kinematics
    def _kinematics(self, q, v):
        from redysim.algorithms._kernels.kinematics import kinematics

        ws = self.ws
        kinematics(ws.tree, q, v, ws.zeros, ws.no_accel, ws.s)  # true accelerations at qdd = 0
        return ws

    @staticmethod
    def _point(ws, body, point):
        """World position, velocity and acceleration (at qdd = 0, no gravity) of a body point."""
        if body < 0:
            return np.asarray(point, dtype=float), np.zeros(3), np.zeros(3)
        r = ws.oR[body] @ np.asarray(point, dtype=float)
        w, vO = ws.t[body, :3], ws.t[body, 3:]
        wd, aO = ws.td[body, :3], ws.td[body, 3:]
        return ws.oO[body] + r, vO + cross(w, r), aO + cross(wd, r) \
            + cross(w, cross(w, r))

    def _jacobian_block(self, ws, path, x) -> np.ndarray:
        """(3, n): the velocity of world point x fixed to the body at the path's start."""
        axes, owners = path
        J = np.zeros((3, self.model.n_v))
        if axes.size:
            P = ws.oP[axes]
            J[:, axes] = (P[:, 3:] + cross(P[:, :3], x - ws.oO[owners])).T
        return J

    def _angular_block(self, ws, path) -> np.ndarray:
        """(3, n): the angular velocity of the body at the path's start."""
        axes, _ = path
        J = np.zeros((3, self.model.n_v))
        if axes.size:
            J[:, axes] = ws.oP[axes][:, :3].T
        return J

    @staticmethod
    def _frame(ws, body, rot):
        """World rotation, angular velocity and angular acceleration (qdd = 0, no gravity) of
        a frame fixed to a body (the world: fixed)."""
        if body < 0:
            return rot, np.zeros(3), np.zeros(3)
        return ws.oR[body] @ rot, ws.t[body, :3], ws.td[body, :3]

    def _rotation_rows(self, ws, c, rots, paths):
        """(phi, J, J v, Jdot v) of a revolute or weld cut's rotation equations."""
        RA, wa, aa = self._frame(ws, c.body_a, rots[0])
        RB, wb, ab = self._frame(ws, c.body_b, rots[1])
        Jw = self._angular_block(ws, paths[0])
        if c.body_b >= 0:
            Jw = Jw - self._angular_block(ws, paths[1])
        w, alpha = wa - wb, aa - ab
        if c.kind == "weld":  # w_a - w_b = 0 along the world axes
            phi = 0.5 * sum(cross(RB[:, k], RA[:, k]) for k in range(3))
            return phi, Jw, w, alpha
        u = np.column_stack([RB[:, 1], RB[:, 0]])  # along y_B and x_B: fixed on body b
        zA = RA[:, 2]
        phi = np.array([zA @ RB[:, 0], -(zA @ RB[:, 1])])
        Jdv = u.T @ alpha + np.array([w @ cross(wb, u[:, 0]), w @ cross(wb, u[:, 1])])
        return phi, u.T @ Jw, u.T @ w, Jdv

    def _plane_rows(self, ws, c, rot, path_b, diff, Jc):
        """(phi, J, J v, Jdot v) of a 'plane' cut: u_k . d, d = x_a - x_b, along u_k the x and
        y axes of frame ``rot`` on body b (a 'line' cut: x only); d/dt u_k = w_b x u_k, so the
        rows carry (u_k x d) . w_b, and Jdot v adds 2 (w_b x u_k) . d' + (alpha_b x u_k + w_b x
        (w_b x u_k)) . d (alpha_b at qdd = 0)."""
        d, dv, da = diff
        RB, wb, ab = self._frame(ws, c.body_b, rot)
        n = KINDS[c.kind]
        u = RB[:, :n]
        wu = [cross(wb, u[:, k]) for k in range(n)]
        J = u.T @ Jc
        if c.body_b >= 0:
            J = J + np.vstack([cross(u[:, k], d) for k in range(n)]) @ \
                self._angular_block(ws, path_b)
        Jv = u.T @ dv + np.array([wu[k] @ d for k in range(n)])
        Jdv = u.T @ da + np.array([2.0 * (wu[k] @ dv) + cross(ab, u[:, k]) @ d
                                   + cross(wb, wu[k]) @ d for k in range(n)])
        return u.T @ d, J, Jv, Jdv

    def evaluate(self, q, v):
        """(phi (m,), J (m, n), J v (m,), Jdot v (m,)) at (q, v)."""
        ws = self._kinematics(self._state("q", q), self._state("v", v))
        phi, J, Jv, Jdv = [], [], [], []
        for i, (c, (pa, pb)) in enumerate(zip(self.cuts, self._paths, strict=True)):
            xa, va, aa = self._point(ws, c.body_a, c.point_a)
            xb, vb, ab = self._point(ws, c.body_b, c.point_b)
            Jc = self._jacobian_block(ws, pa, xa) - (self._jacobian_block(ws, pb, xb)
                                                     if c.body_b >= 0 else 0.0)
            if c.kind in ("plane", "line"):
                rows = self._plane_rows(ws, c, self._rots[i][1], pb, (xa - xb, va - vb, aa - ab),
                                        Jc)
                for out, x in zip((phi, J, Jv, Jdv), rows, strict=True):
                    out.append(x)
                continue
            k = min(KINDS[c.kind], 3)
            phi.append((xa - xb)[:k])
            J.append(Jc[:k])
            Jv.append((va - vb)[:k])
            Jdv.append((aa - ab)[:k])
            if c.kind in ("revolute", "weld"):
                rows = self._rotation_rows(ws, c, self._rots[i], (pa, pb))
                for out, x in zip((phi, J, Jv, Jdv), rows, strict=True):
                    out.append(x)
        return (np.concatenate(phi), np.vstack(J), np.concatenate(Jv), np.concatenate(Jdv))

    def _newton_step(self, q, v, phi, step, J):
        """(q, phi, J) after the projection's Newton step ``step`` (velocity space), halved
        while it does not shrink |phi|; where no halving does (a body of almost no inertia
        about an axis the loops barely see, as a rod spinning about its length, makes the
        mass-weighted step large and its second-order change of phi larger than phi), the
        least-squares step -J^T (J J^T)^-1 phi instead, which moves every coordinate alike."""
        worst = np.abs(phi).max()
        for attempt in range(2):
            for _ in range(PROJECTION_HALVINGS):
                q_new = self._moved(q, step)
                phi_new, J_new, _, _ = self.evaluate(q_new, v)
                if np.abs(phi_new).max() < worst:
                    return q_new, phi_new, J_new
                step = 0.5 * step
            if attempt == 0:
                step = -(J.T @ np.linalg.lstsq(J @ J.T, phi, rcond=None)[0])
        return q_new, phi_new, J_new

    def _moved(self, q, dv):
        """q moved by the velocity-space step dv: q + dv where dq/dt = v; a free or ball joint's
        position by dv's linear part and its quaternion by q (x) [0; w] / 2, then normalised (a
        first-order move: the projection's Newton steps converge on it)."""
        if self._rate is None:
            return q + dv
        from redysim.algorithms._kernels.system import configuration_rate

        nq = q.shape[0]
        rate = np.empty(nq)
        configuration_rate(nq, *self._rate[:6], np.concatenate((q, dv)), rate)
        q = q + rate
        for i in self._rate[6]:  # each quaternion's w slot: back onto the unit sphere
            q[i:i + 4] /= np.linalg.norm(q[i:i + 4])
        return q

    def residuals(self, q, v) -> tuple[float, float]:
        """(max |phi| [m], max |J v| [m/s]): how far (q, v) is off the loops."""
        phi, _, Jv, _ = self.evaluate(q, v)
        return float(np.abs(phi).max()), float(np.abs(Jv).max())

    # ----------------------------------------------------------------------- dynamics
    def _mobility(self, q, J):
        """X = M^-1 J^T (n, m), each column by RGE-A with no gravity and no velocity."""
        from redysim.algorithms.dynamics import forward_dynamics

        model0 = self.ws0.model
        return np.column_stack([forward_dynamics(model0, q, self._zeros, Jrow, ws=self.ws0)
                                for Jrow in J])

    def _solve(self, A, b, q):
        """A x = b for the m x m J X at configuration q, refusing redundant loops by name (and
        saying whether q is a change point: redundant here only)."""
        s = np.linalg.svd(A, compute_uv=False)
        ratio = float(s[-1] / s[0]) if s[0] > 0 else 0.0
        self.nearest_singular = min(self.nearest_singular, ratio)
        if not ratio > SINGULAR:
            _, _, Vt = np.linalg.svd(A)
            null = np.abs(Vt[-1])
            culprits = ", ".join(map(repr, sorted({self.cuts[self.rows[i][0]].name for i in
                                                   np.flatnonzero(null > 0.1 * null.max())})))
            values = f"singular J M^-1 J^T, singular values {s[-1]:.3g} / {s[0]:.3g}"
            if self._regular_near(q):
                raise StateError(f"the cut joints {culprits} are redundant at this "
                                 f"configuration ({values}) but not at those near it: a change "
                                 "point, a singular configuration where the mechanism can "
                                 "switch branches (a parallelogram four-bar with its bars in "
                                 "a line, say), and where the loops do not determine the "
                                 "motion; start, or drive the mechanism, away from it")
            raise StateError(f"the cut joints {culprits} are redundant: their equations are "
                             f"dependent at this configuration and at those near it ({values})"
                             "; remove or lower the rank of one, e.g. a 'planar' cut for a "
                             "mechanism in the xy plane")
        return np.linalg.solve(A, b)

    def _regular_near(self, q) -> bool:
        """Whether J X is regular at configurations near q (each coordinate moved by up to
        CHANGE_POINT_STEP rad, or that times the model's size for a prismatic one; fixed
        directions): the redundancy at q is then a change point's, not the cuts' own."""
        dq = np.random.default_rng(CHANGE_POINT_SEED).uniform(-1.0, 1.0, self.model.n_v)
        dq *= CHANGE_POINT_STEP * np.where(self.model.dof_kind == 1, self.size, 1.0)
        near = self.model.couple(self._moved(np.asarray(q, dtype=float), dq))  # on the couplings
        J = self.evaluate(near, self._zeros)[1]
        s = np.linalg.svd(J @ self._mobility(near, J), compute_uv=False)
        return bool(s[0] > 0 and s[-1] > REGULAR_NEAR * s[0])

    def nearest_change_point(self) -> float:
        """The least s_min / s_max of J M^-1 J^T met since the last call (inf: none met), and
        start afresh: how close the motion came to a change point."""
        nearest, self.nearest_singular = self.nearest_singular, math.inf
        if self.bundle is not None:
            met = self.bundle.nearest
            nearest, met[0] = min(nearest, float(met[0])), math.inf
        return nearest

    def forward_dynamics(self, q, v, tau=None) -> np.ndarray:
        """qdd with the loops closed (as :func:`redysim.forward_dynamics` for a tree)."""
        return self.forward_dynamics_and_forces(q, v, tau)[0]

    def forward_dynamics_and_forces(self, q, v, tau=None) -> tuple[np.ndarray, np.ndarray]:
        """(qdd, lambda): accelerations with the loops closed, and the loop forces (m,) (on body
        a at its point, world frame; -lambda on body b). In compiled code
        (:func:`redysim.algorithms._kernels.constraints.loops_qdd`, what the compiled steps
        call); where it fails (redundant loops, a non-finite state), the same method in numpy
        says why."""
        from redysim.algorithms._kernels.constraints import OK, loops_qdd
        from redysim.algorithms.dynamics import check_state, forward_dynamics

        q = check_state(self.tree, "q", q)
        v = check_state(self.tree, "v", v)
        tau = check_state(self.tree, "tau", tau, optional=True)
        qdd = np.empty(self.model.n_v)
        lp = self.bundle
        if lp is not None and loops_qdd(lp, q, v, self._zeros if tau is None else tau,
                                        qdd) == OK:
            return qdd, lp.lam.copy()
        qdd0 = forward_dynamics(self.tree, q, v, tau, ws=self.ws)
        _, J, _, Jdv = self.evaluate(q, v)
        X = self._mobility(q, J)
        lam = self._solve(J @ X, -(J @ qdd0 + Jdv), q)
        return qdd0 + X @ lam, lam

    def cut_points(self, q) -> list[tuple[np.ndarray, np.ndarray]]:
        """World positions (point a, point b) of every cut joint's two points at q (they meet,
        where a loop is closed, in the coordinates the cut constrains)."""
        ws = self._kinematics(self._state("q", q), self._zeros)
        return [(self._point(ws, c.body_a, c.point_a)[0], self._point(ws, c.body_b, c.point_b)[0])
                for c in self.cuts]

    def check_start(self, q, tol: float = 1e-6) -> None:
        """Refuse a configuration that violates a loop by more than ``tol`` (relative to the
        model's size), naming the cut joint: a start to be projected is one near the loops."""
        tol = door.number("check_start", "tol", tol, at_least=0.0)
        phi = self.evaluate(q, self._zeros)[0]
        worst = int(np.argmax(np.abs(phi)))
        if abs(phi[worst]) > tol * self.size:
            cut = self.cuts[self.rows[worst][0]]
            raise StateError(f"q violates the cut joint {cut.name!r} by {abs(phi[worst]):.3g} m "
                             f"(more than {tol * self.size:.3g}): its points {cut.point_a} on "
                             f"body {cut.body_a} and {cut.point_b} on body {cut.body_b} must "
                             "meet; start from an assembled configuration")

    def project(self, q, v) -> tuple[np.ndarray, np.ndarray, float, float]:
        """(q, v) moved onto the loops along the mass-weighted normal (module docstring), and
        the residuals (max |phi|, max |J v|) found before. In compiled code
        (:func:`redysim.algorithms._kernels.constraints.loops_project`, what the compiled steps
        call); where it fails, the same method in numpy says why."""
        from redysim.algorithms._kernels.constraints import OK, loops_project

        q, v = self._state("q", q).copy(), self._state("v", v).copy()
        met = np.zeros(2)
        q1, v1 = q.copy(), v.copy()
        if self.bundle is not None and loops_project(self.bundle, q1, v1, met) == OK:
            return q1, v1, float(met[0]), float(met[1])
        phi, J, Jv, _ = self.evaluate(q, v)
        before = (float(np.abs(phi).max()), float(np.abs(Jv).max()))
        for _ in range(PROJECTION_ITERATIONS):
            if np.abs(phi).max() <= PROJECTION_TOL * self.size:
                break
            X = self._mobility(q, J)
            q, phi, J = self._newton_step(q, v, phi, -(X @ self._solve(J @ X, phi, q)), J)
        X = self._mobility(q, J)
        v -= X @ self._solve(J @ X, J @ v, q)
        return q, v, before[0], before[1]


def _rate_layout(model: Model):
    """The index arrays of :func:`redysim.algorithms._kernels.system.configuration_rate` for a
    model with free or ball joints, and each quaternion's q slot last; None without them."""
    from redysim.model.tree import BALL_JOINT

    if not any(t in (FREE, BALL_JOINT) for t in model.joint_types):
        return None
    plain_q: list[int] = []
    plain_v: list[int] = []
    free_q, free_v, ball_q, ball_v, quats = [], [], [], [], []
    for k, t in enumerate(model.joint_types):
        qs, vs = int(model.joint_qoff[k]), int(model.joint_voff[k])
        if t == FREE:
            free_q.append(qs)
            free_v.append(vs)
            quats.append(qs + 3)
        elif t == BALL_JOINT:
            ball_q.append(qs)
            ball_v.append(vs)
            quats.append(qs)
        else:
            plain_q.extend(range(qs, int(model.joint_qoff[k + 1])))
            plain_v.extend(range(vs, int(model.joint_voff[k + 1])))
    return tuple(np.array(a, dtype=np.int64)
                 for a in (plain_q, plain_v, free_q, free_v, ball_q, ball_v, quats))
