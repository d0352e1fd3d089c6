"""Ball joints: q a unit quaternion (w, x, y, z), v the body's angular velocity relative to its
parent in its own frame (MuJoCo's ``ball``), anywhere in a tree.

Checked on a floating robot with ball hips and ankles and on a small ball-jointed chain, three
ways: against the engines that have one (MuJoCo's mjJNT_BALL, Pinocchio's JointModelSpherical:
engine-marked); against identities that need no reference (the GIM by composite bodies against
the one assembled from inverse dynamics, inverse of forward, T = v^T I v / 2, the energy of a
run kept, the angular momentum about the centre of mass kept with gravity off, dq/dt of the
quaternion against a finite difference of the motion); and the compiled and the Python stepping
in the same bits. The MJCF round trip, the refusals by name (URDF, the engines without one,
springs) too.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_inertia, rel, stable_seed
from scipy.spatial.transform import Rotation
from test_integrate import _compiled_and_python_runs

from redysim import (
    SettingsError,
    StateError,
    energy,
    evaluator,
    forward_dynamics,
    inverse_dynamics,
    mass_matrix,
    rbda,
)
from redysim.algorithms.system import System
from redysim.io.export import ExportError, to_mjcf, to_urdf
from redysim.model.tree import Body, Model, TreeJoint
from redysim.simulation import Integrator, Simulator, momentum_observer


def _body(rng, name, length=0.4):
    m = rng.uniform(0.5, 2.0)
    return Body(name, m, tuple(rng.normal(scale=0.1, size=3)),
                tuple(map(tuple, random_inertia(rng, m, length))))


def _placed(rng, name, jtype, axis=None, shift=0.3):
    R = Rotation.random(random_state=rng).as_matrix()
    return TreeJoint(name, jtype, axis, tuple(map(tuple, R)),
                     tuple(rng.normal(scale=shift, size=3)))


def ball_chain(seed=1, n=3, gravity=(0.0, 0.0, -9.81)) -> Model:
    """n bodies hanging one from the other by ball joints, placed by random transforms."""
    rng = np.random.default_rng(seed)
    bodies = [_body(rng, f"link{k}") for k in range(n)]
    joints = [_placed(rng, f"ball{k}", "ball") for k in range(n)]
    return Model.build(bodies, joints, list(range(-1, n - 1)), gravity=gravity,
                       name="ball-chain")


def ball_robot(seed=2, gravity=(0.0, 0.0, -9.81)) -> Model:
    """A floating torso with two legs: ball hip, revolute knee, ball ankle, and an arm on a U
    joint."""
    rng = np.random.default_rng(seed)
    bodies = [_body(rng, "torso", 0.6)]
    joints = [TreeJoint("root", "free")]
    parents = [-1]
    for side in ("left", "right"):
        for part, jtype, axis in (("thigh", "ball", None), ("shin", "R", "y"),
                                  ("foot", "ball", None)):
            parents.append(len(bodies) - 1 if part != "thigh" else 0)
            bodies.append(_body(rng, f"{side}_{part}"))
            joints.append(_placed(rng, f"{side}_{part}_joint", jtype, axis))
    parents.append(0)
    bodies.append(_body(rng, "arm"))
    joints.append(_placed(rng, "shoulder", "U"))
    return Model.build(bodies, joints, parents, gravity=gravity, name="ball-robot")


MODELS = {"chain": ball_chain, "robot": ball_robot}


def random_state(rng, model):
    """A configuration with random unit quaternions, random velocities and forces."""
    q = model.neutral()
    for k, t in enumerate(model.joint_types):
        qs, qe = int(model.joint_qoff[k]), int(model.joint_qoff[k + 1])
        if t in ("ball", "free"):
            i = qs + (3 if t == "free" else 0)
            x, y, z, w = Rotation.random(random_state=rng).as_quat()
            q[i:i + 4] = [w, x, y, z]
            q[qs:i] = rng.normal(size=i - qs)
        else:
            q[qs:qe] = rng.uniform(-1.2, 1.2, qe - qs)
    return q, rng.normal(size=model.n_v), rng.normal(size=model.n_v)


# --------------------------------------------------------------------------- the model
def test_a_ball_joint_has_four_coordinates_and_three_velocities():
    """n_q = 4 and n_v = 3 per ball joint; its quaternion's index; the neutral configuration
    the identity; locking a ball at a quaternion welds the body at that rotation."""
    chain = ball_chain()
    assert (chain.n_q, chain.n_v) == (12, 9)
    assert chain.quaternions.tolist() == [0, 4, 8]
    assert chain.neutral().tolist() == [1.0, 0, 0, 0] * 3
    robot = ball_robot()
    assert (robot.n_q, robot.n_v) == (7 + 2 * (4 + 1 + 4) + 2, 6 + 2 * (3 + 1 + 3) + 2)
    rng = np.random.default_rng(3)
    q, v, tau = random_state(rng, chain)
    held = chain.locked({"ball1": q[4:8]})
    assert (held.n_q, held.n_v) == (8, 6)
    # the frame of the last body, locked or not, at the same configuration
    free_pose = rbda.kinematics(chain, q, np.zeros(chain.n_v))
    held_pose = rbda.kinematics(held, np.concatenate((q[:4], q[8:])), np.zeros(held.n_v))
    assert np.abs(free_pose.R[2] - held_pose.R[1]).max() < 1e-14
    assert np.abs(free_pose.O[2] - held_pose.O[1]).max() < 1e-14


@pytest.mark.parametrize("name", list(MODELS))
def test_identities_with_ball_joints(name):
    """Inverse of forward returns tau; the compiled qdd equals the readable recursions'
    (rbda); the GIM by composite bodies equals the one assembled from inverse dynamics (tau(q,
    0, e_i) - tau(q, 0, 0), column by column); T = v^T I v / 2."""
    model = MODELS[name]()
    rng = np.random.default_rng(stable_seed("ball-identities", name))
    for _ in range(3):
        q, v, tau = random_state(rng, model)
        qdd = forward_dynamics(model, q, v, tau)
        assert rel(rbda.forward_dynamics(model, q, v, tau), qdd) < 1e-12
        assert rel(inverse_dynamics(model, q, v, qdd), tau) < 1e-12
        M = mass_matrix(model, q)
        zero = np.zeros(model.n_v)
        bias = inverse_dynamics(model, q, zero, zero)
        cols = np.array([inverse_dynamics(model, q, zero, e) - bias
                         for e in np.eye(model.n_v)]).T
        assert rel(cols, M) < 1e-12
        T, _ = energy(model, q, v)
        assert T == pytest.approx(0.5 * v @ M @ v, rel=1e-12)


def test_a_batch_of_ball_jointed_states_is_its_single_calls():
    """Forward dynamics of 40 states at once (the SIMD tiles of a tree, and row by row) against
    one call each; the evaluator's (the lean entries) in the bits of the public functions."""
    model = ball_robot()
    rng = np.random.default_rng(stable_seed("ball-batch"))
    Q, V, T = (np.array(x) for x in zip(*(random_state(rng, model) for _ in range(40)),
                                        strict=True))
    want = np.array([forward_dynamics(model, Q[i], V[i], T[i]) for i in range(40)])
    assert rel(forward_dynamics(model, Q, V, T), want) < 1e-12
    assert np.array_equal(forward_dynamics(model, Q, V, T, simd=False), want)
    fd, inv = evaluator(model), evaluator(model, "inverse_dynamics")
    assert np.array_equal(fd(Q[0], V[0], T[0]), want[0])
    assert np.array_equal(inv(Q[0], V[0], want[0]), inverse_dynamics(model, Q[0], V[0], want[0]))


