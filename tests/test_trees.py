"""Kinematic trees: the Model, the reference recursions (redysim.algorithms.rbda) and the importers.

Three ways, as everywhere here: the tree recursions on a chain against the chain's own compiled
kernels (an independent implementation); identities (fused fixed joints, inverse of forward,
T = v^T I v / 2, dq/dt of a quaternion); and agreement with engines on models no one here wrote:
the robots of ``example-robot-data`` read by Pinocchio's URDF parser and ours (MuJoCo's), and an
MJCF tree in MuJoCo.
"""

from __future__ import annotations

from importlib import metadata

import numpy as np
import pytest
from conftest import random_chain, random_inertia, random_state, rel, stable_seed
from scipy.spatial.transform import Rotation

from redysim import (
    Workspace,
    forward_dynamics,
    generalized_momentum,
    inverse_dynamics,
    mass_matrix,
    rbda,
    tip,
    udu_factors,
)
from redysim import energy as system_energy
from redysim.errors import CaseError, FieldError
from redysim.io.importers import ModelFileError, load_urdf
from redysim.io.kinds import load_model
from redysim.model.tree import Body, Model, TreeJoint

MIXES = [("R",), ("U",), ("S",), ("P",), ("R", "U", "S", "P")]


# --------------------------------------------------------------------------- chains as trees
@pytest.mark.parametrize("mix", MIXES, ids="".join)
@pytest.mark.parametrize("n_links", [1, 2, 10, 40])
def test_the_tree_recursions_on_a_chain_are_the_chain_kernels(mix, n_links):
    """qdd, tau, GIM, energy and tip of a chain by the tree's reference recursions
    (redysim.rbda) equal the chain's compiled kernels, which it runs as a serial tree: to 1e-12
    relative where cond2 < 1e3, else within cond2 x 10 eps (near-singular S chains)."""
    rng = np.random.default_rng(stable_seed("tree-chain", mix, n_links))
    chain = model = random_chain(rng, n_links, mix)
    q, qd, tau = random_state(rng, chain, "wide")
    gim = mass_matrix(chain, q)
    tol = max(1e-12, 10 * np.linalg.cond(gim) * np.finfo(float).eps)
    qdd = forward_dynamics(chain, q, qd, tau)
    assert rel(rbda.forward_dynamics(model, q, qd, tau), qdd) < tol
    assert rel(rbda.mass_matrix(model, q), gim) < 1e-13
    assert rel(rbda.inverse_dynamics(model, q, qd, qdd), inverse_dynamics(chain, q, qd, qdd)) \
        < tol
    assert np.allclose(rbda.energy(model, q, qd), system_energy(chain, q, qd), rtol=1e-13,
                       atol=1e-13)
    assert np.allclose(rbda.frame_position(model, q, "tip"), tip(chain, q, qd).position,
                       rtol=0, atol=1e-13)
    assert model.is_chain and model.n_q == model.n_v == chain.n_dof
    assert Workspace(chain).tree.serial == 1  # the kernels then read no tree table


# --------------------------------------------------------------------------- random trees
def random_tree(seed, n_bodies=8, free=True, fixed=2):
    """A branched tree: a free (or fixed-to-the-world) base, R, P, U, S joints about random
    axes placed by random transforms, and ``fixed`` welded bodies."""
    rng = np.random.default_rng(seed)
    bodies, joints, parents = [], [], []
    types = ["R", "P", "U", "S"]
    for k in range(n_bodies):
        m = rng.uniform(0.3, 2.0)
        bodies.append(Body(f"b{k}", m, tuple(rng.normal(scale=0.1, size=3)),
                           tuple(map(tuple, random_inertia(rng, m, rng.uniform(0.2, 0.8))))))
        if k == 0:
            joints.append(TreeJoint("base", "free" if free else "R", None if free else "y"))
            parents.append(-1)
            continue
        jtype = "fixed" if k > n_bodies - 1 - fixed else str(rng.choice(types))
        axis = tuple(rng.normal(size=3)) if jtype in ("R", "P") else None
        R = Rotation.random(random_state=rng).as_matrix()
        joints.append(TreeJoint(f"j{k}", jtype, axis, tuple(map(tuple, R)),
                                tuple(rng.normal(scale=0.3, size=3))))
        parents.append(int(rng.integers(0, k)))
    return Model.build(bodies, joints, parents, gravity=(0.2, -9.81, 0.4), name="tree")


