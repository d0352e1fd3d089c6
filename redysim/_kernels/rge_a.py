"""RGE-A: forward dynamics in O(n) by Reverse Gaussian Elimination done analytically.

Solves I(q) qdd = phi for qdd without forming the GIM I, through its analytic U D U^T
factorisation (Table A.1):

    articulated masses (backward, k = nl..1; Mhat_nl = M_nl):
        Psi_k = Mhat_k P_k,  Ihat_k = P_k^T Psi_k,  Psihat_k = Psi_k Ihat_k^-1,
        Mbar_k = Mhat_k - Psihat_k Psi_k^T,  Mhat_{k-1} = M_{k-1} + A_{k,k-1}^T Mbar_k A_{k,k-1}
    backward, k = nl..1 (eta_{nl+1} = 0):
        eta_{k,k+1} = A_{k+1,k}^T eta_{k+1},  phihat_k = phi_k - P_k^T eta_{k,k+1},
        phitil_k = Ihat_k^-1 phihat_k,        eta_k = Psi_k phitil_k + eta_{k,k+1}
    forward, k = 1..nl (mu_0 = 0):
        mu_{k,k-1} = A_{k,k-1} mu_{k-1},  qdd_k = phitil_k - Psihat_k^T mu_{k,k-1},
        mu_k = P_k qdd_k + mu_{k,k-1}

Stability: every articulated mass is written through its upper triangle and mirrored, so it is
exactly symmetric by construction. A literal 6 x 6 transcription lets rounding make Mhat_k
slightly asymmetric, the recursion amplifies that, and all accuracy is gone by ~100 U-links
(DESIGN.md section 3; the same failure as stock Pinocchio ABA on such chains).

References:
    Agarwal et al., Appendix A.1, Eq. (A.1)-(A.8) and Table A.1; Saha, "Analytical expression for
    the inverted inertia matrix of serial robots", Int. J. Robotics Research 18 (1999).
"""

from __future__ import annotations

import numpy as np

from .._jit import inline, jit
from .spatial import add_shifted_mass, link_mass


@inline
def sym_inverse(H, z, Hinv):
    """Hinv = H^-1 for a symmetric z x z block (z = 1, 2, 3) by its adjugate; exactly symmetric."""
    if z == 1:
        Hinv[0, 0] = 1.0 / H[0, 0]
    elif z == 2:
        det = H[0, 0] * H[1, 1] - H[0, 1] * H[0, 1]
        Hinv[0, 0] = H[1, 1] / det
        Hinv[1, 1] = H[0, 0] / det
        x = -H[0, 1] / det
        Hinv[0, 1] = x
        Hinv[1, 0] = x
    else:
        c00 = H[1, 1] * H[2, 2] - H[1, 2] * H[1, 2]
        c01 = H[0, 2] * H[1, 2] - H[0, 1] * H[2, 2]
        c02 = H[0, 1] * H[1, 2] - H[0, 2] * H[1, 1]
        c11 = H[0, 0] * H[2, 2] - H[0, 2] * H[0, 2]
        c12 = H[0, 2] * H[0, 1] - H[0, 0] * H[1, 2]
        c22 = H[0, 0] * H[1, 1] - H[0, 1] * H[0, 1]
        det = H[0, 0] * c00 + H[0, 1] * c01 + H[0, 2] * c02
        Hinv[0, 0] = c00 / det
        Hinv[1, 1] = c11 / det
        Hinv[2, 2] = c22 / det
        Hinv[0, 1] = Hinv[1, 0] = c01 / det
        Hinv[0, 2] = Hinv[2, 0] = c02 / det
        Hinv[1, 2] = Hinv[2, 1] = c12 / det


