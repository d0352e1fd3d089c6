"""The explicit factors of the GIM, I = U D U^T, from RGE-A's articulated quantities.

    D = blockdiag(Ihat_k),   U_kk = 1,   U_{k,j} = P_k^T A_{j,k}^T Psihat_j   (j > k),

i.e. column block j of U is the wrench Psihat_j carried from O_j towards the base and projected on
each joint's motion subspace. O(n^2) entries; meant for the conditioning study (Table A.2), not
for simulation, which never forms U.

References:
    Agarwal et al., Appendix A.1, Eq. (A.5)-(A.8); Saha, Int. J. Robotics Research 18 (1999).
"""

from __future__ import annotations

import numpy as np

from .._jit import jit


@jit
def udu_assemble(joint_qoff, oO, oP, Ihat, Psihat, U, D):
    """Fill U (unit upper block-triangular) and D (block diagonal) from RGE-A's backward pass."""
    nl = joint_qoff.shape[0] - 1
    F = np.empty(6)
    for k in range(nl):
        j0 = joint_qoff[k]
        z = joint_qoff[k + 1] - j0
        for c in range(z):
            U[j0 + c, j0 + c] = 1.0
            for d in range(z):
                D[j0 + c, j0 + d] = Ihat[k, c, d]
        for c in range(z):
            for i in range(6):
                F[i] = Psihat[j0 + c, i]
            # carry towards the base: i = k-1..1
            for i in range(k - 1, -1, -1):
                r0 = oO[i + 1, 0] - oO[i, 0]
                r1 = oO[i + 1, 1] - oO[i, 1]
                r2 = oO[i + 1, 2] - oO[i, 2]
                F[0] += r1 * F[5] - r2 * F[4]
                F[1] += r2 * F[3] - r0 * F[5]
                F[2] += r0 * F[4] - r1 * F[3]
                for jj in range(joint_qoff[i], joint_qoff[i + 1]):
                    U[jj, j0 + c] = (oP[jj, 0] * F[0] + oP[jj, 1] * F[1] + oP[jj, 2] * F[2]
                                     + oP[jj, 3] * F[3] + oP[jj, 4] * F[4] + oP[jj, 5] * F[5])
