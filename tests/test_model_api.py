"""The public functions take a Model as they take a Chain: the tip, any frame's motion, the joint
positions, coarse-graining; and batch shape errors say what a batch needs."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import random_chain, random_state
from test_trees import random_configuration, random_tree

from redysim import (
    CaseError,
    Chain,
    FieldError,
    Model,
    StateError,
    coarsen,
    forward_dynamics,
    frame_motion,
    inverse_dynamics,
    joint_positions,
    load_case,
    mass_matrix,
    tip,
)
from redysim.algorithms.coarse import chain_of
from redysim.algorithms.rbda import configuration_rate, frame_position

CHAIN_FIELDS = ("length", "mass", "com", "inertia_com", "gravity", "joint_qoff", "dof_kind",
                "dof_axis", "dof_u", "inertia_O", "mass_com")


def body_by_body(chain: Chain) -> Model:
    """The chain rebuilt as a plain Model, body by body (Model.build), its tip frame given:
    what the chain's own constructor must equal."""
    k = chain.n_links - 1
    return Model.build(*_parts(chain), gravity=tuple(chain.gravity), name=chain.name,
                       frames={"tip": (k, (float(chain.length[k]), 0.0, 0.0))})


@pytest.mark.parametrize("seed", range(3))
def test_a_chains_model_has_the_chains_tip_and_joint_positions(seed):
    rng = np.random.default_rng(seed)
    chain = random_chain(rng, 7)
    model = body_by_body(chain)
    assert type(model) is Model
    q, qd, _ = random_state(rng, chain)
    qdd = forward_dynamics(chain, q, qd)
    for a, b in zip(tip(chain, q, qd, qdd), tip(model, q, qd, qdd), strict=True):
        np.testing.assert_array_equal(a, b)
    np.testing.assert_array_equal(joint_positions(chain, q), joint_positions(model, q))


def test_a_model_without_a_tip_names_its_frames():
    model = random_tree(0, n_bodies=4)
    q, v = random_configuration(np.random.default_rng(0), model), np.zeros(model.n_v)
    with pytest.raises(FieldError, match=r"tip = 'tip': no such frame or body; known: .*b0.*"
                                         r"frame_motion"):
        tip(model, q, v)
    with pytest.raises(FieldError, match=r"frame = 'nose': no such frame or body"):
        frame_motion(model, q, v, frame="nose")
    assert joint_positions(model, q).shape == (model.n_bodies, 3)


