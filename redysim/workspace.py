"""Preallocated per-chain scratch arrays (Pinocchio's ``Data``): the kernels write into these."""

from __future__ import annotations

import numpy as np

from .chain import Chain, kernel_alias


class Workspace:
    """O(n) scratch for one chain. Not thread-safe: use one workspace per thread.

    Arrays (nl links, n DOF), all world frame: ``oR`` (nl,3,3) link rotations, ``oO`` (nl,3) joint
    positions, ``oP`` (n,6) motion subspaces, ``t`` and ``td`` (nl,6) twists and twist-rates, ``W``
    (nl,6) resultant wrenches, ``Ihat`` (n,) and ``Psihat`` (n,6) of RGE-A,
    ``phitil``/``phihat``/``phi``/``zeros``
    (n,), ``planar`` (nl,12) for the planar kernel.
    """

    def __init__(self, chain: Chain):
        nl, n = chain.n_links, chain.n_dof
        self.chain = chain
        self.oR = np.empty((nl, 3, 3))
        self.oO = np.empty((nl, 3))
        self.oP = np.empty((n, 6))
        self.t = np.empty((nl, 6))
        self.td = np.empty((nl, 6))
        self.W = np.empty((nl, 6))
        self.Ihat = np.empty(n)
        self.Psihat = np.empty((n, 6))
        self.phitil = np.empty(n)
        self.phihat = np.empty(n)
        self.phi = np.empty(n)
        self.zeros = np.zeros(n)
        self.zeros6 = np.zeros((nl, 6))
        self.base_accel = -np.asarray(chain.gravity, dtype=float)
        self.no_accel = np.zeros(3)
        self.planar = np.empty((nl, 12)) if chain.is_planar else None
        # forward dynamics' kernel arguments before and after the state, gathered once; the
        # chain's arrays as writeable aliases (chain.kernel_alias: numba types read-only arrays
        # on a slow path)
        c, k = chain, kernel_alias
        self.rge_a_head = (k(c.length), k(c.mass), k(c.inertia_O), k(c.mass_com),
                           k(c.dof_kind), k(c.dof_axis), k(c.dof_u), k(c.joint_qoff))
        self.rge_a_tail = (self.oR, self.oO, self.oP, self.t, self.td, self.Ihat, self.Psihat,
                           self.phitil, self.phihat)
        self.planar_head = ((k(c.length), k(c.mass), np.ascontiguousarray(c.inertia_O[:, 2, 2]),
                             np.ascontiguousarray(c.mass_com[:, 0]),
                             np.ascontiguousarray(c.mass_com[:, 1]), k(c.gravity))
                            if chain.is_planar else None)

    @property
    def nbytes(self) -> int:
        """Bytes held by the workspace's arrays (O(n))."""
        return sum(v.nbytes for v in vars(self).values() if isinstance(v, np.ndarray))
