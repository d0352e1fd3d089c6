"""The DH-specialised kernels (redysim.algorithms._kernels.dh): when they run, and that they
compute what the general kernels compute.

Checked against the general recursions (``dh=False``: any joint placement, full rotations), the
dense GIM solved by GE-N, the identity inverse(forward(tau)) = tau, and the robot files' published
numbers (tests/test_dh.py's Robotics Toolbox values, which now run through these kernels). Every
path that computes qdd or tau of one state (the public functions, the evaluator, batches row by
row, the compiled stepping) runs the same kernels: same bits. The operation counts are
counted in the kernels' own source (reports/opcount.py) and compared with the talk's.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import stable_seed

import redysim
from redysim import Chain, Workspace, forward_dynamics, inverse_dynamics, load_model
from redysim.algorithms.dh_form import dh_constants, dh_problem
from redysim.errors import FieldError
from redysim.io.dh import DHLink, dh_model

PUMA, STANFORD = "cases/robots/puma560.toml", "cases/robots/stanford_arm.toml"


def random_robot(joints: str, convention: str = "modified", seed: str = "dh",
                 twists=None) -> redysim.Model:
    """A DH table with seeded values (any twist, length, offset and angle; COMs off the axes;
    full inertias about the COM), one joint per letter of ``joints`` (R or P); ``twists``: each
    joint's alpha in degrees instead."""
    rng = np.random.default_rng(stable_seed(seed, joints, convention))
    links = []
    for k, j in enumerate(joints):
        m = rng.uniform(0.5, 4.0)
        A = rng.normal(size=(3, 3))
        inertia = 0.05 * m * (A @ A.T + np.eye(3))
        alpha = rng.uniform(-math.pi, math.pi) if twists is None else math.radians(twists[k])
        links.append(DHLink(a=rng.uniform(-0.4, 0.4), alpha=alpha,
                            d=rng.uniform(-0.3, 0.3), theta=rng.uniform(-math.pi, math.pi),
                            joint=j, mass=m, com=tuple(rng.uniform(-0.2, 0.2, 3)),
                            inertia=inertia, physical=False))
    return dh_model(links, convention=convention, name=f"DH-{joints}")


ROBOTS = {
    "PUMA 560": lambda: load_model(PUMA),
    "Stanford arm": lambda: load_model(STANFORD),
    "7R modified": lambda: random_robot("RRRRRRR"),
    "RPRRPR standard": lambda: random_robot("RPRRPR", "standard"),
    "P at the base": lambda: random_robot("PRRP"),
    "one joint": lambda: random_robot("R"),
    "right-angle twists": lambda: random_robot("RRPRR", twists=(90, -90, 0, 180, 90)),
    # the forward kernel's special bodies (the base's, its child's, the last's; the second body
    # the last) under each kind of twist
    "two joints": lambda: random_robot("RR"),
    "two joints, right angles": lambda: random_robot("RR", twists=(90, 0)),
    "RP": lambda: random_robot("RP", twists=(0, -90)),
    "right angles, 180 second": lambda: random_robot("RRRR", twists=(0, 180, 90, -90)),
}


def states(model, count, seed):
    rng = np.random.default_rng(stable_seed("dh-states", seed))
    for _ in range(count):
        yield tuple(rng.uniform(-1.5, 1.5, model.n_v) for _ in range(4))


@pytest.mark.parametrize("name", ROBOTS)
def test_dh_robots_run_the_dh_kernels_equal_to_the_general_ones(name):
    """Forward and inverse dynamics of a robot in DH form by the DH kernels equal the general
    recursions' to rounding (and the GIM solved by GE-N), and invert each other."""
    model = ROBOTS[name]()
    assert dh_problem(model) is None and Workspace(model).dh
    for q, v, tau, qdd in states(model, 25, name):
        ref = forward_dynamics(model, q, v, tau, dh=False)
        got = forward_dynamics(model, q, v, tau)
        scale = np.abs(ref).max()
        # the GIM's conditioning sets how far two exact-in-theory recursions may drift apart:
        # measured against GE-N on the dense GIM too (the Stanford arm's COMs, published in
        # decimetres as metres, make its GIM the worst conditioned here)
        cond = np.linalg.cond(redysim.mass_matrix(model, q))
        tol = 50 * np.finfo(float).eps * cond * scale
        assert np.abs(got - ref).max() <= tol
        assert np.abs(got - forward_dynamics(model, q, v, tau, method="ge-n")).max() <= tol
        t_ref = inverse_dynamics(model, q, v, qdd, dh=False)
        t_got = inverse_dynamics(model, q, v, qdd)
        assert np.abs(t_got - t_ref).max() <= 1e-13 * np.abs(t_ref).max()
        # inverse of forward, both by the DH kernels
        back = inverse_dynamics(model, q, v, got)
        bias = inverse_dynamics(model, q, v, np.zeros(model.n_v))
        size = max(np.abs(tau).max(), np.abs(bias).max())
        assert np.abs(back - tau).max() <= 50 * np.finfo(float).eps * cond * size


