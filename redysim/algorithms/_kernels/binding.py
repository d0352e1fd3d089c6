"""An evaluator as a CPython builtin: a lean entry called with nothing in Python between.

:func:`redysim.evaluator` returns, where :data:`BINDING_OK`, the function :func:`bind` makes:
a ``builtin_function_or_method`` (METH_FASTCALL | METH_KEYWORDS, as CPython's own builtins)
whose C function is generated here, in LLVM IR, and calls the entry's own compiled code
(:mod:`.lean`) by its address. A call ``fd(q, v, tau=None, out=None)`` (``id(q, v, qdd,
out=None)``) then runs, in that one function: its arguments taken from the call (two to four
positional; ``tau`` or ``qdd`` and ``out`` also by name), ``tau`` None as the workspace's
zeros, ``out`` None as a new vector (NumPy's ``PyArray_New``), each vector's checks (an ndarray
or subclass, one dimension, aligned native float64, ``out`` writeable), the evaluator's
workspace arrays as described once at binding, and the entry (which checks lengths and strides,
and that the result is finite). Anything else, or anything the entry refuses, goes to the
evaluator's checked path, a Python function with the same parameters, called with the same
arguments (vectorcall): the
public function's conversions, errors and bits.

Why: with a Python function between the call and the compiled wrapper (numba's, which takes
fixed positional arguments and ignores keywords), a small system's call spent much of its time
around the kernel: the Python frame, ``np.empty`` called from Python and seven arrays unboxed by
numba's adaptor (docs/notes/2026-11-evaluator-and-ladder.md).

What it relies on, checked at import (:func:`_binding_ok`; without it the evaluator is the
checked path): NumPy's C-API table (the ``_ARRAY_API`` capsule, through which every extension
module calls NumPy: ``PyArray_Type`` and ``PyArray_New`` at their slots, called here through
ctypes on a vector, checked as such), the array fields read here at their offsets in
``PyArrayObject_fields`` (:mod:`.lean`'s, plus data, dimensions and strides, compared with
NumPy's own answers) and CPython's ``PyCFunction_NewEx`` and ``PyObject_Vectorcall``.

Lifetimes: the builtin's ``__self__`` is a :class:`Bound` (a tuple) holding the workspace, its
arrays, the words that describe them, the checked path and the method definition, so nothing
the compiled function reads is freed before the builtin is. The C function is made once per
entry and process (a few tens of ms), not cached on disk; the entry's own code is (numba's
cache).
"""

from __future__ import annotations

import ctypes
import sys
from functools import cache
from operator import itemgetter

import numpy as np
from llvmlite import ir
from numba.core import cgutils
from numba.core.compiler_lock import global_compiler_lock

from .lean import NPY_DOUBLE, NUMPY_LAYOUT_OK, _read, vector_fields_ok

TYPE_OFFSET = 8  # in any object: PyTypeObject *ob_type
DATA_OFFSET, DIMS_OFFSET, STRIDES_OFFSET = 16, 32, 40  # in the array: char *data, npy_intp *
PYARRAY_TYPE_SLOT, PYARRAY_NEW_SLOT = 2, 93  # in NumPy's C-API table (__multiarray_api.h)
METH_FASTCALL_KEYWORDS = 0x0080 | 0x0002
WORDS = 5  # a workspace array described: nitems, itemsize, data, shape, stride

I64 = ir.IntType(64)
I32 = ir.IntType(32)
I8P = ir.IntType(8).as_pointer()


class PyMethodDef(ctypes.Structure):
    _fields_ = [("ml_name", ctypes.c_char_p), ("ml_meth", ctypes.c_void_p),
                ("ml_flags", ctypes.c_int), ("ml_doc", ctypes.c_char_p)]


_cfunction_new = ctypes.pythonapi.PyCFunction_NewEx
_cfunction_new.restype = ctypes.py_object
_cfunction_new.argtypes = [ctypes.POINTER(PyMethodDef), ctypes.py_object, ctypes.py_object]


def _numpy_api() -> tuple[int, int]:
    """The addresses of ``PyArray_Type`` and ``PyArray_New`` in NumPy's C-API table."""
    try:
        from numpy._core import _multiarray_umath as mu  # type: ignore[attr-defined]
    except ImportError:  # NumPy 1.x
        from numpy.core import _multiarray_umath as mu  # type: ignore[no-redef]
    get = ctypes.pythonapi.PyCapsule_GetPointer
    get.restype, get.argtypes = ctypes.c_void_p, [ctypes.py_object, ctypes.c_char_p]
    table = (ctypes.c_void_p * (PYARRAY_NEW_SLOT + 1)).from_address(get(mu._ARRAY_API, None))
    return int(table[PYARRAY_TYPE_SLOT] or 0), int(table[PYARRAY_NEW_SLOT] or 0)


