"""Forward dynamics needs O(n) memory: the workspace grows linearly with the DOF, and a call
with a workspace and ``out`` allocates nothing that grows with them; nor, after its first, does a
call without one (it reuses the model's own).

Measured by tracemalloc, which sees numpy's array data. ``benchmarks/jit_times.py`` reports the
process's peak RSS at 100,000 DOF (231 MiB here, of which the workspace is 36 MiB).
"""

from __future__ import annotations

import tracemalloc

import numpy as np
import pytest

from redysim import Chain, Workspace, forward_dynamics

SIZES = (2_000, 8_000)  # DOF


def u_chain(n_dof: int) -> Chain:
    return Chain.uniform(n_dof // 2, "U", length=0.02, linear_density=61.6538, radius=0.05)


def traced_peak(fn) -> int:
    """Peak bytes allocated (and still counted by tracemalloc) while ``fn()`` runs."""
    tracemalloc.start()
    try:
        tracemalloc.reset_peak()
        base, _ = tracemalloc.get_traced_memory()
        fn()
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    return peak - base


@pytest.fixture(scope="module")
def chains():
    chains = {n: u_chain(n) for n in SIZES}
    for c in chains.values():  # compile or load the kernels outside the measurements
        forward_dynamics(c, np.zeros(c.n_dof), np.zeros(c.n_dof))
    return chains


def test_the_workspace_is_linear_in_the_dof(chains):
    per_dof = {n: Workspace(c).nbytes / n for n, c in chains.items()}
    small, big = (per_dof[n] for n in SIZES)
    assert abs(big / small - 1) < 0.01, per_dof  # the same bytes per DOF at 4x the DOF
    assert big < 400, per_dof  # 380 B/DOF: ~47 doubles (scratch, chain copies, W, phi)


@pytest.mark.parametrize("n", SIZES)
def test_a_call_with_a_workspace_allocates_nothing_that_grows_with_n(chains, n):
    c = chains[n]
    ws, out = Workspace(c), np.empty(c.n_dof)
    q, qd = np.full(c.n_dof, 0.1), np.full(c.n_dof, 0.2)
    forward_dynamics(c, q, qd, ws=ws, out=out)
    peak = traced_peak(lambda: forward_dynamics(c, q, qd, ws=ws, out=out))
    assert peak < 4096, peak  # a few Python objects; one qdd alone would be 8 n bytes


def test_a_call_without_a_workspace_makes_the_models_once(chains):
    """The first call without ws= (on a thread) makes the model's own workspace, linear in n and
    kept by the model (redysim.algorithms.workspace.model_workspace); later calls allocate their
    qdd only."""
    first, later = {}, {}
    for n in chains:  # (the fixture's chains have loaded the kernels)
        c = u_chain(n)  # a model of its own: no workspace yet
        q, qd = np.full(c.n_dof, 0.1), np.full(c.n_dof, 0.2)
        first[n] = traced_peak(lambda c=c, q=q, qd=qd: forward_dynamics(c, q, qd)) / n
        later[n] = traced_peak(lambda c=c, q=q, qd=qd: forward_dynamics(c, q, qd))
    small, big = (first[n] for n in SIZES)
    assert abs(big / small - 1) < 0.05, first  # bytes per DOF constant at 4x the DOF
    assert big < 450, first  # 409 B/DOF: the workspace it makes (380) and qdd
    for n in SIZES:
        assert later[n] < 4096 + 8 * n, later  # qdd (8 n bytes) and a few Python objects
