"""Every reference engine on kinematic trees: the same ``redysim.Model`` built in each engine from
the Model's arrays (``references.base.Engine``: one adapter class per engine, the Model its one
input), compared stage by stage with the core.

Models: robots of example-robot-data read by our importer (UR5, Panda, the Allegro hand, Solo12
with a fixed and with a floating base, Go1 floating, Talos reduced with a fixed base and Talos
full floating), and seeded random branched trees (R, P, U and S joints about random axes,
random placements, welded bodies; a free and a fixed base; bodies not in depth-first order). At
seeded random states (a random quaternion for a free joint; q, v, tau otherwise uniform and
normal), each stage is compared separately, the engine answering in the core's coordinates
(a free joint's (x, y, z, qw, qx, qy, qz) and (v_world, w_body), converted in each adapter):

- ``qdd``: ``eng.qdd(q, v, tau)`` vs ``redysim.forward_dynamics``,  max|diff| / max|qdd|
- ``gim``: ``eng.mass_matrix(q)`` vs ``redysim.mass_matrix``,       max|diff| / max|I|
- ``phi``: ``eng.bias(q, v)`` vs ``redysim.phi`` (tau = 0),          max|diff| / max|phi|
- ``energy``: (T, V) vs ``redysim.energy``,                          |diff| / (|T| + |V|)

Each engine has ONE tolerance for every stage (``engine_chains.TOLERANCE``, its ``trees``
column). Where an engine cannot build a model, its ``limits`` must refuse it with the reason, and
the test checks that refusal (never a skip). Beside the stages: a Case or Chain goes to the same
class as a Model (converted at the door, the same numbers bit for bit), frame positions, and
each engine's native ``simulate`` on trees and chains, which must converge to the core's motion
at the order of its integrator.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
import pytest
from conftest import rel, stable_seed
from engine_chains import TOLERANCE as ENGINE_TOLERANCE
from engine_chains import engine_or_skip, engine_test_chain
from scipy.integrate import solve_ivp
from test_model_api import body_by_body
from test_trees import random_configuration, random_tree, robot_urdf

import redysim
from redysim import references
from redysim.algorithms.rbda import configuration_rate, frame_position, quaternion_matrix
from redysim.model.tree import Body, Model, TreeJoint
from redysim.references import EngineLimitExceeded, Limits

pytestmark = pytest.mark.engine

# --------------------------------------------------------------------------- tolerances
# One per engine for every stage, and why: engine_chains.TOLERANCE (the O(n) recursions 1e-11;
# the dense solves the bound, 1e-10).
TOLERANCE = {name: tol.trees for name, tol in ENGINE_TOLERANCE.items()}
assert max(TOLERANCE.values()) <= 1e-10

ROBOTS = {  # id -> (file in example-robot-data, floating base)
    "ur5": ("ur_description/urdf/ur5_robot.urdf", False),
    "panda": ("panda_description/urdf/panda.urdf", False),
    "allegro": ("allegro_hand_description/urdf/allegro_right_hand.urdf", False),
    "solo12": ("solo12.urdf", False),
    "solo12-floating": ("solo12.urdf", True),
    "go1-floating": ("go1_description/urdf/go1.urdf", True),
    "talos-reduced": ("talos_reduced.urdf", False),
    "talos-full-floating": ("talos_full_v2.urdf", True),
}
# random branched trees (test_trees.random_tree): id -> (seed, free base); 12 bodies, 2 welded
TREES = {"tree-free": (1, True), "tree-fixed": (2, False)}
MODELS = (*ROBOTS, *TREES)
STAGES = ("qdd", "gim", "phi", "energy")
SEEDS = (0, 1, 2)


_MODELS: dict = {}
_ENGINES: dict = {}


def model_of(model_id: str) -> Model:
    if model_id not in _MODELS:
        if model_id in ROBOTS:
            pytest.importorskip("mujoco", reason="URDF import needs MuJoCo's parser")
            path, floating = ROBOTS[model_id]
            # Panda and Talos have mimic joints (fingers, grippers): moved independently, as
            # Pinocchio's URDF parser does by default
            _MODELS[model_id] = redysim.load_model(robot_urdf(path), floating=floating,
                                                   mimic="independent")
        else:
            seed, free = TREES[model_id]
            _MODELS[model_id] = random_tree(seed, n_bodies=12, free=free)
    return _MODELS[model_id]


def engine_of(name: str, model_id: str):
    cls = engine_or_skip(name)
    key = (name, model_id)
    if key not in _ENGINES:
        model = model_of(model_id)
        assert cls.limits(model).ok, cls.limits(model).reason  # every engine takes these
        _ENGINES[key] = cls(model)
    return _ENGINES[key]


def state(model: Model, model_id: str, seed: int):
    rng = np.random.default_rng(stable_seed("engine-tree-state", model_id, seed))
    return (random_configuration(rng, model), rng.normal(size=model.n_v),
            rng.normal(size=model.n_v))


def stage_error(model, eng, stage, q, v, tau) -> float:
    if stage == "qdd":
        return rel(eng.qdd(q, v, tau), redysim.forward_dynamics(model, q, v, tau))
    if stage == "gim":
        return rel(eng.mass_matrix(q), redysim.mass_matrix(model, q))
    if stage == "phi":
        return rel(eng.bias(q, v), redysim.phi(model, q, v))
    T, V = redysim.energy(model, q, v)
    Te, Ve = eng.energy(q, v)
    return max(abs(Te - T), abs(Ve - V)) / (abs(T) + abs(V))


# --------------------------------------------------------------------------- agreement
def test_the_models_hold_what_they_say():
    """Fixed and free bases, branched trees, a random tree out of depth-first order (Pinocchio's
    CRBA needs its subtrees contiguous: the adapter reorders) with R, P, U and S joints."""
    pytest.importorskip("mujoco")
    for model_id, (_, floating) in ROBOTS.items():
        assert ("free" in model_of(model_id).joint_types) == floating, model_id
    assert {r for r in ROBOTS if model_of(r).is_chain} == {"ur5"}  # the others branch
    assert model_of("talos-full-floating").n_v == 50 and model_of("allegro").n_v == 16
    for model_id, (_, free) in TREES.items():
        m = model_of(model_id)
        assert (m.joint_types[0] == "free") == free
        assert {"R", "P", "U", "S"} <= set(m.joint_types), m.joint_types
        children_first = [k for k in range(1, m.n_bodies) if m.parent[k] != k - 1]
        assert children_first  # branched


@pytest.mark.parametrize("stage", STAGES)
@pytest.mark.parametrize("name", list(references.ENGINES))
@pytest.mark.parametrize("model_id", MODELS)
def test_stage_agrees_with_core(model_id, name, stage):
    eng = engine_of(name, model_id)
    model = model_of(model_id)
    err = max(stage_error(model, eng, stage, *state(model, model_id, s)) for s in SEEDS)
    assert err <= TOLERANCE[name], (
        f"{name} on {model_id}, {stage}: max relative difference {err:.3e} > tolerance "
        f"{TOLERANCE[name]:.0e}")


@pytest.mark.parametrize("name", list(references.ENGINES))
def test_a_free_joint_at_any_orientation(name):
    """The free joint's conversions (Pinocchio's local velocity and w-last quaternion, DART's
    rotation vector and world angular velocity, Exudyn's chart) hold at orientations where a
    fixed Euler-angle chart is singular (a quarter turn about y, x, z) and where a rotation
    vector's length is pi (a half turn), with a quaternion of norm != 1 (read as a direction)."""
    eng = engine_of(name, "tree-free")
    model = model_of("tree-free")
    q, v, tau = state(model, "tree-free", 7)
    s = np.sqrt(0.5)
    for quat in ([s, 0, s, 0], [s, s, 0, 0], [s, 0, 0, s], [0, 1, 0, 0], [0, 0.6, 0, 0.8],
                 [1, 0, 0, 0], [1.3, -0.2, 0.4, 0.1]):
        q[3:7] = quat
        for stage in STAGES:
            err = stage_error(model, eng, stage, q, v, tau)
            assert err <= TOLERANCE[name], (quat, stage, err)


