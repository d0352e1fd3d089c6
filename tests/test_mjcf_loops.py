"""Loops and chained couplings from MJCF files (issue 56, item 4): a connect or weld equality
is a cut joint of the model (closed exactly, by default), a chain of joint equalities composes
onto its first leader, a tendon equality of a fixed two-joint tendon is a coupling, and what the
core cannot hold is refused naming the <equality>. Checked against MuJoCo (its constraint
residuals, and its accelerations with the equalities at its hardest solimp: MuJoCo's soft
constraints differ by their regulariser), against hand calculations and against identities
(the residuals, J qdd = -Jdot v, the couplings, energy kept by a run)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import stable_seed

from redysim import mass_matrix, phi, simulate
from redysim.algorithms.loops import ClosedLoops
from redysim.errors import StateError
from redysim.io.importers import ModelFileError, load_mjcf
from redysim.io.kinds import load_model

pytest.importorskip("mujoco")
pytestmark = pytest.mark.engine

HEAD = ('<mujoco><compiler angle="radian"/><option gravity="0 0 -9.81"/>'
        '<default><geom contype="0" conaffinity="0" type="capsule" size="0.02"/></default>')

# a four-bar in the world's xz plane (hinges about y): crank A-B, coupler B-C, rocker D-C,
# closed at C by a connect (of the bodies' points, or of two sites)
FOURBAR = HEAD + """<worldbody>
<body name="crank"><joint name="a" axis="0 1 0"/><geom fromto="0 0 0 0 0 0.3" mass="1"/>
 <body name="coupler" pos="0 0 0.3"><joint name="b" axis="0 1 0"/>
  <geom fromto="0 0 0 0.4 0 0.1" mass="2"/><site name="c1" pos="0.4 0 0.1"/></body></body>
<body name="rocker" pos="0.5 0 0"><joint name="d" axis="0 1 0"/>
 <geom fromto="0 0 0 -0.1 0 0.4" mass="1.5"/><site name="c2" pos="-0.1 0 0.4"/></body>
</worldbody><equality>{eq}</equality></mujoco>"""
CONNECT = '<connect name="pin" body1="coupler" body2="rocker" anchor="0.4 0 0.1"/>'
SITES = '<connect name="pin" site1="c1" site2="c2"/>'

# a parallel gripper like Robotiq 2F-85's: on each side a driver (crank), a coupler on it and
# a follower on a second base pivot, closed by a connect; the drivers coupled by a joint
# equality (mirror images: left = -right)
FINGER = """<body name="{s}_driver" pos="{x} 0 0"><joint name="{s}_driver_joint" axis="0 1 0"/>
 <geom fromto="0 0 0 {x} 0 0.3" mass="0.5"/>
 <body name="{s}_coupler" pos="{x} 0 0.3"><joint name="{s}_coupler_joint" axis="0 1 0"/>
  <geom fromto="0 0 0 {y} 0 0.2" mass="0.4"/></body></body>
<body name="{s}_follower" pos="{z} 0 0.05"><joint name="{s}_follower_joint" axis="0 1 0"/>
 <geom fromto="0 0 0 {w} 0 0.45" mass="0.3"/></body>"""
GRIPPER = HEAD + "<worldbody>" + FINGER.format(s="right", x=0.1, y=0.05, z=0.25, w=0.0) + \
    FINGER.format(s="left", x=-0.1, y=-0.05, z=-0.25, w=-0.0) + """</worldbody><equality>
