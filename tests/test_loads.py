"""A constant world-frame force at the tip (redysim.algorithms.loads) and the case files' [load]
table.

tau = J_tip^T F is checked three ways: against the tip velocity that redysim.tip computes by its
own route (virtual power, tau . qd = F . v_tip, to round-off, and column by column), against a
central finite difference of the work F . p_tip(q), and by the energy balance of a chain pulled
at its end (T + V - F . p_tip conserved).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from redysim import (
    CaseError,
    Chain,
    FieldError,
    Joint,
    Link,
    Model,
    StateError,
    Workspace,
    case_from_dict,
    energy,
    forward_dynamics,
    load_case,
    mass_matrix,
    tip,
)
from redysim.algorithms.loads import tip_force_potential, tip_force_torques
from redysim.model.tree import Body, TreeJoint

# every joint type, and revolute axes default (z), named, negative and tilted
MIXED_JOINTS = [Joint("R"), Joint("R", "x"), Joint("R", (0.0, 0.0, -1.0)),
                Joint("R", (0.3, -0.5, 0.8)), Joint("P"), Joint("P", (0.2, 0.9, -0.4)),
                Joint("U"), Joint("S"), Joint("R", "y")]


def mixed_chain() -> Chain:
    links = [Link.uniform(0.2 + 0.1 * k, 0.5 + 0.2 * k, 0.02, "cylinder")
             for k in range(len(MIXED_JOINTS))]
    return Chain.build(links, MIXED_JOINTS, name="mixed")


CHAINS = {
    "mixed": mixed_chain,
    "planar R": lambda: Chain.uniform(6, "R", length=0.4, mass=1.0),
    "one P": lambda: Chain.uniform(1, Joint("P", (1.0, 1.0, 0.0)), length=0.5, mass=1.0),
    "U": lambda: Chain.uniform(4, "U", length=0.3, mass=1.0),
}


@pytest.mark.parametrize("name", CHAINS)
def test_virtual_power_is_the_tip_force_times_the_tip_velocity(name):
    """tau . qd = F . v_tip for any qd: tau is J^T F for the J that moves the tip."""
    chain = CHAINS[name]()
    rng = np.random.default_rng(7)
    for _ in range(20):
        q = rng.uniform(-math.pi, math.pi, chain.n_dof)
        qd = rng.normal(size=chain.n_dof)
        F = rng.normal(scale=10.0, size=3)
        tau = tip_force_torques(chain, q, F)
        v = tip(chain, q, qd).velocity
        scale = np.abs(tau * qd).sum() + np.abs(F * v).sum()
        assert abs(tau @ qd - F @ v) <= 1e-12 * scale


def test_every_column_is_the_force_on_that_dofs_tip_velocity():
    """tau_j = F . (dp_tip / dq_j): the tip's velocity with qd the j-th unit vector."""
    chain = mixed_chain()
    rng = np.random.default_rng(7)
    q = rng.uniform(-math.pi, math.pi, chain.n_dof)
    F = np.array([3.0, -1.5, 2.0])
    tau = tip_force_torques(chain, q, F)
    J = np.column_stack([tip(chain, q, e).velocity for e in np.eye(chain.n_dof)])
    np.testing.assert_allclose(tau, J.T @ F, rtol=0,
                               atol=1e-13 * np.abs(J).max() * np.abs(F).sum())


def test_torques_are_the_gradient_of_the_work():
    """tau = d/dq (F . p_tip), by central differences (h = 1e-6: error ~ h^2 and eps / h)."""
    chain = mixed_chain()
    rng = np.random.default_rng(7)
    q = rng.uniform(-math.pi, math.pi, chain.n_dof)
    F = np.array([1.0, -2.0, 0.5])
    h = 1e-6
    fd = np.empty(chain.n_dof)
    for j in range(chain.n_dof):
        dq = np.zeros(chain.n_dof)
        dq[j] = h
        fd[j] = (tip_force_potential(chain, q - dq, F) - tip_force_potential(chain, q + dq, F)) \
            / (2 * h)
    tau = tip_force_torques(chain, q, F)
    np.testing.assert_allclose(tau, fd, rtol=0, atol=1e-6 * np.abs(tau).max())