def _rebuilt(model: Model, heavier: int | None = None) -> Model:
    """The model built again from its arrays (R joints and a free base only), body ``heavier``
    1e-6 heavier."""
    assert set(model.joint_types) <= {"R", "free"}
    bodies = [Body(model.body_names[i], float(model.mass[i]) * (1 + 1e-6 * (i == heavier)),
                   tuple(model.com[i]), tuple(map(tuple, model.inertia_com[i])), physical=False)
              for i in range(model.n_bodies)]
    joints = [TreeJoint(model.joint_names[i], model.joint_types[i],
                        None if model.joint_types[i] == "free" else
                        tuple(model.dof_u[model.joint_voff[i]]),
                        tuple(map(tuple, model.placement_R[i])), tuple(model.placement_p[i]))
              for i in range(model.n_bodies)]
    return Model.build(bodies, joints, [int(p) for p in model.parent],
                       gravity=tuple(model.gravity))


@pytest.mark.parametrize("name", list(references.ENGINES))
def test_wrong_model_is_caught(name):
    """Solo12 floating with one leg's body 1e-6 heavier fails the qdd stage: the comparison has
    teeth at every engine's tolerance (and the free base's conversion cannot hide an error)."""
    engine_or_skip(name)
    model = model_of("solo12-floating")
    q, v, tau = state(model, "solo12-floating", 0)
    ref = redysim.forward_dynamics(model, q, v, tau)
    same = references.get(name)(_rebuilt(model))
    assert rel(same.qdd(q, v, tau), ref) <= TOLERANCE[name]  # the rebuilt model is the model
    heavier = references.get(name)(_rebuilt(model, heavier=5))
    assert rel(heavier.qdd(q, v, tau), ref) > TOLERANCE[name]


