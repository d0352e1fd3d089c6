"""One run (harness.run.execute): what it records, how it fails, and the reference solution."""

from __future__ import annotations

import math

import numpy as np
import pytest

from redysim import energy, forward_dynamics, load_case
from redysim.harness import reference as ref_mod
from redysim.harness.run import SAMPLE_COLUMNS, execute
from redysim.harness.spec import RunSpec
from redysim.integrators.explicit import integrate
from redysim.io.cases import CASES_DIR


@pytest.fixture
def results_tmp(tmp_path, monkeypatch):
    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path))
    return tmp_path


def test_a_run_records_samples_counts_and_provenance(results_tmp):
    spec = RunSpec(case="STUDY-R3", t_end=0.2, sample=0.05)
    res = execute(spec)
    s = res.summary
    assert res.ok and s["reason"] == ""
    assert list(res.samples.columns) == list(SAMPLE_COLUMNS)
    assert np.allclose(res.samples["t"], [0, 0.05, 0.1, 0.15, 0.2])
    case = load_case("STUDY-R3")
    assert s["E0"] == pytest.approx(sum(energy(case.chain, case.q0, case.v0)), rel=1e-15)
    assert res.samples["delta_M"].iloc[0] == 0.0
    # ode45's RHS count: 1 + 6 (steps + rejected), the first (JIT) call timed apart
    assert s["nfev"] == 1 + 6 * (s["steps"] + s["rejected"])
    assert s["jit_s"] >= 0 and s["cpu_s"] > 0 and s["peak_rss_mib"] > 0
    for key in ("python", "numpy", "numba", "machine", "cpu", "git_commit", "date"):
        assert key in s
    assert math.isnan(s["max_tip_err"])  # no reference was computed


def test_the_tip_of_the_first_sample_is_the_cases_tip(results_tmp):
    res = execute(RunSpec(case="RE-U125-L1", t_end=0.01, sample=0.01))
    first = res.samples.iloc[0]
    # straight along +X, 1 m long: the tip at (1, 0, 0), moving at w x r = (0, 0, -1) m/s
    assert np.allclose(first[["tip_x", "tip_y", "tip_z"]].astype(float), [1, 0, 0], atol=1e-12)
    assert np.allclose(first[["tip_vx", "tip_vy", "tip_vz"]].astype(float), [0, 0, -1],
                       atol=1e-12)


def test_errors_against_a_cached_reference(results_tmp):
    case = load_case("STUDY-R3")
    ref = ref_mod.compute_reference(case, 0.2, 0.05)
    assert ref.tol_estimate < 1e-9
    assert ref_mod.reference_path(case, 0.2, 0.05).exists()
    coarse = execute(RunSpec(case="STUDY-R3", t_end=0.2, sample=0.05, rtol=1e-3, atol=1e-5))
    fine = execute(RunSpec(case="STUDY-R3", t_end=0.2, sample=0.05, rtol=1e-7, atol=1e-9))
    assert 0 < fine.summary["max_tip_err"] < coarse.summary["max_tip_err"]
    assert fine.summary["final_state_err"] < coarse.summary["final_state_err"]


def test_every_integrator_and_the_native_stepper(results_tmp):
    for integrator, h in (("dop853", 0.0), ("rk4", 1e-3), ("scipy-RK45", 0.0),
                          ("scipy-LSODA", 0.0)):
        res = execute(RunSpec(case="STUDY-R3", integrator=integrator, h=h, t_end=0.1,
                              sample=0.05))
        assert res.ok, res.summary["reason"]
        assert abs(res.samples["delta_M"]).max() < 1e-3


def test_an_energy_blow_up_is_a_failed_run_with_its_reason(results_tmp):
    res = execute(RunSpec(case="RE-U125-L1", t_end=0.05, sample=0.01, energy_bound=1e-14))
    assert res.summary["status"] == "failed"
    assert "energy blow-up" in res.summary["reason"] and "1e-14" in res.summary["reason"]
    assert len(res.samples) >= 1  # the samples before it are kept


@pytest.mark.parametrize("integrator", ["ode45", "scipy-Radau"])
def test_a_time_limit_stops_the_run(results_tmp, integrator):
    # Radau: one step (Newton iterations, finite-difference Jacobians of 500 states) can take
    # longer than the limit, so the limit is checked at every RHS call, not only between steps.
    # The limit is CPU time (RunSpec.max_cpu_s): what else the machine does decides nothing.
    res = execute(RunSpec(case="RE-U125-L1", integrator=integrator, t_end=1.0, sample=0.01,
                          rtol=1e-9, atol=1e-11, max_cpu_s=0.2))
    assert res.summary["status"] == "failed"
    assert "time limit: max_cpu_s = 0.2 s of CPU reached" in res.summary["reason"]
    assert res.summary["t_reached"] < 1.0 and res.summary["cpu_s"] >= 0.2


