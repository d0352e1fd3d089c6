"""STUDY KERNEL, not for use: RGE-A with gravity entered as the base's acceleration in the
forward pass (the articulated-body algorithm's treatment) instead of inside phi.

Table A.1 as the paper (and the core) runs it: phi = tau - (C qd + gravity terms) by Newton-Euler
with the base accelerating at -g, then the backward pass phihat_k = phi_k - P_k^T eta_{k,k+1}
and the forward pass from mu_0 = 0. On a long chain phi_k holds the gravity moment of every link
outboard of joint k (~(n - k)^2 m g l), while phihat_k is of order m g l: the subtraction cancels
~2 log10(n) digits, and the true error grows ~n^2 eps (measured: 2.6e-9 at 1,000 straight links).

Here the kinematics pass runs with the base at rest (td holds only the velocity terms), so phi
has no gravity, and the forward pass starts from mu_0 = [0; -g] (the base's twist-rate), which
A_{k,k-1} carries up the chain like any other acceleration. Same factors, same backward pass
(the core's compiled kernels); only where gravity enters differs. In exact arithmetic both give
the same qdd (I qdd = phi(qd) - N^T M N_l [0; -g] is what the forward pass solves).

References:
    Agarwal et al., Table A.1 and Appendix A.1 (gravity as a base acceleration);
    Featherstone, Rigid Body Dynamics Algorithms (2008), section 7.3 (ABA, a_0 = -g).
"""

from __future__ import annotations

import numpy as np

from redysim import Chain, Workspace
from redysim._kernels.kinematics import kinematics
from redysim._kernels.rge_a import rge_a_backward


def rge_a_gravity_forward(chain: Chain, q, qd, tau=None) -> np.ndarray:
    """qdd with gravity in the forward pass (module docstring); float64."""
    c = chain
    ws = Workspace(c)
    n = c.n_dof
    q = np.ascontiguousarray(q, dtype=float)
    qd = np.ascontiguousarray(qd, dtype=float)
    tau = np.zeros(n) if tau is None else np.ascontiguousarray(tau, dtype=float)
    # kinematics with the base at rest: td = velocity terms only
    kinematics(c.length, c.dof_kind, c.dof_axis, c.dof_u, c.joint_qoff, q, qd, ws.zeros,
               np.zeros(3), ws.oR, ws.oO, ws.oP, ws.t, ws.td)
    # backward: k = nl..1 (the core's kernel: phi without gravity, Ihat, Psihat, phitil)
    rge_a_backward(c.mass, c.inertia_O, c.mass_com, c.dof_kind, c.joint_qoff, ws.oR, ws.oO,
                   ws.oP, ws.t, ws.td, tau, ws.Ihat, ws.Psihat, ws.phitil, ws.phi)
    # forward: k = 1..nl, mu_0 = [0; -g] (the base's twist-rate; O_1 is at the base)
    qoff, oO, oP, Psihat, phitil = c.joint_qoff, ws.oO, ws.oP, ws.Psihat, ws.phitil
    mu = np.concatenate([np.zeros(3), -np.asarray(c.gravity, dtype=float)])
    qdd = np.empty(n)
    for k in range(c.n_links):
        if k > 0:
            a = oO[k - 1] - oO[k]  # mu_{k,k-1} = A_{k,k-1} mu_{k-1}
            mu[3:] += np.cross(a, mu[:3])
        for j in range(qoff[k], qoff[k + 1]):
            x = phitil[j] - Psihat[j] @ mu
            qdd[j] = x
            mu += oP[j] * x
    return qdd
