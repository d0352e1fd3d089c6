"""The door: every public function and method that takes a model, a state or a vector checks
it here, before anything compiled sees it (docs/design.md, "Checked at the door").

Compiled code indexes without bounds checks and numba's dispatch types an array by its dtype,
layout, alignment and byte order: a short vector would be read past its end, a view read with
its neighbours, and an unaligned or big-endian array refused with numba's own message (or, past
the dispatch, read wrong). So what reaches a kernel is what this module returns: an ndarray of
exactly the expected length, float64 in native byte order, aligned and C-contiguous; anything
else convertible is converted (a copy), the rest refused by name (:class:`StateError`, and
:class:`~redysim.errors.ModelTypeError`, a TypeError, for something that is not a model).
"""

from __future__ import annotations

import reprlib

import numpy as np

from redysim.errors import ModelTypeError, StateError
from redysim.model.parts import NUMERIC_KINDS

FLOAT64, FLOAT64_STRIDES = np.dtype(np.float64), (8,)
MODEL_MARK = "__redysim_model__"  # a class attribute of redysim.Model (and its subclasses)


def require_model(model, where: str):
    """``model`` if it is a :class:`redysim.Model` (a Chain is one), else ModelTypeError naming
    ``where`` (the function called) and what was given."""
    if getattr(type(model), MODEL_MARK, False):
        return model
    hint = (" (a Case: give its .chain)" if hasattr(model, "chain") else
            " (a Linkage: give its .model, the open tree)" if hasattr(model, "loops")
            and hasattr(model, "q0") else
            " (a ClosedLoops: give its .model, or call its own methods)"
            if hasattr(model, "cuts") and hasattr(model, "tree") else "")
    raise ModelTypeError(where, "model", type(model).__name__,
                         "must be a redysim.Model (Chain.uniform, Model.build, load_model(...), "
                         f"load_case(...).chain){hint}")


def plain_vector(x, n: int) -> bool:
    """True for what the kernels take as is: an ndarray (not a subclass) of shape (n,), native
    float64, aligned, contiguous and writeable (a read-only array is another numba type: each
    kernel would compile once more for it, so it is copied too)."""
    return (type(x) is np.ndarray and x.shape == (n,) and x.dtype is FLOAT64
            and x.strides == FLOAT64_STRIDES and x.flags.aligned and x.flags.writeable)


def native(arr: np.ndarray) -> np.ndarray:
    """``arr`` as C-contiguous, aligned, writeable, native-order float64 (a copy where it is
    not)."""
    arr = np.asarray(arr, dtype=FLOAT64)  # (a big-endian float64 becomes native: a copy)
    if (arr.flags.c_contiguous and arr.flags.aligned and arr.flags.writeable
            and arr.dtype is FLOAT64):
        return arr
    return np.array(arr, dtype=FLOAT64, order="C", copy=True)


def numeric(name: str, x) -> np.ndarray:
    """``x`` as an ndarray of int or float entries (not yet converted), or StateError."""
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError) as exc:  # ragged nesting
        raise StateError(f"{name} = {reprlib.repr(x)}: not a numeric vector ({exc})") from None
    if arr.dtype.kind not in NUMERIC_KINDS:  # strings, bools, complex, None/objects
        raise StateError(f"{name} = {reprlib.repr(x)}: not a numeric vector (its entries are "
                         f"{arr.dtype}; need int or float)")
    return arr


def vector(name: str, x, n: int, *, owner: str, what: str = "values", finite: bool = True,
           hint: str = "") -> np.ndarray:
    """``x`` as the kernels take it (:func:`plain_vector`), of length ``n``, or StateError
    naming it: ``owner`` says whose length it is (``"chain 'rope'"``), ``what`` what ``n``
    counts (``"DOF"``). ``finite``: refuse NaN and Inf too (naming the first)."""
    if plain_vector(x, n):  # the hot path: as given
        if finite:
            require_finite(name, x)
        return x
    arr = numeric(name, x)
    if arr.shape != (n,):
        raise StateError(f"{name} has shape {arr.shape}; {owner} has {n} {what}, so {name} "
                         f"must have shape ({n},)" + hint)
    arr = native(arr)
    if finite:
        require_finite(name, arr)
    return arr


def out_vector(out, n: int, *, owner: str) -> np.ndarray:
    """``out`` as given if the kernels can write an (n,) float vector into it, else StateError.
    Never converted: a copy would not reach the caller."""
    if out is None:
        return np.empty(n)
    if plain_vector(out, n) and out.flags.writeable:
        return out
    what = (f"shape {out.shape}, dtype {out.dtype}, strides {out.strides}, "
            f"aligned {out.flags.aligned}, writeable {out.flags.writeable}"
            if isinstance(out, np.ndarray) else f"a {type(out).__name__}")
    raise StateError(f"out ({what}) must be a writeable, aligned, contiguous float64 array of "
                     f"shape ({n},): {owner} has {n} DOF")


def require_finite(name: str, arr: np.ndarray) -> None:
    """Raise StateError naming the first NaN or Inf entry of ``arr``."""
    if not np.isfinite(arr).all():
        bad = np.flatnonzero(~np.isfinite(arr))
        raise StateError(f"{name}[{bad[0]}] = {float(arr[bad[0]])!r}: not finite "
                         f"({bad.size} non-finite value{'s' if bad.size > 1 else ''})")


def number(where: str, name: str, x, *, finite: bool = False, at_least: float | None = None
           ) -> float:
    """``x`` as a float if it is a real number (not a string, a bool or an array), else
    StateError naming ``where`` and ``name``; with ``finite``, NaN and Inf refused too, with
    ``at_least``, a number below it."""
    if isinstance(x, bool | np.bool_) or not isinstance(x, int | float | np.integer
                                                         | np.floating):
        raise StateError(f"{where}: {name} = {reprlib.repr(x)}: must be a number (a "
                         f"{type(x).__name__} was given)")
    if finite and not np.isfinite(x):
        raise StateError(f"{where}: {name} = {float(x)!r}: must be a finite number")
    if at_least is not None and not x >= at_least:
        raise StateError(f"{where}: {name} = {float(x)!r}: must be >= {at_least:g}")
    return float(x)
