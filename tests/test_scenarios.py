"""Scenarios as data (redysim.io.scenarios): every built-in one loads and runs; bad files get named
errors; a rope case run as a scenario is the case's run; and the truths no engine supplies hold in
the core (free fall, zero gravity, the Dzhanibekov flip's period)."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from redysim.errors import CaseError, SettingsError
from redysim.harness.run import execute
from redysim.harness.spec import RunSpec
from redysim.harness.truths import flip_half_period
from redysim.io.scenarios import list_scenarios, load_scenario, robot_data_file
from redysim.simulation import frame_observer, simulator

REPO = Path(__file__).resolve().parents[1]
NEEDS_ROBOTS = pytest.mark.skipif(robot_data_file("ur5_robot.urdf") is None,
                                  reason="example-robot-data is not installed")


def test_the_built_in_scenarios_are_there():
    assert {"UR5-FALL", "PANDA-FALL", "TALOS-FALL", "TALOS-ZERO-G", "DZHANIBEKOV",
            "DOUBLE-PENDULUM", "FOUR-BAR", "JANSEN-LEG", "PUMA560-FALL", "HANGING-MODE",
            "CATENARY"} <= set(list_scenarios())


@NEEDS_ROBOTS
@pytest.mark.parametrize("name", list_scenarios())
def test_every_built_in_scenario_loads_and_runs_a_short_while(name):
    scn = load_scenario(name)
    assert scn.model.n_q == scn.q0.size and scn.model.n_v == scn.v0.size
    res = execute(RunSpec(name, t_end=min(scn.t_end, 0.05), sample=0.01), reference=False)
    assert res.ok, res.summary["reason"]
    assert res.summary["frame"] == scn.frame and len(res.rows) == 6


def test_a_rope_case_as_a_scenario_is_the_case():
    """The same chain, state, settings and tip: the rope's harness is the scenario harness."""
    from redysim import load_case

    case, scn = load_case("STUDY-R3"), load_scenario("STUDY-R3")
    assert scn.kind == "case" and scn.frame == "tip" and scn.digest == case.digest
    assert np.array_equal(scn.q0, case.q0) and scn.model.n_links == case.chain.n_links
    res = execute(RunSpec("STUDY-R3", t_end=0.1, sample=0.05), reference=False)
    sim = case.simulator(0.1, sample=0.05,
                         observe={"tip": frame_observer(case.chain, "tip")}).run()
    tip = np.array([r[2:5] for r in res.rows])
    assert np.array_equal(tip, sim.observed["tip"][:, :3])  # bit for bit


def _write(tmp_path, text: str, name: str = "s.toml") -> Path:
    p = tmp_path / name
    p.write_text(text)
    return p


PENDULUM = (REPO / "cases" / "scenarios" / "models" / "double_pendulum.urdf").as_posix()
HANDLE = (REPO / "cases" / "scenarios" / "models" / "t_handle.urdf").as_posix()
CRANK = (REPO / "cases" / "loops" / "crank_rocker.toml").as_posix()


