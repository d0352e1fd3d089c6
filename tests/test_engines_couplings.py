"""A robot with a coupled gripper keeps every engine (issue 56, item 6): a small arm whose two
pairs of fingers are coupled (tests/models/coupled_gripper.xml, MJCF joint equalities, and
coupled_gripper.urdf, URDF mimic joints), one follower before its leader in the tree (as
Menagerie's Panda's fingers) and one after, with multipliers other than +-1 and offsets.

Each engine's qdd against the core's coupled qdd (the core's own check of that qdd is
tests/test_couplings.py: the reduced-coordinate solve written independently): Pinocchio's CRBA
on its own mimic joints, Exudyn's CoordinateConstraints (its implicit solver's initial
accelerations), DART and Drake on their own mass matrix and bias coupled by the adapter (they
have no coupling reachable: each says why). MuJoCo holds couplings softly, which
tests/test_couplings.py checks against its regulariser. Then short runs: each engine's qdd in
redysim's integrator along the core's path, MuJoCo's own integrator, which holds the couplings,
and DART's, Exudyn's and Drake's own integrators refused by name. Last, ``redysim compare`` on
the gripper keeps the engines, and its first screen says what the file has that the run does
not simulate.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import stable_seed
from engine_chains import engine_or_skip

import redysim

MODELS = Path(__file__).parent / "models"
FILES = ("coupled_gripper.xml", "coupled_gripper.urdf")
PROJECTED = ("dart", "drake")  # no coupling of their own reachable (each says why)
BUILT = ("pinocchio-crba", "exudyn", *PROJECTED)
UNCOUPLED_STEPS = ("dart", "exudyn", "drake")  # their own integrators would not hold them


def gripper(file):
    model = redysim.load_model(MODELS / file)
    names = list(model.joint_names)
    # the test's premise: one follower before its leader in the tree, one after
    fingers, thumbs = model.couplings
    assert (fingers.follower, fingers.leader) == ("finger_a", "finger_b")
    assert names.index("finger_a") < names.index("finger_b")
    assert (thumbs.follower, thumbs.leader) == ("thumb_b", "thumb_a")
    assert names.index("thumb_a") < names.index("thumb_b")
    return model


def coupled_state(model, rng):
    q = model.initial() + rng.uniform(-0.8, 0.8, model.n_q)
    q, v = model.couple(q, rng.normal(size=model.n_v))
    return q, v, rng.normal(size=model.n_v)


def test_pinocchios_mimic_joint_comes_after_the_joint_it_mimics():
    """transformJointIntoMimic needs the mimicked joint first: finger_a = 0.8 finger_b + 0.001
    with finger_a first becomes finger_b = finger_a / 0.8 - 0.001 / 0.8 (by hand: 1.25,
    -0.00125); thumb_b after thumb_a stays as written."""
    from redysim.references.pinocchio_engine import mimic_order

    (f1, l1, m1, c1), second = mimic_order(gripper("coupled_gripper.xml"))
    assert (f1, l1) == ("finger_b", "finger_a")
    assert m1 == pytest.approx(1.25, rel=1e-15) and c1 == pytest.approx(-0.00125, rel=1e-15)
    assert second == ("thumb_b", "thumb_a", -1.3, 0.05)


@pytest.mark.engine
@pytest.mark.parametrize("name", BUILT)
@pytest.mark.parametrize("file", FILES)
def test_each_engine_gives_the_cores_coupled_qdd(file, name):
    model = gripper(file)
    eng = engine_or_skip(name)(model)
    rng = np.random.default_rng(stable_seed("engine-coupled", file, name))
    for _ in range(4):
        q, v, tau = coupled_state(model, rng)
        for t in (tau, None):
            core = redysim.forward_dynamics(model, q, v, t)
            got = eng.qdd(q, v, t)
            assert np.abs(got - core).max() < 1e-9 * np.abs(core).max(), (name, t is None)
            _, _, fv, lv, m, _ = model.coupling_index
            assert np.allclose(got[fv], m * got[lv], rtol=1e-12, atol=0.0)  # on the couplings


@pytest.mark.engine
@pytest.mark.parametrize("file", FILES)
def test_the_engines_without_coupling_refuse_nothing_and_say_how_they_couple(file):
    """Every engine but Pinocchio's ABA (pinocchio-crba builds the mimic joints) takes the
    coupled model; the ones without a coupling of their own name why in how they couple."""
    from redysim import references

    model = gripper(file)
    for name in references.ENGINES:
        lim = references.get(name).limits(model)
        assert lim.ok == (name not in ("pinocchio-aba", "pinocchio-aba-ryrz")), (name, lim)
    for name in PROJECTED:
        how = references.get(name).coupling()
        assert "G^T M G" in how and references.get(name).no_couplings in how
    assert "CoordinateConstraint" in references.get("exudyn").coupling()
    assert "pinocchio-crba builds them" in references.get("pinocchio-aba").limits(model).reason


@pytest.mark.engine
@pytest.mark.parametrize("name", BUILT)
def test_a_short_run_on_each_engines_qdd_follows_the_cores_path(name):
    """0.3 s of free fall from a coupled state, DOP853 at 1e-10 on the engine's qdd and on the
    core's: the same path to the integrator's tolerance, the couplings held."""
    from redysim.simulation import simulator

    model = gripper("coupled_gripper.urdf")
    eng = engine_or_skip(name)(model)
    q0, v0, _ = coupled_state(model, np.random.default_rng(stable_seed("engine-coupled-run")))
    runs = [simulator(model, 0.3, q0=q0, v0=v0, integrator="dop853", rtol=1e-10, atol=1e-10,
                      sample=0.05, **kw).run() for kw in ({}, {"qdd": eng.qdd})]
    core, got = runs
    assert got.status == 0 and len(got.t) == len(core.t) == 7
    assert np.abs(got.q - core.q).max() < 1e-7
    fq, lq, _, _, m, off = model.coupling_index
    assert np.abs(got.q[:, fq] - (m * got.q[:, lq] + off)).max() < 1e-9


@pytest.mark.engine
def test_mujocos_own_integrator_holds_the_coupling_and_the_others_refuse_theirs():
    """MuJoCo's RK4 with its joint equalities: the core's path within MuJoCo's softness and
    step (0.3 s, h = 1 ms), the couplings held to it; DART's, Exudyn's and Drake's own
    integrators would step the joints uncoupled: refused, naming the couplings."""
    from redysim.simulation import simulator

    model = gripper("coupled_gripper.xml")
    q0, v0, _ = coupled_state(model, np.random.default_rng(stable_seed("engine-coupled-own")))
    mj = engine_or_skip("mujoco")(model)
    traj = mj.simulate(q0, v0, 0.3, 1e-3, every=50)
    core = simulator(model, 0.3, q0=q0, v0=v0, integrator="dop853", rtol=1e-10, atol=1e-10,
                     sample=0.05).run()
    assert np.allclose(traj.t, core.t)
    err = np.abs(traj.q - core.q).max()
    assert err < 1e-4, err  # measured 3.0e-6 (the equality's softness and the step)
    fq, lq, _, _, m, off = model.coupling_index
    assert np.abs(traj.q[:, fq] - (m * traj.q[:, lq] + off)).max() < 1e-4  # measured 5.0e-6
    for name in UNCOUPLED_STEPS:
        eng = engine_or_skip(name)(model)
        info = eng.native_integrator()
        settings = {"rtol": 1e-6} if info.adaptive else {}
        with pytest.raises(ValueError, match="does not hold the model's couplings"):
            eng.sim_reset(q0, v0, 1e-3, **settings)


@pytest.mark.engine
def test_compare_keeps_the_engines_on_a_coupled_gripper(tmp_path, monkeypatch):
    """``redysim compare`` on the gripper with a tiny budget (one setting per ladder, 0.02 s):
    at least four engines beside the core run ok (Pinocchio by its CRBA's mimic joints, DART,
    Exudyn and Drake through their qdd, MuJoCo with its own integrators too); the engines whose
    own integrators do not hold the couplings get no run of those (Exudyn's implicit ones
    run), and the page's first screen
    (before its first section) names what the file has that the run does not simulate."""
    import pandas as pd

    from redysim.harness.spec import CORE
    from redysim.reports import compare as cmp

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))  # the reference's cache
    for key, value in (("CORE_RTOLS", (1e-7,)), ("ENGINE_RTOLS", (1e-7,)),
                       ("STEP_DIVISIONS", (5,)), ("NATIVE_RTOLS", (1e-6,))):
        monkeypatch.setattr(cmp, key, value)
    out = tmp_path / "cmp"
    html, _ = cmp.compare(str(MODELS / "coupled_gripper.urdf"), out, t_end=0.02, workers=1,
                          progress=False, log=lambda *a: None)
    runs = pd.read_parquet(out / "runs.parquet")
    ok = runs[runs["status"] == "ok"]
    engines = set(ok["engine"]) - {CORE}
    assert len(engines) >= 4, sorted(engines)
    assert (runs["status"] == "ok").all(), runs.loc[runs["status"] != "ok", "reason"].tolist()
    native = runs[runs["integrator"].str.startswith("native:")]
    assert set(native["engine"]) <= {"mujoco", "exudyn"}
    assert set(native.loc[native["engine"] == "exudyn", "integrator"]) <= {
        "native:generalized-alpha", "native:trapezoidal"}  # its implicit ones hold them
    page = html.read_text()
    first_screen = page[:page.index('<section id="model">')]
    assert "in the file, not simulated" in first_screen
    assert "joint &lt;limit&gt; lower, upper (4 joints)" in first_screen
    assert "engines that ran" in first_screen
    assert "no effect on the motion" not in first_screen


@pytest.mark.engine
@pytest.mark.parametrize("name", BUILT)
def test_the_manifest_says_how_the_couplings_are_held(name):
    from redysim import references

    eng = engine_or_skip(name)(gripper("coupled_gripper.xml"))
    assert eng.manifest()["couplings"] == references.get(name).coupling()
    assert "couplings" not in engine_or_skip(name)(eng.model.tree).manifest()


@pytest.mark.engine
def test_exudyns_coordinate_constraints_hold_the_offsets_in_its_own_step():
    """The offsets, which no acceleration sees: one GeneralizedAlpha step (1 ms, Newton to
    1e-12) of Exudyn's coupled system from a coupled state stays on q_f = m q_l + c (with the
    offset's sign the other way it is pulled 0.1 rad off at once: measured)."""
    from redysim.references.exudyn_engine import _settings

    model = gripper("coupled_gripper.xml")
    eng = engine_or_skip("exudyn")(model)
    tree, _, _ = eng.coupled
    exu = eng.lib
    q, v, _ = coupled_state(model, np.random.default_rng(stable_seed("exudyn-offset")))
    qe, blocks = tree._state(q, v)
    tree._set_state(qe, tree._to_engine(v, blocks), None)
    ss = _settings(exu, exu.DynamicSolverType.GeneralizedAlpha, 1e-3, 1)
    ss.timeIntegration.newton.relativeTolerance = 1e-12
    ss.timeIntegration.newton.absoluteTolerance = 1e-12
    assert exu.MainSolverImplicitSecondOrder().SolveSystem(tree.mbs, ss)
    after = np.array(tree.mbs.systemData.GetODE2Coordinates())[tree.eidx]
    assert np.abs(after - q).max() > 1e-4  # it moved
    fq, lq, _, _, m, off = model.coupling_index
    assert np.abs(after[fq] - (m * after[lq] + off)).max() < 1e-12


