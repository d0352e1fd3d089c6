"""No traceback, no hang, no wrong advice, no result that depends on the machine's load.

Each test here was written against a defect (redysim issue 33): advice counting modes a model
does not have, flags a kind of file ignored, notes not shown, tracebacks from bad keywords,
cases that hang or blame the wrong thing, a linkage stepped through 1e5 rad, change points not
named, a wrong norm in a message, wall-clock limits deciding results, and the refinement
advice test choosing by measured CPU.
"""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pytest

import redysim
import redysim.io.linkage_files as linkage_files
from redysim import CutJoint, Model, load_case, load_linkage, simulate
from redysim.algorithms.linkages import four_bar
from redysim.algorithms.loops import ClosedLoops
from redysim.errors import CaseError, SettingsError, StateError
from redysim.harness import refine
from redysim.harness.cli import main, time_to_go
from redysim.harness.run import execute
from redysim.harness.spec import RunSpec
from redysim.io.cases import MAX_RADIANS, case_from_dict, fastest_motion
from redysim.simulation import simulate_batch

REPO = Path(__file__).resolve().parents[1]
PUMA = str(REPO / "cases" / "robots" / "puma560.toml")
CRANK_ROCKER = str(REPO / "cases" / "loops" / "crank_rocker.toml")

# A two-link arm whose joints carry <dynamics> (damping, friction) and <limit>, which the core
# does not simulate: the importer drops them and says so in Model.notes.
URDF = """<robot name="two">
  <link name="base"><inertial><mass value="1"/><origin xyz="0 0 0"/>
    <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l1"><inertial><mass value="1"/><origin xyz="0.25 0 0"/>
    <inertia ixx="0.001" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <link name="l2"><inertial><mass value="1"/><origin xyz="0.25 0 0"/>
    <inertia ixx="0.001" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial></link>
  <joint name="j1" type="revolute"><parent link="base"/><child link="l1"/><axis xyz="0 1 0"/>
    <limit lower="-3" upper="3" effort="10" velocity="5"/>
    <dynamics damping="0.5" friction="0.1"/></joint>
  <joint name="j2" type="continuous"><parent link="l1"/><child link="l2"/>
    <origin xyz="0.5 0 0"/><axis xyz="0 1 0"/><dynamics damping="0.2"/></joint>
</robot>
"""
MJCF = """<mujoco model="two">
  <worldbody>
    <body name="base" pos="0 0 1">
      <inertial pos="0 0 0" mass="1" diaginertia="0.01 0.01 0.01"/>
      <body name="l1">
        <joint name="j1" type="hinge" axis="0 1 0"/>
        <inertial pos="0.25 0 0" mass="1" diaginertia="0.001 0.02 0.02"/>
        <body name="l2" pos="0.5 0 0">
          <joint name="j2" type="hinge" axis="0 1 0"/>
          <inertial pos="0.25 0 0" mass="1" diaginertia="0.001 0.02 0.02"/>
        </body>
      </body>
    </body>
  </worldbody>
</mujoco>
"""
ROPE = """
[case]
name = "rope"
[chain]
links = 4
joint = "R"
link_length = 0.25
link_mass = 0.1
[initial]
q = 0.0
[simulation]
t_end = 1.0
"""


@pytest.fixture
def robot_files(tmp_path):
    """{kind: path} of one small file of each kind `redysim simulate` takes."""
    urdf, mjcf, rope = tmp_path / "two.urdf", tmp_path / "two.xml", tmp_path / "rope.toml"
    urdf.write_text(URDF)
    mjcf.write_text(MJCF)
    rope.write_text(ROPE)
    return {"urdf": str(urdf), "mjcf": str(mjcf), "dh": PUMA, "linkage": CRANK_ROCKER,
            "case": str(rope)}


def _refused(capsys, argv, *fragments):
    """The command exits 2 with a message holding every fragment, and prints no traceback."""
    assert main(argv) == 2
    err = capsys.readouterr().err
    for fragment in fragments:
        assert fragment in err, err
    assert "Traceback" not in err


# --------------------------------------------------------------------------- 1: advice on modes
def test_asking_for_more_modes_than_the_finest_model_has_is_refused(capsys):
    """Before: "2 links have the first 3000 frequencies within 0.5" (a 2-link chain has 2
    modes; the missing ones were NaN, which max() skipped)."""
    _refused(capsys, ["advise", "hanging", "--modes", "3000", "--freq-tol", "0.5"],
             "--modes = 3000", "the study's finest model, 1024 links, has 1024 modes",
             "ask for at most 1024")


