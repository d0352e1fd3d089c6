"""Refinement studies (harness.refine) and the runs they are made of (RunSpec.links and
.precision): the hanging chain's modes against an independent stiffness and the continuum's
Bessel-zero frequencies, a small study end to end, the advice and its check."""

import math
from pathlib import Path

import numpy as np
import pytest

import redysim
from redysim.errors import SettingsError
from redysim.harness import refine
from redysim.harness.run import execute
from redysim.harness.spec import RunSpec
from redysim.harness.sweep import SweepError, run_sweep, sweep_from_dict

REPO = Path(__file__).resolve().parents[1]

SMALL_FALL = """
[case]
name = "small-fall"
[chain]
links = 8
joint = "R"
total_length = 1.0
density = 7850.0
radius = 0.005
inertia = "cylinder"
[initial]
q = 0.0
v = 0.0
[simulation]
t_end = 0.1
sample_interval = 0.02
"""


@pytest.fixture
def small_fall(tmp_path):
    path = tmp_path / "small-fall.toml"
    path.write_text(SMALL_FALL)
    return path


def planar_chain(n=6):
    rng = np.random.default_rng(11)
    links = [redysim.Link(float(rng.uniform(0.1, 0.3)), float(rng.uniform(0.5, 2.0)),
                          (float(rng.uniform(0.05, 0.1)), 0.0, 0.0),
                          ((1e-4, 0, 0), (0, 2e-3, 0), (0, 0, 2e-3))) for _ in range(n)]
    return redysim.Chain.build(links, ["R"] * n, name="planar")


def test_the_hanging_stiffness_is_the_gradient_of_the_gravity_torques():
    """K from the closed form against central differences of the core's inverse dynamics (the
    joint torques that hold the chain still: the potential's gradient)."""
    chain = planar_chain()
    n = chain.n_dof
    q0 = np.zeros(n)
    q0[0] = -math.pi / 2
    zero = np.zeros(n)
    h = 1e-6
    K_fd = np.empty((n, n))
    for j in range(n):
        dq = np.zeros(n)
        dq[j] = h
        K_fd[:, j] = (redysim.inverse_dynamics(chain, q0 + dq, zero, zero)
                      - redysim.inverse_dynamics(chain, q0 - dq, zero, zero)) / (2 * h)
    from scipy.linalg import eigh

    M = redysim.mass_matrix(chain, q0)
    expected = np.sqrt(eigh(0.5 * (K_fd + K_fd.T), M, eigvals_only=True))
    np.testing.assert_allclose(refine.hanging_modes(chain, n), expected, rtol=1e-7)


def test_hanging_chain_frequencies_converge_to_the_continuum_at_second_order(tmp_path):
    study = refine.modes_study(levels=(8, 16, 32, 64, 128, 256), m=3)
    for p in study["orders"]:
        assert 1.9 < p < 2.1
    finest = study["levels"][-1]["rel_err"]
    for extrapolated, last in zip(study["richardson_rel_err"], finest, strict=True):
        assert extrapolated < last / 20  # Richardson lands far closer to the Bessel zeros
    advice = refine.advise_modes(study, 1, 1e-4)  # mode 1: 1.2e-4 at 16 links, 3.0e-5 at 32
    assert advice["links"] == 32 and advice["max_rel_err"] <= 1e-4
    assert refine.advise_modes(study, 3, 1e-9) is None


def test_a_coarse_run_starts_from_the_same_state_and_records_its_size(small_fall):
    fine = execute(RunSpec(str(small_fall), t_end=0.02, sample=0.01), reference=False).summary
    coarse = execute(RunSpec(str(small_fall), t_end=0.02, sample=0.01, links=2),
                     reference=False).summary
    assert (fine["n_links"], coarse["n_links"], coarse["n_dof"]) == (8, 2, 2)
    assert coarse["E0"] == pytest.approx(fine["E0"], rel=1e-13)  # straight at rest: exact map
    assert coarse["model_mib"] < fine["model_mib"]


