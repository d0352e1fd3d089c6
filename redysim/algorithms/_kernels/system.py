"""A run's physics in compiled code: the state derivative and the projection after a step.

The contract every stepper calls (:mod:`.rk_run` in compiled code; :class:`redysim.algorithms.system
.System` from Python, through these same functions, so that both round alike):

    derivative(sd, extras, t, y, out) -> bool    dy/dt at (t, y) into out; False: not finite
    project_step(sd, extras, y) -> int           y moved back onto the constraints after a step
                                                 (OK, or a status the Python side explains)

for y = (q, v): dq/dt = v, but a free or ball joint's quaternion, which moves as q (x) [0; w] / 2;
dv/dt =
qdd(q, v, tau) from the tree's forward-dynamics entry (:mod:`.entry`: RGE-A, the planar or the DH
kernel), with the loops closed (:mod:`.constraints`) and the couplings kept in RGE-A's
recursion (:func:`.couplings.coupled_qdd`). The generalized forces tau are assembled in one place,
:func:`generalized_forces`: a constant force at a chain's tip, constant world forces at points
of bodies (gravity compensation is one), viscous joint damping and joint springs. A new force is
one term there; a new constraint one step in :func:`derivative` and :func:`project`.

The work of the forces that have no potential in the system's energy, W(t) = int v . tau_nc dt,
can ride along as one more component of the state, y = (q, v, W): :func:`derivative` then writes
dW/dt = v . tau_nc after the velocities (when ``out`` has that slot; a stepper's y without it is
stepped exactly as before). Of the terms here only the damping has no potential (the tip force's,
the bodies' forces' and the springs' are counted in the energy), so tau_nc is the damping's,
v . (-c v), summed in :func:`generalized_forces` beside its term into ``SystemData.power``.

Two bundles: :class:`SystemData` (what every system has: the tree's packed arrays, the force
terms, the free joints' slots) and :class:`Extras` (what only some have: couplings, loops, a
spatial chain's tip force), or None, for which numba prunes their branches (a chain's or a
robot's first compiled run then compiles none of their kernels).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from redysim._jit import inline, jit_borrowed, jit_exact

from .batch import dh_call as _dh
from .batch import planar_call as _planar
from .batch import rge_a_call as _rge_a
from .constraints import OK, Loops, loops_project, loops_qdd
from .couplings import coupled_qdd
from .entry import bundles
from .kinematics import kinematics
from .planar import planar_tip_torques

RGE_A, PLANAR, DH = 0, 1, 2  # which entry computes the tree's qdd
QUATERNION, RESIDUAL_Q, RESIDUAL_V = 0, 1, 2  # the rows of SystemData.worst


class SystemData(NamedTuple):
    """What every system has (module docstring).

    ``kind``: the entry computing qdd (RGE_A, PLANAR or DH) on a workspace's packed arrays
    ``fdata``, ``idata``, ``scratch``; ``nq``: the length of q. Forces: ``zeros`` (n_v,) the tau
    of a system without any, ``tau`` (n_v,) where they are summed; ``tip`` (3,) a constant world
    force at a chain's tip (empty: none), ``length`` the chain's link lengths (nl,);
    ``damping`` (n_v,) minus each DOF's viscous coefficient (empty: none); ``stiffness`` (n_v,)
    minus each DOF's spring constant, ``spring_ref`` (n_v,) its rest position, ``spring_q`` its q
    slot (all empty: no springs); ``body`` (m,) the bodies that constant world forces ``force``
    (m, 3) act on, at points ``point`` (m, 3) in the bodies' frames, ``wrench`` (nb, 6) their
    work array (all empty: none); ``base0`` (3,) zeros, the base at rest for a position pass.
    Free joints: each one's q slot of x in ``free_q``, its v slot
    of the linear velocity in ``free_v``; ball joints: each one's q slot of its quaternion's w
    in ``ball_q``, its v slot of w_x in ``ball_v``; every other coordinate q[plain_q[i]] moves
    as v[plain_v[i]] (all empty without free and ball joints: dq/dt = v). ``worst`` (3,): the
    largest | |quaternion| - 1 |, |loop or coupling residual in q| and |in v| met before a
    projection. ``power`` (1,): the damping's power v . (-c v) at the last forces' call (0
    without damping), the rate of the work W (module docstring)."""

    kind: int
    fdata: np.ndarray
    idata: np.ndarray
    scratch: np.ndarray
    nq: int
    zeros: np.ndarray
    tau: np.ndarray
    tip: np.ndarray
    length: np.ndarray
    damping: np.ndarray
    stiffness: np.ndarray
    spring_ref: np.ndarray
    spring_q: np.ndarray
    body: np.ndarray
    force: np.ndarray
    point: np.ndarray
    wrench: np.ndarray
    base0: np.ndarray
    plain_q: np.ndarray
    plain_v: np.ndarray
    free_q: np.ndarray
    free_v: np.ndarray
    ball_q: np.ndarray
    ball_v: np.ndarray
    worst: np.ndarray
    power: np.ndarray


class Couplings(NamedTuple):
    """A coupled model's couplings (q_f = m q_l + offset, mimic joints), for the projection after
    a step (:func:`project_couplings`) and to say that the derivative couples the tree's qdd
    (:func:`.couplings.coupled_qdd`, on the system's workspace, whose packed arrays hold the
    couplings' own segments); every array empty for a model without couplings. ``fq``, ``lq``,
    ``fv``, ``lv``: each coupling's follower's and leader's q and v slots; ``m``, ``off``:
    multiplier and offset."""

    fq: np.ndarray
    lq: np.ndarray
    fv: np.ndarray
    lv: np.ndarray
    m: np.ndarray
    off: np.ndarray


def no_couplings() -> Couplings:
    """The empty bundle (a model without couplings)."""
    f, i = np.zeros(0), np.zeros(0, dtype=np.int64)
    return Couplings(i, i, i, i, f, f)


def couplings_of(model) -> Couplings:
    """The bundle of a coupled ``model`` (:meth:`redysim.Model.with_couplings`)."""
    return Couplings(*(np.array(a) for a in model.coupling_index))  # writable copies


class Extras(NamedTuple):
    """What only some systems have, an argument of its own (None for the others, whose branches
    numba then prunes before typing): ``couplings`` (:class:`Couplings`), ``loops``
    (:class:`.constraints.Loops`), ``base0`` (3,) zeros, the base at rest for
    :func:`spatial_tip_torques`' position pass (a tip force on a chain that is not planar)."""

    couplings: Couplings
    loops: Loops
    base0: np.ndarray


# --------------------------------------------------------------------------- forces
@jit_borrowed
def generalized_forces(sd, extras, t, q, v, tau):
    """The generalized forces at (t, q, v) into ``tau`` (n_v,), term after term: the tip force's
    J^T F, the bodies' forces' J^T f, the joints' damping, their springs; False (tau untouched)
    when the system has none. The one place a force is written (module docstring); the
    damping's power v . (-c v) into ``sd.power[0]``, summed in the order of the DOFs."""
    if sd.tip.shape[0] == 0 and sd.damping.shape[0] == 0 and sd.stiffness.shape[0] == 0 \
            and sd.body.shape[0] == 0:
        return False
    first = True  # the first term assigns (so that a lone term's bits are its own)
    if sd.tip.shape[0] != 0:
        if extras is not None and sd.kind != PLANAR:  # (without extras: a planar chain)
            spatial_tip_torques(sd.fdata, sd.idata, sd.scratch, sd.zeros, extras.base0,
                                sd.length, q, sd.tip, tau)
        else:
            planar_tip_torques(sd.length, q, sd.tip, 0.0, v, tau)
        first = False
    if sd.body.shape[0] != 0:
        body_force_torques(sd, q, tau, first)
        first = False
    if sd.damping.shape[0] != 0:
        d = sd.damping
        if first:
            for k in range(tau.shape[0]):
                tau[k] = d[k] * v[k]
        else:
            for k in range(tau.shape[0]):
                tau[k] = tau[k] + d[k] * v[k]
        p = 0.0  # the damping's power (the work W's rate), its own loop: tau's bits as before
        for k in range(tau.shape[0]):
            p += v[k] * (d[k] * v[k])
        sd.power[0] = p
        first = False
    if sd.stiffness.shape[0] != 0:
        s, ref, at = sd.stiffness, sd.spring_ref, sd.spring_q
        if first:
            for k in range(tau.shape[0]):
                tau[k] = s[k] * (q[at[k]] - ref[k])
        else:
            for k in range(tau.shape[0]):
                tau[k] = tau[k] + s[k] * (q[at[k]] - ref[k])
    return True


@jit_borrowed
def spatial_tip_torques(fdata, idata, scratch, zeros, base0, length, q, force, out):
    """out = J_tip(q)^T F (n_v,) for a chain of any joints: the joint forces of a constant world
    force ``force`` (3,) at its tip (the distal end of the last link, along its x; ``length``:
    the links' (nl,)), each DOF's moment arm from its joint's origin, as
    :func:`redysim.algorithms.loads.tip_force_torques`, from the position pass of the kinematics
    on a workspace's packed arrays (its scratch overwritten; ``zeros`` (n_v,) and ``base0`` (3,)
    zeros)."""
    tree, s = bundles(fdata, idata, scratch)
    kinematics(tree, q, zeros, zeros, base0, s)  # (the energy's specialisation)
    oO, oR, oP, voff = s.oO, s.oR, s.oP, tree.joint_voff
    k = length.shape[0] - 1
    p0 = oO[k, 0] + length[k] * oR[k, 0, 0]
    p1 = oO[k, 1] + length[k] * oR[k, 1, 0]
    p2 = oO[k, 2] + length[k] * oR[k, 2, 0]
    f0, f1, f2 = force[0], force[1], force[2]
    for b in range(k + 1):
        a0, a1, a2 = p0 - oO[b, 0], p1 - oO[b, 1], p2 - oO[b, 2]
        c0, c1, c2 = a1 * f2 - a2 * f1, a2 * f0 - a0 * f2, a0 * f1 - a1 * f0  # arm x F
        for i in range(voff[b], voff[b + 1]):
            out[i] = (oP[i, 0] * c0 + oP[i, 1] * c1 + oP[i, 2] * c2) + (
                oP[i, 3] * f0 + oP[i, 4] * f1 + oP[i, 5] * f2)


@jit_borrowed
def body_force_torques(sd, q, tau, first):
    """tau (+)= sum_i J_i(q)^T f_i: constant world forces ``sd.force`` at points ``sd.point`` of
    bodies ``sd.body``, from the position pass of the kinematics on the workspace's packed arrays
    (its scratch overwritten): each force's wrench about its body's origin, gathered from child
    to parent (n_p += n_k + (O_k - O_p) x f_k), each axis j of body k taking P_j . [n_k; f_k].
    ``first``: assign (else add)."""
    tree, s = bundles(sd.fdata, sd.idata, sd.scratch)
    kinematics(tree, q, sd.zeros, sd.zeros, sd.base0, s)
    oO, oR, oP, voff, parent, W = s.oO, s.oR, s.oP, tree.joint_voff, tree.parent, sd.wrench
    nb = W.shape[0]
    for k in range(nb):
        for i in range(6):
            W[k, i] = 0.0
    for i in range(sd.body.shape[0]):
        k = sd.body[i]
        R, x, f = oR[k], sd.point[i], sd.force[i]
        r0 = R[0, 0] * x[0] + R[0, 1] * x[1] + R[0, 2] * x[2]  # the point from O_k, world
        r1 = R[1, 0] * x[0] + R[1, 1] * x[1] + R[1, 2] * x[2]
        r2 = R[2, 0] * x[0] + R[2, 1] * x[1] + R[2, 2] * x[2]
        W[k, 0] += r1 * f[2] - r2 * f[1]
        W[k, 1] += r2 * f[0] - r0 * f[2]
        W[k, 2] += r0 * f[1] - r1 * f[0]
        W[k, 3] += f[0]
        W[k, 4] += f[1]
        W[k, 5] += f[2]
    serial = tree.serial != 0
    # backward: k = nb..1, children first
    for k in range(nb - 1, -1, -1):
        n0, n1, n2, f0, f1, f2 = W[k, 0], W[k, 1], W[k, 2], W[k, 3], W[k, 4], W[k, 5]
        for j in range(voff[k], voff[k + 1]):
            x = (oP[j, 0] * n0 + oP[j, 1] * n1 + oP[j, 2] * n2) + (
                oP[j, 3] * f0 + oP[j, 4] * f1 + oP[j, 5] * f2)
            tau[j] = x if first else tau[j] + x
        p = k - 1 if serial else parent[k]
        if p >= 0:
            a0, a1, a2 = oO[k, 0] - oO[p, 0], oO[k, 1] - oO[p, 1], oO[k, 2] - oO[p, 2]
            W[p, 0] += n0 + (a1 * f2 - a2 * f1)
            W[p, 1] += n1 + (a2 * f0 - a0 * f2)
            W[p, 2] += n2 + (a0 * f1 - a1 * f0)
            W[p, 3] += f0
            W[p, 4] += f1
            W[p, 5] += f2


# --------------------------------------------------------------------------- the derivative
@jit_borrowed
def derivative(sd, extras, t, y, out):
    """out = (dq/dt, qdd) at (t, y), y = (q, v), or (dq/dt, qdd, dW/dt) for y = (q, v, W)
    (module docstring); False when qdd is not finite (or the loops are redundant: the Python
    side says which)."""
    nq, nv = sd.nq, sd.zeros.shape[0]
    q, v, qdd = y[:nq], y[nq:nq + nv], out[nq:nq + nv]
    tau = sd.tau if generalized_forces(sd, extras, t, q, v, sd.tau) else sd.zeros
    if extras is not None and extras.loops.ckind.shape[0] != 0:
        flag = 0.0 if loops_qdd(extras.loops, q, v, tau, qdd) == OK else 1.0
    elif extras is not None and extras.couplings.fv.shape[0] != 0:  # (RGE-A: not planar)
        flag = coupled_qdd(sd.fdata, sd.idata, sd.scratch, q, v, tau, qdd)
    elif sd.kind == RGE_A:
        flag = _rge_a(sd.fdata, sd.idata, q, v, tau, sd.scratch, qdd)
    elif sd.kind == PLANAR:
        flag = _planar(sd.fdata, sd.idata, q, v, tau, sd.scratch, qdd)
    else:
        flag = _dh(sd.fdata, sd.idata, q, v, tau, sd.scratch, qdd)
    if sd.free_q.shape[0] == 0 and sd.ball_q.shape[0] == 0:
        for k in range(nq):
            out[k] = y[nq + k]
    else:
        configuration_rate(nq, sd.plain_q, sd.plain_v, sd.free_q, sd.free_v, sd.ball_q,
                           sd.ball_v, y, out)
    if out.shape[0] > nq + nv:  # y = (q, v, W): the work's rate (module docstring)
        out[nq + nv] = sd.power[0]
    return flag == 0.0


@jit_borrowed
def configuration_rate(nq, plain_q, plain_v, free_q, free_v, ball_q, ball_v, y, out):
    """dq/dt into out[:nq] for y = (q, v) with free joints (``free_q``: each one's q slot of x,
    ``free_v`` its v slot of the linear velocity): v_world and q (x) [0; w] / 2; with ball
    joints (``ball_q``: each one's q slot of w, ``ball_v`` its v slot of w_x): q (x) [0; w] / 2;
    every other coordinate q[plain_q[i]] moving as v[plain_v[i]]."""
    for i in range(plain_q.shape[0]):
        out[plain_q[i]] = y[nq + plain_v[i]]
    for j in range(free_q.shape[0]):
        qs, vs = free_q[j], nq + free_v[j]
        for k in range(3):
            out[qs + k] = y[vs + k]
        quaternion_rate(qs + 3, vs + 3, y, out)
    for j in range(ball_q.shape[0]):
        quaternion_rate(ball_q[j], nq + ball_v[j], y, out)


@inline
def quaternion_rate(i, w, y, out):
    """out[i:i + 4] = q (x) [0; w] / 2 for the quaternion (w, x, y, z) at y[i] and the body's
    own angular velocity at y[w]."""
    qw, qx, qy, qz = y[i], y[i + 1], y[i + 2], y[i + 3]
    wx, wy, wz = y[w], y[w + 1], y[w + 2]
    out[i] = 0.5 * (-qx * wx - qy * wy - qz * wz)
    out[i + 1] = 0.5 * (qw * wx + qy * wz - qz * wy)
    out[i + 2] = 0.5 * (qw * wy - qx * wz + qz * wx)
    out[i + 3] = 0.5 * (qw * wz + qx * wy - qy * wx)


# --------------------------------------------------------------------------- the projection
@jit_borrowed
def project(sd, extras, y, worst):
    """y = (q, v) (or (q, v, W), W untouched) moved back onto the system's constraints after a
    step, in place: the loops
    (:func:`.constraints.loops_project`), then each coupling's follower onto its leader, then
    each quaternion onto the unit sphere; the largest departures met into ``worst`` (as
    :attr:`SystemData.worst`). Returns OK, or the loops' status (the Python side says why)."""
    nq, nv = sd.nq, sd.zeros.shape[0]
    if extras is not None and extras.loops.ckind.shape[0] != 0:
        status = loops_project(extras.loops, y[:nq], y[nq:nq + nv], worst[RESIDUAL_Q:])
        if status != OK:
            return status
    if extras is not None:
        project_couplings(extras.couplings, nq, y, worst[RESIDUAL_Q:])
    project_quaternions(sd.free_q, 3, y, worst)
    project_quaternions(sd.ball_q, 0, y, worst)
    return OK


@jit_borrowed
def project_step(sd, extras, y):
    """:func:`project` after a step, the departures met kept in ``sd.worst``."""
    return project(sd, extras, y, sd.worst)


@jit_exact
def project_couplings(cp, nq, y, worst):
    """Each follower's coordinate and velocity in y = (q, v) set from its leader's (q_f = m q_l
    + offset, v_f = m v_l), in place, IEEE as written; the largest departures met before into
    worst[0] (q) and worst[1] (v)."""
    for i in range(cp.fq.shape[0]):
        want = cp.m[i] * y[cp.lq[i]] + cp.off[i]
        e = abs(y[cp.fq[i]] - want)
        if e > worst[0]:
            worst[0] = e
        y[cp.fq[i]] = want
        want = cp.m[i] * y[nq + cp.lv[i]]
        e = abs(y[nq + cp.fv[i]] - want)
        if e > worst[1]:
            worst[1] = e
        y[nq + cp.fv[i]] = want


@jit_borrowed
def project_quaternions(slots, shift, y, worst):
    """Each quaternion, at y[slots[j] + shift] (a free joint's: its q slot of x and 3; a ball
    joint's: its slot of w and 0), divided by its norm, in place; the largest | |q| - 1 | met
    into worst[0]."""
    for j in range(slots.shape[0]):
        i = slots[j] + shift
        norm = math.sqrt(y[i] * y[i] + y[i + 1] * y[i + 1] + y[i + 2] * y[i + 2]
                         + y[i + 3] * y[i + 3])
        e = abs(norm - 1.0)
        if e > worst[0]:
            worst[0] = e
        for k in range(4):
            y[i + k] = y[i + k] / norm