@pytest.mark.engine
@pytest.mark.parametrize("integrator", ["generalized-alpha", "trapezoidal"])
def test_exudyns_implicit_integrators_step_the_coupled_gripper(integrator):
    """Exudyn's implicit solvers on its CoordinateConstraints: the core's path, second order
    (0.3 s at h = 2 and 1 ms: measured 4.6e-4 and 1.1e-4 rad, ratio 4.0), the couplings held
    to rounding (measured <= 5e-15); its explicit ones (rk44, the default) refused by name."""
    from redysim.simulation import simulator

    model = gripper("coupled_gripper.xml")
    q0, v0, _ = coupled_state(model, np.random.default_rng(stable_seed("engine-coupled-own")))
    core = simulator(model, 0.3, q0=q0, v0=v0, integrator="dop853", rtol=1e-10, atol=1e-10,
                     sample=0.05).run()
    eng = engine_or_skip("exudyn")(model)
    fq, lq, _, _, m, off = model.coupling_index
    errs = []
    for h in (2e-3, 1e-3):
        traj = eng.simulate(q0, v0, 0.3, h, every=int(round(0.05 / h)), integrator=integrator)
        assert np.allclose(traj.t, core.t)
        errs.append(np.abs(traj.q - core.q).max())
        assert np.abs(traj.q[:, fq] - (m * traj.q[:, lq] + off)).max() < 1e-12
    assert errs[1] < 1e-3 and 3.0 < errs[0] / errs[1] < 5.0, errs  # second order
    assert eng.manifest()["constraints"] == len(model.couplings)
    with pytest.raises(ValueError, match="'rk44' does not hold the model's couplings"):
        eng.simulate(q0, v0, 0.3, 1e-3)


