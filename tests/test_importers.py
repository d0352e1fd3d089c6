"""The importers tell the truth: every attribute of a URDF or MJCF file that changes the motion is
honoured (agreement with MuJoCo's mj_forward / mj_fullM or Pinocchio's aba / crba at seeded random
states), announced (a line of Model.notes naming the element, the name and the value; strict=True
refuses it) or refused (a ModelFileError naming the file, the element and the value).

Tolerances: 1e-12 relative (max-norm) on the mass matrix and qacc of these small, well-conditioned
trees, as in tests/test_trees.py (measured: a few 1e-15); the engines compute the same quantities
in another order, so only round-off separates them.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from conftest import rel, stable_seed
from test_trees import random_configuration

import redysim
from redysim import forward_dynamics, inverse_dynamics, mass_matrix, passive_forces, rbda
from redysim.errors import CaseError, FieldError
from redysim.io.importers import MJCF_MAX_DEPTH, ModelFileError, load_mjcf, load_urdf
from redysim.io.kinds import load_model
from redysim.model.tree import Body, Model, TreeJoint


# --------------------------------------------------------------------------- helpers
def write(tmp_path, text, name):
    path = tmp_path / name
    path.write_text(text)
    return path


def mujoco_truth(path, q, v, tau, set_aside=False):
    """MuJoCo's qacc and mass matrix of the file at (qpos, qvel, qfrc_applied), its contacts and
    constraints off (what the tree holds: its honoured dynamics, the joints' passive forces
    included). ``set_aside``: also what an importer announces as dropped: actuators, equality
    constraints, tendons' springs and dampers, fluid forces, nonlinear damping and springs."""
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_path(str(path))
    off = mujoco.mjtDisableBit
    m.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_CONSTRAINT
    if set_aside:
        m.opt.disableflags |= off.mjDSBL_ACTUATION | off.mjDSBL_EQUALITY
        for name in ("tendon_stiffness", "tendon_damping", "tendon_stiffnesspoly",
                     "tendon_dampingpoly", "dof_dampingpoly", "jnt_stiffnesspoly"):
            getattr(m, name)[:] = 0.0
        m.opt.density = m.opt.viscosity = 0.0
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    return d.qacc.copy(), M


def assert_agrees_with_mujoco(path, model, seed, states=5, tol=1e-12, set_aside=False):
    """qacc and mass matrix at qpos0 and at seeded random (q, v, tau): q is MuJoCo's qpos."""
    rng = np.random.default_rng(seed)
    worst = 0.0
    for i in range(states):
        q = model.initial() if i == 0 else random_configuration(rng, model)
        v, tau = rng.normal(size=model.n_v), rng.normal(size=model.n_v)
        qacc, M = mujoco_truth(path, q, v, tau, set_aside)
        worst = max(worst, rel(mass_matrix(model, q), M),
                    rel(forward_dynamics(model, q, v, tau + passive_forces(model, q, v)), qacc))
    assert worst < tol, worst


def refused(call, field, *fragments, error=ModelFileError):
    """The error of ``call``: its field is ``field`` and its message has every fragment."""
    with pytest.raises(error) as err:
        call()
    assert err.value.field == field, err.value
    for fragment in fragments:
        assert fragment in str(err.value), err.value
    assert "np.float64" not in str(err.value) and "array(" not in str(err.value)
    return err.value


def notes_with(model, *fragments):
    """The notes that have every fragment (at least one)."""
    hits = [n for n in model.notes if all(f in n for f in fragments)]
    assert hits, model.notes
    return hits


def only_unread(model):
    """Nothing dropped: at most the summary of what does not act on the motion."""
    return all(n.startswith("not read (no effect on the motion)") for n in model.notes)


# --------------------------------------------------------------------------- MJCF: honoured
REF = """<mujoco><compiler angle="{angle}"/><option gravity="0 0 -9.81"/>
<worldbody><body name="a" pos="0 0 0"><joint name="h" type="hinge" axis="0 1 0" ref="{ref}"/>
<inertial pos="0.3 0 0.1" mass="2" diaginertia="0.1 0.2 0.3"/>
<body name="b" pos="0.5 0 0"><joint name="s" type="slide" axis="1 0 0" ref="0.25"/>
<inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.02 0.03"/>
<body name="c" pos="0.2 0.1 0" euler="{euler}">
<joint name="h2" type="hinge" axis="1 0 1" ref="{ref2}"/>
<inertial pos="0.1 0.05 0" mass="0.5" diaginertia="0.01 0.02 0.015"/>
</body></body></body></worldbody></mujoco>"""


@pytest.mark.engine
@pytest.mark.parametrize("angle, ref, ref2, euler", [("radian", 0.7, -1.1, "0.1 0.2 0.3"),
                                                     ("degree", 40, -63, "6 11 17")])
def test_an_mjcf_joint_ref_is_honoured(tmp_path, angle, ref, ref2, euler):
    """MuJoCo measures a hinge or slide coordinate from its ref: body pose = XML pose moved by
    qpos - ref. Before: the ref was ignored, the GIM off by 65 % and qacc by 5x at the same qpos.
    Model.initial() is MuJoCo's qpos0 (the refs, in radians)."""
    mujoco = pytest.importorskip("mujoco")
    path = write(tmp_path, REF.format(angle=angle, ref=ref, ref2=ref2, euler=euler), "ref.xml")
    model = load_model(path)
    m = mujoco.MjModel.from_xml_path(str(path))
    assert np.array_equal(model.initial(), m.qpos0)
    assert model.initial()[1] == 0.25 and model.initial()[0] == pytest.approx(
        ref if angle == "radian" else np.radians(ref), rel=1e-15)
    assert_agrees_with_mujoco(path, model, stable_seed("ref", angle), states=6)


GRAVITY_OFF = """<mujoco><option gravity="0 0 -9.81"><flag gravity="disable"/></option>
<worldbody><body name="a"><joint name="h" axis="0 1 0"/>
<inertial pos="0.3 0 0.1" mass="2" diaginertia="0.1 0.2 0.3"/></body></worldbody></mujoco>"""


@pytest.mark.engine
def test_mjcf_gravity_disabled_by_a_flag_is_honoured(tmp_path):
    """<flag gravity="disable"/>: MuJoCo has no gravity. Before: ours kept it (qacc 26x off)."""
    path = write(tmp_path, GRAVITY_OFF, "nograv.xml")
    model = load_model(path)
    assert np.array_equal(model.gravity, np.zeros(3))
    assert_agrees_with_mujoco(path, model, stable_seed("gravity-off"))


# a walker2d-like planar tree: a torso on slides x and z (z with a ref) and a hinge away from its
# origin, two legs of three bodies each whose hinges sit at the top of their capsules (pos), one
# hinge with a ref; inertias from geometry, angles in degrees
WALKER = """<mujoco model="walker">
  <compiler angle="degree"/>
  <option gravity="0 0 -9.81"/>
  <default><geom density="1000"/></default>
  <worldbody>
    <body name="torso" pos="0 0 1.25">
      <joint name="rootx" type="slide" axis="1 0 0"/>
      <joint name="rootz" type="slide" axis="0 0 1" ref="1.25"/>
      <joint name="rooty" type="hinge" axis="0 1 0" pos="0 0 -0.1"/>
      <geom type="capsule" fromto="0 0 -0.2 0 0 0.2" size="0.05"/>
      <body name="thigh" pos="0 0 -0.2">
        <joint name="thigh_joint" type="hinge" axis="0 -1 0" pos="0 0 0.0"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.45" size="0.05"/>
        <body name="leg" pos="0 0 -0.7">
          <joint name="leg_joint" type="hinge" axis="0 -1 0" pos="0 0 0.25" ref="10"/>
          <geom type="capsule" fromto="0 0 0.25 0 0 -0.25" size="0.04"/>
          <body name="foot" pos="0.1 0 -0.25">
            <joint name="foot_joint" type="hinge" axis="0 -1 0" pos="-0.1 0 0"/>
            <geom type="capsule" fromto="-0.1 0 0 0.1 0 0" size="0.06"/>
          </body>
        </body>
      </body>
      <body name="thigh_left" pos="0 0 -0.2">
        <joint name="thigh_left_joint" type="hinge" axis="0 -1 0" pos="0 0 0.0" ref="-5"/>
        <geom type="capsule" fromto="0 0 0 0 0 -0.45" size="0.05"/>
        <body name="leg_left" pos="0 0 -0.7">
          <joint name="leg_left_joint" type="hinge" axis="0 -1 0" pos="0 0 0.25"/>
          <geom type="capsule" fromto="0 0 0.25 0 0 -0.25" size="0.04"/>
          <body name="foot_left" pos="0.1 0 -0.25">
            <joint name="foot_left_joint" type="hinge" axis="0 -1 0" pos="-0.1 0 0"/>
            <geom type="capsule" fromto="-0.1 0 0 0.1 0 0" size="0.06"/>
          </body>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""

# a free base carrying a body with four joints at different anchors (hinges with refs, a slide
# whose own pos does not matter) and three bodies below it, one of them with two hinges again
MULTI = """<mujoco model="multi">
  <option gravity="0.3 -0.2 -9.81"/>
  <worldbody>
    <body name="base" pos="0.1 0.2 1.0" quat="0.9 0.1 0.3 -0.2">
      <freejoint name="root"/>
      <geom type="box" size="0.2 0.1 0.05" density="800"/>
      <body name="multi" pos="0.2 0.05 -0.1" euler="0.2 0.4 -0.3">
        <joint name="m1" type="hinge" axis="1 0 0" pos="0.05 0 0" ref="0.3"/>
        <joint name="m2" type="hinge" axis="0 1 1" pos="0 0.1 -0.05" ref="-0.5"/>
        <joint name="m3" type="slide" axis="1 1 0" pos="0.3 0 0" ref="0.1"/>
        <joint name="m4" type="hinge" axis="0 0.3 1" pos="-0.1 0.05 0.02"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.03"/>
        <body name="c1" pos="0.3 0 0" euler="0.1 -0.2 0.5">
          <joint name="c1j" type="hinge" axis="0 1 0" pos="0.02 0 0.01" ref="0.4"/>
          <geom type="capsule" fromto="0 0 0 0.25 0 0" size="0.025"/>
          <body name="c2" pos="0.25 0 0">
            <joint name="c2a" type="hinge" axis="0 0 1" pos="0 0.03 0"/>
            <joint name="c2b" type="hinge" axis="1 0 0" pos="0.05 0 0" ref="-0.2"/>
            <inertial pos="0.05 0.01 0" mass="0.3" diaginertia="0.002 0.001 0.0015"/>
          </body>
        </body>
        <body name="c3" pos="0 0.1 0">
          <joint name="c3j" type="slide" axis="0 1 0" pos="0.5 0.5 0.5" ref="-0.05"/>
          <geom type="sphere" size="0.04" pos="0 0.05 0"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.engine