@pytest.mark.parametrize("seed", range(4))
def test_frame_motion_is_the_derivative_of_the_frames_position(seed):
    """Position against rbda's plain kinematics; velocity and acceleration against central
    differences along the motion (dq/dt from v, a free joint's quaternion too; dv/dt = qdd)."""
    rng = np.random.default_rng(100 + seed)
    model = random_tree(seed, n_bodies=7)
    point = rng.normal(scale=0.3, size=3)
    body = int(rng.integers(model.n_bodies))
    model = Model.build(*_parts(model), gravity=tuple(model.gravity),
                        frames={"probe": (body, tuple(point))})
    q, v = random_configuration(rng, model), rng.normal(size=model.n_v)
    qdd = forward_dynamics(model, q, v)
    m = frame_motion(model, q, v, qdd, frame="probe")
    np.testing.assert_allclose(m.position, frame_position(model, q, "probe"), rtol=0,
                               atol=1e-13)
    qdot, h = configuration_rate(model, q, v), 1e-5

    def at(s):
        return frame_motion(model, q + s * qdot, v + s * qdd, frame="probe")

    vel = (at(h).position - at(-h).position) / (2 * h)
    acc = (at(h).velocity - at(-h).velocity) / (2 * h)
    scale = 1 + np.abs(m.velocity).max() + np.abs(m.acceleration).max()
    np.testing.assert_allclose(m.velocity, vel, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(m.acceleration, acc, rtol=0, atol=1e-7 * scale)
    # a body's name is its origin
    origin = frame_motion(model, q, v, frame=model.body_names[body])
    np.testing.assert_allclose(origin.position, m.position - _rotation(model, q, body) @ point,
                               rtol=0, atol=1e-13)


@pytest.mark.parametrize("seed", range(4))
def test_a_frames_axes_and_angular_motion_are_the_derivatives_of_its_rotation(seed):
    """frame_motion's rotation is its body's (rbda's plain kinematics) times the frame's own axes;
    its angular velocity w is what turns it, dR/dt = [w]x R, and its angular acceleration the
    derivative of w: central differences along the motion (dq/dt from v, dv/dt = qdd), on a
    random tree with a free base and on a frame of a body fused by a fixed joint."""
    from redysim.model.tree import quaternion_matrix

    rng = np.random.default_rng(200 + seed)
    model = random_tree(seed, n_bodies=7)
    body = int(rng.integers(model.n_bodies))
    quat = rng.normal(size=4)
    axes = quaternion_matrix(*(quat / np.linalg.norm(quat)))
    model = Model.build(*_parts(model), gravity=tuple(model.gravity),
                        frames={"probe": (body, tuple(rng.normal(size=3)))},
                        frame_rotations={"probe": axes})
    q, v = random_configuration(rng, model), rng.normal(size=model.n_v)
    qdd = forward_dynamics(model, q, v)
    m = frame_motion(model, q, v, qdd, frame="probe")
    np.testing.assert_allclose(m.rotation, _rotation(model, q, body) @ axes, rtol=0, atol=1e-14)
    qdot, h = configuration_rate(model, q, v), 1e-5

    def at(s):
        return frame_motion(model, q + s * qdot, v + s * qdd, frame="probe")

    dR = (at(h).rotation - at(-h).rotation) / (2 * h)
    W = dR @ m.rotation.T  # [w]x
    w = np.array([W[2, 1] - W[1, 2], W[0, 2] - W[2, 0], W[1, 0] - W[0, 1]]) / 2
    wd = (at(h).angular_velocity - at(-h).angular_velocity) / (2 * h)
    scale = 1 + np.abs(m.angular_velocity).max() + np.abs(m.angular_acceleration).max()
    np.testing.assert_allclose(m.angular_velocity, w, rtol=0, atol=1e-7 * scale)
    np.testing.assert_allclose(m.angular_acceleration, wd, rtol=0, atol=1e-7 * scale)
    # a body's name: its own axes; no qdd, no angular acceleration
    origin = frame_motion(model, q, v, frame=model.body_names[body])
    np.testing.assert_allclose(origin.rotation, _rotation(model, q, body), rtol=0, atol=1e-14)
    np.testing.assert_array_equal(origin.angular_velocity, m.angular_velocity)
    assert origin.acceleration is None and origin.angular_acceleration is None


def test_a_frame_on_a_fused_body_keeps_that_bodys_axes():
    """A frame given on a body that a fixed joint fuses into its parent keeps the fused body's
    axes (its placement's rotation, composed with the frame's own), and its point its place."""
    from redysim.model.tree import Body, TreeJoint

    R_fix = frame_R = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])  # z, 90 deg
    bodies = [Body("a", 1.0, (0.1, 0, 0), ((0.01, 0, 0), (0, 0.02, 0), (0, 0, 0.03))),
              Body("b", 0.5, (0, 0, 0), ((0.01, 0, 0), (0, 0.01, 0), (0, 0, 0.01)))]
    joints = [TreeJoint("j", "R", (0.0, 1.0, 0.0)),
              TreeJoint("w", "fixed", rotation=tuple(map(tuple, R_fix)), translation=(0.3, 0, 0))]
    model = Model.build(bodies, joints, [-1, 0], frames={"tool": (1, (0.0, 0.2, 0.0)),
                                                        "flange": (1, (0.0, 0.0, 0.0))},
                        frame_rotations={"tool": frame_R})
    q = np.array([0.4])
    Ra = _rotation(model, q, 0)
    tool = frame_motion(model, q, [0.0], frame="tool")
    np.testing.assert_allclose(tool.rotation, Ra @ R_fix @ frame_R, atol=1e-15)
    np.testing.assert_allclose(tool.position, Ra @ (np.array([0.3, 0, 0]) + R_fix @ [0, 0.2, 0]),
                               atol=1e-15)
    np.testing.assert_allclose(frame_motion(model, q, [0.0], frame="flange").rotation,
                               Ra @ R_fix, atol=1e-15)


