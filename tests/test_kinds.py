"""File kinds (redysim.io.kinds): one registry, and a new kind is one class.

A kind of this test's own, a tiny JSON chain format, is registered; with no other edit, the
registry detects its files, ``load_model`` reads them, the scenario loader makes their passive
motion and takes them as a scenario file's model, and ``redysim info``, ``simulate`` and their
help take them, refusing by name the flags the kind has no use for. Then it is removed, and its
files are nothing redysim reads again."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from redysim import Chain, load_model
from redysim.errors import CaseError, ModelFileError
from redysim.harness.cli import main
from redysim.io.kinds import CASE, KINDS, FileKind, kind_of, register, unregister
from redysim.io.scenarios import load_scenario


class ToyKind(FileKind):
    """A chain of uniform revolute links as JSON: {"name", "links", "length", "mass"}."""

    name, noun, files = "toy", "a toy chain file", ".json (this test's own)"
    suffixes = (".json",)
    options = ("lock",)

    def model(self, path, **_):
        doc = json.loads(Path(path).read_text())
        return Chain.uniform(doc["links"], "R", length=doc["length"], mass=doc["mass"],
                             name=doc["name"])


@pytest.fixture
def toy(tmp_path):
    path = tmp_path / "three.json"
    path.write_text(json.dumps({"name": "three", "links": 3, "length": 0.5, "mass": 1.0}))
    register(ToyKind())
    try:
        yield path
    finally:
        unregister("toy")
    assert all(k.name != "toy" for k in KINDS)


def test_before_and_after_the_toy_kind_a_json_file_is_nothing_redysim_reads(tmp_path):
    path = tmp_path / "three.json"
    path.write_text("{}")
    assert kind_of(path) is CASE  # the fallback: the case loader says what is wrong
    with pytest.raises(ModelFileError, match="a model file is .urdf, .xml or .toml"):
        load_model(path)


def test_the_registry_detects_and_loads_a_new_kind(toy):
    assert kind_of(toy).name == "toy"
    model = load_model(toy)
    assert model.name == "three" and model.n_v == 3
    other = toy.with_name("model.sdf")
    other.write_text("<sdf/>")
    with pytest.raises(ModelFileError, match="a model file is .urdf, .xml, .toml or .json"):
        load_model(other)  # the refusal lists the new kind's suffix


def test_the_scenario_loader_takes_a_new_kind(toy):
    scn = load_scenario(toy)
    assert scn.kind == "toy" and scn.model.n_v == 3 and scn.frame == "tip"
    assert "a passive motion of three.json" in scn.description and scn.digest
    locked = load_scenario(toy, options={"lock": {"joint1": 0.3}})
    assert locked.model.n_v == 2 and locked.digest != scn.digest
    with pytest.raises(CaseError, match="a toy chain file takes lock, not floating"):
        load_scenario(toy, options={"floating": True})
    scenario = toy.with_name("TOY-FALL.toml")
    scenario.write_text('[scenario]\nname = "TOY-FALL"\n\n[model]\nfile = "three.json"\n'
                        'lock = {joint3 = 0.0}\n\n[simulation]\nt_end = 0.5\n')
    scn = load_scenario(scenario)
    assert scn.name == "TOY-FALL" and scn.kind == "toy" and scn.model.n_v == 2
    assert scn.model_file == toy and scn.t_end == 0.5


def test_the_command_line_takes_a_new_kind(toy, capsys):
    assert main(["info", str(toy)]) == 0
    out = capsys.readouterr().out
    assert out.startswith("three: 3 bodies, n_q = 3, n_v = 3")
    assert main(["info", str(toy), "--floating"]) == 2
    assert "--floating: gives the root body of" in capsys.readouterr().err
    assert main(["simulate", str(toy), "--links", "2"]) == 2
    assert "a toy chain file has no use for it" in capsys.readouterr().err
    assert main(["simulate", str(toy), "--t-end", "0.02", "--sample", "0.01", "--lock",
                 "joint1=0.2"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("three (1 joints locked)   (") and "n_v = 2" in out  # printed, locked
    with pytest.raises(SystemExit):
        main(["info", "--help"])
    assert "a toy chain file" in capsys.readouterr().out


REPO = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("folder, pattern, name", [
    ("cases", "*.toml", "case"), ("cases/robots", "*.toml", "dh"),
    ("cases/loops", "*.toml", "linkage"), ("cases/proteins", "*.toml", "protein"),
    ("cases/scenarios", "*.toml", "scenario"), ("cases/scenarios/models", "*.urdf", "urdf")])
def test_every_shipped_file_is_the_kind_its_folder_says(folder, pattern, name):
    files = sorted((REPO / folder).glob(pattern))
    assert files and {kind_of(f).name for f in files} == {name}


def test_an_option_a_kind_does_not_take_is_refused_by_name(tmp_path):
    """Before the registry, a scenario's option that the model file's loader did not use was
    dropped in silence: mimic on a DH robot, lock on a rope case named by a scenario file."""
    puma = REPO / "cases" / "robots" / "puma560.toml"
    with pytest.raises(CaseError, match="model.mimic = 'refuse': a DH robot file takes lock, "
                                        "not mimic"):
        load_scenario(puma, options={"mimic": "refuse"})
    scenario = tmp_path / "rope.toml"
    scenario.write_text('[scenario]\nname = "ROPE"\n\n[model]\nfile = "STUDY-R3"\n'
                        'lock = {joint1 = 0.0}\n')
    with pytest.raises(CaseError, match="model.lock = .*a rope case has no named joints"):
        load_scenario(scenario)
