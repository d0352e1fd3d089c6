"""Armature: a joint's own inertia on the diagonal of the joint-space inertia, in every entry.

Armature (``Model.armature``, one number per velocity coordinate: MuJoCo's ``dof_armature``,
Pinocchio's ``Model.armature``) enters where the kernels form an axis's joint-space inertia, in
one helper (``redysim.algorithms._kernels.joints.joint_inertia``): the pivot D = P^T Mhat P +
armature of every elimination (scalar RGE-A, its U-joint block, the lean entries, the SIMD
tiles, the DH and planar kernels), the GIM's diagonal; and as armature qdd in the torques
(``joint_force``), 1/2 armature v^2 in the kinetic energy, armature v in the generalized
momentum.

Checked here: with zero armature every entry's results are those of be08d5d, bit for bit (the
fixture ``tests/models/armature_zero_be08d5d.npz``, module's ``__main__``); with armature, each
entry against (M + A)^-1 (tau - h) from the GIM, against the readable reference
(``redysim.algorithms.rbda``), the entries against each other, inverse of forward, the energy's
rate against the power of tau, the momentum against (M + A) v, the U D U^T factors against M + A;
Pinocchio 4.1 (``pm.armature``: aba, crba) and MuJoCo (``dof_armature``) through their adapters,
and Drake (a JointActuator's rotor inertia); the adapters that cannot hold armature refuse it by
name; MJCF holds it and URDF refuses it; the Model checks it and every transformation keeps it.
"""

from __future__ import annotations

import functools
import hashlib
import sys
from pathlib import Path

import numpy as np
import pytest

import redysim
from redysim import Chain, forward_dynamics, inverse_dynamics, load_model, mass_matrix
from redysim.algorithms import rbda
from redysim.algorithms.dynamics import energy, generalized_momentum, phi, udu_factors
from redysim.errors import CaseError

HERE = Path(__file__).parent
FIXTURE = HERE / "models" / "armature_zero_be08d5d.npz"
ROOT = HERE.parent
PUMA = ROOT / "cases" / "robots" / "puma560.toml"
STANFORD = ROOT / "cases" / "robots" / "stanford_arm.toml"
BATCH = 21  # states of a batch: a full SIMD tile and a partial one
LARGE = 2000  # numbers: a larger array's SHA-256 is kept in the fixture


def _rope():
    return Chain.uniform(125, "U", length=0.02, linear_density=7850 * np.pi * 0.05**2,
                         radius=0.05)


def _tree():
    from test_trees import random_tree
    return random_tree(7, n_bodies=12, free=True)


def _planar():
    return Chain.uniform(12, "R", length=0.5, linear_density=7025 * np.pi * 0.02**2,
                         radius=0.02, inertia="cylinder")


def fixture_models() -> dict:
    """The fixture's models, built by the public API of be08d5d and of today alike."""
    sys.path.insert(0, str(HERE))
    return {"rope": _rope(), "tree": _tree(), "puma": load_model(str(PUMA)),
            "planar": _planar()}


def _state(model, seed):
    from test_trees import random_configuration
    rng = np.random.default_rng(seed)
    q = random_configuration(rng, model)
    return q, rng.normal(size=model.n_v), rng.normal(size=model.n_v)


def _batch(model, seed):
    rows = [_state(model, seed + i) for i in range(BATCH)]
    return tuple(np.array([r[i] for r in rows]) for i in range(3))


def fixture_arrays() -> dict:
    """Every entry's result on the fixture's models: forward dynamics (the entry the public
    function takes: scalar RGE-A, the DH kernel, the planar kernel), the general kernels where
    another runs (dh=False, planar=False), the evaluator, a batch in SIMD tiles and row by row,
    inverse dynamics, the GIM, the energy."""
    out = {}
    for name, m in fixture_models().items():
        q, v, tau = _state(m, 11)
        Q, V, T = _batch(m, 100)
        out[f"{name}/qdd"] = forward_dynamics(m, q, v, tau)
        out[f"{name}/qdd_general"] = forward_dynamics(m, q, v, tau, dh=False, planar=False)
        out[f"{name}/qdd_evaluator"] = redysim.evaluator(m)(q, v, tau)
        out[f"{name}/qdd_tiles"] = forward_dynamics(m, Q, V, T, threads=1)
        out[f"{name}/qdd_rows"] = forward_dynamics(m, Q, V, T, threads=1, simd=False)
        out[f"{name}/tau"] = inverse_dynamics(m, q, v, tau)
        out[f"{name}/gim"] = mass_matrix(m, q)
        out[f"{name}/energy"] = np.array(energy(m, q, v))
    return out


