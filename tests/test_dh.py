"""Robots from DH tables (redysim.io.dh) and the robot files in cases/robots/.

Checked against what is independent of redysim.io.dh: the DH homogeneous transforms written out
here in closed form (both conventions), a modified table against its standard equivalent (the
same robot, so the same flange pose, GIM and torques), hand-computed PUMA 560 positions, and the
numbers Peter Corke's Robotics Toolbox publishes for its PUMA 560 model in its own unit tests.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import random_inertia, stable_seed

import redysim
from redysim import CaseError, list_cases, load_model, rbda
from redysim.io.cases import CASES_DIR
from redysim.io.dh import DHLink, dh_robot, load_robot

ROBOTS = Path(__file__).resolve().parents[1] / "cases" / "robots"
PUMA = ROBOTS / "puma560.toml"
STANFORD = ROBOTS / "stanford_arm.toml"


# --------------------------------------------------------------------------- the transforms
def dh_standard(a, alpha, d, theta) -> np.ndarray:
    """Rz(theta) Tz(d) Tx(a) Rx(alpha), multiplied out (Paul 1981; Spong, eq. 3.10)."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st * ca, st * sa, a * ct],
                     [st, ct * ca, -ct * sa, a * st],
                     [0.0, sa, ca, d],
                     [0.0, 0.0, 0.0, 1.0]])


def dh_modified(a, alpha, d, theta) -> np.ndarray:
    """Rx(alpha_{i-1}) Tx(a_{i-1}) Rz(theta_i) Tz(d_i), multiplied out (Craig, eq. 3.6)."""
    ct, st, ca, sa = math.cos(theta), math.sin(theta), math.cos(alpha), math.sin(alpha)
    return np.array([[ct, -st, 0.0, a],
                     [st * ca, ct * ca, -sa, -sa * d],
                     [st * sa, ct * sa, ca, ca * d],
                     [0.0, 0.0, 0.0, 1.0]])


def forward_kinematics(links, convention, q) -> list[np.ndarray]:
    """World poses of DH frames 1..n: the product of the rows' transforms."""
    T, out = np.eye(4), []
    step = dh_standard if convention == "standard" else dh_modified
    for link, qk in zip(links, q, strict=True):
        theta = link.theta + (qk if link.joint == "R" else 0.0)
        d = link.d + (qk if link.joint == "P" else 0.0)
        T = T @ step(link.a, link.alpha, d, theta)
        out.append(T)
    return out


def random_table(rng, n, joints=("R", "P")) -> list[DHLink]:
    links = []
    for k in range(n):
        mass = rng.uniform(0.2, 3.0)
        links.append(DHLink(a=rng.uniform(-0.5, 0.5), alpha=rng.uniform(-np.pi, np.pi),
                            d=rng.uniform(-0.5, 0.5), theta=rng.uniform(-np.pi, np.pi),
                            joint=str(rng.choice(joints)), mass=mass,
                            com=tuple(rng.normal(scale=0.2, size=3)),
                            inertia=random_inertia(rng, mass, rng.uniform(0.1, 0.6)),
                            name=f"l{k}"))
    return links


# --------------------------------------------------------------------------- (a) frames
@pytest.mark.parametrize("convention", ["standard", "modified"])
@pytest.mark.parametrize("n", [1, 2, 7])
def test_the_models_frames_are_the_dh_product(convention, n):
    """Every DH frame's pose (dh_frames), the named frame origins dh1..dhN and the flange equal
    the product of the DH transforms, at random configurations of random R/P tables; the
    body frames are Craig's: for a modified table the DH frames themselves, for a standard one
    frame k-1 turned by theta_k and moved d_k along z_{k-1}."""
    rng = np.random.default_rng(stable_seed("dh-frames", convention, n))
    links = random_table(rng, n)
    flange = rng.normal(scale=0.1, size=3)
    robot = dh_robot(links, convention=convention, flange=flange)
    model = robot.model
    for _ in range(3):
        q = rng.uniform(-np.pi, np.pi, n)
        expected = forward_kinematics(links, convention, q)
        got = robot.dh_frames(q)
        for k in range(n):
            assert np.allclose(got[k], expected[k], rtol=0, atol=1e-13)
            assert np.allclose(rbda.frame_position(model, q, f"dh{k + 1}"),
                               expected[k][:3, 3], rtol=0, atol=1e-13)
        tip = expected[-1] @ np.append(flange, 1.0)
        assert np.allclose(rbda.frame_position(model, q, "flange"), tip[:3], atol=1e-13)
        assert np.allclose(robot.flange_pose(q)[:3, 3], tip[:3], atol=1e-13)
        kin = rbda.kinematics(model, q, np.zeros(n))
        for k in range(n):
            if convention == "modified":
                body = expected[k]
            else:
                link, prev = links[k], (expected[k - 1] if k else np.eye(4))
                theta = link.theta + (q[k] if link.joint == "R" else 0.0)
                d = link.d + (q[k] if link.joint == "P" else 0.0)
                body = prev @ dh_standard(0.0, 0.0, d, theta)
            assert np.allclose(kin.R[k], body[:3, :3], atol=1e-13)
            assert np.allclose(kin.O[k], body[:3, 3], atol=1e-13)