<connect name="right_loop" body1="right_coupler" body2="right_follower" anchor="0.05 0 0.2"/>
<connect name="left_loop" body1="left_coupler" body2="left_follower" anchor="-0.05 0 0.2"/>
<joint name="drivers" joint1="left_driver_joint" joint2="right_driver_joint"
 polycoef="0 -1 0 0 0"/></equality></mujoco>"""

# three links on hinge triples (x, y, z) from the origin, bent (a straight chain is singular):
# 9 DOF; the last welded to the world where it starts (6 equations: 3 DOF left)
LINK = """<body name="b{k}" pos="{p} 0 0" euler="{e}"><joint name="x{k}" axis="1 0 0"/>
<joint name="y{k}" axis="0 1 0"/><joint name="z{k}" axis="0 0 1"/>
<geom fromto="0 0 0 0.6 0.02 -0.01" size="0.1" mass="{m}"/>"""
SPATIAL = HEAD + "<worldbody>" + LINK.format(k=0, p=0, m=1.0, e="0 0 0") + \
    LINK.format(k=1, p=0.6, m=1.3, e="0.3 -0.4 0.5") + \
    LINK.format(k=2, p=0.6, m=1.6, e="-0.2 0.6 0.4") + "</body></body></body></worldbody>" \
    "<equality>{eq}</equality></mujoco>"

# three hinges on their own bodies, for couplings
THREE = HEAD + "<worldbody>" + "".join(
    f'<body name="l{k}" pos="{0.5 * k} 0 0"><joint name="j{k}" axis="0 1 0"/>'
    f'<geom fromto="0 0 0 0.3 0 0.1" mass="{1 + k}"/></body>' for k in (1, 2, 3)) + \
    "</worldbody>{tendon}<equality>{eq}</equality></mujoco>"


def write(tmp_path, text, name="m.xml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def refused(call, field, *fragments):
    with pytest.raises(ModelFileError) as err:
        call()
    assert err.value.field == field, err.value
    for fragment in fragments:
        assert fragment in str(err.value), err.value
    return err.value


def mujoco_at(path, q, v, tau, d_imp=None):
    """MuJoCo's (qacc, equality residuals efc_pos) at (q, v, tau), its equalities at solimp d
    (default its hardest, mjMAXIMP), Newton's solver iterated to its floor."""
    import mujoco as mj

    m = mj.MjModel.from_xml_path(str(path))
    d_imp = mj.mjMAXIMP if d_imp is None else d_imp
    m.eq_solimp[:] = [d_imp, d_imp, 0.001, 0.5, 2.0]
    m.opt.solver = mj.mjtSolver.mjSOL_NEWTON
    m.opt.tolerance, m.opt.iterations = 1e-15, 1000
    d = mj.MjData(m)
    d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
    mj.mj_forward(m, d)
    rows = d.efc_type == mj.mjtConstraint.mjCNSTR_EQUALITY
    return d.qacc.copy(), d.efc_pos[rows].copy()


def mujoco_hard(path, q, v, tau):
    """MuJoCo's qacc with its equalities hard: its soft solve regularises A = J M^-1 J^T by
    R = r diagApprox, r = (1 - d) / d, so its qacc is smooth in r; extrapolated to r = 0 from
    r = 1e-4 (d = mjMAXIMP), 2e-4 and 4e-4 (Richardson, exact for a quadratic in r), and the
    regularised answer itself (to show the extrapolation is needed)."""
    import mujoco as mj

    r = (1 - mj.mjMAXIMP) / mj.mjMAXIMP
    a1, a2, a4 = (mujoco_at(path, q, v, tau, 1 / (1 + k * r))[0] for k in (1, 2, 4))
    return (8 * a1 - 6 * a2 + a4) / 3, a1


def check_mujoco(path, q, v, tau, qdd, tol):
    """qdd is MuJoCo's hard limit to ``tol`` relative, nearer than MuJoCo's own soft answer."""
    hard, soft = mujoco_hard(path, q, v, tau)
    scale = np.abs(qdd).max()
    assert np.abs(qdd - hard).max() < tol * scale
    assert np.abs(qdd - hard).max() < np.abs(qdd - soft).max()


def on_the_loops(loops, q, rng):
    """A velocity the loops and couplings allow (J v = 0, followers at m times their
    leaders), of size about 1."""
    model = loops.model
    v = model.couple(q, rng.normal(size=model.n_v))[1]
    return loops.project(q, v)[1]