@pytest.mark.parametrize("text", [WALKER, MULTI], ids=["walker", "multi"])
def test_joints_away_from_the_body_origin_are_honoured(tmp_path, text):
    """A joint's anchor (pos), several joints in one body (each about its own anchor, in order)
    and refs: qacc and mass matrix against MuJoCo's at qpos0 and random states, with bodies
    below. Before: refused ("a joint away from its body's origin is not read yet")."""
    path = write(tmp_path, text, "anchors.xml")
    model = load_model(path)
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_path(str(path))
    assert (model.n_q, model.n_v) == (m.nq, m.nv)
    assert model.total_mass == pytest.approx(float(m.body_mass.sum()), rel=1e-14)
    assert_agrees_with_mujoco(path, model, stable_seed("anchors", text[:20]), states=8)


HUMANOID = Path(__file__).parent / "models" / "humanoid.xml"  # MuJoCo's, model/humanoid/


@pytest.mark.engine
def test_mujocos_humanoid_is_honoured_and_its_dropped_attributes_announced():
    """A published model (MuJoCo's repository, Apache 2.0, unchanged): hinges away from their
    bodies' origins, two or three joints in a body; its damping, stiffness, armature, limits,
    tendon limits, motors and contacts announced (by joint name, with values), and the rest
    of its dynamics MuJoCo's with those set aside, at qpos0 and at random states. Before:
    refused ("a joint away from its body's origin is not read yet")."""
    model = load_model(HUMANOID)
    assert (model.n_q, model.n_v) == (28, 27)
    assert not any(key in n for n in model.notes for key in ("damping", "stiffness", "armature"))
    k = model.joint_voff[model.joint_names.index("abdomen_z")]
    assert (model.damping[k], model.stiffness[k], model.armature[k]) == (5, 20, 0.01)
    notes_with(model, "joint range dropped", "'abdomen_z' = [-0.785398, 0.785398]")
    notes_with(model, "tendon range dropped", "'hamstring_right' = [-0.3, 2]")
    notes_with(model, "actuator force dropped (an input: give it as tau)", "(21 actuators)")
    notes_with(model, "body contact geometry dropped", "(13 bodies)")
    refused(lambda: load_model(HUMANOID, strict=True), "joint 'abdomen_z'.range",
            "more joints")
    assert_agrees_with_mujoco(HUMANOID, model, stable_seed("humanoid"), states=8,
                              set_aside=True)


@pytest.mark.engine
def test_the_chain_of_a_body_with_several_joints_is_as_documented(tmp_path):
    """The representation the exporter writes back: one massless body f"{body}_{joint}" per
    joint but the last, the real body's frame at its last hinge's anchor a_n (COM = ipos - a_n,
    children shifted by -a_n), joint 1 at P_body T(a_1) Rot(u_1, -ref_1), joint i at
    T(a_i - a_(i-1)) Rot(u_i, -ref_i), a slide at T(-ref u) with the previous anchor."""
    path = write(tmp_path, MULTI, "multi.xml")
    model = load_model(path)
    k = model.body_names.index("multi")
    names = [model.body_names[i] for i in range(k - 3, k + 1)]
    assert names == ["multi_m1", "multi_m2", "multi_m3", "multi"]
    assert model.joint_names[k - 3:k + 1] == ("m1", "m2", "m3", "m4")
    assert all(model.mass[i] == 0 for i in range(k - 3, k))
    a2, a4 = np.array([0, 0.1, -0.05]), np.array([-0.1, 0.05, 0.02])
    u3 = np.array([1, 1, 0]) / np.sqrt(2)
    assert np.allclose(model.placement_p[k - 2], a2 - np.array([0.05, 0, 0]), atol=1e-15)
    assert np.allclose(model.placement_p[k - 1], -0.1 * u3, atol=1e-15)  # the slide
    assert np.allclose(model.placement_R[k - 1], np.eye(3), atol=0)
    assert np.allclose(model.placement_p[k], a4 - a2, atol=1e-15)  # m4 after the slide
    c3 = model.body_names.index("c3")
    # c3 at its pos shifted by -a4, and by -ref u of its own slide (ref -0.05 along y)
    assert np.allclose(model.placement_p[c3], np.array([0, 0.1, 0]) - a4 + [0, 0.05, 0],
                       atol=1e-15)


# --------------------------------------------------------------------------- URDF: honoured
MASSLESS_URDF = """<robot name="m">
  <link name="base"/>
  <link name="waist"><inertial><origin xyz="0.1 0 0.2" rpy="0.3 0.2 0.1"/><mass value="0"/>
    <inertia ixx="0.1" ixy="0.01" ixz="0" iyy="0.2" iyz="0" izz="0.35"/></inertial></link>
  <link name="arm"><inertial><origin xyz="0.3 0 0"/><mass value="2"/>
    <inertia ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="waist"/>
    <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
  <joint name="j2" type="revolute"><parent link="waist"/><child link="arm"/>
    <origin xyz="0 0 0.3" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
</robot>
"""


def pinocchio_truth(path, q, v, tau):
    pin = pytest.importorskip("pinocchio")
    pm = pin.buildModelFromUrdf(str(path))
    pd = pin.Data(pm)
    a = pin.aba(pm, pd, q, v, tau)
    pin.crba(pm, pd, q)
    return a, np.triu(pd.M) + np.triu(pd.M, 1).T


@pytest.mark.engine
def test_a_urdf_link_of_mass_zero_keeps_its_rotational_inertia(tmp_path):
    """As Pinocchio reads it (the PUMA 560's waist: mass 0, Izz 0.35). Before: the inertia was
    zeroed, the GIM 37 % off Pinocchio's."""
    path = write(tmp_path, MASSLESS_URDF, "massless.urdf")
    model = load_urdf(path)
    rng = np.random.default_rng(stable_seed("massless-urdf"))
    for _ in range(4):
        q, v, tau = rng.uniform(-2, 2, 2), rng.normal(size=2), rng.normal(size=2)
        a, M = pinocchio_truth(path, q, v, tau)
        assert rel(mass_matrix(model, q), M) < 1e-12
        assert rel(forward_dynamics(model, q, v, tau), a) < 1e-12


@pytest.mark.engine
def test_an_mjcf_body_of_mass_zero_is_refused_as_mujoco_refuses_it(tmp_path):
    """MuJoCo's MJCF compiler refuses a moving body of mass 0 even with a rotational inertia
    (mjMINVAL): the file has no meaning in MuJoCo, so it is refused, the body named."""
    text = ('<mujoco><worldbody><body name="waist"><joint name="j"/><inertial pos="0 0 0" '
            'mass="0" diaginertia="0.2 0.2 0.35"/></body></worldbody></mujoco>')
    path = write(tmp_path, text, "m0.xml")
    refused(lambda: load_model(path), "body 'waist' (line 1)", "mjMINVAL", "mass 0")