def test_right_angle_twists_are_recognised_to_rounding():
    """Twists of 0, 90, -90 and 180 degrees (radians(90) has a cosine of 6e-17, not 0) are
    coded as right angles, their cos and sin exact; any other twist is not."""
    table = dh_constants(random_robot("RRRRR", twists=(90, -90, 0, 180, 45)))
    twist = redysim.algorithms.dh_form.COLUMNS.index("twist")
    ca, sa = (redysim.algorithms.dh_form.COLUMNS.index(c) for c in ("ca", "sa"))
    assert table[:, twist].tolist() == [2.0, 3.0, 1.0, 4.0, 0.0]
    assert table[:4, [ca, sa]].tolist() == [[0.0, 1.0], [0.0, -1.0], [1.0, 0.0], [-1.0, 0.0]]
    puma = dh_constants(load_model(PUMA))
    assert (puma[:, twist] != 0).all()


def test_the_form_is_recognised_and_refused_by_name():
    """Serial R/P chains placed by DH transforms qualify; a tree, a ball joint, an axis off z, a
    placement off the DH form by 1e-9 do not, each said; a planar chain runs the planar kernel."""
    assert dh_problem(load_model(PUMA)) is None
    rope = Chain.uniform(6, "R", length=0.3, linear_density=2.0, radius=0.02)
    ws = Workspace(rope)
    assert rope.is_planar and ws.planar is not None and not ws.dh  # the planar kernel's
    assert "revolute or prismatic" in dh_problem(Chain.uniform(3, "U", length=0.3,
                                                               linear_density=2.0, radius=0.02))
    robot = random_robot("RRR")
    R = np.array(robot.placement_R)
    R[1] = np.array([[1, 0, 0], [0, math.cos(1e-9), -math.sin(1e-9)],
                     [0, math.sin(1e-9), math.cos(1e-9)]]) @ R[1]
    p = np.array(robot.placement_p)
    import dataclasses
    tilted = dataclasses.replace(robot, placement_R=R)
    assert "joint2" in dh_problem(tilted) and "DH transform" in dh_problem(tilted)
    assert dh_constants(tilted) is None and not Workspace(tilted).dh
    p[2, 1] += 1e-6 * (1 + abs(p[2]).max())
    shifted = dataclasses.replace(robot, placement_p=p)
    assert "joint3" in dh_problem(shifted)


def test_dh_true_requires_the_form_and_dh_must_be_a_flag():
    rope = Chain.uniform(3, "U", length=0.3, linear_density=2.0, radius=0.02)
    q = np.zeros(rope.n_q)
    with pytest.raises(ValueError, match="not a robot in DH form: not every joint"):
        forward_dynamics(rope, q, q, dh=True)
    with pytest.raises(ValueError, match="not a robot in DH form"):
        inverse_dynamics(rope, q, q, q, dh=True)
    with pytest.raises(FieldError, match="dh"):
        forward_dynamics(load_model(PUMA), np.zeros(6), np.zeros(6), dh="yes")
    robot = load_model(PUMA)
    z = np.zeros(6)
    assert np.array_equal(forward_dynamics(robot, z, z, dh=True), forward_dynamics(robot, z, z))