def check_constrained_qdd(loops, q, v, tau):
    """qdd keeps the loops' second derivative (J qdd = -Jdot v), the couplings, and equals the
    dense KKT system's (the GIM and its bias assembled, not the loops' recursions)."""
    model = loops.model
    qdd = loops.forward_dynamics(q, v, tau)
    _, J, Jv, Jdv = loops.evaluate(q, v)
    assert np.abs(Jv).max() < 1e-12
    assert np.abs(J @ qdd + Jdv).max() < 1e-9 * (1 + np.abs(qdd).max())
    A = np.vstack([J] + [np.eye(model.n_v)[int(fv)] - m * np.eye(model.n_v)[int(lv)]
                         for fv, lv, m in zip(*model.coupling_index[2:5], strict=True)])
    b = np.concatenate([-Jdv, np.zeros(A.shape[0] - J.shape[0])])
    M, k = mass_matrix(model.tree, q), A.shape[0]
    dense = np.linalg.lstsq(np.block([[M, -A.T], [A, np.zeros((k, k))]]),
                            np.concatenate([phi(model.tree, q, v) + tau, b]), rcond=None)[0]
    assert np.abs(qdd - dense[:model.n_v]).max() < 1e-8 * np.abs(dense[:model.n_v]).max()
    return qdd


# --------------------------------------------------------------------------- loops
@pytest.mark.parametrize("eq", [CONNECT, SITES], ids=["bodies", "sites"])
def test_a_four_bar_closed_by_connect(tmp_path, eq):
    """The connect is the model's cut, by default: its two in-plane equations (the mechanism
    moves in the xz plane; the y equation repeats them), announced with MuJoCo's softness. Its
    residual is MuJoCo's (at configurations off the loop too), qdd is MuJoCo's to its
    regulariser and keeps J qdd = -Jdot v, and a passive run keeps the energy and the loop."""
    path = write(tmp_path, FOURBAR.format(eq=eq))
    model = load_model(path)
    (cut,) = model.cuts
    assert (cut.name, cut.kind, model.n_v) == ("pin", "plane", 3)
    assert any("equality 'pin': solref, solimp" in n and "held exactly" in n
               for n in model.notes), model.notes
    assert any("'plane' cut" in n for n in model.notes), model.notes
    loops = ClosedLoops(model)
    q0 = model.initial()
    assert max(loops.residuals(q0, np.zeros(3))) < 1e-15
    rng = np.random.default_rng(stable_seed("fourbar", eq))
    for q in (q0 + rng.uniform(-0.3, 0.3, 3) for _ in range(3)):  # off the loop
        gap = loops.evaluate(q, np.zeros(3))[0]
        mj_gap = mujoco_at(path, q, np.zeros(3), np.zeros(3))[1]
        assert abs(mj_gap[1]) < 1e-15  # the normal (y) row is identically zero
        assert np.linalg.norm(gap) == pytest.approx(np.linalg.norm(mj_gap), rel=1e-12)
    v = on_the_loops(loops, q0, rng)
    tau = rng.normal(size=3)
    qdd = check_constrained_qdd(loops, q0, v, tau)
    check_mujoco(path, q0, v, tau, qdd, 1e-9)  # measured 1e-11, soft 1e-4
    sim = simulate(model, 1.0, v0=v, rtol=1e-10, atol=1e-12, sample=0.1)
    assert sim.status == 0, sim.message
    assert np.abs(sim.delta_M).max() < 1e-8
    assert sim.residual_q < 1e-8 and sim.residual_v < 1e-8


def test_a_parallel_gripper_closed_by_connects_and_coupled(tmp_path):
    """Two four-bar fingers, each closed by a connect, the drivers coupled (left = -right): the
    model carries both its cuts and its coupling; qdd is MuJoCo's to its regulariser, keeps the
    loops and the coupling, and a passive run keeps the energy."""
    path = write(tmp_path, GRIPPER)
    model = load_model(path)
    assert [c.name for c in model.cuts] == ["right_loop", "left_loop"]
    (c,) = model.couplings
    assert (c.follower, c.leader, c.multiplier, c.offset) == \
        ("left_driver_joint", "right_driver_joint", -1.0, 0.0)
    loops = ClosedLoops(model)
    q0 = model.initial()
    rng = np.random.default_rng(stable_seed("gripper"))
    v = on_the_loops(loops, q0, rng)
    assert np.linalg.norm(v) > 0.1
    tau = rng.normal(size=model.n_v)
    qdd = check_constrained_qdd(loops, q0, v, tau)
    fv, lv, m = model.coupling_index[2:5]
    assert np.allclose(qdd[fv], m * qdd[lv], rtol=0, atol=1e-12 * np.abs(qdd).max())
    check_mujoco(path, q0, v, tau, qdd, 1e-8)  # measured 7e-10, soft 2e-4
    # (a short run: under gravity the fingers reach a change point, bars in line, at 0.35 s)
    sim = simulate(model, 0.2, v0=0.3 * v, rtol=1e-10, atol=1e-12, sample=0.05)
    assert sim.status == 0, sim.message
    assert np.abs(sim.delta_M).max() < 1e-8
    assert sim.residual_q < 1e-8 and sim.residual_v < 1e-8


