"""The high-precision reference (harness.hiprec) and the true errors it measures.

The reference is the core's own RGE-A kernel run in 50-digit mpmath arithmetic; here it is checked
against an independent dense mpmath solve, against float64 dense solves, against itself at more
digits, and the study kernels' true errors are pinned (harness.nonsymmetric, the literal
non-symmetric Table A.1).
"""

from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest
from conftest import random_chain, random_state

from redysim import forward_dynamics, mass_matrix, phi
from redysim.harness import hiprec
from redysim.harness.error_study import make_chain, make_state, rge_a_on_phi
from redysim.harness.nonsymmetric import literal_rge_a


def mp_rel(a, b) -> float:
    """max |a - b| / max |b| for lists of mpf, at the working precision of b."""
    with mpmath.workdps(60):
        return float(max(abs(x - y) for x, y in zip(a, b, strict=True)) / max(abs(y) for y in b))


@pytest.mark.parametrize("mix", [("R",), ("U",), ("R", "U", "S")], ids=["R", "U", "mixed"])
@pytest.mark.parametrize("n_links", [1, 2, 4, 8, 15])
def test_reference_equals_an_independent_dense_mpmath_solve(mix, n_links):
    """RGE-A in mpmath == mpmath.lu_solve of a GIM built by Newton-Euler about the COMs (no
    DeNOC, no articulated masses), on random chains (random masses, COMs, rotated inertias,
    general axes) at random states over (-pi, pi). Measured ~1e-47 at dps = 50 (cond2 up to ~1e7
    here); 1e-30 leaves room."""
    rng = np.random.default_rng([7, n_links, len(mix)])
    chain = random_chain(rng, n_links, mix)
    q, qd, tau = random_state(rng, chain)
    ref = hiprec.qdd_reference(chain, q, qd, tau, output="mpf")
    dense = hiprec.dense_reference(chain, q, qd, tau)
    assert mp_rel(ref, dense) < 1e-30


@pytest.mark.parametrize("mix", [("R",), ("U",)], ids=["R", "U"])
def test_independent_gim_equals_the_core_mass_matrix(mix, rng):
    """The independent Newton-Euler GIM (the dense check's) is the core's, to double rounding."""
    chain = random_chain(rng, 6, mix)
    q, _, _ = random_state(rng, chain)
    gim = hiprec.dense_gim_mp(chain, q)
    dense = np.array([[float(gim[i, j]) for j in range(chain.n_dof)] for i in range(chain.n_dof)])
    core = mass_matrix(chain, q)
    assert np.abs(dense - core).max() / np.abs(core).max() < 1e-13


@pytest.mark.parametrize("joint", ["R", "U"])
def test_reference_agrees_with_float_solve_on_well_conditioned_chains(joint, rng):
    """numpy.linalg.solve(GIM, phi) in float64 where cond2 < 1e4: agreement ~cond2 eps."""
    for n_links in (1, 2, 3):
        chain = random_chain(rng, n_links, (joint,), general_axes=False)
        q, qd, tau = random_state(rng, chain)
        gim = mass_matrix(chain, q)
        cond = np.linalg.cond(gim)
        assert cond < 1e4
        ref = hiprec.qdd_reference(chain, q, qd, tau)
        x = np.linalg.solve(gim, phi(chain, q, qd, tau))
        assert np.abs(x - ref).max() / np.abs(ref).max() < 10 * cond * np.finfo(float).eps


def test_planar_and_spatial_kernels_agree_in_mpmath():
    """The planar specialisation and the spatial kernel, both in mpmath, on a 60-link study
    chain at a random state: the same qdd to ~45 digits (two different kernels)."""
    chain = make_chain("R", 60)
    q, qd = make_state(chain, "R", 60, "random")
    spatial = hiprec.qdd_reference(chain, q, qd, output="mpf")
    with mpmath.workdps(50):
        planar = list(hiprec.planar_qdd(chain, q, qd, arith=hiprec.mpf_arithmetic(50)))
    assert mp_rel(planar, spatial) < 1e-40


def test_reference_has_its_digits_on_a_long_straight_chain():
    """dps = 50 against dps = 70 on 200 straight U-links (cond2 6e9): ~1e-46 apart, so the
    reference holds ~45 digits; anything below 1e-35 would do for a float64 study."""
    chain = make_chain("U", 200)
    q, qd = make_state(chain, "U", 200, "stretched")
    a = hiprec.qdd_reference(chain, q, qd, dps=50, output="mpf")
    b = hiprec.qdd_reference(chain, q, qd, dps=70, output="mpf")
    assert mp_rel(a, b) < 1e-35


def test_python_path_runs_the_compiled_kernel():
    """The rebound Python source in float64 gives the compiled kernel's qdd to rounding (not
    bit for bit: numba contracts a*b + c into FMAs), and float32 is really float32."""
    rng = np.random.default_rng(3)
    chain = random_chain(rng, 20, ("R", "U", "S", "P"))
    q, qd, tau = random_state(rng, chain, "straight")
    compiled = forward_dynamics(chain, q, qd, tau)
    py64 = hiprec.rge_a_qdd(chain, q, qd, tau, arith=hiprec.FLOAT64).astype(float)
    assert np.abs(py64 - compiled).max() / np.abs(compiled).max() < 1e-12
    py32 = hiprec.rge_a_qdd(chain, q, qd, tau, arith=hiprec.FLOAT32)
    assert py32.dtype == np.float32
    err32 = np.abs(py32 - compiled).max() / np.abs(compiled).max()
    assert 1e-9 < err32 < 1e-2