def test_a_count_that_does_not_divide_rebuilds_a_straight_rope(small_fall, tmp_path):
    """links = 3 of an 8-link rope: the rope rebuilt from its file at 3 links (the same body:
    its potential energy at rest is the 8-link rope's); where lumping also applies (4 links)
    the two are the same model to rounding."""
    fine = execute(RunSpec(str(small_fall), t_end=0.02, sample=0.01), reference=False).summary
    three = execute(RunSpec(str(small_fall), t_end=0.02, sample=0.01, links=3),
                    reference=False).summary
    assert (three["n_links"], three["n_dof"]) == (3, 3)
    assert three["E0"] == pytest.approx(fine["E0"], rel=1e-13)
    from redysim.harness.run import coarse_case
    from redysim.io.cases import rebuilt_case

    case = redysim.load_case(small_fall)
    lumped, rebuilt = coarse_case(case, 4)[0].chain, rebuilt_case(case, 4).chain
    for field in ("mass", "length", "inertia_O", "mass_com"):
        assert np.allclose(getattr(lumped, field), getattr(rebuilt, field), rtol=1e-13,
                           atol=1e-16), field
    q = np.random.default_rng(3).uniform(-1.0, 1.0, 4)
    v = np.random.default_rng(4).uniform(-1.0, 1.0, 4)
    a = redysim.forward_dynamics(lumped, q, v)
    assert np.abs(a - redysim.forward_dynamics(rebuilt, q, v)).max() <= 1e-12 * np.abs(a).max()


@pytest.mark.parametrize("per_link", ["link_length", "link_mass"])
def test_a_rope_given_link_by_link_keeps_its_length_and_mass_when_rebuilt(tmp_path, per_link):
    """A fourth hold-out battery: STUDY-R10 (10 links of link_length 1 m) rebuilt at 20 links
    was a 20 m rope (`simulate STUDY-R10 --links 20`: the tip at x = 20 m), and `advise` then
    blamed the model for a 10 m gap. The rebuilt rope is the same body: where lumping applies
    (10 -> 5 links, two links each) the two are the same model to rounding, and at any count
    its length, mass and resting energy are the file's."""
    from redysim.harness.run import coarse_case
    from redysim.io.cases import rebuilt_case

    text = (REPO / "cases" / "STUDY-R10.toml").read_text()
    if per_link == "link_mass":  # the same rope by each link's mass (pi r^2 l rho)
        text = text.replace("density = 7025.0", f"link_mass = {np.pi * 0.02**2 * 7025.0!r}")
    path = tmp_path / "r10.toml"
    path.write_text(text)
    case = redysim.load_case(path)
    lumped, rebuilt = coarse_case(case, 5)[0].chain, rebuilt_case(case, 5).chain
    for field in ("mass", "length", "inertia_O", "mass_com"):
        assert np.allclose(getattr(lumped, field), getattr(rebuilt, field), rtol=1e-13,
                           atol=1e-16), field
    for links in (7, 20):
        chain = rebuilt_case(case, links).chain
        assert chain.n_links == links
        assert float(np.sum(chain.length)) == pytest.approx(10.0, rel=1e-14)
        assert float(chain.total_mass) == pytest.approx(float(case.chain.total_mass), rel=1e-14)


def test_bad_links_and_precision_are_named(small_fall, tmp_path):
    case = redysim.load_case(small_fall)
    with pytest.raises(SettingsError, match="links = 0.5: must be a whole number of links"):
        RunSpec(str(small_fall), links=0.5).resolved(case)  # type: ignore[arg-type]
    curled = tmp_path / "curled.toml"  # bent from the start: another shape at 3 links
    curled.write_text(SMALL_FALL.replace("q = 0.0", "q = { fill = 10.0, unit = \"deg\" }"))
    with pytest.raises(SettingsError, match=r"links = 3: does not divide the case's 8 links.*"
                                            r"cannot be rebuilt.*curled.toml starts bent"):
        RunSpec(str(curled), links=3).resolved(redysim.load_case(curled))
    with pytest.raises(SettingsError, match="precision = 'float16': choose one of"):
        RunSpec(str(small_fall), precision="float16").resolved(case)
    with pytest.raises(SettingsError, match="reduced precision is the core's only"):
        RunSpec(str(small_fall), engine="mujoco", precision="float32").resolved(case)
    doc = {"sweep": {"name": "s", "cases": [str(curled)], "links": [8, 3]}}
    with pytest.raises(SweepError, match=r"sweep.links.*3.*starts bent"):
        sweep_from_dict(doc, source="s.toml")
    doc["sweep"]["links"] = [8, 2.5]
    with pytest.raises(SweepError, match=r"sweep.links\[1\] = 2.5: must be a whole number"):
        sweep_from_dict(doc, source="s.toml")


