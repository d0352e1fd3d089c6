"""Robots by name (redysim.io.robots): ``example-robot-data:<name>`` wherever a model file is
taken, a bare package file name refused with the name to give, ``redysim robots``; and the
note on stderr when the kernels' cache is cold.

The expected files come from the package's own file list, read here apart from the code under
test (``test_trees.robot_urdf``).
"""

from __future__ import annotations

import io
from pathlib import Path

import pytest
from test_trees import robot_urdf

from redysim import load_model
from redysim.harness.cli import main
from redysim.io.importers import load_urdf
from redysim.io.robots import robot_file, robots
from redysim.io.scenarios import load_scenario

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")


@pytest.fixture(scope="module")
def ur5() -> Path:
    return Path(robot_urdf("ur_description/urdf/ur5_robot.urdf"))


def test_a_robot_by_short_name_stem_or_path_is_its_file(ur5):
    for name in ("ur5", "ur5_robot", "ur5_robot.urdf", "ur_description/urdf/ur5_robot.urdf",
                 "/ur_description/urdf/ur5_robot.urdf"):
        assert robot_file(name) == ur5, name
    # ur3.urdf holds "ur3": ur3_robot.urdf keeps its stem only
    assert robot_file("ur3").name == "ur3.urdf"
    assert robot_file("ur3_robot").name == "ur3_robot.urdf"


def test_every_loader_takes_the_name(ur5):
    by_file = load_model(ur5)
    for model in (load_model("example-robot-data:ur5"), load_urdf("example-robot-data:ur5"),
                  load_scenario("example-robot-data:ur5").model):
        assert model.body_names == by_file.body_names
        assert model.total_mass == by_file.total_mass


def test_a_shared_stem_or_an_unknown_name_is_refused_saying_why():
    with pytest.raises(FileNotFoundError, match="ambiguous") as exc:
        load_model("example-robot-data:anymal")
    assert "anymal_b_simple_description/robots/anymal.urdf" in str(exc.value)
    assert "anymal_c_simple_description/urdf/anymal.urdf" in str(exc.value)
    with pytest.raises(FileNotFoundError, match="ambiguous"):
        robot_file("anymal.urdf")
    assert robot_file("anymal_c_simple_description/urdf/anymal.urdf").parts[-3] == \
        "anymal_c_simple_description"
    with pytest.raises(FileNotFoundError, match="no such robot.*example-robot-data:ur5"):
        load_model("example-robot-data:ur6")
    with pytest.raises(FileNotFoundError, match="no robot named"):
        load_model("example-robot-data:")


def test_a_bare_package_file_name_names_the_prefixed_form(tmp_path, monkeypatch, ur5):
    monkeypatch.chdir(tmp_path)
    for load in (load_model, load_urdf, load_scenario):
        with pytest.raises(FileNotFoundError, match="give example-robot-data:ur5"):
            load("ur5_robot.urdf")
    # a file of that name where it is given is that file, not the package's
    (tmp_path / "ur5_robot.urdf").write_text(
        '<robot name="mine"><link name="base"/><link name="arm"><inertial><mass value="2"/>'
        '<inertia ixx="1" iyy="1" izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link>'
        '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
        '<axis xyz="0 0 1"/></joint></robot>')
    assert load_model("ur5_robot.urdf").total_mass == 2.0


def test_a_scenario_file_and_a_sweep_take_a_robot_by_name(tmp_path, ur5):
    from redysim.harness.sweep import load_sweep

    (tmp_path / "fall.toml").write_text(
        '[scenario]\nname = "MY-UR5"\n[model]\nfile = "example-robot-data:ur5"\n'
        '[simulation]\nt_end = 0.1\n[observe]\nframes = ["wrist_3_link"]\n')
    scn = load_scenario(tmp_path / "fall.toml")
    assert scn.model.body_names == load_model(ur5).body_names
    (tmp_path / "bad.toml").write_text(
        '[scenario]\nname = "BAD"\n[model]\nfile = "example-robot-data:anymal"\n')
    with pytest.raises(Exception, match="model.file.*ambiguous"):
        load_scenario(tmp_path / "bad.toml")
    (tmp_path / "sweep.toml").write_text(
        '[sweep]\nname = "s"\ncases = ["example-robot-data:ur5"]\nintegrators = ["ode45"]\n'
        'rtols = [1e-6]\nt_end = 0.01\n')
    sweep = load_sweep(tmp_path / "sweep.toml")
    assert {s.case for s in sweep.specs} == {"example-robot-data:ur5"}
    (tmp_path / "sweep2.toml").write_text(
        '[sweep]\nname = "s"\ncases = ["example-robot-data:ur6"]\nintegrators = ["ode45"]\n'
        'rtols = [1e-6]\n')
    with pytest.raises(Exception, match="cases.*no such robot"):
        load_sweep(tmp_path / "sweep2.toml")


def test_redysim_robots_lists_names_paths_and_scenarios(capsys):
    table = dict((rel, name) for name, rel in robots())
    assert table["ur_description/urdf/ur5_robot.urdf"] == "ur5"
    assert table["anymal_c_simple_description/urdf/anymal.urdf"] == ""  # a shared stem
    assert main(["robots"]) == 0
    out = capsys.readouterr().out
    assert "example-robot-data:ur5 " in out and "ur_description/urdf/ur5_robot.urdf" in out
    assert "anymal_b_simple_description/robots/anymal.urdf" in out and "UR5-FALL" in out
    # every name listed loads to the file listed beside it
    for name, rel in robots():
        if name:
            assert str(robot_file(name)).endswith(rel)


def test_the_cold_cache_note(tmp_path, monkeypatch):
    import redysim.algorithms._kernels as kernels

    monkeypatch.setattr(kernels, "compiled_cache_dir", lambda: tmp_path)
    monkeypatch.delenv("NUMBA_DISABLE_JIT", raising=False)
    said = io.StringIO()
    assert kernels.announce_cold_cache(said) and "compiling the numba kernels" in said.getvalue()
    assert str(tmp_path) in said.getvalue()
    (tmp_path / "articulated.f-1.py311.nbi").write_bytes(b"")
    said = io.StringIO()
    assert not kernels.announce_cold_cache(said) and said.getvalue() == ""


def test_advise_on_a_robot_by_name_writes_its_reduced_scenario(tmp_path, monkeypatch, capsys):
    """`redysim advise` on a model file by itself (here by name) writes the reduced scenario
    naming the robot (it read the URDF as TOML and failed), and the file runs."""
    import tomllib

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path))
    assert main(["advise", "example-robot-data:ur5", "--tip-tol", "1e-2", "--t-end",
                 "0.1"]) == 0
    reduced = tmp_path / "advise" / "ur5" / "ur5-REDUCED.toml"
    assert f"redysim simulate {reduced}" in capsys.readouterr().out
    doc = tomllib.loads(reduced.read_text())
    assert doc["model"]["file"] == "example-robot-data:ur5" and doc["model"]["lock"]
    scn = load_scenario(reduced)
    assert scn.model.n_v == 6 - len(doc["model"]["lock"])