_NEW = ctypes.PYFUNCTYPE(ctypes.py_object, ctypes.c_void_p, ctypes.c_int,
                         ctypes.POINTER(ctypes.c_int64), ctypes.c_int, ctypes.c_void_p,
                         ctypes.c_void_p, ctypes.c_int, ctypes.c_int, ctypes.py_object)


def _binding_ok() -> bool:
    """True when the table's slots and the array fields read here are what NumPy says."""
    if not NUMPY_LAYOUT_OK or sys.implementation.name != "cpython":
        return False
    try:
        array_type, new = _numpy_api()
        if not new or array_type != id(np.ndarray):
            return False
        made = _NEW(new)(array_type, 1, ctypes.byref(ctypes.c_int64(7)), NPY_DOUBLE, None, None,
                         0, 0, None)
        if not (type(made) is np.ndarray and made.shape == (7,) and made.dtype == np.float64
                and made.flags.c_contiguous and made.flags.writeable and made.flags.aligned):
            return False
        for a in (np.zeros(3), np.zeros((2, 3)), np.zeros(6)[::2], np.zeros(0), made):
            at = id(a)
            if (ctypes.c_void_p.from_address(at + TYPE_OFFSET).value != id(type(a))
                    or ctypes.c_void_p.from_address(at + DATA_OFFSET).value != (
                        a.ctypes.data or None)):
                return False
            dims = ctypes.c_void_p.from_address(at + DIMS_OFFSET).value or 0
            strides = ctypes.c_void_p.from_address(at + STRIDES_OFFSET).value or 0
            if (tuple((ctypes.c_int64 * a.ndim).from_address(dims)) != a.shape
                    or tuple((ctypes.c_int64 * a.ndim).from_address(strides)) != a.strides):
                return False
    except (ValueError, TypeError, OverflowError, AttributeError, ImportError):
        return False
    return True


BINDING_OK: bool = _binding_ok()


# positions in a Bound: what the C function reads (ZEROS, CHECKED, WORDS_AT), what it says
ZEROS, CHECKED, WORDS_AT, MODEL_AT, KIND_AT = 3, 4, 5, 8, 9


class Bound(tuple):
    """The builtin's ``__self__``: what its compiled function reads (by position: the
    workspace's three arrays, the zeros, the checked path, the address of the words describing
    the arrays), and what keeps them alive. ``fd.__self__.model``, ``.kind``: what it computes."""

    model = property(itemgetter(MODEL_AT), doc="the model")
    kind = property(itemgetter(KIND_AT), doc="'forward_dynamics' or 'inverse_dynamics'")

    @classmethod
    def of_checked_path(cls, model, kind: str) -> Bound:
        """The ``__self__`` of an evaluator that is its checked path: what it computes only."""
        return cls((None,) * MODEL_AT + (model, kind))

    def __repr__(self) -> str:
        return f"<redysim.evaluator {self.kind} of {self.model.name!r}>"

    def __reduce__(self):
        raise TypeError(f"cannot pickle {self!r}: evaluators are per process: make one in "
                        "each (send the model, which pickles, and call redysim.evaluator(model) "
                        "there; an evaluator is compiled code and scratch at this process's "
                        "addresses)")


def bind(entry, forward: bool, ws, checked, model, kind: str, doc: str):
    """The builtin calling ``entry`` (a :class:`redysim._jit.EntryPoint` of :mod:`.lean`) on
    workspace ``ws``; ``checked(q, v, x=None, out=None)``: the checked path; ``doc``: its
    docstring (first line: its signature, as ``inspect.signature`` reads a builtin's). None
    where the entry's machine code has no address to call."""
    arrays = (ws.kernel_f, ws.kernel_i, ws.scratch)
    words = np.array([w for a in arrays for w in (a.size, a.itemsize, a.ctypes.data,
                                                  a.shape[0], a.strides[0])]
                     + [model.n_v], dtype=np.int64)
    address = _compiled(entry, forward)
    if not address:
        return None
    definition = PyMethodDef(kind.encode(), address, METH_FASTCALL_KEYWORDS, doc.encode())
    bound = Bound((*arrays, ws.zeros, checked, int(words.ctypes.data), words, ws, model, kind,
                   definition))
    return _cfunction_new(ctypes.byref(definition), bound, None)


