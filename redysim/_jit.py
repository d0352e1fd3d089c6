"""The one place numba is configured.

Every kernel in ``redysim._kernels`` is decorated with :func:`jit` (a compiled function cached on
disk, so a second process loads machine code instead of recompiling) or :func:`inline` (a small
helper that numba inlines into its callers at the IR level).

``fastmath`` stays off: the kernels rely on IEEE semantics (exactly mirrored symmetric blocks,
reproducible round-off), and reassociation would make results depend on the compiler's choices.
"""

from __future__ import annotations

import numba

jit = numba.njit(cache=True, nogil=True, fastmath={"contract"}, error_model="numpy")


def inline(func):
    """A helper small enough to inline into every caller (numba ``inline='always'``)."""
    return numba.njit(inline="always", cache=True, nogil=True, error_model="numpy")(func)