@pytest.mark.parametrize("body, field, fragment", [
    ('[model]\nfile = "no_such.urdf"\n', "model.file", "no such file"),
    ('[model]\n', "model.file", "missing"),
    (f'[model]\nfile = "{PENDULUM}"\n[observe]\nframes = ["elbowz"]\n', "observe.frames",
     "no such frame or body"),
    (f'[model]\nfile = "{PENDULUM}"\n[initial]\nq = [0.1]\n', "initial.q",
     "must be a list of 2 numbers"),
    (f'[model]\nfile = "{PENDULUM}"\n[initial]\nv = [0.1, 0.2, 0.3]\n', "initial.v",
     "must be a list of 2 numbers"),
    (f'[model]\nfile = "{HANDLE}"\nfloating = true\n[initial]\nq = [0, 0, 0, 2, 0, 0, 0]\n',
     "initial.q[3:7]", "unit quaternion"),
    (f'[model]\nfile = "{PENDULUM}"\n[initial]\nrandom = {{ q = 0.1 }}\n', "initial.random",
     "seed required"),
    (f'[model]\nfile = "{PENDULUM}"\nmass = 3\n', "model.mass", "unknown field"),
    (f'[model]\nfile = "{PENDULUM}"\n[simulation]\nrtol = 2.0\n', "simulation.rtol",
     "must be < 1"),
    (f'[model]\nfile = "{PENDULUM}"\ndamping = -0.1\n', "model.damping", "finite number >= 0"),
    (f'[model]\nfile = "{PENDULUM}"\n[initial]\ndriver_v = 1.0\n', "initial.driver_v",
     "needs a linkage file with an [initial] driver"),
    (f'[model]\nfile = "{CRANK}"\n[initial]\ndriver_v = 1.0\nv = [1, 2, 3]\n',
     "initial.driver_v", "give v or driver_v, not both"),
    (f'[model]\nfile = "{CRANK}"\n[initial]\ndriver_v = "fast"\n', "initial.driver_v",
     "must be a finite number"),
    (f'[model]\nfile = "{PENDULUM}"\ndamping = "some"\n', "model.damping", "finite number >= 0"),
    (f'[model]\nfile = "{PENDULUM}"\n[observe]\npoints = {{ p = {{ body = "nobody", '
     'at = [0, 0, 0] } }\n', "observe.points.p.body", "no such body"),
])
def test_bad_scenario_files_get_named_errors(tmp_path, body, field, fragment):
    p = _write(tmp_path, "[scenario]\nname = \"bad\"\n" + body)
    with pytest.raises((CaseError, FileNotFoundError)) as info:
        load_scenario(p)
    text = str(info.value)
    assert str(p) in text and field in text and fragment in text, text


def test_an_engine_without_that_integrator_is_named():
    scn = load_scenario("DOUBLE-PENDULUM")
    with pytest.raises(SettingsError, match="has no such integrator; its own: native:"):
        RunSpec("DOUBLE-PENDULUM", engine="mujoco", integrator="native:leapfrog",
                h=1e-3).resolved(scn)
    with pytest.raises(SettingsError, match="needs a reference engine"):
        RunSpec("DOUBLE-PENDULUM", integrator="native", h=1e-3).resolved(scn)
    # an engine's error-controlled integrator takes tolerances, as ours: a step is refused
    with pytest.raises(SettingsError, match="'native:dopri5' is error-controlled"):
        RunSpec("DOUBLE-PENDULUM", engine="exudyn", integrator="native:dopri5",
                h=1e-3).resolved(scn)
    with pytest.raises(SettingsError, match="applies to adaptive integrators"):
        RunSpec("DOUBLE-PENDULUM", engine="mujoco", integrator="native:rk4", h=1e-3,
                rtol=1e-6).resolved(scn)


def test_the_double_pendulum_conserves_energy():
    scn = load_scenario("DOUBLE-PENDULUM")
    sim = scn.simulator(rtol=1e-10, atol=1e-12).run()
    assert sim.status == 0 and np.ptp(sim.q[:, 1]) > 1.0  # the lower bar swings
    # 2 kg of bars falling ~1.5 m: E ~ 30 J; the integrator's tolerance bounds the drift
    assert np.abs(sim.delta_M).max() < 1e-8


@NEEDS_ROBOTS
def test_talos_in_free_fall_keeps_its_com_on_the_parabola():
    """Only gravity acts: c(t) = c0 + cdot0 t + g t^2 / 2 exactly (the floating base's truth)."""
    scn = load_scenario("TALOS-FALL")
    sim = scn.simulator(rtol=1e-10, atol=1e-12).run()
    assert sim.status == 0
    t, c = sim.t, sim.com
    cdot0 = (c[1] - c[0]) / (t[1] - t[0]) - 0.5 * scn.model.gravity * (t[1] - t[0])
    parabola = c[0] + np.outer(t, cdot0) + 0.5 * np.outer(t ** 2, scn.model.gravity)
    # cdot0 from the first interval carries the integrator's error over it: ~1e-9 m here
    assert np.abs(c - parabola).max() < 1e-7
    assert abs(c[-1, 2] - c[0, 2] - cdot0[2] * t[-1] + 0.5 * 9.81 * t[-1] ** 2) < 1e-7