def test_the_quaternion_moves_as_q_times_the_angular_velocity():
    """A ball-jointed body's frame at q + h dq/dt (dq/dt = q (x) [0; w] / 2) is its frame at q
    turned by h w in its own axes, to first order: R(q)^T dR/dt = [w]x (a central difference)."""
    model = ball_chain()
    rng = np.random.default_rng(5)
    q, v, _ = random_state(rng, model)
    qdot = rbda.configuration_rate(model, q, v)
    h = 1e-6
    frames = [rbda.kinematics(model, q + s * h * qdot, np.zeros(model.n_v)).R for s in (-1, 1)]
    R = rbda.kinematics(model, q, np.zeros(model.n_v)).R
    w_parent = np.zeros(3)  # the parent's angular velocity in the world frame
    for k in range(model.n_bodies):
        W = R[k].T @ (frames[1][k] - frames[0][k]) / (2 * h)  # the body's [w_k]x in its frame
        w_body = np.array([W[2, 1], W[0, 2], W[1, 0]])
        assert np.abs(w_body - R[k].T @ w_parent - v[3 * k:3 * k + 3]).max() < 1e-8
        w_parent = R[k] @ w_body


# --------------------------------------------------------------------------- runs
def test_a_ball_chain_keeps_its_energy_and_steps_alike_compiled_and_python():
    """A ball-jointed chain swinging under gravity: the compiled and the Python stepping take
    the same steps to the same bits (quaternions projected after every step in both), each
    quaternion stays unit, and the energy is kept to the integrator's tolerance."""
    model = ball_chain()
    rng = np.random.default_rng(stable_seed("ball-run"))
    q0, v0, _ = random_state(rng, model)
    a, _ = _compiled_and_python_runs(model, 0.5, q0=q0, v0=v0, integrator="dop853",
                                     rtol=1e-10, atol=1e-12)
    norms = np.array([np.linalg.norm(a.q[:, i:i + 4], axis=1) for i in model.quaternions])
    assert np.abs(norms - 1.0).max() < 1e-15 * 4
    assert np.abs(a.energy - a.energy[0]).max() < 1e-8 * np.abs(a.energy).max()
    _compiled_and_python_runs(model, 0.3, q0=q0, v0=v0, integrator="rk4", h=1e-3)