def test_the_potential_is_minus_the_work_at_the_tip():
    chain = mixed_chain()
    q = np.random.default_rng(7).normal(size=chain.n_dof)
    F = [1, 2, 3]  # integers are numbers too
    p = tip(chain, q, np.zeros(chain.n_dof)).position
    assert tip_force_potential(chain, q, F) == pytest.approx(-(p @ F), rel=1e-15)


def test_energy_is_conserved_with_the_tip_force():
    """A planar 5-link R chain under gravity, pulled at its end by a constant force: T + V plus
    the force's potential stays constant (rtol 1e-10 integration)."""
    chain = Chain.uniform(5, "R", length=0.3, mass=0.5, radius=0.01, inertia="cylinder")
    F = np.array([4.0, 3.0, 0.0])
    ws = Workspace(chain)
    n = chain.n_dof

    def rhs(_t, y):
        q, qd = y[:n], y[n:]
        tau = tip_force_torques(chain, q, F, ws=ws)
        return np.concatenate((qd, forward_dynamics(chain, q, qd, tau, ws=ws)))

    def total(y):
        T, V = energy(chain, y[:n], y[n:])
        return T + V + tip_force_potential(chain, y[:n], F), T + abs(V)

    y0 = np.concatenate((np.linspace(-0.6, 0.4, n), np.zeros(n)))
    sol = solve_ivp(rhs, (0.0, 2.0), y0, rtol=1e-10, atol=1e-12,
                    t_eval=np.linspace(0.0, 2.0, 41))
    assert sol.success
    E = np.array([total(y) for y in sol.y.T])
    scale = E[:, 1].max() + abs(tip_force_potential(chain, y0[:n], F))
    assert np.ptp(E[:, 1]) > 0.1 * scale  # the chain did move
    assert np.abs(E[:, 0] - E[0, 0]).max() <= 1e-7 * scale


def test_a_workspace_is_reused_and_must_be_the_chains():
    chain = mixed_chain()
    q = np.random.default_rng(7).normal(size=chain.n_dof)
    F = np.array([0.0, -9.0, 1.0])
    ws = Workspace(chain)
    assert np.array_equal(tip_force_torques(chain, q, F, ws=ws), tip_force_torques(chain, q, F))
    assert tip_force_potential(chain, q, F, ws=ws) == tip_force_potential(chain, q, F)
    with pytest.raises(FieldError, match="another chain"):
        tip_force_torques(chain, q, F, ws=Workspace(Chain.uniform(2, "R", mass=1.0)))


@pytest.mark.parametrize("func", [tip_force_torques, tip_force_potential])
@pytest.mark.parametrize("bad, fragment", [
    ([1.0, 2.0], r"force = \[1.0, 2.0\]: must be a vector of 3 numbers.*shape \(2,\)"),
    ("abc", r"force = 'abc': must be a vector of 3 numbers"),
    ([1.0, "2", 3.0], r"force = \[1.0, '2', 3.0\]: must be"),
    ([[1.0, 2.0, 3.0]], r"force = \[\[1.0, 2.0, 3.0\]\]: .*shape \(1, 3\)"),
    (None, r"force = None: must be"),
    ([1.0, math.nan, 0.0], r"force = \[1.0, nan, 0.0\]: not finite"),
    ([math.inf, 0.0, 0.0], r"force = \[inf, 0.0, 0.0\]: not finite"),
])
def test_a_bad_force_is_named_with_its_value(func, bad, fragment):
    chain = Chain.uniform(3, "U", mass=1.0)
    with pytest.raises(StateError, match=fragment):
        func(chain, np.zeros(chain.n_dof), bad)


