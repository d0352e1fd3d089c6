"""The one place numba is configured.

Every kernel in ``redysim._kernels`` is decorated with :func:`jit` (a compiled function cached on
disk, so a second process loads machine code instead of recompiling) or :func:`inline` (a small
helper that numba inlines into its callers at the IR level); the entry points that the public
functions call on their hot path are :class:`EntryPoint` s.

``fastmath`` stays off: the kernels rely on IEEE semantics (exactly mirrored symmetric blocks,
reproducible round-off), and reassociation would make results depend on the compiler's choices.
"""

from __future__ import annotations

from functools import cached_property

import numba

OPTIONS = dict(cache=True, nogil=True, fastmath={"contract"}, error_model="numpy")
jit = numba.njit(**OPTIONS)


def inline(func):
    """A helper small enough to inline into every caller (numba ``inline='always'``)."""
    return numba.njit(inline="always", cache=True, nogil=True, error_model="numpy")(func)


class EntryPoint:
    """A kernel compiled for exactly one signature, on first use of :attr:`compiled` (so importing
    redysim compiles nothing, and the first call pays the compile or the disk-cache load, as for
    :func:`jit`).

    Given a signature, numba compiles nothing else: a call with other argument types raises
    TypeError instead of compiling a new specialisation (a float32 or strided array, say), which
    makes the dispatcher itself the type check of the hot path.
    """

    def __init__(self, func, signature):
        self.func = func
        self.signature = signature

    @cached_property
    def compiled(self):
        """The compiled dispatcher (compiled, or loaded from the disk cache, on first access)."""
        return numba.njit(self.signature, **OPTIONS)(self.func)