# --------------------------------------------------------------------------- what is refused
def _massless_gimbal() -> Model:
    """A tree with a massless body between two revolute joints (a gimbal written as two R
    joints, as URDF files do), and a branch: the core and Pinocchio/Exudyn take it."""
    rng = np.random.default_rng(20261124)
    I = np.diag([0.02, 0.03, 0.04])
    bodies = [Body("base", 2.0, (0.1, 0.0, 0.0), tuple(map(tuple, I))),
              Body("gimbal", 0.0),
              Body("arm", 1.0, (0.2, 0.01, 0.0), tuple(map(tuple, I / 2))),
              Body("side", 0.5, (0.0, 0.1, 0.0), tuple(map(tuple, I / 3)))]
    joints = [TreeJoint("j0", "R", "z"), TreeJoint("j1", "R", "x", translation=(0.4, 0, 0)),
              TreeJoint("j2", "R", "y"), TreeJoint("j3", "P", tuple(rng.normal(size=3)),
                                                   translation=(0.0, 0.2, 0.1))]
    return Model.build(bodies, joints, [-1, 0, 1, 0], gravity=(0.0, 0.0, -9.81), name="gimbal")


# engine -> what its refusal must say (the engines not named here must build the model)
MASSLESS_REFUSED = {"mujoco": "mjMINVAL", "dart": "massless"}


@pytest.mark.parametrize("name", list(references.ENGINES))
def test_a_massless_body_is_built_or_refused_with_the_reason(name):
    """MuJoCo's compiler refuses a moving body with mass or inertia below mjMINVAL (even with
    massive children: measured), DART warns that a zero mass "can cause invalid physical behavior
    or segfault": their ``limits`` refuse the model, naming the body and why, and building it
    raises EngineLimitExceeded. Pinocchio and Exudyn build it and agree with the core."""
    cls = references.get(name)
    model = _massless_gimbal()
    lim = cls.limits(model)
    if name in MASSLESS_REFUSED:
        assert not lim.ok
        assert lim.reason.startswith(f"{name}: body 'gimbal'")
        assert MASSLESS_REFUSED[name] in lim.reason
        engine_or_skip(name)
        with pytest.raises(EngineLimitExceeded, match=MASSLESS_REFUSED[name]):
            cls(model)
        return
    assert lim.ok, lim.reason
    eng = engine_or_skip(name)(model)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v, tau = rng.uniform(-1.2, 1.2, 4), rng.normal(size=4), rng.normal(size=4)
        for stage in STAGES:
            assert stage_error(model, eng, stage, q, v, tau) <= TOLERANCE[name], stage


