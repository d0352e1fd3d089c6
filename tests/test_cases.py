"""Every case file loads; computed initial shapes are what the paper describes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from redysim import CaseError, joint_positions, list_cases, load_case, load_published
from redysim.io.cases import CASES_DIR

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
    assert case.q0.shape == case.v0.shape == (case.chain.n_dof,)
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
    assert np.array_equal(case.v0, expected_qd)
    assert case.simulation["rtol"] == load_published()["conventions"]["rtol"]
    assert case.simulation["atol"] == load_published()["conventions"]["atol"]


@pytest.mark.parametrize("dX", [1.02, 0.765])
def test_catenary_initial_shape(dX):
    case = load_case(f"RE-R229-L1.02-DX{dX}")
    chain = case.chain
    assert chain.is_planar and chain.n_links == 229
    assert math.isclose(chain.total_mass, 0.0208, rel_tol=1e-12)
    if dX == 1.02:
        assert np.array_equal(case.q0, np.zeros(229))
    _check_on_one_catenary(chain, case.q0, dX)
    P = joint_positions(chain, case.q0)
    assert np.allclose(P[:, 1], P[::-1, 1], atol=1e-12)  # symmetric about the middle
    if dX != 1.02:
        assert P[:, 1].min() < -0.25  # sagging below the X axis
        # the catenary of the chain's own arc length, its joints at equal arc length (the
        # paper's wording; their chords are shorter than the links): within microns of ours
        u = _solve_u(1.02 / dX)
        a = dX / (2 * u)
        s = np.linspace(0, 1.02, 230)
        xs = dX / 2 + a * np.arcsinh(s / a - math.sinh(u))
        ys = a * np.cosh((xs - dX / 2) / a) - a * math.cosh(u)
        assert np.max(np.hypot(P[:, 0] - xs, P[:, 1] - ys)) < 1e-5


def _check_on_one_catenary(chain, q, dX):
    """The chain starts at (0, 0), ends exactly at (dX, 0), and every joint lies on one catenary
    y = a cosh((x - dX/2)/a) - a cosh(dX/(2a)) (a from the lowest joint, by bisection)."""
    P = joint_positions(chain, q)
    assert np.allclose(P[0], 0.0, atol=0)
    assert np.hypot(P[-1, 0] - dX, P[-1, 1]) < 1e-12
    if np.all(q == 0):
        return
    m = dX / 2

    def curve(x, a):
        return a * np.cosh((x - m) / a) - a * np.cosh(m / a)

    k = int(np.argmin(P[:, 1]))
    lo, hi = 1e-3 * dX, 1e3 * dX  # curve(x_k, a) falls as a shrinks (a deeper sag)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if curve(P[k, 0], mid) < P[k, 1] else (lo, mid)
    assert np.max(np.abs(curve(P[:, 0], lo) - P[:, 1])) < 1e-12 * max(1.0, dX)


@pytest.mark.parametrize("n_links", [2, 3, 4, 10, 57])
def test_a_catenary_start_of_any_number_of_links_spans_dX(n_links, tmp_path):
    """Few links hang on the catenary as exactly as many: the end at (dX, 0), every joint on the
    curve (equal arc-length placement, which the links' chords cannot follow, ended 37 mm short
    with 2 links)."""
    text = CATENARY.format(links=n_links, dX=0.6)
    case = load_case(_write(tmp_path, text))
    _check_on_one_catenary(case.chain, case.q0, 0.6)


def test_a_catenary_start_of_one_link_is_refused(tmp_path):
    path = _write(tmp_path, CATENARY.format(links=1, dX=0.6))
    with pytest.raises(CaseError, match=r"initial.dX = 0.6: .*one link"):
        load_case(path)
    assert np.array_equal(load_case(_write(tmp_path, CATENARY.format(links=1, dX=1.0))).q0, [0.0])


CATENARY = """
[case]
name = "catenary"
[chain]
links = {links}
total_length = 1.0
total_mass = 0.1
radius = 0.001
joint = "R"
[initial]
shape = "catenary"
dX = {dX}
[simulation]
t_end = 0.1
"""


def _write(tmp_path, text, name="case.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


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
    assert np.array_equal(case.v0, np.zeros(3))


def test_a_file_named_like_a_case_never_replaces_it(tmp_path, monkeypatch):
    """An extensionless file or a folder called STUDY-R3 in the working directory is not read
    in place of the built-in case (it was, silently, with the same run id); its path is."""
    monkeypatch.chdir(tmp_path)
    text = (CASES_DIR / "STUDY-R3.toml").read_text().replace("links = 3", "links = 4")
    (tmp_path / "STUDY-R3").write_text(text)
    assert load_case("STUDY-R3").chain.n_links == 3
    assert load_case("./STUDY-R3").chain.n_links == 4
    (tmp_path / "STUDY-R5").mkdir()
    assert load_case("STUDY-R5").chain.n_links == 5
    (tmp_path / "MINE").write_text(text)
    with pytest.raises(FileNotFoundError, match=r"no case named 'MINE'.*give its path, ./MINE"):
        load_case("MINE")


@pytest.mark.parametrize("bad, fragment", [(5, "must be a case name"), ("", "must not be empty"),
                                           ("   ", "must not be empty"), (None, "must be")])
def test_load_case_names_a_bad_argument(bad, fragment):
    with pytest.raises(CaseError, match=fragment) as err:
        load_case(bad)
    assert err.value.field == "name_or_path"


def test_a_folder_given_as_a_case_file_is_named(tmp_path):
    with pytest.raises(CaseError, match="is a folder, not a case file"):
        load_case(str(tmp_path) + "/")