def small_study(case, out):
    """The refinement study of an 8-link rope case file: at 8, 4 and 2 links, ode45 at two
    tolerances, and the reference run (DOP853 at 1e-10 on 8 links), swept into ``out``."""
    doc = {"sweep": {"name": "small", "cases": [str(case)], "links": [8, 4, 2],
                     "integrators": ["ode45"], "rtols": [1e-3, 1e-6],
                     "extra": [{"case": str(case), "links": 8, "integrator": "dop853",
                                "rtol": 1e-10, "atol": 1e-12}]}}
    sweep = sweep_from_dict(doc, source="small.toml")
    run_sweep(sweep.specs, out, name="small", workers=1, progress=False)
    return refine.load_study(out, "small")


@pytest.fixture
def study(tmp_path, small_fall):
    return small_study(small_fall, tmp_path / "out")


def test_a_study_measures_every_run_against_its_finest_tightest_run(study):
    ref = study.reference
    assert (ref["n_links"], ref["integrator"], ref["rtol"]) == (8, "dop853", 1e-10)
    r = study.runs.set_index(["n_links", "rtol"])
    assert study.runs.loc[study.runs["run_id"] == ref["run_id"], "tip_err"].iloc[0] == 0.0
    # coarser models are further off; at 8 links the integrator's error is all there is
    assert r.loc[(2, 1e-6), "tip_err"] > r.loc[(4, 1e-6), "tip_err"] > r.loc[(8, 1e-6),
                                                                             "tip_err"]
    conv = refine.convergence(study)
    assert [lv["links"] for lv in conv["levels"]] == [2, 4, 8]
    assert conv["order_levels"] == [2]  # only levels <= finest / 4 are fitted


def _inject_costs(study, cost):
    """The study with its runs' CPU times replaced by ``cost(n_links, rtol)``: the choosing
    logic is tested on known costs, not on what this machine measured (an 8-link study's runs
    take milliseconds, and their measured order is noise)."""
    r = study.runs
    c = [float(cost(n, t)) for n, t in zip(r["n_links"], r["rtol"], strict=True)]
    # as measured by harness.cost: the least of 20 repeats, spread 0 (uncertainty: the noise
    # floor), no work measured (the pick among indistinguishable runs by the order given)
    study.runs = r.assign(cpu_s=c, cost_s=c, cost_repeats=20, cost_spread=0.0,
                          work_s=float("nan"))
    return study


def test_advice_names_the_runs_it_cannot_tell_from_the_pick(study):
    """Costs within the noise floor of each other are indistinguishable: the advice says so,
    and picks among them the one of least work (RHS calls x one call's CPU)."""
    _inject_costs(study, lambda links, rtol: {2: 9.0, 4: 4.0, 8: 4.2}[links])
    r = study.runs
    tol = float(r.loc[r["n_links"] == 4, "tip_err"].max()) * 1.01
    a = refine.advise(study, tol)
    assert a.links == 4 and a.cpu_s == 4.0
    assert any(t.startswith("8 links") for t in a.indistinguishable)
    # the 8-link runs of least work: picked among the indistinguishable
    study.runs = study.runs.assign(work_s=[1.0 if n == 8 else 2.0 for n in r["n_links"]])
    b = refine.advise(study, tol)
    assert b.links == 8 and any(t.startswith("4 links") for t in b.indistinguishable)


def test_advice_is_the_cheapest_run_that_met_the_tolerance(study):
    # a cost that grows with the links and the tolerance's tightness
    _inject_costs(study, lambda links, rtol: links * (1.0 if rtol == 1e-3 else 3.0))
    r = study.runs
    tol = float(r.loc[r["n_links"] == 4, "tip_err"].max()) * 1.01
    a = refine.advise(study, tol)
    met = r[(r["tip_err"] <= tol) & (r["run_id"] != study.reference["run_id"])]
    assert set(met["n_links"]) == {4, 8}  # the 2-link model is further off than tol
    assert (a.links, a.rtol, a.cpu_s) == (4, 1e-3, 4.0) and a.tip_err <= tol
    assert a.candidates == len(met)
    finest = met[met["n_links"] == 8]
    assert a.finest_cpu_s == finest["cpu_s"].min() and a.saved == a.finest_cpu_s / 4.0
    assert refine.advise(study, 1e-30) is None
    with pytest.raises(ValueError, match="tol = -1"):
        refine.advise(study, -1)