def test_a_model_with_fewer_modes_than_asked_cannot_meet_the_request(capsys):
    """Before: --modes 3 --freq-tol 1e9 advised 2 links (which have 2 modes)."""
    study = refine.modes_study(levels=(2, 4, 8), m=3)
    assert [len(r["rel_err"]) for r in study["levels"]] == [3, 3, 3]
    assert math.isnan(study["levels"][0]["rel_err"][2])  # the 2-link chain's third mode
    assert refine.advise_modes(study, 3, 1e9)["links"] == 4
    assert main(["advise", "hanging", "--modes", "3", "--freq-tol", "1e9"]) == 0
    out = capsys.readouterr().out
    assert "hanging chain: 4 links have the first 3 frequencies" in out
    assert "the coarser models, 2 links, have fewer than 3 modes" in out


def test_nan_is_never_within_a_tolerance():
    """A level whose error is NaN for an asked mode does not meet the tolerance, whatever the
    other modes' errors (max([0.1, nan]) is 0.1 in Python: it was advised)."""
    study = {"modes": 2, "levels": [{"links": 4, "rel_err": [0.1, math.nan]},
                                    {"links": 8, "rel_err": [0.1, 0.2]}]}
    assert refine.advise_modes(study, 2, 1.0)["links"] == 8
    assert refine.advise_modes(study, 1, 1.0)["links"] == 4
    assert refine.advise_modes({"modes": 1, "levels": [{"links": 4, "rel_err": [math.nan]}]},
                               1, 1.0) is None


@pytest.mark.parametrize("m, tol, field", [(0, 0.1, "m = 0"), (3, 0.1, "m = 3"),
                                           (True, 0.1, "m = True"), (1, -1.0, "tol = -1.0"),
                                           (1, math.nan, "tol = nan"), (1, "1%", "tol = '1%'")])
def test_advise_modes_names_a_bad_argument(m, tol, field):
    study = {"modes": 2, "levels": [{"links": 4, "rel_err": [0.1, 0.2]}]}
    with pytest.raises(SettingsError, match=f"advise_modes: {field}"):
        refine.advise_modes(study, m, tol)


# --------------------------------------------------------------------------- 2: ignored flags
@pytest.mark.parametrize("kind, flags, named", [
    ("urdf", ["--links", "2"], "--links = 2"),
    ("dh", ["--links", "2"], "--links = 2"),
    ("linkage", ["--links", "2"], "--links = 2"),
    ("mjcf", ["--links", "2"], "--links = 2"),
    ("urdf", ["--precision", "float32"], "--precision = 'float32'"),
    ("dh", ["--precision", "float32"], "--precision = 'float32'"),
    ("linkage", ["--precision", "float32"], "--precision = 'float32'"),
    ("case", ["--floating"], "--floating"),
    ("linkage", ["--floating"], "--floating"),
    ("case", ["--mimic", "independent"], "--mimic = 'independent'"),
    ("mjcf", ["--mimic", "independent"], "--mimic = 'independent'"),
    ("dh", ["--mimic", "refuse"], "--mimic = 'refuse'"),
])
def test_a_flag_a_kind_of_file_would_ignore_is_refused_by_name(robot_files, capsys, kind,
                                                               flags, named):
    """Before: each was ignored and the run went ahead without it."""
    _refused(capsys, ["simulate", robot_files[kind], "--t-end", "0.01", *flags],
             f"command line: {named}", "has no use for it")


@pytest.mark.parametrize("kind, flags, named", [
    ("case", ["--floating"], "--floating"), ("linkage", ["--floating"], "--floating"),
    ("mjcf", ["--mimic", "independent"], "--mimic = 'independent'"),
])
def test_info_refuses_the_flags_a_kind_of_file_would_ignore(robot_files, capsys, kind, flags,
                                                            named):
    _refused(capsys, ["info", robot_files[kind], *flags], f"command line: {named}")


def test_a_case_name_with_floating_is_refused(capsys):
    _refused(capsys, ["simulate", "STUDY-R3", "--floating"], "--floating",
             "a rope case has no use for it")
    _refused(capsys, ["info", "STUDY-R3", "--floating"], "--floating")


def test_the_flags_a_kind_of_file_uses_are_still_taken(robot_files, capsys):
    """The door is not too strict: float64 on a robot is what it runs in, --floating on an
    MJCF file gives its root body a free joint, --mimic on a URDF is its own."""
    assert main(["simulate", robot_files["urdf"], "--t-end", "0.01", "--precision", "float64",
                 "--mimic", "independent"]) == 0
    assert main(["info", robot_files["mjcf"], "--floating"]) == 0
    assert "free" in capsys.readouterr().out


def test_floating_on_a_dh_file_is_refused(capsys):
    """(the importer's refusal: a DH table has no base body to float)"""
    _refused(capsys, ["simulate", PUMA, "--floating"], "floating")