def _parts(model: Model):
    """Bodies, joints, parents that rebuild ``model`` (no fixed joints left to fuse)."""
    from redysim.model.tree import Body, TreeJoint

    bodies, joints = [], []
    for k in range(model.n_bodies):
        bodies.append(Body(model.body_names[k], float(model.mass[k]), tuple(model.com[k]),
                           tuple(map(tuple, model.inertia_com[k])), physical=False))
        jt = model.joint_types[k]
        sl = slice(model.joint_voff[k], model.joint_voff[k + 1])
        axis = tuple(model.dof_u[sl][0]) if jt in ("R", "P") else None
        joints.append(TreeJoint(model.joint_names[k], jt, axis,
                                tuple(map(tuple, model.placement_R[k])),
                                tuple(model.placement_p[k])))
    return bodies, joints, [int(p) for p in model.parent]


def _rotation(model, q, body):
    from redysim.algorithms.rbda import kinematics

    return kinematics(model, q, np.zeros(model.n_v)).R[body]


@pytest.mark.parametrize("name", ["RE-U125-L1", "cases/refine/fall-R256.toml", "STUDY-R10"])
def test_a_chains_model_is_read_back_as_the_chain(name):
    chain = load_case(name).chain
    back = chain_of(body_by_body(chain))
    for field in CHAIN_FIELDS:
        np.testing.assert_array_equal(getattr(chain, field), getattr(back, field), err_msg=field)
    assert back.is_planar == chain.is_planar
    fine, coarse = coarsen(chain, 2 if chain.n_links % 2 == 0 else 5), \
        coarsen(body_by_body(chain), 2 if chain.n_links % 2 == 0 else 5)
    for field in CHAIN_FIELDS:
        np.testing.assert_array_equal(getattr(fine.coarse, field), getattr(coarse.coarse, field))


def test_coarsen_refuses_a_model_that_is_not_a_chain():
    with pytest.raises(CaseError, match=r"not a chain of links: body 'b\d' hangs from body \d+"):
        coarsen(random_tree(1, n_bodies=6, free=False, fixed=0), 2)
    chain = Chain.uniform(4, "U", mass=1.0)
    bent = Model.build(*_parts(chain), gravity=tuple(chain.gravity))  # no tip
    with pytest.raises(CaseError, match=r"not a chain of links: it has no frame 'tip'"):
        coarsen(bent, 2)


# --------------------------------------------------------------------------- batch shapes
def test_batch_shape_errors_say_what_a_batch_needs():
    chain = Chain.uniform(5, "U", mass=1.0)
    Q, n = np.zeros((4, chain.n_dof)), chain.n_dof
    with pytest.raises(StateError) as err:
        forward_dynamics(chain, Q, np.zeros(n))
    text = str(err.value)
    assert "q is a batch of 4 states, so v must have shape (4, 10)" in text
    assert "np.tile(v, (4, 1))" in text
    assert "must have shape (10,)" not in text  # the single state's shape is not the answer
    with pytest.raises(StateError, match=r"v has shape \(4, 10\).*q is one state; for a batch "
                                         r"of states give q as \(B, 10\) too"):
        forward_dynamics(chain, np.zeros(n), Q)
    with pytest.raises(StateError, match=r"q has shape \(4, 3\); .* has 10 configuration "
                                         r"coordinates, so q must have shape \(10,\) for one "
                                         r"state, or \(B, 10\) for a batch, one state a row"):
        forward_dynamics(chain, np.zeros((4, 3)), Q)
    with pytest.raises(StateError, match=r"qdd has shape \(3, 10\); q is a batch of 4 states"):
        inverse_dynamics(chain, Q, Q, np.zeros((3, n)))