def test_equal_costs_are_broken_by_fewer_links_then_the_run_id(study):
    _inject_costs(study, lambda links, rtol: 1.0)
    r = study.runs
    a = refine.advise(study, float(r["tip_err"].max()))
    first = r[(r["n_links"] == 2) & (r["run_id"] != study.reference["run_id"])]
    assert a.links == 2 and a.rtol == float(first.sort_values("run_id")["rtol"].iloc[0])


def test_advice_by_rhs_calls_needs_no_clock(study):
    """cost = "nfev": the run of fewest RHS calls, the same on every machine."""
    r = study.runs
    tol = float(r["tip_err"].max())
    a = refine.advise(study, tol, cost="nfev")
    others = r[r["run_id"] != study.reference["run_id"]]
    fewest = others.sort_values(["nfev", "n_links", "run_id"]).iloc[0]
    assert (a.links, a.rtol) == (int(fewest["n_links"]), float(fewest["rtol"]))


def test_the_check_reproduces_the_sweeps_error_and_a_finer_reference(study):
    """The advised model run again by the Python stepping loop gives the sweep's error (the
    compiled loop takes the same steps), and the rope at twice the links is a reference close to
    the finest (the study's own error bound)."""
    # by RHS calls, not measured CPU: the same advice on any machine (the coarsest, loosest)
    a = refine.advise(study, float(study.runs["tip_err"].max()), cost="nfev")
    assert (a.links, a.rtol) == (2, 1e-3)
    check = refine.check_advice(study, a)
    assert check["error_vs_finest"] == pytest.approx(a.tip_err, rel=1e-9, abs=1e-13)
    assert check["finer_links"] == 16
    assert check["finest_vs_finer"] < check["error_vs_finest"]


def test_a_finer_case_is_the_same_rope(small_fall):
    case = redysim.load_case(small_fall)
    finer = refine.finer_case(small_fall, 3)
    assert finer.chain.n_links == 24
    assert finer.chain.total_mass == pytest.approx(case.chain.total_mass, rel=1e-14)
    assert finer.chain.length.sum() == pytest.approx(1.0, rel=1e-14)


def test_a_study_folder_that_is_not_one_is_named(tmp_path):
    with pytest.raises(refine.StudyError, match="no runs/ folder"):
        refine.load_study(tmp_path)


def test_advise_from_the_command_line(study, capsys):
    from redysim.harness.cli import main

    tol = float(study.runs["tip_err"].max())
    assert main(["advise", str(study.folder), "--tip-tol", f"{tol:.6g}"]) == 0
    out = capsys.readouterr().out
    assert "advice for a tip path within" in out and "--links" in out
    assert main(["advise", str(study.folder), "--tip-tol", "1e-30"]) == 1
    assert "no measured run met" in capsys.readouterr().out
    assert main(["advise", "hanging", "--modes", "1", "--freq-tol", "0.01"]) == 0
    assert "links have the first 1 frequencies within 0.01" in capsys.readouterr().out


@pytest.mark.parametrize("argv, fragment", [
    (["advise", "fall"], "--tip-tol: missing"),
    (["advise", "hanging", "--modes", "2"], "needs both"),
    (["advise", "fall", "--tip-tol", "0.1", "--modes", "2"], "apply to the hanging chain only"),
    (["advise", "STUDY-R10", "--modes", "3", "--freq-tol", "0.01"],  # (a fourth battery: was
     "apply to the hanging chain only"),                               # "--tip-tol missing")
    (["advise", "/nonexistent/study", "--tip-tol", "0.1"], "no runs/ folder"),
])
def test_bad_advise_arguments_are_named(argv, fragment, capsys):
    from redysim.harness.cli import main

    assert main(argv) == 2
    assert fragment in capsys.readouterr().err


# --------------------------------------------------------------------------- a user's rope
def test_coarse_levels_divide_the_links_and_step_down_by_at_least_1_8():
    assert refine.coarse_levels(250) == [125, 50, 25, 10, 5, 2]
    assert refine.coarse_levels(12) == [6, 3]
    assert refine.coarse_levels(7) == []  # a prime: no coarse link lumps the same number


