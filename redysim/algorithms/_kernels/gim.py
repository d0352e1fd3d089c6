"""The generalized inertia matrix (GIM) from composite masses, Eq. (10a).

    M~_nl = M_nl,   M~_k = M_k + A_{k+1,k}^T M~_{k+1} A_{k+1,k}     (backward, k = nl..1;
                    on a tree the sum runs over k's children)
    I_ij = P_i^T M~_i A_{i,j} P_j  (i >= j),  computed as I_ji = P_j^T A_{i,j}^T (M~_i P_i),
    and each joint's own inertia (armature) on the diagonal: I_jj + armature_j

O(n^2) entries, each block from a wrench M~_i P_i carried towards the base. Written through the
upper triangle and mirrored, so I is exactly symmetric.

References:
    Agarwal et al., Eq. (9)-(10a); Saha, J. Appl. Mech. 66 (1999), Eq. (24).
"""

from __future__ import annotations

import numpy as np

from redysim._jit import jit

from .joints import joint_inertia
from .spatial import add_shifted_mass, link_mass


@jit
def gim_composite(tree, s, I):
    """Fill the (n, n) GIM I from the kinematics pass (only s.oR, s.oO, s.oP are read).

    On a tree, M~_k gathers every child's composite mass, and each block I_ij (i an ancestor of
    j's body) is the wrench M~_j P_j carried up the path to the base; the blocks of bodies on
    different branches are zero."""
    mass, inertia_O, mass_com, joint_voff, armature = (tree.mass, tree.inertia_O, tree.mass_com,
                                                       tree.joint_voff, tree.armature)
    serial, parent, gather = tree.serial, tree.parent, tree.gather
    oR, oO, oP = s.oR, s.oO, s.oP
    nl = mass.shape[0]
    n = oP.shape[0]
    if serial == 0:  # blocks of bodies on different branches are zero (a chain has none)
        for i in range(n):
            for j in range(n):
                I[i, j] = 0.0
    Mtil = np.empty((6, 6))
    Mnext = np.zeros((6, 6))
    # the composite masses of the children that do not follow their parent, moved to its O
    Mgather = np.zeros((gather.shape[0] if serial == 0 else 0, 6, 6))
    S = np.empty((3, 3))
    a = np.empty(3)
    F = np.empty(6)
    # backward: k = nl..1, children first
    for k in range(nl - 1, -1, -1):
        link_mass(oR[k], inertia_O[k], mass_com[k], mass[k], Mtil)
        if serial == 0 and gather[k] >= 0:
            for i in range(6):
                for jj in range(6):
                    Mtil[i, jj] += Mgather[k, i, jj]
        if k < nl - 1 and (serial != 0 or parent[k + 1] == k):
            a[0] = oO[k, 0] - oO[k + 1, 0]
            a[1] = oO[k, 1] - oO[k + 1, 1]
            a[2] = oO[k, 2] - oO[k + 1, 2]
            add_shifted_mass(Mnext, a, Mtil, S)
        for j in range(joint_voff[k], joint_voff[k + 1]):
            p = oP[j]
            for i in range(6):
                F[i] = (Mtil[i, 0] * p[0] + Mtil[i, 1] * p[1] + Mtil[i, 2] * p[2]
                        + Mtil[i, 3] * p[3] + Mtil[i, 4] * p[4] + Mtil[i, 5] * p[5])
            # diagonal block: columns of joint k up to j (I_jj + armature_j on the diagonal)
            for jj in range(joint_voff[k], j + 1):
                x = (oP[jj, 0] * F[0] + oP[jj, 1] * F[1] + oP[jj, 2] * F[2]
                     + oP[jj, 3] * F[3] + oP[jj, 4] * F[4] + oP[jj, 5] * F[5])
                if jj == j:
                    x = joint_inertia(x, armature, j)
                I[jj, j] = x
                I[j, jj] = x
            # off-diagonal blocks: carry F = A^T F towards the base, over k's ancestors b
            c = k
            b = (c - 1 if serial != 0 else parent[c])
            while b >= 0:
                r0 = oO[c, 0] - oO[b, 0]
                r1 = oO[c, 1] - oO[b, 1]
                r2 = oO[c, 2] - oO[b, 2]
                F[0] += r1 * F[5] - r2 * F[4]
                F[1] += r2 * F[3] - r0 * F[5]
                F[2] += r0 * F[4] - r1 * F[3]
                for jj in range(joint_voff[b], joint_voff[b + 1]):
                    x = (oP[jj, 0] * F[0] + oP[jj, 1] * F[1] + oP[jj, 2] * F[2]
                         + oP[jj, 3] * F[3] + oP[jj, 4] * F[4] + oP[jj, 5] * F[5])
                    I[jj, j] = x
                    I[j, jj] = x
                c = b
                b = (c - 1 if serial != 0 else parent[c])
        pk = (k - 1 if serial != 0 else parent[k])
        if pk >= 0 and (serial == 0 and parent[k] != k - 1):
            a[0] = oO[pk, 0] - oO[k, 0]
            a[1] = oO[pk, 1] - oO[k, 1]
            a[2] = oO[pk, 2] - oO[k, 2]
            add_shifted_mass(Mtil, a, Mgather[pk], S)
        for i in range(6):
            for jj in range(6):
                Mnext[i, jj] = Mtil[i, jj]
