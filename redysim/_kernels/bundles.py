"""The two named bundles the kernels pass: a tree's arrays and the scratch they write into.

numba types a NamedTuple of arrays field by field and unpacks it at no cost inside compiled code,
so a kernel's signature names what it reads (``tree.mass``, ``s.oR``) instead of two dozen
positional arrays, and adding a quantity changes one definition (docs/design.md, "Kinematic
trees"). The bundles are built once per chain or model (:mod:`redysim.workspace`) and, on the hot
path, sliced out of a workspace's packed arrays inside compiled code (:mod:`.entry`).

Kernels read the fields into locals at their top, once per call, and pass helpers scalars, never
arrays: an array handed to an inlined helper in a loop costs reference counting per call, ten
times a rope body's work. The kernels that take the bundles compile without numba's reference
counting altogether (``redysim._jit.jit_borrowed``).

A serial chain is a tree (parent k - 1, each joint at the parent's ``along`` on its x axis, no
free joint): ``serial = 1`` tells the kernels so, and they then read none of the tree's tables
(``parent``, ``gather``, ``placement_code``, ``qshift``, ``placement_R``, ``placement_p``, which
a serial chain leaves empty): the rope streams no byte more than before trees existed.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

ALONG_X, PLACED = 0, 1  # placement_code: a translation along the parent's x; any rotation and shift
GATHER_MASS = 21  # an articulated mass's numbers: X and Z upper triangles (6 + 6), Y (9)


class Tree(NamedTuple):
    """A tree's arrays (nb bodies, n velocity coordinates), body k's parent before it.

    serial:          1 for a serial chain as above (the tables below then empty), else 0.
    parent:          (nb,) parent body, -1 for the base.
    gather:          (nb,) -1, or the row in the scratch's gather arrays where the children of
                     body k that do not directly follow it (k + 1) leave their articulated masses
                     and biases (backward passes) and where body k leaves its forward carry-over.
    placement_code:  (nb,) ALONG_X or PLACED.
    qshift:          (nb,) joint k's first configuration index minus its first velocity index
                     (a free joint's quaternion has 4 numbers for 3 velocities).
    along:           (nb,) joint k's offset along the parent's x (the parent's length in a chain).
    placement_R:     (nb, 3, 3), placement_p (nb, 3): joint k's frame in the parent's (PLACED).
    joint_voff:      (nb + 1,) first velocity coordinate of joint k.
    dof_kind, dof_axis, dof_u: (n,) per axis (:mod:`.joints`).
    mass, inertia_O, mass_com: per body, about its origin O_k in its own frame.
    """

    serial: int
    parent: np.ndarray
    gather: np.ndarray
    placement_code: np.ndarray
    qshift: np.ndarray
    along: np.ndarray
    placement_R: np.ndarray
    placement_p: np.ndarray
    joint_voff: np.ndarray
    dof_kind: np.ndarray
    dof_axis: np.ndarray
    dof_u: np.ndarray
    mass: np.ndarray
    inertia_O: np.ndarray
    mass_com: np.ndarray


class Scratch(NamedTuple):
    """What the kernels write (all world frame; nb bodies, n DOF, ng gathering bodies).

    oR (nb, 3, 3), oO (nb, 3): body frames; oP (n, 6): motion subspace columns; t, td (nb, 6):
    twists and twist-rates; Ihat (n,), Psihat (n, 6), phitil, phihat (n,): RGE-A; W (nb, 6):
    resultant wrenches; gather_mass (ng, 21), gather_wrench (ng, 6), gather_twist (ng, 6): the
    gathering bodies' rows (``Tree.gather``).
    """

    oR: np.ndarray
    oO: np.ndarray
    oP: np.ndarray
    t: np.ndarray
    td: np.ndarray
    Ihat: np.ndarray
    Psihat: np.ndarray
    phitil: np.ndarray
    phihat: np.ndarray
    W: np.ndarray
    gather_mass: np.ndarray
    gather_wrench: np.ndarray
    gather_twist: np.ndarray