def test_gravity_defaults_to_minus_z_and_inertia_is_in_the_dh_frame():
    """Robot convention: z up. One link turning about z0, with its COM at (a, 0, 0) + c in its
    DH frame: the gravity torque and the moment of inertia about z0 by hand."""
    a, m, c = 0.5, 2.0, np.array([0.1, 0.2, 0.3])
    I_c = np.diag([0.01, 0.02, 0.025])
    # alpha = 90 deg: frame 1's y is z0, so I_c's Iyy is the moment about the joint axis
    robot = dh_robot([DHLink(a=a, alpha=np.pi / 2, joint="R", mass=m, com=c, inertia=I_c)],
                     convention="standard")
    model = robot.model
    assert np.array_equal(model.gravity, [0.0, 0.0, -9.81])
    gim = redysim.mass_matrix(model, np.zeros(1))
    # COM in frame 0 at q = 0: (a + cx, -cz, cy); distance^2 from the z0 axis
    r2 = (a + c[0]) ** 2 + c[2] ** 2
    assert gim[0, 0] == pytest.approx(0.02 + m * r2, rel=1e-13)
    # a vertical axis: gravity along -z0 gives no torque about z0
    tau = redysim.inverse_dynamics(model, np.zeros(1), np.zeros(1), np.zeros(1))
    assert tau[0] == pytest.approx(0.0, abs=1e-14)


# --------------------------------------------------------------------------- (b) conventions
def standard_to_modified(links) -> list[DHLink]:
    """The modified table of the same robot: row k takes standard row k-1's (a, alpha) and
    link k's COM and inertia move from standard frame k to Craig's frame k, which is standard
    frame k . (Tx(a_k) Rx(alpha_k))^-1."""
    out, prev_a, prev_alpha = [], 0.0, 0.0
    for link in links:
        ca, sa = math.cos(link.alpha), math.sin(link.alpha)
        Rx = np.array([[1, 0, 0], [0, ca, -sa], [0, sa, ca]])
        com = np.array([link.a, 0.0, 0.0]) + Rx @ np.asarray(link.com)
        inertia = Rx @ np.asarray(link.inertia) @ Rx.T
        out.append(DHLink(a=prev_a, alpha=prev_alpha, d=link.d, theta=link.theta,
                          joint=link.joint, mass=link.mass, com=tuple(com), inertia=inertia))
        prev_a, prev_alpha = link.a, link.alpha
    return out


@pytest.mark.parametrize("n", [3, 8])
def test_a_modified_table_and_its_standard_equivalent_are_one_robot(n):
    """Same flange pose, GIM, gravity and velocity torques: the standard table's last row has
    a = alpha = 0 (a flange row), so its frame n is the modified table's."""
    rng = np.random.default_rng(stable_seed("dh-std-mod", n))
    std = random_table(rng, n)
    last = std[-1]
    std[-1] = DHLink(a=0.0, alpha=0.0, d=last.d, theta=last.theta, joint=last.joint,
                     mass=last.mass, com=last.com, inertia=last.inertia)
    flange = rng.normal(scale=0.1, size=3)
    g = (0.0, 0.0, -9.81)
    robot_s = dh_robot(std, convention="standard", flange=flange, gravity=g)
    robot_m = dh_robot(standard_to_modified(std), convention="modified", flange=flange,
                       gravity=g)
    for _ in range(3):
        q, v, vd = (rng.uniform(-np.pi, np.pi, n), rng.normal(size=n), rng.normal(size=n))
        assert np.allclose(robot_s.flange_pose(q), robot_m.flange_pose(q), atol=1e-13)
        gim_s = redysim.mass_matrix(robot_s.model, q)
        gim_m = redysim.mass_matrix(robot_m.model, q)
        assert np.allclose(gim_s, gim_m, rtol=0, atol=1e-12 * np.abs(gim_s).max())
        tau_s = redysim.inverse_dynamics(robot_s.model, q, v, vd)
        tau_m = redysim.inverse_dynamics(robot_m.model, q, v, vd)
        assert np.allclose(tau_s, tau_m, rtol=0, atol=1e-12 * np.abs(tau_s).max())
        # and the GIM is the one the reference recursion assembles
        assert np.allclose(rbda.mass_matrix(robot_m.model, q), gim_m, atol=1e-12)