@pytest.mark.skipif(not FIXTURE.exists(), reason="the fixture of be08d5d is not there")
def test_with_zero_armature_every_entry_gives_be08d5ds_bits():
    """A 250-DOF U rope, a branched tree with a free joint, the PUMA 560 (the DH kernels) and a
    planar chain: qdd of every entry, tau, the GIM and the energy are the arrays be08d5d gave,
    bit for bit (written by this module's ``__main__`` on a checkout of be08d5d)."""
    want = np.load(FIXTURE)
    got = fixture_arrays()
    assert sorted(got) == sorted(want.files)
    for key, a in got.items():
        assert _stored(a).tobytes() == want[key].tobytes(), key


def _stored(a: np.ndarray) -> np.ndarray:
    """What the fixture keeps of an array: the array, or for a large one (the rope's GIM and
    batches) the SHA-256 of its bytes (the fixture stays small; bits are bits)."""
    if a.size <= LARGE:
        return a
    return np.array(hashlib.sha256(np.ascontiguousarray(a).tobytes()).hexdigest())


# --------------------------------------------------------------------------- the Model
def test_the_model_checks_its_armature_naming_the_field():
    c = Chain.uniform(3, "U", length=0.5, mass=1.0, radius=0.02)
    assert np.array_equal(c.armature, np.zeros(6)) and not c.armature.flags.writeable
    for bad, fragment in ((-0.1, "armature[0] = -0.1"), (np.nan, "armature[0] = nan"),
                          ([0.1] * 5, "must be 6 numbers"), ("x", "must be numbers"),
                          ({"nope": 1.0}, "no such joint"),
                          ({"joint2": [1.0, 2.0, 3.0]}, "joint 'joint2' has 2 velocity")):
        with pytest.raises(CaseError, match="armature") as err:
            c.with_armature(bad)
        assert fragment in str(err.value), (bad, str(err.value))
    a = c.with_armature({"joint2": 0.5, "joint3": [0.1, 0.2]})
    assert np.array_equal(a.armature, [0, 0, 0.5, 0.5, 0.1, 0.2])
    assert np.array_equal(c.with_armature(0.3).armature, np.full(6, 0.3))
    b = Chain.uniform(3, "U", length=0.5, mass=1.0, radius=0.02, armature=0.3)
    assert np.array_equal(b.armature, np.full(6, 0.3))


def test_every_transformation_keeps_the_armature():
    from redysim import Coupling
    from redysim.algorithms.coarse import coarsen
    arm = np.arange(1.0, 11.0) / 10
    c = Chain.uniform(5, "U", length=0.4, mass=1.0, radius=0.02, armature=arm)
    assert np.array_equal(c.free_tree.armature, arm)
    assert np.array_equal(c.tree.armature, arm)
    r = Chain.uniform(4, "R", length=0.4, mass=1.0, radius=0.02, armature=[1, 2, 3, 4])
    assert np.array_equal(r.with_couplings([Coupling("joint2", "joint1", 2.0)]).armature,
                          [1, 2, 3, 4])
    locked = c.locked({"joint2": [0.1, 0.2]})
    assert np.array_equal(locked.armature, np.delete(arm, [2, 3]))
    coarse = coarsen(c, links=1).coarse  # every joint after the first locked into the link
    assert np.array_equal(coarse.armature, arm[:2])
    from redysim import CutJoint
    cut = c.with_cuts([CutJoint("tip", 4, (0.4, 0.0, 0.0), -1, (1.0, 0.2, 0.0))])
    assert np.array_equal(cut.armature, arm)


# --------------------------------------------------------------------------- every entry
@functools.cache
def _armed_models():
    rng = np.random.default_rng(5)
    from conftest import random_chain
    chain = random_chain(rng, 9)
    models = {"rope": _rope(), "mixed chain": chain, "tree": _tree(),
              "puma": load_model(str(PUMA)), "stanford": load_model(str(STANFORD)),
              "planar": _planar()}
    out = {}
    for name, m in models.items():
        arm = np.random.default_rng(len(name)).uniform(0.05, 0.6, m.n_v)
        if name == "rope":
            arm *= 1e-4  # (the rope's links: 0.2 kg, 2 cm)
        if name == "tree":  # none on its free joint's translations: Pinocchio's free flyer
            arm[:3] = 0.0  # holds it on another velocity (its adapter's docstring)
        out[name] = m.with_armature(arm)
    return out


NAMES = ("mixed chain", "planar", "puma", "rope", "stanford", "tree")


def _gim_qdd(m, q, v, tau):
    """(M + A)^-1 (tau - h): the GIM with armature on its diagonal, solved densely."""
    return np.linalg.solve(mass_matrix(m, q), phi(m, q, v, tau))