@NEEDS_ROBOTS
def test_talos_in_zero_gravity_keeps_its_com_on_a_line_and_its_energy():
    scn = load_scenario("TALOS-ZERO-G")
    assert not scn.model.gravity.any()
    sim = scn.simulator(rtol=1e-10, atol=1e-12).run()
    assert sim.status == 0
    second = sim.com[2:] - 2 * sim.com[1:-1] + sim.com[:-2]  # a straight line, uniform speed
    assert np.abs(second).max() < 1e-9
    # the file's joint damping (talos_reduced.urdf's <dynamics damping>) is internal: it keeps
    # the line but takes energy out, never in, all of it its work W (delta_M: the balance
    # E - W - E0 per kg); without it the energy is kept
    assert scn.model.damping.any() and not scn.model.gravcomp.any()
    assert np.all(np.diff(sim.energy) < 1e-9 * abs(sim.energy[0]))
    assert (sim.energy[-1] - sim.E0) / scn.model.total_mass < -1e-3
    assert np.abs(sim.delta_M).max() < 1e-9
    rigid = simulator(scn.model.without_passive(), scn.t_end, q0=scn.q0, v0=scn.v0,
                      rtol=1e-10, atol=1e-12, sample=0.05).run()
    assert rigid.status == 0 and np.abs(rigid.delta_M).max() < 1e-9


def test_the_dzhanibekov_flip_has_its_closed_form_period():
    """A free body spun about its middle axis flips over: the times between the sign changes of
    its body-frame spin about that axis match 2 K(k) / lambda, and energy is kept."""
    scn = load_scenario("DZHANIBEKOV")
    w0 = scn.v0[3:]
    sim = scn.simulator(16.0, rtol=1e-11, atol=1e-12, sample=0.001).run()
    assert sim.status == 0
    w2 = sim.v[:, 4]  # body-frame y
    crossings = []
    for i in np.flatnonzero(np.sign(w2[1:]) != np.sign(w2[:-1])):
        t0, t1 = sim.t[i], sim.t[i + 1]
        crossings.append(t0 + (t1 - t0) * w2[i] / (w2[i] - w2[i + 1]))  # linear, 1 ms apart
    assert len(crossings) >= 3, "it flips over several times in 16 s"
    half = flip_half_period(1.0, 2.0, 3.0, w0)  # 2 K(k) / lambda, the gate's closed form
    assert np.diff(crossings) == pytest.approx(half, rel=1e-5)
    assert np.abs(sim.delta_M).max() < 1e-9


@pytest.mark.engine
def test_redysim_compare_writes_a_page_with_agreement_runs_and_advice(tmp_path, capsys,
                                                                      monkeypatch):
    """The user's command on a small model: every run against the reference, the page and PDF
    written, the advice naming a run that met the tolerance."""
    pytest.importorskip("mujoco")
    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))  # the reference's cache
    from redysim.reports.commands import main  # the console script: the harness's + compare

    out = tmp_path / "cmp"
    assert main(["compare", "DOUBLE-PENDULUM", "--t-end", "0.2", "--engine", "mujoco",
                 "--out", str(out), "--workers", "1", "--no-progress"]) == 0
    html = (out / "compare.html").read_text()
    assert "Single-state agreement with the core" in html and "cheapest here" in html
    assert (out / "compare.pdf").read_bytes().startswith(b"%PDF")
    import pandas as pd

    runs = pd.read_parquet(out / "runs.parquet")
    assert set(runs["engine"]) == {"redysim", "mujoco"} and (runs["status"] == "ok").all()
    assert runs["max_tip_err"].notna().all()  # every run measured against the reference
    assert {"native:rk4", "ode45"} <= set(runs[runs["engine"] == "mujoco"]["integrator"])
    assert main(["compare", str(tmp_path / "none.urdf")]) == 2
    assert "does not exist" in capsys.readouterr().err


def test_compare_runs_pinocchio_with_its_stable_u_joints_on_a_rope():
    """One Pinocchio adapter a comparison: pin.aba with U joints split into two revolute joints
    on a model that has U joints (its JointModelUniversal drifts on long chains), pin.aba with
    its own joints on the rest; never the CRBA adapter (the same model as pin.aba's)."""
    from redysim import references
    from redysim.reports.compare import engine_names

    rope = engine_names(load_scenario("RE-U125-L1").model)
    pendulum = engine_names(load_scenario("DOUBLE-PENDULUM").model)
    assert "pinocchio-aba-ryrz" in rope and "pinocchio-aba" not in rope
    assert "pinocchio-aba" in pendulum and "pinocchio-aba-ryrz" not in pendulum
    others = set(references.ENGINES) - {"pinocchio-aba", "pinocchio-aba-ryrz", "pinocchio-crba"}
    assert others <= set(rope) and others <= set(pendulum)
    assert "pinocchio-crba" not in rope + pendulum