def long_urdf(tmp_path, n):
    """A URDF chain of n links 0.1 m long, revolute joints alternately about z and y."""
    links = "".join(f'<link name="l{i}"><inertial><origin xyz="0.05 0 0"/><mass value="1"/>'
                    '<inertia ixx="0.001" ixy="0" ixz="0" iyy="0.01" iyz="0" izz="0.01"/>'
                    '</inertial></link>' for i in range(n + 1))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l{i}"/>'
                     f'<child link="l{i + 1}"/><origin xyz="0.1 0 0"/>'
                     f'<axis xyz="0 {i % 2} {1 - i % 2}"/>'
                     '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
                     for i in range(n))
    return write(tmp_path, f'<robot name="long">{links}{joints}</robot>', "long.urdf")


def long_chain(n):
    """The same chain built by hand (its base 0.1 m away: uniform gravity does not see it)."""
    from redysim import Chain, Joint, Link

    link = Link(0.1, 1.0, (0.05, 0.0, 0.0), ((0.001, 0, 0), (0, 0.01, 0), (0, 0, 0.01)))
    return Chain.build([link] * n, [Joint("R", "zy"[i % 2]) for i in range(n)],
                       gravity=(0.0, 0.0, -9.81))


@pytest.mark.engine
def test_the_long_chain_file_means_what_pinocchio_reads(tmp_path):
    """The generator of the long chain below, at 40 links, against Pinocchio's aba and crba."""
    path = long_urdf(tmp_path, 40)
    model = load_model(path)
    rng = np.random.default_rng(stable_seed("long-40"))
    q, v, tau = rng.uniform(-1, 1, 40), rng.normal(size=40), rng.normal(size=40)
    a, M = pinocchio_truth(path, q, v, tau)
    assert rel(mass_matrix(model, q), M) < 1e-12
    assert rel(forward_dynamics(model, q, v, tau), a) < 1e-12
    assert rel(mass_matrix(long_chain(40), q), M) < 1e-12


def test_a_chain_of_1200_links_loads_without_recursion(tmp_path):
    """A URDF chain of 1,200 links: the old importer's recursive walk raised RecursionError
    (MuJoCo's own compiler stops at a depth of 1,024 bodies, and Pinocchio's Data for 1,200
    joints exhausts the memory, so the truth is the same chain built by hand). GIM and inverse
    dynamics agree to 1e-12."""
    n = 1200
    model = load_model(long_urdf(tmp_path, n))
    chain = long_chain(n)
    assert model.n_v == n and model.total_mass == n
    rng = np.random.default_rng(stable_seed("long"))
    q, v, a = rng.uniform(-0.3, 0.3, n), rng.normal(size=n), rng.normal(size=n)
    assert rel(mass_matrix(model, q), mass_matrix(chain, q)) < 1e-12
    assert rel(inverse_dynamics(model, q, v, a), inverse_dynamics(chain, q, v, a)) < 1e-12


@pytest.mark.slow
def test_a_chain_of_100000_links_loads(tmp_path):
    """Nothing recursive, nothing quadratic: 100,000 links (measured: 50 s on the shared
    machine, most of it the reference recursion that checks every joint has inertia to
    move; MuJoCo's URDF parser crashes near 60,000)."""
    n = 100_000
    model = load_model(long_urdf(tmp_path, n))
    rng = np.random.default_rng(stable_seed("longest"))
    q, v, a = rng.uniform(-0.3, 0.3, n), rng.normal(size=n), rng.normal(size=n)
    assert rel(inverse_dynamics(model, q, v, a), inverse_dynamics(long_chain(n), q, v, a)) \
        < 1e-12


@pytest.mark.engine
def test_an_mjcf_deeper_than_mujocos_reader_is_refused_naming_the_limit(tmp_path):
    """MuJoCo's XML reader (tinyxml2) stops at MJCF_MAX_DEPTH nested elements: 496 nested
    bodies with a joint read, 497 do not (measured); the refusal says so and names URDF."""
    mujoco = pytest.importorskip("mujoco")

    def chain(n):
        return ("<mujoco><worldbody>" + "".join(f'<body name="b{i}" pos="0.1 0 0">'
                                               for i in range(n))
                + '<joint/><geom size="0.01"/>' + "</body>" * n + "</worldbody></mujoco>")

    assert MJCF_MAX_DEPTH == 499
    mujoco.MjModel.from_xml_string(chain(MJCF_MAX_DEPTH - 3))  # the deepest MuJoCo reads
    with pytest.raises(ValueError, match="XML_ELEMENT_DEPTH_EXCEEDED"):
        mujoco.MjModel.from_xml_string(chain(MJCF_MAX_DEPTH - 2))
    path = write(tmp_path, chain(600), "deep.xml")
    err = refused(lambda: load_model(path), "<mujoco>", "at most 499 nested elements", "URDF")
    assert err.value == 603


# --------------------------------------------------------------------------- MJCF: announced
def mjcf_pendulum(joint_attrs="", body_attrs="", option="", extra="", flags=""):
    """Two hinged bodies (the second away from the first, so their geoms do not touch)."""
    return f"""<mujoco model="p"><option {option}>{flags}</option><worldbody>
<body name="upper" {body_attrs}><joint name="shoulder" axis="0 1 0" {joint_attrs}/>
<geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.02" contype="0" conaffinity="0"
 mass="1"/>
<body name="lower" pos="0.3 0 0"><joint name="elbow" axis="0 1 0"/>
<geom type="sphere" size="0.05" pos="0.2 0 0" contype="0" conaffinity="0" mass="0.5"/>
</body></body></worldbody>{extra}</mujoco>"""


ANNOUNCED_MJCF = [
    # (id, file, field of the strict refusal, value, the note)
    ("frictionloss", mjcf_pendulum('frictionloss="0.3"'), "joint 'shoulder'.frictionloss", 0.3,
     "joint 'shoulder': frictionloss = 0.3 dropped (no joint friction in the core)"),
    ("range", mjcf_pendulum('range="-30 45"'), "joint 'shoulder'.range",
     [-0.5235987755982988, 0.7853981633974483],
     "joint 'shoulder': range = [-0.523599, 0.785398] dropped (no joint limits in the core: the "
     "joint moves through them)"),
    ("density", mjcf_pendulum(option='density="1.2"'), "<option>.density", 1.2,
     "<option>: density = 1.2 dropped (no fluid forces in the core)"),
    ("viscosity", mjcf_pendulum(option='viscosity="0.002"'), "<option>.viscosity", 0.002,
     "<option>: viscosity = 0.002 dropped (no fluid forces in the core)"),
    ("tendon", mjcf_pendulum(extra='<tendon><fixed name="t" stiffness="3"><joint joint='
                                   '"shoulder" coef="1"/><joint joint="elbow" coef="-1"/>'
                                   '</fixed></tendon>'),
     "tendon 't'.stiffness", 3.0, "tendon 't': stiffness = 3 dropped (no tendons in the core)"),
    ("tendon-range", mjcf_pendulum(extra='<tendon><fixed name="t" range="-0.2 0.3"><joint '
                                         'joint="shoulder" coef="1"/></fixed></tendon>'),
     "tendon 't'.range", [-0.2, 0.3],
     "tendon 't': range = [-0.2, 0.3] dropped (no tendons in the core)"),
    ("tendon-damping", mjcf_pendulum(extra='<tendon><fixed name="t" damping="0.7"><joint '
                                           'joint="shoulder" coef="1"/></fixed></tendon>'),
     "tendon 't'.damping", 0.7, "tendon 't': damping = 0.7 dropped (no tendons in the core)"),
    ("velocity-actuator", mjcf_pendulum(extra='<actuator><velocity name="v" joint="elbow" '
                                              'kv="3"/></actuator>'),
     "actuator 'v'.biasprm", [0.0, 0.0, -3.0], "actuator 'v': biasprm = [0, 0, -3] dropped"),
    ("position-actuator", mjcf_pendulum(extra='<actuator><position name="servo" joint="elbow" '
                                              'kp="100"/></actuator>'),
     "actuator 'servo'.biasprm", [0.0, -100.0],
     "actuator 'servo': biasprm = [0, -100] dropped (a force even at ctrl 0"),
    ("contact", mjcf_pendulum().replace(
        '<body name="upper"', '<geom name="floor" type="plane" size="1 1 0.1"/>'
        '<body name="upper"').replace('size="0.05" pos="0.2 0 0" contype="0" conaffinity="0"',
                                      'size="0.05" pos="0.2 0 0"'),
     "body 'lower'.contact geometry", None,
     "body 'lower': contact geometry dropped (no contacts in the core)"),
    ("pair", mjcf_pendulum(extra='<contact><pair name="p" geom1="g1" geom2="g2"/></contact>')
     .replace('<geom type="capsule"', '<geom name="g1" type="capsule"')
     .replace('<geom type="sphere"', '<geom name="g2" type="sphere"'),
     "contact 'p'.<pair>", None, "contact 'p': <pair> dropped (no contacts in the core)"),
]