@jit
def rge_a_backward(mass, inertia_O, mass_com, joint_qoff, oR, oO, oP, phi,
                   Ihat, Psihat, phitil):
    """Backward pass of Table A.1: articulated masses and phitil.

    Writes Ihat (nl, 3, 3) (the D blocks of I = U D U^T), Psihat (n, 6) and phitil (n,).
    """
    nl = mass.shape[0]
    Mhat = np.empty((6, 6))
    Mbar = np.zeros((6, 6))
    S = np.empty((3, 3))
    Psi = np.empty((3, 6))
    Hinv = np.empty((3, 3))
    eta = np.zeros(6)
    a = np.empty(3)
    # backward: k = nl..1
    for k in range(nl - 1, -1, -1):
        j0 = joint_qoff[k]
        z = joint_qoff[k + 1] - j0
        # Mhat_k = M_k + A_{k+1,k}^T Mbar_{k+1} A_{k+1,k};  eta_{k,k+1} = A_{k+1,k}^T eta_{k+1}
        link_mass(oR[k], inertia_O[k], mass_com[k], mass[k], Mhat)
        if k < nl - 1:
            a[0] = oO[k, 0] - oO[k + 1, 0]
            a[1] = oO[k, 1] - oO[k + 1, 1]
            a[2] = oO[k, 2] - oO[k + 1, 2]
            add_shifted_mass(Mbar, a, Mhat, S)
            f0, f1, f2 = eta[3], eta[4], eta[5]
            eta[0] -= a[1] * f2 - a[2] * f1
            eta[1] -= a[2] * f0 - a[0] * f2
            eta[2] -= a[0] * f1 - a[1] * f0
        # Psi_k = Mhat_k P_k
        for c in range(z):
            p = oP[j0 + c]
            for i in range(6):
                Psi[c, i] = (Mhat[i, 0] * p[0] + Mhat[i, 1] * p[1] + Mhat[i, 2] * p[2]
                             + Mhat[i, 3] * p[3] + Mhat[i, 4] * p[4] + Mhat[i, 5] * p[5])
        # Ihat_k = P_k^T Psi_k (upper triangle, mirrored) and its inverse
        H = Ihat[k]
        for c in range(z):
            p = oP[j0 + c]
            for d in range(c, z):
                x = (p[0] * Psi[d, 0] + p[1] * Psi[d, 1] + p[2] * Psi[d, 2]
                     + p[3] * Psi[d, 3] + p[4] * Psi[d, 4] + p[5] * Psi[d, 5])
                H[c, d] = x
                H[d, c] = x
        sym_inverse(H, z, Hinv)
        # Psihat_k = Psi_k Ihat_k^-1;  phihat_k = phi_k - P_k^T eta_{k,k+1}
        for c in range(z):
            ph = Psihat[j0 + c]
            for i in range(6):
                x = 0.0
                for d in range(z):
                    x += Psi[d, i] * Hinv[d, c]
                ph[i] = x
        for c in range(z):
            p = oP[j0 + c]
            phitil[j0 + c] = phi[j0 + c] - (p[0] * eta[0] + p[1] * eta[1] + p[2] * eta[2]
                                            + p[3] * eta[3] + p[4] * eta[4] + p[5] * eta[5])
        # phitil_k = Ihat_k^-1 phihat_k (in place; phihat kept in locals)
        if z == 1:
            phitil[j0] = Hinv[0, 0] * phitil[j0]
        else:
            h0 = phitil[j0]
            h1 = phitil[j0 + 1]
            h2 = phitil[j0 + 2] if z == 3 else 0.0
            for c in range(z):
                x = Hinv[c, 0] * h0 + Hinv[c, 1] * h1
                if z == 3:
                    x += Hinv[c, 2] * h2
                phitil[j0 + c] = x
        # eta_k = Psi_k phitil_k + eta_{k,k+1}
        for c in range(z):
            x = phitil[j0 + c]
            for i in range(6):
                eta[i] += Psi[c, i] * x
        # Mbar_k = Mhat_k - Psihat_k Psi_k^T (upper triangle, mirrored)
        for i in range(6):
            for j in range(i, 6):
                x = Mhat[i, j]
                for c in range(z):
                    x -= Psihat[j0 + c, i] * Psi[c, j]
                Mbar[i, j] = x
                Mbar[j, i] = x


@jit
def rge_a_forward(joint_qoff, oO, oP, Psihat, phitil, qdd):
    """Forward pass of Table A.1: qdd_k = phitil_k - Psihat_k^T mu_{k,k-1}."""
    nl = joint_qoff.shape[0] - 1
    m0 = m1 = m2 = m3 = m4 = m5 = 0.0
    # forward: k = 1..nl
    for k in range(nl):
        if k > 0:
            # mu_{k,k-1} = A_{k,k-1} mu_{k-1}, a = O_{k-1} - O_k
            a0 = oO[k - 1, 0] - oO[k, 0]
            a1 = oO[k - 1, 1] - oO[k, 1]
            a2 = oO[k - 1, 2] - oO[k, 2]
            m3 += a1 * m2 - a2 * m1
            m4 += a2 * m0 - a0 * m2
            m5 += a0 * m1 - a1 * m0
        j0 = joint_qoff[k]
        z = joint_qoff[k + 1] - j0
        for c in range(z):
            ph = Psihat[j0 + c]
            qdd[j0 + c] = phitil[j0 + c] - (ph[0] * m0 + ph[1] * m1 + ph[2] * m2
                                            + ph[3] * m3 + ph[4] * m4 + ph[5] * m5)
        # mu_k = P_k qdd_k + mu_{k,k-1}
        for c in range(z):
            p = oP[j0 + c]
            x = qdd[j0 + c]
            m0 += p[0] * x
            m1 += p[1] * x
            m2 += p[2] * x
            m3 += p[3] * x
            m4 += p[4] * x
            m5 += p[5] * x
