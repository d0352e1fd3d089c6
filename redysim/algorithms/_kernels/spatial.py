"""Small spatial-algebra helpers in the world frame, inlined into the recursions.

The twist propagation matrix of Eq. (4), A_{k,k-1} = [[1, 0], [C(a), 1]], is a pure translation in
the world frame; every helper here applies it, or its transpose, with cross products.

References:
    Agarwal, Shah, Bandyopadhyay, Saha, "Dynamics of serial kinematic chains with large number of
    degrees-of-freedom", Eq. (4)-(10a); Saha, "Dynamics of serial multibody systems using the
    decoupled natural orthogonal complement matrices", J. Appl. Mech. 66 (1999).
"""

from __future__ import annotations

from redysim._jit import inline


@inline
def link_mass(Rk, inertia_O, mass_com, m, Mk):
    """The extended mass matrix M_k about O_k in the world frame, exactly symmetric.

    X = R I_O R^T (upper triangle, mirrored), Y = C(m d) with m d = R (m c), Z = m 1.
    """
    # B = R I_O (3 x 3), then X = B R^T (upper triangle only)
    for i in range(3):
        b0 = Rk[i, 0] * inertia_O[0, 0] + Rk[i, 1] * inertia_O[1, 0] + Rk[i, 2] * inertia_O[2, 0]
        b1 = Rk[i, 0] * inertia_O[0, 1] + Rk[i, 1] * inertia_O[1, 1] + Rk[i, 2] * inertia_O[2, 1]
        b2 = Rk[i, 0] * inertia_O[0, 2] + Rk[i, 1] * inertia_O[1, 2] + Rk[i, 2] * inertia_O[2, 2]
        for j in range(i, 3):
            x = b0 * Rk[j, 0] + b1 * Rk[j, 1] + b2 * Rk[j, 2]
            Mk[i, j] = x
            Mk[j, i] = x
    md0 = Rk[0, 0] * mass_com[0] + Rk[0, 1] * mass_com[1] + Rk[0, 2] * mass_com[2]
    md1 = Rk[1, 0] * mass_com[0] + Rk[1, 1] * mass_com[1] + Rk[1, 2] * mass_com[2]
    md2 = Rk[2, 0] * mass_com[0] + Rk[2, 1] * mass_com[1] + Rk[2, 2] * mass_com[2]
    # Y = C(md), Y^T = -C(md) in the lower-left block
    Mk[0, 3] = 0.0
    Mk[0, 4] = -md2
    Mk[0, 5] = md1
    Mk[1, 3] = md2
    Mk[1, 4] = 0.0
    Mk[1, 5] = -md0
    Mk[2, 3] = -md1
    Mk[2, 4] = md0
    Mk[2, 5] = 0.0
    for i in range(3):
        for j in range(3):
            Mk[3 + j, i] = Mk[i, 3 + j]
    for i in range(3):
        for j in range(3):
            Mk[3 + i, 3 + j] = m if i == j else 0.0


