"""Every engine on the same protein backbone (redysim.io.proteins): the GIM, the bias and the
energy against the core's, and qdd against the 50-digit reference, on a poly-alanine chain in a
seeded random conformation and on ubiquitin's floating backbone.

qdd is judged against the reference, not against the core: an engine that solves the dense GIM
(Pinocchio's CRBA adapter, MuJoCo, Exudyn) loses cond(GIM) eps to its Cholesky solve (measured
~1e-10 on these chains, cond ~1e7-1e8), the O(n) recursions (the core, Pinocchio's ABA, DART,
Drake) ~1e-14."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from conftest import rel
from engine_chains import engine_or_skip

import redysim
from redysim import references
from redysim.harness import hiprec
from redysim.io.cases import CASES_DIR

pytestmark = pytest.mark.engine

PROTEINS = Path(CASES_DIR) / "proteins"
STAGE_TOL = 1e-12  # GIM, bias, energy: no solve, so no conditioning (measured <= 1.4e-13)
RECURSIVE_TOL = 1e-12  # qdd's true error of an O(n) recursion (measured <= 1.5e-14)
DENSE_TOL = 1e-8  # qdd's true error of a dense Cholesky solve (measured <= 3.5e-9)
DENSE = ("pinocchio-crba", "mujoco", "exudyn")


def _state(model, seed):
    rng = np.random.default_rng(seed)
    q = model.initial()
    fixed = slice(7, None) if model.quaternions.size else slice(None)
    q[fixed] = rng.uniform(-math.pi, math.pi, q[fixed].size)
    return q, rng.normal(0.0, 0.5, model.n_v), rng.normal(0.0, 1.0, model.n_v)


@pytest.fixture(scope="module", params=["poly-ala-100", "ubiquitin"])
def case(request):
    model = redysim.load_model(PROTEINS / f"{request.param}.toml")
    q, v, tau = _state(model, 20261127)
    return model, q, v, tau, hiprec.qdd_reference(model, q, v, tau, output="dd") \
        if not model.quaternions.size else None


def test_the_cores_qdd_is_within_rounding_of_the_reference():
    """The 1,000-residue chain (2,000 DOF) in a random conformation: RGE-A's true error."""
    model = redysim.load_model(PROTEINS / "poly-ala-1000.toml")
    q, v, tau = _state(model, 20261128)
    ref = hiprec.qdd_reference(model, q, v, tau, output="dd")
    assert hiprec.relative_errors(redysim.forward_dynamics(model, q, v, tau), ref)[0] \
        < RECURSIVE_TOL


@pytest.mark.parametrize("name", list(references.ENGINES))
def test_every_engine_builds_and_agrees(case, name):
    model, q, v, tau, ref = case
    cls = engine_or_skip(name)
    assert cls.limits(model).ok, cls.limits(model).reason
    eng = cls(model)
    assert rel(eng.mass_matrix(q), redysim.mass_matrix(model, q)) < STAGE_TOL
    assert rel(eng.bias(q, v), redysim.phi(model, q, v)) < STAGE_TOL
    assert rel(np.array(eng.energy(q, v)), np.array(redysim.energy(model, q, v))) < STAGE_TOL
    qdd = eng.qdd(q, v, tau)
    if ref is not None:
        err = hiprec.relative_errors(qdd, ref)[0]
        assert err < (DENSE_TOL if name in DENSE else RECURSIVE_TOL), err
    else:  # floating: against the core, which the fixed-base case ties to the reference
        core = redysim.forward_dynamics(model, q, v, tau)
        assert rel(qdd, core) < (DENSE_TOL if name in DENSE else 1e-11)


def test_the_reports_study_runs_and_judges_the_core(tmp_path):
    """reports/proteins.py on the 100-residue chain: a row per method and state, the core's
    within its bound, every engine's row numbered or refused by name; the section renders."""
    from redysim.reports.content import MATCH
    from redysim.reports.proteins import RECURSIVE_BOUND, proteins_section, run
    from redysim.reports.results import Results

    doc = run(tmp_path / "proteins", sizes=(100,), log=lambda _msg: None)
    core = [r for r in doc["true_error"] if r["method"].startswith("redysim")]
    assert len(core) == 2 and all(r["rel2"] < RECURSIVE_BOUND for r in core)
    assert {r["method"] for r in doc["true_error"]} >= {"redysim (RGE-A)", *references.ENGINES}
    assert all(r["status"] == "ok" or r["reason"] for r in doc["true_error"])
    assert doc["per_call"][0]["backbone_s"] > 0 and doc["per_call"][0]["rope_s"] > 0
    sec = proteins_section(Results(tmp_path))
    err = sec.items[0]
    assert err.not_run == ""
    assert [r.kind for r in err.rows if r.cells[4].startswith("redysim")] == [MATCH, MATCH]