def test_a_weld_holds_frame_and_point(tmp_path):
    """The last of three spatial links welded to the world: a 'weld' cut (6 equations, 3 DOF
    left) whose position residual is MuJoCo's and whose qdd is MuJoCo's to its regulariser;
    torquescale 0 leaves the rotation free: a point cut, announced."""
    path = write(tmp_path, SPATIAL.format(eq='<weld name="w" body1="b2"/>'))
    model = load_model(path)
    (cut,) = model.cuts
    assert (cut.kind, cut.body_b) == ("weld", -1)
    loops = ClosedLoops(model)
    q0 = model.initial()
    rng = np.random.default_rng(stable_seed("weld"))
    q = q0 + rng.uniform(-0.2, 0.2, 9)
    assert np.allclose(loops.evaluate(q, np.zeros(9))[0][:3],
                       mujoco_at(path, q, np.zeros(9), np.zeros(9))[1][:3], rtol=0, atol=1e-14)
    v = on_the_loops(loops, q0, rng)
    tau = rng.normal(size=9)
    qdd = check_constrained_qdd(loops, q0, v, tau)
    # MuJoCo's soft weld is 2e-3 off, its extrapolation 6e-5 (the 3 DOF left are stiff: r^3
    # terms still show)
    check_mujoco(path, q0, v, tau, qdd, 3e-4)
    free = load_model(write(tmp_path, SPATIAL.format(
        eq='<weld name="w" body1="b2" torquescale="0"/>'), "ts.xml"))
    assert free.cuts[0].kind == "point"
    assert any("torquescale = 0" in n for n in free.notes), free.notes


# two connects on the hinge line (as ToddlerBot closes its neck's loops): the four-bar's pin
# at C written as two points, C and C + 0.1 y, on each body
HINGE = FOURBAR.replace('<site name="c1" pos="0.4 0 0.1"/>', '<site name="c1" pos="0.4 0 0.1"/>'
                        '<site name="c1z" pos="0.4 0.1 0.1"/>').replace(
    '<site name="c2" pos="-0.1 0 0.4"/>', '<site name="c2" pos="-0.1 0 0.4"/>'
    '<site name="c2z" pos="-0.1 {y} 0.4"/>')
PAIR = '<connect name="pin" site1="c1" site2="c2"/><connect name="pin_z" site1="c1z" site2="c2z"/>'
# a parallelogram (crank and rocker equal and parallel, the coupler the ground's length) with a
# third bar, parallel to both, pinned to the coupler's middle: its loop repeats one equation of
# the first's (each pin written as two connects on the hinge line)
PARALLEL = HEAD + """<worldbody>
<body name="crank"><joint name="a" axis="0 1 0"/><geom fromto="0 0 0 0.1 0 0.3" mass="1"/>
 <body name="coupler" pos="0.1 0 0.3"><joint name="b" axis="0 1 0"/>
  <geom fromto="0 0 0 0.5 0 0" mass="2"/>
  <site name="c1" pos="0.5 0 0"/><site name="c1z" pos="0.5 0.1 0"/>
  <site name="m1" pos="0.25 0 0"/><site name="m1z" pos="0.25 0.1 0"/></body></body>
<body name="rocker" pos="0.5 0 0"><joint name="d" axis="0 1 0"/>
 <geom fromto="0 0 0 0.1 0 0.3" mass="1.5"/>
 <site name="c2" pos="0.1 0 0.3"/><site name="c2z" pos="0.1 0.1 0.3"/></body>
<body name="middle" pos="0.25 0 0"><joint name="e" axis="0 1 0"/>
 <geom fromto="0 0 0 0.1 0 0.3" mass="0.7"/>
 <site name="m2" pos="0.1 0 0.3"/><site name="m2z" pos="0.1 0.1 0.3"/></body>
</worldbody><equality>
<connect name="outer" site1="c1" site2="c2"/><connect name="outer_z" site1="c1z" site2="c2z"/>
<connect name="middle" site1="m1" site2="m2"/><connect name="middle_z" site1="m1z" site2="m2z"/>
</equality></mujoco>"""