@cache
def _compiled(entry, forward: bool) -> int:
    """The address of the builtin's C function for ``entry``, compiled once a process."""
    with global_compiler_lock:
        return _build(entry, forward)


def _build(entry, forward: bool) -> int:
    overload = next(iter(entry.compiled.overloads.values()))
    ctx, fndesc = overload.target_context, overload.fndesc
    name = f"redysim_evaluator_{entry.func.__name__}"
    library = ctx.codegen().create_library(name)
    module = library.create_ir_module(name)
    fnty = ir.FunctionType(I8P, [I8P, I8P.as_pointer(), I64, I8P])
    function = cgutils.get_or_insert_function(module, fnty, name)
    b = ir.IRBuilder(function.append_basic_block("entry"))
    api = ctx.get_python_api(b)
    bound, argv, nargs, kwnames = function.args
    checked_path = function.append_basic_block("checked_path")
    array_type, array_new = _numpy_api()
    array_type_ptr = b.inttoptr(ir.Constant(I64, array_type), I8P)

    def c_function(ret, args, symbol):
        return cgutils.get_or_insert_function(module, ir.FunctionType(ret, args), symbol)

    tuple_item = c_function(I8P, [I8P, I64], "PyTuple_GetItem")

    # the arguments: two to four positional; the third's and fourth's interned names
    slots = [cgutils.alloca_once_value(b, api.get_null_object()) for _ in range(4)]
    with b.if_then(b.or_(b.icmp_signed("<", nargs, I64(2)), b.icmp_signed(">", nargs, I64(4))),
                   likely=False):
        b.branch(checked_path)
    for k in range(4):
        with b.if_then(b.icmp_signed(">", nargs, I64(k))):
            b.store(b.load(b.gep(argv, [I64(k)])), slots[k])
    names = [sys.intern("tau" if forward else "qdd"), sys.intern("out")]
    _KEEP.extend(names)  # (interned strings die with their last reference)
    with b.if_then(cgutils.is_not_null(b, kwnames), likely=False):
        with cgutils.for_range(b, api.tuple_size(kwnames)) as loop:
            key = b.call(tuple_item, [kwnames, loop.index])
            value = b.load(b.gep(argv, [b.add(nargs, loop.index)]))
            hits = [b.icmp_unsigned("==", key, b.inttoptr(I64(id(n)), I8P)) for n in names]
            twice = [b.and_(h, cgutils.is_not_null(b, b.load(slots[2 + k])))
                     for k, h in enumerate(hits)]
            # a name given twice, or any other name (q=, v=, or one not interned): the checked
            # path says what it makes of it
            with b.if_then(b.or_(b.or_(*twice), b.not_(b.or_(*hits))), likely=False):
                b.branch(checked_path)
            for k, h in enumerate(hits):
                with b.if_then(h):
                    b.store(value, slots[2 + k])

    none = api.borrow_none()

    def absent(obj):
        return b.or_(cgutils.is_null(b, obj), b.icmp_unsigned("==", obj, none))

    x = b.load(slots[2])
    if forward:  # tau None: the workspace's zeros
        x = b.select(absent(x), b.call(tuple_item, [bound, I64(ZEROS)]), x)
    else:
        with b.if_then(absent(x), likely=False):  # no qdd: the checked path says so
            b.branch(checked_path)
    words = b.inttoptr(b.ptrtoint(api.long_as_voidptr(b.call(tuple_item, [bound, I64(WORDS_AT)])),
                                  I64), I64.as_pointer())
    out = b.load(slots[3])
    own = absent(out)
    out_slot = cgutils.alloca_once_value(b, out)
    with b.if_then(own):  # a new vector of n_v float64
        dims = cgutils.alloca_once_value(b, b.load(b.gep(words, [I64(3 * WORDS)])))
        new_ty = ir.FunctionType(I8P, [I8P, I32, I64.as_pointer(), I32, I8P, I8P, I32, I32, I8P])
        made = b.call(b.inttoptr(I64(array_new), new_ty.as_pointer()),
                      [array_type_ptr, I32(1), dims, I32(NPY_DOUBLE), *[ir.Constant(I8P, None)] * 2,
                       I32(0), I32(0), ir.Constant(I8P, None)])
        with b.if_then(cgutils.is_null(b, made), likely=False):
            b.ret(api.get_null_object())  # (MemoryError, set by NumPy)
        b.store(made, out_slot)
    out = b.load(out_slot)

    release = function.append_basic_block("release")
    natives = []
    vectors = (b.load(slots[0]), b.load(slots[1]), x, out)
    for obj, ty in zip(vectors, fndesc.argtypes[:4], strict=True):
        ok, value = _vector(b, ctx, obj, ty, array_type_ptr, c_function)
        with b.if_then(b.not_(ok), likely=False):
            b.branch(release)
        natives.append(value)
    for k, ty in enumerate(fndesc.argtypes[4:]):  # the workspace's arrays, as described
        arr = ctx.make_array(ty)(ctx, b)
        w = [b.load(b.gep(words, [I64(WORDS * k + j)])) for j in range(WORDS)]
        arr.meminfo = cgutils.get_null_value(arr.meminfo.type)
        arr.parent = cgutils.get_null_value(arr.parent.type)
        arr.nitems, arr.itemsize = w[0], w[1]
        arr.data = b.inttoptr(w[2], arr.data.type)
        arr.shape = cgutils.pack_array(b, [w[3]])
        arr.strides = cgutils.pack_array(b, [w[4]])
        natives.append(arr._getvalue())
    # the entry's own machine code, called by its address: linking its library instead would
    # copy the entry's IR into this module and optimise it again here (numba links a library's
    # callees that way), a second compiled copy of the kernel
    entry_ty = ctx.call_conv.get_function_type(fndesc.restype, fndesc.argtypes)
    address = overload.library.get_pointer_to_function(fndesc.mangled_name)
    if not address:  # (numba keeps it: never seen) the evaluator is then the checked path
        return 0
    entry_fn = b.inttoptr(I64(address), entry_ty.as_pointer())
    status, _ = ctx.call_conv.call_function(b, entry_fn, fndesc.restype, fndesc.argtypes,
                                            natives)
    with b.if_then(status.is_ok, likely=True):
        with b.if_then(b.not_(own)):
            api.incref(out)  # the caller's out, returned (a new vector: our reference)
        b.ret(out)
    b.branch(release)  # refused by the entry (nothing raised in Python)

    b.position_at_end(release)
    with b.if_then(own):
        api.decref(out)
    b.branch(checked_path)

    b.position_at_end(checked_path)
    vectorcall = c_function(I8P, [I8P, I8P.as_pointer(), I64, I8P], "PyObject_Vectorcall")
    b.ret(b.call(vectorcall, [b.call(tuple_item, [bound, I64(CHECKED)]), argv, nargs, kwnames]))

    library.add_ir_module(module)
    library.finalize()
    _KEEP.extend((library, overload.library))
    return library.get_pointer_to_function(name)


