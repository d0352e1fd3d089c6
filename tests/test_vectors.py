"""redysim.algorithms.vectors: np.cross's results, bit for bit, without its overhead."""

import numpy as np

from redysim.algorithms.vectors import cross


def test_cross_is_np_cross_bit_for_bit():
    rng = np.random.default_rng(17)
    for _ in range(50):
        a, b = rng.normal(size=3) * 10.0 ** rng.integers(-8, 8), rng.normal(size=3)
        assert np.array_equal(cross(a, b), np.cross(a, b))
    A, B = rng.normal(size=(12, 3)), rng.normal(size=(12, 3))
    assert np.array_equal(cross(A, B), np.cross(A, B))
    assert np.array_equal(cross(A, B[0]), np.cross(A, B[0]))  # rows against one vector
    assert np.array_equal(cross(A[:, ::-1][:, ::-1].T[0:3, 0], B[1]),  # a strided view
                          np.cross(A[0], B[1]))
    assert np.array_equal(cross([1.0, 0.0, 0.0], [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0])
    f = A.astype(np.float32)
    assert cross(f, f[::-1]).dtype == np.float32
    assert np.array_equal(cross(f, f[::-1]), np.cross(f, f[::-1]))


def test_cross_keeps_overflow_and_nan_as_np_cross():
    big = np.array([1e308, 1e308, 0.0])
    with np.errstate(over="ignore", invalid="ignore"):
        want = np.cross(big, big[::-1] * 10.0)
        got = cross(big, big[::-1] * 10.0)
    assert np.array_equal(got, want, equal_nan=True)