def test_the_first_screen_names_what_acts_and_leaves_out_what_does_not():
    """compare's first-screen card: the notes that change the motion, each by its head and
    count; the importers' summary of what has no effect on the motion is not among them."""
    from redysim.reports.compare import _short, acting_notes

    model = gripper("coupled_gripper.urdf")
    assert any("no effect on the motion" in n for n in model.notes)  # the file's bounds
    assert [_short(n) for n in acting_notes(model)] == ["joint <limit> lower, upper (4 joints)"]
    note = ("equality 'e0': solref, solimp = 'j1' = 1 'j2' + 0 dropped (a joint coupling, held "
            "exactly (Model.couplings), not softly as MuJoCo does)")
    assert _short(note) == "equality 'e0': solref, solimp"
    assert len(_short("x" * 200)) == 80


def test_a_mimic_on_a_fixed_joint_is_noted_as_changing_nothing(tmp_path):
    """A URDF's <mimic> on a fixed joint (Talos's grippers have them) couples nothing: its note
    says so in the importers' phrase, and compare's first screen leaves it out; a mimic kept
    independent at the user's request does change the motion and stays on it."""
    from redysim.io.importers import SAME_MOTION
    from redysim.reports.compare import acting_notes

    link = ('<link name="{0}"><inertial><mass value="1"/><origin xyz="0 0 0.1"/>'
            '<inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')
    urdf = tmp_path / "fixed_mimic.urdf"
    urdf.write_text(
        '<robot name="r">' + "".join(link.format(n) for n in ("base", "a", "b", "c")) +
        '<joint name="j1" type="revolute"><parent link="base"/><child link="a"/>'
        '<axis xyz="0 1 0"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
        '<joint name="j2" type="revolute"><parent link="a"/><child link="b"/>'
        '<origin xyz="0 0 0.2"/><axis xyz="0 1 0"/><mimic joint="j1" multiplier="0.5"/>'
        '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
        '<joint name="f" type="fixed"><parent link="b"/><child link="c"/>'
        '<origin xyz="0 0 0.2"/><mimic joint="j1"/></joint></robot>')
    model = redysim.load_model(urdf)
    fixed = [n for n in model.notes if "'f'" in n and "mimic" in n]
    assert len(fixed) == 1 and SAME_MOTION in fixed[0], model.notes
    assert not any("mimic" in n for n in acting_notes(model)), acting_notes(model)
    loose = redysim.load_model(urdf, mimic="independent")
    assert [n for n in acting_notes(loose) if "mimic" in n and "'j2'" in n], loose.notes
    assert not any("'f'" in n for n in acting_notes(loose)), loose.notes


