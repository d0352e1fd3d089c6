"""Forward dynamics' entry points: a workspace's packed arrays in, 7 arguments instead of 23.

numba's dispatcher types and unboxes every argument of every call, at a cost per array that
matters for small chains (docs/design.md, "Performance notes"). A
:class:`~redysim.workspace.Workspace` therefore packs the chain's arrays into one float
and one int array (copies: the chain is immutable) and its scratch arrays into one float array,
and these entries slice the kernels' arrays back out of them (views: nothing is copied or
allocated). The int array starts with a header, ``nl``, ``n`` and the offset of every
segment, written by the workspace (the one place that lays the arrays out) and read here by the
slot numbers below.

Each entry is compiled for exactly one signature (:class:`redysim._jit.EntryPoint`): q, qd and tau
C-contiguous float64 vectors, read-only or not; the packed arrays and qdd writeable C-contiguous
float64 (int64) vectors. numba refuses any other argument types with TypeError rather than
compile them, and the entry checks the lengths (the kernels index without bounds checks), so
these two are the whole of the type and size checks a plain call needs; the caller checks and
converts anything else (:func:`redysim.dynamics.forward_dynamics`).

Both return 0.0, NaN when some qdd is not finite, or SIZE_MISMATCH, having written nothing, when
q, qd, tau or qdd is not of length n.
"""

from __future__ import annotations

from numba import types

from .._jit import EntryPoint
from .kinematics import kinematics
from .planar import planar_forward_dynamics
from .rge_a import rge_a_backward, rge_a_forward

SIZE_MISMATCH = -1.0

# slots of the int array's header: nl, n, then the offset of each segment in its array
H_NL, H_N = 0, 1
# float array (the chain's): length, mass, inertia_O, mass_com, dof_u, -g, g, zeros (n) and, for
# a planar chain, izz_O, m c_x, m c_y
(F_LENGTH, F_MASS, F_INERTIA_O, F_MASS_COM, F_DOF_U, F_BASE_ACCEL, F_GRAVITY, F_ZEROS, F_IZZ_O,
 F_MC_X, F_MC_Y) = range(2, 13)
# int array (the chain's): dof_kind, dof_axis, joint_qoff
I_DOF_KIND, I_DOF_AXIS, I_JOINT_QOFF = range(13, 16)
# scratch array: the workspace's oR, oO, oP, t, td, Ihat, Psihat, phitil, phihat, planar
(S_OR, S_OO, S_OP, S_T, S_TD, S_IHAT, S_PSIHAT, S_PHITIL, S_PHIHAT, S_PLANAR) = range(16, 26)
HEADER = 26

_F1, _F2, _F3 = (types.Array(types.float64, d, "C") for d in (1, 2, 3))
_RO = types.Array(types.float64, 1, "C", readonly=True)
_I1 = types.Array(types.int64, 1, "C")
SIGNATURE = types.float64(_F1, _I1, _RO, _RO, _RO, _F1, _F1)
# the kernels as the entries call them (the segments' types), loaded before the entries
# (redysim._jit.EntryPoint: the callees' own machine code, not the entries' copies of it)
RGE_A_CALLEES = (
    (kinematics, (_F1, _I1, _I1, _F2, _I1, _RO, _RO, _F1, _F1, _F3, _F2, _F2, _F2, _F2,
                  types.literal(True))),  # local_rates=True
    (rge_a_backward, (_F1, _F3, _F2, _I1, _I1, _F3, _F2, _F2, _F2, _F2, _RO, _F1, _F2, _F1,
                      _F1)),
    (rge_a_forward, (_I1, _F2, _F2, _F2, _F1, _F2, _F1, _F1)))
PLANAR_CALLEES = (
    (planar_forward_dynamics, (_F1, _F1, _F1, _F1, _F1, _F1, _RO, _RO, _RO, _F1, _F2)),)