@pytest.mark.engine
@NEEDS_ROBOTS
def test_a_robots_reference_is_confirmed_by_a_second_implementation(tmp_path, monkeypatch):
    """Two checks of a reference: a second integrator on the core's qdd (SciPy's DOP853 at
    1e-13), and the same DOP853 on Pinocchio's qdd (an independent implementation of the
    dynamics); a rope and a linkage say why they have no engine check."""
    pytest.importorskip("pinocchio")
    from redysim.harness.reference import compute_reference

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path))
    ref = compute_reference(load_scenario("UR5-FALL"), 0.2, 0.05)
    assert ref.engine_check_by.startswith("pinocchio-aba ")
    assert ref.engine_check < 1e-10 and ref.tol_estimate < 1e-9  # measured 4e-15 and 1.7e-12
    for name, why in (("STUDY-R3", "a rope case"), ("FOUR-BAR", "closed loops")):
        ref = compute_reference(load_scenario(name), 0.1, 0.05)
        assert math.isnan(ref.engine_check) and why in ref.engine_check_by


def test_a_scenario_on_a_rope_case_runs_its_own_gravity(tmp_path):
    """A scenario's [model] gravity replaces the case file's, in the rope's own harness too."""
    p = _write(tmp_path, '[scenario]\nname = "moon"\n[model]\nfile = "STUDY-R3"\n'
                         'gravity = [0.0, -1.62, 0.0]\n[simulation]\nt_end = 0.2\n')
    moon, earth = load_scenario(p), load_scenario("STUDY-R3")
    assert moon.kind == "case" and moon.case.chain.gravity[1] == -1.62
    fall = [s.simulator(0.2, sample=0.1, rtol=1e-10, atol=1e-12).run().q[-1, 0]
            for s in (moon, earth)]
    # released horizontal, the first joint turns about 6x less far on the moon (g ratio 6.06)
    assert fall[1] / fall[0] == pytest.approx(9.81 / 1.62, rel=0.05)


@pytest.mark.parametrize("name", ["FOUR-BAR-ROUND", "JANSEN-LEG-ROUND"])
def test_driver_v_spins_the_crank_with_the_loops_kept(name):
    """driver_v sets the crank's velocity; the other joints' follow from the loops: J v0 = 0 to
    rounding, and the crank's entry is the one given."""
    from redysim.algorithms.loops import ClosedLoops
    from redysim.io.linkage_files import load_linkage

    scn = load_scenario(name)
    driver = load_linkage(scn.model_file).driver
    _, J, Jv, _ = ClosedLoops(scn.model).evaluate(scn.q0, scn.v0)
    assert scn.v0[driver] == pytest.approx(2 * math.pi * (2 if name.startswith("FOUR") else 1),
                                           rel=1e-14)
    assert np.abs(Jv).max() <= 1e-13 * np.abs(scn.v0).max()
    assert np.count_nonzero(scn.v0) > 1  # the others move too


def test_a_files_kind_follows_an_edit_of_it(tmp_path):
    """A file's kind is kept per version of the file (size, modification time, inode): the same
    path rewritten as another kind of file is that kind at once."""
    from redysim.io.cases import CASES_DIR
    from redysim.io.kinds import kind_of
    from redysim.io.scenarios import SCENARIOS_DIR

    path = tmp_path / "mine.toml"
    path.write_text((CASES_DIR / "STUDY-R3.toml").read_text())
    assert kind_of(path).name == "case"
    path.write_text((SCENARIOS_DIR / "CATENARY.toml").read_text())
    assert kind_of(path).name == "scenario"
    path.write_text((CASES_DIR / "robots" / "puma560.toml").read_text())
    assert kind_of(path).name == "dh"
    path.unlink()
    assert kind_of(path).name == "case"  # (no file: a case name's kind, as before)
