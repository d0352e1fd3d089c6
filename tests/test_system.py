"""A run's physics as one object (:class:`redysim.algorithms.system.System`): its forces written
once, seen alike by the compiled and the Python stepping; its settings checked at the door.

The joint springs are the newest term of the system's one force function
(``redysim.algorithms._kernels.system.generalized_forces``): these tests add one to a model and
check it three ways: against a closed form (a torsional pendulum without gravity), by the energy
balance with the spring's potential, and in the compiled and the Python stepping, which must take
the same steps to the same bits since both call that one function.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from conftest import stable_seed
from test_integrate import _compiled_and_python_runs
from test_trees import random_configuration, random_tree

from redysim import Chain, SettingsError
from redysim.algorithms.system import System
from redysim.simulation import Integrator, Simulator


def test_a_joint_spring_makes_a_torsional_pendulum_oscillate_at_its_frequency():
    """One link about z, no gravity, a spring k at its joint: theta(t) = theta0 cos(w t) with
    w = sqrt(k / I_O), I_O the link's inertia about its joint (closed form, no reference run)."""
    chain = Chain.uniform(1, "R", length=0.8, mass=2.0, radius=0.01)
    chain = dataclasses.replace(chain, gravity=np.zeros(3))
    k = 3.0
    I_O = float(chain.inertia_O[0, 2, 2])
    w = math.sqrt(k / I_O)
    system = System(chain, stiffness=k, spring_ref=[0.25])
    run = Simulator(system, 2.0, q0=[0.25 + 0.1], integrator=Integrator("dop853", rtol=1e-12,
                                                                         atol=1e-14),
                    sample=0.1).run()
    assert run.status == 0
    want = 0.25 + 0.1 * np.cos(w * run.t)
    assert np.abs(run.q[:, 0] - want).max() < 1e-10
    # the spring's potential is in the energy, which the motion keeps, to the integrator's
    # tolerance: 1.2e-13 J of E = 0.015 J (8e-12 relative) at rtol 1e-12 since dop853's error
    # norm is Hairer's over the whole vector (1e-12 relative held under the max norm it had)
    assert np.abs(run.energy - run.energy[0]).max() < 1e-11 * abs(run.energy[0]) + 1e-13


@pytest.mark.parametrize("method, kw", [("ode45", {"rtol": 1e-8, "atol": 1e-10}),
                                        ("dop853", {"rtol": 1e-9, "atol": 1e-11}),
                                        ("rk4", {"h": 1e-3})])
def test_a_new_force_is_seen_in_the_same_bits_by_the_compiled_and_the_python_stepping(method,
                                                                                     kw):
    """Springs (and damping) on a random tree: the compiled steps and the Python stepping take
    the same steps to the same samples, bit for bit (both call the system's one force
    function); the springs change the motion; undamped, E with the springs' potential is kept;
    the forces are -k (q - q_ref) - d v."""
    model = random_tree(stable_seed("system-springs"), n_bodies=8, free=False, fixed=1)
    rng = np.random.default_rng(17)
    q0, v0 = random_configuration(rng, model), rng.normal(size=model.n_v)
    k = rng.uniform(0.5, 4.0, model.n_v)
    ref = rng.uniform(-0.3, 0.3, model.n_v)
    sprung, _ = _compiled_and_python_runs(model, 0.3, q0=q0, v0=v0, integrator=method,
                                          stiffness=k, spring_ref=ref, **kw)
    free, _ = _compiled_and_python_runs(model, 0.3, q0=q0, v0=v0, integrator=method, **kw)
    assert np.abs(sprung.q[-1] - free.q[-1]).max() > 1e-3
    assert np.abs(sprung.delta_M).max() < (1e-5 if method == "rk4" else 1e-7)
    _compiled_and_python_runs(model, 0.3, q0=q0, v0=v0, integrator=method, stiffness=k,
                              spring_ref=ref, damping=0.2, **kw)
    tau = System(model, stiffness=k, spring_ref=ref, damping=0.2).forces(0.0, q0, v0)
    assert np.abs(tau - (-k * (q0 - ref) - 0.2 * v0)).max() < 1e-14 * np.abs(tau).max()


