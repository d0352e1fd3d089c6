"""Preallocated per-chain scratch arrays (Pinocchio's ``Data``): the kernels write into these."""

from __future__ import annotations

import math
from functools import cached_property

import numpy as np

from ._kernels import entry as E
from .chain import Chain, kernel_alias
from .errors import FieldError

ALIGN = 8  # every packed segment starts on a 64-byte boundary (8 doubles)


def _layout(sizes: dict[int, int], header: np.ndarray, start: int = 0) -> int:
    """Lay segments (slot -> number of items) back to back, each padded to ALIGN items: write
    each one's offset, counted from ``start``, into ``header`` at its slot; return the total."""
    end = start
    for slot, size in sizes.items():
        header[slot] = end
        end += -(-size // ALIGN) * ALIGN
    return end - start


def _pack(segments: dict[int, np.ndarray], dtype, header: np.ndarray, start: int = 0
          ) -> np.ndarray:
    """One array holding ``segments`` (slot -> array) as laid out by :func:`_layout`."""
    packed = np.zeros(_layout({k: a.size for k, a in segments.items()}, header, start), dtype)
    for slot, a in segments.items():
        packed[header[slot] - start:header[slot] - start + a.size] = np.ravel(a)
    return packed


class Workspace:
    """O(n) scratch for one chain. Not thread-safe: use one workspace per thread.

    Arrays (nl links, n DOF), all world frame: ``oR`` (nl,3,3) link rotations, ``oO`` (nl,3) joint
    positions, ``oP`` (n,6) motion subspaces, ``t`` and ``td`` (nl,6) twists and twist-rates,
    ``Ihat`` (n,) and ``Psihat`` (n,6) of RGE-A, ``phitil``/``phihat`` (n,), ``planar`` (nl,12)
    for the planar kernel: views of one array, ``scratch``. Besides: ``W`` (nl,6) resultant
    wrenches, ``phi`` (n,), and ``zeros`` (n,), ``zeros6`` (nl,6) that no kernel writes.
    ``kernel_f`` and ``kernel_i`` hold copies of the chain's arrays, packed with ``scratch`` for
    forward dynamics' entry points (:mod:`redysim._kernels.entry`: 7 arguments instead of 23).
    """

    def __init__(self, chain: Chain):
        if not isinstance(chain, Chain):
            raise FieldError("Workspace", "chain", type(chain).__name__,
                             "must be a redysim.Chain (Chain.build, Chain.uniform or "
                             "load_case(...).chain)")
        nl, n = chain.n_links, chain.n_dof
        c = chain
        self.chain = chain
        header = np.zeros(E.HEADER, dtype=np.int64)
        header[E.H_NL], header[E.H_N] = nl, n
        floats = {E.F_LENGTH: c.length, E.F_MASS: c.mass, E.F_INERTIA_O: c.inertia_O,
                  E.F_MASS_COM: c.mass_com, E.F_DOF_U: c.dof_u,
                  E.F_BASE_ACCEL: -np.asarray(c.gravity, dtype=float),
                  E.F_GRAVITY: np.asarray(c.gravity, dtype=float), E.F_ZEROS: np.zeros(n)}
        if chain.is_planar:
            floats.update({E.F_IZZ_O: c.inertia_O[:, 2, 2], E.F_MC_X: c.mass_com[:, 0],
                           E.F_MC_Y: c.mass_com[:, 1]})
        self.kernel_f = _pack(floats, np.float64, header)
        ints = {E.I_DOF_KIND: c.dof_kind, E.I_DOF_AXIS: c.dof_axis, E.I_JOINT_QOFF: c.joint_qoff}
        ints_packed = _pack(ints, np.int64, header, start=E.HEADER)  # after the header
        shapes = {E.S_OR: (nl, 3, 3), E.S_OO: (nl, 3), E.S_OP: (n, 6), E.S_T: (nl, 6),
                  E.S_TD: (nl, 6), E.S_IHAT: (n,), E.S_PSIHAT: (n, 6), E.S_PHITIL: (n,),
                  E.S_PHIHAT: (n,)}
        if chain.is_planar:
            shapes[E.S_PLANAR] = (nl, 12)
        self.scratch = np.empty(_layout({s: math.prod(shape) for s, shape in shapes.items()},
                                        header))
        self.kernel_i = np.concatenate((header, ints_packed))
        view = self._view
        self.oR, self.oO, self.oP = view(E.S_OR, shapes), view(E.S_OO, shapes), view(E.S_OP, shapes)
        self.t, self.td = view(E.S_T, shapes), view(E.S_TD, shapes)
        self.Ihat, self.Psihat = view(E.S_IHAT, shapes), view(E.S_PSIHAT, shapes)
        self.phitil, self.phihat = view(E.S_PHITIL, shapes), view(E.S_PHIHAT, shapes)
        self.planar = view(E.S_PLANAR, shapes) if chain.is_planar else None
        self.W = np.empty((nl, 6))
        self.phi = np.empty(n)
        # views of the packed chain data that the other functions take too: no kernel writes them
        self.zeros = self.kernel_f[header[E.F_ZEROS]:header[E.F_ZEROS] + n]  # (n,) of zeros
        self.zeros6 = np.zeros((nl, 6))
        self.base_accel = self.kernel_f[header[E.F_BASE_ACCEL]:header[E.F_BASE_ACCEL] + 3]  # -g
        self.no_accel = np.zeros(3)

    @cached_property
    def rge_a_head(self) -> tuple:
        """The spatial kernel's (``rge_a_forward_dynamics``) arguments before the state, for
        calling it directly (benchmarks/ab_kernels.py): the chain's arrays as writeable aliases
        (chain.kernel_alias: numba types read-only arrays on a slow path)."""
        c, k = self.chain, kernel_alias
        return (k(c.length), k(c.mass), k(c.inertia_O), k(c.mass_com), k(c.dof_kind),
                k(c.dof_axis), k(c.dof_u), k(c.joint_qoff))

    @property
    def rge_a_tail(self) -> tuple:
        """The spatial kernel's scratch arguments, after the state (the workspace's arrays)."""
        return (self.oR, self.oO, self.oP, self.t, self.td, self.Ihat, self.Psihat, self.phitil,
                self.phihat)

    def _view(self, slot: int, shapes: dict) -> np.ndarray:
        start = self.kernel_i[slot]
        size = math.prod(shapes[slot])
        return self.scratch[start:start + size].reshape(shapes[slot])

    @property
    def nbytes(self) -> int:
        """Bytes held by the workspace's own arrays (O(n); views of ``scratch`` not counted
        twice, the chain's arrays not counted)."""
        return sum(v.nbytes for v in vars(self).values()
                   if isinstance(v, np.ndarray) and v.base is None)
