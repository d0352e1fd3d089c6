"""STUDY KERNEL, not for use: a literal full-6x6 transcription of Table A.1 (non-symmetric RGE-A).

Tests the paper's implicit stability claim for RGE-A. The core's kernel
(``redysim/algorithms/_kernels/rge_a.py``) carries each articulated mass as symmetric blocks and
eliminates a U joint axis by axis. This one does what the table says, in whole matrices, with
nothing kept symmetric by construction:

    backward, k = nl..1 (Mbar_{nl+1} = 0, eta_{nl+1} = 0):
        Mhat_k   = M_k + A_{k+1,k}^T Mbar_{k+1} A_{k+1,k}      (full 6x6 products)
        Psi_k    = Mhat_k P_k                 (6 x z_k)
        Ihat_k   = P_k^T Psi_k                (z_k x z_k: 2 x 2 for a U joint)
        Psihat_k = Psi_k Ihat_k^-1            (numpy.linalg.inv)
        Mbar_k   = Mhat_k - Psihat_k Psi_k^T
        eta_{k,k+1} = A_{k+1,k}^T eta_{k+1};  phihat_k = phi_k - P_k^T eta_{k,k+1}
        phitil_k = Ihat_k^-1 phihat_k;        eta_k = Psi_k phitil_k + eta_{k,k+1}
    forward, k = 1..nl (mu_0 = 0):
        mu_{k,k-1} = A_{k,k-1} mu_{k-1};  qdd_k = phitil_k - Psihat_k^T mu_{k,k-1}
        mu_k = P_k qdd_k + mu_{k,k-1}

with M_k = [[R I_O R^T, C(m d)], [-C(m d), m 1]] (R I_O R^T as a full product) and
A_{k+1,k} = [[1, 0], [C(a_{k+1,k}), 1]] as explicit 6 x 6 matrices. Rounding makes Mhat_k
slightly non-symmetric; nothing removes it. ``resymmetrise=True`` replaces Mhat_k by
(Mhat_k + Mhat_k^T) / 2 at every step, everything else unchanged: the control that isolates
symmetry as the cause.

Inputs are the core's: kinematics (oR, oO, oP) and phi from the compiled kernels in float64 (what
:func:`redysim.phi` leaves in its workspace), or from the same kernels' Python source in float32
(:func:`redysim.harness.hiprec.kinematics_and_phi`), so the only difference from the core is the
elimination. numpy, one link per Python iteration
(~40 us/link): slow, and meant to be.

References:
    Agarwal et al., Appendix A.1, Table A.1; docs/design.md, "The algorithm" (exact symmetry).
"""

from __future__ import annotations

import numpy as np

from redysim import Chain, Workspace
from redysim import phi as _phi

from .hiprec import FLOAT32, kinematics_and_phi


def _cross_matrix(a, dtype):
    return np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]], dtype=dtype)


def _shift(a, dtype):
    """A = [[1, 0], [C(a), 1]] (6 x 6)."""
    A = np.eye(6, dtype=dtype)
    A[3:, :3] = _cross_matrix(a, dtype)
    return A


def _inputs(chain: Chain, q, v, tau, dtype):
    """oR, oO, oP, phi, inertia_O, mass_com, mass in ``dtype``."""
    if dtype == np.float64:
        ws = Workspace(chain)
        c = chain
        # phi runs the kinematics pass in ws (qdd = 0, base at -g) and leaves oR, oO, oP there
        phi = _phi(c, q, v, tau, ws=ws)
        return ws.oR, ws.oO, ws.oP, phi, c.inertia_O, c.mass_com, c.mass
    if dtype == np.float32:
        oR, oO, oP, phi, a = kinematics_and_phi(chain, q, v, tau, FLOAT32)
        return oR, oO, oP, phi, a["inertia_O"], a["mass_com"], a["mass"]
    raise ValueError(f"dtype {dtype!r}: float64 or float32")


def literal_rge_a(chain: Chain, q, v, tau=None, *, dtype=np.float64,
                  resymmetrise: bool = False, return_asymmetry: bool = False):
    """qdd by the literal, non-symmetric 6 x 6 transcription of Table A.1 (module docstring).

    chain: a serial chain (body k on body k - 1: each body's terms are shifted to the next one's).
    dtype: numpy.float64 or numpy.float32 (all arithmetic, kinematics and phi included).
    resymmetrise: replace Mhat_k by its symmetric part at every step (the control).
    return_asymmetry: also return max_k ||Mhat_k - Mhat_k^T||_max / ||Mhat_k||_max.
    """
    dtype = np.dtype(dtype).type
    oR, oO, oP, phi, inertia_O, mass_com, mass = _inputs(chain, q, v, tau, dtype)
    qoff = chain.joint_qoff
    nl, n = chain.n_links, chain.n_dof
    Psihat: list[np.ndarray] = [None] * nl  # type: ignore[list-item]
    phitil: list[np.ndarray] = [None] * nl  # type: ignore[list-item]
    asym = 0.0
    Mbar = None
    eta = np.zeros(6, dtype=dtype)
    # backward: k = nl..1
    for k in range(nl - 1, -1, -1):
        R = oR[k]
        M = np.zeros((6, 6), dtype=dtype)
        M[:3, :3] = R @ inertia_O[k] @ R.T
        md = R @ mass_com[k]
        M[:3, 3:] = _cross_matrix(md, dtype)
        M[3:, :3] = -_cross_matrix(md, dtype)
        M[3:, 3:] = mass[k] * np.eye(3, dtype=dtype)
        if Mbar is None:
            Mhat = M
            eta_kk1 = np.zeros(6, dtype=dtype)
        else:
            A = _shift(oO[k] - oO[k + 1], dtype)  # A_{k+1,k}, a_{k+1,k} = O_k - O_{k+1}
            Mhat = M + A.T @ Mbar @ A
            eta_kk1 = A.T @ eta
        if resymmetrise:
            Mhat = (Mhat + Mhat.T) / dtype(2)
        if return_asymmetry:
            asym = max(asym, float(np.abs(Mhat - Mhat.T).max() / np.abs(Mhat).max()))
        P = oP[qoff[k]:qoff[k + 1]].T  # 6 x z_k
        Psi = Mhat @ P
        Ihat = P.T @ Psi
        Ihat_inv = np.linalg.inv(Ihat)
        Ph = Psi @ Ihat_inv
        Mbar = Mhat - Ph @ Psi.T
        phihat = phi[qoff[k]:qoff[k + 1]] - P.T @ eta_kk1
        pt = Ihat_inv @ phihat
        eta = Psi @ pt + eta_kk1
        Psihat[k] = Ph
        phitil[k] = pt
    # forward: k = 1..nl
    qdd = np.empty(n, dtype=dtype)
    mu = np.zeros(6, dtype=dtype)
    for k in range(nl):
        mu_kk1 = mu if k == 0 else _shift(oO[k - 1] - oO[k], dtype) @ mu  # A_{k,k-1} mu_{k-1}
        x = phitil[k] - Psihat[k].T @ mu_kk1
        qdd[qoff[k]:qoff[k + 1]] = x
        mu = oP[qoff[k]:qoff[k + 1]].T @ x + mu_kk1
    return (qdd, asym) if return_asymmetry else qdd