@pytest.mark.parametrize("name", NAMES)
def test_every_entry_honours_armature(name):
    """The entry forward_dynamics takes (RGE-A, the DH or the planar kernel), the general
    kernels, the evaluator, SIMD tiles and rows, GE-N, all equal (M + A)^-1 (tau - h); the GIM
    is the unarmed one plus diag(A) exactly; the readable reference agrees; the U D U^T
    factors give M + A."""
    m = _armed_models()[name]
    bare = m.with_armature(None)
    q, v, tau = _state(m, 3)
    want = _gim_qdd(m, q, v, tau)
    scale = np.abs(want).max()
    M = mass_matrix(m, q)
    assert np.array_equal(M, mass_matrix(bare, q) + np.diag(m.armature))
    tol = 100 * np.finfo(float).eps * np.linalg.cond(M)  # the dense solve's own error
    for label, got in (
            ("entry", forward_dynamics(m, q, v, tau)),
            ("general", forward_dynamics(m, q, v, tau, dh=False, planar=False)),
            ("evaluator", redysim.evaluator(m)(q, v, tau)),
            ("ge-n", forward_dynamics(m, q, v, tau, method="ge-n")),
            ("rbda", rbda.forward_dynamics(m, q, v, tau))):
        assert np.abs(got - want).max() <= tol * scale, label
    assert not np.allclose(forward_dynamics(bare, q, v, tau), want, rtol=1e-6)
    Q, V, T = _batch(m, 40)
    rows = forward_dynamics(m, Q, V, T, threads=1, simd=False)
    tiles = forward_dynamics(m, Q, V, T, threads=1)
    for i in range(BATCH):
        assert rows[i].tobytes() == forward_dynamics(m, Q[i], V[i], T[i]).tobytes()
        one = _gim_qdd(m, Q[i], V[i], T[i])
        assert np.abs(tiles[i] - one).max() <= tol * np.abs(one).max(), i
    U, D = udu_factors(m, q)[:2]
    assert np.abs(U @ D @ U.T - M).max() <= 1e-12 * np.abs(M).max()
    assert np.allclose(np.diag(rbda.mass_matrix(m, q)), np.diag(M), rtol=1e-13, atol=0)


@pytest.mark.parametrize("name", NAMES)
def test_inverse_energy_and_momentum_honour_armature(name):
    """tau = (M + A) qdd + h (inverse of forward, the DH kernel's too); T = 1/2 v^T (M + A) v;
    p = (M + A) v; and along the motion dE/dt = v . tau (central differences)."""
    m = _armed_models()[name]
    q, v, tau = _state(m, 4)
    qdd = forward_dynamics(m, q, v, tau)
    for label, got in (("entry", inverse_dynamics(m, q, v, qdd)),
                       ("general", inverse_dynamics(m, q, v, qdd, dh=False)),
                       ("evaluator", redysim.evaluator(m, "inverse_dynamics")(q, v, qdd)),
                       ("rbda", rbda.inverse_dynamics(m, q, v, qdd))):
        assert np.abs(got - tau).max() <= 1e-10 * np.abs(tau).max() + 1e-12, label
    M = mass_matrix(m, q)
    T, _ = energy(m, q, v)
    assert T == pytest.approx(0.5 * v @ M @ v, rel=1e-12)
    assert T == pytest.approx(rbda.energy(m, q, v)[0], rel=1e-12)
    assert np.allclose(generalized_momentum(m, q, v), M @ v, rtol=1e-11, atol=1e-12)
    if "free" in m.joint_types:  # (a quaternion's rate is not v: the chains below do it)
        return
    h = 1e-6
    E = [sum(energy(m, q + s * h * v, v + s * h * qdd)) for s in (-1, 1)]
    assert (E[1] - E[0]) / (2 * h) == pytest.approx(v @ tau, rel=1e-5, abs=1e-7)


