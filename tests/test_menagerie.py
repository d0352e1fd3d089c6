"""Robots no one here wrote: seven MuJoCo Menagerie models (tests/models/menagerie, mesh-free
fixtures written and checked by ``python -m redysim.references.menagerie --fixtures``), loaded by
``redysim.load_model`` with its default options, against MuJoCo's compile of the same file: the
mass matrix within 1e-12 and the smooth dynamics' qacc within 1e-9 relative (max-norm), with only
what is not smooth dynamics announced (contacts, frictionloss, actuators, ...; the survey's
module docstring says what is compared and how MuJoCo's soft equality constraints are made
exact).

The survey's own yardstick is checked first, on MuJoCo's quantities alone: its exact-constraint
accelerations (Gauss's principle with MuJoCo's equality rows and a differenced Jdot v) against
the reduced-coordinate solution of a joint coupling, G^T M G x = G^T f, and against the
acceleration constraint of a loop closed by ``connect``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.engine
mujoco = pytest.importorskip("mujoco")

from redysim.references import menagerie  # noqa: E402

FIXTURES = Path(__file__).parent / "models" / "menagerie"

COUPLED = """
<mujoco>
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="a" pos="0 0 0">
      <joint name="j1" type="hinge" axis="0 1 0"/>
      <inertial pos="0.2 0 0" mass="1.3" diaginertia="0.01 0.02 0.03"/>
      <body name="b" pos="0.4 0 0">
        <joint name="j2" type="hinge" axis="0 1 0"/>
        <inertial pos="0.15 0.01 0" mass="0.7" diaginertia="0.004 0.006 0.005"/>
        <body name="c" pos="0.3 0 0">
          <joint name="j3" type="slide" axis="1 0 0"/>
          <inertial pos="0.05 0 0.02" mass="0.4" diaginertia="0.002 0.001 0.002"/>
        </body>
      </body>
    </body>
  </worldbody>
  <equality><joint joint1="j3" joint2="j1" polycoef="0.1 -0.5 0 0 0"/></equality>
</mujoco>
"""

FOURBAR = """
<mujoco>
  <worldbody>
    <body name="crank" pos="0 0 0">
      <joint name="c" type="hinge" axis="0 1 0"/>
      <inertial pos="0.1 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <body name="coupler" pos="0.2 0 0">
        <joint name="k" type="hinge" axis="0 1 0"/>
        <inertial pos="0.25 0 0" mass="2" diaginertia="0.02 0.05 0.04"/>
      </body>
    </body>
    <body name="rocker" pos="0.6 0 0.3">
      <joint name="r" type="hinge" axis="0 1 0"/>
      <inertial pos="0 0 0.2" mass="1.5" diaginertia="0.03 0.03 0.01"/>
    </body>
  </worldbody>
  <equality><connect body1="coupler" body2="rocker" anchor="0.5 0 0"/></equality>
</mujoco>
"""


def _model(tmp_path, text, name):
    path = tmp_path / name
    path.write_text(text)
    return path, menagerie._mujoco_model(mujoco, path)


def test_exact_coupling_is_the_reduced_coordinate_solution(tmp_path):
    """q3 = 0.1 - 0.5 q1: with G = d(q)/d(q1, q2), G^T M G x = G^T f, qacc = G x."""
    _, m = _model(tmp_path, COUPLED, "coupled.xml")
    rng = np.random.default_rng(3)
    q = np.array([0.3, -0.7, 0.0])
    q[2] = 0.1 - 0.5 * q[0]
    v = rng.normal(size=3)
    v[2] = -0.5 * v[0]
    tau = rng.normal(size=3)
    qacc, M = menagerie.mujoco_truth(mujoco, m, q, v, tau)
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
    m.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_EQUALITY
    mujoco.mj_forward(m, d)
    G = np.array([[1.0, 0.0], [0.0, 1.0], [-0.5, 0.0]])
    x = np.linalg.solve(G.T @ M @ G, G.T @ (tau + d.qfrc_passive - d.qfrc_bias))
    assert np.max(np.abs(qacc - G @ x)) <= 1e-12 * np.max(np.abs(G @ x))


def test_exact_connect_keeps_the_loop_closed(tmp_path):
    """A four-bar closed by ``connect``: at a closed configuration the exact-constraint qacc
    keeps the two anchors together to second order (the anchors' relative acceleration, by
    differencing positions along the motion, is zero), and the constraint force is along J^T."""
    _, m = _model(tmp_path, FOURBAR, "fourbar.xml")
    d = mujoco.MjData(m)

    def gap(q):  # anchor on the coupler minus the rocker's (the connect's two points)
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        c, r = m.body("coupler").id, m.body("rocker").id
        # MuJoCo's second point: the anchor, in body2's frame as it lies at qpos0
        return (d.xpos[c] + d.xmat[c].reshape(3, 3) @ [0.5, 0, 0]
                - d.xpos[r] - d.xmat[r].reshape(3, 3) @ [0.1, 0, -0.3])

    from scipy.optimize import least_squares

    sol = least_squares(lambda x: gap(np.array([0.4, x[0], x[1]]))[[0, 2]], [0.3, 0.3],
                        xtol=1e-15, ftol=1e-15, gtol=1e-15)
    q = np.array([0.4, *sol.x])
    assert np.max(np.abs(gap(q))) < 1e-12
    J = np.array([(gap(q + 1e-6 * e) - gap(q - 1e-6 * e))[[0, 2]] / 2e-6 for e in np.eye(3)]).T
    v = np.linalg.svd(J)[2][-1]  # a velocity along the loop's one DOF
    tau = np.array([0.3, -0.2, 0.1])
    qacc, _ = menagerie.mujoco_truth(mujoco, m, q, v, tau)
    h = 1e-4  # gap(q(t)) with q(t) = q + v t + qacc t^2 / 2: second differences vanish
    second = (gap(q + v * h + qacc * h * h / 2) - 2 * gap(q) + gap(q - v * h + qacc * h * h / 2))
    assert np.max(np.abs(second)) / (h * h) < 1e-5 * max(1.0, np.max(np.abs(qacc)))


@pytest.mark.parametrize("path", sorted(FIXTURES.glob("*/*.xml")), ids=lambda p: p.parent.name)
def test_fixture_is_the_file(path):
    """Each fixture compiles in MuJoCo without any other file (its meshes removed)."""
    m = mujoco.MjModel.from_xml_path(str(path))
    assert m.nmesh == 0 and m.nv > 0


@pytest.mark.parametrize("path", sorted(FIXTURES.glob("*/*.xml")), ids=lambda p: p.parent.name)
def test_a_menagerie_robot_is_its_file(path):
    """Loaded with default options, each robot agrees with MuJoCo: M within 1e-12, the smooth
    dynamics' qacc within 1e-9 (armature, damping, springs and gravity compensation simulated;
    the Panda's and Talos's joint equalities as couplings, the 2F-85's and Cassie's connects as
    loops, Cassie's ball joints, Stretch 3's jointless bodies of another gravcomp fraction than
    the link they are fused into), and its notes announce only what is not smooth dynamics.
    Before this: every one of them differed or was refused (armature and damping dropped, loops
    and ball joints refused, Talos's chained equalities failing to load; Stretch 3 refused, 'one
    body holds one fraction')."""
    row = menagerie.compare_one(path)
    assert row["status"] == "agrees", row