# --------------------------------------------------------------------------- the kernels' layout
@pytest.mark.parametrize("system", ["chain", "planar", "tree"])
def test_the_workspace_packs_what_the_layout_table_declares(system):
    """Every array of the bundles, sliced by the compiled slicer's Python form out of the packed
    arrays, has the shape the table gives it and holds the system's values."""
    from redysim import Workspace
    from redysim.algorithms._kernels.bundles import FIELDS, shape_of, sizes_of
    from redysim.algorithms.workspace import tree_tables

    sys_ = {"chain": lambda: random_chain(np.random.default_rng(3), 9),
            "planar": lambda: Chain.uniform(6, "R", mass=1.0),
            "tree": lambda: random_tree(2, n_bodies=7)}[system]()
    ws = Workspace(sys_)
    t = tree_tables(sys_)
    sizes = sizes_of(t["mass"].shape[0], t["dof_kind"].shape[0], int((t["gather"] >= 0).sum()),
                     bool(t["serial"]))
    for bundle in (ws.tree, ws.s):
        for name in bundle._fields:
            if name == "serial":
                assert bundle.serial == t["serial"]
                continue
            value = getattr(bundle, name)
            assert value.shape == shape_of(FIELDS[name], sizes), name
            assert value.dtype == FIELDS[name].dtype, name
            if bundle is ws.tree:
                np.testing.assert_array_equal(value, np.asarray(t[name]).reshape(value.shape))
    np.testing.assert_array_equal(ws.base_accel, -np.asarray(sys_.gravity))
    assert (ws.planar is not None) == (system == "planar")


# --------------------------------------------------------------------------- one model type
def test_a_chain_is_a_model_and_every_model_function_takes_it():
    """A chain was a type of its own: rbda's recursions raised AttributeError on it, tip and
    joint_positions on a Model; now a Chain is a Model laid out as a chain."""
    from redysim import rbda

    rng = np.random.default_rng(7)
    chain = random_chain(rng, 6)
    assert isinstance(chain, Model)
    assert chain.chain_layout is None and chain.n_links == chain.n_bodies == 6
    q, qd, _ = random_state(rng, chain)
    qdd = forward_dynamics(chain, q, qd)
    # Two sound solutions differ by up to cond(M) * eps (cond = 1.3e6 here, so 2.9e-10 of the
    # largest qdd): rbda solves with LAPACK, whose rounding follows the BLAS kernel (1.3e-12
    # measured under OPENBLAS_CORETYPE=Sandybridge, 5.5e-13 under Haswell, Zen and SkylakeX).
    bound = np.linalg.cond(mass_matrix(chain, q)) * np.finfo(float).eps
    np.testing.assert_allclose(rbda.forward_dynamics(chain, q, qd), qdd, rtol=0,
                               atol=bound * np.abs(qdd).max())
    assert chain.locked({"joint2": np.zeros(chain.joint_qoff[2] - chain.joint_qoff[1])}).n_bodies \
        == 5


@pytest.mark.parametrize("joint", ["R", "U"])
def test_a_model_built_body_by_body_as_a_chain_is_one(joint):
    """Model.build with a chain's layout (links along x, a tip frame) has the chain's lengths,
    joints, planarity and numbers: the Chain class only builds it faster."""
    chain = Chain.uniform(5, joint, mass=2.0, length=0.3, radius=0.02, inertia="cylinder")
    model = Model.build(*_parts(chain), gravity=tuple(chain.gravity),
                        frames={"tip": (4, (0.3, 0.0, 0.0))})
    assert type(model) is Model and model.chain_layout is None
    np.testing.assert_array_equal(model.length, chain.length)
    assert model.joints == chain.joints and model.is_planar == chain.is_planar == (joint == "R")
    q = np.linspace(0.1, 0.5, chain.n_dof)
    np.testing.assert_array_equal(forward_dynamics(model, q, q), forward_dynamics(chain, q, q))
    tree = random_tree(3, n_bodies=5)
    assert "a tree" in tree.chain_layout and not tree.is_planar
    with pytest.raises(CaseError, match="length: defined for a chain of links"):
        tree.length  # noqa: B018