def test_a_floating_ball_robot_keeps_its_angular_momentum_without_gravity():
    """Gravity off, no forces: the angular momentum about the centre of mass and the linear
    momentum are constant, and the energy is kept."""
    model = ball_robot(gravity=(0.0, 0.0, 0.0))
    rng = np.random.default_rng(stable_seed("ball-momentum"))
    q0, v0, _ = random_state(rng, model)
    run = Simulator(model, 0.5, q0=q0, v0=v0, integrator=Integrator("dop853", rtol=1e-11,
                                                                    atol=1e-13),
                    sample=0.05, observe={"momentum": momentum_observer(model)}).run()
    assert run.status == 0
    h = run.observed["momentum"]
    scale = np.abs(h).max()
    assert scale > 0.1  # it moves
    assert np.abs(h - h[0]).max() < 1e-8 * scale
    assert np.abs(run.energy - run.energy[0]).max() < 1e-8 * np.abs(run.energy).max()


def test_ball_joints_bad_settings_and_states_are_named():
    """A spring on a ball joint (its q is a quaternion) and a quaternion off the unit sphere
    in q0 are refused by name; a zero quaternion in a dynamics call too."""
    model = ball_chain()
    with pytest.raises(SettingsError, match="ball joint 'ball0'.*not on a free or ball joint"):
        System(model, stiffness=1.0)
    q0 = model.neutral()
    q0[4:8] = [2.0, 0.0, 0.0, 0.0]
    with pytest.raises(StateError, match=r"q0\[4:8\].*joint 'ball1', has norm 2"):
        Simulator(model, 0.1, q0=q0)
    q0[4:8] = 0.0
    with pytest.raises(StateError, match="ball joint 'ball1' is zero"):
        forward_dynamics(model, q0, np.zeros(model.n_v))


# --------------------------------------------------------------------------- files
def test_what_a_file_cannot_hold_of_a_ball_joint_is_refused_by_name():
    """URDF has no ball joint; MJCF's has no ref (an initial quaternion other than the
    identity) and MuJoCo refuses a rotation after a ball in one body (a massless body on a ball
    merged into its child on a hinge)."""
    with pytest.raises(ExportError, match="joint 'ball0'.type.*URDF has no ball"):
        to_urdf(ball_chain())
    chain = ball_chain()
    q0 = chain.neutral()
    q0[4:8] = [0.0, 1.0, 0.0, 0.0]
    object.__setattr__(chain, "initial_q", q0)
    with pytest.raises(ExportError, match="joint 'ball1'.*MJCF's ball joint has no ref"):
        to_mjcf(chain)
    rng = np.random.default_rng(7)
    merged = Model.build([Body("frame", 0.0, physical=False), _body(rng, "arm")],
                         [TreeJoint("s", "ball"), TreeJoint("h", "R", "y", None, (0.2, 0, 0))],
                         [-1, 0])
    with pytest.raises(ExportError, match="joint 's'.*a ball joint followed"):
        to_mjcf(merged)