@pytest.mark.parametrize("argv, named", [
    (["advise", "hanging", "--modes", "1", "--freq-tol", "0.01", "--tip-tol", "0.1"],
     "--tip-tol = 0.1: the hanging chain's advice is computed"),
    (["advise", "hanging", "--modes", "1", "--freq-tol", "0.01", "--results", "elsewhere"],
     "--results = 'elsewhere'"),
    (["advise", "/some/study", "--tip-tol", "0.1", "--results", "elsewhere"],
     "--results = 'elsewhere': says where the studies of spin, fall, whip, pulled are"),
    (["sweep", "{tmp}/none.toml", "--out", "{tmp}/out", "--dask", "local", "--workers", "4"],
     "--workers = 4: sets the local process pool"),
])
def test_other_commands_refuse_a_flag_they_would_ignore(capsys, tmp_path, argv, named):
    """Before: each was ignored (--workers with --dask, --tip-tol and --results for the
    hanging chain, --results beside a study folder)."""
    _refused(capsys, [a.format(tmp=tmp_path) for a in argv], named)


def test_a_joint_locked_twice_is_refused(capsys):
    """Before: --lock joint1=0 --lock joint1=1 kept one of the two values, silently."""
    _refused(capsys, ["simulate", PUMA, "--t-end", "0.01", "--lock", "joint1=0", "--lock",
                      "joint1=1"], "--lock = 'joint1'", "locked twice (at 0 and at 1)")


def test_tolerances_given_to_a_fixed_step_integrator_on_a_robot_are_refused(capsys):
    """Before: --rtol was ignored by rk4 on a robot file (a rope case refused it)."""
    _refused(capsys, ["simulate", PUMA, "--integrator", "rk4", "--h", "1e-3", "--rtol", "1e-8"],
             "--rtol = 1e-08", "applies to adaptive integrators")


# --------------------------------------------------------------------------- 3: notes printed
def test_simulate_on_a_model_file_prints_what_was_dropped(robot_files, capsys):
    """Before: `redysim info` listed Model.notes and `redysim simulate` never did, so a URDF's
    joint damping and friction vanished from a run without a word. (Its damping is now
    simulated, Model.damping; its friction is still dropped, and said.)"""
    model = redysim.load_model(robot_files["urdf"])
    notes = model.notes
    assert model.damping.any() and not any("damping" in n for n in notes)
    assert any("friction" in n for n in notes)
    assert main(["simulate", robot_files["urdf"], "--t-end", "0.01"]) == 0
    out = capsys.readouterr().out
    assert "dropped       from the file, not simulated" in out
    for note in notes:
        assert f"\n    {note}\n" in out


# --------------------------------------------------------------------------- 4: tracebacks
@pytest.fixture(scope="module")
def small_model():
    return load_case("STUDY-R3").chain


@pytest.mark.parametrize("kw, fragment", [
    (dict(damping="lots"), "simulate: damping = 'lots': must be a finite number >= 0"),
    (dict(damping=-1.0), "simulate: damping = -1.0: must be a finite number >= 0"),
    (dict(damping=math.inf), "simulate: damping = inf"),
    (dict(damping=np.float64(-2)), "simulate: damping = -2.0:"),
    (dict(progress=1), "simulate: progress = 1: must be None or a callable"),
    (dict(integrator=None), "simulate: integrator: must be an integrator's name; known: ode45"),
])
def test_simulates_bad_keywords_are_named(small_model, kw, fragment):
    """Before: ValueError from float('lots'), TypeError 'int' object is not callable; a
    negative damping was taken (energy pumped in)."""
    with pytest.raises(SettingsError) as err:
        simulate(small_model, 0.01, **kw)
    assert fragment in str(err.value)


def test_a_missing_horizon_is_named(small_model):
    """Before: TypeError: unsupported operand type(s) for /: 'NoneType' and 'int'."""
    with pytest.raises(SettingsError, match="simulate: t_end: missing: the horizon"):
        simulate(small_model, None)


def test_a_progress_callback_can_stop_a_run(small_model):
    sim = simulate(small_model, 1.0, progress=lambda t, t_end, steps, wall: "enough")
    assert sim.status == 1 and sim.message == "enough" and 0 < sim.t[-1] < 1.0


@pytest.mark.parametrize("kw, exc, fragment", [
    (dict(q0=np.zeros((2, 3)), foo=1), SettingsError, "simulate_batch: foo = 1: unknown "
                                                      "setting"),
    (dict(q0=np.zeros((2, 3)), damping=-1.0), SettingsError, "simulate_batch: damping = -1.0"),
    (dict(q0=np.zeros((2, 3)), rtol=2.0), SettingsError, "simulate_batch: rtol = 2.0"),
    (dict(q0=np.zeros(3)), StateError, "simulate_batch: q0 has shape (3,): a batch needs "
                                       "(B, 3), one initial state a row"),
    (dict(q0=np.zeros((2, 3)), v0=np.zeros(3)), StateError, "v0 has shape (3,): a batch "
                                                            "needs (B, 3)"),
])
def test_simulate_batchs_bad_arguments_are_named_before_any_thread_starts(small_model, kw, exc,
                                                                         fragment):
    """Before: an unknown keyword raised simulate()'s TypeError from inside a worker thread,
    and a 1-D q0 was told it "must have shape (3,) for one state" (which it had)."""
    with pytest.raises(exc) as err:
        simulate_batch(small_model, 0.01, **kw)
    assert fragment in str(err.value)


