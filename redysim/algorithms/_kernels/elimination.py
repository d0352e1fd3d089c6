"""GE-N and RGE-N: the numerical O(n^3) comparators of section 5.2.

GE-N eliminates the below-diagonal entries of the GIM column by column from the first (the
sweep-out phase, I = L U), then back-substitutes. RGE-N eliminates the above-diagonal entries
from the last column towards the first (I = U' L'), then forward-substitutes. Same operation
count, different conditioning of the factors (Appendix A.2, Table A.2). No pivoting: the GIM is
symmetric positive definite, and the paper's comparison is of the unpivoted orders.

Both work in place on copies: ``A`` ends as the triangular factor (U, resp. L'), ``mult`` holds the
multipliers (L, resp. U', unit diagonal), ``b`` the transformed right-hand side phi-hat, ``x`` qdd.

References:
    Agarwal et al., section 5.2, Eq. (12), Appendix A.2, Eq. (A.9)-(A.10), Table A.2.
"""

from __future__ import annotations

from redysim._jit import jit


@jit
def ge_n(A, b, mult, x):
    """Gaussian elimination from the first column, then backward substitution."""
    n = A.shape[0]
    for i in range(n):
        mult[i, i] = 1.0
    # sweep-out: columns 1..n
    for c in range(n):
        piv = A[c, c]
        for r in range(c + 1, n):
            f = A[r, c] / piv
            mult[r, c] = f
            A[r, c] = 0.0
            for j in range(c + 1, n):
                A[r, j] -= f * A[c, j]
            b[r] -= f * b[c]
    # backward substitution: k = n..1
    for r in range(n - 1, -1, -1):
        s = b[r]
        for j in range(r + 1, n):
            s -= A[r, j] * x[j]
        x[r] = s / A[r, r]


@jit
def rge_n(A, b, mult, x):
    """Reverse Gaussian elimination from the last column, then forward substitution."""
    n = A.shape[0]
    for i in range(n):
        mult[i, i] = 1.0
    # sweep-out: columns n..1
    for c in range(n - 1, -1, -1):
        piv = A[c, c]
        for r in range(c - 1, -1, -1):
            f = A[r, c] / piv
            mult[r, c] = f
            A[r, c] = 0.0
            for j in range(c):
                A[r, j] -= f * A[c, j]
            b[r] -= f * b[c]
    # forward substitution: k = 1..n
    for r in range(n):
        s = b[r]
        for j in range(r):
            s -= A[r, j] * x[j]
        x[r] = s / A[r, r]