@pytest.mark.parametrize("name", ["PUMA 560", "RPRRPR standard"])
def test_every_path_runs_the_same_kernels_bit_for_bit(name):
    """The public functions' fast and checked paths, the evaluator and batches row by row
    (simd=False) give the same bits on a DH robot."""
    model = ROBOTS[name]()
    fd, inv = redysim.evaluator(model), redysim.evaluator(model, "inverse_dynamics")
    rows = list(states(model, 9, name))
    Q, V, T, A = (np.array([r[i] for r in rows]) for i in range(4))
    batch = forward_dynamics(model, Q, V, T, simd=False)
    batch_inv = inverse_dynamics(model, Q, V, A)
    for i, (q, v, tau, qdd) in enumerate(rows):
        one = forward_dynamics(model, q, v, tau)
        assert one.tobytes() == fd(q, v, tau).tobytes() == batch[i].tobytes()
        assert one.tobytes() == forward_dynamics(model, q.tolist(), v.tolist(),
                                                 tau.tolist()).tobytes()
        t = inverse_dynamics(model, q, v, qdd)
        assert t.tobytes() == inv(q, v, qdd).tobytes() == batch_inv[i].tobytes()
        assert t.tobytes() == inverse_dynamics(model, q.tolist(), v.tolist(),
                                               qdd.tolist()).tobytes()


def test_a_singular_robot_is_named_as_the_general_path_names_it():
    """A joint that moves nothing with inertia about its axis: the same StateError text."""
    robot = random_robot("RR")
    import dataclasses
    mass = np.array(robot.mass)
    mass[1] = 0.0
    massless = dataclasses.replace(robot, mass=mass, inertia_O=np.zeros_like(robot.inertia_O),
                                   mass_com=np.zeros_like(robot.mass_com))
    q = np.array([0.3, 0.2])
    with pytest.raises(redysim.StateError) as general:
        forward_dynamics(massless, q, q, dh=False)
    with pytest.raises(redysim.StateError) as special:
        forward_dynamics(massless, q, q)
    assert str(special.value) == str(general.value)
    assert "singular at DOF 1" in str(special.value)


def test_the_dh_kernels_count_fewer_operations_than_the_general_and_the_talks():
    """The counts in the kernels' own source (reports/opcount.py): the DH kernels below the
    general ones; on right-angle twists (the PUMA 560's kind) the inverse dynamics at or below
    the talk's 120n - 44 multiplications and 97n - 55 additions for every n > 1, the forward
    dynamics' multiplications at or below its 191n - 284 at the talk's n = 6, both slopes
    below the talk's, and its additions at or below 187n - 325 from n = 10 (seed 001's
    comparison tables; at n = 6 the talk's additions are fewer than ours)."""
    from redysim.reports import opcount

    res = opcount.measure_robots()
    fits = {f["algorithm"]: f for f in res["fits"]}
    assert all(f["exact"] for f in fits.values())

    def at(fit, what, n):
        return np.polyval(fit[f"{what}_coef"], n)

    for kind in ("forward", "inverse"):
        right = fits[f"{kind} dynamics, DH kernel, right-angle twists"]
        any_ = fits[f"{kind} dynamics, DH kernel, any twists"]
        general = next(f for a, f in fits.items() if a.startswith(kind) and "general" in a)
        for what in ("mult", "add"):
            assert right[f"{what}_coef"][0] < any_[f"{what}_coef"][0] \
                < general[f"{what}_coef"][0]
    inv = fits["inverse dynamics, DH kernel, right-angle twists"]
    fwd = fits["forward dynamics, DH kernel, right-angle twists"]
    for n in (2, 6, 100):
        assert at(inv, "mult", n) <= 120 * n - 44 and at(inv, "add", n) <= 97 * n - 55
    assert at(fwd, "mult", 6) <= 191 * 6 - 284
    assert fwd["mult_coef"][0] < 191 and fwd["add_coef"][0] < 187
    assert all(at(fwd, "add", n) <= 187 * n - 325 for n in (10, 100))


@pytest.mark.parametrize("damping", [0.0, 0.2])
def test_a_dh_robot_steps_in_compiled_code_in_the_same_bits(damping):
    """The compiled stepping calls the DH kernel as the Python loop's forward_dynamics does:
    the same steps and every sample bit for bit (the Stanford arm: a prismatic joint too)."""
    from test_integrate import _compiled_and_python_runs

    model = load_model(STANFORD)
    q0 = np.array([0.3, -0.5, 0.2, 0.4, -0.3, 0.6])
    _compiled_and_python_runs(model, 0.3, q0=q0, integrator="ode45", rtol=1e-8, atol=1e-10,
                              damping=damping)