# --------------------------------------------------------------------------- (c) PUMA 560
def test_robot_files_load_and_are_not_rope_cases():
    puma, stanford = load_model(PUMA), load_model(STANFORD)
    assert (puma.n_v, stanford.n_v) == (6, 6)
    assert puma.total_mass == pytest.approx(17.4 + 4.8 + 0.82 + 0.34 + 0.09, rel=1e-15)
    assert stanford.joint_types == ("R", "R", "P", "R", "R", "R")
    assert not {"puma560", "stanford_arm"} & set(list_cases())
    rope = load_model(Path(CASES_DIR) / "STUDY-R3.toml")  # still a rope case
    assert rope.n_bodies == 3


def test_puma_560_positions_by_hand():
    """Hand-computed from the file's table (standard DH, a2 = 0.4318, d3 = 0.15005,
    a3 = 0.0203, d4 = 0.4318, flange 0.056 along z6).

    qz = 0: frames 1 and 2 turn z to -y0 (alpha1 = 90 deg), frame 3 turns it back (alpha3 =
    -90 deg): O2 = (0.4318, 0, 0), O3 = O2 + 0.15005 z2 + 0.0203 x2 = (0.4521, -0.15005, 0),
    the wrist centre O4 = O3 + 0.4318 z3 = (0.4521, -0.15005, 0.4318), and z6 = z0, so the
    flange is 0.056 above it. Corke (Robotics, Vision and Control, 2011, sec. 7.2.2) prints
    p560.fkine(qz) with translation (0.4521, -0.1500, 0.4318).

    qr = (0, 90, -90, 0, 0, 0) deg, the arm straight up: x2 = z0, O2 = (0, 0, 0.4318); joint 3
    turns x back to x0: O3 = (0.0203, -0.15005, 0.4318), the wrist centre 0.4318 higher at
    (0.0203, -0.15005, 0.8636), the flange at 0.9196."""
    model = load_model(PUMA)
    qz = np.zeros(6)
    qr = np.radians([0.0, 90.0, -90.0, 0.0, 0.0, 0.0])
    for q, wrist in ((qz, (0.4521, -0.15005, 0.4318)), (qr, (0.0203, -0.15005, 0.8636))):
        assert np.allclose(rbda.frame_position(model, q, "dh6"), wrist, rtol=0, atol=1e-12)
        flange = np.array(wrist) + (0.0, 0.0, 0.056)
        assert np.allclose(rbda.frame_position(model, q, "flange"), flange, rtol=0, atol=1e-12)


def test_stanford_arm_position_by_hand():
    """qz: d1 = 0.412 up z0, alpha1 = -90 deg turns z1 to +y0, d2 = 0.154 along it, alpha2 =
    90 deg turns z2 back to z0; the boom (q3 = 0) and the wrist add nothing, the flange is
    0.263 up z6 = z0: (0, 0.154, 0.675). With q3 = 0.5 m the boom slides 0.5 along z2 = z0."""
    model = load_model(STANFORD)
    q = np.zeros(6)
    assert np.allclose(rbda.frame_position(model, q, "flange"), (0, 0.154, 0.675), atol=1e-12)
    q[2] = 0.5
    assert np.allclose(rbda.frame_position(model, q, "flange"), (0, 0.154, 1.175), atol=1e-12)


# Corke's PUMA 560 adds each motor's reflected inertia G^2 Jm to the GIM's diagonal (its rne:
# "+ link.G**2 * link.Jm * qdd"); the rigid-body GIM is its inertia(q) less these. Jm and G are
# the toolbox's, from mdl_puma560.m / Puma560.py.
JM = np.array([200e-6, 200e-6, 200e-6, 33e-6, 33e-6, 33e-6])
GEAR = np.array([-62.6111, 107.815, -53.7063, 76.0364, 71.923, 76.686])
ARMATURE = np.diag(JM * GEAR**2)
# Printed with 4 decimals: a value agrees when within half a unit of the last digit.
PRINTED = 0.5e-4 + 1e-12