def test_two_connects_on_a_hinge_line_are_one_revolute_cut(tmp_path):
    """ToddlerBot's way to close a loop: two connects of the same two bodies, their points on
    the hinge line (6 equations, 2 independent in this planar four-bar). Merged into one
    revolute cut about the line, reduced to its two in-plane equations (a 'plane' cut), both
    announced by the connects' names; the residuals of both of MuJoCo's connects vanish on our
    loops, and qdd is MuJoCo's hard limit (its soft rows take the redundant equations).
    (Before: refused, 'its equations are redundant'.)"""
    path = write(tmp_path, HINGE.format(eq=PAIR, y="0.1"))
    model = load_model(path)
    (cut,) = model.cuts
    assert (cut.name, cut.kind, model.n_v) == ("pin", "plane", 3)
    assert any("'pin', 'pin_z'" in n and "'revolute' cut" in n for n in model.notes), \
        model.notes
    assert any("equality 'pin': 3 of its 5 equations repeat its others" in n and
               "'plane' cut" in n for n in model.notes), model.notes
    loops = ClosedLoops(model)
    rng = np.random.default_rng(stable_seed("hinge pair"))
    q = loops.project(model.initial() + rng.uniform(-0.05, 0.05, 3), np.zeros(3))[0]
    assert np.abs(mujoco_at(path, q, np.zeros(3), np.zeros(3))[1]).max() < 1e-12
    v = on_the_loops(loops, q, rng)
    tau = rng.normal(size=3)
    qdd = check_constrained_qdd(loops, q, v, tau)
    check_mujoco(path, q, v, tau, qdd, 1e-9)
    single = load_model(write(tmp_path, FOURBAR.format(eq=SITES), "one.xml"))
    assert np.allclose(ClosedLoops(single).forward_dynamics(q, v, tau), qdd, rtol=0,
                       atol=1e-12 * np.abs(qdd).max())


def test_a_connect_pair_of_a_spatial_chain_is_a_revolute_cut(tmp_path):
    """Two connects of the last of three spatial links to the world, on a line: one
    'revolute' cut (5 independent equations of 6: 4 DOF left), qdd MuJoCo's hard limit."""
    pair = ('<connect name="p" body1="b2" anchor="0.6 0 0"/>'
            '<connect name="q" body1="b2" anchor="0.3 0.01 -0.005"/>')
    path = write(tmp_path, SPATIAL.format(eq=pair))
    model = load_model(path)
    (cut,) = model.cuts
    assert (cut.name, cut.kind, cut.body_b) == ("p", "revolute", -1)
    loops = ClosedLoops(model)
    q0 = model.initial()
    assert max(loops.residuals(q0, np.zeros(9))) < 1e-12
    rng = np.random.default_rng(stable_seed("spatial pair"))
    v = on_the_loops(loops, q0, rng)
    tau = rng.normal(size=9)
    qdd = check_constrained_qdd(loops, q0, v, tau)
    assert np.linalg.matrix_rank(loops.evaluate(q0, v)[1]) == 5
    check_mujoco(path, q0, v, tau, qdd, 3e-4)  # (MuJoCo's stiff soft rows, as the weld's)


