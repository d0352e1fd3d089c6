"""Protein backbones (redysim.io.proteins): the geometry against the standard values it is built
from, the chirality against an independent construction of CB, the masses against the published
residue masses, the torsion convention, the 50-digit reference against an independent dense
solve, the conservation laws of a free run, the loader's refusals, and every engine on the
same backbone."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import redysim
from redysim.errors import CaseError
from redysim.io.cases import CASES_DIR
from redysim.io.kinds import kind_of
from redysim.io.proteins import (
    ANGLE_DEG,
    BOND,
    CONFORMATIONS,
    RESIDUES,
    backbone,
    dihedral,
    load_protein,
    wrap_deg,
)

PROTEINS = Path(CASES_DIR) / "proteins"

# Average residue masses [u] (residue = amino acid - H2O), ExPASy's "Amino acid residue masses"
# table (average isotopic composition): an independent source for the side-chain formulas.
EXPASY_RESIDUE_MASS = {
    "G": 57.0519, "A": 71.0788, "S": 87.0782, "P": 97.1167, "V": 99.1326, "T": 101.1051,
    "C": 103.1388, "L": 113.1594, "I": 113.1594, "N": 114.1038, "D": 115.0886, "Q": 128.1307,
    "K": 128.1741, "E": 129.1155, "M": 131.1926, "H": 137.1411, "F": 147.1766, "R": 156.1875,
    "Y": 163.1760, "W": 186.2132,
}


def _positions(p, q):
    return dict(zip((a.name for a in p.atoms), p.atom_positions(q), strict=True))


def _torsions(p, q):
    """(phi, psi, omega) of every residue from the atoms' positions (None at the ends)."""
    P, n = _positions(p, q), len(p.sequence)
    out = []
    for i in range(1, n + 1):
        phi = dihedral(P[f"C{i - 1}"], P[f"N{i}"], P[f"CA{i}"], P[f"C{i}"]) if i > 1 else None
        psi = omega = None
        if i < n:
            psi = dihedral(P[f"N{i}"], P[f"CA{i}"], P[f"C{i}"], P[f"N{i + 1}"])
            omega = dihedral(P[f"CA{i}"], P[f"C{i}"], P[f"N{i + 1}"], P[f"CA{i + 1}"])
        out.append((phi, psi, omega))
    return out


def _angle(a, b, c):
    u, v = a - b, c - b
    return math.degrees(math.acos(u @ v / np.linalg.norm(u) / np.linalg.norm(v)))


@pytest.fixture(scope="module")
def mixed():
    return backbone("MGSPWDKA", conformation="alpha")


def test_bonds_and_angles_stay_standard_at_any_configuration(mixed):
    """The joints turn torsions only: at a random configuration every bond length and bond
    angle of the backbone equals Engh & Huber's value."""
    q = np.random.default_rng(7).uniform(-math.pi, math.pi, mixed.model.n_q)
    P, n = _positions(mixed, q), len(mixed.sequence)
    for i in range(1, n + 1):
        assert np.linalg.norm(P[f"CA{i}"] - P[f"N{i}"]) == pytest.approx(BOND["N-CA"], abs=1e-12)
        assert np.linalg.norm(P[f"C{i}"] - P[f"CA{i}"]) == pytest.approx(BOND["CA-C"], abs=1e-12)
        assert np.linalg.norm(P[f"O{i}"] - P[f"C{i}"]) == pytest.approx(BOND["C-O"], abs=1e-12)
        assert _angle(P[f"N{i}"], P[f"CA{i}"], P[f"C{i}"]) == pytest.approx(
            ANGLE_DEG["N-CA-C"], abs=1e-9)
        if i < n:
            assert np.linalg.norm(P[f"N{i + 1}"] - P[f"C{i}"]) == pytest.approx(BOND["C-N"],
                                                                                abs=1e-12)
            assert _angle(P[f"CA{i}"], P[f"C{i}"], P[f"N{i + 1}"]) == pytest.approx(
                ANGLE_DEG["CA-C-N"], abs=1e-9)
            assert _angle(P[f"C{i}"], P[f"N{i + 1}"], P[f"CA{i + 1}"]) == pytest.approx(
                ANGLE_DEG["C-N-CA"], abs=1e-9)
            assert _angle(P[f"CA{i}"], P[f"C{i}"], P[f"O{i}"]) == pytest.approx(
                ANGLE_DEG["CA-C-O"], abs=1e-9)