@pytest.mark.engine
@pytest.mark.parametrize("case", ANNOUNCED_MJCF, ids=[c[0] for c in ANNOUNCED_MJCF])
def test_an_mjcf_attribute_that_acts_is_announced_or_refused_with_strict(tmp_path, case):
    """The note names the element, its name and the value; strict=True refuses it naming the
    same. What is dropped is that attribute and nothing else: the model's dynamics is MuJoCo's
    with it set aside. Before: a vague global note, or nothing."""
    pytest.importorskip("mujoco")
    _, text, field, value, note = case
    path = write(tmp_path, text, "p.xml")
    model = load_model(path)
    notes_with(model, note)
    assert_agrees_with_mujoco(path, model, stable_seed("announced", case[0]), states=3,
                              set_aside=True)
    err = refused(lambda: load_model(path, strict=True), field, "strict=True refuses")
    assert err.value == value


@pytest.mark.engine
@pytest.mark.parametrize("attrs, flag", [('damping="0.5"', 'damper="disable"'),
                                         ('stiffness="2"', 'spring="disable"'),
                                         ('frictionloss="0.3"', 'frictionloss="disable"'),
                                         ('range="-30 45"', 'limit="disable"'),
                                         ('range="-30 45"', 'constraint="disable"')])
def test_an_attribute_mujoco_disables_is_no_news(tmp_path, attrs, flag):
    """Only values that act are announced: a flag that switches them off in MuJoCo silences
    them (strict=True then loads the file)."""
    path = write(tmp_path, mjcf_pendulum(attrs, flags=f"<flag {flag}/>"), "p.xml")
    model = load_model(path, strict=True)
    assert only_unread(model) and not model.has_passive


@pytest.mark.engine
def test_gravcomp_and_fluid_forces_follow_mujocos_flags(tmp_path):
    """MuJoCo skips gravity compensation and fluid forces when springs and dampers are both
    disabled, and gravity compensation without gravity (checked on MuJoCo itself)."""
    mujoco = pytest.importorskip("mujoco")
    both = '<flag spring="disable" damper="disable"/>'
    for body, option, flags in (('gravcomp="1"', "", both), ('gravcomp="1"', "", '<flag '
                                'gravity="disable"/>'), ("", 'density="1.2"', both)):
        path = write(tmp_path, mjcf_pendulum(body_attrs=body, option=option, flags=flags),
                     "p.xml")
        m = mujoco.MjModel.from_xml_path(str(path))
        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:] = 0.4, 1.0
        mujoco.mj_forward(m, d)
        assert np.all(d.qfrc_passive == 0)
        model = load_model(path, strict=True)
        assert only_unread(model) and not model.has_passive


@pytest.mark.engine
def test_contacts_are_announced_as_mujoco_finds_them(tmp_path):
    """Two sibling bodies whose spheres overlap touch in MuJoCo (announced); a parent and child
    whose spheres overlap do not (MuJoCo filters the pair), nor an <exclude>d pair."""
    mujoco = pytest.importorskip("mujoco")
    text = """<mujoco><worldbody><body name="a"><joint axis="0 1 0"/><geom size="0.1"/>
    <body name="b" pos="0.05 0 0"><joint axis="0 1 0"/><geom size="0.1"/></body>
    <body name="c" pos="0 0.05 0"><joint axis="0 0 1"/><geom size="0.1"/></body></body>
    </worldbody>{extra}</mujoco>"""
    for extra, touching in (("", {"b", "c"}), ('<contact><exclude body1="b" body2="c"/>'
                                               "</contact>", set())):
        path = write(tmp_path, text.format(extra=extra), "c.xml")
        m = mujoco.MjModel.from_xml_path(str(path))
        d = mujoco.MjData(m)
        mujoco.mj_forward(m, d)
        found = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(m.geom_bodyid[g]))
                 for c in d.contact[:d.ncon] for g in (c.geom1, c.geom2)}
        assert found == touching
        model = load_model(path)
        if touching:
            notes_with(model, "body contact geometry dropped", "'b', 'c' (2 bodies)")
        else:
            assert not any("contact" in n for n in model.notes), model.notes


FLOOR = '<geom name="floor" type="plane" size="5 5 0.1"/>'


@pytest.mark.engine
@pytest.mark.parametrize("text", [WALKER, MULTI, WALKER.replace("<worldbody>", "<worldbody>"
                                                                + FLOOR),
                                  MULTI.replace("<worldbody>", "<worldbody>" + FLOOR)],
                         ids=["walker", "multi", "walker-floor", "multi-floor"])
def test_the_bodies_announced_in_contact_are_mujocos(tmp_path, text):
    """With every geom's margin at 100 m MuJoCo's collision pass reports every pair its filters
    let through (contype/conaffinity, parent and child, same weld body): the bodies of those
    pairs are the ones the note lists (by their weld body, as the tree fuses them)."""
    mujoco = pytest.importorskip("mujoco")
    if '<geom density="1000"/>' in text:  # the walker has a default class already
        wide = text.replace('<geom density="1000"/>', '<geom density="1000" margin="100"/>')
    else:
        wide = text.replace("<worldbody>", '<default><geom margin="100"/></default><worldbody>')
    wide = write(tmp_path, wide, "wide.xml")
    m = mujoco.MjModel.from_xml_path(str(wide))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    weld = m.body_weldid
    found = {mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, int(weld[m.geom_bodyid[g]]))
             for c in d.contact[:d.ncon] for g in (c.geom1, c.geom2)} - {"world"}
    assert found
    (note,) = notes_with(load_model(write(tmp_path, text, "m.xml")), "body contact geometry")
    listed = set(re.findall(r"'([^']+)'", note.split(": ", 1)[1]))
    count = int(re.search(r"\((\d+) bodies\)", note).group(1))
    assert listed <= found and count == len(found), (note, found)


@pytest.mark.engine
def test_a_motor_is_an_input_and_visual_things_are_one_line(tmp_path):
    """A motor has no force at ctrl 0 (its force is a tau the caller gives); sensors, cameras,
    lights, visual geoms and keyframes do not act on the motion: one summary line, and
    strict=True loads the file (a site is read: a frame)."""
    extra = ('<actuator><motor name="m" joint="elbow" gear="2"/></actuator><sensor>'
             '<jointpos joint="elbow"/></sensor><keyframe><key qpos="0.1 0.2"/></keyframe>')
    text = mjcf_pendulum(extra=extra).replace(
        '<body name="lower"', '<site name="s"/><camera name="cam"/><light name="l"/>'
        '<body name="lower"')
    path = write(tmp_path, text, "p.xml")
    model = load_model(path, strict=True)
    notes_with(model, "actuator 'm': force dropped (an input: give it as tau)")
    notes_with(model, "not read (no effect on the motion): ", "1 cameras",
               "1 lights", "1 sensors", "1 keyframes", "2 visual-only geoms")
    assert model.frames["s"] == (0, (0.0, 0.0, 0.0))  # a site on a moving body is a frame


@pytest.mark.engine
@pytest.mark.parametrize("body, field, fragment", [
    ('<body name="a"><joint name="h"/><geom size=".1"/><body name="b" pos="0.3 0 0">'
     '<freejoint name="f"/><geom size=".1"/></body></body>', "body 'b' (line 1)",
     "free joint can only be used on top level"),
])
def test_joints_the_tree_cannot_hold_are_refused(tmp_path, body, field, fragment):
    """A free joint below the root (MuJoCo's compiler refuses it: its message kept, the body
    named). (A ball joint is read: tests/test_ball.py.)"""
    path = write(tmp_path, f"<mujoco><worldbody>{body}</worldbody></mujoco>", "j.xml")
    refused(lambda: load_model(path), field, fragment)


@pytest.mark.engine
def test_what_only_bounds_inputs_or_holds_still_is_announced_but_not_refused(tmp_path):
    """A joint's actuatorfrcrange (bounds actuator forces, which the caller gives as tau) and a
    mocap body (held at its pose) are announced; strict=True loads the file. MuJoCo's
    numerical options (timestep, integrator) are no news."""
    text = ('<mujoco><option timestep="0.01" integrator="RK4"/><worldbody><body name="a">'
            '<joint name="h" actuatorfrcrange="-1 1"/><geom size=".1" contype="0" '
            'conaffinity="0"/></body><body name="m" mocap="true" pos="1 0 0"><geom size=".1" '
            'contype="0" conaffinity="0"/></body></worldbody><actuator><motor joint="h"/>'
            "</actuator></mujoco>")
    model = load_model(write(tmp_path, text, "m.xml"), strict=True)
    notes_with(model, "joint 'h': actuatorfrcrange = [-1, 1] dropped (bounds actuator forces")
    notes_with(model, "body 'm': mocap dropped (held at its file pose")
    assert not any("timestep" in n or "integrator" in n for n in model.notes)