def test_cut_joints_belong_to_the_model():
    """A closed mechanism is its tree with cut joints: simulate closes them without being told,
    locking its joints is refused (the cuts name bodies by index), with_cuts(()) opens it."""
    from redysim import load_linkage, simulate

    link = load_linkage("cases/loops/crank_rocker.toml")
    assert link.model.cuts and link.loops.cuts == link.model.cuts
    told = simulate(link.model, 0.05, q0=link.q0, loops=link.loops, rtol=1e-8, atol=1e-10)
    own = simulate(link.model, 0.05, q0=link.q0, rtol=1e-8, atol=1e-10)
    np.testing.assert_array_equal(told.q, own.q)
    assert own.forces is not None and own.residual_q < 1e-9
    with pytest.raises(CaseError, match=r"cuts = \['coupler-rocker pin'\]: a model with cut "
                                        r"joints"):
        link.model.locked({"crank": 0.0})
    tree = link.model.with_cuts(())
    assert not tree.cuts and tree.n_bodies == link.model.n_bodies
    free = simulate(tree, 0.05, q0=link.q0, rtol=1e-8, atol=1e-10)
    assert free.forces is None


def test_a_closed_model_is_never_answered_for_as_its_tree():
    """forward_dynamics on a model with cut joints returned the open tree's qdd (the four-bar's
    crank at rest: -95.4 rad/s^2 against -39.1 with the loop closed), silently. Now it and
    inverse_dynamics refuse, naming the cuts; ClosedLoops answers with the loops closed, in
    forward_dynamics' signature (model state in, qdd out), and with the forces beside."""
    from redysim import ClosedLoops, inverse_dynamics, load_linkage

    link = load_linkage("cases/loops/crank_rocker.toml")
    q, v = link.q0, np.zeros(link.model.n_v)
    for call in (lambda: forward_dynamics(link.model, q, v),
                 lambda: inverse_dynamics(link.model, q, v, v)):
        with pytest.raises(CaseError, match=r"cuts = \['coupler-rocker pin'\]: .*cut joints"):
            call()
    loops = ClosedLoops(link.model)
    qdd = loops.forward_dynamics(q, v)
    both = loops.forward_dynamics_and_forces(q, v)
    np.testing.assert_array_equal(qdd, both[0])
    assert both[1].shape == (2,)
    open_qdd = forward_dynamics(link.model.with_cuts(()), q, v)
    assert np.abs(qdd - open_qdd).max() > 10.0  # the loop's force matters here


def test_a_simulator_runs_once_and_keeps_what_it_observes():
    """The one driver: observers see every sample, a second run() is refused (its solver is at
    the end), and a chain's tip observed equals redysim.tip at the sampled states."""
    from redysim.simulation import frame_observer, simulator

    chain = Chain.uniform(4, "U", mass=1.0, length=0.5)
    q0 = np.full(chain.n_dof, 0.2)
    sim = simulator(chain, 0.05, q0=q0, sample=0.01,
                    observe={"tip": frame_observer(chain, "tip", acceleration=True),
                             "t": lambda s: np.array([s.t])})
    res = sim.run()
    assert res.status == 0 and res.observed["tip"].shape == (6, 9)
    np.testing.assert_array_equal(res.observed["t"][:, 0], res.t)
    for i in (0, 3, 5):
        q, v = res.q[i], res.v[i]
        ref = tip(chain, q, v, forward_dynamics(chain, q, v))
        np.testing.assert_array_equal(res.observed["tip"][i], np.concatenate(ref))
    with pytest.raises(RuntimeError, match="runs once"):
        sim.run()