# Robotics Toolbox for MATLAB, unit_test/SerialLinkTest.m (github.com/petercorke/robotics-
# toolbox-matlab, commit bd7a9d75, 2020), gravload_test and inertia_test, model mdl_puma560.
MATLAB_Q = [(0, np.pi / 4, -np.pi, 1, np.pi / 4, 0), (0, np.pi / 2, -np.pi, 1, np.pi / 2, 0)]
MATLAB_GRAVLOAD = [(-0.0000, 31.6334, 6.0286, -0.0119, 0.0218, 0),
                   (0.0000, 7.7198, 8.7439, -0.0238, -0.0000, 0)]
MATLAB_INERTIA = [
    [[3.6591, -0.4042, 0.1013, -0.0021, -0.0015, -0.0000],
     [-0.4042, 4.4128, 0.3504, -0.0008, 0.0017, 0.0000],
     [0.1013, 0.3504, 0.9377, -0.0008, 0.0008, 0.0000],
     [-0.0021, -0.0008, -0.0008, 0.1925, 0.0000, 0.0000],
     [-0.0015, 0.0017, 0.0008, 0.0000, 0.1713, 0.0000],
     [-0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.1941]],
    [[2.6621, -0.6880, 0.0035, -0.0007, -0.0010, 0.0000],
     [-0.6880, 4.4114, 0.3487, -0.0010, 0.0015, 0.0000],
     [0.0035, 0.3487, 0.9359, -0.0010, 0.0003, 0.0000],
     [-0.0007, -0.0010, -0.0010, 0.1926, 0.0000, 0.0000],
     [-0.0010, 0.0015, 0.0003, 0.0000, 0.1713, 0.0000],
     [0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.1941]]]
# Robotics Toolbox for Python, tests/test_DHRobot.py (github.com/petercorke/robotics-toolbox-
# python, commit a9ed8d45), test_gravload and test_inertia, model Puma560 at its qn.
PYTHON_Q = (0, np.pi / 4, np.pi, 0, np.pi / 4, 0)
PYTHON_GRAVLOAD = (-0.0000, 31.6399, 6.0351, 0.0000, 0.0283, 0)
PYTHON_INERTIA = [[3.6594, -0.4044, 0.1006, -0.0025, 0.0000, -0.0000],
                  [-0.4044, 4.4137, 0.3509, 0.0000, 0.0024, 0.0000],
                  [0.1006, 0.3509, 0.9378, 0.0000, 0.0015, 0.0000],
                  [-0.0025, 0.0000, 0.0000, 0.1925, 0.0000, 0.0000],
                  [0.0000, 0.0024, 0.0015, 0.0000, 0.1713, 0.0000],
                  [-0.0000, 0.0000, 0.0000, 0.0000, 0.0000, 0.1941]]


@pytest.mark.parametrize("q, gravload, inertia", [
    (MATLAB_Q[0], MATLAB_GRAVLOAD[0], MATLAB_INERTIA[0]),
    (MATLAB_Q[1], MATLAB_GRAVLOAD[1], MATLAB_INERTIA[1]),
    (PYTHON_Q, PYTHON_GRAVLOAD, PYTHON_INERTIA),
], ids=["matlab-qn", "matlab-q2", "python-qn"])
def test_puma_560_against_the_robotics_toolbox(q, gravload, inertia):
    """Gravity torques (the torque that holds the arm still: tau at v = vdot = 0) and the GIM
    (plus the toolbox's armature terms) at the toolbox's configurations, to its printed digits.
    The toolbox's d1 (0 in MATLAB, 0.672 m in Python) moves the arm vertically and changes
    neither."""
    model = load_model(PUMA)
    q = np.array(q, dtype=float)
    tau = redysim.inverse_dynamics(model, q, np.zeros(6), np.zeros(6))
    assert np.abs(tau - gravload).max() <= PRINTED
    gim = redysim.mass_matrix(model, q) + ARMATURE
    assert np.abs(gim - np.array(inertia)).max() <= PRINTED
    assert np.abs(rbda.mass_matrix(model, q) + ARMATURE - np.array(inertia)).max() <= PRINTED


# --------------------------------------------------------------------------- (d) bad files
GOOD = """\
[robot]
name = "two links"
convention = "standard"

[[link]]
joint = "R"
a = 0.4
alpha_deg = 90.0
d = 0.1
theta_deg = 0.0
mass = 2.0
com = [-0.2, 0.0, 0.0]
inertia = [0.01, 0.03, 0.03]

[[link]]
joint = "P"
a = 0.0
alpha_deg = 0.0
d = 0.0
theta_deg = -90.0
mass = 1.0
com = [0.0, 0.0, -0.1]
inertia = [0.02, 0.02, 0.001]
"""


def test_the_good_file_loads(tmp_path):
    path = tmp_path / "robot.toml"
    path.write_text(GOOD)
    robot = load_robot(path)
    assert robot.model.joint_types == ("R", "P") and robot.model.name == "two links"


