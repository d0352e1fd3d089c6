"""Every case file loads; computed initial shapes are what the paper describes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from redysim import joint_positions, list_cases, load_case, load_published

ALL = list_cases()


def test_every_paper_case_is_there():
    expected = {"RE-R229-L1.02-DX1.02", "RE-R229-L1.02-DX0.765", "STUDY-R3-TABLE9"}
    expected |= {f"RE-U{n}-L{L}" for n, L in [(125, 1), (250, 2), (375, 3), (750, 6), (1250, 10),
                                              (3750, 30), (5000, 100), (7500, 150),
                                              (10000, 200), (15000, 300), (50000, 1000)]}
    expected |= {f"STUDY-R{n}" for n in (3, 5, 10, 20, 40, 60, 80, 100)}
    assert expected <= set(ALL)


@pytest.mark.parametrize("name", ALL)
def test_case_loads_and_refers_to_published_entries(name):
    case = load_case(name)
    assert case.q0.shape == case.qd0.shape == (case.chain.n_dof,)
    assert case.t_end > 0
    assert case.paper_tables, "every case names the published.toml entry it is compared with"
    assert case.published()


@pytest.mark.parametrize("name", [n for n in ALL if n.startswith("RE-U")])
def test_reu_cases_match_their_names_and_the_paper(name):
    case = load_case(name)
    n_links, L = (int(x[1:]) for x in name.split("-")[1:])
    chain = case.chain
    assert chain.n_links == n_links and chain.n_dof == 2 * n_links
    assert math.isclose(chain.length.sum(), L, rel_tol=1e-12)
    rho_l = chain.mass / chain.length
    assert np.allclose(rho_l, 7850 * math.pi * 0.05**2, rtol=1e-12)  # 61.6538 kg/m
    # rod inertia: transverse m l^2 / 12 about the COM
    assert np.allclose(chain.inertia_com[:, 1, 1], chain.mass * chain.length**2 / 12)
    assert np.array_equal(case.q0, np.zeros(chain.n_dof))
    expected_qd = np.zeros(chain.n_dof)
    expected_qd[0] = 1.0  # joint 1's first (y) rate
    assert np.array_equal(case.qd0, expected_qd)
    assert case.simulation["rtol"] == load_published()["conventions"]["rtol"]
    assert case.simulation["atol"] == load_published()["conventions"]["atol"]


@pytest.mark.parametrize("dX", [1.02, 0.765])
def test_catenary_initial_shape(dX):
    case = load_case(f"RE-R229-L1.02-DX{dX}")
    chain = case.chain
    assert chain.is_planar and chain.n_links == 229
    assert math.isclose(chain.total_mass, 0.0208, rel_tol=1e-12)
    P = joint_positions(chain, case.q0)
    assert np.allclose(P[0], 0.0)
    # the far end is at (dX, 0) up to the chord-vs-arc shortening of 229 links (a few microns)
    assert np.hypot(P[-1, 0] - dX, P[-1, 1]) < 1e-5
    if dX == 1.02:
        assert np.array_equal(case.q0, np.zeros(229))
        return
    # every joint lies on the catenary y = a cosh((x - dX/2)/a) - a cosh(dX/(2a)) with arc 1.02
    u = _solve_u(1.02 / dX)
    a = dX / (2 * u)
    # Links keep their length l while following chords (slightly shorter than l), so joints drift
    # off the curve by at most the summed chord deficit sum(l - chord): bound them by it.
    s = np.linspace(0, 1.02, 230)
    xs = dX / 2 + a * np.arcsinh(s / a - math.sinh(u))
    ys = a * np.cosh((xs - dX / 2) / a) - a * math.cosh(u)
    deficit = np.sum(1.02 / 229 - np.hypot(np.diff(xs), np.diff(ys)))
    assert 0 < deficit < 1e-5
    assert np.max(np.hypot(P[:, 0] - xs, P[:, 1] - ys)) <= 2 * deficit
    # symmetric about the middle, sagging below the X axis
    assert np.allclose(P[:, 1], P[::-1, 1], atol=1e-5)
    assert P[:, 1].min() < -0.25


def _solve_u(ratio):
    """sinh(u)/u = ratio by bisection (independent of the code's brentq)."""
    lo, hi = 1e-9, 20.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if math.sinh(mid) / mid < ratio else (lo, mid)
    return 0.5 * (lo + hi)


def test_table9_state():
    case = load_case("STUDY-R3-TABLE9")
    np.testing.assert_allclose(case.q0, [math.pi / 3, 0, 0], rtol=1e-15)
    assert np.array_equal(case.qd0, np.zeros(3))