def level(links, err):
    return {"links": links, "tip_err": err}


def test_the_verdict_on_a_studys_levels():
    # errors 4^-k at 2^k links: order 2 throughout, steady
    orders, converges, steady = refine.verdict([level(2, 1 / 4), level(4, 1 / 16),
                                                level(8, 1 / 64)])
    assert orders == pytest.approx([2.0, 2.0]) and converges and steady
    # falling at orders 1 then 2: converging, not steady
    orders, converges, steady = refine.verdict([level(2, 0.4), level(4, 0.2), level(8, 0.05)])
    assert orders == pytest.approx([1.0, 2.0]) and converges and not steady
    # a whip's tip: the error grows with the links somewhere: no convergence
    assert refine.verdict([level(2, 0.1), level(4, 0.12), level(8, 0.05)])[1:] == (False, False)
    # falling too slowly (order 0.1) to be a convergence
    assert refine.verdict([level(2, 0.1), level(4, 0.0933), level(8, 0.0871)])[1] is False


def test_a_rope_whose_initial_state_depends_on_its_links_is_not_refined(small_fall, tmp_path):
    curled = tmp_path / "curled.toml"
    curled.write_text(SMALL_FALL.replace("q = 0.0", "q = { fill = 10.0, unit = \"deg\" }"))
    fine, why = refine._refined(str(curled), redysim.load_case(curled))
    assert fine is None and "depends on the link count" in why
    fine, why = refine._refined(str(small_fall), redysim.load_case(small_fall))
    assert fine is not None and fine.chain.n_links == 16 and why == ""


@pytest.mark.slow
def test_a_rope_cases_own_study_advises_a_model_that_meets_the_tolerance(tmp_path):
    """The study of a 32-link falling rope over 0.1 s; its advice, simulated through the public
    API, is within the tolerance of a 128-link rope by DOP853 at 1e-10 (a model the study never
    ran), and cheaper in RHS calls x links than the user's model meeting it."""
    case = tmp_path / "fall32.toml"
    case.write_text(SMALL_FALL.replace("links = 8", "links = 32"))
    tol = 2e-3
    st = refine.own_study(case, tol, tmp_path / "study", workers=1, progress=False,
                          log=lambda *_: None)
    a = st.advice
    assert st.converges and a is not None and a.links < 32
    # between the last level that missed (4 links) and the first that met (8), the rope was
    # rebuilt at counts that do not divide 32, and the advice is one of them
    levels = {d["links"]: d["tip_err"] for d in st.conv["levels"]}
    budget = tol - st.ref_error
    assert levels[4] > budget >= levels[8]
    assert st.searched and all(4 < d["links"] < 8 for d in st.searched)
    assert a.links in {d["links"] for d in st.searched if d["tip_err"] <= budget}
    assert st.check["tip_err"] == pytest.approx(a.tip_err, rel=1e-9)  # run again: the same
    assert math.isfinite(st.ref_error) and a.tip_err + st.ref_error <= tol
    # independently: the advised model against a 4x finer rope
    from redysim.harness.run import coarse_case
    from redysim.simulation import frame_observer, simulator

    def tips(chain, q0, v0, integrator, rtol):
        sim = simulator(chain, 0.1, q0=q0, v0=v0, integrator=integrator, rtol=rtol,
                                atol=rtol * 1e-2, sample=0.02,
                                observe={"tip": frame_observer(chain, "tip")})
        return sim.run().observed["tip"][:, :3]

    fine = refine.finer_case(case, 4)
    ref = tips(fine.chain, fine.q0, fine.v0, "dop853", 1e-10)
    model = coarse_case(redysim.load_case(case), a.links)[0]  # lumped or rebuilt
    got = tips(model.chain, model.q0, model.v0, a.integrator, a.rtol)
    assert np.linalg.norm(got - ref, axis=1).max() <= tol
    # asked again: every run cached (its file untouched), none run again
    files = {p.name: p.stat().st_mtime_ns for p in (tmp_path / "study" / "runs").iterdir()}
    again = refine.own_study(case, tol, tmp_path / "study", workers=1, progress=False,
                             log=lambda *_: None, check=False)
    assert {p.name: p.stat().st_mtime_ns
            for p in (tmp_path / "study" / "runs").iterdir()} == files
    assert again.advice == st.advice