@functools.cache
def _uniform_model(n_links: int, joint: str = "U") -> Model:
    return redysim.Chain.uniform(n_links, joint, length=0.01, mass=0.1, radius=0.002,
                                 inertia="cylinder")


@pytest.mark.parametrize("name", list(references.ENGINES))
def test_a_tree_beyond_the_measured_limits_is_refused(name):
    """references/limits.toml holds for trees: DOF = n_v, links = bodies (DART), the body tree's
    depth (MuJoCo, whose limit is the depth). Decided before anything is built."""
    cls = references.get(name)
    entry = references.load_limits()["engine"][name]
    huge = _uniform_model(5001)  # 10,002 DOF: beyond every engine (Drake's 10,000 the largest)
    lim = cls.limits(huge)
    assert not lim.ok and "10,002 DOF" in lim.reason and entry["stops"] in lim.reason
    if cls.available():
        with pytest.raises(EngineLimitExceeded, match=name):
            cls(huge)
    small = _uniform_model(3)
    assert cls.limits(small).ok and references.get(name).limits(small).ok


def test_mujoco_limits_a_trees_depth_not_its_size():
    """MuJoCo's limit is the depth of its body tree (1,023): a chain of 1,024 R links is refused,
    1,100 bodies hanging from the world side by side (depth 1) are not."""
    mujoco = references.get("mujoco")
    deep = _uniform_model(1024, "R")
    lim = mujoco.limits(deep)
    assert not lim.ok and "a body tree 1,024 deep" in lim.reason
    I = ((1e-3, 0, 0), (0, 1e-3, 0), (0, 0, 1e-3))
    wide = Model.build([Body(f"b{k}", 1.0, inertia=I) for k in range(1100)],
                       [TreeJoint(f"j{k}", "R", "z", translation=(k, 0, 0)) for k in range(1100)],
                       [-1] * 1100)
    assert mujoco.limits(wide).ok
    assert not references.get("dart").limits(_uniform_model(1401, "R")).ok


# --------------------------------------------------------------------------- the interface
@pytest.mark.parametrize("name", list(references.ENGINES))
def test_one_class_takes_a_model_a_chain_or_a_case(name):
    """``references.get(name)`` is the engine's one adapter class, with no ``__new__`` handing
    out another class: a Model (the one input), a Chain built body by body as a Model, a Chain
    and a Case (its chain, taken at the door) build instances of it that answer the same
    numbers bit for bit, and its ``limits`` judge them alike. Anything else is refused naming
    its type; sizes are checked at the door; every answer is a new array (a later call leaves
    it as it was)."""
    cls = engine_or_skip(name)
    assert all("__new__" not in vars(c) for c in cls.__mro__ if c is not object)
    case = redysim.load_case("STUDY-R3")
    systems = (body_by_body(case.chain), case.chain, case)
    assert [cls.limits(x) for x in systems] == [Limits(True, "")] * 3
    engines = [cls(x) for x in systems]
    assert all(type(e) is cls and e.name == name and e.model.n_v == 3 for e in engines)
    assert all(e.identity for e in engines)  # a chain: the engine's coordinates are the core's
    rng = np.random.default_rng(stable_seed("one-class", name))
    q, v, tau = rng.uniform(-2, 2, 3), rng.normal(size=3), rng.normal(size=3)
    answers = [(e.qdd(q, v, tau), e.qdd(q, v), e.mass_matrix(q), e.bias(q, v),
                np.array(e.energy(q, v)), e.tip(q)) for e in engines]
    for got in answers[1:]:
        for a, b in zip(got, answers[0], strict=True):
            assert np.array_equal(a, b)
    before = [a.copy() for a in answers[0]]
    e = engines[0]
    e.qdd(-q, 2 * v, -tau)
    e.mass_matrix(-q)
    e.bias(-q, 2 * v)
    e.tip(-q)
    assert all(np.array_equal(a, b) for a, b in zip(answers[0], before, strict=True))
    with pytest.raises(TypeError, match="expected a redysim Model .* got str"):
        cls.limits("STUDY-R3")
    with pytest.raises(TypeError, match="got ndarray"):
        cls(np.zeros(3))
    tree = engine_of(name, "tree-free")
    model = model_of("tree-free")
    assert not tree.identity  # a free joint: converted
    with pytest.raises(ValueError, match="q has shape .*n_q = "):
        tree.qdd(np.zeros(model.n_v), np.zeros(model.n_v))
    with pytest.raises(ValueError, match="v has shape .*n_v = "):
        tree.bias(model.neutral(), np.zeros(model.n_q))