EQUALITY = """<mujoco><default><geom contype="0" conaffinity="0"/></default><worldbody>
<body name="a"><joint name="ja" axis="0 1 0"/><geom size="0.05" pos="0.2 0 0" mass="1"/></body>
<body name="b" pos="0.5 0 0"><joint name="jb" axis="0 1 0"/>
<geom size="0.05" pos="0.2 0 0" mass="1"/></body></worldbody>
<equality>{eq}</equality></mujoco>"""


@pytest.mark.engine
def test_a_joint_equality_of_degree_one_is_a_coupling(tmp_path):
    """MuJoCo's y - y0 = a0 + a1 (x - x0) about the joints' refs: q_ja = a1 q_jb + a0 + y0 -
    a1 x0, held exactly (MuJoCo's softness announced); equality="drop" drops it."""
    text = EQUALITY.format(eq='<joint name="c" joint1="ja" joint2="jb" polycoef="0.1 -2 0 0 0"/>')
    text = text.replace('<joint name="ja" axis="0 1 0"/>', '<joint name="ja" axis="0 1 0" '
                        'ref="0.2"/>').replace('<joint name="jb" axis="0 1 0"/>',
                                               '<joint name="jb" axis="0 1 0" ref="0.3"/>')
    path = write(tmp_path, f'<mujoco><compiler angle="radian"/>{text[len("<mujoco>"):]}',
                 "c.xml")
    model = load_model(path)
    (c,) = model.couplings
    assert (c.follower, c.leader, c.multiplier) == ("ja", "jb", -2.0)
    assert c.offset == pytest.approx(0.1 + 0.2 + 2 * 0.3, abs=1e-15)
    notes_with(model, "equality 'c': solref, solimp", "held exactly")
    assert not load_model(path, equality="drop").couplings


@pytest.mark.engine
@pytest.mark.parametrize("eq, what", [
    ('<connect name="loop" body1="a" body2="b" anchor="0.3 0 0"/>',
     "connect of body 'a' and body 'b'"),
    ('<weld name="loop" body1="a" body2="b"/>', "weld of body 'a' and body 'b'"),
])
def test_a_loop_closure_is_refused_or_dropped_by_name(tmp_path, eq, what):
    """A loop closure is closed by default (tests/test_mjcf_loops.py); equality="refuse" refuses
    it by name, equality="drop" drops it, announced (strict=True does not refuse what the
    caller dropped by name); an inactive one is announced. Here the two bars lie in a line, so
    that the closure is redundant: refused by name (MuJoCo's soft rows take it)."""
    path = write(tmp_path, EQUALITY.format(eq=eq), "eq.xml")
    err = refused(lambda: load_model(path, equality="refuse"), "equality 'loop'",
                  "equality='close'", "equality='drop'")
    assert err.value == what
    err = refused(lambda: load_model(path), "equality 'loop'", "redundant", "equality='drop'")
    assert err.value == what
    model = load_model(path, equality="drop", strict=True)
    notes_with(model, f"equality 'loop': constraint = {what} dropped (equality='drop'")
    inactive = write(tmp_path, EQUALITY.format(eq=eq.replace("/>", ' active="false"/>')),
                     "off.xml")
    notes_with(load_model(inactive, strict=True), "equality 'loop'", "inactive")


@pytest.mark.engine
def test_flex_and_plugins_are_announced(tmp_path):
    """A flex (a deformable, with its own bodies and an edge equality) and a plugin (a PID
    actuator: forces the core cannot know)."""
    flex = """<mujoco><worldbody><body name="a"><joint name="h" axis="0 1 0"/>
    <geom size="0.1" mass="1" contype="0" conaffinity="0"/></body>
    <flexcomp name="cloth" type="grid" count="3 3 1" spacing="0.1 0.1 0.1" mass="0.1"
     radius="0.01" dim="2" pos="0 0 1"><edge equality="true"/></flexcomp>
    </worldbody></mujoco>"""
    path = write(tmp_path, flex, "flex.xml")
    refused(lambda: load_model(path), "equality 'equality0'", "a flex equality")
    model = load_model(path, equality="drop")
    notes_with(model, "flex 'cloth': elasticity and contacts dropped")
    refused(lambda: load_model(path, equality="drop", strict=True),
            "flex 'cloth'.elasticity and contacts", "strict=True")
    pid = """<mujoco><extension><plugin plugin="mujoco.pid"><instance name="pid1">
    <config key="kp" value="10"/></instance></plugin></extension><worldbody><body name="a">
    <joint name="h" axis="0 1 0"/><geom size="0.1" mass="1"/></body></worldbody>
    <actuator><plugin joint="h" plugin="mujoco.pid" instance="pid1"/></actuator></mujoco>"""
    path = write(tmp_path, pid, "pid.xml")
    notes_with(load_model(path), "plugin 'pid1': forces dropped")
    refused(lambda: load_model(path, strict=True), "actuator 'actuator0'.plugin", "strict=True",
            "also: plugin forces")


@pytest.mark.engine
def test_many_joints_are_listed_abbreviated(tmp_path):
    """A note lists the joints concerned with their values, the first few then 'and N more'."""
    bodies = "".join(f'<body name="b{i}" pos="0.1 0 0"><joint name="j{i}" axis="0 1 0" '
                     f'frictionloss="{i + 1}"/><geom size="0.02" mass="1" contype="0" '
                     'conaffinity="0"/>' for i in range(9)) + "</body>" * 9
    path = write(tmp_path, f"<mujoco><worldbody>{bodies}</worldbody></mujoco>", "many.xml")
    notes_with(load_model(path), "joint frictionloss dropped (no joint friction in the core): "
               "'j0' = 1, 'j1' = 2, 'j2' = 3, 'j3' = 4, 'j4' = 5, 'j5' = 6 and 3 more (9 joints)")
    refused(lambda: load_model(path, strict=True), "joint 'j0'.frictionloss", "8 more joints")


# --------------------------------------------------------------------------- MJCF: floating
@pytest.mark.engine
def test_floating_mjcf_gives_the_jointless_root_a_free_joint(tmp_path):
    """floating=True on MJCF: the root body without joints gets a free joint, its XML pose the
    initial q; the same as the file with a <freejoint/> (checked against MuJoCo). Before:
    floating was ignored (no free joint, no error)."""
    fixed = MULTI.replace('<freejoint name="root"/>', "")
    path = write(tmp_path, fixed, "fixed.xml")
    assert load_model(path).n_v == 8  # welded to the world
    model = load_model(path, floating=True)
    assert model.joint_names[0] == "base_free" and model.n_v == 14
    free = write(tmp_path, MULTI.replace('name="root"', 'name="base_free"'), "free.xml")
    assert np.allclose(model.initial()[:7], [0.1, 0.2, 1.0, *np.array([0.9, 0.1, 0.3, -0.2]) /
                                             np.linalg.norm([0.9, 0.1, 0.3, -0.2])], atol=1e-15)
    assert_agrees_with_mujoco(free, model, stable_seed("floating-mjcf"))
    assert load_model(free, floating=True).n_v == 14  # already floating: nothing to add


@pytest.mark.engine
def test_floating_mjcf_is_refused_where_it_cannot_float(tmp_path):
    path = write(tmp_path, WALKER, "walker.xml")
    refused(lambda: load_model(path, floating=True), "body 'torso'", "already moves",
            "rootx")
    two = MULTI.replace('<freejoint name="root"/>', "").replace(
        "<worldbody>", '<worldbody><body name="table" pos="1 0 0"><geom size="0.1"/></body>')
    path = write(tmp_path, two, "two.xml")
    refused(lambda: load_model(path, floating=True), "body 'table'", "and body 'base'",
            "both root bodies without joints")


def test_floating_is_refused_for_a_dh_robot_or_a_rope_case():
    """A DH table's base is its frame 0, fixed in the world; a rope hangs from the world.
    Before: floating=True was ignored."""
    from redysim.io.cases import CASES_DIR

    puma = Path(CASES_DIR) / "robots" / "puma560.toml"
    refused(lambda: load_model(puma, floating=True), "floating", "DH robot's base")
    rope = Path(CASES_DIR) / "STUDY-R3.toml"
    refused(lambda: load_model(rope, floating=True), "floating", "rope case")


# --------------------------------------------------------------------------- URDF: announced
LINK = ('<link name="{n}"><inertial><origin xyz="0.1 0 0"/><mass value="1"/><inertia '
        'ixx="0.01" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>{extra}</link>')