def test_double_double_round_trip():
    x = [mpmath.mpf(1) / 3, -mpmath.mpf(2) ** 0.5 * 1e-7, mpmath.mpf(0)]
    dd = hiprec.to_double_double(x)
    with mpmath.workdps(50):
        for (hi, lo), v in zip(dd, x, strict=True):
            assert abs(mpmath.mpf(hi) + mpmath.mpf(lo) - v) <= abs(v) * mpmath.mpf(2) ** -104
    rel2, relmax = hiprec.relative_errors(dd[:, 0], dd)
    assert rel2 < 1e-16 and relmax < 1e-16
    assert all(math.isnan(v) for v in hiprec.relative_errors([np.nan, 0.0, 1.0], dd))


# --------------------------------------------------------------------------- true errors
@pytest.fixture(scope="module")
def u200_random():
    chain = make_chain("U", 200)
    q, qd = make_state(chain, "U", 200, "random")
    return chain, q, qd, hiprec.qdd_reference(chain, q, qd, output="dd")


def test_core_rge_a_true_error_200_U_links(u200_random):
    """Core RGE-A on 200 RE-U rod links at a random state (cond2 1.1e9): measured 7.1e-15.

    Bound 1e-13 (~500 eps; the measured error grows to 4.4e-13 at 100,000 U-links, error
    study). Table A.1 as printed, with gravity and the velocity terms inside phi, is measured
    here at 2.9e-11 and grows ~n^2 eps (2.1e-9 at 1,000 straight links, 1.1e-6 at 10,000):
    phi_k carries the gravity moment of every outboard link (~(n - k)^2 m g l) and
    phihat_k = phi_k - P^T eta cancels it down to ~m g l. The assertion on it (> 1e-12) keeps
    the test able to tell the two formulations apart.
    """
    chain, q, qd, ref = u200_random
    rel2, relmax = hiprec.relative_errors(forward_dynamics(chain, q, qd), ref)
    assert rel2 < 1e-13 and relmax < 1e-13
    rel2_phi, _ = hiprec.relative_errors(rge_a_on_phi(chain, q, qd), ref)
    assert 1e-12 < rel2_phi < 1e-10


def test_literal_nonsymmetric_rge_a_fails_on_long_U_chains(u200_random):
    """The literal full-6x6 Table A.1 (Mhat_k as a full product, 2 x 2 Ihat inverted whole) loses
    every digit on 200 U-links at a random state (measured rel2 1.2; Mhat's relative asymmetry
    grows to O(1)), while the same code with Mhat_k re-symmetrised at each step stays at the
    core's 3e-11. Why: with Mhat non-symmetric, Mbar = Mhat - Psi Ihat^-1 Psi^T no longer
    annihilates P (P^T Mhat^T P != Ihat for a 2 x 2 Ihat), the left-over grows link by link.
    For 1-DOF joints (R chains) and at q = 0 (exact zeros keep Mhat symmetric) it stays accurate.
    """
    chain, q, qd, ref = u200_random
    lit, asym = literal_rge_a(chain, q, qd, return_asymmetry=True)
    rel2_lit, _ = hiprec.relative_errors(lit, ref)
    rel2_sym, _ = hiprec.relative_errors(literal_rge_a(chain, q, qd, resymmetrise=True), ref)
    assert rel2_lit > 1e-2 and asym > 1e-2
    assert rel2_sym < 1e-10


def test_literal_is_fine_with_one_dof_joints():
    chain = make_chain("R", 200)
    q, qd = make_state(chain, "R", 200, "random")
    ref = hiprec.qdd_reference(chain, q, qd, output="dd")
    rel2, _ = hiprec.relative_errors(literal_rge_a(chain, q, qd), ref)
    assert rel2 < 1e-10


def test_rebound_kernels_take_cos_and_sin_in_the_arithmetic():
    """jcalc's sincos is a plain helper, not a numba dispatcher: the high-precision source must
    still get mpmath's cos and sin (a float cos would cap the reference at double accuracy while
    its 50- vs 70-digit self-check still agreed)."""
    a = hiprec.mpf_arithmetic(50)
    body = hiprec.kernel_function("kinematics", a).__globals__["_kinematics"]  # (one source,
    sincos = body.__globals__["jcalc"].__globals__["sincos"]  # compiled for chains and trees)
    with mpmath.workdps(50):
        c, s = sincos(mpmath.mpf(1) / 3)
        assert isinstance(c, mpmath.mpf) and abs(c - mpmath.cos(mpmath.mpf(1) / 3)) < 1e-45
        assert abs(s - mpmath.sin(mpmath.mpf(1) / 3)) < 1e-45