@inline
def add_shifted_mass(Mbar, a, Mhat, S):
    """Mhat += A^T Mbar A with A = [[1, 0], [C(a), 1]], keeping Mhat exactly symmetric.

    With Mbar = [[X, Y], [Y^T, Z]] and C = C(a):
        A^T Mbar A = [[X + YC + (YC)^T - C Z C, Y - C Z], [(Y - C Z)^T, Z]].
    Only upper triangles of the symmetric blocks are computed; the rest is mirrored. ``S`` is a
    (3, 3) scratch array.
    """
    a0, a1, a2 = a[0], a[1], a[2]
    # S = Y C, column j of C(a) is a x e_j: (0, a2, -a1), (-a2, 0, a0), (a1, -a0, 0)
    for i in range(3):
        y0 = Mbar[i, 3]
        y1 = Mbar[i, 4]
        y2 = Mbar[i, 5]
        S[i, 0] = y1 * a2 - y2 * a1
        S[i, 1] = y2 * a0 - y0 * a2
        S[i, 2] = y0 * a1 - y1 * a0
    # CZ = C(a) Z: row i of C(a) times Z, i.e. (a x Z[:, j])_i
    z00, z01, z02 = Mbar[3, 3], Mbar[3, 4], Mbar[3, 5]
    z11, z12, z22 = Mbar[4, 4], Mbar[4, 5], Mbar[5, 5]
    cz00 = a1 * z02 - a2 * z01
    cz01 = a1 * z12 - a2 * z11
    cz02 = a1 * z22 - a2 * z12
    cz10 = a2 * z00 - a0 * z02
    cz11 = a2 * z01 - a0 * z12
    cz12 = a2 * z02 - a0 * z22
    cz20 = a0 * z01 - a1 * z00
    cz21 = a0 * z11 - a1 * z01
    cz22 = a0 * z12 - a1 * z02
    # CZC = (C Z) C(a); only the upper triangle, columns of C(a) as above
    czc00 = cz01 * a2 - cz02 * a1
    czc01 = cz02 * a0 - cz00 * a2
    czc02 = cz00 * a1 - cz01 * a0
    czc11 = cz12 * a0 - cz10 * a2
    czc12 = cz10 * a1 - cz11 * a0
    czc22 = cz20 * a1 - cz21 * a0
    # X' = X + S + S^T - CZC (upper triangle, mirrored)
    x = Mhat[0, 0] + Mbar[0, 0] + 2.0 * S[0, 0] - czc00
    Mhat[0, 0] = x
    x = Mhat[0, 1] + Mbar[0, 1] + S[0, 1] + S[1, 0] - czc01
    Mhat[0, 1] = x
    Mhat[1, 0] = x
    x = Mhat[0, 2] + Mbar[0, 2] + S[0, 2] + S[2, 0] - czc02
    Mhat[0, 2] = x
    Mhat[2, 0] = x
    x = Mhat[1, 1] + Mbar[1, 1] + 2.0 * S[1, 1] - czc11
    Mhat[1, 1] = x
    x = Mhat[1, 2] + Mbar[1, 2] + S[1, 2] + S[2, 1] - czc12
    Mhat[1, 2] = x
    Mhat[2, 1] = x
    x = Mhat[2, 2] + Mbar[2, 2] + 2.0 * S[2, 2] - czc22
    Mhat[2, 2] = x
    # Y' = Y - C Z (full block), mirrored into the lower-left block
    y = Mhat[0, 3] + Mbar[0, 3] - cz00
    Mhat[0, 3] = y
    Mhat[3, 0] = y
    y = Mhat[0, 4] + Mbar[0, 4] - cz01
    Mhat[0, 4] = y
    Mhat[4, 0] = y
    y = Mhat[0, 5] + Mbar[0, 5] - cz02
    Mhat[0, 5] = y
    Mhat[5, 0] = y
    y = Mhat[1, 3] + Mbar[1, 3] - cz10
    Mhat[1, 3] = y
    Mhat[3, 1] = y
    y = Mhat[1, 4] + Mbar[1, 4] - cz11
    Mhat[1, 4] = y
    Mhat[4, 1] = y
    y = Mhat[1, 5] + Mbar[1, 5] - cz12
    Mhat[1, 5] = y
    Mhat[5, 1] = y
    y = Mhat[2, 3] + Mbar[2, 3] - cz20
    Mhat[2, 3] = y
    Mhat[3, 2] = y
    y = Mhat[2, 4] + Mbar[2, 4] - cz21
    Mhat[2, 4] = y
    Mhat[4, 2] = y
    y = Mhat[2, 5] + Mbar[2, 5] - cz22
    Mhat[2, 5] = y
    Mhat[5, 2] = y
    # Z' = Z (upper triangle, mirrored)
    for i in range(3, 6):
        for j in range(i, 6):
            z = Mhat[i, j] + Mbar[i, j]
            Mhat[i, j] = z
            Mhat[j, i] = z