def test_bad_specs_fail_with_reasons(results_tmp):
    cases = {
        RunSpec(case="NO-SUCH-CASE"): "no case named 'NO-SUCH-CASE'",
        RunSpec(case="STUDY-R3", integrator="rk4"): "needs a step h > 0",
        RunSpec(case="STUDY-R3", integrator="native", h=1e-3): "needs a reference engine",
        RunSpec(case="STUDY-R3", integrator="ode23"): "unknown",
        RunSpec(case="STUDY-R3", engine="no-engine"): "no engine 'no-engine'",
    }
    for spec, fragment in cases.items():
        res = execute(spec)
        assert res.summary["status"] == "failed", spec
        assert fragment in res.summary["reason"], res.summary["reason"]


def test_an_engine_refusal_is_recorded_before_building(results_tmp):
    res = execute(RunSpec(case="RE-U50000-L1000", engine="mujoco", t_end=0.01))
    assert res.summary["status"] == "failed"
    assert "refused by the engine" in res.summary["reason"]
    assert res.summary["n_dof"] == 100_000 and len(res.samples) == 0


@pytest.mark.engine
def test_an_engine_through_ode45_matches_the_core(results_tmp):
    pytest.importorskip("mujoco")
    core = execute(RunSpec(case="RE-U125-L1", t_end=0.02, sample=0.01))
    eng = execute(RunSpec(case="RE-U125-L1", engine="mujoco", t_end=0.02, sample=0.01))
    assert eng.ok, eng.summary["reason"]
    assert eng.summary["engine_version"]
    tip = ["tip_x", "tip_y", "tip_z"]
    assert np.abs(core.samples[tip].to_numpy() - eng.samples[tip].to_numpy()).max() < 1e-9


def test_a_perturbed_run_starts_from_the_shifted_state_and_keeps_its_own_E0(results_tmp):
    base = RunSpec(case="RE-U125-L1", t_end=0.01, sample=0.005)
    pert = RunSpec(case="RE-U125-L1", t_end=0.01, sample=0.005, perturb=1e-9)
    assert pert.run_id != base.run_id and "perturb=1e-09" in pert.label
    a, b = execute(base), execute(pert)
    assert a.ok and b.ok
    case = load_case("RE-U125-L1")
    # every component moves by perturb * max(|y0_i|, 1): q0 = 0 and v0 = (1, 0, ...) -> +1e-9
    q, qd = case.q0 + 1e-9, case.v0 + 1e-9
    assert b.summary["E0"] == pytest.approx(sum(energy(case.chain, q, qd)), rel=1e-15)
    assert b.summary["E0"] != a.summary["E0"]
    assert b.samples["delta_M"].iloc[0] == 0.0  # measured from the run's own E(0)
    # every joint bent by 1e-9 rad about y and z: the tip moves by 1e-9 x (sum of the distances
    # from each joint to the tip) = 1e-9 x (125 - 124 x 125 / 2 / 125) m in -z and in y
    d = (b.samples.iloc[0][["tip_x", "tip_y", "tip_z"]].astype(float).to_numpy()
         - a.samples.iloc[0][["tip_x", "tip_y", "tip_z"]].astype(float).to_numpy())
    lever = 1e-9 * (125 - 124 / 2)
    assert np.allclose(d, [0.0, lever, -lever], rtol=1e-6, atol=1e-13)


def test_the_run_id_follows_the_case_file_s_content(tmp_path):
    """An edited case file is another run: its id changes with the file's bytes (not only its
    name or path), and comes back when the bytes do."""
    path = tmp_path / "mine.toml"
    text = (CASES_DIR / "STUDY-R3.toml").read_text()
    path.write_text(text)
    before = RunSpec(case=str(path), t_end=0.2).run_id
    assert RunSpec(case=str(path), t_end=0.2).run_id == before
    path.write_text(text.replace("links = 3", "links = 5"))
    assert RunSpec(case=str(path), t_end=0.2).run_id != before
    path.write_text(text)
    assert RunSpec(case=str(path), t_end=0.2).run_id == before