def random_configuration(rng, model):
    q = model.neutral()
    for k, t in enumerate(model.joint_types):
        qs, qe = model.joint_qoff[k], model.joint_qoff[k + 1]
        if t == "free":
            x, y, z, w = Rotation.random(random_state=rng).as_quat()
            q[qs:qs + 7] = [*rng.normal(size=3), w, x, y, z]
        else:
            q[qs:qe] = rng.uniform(-1.2, 1.2, qe - qs)
    return q


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("free", [True, False])
def test_identities_on_random_trees(seed, free):
    """Inverse of forward returns tau; the GIM by composite bodies equals the one assembled from
    inverse dynamics, column by column; T = v^T I(q) v / 2."""
    model = random_tree(stable_seed("tree", seed), free=free)
    rng = np.random.default_rng(seed)
    q, v, tau = random_configuration(rng, model), rng.normal(size=model.n_v), \
        rng.normal(size=model.n_v)
    vdot = rbda.forward_dynamics(model, q, v, tau)
    scale = np.abs(rbda.mass_matrix(model, q)).max() * np.abs(vdot).max() + np.abs(tau).max()
    assert np.abs(rbda.inverse_dynamics(model, q, v, vdot) - tau).max() < 1e-12 * scale
    M = rbda.mass_matrix(model, q)
    bias = rbda.inverse_dynamics(model, q, np.zeros(model.n_v), np.zeros(model.n_v))
    cols = np.array([rbda.inverse_dynamics(model, q, np.zeros(model.n_v), e) - bias
                     for e in np.eye(model.n_v)]).T
    assert rel(cols, M) < 1e-12
    assert np.allclose(M, M.T, rtol=0, atol=0)
    T, _ = rbda.energy(model, q, v)
    assert T == pytest.approx(0.5 * v @ M @ v, rel=1e-12)


@pytest.mark.parametrize("seed", range(4))
def test_generalized_momentum_on_trees(seed):
    """p = I(q) v on a tree (branches gathered into their parents) against the reference
    recursions' GIM; dp/dt = dL/dq + tau along forward dynamics' motion (central difference,
    one Richardson step); a free joint's gradient is refused by name (its q is a quaternion)."""
    model = random_tree(stable_seed("tree", seed), free=False)
    rng = np.random.default_rng(seed)
    q, v, tau = random_configuration(rng, model), rng.normal(size=model.n_v), \
        rng.normal(size=model.n_v)
    assert rel(generalized_momentum(model, q, v), rbda.mass_matrix(model, q) @ v) < 1e-12
    vdot = forward_dynamics(model, q, v, tau)
    h = 1e-3 / (1.0 + np.abs(v).max() + np.sqrt(np.abs(vdot).max()))

    def central(h):
        p = [generalized_momentum(model, q + s * h * v + 0.5 * h * h * vdot, v + s * h * vdot)
             for s in (-1.0, 1.0)]
        return (p[1] - p[0]) / (2 * h)

    _, grad = generalized_momentum(model, q, v, gradient=True)
    assert rel((4 * central(h / 2) - central(h)) / 3, grad + tau) < 1e-9
    floating = random_tree(stable_seed("tree", seed), free=True)
    qf = random_configuration(rng, floating)
    vf = rng.normal(size=floating.n_v)
    assert rel(generalized_momentum(floating, qf, vf), rbda.mass_matrix(floating, qf) @ vf) \
        < 1e-12
    with pytest.raises(FieldError, match="quaternion"):
        generalized_momentum(floating, qf, vf, gradient=True)


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("free", [True, False])
def test_compiled_kernels_on_trees_equal_the_reference_recursions(seed, free):
    """The compiled kernels (one source for chains and trees) against redysim.algorithms.rbda on
    branched trees, free base or not: qdd, GIM, inverse dynamics, energy, and the U D U^T
    factors."""
    model = random_tree(stable_seed("tree-kernels", seed), n_bodies=10, free=free)
    assert not model.is_chain
    rng = np.random.default_rng(seed)
    q, v, tau = random_configuration(rng, model), rng.normal(size=model.n_v), \
        rng.normal(size=model.n_v)
    vdot = forward_dynamics(model, q, v, tau)
    M = mass_matrix(model, q)
    assert rel(vdot, rbda.forward_dynamics(model, q, v, tau)) < 1e-12
    assert rel(M, rbda.mass_matrix(model, q)) < 1e-13
    assert np.array_equal(M, M.T)
    assert rel(inverse_dynamics(model, q, v, vdot), rbda.inverse_dynamics(model, q, v, vdot)) \
        < 1e-12
    assert np.allclose(system_energy(model, q, v), rbda.energy(model, q, v), rtol=1e-13,
                       atol=1e-13)
    U, D = udu_factors(model, q)
    assert rel(U @ D @ U.T, M) < 1e-13
    assert np.array_equal(np.tril(U, -1), np.zeros_like(U))


