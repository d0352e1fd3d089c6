"""Seeded random chains and states for engine-versus-core comparisons.

Shared by the engine agreement tests (``tests/test_engines_agreement.py``, through
``tests/engine_chains.py``) and the accuracy gates (:mod:`harness.gates`), so that both compare the
engines on exactly the same chains and states. Only R and U joints (the ones every reference
adapter models); links have random lengths, masses, off-axis centres of mass and rotated full
inertias that satisfy the triangle inequality (MuJoCo checks it).
"""

from __future__ import annotations

import numpy as np

import redysim

STATE_KINDS = ("spread", "straight")


def random_link(rng: np.random.Generator) -> redysim.Link:
    """A link with random length, mass, off-axis COM and a full (rotated) inertia about the COM
    whose principal moments satisfy the triangle inequality (a physical body: MuJoCo checks it)."""
    length = rng.uniform(0.5, 1.5)
    mass = rng.uniform(0.5, 2.0)
    com = (length * rng.uniform(0.3, 0.7), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05))
    a, b = rng.uniform(0.01, 0.1, 2)
    moments = np.array([a + b, a + 0.5 * b, 0.5 * a + b]) * mass  # each < sum of the others
    Q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    inertia = Q @ np.diag(moments) @ Q.T
    inertia = 0.5 * (inertia + inertia.T)
    return redysim.Link(length, mass, com, tuple(map(tuple, inertia)))


def random_chain(joint: str, n_links: int, seed: int) -> redysim.Chain:
    """``n_links`` random links, every joint of type ``joint`` ("R" or "U")."""
    rng = np.random.default_rng(seed)
    links = [random_link(rng) for _ in range(n_links)]
    return redysim.Chain.build(links, [joint] * n_links, name=f"rand-{joint}{n_links}")


def engine_test_chain(joint: str, n_links: int) -> redysim.Chain:
    """The chain the engine agreement tests use for (joint, n_links): seed n_links for R chains,
    n_links + 1000 for U chains."""
    return random_chain(joint, n_links, seed=n_links + (0 if joint == "R" else 1000))


def random_state(chain: redysim.Chain, kind: str, seed: int):
    """(q, qd, tau): ``spread`` draws q uniformly in (-pi, pi); ``straight`` within 1e-3 rad of
    the straight chain (q = 0), where U joints are far from their singular configuration
    but the chain is at its stiffest conditioning."""
    if kind not in STATE_KINDS:
        raise ValueError(f"kind = {kind!r}: choose one of {', '.join(STATE_KINDS)}")
    rng = np.random.default_rng(seed)
    n = chain.n_dof
    if kind == "spread":
        q = rng.uniform(-np.pi, np.pi, n)
    else:
        q = rng.normal(scale=1e-3, size=n)
    qd = rng.normal(size=n)
    tau = rng.normal(size=n)
    return q, qd, tau
