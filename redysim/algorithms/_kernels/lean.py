"""Lean entries: one compiled function per call of an evaluator, for small systems.

:func:`redysim.evaluator` calls these from the builtin :mod:`.binding` generates for each,
and :func:`redysim.inverse_dynamics` with numba's dispatch bypassed
(``redysim._jit.unchecked_call``: the compiled wrapper itself, its arguments not typed), so they
check for themselves what the dispatcher would have: every vector's length and that its elements
are contiguous (stride 8).
Each caller checks before the call that each vector is a 1-D aligned native float64 ndarray,
``out`` writeable (the builtin in its own C function; numba's wrapper through
:class:`CheckedVector`'s unboxing, below). Anything they refuse (a length, a stride, a qdd or
tau that is not finite) raises :class:`Refused` (to the builtin: a failed status) having written
at most ``out``; the caller then takes the checked path (:func:`redysim.forward_dynamics`,
:func:`redysim.inverse_dynamics`), which converts the input or says what is wrong with it. They
return ``out``: numba hands back the caller's own array
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

import ctypes

import numpy as np
from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba.core.boxing import box_array
from numba.core.datamodel.models import ArrayModel
from numba.core.imputils import impl_ret_borrowed, lower_cast
from numba.extending import NativeValue, box, intrinsic, register_model, unbox
from numba.np.arrayobj import make_array, populate_array

from redysim._jit import INTERNALS_OK, LEAN_OPTIONS, EntryPoint, inline, inline_generated

from . import entry as E
from .bundles import DH_SCRATCH, H_NB, H_NQ, H_NV, Scratch, Tree, bundles_source
from .couplings import couple_step, on_couplings
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


# ---- Vectors that check themselves: q, v, tau (or qdd) and out
#
# The evaluator calls an entry's compiled wrapper directly (redysim._jit.unchecked_call: numba's
# dispatch types every argument, at a cost per array). That wrapper unboxes a declared 1-D float64
# array from any ndarray of 8-byte items: numba's adaptor copies one shape and one stride per
# dimension into a slot made for one (a 2-D array writes past it), and an int64 array passes as
# float64. The four vectors are declared as a CheckedVector instead, whose unboxing (below, in
# compiled code) refuses, with a TypeError, anything but an ndarray (or subclass) of one dimension
# of aligned native float64, and a read-only one where the entry writes: the checks that took six
# attribute reads in Python, a part of a small system's call worth saving. It reads the array's
# fields at their offsets in NumPy's C structs (PyArrayObject_fields and PyArray_Descr of
# numpy/ndarraytypes.h, unchanged since NumPy 1.7 for the array and in NumPy 2 for the descriptor's
# fields read here); NUMPY_LAYOUT_OK checks them against NumPy's own answers at import, and without
# it the entries are never called (the evaluator and inverse_dynamics take their checked paths).
ND_OFFSET, DESCR_OFFSET, FLAGS_OFFSET = 24, 56, 64  # in the array: int nd, descr*, int flags
BYTEORDER_OFFSET, TYPE_NUM_OFFSET = 26, 28  # in the descriptor: char byteorder, int type_num
NPY_DOUBLE, NPY_ARRAY_ALIGNED, NPY_ARRAY_WRITEABLE = 12, 0x0100, 0x0400
NPY_MAXDIMS = 64  # (NumPy 2; 32 before): the room the adaptor may write shapes and strides in


def _numpy_layout_ok() -> bool:
    """True when the offsets above read what NumPy itself reports, on arrays of every case the
    unboxing tells apart."""
    ro = np.zeros(3)
    ro.flags.writeable = False
    arrays = (np.zeros(3), np.zeros((2, 3)), np.zeros(3, np.int64), np.zeros(3, ">f8"),
              np.zeros(3, np.float32), np.zeros(6)[::2], ro, np.zeros(0), np.array(1.0))
    try:
        for a in arrays:
            at, dt = id(a), id(a.dtype)
            if (ctypes.c_int.from_address(at + ND_OFFSET).value != a.ndim
                    or ctypes.c_void_p.from_address(at + DESCR_OFFSET).value != dt
                    or ctypes.c_int.from_address(at + FLAGS_OFFSET).value != a.flags.num
                    or ctypes.c_int.from_address(dt + TYPE_NUM_OFFSET).value != a.dtype.num
                    or ctypes.c_char.from_address(dt + BYTEORDER_OFFSET).value
                    != a.dtype.byteorder.encode()):
                return False
    except (ValueError, TypeError, OverflowError):  # (an address ctypes would not read)
        return False
    return np.dtype(np.float64).num == NPY_DOUBLE and ro.flags.num & NPY_ARRAY_WRITEABLE == 0


# (and numba's internals as this module builds on them: redysim._jit.INTERNALS_OK, by version)
NUMPY_LAYOUT_OK: bool = INTERNALS_OK and _numpy_layout_ok()


class CheckedVector(types.Array):
    """A C-contiguous 1-D float64 array argument whose unboxing checks the Python object
    (above); inside, :func:`as_array` makes it the plain array type."""

    def __init__(self, mutable: bool = False):
        super().__init__(types.float64, 1, "C", readonly=not mutable,
                         name=f"CheckedVector({'mutable' if mutable else 'readonly'})")


register_model(CheckedVector)(ArrayModel)
box(CheckedVector)(box_array)  # returned: the caller's own array, as a plain array's


@lower_cast(types.Array, CheckedVector)
def _array_as_checked(context, builder, fromty, toty, val):
    """A plain vector handed to an entry from compiled code (a benchmark's loop): the same
    struct (numba's typing converts only arrays of the same dtype, dimension and layout)."""
    return impl_ret_borrowed(context, builder, toty, val)


def _read(builder, address, offset: int, ty):
    """The ``ty`` at byte ``offset`` from pointer ``address``."""
    at = builder.add(builder.ptrtoint(address, ir.IntType(64)), ir.Constant(ir.IntType(64),
                                                                            offset))
    return builder.load(builder.inttoptr(at, ty.as_pointer()))


def vector_fields_ok(builder, obj, mutable: bool):
    """The bit saying that ndarray ``obj`` (known to be one) has one dimension of aligned native
    float64, writeable if ``mutable``: its fields read at the offsets above. Also the
    evaluator's builtin's check (:mod:`.binding`)."""
    b, i32, i8 = builder, ir.IntType(32), ir.IntType(8)
    descr = _read(b, obj, DESCR_OFFSET, i8.as_pointer())
    need = NPY_ARRAY_ALIGNED | (NPY_ARRAY_WRITEABLE if mutable else 0)
    good = b.and_(b.icmp_signed("==", _read(b, obj, ND_OFFSET, i32), i32(1)),
                  b.icmp_signed("==", _read(b, descr, TYPE_NUM_OFFSET, i32), i32(NPY_DOUBLE)))
    good = b.and_(good, b.icmp_signed("!=", _read(b, descr, BYTEORDER_OFFSET, i8), i8(ord(">"))))
    flags = _read(b, obj, FLAGS_OFFSET, i32)
    return b.and_(good, b.icmp_signed("==", b.and_(flags, i32(need)), i32(need)))


@unbox(CheckedVector)
def _unbox_checked(typ, obj, c):
    b, i32 = c.builder, ir.IntType(32)
    # numba's adaptor first (an ndarray? data, shapes, strides), into room for any dimension
    room = c.context.make_array(types.Array(types.float64, NPY_MAXDIMS, "A"))(c.context, b)
    adapt = c.pyapi._get_function(ir.FunctionType(i32, [c.pyapi.pyobj, c.pyapi.voidptr]),
                                  name="numba_adapt_ndarray")
    err = b.call(adapt, (obj, b.bitcast(room._getpointer(), c.pyapi.voidptr)))
    vec = c.context.make_array(typ)(c.context, b)
    ok = cgutils.alloca_once_value(b, cgutils.false_bit)
    with b.if_then(b.icmp_signed("==", err, i32(0)), likely=True):
        b.store(vector_fields_ok(b, obj, typ.mutable), ok)
        vec.meminfo = cgutils.get_null_value(vec.meminfo.type)
        vec.parent = obj
        vec.nitems = room.nitems
        vec.itemsize = room.itemsize
        vec.data = room.data
        # the adaptor writes an array's nd shapes, then its nd strides, from the first shape's
        # place on: a vector's stride lands in the room's second shape
        shape0, stride0 = cgutils.unpack_tuple(b, room.shape, 2)
        vec.shape = cgutils.pack_array(b, [shape0])
        vec.strides = cgutils.pack_array(b, [stride0])
    failed = b.not_(b.load(ok))
    with b.if_then(failed, likely=False):
        c.pyapi.err_set_string("PyExc_TypeError", "not a 1-D array of aligned native float64 "
                               "(writeable, for out)")
    return NativeValue(vec._getvalue(), is_error=failed)


@intrinsic
def as_array(typingctx, vec):
    """A CheckedVector as the plain 1-D array it is (the same struct)."""
    if not isinstance(vec, CheckedVector):
        return None
    result = types.Array(types.float64, 1, "C", readonly=not vec.mutable)

    def codegen(context, builder, sig, args):
        return impl_ret_borrowed(context, builder, result, args[0])

    return result(vec), codegen


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
    _forward(as_array(q), as_array(v), as_array(tau), as_array(out), fdata, idata, scratch, True)
    return out  # (numba returns an argument only by name, unboxed: the caller's own array)


def forward_tree(q, v, tau, out, fdata, idata, scratch):
    """qdd by RGE-A into ``out``, any tree (module docstring)."""
    _forward(as_array(q), as_array(v), as_array(tau), as_array(out), fdata, idata, scratch, False)
    return out


@inline
def _forward_coupled(q, v, tau, out, fdata, idata, scratch, serial):
    """A coupled model (a workspace with the couplings' segments): the state's check against
    its couplings, :func:`_forward`'s passes, then the couplings in RGE-A's recursion
    (:func:`.couplings.couple_step`, inlined on the same bundles, as :func:`.couplings.
    coupled_qdd` inlines it: the same bits)."""
    h = idata
    nv = h[H_NV]
    if not (_plain(q, h[H_NQ]) and _plain(v, nv) and _plain(tau, nv) and _plain(out, nv)):
        raise Refused()
    if not on_couplings(fdata, idata, scratch, q, v):
        raise Refused()  # the checked path names the joint
    tree, s = bundles(fdata, idata, scratch)
    base_accel = fdata[h[E.F_BASE_ACCEL]:h[E.F_BASE_ACCEL] + 3]
    zeros = fdata[h[E.F_ZEROS]:h[E.F_ZEROS] + nv]
    _kinematics(tree, q, v, zeros, base_accel, s, True, serial)
    _rge_a_backward(tree, s, tau, serial)
    if _rge_a_forward(tree, s, base_accel, out, serial) != 0.0:
        raise Refused()  # some qdd is not finite
    if couple_step(tree, s, fdata, idata, scratch, out) != 0.0:
        raise Refused()


def forward_coupled_chain(q, v, tau, out, fdata, idata, scratch):
    """The coupled qdd into ``out``, a serial chain with couplings (module docstring)."""
    _forward_coupled(as_array(q), as_array(v), as_array(tau), as_array(out), fdata, idata,
                     scratch, True)
    return out


def forward_coupled_tree(q, v, tau, out, fdata, idata, scratch):
    """The coupled qdd into ``out``, any tree with couplings (module docstring)."""
    _forward_coupled(as_array(q), as_array(v), as_array(tau), as_array(out), fdata, idata,
                     scratch, False)
    return out


_planar_entry = inline(E.planar_entry)


def forward_planar(q, v, tau, out, fdata, idata, scratch):
    """qdd into ``out`` by the planar kernel, a planar chain (module docstring): .entry's planar
    entry, strides checked."""
    n = idata[H_NV]
    qa, va, ta, o = as_array(q), as_array(v), as_array(tau), as_array(out)
    if not (_plain(qa, n) and _plain(va, n) and _plain(ta, n) and _plain(o, n)):
        raise Refused()
    if _planar_entry(fdata, idata, qa, va, ta, scratch, o) != 0.0:
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
    qa, va, ta, o = as_array(q), as_array(v), as_array(tau), as_array(out)
    if not (_plain(qa, n) and _plain(va, n) and _plain(ta, n) and _plain(o, n)):
        raise Refused()
    table, base_accel, scr = _dh_views(fdata, idata, scratch)
    # the kernel's compiled code, called: IEEE as written (redysim._jit.jit_exact), the bits of
    # every other caller; inlining its source here would compile it with this entry's FMA fusion
    dh_forward_dynamics(table, qa, va, ta, base_accel, o, scr)
    if E._finite(o) != 0.0:
        raise Refused()  # some qdd is not finite
    return out


def inverse_dh(q, v, qdd, out, fdata, idata, scratch):
    """tau into ``out`` by the DH kernel, a robot in DH form (module docstring)."""
    n = idata[H_NV]
    qa, va, xa, o = as_array(q), as_array(v), as_array(qdd), as_array(out)
    if not (_plain(qa, n) and _plain(va, n) and _plain(xa, n) and _plain(o, n)):
        raise Refused()
    table, base_accel, scr = _dh_views(fdata, idata, scratch)
    dh_inverse_dynamics(table, qa, va, xa, base_accel, o, scr)
    if E._finite(o) != 0.0:
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
    _rnea_backward(tree, s, qdd, out)
    bad = 0.0
    for j in range(nv):
        bad += out[j] * 0.0
    if bad != 0.0:
        raise Refused()  # some tau is not finite


def inverse_chain(q, v, qdd, out, fdata, idata, scratch):
    """tau by Newton-Euler into ``out``, a serial chain (module docstring)."""
    _inverse(as_array(q), as_array(v), as_array(qdd), as_array(out), fdata, idata, scratch, True)
    return out


def inverse_tree(q, v, qdd, out, fdata, idata, scratch):
    """tau by Newton-Euler into ``out``, any tree (module docstring)."""
    _inverse(as_array(q), as_array(v), as_array(qdd), as_array(out), fdata, idata, scratch, False)
    return out


_F1 = types.Array(types.float64, 1, "C")
_I1 = types.Array(types.int64, 1, "C")
_IN, _OUT = CheckedVector(mutable=False), CheckedVector(mutable=True)
SIGNATURE = _OUT(_IN, _IN, _IN, _OUT, _F1, _I1, _F1)

FORWARD_CHAIN = EntryPoint(forward_chain, SIGNATURE, options=LEAN_OPTIONS)
FORWARD_TREE = EntryPoint(forward_tree, SIGNATURE, options=LEAN_OPTIONS)
FORWARD_PLANAR = EntryPoint(forward_planar, SIGNATURE, E.PLANAR_CALLEES, options=LEAN_OPTIONS)
INVERSE_CHAIN = EntryPoint(inverse_chain, SIGNATURE, options=LEAN_OPTIONS)
INVERSE_TREE = EntryPoint(inverse_tree, SIGNATURE, options=LEAN_OPTIONS)
FORWARD_DH = EntryPoint(forward_dh, SIGNATURE, E.DH_CALLEES, options=LEAN_OPTIONS)
FORWARD_COUPLED_CHAIN = EntryPoint(forward_coupled_chain, SIGNATURE, options=LEAN_OPTIONS)
FORWARD_COUPLED_TREE = EntryPoint(forward_coupled_tree, SIGNATURE, options=LEAN_OPTIONS)
INVERSE_DH = EntryPoint(inverse_dh, SIGNATURE, E.DH_INVERSE_CALLEES, options=LEAN_OPTIONS)
