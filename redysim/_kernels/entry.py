"""Forward dynamics' entry points: a workspace's packed arrays in, 7 arguments instead of 28.

numba's dispatcher types and unboxes every argument of every call, at a cost per array that
matters for small systems (docs/design.md, "Performance notes"). A
:class:`~redysim.workspace.Workspace` therefore packs the tree's arrays into one float and one
int array and its scratch arrays into one float array, and these entries slice the named bundles
(:mod:`.bundles`) back out of them (views: nothing is copied or allocated). The int array starts
with a header, the sizes and the offset of every segment, written by the workspace (the one place
that lays the arrays out) and read here by the slot numbers below.

Each entry is compiled for exactly one signature (:class:`redysim._jit.EntryPoint`): q, qd and tau
C-contiguous float64 vectors, read-only or not; the packed arrays and qdd writeable C-contiguous
float64 (int64) vectors. numba refuses any other argument types with TypeError rather than
compile them, and the entry checks the lengths (the kernels index without bounds checks), so
these two are the whole of the type and size checks a plain call needs; the caller checks and
converts anything else (:func:`redysim.dynamics.forward_dynamics`).

Both return 0.0, NaN when some qdd is not finite, or SIZE_MISMATCH, having written nothing, when
q is not of length n_q or qd, tau or qdd not of length n_v.
"""

from __future__ import annotations

from numba import types

from .._jit import EntryPoint, inline
from .bundles import GATHER_MASS, Scratch, Tree
from .kinematics import kinematics
from .planar import planar_forward_dynamics
from .rge_a import rge_a_backward, rge_a_forward

SIZE_MISMATCH = -1.0

# the int array's header: sizes (bodies, velocity and configuration coordinates, gathering
# bodies), the serial flag, then the offset of each segment in its array
H_NB, H_NV, H_NQ, H_NG, H_SERIAL = range(5)
# float array (the tree's): along, placement_R, placement_p, dof_u, mass, inertia_O, mass_com,
# -g, g, zeros (n_v) and, for a planar chain, length, izz_O, m c_x, m c_y
(F_ALONG, F_PLACEMENT_R, F_PLACEMENT_P, F_DOF_U, F_MASS, F_INERTIA_O, F_MASS_COM, F_BASE_ACCEL,
 F_GRAVITY, F_ZEROS, F_LENGTH, F_IZZ_O, F_MC_X, F_MC_Y) = range(5, 19)
# int array (the tree's): parent, gather, placement_code, qshift, joint_voff, dof_kind, dof_axis
(I_PARENT, I_GATHER, I_PLACEMENT_CODE, I_QSHIFT, I_JOINT_VOFF, I_DOF_KIND,
 I_DOF_AXIS) = range(19, 26)
# scratch array: the Scratch bundle's arrays, then the planar kernel's
(S_OR, S_OO, S_OP, S_T, S_TD, S_IHAT, S_PSIHAT, S_PHITIL, S_PHIHAT, S_W, S_GATHER_MASS,
 S_GATHER_WRENCH, S_GATHER_TWIST, S_PLANAR) = range(26, 40)
HEADER = 40

_F1, _F2, _F3 = (types.Array(types.float64, d, "C") for d in (1, 2, 3))
_RO = types.Array(types.float64, 1, "C", readonly=True)
_I1 = types.Array(types.int64, 1, "C")
TREE = types.NamedTuple((types.int64, _I1, _I1, _I1, _I1, _F1, _F3, _F2, _I1, _I1, _I1, _F2,
                         _F1, _F3, _F2), Tree)
SCRATCH = types.NamedTuple((_F3, _F2, _F2, _F2, _F2, _F1, _F2, _F1, _F1, _F2, _F2, _F2, _F2),
                           Scratch)
SIGNATURE = types.float64(_F1, _I1, _RO, _RO, _RO, _F1, _F1)
# the kernels as the entries call them (the bundles' types), loaded before the entries
# (redysim._jit.EntryPoint: the callees' own machine code, not the entries' copies of it)
RGE_A_CALLEES = (
    (kinematics, (TREE, _RO, _RO, _F1, _F1, SCRATCH, types.literal(True))),  # local_rates=True
    (rge_a_backward, (TREE, SCRATCH, _RO)),
    (rge_a_forward, (TREE, SCRATCH, _F1, _F1)))
PLANAR_CALLEES = (
    (planar_forward_dynamics, (_F1, _F1, _F1, _F1, _F1, _F1, _RO, _RO, _RO, _F1, _F2)),)