def test_the_engines_without_a_ball_joint_refuse_it_by_name():
    """DART, Drake and Exudyn refuse a ball-jointed model in ``limits``, before anything is
    built, naming the body, the joint and why."""
    from redysim.references import ENGINES

    for name in ("dart", "drake", "exudyn"):
        lim = ENGINES[name].limits(ball_robot())
        assert not lim.ok
        assert "joint 'left_thigh_joint' (ball): a ball joint" in lim.reason, lim.reason
    for name in ("mujoco", "pinocchio-aba", "pinocchio-crba"):
        assert ENGINES[name].limits(ball_robot()).ok


@pytest.mark.engine
@pytest.mark.parametrize("name", list(MODELS))
def test_an_mjcf_round_trip_keeps_the_ball_joints(tmp_path, name):
    """to_mjcf writes each ball as MuJoCo's ball joint at its anchor; read back (MuJoCo's
    compiler, our reader) it has the same q layout, GIM and qdd."""
    from redysim.io.kinds import load_model

    model = MODELS[name]()
    path = tmp_path / "ball.xml"
    path.write_text(to_mjcf(model))
    back = load_model(path)
    balls = [name for name, t in zip(model.joint_names, model.joint_types, strict=True)
             if t == "ball"]
    assert [name for name, t in zip(back.joint_names, back.joint_types, strict=True)
            if t == "ball"] == balls  # (a U joint reads back as two hinges)
    assert (back.n_q, back.n_v) == (model.n_q, model.n_v)
    rng = np.random.default_rng(stable_seed("ball-mjcf", name))
    for _ in range(3):
        q, v, tau = random_state(rng, model)
        assert rel(mass_matrix(back, q), mass_matrix(model, q)) < 1e-12
        assert rel(forward_dynamics(back, q, v, tau), forward_dynamics(model, q, v, tau)) < 1e-11


@pytest.mark.engine
@pytest.mark.parametrize("engine", ["mujoco", "pinocchio-aba", "pinocchio-crba"])
@pytest.mark.parametrize("name", list(MODELS))
def test_qdd_with_ball_joints_agrees_with_the_engines(engine, name):
    """qdd, the GIM and the energy against MuJoCo (mjJNT_BALL) and Pinocchio
    (JointModelSpherical, its quaternion w last), each building the core's model."""
    from redysim.references import ENGINES

    model = MODELS[name]()
    eng = ENGINES[engine](model)
    rng = np.random.default_rng(stable_seed("ball-engines", name))
    for _ in range(3):
        q, v, tau = random_state(rng, model)
        assert rel(eng.qdd(q, v, tau), forward_dynamics(model, q, v, tau)) < 1e-10
        assert rel(eng.mass_matrix(q), mass_matrix(model, q)) < 1e-12
        T, V = eng.energy(q, v)
        assert np.allclose((T, V), energy(model, q, v), rtol=1e-12, atol=1e-12)


@pytest.mark.engine
def test_an_mjcf_ball_joint_away_from_its_body_origin_is_read(tmp_path):
    """A ball joint with an anchor ``pos`` after a hinge in one body (MuJoCo refuses a hinge
    after a ball: "ball followed by rotation"), and one in a child body: qdd equals MuJoCo's own
    on the file (q its qpos, v its qvel)."""
    import mujoco

    from redysim.io.kinds import load_model

    text = """<mujoco><option gravity="0.3 -0.2 -9.81"/><worldbody>
<body name="a" pos="0.1 0.2 0.3" euler="10 20 30"><joint name="h" axis="0 1 0" pos="0.1 0 0"/>
<joint name="s" type="ball" pos="0 0 0.2"/>
<inertial pos="0.2 0.05 0" mass="1.5" diaginertia="0.1 0.2 0.25"/>
<body name="b" pos="0.4 0 0"><joint name="s2" type="ball" pos="0.05 0 0"/>
<inertial pos="0.2 0 0.1" mass="0.8" diaginertia="0.05 0.06 0.07" euler="5 0 0"/></body>
</body></worldbody></mujoco>"""
    path = tmp_path / "ball.xml"
    path.write_text(text)
    model = load_model(path)
    assert model.joint_types[-1] == "ball" and model.n_q == 9 and model.n_v == 7
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(11)
    for _ in range(3):
        q, v, tau = random_state(rng, model)
        d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
        mujoco.mj_forward(m, d)
        assert rel(forward_dynamics(model, q, v, tau), d.qacc) < 1e-10