def test_the_reduced_precision_path_runs_with_armature():
    """The kernels' Python source (redysim.algorithms.precision) in float64 equals the compiled
    kernels with armature, on the spatial and the planar kernel."""
    from redysim.algorithms.precision import ieee_qdd
    for m in (_armed_models()["mixed chain"], _armed_models()["planar"]):
        q, v, _ = _state(m, 9)
        got = ieee_qdd(m, q, v, "rge-a", np.float64, fused_phi=True)
        want = forward_dynamics(m, q, v, planar=m.is_planar)
        assert np.allclose(got, want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


# --------------------------------------------------------------------------- engines and files
def _engine_qdd(engine_name, m, q, v, tau):
    from redysim.references import ENGINES
    return ENGINES[engine_name](m).qdd(q, v, tau)


@pytest.mark.engine
@pytest.mark.parametrize("engine", ["pinocchio-aba-ryrz", "pinocchio-crba", "mujoco", "drake",
                                    "dart", "exudyn"])
@pytest.mark.parametrize("name", ["puma", "stanford", "tree", "mixed chain"])
def test_the_engines_that_hold_armature_agree(engine, name):
    """Pinocchio (pm.armature: aba, crba), MuJoCo (dof_armature, mj_setConst) and Drake (a
    JointActuator's rotor inertia, gear ratio 1) give the core's qdd and GIM with armature;
    DART and Exudyn, which have no armature field, through (M + diag(a)) qdd = tau + phi from
    their own M and bias (their adapters' ``holds_armature``)."""
    from redysim.references import ENGINES
    m = _armed_models()[name]
    cls = ENGINES[engine]
    lim = cls.limits(m)
    if not lim.ok:
        pytest.skip(lim.reason)
    try:
        eng = cls(m)
    except Exception as exc:  # an engine not installed: its adapter says so
        if "not installed" in str(exc):
            pytest.skip(str(exc))
        raise
    q, v, tau = _state(m, 6)
    want = forward_dynamics(m, q, v, tau)
    M = mass_matrix(m, q)
    tol = 100 * np.finfo(float).eps * np.linalg.cond(M)
    assert np.abs(eng.qdd(q, v, tau) - want).max() <= tol * np.abs(want).max()
    assert np.abs(eng.mass_matrix(q) - M).max() <= 1e-10 * np.abs(M).max()
    T = energy(m, q, v)[0]
    assert eng.energy(q, v)[0] == pytest.approx(T, rel=1e-9)


@pytest.mark.engine
@pytest.mark.parametrize("engine", ["dart", "exudyn"])
def test_armature_held_in_the_qdd_only_is_refused_where_the_engine_steps(engine):
    """DART and Exudyn hold armature in their qdd, not in their own models: their native
    stepping of a model with armature, Exudyn's loop adapter (DART's holds it by its KKT solve,
    not by World.step) and armature on a free joint (whose engine coordinates are not the
    core's) are refused by name, never run without it."""
    from redysim.algorithms.loops import ClosedLoops
    from redysim.references import ENGINES, LOOP_ENGINES
    cls = ENGINES[engine]
    if not cls.available():
        pytest.skip(f"{engine} not installed")
    m = _armed_models()["mixed chain"]
    eng = cls(m)
    q, v, _ = _state(m, 2)
    with pytest.raises(ValueError, match=r"has no armature \(armature\[0\]"):
        eng.simulate(q, v, 0.01, 1e-3, integrator=list(cls.integrators)[0]
                     if not next(iter(cls.integrators.values())).adaptive else None)
    assert cls(m.with_armature(None)).no_native_armature() == ""
    tree = _armed_models()["tree"]
    arm = np.array(tree.armature)
    arm[3] = 0.2  # a rotation of the free joint
    lim = cls.limits(tree.with_armature(arm))
    assert not lim.ok and "free joint" in lim.reason and "armature" in lim.reason, lim.reason
    from redysim.algorithms.linkages import four_bar
    loops = four_bar(0.3, 0.1, 0.35, 0.3, rp=0.2, gamma=0.4, density=2.0).loops
    armed = ClosedLoops(loops.model.with_armature(0.01))
    lim = LOOP_ENGINES[engine].limits(armed)
    if engine == "exudyn":
        assert not lim.ok and "armature" in lim.reason, lim.reason
        return
    # DART's loop adapter holds it by its KKT solve on DART's M + armature (at any velocity)
    from redysim.references import loop_engine
    assert lim.ok, lim.reason
    eng = loop_engine(engine, armed)
    q = armed.project(loops.model.neutral() + 0.3, np.zeros(armed.model.n_v))[0]
    q, v = armed.project(q, np.random.default_rng(4).normal(size=armed.model.n_v))[:2]
    want = armed.forward_dynamics(q, v)
    assert np.abs(eng.forward_dynamics(q, v) - want).max() < 1e-10 * np.abs(want).max()
    bare = ClosedLoops(loops.model).forward_dynamics(q, v)
    assert np.abs(bare - want).max() > 1e-4 * np.abs(want).max()  # (the armature acts)
    with pytest.raises(Exception, match="armature"):
        eng.simulate(q, v, 0.01, 1e-3)


def test_mjcf_holds_armature_and_urdf_refuses_it():
    from redysim.io.export import ExportError, to_mjcf, to_urdf
    m = _armed_models()["mixed chain"]
    with pytest.raises(ExportError, match="armature"):
        to_urdf(m)
    text = to_mjcf(m)
    assert text.count("armature=") == m.n_v
    mujoco = pytest.importorskip("mujoco")
    mj = mujoco.MjModel.from_xml_string(text)
    assert np.array_equal(np.sort(mj.dof_armature), np.sort(m.armature))


if __name__ == "__main__":
    # The fixture, written on a checkout of be08d5d (the commit before armature):
    #   PYTHONPATH=<that checkout> python tests/test_armature.py
    # (its public functions on the models above; the models built by its own API)
    np.savez_compressed(FIXTURE, **{k: _stored(a) for k, a in fixture_arrays().items()})
    print("wrote", FIXTURE)
