"""Small-vector arithmetic for the per-sample and per-call paths written in numpy.

``np.cross`` spends far longer on its axis handling than on the arithmetic, and at a
simulation's every sample the observers called it six times, more than the steps cost on a small
model (the figures: docs/notes/2026-11-costs-in-the-code.md).
"""

from __future__ import annotations

import numpy as np

F64 = np.dtype(np.float64)


def cross(a, b) -> np.ndarray:
    """a x b over the last axis (3-vectors, or rows of them, broadcast as ``np.cross``): numpy's
    own arithmetic, (a1 b2 - a2 b1, a2 b0 - a0 b2, a0 b1 - a1 b0) with each product rounded, so
    the same bits as ``np.cross``; two float64 3-vectors in Python floats (IEEE double too)."""
    a, b = np.asarray(a), np.asarray(b)
    if a.shape == (3,) and b.shape == (3,) and a.dtype == F64 and b.dtype == F64:
        a0, a1, a2 = a.tolist()
        b0, b1, b2 = b.tolist()
        return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0])
    a0, a1, a2 = a[..., 0], a[..., 1], a[..., 2]
    b0, b1, b2 = b[..., 0], b[..., 1], b[..., 2]
    return np.stack((a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0), axis=-1)