def _two_links():
    bars = [redysim.Body(name, 1.0, (0.5, 0, 0), ((0, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
            for name in ("bar", "bar2")]  # (names are unique: Model.build)
    return Model.build(bars, [redysim.TreeJoint("a", "R", "z"),
                                    redysim.TreeJoint("b", "R", "z", translation=(1.0, 0, 0))],
                       [-1, 0], gravity=(0.0, -9.81, 0.0))


@pytest.mark.parametrize("args, kw, fragment", [
    (("pin", 1.5, (1, 0, 0), -1, (0, 0, 0)), {}, "CutJoint 'pin': body_a = 1.5: must be a "
                                                "body index"),
    (("pin", 1, (1, 0, 0), "world", (0, 0, 0)), {}, "body_b = 'world'"),
    (("pin", True, (1, 0, 0), -1, (0, 0, 0)), {}, "body_a = True"),
    (("pin", 1, (1, 0), -1, (0, 0, 0)), {}, "point_a = (1, 0): must be 3 finite numbers"),
    (("pin", 1, "origin", -1, (0, 0, 0)), {}, "point_a = 'origin'"),
    (("pin", 1, (1, 0, 0), -1, (0, 0, 0), "hinge"), {}, "kind = 'hinge': unknown"),
    (("", 1, (1, 0, 0), -1, (0, 0, 0)), {}, "name = '': must be a non-empty string"),
    (("pin", 1, (1, 0, 0), -1, (0, 0, 0), "point"), {"rot_a": np.eye(3)},
     "a 'point' cut would ignore it"),
    (("pin", 1, (1, 0, 0), -1, (0, 0, 0), "line"), {"rot_a": np.eye(3)},
     "a 'line' cut would ignore it"),
])
def test_a_cut_joints_bad_field_is_named_at_construction(args, kw, fragment):
    """Before: CutJoint(body_a=1.5) was built, and failed deep inside (an index error) or not
    at all; a frame given to a point cut was ignored."""
    with pytest.raises(CaseError) as err:
        CutJoint(*args, **kw)
    assert fragment in str(err.value)


@pytest.mark.parametrize("cuts, fragment", [
    (5, "cuts = 'int': must be a list of CutJoint"),
    (["pin"], "cuts[0] = 'str': must be a redysim.CutJoint"),
    ("pin", "cuts = 'str'"),
])
def test_closed_loops_names_bad_cuts(cuts, fragment):
    with pytest.raises(CaseError) as err:
        ClosedLoops(_two_links(), cuts)
    assert fragment in str(err.value)


def test_two_cut_joints_of_one_name_are_refused():
    pin = CutJoint("pin", 1, (1, 0, 0), -1, (1.5, 0, 0), "planar")
    with pytest.raises(CaseError, match="two cut joints have this name"):
        ClosedLoops(_two_links(), [pin, pin])


def test_load_linkage_names_a_bad_path(tmp_path):
    with pytest.raises(CaseError, match="load_linkage: path: must be the path"):
        load_linkage(None)
    with pytest.raises(CaseError, match="load_linkage: path = 5: must be the path"):
        load_linkage(5)
    with pytest.raises(CaseError, match="is a folder"):
        load_linkage(tmp_path)
    with pytest.raises(FileNotFoundError, match="does not exist"):
        load_linkage(tmp_path / "none.toml")


@pytest.mark.parametrize("kw, exc, fragment", [
    (dict(value=math.nan), SettingsError, "Linkage.at: value = nan: must be a finite number"),
    (dict(value=math.inf), SettingsError, "value = inf"),
    (dict(value="90"), SettingsError, "value = '90'"),
    (dict(value=1.0, step=0.0), SettingsError, "step = 0.0: must be a finite number > 0"),
    (dict(value=1.0, step=-0.1), SettingsError, "step = -0.1"),
    (dict(value=1.0, step=1e-9), SettingsError, "more than 10,000 assemblies"),
    (dict(value=1.0, q=np.zeros(2)), StateError, "q has shape (2,)"),
])
def test_linkage_at_names_a_bad_argument(kw, exc, fragment):
    """Before: math.ceil(nan) raised ValueError, a step of 0 ZeroDivisionError, a negative
    step jumped straight to the value, and 1e-9 rad steps ran for hours."""
    with pytest.raises(exc) as err:
        load_linkage(CRANK_ROCKER).at(**kw)
    assert fragment in str(err.value)


@pytest.fixture(scope="module")
def tiny_study(tmp_path_factory):
    """A refinement study's folder: an 8-link rope at 8, 4 and 2 links, two tolerances, and
    the reference run."""
    from test_refine import small_study

    folder = tmp_path_factory.mktemp("study")
    case = folder / "small.toml"
    case.write_text(ROPE.replace("links = 4", "links = 8").replace("t_end = 1.0",
                                                                   "t_end = 0.05"))
    return small_study(case, folder / "out")


@pytest.mark.parametrize("kw, fragment", [
    (dict(tol=-1.0), "advise: tol = -1.0: must be a tip distance > 0"),
    (dict(tol=math.nan), "tol = nan"),
    (dict(tol=0.1, precision="float16"), "precision = 'float16': choose one of"),
    (dict(tol=0.1, cost="wall_s"), "cost = 'wall_s': choose one of cpu_s, nfev, steps"),
])
def test_advise_names_a_bad_argument(tiny_study, kw, fragment):
    """Before: precision='float16' answered "no measured run met" (None), not an error."""
    with pytest.raises(SettingsError) as err:
        refine.advise(tiny_study, **kw)
    assert fragment in str(err.value)


# --------------------------------------------------------------------------- 5: hangs
def _case(chain_extra: dict | None = None, load: dict | None = None, initial=None,
          t_end: float = 1.0):
    doc = {"case": {"name": "pulled"},
           "chain": {"links": 4, "joint": "R", "link_length": 0.25, "link_mass": 0.1,
                     **(chain_extra or {})},
           "initial": initial or {"q": 0.0}, "simulation": {"t_end": t_end}}
    if load:
        doc["load"] = load
    return case_from_dict(doc, source="pulled.toml")


@pytest.mark.parametrize("chain_extra, load, initial, field, value", [
    ({}, {"tip_force": [0, 1e300, 0]}, None, "load.tip_force", "[0.0, 1e+300, 0.0]"),
    ({}, {"tip_force": [0, 1e13, 0]}, None, "load.tip_force", "10000000000000.0"),
    ({"tip_mass": 1e9}, None, {"q": 0.0}, "chain.tip_mass", "1000000000.0"),
    ({"gravity": [0, -1e300, 0]}, None, None, "chain.gravity", "-1e+300"),
    ({"link_length": 1e-30}, None, None, "chain.link_length", "1e-30"),
    ({}, None, {"q": 0.0, "v": 1e150}, "initial.v[0]", "1e+150"),
])
def test_a_case_whose_motion_no_run_can_integrate_is_refused_at_the_door(chain_extra, load,
                                                                         initial, field,
                                                                         value):
    """Before: tip_force = [0, 1e300, 0] hung (ode45 at steps of 1e-152 s, a 200-digit time to
    go); tip_mass = 1e300 was blamed on a singular GIM."""
    with pytest.raises(CaseError) as err:
        _case(chain_extra, load, initial, t_end=100.0 if "tip_mass" in chain_extra else 1.0)
    assert err.value.field == field
    assert value in str(err.value)
    assert "the chain's fastest motion would be" in str(err.value)
    assert f"more than the {MAX_RADIANS:.0e} a run can integrate" in str(err.value)


def test_a_tip_mass_that_swamps_the_links_is_refused():
    """Before: tip_mass = 1e300 was blamed on a singular GIM. Without gravity a heavy tip mass
    moves nothing fast, but the GIM's condition grows with the mass ratio: beyond 1e10 the
    links' own masses are rounding noise."""
    for extra in ({"tip_mass": 1e300}, {"tip_mass": 1e300, "gravity": [0, 0, 0]}):
        with pytest.raises(CaseError, match="chain.tip_mass = 1e[+]300: 1e[+]301 times the "
                                            "lightest link's mass"):
            _case(extra)
    with pytest.raises(CaseError) as err:
        _case({"tip_mass": 1e12, "gravity": [0, 0, 0]})
    assert err.value.field == "chain.tip_mass" and "1e+13 times the lightest link" in str(
        err.value)
    _case({"tip_mass": 1e9, "gravity": [0, 0, 0]})  # 1e10 times: still taken


def test_the_fastest_motion_is_the_pendulum_rate_of_the_pull():
    """One 1 m link of 1 kg (a rod: I = m l^2 / 3 about its joint) pulled at its tip by F:
    a pendulum of rate sqrt(F l / I) = sqrt(3 F) (F along the link, no gravity)."""
    chain = redysim.Chain.build([redysim.Link.uniform(1.0, 1.0)], ["R"], gravity=(0, 0, 0))
    motion = fastest_motion(chain, (12.0, 0.0, 0.0))
    assert motion.omega == pytest.approx(6.0, rel=1e-14) and motion.cause == "tip_force"
    spin = fastest_motion(chain, None, [50.0])  # a spin faster than its own pull's swing
    assert spin.cause == "rate" and spin.link == 0


def test_the_shipped_cases_are_far_from_the_bound():
    for name in ("RE-U50000-L1000", "RE-U15000-L300"):
        case = load_case(name)
        assert fastest_motion(case.chain, case.tip_force, case.v0).omega * case.t_end < \
            MAX_RADIANS / 50


def test_a_horizon_given_to_a_run_is_checked_as_the_cases_own():
    case = load_case("RE-U125-L1")
    omega = fastest_motion(case.chain, case.tip_force, case.v0).omega
    too_long = 2 * MAX_RADIANS / omega
    with pytest.raises(SettingsError, match=r"--t-end = .*: the case's fastest motion, ~"):
        RunSpec("RE-U125-L1", t_end=too_long).resolved(case, names={"t_end": "--t-end"})
    RunSpec("RE-U125-L1", t_end=0.5 * MAX_RADIANS / omega).resolved(case)


@pytest.mark.parametrize("seconds, text", [
    (30.4, "about 30 s"), (600.0, "about 10 min"), (3 * 3600.0, "about 3.0 h"),
    (5 * 86400.0, "about 5.0 days"), (2.3e150, "unknown (more than 116 days at this rate)"),
    (math.inf, "unknown (more than"), (math.nan, "unknown"),
])
def test_the_time_to_go_is_never_a_200_digit_number(seconds, text):
    assert time_to_go(seconds).startswith(text)
    assert len(time_to_go(seconds)) < 50


def test_the_progress_line_of_a_crawling_run_is_sane(capsys):
    """Before: 'about 23,633,083,758,925,228,311,... s to go' (200 digits)."""
    from redysim.harness.cli import _report_progress

    _report_progress(2.1e-148, 1.0, 11034, 5.0)
    err = capsys.readouterr().err
    assert "time to go unknown (more than 116 days at this rate)" in err and len(err) < 120


def test_a_long_runs_time_to_finish_is_sane():
    """Before: 'time to finish at this rate 6.6e+143 h' printed in full (`{:.1f}`)."""
    from redysim.harness.longrun import summary

    ck = {"samples": np.zeros((0, 6)), "t": np.array(2.1e-148), "wall_s": np.array(5.0),
          "t_end": np.array(1.0), "case": np.array("x"), "steps": np.array(11034),
          "rejected": np.array(0), "nfev": np.array(0), "cpu_s": np.array(5.0),
          "peak_rss_mib": np.array(100.0)}
    text = summary(ck)
    assert text.endswith("time to finish at this rate: unknown (more than 116 days at this "
                         "rate)") and len(text) < 400


def test_a_far_driver_angle_costs_at_most_two_turns(monkeypatch):
    """at(1e5) stepped the crank through 1e5 rad at 5 deg a step: 1.15e6 assemblies, ~45
    minutes. A crank-rocker comes back after a whole turn (each joint by whole turns), so only
    one turn and the rest are followed: a bounded number of assemblies (counted, not timed)."""
    linkage = load_linkage(CRANK_ROCKER)
    calls = []
    assemble = linkage_files.assemble

    def counted(*args, **kwargs):
        calls.append(1)
        if len(calls) > 200:
            raise AssertionError("more than 200 assemblies: stepping through every turn")
        return assemble(*args, **kwargs)

    monkeypatch.setattr(linkage_files, "assemble", counted)
    q = linkage.at(1e5)
    assert len(calls) <= 2 * 72 + 2 and q[linkage.driver] == 1e5
    # the same pose as the driver at 1e5 rad reduced by whole turns, every joint by whole turns
    start = float(linkage.q0[linkage.driver])
    near = linkage.at(start + (1e5 - start) % (2 * math.pi))
    turns = (q - near) / (2 * math.pi)
    assert np.abs(turns - np.round(turns)).max() < 1e-9
    assert linkage.loops.residuals(q, np.zeros(3))[0] < 1e-11  # rounding of 1e5 rad: 1.5e-11


def test_a_far_driver_angle_is_where_following_every_step_would_lead():
    """Three turns and a bit, by the periodic shortcut and by stepping all the way (the old
    way, 265 assemblies): the same configuration to the assembly's tolerance."""
    linkage = load_linkage(CRANK_ROCKER)
    start = float(linkage.q0[linkage.driver])
    value = start - 3 * 2 * math.pi - 1.0
    followed = linkage._follow(np.array(linkage.q0), start, value, math.radians(5.0))
    np.testing.assert_allclose(linkage.at(value), followed, rtol=0, atol=1e-9)


# --------------------------------------------------------------------------- 6: change points
def _parallelogram(gravity=9.81):
    return four_bar(1.0, 0.5, 1.0, 0.5, gravity=gravity)  # ground = coupler, crank = rocker


def test_a_parallelogram_at_its_flat_configuration_is_named_a_change_point():
    """Before: "the cut joints coupler-rocker pin are redundant here", with no hint that the
    loops are fine elsewhere and this is a configuration where the mechanism can switch."""
    fb = _parallelogram()
    with pytest.raises(StateError) as err:
        fb.loops.forward_dynamics(np.zeros(3), np.zeros(3))
    msg = str(err.value)
    assert "'coupler-rocker pin' are redundant at this configuration" in msg
    assert "change point" in msg and "switch branches" in msg
    assert "remove or lower the rank" not in msg
    qdd, _ = fb.loops.forward_dynamics_and_forces(np.array([0.3, -0.3, 0.3]), np.zeros(3))
    assert np.isfinite(qdd).all()  # regular away from it


def test_a_run_that_stops_at_a_change_point_says_so():
    fb = _parallelogram(gravity=0.0)
    q0, v0 = np.array([0.3, -0.3, 0.3]), np.array([-3.0, 3.0, -3.0])  # flat at t = 0.1
    sim = simulate(fb.model, 0.5, q0=q0, v0=v0, loops=fb.loops, rtol=1e-8, atol=1e-10)
    assert sim.status == -1 and "change point" in sim.message, sim.message


def test_a_run_stopped_after_passing_near_a_change_point_says_so(monkeypatch):
    """The parallelogram swings through its flat configuration (J M^-1 J^T's singular values
    5e-6 apart at the nearest step, not singular) and is stopped later by its caller: the
    message says where it passed. NEAR_CHANGE_POINT is raised to 1e-4 here so that the test does
    not hang on where exactly the steps land near the flat configuration."""
    import redysim.simulation as simulation

    monkeypatch.setattr(simulation, "NEAR_CHANGE_POINT", 1e-4)
    fb = _parallelogram(gravity=0.0)
    q0, v0 = np.array([0.3, -0.3, 0.3]), np.array([-2.9, 2.9, -2.9])  # flat at t = 0.103

    def stop_late(t, t_end, steps, wall):
        return "stopped by the caller" if t > 0.3 else None

    sim = simulate(fb.model, 0.5, q0=q0, v0=v0, loops=fb.loops, rtol=1e-8, atol=1e-10,
                   progress=stop_late)
    assert sim.status == 1 and sim.message.startswith("stopped by the caller")
    assert "passed near a change point at t = " in sim.message
    assert 0.05 < sim.near_change_point < 0.15
    ok = simulate(fb.model, 0.2, q0=q0, v0=v0, loops=fb.loops, rtol=1e-8, atol=1e-10)
    assert ok.status == 0 and ok.message == "ok" and ok.near_change_point is not None


# --------------------------------------------------------------------------- 7: messages
def test_a_zero_quaternion_is_reported_with_its_own_norm():
    """Before: "q0's quaternion has norm 2" for a quaternion of norm 0 (1 + | |q| - 1 |)."""
    body = redysim.Body("b", 1.0, (0, 0, 0), ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
    model = Model.build([body], [redysim.TreeJoint("base", "free")], [-1])
    q0 = np.zeros(7)
    with pytest.raises(StateError) as err:
        simulate(model, 0.01, q0=q0)
    assert "q0[3:7], the quaternion (w, x, y, z) of joint 'base', has norm 0:" in str(err.value)
    q0[3] = 3.0
    with pytest.raises(StateError, match="has norm 3:"):
        simulate(model, 0.01, q0=q0)


# --------------------------------------------------------------------------- 8: limits and load
def test_a_cpu_limit_stops_a_run_and_the_wall_clock_does_not(monkeypatch):
    """A run's limit is CPU time: a wall clock racing ahead (a machine busy with other work:
    here perf_counter jumps 1000 s a call) neither stops a run nor changes its result."""
    import redysim.harness.run as run

    class Racing:
        def __init__(self):
            self.now = 0.0

        def perf_counter(self):
            self.now += 1000.0
            return self.now

        process_time = staticmethod(time.process_time)

    spec = RunSpec(case="STUDY-R3", t_end=0.2, sample=0.05, max_cpu_s=600.0)
    calm = execute(spec, reference=False)
    monkeypatch.setattr(run, "time", Racing())
    busy = execute(spec, reference=False)
    assert calm.summary["status"] == busy.summary["status"] == "ok"
    assert busy.summary["steps"] == calm.summary["steps"]
    assert busy.samples["tip_x"].tolist() == calm.samples["tip_x"].tolist()


def test_a_run_past_its_cpu_limit_is_a_failed_result():
    res = execute(RunSpec(case="RE-U125-L1", integrator="rk4", h=1e-6, t_end=1.0, sample=0.01,
                          max_cpu_s=0.2), reference=False)
    s = res.summary
    assert s["status"] == "failed" and s["reason"].startswith(
        "time limit: max_cpu_s = 0.2 s of CPU reached at t = ")
    assert s["cpu_s"] >= 0.2 and s["t_reached"] < 1.0


def test_the_callers_wall_limit_stops_a_run_as_stopped_not_failed():
    res = execute(RunSpec(case="RE-U125-L1", integrator="rk4", h=1e-6, t_end=1.0, sample=0.01),
                  reference=False, max_wall_s=0.2)
    assert res.summary["status"] == "stopped"
    assert res.summary["reason"].startswith("stopped by the wall-clock limit, max_wall_s = 0.2 s")
    assert len(res.samples) >= 1


def test_a_sweep_never_keeps_a_stopped_run_as_a_result(tmp_path):
    """A row stopped by a wall-clock limit (the user's patience) is run again by a sweep,
    not reused as "failed"."""
    from redysim.harness.sweep import _store, run_sweep

    spec = RunSpec(case="STUDY-R3", t_end=0.02, sample=0.01)
    stopped = execute(spec, reference=False, max_wall_s=1e-9)
    assert stopped.summary["status"] == "stopped"
    _store(tmp_path, spec, stopped.summary, stopped.samples)
    runs = run_sweep([spec], tmp_path, workers=1, progress=False)
    assert runs.attrs["ran"] == 1 and runs["status"].tolist() == ["ok"]


def test_a_sweep_file_with_the_old_wall_limit_is_told_its_new_name():
    from redysim.harness.sweep import SweepError, sweep_from_dict

    with pytest.raises(SweepError, match="sweep.max_wall_s = 60: renamed max_cpu_s: a run's "
                                         "time limit counts seconds of CPU time"):
        sweep_from_dict({"sweep": {"cases": ["STUDY-R3"], "max_wall_s": 60}}, source="s.toml")
    with pytest.raises(SweepError, match=r"sweep.extra\[0\].max_wall_s = 5: renamed"):
        sweep_from_dict({"sweep": {"cases": ["STUDY-R3"],
                                   "extra": [{"case": "STUDY-R3", "max_wall_s": 5}]}},
                        source="s.toml")
    sweep = sweep_from_dict({"sweep": {"cases": ["STUDY-R3"], "max_cpu_s": 60}},
                            source="s.toml")
    assert {s.max_cpu_s for s in sweep.specs} == {60.0}


def test_the_sweep_files_give_cpu_limits():
    from redysim.harness.sweep import load_sweep

    for path in sorted((REPO / "sweeps").glob("*.toml")):
        assert "max_wall_s" not in path.read_text(), path.name
        load_sweep(path)


def test_max_wall_on_a_model_file_stops_it_as_stopped(capsys):
    """Before: --max-wall was refused for a robot file ("its runs are short"; a 10,000-rod
    linkage is not)."""
    code = main(["simulate", PUMA, "--t-end", "1000", "--integrator", "rk4", "--h", "1e-5",
                 "--sample", "1", "--max-wall", "0.5"])
    out, err = capsys.readouterr()
    assert code == 3
    assert "status        stopped: stopped by the wall-clock limit, max_wall_s = 0.5 s" in out
    assert "run stopped:" in err


def test_max_cpu_on_a_model_file_fails_it(capsys):
    code = main(["simulate", PUMA, "--t-end", "1000", "--integrator", "rk4", "--h", "1e-5",
                 "--sample", "1", "--max-cpu", "0.3"])
    out, err = capsys.readouterr()
    assert code == 1 and "status        failed: time limit: max_cpu_s = 0.3 s of CPU" in out
    assert "run failed: time limit" in err


def test_simulates_cpu_limit_fails_the_run_and_is_checked(small_model):
    sim = simulate(small_model, 1e3, integrator="rk4", h=1e-5, sample=1.0, max_cpu_s=0.2)
    assert sim.status == -1 and sim.message.startswith("time limit: max_cpu_s = 0.2 s of CPU")
    assert sim.cpu_s >= 0.2 and sim.t[-1] < 1e3
    for bad in (0, -1.0, math.nan, "1"):
        with pytest.raises(SettingsError, match="max_cpu_s = .*: must be None or a finite"):
            simulate(small_model, 0.01, max_cpu_s=bad)


def test_table8s_runs_stop_on_cpu_time():
    """reports/precision_tables.py stopped its rounded-RHS runs on wall time."""
    from redysim.reports.precision_tables import _simulate

    r = _simulate(load_case("STUDY-R3"), "ge-n", 4, cpu_limit=1e-9)
    assert r["status"].startswith("time limit: max_cpu_s = 1e-09 s of CPU") \
        and r["t_reached"] < 1.0