@pytest.mark.parametrize("func", [tip_force_torques, tip_force_potential])
def test_a_bad_q_or_system_is_named(func):
    chain = Chain.uniform(3, "U", mass=1.0)
    with pytest.raises(StateError, match=r"q has shape \(5,\).*shape \(6,\)"):
        func(chain, np.zeros(5), [0.0, 1.0, 0.0])
    with pytest.raises(StateError, match=r"q\[2\] = nan"):
        func(chain, [0, 0, math.nan, 0, 0, 0], [0.0, 1.0, 0.0])
    # a tree has no single tip
    tree = Model.build([Body("a", 1.0, (0.5, 0, 0), (0.1, 0.1, 0.1)),
                        Body("b", 1.0, (0.5, 0, 0), (0.1, 0.1, 0.1)),
                        Body("c", 1.0, (0.5, 0, 0), (0.1, 0.1, 0.1))],
                       [TreeJoint("ja", "R"), TreeJoint("jb", "R", translation=(1, 0, 0)),
                        TreeJoint("jc", "R", translation=(0, 1, 0))], [-1, 0, 0], name="tree")
    with pytest.raises(FieldError, match="chain = 'tree': must be a chain of links"):
        func(tree, np.zeros(tree.n_q), [0.0, 1.0, 0.0])


# --------------------------------------------------------------------------- case files
def pulled_case(**load) -> dict:
    doc = {"case": {"name": "pulled"},
           "chain": {"links": 3, "joint": "R", "link_length": 0.5, "link_mass": 1.0},
           "simulation": {"t_end": 1.0}}
    if load:
        doc["load"] = load
    return doc


def test_a_case_without_load_has_no_tip_force():
    assert case_from_dict(pulled_case()).tip_force is None


def test_a_case_reads_its_tip_force():
    case = case_from_dict(pulled_case(tip_force=[1, 0, 0]))
    assert case.tip_force.dtype == float and np.array_equal(case.tip_force, [1.0, 0.0, 0.0])
    assert not case.tip_force.flags.writeable
    given = np.array([0.0, -2.5, 0.0])
    case = case_from_dict(pulled_case(tip_force=given))
    assert given.flags.writeable and case.tip_force is not given  # the caller's array untouched
    tau = tip_force_torques(case.chain, case.q0, case.tip_force)
    np.testing.assert_allclose(tau, [-3.75, -2.5, -1.25], rtol=1e-15)  # straight along +X


def test_a_case_file_reads_its_tip_force(tmp_path):
    path = tmp_path / "pulled.toml"
    path.write_text('[case]\nname = "pulled"\n[chain]\nlinks = 2\njoint = "U"\n'
                    'link_length = 1.0\nlink_mass = 1.0\n[simulation]\nt_end = 1.0\n'
                    '[load]\ntip_force = [0, -5.5, 2]\n')
    assert np.array_equal(load_case(path).tip_force, [0.0, -5.5, 2.0])


@pytest.mark.parametrize("bad, fragment", [
    ([1.0, 2.0], "must be a list of 3 numbers, got shape (2,)"),
    ([1.0, 2.0, 3.0, 4.0], "must be a list of 3 numbers, got shape (4,)"),
    ("north", "must be a list of 3 numbers"),
    (5.0, "must be a list of 3 numbers, got shape ()"),
    ([1.0, "2", 3.0], "must be a list of 3 numbers"),
    ([True, False, False], "must be a list of 3 numbers"),
    ([0.0, math.nan, 0.0], "must be finite"),
    ([math.inf, 0.0, 0.0], "must be finite"),
])
def test_a_bad_tip_force_is_named(bad, fragment):
    with pytest.raises(CaseError) as err:
        case_from_dict(pulled_case(tip_force=bad), source="pulled.toml")
    assert err.value.field == "load.tip_force"
    assert str(err.value).startswith("pulled.toml: load.tip_force = ")
    assert fragment in str(err.value)


def test_an_unknown_load_field_or_a_load_that_is_no_table_is_refused():
    with pytest.raises(CaseError) as err:
        case_from_dict(pulled_case(tip_force=[1, 0, 0], tip_torque=[0, 0, 1]), source="p.toml")
    assert err.value.field == "load.tip_torque"
    assert "unknown field; expected one of tip_force" in str(err.value)
    doc = pulled_case()
    doc["load"] = [1, 0, 0]
    with pytest.raises(CaseError, match=r"load = \[1, 0, 0\]: \[load\] must be a table"):
        case_from_dict(doc)