@inline
def bundles(fdata, idata, scratch):
    """The Tree and Scratch bundles as views of a workspace's packed arrays (its Python source
    also runs in the workspace itself: one layout, read in one place)."""
    h = idata
    nb, nv, ng = h[H_NB], h[H_NV], h[H_NG]
    nt = 0 if h[H_SERIAL] else nb  # a serial chain's tree tables are empty
    # the segments, sliced out inline: a helper taking the slot (a literal int) was compiled
    # once per slot, 3 s of the cold compile
    tree = Tree(
        h[H_SERIAL],
        idata[h[I_PARENT]:h[I_PARENT] + nt],
        idata[h[I_GATHER]:h[I_GATHER] + nt],
        idata[h[I_PLACEMENT_CODE]:h[I_PLACEMENT_CODE] + nt],
        idata[h[I_QSHIFT]:h[I_QSHIFT] + nt],
        fdata[h[F_ALONG]:h[F_ALONG] + nb],
        fdata[h[F_PLACEMENT_R]:h[F_PLACEMENT_R] + 9 * nt].reshape((nt, 3, 3)),
        fdata[h[F_PLACEMENT_P]:h[F_PLACEMENT_P] + 3 * nt].reshape((nt, 3)),
        idata[h[I_JOINT_VOFF]:h[I_JOINT_VOFF] + nb + 1],
        idata[h[I_DOF_KIND]:h[I_DOF_KIND] + nv],
        idata[h[I_DOF_AXIS]:h[I_DOF_AXIS] + nv],
        fdata[h[F_DOF_U]:h[F_DOF_U] + 3 * nv].reshape((nv, 3)),
        fdata[h[F_MASS]:h[F_MASS] + nb],
        fdata[h[F_INERTIA_O]:h[F_INERTIA_O] + 9 * nb].reshape((nb, 3, 3)),
        fdata[h[F_MASS_COM]:h[F_MASS_COM] + 3 * nb].reshape((nb, 3)))
    s = Scratch(
        scratch[h[S_OR]:h[S_OR] + 9 * nb].reshape((nb, 3, 3)),
        scratch[h[S_OO]:h[S_OO] + 3 * nb].reshape((nb, 3)),
        scratch[h[S_OP]:h[S_OP] + 6 * nv].reshape((nv, 6)),
        scratch[h[S_T]:h[S_T] + 6 * nb].reshape((nb, 6)),
        scratch[h[S_TD]:h[S_TD] + 6 * nb].reshape((nb, 6)),
        scratch[h[S_IHAT]:h[S_IHAT] + nv],
        scratch[h[S_PSIHAT]:h[S_PSIHAT] + 6 * nv].reshape((nv, 6)),
        scratch[h[S_PHITIL]:h[S_PHITIL] + nv],
        scratch[h[S_PHIHAT]:h[S_PHIHAT] + nv],
        scratch[h[S_W]:h[S_W] + 6 * nb].reshape((nb, 6)),
        scratch[h[S_GATHER_MASS]:h[S_GATHER_MASS] + GATHER_MASS * ng].reshape((ng, GATHER_MASS)),
        scratch[h[S_GATHER_WRENCH]:h[S_GATHER_WRENCH] + 6 * ng].reshape((ng, 6)),
        scratch[h[S_GATHER_TWIST]:h[S_GATHER_TWIST] + 6 * ng].reshape((ng, 6)))
    return tree, s


def rge_a_entry(fdata, idata, q, qd, tau, scratch, qdd):
    """Kinematics and RGE-A's two passes, as :func:`rge_a_forward_dynamics`, on a workspace's
    packed arrays (module docstring)."""
    h = idata
    nv = h[H_NV]
    if q.shape[0] != h[H_NQ] or qd.shape[0] != nv or tau.shape[0] != nv or qdd.shape[0] != nv:
        return SIZE_MISMATCH
    tree, s = bundles(fdata, idata, scratch)
    base_accel = fdata[h[F_BASE_ACCEL]:h[F_BASE_ACCEL] + 3]
    zeros = fdata[h[F_ZEROS]:h[F_ZEROS] + nv]
    # rge_a_forward_dynamics' three passes, called directly (one level of calls less to compile)
    kinematics(tree, q, qd, zeros, base_accel, s, True)
    rge_a_backward(tree, s, tau)
    return rge_a_forward(tree, s, base_accel, qdd)


def planar_entry(fdata, idata, q, qd, tau, scratch, qdd):
    """:func:`planar_forward_dynamics` on a planar chain's packed arrays (module docstring)."""
    h = idata
    nl, n = h[H_NB], h[H_NV]
    if q.shape[0] != n or qd.shape[0] != n or tau.shape[0] != n or qdd.shape[0] != n:
        return SIZE_MISMATCH
    return planar_forward_dynamics(
        fdata[h[F_LENGTH]:h[F_LENGTH] + nl], fdata[h[F_MASS]:h[F_MASS] + nl],
        fdata[h[F_IZZ_O]:h[F_IZZ_O] + nl], fdata[h[F_MC_X]:h[F_MC_X] + nl],
        fdata[h[F_MC_Y]:h[F_MC_Y] + nl], fdata[h[F_GRAVITY]:h[F_GRAVITY] + 3], q, qd, tau, qdd,
        scratch[h[S_PLANAR]:h[S_PLANAR] + 12 * nl].reshape((nl, 12)))


RGE_A = EntryPoint(rge_a_entry, SIGNATURE, RGE_A_CALLEES)
PLANAR = EntryPoint(planar_entry, SIGNATURE, PLANAR_CALLEES)
