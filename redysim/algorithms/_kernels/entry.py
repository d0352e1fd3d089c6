"""Forward dynamics' entry points: a workspace's packed arrays in, 7 arguments instead of 28.

numba's dispatcher types and unboxes every argument of every call, at a cost per array that matters
for small systems (docs/design.md, "Performance notes"). A
:class:`~redysim.algorithms.workspace.Workspace` therefore packs the tree's arrays into one float
and one int array and its scratch arrays into one float array, and these entries slice the named
bundles (:mod:`.bundles`) back out of them (views: nothing is copied or allocated). The int array
starts with a header, the sizes and the offset of every segment, written by the workspace (the one
place that lays the arrays out, both from the one table of :mod:`.bundles`) and read here by its
slots.

Each entry is compiled for exactly one signature (:class:`redysim._jit.EntryPoint`): q, qd and tau
C-contiguous float64 vectors, read-only or not; the packed arrays and qdd writeable C-contiguous
float64 (int64) vectors. numba refuses any other argument types with TypeError rather than
compile them, and the entry checks the lengths (the kernels index without bounds checks), so
these two are the whole of the type and size checks a plain call needs; the caller checks and
converts anything else (:func:`redysim.algorithms.dynamics.forward_dynamics`).

Both return 0.0, NaN when some qdd is not finite, or SIZE_MISMATCH, having written nothing, when
q is not of length n_q or qd, tau or qdd not of length n_v.
"""

from __future__ import annotations

from numba import types

from redysim._jit import EntryPoint, inline, inline_generated

from .bundles import (
    DH_COLUMNS,
    DH_SCRATCH,
    H_NA,
    H_NB,
    H_NQ,
    H_NV,
    SLOT,
    Scratch,
    Tree,
    bundles_source,
    numba_types,
)
from .dh import dh_forward_dynamics, dh_inverse_dynamics
from .kinematics import kinematics
from .planar import planar_forward_dynamics
from .rge_a import rge_a_backward, rge_a_forward

SIZE_MISMATCH = -1.0

# the header slots of the segments the entries read besides the bundles (.bundles.LAYOUT)
F_BASE_ACCEL, F_GRAVITY, F_ZEROS, F_MASS = (SLOT[k] for k in ("base_accel", "gravity", "zeros",
                                                               "mass"))
F_LENGTH, F_IZZ_O, F_MC_X, F_MC_Y, S_PLANAR = (SLOT[k] for k in ("length", "izz_O", "mc_x",
                                                                  "mc_y", "planar"))
F_ARMATURE = SLOT["armature"]
F_DH, S_DH = SLOT["dh"], SLOT["dh_scratch"]
DHC = len(DH_COLUMNS)

_F1, _F2 = (types.Array(types.float64, d, "C") for d in (1, 2))
_RO = types.Array(types.float64, 1, "C", readonly=True)
_I1 = types.Array(types.int64, 1, "C")
TREE, SCRATCH = numba_types()[:2]
SIGNATURE = types.float64(_F1, _I1, _RO, _RO, _RO, _F1, _F1)
# the kernels as the entries call them (the bundles' types), loaded before the entries
# (redysim._jit.EntryPoint: the callees' own machine code, not the entries' copies of it)
RGE_A_CALLEES = (
    (kinematics, (TREE, _RO, _RO, _F1, _F1, SCRATCH, types.literal(True))),  # local_rates=True
    (rge_a_backward, (TREE, SCRATCH, _RO)),
    (rge_a_forward, (TREE, SCRATCH, _F1, _F1)))
PLANAR_CALLEES = (
    (planar_forward_dynamics, (_F1, _F1, _F1, _F1, _F1, _F1, _F1, _RO, _RO, _RO, _F1, _F2)),)
DH_CALLEES = ((dh_forward_dynamics, (_F2, _RO, _RO, _RO, _F1, _F1, _F2)),)
DH_INVERSE_CALLEES = ((dh_inverse_dynamics, (_F2, _RO, _RO, _RO, _F1, _F1, _F2)),)

# The Tree and Scratch bundles as views of a workspace's packed arrays, generated from the
# layout table (.bundles.bundles_source; its Python form also runs in the workspace itself).
bundles = inline_generated(bundles_source(), "bundles", dict(Tree=Tree, Scratch=Scratch))


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
        fdata[h[F_MC_Y]:h[F_MC_Y] + nl], fdata[h[F_ARMATURE]:h[F_ARMATURE] + h[H_NA]],
        fdata[h[F_GRAVITY]:h[F_GRAVITY] + 3], q, qd, tau, qdd,
        scratch[h[S_PLANAR]:h[S_PLANAR] + 12 * nl].reshape((nl, 12)))


@inline
def _finite(x):
    """0.0 when every x is finite, else NaN."""
    bad = 0.0
    for k in range(x.shape[0]):
        bad += x[k] * 0.0
    return bad


@inline
def _dh_views(fdata, idata, scratch):
    """A DH robot's constants (nb, DHC), -g and the DH kernels' scratch (nb, DH_SCRATCH), as
    views of a workspace's packed arrays."""
    h = idata
    nb = h[H_NB]
    return (fdata[h[F_DH]:h[F_DH] + DHC * nb].reshape((nb, DHC)),
            fdata[h[F_BASE_ACCEL]:h[F_BASE_ACCEL] + 3],
            scratch[h[S_DH]:h[S_DH] + DH_SCRATCH * nb].reshape((nb, DH_SCRATCH)))


def dh_entry(fdata, idata, q, qd, tau, scratch, qdd):
    """:func:`.dh.dh_forward_dynamics` on a DH robot's packed arrays (module docstring)."""
    n = idata[H_NV]
    if q.shape[0] != n or qd.shape[0] != n or tau.shape[0] != n or qdd.shape[0] != n:
        return SIZE_MISMATCH
    table, base_accel, scr = _dh_views(fdata, idata, scratch)
    dh_forward_dynamics(table, q, qd, tau, base_accel, qdd, scr)
    return _finite(qdd)


def dh_inverse_entry(fdata, idata, q, qd, qdd, scratch, tau):
    """:func:`.dh.dh_inverse_dynamics` on a DH robot's packed arrays: tau into ``tau``
    (module docstring; NaN when some tau is not finite)."""
    n = idata[H_NV]
    if q.shape[0] != n or qd.shape[0] != n or qdd.shape[0] != n or tau.shape[0] != n:
        return SIZE_MISMATCH
    table, base_accel, scr = _dh_views(fdata, idata, scratch)
    dh_inverse_dynamics(table, q, qd, qdd, base_accel, tau, scr)
    return _finite(tau)


RGE_A = EntryPoint(rge_a_entry, SIGNATURE, RGE_A_CALLEES)
PLANAR = EntryPoint(planar_entry, SIGNATURE, PLANAR_CALLEES)
DH = EntryPoint(dh_entry, SIGNATURE, DH_CALLEES)
DH_INVERSE = EntryPoint(dh_inverse_entry, SIGNATURE, DH_INVERSE_CALLEES)