def _with_frames(model: Model, seed: int) -> Model:
    """The model with a frame on every body at a seeded point."""
    rng = np.random.default_rng(seed)
    return dataclasses.replace(model, frames={f"f{k}": (k, tuple(rng.normal(scale=0.3, size=3)))
                                              for k in range(model.n_bodies)})


@pytest.mark.parametrize("name", list(references.ENGINES))
def test_the_position_of_every_frame(name):
    """``position(q, frame)`` of every body's frame of the free random tree (and of Talos full,
    floating, whose 50 DOF reach far from the base) against the core's ``frame_position``, at
    the seeded states: kinematics only, no solve, so to 1e-14 relative to the distance from the
    origin, or 1 m (measured <= 7.4e-16, DART). A frame the model does not have is
    refused, naming it and the model's frames."""
    engine_or_skip(name)
    for model_id in ("tree-free", "talos-full-floating"):
        model = _with_frames(model_of(model_id), 11)
        eng = references.get(name)(model)
        for s in SEEDS:
            q = state(model, model_id, s)[0]
            for frame in model.frames:
                ref = frame_position(model, q, frame)
                err = np.abs(eng.position(q, frame) - ref).max() / max(1.0, np.abs(ref).max())
                assert err <= 1e-14, (model_id, frame, err)
    with pytest.raises(ValueError, match=r"no frame 'tip'; its frames: 'f0', 'f1'"):
        eng.tip(model.neutral())


# --------------------------------------------------------------------------- native simulate
# Each engine's own default integrator and its order: DART's World.step is first order, MuJoCo's
# RK4 and Exudyn's RK44 fourth order (Pinocchio has none; every integrator of every engine:
# tests/test_engines_native.py). Steps h and h/2 such that the error is well above rounding and
# in the asymptotic range: measured over 0.1 s on every model here, err(h/2)/err(h) =
# 0.4996..0.5002 (order 1, h = 1e-3 s) and 0.0615..0.0654 (order 4, h = 5e-3 s), i.e. 2^-order
# within 5 %; err(h) <= 2.4e-3 and 1.9e-8.
SIM_T_END = 0.1
SIM_ORDER = {"dart": 1, "mujoco": 4, "exudyn": 4, "drake": 2}
SIM_H = {1: 1e-3, 2: 2e-3, 4: 5e-3}
SIM_MAX_ERR = {1: 1e-2, 2: 1e-4, 4: 1e-7}
SIM_MODELS = ("chain-mix10", "tree-free", "tree-free-quarter-turn", "tree-fixed")
assert set(SIM_ORDER) == {n for n, c in references.ENGINES.items() if c.integrators}


@functools.cache
def _sim_start(model_id: str):
    """(model, q0, v0, (q, v) of the core at SIM_T_END): the core's motion by DOP853 at
    rtol = atol = 1e-13 (forward_dynamics, and configuration_rate for the quaternions)."""
    if model_id == "chain-mix10":
        model = engine_test_chain("mix", 10)
    else:
        model = model_of(model_id.replace("-quarter-turn", ""))
    rng = np.random.default_rng(stable_seed("engine-simulate", model_id))
    q0, v0 = random_configuration(rng, model), rng.normal(size=model.n_v)
    if model_id.endswith("quarter-turn"):  # a quarter turn about y: an XYZ Euler chart's pole
        q0[3:7] = [np.sqrt(0.5), 0.0, np.sqrt(0.5), 0.0]
    nq = model.n_q

    def rhs(_t, y):
        q, v = y[:nq], y[nq:]
        return np.concatenate([configuration_rate(model, q, v),
                               redysim.forward_dynamics(model, q, v)])

    sol = solve_ivp(rhs, (0.0, SIM_T_END), np.concatenate([q0, v0]), method="DOP853",
                    rtol=1e-13, atol=1e-13)
    assert sol.success
    return model, q0, v0, (sol.y[:nq, -1], sol.y[nq:, -1])