def urdf(joint_extra="", link_extra="", more=""):
    """base -(j1, revolute)-> arm; ``joint_extra`` inside j1, ``link_extra`` inside arm."""
    return (f'<robot name="r">{LINK.format(n="base", extra="")}'
            f'{LINK.format(n="arm", extra=link_extra)}'
            '<joint name="j1" type="revolute"><parent link="base"/><child link="arm"/>'
            f'<axis xyz="0 0 1"/>{joint_extra}</joint>{more}</robot>')


ANNOUNCED_URDF = [
    ("friction", urdf('<dynamics friction="0.2"/>'), "joint 'j1'.<dynamics> friction", 0.2,
     "joint 'j1': <dynamics> friction = 0.2 dropped (no joint friction in the core)"),
    ("limit", urdf('<limit lower="-1" upper="2" effort="10" velocity="3"/>'),
     "joint 'j1'.<limit> lower, upper", [-1.0, 2.0],
     "joint 'j1': <limit> lower, upper = [-1, 2] dropped (no joint limits in the core"),
    ("collision", urdf(link_extra='<collision><geometry><sphere radius="0.1"/></geometry>'
                                  '</collision>'),
     "link 'arm'.<collision>", None, "link 'arm': <collision> dropped (no contacts in the core)"),
]


@pytest.mark.parametrize("case", ANNOUNCED_URDF, ids=[c[0] for c in ANNOUNCED_URDF])
def test_a_urdf_attribute_that_acts_is_announced_or_refused_with_strict(tmp_path, case):
    _, text, field, value, note = case
    path = write(tmp_path, text, "r.urdf")
    notes_with(load_model(path), note)
    err = refused(lambda: load_model(path, strict=True), field, "strict=True refuses")
    assert err.value == value


def test_what_does_not_act_in_a_urdf_is_one_line(tmp_path):
    """Visual geometry, materials, transmissions, Gazebo tags, a joint's effort and velocity
    bounds, safety controllers and calibration: one line; strict=True loads the file. A zero
    damping is no news."""
    text = urdf('<limit effort="10" velocity="3"/><dynamics damping="0"/>'
                '<safety_controller k_velocity="1"/><calibration rising="0"/>',
                '<visual><geometry><box size="1 1 1"/></geometry></visual>',
                '<material name="grey"/><transmission name="t"/><gazebo/>')
    path = write(tmp_path, text, "r.urdf")
    model = load_model(path, strict=True)
    assert model.notes == ("not read (no effect on the motion): 1 <visual>, 1 joint "
                           "effort/velocity bounds (tau is the caller's), 1 <safety_controller>, "
                           "1 <calibration>, 1 <material>, 1 <transmission>, 1 <gazebo>",)
    assert load_model(path).n_v == 1


def test_a_mimic_joint_is_a_coupling_or_moves_independently_as_asked(tmp_path):
    """By default a mimic couples (q_j2 = 2 q_j1 + 0.1, the model's Coupling); "independent"
    lets it move on its own, announced; "refuse" refuses it by name."""
    text = urdf(more=LINK.format(n="tip", extra="") + '<joint name="j2" type="revolute">'
                '<parent link="arm"/><child link="tip"/><axis xyz="0 0 1"/>'
                '<mimic joint="j1" multiplier="2" offset="0.1"/></joint>')
    path = write(tmp_path, text, "r.urdf")
    model = load_model(path, strict=True)
    assert model.couplings == (redysim.Coupling("j2", "j1", 2.0, 0.1),)
    assert model.neutral()[model.joint_names.index("j2")] == 0.1  # on its leader at 0
    refused(lambda: load_model(path, mimic="refuse"), "joint 'j2'/mimic.joint",
            "mimic joint couples", "mimic='couple'")
    model = load_model(path, mimic="independent", strict=True)
    assert not model.couplings
    notes_with(model, "joint 'j2': mimic = 'j1' * 2 + 0.1 dropped (it moves independently")


@pytest.mark.parametrize("extra, field, fragments", [
    ('<mimic joint="nope"/>', "joint 'j2'/mimic.joint", ("no joint of that name",)),
    ('<mimic joint="j1" multiplier="x"/>', "joint 'j2'/mimic.multiplier", ()),
    ('<mimic joint="j2"/>', "joint 'j2'/mimic.joint", ("cycle",)),
])
def test_a_bad_mimic_is_refused_by_name(tmp_path, extra, field, fragments):
    text = urdf(more=LINK.format(n="tip", extra="") + '<joint name="j2" type="revolute">'
                f'<parent link="arm"/><child link="tip"/><axis xyz="0 0 1"/>{extra}</joint>')
    refused(lambda: load_model(write(tmp_path, text, "r.urdf")), field, *fragments)


def test_a_mimic_of_a_mimic_is_composed_onto_the_first_leader(tmp_path):
    """j3 mimics j2 (x3, +0.2), which mimics j1 (x2, +0.1): q3 = 3 (2 q1 + 0.1) + 0.2."""
    text = urdf(more=LINK.format(n="tip", extra="") + LINK.format(n="end", extra="")
                + '<joint name="j2" type="revolute"><parent link="arm"/><child link="tip"/>'
                '<axis xyz="0 0 1"/><mimic joint="j1" multiplier="2" offset="0.1"/></joint>'
                '<joint name="j3" type="prismatic"><parent link="tip"/><child link="end"/>'
                '<axis xyz="1 0 0"/><mimic joint="j2" multiplier="3" offset="0.2"/></joint>')
    model = load_model(write(tmp_path, text, "r.urdf"))
    assert set(model.couplings) == {redysim.Coupling("j2", "j1", 2.0, 0.1),
                                    redysim.Coupling("j3", "j1", 6.0, 0.5)}


# --------------------------------------------------------------------------- URDF: refused
TWO = LINK.format(n="a", extra="") + LINK.format(n="b", extra="")
JOINT = '<joint name="{n}" type="revolute"><parent link="{p}"/><child link="{c}"/></joint>'


@pytest.mark.parametrize("body, field, fragments", [
    (TWO + LINK.format(n="c", extra="") + JOINT.format(n="j", p="a", c="b"), "link 'a'",
     ("and link 'c' are both root links", "one tree")),
    (TWO + LINK.format(n="c", extra="") + JOINT.format(n="j", p="a", c="b")
     + JOINT.format(n="j", p="b", c="c"), "joint 'j'", ("defined twice",)),
    (TWO + LINK.format(n="a", extra="") + JOINT.format(n="j", p="a", c="b"), "link 'a'",
     ("defined twice",)),
    (TWO + LINK.format(n="c", extra="") + JOINT.format(n="j", p="a", c="b")
     + JOINT.format(n="k", p="c", c="c"), "joint 'k'", ("form a cycle", "link 'c' is its own")),
    (TWO + LINK.format(n="c", extra="") + LINK.format(n="d", extra="")
     + JOINT.format(n="j", p="a", c="b") + JOINT.format(n="k", p="d", c="c")
     + JOINT.format(n="l", p="c", c="d"), "joint 'k'", ("joints 'k' -> 'l' form a cycle",)),
    (TWO + JOINT.format(n="j", p="a", c="x"), "joint 'j'/child.link", ("no such link",)),
    (TWO + JOINT.format(n="j", p="y", c="b"), "joint 'j'/parent.link", ("no such link",)),
    (TWO + '<joint name="j" type="revolute"><child link="b"/></joint>', "joint 'j'/parent.link",
     ("missing",)),
    (TWO.replace('<mass value="1"/>', '<mass value="-2"/>', 1) + JOINT.format(n="j", p="a",
                                                                             c="b"),
     "link 'a'/inertial/mass.value", ("must be >= 0",)),
    (TWO.replace('ixx="0.01"', 'ixx="-0.5"', 1) + JOINT.format(n="j", p="a", c="b"),
     "link 'a'/inertial/inertia", ("positive semi-definite",)),
    (TWO.replace('<inertia ixx="0.01" ixy="0" ixz="0"', '<inertia', 1)
     + JOINT.format(n="j", p="a", c="b"), "link 'a'/inertial/inertia",
     ("missing ixx, ixy, ixz",)),
    (TWO.replace('xyz="0.1 0 0"', 'xyz="0.1 0"', 1) + JOINT.format(n="j", p="a", c="b"),
     "link 'a'/inertial/origin.xyz", ("must be 3 finite numbers",)),
    (TWO + JOINT.format(n="j", p="a", c="b").replace("</joint>", '<axis xyz="0 0 0"/></joint>'),
     "joint 'j'/axis.xyz", ("zero vector",)),
])
def test_a_bad_urdf_is_refused_naming_its_own_elements(tmp_path, body, field, fragments):
    """Two root links (urdfdom and Pinocchio refuse them; we took them), duplicated names
    (MuJoCo's ValueError escaped, or 'repeated URDF name:' with no name), a cycle (MuJoCo said
    'URDF body not found'), a missing link, a bad inertial (named by link, not bodies[1]) or
    number: the file's own element named."""
    path = write(tmp_path, f'<robot name="r">{body}</robot>', "bad.urdf")
    err = refused(lambda: load_model(path), field, *fragments)
    assert str(err).startswith(str(path) + ": ")