def rge_a_entry(fdata, idata, q, qd, tau, scratch, qdd):
    """Kinematics and RGE-A's two passes, as :func:`rge_a_forward_dynamics`, on a workspace's
    packed arrays (module docstring)."""
    h = idata
    nl, n = h[H_NL], h[H_N]
    if q.shape[0] != n or qd.shape[0] != n or tau.shape[0] != n or qdd.shape[0] != n:
        return SIZE_MISMATCH
    # the segments, sliced out inline: a helper taking the slot (a literal int) was compiled
    # once per slot, 3 s of the cold compile
    length = fdata[h[F_LENGTH]:h[F_LENGTH] + nl]
    mass = fdata[h[F_MASS]:h[F_MASS] + nl]
    inertia_O = fdata[h[F_INERTIA_O]:h[F_INERTIA_O] + 9 * nl].reshape((nl, 3, 3))
    mass_com = fdata[h[F_MASS_COM]:h[F_MASS_COM] + 3 * nl].reshape((nl, 3))
    dof_u = fdata[h[F_DOF_U]:h[F_DOF_U] + 3 * n].reshape((n, 3))
    base_accel = fdata[h[F_BASE_ACCEL]:h[F_BASE_ACCEL] + 3]
    zeros = fdata[h[F_ZEROS]:h[F_ZEROS] + n]
    dof_kind = idata[h[I_DOF_KIND]:h[I_DOF_KIND] + n]
    dof_axis = idata[h[I_DOF_AXIS]:h[I_DOF_AXIS] + n]
    joint_qoff = idata[h[I_JOINT_QOFF]:h[I_JOINT_QOFF] + nl + 1]
    oR = scratch[h[S_OR]:h[S_OR] + 9 * nl].reshape((nl, 3, 3))
    oO = scratch[h[S_OO]:h[S_OO] + 3 * nl].reshape((nl, 3))
    oP = scratch[h[S_OP]:h[S_OP] + 6 * n].reshape((n, 6))
    t = scratch[h[S_T]:h[S_T] + 6 * nl].reshape((nl, 6))
    c = scratch[h[S_TD]:h[S_TD] + 6 * nl].reshape((nl, 6))
    Ihat = scratch[h[S_IHAT]:h[S_IHAT] + n]
    Psihat = scratch[h[S_PSIHAT]:h[S_PSIHAT] + 6 * n].reshape((n, 6))
    phitil = scratch[h[S_PHITIL]:h[S_PHITIL] + n]
    phihat = scratch[h[S_PHIHAT]:h[S_PHIHAT] + n]
    # rge_a_forward_dynamics' three passes, called directly (one level of calls less to compile)
    kinematics(length, dof_kind, dof_axis, dof_u, joint_qoff, q, qd, zeros, base_accel,
               oR, oO, oP, t, c, True)
    rge_a_backward(mass, inertia_O, mass_com, dof_kind, joint_qoff, oR, oO, oP, t, c, tau,
                   Ihat, Psihat, phitil, phihat)
    return rge_a_forward(joint_qoff, oO, oP, Psihat, phitil, c, base_accel, qdd)


def planar_entry(fdata, idata, q, qd, tau, scratch, qdd):
    """:func:`planar_forward_dynamics` on a planar chain's packed arrays (module docstring)."""
    h = idata
    nl, n = h[H_NL], h[H_N]
    if q.shape[0] != n or qd.shape[0] != n or tau.shape[0] != n or qdd.shape[0] != n:
        return SIZE_MISMATCH
    return planar_forward_dynamics(
        fdata[h[F_LENGTH]:h[F_LENGTH] + nl], fdata[h[F_MASS]:h[F_MASS] + nl],
        fdata[h[F_IZZ_O]:h[F_IZZ_O] + nl], fdata[h[F_MC_X]:h[F_MC_X] + nl],
        fdata[h[F_MC_Y]:h[F_MC_Y] + nl], fdata[h[F_GRAVITY]:h[F_GRAVITY] + 3], q, qd, tau, qdd,
        scratch[h[S_PLANAR]:h[S_PLANAR] + 12 * nl].reshape((nl, 12)))


RGE_A = EntryPoint(rge_a_entry, SIGNATURE, RGE_A_CALLEES)
PLANAR = EntryPoint(planar_entry, SIGNATURE, PLANAR_CALLEES)
