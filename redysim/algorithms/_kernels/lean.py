"""Lean entries: one compiled function per call of an evaluator, for small systems.

:func:`redysim.evaluator` calls these with numba's dispatch bypassed
(``redysim._jit.unchecked_call``: the compiled wrapper itself, its arguments not typed), so they
check for themselves what the dispatcher would have: every vector's length and that its elements
are contiguous (stride 8).
The caller checks before the call what the wrapper cannot (that each argument is a 1-D float64
ndarray, ``out`` writeable). Anything they refuse (a length, a stride, a qdd or tau that is not
finite) raises :class:`Refused` having written at most ``out``; the caller then takes the checked
path (:func:`redysim.forward_dynamics`, :func:`redysim.inverse_dynamics`), which converts the
input or says what is wrong with it. They return ``out``: numba hands back the caller's own array
object (nothing is boxed; compiled without reference counting).

Arguments: ``q, v, x, out, fdata, idata, scratch``, with ``x`` tau (forward dynamics: zeros for
none) or qdd (inverse dynamics), and a workspace's packed arrays
(:class:`redysim.algorithms.workspace.Workspace`).

Where the time of a small system's call went, and what these do instead (docs/design.md,
"Performance notes"): numba's dispatch of the entry's 7 arrays; the bundles cut out of the packed
arrays by ``reshape``, whose result numba gets from a C helper, so that the strides of every 2-D
and 3-D array were numbers LLVM could not see (:func:`c_view` builds the C-contiguous view
itself); and the three passes called as functions, each handed the 27 arrays of the bundles as
~250 scalar arguments. Here the passes are inlined into one function, a serial chain's and a
tree's compiled apart (as the passes are), so only the one a model needs is compiled. Same
source as the passes that :func:`redysim.forward_dynamics` calls: the results are theirs, bit for
bit (``tests/test_evaluator.py``).
"""

from __future__ import annotations

from numba import types
from numba.core import cgutils
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array

from redysim._jit import LEAN_OPTIONS, EntryPoint, inline, inline_generated

from . import entry as E
from .bundles import DH_SCRATCH, H_NB, H_NQ, H_NV, Scratch, Tree, bundles_source
from .dh import dh_forward_dynamics, dh_inverse_dynamics
from .inverse_dynamics import rnea_backward
from .kinematics import _kinematics
from .rge_a import _rge_a_backward, _rge_a_forward


class Refused(Exception):
    """A lean entry's refusal of its arguments: the caller's checked path says why."""


@intrinsic
def c_view(typingctx, segment, shape):
    """``segment``'s data as a C-contiguous array of ``shape`` (an int tuple), its strides
    computed here, where LLVM sees them; no check that the shape fits the segment (the layout
    table sized the segment: :mod:`.bundles`). ``reshape`` gets them from a C helper instead."""
    if not isinstance(segment, types.Array) or not isinstance(shape, types.BaseTuple):
        return None
    result = segment.copy(ndim=len(shape), layout="C")

    def codegen(context, builder, sig, args):
        source = make_array(sig.args[0])(context, builder, args[0])
        view = make_array(result)(context, builder)
        dims = cgutils.unpack_tuple(builder, args[1])
        strides, step = [], source.itemsize
        for d in reversed(dims):
            strides.insert(0, step)
            step = builder.mul(step, d)
        populate_array(view, data=source.data, shape=dims, strides=strides,
                       itemsize=source.itemsize, meminfo=source.meminfo)
        return impl_ret_borrowed(context, builder, result, view._getvalue())

    return result(segment, shape), codegen


# The Tree and Scratch bundles, as .entry's bundles but every array shaped by c_view
bundles = inline_generated(bundles_source(shaper="c_view"), "bundles",
                           dict(Tree=Tree, Scratch=Scratch, c_view=c_view))


@inline
def _plain(x, n):
    """True when vector ``x`` has n elements, contiguous."""
    return x.shape[0] == n and (x.strides[0] == 8 or n < 2)


@inline
def _forward(q, v, tau, out, fdata, idata, scratch, serial):
    h = idata
    nv = h[H_NV]
    if not (_plain(q, h[H_NQ]) and _plain(v, nv) and _plain(tau, nv) and _plain(out, nv)):
        raise Refused()
    tree, s = bundles(fdata, idata, scratch)
    base_accel = fdata[h[E.F_BASE_ACCEL]:h[E.F_BASE_ACCEL] + 3]
    zeros = fdata[h[E.F_ZEROS]:h[E.F_ZEROS] + nv]
    _kinematics(tree, q, v, zeros, base_accel, s, True, serial)
    _rge_a_backward(tree, s, tau, serial)
    if _rge_a_forward(tree, s, base_accel, out, serial) != 0.0:
        raise Refused()  # some qdd is not finite


def forward_chain(q, v, tau, out, fdata, idata, scratch):
    """qdd by RGE-A into ``out``, a serial chain (module docstring)."""
    _forward(q, v, tau, out, fdata, idata, scratch, True)
    return out  # (numba returns an argument only by name, unboxed: the caller's own array)