def second(old, new):
    """Replace ``old`` in the second [[link]] only."""
    head, tail = GOOD.split("[[link]]\njoint = \"P\"")
    return lambda s: head + ("[[link]]\njoint = \"P\"" + tail).replace(old, new, 1)


BAD = [  # (edit of GOOD, field named, value shown, words of the problem)
    (lambda s: s.replace('joint = "R"', 'joint = "Q"'), "link[0].joint", "'Q'",
     "unknown joint type"),
    (lambda s: s.replace('joint = "R"', 'joint = "revolute"'), "link[0].joint", "'revolute'",
     "R (revolute about z) or P"),
    (second("alpha_deg = 0.0", "alpha_deg = nan"), "link[1].alpha_deg", "nan", "finite"),
    (lambda s: s.replace("d = 0.1", "d = inf"), "link[0].d", "inf", "finite"),
    (lambda s: s.replace("a = 0.4", 'a = "0.4"'), "link[0].a", "'0.4'", "must be a number"),
    (lambda s: s.replace("mass = 2.0", "mass = -2.0"), "link[0].mass", "-2.0", ">= 0"),
    (lambda s: s.replace("[0.01, 0.03, 0.03]", "[0.1, 0.03, 0.03]"), "link[0].inertia",
     "[0.1, 0.03, 0.03]", "triangle inequality"),
    (lambda s: s.replace("[0.01, 0.03, 0.03]", "[-0.01, 0.03, 0.03]"), "link[0].inertia",
     "[-0.01, 0.03, 0.03]", "positive semi-definite"),
    (lambda s: s.replace("[0.01, 0.03, 0.03]", "[[0.01, 0.002, 0], [0, 0.03, 0], [0, 0, 0.03]]"),
     "link[0].inertia", "[[0.01, 0.002, 0]", "symmetric"),
    (lambda s: s.replace("[-0.2, 0.0, 0.0]", "[-0.2, 0.0]"), "link[0].com", "[-0.2, 0.0]",
     "3 numbers"),
    (lambda s: s.replace('"standard"', '"craig"'), "robot.convention", "'craig'", "modified"),
    (lambda s: s.replace('convention = "standard"\n', ""), "robot.convention", None,
     "missing"),
    (lambda s: s.replace("a = 0.4\n", ""), "link[0].a", None, "missing field (DH row 1)"),
    (lambda s: s.replace("alpha_deg = 90.0", "alpha = 1.5708"), "link[0].alpha", "1.5708",
     "unknown field"),
    (lambda s: s.replace("[robot]", "[robot]\ngravity = [0.0, -9.81]"), "robot.gravity",
     "[0.0, -9.81]", "3 numbers"),
    (lambda s: s + '\n[case]\nname = "x"\n', "case", "{'name': 'x'}", "unknown table"),
    (lambda s: s.split("[[link]]")[0], "link", None, "missing [[link]]"),
    (second("mass = 1.0", "mass = 0.0"), "link[1]", None, "no mass along its axis"),
    (lambda s: s.replace("[0.02, 0.02, 0.001]", "[0.0, 0.0, 0.0]").replace("mass = 1.0",
                                                                            "mass = 0.0"),
     "link[1]", None, "GIM is singular"),
]


@pytest.mark.parametrize("edit, field, shown, words", BAD,
                         ids=[f"{i}-{b[1]}" for i, b in enumerate(BAD)])
def test_bad_robot_files_name_the_file_field_and_value(tmp_path, edit, field, shown, words):
    path = tmp_path / "bad_robot.toml"
    path.write_text(edit(GOOD))
    with pytest.raises(CaseError) as info:
        load_model(path)
    err = info.value
    message = str(err)
    assert message.startswith(f"{path}: {field}")
    assert err.field == field and err.source == str(path)
    if shown is not None:
        assert f"{field} = {shown}" in message
    assert words in message


def test_a_table_given_in_python_names_its_row():
    with pytest.raises(CaseError, match=r"dh\[1\]\.joint = 'U'"):
        dh_robot([DHLink(mass=1.0, inertia=(1, 1, 1)), DHLink(joint="U")],
                 convention="standard")
    with pytest.raises(CaseError, match=r"dh\[0\]\.alpha = nan: must be finite"):
        dh_robot([DHLink(alpha=float("nan"), mass=1.0, inertia=(1, 1, 1))],
                 convention="modified")
    with pytest.raises(CaseError, match=r"convention = 'distal'"):
        dh_robot([DHLink(mass=1.0, inertia=(1, 1, 1))], convention="distal")
