"""Every reference engine on kinematic trees: the same ``redysim.Model`` built in each engine from
the Model's arrays (``references.trees``), compared stage by stage with the core.

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

Each engine has ONE tolerance for every stage (below). Where an engine cannot build a model, its
``limits`` must refuse it with the reason, and the test checks that refusal (never a skip).
"""

from __future__ import annotations

import functools

import numpy as np
import pytest
from conftest import rel, stable_seed
from test_trees import random_configuration, random_tree, robot_urdf

import redysim
from redysim import references
from redysim.model import Body, Model, TreeJoint
from redysim.references import EngineLimitExceeded, TreeEngine

pytestmark = pytest.mark.engine

# --------------------------------------------------------------------------- tolerances
# The bound is 1e-10 relative. The O(n) recursions (pin.aba, DART's ABA) measured
# <= 3.2e-13 on qdd over 150 random-tree states (50 trees of 12 bodies, R, P, U, S joints, free
# and fixed base; cond(I) up to 3.9e4) and <= 2.5e-15 on the robots: 1e-11, as for chains. The
# dense solves (Cholesky, MuJoCo's LDL, Exudyn's LU) measured <= 9.7e-13 on the random trees and
# 1.3e-13 on Talos full floating (MuJoCo; cond(I) = 1.3e7 there, so cond * eps = 3e-9 would allow
# more): 1e-10. GIM, phi and energy involve no solve and agree to <= 2e-15 in every engine.
TOL_PINOCCHIO_ABA = 1e-11
TOL_PINOCCHIO_ABA_RYRZ = 1e-11
TOL_DART = 1e-11
TOL_PINOCCHIO_CRBA = 1e-10
TOL_MUJOCO = 1e-10
TOL_EXUDYN = 1e-10
TOLERANCE = {
    "pinocchio-aba": TOL_PINOCCHIO_ABA,
    "pinocchio-aba-ryrz": TOL_PINOCCHIO_ABA_RYRZ,
    "pinocchio-crba": TOL_PINOCCHIO_CRBA,
    "mujoco": TOL_MUJOCO,
    "dart": TOL_DART,
    "exudyn": TOL_EXUDYN,
}
assert set(TOLERANCE) == set(references.TREE_ENGINES) == set(references.ENGINES)
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


def _engine_class(name) -> type[TreeEngine]:
    cls = references.TREE_ENGINES[name]
    pytest.importorskip(cls.module, reason=f"engine {name!r} needs {cls.package!r}")
    return cls


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
    cls = _engine_class(name)
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
@pytest.mark.parametrize("name", list(references.TREE_ENGINES))
@pytest.mark.parametrize("model_id", MODELS)
def test_stage_agrees_with_core(model_id, name, stage):
    eng = engine_of(name, model_id)
    model = model_of(model_id)
    err = max(stage_error(model, eng, stage, *state(model, model_id, s)) for s in SEEDS)
    assert err <= TOLERANCE[name], (
        f"{name} on {model_id}, {stage}: max relative difference {err:.3e} > tolerance "
        f"{TOLERANCE[name]:.0e}")


@pytest.mark.parametrize("name", list(references.TREE_ENGINES))
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


@pytest.mark.parametrize("name", list(references.TREE_ENGINES))
def test_wrong_model_is_caught(name):
    """Solo12 floating with one leg's body 1e-6 heavier fails the qdd stage: the comparison has
    teeth at every engine's tolerance (and the free base's conversion cannot hide an error)."""
    _engine_class(name)
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


