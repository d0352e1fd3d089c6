"""Seeded random chains and states shared by the engine tests (not a test module).

They live in :mod:`harness.random_chains`, so that the accuracy gates (``python -m
harness.gates``) compare the engines on exactly the chains and states these tests use.
"""

from __future__ import annotations

import redysim
from redysim.harness.random_chains import (  # noqa: F401
    FAMILIES,
    engine_test_chain,
    random_chain,
    random_link,
    random_state,
)


def chain_links(chain: redysim.Chain) -> list[redysim.Link]:
    """The chain's links, to build a variant of it (other joints, one link changed)."""
    return [redysim.Link(float(chain.length[k]), float(chain.mass[k]), tuple(chain.com[k]),
                         tuple(map(tuple, chain.inertia_com[k]))) for k in range(chain.n_links)]