def test_a_parallelogram_bar_keeps_its_one_independent_equation(tmp_path):
    """A parallelogram with a third parallel bar, each pin two connects on the hinge line: the
    first loop a 'plane' cut, the second's in-plane equation along the bar repeats the first
    loop's (the parallelogram moves anyway): a 'line' cut, announced naming the first. One DOF
    left; qdd MuJoCo's hard limit, and a passive run keeps the energy and all of MuJoCo's
    connects shut."""
    path = write(tmp_path, PARALLEL)
    model = load_model(path)
    assert [(c.name, c.kind) for c in model.cuts] == [("outer", "plane"), ("middle", "line")]
    assert any("equality 'middle': 4 of its 5 equations repeat its others and those of "
               "'outer'" in n and "'line' cut" in n for n in model.notes), model.notes
    # the repeated equations are closed by the others, the same motion: `compare` lists them as
    # read with no effect on the motion, not among what the file has and the run does not
    # simulate (issue 56: the 2F-85's page listed them there)
    from redysim.reports.compare import acting_notes

    closing = [n for n in model.notes if n.startswith("equality 'outer'")
               or n.startswith("equality 'middle'")]
    assert len(closing) == 4 and all("no effect on the motion" in n for n in closing), closing
    assert not set(closing) & set(acting_notes(model))
    loops = ClosedLoops(model)
    rng = np.random.default_rng(stable_seed("parallelogram"))
    q = model.initial()
    v = on_the_loops(loops, q, rng)
    assert np.linalg.norm(v) > 0.1
    tau = rng.normal(size=model.n_v)
    qdd = check_constrained_qdd(loops, q, v, tau)
    check_mujoco(path, q, v, tau, qdd, 1e-8)
    sim = simulate(model, 0.3, v0=v, rtol=1e-10, atol=1e-12, sample=0.1)
    assert sim.status == 0, sim.message
    assert np.abs(sim.delta_M).max() < 1e-8
    assert np.abs(mujoco_at(path, sim.q[-1], np.zeros(4), np.zeros(4))[1]).max() < 1e-8


@pytest.mark.parametrize("eq, y, field, fragment", [
    (PAIR, "0.12", "equality 'pin_z'", "0.1 m apart on one body and 0.12 m on the other"),
    (PAIR + '<connect name="third" body1="coupler" body2="rocker" anchor="0.3 0 0.1"/>', "0.1",
     "equality 'third'", "write one <weld> instead"),
])
def test_connects_of_two_bodies_that_cannot_all_hold_are_refused(tmp_path, eq, y, field,
                                                                  fragment):
    """Two connects of the same two bodies whose points are further apart on one body than on
    the other cannot both hold; a third off the line of the first two welds the bodies: both
    refused naming the connect (no traceback from the loops' solve)."""
    path = write(tmp_path, HINGE.format(eq=eq, y=y))
    refused(lambda: load_model(path), field, fragment, "equality='drop'")


def test_equality_options_and_inactive_closures(tmp_path):
    """equality='refuse' refuses a loop closure by name, 'drop' drops it (announced); an
    inactive one is announced, not built."""
    path = write(tmp_path, FOURBAR.format(eq=CONNECT))
    refused(lambda: load_mjcf(path, equality="refuse"), "equality 'pin'", "equality='close'")
    dropped = load_mjcf(path, equality="drop", strict=True)
    assert not dropped.cuts and any("equality 'pin': constraint" in n for n in dropped.notes)
    off = load_mjcf(write(tmp_path, FOURBAR.format(eq=CONNECT.replace(
        "/>", ' active="false"/>')), "off.xml"), strict=True)
    assert not off.cuts and any("inactive" in n for n in off.notes), off.notes


# --------------------------------------------------------------------------- couplings
def test_a_chain_of_joint_equalities_is_composed(tmp_path):
    """j1 = 0.1 - j2 and j2 = 0.2 + j3 (about qpos0 = 0): j1 = -j3 - 0.1 and j2 = j3 + 0.2, both
    led by j3 (by hand); MuJoCo's equality residuals vanish on them, and its qdd agrees."""
    eq = ('<joint name="e1" joint1="j1" joint2="j2" polycoef="0.1 -1 0 0 0"/>'
          '<joint name="e2" joint1="j2" joint2="j3" polycoef="0.2 1 0 0 0"/>')
    path = write(tmp_path, THREE.format(eq=eq, tendon=""))
    model = load_model(path)
    got = {c.follower: (c.leader, c.multiplier, c.offset) for c in model.couplings}
    assert got == {"j1": ("j3", -1.0, pytest.approx(-0.1, abs=1e-15)),
                   "j2": ("j3", 1.0, pytest.approx(0.2, abs=1e-15))}
    rng = np.random.default_rng(stable_seed("chain"))
    q, v = model.couple(rng.normal(size=3), rng.normal(size=3))
    _, gap = mujoco_at(path, q, v, np.zeros(3))
    assert np.abs(gap).max() < 1e-15
    from redysim import forward_dynamics
    tau = rng.normal(size=3)
    qdd = forward_dynamics(model, q, v, tau)
    check_mujoco(path, q, v, tau, qdd, 1e-8)  # measured 4e-10, soft 2e-3