def test_a_quaternion_off_the_unit_sphere_is_normalised():
    """An integrator's stage leaves a free joint's quaternion slightly off norm 1: the kernels
    read its direction (as MuJoCo does), so a scaled quaternion gives the same dynamics."""
    model = random_tree(stable_seed("tree-norm"), n_bodies=5)
    rng = np.random.default_rng(3)
    q, v = random_configuration(rng, model), rng.normal(size=model.n_v)
    scaled = q.copy()
    scaled[model.quaternions[0]:model.quaternions[0] + 4] *= 1.0 + 1e-6
    assert rel(forward_dynamics(model, scaled, v), forward_dynamics(model, q, v)) < 1e-13


def test_a_fixed_joint_is_fused_as_a_locked_one():
    """Welding a body (fixed) gives the dynamics of the same tree with that joint held at zero:
    its GIM is the locked tree's without the locked row and column, its bias too."""
    rng = np.random.default_rng(4)
    bodies = [Body(f"b{k}", rng.uniform(0.5, 2), tuple(rng.normal(scale=0.1, size=3)),
                   tuple(map(tuple, random_inertia(rng, 1.0, 0.5)))) for k in range(4)]
    R = tuple(map(tuple, Rotation.random(random_state=rng).as_matrix()))

    def tree(mid):
        joints = [TreeJoint("a", "R", "z"), TreeJoint("b", mid, "x" if mid == "R" else None, R,
                                                      (0.4, 0.1, 0.0)),
                  TreeJoint("c", "R", (1.0, 1.0, 0.0), translation=(0.3, 0, 0)),
                  TreeJoint("d", "P", "y", translation=(0.0, 0.2, 0.1))]
        return Model.build(bodies, joints, [-1, 0, 1, 1],
                           frames={"end": (2, (0.3, 0.0, 0.0))})

    welded, locked = tree("fixed"), tree("R")
    assert welded.n_bodies == 3 and welded.n_v == 3 and locked.n_v == 4
    q = np.array([0.3, -0.7, 0.2])
    qlocked = np.insert(q, 1, 0.0)
    keep = [0, 2, 3]
    assert rel(rbda.mass_matrix(welded, q),
               rbda.mass_matrix(locked, qlocked)[np.ix_(keep, keep)]) < 1e-14
    v = np.array([0.5, -1.0, 0.8])
    bias_w = rbda.inverse_dynamics(welded, q, v, np.zeros(3))
    bias_l = rbda.inverse_dynamics(locked, qlocked, np.insert(v, 1, 0.0), np.zeros(4))[keep]
    assert rel(bias_w, bias_l) < 1e-14
    assert np.allclose(rbda.frame_position(welded, q, "end"),
                       rbda.frame_position(locked, qlocked, "end"), atol=1e-15)
    assert welded.total_mass == pytest.approx(locked.total_mass, rel=1e-15)


