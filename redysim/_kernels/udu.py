"""The explicit factors of the GIM, I = U D U^T, from RGE-A's articulated quantities.

With RGE-A eliminating axis by axis (see ``rge_a.py``), D = diag(Ihat_j) is diagonal and U is unit
upper triangular with, for DOF i before DOF j,

    U_ij = P_i^T A_{j,i}^T Psihat_j,

i.e. column j of U is the wrench Psihat_j carried from O_j towards the base and projected on every
earlier axis (axes of the same joint need no carrying: they meet at O_j). O(n^2) entries; for the
conditioning study (Table A.2), never formed in a simulation.

References:
    Agarwal et al., Appendix A.1, Eq. (A.5)-(A.8); Saha, Int. J. Robotics Research 18 (1999).
"""

from __future__ import annotations

from .._jit import jit


@jit
def udu_assemble(joint_qoff, oO, oP, Ihat, Psihat, U, D):
    """Fill U (unit upper triangular) and D (diagonal) from RGE-A's backward pass."""
    nl = joint_qoff.shape[0] - 1
    for k in range(nl):
        for j in range(joint_qoff[k], joint_qoff[k + 1]):
            U[j, j] = 1.0
            D[j, j] = Ihat[j]
            F0, F1, F2 = Psihat[j, 0], Psihat[j, 1], Psihat[j, 2]
            F3, F4, F5 = Psihat[j, 3], Psihat[j, 4], Psihat[j, 5]
            # earlier axes of the same joint
            for i in range(joint_qoff[k], j):
                U[i, j] = (oP[i, 0] * F0 + oP[i, 1] * F1 + oP[i, 2] * F2
                           + oP[i, 3] * F3 + oP[i, 4] * F4 + oP[i, 5] * F5)
            # carry towards the base: links k-1..1
            for b in range(k - 1, -1, -1):
                r0 = oO[b + 1, 0] - oO[b, 0]
                r1 = oO[b + 1, 1] - oO[b, 1]
                r2 = oO[b + 1, 2] - oO[b, 2]
                F0 += r1 * F5 - r2 * F4
                F1 += r2 * F3 - r0 * F5
                F2 += r0 * F4 - r1 * F3
                for i in range(joint_qoff[b], joint_qoff[b + 1]):
                    U[i, j] = (oP[i, 0] * F0 + oP[i, 1] * F1 + oP[i, 2] * F2
                               + oP[i, 3] * F3 + oP[i, 4] * F4 + oP[i, 5] * F5)