def test_a_systems_bad_settings_are_named():
    """The door: a negative or ill-shaped stiffness, a spring on a free joint, a tip force on a
    tree, a damping that is not a number: SettingsError naming the field and the value."""
    chain = Chain.uniform(3, "R", length=0.3, mass=0.5, radius=0.01)
    with pytest.raises(SettingsError, match=r"stiffness = -1.0: must be a finite number >= 0"):
        System(chain, stiffness=-1.0)
    with pytest.raises(SettingsError, match=r"stiffness = \[1.0, 2.0\]: must be a number or 3"):
        System(chain, stiffness=[1.0, 2.0])
    with pytest.raises(SettingsError, match=r"spring_ref = 'up': must be a number or 3"):
        System(chain, stiffness=1.0, spring_ref="up")
    with pytest.raises(SettingsError, match=r"damping = 'lots': must be a finite number >= 0"):
        System(chain, damping="lots")
    floating = random_tree(stable_seed("system-free"), n_bodies=3, free=True)
    with pytest.raises(SettingsError, match="stiffness = \"free joint 'base'\": springs act on"):
        System(floating, stiffness=1.0)
    with pytest.raises(SettingsError, match="tip_force = .*is a tree"):
        System(random_tree(3, free=False), tip_force=[1.0, 0.0, 0.0])


def test_gravity_compensation_holds_up_the_weight_it_is_given():
    """gravcomp = 1 on every body of a floating robot cancels gravity: at rest it stays at rest;
    gravcomp = 0.5 gives the accelerations of the same robot under half gravity (an independent
    model: its gravity halved), on a fixed-base tree too."""
    for free in (True, False):
        model = random_tree(stable_seed("gravcomp", free), n_bodies=7, free=free, fixed=1)
        rng = np.random.default_rng(23)
        q = random_configuration(rng, model)
        rest = np.zeros(model.n_v)
        held = System(model, gravcomp=1.0).qdd(0.0, q, rest)
        assert np.abs(held).max() < 1e-12 * max(1.0, np.abs(System(model).qdd(0.0, q, rest)).max())
        half = dataclasses.replace(model, gravity=0.5 * np.asarray(model.gravity))
        v = rng.normal(size=model.n_v)
        want = System(half).qdd(0.0, q, v)
        got = System(model, gravcomp=0.5).qdd(0.0, q, v)
        assert np.abs(got - want).max() < 1e-12 * np.abs(want).max()


def test_a_body_force_is_its_points_jacobian_transposed():
    """Constant world forces at points of bodies: tau = sum_i J_i^T f_i, J_i the point's
    Jacobian by central differences of its world position (a fixed-base tree: v is dq/dt); the
    energy counts -f . p, so a run keeps E (compiled and Python stepping in the same bits)."""
    model = random_tree(stable_seed("body-forces"), n_bodies=6, free=False, fixed=1)
    rng = np.random.default_rng(29)
    q = random_configuration(rng, model)
    names = list(model.body_names)
    forces = [(names[2], rng.normal(size=3), rng.normal(size=3) * 0.2),
              (names[-1], rng.normal(size=3), np.zeros(3)),
              (names[-1], rng.normal(size=3), rng.normal(size=3) * 0.1)]
    system = System(model, body_forces=forces)
    ws = system.ws

    def position(qq, body, point):
        from redysim import energy

        energy(model, qq, np.zeros(model.n_v), ws=ws)  # (its kinematics pass)
        return ws.oO[body] + ws.oR[body] @ point

    want = np.zeros(model.n_v)
    for name, f, x in forces:
        b = names.index(name)
        J = np.empty((3, model.n_v))
        for j in range(model.n_v):
            d = np.zeros(model.n_q)
            d[j] = 1e-6
            J[:, j] = (position(q + d, b, x) - position(q - d, b, x)) / 2e-6
        want += J.T @ f
    got = system.forces(0.0, q, np.zeros(model.n_v))
    assert np.abs(got - want).max() < 1e-8 * np.abs(want).max()
    a, _ = _compiled_and_python_runs(model, 0.3, q0=q, integrator="dop853", rtol=1e-10,
                                     atol=1e-12, body_forces=forces)
    assert np.abs(a.delta_M).max() < 1e-8
    with pytest.raises(SettingsError, match=r"body_forces\[0\] = 'nowhere': no such body"):
        System(model, body_forces=[("nowhere", [0, 0, 1], [0, 0, 0])])
    with pytest.raises(SettingsError, match=r"body_forces\[0\].force = .*3 finite numbers"):
        System(model, body_forces=[(names[1], [0, 1], [0, 0, 0])])
    with pytest.raises(SettingsError, match=r"gravcomp = 'arm': no such body"):
        System(model, gravcomp={"arm": 1.0})