def test_the_quaternion_rate_is_the_derivative_of_the_rotation():
    """dq/dt of a free joint, integrated over a short time, turns the body by its angular
    velocity in its own frame: R(t + dt) = R(t) exp(C(w_body) dt)."""
    model = random_tree(1, n_bodies=1, fixed=0)
    rng = np.random.default_rng(0)
    q, v = random_configuration(rng, model), rng.normal(size=6)
    dt = 1e-6
    q2 = q + dt * rbda.configuration_rate(model, q, v)
    R1, R2 = (rbda.quaternion_matrix(*x[3:7] / np.linalg.norm(x[3:7])) for x in (q, q2))
    expected = R1 @ Rotation.from_rotvec(v[3:] * dt).as_matrix()
    assert np.abs(R2 - expected).max() < 1e-11
    assert np.allclose(q2[:3], q[:3] + dt * v[:3], atol=1e-15)


# --------------------------------------------------------------------------- bad trees
@pytest.mark.parametrize("make, field, fragment", [
    (lambda: Model.build([Body("a", 1.0)], [TreeJoint("j", "R")], [0]), "parents[0]",
     "must be -1"),
    (lambda: Model.build([Body("a", 1.0), Body("b", 1.0)],
                         [TreeJoint("j", "R"), TreeJoint("f", "free")], [-1, 0]),
     "joint 'f' (joints[1]).type", "free joint must hang from the base"),
    (lambda: Model.build([Body("a", 1.0)], [TreeJoint("j", "Q")], [-1]),
     "joint 'j' (joints[0]).type", "unknown joint type"),
    (lambda: Model.build([Body("a", 1.0)], [TreeJoint("j", "R", rotation=((1, 0, 0),
                                                                         (0, 1, 0),
                                                                         (0, 0, 2)))], [-1]),
     "joint 'j' (joints[0]).rotation", "must be a rotation"),
    (lambda: Model.build([Body("a", -1.0)], [TreeJoint("j", "R")], [-1]),
     "body 'a' (bodies[0]).mass", "must be >= 0"),
])
def test_a_bad_tree_is_refused_naming_the_field(make, field, fragment):
    with pytest.raises(CaseError, match=fragment) as err:
        make()
    assert err.value.field == field


# --------------------------------------------------------------------------- files
def robot_urdf(name: str) -> str:
    """The path of a URDF of the example-robot-data package (skip when it is not installed)."""
    try:
        dist = metadata.distribution("example-robot-data")
    except metadata.PackageNotFoundError:
        pytest.skip("example-robot-data is not installed (the test extra installs it)")
    hits = [f for f in dist.files if str(f).endswith("/" + name)]
    assert hits, f"no {name} in example-robot-data"
    return str(dist.locate_file(hits[0]))


ROBOTS = ["ur_description/urdf/ur5_robot.urdf", "panda_description/urdf/panda.urdf",
          "allegro_hand_description/urdf/allegro_right_hand.urdf", "solo12.urdf",
          "go1_description/urdf/go1.urdf", "talos_reduced.urdf", "talos_full_v2.urdf"]


def _pinocchio_state(model, pm, q, v, tau):
    """Our (q, v, tau) as Pinocchio's, by joint name: continuous joints as (cos, sin), a free
    joint's quaternion as (x, y, z, w) and its linear velocity and force in the body frame.
    Returns (qp, vp, taup, perm, R): perm maps our v to Pinocchio's, R the base's rotation."""
    import pinocchio as pin

    qp, vp, taup = pin.neutral(pm), np.zeros(pm.nv), np.zeros(pm.nv)
    perm, R = np.zeros(model.n_v, dtype=int), np.eye(3)
    for k, name in enumerate(model.joint_names):
        qs, vs = model.joint_qoff[k], model.joint_voff[k]
        if model.joint_types[k] == "free":
            R = rbda.quaternion_matrix(*q[qs + 3:qs + 7])
            qp[:3], qp[3:7] = q[qs:qs + 3], [*q[qs + 4:qs + 7], q[qs + 3]]
            vp[:3], vp[3:6] = R.T @ v[vs:vs + 3], v[vs + 3:vs + 6]
            taup[:3], taup[3:6] = R.T @ tau[vs:vs + 3], tau[vs + 3:vs + 6]
            perm[vs:vs + 6] = np.arange(6)
            continue
        jm = pm.joints[pm.getJointId(name)]
        if jm.nq == 2:
            qp[jm.idx_q:jm.idx_q + 2] = np.cos(q[qs]), np.sin(q[qs])
        else:
            qp[jm.idx_q] = q[qs]
        vp[jm.idx_v], taup[jm.idx_v], perm[vs] = v[vs], tau[vs], jm.idx_v
    return qp, vp, taup, perm, R


