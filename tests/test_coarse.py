"""Coarse-graining (redysim.algorithms.coarse): lumped links are the fine chain with its inner
joints locked, checked through quantities the lumping does not compute (the fine chain's GIM, qdd of
the locked tree model, energy, tip), and the two state maps."""

import numpy as np
import pytest

import redysim
from redysim.algorithms.coarse import coarsen
from redysim.algorithms.dynamics import mass_matrix
from redysim.errors import CaseError

RNG_SEED = 20261123


def uneven_chain(joint="U", n=12):
    """A chain whose links differ in length, mass, COM (off the axis too) and inertia."""
    rng = np.random.default_rng(3)
    links = []
    for _ in range(n):
        length = rng.uniform(0.05, 0.2)
        mass = rng.uniform(0.2, 2.0)
        com = (rng.uniform(0.2, 0.8) * length, rng.uniform(-0.01, 0.01),
               rng.uniform(-0.01, 0.01))
        a, b = rng.uniform(1e-4, 1e-3, 2)
        links.append(redysim.Link(length, mass, com, ((a + b, 0, 0), (0, a + b, 0),
                                                      (0, 0, 2 * a))))
    return redysim.Chain.build(links, [joint] * n, name=f"uneven-{joint}")


def test_lumped_rod_links_are_the_coarser_rod():
    fine = redysim.Chain.uniform(120, "U", length=1 / 120, linear_density=61.65, radius=0.05)
    for k in (2, 3, 5, 24, 120):
        coarse = coarsen(fine, k).coarse
        same = redysim.Chain.uniform(120 // k, "U", length=k / 120, linear_density=61.65,
                                     radius=0.05)
        assert coarse.n_links == 120 // k
        np.testing.assert_allclose(coarse.length, same.length, rtol=1e-14)
        np.testing.assert_allclose(coarse.mass, same.mass, rtol=1e-14)
        np.testing.assert_allclose(coarse.com, same.com, rtol=1e-13, atol=1e-17)
        np.testing.assert_allclose(coarse.inertia_com, same.inertia_com, rtol=1e-12,
                                   atol=1e-15 * same.inertia_com.max())


@pytest.mark.parametrize("joint", ["U", "R"])
def test_the_coarse_gim_is_the_fine_gim_of_the_group_joints(joint):
    """M_coarse(q) = M_fine(to_fine(q)) restricted to each group's first joint: the fine chain's
    composite bodies, with its inner joints at zero, are the lumped links."""
    fine = uneven_chain(joint)
    cz = coarsen(fine, 4)
    rng = np.random.default_rng(RNG_SEED)
    q = rng.normal(size=cz.coarse.n_dof)
    qf, _ = cz.to_fine(q, np.zeros_like(q))
    first = cz._fine_first_dofs
    np.testing.assert_allclose(mass_matrix(cz.coarse, q),
                               mass_matrix(fine, qf)[np.ix_(first, first)], rtol=1e-12,
                               atol=1e-14)


@pytest.mark.parametrize("joint", ["U", "R"])
def test_the_coarse_chain_moves_as_the_fine_one_with_inner_joints_locked(joint):
    fine = uneven_chain(joint)
    cz = coarsen(fine, 3)
    rng = np.random.default_rng(RNG_SEED + 1)
    q, qd = rng.normal(size=cz.coarse.n_dof), rng.normal(size=cz.coarse.n_dof)
    qf, qdf = cz.to_fine(q, qd)
    # the same motion: energy and tip
    np.testing.assert_allclose(redysim.energy(cz.coarse, q, qd), redysim.energy(fine, qf, qdf),
                               rtol=1e-12)
    a, b = redysim.tip(cz.coarse, q, qd), redysim.tip(fine, qf, qdf)
    np.testing.assert_allclose(a.position, b.position, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(a.velocity, b.velocity, rtol=1e-12, atol=1e-13)
    # the same dynamics: the tree model of the fine chain with the inner joints locked at zero
    model = fine
    inner = [model.joint_names[j] for j in range(fine.n_links) if j % 3]
    width = {"U": 2, "R": 1}[joint]
    locked = model.locked({name: [0.0] * width for name in inner})
    np.testing.assert_allclose(redysim.forward_dynamics(cz.coarse, q, qd),
                               redysim.forward_dynamics(locked, q, qd), rtol=1e-10, atol=1e-10)


@pytest.mark.parametrize("joint", ["U", "R"])
def test_to_coarse_inverts_to_fine(joint):
    fine = uneven_chain(joint)
    cz = coarsen(fine, links=4)
    rng = np.random.default_rng(RNG_SEED + 2)
    q, qd = 0.8 * rng.normal(size=cz.coarse.n_dof), rng.normal(size=cz.coarse.n_dof)
    q2, qd2 = cz.to_coarse(*cz.to_fine(q, qd))
    np.testing.assert_allclose(q2, q, atol=1e-13)
    np.testing.assert_allclose(qd2, qd, atol=1e-12)


@pytest.mark.parametrize("joint", ["U", "R"])
def test_to_coarse_follows_the_chords_and_their_turning(joint):
    """From a bent fine state: each coarse link points along its group's chord, and the coarse
    rates are the time derivative of the coarse angles along the fine motion (central
    differences of the position map)."""
    fine = uneven_chain(joint)
    cz = coarsen(fine, 4)
    rng = np.random.default_rng(RNG_SEED + 3)
    q, qd = 0.3 * rng.normal(size=fine.n_dof), rng.normal(size=fine.n_dof)
    qc, qdc = cz.to_coarse(q, qd)
    pf = redysim.joint_positions(fine, q)[cz.starts]
    pc = redysim.joint_positions(cz.coarse, qc)
    chords = np.diff(pf, axis=0)
    links = np.diff(pc, axis=0)
    cosines = np.einsum("ij,ij->i", chords, links) / (
        np.linalg.norm(chords, axis=1) * np.linalg.norm(links, axis=1))
    np.testing.assert_allclose(cosines, 1.0, atol=1e-13)
    eps = 1e-6
    plus, _ = cz.to_coarse(q + eps * qd, qd)
    minus, _ = cz.to_coarse(q - eps * qd, qd)
    np.testing.assert_allclose(qdc, (plus - minus) / (2 * eps), rtol=1e-6, atol=1e-7)


def test_bad_coarsening_is_named():
    fine = redysim.Chain.uniform(10, "U", length=0.1, linear_density=1.0)
    with pytest.raises(CaseError, match="k = 3: must divide the chain's 10 links"):
        coarsen(fine, 3)
    with pytest.raises(CaseError, match="links = 4: must divide"):
        coarsen(fine, links=4)
    with pytest.raises(CaseError, match="give exactly one of k and links"):
        coarsen(fine, 2, links=5)
    with pytest.raises(CaseError, match="k = 0"):
        coarsen(fine, 0)
    sliding = redysim.Chain.uniform(4, "P", length=0.1, linear_density=1.0)
    with pytest.raises(CaseError, match=r"joints\[0\] = 'P': coarse joints must be one of"):
        coarsen(sliding, 2)
    twisting = redysim.Chain.uniform(4, redysim.Joint("R", axis="x"), length=0.1,
                                     linear_density=1.0)
    with pytest.raises(CaseError, match="needs an axis normal to the link"):
        coarsen(twisting, 2)
    cz = coarsen(fine, 5)
    with pytest.raises(redysim.StateError):
        cz.to_coarse(np.zeros(3), np.zeros(20))