def _state_error(model: Model, q, v, ref) -> float:
    """max of |q - q_ref| (a free joint's rotation as its matrix, the quaternion's sign being
    free) and |v - v_ref| / max(1, max|v_ref|)."""
    qr, vr = ref
    errs = [np.abs(v - vr).max() / max(1.0, np.abs(vr).max())]
    for k, jtype in enumerate(model.joint_types):
        qs, qe = model.joint_qoff[k], model.joint_qoff[k + 1]
        if jtype == "free":
            R, Rr = (quaternion_matrix(*(x[qs + 3:qs + 7] / np.linalg.norm(x[qs + 3:qs + 7])))
                     for x in (q, qr))
            errs += [np.abs(q[qs:qs + 3] - qr[qs:qs + 3]).max(), np.abs(R - Rr).max()]
        else:
            errs.append(np.abs(q[qs:qe] - qr[qs:qe]).max())
    return float(max(errs))


@pytest.mark.parametrize("model_id", SIM_MODELS)
@pytest.mark.parametrize("name", list(SIM_ORDER))
def test_native_simulate_converges_to_the_core(name, model_id):
    """``simulate`` with the engine's own integrator on a chain (as its Model), on the random
    trees with a free base (from a random orientation, and from a quarter turn about y, where a
    fixed Euler-angle chart of the rotation is singular) and with a fixed one: the state
    reached at 0.1 s converges to the core's motion at the order of the engine's integrator
    (a wrong coordinate conversion would not converge), sampled as asked."""
    cls = engine_or_skip(name)
    model, q0, v0, ref = _sim_start(model_id)
    eng = cls(model)
    order = SIM_ORDER[name]
    h = SIM_H[order]
    errs = []
    for step in (h, h / 2):
        tr = eng.simulate(q0, v0, SIM_T_END, step, every=10)
        n = round(SIM_T_END / step)
        assert tr.integrator == cls.integrator
        assert np.allclose(tr.t, np.r_[0.0, np.arange(10, n + 1, 10) * step], rtol=0, atol=1e-15)
        assert tr.q.shape == (len(tr.t), model.n_q) and tr.v.shape == (len(tr.t), model.n_v)
        assert np.array_equal(tr.q[0], q0) and np.array_equal(tr.v[0], v0)
        errs.append(_state_error(model, tr.q[-1], tr.v[-1], ref))
    assert errs[0] <= SIM_MAX_ERR[order], errs
    assert 0.8 <= errs[1] / errs[0] * 2**order <= 1.25, (errs, errs[1] / errs[0])
    eng.sim_reset(q0, v0, h)  # the same stepper, a step at a time
    for _ in range(3):
        eng.step_once()
    q, v = eng.sim_state()
    three = eng.simulate(q0, v0, 3 * h, h)
    assert np.array_equal(q, three.q[-1]) and np.array_equal(v, three.v[-1])


@pytest.mark.parametrize("name", list(references.ENGINES))
def test_simulate_refuses_bad_settings(name):
    """A step, horizon or sampling that is not one is refused by name, before any step."""
    eng = engine_of(name, "tree-fixed")
    model = model_of("tree-fixed")
    q0, v0 = model.neutral(), np.zeros(model.n_v)
    for h, t_end, every, what in ((0.0, 1.0, 1, "h > 0"), (1e-3, -1.0, 1, "t_end >= 0"),
                                  (float("nan"), 1.0, 1, "finite h"),
                                  (1e-3, 1.0, 0, "every must be a whole number >= 1"),
                                  (1e-3, 1.0, 2.5, "every must be a whole number >= 1")):
        with pytest.raises(ValueError, match=what):
            eng.simulate(q0, v0, t_end, h, every=every)
    with pytest.raises(ValueError, match="q0 has shape"):
        eng.simulate(np.zeros(model.n_q + 1), v0, 1.0, 1e-3)