@pytest.mark.engine
@pytest.mark.parametrize("floating", [False, True], ids=["fixed", "floating"])
@pytest.mark.parametrize("urdf", ROBOTS, ids=lambda p: p.rsplit("/", 1)[-1][:-5])
def test_robots_agree_with_pinocchio(urdf, floating):
    """Real robots no one here wrote, read by two parsers (Pinocchio's and MuJoCo's): qdd, GIM
    and energy of the reference recursions against pin.aba, pin.crba and Pinocchio's energies at
    a random state, to 1e-12 relative (measured <= 3.2e-14)."""
    pin = pytest.importorskip("pinocchio")
    path = robot_urdf(urdf)
    model = load_urdf(path, floating=floating, mimic="independent")
    pm = pin.buildModelFromUrdf(path, pin.JointModelFreeFlyer()) if floating else \
        pin.buildModelFromUrdf(path)
    pd = pin.Data(pm)
    assert pm.nv == model.n_v
    rng = np.random.default_rng(stable_seed("robot", urdf, floating))
    q = random_configuration(rng, model)
    v, tau = rng.normal(size=model.n_v), rng.normal(size=model.n_v)
    qp, vp, taup, perm, R = _pinocchio_state(model, pm, q, v, tau)
    a = pin.aba(pm, pd, qp, vp, taup)
    theirs = a[perm]
    T = np.eye(model.n_v)
    if floating:  # d/dt of the world velocity R v_local
        theirs[:3] = R @ (a[:3] + np.cross(vp[3:6], vp[:3]))
        T[:3, :3] = R.T
    assert rel(rbda.forward_dynamics(model, q, v, tau), theirs) < 1e-12
    pin.crba(pm, pd, qp)
    M = np.triu(pd.M) + np.triu(pd.M, 1).T
    assert rel(rbda.mass_matrix(model, q), T.T @ M[np.ix_(perm, perm)] @ T) < 1e-12
    E = pin.computeKineticEnergy(pm, pd, qp, vp) + pin.computePotentialEnergy(pm, pd, qp)
    assert sum(rbda.energy(model, q, v)) == pytest.approx(E, rel=1e-12)


