"""What the engine tests share (not a test module): seeded random chains and states, and each
engine's tolerance.

The chains and states live in :mod:`harness.random_chains`, so that the accuracy gates (``python
-m harness.gates``) compare the engines on exactly the chains and states these tests use.
"""

from __future__ import annotations

from typing import NamedTuple

import pytest

import redysim
from redysim import references
from redysim.harness.random_chains import (  # noqa: F401
    FAMILIES,
    engine_test_chain,
    random_chain,
    random_link,
    random_state,
)


class Tolerance(NamedTuple):
    """One engine's tolerance, relative, for every stage (GIM, phi, qdd, tip, energy): on the
    seeded random chains (tests/test_engines_agreement.py) and on trees and robots
    (tests/test_engines_trees.py)."""

    chains: float
    trees: float


# O(n) recursive solvers (the articulated-body algorithm: pin.aba, DART's ABA, like the core's
# RGE-A): their rounding error grows with the number of links, not with cond(I). Chains:
# measured <= 1.2e-14 on qdd at 50 links (GIM, phi, tip <= 4e-15; 3.4e-13 while the core still
# carried gravity inside phi); 1e-11 is ~1000x tighter than a cond(I) * eps bound, so it catches
# a wrong model or a drifting recursion, and stays above the ~n^2 eps growth of Table A.1 as
# printed should an engine work that way. With S joints (Euler angles) the conditioning of each
# joint's own block enters too: measured <= 2.0e-12 on the S and mix chains of up to 50 links
# (cond(I) up to 9.6e8), DART's EulerJoint aside (test_engines_agreement.KNOWN_DEFECTS). Trees:
# measured <= 3.2e-13 on qdd over 150 random-tree states (50 trees of 12 bodies, R, P, U, S
# joints, free and fixed base; cond(I) up to 3.9e4) and <= 2.5e-15 on the robots: 1e-11 too.
# pin.aba with JointModelUniversal misses it on 50-link U chains (a known defect, see
# test_pinocchio_universal_aba_defect and the xfail marks) - the tolerance is NOT loosened for it.
#
# Dense factorisations of the assembled mass matrix (Cholesky, MuJoCo's L^T D L, Exudyn's
# EigenDense LU): a backward-stable dense solve has a relative forward error up to
# ~cond(I) * eps. Chains: the 50-link chains reach cond(I) = 3.4e7 near straight, i.e. 7.5e-9;
# measured 4.8e-10: 1e-8. Trees: the bound, 1e-10 (measured <= 9.7e-13 on the random
# trees and 1.3e-13 on Talos full floating, MuJoCo; cond(I) = 1.3e7 there, so cond * eps = 3e-9
# would allow more). The GIM, phi, tip and energy stages involve no solve and agree to ~1e-15 in
# every engine, at these tolerances too.
TOLERANCE = {
    "pinocchio-aba": Tolerance(chains=1e-11, trees=1e-11),
    "pinocchio-aba-ryrz": Tolerance(chains=1e-11, trees=1e-11),
    "pinocchio-crba": Tolerance(chains=1e-8, trees=1e-10),
    "mujoco": Tolerance(chains=1e-8, trees=1e-10),
    "dart": Tolerance(chains=1e-11, trees=1e-11),
    "exudyn": Tolerance(chains=1e-8, trees=1e-10),
    "drake": Tolerance(chains=1e-11, trees=1e-11),
}
assert set(TOLERANCE) == set(references.ENGINES)


def engine_or_skip(name: str) -> type[references.Engine]:
    """The adapter class of engine ``name``; the test is skipped when its package is missing."""
    cls = references.get(name)
    if not cls.available():
        pytest.skip(f"engine {name!r} needs the Python package {cls.package!r}, not installed")
    return cls


def chain_links(chain: redysim.Chain) -> list[redysim.Link]:
    """The chain's links, to build a variant of it (other joints, one link changed)."""
    return [redysim.Link(float(chain.length[k]), float(chain.mass[k]), tuple(chain.com[k]),
                         tuple(map(tuple, chain.inertia_com[k]))) for k in range(chain.n_links)]