_KEEP: list = []  # the compiled libraries and interned names, for the process's life


def _vector(b, ctx, obj, ty, array_type_ptr, c_function):
    """(ok, the native array) of a vector argument: an ndarray (or subclass) of one dimension
    of aligned native float64, writeable where ``ty`` is mutable; its length and stride are the
    entry's to check. Fields read at their offsets (module docstring), only past the type
    check."""
    result = cgutils.alloca_once(b, ctx.get_value_type(ty))
    ok = cgutils.alloca_once_value(b, cgutils.false_bit)

    obj_type = _read(b, obj, TYPE_OFFSET, I8P)
    is_array = b.icmp_unsigned("==", obj_type, array_type_ptr)
    with b.if_then(b.not_(is_array), likely=False):
        subtype = c_function(I32, [I8P, I8P], "PyType_IsSubtype")
        b.store(b.icmp_signed("!=", b.call(subtype, [obj_type, array_type_ptr]), I32(0)), ok)
    is_array = b.or_(is_array, b.load(ok))
    b.store(cgutils.false_bit, ok)
    with b.if_then(is_array, likely=True):
        b.store(vector_fields_ok(b, obj, ty.mutable), ok)
    with b.if_then(b.load(ok), likely=True):  # (a 0-D array may have no dimensions to read)
        arr = ctx.make_array(ty)(ctx, b)
        length = b.load(_read(b, obj, DIMS_OFFSET, I64.as_pointer()))
        arr.meminfo = cgutils.get_null_value(arr.meminfo.type)
        arr.parent = obj
        arr.nitems, arr.itemsize = length, I64(8)
        arr.data = b.bitcast(_read(b, obj, DATA_OFFSET, I8P), arr.data.type)
        arr.shape = cgutils.pack_array(b, [length])
        arr.strides = cgutils.pack_array(b, [b.load(_read(b, obj, STRIDES_OFFSET,
                                                                 I64.as_pointer()))])
        b.store(arr._getvalue(), result)
    return b.load(ok), b.load(result)