def test_a_top_level_link_table_is_refused_not_ignored():
    """[[chain.link]] entries belong under [chain]; a top-level [link] once passed silently."""
    doc = pulled_case()
    doc["link"] = {"length": 1.0}
    with pytest.raises(CaseError) as err:
        case_from_dict(doc, source="p.toml")
    assert err.value.field == "<top>.link"


def test_a_tip_mass_is_a_point_mass_at_the_last_links_end():
    """One rod of mass m and length l carrying M at its end: about the joint, m l^2 / 3 + M l^2
    (the GIM of a planar link), and its centre of mass and total mass."""
    doc = pulled_case()
    doc["chain"] = {"links": 1, "joint": "R", "link_length": 0.5, "link_mass": 2.0,
                    "tip_mass": 3.0}
    chain = case_from_dict(doc).chain
    assert chain.total_mass == 5.0
    np.testing.assert_allclose(chain.com[0], [(2.0 * 0.25 + 3.0 * 0.5) / 5.0, 0.0, 0.0])
    gim = mass_matrix(chain, [0.3])
    np.testing.assert_allclose(gim, [[2.0 * 0.25 / 3 + 3.0 * 0.25]], rtol=1e-14)
    doc["chain"]["links"] = 3  # only the last link carries it
    chain = case_from_dict(doc).chain
    np.testing.assert_array_equal(chain.mass, [2.0, 2.0, 5.0])


@pytest.mark.parametrize("bad", [0.0, -1.0, "heavy", math.inf])
def test_a_bad_tip_mass_is_named(bad):
    doc = pulled_case()
    doc["chain"]["tip_mass"] = bad
    with pytest.raises(CaseError) as err:
        case_from_dict(doc, source="p.toml")
    assert err.value.field == "chain.tip_mass"


def test_a_simulators_tip_force_adds_to_its_tau_and_potential():
    """simulator(tip_force=): the force's torques added to a tau given with it, its potential
    to that tau's (a constant joint torque c, potential -c . q): the balance holds with both
    (the Python loop: a tau provider) and with the force alone (compiled), on a spatial chain
    and a planar one. A tree, and a force that is not 3 numbers, are refused by name."""
    from redysim.errors import SettingsError
    from redysim.simulation import simulator

    F = np.array([2.0, -1.0, 0.5])
    for chain in (Chain.uniform(4, "U", length=0.3, mass=0.5, radius=0.01),
                  Chain.uniform(4, "R", length=0.3, mass=0.5, radius=0.01)):
        c = np.linspace(0.2, -0.1, chain.n_dof)
        q0 = np.linspace(-0.6, 0.4, chain.n_dof)
        sim = simulator(chain, 0.5, q0=q0, tip_force=F, tau=lambda _t, _q, _v, c=c: c,
                        potential=lambda q, c=c: -float(c @ q), rtol=1e-10, atol=1e-12,
                        sample=0.05)
        assert sim.compiled is False  # a tau provider: the Python loop
        run = sim.run()
        moved = np.abs(run.q - q0).max()
        assert run.status == 0 and moved > 0.05
        assert np.abs(run.delta_M).max() < 1e-8
        alone = simulator(chain, 0.5, q0=q0, tip_force=F, rtol=1e-10, atol=1e-12, sample=0.05)
        assert alone.compiled  # planar or spatial, the steps compiled
        assert np.abs(alone.run().delta_M).max() < 1e-8
    from test_trees import random_tree

    with pytest.raises(SettingsError, match="tip_force = .*is a tree"):
        simulator(random_tree(3, free=False), 0.1, tip_force=F)
    with pytest.raises(SettingsError, match="tip_force = 'north'.*3 numbers"):
        simulator(Chain.uniform(2, "R", length=0.3, mass=0.5, radius=0.01), 0.1,
                  tip_force="north")
