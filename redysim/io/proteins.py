"""Protein backbones: a polypeptide chain as a serial linkage of rigid groups turned by torsions.

The talk's protein chain (after Chirikjian, "Analysis and design of protein based nanodevices",
ASME J. Mech. Design 127, 2005): "a chain of miniature rigid bodies connected by revolute hinge
joints", hundreds of them, whose axes are neither parallel nor along the links. Bond lengths and
bond angles are held at their standard values; the torsions phi (about N-CA) and psi (about CA-C)
of every residue are R joints, and omega (about the peptide bond C-N) is held at 180 degrees
(trans, the peptide bond's partial double bond) or free (``omega = "free"``).

Atoms. Every residue has its backbone N, CA, C, O, the amide H on N (none on proline) and HA on
CA, each a point mass at its standard position; the side chain is one point mass at the CB
position (a united side chain: its whole mass, from its formula, at CB; glycine's is its second
HA). Masses from the IUPAC conventional atomic weights (H 1.008, C 12.011, N 14.007, O 15.999,
S 32.06); a residue's atoms then add up to its average residue mass (ExPASy's table, checked in
``tests/test_proteins.py``). The chain's ends are neutral: NH2 (a second H on the first N) and
COOH (OXT, the hydroxyl's H lumped into it).

Geometry (nm, degrees). Engh & Huber (Acta Cryst. A47, 392-400, 1991): N-CA 0.1458, CA-C 0.1525,
C-N 0.1329, C=O 0.1231, CA-CB 0.1530; N-CA-C 111.2, CA-C-N 116.2, C-N-CA 121.7, CA-C-O 120.1
(O in the peptide plane, opposite N), C-CA-CB 110.1. CB by the improper torsion N-C-CA-CB =
122.686 (L-amino acids; PeptideBuilder, Tien et al., PeerJ 2013); HA completes the tetrahedron at
CA (its direction minus the sum of the unit bonds to N, C and CB). N-H 0.101 in the peptide plane
bisecting C-N-CA's outer angle; CA-HA 0.109; OXT where the next residue's N would be, at C=O's
length. Atoms are placed by NeRF (natural extension reference frame: each atom from the three
before it by bond length, bond angle and torsion).

Bodies. Each atom belongs to the last joint that moves it; an atom on a joint's axis (which that
joint does not move) is put with the joint's body where that keeps every body's inertia positive
definite (three atoms not on a line), so every engine can build it:

    phi_i:   CA_i, HA_i, CB_i                        (axis N_i -> CA_i)
    psi_i:   C_i, O_i, N_i+1, H_i+1                  (axis CA_i -> C_i; omega fixed: the peptide
                                                      plane; the last residue: C, O, OXT)
    omega_i: H_i+1 (omega free; psi_i then keeps C_i, O_i, N_i+1; a one-atom body, which an engine
             that needs positive inertia refuses by name)

The first N and CA are the world's (a fixed base, ``floating = false``: phi_1 is the first joint)
or, floating, a free root body {N_1, its two H}. Body frames are parallel to the world's in the
extended chain (q = 0: every torsion at 180 degrees), each with its origin on its joint's axis;
q_k = torsion_k - 180 degrees, wrapped to (-180, 180]: a joint turning by +x turns its torsion by
+x (IUPAC's sign: clockwise looking along the axis).

Units: nm, u (g/mol), ps, so energies are kJ/mol (the units of GROMACS); no gravity. No force
field: the chain moves under its own inertia (a denatured chain's free torsional motion), which
conserves energy and, floating, momentum: the truths a run is checked against.

Protein files (TOML, ``cases/proteins/``)::

    [protein]
    name = "poly-ALA-100"
    description = "..."                 # optional, one line
    sequence = "A"                      # one-letter codes of the 20 residues
    residues = 100                      # optional: the sequence repeated to this many residues
    omega = "fixed"                     # or "free"
    floating = false                    # a free first residue
    conformation = "extended"           # or "alpha", "beta", "ppII", or [phi_deg, psi_deg]

Bad values raise :class:`~redysim.errors.CaseError` naming the file, the field and the value.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

import numpy as np

from redysim.errors import CaseError
from redysim.model.tree import FREE, Body, Model, TreeJoint

# --------------------------------------------------------------------------- constants
ATOMIC_WEIGHT = {"H": 1.008, "C": 12.011, "N": 14.007, "O": 15.999, "S": 32.06}  # IUPAC, u

# Side chains (the residue's atoms beyond N, H, CA, HA, C, O; proline has no amide H and its
# side chain C3H6 closes on N): formulas as {element: count}.
SIDE_CHAIN_FORMULA = {
    "G": {"H": 1}, "A": {"C": 1, "H": 3}, "S": {"C": 1, "H": 3, "O": 1},
    "C": {"C": 1, "H": 3, "S": 1}, "V": {"C": 3, "H": 7}, "T": {"C": 2, "H": 5, "O": 1},
    "L": {"C": 4, "H": 9}, "I": {"C": 4, "H": 9}, "N": {"C": 2, "H": 4, "N": 1, "O": 1},
    "D": {"C": 2, "H": 3, "O": 2}, "Q": {"C": 3, "H": 6, "N": 1, "O": 1},
    "E": {"C": 3, "H": 5, "O": 2}, "K": {"C": 4, "H": 10, "N": 1},
    "M": {"C": 3, "H": 7, "S": 1}, "H": {"C": 4, "H": 5, "N": 2}, "F": {"C": 7, "H": 7},
    "R": {"C": 4, "H": 10, "N": 3}, "Y": {"C": 7, "H": 7, "O": 1}, "W": {"C": 9, "H": 8, "N": 1},
    "P": {"C": 3, "H": 6},
}
RESIDUES = tuple(SIDE_CHAIN_FORMULA)

# Engh & Huber 1991 (nm); N-H and CA-HA as CHARMM's (0.101, 0.109 nm rounded)
BOND = {"N-CA": 0.1458, "CA-C": 0.1525, "C-N": 0.1329, "C-O": 0.1231, "CA-CB": 0.1530,
        "N-H": 0.1010, "CA-HA": 0.1090}
ANGLE_DEG = {"N-CA-C": 111.2, "CA-C-N": 116.2, "C-N-CA": 121.7, "CA-C-O": 120.1,
             "C-CA-CB": 110.1}
CB_IMPROPER_DEG = 122.686  # torsion N-C-CA-CB of an L-amino acid (PeptideBuilder)

# named conformations: (phi, psi) in degrees
CONFORMATIONS = {"extended": (180.0, 180.0), "alpha": (-57.0, -47.0), "beta": (-139.0, 135.0),
                 "ppII": (-75.0, 145.0)}
OMEGA = ("fixed", "free")
_FIELDS = {"name", "description", "sequence", "residues", "omega", "floating", "conformation"}


def _fail(source, field_name, value, problem) -> NoReturn:
    raise CaseError(source, field_name, value, problem)


def wrap_deg(x: float) -> float:
    """An angle in degrees wrapped to (-180, 180]."""
    y = math.fmod(x, 360.0)
    return y - 360.0 if y > 180.0 else y + 360.0 if y <= -180.0 else y


def formula_mass(formula: dict[str, int]) -> float:
    """The mass [u] of a formula {element: count} from :data:`ATOMIC_WEIGHT`."""
    return sum(ATOMIC_WEIGHT[e] * n for e, n in formula.items())


# --------------------------------------------------------------------------- geometry
def nerf(a, b, c, bond: float, angle_deg: float, torsion_deg: float) -> np.ndarray:
    """The atom d bonded to c at distance ``bond``, with angle b-c-d = ``angle_deg`` and torsion
    a-b-c-d = ``torsion_deg`` (natural extension reference frame)."""
    bc = c - b
    bc /= np.linalg.norm(bc)
    n = np.cross(b - a, bc)
    n /= np.linalg.norm(n)
    th, ch = math.radians(angle_deg), math.radians(torsion_deg)
    d2 = np.array([-bond * math.cos(th), bond * math.sin(th) * math.cos(ch),
                   bond * math.sin(th) * math.sin(ch)])
    return c + d2[0] * bc + d2[1] * np.cross(n, bc) + d2[2] * n


def dihedral(a, b, c, d) -> float:
    """The torsion a-b-c-d in degrees, (-180, 180] (IUPAC's sign)."""
    b0, b1, b2 = a - b, c - b, d - c
    b1 = b1 / np.linalg.norm(b1)
    v = b0 - (b0 @ b1) * b1
    w = b2 - (b2 @ b1) * b1
    return math.degrees(math.atan2(np.cross(b1, v) @ w, v @ w))


@dataclass(frozen=True)
class Atom:
    """One atom: its name (``CA``), residue (1-based), element, mass [u], the body it rides on
    (an index into the model's bodies, -1 for the world) and its position in that body's frame
    [nm]."""

    name: str
    residue: int
    mass: float
    body: int
    point: tuple[float, float, float]


@dataclass(frozen=True)
class Protein:
    """A backbone: its model, sequence, atoms, and the q of its file's conformation."""

    model: Model
    sequence: str
    omega: str
    floating: bool
    atoms: tuple[Atom, ...]
    conformation: tuple[float, float]

    def atom_positions(self, q) -> np.ndarray:
        """(n_atoms, 3) world positions [nm] at configuration ``q``."""
        from redysim.algorithms.rbda import kinematics

        kin = kinematics(self.model, q, np.zeros(self.model.n_v))
        out = np.empty((len(self.atoms), 3))
        for i, a in enumerate(self.atoms):
            out[i] = a.point if a.body < 0 else kin.O[a.body] + kin.R[a.body] @ a.point
        return out


def _extended_atoms(sequence: str, floating: bool) -> list[tuple[str, int, float, str, np.ndarray]]:
    """Every atom of the extended chain (all torsions 180 degrees) as (name, residue, mass, the
    joint group it moves with, position): groups ``root``, ``phi{i}``, ``psi{i}``, ``omega{i}``
    (the omega group is H_i+1, which moves with psi_i when omega is fixed)."""
    W = ATOMIC_WEIGHT
    atoms: list[tuple[str, int, float, str, np.ndarray]] = []
    N = np.zeros(3)
    CA = np.array([BOND["N-CA"], 0.0, 0.0])
    th = math.radians(ANGLE_DEG["N-CA-C"])
    C = CA + BOND["CA-C"] * np.array([-math.cos(th), math.sin(th), 0.0])
    n_res = len(sequence)
    prev_C = None
    for r in range(n_res):
        i = r + 1
        aa = sequence[r]
        # the amide H (none on proline), in the peptide plane bisecting C-N-CA's outer angle
        h_angle = (360.0 - ANGLE_DEG["C-N-CA"]) / 2.0
        if r == 0:  # N-terminus: NH2, both H on the root (or the world)
            nh_mass = 0.0 if aa == "P" else W["H"]
            atoms.append((f"N{i}", i, W["N"], "root", N))
            for k, tor in enumerate((0.0, 180.0)):
                if aa == "P" and k == 0:
                    continue
                atoms.append((f"H{i}" + "ab"[k], i, W["H"], "root",
                              nerf(C, CA, N, BOND["N-H"], h_angle, tor)))
            del nh_mass
        else:
            assert prev_C is not None
            atoms.append((f"N{i}", i, W["N"], f"psi{i - 1}", N))
            if aa != "P":
                atoms.append((f"H{i}", i, W["H"], f"omega{i - 1}",
                              nerf(CA, prev_C, N, BOND["N-H"], h_angle, 180.0)))
        # CA and its substituents turn with phi_i
        CB = nerf(N, C, CA, BOND["CA-CB"] if aa != "G" else BOND["CA-HA"],
                  ANGLE_DEG["C-CA-CB"], CB_IMPROPER_DEG)
        u = [(x - CA) / np.linalg.norm(x - CA) for x in (N, C, CB)]
        ha = -(u[0] + u[1] + u[2])
        HA = CA + BOND["CA-HA"] * ha / np.linalg.norm(ha)
        atoms.append((f"CA{i}", i, W["C"], f"phi{i}", CA))
        atoms.append((f"HA{i}", i, W["H"], f"phi{i}", HA))
        atoms.append((f"SC{i}", i, formula_mass(SIDE_CHAIN_FORMULA[aa]), f"phi{i}", CB))
        # C, O (and the next N, or OXT) turn with psi_i
        N_next = nerf(N, CA, C, BOND["C-N"], ANGLE_DEG["CA-C-N"], 180.0)
        O = nerf(N_next, CA, C, BOND["C-O"], ANGLE_DEG["CA-C-O"], 180.0)
        atoms.append((f"C{i}", i, W["C"], f"psi{i}", C))
        atoms.append((f"O{i}", i, W["O"], f"psi{i}", O))
        if r == n_res - 1:  # C-terminus: COOH, the hydroxyl's H lumped into OXT
            OXT = C + BOND["C-O"] * (N_next - C) / np.linalg.norm(N_next - C)
            atoms.append((f"OXT{i}", i, W["O"] + W["H"], f"psi{i}", OXT))
            break
        CA_next = nerf(CA, C, N_next, BOND["N-CA"], ANGLE_DEG["C-N-CA"], 180.0)
        C_next = nerf(C, N_next, CA_next, BOND["CA-C"], ANGLE_DEG["N-CA-C"], 180.0)
        prev_C, N, CA, C = C, N_next, CA_next, C_next
    if not floating:
        atoms = [(n, r, m, "world" if g == "root" else g, p) for n, r, m, g, p in atoms]
    return atoms


def backbone(sequence: str, *, omega: str = "fixed", floating: bool = False,
             conformation: str | Sequence[float] = "extended", name: str | None = None,
             source: str = "backbone") -> Protein:
    """The backbone of ``sequence`` (one-letter codes, :data:`RESIDUES`) as a :class:`Protein`
    (module doc). ``conformation``: a name of :data:`CONFORMATIONS` or (phi, psi) in degrees, for
    every residue: the configuration the model's ``initial_q`` holds (omega at 180 degrees)."""
    if not isinstance(sequence, str) or not sequence:
        _fail(source, "sequence", sequence, "must be a non-empty string of one-letter residue "
              f"codes ({''.join(RESIDUES)})")
    bad = sorted({c for c in sequence if c not in SIDE_CHAIN_FORMULA})
    if bad:
        _fail(source, "sequence", "".join(bad), f"unknown residue code(s); known: "
              f"{''.join(RESIDUES)}")
    if omega not in OMEGA:
        _fail(source, "omega", omega, "must be 'fixed' (trans, 180 degrees) or 'free'")
    if not isinstance(floating, bool):
        _fail(source, "floating", floating, "must be true or false")
    if isinstance(conformation, str):
        if conformation not in CONFORMATIONS:
            _fail(source, "conformation", conformation,
                  f"unknown; known: {', '.join(CONFORMATIONS)}, or [phi_deg, psi_deg]")
        phi_psi = CONFORMATIONS[conformation]
    else:
        arr = np.asarray(conformation, dtype=object)
        ok = arr.shape == (2,) and all(isinstance(x, int | float) and not isinstance(x, bool)
                                       and math.isfinite(x) for x in arr)
        if not ok:
            _fail(source, "conformation", conformation, "must be a name or [phi_deg, psi_deg]")
        phi_psi = (float(conformation[0]), float(conformation[1]))
    atoms = _extended_atoms(sequence, floating)
    groups = ["root"] if floating else []
    for r in range(len(sequence)):
        i = r + 1
        groups.append(f"phi{i}")
        groups.append(f"psi{i}")
        if omega == "free" and r < len(sequence) - 1:
            groups.append(f"omega{i}")
    if omega == "fixed":  # the amide H rides on the peptide plane
        atoms = [(n, r, m, "psi" + g[5:] if g.startswith("omega") else g, p)
                 for n, r, m, g, p in atoms]
    index = {g: k for k, g in enumerate(groups)}
    pos = {a[0]: a[4] for a in atoms}

    def axis_of(g: str) -> tuple[np.ndarray, np.ndarray]:
        i = int(g.lstrip("phisomega"))
        a, b = {"phi": (f"N{i}", f"CA{i}"), "psi": (f"CA{i}", f"C{i}"),
                "omega": (f"C{i}", f"N{i + 1}")}[g.rstrip("0123456789")]
        u = pos[b] - pos[a]
        return pos[b] if g.startswith("phi") else pos[a], u / np.linalg.norm(u)

    origins = [np.zeros(3) if g == "root" else axis_of(g)[0] for g in groups]
    bodies, joints, parents = [], [], []
    members: dict[str, list[int]] = {g: [] for g in groups}
    for k, a in enumerate(atoms):
        if a[3] != "world":
            members[a[3]].append(k)
    for k, g in enumerate(groups):
        ms = np.array([atoms[j][2] for j in members[g]])
        ps = np.array([atoms[j][4] for j in members[g]]) - origins[k]
        m = float(ms.sum())
        c = (ms[:, None] * ps).sum(axis=0) / m if m > 0 else np.zeros(3)
        d = ps - c
        inertia = (ms[:, None, None] * ((d * d).sum(axis=1)[:, None, None] * np.eye(3)
                                        - np.einsum("ki,kj->kij", d, d))).sum(axis=0)
        bodies.append(Body(g, m, tuple(c), tuple(map(tuple, inertia))))
        parent = k - 1
        if g == "root":
            joints.append(TreeJoint("root", FREE))
        else:
            joints.append(TreeJoint(g, "R", tuple(axis_of(g)[1]),
                                    translation=tuple(origins[k] - (origins[parent]
                                                                    if parent >= 0 else 0.0))))
        parents.append(parent)
    frames = {a[0]: (index[a[3]], tuple(a[4] - origins[index[a[3]]]))
              for a in atoms if a[0].startswith("CA") and a[3] != "world"}
    n_res = len(sequence)
    label = name or f"backbone-{n_res}"
    model = Model.build(bodies, joints, parents, gravity=(0.0, 0.0, 0.0), name=label,
                        frames=frames, source=source)
    notes = ["each side chain is one point mass at its CB atom (a united side chain)",
             "no force field: bond lengths and angles are rigid, torsions move freely"]
    if "P" in sequence:
        notes.append("proline: the ring's closure on N, which holds phi near -63 degrees, is "
                     "not modelled (phi moves freely)")
    q0 = model.neutral()
    for g, k in index.items():
        if g == "root":
            continue
        kind = g.rstrip("0123456789")
        value = {"phi": phi_psi[0], "psi": phi_psi[1], "omega": 180.0}[kind]
        q0[model.joint_qoff[k]] = math.radians(wrap_deg(value - 180.0))
    model = dataclasses.replace(model, notes=tuple(notes))
    object.__setattr__(model, "initial_q", q0)
    out_atoms = tuple(Atom(n, r, float(m), -1 if g == "world" else index[g],
                           tuple(p if g == "world" else p - origins[index[g]]))
                      for n, r, m, g, p in atoms)
    return Protein(model, sequence, omega, floating, out_atoms, phi_psi)


# --------------------------------------------------------------------------- files
def load_protein(path: str | os.PathLike, *, floating: bool | None = None) -> Protein:
    """The backbone of a protein file (module doc); ``floating``, when given, overrides the
    file's."""
    from redysim.io.cases import read_toml

    path = Path(path)
    src = str(path)
    doc = read_toml(path)[0]
    for key in doc:
        if key != "protein":
            _fail(src, key, doc[key], "unknown table; a protein file has [protein] only")
    p = doc.get("protein")
    if not isinstance(p, dict):
        _fail(src, "protein", p, "[protein] must be a table")
    for key in p:
        if key not in _FIELDS:
            _fail(src, f"protein.{key}", p[key],
                  f"unknown field; expected one of {', '.join(sorted(_FIELDS))}")
    seq = p.get("sequence")
    if not isinstance(seq, str) or not seq:
        _fail(src, "protein.sequence", seq, "missing or empty: one-letter residue codes")
    n = p.get("residues")
    if n is not None:
        if isinstance(n, bool) or not isinstance(n, int) or n < 1:
            _fail(src, "protein.residues", n, "must be a whole number >= 1 (the sequence "
                  "repeated to this length)")
        seq = (seq * (n // len(seq) + 1))[:n]
    for key, kind in (("name", str), ("description", str), ("omega", str), ("floating", bool)):
        if key in p and not isinstance(p[key], kind):
            _fail(src, f"protein.{key}", p[key], f"must be a {kind.__name__}")
    try:
        return backbone(seq, omega=p.get("omega", "fixed"),
                        floating=p.get("floating", False) if floating is None else floating,
                        conformation=p.get("conformation", "extended"),
                        name=p.get("name", path.stem), source=src)
    except CaseError as e:
        if e.field.startswith("protein."):
            raise
        raise CaseError(src, f"protein.{e.field}", e.value, e.problem) from None