def test_pinocchio_crba_is_right_at_every_call_not_only_the_first(tmp_path):
    """A mimic with a multiplier and an offset: Pinocchio 4.1.0's crba on its mimic model adds
    to what a reused Data holds, so the adapter's second call on was off by 0.04-4 rad/s^2
    (hold-out battery 6); each call now equals the core's, which equals a reduced-coordinate
    solve by NumPy (dq = G d(ja, jc), G^T M G qdd_r = -G^T h)."""
    eng_cls = engine_or_skip("pinocchio-crba")
    inertial = ('<inertial><mass value="{m}"/><origin xyz="{x} 0 0"/><inertia ixx="0.001" '
                'iyy="0.002" izz="0.002" ixy="0" ixz="0" iyz="0"/></inertial>')
    urdf = tmp_path / "grip.urdf"
    urdf.write_text(
        '<robot name="grip">'
        + "".join(f'<link name="{n}">{inertial.format(m=m, x=x)}</link>'
                  for n, m, x in (("base", 1, 0), ("a", 0.5, 0.1), ("b", 0.4, 0.1),
                                  ("c", 0.3, 0.05)))
        + '<joint name="ja" type="revolute"><parent link="base"/><child link="a"/>'
          '<axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
          '<joint name="jb" type="revolute"><parent link="a"/><child link="b"/>'
          '<origin xyz="0.2 0 0"/><axis xyz="0 0 1"/><mimic joint="ja" multiplier="-0.5" '
          'offset="0.1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
          '<joint name="jc" type="revolute"><parent link="b"/><child link="c"/>'
          '<origin xyz="0.2 0 0"/><axis xyz="0 1 0"/>'
          '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>')
    model = redysim.load_model(urdf)
    tree = redysim.load_model(urdf, mimic="independent")
    eng = eng_cls(model)
    G = np.array([[1.0, 0.0], [-0.5, 0.0], [0.0, 1.0]])
    for q0, v0 in (([0.64, 0.0, 0.26], [0.5, 0.0, 0.3]), ([0.3, 0.0, 0.2], [0.0, 0.0, 0.0]),
                   ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0]), ([0.64, 0.0, 0.26], [0.5, 0.0, 0.3])):
        q, v = model.couple(np.array(q0), np.array(v0))
        M = redysim.mass_matrix(tree, q)
        h = redysim.inverse_dynamics(tree, q, v, np.zeros(3))
        reduced = G @ np.linalg.solve(G.T @ M @ G, -G.T @ h)
        assert np.abs(redysim.forward_dynamics(model, q, v) - reduced).max() < 1e-12
        assert np.abs(eng.qdd(q, v) - reduced).max() < 1e-10 * (1 + np.abs(reduced).max())


def test_a_urdfs_fixed_links_are_frames_where_pinocchio_puts_them():
    """The UR5's tool0 and ee_link hang from wrist_3_link by fixed joints: fused into it, they
    stay frames by their names (hold-out battery 6: frame_motion refused them, which
    Pinocchio's frames give), their position and axes Pinocchio's to round-off."""
    pin = pytest.importorskip("pinocchio")
    from redysim.io.robots import resolve

    path = str(resolve("example-robot-data:ur5"))
    model = redysim.load_model(path)
    assert {"tool0", "ee_link"} <= set(model.frames)
    pm = pin.buildModelFromUrdf(path)
    pd = pm.createData()
    rng = np.random.default_rng(stable_seed("ur5 frames"))
    for q in rng.uniform(-2.0, 2.0, (3, model.n_v)):
        pin.forwardKinematics(pm, pd, q)
        pin.updateFramePlacements(pm, pd)
        for name in ("tool0", "ee_link"):
            got = redysim.frame_motion(model, q, 0 * q, frame=name)
            want = pd.oMf[pm.getFrameId(name)]
            assert np.abs(got.position - want.translation).max() < 1e-14
            assert np.abs(got.rotation - want.rotation).max() < 1e-14