def test_a_rope_with_one_coarser_divisor_is_judged_by_the_finer_rope_and_bisected(tmp_path):
    """A fourth hold-out battery: a straight 6-link rope (one coarser divisor, 3) was declared
    "does not settle ... local orders " (blank) and advised nothing: one level shows no order,
    and the bisection between 3 and 6 links that --help promises never ran. Now the rope at 12
    links judges the convergence (an order over 3, 6 and 12 links), and the rope rebuilt at 4
    and 5 links is searched."""
    case = tmp_path / "r6.toml"
    case.write_text(SMALL_FALL.replace("links = 8", "links = 6").replace(
        "total_length = 1.0", "total_length = 1.2").replace("t_end = 0.1", "t_end = 0.2"))
    st = refine.own_study(case, 1e-3, tmp_path / "study", workers=1, progress=False,
                          log=lambda *_: None, check=False)
    assert [d["links"] for d in st.conv["levels"]] == [3] and st.orders == []
    assert st.converges and math.isfinite(st.ref_error) and "12 links" in st.ref_error_how
    assert sorted(d["links"] for d in st.searched) == [4, 5]
    assert st.advice is not None


@pytest.mark.slow
def test_advise_on_a_case_file_and_what_it_refuses(tmp_path, small_fall, capsys):
    from redysim.harness.cli import main

    out = tmp_path / "adv"
    assert main(["advise", str(small_fall), "--tip-tol", "0.01", "--out", str(out),
                 "--workers", "1", "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "advice for a tip path within 0.01 m" in text and "run it: redysim simulate" in text
    assert "checked: run again" in text and "model error" in text
    # battery 5 (F9): a straight rope of a prime count was refused ("no coarser model") though
    # --help promises the rope rebuilt at other counts: its coarser models are rebuilt ropes
    prime = tmp_path / "prime.toml"
    prime.write_text(SMALL_FALL.replace("links = 8", "links = 7"))
    assert main(["advise", str(prime), "--tip-tol", "0.01", "--out", str(tmp_path / "p"),
                 "--workers", "1", "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "the coarser models are the rope rebuilt at 3 links" in text
    assert "advice for a tip path within 0.01 m" in text
    bent = tmp_path / "bent.toml"  # a rope that starts bent: no rebuilt rope is the same rope
    bent.write_text(SMALL_FALL.replace("links = 8", "links = 7").replace(
        "q = 0.0", "q = [0.0, 0.1, 0.0, 0.0, 0.0, 0.0, 0.0]"))
    assert main(["advise", str(bent), "--tip-tol", "0.01"]) == 2
    err = capsys.readouterr().err
    assert "no coarser model" in err and "cannot be rebuilt at another count" in err
    robot = tmp_path / "arm.urdf"
    robot.write_text("<robot name='a'><link name='b'/></robot>")
    assert main(["advise", str(robot), "--tip-tol", "0.01"]) == 2  # a robot: its reductions,
    assert "arm.urdf" in (err := capsys.readouterr().err) and "no body moves" in err  # named
    assert main(["advise", "fall", "--tip-tol", "0.01", "--t-end", "1"]) == 2
    assert "a finished study is read as it is" in capsys.readouterr().err


def test_the_reports_advice_tables_judge_the_check_against_the_tolerance():
    pytest.importorskip("matplotlib")
    from redysim.reports.content import DIFFER, MATCH
    from redysim.reports.refine import own_table, reduce_table

    advice = {"links": 25, "integrator": "ode45", "rtol": 1e-3, "tip_err": 1.8e-4,
              "cpu_s": 4e-3, "steps": 89, "finest_cpu_s": 0.04, "finest_rtol": 1e-3,
              "saved": 10.0}
    own = {"case": "C", "tol": 1e-3, "t_end": 0.3, "links": 125, "reference_cpu_s": 0.4,
           "levels": [{"links": 5, "tip_err": 5e-3, "cpu_s": 1e-3}], "orders": [],
           "converges": True, "ref_error": 6e-5, "ref_error_how": "measured", "notes": [],
           "searched": [{"links": 15, "tip_err": 3.8e-4}],
           "advice": advice, "check": {"tip_err": 1.8e-4, "cpu_s": 4e-3, "steps": 89,
                                       "bound": 2.4e-4}}
    rows = {r.cells[0]: r for r in own_table({"own": own}).rows}
    assert "15 links 3.80e-04 m" in rows["the rope rebuilt between two levels (bisected; ode45 "
                                        "1e-8)"].cells[1]
    kinds = {r.cells[0]: r.kind for r in own_table({"own": own}).rows}
    assert kinds["advice"] == MATCH and kinds["checked (run again)"] == MATCH
    own["check"]["bound"] = 2e-3  # the advice, run again, out of the tolerance: red
    kinds = {r.cells[0]: r.kind for r in own_table({"own": own}).rows}
    assert kinds["advice"] == DIFFER and kinds["checked (run again)"] == DIFFER
    assert own_table({}).not_run
    red = {"scenario": "S", "frame": "f", "tol": 1e-3, "t_end": 0.5, "full_dof": 38,
           "reduced_dof": 17, "candidates": [["a", 1e-6]] * 10, "locked": ["a"],
           "error": 3e-4, "file_check": 0.0, "notes": [],
           "practical": {"full": {"nfev": 79, "dof": 38, "cpu_s": 2e-3},
                         "reduced": {"nfev": 79, "dof": 17, "cpu_s": 1e-3}, "error": 3e-4}}
    rows = {r.cells[0]: r for r in reduce_table({"reduce": red}).rows}
    assert rows["their path error (each set run)"].kind == MATCH
    assert "38 -> 17 DOF" in rows["locked together"].cells[1]
    red["error"] = 2e-3
    rows = {r.cells[0]: r for r in reduce_table({"reduce": red}).rows}
    assert rows["their path error (each set run)"].kind == DIFFER
    assert reduce_table({"reduce": {"skipped": "no robots"}}).not_run == "not run: no robots"


def test_the_order_of_three_models_from_their_two_differences():
    e = [n ** -2.0 for n in (10, 20, 40)]  # errors C n^-p with p = 2 exactly
    assert refine.three_level_order(10, 20, 40, e[0] - e[1], e[1] - e[2]) == pytest.approx(2.0)
    e = [n ** -0.5 for n in (25, 125, 250)]  # unequal ratios, a low order
    assert refine.three_level_order(25, 125, 250, e[0] - e[1], e[1] - e[2]) == \
        pytest.approx(0.5)
    # differences that do not shrink: no positive order (a singular scene)
    assert refine.three_level_order(10, 20, 40, 1.0, 1.0) == 0.0
    assert math.isnan(refine.three_level_order(10, 20, 40, 0.0, 1.0))


def test_the_adaptive_table_marks_the_best_static_model_and_adaptive_runs_short_of_the_target():
    """benchmarks/adaptive_rope.py's results in the report: green the best static model, red an
    adaptive run within the tolerance that does not halve its work; the figure draws."""
    pytest.importorskip("matplotlib")
    from redysim.reports.content import DIFFER, INFO, MATCH
    from redysim.reports.refine import adaptive_figure, adaptive_table

    static = [{"links": 8, "error": 6e-2, "nfev": 500, "work": 4000},
              {"links": 9, "error": 4.8e-2, "nfev": 600, "work": 5400}]
    run = {"error": 4.5e-2, "work": 11500, "work_normalised": 8100.0, "switches": 2,
           "mean_groups": 10.0, "max_groups": 16, "weld_energy_J": -2e-3,
           "momentum_residual": 1e-15}
    cheap = {**run, "error": 9e-2, "work_normalised": 2000.0, "eps": 0.1, "coarsest": 4,
             "finest": 16}
    scene = {"scene": "whip", "case": "fall-R256.toml", "t_end": 0.8, "tip_tol": 5e-2,
             "rtol": 1e-3, "static": static, "best_static": static[1],
             "oracle": [{**run, "plan": [[0.0, 8], [0.4, 16]]}], "indicator": [cheap],
             "best_adaptive": {**run, "plan": [[0.0, 8], [0.4, 16]]}}

    class Res:
        def bench(self, name):
            return {"scenes": [scene], "provenance": {}} if name == "adaptive_rope" else None

    t = adaptive_table(Res())
    kinds = [r.kind for r in t.rows]
    assert kinds == [INFO, MATCH, DIFFER, INFO]  # 8 links; 9 (best); the schedule; missed
    assert "8 links, then 16 links from 0.4 s" in t.rows[2].cells[1]
    assert "1.50x the static's" in t.notes[0]
    assert not adaptive_figure(Res()).not_run

    class Empty:
        def bench(self, name):
            return None

    assert adaptive_table(Empty()).not_run and adaptive_figure(Empty()).not_run


def test_the_search_runs_when_no_divisor_meets_the_tolerance(tmp_path):
    """An 8-link rope whose divisors (4 and 2 links) both miss the budget: the counts between 4
    and 8 are searched (they were not: the advice was the user's 8 links), and the advice is a
    rebuilt count under 8 whose model error, measured by the study, is within the budget; its
    path, simulated afresh through the public API, is within the budget of the user's model by
    DOP853 at 1e-10."""
    case = tmp_path / "r8.toml"
    case.write_text(SMALL_FALL)
    tol = 1.5e-3
    st = refine.own_study(case, tol, tmp_path / "study", workers=1, progress=False,
                          log=lambda *_: None, check=False)
    budget = tol - st.ref_error
    levels = {d["links"]: d["tip_err"] for d in st.conv["levels"]}
    assert set(levels) == {2, 4} and min(levels.values()) > budget  # no divisor meets it
    assert st.searched and all(4 < d["links"] < 8 for d in st.searched)
    a = st.advice
    assert a is not None and 4 < a.links < 8
    assert a.links in {d["links"] for d in st.searched if d["tip_err"] <= budget}
    from redysim.harness.run import coarse_case
    from redysim.simulation import frame_observer, simulator

    def tips(model, integrator, rtol):
        sim = simulator(model.chain, 0.1, q0=model.q0, v0=model.v0, integrator=integrator,
                        rtol=rtol, atol=rtol * 1e-2, sample=0.02,
                        observe={"tip": frame_observer(model.chain, "tip")})
        return sim.run().observed["tip"][:, :3]

    own = redysim.load_case(case)
    got = tips(coarse_case(own, a.links)[0], a.integrator, a.rtol)
    assert np.linalg.norm(got - tips(own, "dop853", 1e-10), axis=1).max() <= budget


@pytest.mark.parametrize("times", [1, 2])
def test_an_advise_study_survives_its_runs_being_set_aside(tmp_path, monkeypatch, times):
    """Battery 5 (F10): the code changing while `advise` ran made each fresh run's row
    another run id's: the sweep set the files aside as damaged, and the study then raised
    KeyError 'run_id'. Here the first ``times`` sweeps' answers lose every fresh row as that
    did (their files moved to damaged/): once, the runs are redone and the study advises as
    on a quiet tree; twice, it is refused by name."""
    import sys

    sweep = sys.modules[refine.__package__ + ".sweep"]
    real = sweep.run_sweep
    calls = [0]

    def setting_aside(specs, out, **kw):
        runs = real(specs, out, **kw)
        calls[0] += 1
        if calls[0] > times:
            return runs
        (out / "damaged").mkdir(exist_ok=True)
        for s in specs:
            for sub, ext in (("runs", ".parquet"), ("samples", ".parquet"), ("manifest", ".json")):
                f = out / sub / f"{s.run_id}{ext}"
                if f.exists():
                    f.replace(out / "damaged" / f"{sub}-{f.name}")
        return runs.iloc[0:0][[]]  # no row kept: not even the run_id column

    monkeypatch.setattr(sweep, "run_sweep", setting_aside)
    case = tmp_path / "r8.toml"
    case.write_text(SMALL_FALL)
    study = dict(workers=1, progress=False, log=lambda *_: None, check=False)
    if times == 2:
        with pytest.raises(SweepError, match=r"runs = .*have no result there after being done "
                                             r"twice.*run the same command again"):
            refine.own_study(case, 0.01, tmp_path / "study", **study)
        return
    st = refine.own_study(case, 0.01, tmp_path / "study", **study)
    assert st.advice is not None and calls[0] >= 2
    monkeypatch.undo()  # the same advice as a study whose runs were never set aside
    quiet = refine.own_study(case, 0.01, tmp_path / "quiet", **study)
    assert (st.advice.links, st.advice.integrator, st.advice.rtol) == \
        (quiet.advice.links, quiet.advice.integrator, quiet.advice.rtol)