def test_a_scenario_s_sources_follow_an_edit_of_the_model_file_it_names(tmp_path):
    """source_files is kept per version of the scenario file: pointed at another model file,
    the scenario's sources (and its runs' ids) follow at once."""
    import shutil

    from redysim.io.scenarios import SCENARIOS_DIR, source_files

    loops = tmp_path / "loops"
    loops.mkdir()
    for name in ("pinned_chain_10.toml", "crank_rocker.toml"):
        shutil.copy(SCENARIOS_DIR.parent / "loops" / name, loops / name)
    scenario = tmp_path / "scenes" / "mine.toml"
    scenario.parent.mkdir()
    text = (SCENARIOS_DIR / "CATENARY.toml").read_text()
    scenario.write_text(text)
    first = source_files(scenario)
    assert [p.name for p in first] == ["mine.toml", "pinned_chain_10.toml"]
    before = RunSpec(case=str(scenario)).run_id
    scenario.write_text(text.replace("pinned_chain_10.toml", "crank_rocker.toml"))
    assert [p.name for p in source_files(scenario)] == ["mine.toml", "crank_rocker.toml"]
    switched = RunSpec(case=str(scenario)).run_id
    assert switched != before
    model = loops / "crank_rocker.toml"
    model.write_text(model.read_text() + "\n# edited\n")  # the model file's bytes count too
    assert RunSpec(case=str(scenario)).run_id != switched


def test_a_run_takes_the_case_file_s_integrator_and_tolerances(tmp_path):
    """[simulation] integrator, rtol and atol are honoured where the run leaves them to the case
    (they were ignored: every run was ode45 at 1e-4), and a run's own settings win."""
    path = tmp_path / "mine.toml"
    text = (CASES_DIR / "STUDY-R3.toml").read_text()
    assert 'integrator = "ode45"' in text and "rtol = 1e-4" in text
    path.write_text(text.replace('integrator = "ode45"', 'integrator = "dop853"')
                    .replace("rtol = 1e-4", "rtol = 1e-7").replace("atol = 1e-6", "atol = 1e-9"))
    res = execute(RunSpec(case=str(path), t_end=0.2), reference=False)
    assert res.ok, res.summary["reason"]
    s = res.summary
    assert (s["integrator"], s["rtol"], s["atol"]) == ("dop853", 1e-7, 1e-9)
    assert "dop853 rtol=1e-07" in s["label"]
    direct = integrate(lambda t, y: np.concatenate((y[3:], forward_dynamics(
        load_case(path).chain, y[:3], y[3:]))), (0.0, 0.2), np.zeros(6), "dop853", rtol=1e-7,
        atol=1e-9, t_eval=[0.2])
    assert s["steps"] == direct.steps
    own = execute(RunSpec(case=str(path), t_end=0.2, integrator="ode45", rtol=1e-5),
                  reference=False).summary
    assert (own["integrator"], own["rtol"], own["atol"]) == ("ode45", 1e-5, 1e-9)
    fixed = tmp_path / "fixed.toml"
    fixed.write_text(text.replace('integrator = "ode45"', 'integrator = "rk4"\nh = 0.01')
                     .replace("rtol = 1e-4\n", "").replace("atol = 1e-6\n", ""))
    run = execute(RunSpec(case=str(fixed), t_end=0.2), reference=False).summary
    assert (run["integrator"], run["h"], run["steps"]) == ("rk4", 0.01, 20), run["reason"]


@pytest.mark.parametrize("given, field, fragment", [
    (dict(integrator="ode45", h=1e-3), "h", "is the step of a fixed-step integrator"),
    (dict(integrator="rk4", h=1e-3, rtol=1e-6), "rtol", "applies to adaptive integrators"),
    (dict(integrator="rk4"), "h", "missing"),
    (dict(rtol=2.0), "rtol", "must be < 1"),
    (dict(rtol=1e-300), "rtol", "must be at least"),
    (dict(sample=1e-9), "sample", "at most 10,000,000"),
    (dict(integrator="rk4", h=1e-9), "h", "at most 100,000,000"),
    (dict(t_end=1e300), "t_end", "at most 1e+06 s"),
])
def test_settings_that_cannot_run_are_refused_naming_the_field(given, field, fragment):
    """What hung or ran silently with another meaning (--sample 1e-9, rk4 at h = 1e-9,
    rtol = 1e-300, t_end = 1e300, a step given to ode45) fails at once, naming the field."""
    res = execute(RunSpec(case="STUDY-R3", **given), reference=False)
    assert res.summary["status"] == "failed"
    assert res.summary["reason"].startswith(f"SettingsError: run: {field}"), res.summary["reason"]
    assert fragment in res.summary["reason"]
    assert res.summary["cpu_s"] != res.summary["cpu_s"]  # NaN: it never started
