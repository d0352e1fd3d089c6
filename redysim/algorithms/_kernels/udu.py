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

from redysim._jit import jit_borrowed


@jit_borrowed
def udu_assemble(tree, s, U, D):
    """Fill U (unit upper triangular) and D (diagonal) from RGE-A's backward pass (s.Ihat,
    s.Psihat, with s.oO, s.oP); U and D come in zeroed. On a tree, U_ij is non-zero only for i
    on the path from j's body to the base."""
    joint_voff, oO, oP, Ihat, Psihat = tree.joint_voff, s.oO, s.oP, s.Ihat, s.Psihat
    serial, parent = tree.serial, tree.parent
    nl = joint_voff.shape[0] - 1
    for k in range(nl):
        for j in range(joint_voff[k], joint_voff[k + 1]):
            U[j, j] = 1.0
            D[j, j] = Ihat[j]
            F0, F1, F2 = Psihat[j, 0], Psihat[j, 1], Psihat[j, 2]
            F3, F4, F5 = Psihat[j, 3], Psihat[j, 4], Psihat[j, 5]
            # earlier axes of the same joint
            for i in range(joint_voff[k], j):
                U[i, j] = (oP[i, 0] * F0 + oP[i, 1] * F1 + oP[i, 2] * F2
                           + oP[i, 3] * F3 + oP[i, 4] * F4 + oP[i, 5] * F5)
            # carry towards the base over k's ancestors b
            c = k
            b = (c - 1 if serial != 0 else parent[c])
            while b >= 0:
                r0 = oO[c, 0] - oO[b, 0]
                r1 = oO[c, 1] - oO[b, 1]
                r2 = oO[c, 2] - oO[b, 2]
                F0 += r1 * F5 - r2 * F4
                F1 += r2 * F3 - r0 * F5
                F2 += r0 * F4 - r1 * F3
                for i in range(joint_voff[b], joint_voff[b + 1]):
                    U[i, j] = (oP[i, 0] * F0 + oP[i, 1] * F1 + oP[i, 2] * F2
                               + oP[i, 3] * F3 + oP[i, 4] * F4 + oP[i, 5] * F5)
                c = b
                b = (c - 1 if serial != 0 else parent[c])