MJCF = """<mujoco model="tree">
  <option gravity="0.3 -0.2 -9.81"/>
  <worldbody>
    <body name="base" pos="0.1 0.2 1.0" quat="0.9 0.1 0.3 -0.2">
      <freejoint name="root"/>
      <geom type="box" size="0.2 0.1 0.05" density="800"/>
      <body name="arm" pos="0.2 0 0" euler="10 20 30">
        <joint name="shoulder" type="hinge" axis="0 1 1"/>
        <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03"/>
        <body name="hand" pos="0.4 0 0">
          <joint name="wrist" type="slide" axis="1 0 0"/>
          <inertial pos="0.05 0.01 0" mass="0.3" diaginertia="0.002 0.001 0.0015"/>
        </body>
      </body>
      <body name="leg" pos="-0.2 0 -0.1">
        <joint name="hip" type="hinge" axis="1 0 0"/>
        <geom type="sphere" size="0.05" pos="0 0 -0.2"/>
        <body name="foot" pos="0 0 -0.3">
          <geom type="box" size="0.05 0.03 0.02"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.engine
def test_an_mjcf_tree_agrees_with_mujoco(tmp_path):
    """An MJCF tree with a free base, inertias from geometry, a welded body (foot) and
    orientations given as euler angles: qacc and the mass matrix against MuJoCo's own, whose
    free joint has our velocity convention (world linear, body angular)."""
    mujoco = pytest.importorskip("mujoco")
    path = tmp_path / "tree.xml"
    path.write_text(MJCF)
    model = load_model(path)
    m = mujoco.MjModel.from_xml_path(str(path))
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT | \
        mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    d = mujoco.MjData(m)
    assert (model.n_q, model.n_v, model.n_bodies) == (m.nq, m.nv, 4)
    assert model.joint_names == ("root", "shoulder", "wrist", "hip")
    rng = np.random.default_rng(5)
    q = random_configuration(rng, model)
    v, tau = rng.normal(size=m.nv), rng.normal(size=m.nv)
    d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
    mujoco.mj_forward(m, d)
    assert rel(rbda.forward_dynamics(model, q, v, tau), d.qacc) < 1e-12
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    assert rel(rbda.mass_matrix(model, q), M) < 1e-12


def _urdf(tmp_path, body: str, name: str = "bad.urdf"):
    path = tmp_path / name
    path.write_text(f'<robot name="r">{body}</robot>')
    return path


LINK = '<link name="{n}"><inertial><mass value="1"/><inertia ixx="0.1" iyy="0.1" izz="0.1" ' \
       'ixy="0" ixz="0" iyz="0"/></inertial></link>'
JOINT = '<joint name="{n}" type="{t}"><parent link="{p}"/><child link="{c}"/>' \
        '<axis xyz="0 0 1"/>{extra}</joint>'


def _robot(*joints):
    links = {x for j in joints for x in (j[2], j[3])}
    return "".join(LINK.format(n=n) for n in sorted(links)) + "".join(
        JOINT.format(n=n, t=t, p=p, c=c, extra=extra) for n, t, p, c, extra in joints)


@pytest.mark.engine
@pytest.mark.parametrize("body, element, fragment", [
    ("<link name='a'>", "<xml>", "not well-formed"),
    (_robot(("j", "revolute", "a", "b", ""), ("k", "revolute", "b", "c",
                                              '<mimic joint="x"/>')),
     "joint 'k'/mimic.joint", "no joint of that name"),
    (_robot(("j", "planar", "a", "b", "")), "joint 'j'.type", "unsupported joint type"),
    (_robot(("j", "revolute", "a", "b", ""), ("k", "revolute", "c", "b", "")),
     "joint 'k'/child.link", "kinematic loop"),
    ('<link name="a"/><link name="b"/><joint name="j" type="revolute"><parent link="a"/>'
     '<child link="b"/><axis xyz="0 0 1"/></joint>', "joint 'j'", "no inertia"),
    (_robot(("j", "revolute", "a", "b", ""), ("f", "floating", "b", "c", "")),
     "joint 'f'.type", "must join a link fixed to the world"),
])
def test_a_bad_urdf_is_refused_naming_file_element_and_attribute(tmp_path, body, element,
                                                                 fragment):
    pytest.importorskip("mujoco")
    path = _urdf(tmp_path, body)
    with pytest.raises(ModelFileError, match=fragment) as err:
        load_model(path)
    assert err.value.field == element and str(err.value).startswith(str(path))


@pytest.mark.engine
def test_what_the_importer_drops_it_says():
    pytest.importorskip("mujoco")
    model = load_urdf(robot_urdf("ur_description/urdf/ur5_robot.urdf"))
    assert model.n_v == 6 and model.joint_names[0] == "shoulder_pan_joint"
    assert any(n.startswith("joint <limit> lower, upper dropped") and n.endswith("(6 joints)")
               for n in model.notes)
    assert any("visual" in n for n in model.notes)
    panda = load_urdf(robot_urdf("panda_description/urdf/panda.urdf"), mimic="independent")
    assert any("mimic" in n and "independently" in n for n in panda.notes)


def test_load_model_names_what_it_cannot_read(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_model(tmp_path / "none.urdf")
    other = tmp_path / "model.sdf"
    other.write_text("<sdf/>")
    with pytest.raises(ModelFileError, match="a model file is .urdf, .xml or .toml"):
        load_model(other)


@pytest.mark.engine
def test_redysim_info_prints_the_tree(capsys, tmp_path):
    from redysim.harness.cli import main

    pytest.importorskip("mujoco")
    path = tmp_path / "tree.xml"
    path.write_text(MJCF)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "tree: 4 bodies, n_q = 10, n_v = 9, mass 8.70767 kg, gravity (0.3, -0.2, " \
                     "-9.81)"
    assert out[1].split() == ["base", "free", "root", "[P", "x,", "P", "y,", "P", "z,", "ball",
                              "x,", "ball", "y,", "ball", "z]", "m", "=", "6.4", "kg"]
    assert out[3].startswith("      hand") and out[4].startswith("    leg")  # under their parents
    assert out[-1] == "  note: body contact geometry dropped (no contacts in the core): " \
                      "'arm', 'leg' (2 bodies)"
    assert main(["info", robot_urdf("solo12.urdf"), "--floating"]) == 0
    text = capsys.readouterr().out
    assert "n_q = 19, n_v = 18" in text and "note: joint <limit> lower, upper" in text
    assert main(["info", "STUDY-R3"]) == 0
    assert "frame tip: on link3 at (1.0, 0.0, 0.0)" in capsys.readouterr().out
    assert main(["info", robot_urdf("panda_description/urdf/panda.urdf")]) == 0  # coupled
    assert "  coupling: panda_finger_joint2 = 1 * panda_finger_joint1 + 0" in \
        capsys.readouterr().out.splitlines()
    # a chain 5,000 bodies deep (the tree was printed by recursion, which stopped at ~1,000):
    # indented 12 levels, deeper bodies by their depth
    assert main(["info", "RE-U5000-L100"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[5000].split()[:2] == ["[4999]", "link5000"]
    assert lines[5000].startswith("  " + "  " * 12 + "[4999]")


@pytest.mark.parametrize("seed", range(4))
def test_a_locked_model_is_the_full_one_with_those_joints_held(seed):
    """Locking joints (a reduced model) keeps the rest of the dynamics: the locked model's GIM
    is the full GIM's block of the free coordinates, and its qdd solves that block against the
    full model's phi with the locked velocities zero."""
    model = random_tree(stable_seed("locked", seed), n_bodies=9, free=False, fixed=0)
    rng = np.random.default_rng(seed)
    q = random_configuration(rng, model)
    names = [n for k, n in enumerate(model.joint_names) if k % 3 == 1]  # a few, root included
    names.append(model.joint_names[0])
    values = {n: q[model.joint_qoff[k]:model.joint_qoff[k + 1]]
              for k, n in enumerate(model.joint_names) if n in names}
    small = model.locked(values)
    free = np.concatenate([np.arange(model.joint_voff[k], model.joint_voff[k + 1])
                           for k, n in enumerate(model.joint_names) if n not in values])
    assert small.n_v == free.size and model.joint_names[0] not in small.joint_names
    v = np.zeros(model.n_v)
    v[free] = rng.normal(size=free.size)
    M = mass_matrix(model, q)
    assert rel(mass_matrix(small, q[free]), M[np.ix_(free, free)]) < 1e-13
    from redysim import phi
    expect = np.linalg.solve(M[np.ix_(free, free)], phi(model, q, v)[free])
    assert rel(forward_dynamics(small, q[free], v[free]), expect) < 1e-11


def test_locking_names_a_bad_joint_or_value():
    model = random_tree(stable_seed("locked-bad"), n_bodies=4, free=True, fixed=0)
    with pytest.raises(CaseError, match="no such joint"):
        model.locked({"nope": 0.0})
    with pytest.raises(CaseError, match="takes 7"):
        model.locked({"base": [0.0, 0.0]})
    with pytest.raises(CaseError, match="nothing moves"):
        model.locked({n: ([0, 0, 0, 1, 0, 0, 0] if t == "free" else np.zeros(
            model.joint_qoff[k + 1] - model.joint_qoff[k]))
            for k, (n, t) in enumerate(zip(model.joint_names, model.joint_types, strict=True))})