def test_a_joint_turns_its_torsion_by_its_own_angle(mixed):
    """q_k = torsion_k - 180 degrees (IUPAC's sign): the model's initial configuration gives
    the named conformation, and each joint's +x adds x to its torsion and to no other."""
    m = mixed.model
    phi0, psi0 = CONFORMATIONS["alpha"]
    for i, (phi, psi, omega) in enumerate(_torsions(mixed, m.initial()), start=1):
        if phi is not None:
            assert wrap_deg(phi - phi0) == pytest.approx(0.0, abs=1e-9), i
        if psi is not None:
            assert wrap_deg(psi - psi0) == pytest.approx(0.0, abs=1e-9), i
            assert abs(wrap_deg(omega - 180.0)) < 1e-9, i
    base = _torsions(mixed, np.zeros(m.n_q))
    for k, name in enumerate(m.joint_names):
        q = np.zeros(m.n_q)
        q[k] = 0.3
        turned = _torsions(mixed, q)
        kind, i = name.rstrip("0123456789"), int(name.lstrip("phisomega"))
        col = ("phi", "psi", "omega").index(kind)
        for r, (a, b) in enumerate(zip(base, turned, strict=True), start=1):
            for c in range(3):
                if a[c] is None:
                    continue
                want = math.degrees(0.3) if (r, c) == (i, col) else 0.0
                assert wrap_deg(b[c] - a[c]) == pytest.approx(want, abs=1e-9), (name, r, c)


def test_cb_is_where_an_l_amino_acid_has_it(mixed):
    """CB against trRosetta's ideal-CB construction (Yang et al., PNAS 2020: -0.58273431 a +
    0.56802827 b - 0.54067466 c + CA, b = CA - N, c = C - CA, a = b x c; Angstrom-fitted
    coefficients, so a direction check): the same side, i.e. L chirality."""
    P = _positions(mixed, mixed.model.initial())
    for i, aa in enumerate(mixed.sequence, start=1):
        if aa == "G":
            continue
        b, c = 10.0 * (P[f"CA{i}"] - P[f"N{i}"]), 10.0 * (P[f"C{i}"] - P[f"CA{i}"])  # A
        ideal = -0.58273431 * np.cross(b, c) + 0.56802827 * b - 0.54067466 * c
        ours = P[f"SC{i}"] - P[f"CA{i}"]
        assert ours @ ideal / np.linalg.norm(ours) / np.linalg.norm(ideal) > 0.99, aa


@pytest.mark.parametrize("aa", RESIDUES)
def test_each_residue_weighs_its_published_mass(aa):
    """A middle residue's atoms (N, H, CA, HA, side chain, C, O) add up to ExPASy's average
    residue mass (the small difference: IUPAC's current atomic weights against older ones)."""
    p = backbone(f"G{aa}G")
    assert sum(a.mass for a in p.atoms if a.residue == 2) == pytest.approx(
        EXPASY_RESIDUE_MASS[aa], abs=0.01)


def test_ubiquitin_weighs_what_it_is_known_to():
    """Human ubiquitin (P0CG48, residues 1-76): the atoms, termini included, weigh its average
    mass, 8,564.8 Da (the residues above plus one water)."""
    p = load_protein(PROTEINS / "ubiquitin.toml")
    assert len(p.sequence) == 76
    assert sum(a.mass for a in p.atoms) == pytest.approx(
        sum(EXPASY_RESIDUE_MASS[c] for c in p.sequence) + 18.0153, abs=0.5)
    assert sum(a.mass for a in p.atoms) == pytest.approx(8564.8, abs=1.0)
    assert p.model.quaternions.size == 1 and p.model.n_v == 6 + 2 * 76  # one free joint
    assert any("proline" in n for n in p.model.notes)