def test_a_floating_joint_and_a_world_link(tmp_path):
    """A URDF floating joint from a link fixed to the world is a free joint, its origin the
    initial pose; floating=True on a file whose root link is 'world' floats the link fixed to
    it (MuJoCo's and Gazebo's reading of 'world')."""
    text = (f'<robot name="r"><link name="world"/>{TWO}'
            '<joint name="fly" type="floating"><parent link="world"/><child link="a"/>'
            '<origin xyz="1 2 3" rpy="0 0 1.5707963267948966"/></joint>'
            + JOINT.format(n="j", p="a", c="b").replace("</joint>", '<axis xyz="0 0 1"/>'
                                                                   '</joint>') + "</robot>")
    model = load_model(write(tmp_path, text, "fly.urdf"))
    assert model.joint_types[0] == "free" and model.joint_names[0] == "fly"
    assert np.allclose(model.initial()[:7], [1, 2, 3, np.sqrt(0.5), 0, 0, np.sqrt(0.5)],
                       atol=1e-15)
    fixed = text.replace('type="floating"', 'type="fixed"')
    model = load_model(write(tmp_path, fixed, "fixed.urdf"), floating=True)
    assert model.joint_names[0] == "a_free" and model.body_names[0] == "a"
    assert np.allclose(model.initial()[:7], [1, 2, 3, np.sqrt(0.5), 0, 0, np.sqrt(0.5)],
                       atol=1e-15)
    again = load_model(write(tmp_path, text, "fly.urdf"), floating=True)  # it floats already
    assert again.joint_names[0] == "fly" and again.n_v == 7
    moving = text.replace('type="floating"', 'type="revolute"')
    refused(lambda: load_model(write(tmp_path, moving, "moving.urdf"), floating=True),
            "link 'world'", "one fixed joint is needed")


# --------------------------------------------------------------------------- messages
def test_model_build_names_bodies_and_joints_and_prints_plain_numbers():
    """Model.build's fields name the body or joint (and its index); values are plain numbers,
    never np.float64(...) reprs."""
    refused(lambda: Model.build([Body("l2", np.float64(-1.5))], [TreeJoint("j2", "R")], [-1]),
            "body 'l2' (bodies[0]).mass", "= -1.5: must be >= 0", error=CaseError)
    err = refused(lambda: Model.build([Body("a", 1.0)], [TreeJoint("j2", "R", (0.0, 0.0, 0.0))],
                                      [-1]), "joint 'j2' (joints[0]).axis", error=CaseError)
    assert "= (0.0, 0.0, 0.0)" in str(err)
    assert str(FieldError("f", "x", np.array([np.float64(1.5), 2.0]), "p")) == \
        "f: x = [1.5, 2.0]: p"
    assert str(FieldError("f", "x", (np.int64(3), np.float32(0.5)), "p")) == "f: x = (3, 0.5): p"


def test_locking_with_a_bad_argument_is_named():
    """locked({'j1': 'zero'}) and locked(['j1']) raised ValueError / AttributeError from
    numpy and dict; now CaseErrors naming the argument and value."""
    model = Model.build([Body("a", 1.0, (0.1, 0, 0), ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1))),
                         Body("b", 1.0, (0.1, 0, 0), ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))],
                        [TreeJoint("j1", "R", "z"), TreeJoint("j2", "R", "y")], [-1, 0])
    refused(lambda: model.locked({"j1": "zero"}), "values['j1']", "takes 1 finite coordinate",
            error=CaseError)
    refused(lambda: model.locked(["j1"]), "values", "must be a mapping", error=CaseError)
    assert model.locked({"j1": 0.3}).n_v == 1


@pytest.mark.parametrize("kwargs, field", [({"strict": "yes"}, "strict"),
                                           ({"floating": 1}, "floating"),
                                           ({"equality": "keep"}, "equality"),
                                           ({"mimic": "ignore"}, "mimic")])
def test_loader_options_are_checked(tmp_path, kwargs, field):
    path = write(tmp_path, urdf(), "r.urdf")
    refused(lambda: load_model(path, **kwargs), field)


@pytest.mark.engine
@pytest.mark.parametrize("text", [REF.format(angle="radian", ref=0.7, ref2=-1.1,
                                             euler="0.1 0.2 0.3"), WALKER, MULTI],
                         ids=["ref", "walker", "multi"])
def test_bodies_sit_where_mujoco_puts_them(tmp_path, text):
    """Every body's centre of mass in the world at qpos0 and at random q equals MuJoCo's xipos
    (refs and anchors move the bodies, not only the dynamics); load_mjcf takes the options."""
    mujoco = pytest.importorskip("mujoco")
    path = write(tmp_path, text, "m.xml")
    model = load_mjcf(path, floating=False, equality="refuse", strict=False)
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(stable_seed("xipos", text[:30]))
    for q in (model.initial(), random_configuration(rng, model)):
        d.qpos[:] = q
        mujoco.mj_forward(m, d)
        kin = rbda.kinematics(model, q, np.zeros(model.n_v))
        for b in range(1, m.nbody):
            k = model.body_names.index(mujoco.mj_id2name(m, mujoco.mjtObj.mjOBJ_BODY, b))
            assert np.allclose(kin.O[k] + kin.R[k] @ model.com[k], d.xipos[b], rtol=0,
                               atol=1e-14), model.body_names[k]


# --------------------------------------------------------------------------- issue 56: items 5, 7
def _link(name, mass, inertia, com="0 0 0"):
    i = inertia
    return (f'<link name="{name}"><inertial><origin xyz="{com}"/><mass value="{mass}"/>'
            f'<inertia ixx="{i}" ixy="0" ixz="0" iyy="{i}" iyz="0" izz="{i}"/></inertial></link>')


# a 200 kg arm turning about z; at its end a Gazebo placeholder (1e-10 kg, 1e-10 kg m^2) on a
# wheel about y: its pivot is 2e-13 of the arm's (refused before as "no inertia")
PLACEHOLDER = ('<robot name="ph"><link name="base"/>' + _link("arm", 200, 0.1, "1.5 0 0")
               + _link("ph", 1e-10, 1e-10) +
               '<joint name="shoulder" type="continuous"><parent link="base"/><child link="arm"/>'
               '<axis xyz="0 0 1"/></joint><joint name="wheel" type="continuous"><parent '
               'link="arm"/><child link="ph"/><origin xyz="0.6 0 0"/><axis xyz="0 1 0"/></joint>'
               '</robot>')


def test_a_placeholder_link_loads_and_is_announced(tmp_path):
    """Tiny but positive mass and inertia keep the pivot finite: loaded, with a note. At rest at
    q = 0 the wheel's axis (y) is across the shoulder's (z) and the placeholder's centre of mass
    is on it, so the GIM is diagonal and gravity (along -z) turns neither joint: a torque of
    1e-10 N m on the wheel gives it qdd = tau / I_yy = 1 rad/s^2 and the shoulder none (a hand
    calculation)."""
    model = load_urdf(write(tmp_path, PLACEHOLDER, "ph.urdf"), strict=True)
    notes_with(model, "joint 'wheel'", "body 'ph' (1e-10 kg)", "placeholder", "loaded")
    qdd = forward_dynamics(model, model.neutral(), np.zeros(2), [0.0, 1e-10])
    np.testing.assert_allclose(qdd, [0.0, 1.0], rtol=1e-12, atol=1e-15)


@pytest.mark.engine
def test_a_placeholder_link_moves_as_pinocchio_moves_it(tmp_path):
    """Pinocchio's aba on the same file (its continuous joints' q as cos, sin) at seeded random
    states, torques of the placeholder's size: the core's qdd to 1e-12 relative (measured 3e-16)."""
    pin = pytest.importorskip("pinocchio")
    path = write(tmp_path, PLACEHOLDER, "ph.urdf")
    model = load_urdf(path)
    pm = pin.buildModelFromUrdf(str(path))
    pm.gravity.linear[:] = model.gravity
    pd = pm.createData()
    rng = np.random.default_rng(stable_seed("placeholder"))
    for _ in range(5):
        q, v, tau = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2) * 1e-10
        qp = np.array([np.cos(q[0]), np.sin(q[0]), np.cos(q[1]), np.sin(q[1])])
        assert rel(forward_dynamics(model, q, v, tau), pin.aba(pm, pd, qp, v, tau)) < 1e-12


