"""Seeded random chains and states shared by the engine tests (not a test module).

They live in :mod:`harness.random_chains`, so that the accuracy gates (``python -m
harness.gates``) compare the engines on exactly the chains and states these tests use.
"""

from __future__ import annotations

from redysim.harness.random_chains import (  # noqa: F401
    engine_test_chain,
    random_chain,
    random_link,
    random_state,
)