def test_every_body_has_a_positive_definite_inertia():
    """Omega held: every body is three or more atoms off a line (what MuJoCo and Drake need to
    build it); omega free leaves the amide H alone on its body, whose inertia is zero."""
    for floating in (False, True):
        m = backbone("AGPW" * 3, floating=floating).model
        assert np.linalg.eigvalsh(m.inertia_com).min() > 1e-4
    free = backbone("AGAW", omega="free").model
    assert free.n_v == 4 * 2 + 3
    assert np.linalg.eigvalsh(free.inertia_com).min() < 1e-12


def test_the_50_digit_reference_takes_a_backbone():
    """hiprec's O(n) reference (the core's kernel in mpmath) against its independent dense
    Newton-Euler solve, on a backbone (a serial model with general placements and axes), and
    the core's float64 qdd against it."""
    from redysim.harness import hiprec

    m = backbone("AGSWDP", conformation="beta").model
    rng = np.random.default_rng(3)
    q = rng.uniform(-math.pi, math.pi, m.n_q)
    v, tau = rng.normal(0.0, 0.5, m.n_v), rng.normal(0.0, 1.0, m.n_v)
    ref = hiprec.qdd_reference(m, q, v, tau, output="mpf")
    dense = hiprec.dense_reference(m, q, v, tau)
    assert max(abs(a - b) for a, b in zip(ref, dense, strict=True)) < 1e-40 * max(map(abs, ref))
    got = redysim.forward_dynamics(m, q, v, tau)
    want = np.array([float(x) for x in ref])
    assert np.abs(got - want).max() < 1e-12 * np.abs(want).max()


def test_a_free_backbone_keeps_its_energy_and_momentum():
    """No force field, no gravity, floating: energy, linear momentum and the angular momentum
    about the centre of mass stay at their initial values over a run."""
    m = backbone("MQIFVKTLTG", floating=True, conformation="ppII").model
    rng = np.random.default_rng(11)
    v0 = rng.uniform(-0.3, 0.3, m.n_v)
    sim = redysim.simulate(m, 1.0, v0=v0, rtol=1e-10, atol=1e-12)
    assert sim.status == 0
    E0 = sum(redysim.energy(m, m.initial(), v0))
    E1 = sum(redysim.energy(m, sim.q[-1], sim.v[-1]))
    assert abs(E1 - E0) < 1e-8 * E0
    h0, h1 = redysim.momentum(m, m.initial(), v0), redysim.momentum(m, sim.q[-1], sim.v[-1])
    assert np.abs(h1.linear - h0.linear).max() < 1e-9 * np.abs(h0.linear).max()
    assert np.abs(h1.angular - h0.angular).max() < 1e-8 * np.abs(h0.angular).max()


def test_the_shipped_files_load_as_their_headers_say():
    for name, n_res, floating in (("poly-ala-100", 100, False), ("poly-ala-1000", 1000, False),
                                  ("ubiquitin", 76, True)):
        path = PROTEINS / f"{name}.toml"
        assert kind_of(path).name == "protein"
        m = redysim.load_model(path)
        assert m.n_v == 2 * n_res + (6 if floating else 0)
        assert m.gravity.tolist() == [0.0, 0.0, 0.0]
    assert redysim.load_model(PROTEINS / "poly-ala-100.toml", floating=True).n_v == 206


@pytest.mark.parametrize("text, field, value", [
    ('sequence = "AXA"', "protein.sequence", "X"),
    ('sequence = "A"\nresidues = 0', "protein.residues", 0),
    ('sequence = "A"\nomega = "cis"', "protein.omega", "cis"),
    ('sequence = "A"\nconformation = "helix"', "protein.conformation", "helix"),
    ('sequence = "A"\nconformation = [1.0]', "protein.conformation", [1.0]),
    ('sequence = "A"\nfloating = "yes"', "protein.floating", "yes"),
    ('sequence = "A"\ncharge = 1', "protein.charge", 1),
    ('sequence = ""', "protein.sequence", ""),
])
def test_bad_protein_files_are_refused_by_field(tmp_path, text, field, value):
    path = tmp_path / "bad.toml"
    path.write_text(f"[protein]\n{text}\n")
    with pytest.raises(CaseError) as e:
        redysim.load_model(path)
    assert e.value.source == str(path) and e.value.field == field and e.value.value == value