def test_a_tendon_equality_of_a_fixed_two_joint_tendon_is_a_coupling(tmp_path):
    """A fixed tendon L = j1 + 2 j2 held at L0 + 0.3 (L0 = 0 at qpos0): j1 = -2 j2 + 0.3; MuJoCo's
    residual vanishes on it."""
    tendon = ('<tendon><fixed name="t"><joint joint="j1" coef="1"/><joint joint="j2" coef="2"/>'
              '</fixed></tendon>')
    path = write(tmp_path, THREE.format(eq='<tendon name="te" tendon1="t" polycoef="0.3 0 0 0 '
                                           '0"/>', tendon=tendon))
    (c,) = load_model(path).couplings
    assert (c.follower, c.leader, c.multiplier) == ("j1", "j2", -2.0)
    assert c.offset == pytest.approx(0.3, abs=1e-15)
    q = load_model(path).couple(np.array([0.0, 0.4, -0.7]))
    assert np.abs(mujoco_at(path, q, np.zeros(3), np.zeros(3))[1]).max() < 1e-15


TENDONS = ('<tendon><fixed name="t"><joint joint="j1" coef="1"/><joint joint="j2" coef="1"/>'
           '</fixed><fixed name="u"><joint joint="j3" coef="1"/></fixed></tendon>')


@pytest.mark.parametrize("eq, tendon, field, fragment", [
    ('<joint name="sq" joint1="j1" joint2="j2" polycoef="0 1 0.5 0 0"/>', "",
     "equality 'sq'.polycoef", "degree > 1"),
    ('<joint name="e1" joint1="j1" joint2="j2"/><joint name="e2" joint1="j2" joint2="j1"/>', "",
     "equality 'e1'", "cycle"),
    ('<joint name="e1" joint1="j1" joint2="j2"/><joint name="e2" joint1="j1" joint2="j3"/>', "",
     "equality 'e2'", "already follows joint 'j2' (equality 'e1')"),
    ('<joint name="lock" joint1="j1"/>', "", "equality 'lock'.joint1", "holds the joint still"),
    ('<tendon name="tt" tendon1="t" tendon2="u"/>', TENDONS, "equality 'tt'.tendon2",
     "two tendons"),
    ('<tendon name="one" tendon1="u"/>', TENDONS, "equality 'one'.tendon1", "<fixed> one of two"),
])
def test_equalities_the_core_cannot_hold_are_refused_by_name(tmp_path, eq, tendon, field,
                                                             fragment):
    """Before: a chain failed with a CaseError naming an internal field (couplings[0].leader);
    now the file's <equality> is named, with its value."""
    path = write(tmp_path, THREE.format(eq=eq, tendon=tendon))
    refused(lambda: load_model(path), field, fragment, "equality='drop'")
    assert not load_model(path, equality="drop").couplings


