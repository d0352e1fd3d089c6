"""The recursions on kinematic trees in their plain, readable form: numpy, 6 x 6 matrices, one
loop per pass, the paper's names.

These are the reference forms of the algorithms (the compiled kernels are tested against them):
kinematics (Eq. 4, twist propagation), inverse dynamics (Newton-Euler, Eq. 9), the generalized
inertia matrix by composite bodies (Eq. 10a), forward dynamics by RGE-A (Table A.1, on a tree:
each body's articulated mass gathers its children's, joints eliminated axis by axis, gravity and
the velocity terms entered as in the articulated-body algorithm), energy and frame positions.
O(n) each but the GIM (O(n d), d the tree's depth).

Conventions (docs/design.md, "Chain conventions"): everything in the world frame; a twist
t = [w; v] is body k's angular velocity and the velocity of its origin O_k; a wrench [n; f] is a
moment about O_k and a force. Moving a twist from O_p to O_k is A = [[1, 0], [-C(r), 1]] with
r = O_k - O_p; moving a wrench back is A^T. S (6, n_v): the motion-subspace columns, [e; 0] for a
revolute axis e, [0; e] for a prismatic one, [R_k e_i; 0] for a free or ball joint's rotation.
M_k = [[I_O, C(m d)], [-C(m d), m 1]]: body k's extended mass matrix about O_k (Eq. 10a).
A joint's own inertia (``model.armature``, one number per axis) adds to the joint-space inertia's
diagonal: to the GIM, to each axis's pivot D = S^T Mhat S + armature, to the torques
(armature qdd) and to the kinetic energy (1/2 armature v^2).

References:
    Agarwal et al., Eq. (4)-(12), Appendix A.1 and Table A.1. Featherstone, Rigid Body Dynamics
    Algorithms (2008), ch. 5-7 (RNEA, CRBA, ABA on trees; spatial_v2's ID.m, HandC.m, FDab.m).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from redysim.algorithms.vectors import cross as vcross
from redysim.model.parts import KIND_CODES
from redysim.model.tree import BALL, Model, quaternion_matrix  # noqa: F401  (re-exported)

REVOLUTE, PRISMATIC = KIND_CODES["R"], KIND_CODES["P"]


def cross(a) -> np.ndarray:
    """C(a): the matrix of a x."""
    return np.array([[0.0, -a[2], a[1]], [a[2], 0.0, -a[0]], [-a[1], a[0], 0.0]])


def shift(r) -> np.ndarray:
    """A: a twist about a point moved to the point r further on (w stays, v += w x r)."""
    A = np.eye(6)
    A[3:, :3] = -cross(r)
    return A


def rotation(u, angle) -> np.ndarray:
    """Rotation by ``angle`` about the unit axis u (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    return c * np.eye(3) + s * cross(u) + (1 - c) * np.outer(u, u)


def body_mass(model: Model, k: int, R) -> np.ndarray:
    """M_k about O_k in the world frame."""
    md = R @ model.mass_com[k]
    M = np.zeros((6, 6))
    M[:3, :3] = R @ model.inertia_O[k] @ R.T
    M[:3, 3:] = cross(md)
    M[3:, :3] = -cross(md)
    M[3:, 3:] = model.mass[k] * np.eye(3)
    return 0.5 * (M + M.T)


class Kinematics(NamedTuple):
    """World-frame R (nb, 3, 3), O (nb, 3), S (6, n_v), twists t and twist-rates td (nb, 6);
    c (nb, 6): each body's velocity-product twist-rate, td_k - A td_parent - S_k vdot_k."""

    R: np.ndarray
    O: np.ndarray
    S: np.ndarray
    t: np.ndarray
    td: np.ndarray
    c: np.ndarray


def kinematics(model: Model, q, v, vdot=None, base_accel=None) -> Kinematics:
    """Frames, motion subspaces, twists and twist-rates (Eq. 4 and its time derivative),
    parents before children. ``base_accel``: the base's linear acceleration (-g for dynamics)."""
    nb, nv = model.n_bodies, model.n_v
    vdot = np.zeros(nv) if vdot is None else vdot
    a0 = np.zeros(3) if base_accel is None else base_accel
    R, O = np.zeros((nb, 3, 3)), np.zeros((nb, 3))
    S, t, td, c = np.zeros((6, nv)), np.zeros((nb, 6)), np.zeros((nb, 6)), np.zeros((nb, 6))
    # forward: parents before children
    for k in range(nb):
        p = model.parent[k]
        Rp, Op = (np.eye(3), np.zeros(3)) if p < 0 else (R[p], O[p])
        tp = np.zeros(6) if p < 0 else t[p]
        tdp = np.concatenate((np.zeros(3), a0)) if p < 0 else td[p]
        Rk, Ok = Rp @ model.placement_R[k], Op + Rp @ model.placement_p[k]
        om = tp[:3].copy()  # the angular velocity of the frame the next axis is fixed in
        Pd_v = np.zeros(6)  # (d/dt S_k) v_k
        qi = model.joint_qoff[k]
        rel = np.zeros(6)  # S_k v_k about the joint's origin
        for j in range(model.joint_voff[k], model.joint_voff[k + 1]):
            kind, u = model.dof_kind[j], model.dof_u[j]
            if kind == BALL:  # a free or ball joint's rotation: about the body's own axes
                first = 3 if model.joint_types[k] == "free" else 0  # (a free joint's x, y, z)
                if j == model.joint_voff[k] + first:  # the quaternion, after x, y, z if any
                    qs = model.joint_qoff[k] + first
                    Rk = Rk @ quaternion_matrix(*q[qs:qs + 4])
                e = Rk[:, j - model.joint_voff[k] - first]
                S[:3, j] = e
            else:
                e = Rk @ u
                if kind == REVOLUTE:
                    S[:3, j] = e
                    Rk = Rk @ rotation(u, q[qi])
                else:
                    S[3:, j] = e
                    Ok = Ok + e * q[qi]
                qi += 1
            Pd_v += np.concatenate((vcross(om, S[:3, j]), vcross(om, S[3:, j]))) * v[j]
            rel += S[:, j] * v[j]
            if kind == REVOLUTE:
                om = om + S[:3, j] * v[j]
        if model.joint_types[k] == "free":  # the ball's columns turn with the body itself
            w_k = tp[:3] + rel[:3]
            Pd_v[:3] = vcross(w_k, rel[:3])
        r = Ok - Op
        t[k] = shift(r) @ tp + rel
        cb = np.concatenate((np.zeros(3), vcross(tp[:3], t[k, 3:] - tp[3:]))) + Pd_v
        c[k] = cb
        sl = slice(model.joint_voff[k], model.joint_voff[k + 1])
        td[k] = shift(r) @ tdp + cb + S[:, sl] @ vdot[sl]
        R[k], O[k] = Rk, Ok
    return Kinematics(R, O, S, t, td, c)


def _link_wrench(M, w):
    """Body k's velocity-product wrench about O_k when its twist-rate is zero (the angular
    acceleration and the acceleration of O_k): [w x (I_O w); w x (w x m d)] (Newton-Euler)."""
    md = np.array([M[2, 4], M[0, 5], M[1, 3]])  # from C(m d) in M's upper-right block
    return np.concatenate((vcross(w, M[:3, :3] @ w), vcross(w, vcross(w, md))))


def inverse_dynamics(model: Model, q, v, vdot) -> np.ndarray:
    """tau = I(q) vdot + C(q, v) v + gravity terms: Newton-Euler, children before parents."""
    kin = kinematics(model, q, v, vdot, -model.gravity)
    W = np.zeros((model.n_bodies, 6))
    # backward: children before parents
    for k in range(model.n_bodies - 1, -1, -1):
        M = body_mass(model, k, kin.R[k])
        W[k] += M @ kin.td[k] + _link_wrench(M, kin.t[k, :3])
        p = model.parent[k]
        if p >= 0:
            W[p] += shift(kin.O[k] - kin.O[p]).T @ W[k]
    return np.array([kin.S[:, j] @ W[_body_of(model, j)] + model.armature[j] * vdot[j]
                     for j in range(model.n_v)])


def _body_of(model: Model, j: int) -> int:
    return int(np.searchsorted(model.joint_voff, j, side="right") - 1)


def mass_matrix(model: Model, q) -> np.ndarray:
    """The GIM I(q) (n_v, n_v) by composite bodies (Eq. 10a), exactly symmetric."""
    kin = kinematics(model, q, np.zeros(model.n_v))
    nb, n = model.n_bodies, model.n_v
    Mc = np.array([body_mass(model, k, kin.R[k]) for k in range(nb)])
    I = np.zeros((n, n))
    # backward: children before parents
    for k in range(nb - 1, -1, -1):
        p = model.parent[k]
        if p >= 0:
            A = shift(kin.O[k] - kin.O[p])
            Mc[p] += A.T @ Mc[k] @ A
        sl = slice(model.joint_voff[k], model.joint_voff[k + 1])
        F = Mc[k] @ kin.S[:, sl]
        I[sl, sl] = kin.S[:, sl].T @ F
        a, b = k, model.parent[k]
        while b >= 0:  # carry F to every ancestor: I_ij = S_i^T A^T ... F
            F = shift(kin.O[a] - kin.O[b]).T @ F
            sb = slice(model.joint_voff[b], model.joint_voff[b + 1])
            I[sb, sl] = kin.S[:, sb].T @ F
            I[sl, sb] = I[sb, sl].T
            a, b = b, model.parent[b]
    return 0.5 * (I + I.T) + np.diag(model.armature)


class Articulated(NamedTuple):
    """RGE-A's factors: per DOF Ihat (the D of I = U D U^T) and Psihat (6,), and phitil."""

    Ihat: np.ndarray
    Psihat: np.ndarray
    phitil: np.ndarray


def forward_dynamics(model: Model, q, v, tau=None) -> np.ndarray:
    """vdot from I(q) vdot = tau - C(q, v) v - gravity terms, by RGE-A on the tree (Table A.1):
    articulated masses gathered from the children, each joint eliminated axis by axis (last axis
    first), every Mhat kept exactly symmetric; gravity as the base's acceleration and the
    velocity terms as articulated-body biases."""
    return articulated(model, q, v, tau)[0]


def articulated(model: Model, q, v, tau=None) -> tuple[np.ndarray, Articulated]:
    """:func:`forward_dynamics`'s vdot and the articulated factors it eliminated with."""
    nb, n = model.n_bodies, model.n_v
    tau = np.zeros(n) if tau is None else tau
    kin = kinematics(model, q, v)
    Mhat = np.zeros((nb, 6, 6))
    p_bias = np.zeros((nb, 6))  # the articulated bias (Table A.1's eta plus velocity terms)
    Ihat, Psihat, phitil = np.zeros(n), np.zeros((n, 6)), np.zeros(n)
    # backward: children before parents
    for k in range(nb - 1, -1, -1):
        M = body_mass(model, k, kin.R[k])
        Mhat[k] += M
        p_bias[k] += _link_wrench(M, kin.t[k, :3])
        for j in range(model.joint_voff[k + 1] - 1, model.joint_voff[k] - 1, -1):
            s = kin.S[:, j]
            Psi = Mhat[k] @ s
            Ihat[j] = s @ Psi + model.armature[j]
            Psihat[j] = Psi / Ihat[j]
            phitil[j] = (tau[j] - s @ p_bias[k]) / Ihat[j]
            p_bias[k] += Psi * phitil[j]
            Mhat[k] -= np.outer(Psihat[j], Psi)
            Mhat[k] = 0.5 * (Mhat[k] + Mhat[k].T)  # exactly symmetric (docs/design.md)
        p_bias[k] += Mhat[k] @ kin.c[k]  # Mbar_k c_k
        p = model.parent[k]
        if p >= 0:
            A = shift(kin.O[k] - kin.O[p])
            Mhat[p] += A.T @ Mhat[k] @ A
            Mhat[p] = 0.5 * (Mhat[p] + Mhat[p].T)
            p_bias[p] += A.T @ p_bias[k]
    vdot = np.zeros(n)
    mu = np.zeros((nb, 6))
    # forward: parents before children, from the base's twist-rate [0; -g]
    for k in range(nb):
        p = model.parent[k]
        mp = np.concatenate((np.zeros(3), -model.gravity)) if p < 0 else mu[p]
        Op = np.zeros(3) if p < 0 else kin.O[p]
        m = shift(kin.O[k] - Op) @ mp + kin.c[k]
        for j in range(model.joint_voff[k], model.joint_voff[k + 1]):
            vdot[j] = phitil[j] - Psihat[j] @ m
            m = m + kin.S[:, j] * vdot[j]
        mu[k] = m
    return vdot, Articulated(Ihat, Psihat, phitil)


MASSLESS_TOL = 1e-12  # a pivot below this, relative to what it is computed from, is none


def pivots(model: Model) -> tuple[np.ndarray, np.ndarray]:
    """RGE-A's pivots at the neutral configuration (the D of I = U D U^T, one per DOF, as
    :func:`articulated` eliminates them) and, for each, the scale of what it is computed from:
    the largest entry of the block its axis reads (the moment block for a rotation, the mass
    block for a translation) of its body's articulated mass as gathered, before any of the
    body's own axes is eliminated (armature added to both). A pivot of a massless joint is then
    zero or round-off of this scale, whatever the rest of the model weighs; a placeholder's tiny
    inertia (1e-10) is a pivot of its own scale. A pivot after a failed one is NaN or noise."""
    nb, n = model.n_bodies, model.n_v
    kin = kinematics(model, model.neutral(), np.zeros(n))
    Mhat = np.zeros((nb, 6, 6))
    D, scale = np.zeros(n), np.zeros(n)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # zero pivots looked for
        for k in range(nb - 1, -1, -1):  # children before parents
            Mhat[k] += body_mass(model, k, kin.R[k])
            gathered = np.abs(Mhat[k])
            for j in range(model.joint_voff[k + 1] - 1, model.joint_voff[k] - 1, -1):
                s = kin.S[:, j]
                block = gathered[:3, :3] if np.any(s[:3]) else gathered[3:, 3:]
                scale[j] = float(np.max(block)) + model.armature[j]
                Psi = Mhat[k] @ s
                D[j] = s @ Psi + model.armature[j]
                Mhat[k] -= np.outer(Psi / D[j], Psi)
                Mhat[k] = 0.5 * (Mhat[k] + Mhat[k].T)
            p = model.parent[k]
            if p >= 0:
                A = shift(kin.O[k] - kin.O[p])
                Mhat[p] += A.T @ Mhat[k] @ A
    return D, scale


def singular_axes(model: Model, pivoted: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> np.ndarray:
    """The DOFs whose pivot (:func:`pivots`, or ``pivoted``: its result) is zero, not finite,
    or round-off of what it is computed from (at most MASSLESS_TOL of it), in elimination order
    (from the tip: the first is the one that makes the GIM singular; those after it inherit its
    NaN)."""
    D, scale = pivots(model) if pivoted is None else pivoted
    with np.errstate(invalid="ignore"):
        bad = ~(D > MASSLESS_TOL * scale) | ~np.isfinite(D)
    return np.flatnonzero(bad)[::-1]


def massless_axis(model: Model) -> int | None:
    """The first DOF in elimination order (from the tip) whose pivot vanishes at the neutral
    configuration (:func:`singular_axes`): a joint that moves nothing with inertia about its
    axis (a massless body at its end, or a massless body its children move freely on), so the
    GIM is singular. None when there is none. A tiny but positive inertia (a placeholder link)
    is no vanishing pivot: its pivot is its own inertia."""
    bad = singular_axes(model)
    return int(bad[0]) if bad.size else None


def energy(model: Model, q, v) -> tuple[float, float]:
    """(T, V) [J]: T = 1/2 sum t_k^T M_k t_k + 1/2 sum_j armature_j v_j^2,
    V = -sum m_k g . (O_k + R_k c_k)."""
    kin = kinematics(model, q, v)
    T = sum(0.5 * kin.t[k] @ body_mass(model, k, kin.R[k]) @ kin.t[k]
            for k in range(model.n_bodies)) + 0.5 * float(model.armature @ (v * v))
    V = -sum(model.mass[k] * model.gravity @ (kin.O[k] + kin.R[k] @ model.com[k])
             for k in range(model.n_bodies))
    return float(T), float(V)


def frame_position(model: Model, q, name: str) -> np.ndarray:
    """World position of a named frame (``model.frames``)."""
    kin = kinematics(model, q, np.zeros(model.n_v))
    body, point = model.frames[name]
    return kin.O[body] + kin.R[body] @ np.asarray(point)


def configuration_rate(model: Model, q, v) -> np.ndarray:
    """dq/dt (n_q,) from v (n_v,): v itself for R and P coordinates; for a free joint the world
    velocity and q (x) [0; w_body] / 2; for a ball joint q (x) [0; w_body] / 2."""
    qdot = np.empty(model.n_q)
    for k in range(model.n_bodies):
        qs, vs = model.joint_qoff[k], model.joint_voff[k]
        if model.joint_types[k] in ("free", "ball"):
            if model.joint_types[k] == "free":
                qdot[qs:qs + 3] = v[vs:vs + 3]
                qs, vs = qs + 3, vs + 3
            qw, qx, qy, qz = q[qs:qs + 4]
            wx, wy, wz = v[vs:vs + 3]
            qdot[qs:qs + 4] = 0.5 * np.array([-qx * wx - qy * wy - qz * wz,
                                              qw * wx + qy * wz - qz * wy,
                                              qw * wy - qx * wz + qz * wx,
                                              qw * wz + qx * wy - qy * wx])
        else:
            qdot[qs:model.joint_qoff[k + 1]] = v[vs:model.joint_voff[k + 1]]
    return qdot