def test_only_a_vanishing_pivot_is_refused_and_the_massless_body_named(tmp_path):
    """A massless link at the end of a joint is still refused (its pivot is zero), naming it."""
    text = PLACEHOLDER.replace(_link("ph", 1e-10, 1e-10), '<link name="ph"/>')
    refused(lambda: load_urdf(write(tmp_path, text, "m.urdf")), "joint 'wheel'",
            "body 'ph'", "massless", "GIM is singular")


def test_a_floating_massless_base_is_named_not_the_last_body(tmp_path):
    """A massless floating base whose one child turns on its own joint: the base moves without
    moving any mass. The error names the free joint and the massless base (the first pivot
    that vanishes from the tip); before, NaN pivots made every DOF look bad and the last joint
    and its 1.5 kg body were blamed."""
    text = ('<robot name="fl"><link name="base"/>' + _link("arm", 2.2, 0.1, "0.3 0 0")
            + _link("leg", 1.5, 0.1, "0 0 -0.3") +
            '<joint name="shoulder" type="revolute"><parent link="base"/><child link="arm"/>'
            '<axis xyz="0 0 1"/></joint><joint name="hip" type="revolute"><parent link="arm"/>'
            '<child link="leg"/><origin xyz="0 0.2 0"/><axis xyz="0 1 0"/></joint></robot>')
    err = refused(lambda: load_urdf(write(tmp_path, text, "fl.urdf"), floating=True),
                  "joint 'base_free'", "body 'base' is massless", "('shoulder')",
                  "GIM is singular")
    assert "'leg'" not in str(err) and "'hip'" not in str(err)
    load_urdf(write(tmp_path, text.replace('<link name="base"/>', _link("base", 3, 0.05)),
                    "ok.urdf"), floating=True)  # with a mass of its own it floats


def test_an_undeclared_prefix_in_an_element_not_read_does_not_stop_a_load(tmp_path):
    """robot-assets' fetch.urdf: ``<sensor:camera>`` inside <gazebo>, its prefix never declared
    (ElementTree: "unbound prefix"). Read as urdfdom reads it (no namespaces): one line of what is
    not read. XML that is not well-formed is still refused."""
    text = urdf(more='<gazebo reference="arm"><sensor:camera name="c"><sensor:x a:b="1"/>'
                     '</sensor:camera></gazebo>')
    model = load_urdf(write(tmp_path, text, "r.urdf"), strict=True)
    assert model.notes == ("not read (no effect on the motion): 1 <gazebo>",)
    refused(lambda: load_urdf(write(tmp_path, text.replace("</gazebo>", ""), "bad.urdf")),
            "<xml>", "not well-formed XML", "mismatched tag")


@pytest.mark.engine
def test_a_pid_plugin_actuator_is_announced_as_pushing_at_zero_control(tmp_path):
    """shadow_dexee's actuators are mujoco.pid plugins: a servo that pushes at ctrl 0 (MuJoCo's
    actuator force at ctrl 0 and q != 0 is not zero), so it is announced as acting (strict=True
    refuses it), not as an input."""
    mujoco = pytest.importorskip("mujoco")
    extra = ('<extension><plugin plugin="mujoco.pid"><instance name="pid"><config key="kp" '
             'value="2"/></instance></plugin></extension><actuator><plugin name="servo" '
             'plugin="mujoco.pid" instance="pid" joint="elbow" actdim="0"/></actuator>')
    path = write(tmp_path, mjcf_pendulum(extra=extra), "p.xml")
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    d.qpos[:] = [0.0, 0.3]
    mujoco.mj_forward(m, d)
    assert d.ctrl[0] == 0 and abs(d.actuator_force[0]) > 0.1  # it pushes at ctrl 0
    model = load_mjcf(path)
    notes_with(model, "actuator 'servo': plugin = pid dropped", "pushes even at ctrl 0")
    assert not any("an input" in n for n in model.notes)
    refused(lambda: load_mjcf(path, strict=True), "actuator 'servo'.plugin", "ctrl 0")


FRAMED = """<mujoco><worldbody><site name="on_world" pos="1 0 0"/>
<body name="torso" pos="0 0 1.25"><joint name="rootx" type="slide" axis="1 0 0"/>
 <joint name="rooty" axis="0 1 0" pos="0 0 0.1"/>
 <geom type="capsule" fromto="0 0 0.2 0 0 -0.2" size="0.05"/>
 <body name="leg" pos="0.1 0 -0.6" euler="10 20 30">
  <joint name="knee" axis="0.3 1 0.2" pos="0 0 0.25"/>
  <geom type="capsule" fromto="0 0 0.25 0 0.1 -0.25" size="0.04"/>
  <site name="ankle" pos="0.05 0.02 -0.25" euler="30 -40 70"/>
  <body name="foot" pos="0.1 0 -0.3" quat="0.9 0.1 0.3 0.2"><geom type="box" size="0.1 0.05 0.02"/>
   <site name="toe" pos="0.1 0 0"/>
   <body name="heel" pos="-0.1 0 0" euler="0 0 40"><geom type="sphere" size="0.02"/>
    <site name="heel_pad" pos="0 0.01 -0.02" euler="5 0 0"/></body></body></body>
 <body name="arm" pos="0 0.2 0.1"><joint name="a1" axis="1 0 0" pos="0.02 0 0.05"/>
  <joint name="a2" axis="0 0 1" pos="0.05 0.03 0"/><geom type="capsule" fromto="0 0 0 0.3 0 0"
  size="0.03"/><site name="arm" pos="0.3 0 0" quat="0.5 0.5 0.5 0.5"/></body>
</body></worldbody></mujoco>"""


@pytest.mark.engine
@pytest.mark.parametrize("seed", range(3))
def test_sites_and_bodies_are_frames_where_mujoco_puts_them(tmp_path, seed):
    """Every body's origin (a body's name: MuJoCo's xpos and xmat, also where a joint's ``pos``
    moved the body's frame to its anchor, as the hopper's leg, or the body was fused into its
    parent, as the jointless foot and heel) and every site (a frame by its name, ``arm_site``
    where a body is named ``arm``: site_xpos, site_xmat): frame_motion's position, rotation,
    velocity and angular velocity against mj_objectVelocity, acceleration and angular
    acceleration against mj_objectAcceleration after mj_rnePostConstraint (whose linear part is
    the acceleration minus gravity), at random states with the core's qdd."""
    mujoco = pytest.importorskip("mujoco")
    path = write(tmp_path, FRAMED, "framed.xml")
    model = load_mjcf(path)
    assert "on_world" not in model.frames  # a site on the world does not move: not read
    notes_with(model, "not read (no effect on the motion)", "1 sites on the world")
    m = mujoco.MjModel.from_xml_path(str(path))
    d = mujoco.MjData(m)
    rng = np.random.default_rng(stable_seed("frames", seed))
    q = model.initial() + rng.normal(scale=0.5, size=model.n_q)
    v = rng.normal(size=model.n_v)
    qdd = forward_dynamics(model, q, v)
    d.qpos[:], d.qvel[:] = q, v
    mujoco.mj_forward(m, d)
    d.qacc[:] = qdd
    mujoco.mj_rnePostConstraint(m, d)
    obj, res = mujoco.mjtObj, np.zeros(6)
    objects = [(obj.mjOBJ_XBODY, b, mujoco.mj_id2name(m, obj.mjOBJ_BODY, b), d.xpos[b],
                d.xmat[b]) for b in range(1, m.nbody)]
    objects += [(obj.mjOBJ_SITE, i, mujoco.mj_id2name(m, obj.mjOBJ_SITE, i), d.site_xpos[i],
                 d.site_xmat[i]) for i in range(1, m.nsite)]
    assert len(objects) == 9  # 5 bodies, 4 sites
    for kind, i, name, xpos, xmat in objects:
        frame = f"{name}_site" if kind == obj.mjOBJ_SITE and name == "arm" else name
        f = redysim.frame_motion(model, q, v, qdd, frame=frame)
        mujoco.mj_objectVelocity(m, d, kind, i, res, 0)
        vel = res.copy()
        mujoco.mj_objectAcceleration(m, d, kind, i, res, 0)
        acc = res.copy()
        for ours, theirs in ((f.position, xpos), (f.rotation, xmat.reshape(3, 3)),
                             (f.angular_velocity, vel[:3]), (f.velocity, vel[3:]),
                             (f.angular_acceleration, acc[:3]),
                             (f.acceleration - model.gravity, acc[3:])):
            np.testing.assert_allclose(ours, theirs, rtol=0, atol=1e-12, err_msg=frame)
    leg = redysim.frame_motion(model, model.initial(), np.zeros(model.n_v), frame="leg")
    np.testing.assert_allclose(leg.position, [0.1, 0, 0.65], atol=1e-15)  # not the knee's anchor
