"""Seeded random chains and states for engine-versus-core comparisons.

Shared by the engine agreement tests (``tests/test_engines_agreement.py``, through
``tests/engine_chains.py``) and the accuracy gates (:mod:`redysim.harness.gates`), so that both
compare the engines on exactly the same chains and states. Links have random lengths, masses,
off-axis centres of mass and rotated full inertias that satisfy the triangle inequality (MuJoCo
checks it). The joints come in families (:data:`FAMILIES`), every one a chain each reference
adapter builds:

============  ===================================================================================
``R``         every joint R about +z (planar chains); gravity (0, -9.81, 0)
``U``         every joint U = Ry Rz; gravity (0, -9.81, 0)
``R-z``       every joint R about -z: the mirror image of an R chain, which the core once turned
              the +z way (an engine that did the same would be off by O(1))
``Rneg``      R about -x, -y or -z, drawn per joint (each at least once from 3 links on)
``Rxy``       R about exactly +x or +y (named "x", "y"), drawn per joint (each from 2 links on)
``Rgen``      R about a general direction (a normal draw; the core makes it a unit vector)
``P``         P along +x, +y or +z, along -x, -y or -z, or along a general direction, drawn
              per joint (each of the three kinds at least once from 3 links on)
``S``         every joint S = Ry Rz Rx
``mix``       R and P about/along +e, -e or general axes, U and S, mixed (each of these 8 kinds
              at least once in a chain of 8 links or more)
============  ===================================================================================

The families after R and U have a tilted gravity of 9.81 m/s^2 (a random direction near -Y), so
that the engines' gravity vector is tested off the axis too. The R and U chains are exactly those
of the first version (same seeds, same draws: the joints and gravity of the other families are
drawn after the links), so the numbers measured on them hold.
"""

from __future__ import annotations

import numpy as np

import redysim

STATE_KINDS = ("spread", "straight")
FAMILIES = ("R", "U", "R-z", "Rneg", "Rxy", "Rgen", "P", "S", "mix")
MIX_KINDS = ("R+", "R-", "Rgen", "P+", "P-", "Pgen", "U", "S")


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


def _cover(rng: np.random.Generator, options: tuple, n: int) -> list:
    """n draws from ``options``: a permutation of all of them first (so a chain of at least
    len(options) links has each), then uniform draws."""
    first = [options[int(i)] for i in rng.permutation(len(options))]
    return [first[k] if k < len(first) else options[int(rng.integers(len(options)))]
            for k in range(n)]


def _axis(rng: np.random.Generator, how: str):
    """An axis for R or P: "+x", "+y", "+z" the coordinate's name, "-x", "-y", "-z" the negative
    coordinate vector, "+" or "-" one of those drawn, "gen" a general direction (three normal
    draws, not normalised: the core makes it a unit vector)."""
    if how in ("+", "-"):
        how += "xyz"[int(rng.integers(3))]
    if how[0] == "+":
        return how[1]
    if how[0] == "-":
        v = [0.0, 0.0, 0.0]
        v["xyz".index(how[1])] = -1.0
        return tuple(v)
    return tuple(float(x) for x in rng.normal(size=3))


def _mix_joint(rng: np.random.Generator, kind: str) -> redysim.Joint:
    if kind in ("U", "S"):
        return redysim.Joint(kind)
    how = {"R+": "+", "R-": "-", "P+": "+", "P-": "-"}.get(kind, "gen")
    return redysim.Joint(kind[0], _axis(rng, how))


def random_joints(rng: np.random.Generator, family: str, n_links: int) -> list:
    """The joints of a chain of the given family (see the module docstring)."""
    if family in ("R", "U", "S"):
        return [family] * n_links
    if family == "R-z":
        return [redysim.Joint("R", (0.0, 0.0, -1.0))] * n_links
    if family == "Rneg":
        return [redysim.Joint("R", _axis(rng, how))
                for how in _cover(rng, ("-x", "-y", "-z"), n_links)]
    if family == "Rxy":
        return [redysim.Joint("R", _axis(rng, how)) for how in _cover(rng, ("+x", "+y"), n_links)]
    if family == "Rgen":
        return [redysim.Joint("R", _axis(rng, "gen")) for _ in range(n_links)]
    if family == "P":
        return [redysim.Joint("P", _axis(rng, how))
                for how in _cover(rng, ("+", "-", "gen"), n_links)]
    if family == "mix":
        return [_mix_joint(rng, kind) for kind in _cover(rng, MIX_KINDS, n_links)]
    raise ValueError(f"family = {family!r}: choose one of {', '.join(FAMILIES)}")


def random_chain(joint: str, n_links: int, seed: int) -> redysim.Chain:
    """``n_links`` random links with joints of the family ``joint`` (one of :data:`FAMILIES`;
    "R" and "U": every joint of that type, as in the first version)."""
    if joint not in FAMILIES:
        raise ValueError(f"joint = {joint!r}: choose one of {', '.join(FAMILIES)}")
    rng = np.random.default_rng(seed)
    links = [random_link(rng) for _ in range(n_links)]
    joints = random_joints(rng, joint, n_links)
    if joint in ("R", "U"):
        return redysim.Chain.build(links, joints, name=f"rand-{joint}{n_links}")
    tilt = np.array([0.0, -1.0, 0.0]) + 0.3 * rng.normal(size=3)
    gravity = 9.81 * tilt / np.linalg.norm(tilt)
    return redysim.Chain.build(links, joints, gravity=tuple(float(g) for g in gravity),
                               name=f"rand-{joint}{n_links}")


def engine_test_chain(joint: str, n_links: int) -> redysim.Chain:
    """The chain the engine agreement tests use for (family, n_links): seed n_links plus 1000
    times the family's place in :data:`FAMILIES` (n_links for R chains, n_links + 1000 for U)."""
    if joint not in FAMILIES:
        raise ValueError(f"joint = {joint!r}: choose one of {', '.join(FAMILIES)}")
    return random_chain(joint, n_links, seed=n_links + 1000 * FAMILIES.index(joint))


def random_state(model: redysim.Model, kind: str, seed: int):
    """(q, v, tau): ``spread`` draws q uniformly in (-pi, pi); ``straight`` within 1e-3 rad of
    the straight chain (q = 0), where U joints are far from their singular configuration
    but the chain is at its stiffest conditioning. (For a prismatic axis q is a displacement in
    m, drawn the same way.)"""
    if kind not in STATE_KINDS:
        raise ValueError(f"kind = {kind!r}: choose one of {', '.join(STATE_KINDS)}")
    rng = np.random.default_rng(seed)
    n = model.n_dof
    if kind == "spread":
        q = rng.uniform(-np.pi, np.pi, n)
    else:
        q = rng.normal(scale=1e-3, size=n)
    v = rng.normal(size=n)
    tau = rng.normal(size=n)
    return q, v, tau