def forward_tree(q, v, tau, out, fdata, idata, scratch):
    """qdd by RGE-A into ``out``, any tree (module docstring)."""
    _forward(q, v, tau, out, fdata, idata, scratch, False)
    return out


_planar_entry = inline(E.planar_entry)


def forward_planar(q, v, tau, out, fdata, idata, scratch):
    """qdd into ``out`` by the planar kernel, a planar chain (module docstring): .entry's planar
    entry, strides checked."""
    n = idata[H_NV]
    if not (_plain(q, n) and _plain(v, n) and _plain(tau, n) and _plain(out, n)):
        raise Refused()
    if _planar_entry(fdata, idata, q, v, tau, scratch, out) != 0.0:
        raise Refused()
    return out


@inline
def _dh_views(fdata, idata, scratch):
    """A DH robot's constants (nb, DHC), -g and the DH kernels' scratch, as views (.entry's
    dh_entry's, their strides computed here: :func:`c_view`)."""
    h = idata
    nb = h[H_NB]
    return (c_view(fdata[h[E.F_DH]:h[E.F_DH] + E.DHC * nb], (nb, E.DHC)),
            fdata[h[E.F_BASE_ACCEL]:h[E.F_BASE_ACCEL] + 3],
            c_view(scratch[h[E.S_DH]:h[E.S_DH] + DH_SCRATCH * nb], (nb, DH_SCRATCH)))


def forward_dh(q, v, tau, out, fdata, idata, scratch):
    """qdd into ``out`` by the DH kernel, a robot in DH form (module docstring): the kernel on
    the views .entry's dh_entry cuts, strides checked."""
    n = idata[H_NV]
    if not (_plain(q, n) and _plain(v, n) and _plain(tau, n) and _plain(out, n)):
        raise Refused()
    table, base_accel, scr = _dh_views(fdata, idata, scratch)
    # the kernel's compiled code, called: IEEE as written (redysim._jit.jit_exact), the bits of
    # every other caller; inlining its source here would compile it with this entry's FMA fusion
    dh_forward_dynamics(table, q, v, tau, base_accel, out, scr)
    if E._finite(out) != 0.0:
        raise Refused()  # some qdd is not finite
    return out


def inverse_dh(q, v, qdd, out, fdata, idata, scratch):
    """tau into ``out`` by the DH kernel, a robot in DH form (module docstring)."""
    n = idata[H_NV]
    if not (_plain(q, n) and _plain(v, n) and _plain(qdd, n) and _plain(out, n)):
        raise Refused()
    table, base_accel, scr = _dh_views(fdata, idata, scratch)
    dh_inverse_dynamics(table, q, v, qdd, base_accel, out, scr)
    if E._finite(out) != 0.0:
        raise Refused()  # some tau is not finite
    return out


_rnea_backward = inline(getattr(rnea_backward, "py_func", rnea_backward))


@inline
def _inverse(q, v, qdd, out, fdata, idata, scratch, serial):
    h = idata
    nv = h[H_NV]
    if not (_plain(q, h[H_NQ]) and _plain(v, nv) and _plain(qdd, nv) and _plain(out, nv)):
        raise Refused()
    tree, s = bundles(fdata, idata, scratch)
    base_accel = fdata[h[E.F_BASE_ACCEL]:h[E.F_BASE_ACCEL] + 3]
    _kinematics(tree, q, v, qdd, base_accel, s, False, serial)
    _rnea_backward(tree, s, out)
    bad = 0.0
    for j in range(nv):
        bad += out[j] * 0.0
    if bad != 0.0:
        raise Refused()  # some tau is not finite


def inverse_chain(q, v, qdd, out, fdata, idata, scratch):
    """tau by Newton-Euler into ``out``, a serial chain (module docstring)."""
    _inverse(q, v, qdd, out, fdata, idata, scratch, True)
    return out


def inverse_tree(q, v, qdd, out, fdata, idata, scratch):
    """tau by Newton-Euler into ``out``, any tree (module docstring)."""
    _inverse(q, v, qdd, out, fdata, idata, scratch, False)
    return out


_F1 = types.Array(types.float64, 1, "C")
_RO = types.Array(types.float64, 1, "C", readonly=True)
_I1 = types.Array(types.int64, 1, "C")
SIGNATURE = _F1(_RO, _RO, _RO, _F1, _F1, _I1, _F1)

FORWARD_CHAIN = EntryPoint(forward_chain, SIGNATURE, options=LEAN_OPTIONS)
FORWARD_TREE = EntryPoint(forward_tree, SIGNATURE, options=LEAN_OPTIONS)
FORWARD_PLANAR = EntryPoint(forward_planar, SIGNATURE, E.PLANAR_CALLEES, options=LEAN_OPTIONS)
INVERSE_CHAIN = EntryPoint(inverse_chain, SIGNATURE, options=LEAN_OPTIONS)
INVERSE_TREE = EntryPoint(inverse_tree, SIGNATURE, options=LEAN_OPTIONS)
FORWARD_DH = EntryPoint(forward_dh, SIGNATURE, E.DH_CALLEES, options=LEAN_OPTIONS)
INVERSE_DH = EntryPoint(inverse_dh, SIGNATURE, E.DH_INVERSE_CALLEES, options=LEAN_OPTIONS)