@pytest.mark.parametrize("name", list(references.TREE_ENGINES))
def test_a_massless_body_is_built_or_refused_with_the_reason(name):
    """MuJoCo's compiler refuses a moving body with mass or inertia below mjMINVAL (even with
    massive children: measured), DART warns that a zero mass "can cause invalid physical behavior
    or segfault": their ``limits`` refuse the model, naming the body and why, and building it
    raises EngineLimitExceeded. Pinocchio and Exudyn build it and agree with the core."""
    cls = references.TREE_ENGINES[name]
    model = _massless_gimbal()
    lim = references.get(name).limits(model)
    if name in MASSLESS_REFUSED:
        assert not lim.ok
        assert lim.reason.startswith(f"{name}: body 1 (gimbal)")
        assert MASSLESS_REFUSED[name] in lim.reason
        _engine_class(name)
        with pytest.raises(EngineLimitExceeded, match=MASSLESS_REFUSED[name]):
            cls(model)
        return
    assert lim.ok, lim.reason
    eng = _engine_class(name)(model)
    rng = np.random.default_rng(3)
    for _ in range(3):
        q, v, tau = rng.uniform(-1.2, 1.2, 4), rng.normal(size=4), rng.normal(size=4)
        for stage in STAGES:
            assert stage_error(model, eng, stage, q, v, tau) <= TOLERANCE[name], stage


@functools.cache
def _uniform_model(n_links: int, joint: str = "U") -> Model:
    return Model.from_chain(redysim.Chain.uniform(n_links, joint, length=0.01, mass=0.1,
                                                  radius=0.002, inertia="cylinder"))


@pytest.mark.parametrize("name", list(references.TREE_ENGINES))
def test_a_tree_beyond_the_measured_limits_is_refused(name):
    """references/limits.toml holds for trees: DOF = n_v, links = bodies (DART), the body tree's
    depth (MuJoCo, whose limit is the depth). Decided before anything is built."""
    cls = references.TREE_ENGINES[name]
    entry = references.load_limits()["engine"][name]
    huge = _uniform_model(3001)  # 6,002 DOF: beyond every engine
    lim = cls.limits(huge)
    assert not lim.ok and "6,002 DOF" in lim.reason and entry["stops"] in lim.reason
    if cls.available():
        with pytest.raises(EngineLimitExceeded, match=name):
            cls(huge)
    small = _uniform_model(3)
    assert cls.limits(small).ok and references.get(name).limits(small).ok


def test_mujoco_limits_a_trees_depth_not_its_size():
    """MuJoCo's limit is the depth of its body tree (1,023): a chain of 1,024 R links is refused,
    1,100 bodies hanging from the world side by side (depth 1) are not."""
    mujoco = references.TREE_ENGINES["mujoco"]
    deep = _uniform_model(1024, "R")
    lim = mujoco.limits(deep)
    assert not lim.ok and "a body tree 1,024 deep" in lim.reason
    I = ((1e-3, 0, 0), (0, 1e-3, 0), (0, 0, 1e-3))
    wide = Model.build([Body(f"b{k}", 1.0, inertia=I) for k in range(1100)],
                       [TreeJoint(f"j{k}", "R", "z", translation=(k, 0, 0)) for k in range(1100)],
                       [-1] * 1100)
    assert mujoco.limits(wide).ok
    assert not references.TREE_ENGINES["dart"].limits(_uniform_model(1401, "R")).ok


# --------------------------------------------------------------------------- the interface
@pytest.mark.parametrize("name", list(references.TREE_ENGINES))
def test_a_model_goes_to_the_tree_adapter(name):
    """``references.get(name)(model)`` builds the tree adapter, as ``tree_engine(name, model)``;
    a Chain still builds the chain adapter; sizes are checked at the door."""
    _engine_class(name)
    model = model_of("tree-free")
    eng = references.get(name)(model)
    assert isinstance(eng, references.TREE_ENGINES[name]) and eng.name == name
    assert type(references.tree_engine(name, model)) is type(eng)
    chain = redysim.Chain.uniform(2, "U", mass=1.0, radius=0.1, inertia="cylinder")
    assert isinstance(references.get(name)(chain), references.get(name))
    with pytest.raises(ValueError, match="n_q"):
        eng.qdd(np.zeros(model.n_v), np.zeros(model.n_v))
    with pytest.raises(ValueError, match="n_v"):
        eng.bias(model.neutral(), np.zeros(model.n_q))
    with pytest.raises(TypeError, match="Model"):
        references.TREE_ENGINES[name](chain)
