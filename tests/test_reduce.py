"""Which joints a robot's scene needs (redysim.harness.reduce, `redysim advise SCENARIO`): every
number checked against runs made here with the public API, not with the module's own runner."""

from __future__ import annotations

import numpy as np
import pytest

from redysim.errors import SettingsError
from redysim.harness import reduce
from redysim.io.scenarios import load_scenario
from redysim.simulation import frame_observer, simulator

pytest.importorskip("tomli_w")
T_END = 0.3
TOL = 1e-2  # m: the flange's path; the PUMA's wrist joints have effects below it, its arm's not


def path_of(model, q0, v0, frame):
    sim = simulator(model, T_END, q0=q0, v0=v0, integrator="dop853", rtol=1e-10, atol=1e-12,
                    sample=0.05, observe={"f": frame_observer(model, frame)}, keep_states=False)
    return np.asarray(sim.run().observed["f"])[:, :3]


@pytest.fixture(scope="module")
def puma(tmp_path_factory):
    out = tmp_path_factory.mktemp("puma")
    return reduce.reductions("PUMA560-FALL", TOL, out, frame="flange", t_end=T_END,
                             log=lambda *_: None), out


def test_each_lock_is_measured_by_running_the_reduced_model(puma):
    r, _ = puma
    scn = load_scenario("PUMA560-FALL")
    m = scn.model
    errors = [e for _, e in r.candidates]
    assert errors == sorted(errors) and {n for n, _ in r.candidates} == set(m.joint_names)
    full = path_of(m, scn.q0, scn.v0, "flange")
    for name, err in (r.candidates[0], r.candidates[-1]):  # measured here, with the public API
        k = m.joint_names.index(name)
        red = m.locked({name: float(scn.q0[k])})
        keep = [i for i in range(m.n_v) if i != k]
        got = path_of(red, scn.q0[keep], scn.v0[keep], "flange")
        assert np.linalg.norm(got - full, axis=1).max() == pytest.approx(err, rel=1e-6)


def test_the_advised_set_is_within_the_tolerance_when_run_again(puma):
    r, _ = puma
    assert r.locked and r.error <= r.tol and r.reduced_dof == r.full_dof - len(r.locked)
    scn = load_scenario("PUMA560-FALL")
    m = scn.model
    idx = [m.joint_names.index(n) for n in r.locked]
    red = m.locked({n: float(scn.q0[k]) for n, k in zip(r.locked, idx, strict=True)})
    keep = [i for i in range(m.n_v) if i not in idx]
    got = path_of(red, scn.q0[keep], scn.v0[keep], "flange")
    full = path_of(m, scn.q0, scn.v0, "flange")
    assert np.linalg.norm(got - full, axis=1).max() <= r.tol
    # a joint left out was left out for a reason: alone or with the set, over the tolerance
    left = [n for n, _ in r.candidates if n not in r.locked]
    assert left and all(e > 0 for n, e in r.candidates if n in left)
    assert r.practical["reduced"]["dof"] == r.reduced_dof and r.practical["error"] <= 10 * r.tol
    # both models' costs timed by harness.cost (repeats recorded) and compared with their noise
    for m in ("full", "reduced"):
        assert r.practical[m]["cost_repeats"] >= 1 and r.practical[m]["cost_s"] > 0
    assert r.practical["verdict"] in ("cheaper", "dearer", "indistinguishable")


def test_the_reduced_scenario_file_runs_on_its_own_and_follows_the_advised_path(puma):
    r, out = puma
    assert r.file is not None and r.file.parent == out and r.file_check <= 1e-12
    scn = load_scenario(r.file)
    assert scn.model.n_v == r.reduced_dof and scn.name == "PUMA560-FALL-REDUCED"


def test_asked_again_nothing_runs_twice(puma):
    r, out = puma
    cache = out / reduce.RESULTS_FILE
    before = cache.stat().st_mtime_ns
    again = reduce.reductions("PUMA560-FALL", TOL, out, frame="flange", t_end=T_END,
                              log=lambda *_: None)
    assert cache.stat().st_mtime_ns == before and again.locked == r.locked


def test_bad_requests_are_named(tmp_path):
    with pytest.raises(SettingsError, match="--tip-tol"):
        reduce.reductions("PUMA560-FALL", 0.0, tmp_path)
    with pytest.raises(SettingsError, match="'elbow'.*no such frame"):
        reduce.reductions("PUMA560-FALL", 1e-3, tmp_path, frame="elbow")
    with pytest.raises(SettingsError, match="closed mechanism"):
        reduce.reductions("FOUR-BAR", 1e-3, tmp_path)


def test_advise_on_a_robot_scenario_from_the_command_line(tmp_path, capsys):
    from redysim.harness.cli import main

    assert main(["advise", "PUMA560-FALL", "--tip-tol", "0.01", "--t-end", str(T_END),
                 "--observe", "flange", "--out", str(tmp_path)]) == 0
    text = capsys.readouterr().out
    assert "advice for a path within 0.01 m: lock" in text
    assert "run it: redysim simulate" in text and "follows the advised path" in text
    assert "cost of the integration (least of" in text and "saved: " in text
    assert main(["advise", "PUMA560-FALL", "--tip-tol", "1e-6", "--workers", "2"]) == 2
    assert "one after another" in capsys.readouterr().err