def test_a_loop_on_a_floating_model_is_closed(tmp_path):
    """The four-bar on a floating base (a free joint: a quaternion in q, three rates in v): its
    loop is closed with the base free, q moved onto the loop along v by the joints' rates (a
    Newton step that would grow the residual halved); J qdd = -Jdot v, the run keeps the
    energy, the loop and the quaternion's norm, and the free joint's pose never enters the
    loop. (Before: refused as 'not supported yet'.)"""
    path = write(tmp_path, FOURBAR.format(eq=CONNECT).replace(
        "<worldbody>", '<worldbody><body name="base" pos="0 0 1"><freejoint/>'
        '<geom size="0.1" type="sphere" mass="3"/>').replace("</worldbody>",
                                                               "</body></worldbody>"))
    model = load_model(path)
    assert (model.n_q, model.n_v, len(model.cuts)) == (10, 9, 1)
    loops = ClosedLoops(model)
    rng = np.random.default_rng(stable_seed("floating fourbar"))
    q0 = model.initial()
    q = q0.copy()
    q[7:] += rng.uniform(-0.05, 0.05, 3)  # off the loop
    q, v, before, _ = loops.project(q, rng.normal(size=9))
    assert before > 1e-3 and max(loops.residuals(q, v)) < 1e-12
    moved = q.copy()  # the base anywhere, turned anyhow: the loop does not see it
    moved[:3] += (0.3, -2.0, 0.7)
    moved[3:7] = (0.5, 0.5, -0.5, 0.5)
    assert max(loops.residuals(moved, np.zeros(9))) < 1e-12
    check_constrained_qdd(loops, q, v, rng.normal(size=9))
    sim = simulate(model, 0.5, q0=q, v0=v, rtol=1e-10, atol=1e-12, sample=0.1)
    assert sim.status == 0, sim.message
    assert np.abs(sim.delta_M).max() < 1e-8
    assert sim.residual_q < 1e-8 and sim.residual_v < 1e-8


@pytest.mark.parametrize("kind", ["plane", "line"])
def test_a_plane_cut_is_differentiated_right(tmp_path, kind):
    """A 'plane' cut (the points kept together along two axes of a frame on body b, which
    moves and turns; a 'line' cut: along its x axis): its J v and Jdot v are the first and
    second derivatives of its residual along q + t v (hinges: dq/dt = v, qdd = 0), by central
    differences, away from the loop (the residual's normal part and the frame's turning both
    act), and its qdd is the dense KKT system's."""
    from redysim import CutJoint

    model = load_model(write(tmp_path, SPATIAL.format(eq="")))
    turn = np.linalg.qr(np.random.default_rng(5).normal(size=(3, 3)))[0]
    turn *= np.sign(np.linalg.det(turn))
    cut = CutJoint("p", 2, (0.6, 0.0, 0.0), 0, (0.1, 0.2, -0.1), kind,
                   rot_b=tuple(map(tuple, turn)))
    loops = ClosedLoops(model, [cut])
    rng = np.random.default_rng(stable_seed("plane") if kind == "plane" else stable_seed(kind))
    q, v = rng.uniform(-1, 1, 9), rng.normal(size=9)
    gap, J, Jv, Jdv = loops.evaluate(q, v)
    assert np.abs(gap).max() > 0.1 and np.allclose(Jv, J @ v, rtol=0, atol=1e-14)
    h = 1e-4
    up, down = (loops.evaluate(q + s * h * v, np.zeros(9))[0] for s in (1, -1))
    assert np.abs((up - down) / (2 * h) - Jv).max() < 1e-6 * np.abs(Jv).max()
    assert np.abs((up - 2 * gap + down) / h**2 - Jdv).max() < 1e-5 * np.abs(Jdv).max()
    q1 = loops.project(q, v)[0]  # onto the loop, then a velocity it allows
    check_constrained_qdd(loops, q1, on_the_loops(loops, q1, rng), rng.normal(size=9))


def test_a_closure_open_in_the_file_is_announced_and_projected_shut(tmp_path):
    """Two sites 0.01 m apart at qpos0 (MuJoCo pulls them together softly): the model says so
    in its notes, a run refuses the open start by name, and ClosedLoops.project shuts it."""
    path = write(tmp_path, FOURBAR.format(eq=SITES).replace('name="c2" pos="-0.1 0 0.4"',
                                                            'name="c2" pos="-0.1 0 0.41"'))
    model = load_model(path)
    assert any("equality 'pin': open at the file's configuration by up to 0.01" in n
               for n in model.notes), model.notes
    loops = ClosedLoops(model)
    with pytest.raises(StateError, match="violates the cut joint 'pin'"):
        simulate(model, 0.1)
    q, _, _, _ = loops.project(model.initial(), np.zeros(3))
    assert max(loops.residuals(q, np.zeros(3))) < 1e-12
    assert simulate(model, 0.1, q0=q).status == 0
